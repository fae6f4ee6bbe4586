// stipple.mjs: the stipple point-cloud viewer for web pages, an ES module (its types are in
// stipple.d.ts beside it). Modelled on CesiumJS's Viewer: an options object and events.
//
//   import { createViewer } from './stipple.mjs';
//   const viewer = await createViewer(document.getElementById('view'), { url: 'tiles/tileset.json' });
//   viewer.on('load', (info) => console.log(`${info.points} points`));
//   viewer.setOptions({ color: 'classification', pointSize: 2 });
//
// Each viewer is one instance of the WebAssembly program (stipple.js, emscripten's factory: its
// own memory, worker threads and WebGPU device) drawing straight into a canvas the viewer makes
// inside the element: the canvas fills the element and follows its size and devicePixelRatio.
// The viewer talks to its program through slots of the instance's Module object (stipple*: input,
// size, options, camera, what to open, captures, the request to end), which the program polls
// once per animation frame, and the program reports what it does through Module.stippleReport,
// which the viewer turns into its state and events. Threads need a cross-origin isolated page
// (COOP/COEP headers, or stipple-isolation.js beside this file).
import createStippleProgram from './stipple.js';

// The colour modes, as `stipple render --color` names them.
export const colorModes = Object.freeze(['auto', 'rgb', 'intensity', 'classification', 'elevation',
                                         'return', 'constant']);

// The vertical field of view the program frames with (degrees): a link leaves it out.
const defaultFov = 50;

function number(name, lo, hi, { above = false, integer = false } = {}) {
  return (v) => {
    const x = typeof v === 'string' && v.trim() !== '' ? Number(v) : v;
    if (typeof x !== 'number' || !Number.isFinite(x) || x < lo || x > hi || (above && x <= lo) ||
        (integer && !Number.isInteger(x)))
      throw new RangeError(`${name}: not ${integer ? 'an integer' : 'a number'} in ` +
                           `${above ? '(' : '['}${lo} - ${hi}]: ${v}`);
    return x;
  };
}

function boolean(name) {
  return (v) => {
    if (v === true || v === 1 || v === '1' || v === 'true') return true;
    if (v === false || v === 0 || v === '0' || v === 'false') return false;
    throw new RangeError(`${name}: not true or false: ${v}`);
  };
}

// The options setOptions changes while the view runs (camelCase), each with `stipple render`'s
// name for it (the query's and the link's) and the check of its value (render's ranges).
const runtimeOptions = {
  color: {
    name: 'color',
    parse: (v) => {
      if (!colorModes.includes(v))
        throw new RangeError(`color: not one of ${colorModes.join(', ')}: ${v}`);
      return v;
    },
  },
  pointSize: { name: 'point-size', parse: number('pointSize', 0, 64, { above: true }) },
  edl: { name: 'edl', parse: boolean('edl') },
  edlStrength: { name: 'edl-strength', parse: number('edlStrength', 0, 10000) },
  edlRadius: { name: 'edl-radius', parse: number('edlRadius', 0.5, 16) },
  budget: { name: 'budget', parse: number('budget', 0, Number.MAX_SAFE_INTEGER, { integer: true }) },
  maxSse: { name: 'max-sse', parse: number('maxSse', 0, 1e6, { above: true }) },
  memoryMb: { name: 'memory-mb', parse: number('memoryMb', 1, 1048576, { integer: true }) },
};

// What createViewer passes to the program once, besides the runtime options: `stipple render`'s
// options of the same names (the program checks them: a bad value is an 'error' event).
const startOptions = {
  scenePoints: 'scene-points',
  seed: 'seed',
  width: 'width',
  height: 'height',
  camera: 'camera',
  frames: 'frames',
  maxFrames: 'max-frames',
  interactive: 'interactive',
};

// The viewer's own options (not the program's).
const viewerOptions = new Set(['url', 'query', 'scale', 'canvasId', 'keyTarget', 'hash',
                               'viewState']);

// Checks runtime options (throws TypeError for an unknown name, RangeError for a bad value) and
// returns them parsed.
function parseRuntimeOptions(options) {
  const out = {};
  for (const [key, value] of Object.entries(options || {})) {
    const o = runtimeOptions[key];
    if (!o) throw new TypeError(`setOptions: unknown option '${key}' (${Object.keys(runtimeOptions).join(', ')})`);
    out[key] = o.parse(value);
  }
  return out;
}

function vector3(name, v) {
  if (!Array.isArray(v) && !ArrayBuffer.isView(v)) throw new TypeError(`${name}: not [x, y, z]`);
  const out = Array.from(v, Number);
  if (out.length !== 3 || !out.every(Number.isFinite)) throw new TypeError(`${name}: not [x, y, z] of finite numbers`);
  return out;
}

// A camera as the program takes it: position and target in the data's coordinates (Z up), fov in
// degrees (optional: the program keeps its own).
function parseCamera(c) {
  if (!c || typeof c !== 'object') throw new TypeError('camera: not { position, target, fov }');
  const camera = { position: vector3('camera.position', c.position), target: vector3('camera.target', c.target) };
  if (camera.position.every((x, i) => x === camera.target[i]))
    throw new RangeError('camera: the position and target are the same point');
  if (c.fov !== undefined && c.fov !== null) camera.fov = number('camera.fov', 0, 180, { above: true })(c.fov);
  if (camera.fov === 180) throw new RangeError('camera.fov: not a number in (0 - 180): 180');
  return camera;
}

// A number written as the shortest text that reads back as the same number.
const text = (x) => String(x);

// The tools' part of a view state: the filters and clip mode (`stipple render`'s --classes
// '2,6', --returns 'first,last', --intensity-filter 'min,max', --clip-mode), and the
// measurements (GeoJSON in the source CRS, its compact text: clip boxes and polygons among them).
const toolKeys = { classes: 'classes', returns: 'returns', intensityFilter: 'intensity-filter',
                   clipMode: 'clip-mode', measurements: 'measurements' };
const returnNames = ['first', 'last', 'single', 'intermediate'];
const clipModes = ['inside', 'outside', 'highlight'];
function parseToolState(key, v) {
  const list = (t) => String(t).split(',').filter((x) => x !== '');
  switch (key) {
    case 'classes': {
      const out = list(v).map(Number);
      if (!out.every((c) => Number.isInteger(c) && c >= 0 && c <= 255))
        throw new RangeError(`classes: not class numbers 0-255: ${v}`);
      return out;
    }
    case 'returns': {
      const out = list(v);
      if (!out.every((r) => returnNames.includes(r)))
        throw new RangeError(`returns: not of ${returnNames.join(', ')}: ${v}`);
      return out;
    }
    case 'intensityFilter': {
      const out = list(v).map(Number);
      if (out.length !== 2 || !out.every(Number.isFinite)) throw new RangeError(`intensity-filter: not 'min,max': ${v}`);
      return out;
    }
    case 'clipMode':
      if (!clipModes.includes(v)) throw new RangeError(`clip-mode: not one of ${clipModes.join(', ')}: ${v}`);
      return v;
    case 'measurements': {
      const doc = typeof v === 'string' ? JSON.parse(v) : v;
      if (!doc || doc.type !== 'FeatureCollection') throw new RangeError('measurements: not a GeoJSON FeatureCollection');
      return JSON.stringify(doc);
    }
    default:
      throw new TypeError(`unknown view state '${key}'`);
  }
}

// The view state as a link's hash (without '#'): `stipple render`'s option names as keys, as in
// the query string: camera=x,y,z,tx,ty,tz (render's --camera, the data's coordinates, every
// number to the last bit), fov= (degrees, where not the default), color=, point-size=, edl=0|1,
// edl-strength=, edl-radius=, budget=, max-sse=, memory-mb=; the tools' classes=, returns=,
// intensity-filter=, clip-mode= and measurements= (compact GeoJSON). Key=value pairs joined by
// '&' (read with URLSearchParams); readers skip the keys they do not know.
export function encodeViewState(state) {
  const pairs = [];
  const put = (key, value) => pairs.push(`${key}=${encodeURIComponent(value).replace(/%2C/g, ',')}`);
  if (state && state.camera) {
    const c = parseCamera(state.camera);
    put('camera', [...c.position, ...c.target].map(text).join(','));
    if (c.fov !== undefined && Math.abs(c.fov - defaultFov) > 1e-9) put('fov', text(c.fov));
  }
  const options = { ...(state || {}) };
  delete options.camera;
  for (const [key, name] of Object.entries(toolKeys)) {
    if (options[key] === undefined || options[key] === null) continue;
    const v = parseToolState(key, options[key]);
    put(name, Array.isArray(v) ? v.join(',') : v);
    delete options[key];
  }
  for (const [key, value] of Object.entries(parseRuntimeOptions(options))) {
    const name = runtimeOptions[key].name;
    put(name, typeof value === 'boolean' ? (value ? '1' : '0') : String(value));
  }
  return pairs.join('&');
}

// The view state a link's hash (with or without '#') holds: what encodeViewState writes. Keys it
// does not know are skipped; a bad value throws (RangeError, TypeError).
export function decodeViewState(hash) {
  const params = new URLSearchParams(String(hash || '').replace(/^#/, ''));
  const state = {};
  for (const [key, o] of Object.entries(runtimeOptions))
    if (params.has(o.name)) state[key] = o.parse(params.get(o.name));
  for (const [key, name] of Object.entries(toolKeys))
    if (params.has(name)) state[key] = parseToolState(key, params.get(name));
  if (params.has('camera')) {
    const v = params.get('camera').split(',').map((s) => (s.trim() === '' ? NaN : Number(s)));
    if (v.length !== 6 || !v.every(Number.isFinite))
      throw new RangeError(`camera: not six comma-separated numbers: ${params.get('camera')}`);
    state.camera = parseCamera({ position: v.slice(0, 3), target: v.slice(3),
                                 fov: params.has('fov') ? params.get('fov') : undefined });
  }
  return state;
}

let viewers = 0;  // for canvas ids

// A viewer inside `element` (any element with a size: the canvas fills it). Resolves once the
// program runs (before the source is drawn: 'load', or viewer.loaded); rejects where no viewer
// can run here (no WebGPU, a page that is not cross-origin isolated, an element not in the
// document, a bad option of the viewer's own).
export async function createViewer(element, options = {}) {
  if (!(element instanceof Element) || !element.isConnected)
    throw new TypeError('createViewer: the element must be in the document');
  if (!navigator.gpu)
    throw new Error('This browser has no WebGPU (navigator.gpu): stipple needs it. Chrome and ' +
                    'Edge 113+, or a browser with WebGPU enabled.');
  if (!globalThis.crossOriginIsolated)
    throw new Error('This page is not cross-origin isolated: stipple\'s threads need ' +
                    'SharedArrayBuffer (serve it with the headers Cross-Origin-Opener-Policy: ' +
                    'same-origin and Cross-Origin-Embedder-Policy: require-corp, or load ' +
                    'stipple-isolation.js from the page).');
  const viewer = new Viewer(element, options, token);
  await starting.get(viewer);
  starting.delete(viewer);
  return viewer;
}

// Viewer's constructor is the module's: createViewer makes one and waits for its program.
const token = Symbol('stipple viewer');
const starting = new WeakMap();  // viewer -> its program's start

// A promise with its resolve and reject.
const deferred = () => {
  const d = {};
  d.promise = new Promise((resolve, reject) => Object.assign(d, { resolve, reject }));
  d.promise.catch(() => {});  // an unawaited failed load is an 'error' event, not a page error
  return d;
};

export class Viewer {
  #element;
  #canvas;
  #program;  // the instance's Module object
  #args = [];
  #fixedSize = false;
  #scale = 1;
  #abort = new AbortController();  // every listener the viewer added
  #resizeObserver = null;
  #listeners = new Map();  // event -> Set of functions
  #ready = false;  // events before createViewer resolved wait for it
  #queued = [];
  #load = deferred();
  #loadInfo = {};
  #camera = null;  // as reported (or as set, until reported)
  #cameraMoved = false;
  #options = null;  // as reported
  #explicit = {};  // options set since the viewer was made (setOptions, setViewState)
  #stats = null;
  #opening = true;  // open() asked for a source whose view has not started (its camera is not yet)
  #exit = deferred();
  #exited = false;
  #destroyed = false;
  #hash = null;  // the link's hash sync: { timer, dirty }
  #tools = null;  // the tools' state as reported
  #toolsApi = null;

  constructor(element, options, secret) {
    if (secret !== token) throw new TypeError('use createViewer(element, options)');
    this.#element = element;
    for (const key of Object.keys(options))
      if (!viewerOptions.has(key) && !(key in startOptions) && !(key in runtimeOptions))
        throw new TypeError(`createViewer: unknown option '${key}'`);
    const scale = options.scale ?? 1;
    if (!(typeof scale === 'number' && scale >= 0.05 && scale <= 1))
      throw new RangeError(`scale: not a number in [0.05 - 1]: ${scale}`);
    this.#scale = scale;
    // The program's arguments: the query's pairs as they are, then the options (render's names).
    const args = this.#args;
    const query = new URLSearchParams(options.query || '');
    const resolve = (url) => new URL(url, document.baseURI).href;
    for (const [k, v] of query) args.push(`--${k}`, k === 'url' ? resolve(v) : v);
    if (options.url) args.push('--url', resolve(String(options.url)));
    for (const [key, name] of Object.entries({ ...startOptions,
                                               ...Object.fromEntries(Object.entries(runtimeOptions).map(([k, o]) => [k, o.name])) })) {
      let v = options[key];
      if (v === undefined || v === null) continue;
      if (key === 'camera' && typeof v === 'object') {
        const c = parseCamera(v);
        v = [...c.position, ...c.target].join(',');
      }
      if (typeof v === 'boolean') v = v ? '1' : '0';
      args.push(`--${name}`, String(v));
    }
    this.#fixedSize = options.width !== undefined || options.height !== undefined ||
                      query.has('width') || query.has('height');
    // The link's view state (the page's hash) and the one given apply once the source is drawn,
    // as if set then.
    let state = {};
    if (options.hash) {
      try {
        state = decodeViewState(location.hash);
      } catch (e) {
        console.warn(`stipple: the link's view state is not understood: ${e.message}`);
      }
      this.#hash = { timer: null, dirty: false };
    }
    if (options.viewState) state = { ...state, ...options.viewState };
    {
      const { camera, ...rest } = state;  // checked before anything is made
      for (const key of Object.keys(toolKeys))
        if (rest[key] !== undefined) parseToolState(key, rest[key]), delete rest[key];
      if (camera) parseCamera(camera);
    }
    this.#canvas = this.#makeCanvas(options);
    this.#program = this.#makeProgram(options.keyTarget);
    this.setViewState(state);
    starting.set(this, this.#start());
  }

  // ---- the API -----------------------------------------------------------------------------

  // The canvas the viewer draws into (inside the element).
  get canvas() { return this.#canvas; }

  // The element the viewer was made in.
  get element() { return this.#element; }

  // The current source's load: resolves with what 'load' gives once it is drawn, rejects with its
  // error (replaced by open()).
  get loaded() { return this.#load.promise; }

  // The camera: { position: [x, y, z], target: [x, y, z], fov } in the data's coordinates (Z up,
  // what `stipple render --camera` takes), fov in degrees; null before the first view. Setting it
  // moves the view there (drawn once at the next animation frame); fov may be left out.
  get camera() {
    const c = this.#camera;
    return c && { position: [...c.position], target: [...c.target], fov: c.fov };
  }

  set camera(value) {
    this.#alive();
    const c = parseCamera(value);
    this.#program.stippleCamera = c;
    this.#camera = { ...c, fov: c.fov ?? this.#camera?.fov ?? defaultFov };
    this.#cameraMoved = true;
    this.#hashChanged();
  }

  // Changes how the view draws, while it runs (the next frame; `stipple render`'s options,
  // camelCased): color, pointSize, edl, edlStrength, edlRadius, budget (at most this many points;
  // 0: all), maxSse and memoryMb (streamed sources). Throws TypeError for an unknown option,
  // RangeError for a value out of render's range. The options stay set for sources opened later.
  setOptions(options) {
    this.#alive();
    const parsed = parseRuntimeOptions(options);
    Object.assign(this.#explicit, parsed);
    this.#program.stippleOptions = { ...(this.#program.stippleOptions || {}), ...parsed };
    this.#hashChanged();
  }

  // The options the view draws with, as the program reports them: color (as asked), shown (the
  // colour mode drawn), edl, edlStrength, edlRadius, pointSize, budget, and for a streamed
  // source maxSse and memoryMb; null before the first view.
  get options() {
    const o = this.#options;
    return o && { ...o, edl: !!o.edl };
  }

  // The view state a link reopens: the camera once it left the source's first framing, and the
  // options set on this viewer (setOptions, setViewState). encodeViewState writes it as a hash.
  viewState() {
    const state = { ...this.#explicit };
    if (this.#cameraMoved && this.#camera) state.camera = this.camera;
    // The tools' filters, clip mode and measurements, where they are not the defaults.
    const t = this.#tools;
    if (t) {
      const f = t.filter;
      if (f.classes) state.classes = f.classes;
      if (f.returns.length) state.returns = f.returns;
      if (f.intensity) state.intensityFilter = f.intensity;
      if (t.clipMode !== 'inside') state.clipMode = t.clipMode;
      const doc = JSON.parse(t.geojson);
      doc.features = doc.features.filter((x) => x.properties.tool !== 'inspect');
      if (doc.features.length) state.measurements = JSON.stringify(doc);
    }
    return state;
  }

  // Applies a view state (viewState()'s, decodeViewState's): its options as setOptions, its
  // camera as the camera setter, the tools' filters, clip mode and measurements (these replace
  // the measurements there are) once the source is drawn.
  setViewState(state) {
    const { camera, ...options } = state || {};
    const tools = {};
    for (const key of Object.keys(toolKeys))
      if (options[key] !== undefined) tools[key] = parseToolState(key, options[key]), delete options[key];
    if (Object.keys(options).length) this.setOptions(options);
    if (camera) this.camera = camera;
    if ('classes' in tools || 'returns' in tools || 'intensityFilter' in tools) {
      this.tools.setFilter({ classes: tools.classes ?? null, returns: tools.returns ?? [],
                             intensity: tools.intensityFilter ?? null });
    }
    if (tools.clipMode) this.tools.setClipMode(tools.clipMode);
    if (tools.measurements) {
      this.tools.clear();
      this.tools.loadMeasurements(tools.measurements, 'the link');
    }
  }

  // The tools of `stipple view` (inspect, measure, profile, annotate, filter, clip, export; the
  // library's, src/tools): their commands go to the program before its next frame, their state
  // comes back as 'tools' events (viewer.tools.state), what they draw over the view as 'overlay'
  // events (lines, dots and labels in canvas pixels), a point inspected as 'pick', a measurement
  // finished as 'measure', a profile's image as 'profile', an export's files as 'export'. The
  // canvas's clicks and drags reach them (a click of the current tool, a vertex dragged) besides
  // the camera. Positions are the canvas's drawing-buffer pixels.
  get tools() {
    if (this.#toolsApi) return this.#toolsApi;
    const send = (command) => {
      this.#alive();
      this.#program.stippleTools.queue.push(command);
    };
    const self = this;
    this.#toolsApi = Object.freeze({
      get state() { return self.#tools; },
      send,
      setTool: (name) => send({ op: 'tool', name }),
      click: (x, y) => send({ op: 'click', x, y }),
      finish: () => send({ op: 'finish' }),
      undo: () => send({ op: 'undo' }),
      cancel: () => send({ op: 'cancel' }),
      remove: (item = -1) => send({ op: 'remove', item }),
      clear: () => send({ op: 'clear' }),
      select: (item) => send({ op: 'select', item }),
      setLabel: (item, text) => send({ op: 'label', item, text: String(text) }),
      setWidth: (item, value) => send({ op: 'width', item, value }),
      setPlaneZ: (item, value) => send({ op: 'plane', item, value }),
      setFilter: (f) => send({ op: 'filter', ...f }),
      setClipMode: (mode) => send({ op: 'clipMode', mode }),
      loadMeasurements: (geojson, name = 'measurements') =>
        send({ op: 'load', text: typeof geojson === 'string' ? geojson : JSON.stringify(geojson), name }),
      measurements: () => this.#tools?.geojson ?? null,
      exportClip: (name = 'clip.laz') => send({ op: 'exportClip', name }),
      exportProfile: ({ item = -1, name = 'profile', csv = true, las = false, png = false } = {}) =>
        send({ op: 'exportProfile', item, name, csv, las, png }),
      profile: (item = -1, width = 600, height = 240) => send({ op: 'profile', item, width, height }),
    });
    return this.#toolsApi;
  }

  // The stats panel's figures (those of `stipple view`'s panel): frames (drawn so far; it stops
  // while the view is idle), frameMs, fps, pointsDrawn, points, renderer, adapter, canvas, and
  // for a tileset tilesDrawn, tilesResident, tilesLoading, tilesFailed, residentBytes,
  // budgetBytes, gpuBytes; null before the first figures.
  stats() { return this.#stats && { ...this.#stats }; }

  // The view's pixels, drawn once more and read back (the viewer's only readback): an ImageData
  // (RGBA, top row first) of the canvas's drawing buffer.
  pixels() {
    this.#alive();
    const capture = this.#program.stippleCapture;
    return new Promise((resolve, reject) => {
      capture.waiting.push({ resolve, reject });
      capture.wanted = true;
    });
  }

  // A PNG of the view (pixels()), as a Blob.
  async screenshot() {
    const image = await this.pixels();
    const canvas = new OffscreenCanvas(image.width, image.height);
    canvas.getContext('2d').putImageData(image, 0, 0);
    return canvas.convertToBlob({ type: 'image/png' });
  }

  // Opens a new source in place of the one drawn: a URL (relative to the page: LAS/LAZ read
  // whole, a 3D Tiles tileset.json, COPC, EPT or Potree streamed) or a LAS/LAZ File or Blob.
  // Returns viewer.loaded for it. The options set stay; the camera is the new source's framing.
  open(source) {
    this.#alive();
    this.#load = deferred();
    this.#loadInfo = {};
    const program = this.#program;
    program.stippleCamera = null;
    this.#camera = null;
    this.#cameraMoved = false;
    this.#opening = true;
    // The program starts each source from createViewer's options: the ones set since apply on
    // top, as for a link.
    program.stippleOptions = { ...this.#explicit };
    this.#hashChanged();
    if (typeof source === 'string' || source instanceof URL) {
      program.stippleOpen = new URL(source, document.baseURI).href;
    } else if (source instanceof Blob) {
      const name = source.name || 'input.las';
      const load = this.#load;
      if (!/\.(las|laz)$/i.test(name)) {
        this.#fail(`${name}: not a LAS or LAZ file (.las, .laz, .copc.laz)`);
      } else {
        source.arrayBuffer().then((bytes) => {
          if (this.#destroyed || load !== this.#load) return;
          // One file at a time in the instance's memory: the one before is removed.
          const FS = program.FS;
          const dir = '/dropped';
          if (!FS.analyzePath(dir).exists) FS.mkdir(dir);
          for (const f of FS.readdir(dir)) if (f !== '.' && f !== '..') FS.unlink(`${dir}/${f}`);
          const path = `${dir}/${name.replace(/[/]/g, '_')}`;
          FS.writeFile(path, new Uint8Array(bytes));
          program.stippleOpen = path;
        }, (e) => this.#fail(`${name}: ${e.message || e}`));
      }
    } else {
      throw new TypeError('open: not a URL, File or Blob');
    }
    return this.#load.promise;
  }

  // Calls `fn` on each `event`: 'load' (the source is drawn: { points, renderer, adapter, ms,
  // ... }), 'error' (an Error: the source could not be opened or drawn), 'camera' (the camera
  // moved: viewer.camera's value), 'options' (viewer.options's value changed), 'stats' (new
  // figures), 'progress' (a streamed source's progress, text), 'problems' (tiles that failed,
  // text), 'report' ({ key, value }: every report of the program, raw), and the tools' (see
  // viewer.tools): 'tools', 'overlay', 'pick', 'measure', 'profile', 'export'. Returns a function
  // that removes it.
  on(event, fn) {
    if (typeof fn !== 'function') throw new TypeError('on: not a function');
    if (!this.#listeners.has(event)) this.#listeners.set(event, new Set());
    this.#listeners.get(event).add(fn);
    return () => this.off(event, fn);
  }

  off(event, fn) {
    this.#listeners.get(event)?.delete(fn);
  }

  // Ends the program (its threads and WebGPU device go with it) and removes the canvas and every
  // listener the viewer added. Resolves once the program has ended.
  destroy() {
    if (this.#destroyed) return this.#exit.promise;
    this.#destroyed = true;
    this.#abort.abort();
    this.#resizeObserver?.disconnect();
    if (this.#hash?.timer) clearTimeout(this.#hash.timer);
    this.#canvas.remove();
    const program = this.#program;
    program.stippleQuit = true;
    for (const w of program.stippleCapture.waiting.splice(0)) w.reject(new Error('the viewer was destroyed'));
    this.#load.reject(new Error('the viewer was destroyed'));
    this.#listeners.clear();
    if (this.#exited) this.#exit.resolve();
    return this.#exit.promise;
  }

  // Whether destroy() was called.
  get destroyed() { return this.#destroyed; }

  // The instance's Module object, for tests and tools (its stipple* slots are the program's
  // interface: not an API).
  get _program() { return this.#program; }

  // ---- inside ------------------------------------------------------------------------------

  #alive() {
    if (this.#destroyed) throw new Error('the viewer was destroyed');
    if (this.#exited) throw new Error('the viewer\'s program has ended');
  }

  #emit(event, detail) {
    if (!this.#ready) {
      this.#queued.push([event, detail]);
      return;
    }
    for (const fn of [...(this.#listeners.get(event) || [])]) {
      try {
        fn(detail);
      } catch (e) {
        console.error(e);
      }
    }
  }

  #fail(message) {
    const error = new Error(message);
    this.#load.reject(error);
    this.#emit('error', error);
  }

  // The drawing buffer's size for `w` x `h` CSS pixels.
  #sizeFor(w, h) {
    const k = devicePixelRatio * this.#scale;
    return { width: Math.max(1, Math.round(w * k)), height: Math.max(1, Math.round(h * k)) };
  }

  #makeCanvas(options) {
    const canvas = document.createElement('canvas');
    let id = options.canvasId;
    if (id === undefined)
      do id = `stipple-canvas-${++viewers}`; while (document.getElementById(id));
    else if (document.getElementById(id))
      throw new Error(`createViewer: an element with id '${id}' exists already`);
    canvas.id = id;
    canvas.tabIndex = 0;  // the keys turn the view where the canvas has the focus
    canvas.style.touchAction = 'none';  // the viewer's pointer handlers turn, pinch and pan
    canvas.style.outline = 'none';
    if (!this.#fixedSize) {
      // Laid over the element, so that the drawing buffer's size never sizes the element.
      if (getComputedStyle(this.#element).position === 'static') this.#element.style.position = 'relative';
      Object.assign(canvas.style, { position: 'absolute', left: '0', top: '0', width: '100%',
                                    height: '100%', display: 'block' });
    } else {
      canvas.style.display = 'block';
    }
    this.#element.appendChild(canvas);
    return canvas;
  }

  // The instance's Module object: the program's arguments and slots; the listeners that fill
  // them.
  #makeProgram(keyTarget) {
    const canvas = this.#canvas;
    const signal = this.#abort.signal;
    const program = {
      arguments: [...this.#args, '--canvas', `#${CSS.escape(canvas.id)}`],
      print: (t) => console.log(t),
      printErr: (t) => console.warn(t),
      stippleReport: (key, value) => this.#report(key, value),
      stippleInput: { dx: 0, dy: 0, zoom: 0, panX: 0, panY: 0 },
      stippleSize: null,
      stippleOptions: null,
      stippleCamera: null,
      stippleOpen: null,
      stippleQuit: false,
      // The tools' commands (viewer.tools), and the profile images the program sends back.
      stippleTools: { queue: [] },
      stippleToolsProfile: (frame, image) =>
        this.#emit('profile', { frame, image: new ImageData(image.data, image.width, image.height) }),
      stippleCapture: {
        wanted: false,
        waiting: [],
        deliver({ width, height, data }) {
          for (const w of this.waiting.splice(0)) w.resolve(new ImageData(data, width, height));
        },
      },
      onExit: () => {
        this.#exited = true;
        this.#exit.resolve();
      },
    };
    if (!this.#fixedSize) {
      // The canvas's size now, then on every resize (ResizeObserver) and devicePixelRatio change
      // (zoom, a move to another screen): the program takes the latest before its next frame,
      // reconfigures the canvas and draws once. (Not devicePixelContentBoxSize: under emulated
      // device metrics, puppeteer's, it can disagree with devicePixelRatio.)
      const rect = canvas.getBoundingClientRect();
      const first = this.#sizeFor(rect.width, rect.height);
      program.arguments.push('--width', String(first.width), '--height', String(first.height));
      program.stippleSize = { ...first, changed: false };
      const resized = (size) => {
        const s = program.stippleSize;
        if (size.width === s.width && size.height === s.height) return;
        Object.assign(s, size, { changed: true });
      };
      this.#resizeObserver = new ResizeObserver((entries) => {
        const r = entries[entries.length - 1].contentRect;
        resized(this.#sizeFor(r.width, r.height));
      });
      this.#resizeObserver.observe(canvas);
      const watchRatio = () => {
        matchMedia(`(resolution: ${devicePixelRatio}dppx)`).addEventListener('change', () => {
          const r = canvas.getBoundingClientRect();
          resized(this.#sizeFor(r.width, r.height));
          watchRatio();
        }, { once: true, signal });
      };
      watchRatio();
    }
    this.#listenToPointers(program.stippleInput, keyTarget || canvas, signal);
    return program;
  }

  // Camera controls, mouse and touch alike (pointer events): one pointer's drag turns the view
  // about the data (the mouse's right button, or shift, pans instead), two pointers pinch to zoom
  // and drag together to pan; the wheel zooms; arrows turn, +/- and PageUp/PageDown zoom (keys
  // from `keyTarget`: the canvas, once focused, unless the page names another target). The
  // program takes the sums each frame.
  #listenToPointers(input, keyTarget, signal) {
    const canvas = this.#canvas;
    const pointers = new Map();  // id -> { x, y, pan }
    // The tools see the pointer too, in the canvas's drawing-buffer pixels: a press and release
    // in place is a click of the current tool, a press on a measurement's vertex drags it (the
    // program then leaves the camera where it is).
    const tools = (op, e) => {
      const r = canvas.getBoundingClientRect();
      const x = (e.clientX - r.left) * (r.width > 0 ? canvas.width / r.width : 1);
      const y = (e.clientY - r.top) * (r.height > 0 ? canvas.height / r.height : 1);
      this.#program.stippleTools.queue.push({ op, x, y, button: e.button === 2 ? 2 : 0 });
    };
    // Centre and spread of the first two pointers.
    const pair = () => {
      const [a, b] = [...pointers.values()];
      return { x: (a.x + b.x) / 2, y: (a.y + b.y) / 2, d: Math.hypot(a.x - b.x, a.y - b.y) };
    };
    const on = (target, type, fn, options = {}) => target.addEventListener(type, fn, { ...options, signal });
    on(canvas, 'pointerdown', (e) => {
      if (pointers.size >= 2) return;
      // Capture: the drag goes on outside the canvas (synthetic pointers cannot be captured).
      try { canvas.setPointerCapture(e.pointerId); } catch (_) { /* synthetic */ }
      pointers.set(e.pointerId, { x: e.clientX, y: e.clientY,
                                  pan: e.pointerType === 'mouse' && (e.button === 2 || e.shiftKey) });
      if (keyTarget === canvas) canvas.focus({ preventScroll: true });
      if (pointers.size === 1) tools('down', e);
      e.preventDefault();
    });
    on(canvas, 'pointermove', (e) => {
      const p = pointers.get(e.pointerId);
      if (!p) return;
      // Pans in the canvas's pixels (its drawing buffer may be larger or smaller than on screen).
      const k = canvas.clientWidth > 0 ? canvas.width / canvas.clientWidth : 1;
      if (pointers.size === 1) {
        tools('move', e);
        const dx = e.clientX - p.x, dy = e.clientY - p.y;
        if (p.pan) { input.panX += dx * k; input.panY += dy * k; }
        else { input.dx += dx; input.dy += dy; }
        p.x = e.clientX;
        p.y = e.clientY;
        return;
      }
      const before = pair();
      p.x = e.clientX;
      p.y = e.clientY;
      const after = pair();
      // Fingers apart zoom in: the distance shrinks by their spread's ratio (exp(0.1 a step)).
      if (before.d > 0 && after.d > 0) input.zoom -= Math.log(after.d / before.d) / 0.1;
      input.panX += (after.x - before.x) * k;
      input.panY += (after.y - before.y) * k;
    });
    // A second finger (a pinch) is the camera's: the tools let go.
    const release = (cancel) => (e) => {
      const alone = pointers.size === 1;
      if (!pointers.delete(e.pointerId)) return;
      if (alone && !cancel) tools('up', e);
      else this.#program.stippleTools.queue.push({ op: 'pointerCancel' });
    };
    on(canvas, 'pointerup', release(false));
    on(canvas, 'pointercancel', release(true));
    on(canvas, 'contextmenu', (e) => e.preventDefault());
    on(canvas, 'wheel', (e) => {
      e.preventDefault();
      input.zoom += Math.sign(e.deltaY);
    }, { passive: false });
    on(keyTarget, 'keydown', (e) => {
      // A form control's own keys (the page's panel) are not the view's.
      const t = e.target;
      if (t && t.closest && t.closest('input, select, textarea, button, [contenteditable]')) return;
      const step = 20;
      if (e.key === 'ArrowLeft') input.dx -= step;
      else if (e.key === 'ArrowRight') input.dx += step;
      else if (e.key === 'ArrowUp') input.dy -= step;
      else if (e.key === 'ArrowDown') input.dy += step;
      else if (e.key === '+' || e.key === '=' || e.key === 'PageUp') input.zoom -= 1;
      else if (e.key === '-' || e.key === 'PageDown') input.zoom += 1;
      else return;
      e.preventDefault();
    });
  }

  async #start() {
    try {
      await createStippleProgram(this.#program);
    } catch (e) {
      this.#canvas.remove();
      this.#abort.abort();
      this.#resizeObserver?.disconnect();
      throw e instanceof Error ? e : new Error(String(e));
    }
    if (this.#hash) {
      window.addEventListener('hashchange', () => {
        try {
          this.setViewState(decodeViewState(location.hash));
        } catch (e) {
          this.#emit('error', e);
        }
      }, { signal: this.#abort.signal });
    }
    // Events so far wait for the caller's listeners (its code after `await createViewer`).
    setTimeout(() => {
      this.#ready = true;
      for (const [event, detail] of this.#queued.splice(0)) this.#emit(event, detail);
    });
  }

  // A report of the program (Module.stippleReport): the viewer's state and events.
  #report(key, value) {
    this.#emit('report', { key, value });
    const info = this.#loadInfo;
    switch (key) {
      case 'done': {
        const load = { ...info };
        this.#load.resolve(load);
        this.#emit('load', load);
        break;
      }
      case 'error':
        this.#fail(value);
        break;
      case 'camera': {
        if (this.#opening) break;  // the view before's, until the new one starts
        const c = JSON.parse(value);
        this.#camera = { position: c.position, target: c.target, fov: c.fov };
        this.#cameraMoved = this.#cameraMoved || !!c.moved;
        this.#emit('camera', this.camera);
        if (c.moved) this.#hashChanged();
        break;
      }
      case 'controls':
        this.#options = JSON.parse(value);
        this.#emit('options', this.options);
        break;
      case 'stats':
        this.#stats = JSON.parse(value);
        this.#emit('stats', this.stats());
        break;
      case 'progress':
        this.#emit('progress', value);
        break;
      case 'tools':
        this.#tools = JSON.parse(value);
        this.#emit('tools', this.#tools);
        this.#hashChanged();
        break;
      case 'overlay':
      case 'pick':
      case 'measure':
        this.#emit(key, JSON.parse(value));
        break;
      case 'export': {
        // The files the export wrote into the program's memory, handed over and removed there.
        const e = JSON.parse(value);
        const FS = this.#program.FS;
        const files = [];
        for (const name of FS.readdir(e.dir)) {
          if (name === '.' || name === '..') continue;
          files.push({ name, data: FS.readFile(`${e.dir}/${name}`) });
          FS.unlink(`${e.dir}/${name}`);
        }
        this.#emit('export', { result: e.result, files });
        break;
      }
      case 'tileProblems':
        this.#emit('problems', value);
        break;
      case 'renderer':  // the first report of a view
        this.#opening = false;
        info[key] = value;
        break;
      case 'adapter':
        info[key] = value;
        break;
      case 'points':
      case 'tiles':
      case 'errors':
      case 'ms':
      case 'loadMs':
      case 'frameMs':
      case 'pointSize':
        info[key] = Number(value);
        break;
      default:
        break;
    }
  }

  // The link's hash follows the view state (history.replaceState, at most four times a second,
  // the last change always written), where createViewer was given `hash: true`.
  #hashChanged() {
    const h = this.#hash;
    if (!h || this.#destroyed) return;
    if (h.timer) {
      h.dirty = true;
      return;
    }
    let hash = '';
    try {
      hash = encodeViewState(this.viewState());
    } catch (e) {
      console.warn(`stipple: the view state cannot be written as a link: ${e.message}`);
      return;
    }
    // Keys this viewer does not write (a newer page's, another tool's) stay as they were.
    const known = new Set(['camera', 'fov', ...Object.values(runtimeOptions).map((o) => o.name),
                           ...Object.values(toolKeys)]);
    const kept = location.hash.replace(/^#/, '').split('&').filter((pair) => {
      const key = pair.split('=')[0];
      try {
        return key !== '' && !known.has(decodeURIComponent(key));
      } catch (_) {
        return false;
      }
    });
    const url = new URL(location.href);
    url.hash = [hash, ...kept].filter((part) => part !== '').join('&');
    if (url.href !== location.href) history.replaceState(history.state, '', url.href);
    h.timer = setTimeout(() => {
      h.timer = null;
      if (h.dirty) {
        h.dirty = false;
        this.#hashChanged();
      }
    }, 250);
  }
}
