// isotopo's HTML report: plots, the tau slider, the handle table and the 3D view, from the
// data embedded in this file (gzip + base64: the report's JSON, the meshes' binary arrays and
// the three.js bundle). Nothing is fetched.
'use strict';

const state = {
  data: null,      // the report's JSON (see html/mod.rs: data_json)
  bin: null,       // ArrayBuffer of the meshes
  THREE: null,
  tau: 20,         // the slider's tau, voxel edges; Infinity: every handle goes
  sort: { key: 'size', up: true },
  filter: 'all',   // table rows: all, go (smaller than tau), stay
  picked: null,    // ids picked in a plot (table shows only them), or null
  page: 0,
  current: null,   // the handle shown in 3D, or null for the overview
  views: [],       // 3D views: { renderer, scene, camera, controls, root }
};

const PAGE = 100;
const SLIDER = 1000;  // slider positions; tau 3 at 0, one more than the largest handle at the end

/// The largest of `values` and `floor` (a loop: spreading 100,000 values into Math.max
/// overflows the stack).
function maxOf(values, floor) {
  let m = floor;
  for (const v of values) if (v > m) m = v;
  return m;
}

/// Where simplifying with `tau` cuts an axis of integer sizes: between the sizes that go (below
/// tau) and those that stay.
const cutAt = tau => Math.ceil(tau) - 0.5;

const tauAt = p => Math.round(3 * Math.pow(state.tauMax / 3, p / SLIDER));
const sliderAt = tau => Math.round(SLIDER * Math.log(Math.max(tau, 3) / 3) / Math.log(state.tauMax / 3));

window.addEventListener('error', e => showError(e.message));
window.addEventListener('unhandledrejection', e => showError(String(e.reason)));

function showError(message) {
  const el = document.getElementById('error');
  el.hidden = false;
  el.textContent = 'The report failed to load: ' + message;
}

// --- decoding -------------------------------------------------------------------------------

async function inflate(id) {
  const text = document.getElementById(id).textContent.trim();
  const bytes = Uint8Array.from(atob(text), c => c.charCodeAt(0));
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));
  return new Response(stream).arrayBuffer();
}

async function loadThree() {
  const code = new TextDecoder().decode(await inflate('three-bundle'));
  const url = URL.createObjectURL(new Blob([code], { type: 'text/javascript' }));
  await new Promise((resolve, reject) => {
    const s = document.createElement('script');
    s.src = url;
    s.onload = resolve;
    s.onerror = () => reject(new Error('three.js did not load'));
    document.head.appendChild(s);
  });
  URL.revokeObjectURL(url);
  return window.THREE;
}

async function main() {
  const [data, bin] = await Promise.all([inflate('report-data'), inflate('report-bin')]);
  state.data = JSON.parse(new TextDecoder().decode(data));
  state.bin = bin;
  const d = state.data;
  for (const h of d.handles) h.size = h.size ?? Infinity;
  const sizes = d.handles.map(h => h.size).filter(Number.isFinite);
  const largest = maxOf(sizes, 20);
  // The slider is logarithmic: as fine at 3..20, where noise is, as at hundreds. Sizes are
  // exact below the search limit (analyze --tau) or the tau used (simplify): it stops there.
  const slider = document.getElementById('tau');
  state.tauMax = Number.isFinite(d.tau) ? Math.max(4, Math.ceil(d.tau)) : largest + 1;
  state.tau = Number.isFinite(d.tau) ? d.tau : Math.min(20, largest + 1);
  slider.min = '0';
  slider.max = String(SLIDER);
  slider.value = String(sliderAt(state.tau));
  slider.addEventListener('input', () => setTau(tauAt(Number(slider.value))));
  document.getElementById('made-by').textContent = 'isotopo ' + d.version;
  renderSummary();
  renderHeader();
  setupTable();
  setTau(state.tau);
  state.THREE = await loadThree();
  setupViews();
  showOverview();
  document.body.dataset.ready = '1';
}

// --- summary and tau ------------------------------------------------------------------------

function renderHeader() {
  const d = state.data;
  const n = d.handle_count;
  const what = d.kind === 'simplify' ? 'simplify report' : 'analysis';
  document.getElementById('subtitle').innerHTML =
    `${what}: <span id="handle-count">${n}</span> handle${n === 1 ? '' : 's'}` +
    (d.kind === 'simplify' ? simplifyCounts(d) : '');
}

/// ": 685 removed by 669 walls, 21 kept" (a wall may close tiny handles beside its own).
function simplifyCounts(d) {
  const kept = d.handles.filter(h => h.status === 'kept').length;
  const walls = d.handles.length - kept;
  return `: ${d.handle_count - kept} removed by ${walls} wall${walls === 1 ? '' : 's'}, ${kept} kept`;
}

function renderSummary() {
  const table = document.getElementById('summary');
  for (const [label, value] of state.data.summary) {
    const tr = table.insertRow();
    tr.insertCell().textContent = label;
    tr.insertCell().textContent = value;
  }
}

const goes = h => h.size < state.tau;

function setTau(tau) {
  state.tau = tau;
  const d = state.data;
  document.getElementById('tau-value').textContent = String(tau);
  const go = d.handles.filter(goes).length;
  const stay = d.handles.length - go;
  document.getElementById('tau-counts').innerHTML =
    `<span id="count-go">${go}</span> go, <span id="count-stay">${stay}</span> stay` +
    (Number.isFinite(d.tau) && d.kind === 'simplify' ? ` · tau used: ${d.tau}` : '');
  const [lo, hi] = sameResult(tau);
  document.getElementById('tau-range').textContent = hi === Infinity
    ? `Any tau above ${lo} gives the same result.`
    : lo + 1 === hi
      ? `Only tau ${hi} removes exactly these handles (sizes ${lo} and ${hi} are both taken).`
      : `Any tau from ${lo + 1} to ${hi} gives the same result (no handle has a size in between).`;
  renderHistogram();
  renderScatter();
  renderTable();
  if (state.views.length) refreshOverviewColours();
}

/// The tau range [lo + 1, hi] that removes exactly the handles `tau` removes: lo the largest
/// size below tau, hi the smallest size at or above it.
function sameResult(tau) {
  let lo = 2, hi = Infinity;
  for (const h of state.data.handles) {
    if (!Number.isFinite(h.size)) continue;
    if (h.size < tau) lo = Math.max(lo, h.size);
    else hi = Math.min(hi, h.size);
  }
  return [lo, Math.min(hi, state.tauMax)];
}

// --- plots (SVG) ----------------------------------------------------------------------------

const SVG = 'http://www.w3.org/2000/svg';
const W = 640, H = 400, M = { left: 64, right: 16, top: 16, bottom: 48 };

function el(name, attrs = {}, parent = null) {
  const e = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

/// A logarithmic scale from [lo, hi] to [a, b].
function logScale(lo, hi, a, b) {
  const l0 = Math.log(lo), l1 = Math.log(hi);
  const f = v => a + (Math.log(v) - l0) / (l1 - l0) * (b - a);
  f.lo = lo; f.hi = hi;
  return f;
}

/// Tick values on a log axis: 1, 2, 5 × powers of ten within range, thinned so labels at
/// least `gap` pixels apart never overlap.
function logTicks(scale, gap) {
  const out = [];
  for (let p = 1; p <= 1e9; p *= 10) {
    for (const m of [1, 2, 5]) {
      const v = m * p;
      if (v < scale.lo || v > scale.hi) continue;
      if (out.length && Math.abs(scale(v) - scale(out[out.length - 1])) < gap) continue;
      out.push(v);
    }
  }
  return out;
}

function axes(svg, x, y, xLabel, yLabel) {
  const g = el('g', { class: 'axis' }, svg);
  for (const v of logTicks(y, 18)) {
    el('line', { class: 'grid', x1: M.left, x2: W - M.right, y1: y(v), y2: y(v) }, g);
    el('line', { x1: M.left - 5, x2: M.left, y1: y(v), y2: y(v) }, g);
    el('text', { x: M.left - 8, y: y(v) + 4, 'text-anchor': 'end' }, g).textContent = v;
  }
  for (const v of logTicks(x, 36)) {
    el('line', { x1: x(v), x2: x(v), y1: H - M.bottom, y2: H - M.bottom + 5 }, g);
    el('text', { x: x(v), y: H - M.bottom + 18, 'text-anchor': 'middle' }, g).textContent = v;
  }
  el('path', { d: `M${M.left},${M.top}V${H - M.bottom}H${W - M.right}`, fill: 'none' }, g);
  el('text', { x: (M.left + W - M.right) / 2, y: H - 8, 'text-anchor': 'middle' }, g).textContent = xLabel;
  el('text', { transform: `translate(14,${(M.top + H - M.bottom) / 2}) rotate(-90)`, 'text-anchor': 'middle' }, g)
    .textContent = yLabel;
}

/// Bin edges: one per voxel edge up to 20 (where noise is), then growing by a quarter.
function binEdges(max) {
  const edges = [2.5];
  while (edges[edges.length - 1] <= max) {
    const e = edges[edges.length - 1];
    edges.push(e < 20 ? e + 1 : Math.round(e * 1.25) + 0.5);
  }
  return edges;
}

function renderHistogram() {
  const box = document.getElementById('histogram');
  box.textContent = '';
  const handles = state.data.handles.filter(h => Number.isFinite(h.size));
  const edges = binEdges(maxOf(handles.map(h => h.size), 10));
  const bins = edges.slice(1).map(() => []);
  for (const h of handles) {
    const b = edges.findIndex((e, i) => i > 0 && h.size < e) - 1;
    if (b >= 0) bins[b].push(h);
  }
  const top = maxOf(bins.map(b => b.length), 1) * 1.6;
  const x = logScale(edges[0], edges[edges.length - 1], M.left, W - M.right);
  const y = logScale(0.7, top, H - M.bottom, M.top);
  const svg = el('svg', { viewBox: `0 0 ${W} ${H}`, role: 'img', 'aria-label': 'histogram of handle sizes' }, box);
  band(svg, x, (lo, hi) => [x(Math.max(lo + 0.5, x.lo)), x(Math.min(hi + 0.5, x.hi))]);
  axes(svg, x, y, 'handle size (voxel edges)', 'handles');
  bins.forEach((hs, b) => {
    if (!hs.length) return;
    const x0 = x(edges[b]) + 1, x1 = x(edges[b + 1]) - 1;
    const r = el('rect', {
      // Goes when its largest size, edges[b + 1] - 0.5, is below tau.
      class: 'bar' + (edges[b + 1] - 0.5 < state.tau ? ' goes' : ''),
      x: x0, width: Math.max(1, x1 - x0), y: y(hs.length), height: y(0.7) - y(hs.length),
    }, svg);
    const label = `size ${Math.ceil(edges[b])}${edges[b + 1] - edges[b] > 1 ? '–' + Math.floor(edges[b + 1]) : ''}`;
    hover(r, label, hs);
    r.addEventListener('click', () => pick(hs, label));
  });
  if (tauUsed()) {
    const t = x(Math.min(Math.max(cutAt(state.data.tau), x.lo), x.hi));
    el('path', { class: 'used-line', d: `M${t},${M.top}V${H - M.bottom}` }, svg);
  }
  const t = x(Math.min(Math.max(cutAt(state.tau), x.lo), x.hi));
  el('path', { class: 'tau-line', d: `M${t},${M.top}V${H - M.bottom}` }, svg);
  const right = t > W - M.right - 60;
  el('text', { x: right ? t - 4 : t + 4, y: M.top + 12, fill: '#d22', 'text-anchor': right ? 'end' : 'start' }, svg)
    .textContent = `tau ${state.tau}`;
}

/// Whether the report is of a simplification with this tau (drawn dashed beside the slider's).
const tauUsed = () => state.data.kind === 'simplify' && Number.isFinite(state.data.tau);

/// The band of tau values that give the same result, shaded.
function band(svg, x, span) {
  const [lo, hi] = sameResult(state.tau);
  const [a, b] = span(lo, hi === Infinity ? x.hi : hi - 1);
  if (b > a) el('rect', { class: 'band', x: a, width: b - a, y: M.top, height: H - M.top - M.bottom }, svg);
}

function renderScatter() {
  const box = document.getElementById('scatter');
  box.textContent = '';
  const handles = state.data.handles.filter(h => h.reeb != null && h.cross != null);
  const points = new Map();
  for (const h of handles) {
    const key = `${h.reeb},${h.cross},${h.encloses}`;
    if (!points.has(key)) points.set(key, []);
    points.get(key).push(h);
  }
  const max = maxOf(handles.map(h => Math.max(h.reeb, h.cross)), 10);
  // Points at the smallest lengths sit inside the frame, not on the axes.
  const x = logScale(2.4, max * 1.3, M.left, W - M.right);
  const y = logScale(2.4, max * 1.3, H - M.bottom, M.top);
  const svg = el('svg', { viewBox: `0 0 ${W} ${H}`, role: 'img', 'aria-label': 'Reeb loop against cross loop' }, box);
  axes(svg, x, y, 'Reeb loop (voxel edges)', 'cross loop (voxel edges)');
  const lShape = (t, cls) => {
    // A handle goes when either loop is below tau: left of or below the corner.
    const tx = x(Math.min(Math.max(cutAt(t), x.lo), x.hi)), ty = y(Math.min(Math.max(cutAt(t), y.lo), y.hi));
    el('path', { class: cls, d: `M${tx},${M.top}V${ty}H${W - M.right}` }, svg);
  };
  if (tauUsed()) lShape(state.data.tau, 'used-line');
  lShape(state.tau, 'tau-line');
  for (const hs of points.values()) {
    const h = hs[0];
    const c = el('circle', {
      class: `pt ${h.encloses === 'void' ? 'void' : 'material'}${goes(h) ? ' goes' : ''}` +
        (state.current && hs.includes(state.current) ? ' picked' : ''),
      cx: x(h.reeb), cy: y(h.cross), r: Math.min(12, 3 + Math.sqrt(hs.length)),
    }, svg);
    const label = `Reeb ${h.reeb}, cross ${h.cross} (${h.encloses ?? '?'})`;
    hover(c, label, hs);
    c.addEventListener('click', () => { pick(hs, label); showHandle(hs[0]); });
  }
}

function hover(target, label, handles) {
  const tip = document.getElementById('tooltip');
  target.addEventListener('mousemove', e => {
    const ids = handles.slice(0, 12).map(h => h.id).join(', ');
    tip.hidden = false;
    tip.textContent = `${label}: ${handles.length} handle${handles.length === 1 ? '' : 's'} ` +
      `(id ${ids}${handles.length > 12 ? ', …' : ''})`;
    tip.style.left = `${e.clientX + 12}px`;
    tip.style.top = `${e.clientY + 12}px`;
  });
  target.addEventListener('mouseleave', () => { tip.hidden = true; });
}

/// Shows only these handles in the table.
function pick(handles, label) {
  state.picked = new Set(handles.map(h => h.id));
  state.pickedLabel = label;
  state.page = 0;
  renderTable();
  document.getElementById('table-section').scrollIntoView({ block: 'nearest' });
}

// --- table ----------------------------------------------------------------------------------

function columns() {
  const mm = v => v == null ? '–' : v.toFixed(1);
  const n = v => v == null || v === Infinity ? '–' : String(v);
  const box = h => `${h.bbox[0]}..${h.bbox[3]}, ${h.bbox[1]}..${h.bbox[4]}, ${h.bbox[2]}..${h.bbox[5]}`;
  const cols = [
    { key: 'id', label: 'id', show: h => h.id },
    { key: 'size', label: 'size', show: h => n(h.size) },
    { key: 'reeb', label: 'Reeb loop', show: h => n(h.reeb) },
    { key: 'reeb_mm', label: 'Reeb mm', show: h => mm(h.reeb_mm) },
    { key: 'cross', label: 'cross loop', show: h => n(h.cross) },
    { key: 'cross_mm', label: 'cross mm', show: h => mm(h.cross_mm) },
    { key: 'encloses', label: 'encloses', show: h => h.encloses ?? '–', text: true },
    { key: 'kind', label: 'kind', show: h => h.kind.replace('_', ' '), text: true },
  ];
  if (state.data.kind === 'simplify') {
    cols.push({ key: 'status', label: 'simplify', show: h => h.status ?? '', text: true });
    cols.push({ key: 'detail', label: 'wall / why kept', show: h => h.detail ?? '', text: true });
  } else {
    cols.splice(1, 0, { key: 'surface', label: 'surface', show: h => n(h.surface) });
  }
  cols.push({ key: 'bbox', label: 'box (voxels x, y, z)', show: box, text: true, sortBy: h => h.bbox[2] });
  return cols;
}

function setupTable() {
  const head = document.querySelector('#handles thead').insertRow();
  for (const c of columns()) {
    const th = document.createElement('th');
    th.textContent = c.label;
    th.dataset.key = c.key;
    if (c.text) th.className = 'text';
    th.addEventListener('click', () => {
      state.sort = { key: c.key, up: state.sort.key === c.key ? !state.sort.up : true };
      renderTable();
    });
    head.appendChild(th);
  }
  for (const r of document.querySelectorAll('input[name=filter]')) {
    r.addEventListener('change', () => { state.filter = r.value; state.page = 0; renderTable(); });
  }
  document.getElementById('clear-pick').addEventListener('click', () => {
    state.picked = null;
    renderTable();
  });
}

function rows() {
  const cols = columns();
  const col = cols.find(c => c.key === state.sort.key) ?? cols[0];
  const key = col.sortBy ?? (h => h[col.key] ?? Infinity);
  const keep = h => (state.filter === 'all' || (state.filter === 'go') === goes(h)) &&
    (!state.picked || state.picked.has(h.id));
  const list = state.data.handles.filter(keep);
  list.sort((a, b) => {
    const ka = key(a), kb = key(b);
    const c = ka < kb ? -1 : ka > kb ? 1 : a.id - b.id;
    return state.sort.up ? c : -c;
  });
  return list;
}

function renderTable() {
  const cols = columns();
  const list = rows();
  const pages = Math.max(1, Math.ceil(list.length / PAGE));
  state.page = Math.min(state.page, pages - 1);
  const body = document.querySelector('#handles tbody');
  body.textContent = '';
  for (const h of list.slice(state.page * PAGE, (state.page + 1) * PAGE)) {
    const tr = body.insertRow();
    tr.className = (goes(h) ? 'goes' : '') + (h === state.current ? ' current' : '');
    tr.dataset.id = h.id;
    for (const c of cols) {
      const td = tr.insertCell();
      td.textContent = c.show(h);
      if (c.text) td.className = 'text';
    }
    tr.addEventListener('click', () => showHandle(h));
  }
  for (const th of document.querySelectorAll('#handles th')) {
    th.classList.toggle('sorted', th.dataset.key === state.sort.key);
    th.classList.toggle('up', state.sort.up);
  }
  document.getElementById('filter-note').textContent = state.picked
    ? `${list.length} handles of ${state.pickedLabel}` : `${list.length} handles`;
  document.getElementById('clear-pick').hidden = !state.picked;
  pager(pages);
}

function pager(pages) {
  const p = document.getElementById('pager');
  p.textContent = '';
  if (pages <= 1) return;
  const button = (label, page) => {
    const b = document.createElement('button');
    b.textContent = label;
    b.disabled = page < 0 || page >= pages || page === state.page;
    b.addEventListener('click', () => { state.page = page; renderTable(); });
    p.appendChild(b);
  };
  button('‹ previous', state.page - 1);
  p.appendChild(document.createTextNode(`page ${state.page + 1} of ${pages}`));
  button('next ›', state.page + 1);
}

// --- 3D -------------------------------------------------------------------------------------

const COLOURS = { surface: 0xd8dce4, after: 0xb9d3b0, reeb: 0x2850c8, cross: 0xd22222, wall: 0xf0a000 };

function setupViews() {
  const T = state.THREE;
  const simplify = state.data.kind === 'simplify';
  document.getElementById('after-box').hidden = !simplify;
  if (simplify) document.getElementById('label-before').textContent = 'before';
  const canvases = simplify ? ['view-before', 'view-after'] : ['view-before'];
  const camera = new T.PerspectiveCamera(40, 1, 0.1, 1e5);
  for (const id of canvases) {
    const canvas = document.getElementById(id);
    const renderer = new T.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.localClippingEnabled = true;
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    const scene = new T.Scene();
    scene.background = new T.Color(0xf0f2f5);
    scene.add(new T.AmbientLight(0xffffff, 1.0));
    // A headlight: each view has its own, placed at the shared camera (renderAll).
    const light = new T.DirectionalLight(0xffffff, 2.2);
    scene.add(light, light.target);
    const root = new T.Group();
    // Voxel coordinates to world millimetres: the volume's affine.
    const a = state.data.affine;
    root.matrixAutoUpdate = false;
    root.matrix.set(...a[0], ...a[1], ...a[2], ...a[3]);
    scene.add(root);
    const controls = new state.THREE.OrbitControls(camera, canvas);
    controls.addEventListener('change', renderAll);
    state.views.push({ renderer, scene, root, controls, canvas, light });
  }
  state.camera = camera;
  new ResizeObserver(renderAll).observe(document.getElementById('views'));
  document.getElementById('show-overview').addEventListener('click', showOverview);
  document.getElementById('clip').addEventListener('change', () => { if (state.current) showHandle(state.current); });
}

/// What the colours mean: in the overview, or round a handle.
function legend(overview) {
  const simplify = state.data.kind === 'simplify';
  const blue = '<b style="color:#2850c8">blue</b>', red = '<b style="color:#d22">red</b>';
  document.getElementById('legend').innerHTML = (overview
    ? `${red}: loops of the handles smaller than tau, ${blue}: the others (seen through the surface)`
    : simplify
      ? `${red}: the loop closed, <b style="color:#f0a000">orange</b>: the wall’s samples`
      : `${blue}: Reeb loop (along the sweep), ${red}: cross loop`) +
    '. Drag to rotate, scroll to zoom, right-drag to pan.';
}

function renderAll() {
  const cam = state.camera;
  for (const v of state.views) {
    const { clientWidth: w, clientHeight: h } = v.canvas;
    if (v.canvas.width !== Math.round(w * v.renderer.getPixelRatio())) v.renderer.setSize(w, h, false);
    cam.aspect = w / Math.max(1, h);
    cam.updateProjectionMatrix();
    v.light.position.copy(cam.position);
    v.light.target.position.copy(v.controls.target);
    v.renderer.render(v.scene, cam);
  }
}

/// Mesh `ref` of the binary blob (delta-coded: html/blob.rs) as a three.js geometry in voxel
/// coordinates.
function geometry(ref) {
  const T = state.THREE;
  const deltas = new Uint16Array(state.bin, ref.v[0], ref.v[1] * 3);
  const pos = new Float32Array(deltas.length);
  const codes = new Uint16Array(deltas.length);  // wraps as the deltas did
  for (let i = 0; i < deltas.length; i++) {
    codes[i] = (i >= 3 ? codes[i - 3] : 0) + deltas[i];
    pos[i] = ref.origin[i % 3] + ref.scale * codes[i];
  }
  const Index = ref.w === 2 ? Uint16Array : Uint32Array;
  const d = new Index(state.bin, ref.t[0], ref.t[1] * 3);
  const index = new Index(d.length);
  for (let i = 0; i < d.length; i++) index[i] = (i ? index[i - 1] : 0) + d[i];
  // What was decoded against the sums the report carries (html/scene.rs: encode).
  let sumCodes = 0, sumIndices = 0;
  for (const c of codes) sumCodes = (sumCodes + c) >>> 0;
  for (const i of index) sumIndices = (sumIndices + i) >>> 0;
  if (sumCodes !== ref.sum[0] || sumIndices !== ref.sum[1]) {
    throw new Error('a mesh of the report does not decode to what was written: the file is damaged');
  }
  const g = new T.BufferGeometry();
  g.setAttribute('position', new T.BufferAttribute(pos, 3));
  g.setIndex(new T.BufferAttribute(index, 1));
  g.computeVertexNormals();
  return g;
}

const geometries = new Map();  // decoded meshes, kept: a brick serves many handles
const materials = new Map();
const clipping = [];           // planes round the handle shown (none for the overview)

/// The mesh `ref` (cached under `key`) in one colour.
function surface(key, ref, colour) {
  const T = state.THREE;
  if (!geometries.has(key)) geometries.set(key, geometry(ref));
  if (!materials.has(colour)) {
    materials.set(colour, new T.MeshLambertMaterial({
      color: colour, side: T.DoubleSide, polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
      clippingPlanes: clipping,
    }));
  }
  const m = new T.Mesh(geometries.get(key), materials.get(colour));
  m.userData.shared = true;
  return m;
}

/// Polylines (closed loops) of doubled voxel coordinates, one colour each or per loop.
function loopLines(loops, colours) {
  const T = state.THREE;
  const pos = [], col = [];
  const c = new T.Color();
  loops.forEach((flat, k) => {
    c.setHex(colours[k]);
    const n = flat.length / 3;
    for (let i = 0; i < n; i++) {
      const j = (i + 1) % n;
      pos.push(flat[3 * i] / 2, flat[3 * i + 1] / 2, flat[3 * i + 2] / 2,
        flat[3 * j] / 2, flat[3 * j + 1] / 2, flat[3 * j + 2] / 2);
      col.push(c.r, c.g, c.b, c.r, c.g, c.b);
    }
  });
  const g = new T.BufferGeometry();
  g.setAttribute('position', new T.Float32BufferAttribute(pos, 3));
  g.setAttribute('color', new T.Float32BufferAttribute(col, 3));
  return new T.LineSegments(g, new T.LineBasicMaterial({ vertexColors: true, depthTest: false }));
}

/// Closed loops of doubled voxel coordinates as thin tubes (a close-up: lines would be one pixel
/// wide), one colour per loop; drawn over the surface.
function loopTubes(loops, colours, radius) {
  const T = state.THREE;
  const group = new T.Group();
  const up = new T.Vector3(0, 1, 0);
  loops.forEach((flat, k) => {
    const material = new T.MeshBasicMaterial({ color: colours[k], depthTest: false });
    const n = flat.length / 3;
    const at = i => new T.Vector3(flat[3 * i] / 2, flat[3 * i + 1] / 2, flat[3 * i + 2] / 2);
    for (let i = 0; i < n; i++) {
      const a = at(i), b = at((i + 1) % n);
      const along = b.clone().sub(a);
      const tube = new T.Mesh(new T.CylinderGeometry(radius, radius, along.length(), 8), material);
      tube.position.copy(a).add(b).multiplyScalar(0.5);
      tube.quaternion.copy(new T.Quaternion().setFromUnitVectors(up, along.normalize()));
      tube.renderOrder = 1;
      group.add(tube);
    }
  });
  return group;
}

function clearViews() {
  for (const v of state.views) {
    for (const child of [...v.root.children]) {
      v.root.remove(child);
      if (child.userData.shared) continue;
      child.traverse(o => { o.geometry?.dispose(); o.material?.dispose(); });
    }
  }
}

/// Points the camera at the box (voxel coordinates) from the front, `distance` times its radius
/// away.
function frame(min, max, distance) {
  const T = state.THREE;
  const root = state.views[0].root;
  root.updateMatrixWorld(true);
  const box = new T.Box3(new T.Vector3(...min), new T.Vector3(...max)).applyMatrix4(root.matrix);
  const sphere = box.getBoundingSphere(new T.Sphere());
  const r = Math.max(sphere.radius, 1);
  const cam = state.camera;
  cam.near = r / 100;
  cam.far = r * 100;
  cam.position.copy(sphere.center).add(new T.Vector3(0.35, -1, 0.45).normalize().multiplyScalar(r * distance));
  cam.up.set(0, 0, 1);
  for (const v of state.views) {
    v.controls.target.copy(sphere.center);
    v.controls.update();
  }
  renderAll();
}

function handleLoops(h) {
  if (!h.loops) return [];
  return state.data.kind === 'simplify' ? h.loops.map(l => [l, COLOURS.cross]) :
    h.loops.map((l, k) => [l, k === 0 ? COLOURS.reeb : COLOURS.cross]);
}

/// Clips the surfaces to the box (voxel coordinates) so that no fold in front hides the handle;
/// none when `min` is null.
function clipTo(min, max) {
  const T = state.THREE;
  clipping.length = 0;
  if (min) {
    const root = state.views[0].root;
    root.updateMatrixWorld(true);
    for (let a = 0; a < 3; a++) {
      const n = new T.Vector3().setComponent(a, 1);
      // Keeps x_a >= min_a and x_a <= max_a (three.js keeps the side the normal points to).
      clipping.push(new T.Plane(n.clone(), -min[a]).applyMatrix4(root.matrix));
      clipping.push(new T.Plane(n.clone().negate(), max[a]).applyMatrix4(root.matrix));
    }
  }
  for (const m of materials.values()) m.needsUpdate = true;
}

function showOverview() {
  state.current = null;
  clearViews();
  clipTo(null);
  legend(true);
  const d = state.data;
  state.views.forEach((v, k) => {
    v.root.add(surface(`overview ${k}`, d.overview[k], k ? COLOURS.after : COLOURS.surface));
  });
  refreshOverviewColours();
  frame([0, 0, 0], d.dims.map(n => n - 1), 2.3);
  document.getElementById('view-caption').textContent =
    `The whole surface, coarsened ×${state.data.overview_factor}: every loop listed, red where the handle is ` +
    `smaller than tau. Click a handle in the table or a plot to see it up close.`;
  renderTable();
}

/// The overview's loops, coloured by the slider's tau (red: goes).
function refreshOverviewColours() {
  if (state.current !== null) return;
  for (const v of state.views) {
    const old = v.root.children.find(c => c.userData.overviewLoops);
    if (old) { v.root.remove(old); old.geometry.dispose(); old.material.dispose(); }
    const loops = [], colours = [];
    for (const h of state.data.handles) {
      for (const l of h.loops ?? []) { loops.push(l); colours.push(goes(h) ? COLOURS.cross : COLOURS.reeb); }
    }
    const lines = loopLines(loops, colours);
    lines.userData.overviewLoops = true;
    v.root.add(lines);
  }
  renderAll();
}

function showHandle(h) {
  state.current = h;
  clearViews();
  legend(false);
  const d = state.data;
  const scene = h.bricks != null;
  state.views.forEach((v, k) => {
    const colour = k ? COLOURS.after : COLOURS.surface;
    if (scene) {
      for (const b of h.bricks) {
        // After simplify: the brick's own mesh where a sample changed, else the one before.
        const after = k && d.bricks[b].after;
        v.root.add(surface(`${b} ${after ? 1 : 0}`, after || d.bricks[b].before, colour));
      }
    } else {
      v.root.add(surface(`overview ${k}`, d.overview[k], colour));
    }
    const loops = handleLoops(h);
    const radius = Math.max(0.05, maxOf(h.bbox.slice(3).map((v, a) => v - h.bbox[a]), 0) / 60);
    if (loops.length) v.root.add(loopTubes(loops.map(l => l[0]), loops.map(l => l[1]), radius));
    if (h.wall && h.wall.length) v.root.add(wallPoints(h.wall));
  });
  // The box round the handle: the report's margin beyond its loop (and wall), clipped to and
  // framed (its bricks hold that much surface).
  const m = state.data.margin;
  const min = h.bbox.slice(0, 3).map(v => v - m), max = h.bbox.slice(3).map(v => v + m);
  clipTo(scene && document.getElementById('clip').checked ? min : null, max);
  frame(min, max, 2.2);
  const size = Number.isFinite(h.size) ? h.size : 'beyond the limit';
  document.getElementById('view-caption').textContent =
    `Handle ${h.id}: size ${size}` + (h.status ? `, ${h.status}` : '') +
    (scene ? '' : ' (no close-up in this report: shown on the coarse surface)') +
    (h.loops ? '' : ' (its loops are beyond the report’s budget)');
  renderTable();
  renderScatter();
}

function wallPoints(flat) {
  const T = state.THREE;
  const g = new T.BufferGeometry();
  g.setAttribute('position', new T.Float32BufferAttribute(flat.map(v => v / 2), 3));
  return new T.Points(g, new T.PointsMaterial({ color: COLOURS.wall, size: 7, sizeAttenuation: false, depthTest: false }));
}

main();
