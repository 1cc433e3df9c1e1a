// The web viewer (issue 16): a Myriad dataset served by `myriad serve`, read by range requests,
// selected and decoded in workers by the same Rust as `myriad render` (myriad_web.wasm), drawn
// with WebGL2: adaptive point sizes (the drawn nodes' tree, as draw.wgsl walks it), eye-dome
// lighting (as edl.wgsl), positions relative to each node (no jitter at UTM or ECEF sizes).
// Orbit (left drag), pan (right drag or shift), zoom (wheel), double-click to centre; click a
// point for its attributes, measure distances, clip to a box and download its points as LAZ,
// share the camera as a link; annotations and measurements saved with the dataset (work.js);
// cross-sections (profile.js), volumes (volume.js); colour by any attribute through a gradient
// and show only the points that meet conditions (`where`, as `--where` reads them).
// `window.myriad` exposes the state to scripts (tests).
"use strict";

const SCHEMES = ["rgb", "intensity", "elevation", "classification", "return", "source", "level", "uniform"];
const ADAPTIVE_SCALE = 1.5; // myriad_render::PointSize::ADAPTIVE_SCALE
const MAX_SIZE = 32;
const EDL_RADIUS = 1.4;
const EDL_STRENGTH = 1.0;

const state = {
  dataset: null, info: null, converged: false, points: 0, nodes: 0, loaded: 0, errors: [],
  // Times in ms from the navigation's start (performance.now()'s origin).
  requests: 0, bytes: 0, firstImageMs: null, convergedMs: null, selections: 0, frames: 0,
  pagesMissing: 0, picked: null, measure: [],
  // A dataset being built (served before its build ends): the version drawn, and how often a newer
  // one replaced it.
  building: false, version: null, refreshes: 0,
  // Nodes kept across versions (their pages unchanged) and loaded again, in all.
  nodesKept: 0, nodesDropped: 0,
};

// ---- small vector helpers (f64: JavaScript numbers) ----
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const mul = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = (a) => { const l = Math.sqrt(dot(a, a)); return l > 0 ? mul(a, 1 / l) : a; };

// The camera's frame as myriad_lod::Camera::basis.
function basis(c) {
  const f = norm(sub(c.target, c.position));
  let r = cross(f, c.up);
  if (dot(r, r) < 1e-24) r = cross(f, Math.abs(f[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0]);
  r = norm(r);
  return [r, cross(r, f), f];
}

// Near and far around the dataset's bounds (Camera::fit_depth), for the depth buffer.
function fitDepth(c, b) {
  const [, , f] = basis(c);
  let near = Infinity, far = -Infinity;
  for (let i = 0; i < 8; i++) {
    const p = [b[i & 1 ? 3 : 0], b[i & 2 ? 4 : 1], b[i & 4 ? 5 : 2]];
    const d = dot(sub(p, c.position), f);
    near = Math.min(near, d); far = Math.max(far, d);
  }
  far = Math.max(far, 1e-3) * 1.01;
  return [Math.max(near * 0.99, far * 1e-4), far];
}

// View-projection for positions relative to `origin` (column-major), computed in f64 and only
// then rounded to f32: Camera::view_proj, clip depth from 0 (WebGPU) or -1 (WebGL) to 1.
function viewProj(c, origin, width, height, zeroToOne) {
  const [r, u, f] = basis(c);
  const eye = sub(c.position, origin);
  const fy = 1 / Math.tan((c.fov * Math.PI) / 360);
  const fx = (fy * height) / width;
  const [A, B] = zeroToOne ? [c.far / (c.far - c.near), (-c.far * c.near) / (c.far - c.near)]
    : [(c.far + c.near) / (c.far - c.near), (-2 * c.far * c.near) / (c.far - c.near)];
  const rows = [
    [fx * r[0], fx * r[1], fx * r[2], -fx * dot(r, eye)],
    [fy * u[0], fy * u[1], fy * u[2], -fy * dot(u, eye)],
    [A * f[0], A * f[1], A * f[2], -A * dot(f, eye) + B],
    [f[0], f[1], f[2], -dot(f, eye)],
  ];
  const m = new Float32Array(16);
  for (let col = 0; col < 4; col++) for (let row = 0; row < 4; row++) m[col * 4 + row] = rows[row][col];
  return m;
}

let canvas = document.getElementById("view");
// Where the viewer's files are (`/viewer/` behind `myriad serve`, `viewer/` beside a static
// site's page: `myriad export --to web`).
const VIEWER = new URL(".", document.currentScript.src).href;
// A static site's datasets (`window.MYRIAD_SITE`, written into its page by the export), else
// null: the page is `myriad serve`'s, the dataset named by its address.
const SITE = window.MYRIAD_SITE || null;
let renderer = null;

// ---- view state ----
const params = new URLSearchParams(location.hash.slice(1));
const settings = {
  budget: Number(params.get("budget")) || 2000000,
  minPixels: Number(params.get("threshold")) || 1,
  scheme: Math.max(0, SCHEMES.indexOf(params.get("color") || "rgb")),
  // Colour by an attribute through a gradient ({name, gradient, range}; null: the scheme).
  ramp: (!SCHEMES.includes(params.get("color") || "rgb") || params.get("gradient")) ? {
    name: params.get("color"), gradient: params.get("gradient"),
    range: params.get("range") ? params.get("range").split(",").map(Number) : null } : null,
  // Conditions the points shown meet (`--where`'s syntax); "" for all.
  where: params.get("where") || "",
  edl: params.get("edl") !== "0",
  pointSize: Number(params.get("size")) || 0, // 0: adaptive
  // webgl2 or webgpu; default: WebGPU on a hardware adapter, else WebGL2.
  renderer: params.get("renderer"),
  clip: null, // {box: [6], inside: bool}
  // In the parallel (orthographic) view: the field of view to go back to.
  parallel: Number(params.get("parallel")) || null,
  // Classes not drawn (their points are dropped as nodes are decoded): the address's "hide"
  // ("none": every class drawn), else those the class scheme hides (noise by default).
  hidden: new Set((params.get("hide") || "").split(",").filter((c) => c !== "" && c !== "none").map(Number)),
  hideGiven: params.get("hide") !== null,
  // The class scheme of the dataset's saved work ("classes"; null: the default).
  classes: null,
};
// The classes the scheme hides, as the address would name them.
let schemeHidden = "";
let camera = null;
const nodes = new Map(); // key string -> {key, origin, count, buffer vao, positions, spacing, tree}
let selection = null; // the last answer
let selectionCamera = null;
let drawnAtSelection = "";
let dirty = true;

function keyString(k) { return k.join("-"); }

function cameraLink() {
  const c = camera;
  const v = [...c.position, ...c.target].map((x) => +x.toFixed(4)).join(",");
  const p = new URLSearchParams();
  p.set("camera", v);
  if (c.up[2] !== 1) p.set("up", c.up.join(","));
  if (c.fov !== 60) p.set("fov", c.fov);
  if (settings.parallel) p.set("parallel", settings.parallel);
  if (settings.budget !== 2000000) p.set("budget", settings.budget);
  if (settings.ramp) {
    p.set("color", settings.ramp.name);
    if (settings.ramp.gradient) p.set("gradient", settings.ramp.gradient);
    if (settings.ramp.range) p.set("range", settings.ramp.range.join(","));
  } else if (SCHEMES[settings.scheme] !== "rgb") p.set("color", SCHEMES[settings.scheme]);
  if (settings.where) p.set("where", settings.where);
  const hide = [...settings.hidden].sort((a, b) => a - b).join(",");
  if (hide !== schemeHidden) p.set("hide", hide || "none");
  if (settings.clip) p.set("clip", settings.clip.box.join(",") + (settings.clip.inside ? "" : ",outside"));
  return `${location.origin}${location.pathname}${location.search}#${p.toString().replace(/%2C/g, ",")}`;
}

// ---- workers ----
let selector = null;
const decoders = [];
let nextId = 1;
const pending = new Map();
function call(worker, msg, transfer) {
  const id = nextId++;
  msg.id = id;
  return new Promise((resolve, reject) => {
    pending.set(id, { resolve, reject, worker });
    worker.postMessage(msg, transfer || []);
  });
}
const workerStats = new Map();
function onWorker(e) {
  const m = e.data;
  if (m.stats) {
    workerStats.set(e.target, { ...m.stats });
    state.requests = 0; state.bytes = 0;
    for (const s of workerStats.values()) { state.requests += s.requests; state.bytes += s.bytes; }
  }
  const p = pending.get(m.id);
  if (!p) return;
  pending.delete(m.id);
  if (m.error) p.reject(new Error(m.error)); else p.resolve(m);
}

function error(msg) {
  if (!state.errors.includes(msg)) state.errors.push(msg);
  document.getElementById("errors").textContent = state.errors.join("\n");
}

// Workers for the dataset at `url` (`length` bytes): one selects, the others decode.
async function startWorkers(url, name, length) {
  const sel = new Worker(VIEWER + "worker.js");
  sel.onmessage = onWorker;
  const opened = call(sel, { type: "init", role: "select", module: wasmModule, url, name, length });
  const count = Math.min(4, Math.max(2, navigator.hardwareConcurrency || 2));
  const ready = [];
  const decs = [];
  for (let i = 0; i < count; i++) {
    const w = new Worker(VIEWER + "worker.js");
    w.onmessage = onWorker;
    w.busy = 0;
    decs.push(w);
    ready.push(call(w, { type: "init", role: "decode", module: wasmModule, url, name, length }));
  }
  return { sel, decs, opened, ready };
}

// The address of the version a dataset being built answered with (`X-Myriad-Version`; every
// read names it, so a newer one never mixes in), or the plain address.
function versioned(url, head) {
  const v = head.headers.get("x-myriad-version");
  state.building = head.headers.get("x-myriad-building") === "yes";
  state.version = v;
  return v ? `${url}?v=${encodeURIComponent(v)}` : url;
}

// The dataset's HEAD, and on a static site a one-byte range read: one line when the server
// cannot be read from this page (down, or no CORS headers for this origin), answers with an
// error, or ignores ranges (the whole file would come: the read is stopped).
async function reachable(url) {
  const where = new URL(url, location.href);
  const cors = where.origin !== location.origin ? ` (or sends no CORS headers for ${location.origin})` : "";
  let head;
  try {
    head = await fetch(url, { method: "HEAD" });
  } catch (e) {
    throw new Error(`${url}: no answer this page may read: the server is down${cors}`);
  }
  const failed = head.headers.get("x-myriad-failed");
  if (failed) throw new Error(`${url}: its build on the server failed: ${failed}`);
  if (!head.ok) throw new Error(`${url}: HTTP ${head.status}`);
  if (SITE) {
    const stop = new AbortController();
    let r;
    try {
      r = await fetch(url, { headers: { Range: "bytes=0-0" }, signal: stop.signal });
    } catch (e) {
      throw new Error(`${url}: no answer to a range request this page may read${cors}`);
    }
    stop.abort();
    if (r.status !== 206) {
      throw new Error(`${url}: the server does not answer range requests (HTTP ${r.status} to one): ` +
        "serve the site from one that does (nginx, Apache, a bucket)");
    }
  }
  return head;
}

// A static site of several datasets: a link to each in the panel.
function siteLinks(current) {
  if (SITE.datasets.length < 2) return;
  const div = document.createElement("div");
  div.id = "datasets";
  for (const d of SITE.datasets) {
    const a = document.createElement("a");
    a.href = `?d=${encodeURIComponent(d)}`;
    a.textContent = decodeURIComponent(d.split("/").pop());
    if (d === current) a.style.fontWeight = "bold";
    div.append(a, " ");
  }
  document.getElementById("panel").prepend(div);
}

let wasmModule = null;
async function open() {
  let name, base;
  if (SITE) {
    const given = new URLSearchParams(location.search).get("d") || SITE.datasets[0];
    base = new URL(given, location.href).href;
    name = decodeURIComponent(base.split(/[?#]/)[0].split("/").pop());
    siteLinks(given);
  } else {
    name = decodeURIComponent(location.pathname.replace(/^\/view\//, ""));
    base = `/d/${encodeURIComponent(name)}`;
  }
  state.dataset = name;
  document.title = `${name}: Myriad`;
  const head = await reachable(base);
  const url = versioned(base, head);
  const length = Number(head.headers.get("content-length"));
  wasmModule = await WebAssembly.compileStreaming(fetch(VIEWER + "myriad_web.wasm"));
  const { sel, decs, opened, ready } = await startWorkers(url, name, length);
  selector = sel;
  decoders.push(...decs);
  const info = (await opened).info;
  if (info.error) throw new Error(info.error);
  state.info = info;
  const c = params.get("camera");
  if (c) {
    const v = c.split(",").map(Number);
    const up = (params.get("up") || "0,0,1").split(",").map(Number);
    camera = { position: v.slice(0, 3), target: v.slice(3, 6), up, fov: Number(params.get("fov")) || 60 };
  } else {
    const d = (await call(selector, { type: "camera", width: canvas.width, height: canvas.height, fov: 60 })).camera;
    camera = { position: d.position, target: d.target, up: d.up, fov: d.fov };
  }
  const clip = params.get("clip");
  if (clip) {
    const v = clip.split(",");
    settings.clip = { box: v.slice(0, 6).map(Number), inside: v[6] !== "outside" };
  }
  for (const r of await Promise.all(ready)) if (r.info && r.info.error) throw new Error(r.info.error);
  ui();
  // The dataset's edits (classes set, points removed) apply to every node decoded, from the
  // first (and its terrain to colours by height above it); a static site has none.
  if (!SITE) await loadEdits();
  // Saved work lives on `myriad serve`; a static site has none. Its class scheme names,
  // colours and hides classes from the first node decoded.
  if (!SITE) await loadWork().catch((e) => error(`saved work: ${e.message || e}`));
  settings.classes = (work.doc && work.doc.classes) || null;
  await applyStyle();
  requestSelection();
  if (state.building) setTimeout(follow, 1000);
}

// A dataset being built (`myriad serve SCAN`): asked every second what its newest version is
// (`/build/NAME`, telling it where the camera looks: the build goes there next); a newer one (the
// build's next snapshot, then the finished dataset) replaces what is drawn, the camera and
// settings kept, and only the nodes the server says are new are loaded again.
async function follow() {
  const name = encodeURIComponent(state.dataset);
  try {
    const focus = camera.target.map((v) => +v.toFixed(3)).join(",");
    const r = await fetch(`/build/${name}?since=${encodeURIComponent(state.version || "")}&focus=${focus}`,
      { cache: "no-store" });
    if (!r.ok) throw new Error(`HTTP ${r.status}: ${(await r.text()).trim()}`);
    const b = await r.json();
    state.building = b.building;
    if (b.failed) {
      // What is drawn was the preview or a snapshot, never the dataset: said, and no more asked.
      state.failed = b.failed;
      error(`${state.dataset}: its build on the server failed: ${b.failed} (what is shown is not the whole dataset)`);
      return;
    }
    if (b.version !== state.version) {
      const url = `/d/${name}?v=${encodeURIComponent(b.version)}`;
      const { sel, decs, opened, ready } = await startWorkers(url, state.dataset, b.length);
      const info = (await opened).info;
      await Promise.all(ready);
      if (info.error) throw new Error(info.error);
      const old = [selector, ...decoders];
      for (const [id, p] of pending) if (old.includes(p.worker)) pending.delete(id);
      for (const w of old) w.terminate();
      selector = sel;
      decoders.length = 0;
      decoders.push(...decs);
      selecting = false;
      selection = null;
      // Nodes decoded for the elevation scheme took their colours from the old version's heights.
      const [was, vb] = [state.info.view_bounds, info.view_bounds];
      const sameColours = SCHEMES[settings.scheme] !== "elevation" || (was[2] === vb[2] && was[5] === vb[5]);
      state.info = info;
      state.version = b.version;
      state.refreshes = (state.refreshes || 0) + 1;
      // The new workers take the dataset's edits (a dataset being built has none yet).
      await loadEdits();
      if (settings.ramp || settings.where) await applyStyle();
      else if (b.new && sameColours) refresh(new Set(b.new.map(keyString)));
      else reload();
    }
  } catch (e) {
    error(`following the build: ${e.message || e}`);
  }
  if (state.building) setTimeout(follow, 1000);
}

// A newer version of the dataset: the nodes in `fresh` (new or changed in it) and those whose
// loading the old workers took with them are loaded again; the others stay drawn.
function refresh(fresh) {
  let kept = 0, dropped = 0;
  for (const [k, n] of nodes) {
    if (n.state === "loaded" && !fresh.has(k)) { kept += 1; continue; }
    if (n.handle) renderer.release(n.handle);
    nodes.delete(k);
    dropped += 1;
  }
  state.nodesKept = (state.nodesKept || 0) + kept;
  state.nodesDropped = (state.nodesDropped || 0) + dropped;
  state.converged = false;
  requestSelection();
}

let selecting = false;
let selectAgain = false;
function requestSelection() {
  if (selecting) { selectAgain = true; return; }
  selecting = true;
  selectAgain = false;
  const c = { ...camera };
  const clip = settings.clip;
  const args = [...c.position, ...c.target, ...c.up, c.fov, canvas.width, canvas.height,
    settings.budget, settings.minPixels, clip ? (clip.inside ? 1 : 2) : 0,
    ...(clip ? clip.box : [0, 0, 0, 0, 0, 0])];
  const drawn = [];
  for (const n of nodes.values()) if (n.count !== undefined) drawn.push(...n.key);
  const drawnKey = drawn.join(",");
  call(selector, { type: "select", args, drawn }).then((m) => {
    selecting = false;
    state.selections += 1;
    const s = m.selection;
    if (s.error) { error(s.error); return; }
    for (const e of s.errors) error(e);
    selection = s;
    selectionCamera = c;
    drawnAtSelection = drawnKey;
    state.pagesMissing = s.pages_missing;
    renderer.tree(s.tree);
    load();
    dirty = true;
    if (selectAgain || s.pages_missing > 0) requestSelection();
  }, (e) => { selecting = false; error(String(e.message || e)); });
}

const LOADS_PER_DECODER = 2;
function load() {
  if (!selection) return;
  const want = new Set();
  for (const n of selection.nodes) {
    const k = keyString(n.key);
    want.add(k);
    let node = nodes.get(k);
    if (!node) {
      node = { key: n.key, state: "wanted" };
      nodes.set(k, node);
    }
    node.used = state.selections;
    if (node.state !== "wanted") continue;
    const w = decoders.reduce((a, b) => (b.busy < a.busy ? b : a));
    if (w.busy >= LOADS_PER_DECODER) continue;
    w.busy += 1;
    node.state = "loading";
    const origin = [n.cube[0], n.cube[1], n.cube[2]];
    const vb = state.info.view_bounds;
    call(w, { type: "decode", key: n.key, page: n.page, total: n.total, finest: n.finest, origin,
      scheme: settings.scheme, z: [vb[2], vb[5]], hidden: [...settings.hidden] }).then((m) => {
      w.busy -= 1;
      // Dropped while it was decoded (a reload: new edits, a new style): not uploaded.
      if (nodes.get(k) !== node) { requestSelection(); return; }
      upload(node, origin, n.cube[3], m.positions, m.colours);
      node.classes = m.classes;
      classList();
      node.state = "loaded";
      dirty = true;
      requestSelection();
    }, (e) => {
      w.busy -= 1;
      node.state = "failed";
      error(String(e.message || e));
      load();
    });
  }
  evict(want);
}

function upload(node, origin, side, positions, colours) {
  const handle = renderer.upload(positions, colours);
  Object.assign(node, { handle, origin, side, positions, count: positions.length / 3 });
}

// Keeps at most three budgets' worth of points loaded: the least recently selected go first.
function evict(want) {
  let total = 0;
  for (const n of nodes.values()) if (n.count) total += n.count;
  if (total <= 3 * settings.budget) return;
  const old = [...nodes.values()].filter((n) => n.count && !want.has(keyString(n.key)))
    .sort((a, b) => a.used - b.used);
  for (const n of old) {
    if (total <= 2 * settings.budget) break;
    renderer.release(n.handle);
    total -= n.count;
    nodes.delete(keyString(n.key));
  }
}

function reload() {
  for (const n of nodes.values()) {
    if (n.handle) renderer.release(n.handle);
  }
  nodes.clear();
  // Nothing is drawn until the nodes come back: not converged (a script waiting for the view
  // must not take the state of before).
  state.converged = false;
  requestSelection();
}

// ---- drawing ----
function draw() {
  const w = canvas.width, h = canvas.height;
  [camera.near, camera.far] = fitDepth(camera, state.info.bounds);
  const draws = [];
  let drawnPoints = 0, drawnNodes = 0, complete = true;
  const c = settings.clip;
  for (const s of selection ? selection.nodes : []) {
    const n = nodes.get(keyString(s.key));
    if (!n || !n.count) { if (!n || n.state !== "failed") complete = false; continue; }
    const count = Math.min(s.points, n.count);
    const whole = s.leaf && s.points >= s.total ? 1 : 0;
    const o = n.origin;
    draws.push({
      handle: n.handle, count, vp: viewProj(camera, o, w, h, renderer.zeroToOne),
      spacing: s.spacing * ADAPTIVE_SCALE, node: s.tree, side: n.side,
      clipMin: c ? [c.box[0] - o[0], c.box[1] - o[1], c.box[2] - o[2], c.inside ? 1 : 2] : [0, 0, 0, 0],
      // w 1: a leaf node drawn whole, its lone points drawn small (points.rs's Draw::lone).
      clipMax: c ? [c.box[3] - o[0], c.box[4] - o[1], c.box[5] - o[2], whole] : [0, 0, 0, whole],
    });
    drawnPoints += count;
    drawnNodes += 1;
    n.drawnCount = count;
  }
  renderer.draw({
    width: w, height: h, focal: h / (2 * Math.tan((camera.fov * Math.PI) / 360)),
    near: camera.near, far: camera.far, maxSize: MAX_SIZE, fixedSize: settings.pointSize,
    edl: settings.edl ? { radius: EDL_RADIUS, strength: EDL_STRENGTH } : null, draws,
  });
  state.frames += 1;
  state.points = drawnPoints;
  state.nodes = drawnNodes;
  state.loaded = [...nodes.values()].filter((n) => n.count).length;
  if (drawnNodes > 0 && state.firstImageMs === null) state.firstImageMs = performance.now();
  // Converged: the selection was made for this camera with every node drawn now, and each of
  // its nodes is drawn (or failed), with no hierarchy page missing.
  const drawnKey = [...nodes.values()].filter((n) => n.count !== undefined).map((n) => n.key.join(",")).join(",");
  const converged = !!selection && complete && !selecting && state.pagesMissing === 0 &&
    sameCamera(selectionCamera, camera) && drawnKey === drawnAtSelection;
  if (converged && !state.converged) state.convergedMs = performance.now();
  state.converged = converged;
  status();
  placeLabels();
}

function sameCamera(a, b) {
  return !!a && !!b && ["position", "target", "up"].every((k) => a[k].every((v, i) => v === b[k][i])) && a.fov === b.fov;
}

// The scale bar in the parallel view (a round length at the target's depth) and a gradient
// colouring's legend (its colours, the range's ends), over the view as `render --legend` draws
// them into PNGs.
function legends() {
  const bar = document.getElementById("scalebar");
  bar.style.display = settings.parallel && camera ? "block" : "none";
  if (settings.parallel && camera) {
    const d = Math.hypot(...camera.position.map((v, i) => v - camera.target[i]));
    const perPixel = 2 * d * Math.tan(camera.fov * Math.PI / 360) / canvas.clientHeight;
    const want = perPixel * canvas.clientWidth / 5;
    const p = Math.pow(10, Math.floor(Math.log10(want)));
    let len = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= want * 0.999) || 10 * p;
    if (len > want * 1.5) len /= 2;
    bar.querySelector(".bar").style.width = `${Math.round(len / perPixel)}px`;
    const decimals = Math.max(0, Math.ceil(-Math.log10(len)));
    bar.querySelector(".text").textContent = `${len.toFixed(decimals)} ${state.info.units || "units"}`;
  }
  const g = document.getElementById("ramp-legend");
  const r = settings.ramp;
  const stops = state.rampStops;
  g.style.display = r && r.range && stops ? "block" : "none";
  if (r && r.range && stops) {
    g.querySelector(".name").textContent = r.name === "z" ? "elevation" : r.name;
    g.querySelector(".bar").style.background =
      `linear-gradient(to right, ${stops.map((c) => `rgb(${c.join(",")})`).join(", ")})`;
    const [a, b] = g.querySelectorAll(".ends span");
    const step = Math.abs(r.range[1] - r.range[0]) / 10;
    const decimals = Math.max(0, Math.ceil(-Math.log10(step || 1)));
    a.textContent = r.range[0].toFixed(decimals);
    b.textContent = r.range[1].toFixed(decimals);
  }
}

function frame() {
  // (path.js, loaded after this file, may not be there on the first frame.)
  if (typeof pathTick === "function") pathTick();
  const w = Math.round(canvas.clientWidth * (window.devicePixelRatio || 1));
  const h = Math.round(canvas.clientHeight * (window.devicePixelRatio || 1));
  if (w !== canvas.width || h !== canvas.height) {
    canvas.width = w; canvas.height = h; dirty = true;
    if (camera) requestSelection();
  }
  if (dirty && camera && state.info) {
    dirty = false;
    draw();
    legends();
    mapDraw();
    photoMarks();
  }
  requestAnimationFrame(frame);
}

function cameraMoved() {
  state.converged = false;
  dirty = true;
  requestSelection();
  clearTimeout(cameraMoved.t);
  cameraMoved.t = setTimeout(() => history.replaceState(null, "", cameraLink()), 300);
}

// ---- picking (on the CPU, over the points drawn) ----
function pickAt(x, y, radius) {
  const w = canvas.width, h = canvas.height;
  let best = null;
  if (!selection) return null;
  for (const s of selection.nodes) {
    const n = nodes.get(keyString(s.key));
    if (!n || !n.count) continue;
    const m = viewProj(camera, n.origin, w, h);
    const p = n.positions;
    const c = settings.clip;
    for (let i = 0; i < (n.drawnCount || 0); i++) {
      const px = p[3 * i], py = p[3 * i + 1], pz = p[3 * i + 2];
      const cw = m[3] * px + m[7] * py + m[11] * pz + m[15];
      if (cw <= 0) continue;
      const sx = ((m[0] * px + m[4] * py + m[8] * pz + m[12]) / cw * 0.5 + 0.5) * w;
      const sy = (0.5 - (m[1] * px + m[5] * py + m[9] * pz + m[13]) / cw * 0.5) * h;
      const d2 = (sx - x) ** 2 + (sy - y) ** 2;
      if (d2 > radius * radius) continue;
      if (c) {
        const q = [px + n.origin[0], py + n.origin[1], pz + n.origin[2]];
        const inside = q.every((v, a) => v >= c.box[a] && v <= c.box[a + 3]);
        if (inside !== c.inside) continue;
      }
      if (!best || cw < best.depth - 1e-9 || (Math.abs(cw - best.depth) <= 1e-9 && d2 < best.d2)) {
        best = { node: n, sel: s, index: i, depth: cw, d2,
          position: [px + n.origin[0], py + n.origin[1], pz + n.origin[2]] };
      }
    }
  }
  return best;
}

// The attributes of the point drawn nearest the eye within `radius` pixels of (x, y) (CSS
// pixels from the canvas's top left), read from its node's page.
async function pick(x, y, radius = 6) {
  const k = window.devicePixelRatio || 1;
  const hit = pickAt(x * k, y * k, radius * k);
  if (!hit) return null;
  const w = decoders.reduce((a, b) => (b.busy < a.busy ? b : a));
  const m = await call(w, { type: "point", key: hit.sel.key, page: hit.sel.page, total: hit.sel.total,
    origin: hit.node.origin, index: hit.index, hidden: [...settings.hidden] });
  const p = { node: hit.sel.key.join("-"), index: hit.index, ...m.point };
  // Longitude, latitude and ellipsoidal height from the server's PROJ (/geo/), where the
  // dataset names its CRS and the server has PROJ; asked no more once it says it cannot.
  if (state.geo !== false && !SITE) {
    try {
      const r = await fetch(`/geo/${encodeURIComponent(state.dataset)}?at=${p.x},${p.y},${p.z}`);
      if (r.ok) Object.assign(p, await r.json());
      else if (r.status === 503 || r.status === 422) state.geo = false;
    } catch (_) { /* no answer: the dataset's coordinates only */ }
  }
  state.picked = p;
  const shown = { lon: (v) => `${v.toFixed(8)}°`, lat: (v) => `${v.toFixed(8)}°`,
    h: (v) => `${v.toFixed(3)} m above the WGS 84 ellipsoid` };
  document.getElementById("picked").textContent = Object.entries(p)
    .map(([k, v]) => `${k}: ${shown[k] ? shown[k](v) : Array.isArray(v) ? v.join(", ") : v}`).join("\n");
  return p;
}

// ---- interface ----
// The classes of the nodes loaded, each with its colour, name and points there, and a box
// that shows or hides it.
let classesShown = "";
function classList() {
  const counts = new Map();
  for (const n of nodes.values()) {
    for (const [c, k] of n.classes || []) counts.set(c, (counts.get(c) || 0) + k);
  }
  for (const c of settings.hidden) if (!counts.has(c)) counts.set(c, 0);
  const list = [...counts.entries()].sort((a, b) => a[0] - b[0]);
  const key = list.map(([c, k]) => `${c}:${k}:${settings.hidden.has(c)}`).join(",");
  if (key === classesShown) return;
  classesShown = key;
  const el = document.getElementById("classes");
  el.textContent = list.length ? "classes (points loaded)" : "";
  for (const [c, k] of list) {
    const info = state.info.classes[c];
    const row = document.createElement("label");
    row.className = "class";
    const box = document.createElement("input");
    box.type = "checkbox";
    box.dataset.class = c;
    box.checked = !settings.hidden.has(c);
    box.onchange = () => {
      if (box.checked) settings.hidden.delete(c); else settings.hidden.add(c);
      reload();
    };
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    swatch.style.background = `rgb(${info.colour.join(",")})`;
    row.append(box, swatch, ` ${c} ${info.name}: ${k.toLocaleString()}`);
    el.append(row);
  }
}

function status() {
  const s = document.getElementById("status");
  s.textContent = `${state.points.toLocaleString()} points in ${state.nodes} nodes` +
    (state.converged ? "" : " (loading)") +
    ` | ${state.requests} range requests, ${(state.bytes / 1e6).toFixed(1)} MB`;
}

// Measurements: the kinds of myriad_measure::measurement::Kind::ALL, in its order, with the
// points each takes (null: as many as clicked); the figures and labels are its own, from the
// WebAssembly (as `view` and `myriad annotate` give them).
const KINDS = ["point", "distance", "height", "area", "angle", "circle", "azimuth"];
const TAKES = { point: 1, distance: null, height: 2, area: null, angle: 3, circle: 3, azimuth: 2 };
const UNITS = ["data", "m", "ft", "US ft"];
const measuring = { kind: params.get("measure") || "distance", units: 0 };
let measureAsked = 0;
async function measureText() {
  const pts = state.measure.map((q) => q.position);
  const asked = ++measureAsked;
  const el = document.getElementById("measured");
  if (!pts.length) { state.measured = null; el.textContent = ""; dirty = true; return; }
  const m = (await call(selector, { type: "measure", kind: KINDS.indexOf(measuring.kind),
    points: pts.flat(), units: measuring.units })).measured;
  if (asked !== measureAsked) return;
  m.count = pts.length;
  state.measured = m;
  el.textContent = m.complete ? `${m.label} (${pts.length} points)` : `${pts.length} points: click more`;
  dirty = true;
}

// A click while measuring: the point added; a measurement of a fixed count of points that was
// complete is kept with the work and a new one starts.
function measurePoint(p) {
  const n = TAKES[measuring.kind];
  if (n && state.measure.length >= n) {
    keepMeasurement(measuring.kind, state.measure.map((q) => q.position));
    state.measure = [];
  }
  state.measure.push({ position: p });
  measureText().catch((e) => error(String(e.message || e)));
}

function ui() {
  const i = state.info;
  document.getElementById("name").textContent = `${state.dataset}: ${i.points.toLocaleString()} points`;
  styleUi();
  const edlBox = document.getElementById("edl");
  edlBox.checked = settings.edl;
  edlBox.onchange = () => { settings.edl = edlBox.checked; dirty = true; };
  const budget = document.getElementById("budget");
  budget.value = settings.budget;
  budget.onchange = () => { settings.budget = Math.max(1000, Number(budget.value) || 2000000); cameraMoved(); };
  document.getElementById("share").onclick = () => {
    const l = cameraLink();
    document.getElementById("link").value = l;
    if (navigator.clipboard) navigator.clipboard.writeText(l).catch(() => {});
  };
  const measure = document.getElementById("measure");
  measure.onclick = () => setMode(mode === "measure" ? "pick" : "measure");
  const kind = document.getElementById("measure-kind");
  for (const k of KINDS) kind.add(new Option(k, k));
  kind.value = measuring.kind;
  kind.onchange = () => { const was = mode === "measure"; setMode("pick"); measuring.kind = kind.value; if (was) setMode("measure"); };
  const units = document.getElementById("units");
  UNITS.forEach((u, i) => units.add(new Option(u, i)));
  units.onchange = () => { measuring.units = Number(units.value); measureText(); };
  const clipOn = document.getElementById("clip");
  const inputs = [...document.querySelectorAll("#clipbox input[type=number]")];
  const inside = document.getElementById("inside");
  const download = document.getElementById("download");
  const apply = () => {
    if (!clipOn.checked) { settings.clip = null; download.removeAttribute("href"); }
    else {
      const box = inputs.map((e) => Number(e.value));
      settings.clip = { box, inside: inside.checked };
      download.href = `/x/${encodeURIComponent(state.dataset)}?box=${box.join(",")}${filterQuery()}`;
    }
    document.getElementById("clipbox").classList.toggle("on", clipOn.checked);
    cameraMoved();
  };
  const vb = i.view_bounds;
  const c = settings.clip ? settings.clip.box : [0, 1, 2].map((a) => vb[a] + (vb[a + 3] - vb[a]) * 0.25)
    .concat([0, 1, 2].map((a) => vb[a] + (vb[a + 3] - vb[a]) * 0.75));
  inputs.forEach((e, k) => { e.value = +c[k].toFixed(3); e.onchange = apply; });
  clipOn.checked = !!settings.clip;
  inside.checked = settings.clip ? settings.clip.inside : true;
  clipOn.onchange = apply;
  inside.onchange = apply;
  if (settings.clip) apply();
  for (const name of Object.keys(VIEWS)) {
    const b = document.createElement("button");
    b.id = `view-${name}`;
    b.textContent = name;
    b.onclick = () => axisView(name).catch((e) => error(String(e.message || e)));
    document.getElementById("views").append(b, " ");
  }
  const parallel = document.getElementById("parallel");
  parallel.checked = !!settings.parallel;
  parallel.onchange = () => setParallel(parallel.checked);
  profileUi();
  volumeUi();
  editUi();
  contoursUi();
  pathUi();
  mapUi();
  photosUi();
  navigation();
}

// ---- colours and conditions ----
// The colour select: the schemes, then every attribute through a gradient ("ramp:NAME"); the
// ramp's gradient and range; the conditions the points shown meet.
function styleUi() {
  const i = state.info;
  const scheme = document.getElementById("scheme");
  for (const s of SCHEMES) scheme.add(new Option(s, s));
  const group = document.createElement("optgroup");
  group.label = "attribute through a gradient";
  for (const c of ["z", ...i.columns]) group.append(new Option(c, `ramp:${c}`));
  scheme.append(group);
  scheme.value = settings.ramp ? `ramp:${settings.ramp.name}` : SCHEMES[settings.scheme];
  scheme.onchange = () => {
    if (scheme.value.startsWith("ramp:")) {
      settings.ramp = { name: scheme.value.slice(5), gradient: null, range: null };
      applyStyle();
    } else {
      settings.scheme = SCHEMES.indexOf(scheme.value);
      const was = settings.ramp;
      settings.ramp = null;
      if (was) applyStyle(); else reload();
    }
  };
  const gradient = document.getElementById("gradient");
  for (const g of i.gradients) gradient.add(new Option(g, g));
  gradient.onchange = () => { if (settings.ramp) { settings.ramp.gradient = gradient.value; applyStyle(); } };
  const lo = document.getElementById("range-lo"), hi = document.getElementById("range-hi");
  lo.onchange = hi.onchange = () => {
    if (settings.ramp) { settings.ramp.range = [Number(lo.value), Number(hi.value)]; applyStyle(); }
  };
  const where = document.getElementById("where");
  where.value = settings.where;
  where.onchange = () => { settings.where = where.value.trim(); applyStyle(); };
  rampUi();
}

function rampUi() {
  const r = settings.ramp;
  document.getElementById("ramp").style.display = r ? "" : "none";
  if (!r) return;
  if (r.gradient) document.getElementById("gradient").value = r.gradient;
  if (r.range) {
    document.getElementById("range-lo").value = +r.range[0].toPrecision(8);
    document.getElementById("range-hi").value = +r.range[1].toPrecision(8);
  }
}

// The colour and conditions asked for, checked by the selection worker (which fits a ramp's
// range to the overview where none is given), then set in every decode worker; the loaded
// nodes are decoded again. A colour or condition the dataset cannot take is said in the panel
// and the view stays as it was.
let styleAsked = 0;
async function applyStyle() {
  const asked = ++styleAsked;
  const r = settings.ramp;
  const ask = { color: r ? r.name : "rgb", where: settings.where, classes: settings.classes,
    gradient: r ? (r.gradient || (r.name === "z" ? "spectral" : r.name === "above_ground" ? "turbo" : "viridis")) : null, range: r ? r.range : null };
  const problem = document.getElementById("style-problem");
  const answer = (await call(selector, { type: "style", style: ask })).style;
  if (asked !== styleAsked) return false;
  if (answer.error) { problem.textContent = answer.error; state.styleProblem = answer.error; return false; }
  problem.textContent = "";
  state.styleProblem = null;
  // The scheme's names and colours for the class list and legend; its hidden classes hidden
  // where the address names none.
  state.info.classes = answer.classes;
  editClasses();
  schemeHidden = answer.classes.filter((c) => c.hidden).map((c) => c.class).join(",");
  if (!settings.hideGiven) {
    settings.hidden = new Set(answer.classes.filter((c) => c.hidden).map((c) => c.class));
    settings.hideGiven = true;
    classesShown = "";
  }
  if (r && answer.ramp) { r.gradient = answer.ramp.gradient; r.range = answer.ramp.range; }
  state.rampStops = answer.ramp ? answer.ramp.stops : null;
  const fixed = { ...ask, gradient: r ? r.gradient : null, range: r ? r.range : null };
  await Promise.all(decoders.map((w) => call(w, { type: "style", style: fixed })));
  if (asked !== styleAsked) return false;
  state.style = fixed;
  rampUi();
  reload();
  history.replaceState(null, "", cameraLink());
  return true;
}

// The hidden classes and conditions as a download's query.
function filterQuery() {
  const q = new URLSearchParams();
  if (settings.hidden.size) q.set("hide", [...settings.hidden].join(","));
  if (settings.where) q.set("where", settings.where);
  const s = q.toString().replace(/%2C/g, ",");
  return s ? `&${s}` : "";
}

// What a click does: pick (a point's attributes), measure (a distance), annotate.
let mode = "pick";
function setMode(m) {
  // A measurement finished by leaving the measuring mode is kept with the work.
  if (mode === "measure" && m !== "measure" && state.measured && state.measured.complete &&
      state.measured.count === state.measure.length) {
    keepMeasurement(measuring.kind, state.measure.map((q) => q.position));
  }
  if (m === "measure" || mode === "measure") { state.measure = []; measureText(); }
  mode = m;
  for (const id of ["measure", "annotate", "section", "volume"]) {
    const b = document.getElementById(id);
    if (b) b.classList.toggle("on", mode === id);
  }
  if (state.volume) state.volume.drawing = mode === "volume";
  const e = document.getElementById("edit-start");
  if (e) e.classList.toggle("on", mode === "edit");
}

function navigation() {
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => {
    drag = { x: e.clientX, y: e.clientY, button: e.button, shift: e.shiftKey, moved: false };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (Math.abs(dx) + Math.abs(dy) < 2 && !drag.moved) return;
    drag.moved = true;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.button === 2 || drag.shift) pan(dx, dy); else orbit(dx, dy);
  });
  canvas.addEventListener("pointerup", async (e) => {
    const d = drag;
    drag = null;
    if (!d || d.moved || d.button !== 0) return;
    const r = canvas.getBoundingClientRect();
    try {
      const p = await pick(e.clientX - r.left, e.clientY - r.top);
      if (p && mode === "measure") measurePoint([p.x, p.y, p.z]);
      if (p && mode === "annotate") { setMode("pick"); addAnnotation(p); }
      if (p && mode === "section") sectionPoint([p.x, p.y, p.z]);
      if (p && mode === "volume") volumePoint([p.x, p.y, p.z]);
      if (p && mode === "edit") editPoint([p.x, p.y, p.z]);
    } catch (err) {
      error(String(err.message || err));
    }
  });
  canvas.addEventListener("dblclick", (e) => {
    const r = canvas.getBoundingClientRect();
    const k = window.devicePixelRatio || 1;
    const hit = pickAt((e.clientX - r.left) * k, (e.clientY - r.top) * k, 8 * k);
    if (!hit) return;
    const move = sub(hit.position, camera.target);
    camera.target = hit.position;
    camera.position = add(camera.position, move);
    cameraMoved();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const k = Math.exp(Math.sign(e.deltaY) * 0.15);
    camera.position = add(camera.target, mul(sub(camera.position, camera.target), k));
    cameraMoved();
  }, { passive: false });
}

// ---- the six axis views and the parallel (orthographic) view (as myriad-viewer's nav.rs) ----
const PARALLEL_FOV = 1;
const VIEWS = {
  top: [[0, 0, 1], [0, 1, 0]], front: [[0, -1, 0], [0, 0, 1]], right: [[1, 0, 0], [0, 0, 1]],
  bottom: [[0, 0, -1], [0, 1, 0]], back: [[0, 1, 0], [0, 0, 1]], left: [[-1, 0, 0], [0, 0, 1]],
};
// Along an axis at the data's centre, at the distance that frames it for this field of view.
async function axisView(name) {
  const [dir, up] = VIEWS[name];
  const f = (await call(selector, { type: "camera", width: canvas.width, height: canvas.height, fov: camera.fov })).camera;
  const d = Math.sqrt(dot(sub(f.position, f.target), sub(f.position, f.target)));
  camera.target = [...f.target];
  camera.position = add(f.target, mul(dir, d));
  camera.up = up;
  cameraMoved();
}
// The field of view changed keeping the size of what is seen at the target: the eye moves
// along the line of sight.
function refocus(fov) {
  const v = sub(camera.position, camera.target);
  const d = Math.max(Math.sqrt(dot(v, v)), 1e-9);
  const half = d * Math.tan((camera.fov * Math.PI) / 360);
  const far = half / Math.tan((fov * Math.PI) / 360);
  camera.position = add(camera.target, mul(v, far / d));
  camera.fov = fov;
  cameraMoved();
}
function setParallel(on) {
  if (on && !settings.parallel) { settings.parallel = camera.fov; refocus(PARALLEL_FOV); }
  else if (!on && settings.parallel) { const fov = settings.parallel; settings.parallel = null; refocus(fov); }
  document.getElementById("parallel").checked = !!settings.parallel;
}

function orbit(dx, dy) {
  const v = sub(camera.position, camera.target);
  const up = norm(camera.up);
  const yaw = -dx * 0.005, pitch = -dy * 0.005;
  const rot = (p, axis, a) => {
    const c = Math.cos(a), s = Math.sin(a);
    return add(add(mul(p, c), mul(cross(axis, p), s)), mul(axis, dot(axis, p) * (1 - c)));
  };
  let w = rot(v, up, yaw);
  const right = norm(cross(w, up));
  const t = rot(w, right, pitch);
  // Never over the pole.
  if (Math.abs(dot(norm(t), up)) < 0.995) w = t;
  camera.position = add(camera.target, w);
  cameraMoved();
}

function pan(dx, dy) {
  const [r, u] = basis(camera);
  const d = Math.sqrt(dot(sub(camera.position, camera.target), sub(camera.position, camera.target)));
  const k = (2 * d * Math.tan((camera.fov * Math.PI) / 360)) / canvas.clientHeight;
  const move = add(mul(r, -dx * k), mul(u, dy * k));
  camera.position = add(camera.position, move);
  camera.target = add(camera.target, move);
  cameraMoved();
}

window.myriad = {
  state,
  pick,
  link: () => cameraLink(),
  camera: () => camera && { ...camera },
  setCamera(c) { Object.assign(camera, c); cameraMoved(); },
  selection: () => selection && selection.nodes.map((n) => ({ key: n.key, points: n.points })),
  renderer: () => renderer && renderer.kind,
  setMode,
  axisView,
  setParallel,
  cut: (line, width) => cutProfile(line, width),
  // The bounds of the points loaded (as decoded: what is shown of them).
  loadedBounds() {
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (const n of nodes.values()) {
      if (!n.count) continue;
      for (let i = 0; i < n.positions.length; i++) {
        const v = n.positions[i] + n.origin[i % 3];
        lo[i % 3] = Math.min(lo[i % 3], v); hi[i % 3] = Math.max(hi[i % 3], v);
      }
    }
    return [lo, hi];
  },
  volume: (polygon, base, cell) => measureVolume(polygon, base === undefined ? null : base, cell),
  // Edits (`serve --edit`): a polygon in plan given a class (or "remove"), undo, redo.
  edit: (polygon, to) => applyEdit(polygon, to),
  undoEdit: () => changeEdits({ undo: true }),
  redoEdit: () => changeEdits({ redo: true }),
  // The terrain's contours every `interval`: how many lines.
  contours: (interval) => makeContours(interval),
};

// WebGPU where the browser has it on a hardware adapter (or `#renderer=webgpu` asks for it),
// else WebGL2 (`#renderer=webgl2`: always).
async function start() {
  if (settings.renderer !== "webgl2" && typeof makeWebGPU === "function") {
    try {
      // A WebGPU set-up that never answers counts as none.
      const late = new Promise((_, fail) => setTimeout(() => fail(new Error("no answer in 10 s")), 10000));
      renderer = await Promise.race([makeWebGPU(canvas, settings.renderer === "webgpu"), late]);
    } catch (e) {
      renderer = null;
      if (settings.renderer === "webgpu") error(`WebGPU: ${e.message || e}`);
      // A canvas keeps the kind of context it was first asked for: a fresh one for WebGL2.
      const fresh = canvas.cloneNode();
      canvas.replaceWith(fresh);
      canvas = fresh;
    }
  }
  if (!renderer) renderer = makeWebGL2(canvas);
  if (!renderer) throw new Error("this browser has neither WebGPU nor WebGL2");
  state.renderer = renderer.kind;
  requestAnimationFrame(frame);
  await open();
}
start().catch((e) => error(String(e.message || e)));
