// The page's tools: HTML over libstipple's tools module (src/tools, through web/tools_bridge.cpp),
// as `stipple view`'s ImGui panel is the window's layer over it. Everything measured, picked,
// clipped or filtered is decided by the program; this draws its state (the "tools" report), its
// overlay (lines, dots and labels in canvas pixels, after every drawn frame) and the profile
// image it sends, and turns the page's clicks, keys and pointer into its commands.
//
//   const tools = StippleToolsPanel({ panel, view, canvas, send, download });
//   viewer.on('tools', tools.showState); viewer.on('overlay', tools.showOverlay);
//   viewer.on('profile', ({ frame, image }) => tools.showProfile(frame, image));
//   viewer.on('export', tools.showExport);
//   tools.key(event)             // true where a tool's key was taken
// (The viewer passes the canvas's pointer to the tools itself: clicks, vertex drags.)
//
// Keys: 1 inspect, 2 distance, 3 height, 4 area, 5 angle, 6 circle, 7 volume, 8 profile,
// 9 annotation, B clip box, G clip polygon, 0 no tool; Enter finishes a polyline or polygon (or
// a right click), Backspace removes its last point, Escape cancels it, Delete removes the
// selected measurement.
(function () {
  'use strict';
  const TOOLS = [
    ['none', '0', 'no tool'], ['inspect', '1', 'inspect'], ['distance', '2', 'distance'],
    ['height', '3', 'height'], ['area', '4', 'area'], ['angle', '5', 'angle'],
    ['circle', '6', 'circle'], ['volume', '7', 'volume'], ['profile', '8', 'profile'],
    ['annotation', '9', 'annotation'], ['clip_box', 'b', 'clip box'],
    ['clip_polygon', 'g', 'clip polygon'],
  ];
  const HINTS = {
    inspect: 'click a point', distance: 'click points; Enter or right click ends',
    height: 'click two points', area: 'click corners; Enter or right click ends',
    angle: 'click three points (the angle at the second)', circle: 'click three points on it',
    volume: 'click the reference height, then a box: two corners, a width',
    profile: 'click a polyline; Enter or right click ends',
    annotation: 'click where the label goes', clip_box: 'two corners, then a width',
    clip_polygon: 'click corners; Enter or right click ends',
  };
  const SVG = 'http://www.w3.org/2000/svg';

  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (k === 'class') e.className = v;
      else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
      else if (v !== undefined && v !== null) e.setAttribute(k, v);
    }
    for (const c of children) e.append(c);
    return e;
  }

  window.StippleToolsPanel = function (opts) {
    const { panel, view, canvas, send } = opts;
    let state = null;        // the last "tools" report
    let legend = [];

    // ---- the panel -------------------------------------------------------------------------
    const root = el('details', { id: 'tools', open: '' }, el('summary', {}, 'measure, filter, clip'));
    const toolButtons = el('div', { id: 'tool-buttons', class: 'tool-buttons' });
    for (const [name, key, text] of TOOLS)
      toolButtons.append(el('button', { 'data-tool': name, title: `key ${key.toUpperCase()}`,
                                        onclick: () => send({ op: 'tool', name }) }, text));
    const hint = el('div', { id: 'tool-hint', class: 'hint' });
    const drawing = el('div', { id: 'tool-drawing', class: 'row' },
      el('button', { id: 'tool-finish', onclick: () => send({ op: 'finish' }) }, 'finish'),
      el('button', { id: 'tool-undo', onclick: () => send({ op: 'undo' }) }, 'undo point'),
      el('button', { id: 'tool-cancel', onclick: () => send({ op: 'cancel' }) }, 'cancel'));
    const message = el('div', { id: 'tool-message', class: 'message', role: 'status' });
    const list = el('ol', { id: 'measurements' });
    const inspected = el('div', { id: 'inspected' });
    const geo = el('div', { class: 'row' },
      el('button', { id: 'save-geojson', onclick: () => {
        if (state) opts.download('measurements.geojson', state.geojson, 'application/geo+json');
      } }, 'save GeoJSON'),
      el('label', { class: 'button' }, 'load GeoJSON',
         el('input', { type: 'file', id: 'load-geojson', accept: '.geojson,.json',
                       style: 'display:none', onchange: async (e) => {
                         const f = e.target.files[0];
                         if (f) send({ op: 'load', text: await f.text(), name: f.name });
                         e.target.value = '';
                       } })),
      el('button', { id: 'clear-measurements', onclick: () => send({ op: 'clear' }) }, 'clear'));

    // Filters: classes (the ASPRS legend in the classification mode's colours), returns,
    // intensity; the clip mode.
    const classes = el('div', { id: 'filter-classes', class: 'classes' });
    const returns = el('div', { id: 'filter-returns', class: 'row' }, 'returns:');
    for (const r of ['first', 'last', 'single', 'intermediate'])
      returns.append(el('label', {}, el('input', { type: 'checkbox', 'data-return': r,
                                                   onchange: sendFilter }), r));
    const intensityOn = el('input', { type: 'checkbox', id: 'filter-intensity', onchange: sendFilter });
    const intensityMin = el('input', { type: 'number', id: 'filter-intensity-min', value: 0,
                                       min: 0, max: 65535, onchange: sendFilter });
    const intensityMax = el('input', { type: 'number', id: 'filter-intensity-max', value: 65535,
                                       min: 0, max: 65535, onchange: sendFilter });
    const clipMode = el('select', { id: 'clip-mode', onchange: (e) => send({ op: 'clipMode', mode: e.target.value }) },
      el('option', {}, 'inside'), el('option', {}, 'outside'), el('option', {}, 'highlight'));
    const filters = el('details', { id: 'filters' }, el('summary', {}, 'filters and clipping'),
      el('div', { class: 'row' },
         el('button', { onclick: () => setClasses(true) }, 'all classes'),
         el('button', { onclick: () => setClasses(false) }, 'none')),
      classes, returns,
      el('div', { class: 'row' }, el('label', {}, intensityOn, 'intensity'), intensityMin, '–', intensityMax),
      el('label', {}, 'clip mode ', clipMode));
    const exports = el('div', { id: 'exports', class: 'row' },
      el('button', { id: 'export-clip', onclick: () => send({ op: 'exportClip', name: 'clip.laz' }) },
         'export clip (LAZ)'),
      el('button', { id: 'export-profile-csv', onclick: () => send({ op: 'exportProfile', name: 'profile', csv: true }) },
         'profile CSV'),
      el('button', { id: 'export-profile-las', onclick: () => send({ op: 'exportProfile', name: 'profile', las: true }) },
         'profile LAS'));
    root.append(toolButtons, hint, drawing, message, list, inspected, geo, filters, exports);
    panel.append(root);

    // The profile window: the program's image of the corridor, two clicks in it measure.
    const profile = el('div', { id: 'profile', class: 'profile', hidden: '' });
    const profileText = el('div', { id: 'profile-text' });
    const profileCanvas = el('canvas', { id: 'profile-canvas', width: 600, height: 240 });
    const profileMeasure = el('div', { id: 'profile-measure' });
    profile.append(el('div', { class: 'row' }, el('b', {}, 'profile'), profileText,
                      el('button', { onclick: () => { profile.hidden = true; } }, '×')),
                   profileCanvas, profileMeasure);
    document.body.append(profile);
    let profileFrame = null, profileItem = -1, profileVersion = '';
    const profileClicks = [];
    profileCanvas.addEventListener('click', (e) => {
      if (!profileFrame) return;
      const r = profileCanvas.getBoundingClientRect();
      const px = (e.clientX - r.left) * profileCanvas.width / r.width;
      const py = (e.clientY - r.top) * profileCanvas.height / r.height;
      const f = profileFrame;
      // The frame's inverse (pc::ProfileFrame::from_pixel), from the pixel of (0, lowest height).
      const along = (px - f.origin[0]) / f.pixelsPerUnit[0];
      const z = f.zRange[0] + (f.origin[1] - py) / f.pixelsPerUnit[1];
      if (profileClicks.length === 2) profileClicks.length = 0;
      profileClicks.push([along, z]);
      if (profileClicks.length === 2) {
        const [a, b] = profileClicks;
        profileMeasure.textContent = `along ${(b[0] - a[0]).toFixed(3)}, height ` +
          `${(b[1] - a[1] >= 0 ? '+' : '')}${(b[1] - a[1]).toFixed(3)}, slope distance ` +
          `${Math.hypot(b[0] - a[0], b[1] - a[1]).toFixed(3)}`;
      } else {
        profileMeasure.textContent = `distance ${along.toFixed(3)}, height ${z.toFixed(3)}`;
      }
    });

    // ---- the overlay -----------------------------------------------------------------------
    const svg = document.createElementNS(SVG, 'svg');
    svg.id = 'overlay';
    svg.setAttribute('preserveAspectRatio', 'none');
    svg.style.cssText = 'position:absolute;inset:0;width:100%;height:100%;pointer-events:none;overflow:hidden';
    view.append(svg);
    function drawOverlay(o) {
      svg.setAttribute('viewBox', `0 0 ${o.width} ${o.height}`);
      // Canvas pixels per CSS pixel: lines and text keep their on-screen size.
      const k = canvas.clientWidth > 0 ? o.width / canvas.clientWidth : 1;
      const parts = [];
      const esc = (t) => String(t).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);
      for (const [ax, ay, bx, by, color, w, faint] of o.lines)
        parts.push(`<line x1="${ax}" y1="${ay}" x2="${bx}" y2="${by}" stroke="${color}" ` +
                   `stroke-width="${w * k}" stroke-opacity="${faint ? 0.5 : 1}"/>`);
      for (const [x, y, color, item, vertex] of o.dots)
        parts.push(`<circle class="vertex" data-item="${item}" data-vertex="${vertex}" cx="${x}" ` +
                   `cy="${y}" r="${4 * k}" fill="${color}"/>`);
      for (const [x, y, text, color] of o.labels)
        parts.push(`<text class="label" x="${x + 6 * k}" y="${y - 6 * k}" fill="${color}" ` +
                   `font-size="${13 * k}" paint-order="stroke" stroke="#000" ` +
                   `stroke-width="${3 * k}">${esc(text)}</text>`);
      if (o.inspected)
        parts.push(`<circle class="inspected" cx="${o.inspected[0]}" cy="${o.inspected[1]}" ` +
                   `r="${7 * k}" fill="none" stroke="#fff" stroke-width="${2 * k}"/>`);
      svg.innerHTML = parts.join('');
    }

    // ---- state -----------------------------------------------------------------------------
    function setClasses(on) {
      for (const box of classes.querySelectorAll('input')) box.checked = on;
      sendFilter();
    }
    function filterOf() {
      const boxes = [...classes.querySelectorAll('input')];
      const kept = boxes.filter((b) => b.checked).map((b) => Number(b.dataset.class));
      // Every listed class kept: no class filter (classes above the legend's stay drawn).
      const f = { op: 'filter', classes: kept.length === boxes.length ? null : kept,
                  returns: [...returns.querySelectorAll('input:checked')].map((b) => b.dataset.return) };
      if (f.classes) for (let c = legend.length; c < 256; ++c) f.classes.push(c);
      f.intensity = intensityOn.checked ? [Number(intensityMin.value), Number(intensityMax.value)] : null;
      if (state && state.filter) {
        f.gpsTime = state.filter.gpsTime;
        f.pointSource = state.filter.pointSource;
      }
      return f;
    }
    function sendFilter() { send(filterOf()); }

    function showLegend(entries) {
      legend = entries;
      classes.textContent = '';
      for (const c of entries)
        classes.append(el('label', { title: c.name },
          el('input', { type: 'checkbox', 'data-class': c.code, checked: '', onchange: sendFilter }),
          el('span', { class: 'swatch', style: `background:${c.color}` }),
          `${c.code} ${c.name}`));
    }

    function showState(s) {
      state = s;
      if (s.legend) showLegend(s.legend);
      for (const b of toolButtons.children) b.classList.toggle('on', b.dataset.tool === s.tool);
      hint.textContent = HINTS[s.tool] || '';
      drawing.hidden = s.active < 0;
      message.textContent = s.message || '';
      // The measurements, newest last; the selected one with its editable fields.
      list.textContent = '';
      s.items.forEach((m, i) => {
        const li = el('li', { 'data-tool': m.tool, class: i === s.selected ? 'selected' : '',
                              onclick: (e) => { if (e.target === li || e.target.tagName === 'SPAN') send({ op: 'select', item: i }); } },
          el('span', { class: 'what' }, `${m.tool.replace('_', ' ')} `),
          el('span', { class: 'value' }, m.text + (m.complete ? '' : ' …')));
        if (i === s.selected) {
          li.append(el('input', { class: 'label', value: m.label, placeholder: 'label',
                                  onchange: (e) => send({ op: 'label', item: i, text: e.target.value }) }));
          if (m.tool === 'profile')
            li.append(el('label', {}, ' width ', el('input', { type: 'number', step: 'any', value: m.width,
              class: 'width', onchange: (e) => send({ op: 'width', item: i, value: Number(e.target.value) }) })));
          if (m.tool === 'volume' && m.points.length)
            li.append(el('label', {}, ' plane z ', el('input', { type: 'number', step: 'any', value: m.points[0][2],
              class: 'plane', onchange: (e) => send({ op: 'plane', item: i, value: Number(e.target.value) }) })));
        }
        li.append(el('button', { class: 'delete', title: 'delete', onclick: () => send({ op: 'remove', item: i }) }, '×'));
        list.append(li);
      });
      showRecord(s.inspected);
      // Filters as the program applies them.
      const kept = s.filter.classes ? new Set(s.filter.classes) : null;
      for (const box of classes.querySelectorAll('input'))
        box.checked = !kept || kept.has(Number(box.dataset.class));
      for (const box of returns.querySelectorAll('input'))
        box.checked = s.filter.returns.includes(box.dataset.return);
      intensityOn.checked = !!s.filter.intensity;
      if (s.filter.intensity) [intensityMin.value, intensityMax.value] = s.filter.intensity;
      clipMode.value = s.clipMode;
      exports.hidden = !s.canExport;
      // The profile window follows the current profile.
      const p = currentProfile(s);
      const key = p >= 0 ? JSON.stringify([s.items[p].points, s.items[p].width, s.filter, s.clipMode]) : '';
      if (p < 0) {
        profile.hidden = true;
      } else if (p !== profileItem || key !== profileVersion) {
        profileItem = p;
        profileVersion = key;
        send({ op: 'profile', item: p, width: profileCanvas.width, height: profileCanvas.height });
      }
    }
    function currentProfile(s) {
      const sel = s.items[s.selected];
      if (sel && sel.tool === 'profile' && sel.complete) return s.selected;
      let p = -1;
      s.items.forEach((m, i) => { if (m.tool === 'profile' && m.complete) p = i; });
      return p;
    }
    function showRecord(r) {
      inspected.textContent = '';
      if (!r) return;
      const rows = [['source', `${r.source}, record ${r.record}${r.fromSource ? '' : ' (as drawn)'}`],
                    ['x', r.position[0]], ['y', r.position[1]], ['z', r.position[2]]];
      if (r.lonLat) rows.push(['lon, lat', `${r.lonLat[0].toFixed(9)}, ${r.lonLat[1].toFixed(9)}`]);
      for (const [k, v] of Object.entries(r.fields)) rows.push([k, Array.isArray(v) ? v.join(' ') : v]);
      const table = el('table', { id: 'record' });
      for (const [k, v] of rows)
        table.append(el('tr', {}, el('th', {}, k), el('td', {}, typeof v === 'number' ? String(v) : v)));
      inspected.append(el('b', {}, 'inspected point'), table);
    }
    function showProfile(frame, image) {
      profileFrame = frame;
      profileClicks.length = 0;
      profileMeasure.textContent = '';
      if (frame.item < 0) { profile.hidden = true; return; }
      profileCanvas.width = image.width;
      profileCanvas.height = image.height;
      profileCanvas.getContext('2d').putImageData(image, 0, 0);
      profileText.textContent = `length ${frame.length.toFixed(3)}, width ${frame.width.toFixed(3)}; ` +
        `heights ${frame.zRange[0].toFixed(3)} to ${frame.zRange[1].toFixed(3)}; ${frame.points} points`;
      profile.hidden = false;
    }

    // ---- keys -------------------------------------------------------------------------------
    function key(e) {
      const k = e.key.toLowerCase();
      const tool = TOOLS.find(([, key]) => key === k);
      if (tool) send({ op: 'tool', name: tool[0] });
      else if (e.key === 'Enter') send({ op: 'finish' });
      else if (e.key === 'Backspace') send({ op: 'undo' });
      else if (e.key === 'Escape') send({ op: 'cancel' });
      else if (e.key === 'Delete') send({ op: 'remove', item: -1 });
      else return false;
      return true;
    }

    // An export's files (the viewer read them from the program's memory): offered for download.
    function showExport(e) {
      message.textContent = e.result;
      for (const f of e.files)
        opts.download(f.name, f.data, f.name.endsWith('.csv') ? 'text/csv' : 'application/octet-stream');
    }
    return { showState, showOverlay: drawOverlay, showProfile, showExport, key,
             get state() { return state; } };
  };
})();
