// TypeScript declarations of stipple.mjs, the stipple point-cloud viewer for web pages.
//
//   import { createViewer } from './stipple.mjs';
//   const viewer = await createViewer(element, { url: 'tiles/tileset.json' });

/** The colour modes, as `stipple render --color` names them. */
export type ColorMode =
  | 'auto' | 'rgb' | 'intensity' | 'classification' | 'elevation' | 'return' | 'constant';
export declare const colorModes: readonly ColorMode[];

/** A point in the data's coordinates (Z up, the source's CRS units). */
export type Vec3 = [number, number, number];

/** Where the view looks from and at: what `stipple render --camera eye,target` takes. */
export interface Camera {
  position: Vec3;
  target: Vec3;
  /** Vertical field of view in degrees (left out when setting: kept). */
  fov?: number;
}

/** The options setOptions changes while the view runs: `stipple render`'s, camelCased. */
export interface RuntimeOptions {
  color?: ColorMode;
  /** Point size in pixels, (0 - 64]. */
  pointSize?: number;
  /** Eye-dome lighting. */
  edl?: boolean;
  /** [0 - 10000] */
  edlStrength?: number;
  /** [0.5 - 16] pixels */
  edlRadius?: number;
  /** Draw at most this many points (0: all): a point cloud's nearest chunks (point pipeline), a
   * streamed source's coarser tiles. */
  budget?: number;
  /** Streamed sources: refine tiles while their screen-space error exceeds this (pixels). */
  maxSse?: number;
  /** Streamed sources: resident tile memory in MiB, [1 - 1048576]. */
  memoryMb?: number;
}

/** What a link reopens: the camera, options, the tools' filters, clip mode and measurements
 * (viewer.viewState(), encodeViewState). */
export interface ViewState extends RuntimeOptions {
  camera?: Camera;
  /** ASPRS classes kept (`stipple render --classes`). */
  classes?: number[];
  returns?: ReturnKind[];
  /** [min, max] (`--intensity-filter`). */
  intensityFilter?: [number, number];
  clipMode?: ClipMode;
  /** GeoJSON FeatureCollection text in the source CRS (the tools' measurements and clip shapes). */
  measurements?: string;
}

export type ToolName = 'none' | 'inspect' | 'distance' | 'height' | 'area' | 'angle' | 'circle' |
  'volume' | 'profile' | 'annotation' | 'clip_box' | 'clip_polygon';
export type ReturnKind = 'first' | 'last' | 'single' | 'intermediate';
export type ClipMode = 'inside' | 'outside' | 'highlight';

/** A point's record read again from its source (full precision, every attribute). */
export interface PointRecord {
  source: string;
  record: number;
  fromSource: boolean;
  /** Source CRS coordinates. */
  position: Vec3;
  lonLat?: Vec3;
  fields: Record<string, number | string | number[]>;
}

/** A measurement (or annotation, clip shape, profile line). Points in the source CRS, Z up. */
export interface Measurement {
  tool: ToolName;
  label: string;
  complete: boolean;
  /** A profile's corridor width. */
  width: number;
  points: Vec3[];
  values: {
    lengthHorizontal: number; length3d: number; height: number; areaHorizontal: number;
    area3d: number; perimeter: number; angleDegrees: number; center: Vec3; radius: number;
    volumeAbove: number; coveredFraction: number; segments3d: number[]; segmentsHorizontal: number[];
  };
  /** The label's text ("12.345 m", ...). */
  text: string;
}

export interface PointFilter {
  /** Classes kept; null: all. */
  classes?: number[] | null;
  returns?: ReturnKind[];
  intensity?: [number, number] | null;
  gpsTime?: [number, number] | null;
  pointSource?: [number, number] | null;
}

export interface ToolsState {
  tool: ToolName;
  /** The measurement being drawn, or -1. */
  active: number;
  selected: number;
  message: string;
  unit: string;
  unitSymbol: string;
  epsg: number;
  items: Measurement[];
  inspected?: PointRecord;
  filter: Required<PointFilter>;
  clipMode: ClipMode;
  canExport: boolean;
  gpsExtent: [number, number];
  /** The measurements (and the inspected record) as GeoJSON text in the source CRS. */
  geojson: string;
  /** With the first state: the ASPRS classes in the classification mode's colours. */
  legend?: { code: number; name: string; color: string }[];
}

/** What the tools draw over the view, in canvas pixels: [ax, ay, bx, by, color, width, faint],
 * [x, y, color, item, vertex], [x, y, text, color]. */
export interface Overlay {
  width: number;
  height: number;
  lines: [number, number, number, number, string, number, boolean][];
  dots: [number, number, string, number, number][];
  labels: [number, number, string, string][];
  inspected: [number, number] | null;
}

export interface ProfileFrame {
  item: number;
  length: number;
  zRange: [number, number];
  zOrigin: number;
  gridStep: [number, number];
  pixelsPerUnit: [number, number];
  /** The pixel of (0 along, the lowest height). */
  origin: [number, number];
  width: number;
  points: number;
}

/** The tools of `stipple view` (src/tools); positions in canvas pixels. */
export interface Tools {
  readonly state: ToolsState | null;
  send(command: Record<string, unknown>): void;
  setTool(name: ToolName): void;
  click(x: number, y: number): void;
  finish(): void;
  undo(): void;
  cancel(): void;
  remove(item?: number): void;
  clear(): void;
  select(item: number): void;
  setLabel(item: number, text: string): void;
  setWidth(item: number, width: number): void;
  setPlaneZ(item: number, z: number): void;
  setFilter(filter: PointFilter): void;
  setClipMode(mode: ClipMode): void;
  loadMeasurements(geojson: string | object, name?: string): void;
  measurements(): string | null;
  exportClip(name?: string): void;
  exportProfile(options?: { item?: number; name?: string; csv?: boolean; las?: boolean; png?: boolean }): void;
  profile(item?: number, width?: number, height?: number): void;
}

export interface ViewerOptions extends RuntimeOptions {
  /** What to draw: a LAS/LAZ file (read whole), a 3D Tiles tileset.json, COPC, EPT or Potree
   * (streamed); relative to the page. Without one: the built-in scene. */
  url?: string;
  /** Options as a query string or URLSearchParams, `stipple render`'s names (scene-points,
   * point-size, max-sse...): passed to the program as they are (the stock page's query). */
  query?: string | URLSearchParams;
  /** The built-in scene's points and seed. */
  scenePoints?: number;
  seed?: number;
  /** A fixed drawing buffer (pixels) instead of the element's size. */
  width?: number;
  height?: number;
  /** The first camera, as `stipple render --camera` (framing and point size follow it). */
  camera?: string | Camera;
  /** Streamed sources: frames drawn once streamed before 'load', and the most frames waited. */
  frames?: number;
  maxFrames?: number;
  /** false: the first view only (no camera controls), kept for pixels(). */
  interactive?: boolean;
  /** Draw below the element's resolution: 0.05 - 1 (default 1). */
  scale?: number;
  /** The canvas's id (default: stipple-canvas-N, unique in the document). */
  canvasId?: string;
  /** Where the view's keys are listened to (default: the canvas, focused on a click). */
  keyTarget?: EventTarget;
  /** Keep the view state in location.hash (history.replaceState, throttled) and start from the
   * hash's: a link reopens the view. */
  hash?: boolean;
  /** A view state to start from (applied once the source is drawn, as if set then). */
  viewState?: ViewState;
}

/** What 'load' gives (and viewer.loaded resolves with). */
export interface LoadInfo {
  renderer?: 'compute' | 'billboard';
  adapter?: string;
  points?: number;
  /** Streamed sources: tiles drawn and tiles that failed. */
  tiles?: number;
  errors?: number;
  /** Milliseconds: to the first view, reading the file, a streamed source's median frame. */
  ms?: number;
  loadMs?: number;
  frameMs?: number;
  pointSize?: number;
}

/** The options the view draws with (viewer.options). */
export interface DrawnOptions {
  color: ColorMode;
  /** The colour mode drawn (auto, or a mode the data lacks, resolved). */
  shown: ColorMode;
  edl: boolean;
  edlStrength: number;
  edlRadius: number;
  pointSize: number;
  budget: number;
  maxSse?: number;
  memoryMb?: number;
}

/** The stats panel's figures (those of `stipple view`'s panel). */
export interface Stats {
  /** Frames drawn so far: it stops while the view is idle. */
  frames: number;
  frameMs: number;
  /** The last frame's time on the page's thread (the engine's update, ms). */
  cpuMs: number;
  /** The GPU time of the newest frame whose timestamps came back (ms; null without). */
  gpuMs: number | null;
  gpuFrame: number | null;
  gpuTiming: boolean;
  fps: number;
  pointsDrawn: number;
  points: number;
  renderer: string;
  adapter: string;
  /** "WIDTHxHEIGHT format" */
  canvas: string;
  tilesDrawn?: number;
  tilesResident?: number;
  tilesLoading?: number;
  tilesFailed?: number;
  residentBytes?: number;
  budgetBytes?: number;
  gpuBytes?: number;
}

export interface ViewerEvents {
  load: LoadInfo;
  error: Error;
  camera: Camera;
  options: DrawnOptions;
  stats: Stats;
  progress: string;
  problems: string;
  report: { key: string; value: string };
  /** The tools' state changed. */
  tools: ToolsState;
  /** What the tools draw over the frame just drawn. */
  overlay: Overlay;
  /** A point inspected. */
  pick: PointRecord;
  /** A measurement finished. */
  measure: Measurement;
  /** A profile's cross-section (viewer.tools.profile). */
  profile: { frame: ProfileFrame; image: ImageData };
  /** An export's result and files. */
  export: { result: string; files: { name: string; data: Uint8Array }[] };
}

export declare class Viewer {
  private constructor();
  readonly canvas: HTMLCanvasElement;
  readonly element: Element;
  /** The current source's load (replaced by open()). */
  readonly loaded: Promise<LoadInfo>;
  /** In the data's coordinates; null before the first view. Setting it redraws once. */
  get camera(): Required<Camera> | null;
  set camera(camera: Camera);
  setOptions(options: RuntimeOptions): void;
  readonly options: DrawnOptions | null;
  viewState(): ViewState;
  setViewState(state: ViewState): void;
  stats(): Stats | null;
  readonly tools: Tools;
  /** The view drawn once more and read back (RGBA). */
  pixels(): Promise<ImageData>;
  /** A PNG of the view. */
  screenshot(): Promise<Blob>;
  /** A new source in place of the one drawn: a URL, or a LAS/LAZ File or Blob. */
  open(source: string | URL | Blob): Promise<LoadInfo>;
  on<K extends keyof ViewerEvents>(event: K, fn: (detail: ViewerEvents[K]) => void): () => void;
  off<K extends keyof ViewerEvents>(event: K, fn: (detail: ViewerEvents[K]) => void): void;
  /** Ends the program, removes the canvas and the viewer's listeners. */
  destroy(): Promise<void>;
  readonly destroyed: boolean;
}

export declare function createViewer(element: Element, options?: ViewerOptions): Promise<Viewer>;
/** A view state as a link's hash (without '#'): `stipple render`'s option names as keys. */
export declare function encodeViewState(state: ViewState): string;
/** The view state of a hash (with or without '#'). */
export declare function decodeViewState(hash: string): ViewState;
