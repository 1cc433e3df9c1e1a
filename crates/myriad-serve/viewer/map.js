// A map beside the view: the dataset's footprint, the camera and its view cone on a web map of
// tiles from the address template the user gives (`#map=` in the page's address, or the panel's
// box; `{z}/{x}/{y}` as OpenStreetMap-style servers take, `{-y}` for TMS, WMTS's
// `{TileMatrix}/{TileCol}/{TileRow}`). None is built in. Where the dataset lies comes from the
// server's PROJ (`/geo/NAME?footprint`: an affine from its plan to Web Mercator, as
// myriad_measure::map fits it); without a coordinate system, or on a static site, the map says
// why it is off. A click on the map moves the camera there; north is up, a scale bar and the
// cursor's latitude and longitude are shown.
"use strict";

const map = { template: null, georef: null, view: null, images: new Map(), requested: [], off: null,
  cursor: null, drawn: 0 };
state.map = map;

// Web Mercator's unit square (x east from 180 W, y south from the top) and back.
function unitOf(lon, lat) {
  const r = Math.max(-85.0511287798066, Math.min(85.0511287798066, lat)) * Math.PI / 180;
  return [(lon + 180) / 360, (1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2];
}
function lonLatOf(m) {
  return [m[0] * 360 - 180, Math.atan(Math.sinh(Math.PI * (1 - 2 * m[1]))) * 180 / Math.PI];
}
function mapUnit(x, y) {
  const g = map.georef, a = g.a, dx = x - g.origin[0], dy = y - g.origin[1];
  return [a[0] + a[1] * dx + a[2] * dy, a[3] + a[4] * dx + a[5] * dy];
}
function mapPlan(m) {
  const g = map.georef, a = g.a, det = a[1] * a[5] - a[2] * a[4];
  const u = m[0] - a[0], v = m[1] - a[3];
  return [g.origin[0] + (a[5] * u - a[2] * v) / det, g.origin[1] + (a[1] * v - a[4] * u) / det];
}
function tileUrl(t, z, x, y) {
  const s = (v) => String(v);
  return t.replaceAll("{z}", s(z)).replaceAll("{TileMatrix}", s(z)).replaceAll("{x}", s(x))
    .replaceAll("{TileCol}", s(x)).replaceAll("{-y}", s((1 << z) - 1 - y)).replaceAll("{y}", s(y))
    .replaceAll("{TileRow}", s(y));
}

function mapOff(why) {
  map.off = why;
  const el = document.getElementById("map");
  el.querySelector(".off").textContent = why ? `map off: ${why}` : "";
}

// The footprint fitted in the map (the deepest zoom at which it fills at most 80 % of it).
function mapFit() {
  const b = map.georef.bounds;
  const corners = [[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]].map((p) => mapUnit(p[0], p[1]));
  const lo = [Math.min(...corners.map((c) => c[0])), Math.min(...corners.map((c) => c[1]))];
  const hi = [Math.max(...corners.map((c) => c[0])), Math.max(...corners.map((c) => c[1]))];
  const span = Math.max(Math.max((hi[0] - lo[0]) / 256, (hi[1] - lo[1]) / 256), 1e-12);
  const zoom = Math.max(0, Math.min(22, Math.floor(Math.log2(0.8 / (span * 256)))));
  map.view = { centre: [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2], zoom };
  map.footprint = corners;
}

function mapPx(m) {
  const s = 256 * Math.pow(2, map.view.zoom);
  return [128 + (m[0] - map.view.centre[0]) * s, 128 + (m[1] - map.view.centre[1]) * s];
}
function mapFromPx(p) {
  const s = 256 * Math.pow(2, map.view.zoom);
  return [map.view.centre[0] + (p[0] - 128) / s, map.view.centre[1] + (p[1] - 128) / s];
}

async function mapStart(template) {
  map.template = template || null;
  const el = document.getElementById("map");
  el.style.display = template ? "block" : "none";
  if (!template) return;
  if (!/^https?:\/\//.test(template) || !/\{(z|TileMatrix)\}/.test(template) ||
      !/\{(x|TileCol)\}/.test(template) || !/\{(y|-y|TileRow)\}/.test(template)) {
    mapOff("a tile address is http(s)://...{z}/{x}/{y}...");
    return;
  }
  if (SITE) { mapOff("a static site has no PROJ to place the dataset: use `myriad serve`"); return; }
  if (!map.georef) {
    const r = await fetch(`/geo/${encodeURIComponent(state.dataset)}?footprint`);
    if (!r.ok) {
      mapOff(r.status === 422 ? `${(await r.text()).trim()}` : r.status === 503
        ? "the server has no PROJ (apt-get install libproj25)" : `HTTP ${r.status}`);
      return;
    }
    map.georef = await r.json();
  }
  mapOff(null);
  mapFit();
  map.drawn = 0;
  mapDraw();
}

function mapDraw() {
  if (!map.template || !map.georef || map.off || !map.view || !camera) return;
  const c = document.querySelector("#map canvas"), g = c.getContext("2d");
  g.fillStyle = "#333";
  g.fillRect(0, 0, 256, 256);
  const z = map.view.zoom, n = 1 << z;
  const lo = mapFromPx([0, 0]), hi = mapFromPx([256, 256]);
  const clamp = (v) => Math.max(0, Math.min(n - 1, Math.floor(v * n)));
  for (let y = clamp(lo[1]); y <= clamp(hi[1]); y++) {
    for (let x = clamp(lo[0]); x <= clamp(hi[0]); x++) {
      const url = tileUrl(map.template, z, x, y);
      let img = map.images.get(url);
      if (!img) {
        img = new Image();
        img.crossOrigin = "anonymous";
        // The tile server learns nothing of the page (its address names the dataset).
        img.referrerPolicy = "no-referrer";
        img.onload = () => { map.drawn = 0; mapDraw(); };
        img.src = url;
        map.images.set(url, img);
        map.requested.push({ z, x, y, url });
      }
      if (img.complete && img.naturalWidth) {
        const p = mapPx([x / n, y / n]);
        g.drawImage(img, Math.round(p[0]), Math.round(p[1]), 256, 256);
      }
    }
  }
  // The footprint, the camera and its view cone.
  g.strokeStyle = "rgb(255, 210, 0)";
  g.lineWidth = 2;
  g.beginPath();
  map.footprint.forEach((m, i) => { const p = mapPx(m); if (i) g.lineTo(p[0], p[1]); else g.moveTo(p[0], p[1]); });
  g.closePath();
  g.stroke();
  const eye = mapPx(mapUnit(camera.position[0], camera.position[1]));
  const at = mapPx(mapUnit(camera.target[0], camera.target[1]));
  const heading = Math.atan2(at[1] - eye[1], at[0] - eye[0]);
  const half = (camera.fov / 2) * Math.PI / 180 * (canvas.clientWidth / Math.max(1, canvas.clientHeight));
  const reach = Math.max(20, Math.hypot(at[0] - eye[0], at[1] - eye[1]));
  g.fillStyle = "rgba(80, 200, 255, 0.35)";
  g.beginPath();
  g.moveTo(eye[0], eye[1]);
  g.lineTo(eye[0] + reach * Math.cos(heading - half), eye[1] + reach * Math.sin(heading - half));
  g.lineTo(eye[0] + reach * Math.cos(heading + half), eye[1] + reach * Math.sin(heading + half));
  g.closePath();
  g.fill();
  g.fillStyle = "rgb(80, 200, 255)";
  g.beginPath();
  g.arc(eye[0], eye[1], 4, 0, 2 * Math.PI);
  g.fill();
  // A scale bar: a round length of about a third of the map.
  const [, lat] = lonLatOf(map.view.centre);
  const perPx = 2 * Math.PI * 6378137 * Math.cos(lat * Math.PI / 180) / (256 * n);
  const want = perPx * 80, p10 = Math.pow(10, Math.floor(Math.log10(want)));
  const len = [1, 2, 5, 10].map((m) => m * p10).find((s) => s >= want * 0.999);
  document.querySelector("#map .scale").innerHTML =
    `<span style="display:inline-block;width:${Math.round(len / perPx)}px;border-bottom:3px solid #141414"></span> ` +
    (len >= 1000 ? `${len / 1000} km` : `${len} m`);
  map.drawn += 1;
}

function mapUi() {
  const input = document.getElementById("map-url");
  const asked = params.get("map") || localStorage.getItem("myriad.map") || "";
  input.value = asked;
  // Only what is typed here is kept for later pages (not a link's `#map=`).
  input.onchange = () => {
    const t = input.value.trim();
    if (t) localStorage.setItem("myriad.map", t); else localStorage.removeItem("myriad.map");
    mapStart(t).catch((e) => mapOff(String(e.message || e)));
  };
  const c = document.querySelector("#map canvas");
  c.addEventListener("mousemove", (e) => {
    if (!map.view) return;
    const r = c.getBoundingClientRect();
    const [lon, lat] = lonLatOf(mapFromPx([e.clientX - r.left, e.clientY - r.top]));
    map.cursor = [lon, lat];
    document.querySelector("#map .cursor").textContent = `${lat.toFixed(5)}, ${lon.toFixed(5)}`;
  });
  // A click moves the camera there, its height and its offset from the target kept.
  c.addEventListener("click", (e) => {
    if (!map.view || !map.georef) return;
    const r = c.getBoundingClientRect();
    const [x, y] = mapPlan(mapFromPx([e.clientX - r.left, e.clientY - r.top]));
    const d = [x - camera.target[0], y - camera.target[1]];
    camera.target = [x, y, camera.target[2]];
    camera.position = [camera.position[0] + d[0], camera.position[1] + d[1], camera.position[2]];
    cameraMoved();
  });
  if (asked) mapStart(asked).catch((e) => mapOff(String(e.message || e)));
}
