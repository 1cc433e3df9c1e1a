// The web viewer's workers: one selects (myriad-lod's selection in WebAssembly, reading the
// hierarchy pages it needs by synchronous range requests, which workers may make), the others
// fetch node pages by range requests and decode them (myriad-format's decoder, same module).
"use strict";

let wasm = null;
// The dataset's files: its own, then those it links (their pages' offsets are
// file * 2^40 + the offset in the file, myriad-format's linked.rs).
let urls = [];
const SLOT = 2 ** 40;
let failure = "";
const stats = { requests: 0, bytes: 0 };

function memory(ptr, len) {
  return new Uint8Array(wasm.exports.memory.buffer, ptr, len);
}

// One synchronous range request of `url` into memory at `dst`: 0 when it came whole, else 1
// with the reason in `failure`.
function readRange(url, offset, len, dst) {
  const x = new XMLHttpRequest();
  x.open("GET", url, false);
  x.responseType = "arraybuffer";
  x.setRequestHeader("Range", `bytes=${offset}-${offset + len - 1}`);
  try {
    x.send();
  } catch (e) {
    failure = `${url}: ${e}`;
    return 1;
  }
  stats.requests += 1;
  if (x.status !== 206 || !x.response || x.response.byteLength !== len) {
    failure = `${url}: asked for ${len} bytes at ${offset}, got HTTP ${x.status}` +
      (x.status === 200 ? " (the server ignores Range)" : "");
    return 1;
  }
  stats.bytes += len;
  memory(dst, len).set(new Uint8Array(x.response));
  return 0;
}

// The import the module reads the dataset through: file `file` (0: the dataset's own).
function myr_read(file, offset, len, dst) {
  const url = urls[file];
  if (url === undefined) {
    failure = `file ${file} of the dataset is not known`;
    return 1;
  }
  return readRange(url, offset, len, dst);
}

// A cloud format's dataset (COPC, EPT, Potree 2.0) is read by the module itself: its files by
// their URLs, each range by one synchronous request.
let foreign = false;

function urlAt(ptr, len) {
  return new TextDecoder().decode(memory(ptr, len).slice());
}

// The length of the resource at a URL (HEAD), or -1.
function myr_size(ptr, len) {
  const url = urlAt(ptr, len);
  const x = new XMLHttpRequest();
  x.open("HEAD", url, false);
  try {
    x.send();
  } catch (e) {
    failure = `${url}: no answer this page may read (the server is down, or sends no CORS headers)`;
    return -1;
  }
  stats.requests += 1;
  const n = Number(x.getResponseHeader("content-length"));
  if (x.status !== 200 || !(n >= 0)) {
    failure = `${url}: HTTP ${x.status}`;
    return -1;
  }
  return n;
}

// One range of the resource at a URL into memory at `dst`: 0 when it came whole.
function myr_get(ptr, len, offset, n, dst) {
  return readRange(urlAt(ptr, len), offset, n, dst);
}

// The module's imports: the reads above, and stubs that say so for the browser glue some
// crates link in but the viewer never calls (chrono's clock, through wasm-bindgen).
function imports(module) {
  const all = { env: { myr_read, myr_size, myr_get } };
  for (const i of WebAssembly.Module.imports(module)) {
    if (i.kind !== "function" || (all[i.module] && all[i.module][i.name])) continue;
    all[i.module] = all[i.module] || {};
    all[i.module][i.name] = () => {
      throw new Error(`${i.module}.${i.name}: not available in the viewer`);
    };
  }
  return all;
}

function text(len) {
  return new TextDecoder().decode(memory(wasm.exports.myr_out(), len).slice());
}

function json(len) {
  const v = JSON.parse(text(len));
  if (v && v.error && failure) v.error += ` (${failure})`;
  failure = "";
  return v;
}

// Copies bytes into the module's memory; the caller frees them.
function put(bytes) {
  const p = wasm.exports.myr_alloc(bytes.byteLength);
  memory(p, bytes.byteLength).set(new Uint8Array(bytes.buffer || bytes, bytes.byteOffset || 0, bytes.byteLength));
  return p;
}

function withArgs(values, f) {
  const a = new Float64Array(values);
  const p = put(new Uint8Array(a.buffer));
  try {
    return f(p);
  } finally {
    wasm.exports.myr_free(p, a.byteLength);
  }
}

function withName(name, f) {
  const b = new TextEncoder().encode(name);
  const p = put(b);
  try {
    return f(p, b.byteLength);
  } finally {
    wasm.exports.myr_free(p, b.byteLength);
  }
}

async function fetchPage(page) {
  const file = Math.floor(page[0] / SLOT);
  const [offset, length] = [page[0] - file * SLOT, page[1]];
  const url = urls[file];
  if (url === undefined) throw new Error(`page in file ${file} of the dataset, which links ${urls.length - 1}`);
  const r = await fetch(url, { headers: { Range: `bytes=${offset}-${offset + length - 1}` } });
  stats.requests += 1;
  if (r.status !== 206) throw new Error(`${url}: HTTP ${r.status} for a range request`);
  const b = new Uint8Array(await r.arrayBuffer());
  stats.bytes += b.byteLength;
  return b;
}

// The node, its origin, then the hidden classes as 8 words of 32 flags.
function nodeArgs(m) {
  const words = [0, 0, 0, 0, 0, 0, 0, 0];
  for (const c of m.hidden || []) words[c >> 5] += 2 ** (c & 31);
  return [m.key[0], m.key[1], m.key[2], m.key[3], m.page[0], m.page[1], m.page[2], m.total,
    m.origin[0], m.origin[1], m.origin[2], ...words, m.finest || 0];
}

// A node of a cloud format: read and decoded by the module (the range requests synchronous).
function decodeRead(m) {
  const n = withArgs(nodeArgs(m), (a) => wasm.exports.myr_decode_read(a, m.scheme, m.z[0], m.z[1]));
  return decoded(memory(wasm.exports.myr_out(), n).slice());
}

function decoded(out) {
  const count = new DataView(out.buffer).getUint32(0, true);
  if (count === 0xffffffff) {
    const m = new TextDecoder().decode(out.subarray(4)) + (failure ? ` (${failure})` : "");
    failure = "";
    throw new Error(m);
  }
  const positions = new Float32Array(out.buffer.slice(4, 4 + count * 12));
  const colours = new Uint8Array(out.buffer.slice(4 + count * 12, 4 + count * 16));
  // Then the node's points per class (hidden ones included).
  const view = new DataView(out.buffer, 4 + count * 16);
  const classes = [];
  for (let i = 0; i < view.getUint32(0, true); i++) {
    classes.push([view.getUint32(4 + 8 * i, true), view.getUint32(8 + 8 * i, true)]);
  }
  return { positions, colours, classes };
}

async function decode(m) {
  if (foreign) return decodeRead(m);
  const page = await fetchPage(m.page);
  const p = put(page);
  try {
    const n = withArgs(nodeArgs(m), (a) =>
      wasm.exports.myr_decode(p, page.byteLength, a, m.scheme, m.z[0], m.z[1]));
    return decoded(memory(wasm.exports.myr_out(), n).slice());
  } finally {
    wasm.exports.myr_free(p, page.byteLength);
  }
}

async function point(m) {
  const page = foreign ? new Uint8Array(0) : await fetchPage(m.page);
  const p = put(page);
  try {
    return json(withArgs(nodeArgs(m), (a) => wasm.exports.myr_point(p, page.byteLength, a, m.index)));
  } finally {
    wasm.exports.myr_free(p, page.byteLength);
  }
}

onmessage = async (e) => {
  const m = e.data;
  try {
    if (m.type === "init") {
      const url = m.url;
      urls = [url];
      wasm = await WebAssembly.instantiate(m.module, imports(m.module));
      withName(new URL(url, self.location.href).href, (p, n) => wasm.exports.myr_base(p, n));
      const open = m.role === "select" ? wasm.exports.myr_open : wasm.exports.myr_open_pages;
      const info = withName(m.name, (p, n) => json(open(m.length, p, n)));
      const base = new URL(url, self.location.href);
      urls = [url, ...(info.files || []).map((f) => new URL(f, base).href)];
      foreign = !!info.foreign;
      postMessage({ id: m.id, info, stats });
    } else if (m.type === "camera") {
      postMessage({ id: m.id, camera: json(wasm.exports.myr_camera(m.width, m.height, m.fov)) });
    } else if (m.type === "select") {
      const drawn = new Uint32Array(m.drawn);
      const d = put(new Uint8Array(drawn.buffer));
      let answer;
      try {
        answer = withArgs(m.args, (a) => json(wasm.exports.myr_select(a, m.args.length, d, drawn.length / 4)));
      } finally {
        wasm.exports.myr_free(d, drawn.byteLength);
      }
      postMessage({ id: m.id, selection: answer, stats });
    } else if (m.type === "decode") {
      const d = await decode(m);
      postMessage({ id: m.id, positions: d.positions, colours: d.colours, classes: d.classes, stats },
        [d.positions.buffer, d.colours.buffer]);
    } else if (m.type === "measure") {
      const n = m.points.length;
      postMessage({ id: m.id, measured: withArgs(m.points, (a) => json(wasm.exports.myr_measure(m.kind, a, n, m.units))), stats });
    } else if (m.type === "profile") {
      const words = [0, 0, 0, 0, 0, 0, 0, 0];
      for (const c of m.hidden || []) words[c >> 5] += 2 ** (c & 31);
      const n = withArgs([...m.line, ...words], (a) =>
        wasm.exports.myr_profile(a, m.line.length, m.width, m.picture, m.scheme));
      const out = memory(wasm.exports.myr_out(), n).slice();
      const len = new DataView(out.buffer).getUint32(0, true);
      const summary = JSON.parse(new TextDecoder().decode(out.subarray(4, 4 + len)));
      if (summary.error) throw new Error(summary.error);
      const rgba = out.slice(4 + len, 4 + len + summary.rgba);
      const csv = new TextDecoder().decode(out.subarray(4 + len + summary.rgba));
      postMessage({ id: m.id, summary, rgba, csv, stats }, [rgba.buffer]);
    } else if (m.type === "style") {
      postMessage({ id: m.id, style: withName(JSON.stringify(m.style), (p, n) => json(wasm.exports.myr_style(p, n))), stats });
    } else if (m.type === "volume") {
      const words = [0, 0, 0, 0, 0, 0, 0, 0];
      for (const c of m.hidden || []) words[c >> 5] += 2 ** (c & 31);
      const v = withArgs([...m.polygon, ...words], (a) =>
        json(wasm.exports.myr_volume(a, m.polygon.length, m.base, m.z, m.cell)));
      if (v.error) throw new Error(v.error);
      postMessage({ id: m.id, volume: v, stats });
    } else if (m.type === "edits") {
      const n = withName(m.text, (p, len) =>
        withName(m.surfaces, (q, k) => wasm.exports.myr_edits(p, len, q, k)));
      postMessage({ id: m.id, edits: json(n), stats });
    } else if (m.type === "contours") {
      postMessage({ id: m.id, contours: json(wasm.exports.myr_contours(m.interval, m.cells)), stats });
    } else if (m.type === "path") {
      postMessage({ id: m.id, path: withName(JSON.stringify(m.path), (p, n) => json(wasm.exports.myr_path(p, n, m.fps))), stats });
    } else if (m.type === "between") {
      postMessage({ id: m.id, text: json(wasm.exports.myr_between(...m.a, ...m.b)), stats });
    } else if (m.type === "point") {
      postMessage({ id: m.id, point: await point(m), stats });
    }
  } catch (err) {
    postMessage({ id: m.id, error: String(err && err.message || err), stats });
  }
};
