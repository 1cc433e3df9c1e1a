//! The boundary with the viewer's JavaScript: exported functions over linear memory. Answers
//! (JSON, or binary for decoded nodes) are left in one buffer that [`myr_out`] points at until
//! the next call; the JavaScript copies them out. Range reads go out through one import,
//! `env.myr_read`, which the selection worker answers with a synchronous request.

use crate::{Ask, Hidden, Viewer, decode, entry, keep_shown, point_json, shown};
use myriad_core::NodeKey;
use myriad_core::colour::ColorBy;
use myriad_format::{ByteSource, Dataset, PageRef};
use myriad_lod::{Camera, Clip, SelectOptions};
use serde_json::{Value, json};
use std::cell::RefCell;
use std::path::Path;
use std::sync::Arc;

#[link(wasm_import_module = "env")]
unsafe extern "C" {
    /// Copies `len` bytes at `offset` of file `file` (0: the dataset's own, `i`: the `i`-th
    /// it links) into memory at `dst`; 0 when it did.
    fn myr_read(file: u32, offset: f64, len: u32, dst: *mut u8) -> i32;
    /// The length of the resource at the URL (`url_len` bytes at `url`), by a HEAD request; -1
    /// when there was no answer (the reason kept by the JavaScript).
    fn myr_size(url: *const u8, url_len: u32) -> f64;
    /// Copies `len` bytes at `offset` of the resource at the URL into memory at `dst`, by one
    /// range request; 0 when it did.
    fn myr_get(url: *const u8, url_len: u32, offset: f64, len: u32, dst: *mut u8) -> i32;
}

/// A resource of a cloud format's dataset (a COPC file, an EPT node or page, Potree's
/// `octree.bin`) by its URL: its length from a HEAD request, its first `head` bytes read when
/// opened and kept (a COPC header and VLRs, a JSON page read whole), any other range by one
/// request.
struct UrlBytes {
    url: String,
    len: u64,
    head: Vec<u8>,
}

impl UrlBytes {
    fn open(url: &str, head: usize) -> std::io::Result<Arc<dyn ByteSource>> {
        // SAFETY: the import reads `url.len()` bytes at `url.as_ptr()`.
        let len = unsafe { myr_size(url.as_ptr(), url.len() as u32) };
        if !(len >= 0.0) {
            return Err(std::io::Error::other(format!(
                "{url}: no answer to a HEAD request"
            )));
        }
        let mut u = UrlBytes {
            url: url.to_string(),
            len: len as u64,
            head: Vec::new(),
        };
        let n = (head as u64).min(u.len) as usize;
        u.head = u.get(0, n)?;
        Ok(Arc::new(u))
    }

    fn get(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        let mut b = vec![0u8; len];
        if len == 0 {
            return Ok(b);
        }
        // SAFETY: `b` holds `len` writable bytes; the import writes at most that many.
        let r = unsafe {
            myr_get(
                self.url.as_ptr(),
                self.url.len() as u32,
                offset as f64,
                len as u32,
                b.as_mut_ptr(),
            )
        };
        match r {
            0 => Ok(b),
            _ => Err(std::io::Error::other(format!(
                "{}: range request for {len} bytes at {offset} failed",
                self.url
            ))),
        }
    }
}

impl ByteSource for UrlBytes {
    fn len(&self) -> u64 {
        self.len
    }
    fn read_at(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        let end = offset.saturating_add(len as u64);
        if end <= self.head.len() as u64 {
            return Ok(self.head[offset as usize..end as usize].to_vec());
        }
        self.get(offset, len)
    }
}

/// A file of the dataset over the viewer's range requests.
struct Remote {
    file: u32,
    len: u64,
}

impl Remote {
    /// The dataset's own file, of `len` bytes.
    fn dataset(len: f64) -> Arc<Remote> {
        Arc::new(Remote {
            file: 0,
            len: len as u64,
        })
    }
}

/// Opens a dataset whose linked files are read through the same import; a cloud format's
/// (named by the address [`myr_base`] gave) by its URL, its files read through [`UrlBytes`].
fn open(len: f64, name: &str) -> myriad_core::Result<Dataset> {
    let base = BASE.with(|b| b.borrow().clone());
    // The kind by the address's path (a query, such as a version, left out).
    let url = base.split(['?', '#']).next().unwrap_or("").to_string();
    if myriad_format::foreign::kind_of(Path::new(&url)).is_some() {
        myriad_format::foreign::set_url_opener(UrlBytes::open);
        return Dataset::open_url(Path::new(&url));
    }
    let opener: myriad_format::linked::Opener = Arc::new(|i, f| {
        Ok(Arc::new(Remote {
            file: i as u32 + 1,
            len: f.length,
        }))
    });
    Dataset::from_source_linked(
        Remote::dataset(len),
        Path::new(name),
        opener,
        Arc::new(|p: &str| p.to_string()),
    )
}

impl ByteSource for Remote {
    fn len(&self) -> u64 {
        self.len
    }
    fn read_at(&self, offset: u64, len: usize) -> std::io::Result<Vec<u8>> {
        let mut b = vec![0u8; len];
        // SAFETY: `b` holds `len` writable bytes; the import writes at most that many.
        match unsafe { myr_read(self.file, offset as f64, len as u32, b.as_mut_ptr()) } {
            0 => Ok(b),
            _ => Err(std::io::Error::other(format!(
                "range request for {len} bytes at {offset} failed"
            ))),
        }
    }
}

thread_local! {
    /// The dataset's absolute address ([`myr_base`]).
    static BASE: RefCell<String> = const { RefCell::new(String::new()) };
    static VIEWER: RefCell<Option<Viewer>> = const { RefCell::new(None) };
    static DATASET: RefCell<Option<Dataset>> = const { RefCell::new(None) };
    static OUT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
    static STYLE: RefCell<Style> = const { RefCell::new(Style { ramp: None, wheres: String::new() }) };
}

/// What [`myr_style`] set: a ramp (else the scheme each call names) and the `where` conditions.
struct Style {
    ramp: Option<ColorBy>,
    wheres: String,
}

/// The colour a call draws in: the style's ramp, else scheme `scheme` (an index of [`SCHEMES`]).
fn colour(scheme: u32) -> ColorBy {
    STYLE.with(|s| s.borrow().ramp).unwrap_or_else(|| {
        SCHEMES
            .get(scheme as usize)
            .and_then(|s| ColorBy::parse(s))
            .unwrap_or(ColorBy::Rgb)
    })
}

/// The points a call keeps: the classes not `hidden` that meet the style's conditions.
fn shown_by(ds: &Dataset, hidden: &Hidden) -> Result<myriad_measure::Bound, String> {
    STYLE.with(|s| shown(ds, hidden, &s.borrow().wheres))
}

/// Sets what the calls after it show (JSON at `p`: `{"color": NAME, "gradient": G or null,
/// "range": [LOW, HIGH] or null, "where": CONDITIONS, "classes": SCHEME or null}`, as
/// [`crate::style`], [`crate::shown`] and `myriad_measure::scheme` read them). The answer: the
/// colour chosen (a ramp's gradient and range, fitted where none was given) and every class's
/// name, colour and visibility, or an error, the style before it kept.
///
/// # Safety
/// `p..p + n` is memory the JavaScript wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_style(p: *const u8, n: u32) -> u32 {
    let asked: Value = match serde_json::from_str(&name(p, n)) {
        Ok(v) => v,
        Err(e) => return error(format!("style: {e}")),
    };
    let text = |k: &str| asked[k].as_str().map(str::to_string);
    let colour_name = text("color").unwrap_or_else(|| "rgb".into());
    let gradient = text("gradient");
    let range = asked["range"]
        .as_array()
        .and_then(|r| Some([r.first()?.as_f64()?, r.get(1)?.as_f64()?]));
    let wheres = text("where").unwrap_or_default();
    // The class scheme (the `"classes"` of the dataset's saved work; none: the default).
    let scheme = match &asked["classes"] {
        Value::Null => myriad_core::classes::Scheme::default(),
        c => match myriad_measure::scheme::from_json(c) {
            Ok(s) => s,
            Err(e) => return error(format!("class scheme: {e}")),
        },
    };
    let r = with_dataset(|ds| -> Result<(Option<ColorBy>, Value), String> {
        shown(ds, &[false; 256], &wheres)?;
        let (c, v) = crate::style(ds, &colour_name, gradient.as_deref(), range)?;
        Ok((matches!(c, ColorBy::Ramp(_)).then_some(c), v))
    });
    match r {
        Some(Ok((ramp, mut v))) => {
            STYLE.with(|s| {
                *s.borrow_mut() = Style {
                    ramp,
                    wheres: wheres.clone(),
                }
            });
            v["where"] = wheres.into();
            v["classes"] = myriad_measure::scheme::table(&scheme);
            myriad_core::classes::set(scheme);
            answer_json(v)
        }
        Some(Err(e)) => error(e),
        None => error("no dataset open"),
    }
}

fn answer(bytes: Vec<u8>) -> u32 {
    let n = bytes.len() as u32;
    OUT.with(|o| *o.borrow_mut() = bytes);
    n
}

fn answer_json(v: Value) -> u32 {
    answer(v.to_string().into_bytes())
}

fn error(m: impl std::fmt::Display) -> u32 {
    answer_json(json!({ "error": m.to_string() }))
}

/// The last answer (its length was the call's result).
#[unsafe(no_mangle)]
pub extern "C" fn myr_out() -> *const u8 {
    OUT.with(|o| o.borrow().as_ptr())
}

/// `n` bytes for the JavaScript to write arguments into.
#[unsafe(no_mangle)]
pub extern "C" fn myr_alloc(n: u32) -> *mut u8 {
    let mut v = Vec::<u8>::with_capacity(n as usize);
    let p = v.as_mut_ptr();
    std::mem::forget(v);
    p
}

/// Frees what [`myr_alloc`] gave.
///
/// # Safety
/// `p` and `n` as [`myr_alloc`] gave and took them, freed once.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_free(p: *mut u8, n: u32) {
    drop(unsafe { Vec::from_raw_parts(p, 0, n as usize) });
}

/// # Safety
/// `p..p + n` is memory the JavaScript wrote (from [`myr_alloc`]).
unsafe fn bytes<'a>(p: *const u8, n: u32) -> &'a [u8] {
    if n == 0 {
        return &[];
    }
    unsafe { std::slice::from_raw_parts(p, n as usize) }
}

fn name(p: *const u8, n: u32) -> String {
    // SAFETY: as for `bytes`.
    String::from_utf8_lossy(unsafe { bytes(p, n) }).into_owned()
}

/// Gives the dataset's absolute address (before [`myr_open`] or [`myr_open_pages`]): a cloud
/// format's dataset is opened by it, its other files relative to it.
///
/// # Safety
/// `p..p + n` is memory the JavaScript wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_base(p: *const u8, n: u32) {
    let url = name(p, n);
    BASE.with(|b| *b.borrow_mut() = url);
}

/// Applies a dataset's edits (`text`: the layer as `/edits/NAME` answers it) to every node
/// this worker decodes from now on, replacing those applied before; the surfaces ground edits
/// name are read by range requests from `surfaces` followed by their (percent-encoded) name.
/// The answer: `{"edits": N}`, or an error naming the edit at fault.
///
/// # Safety
/// `text..text + text_len` and `surfaces..surfaces + surfaces_len` are memory the JavaScript
/// wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_edits(
    text: *const u8,
    text_len: u32,
    surfaces: *const u8,
    surfaces_len: u32,
) -> u32 {
    let (text, base) = (name(text, text_len), name(surfaces, surfaces_len));
    let layer = match myriad_measure::edits::Layer::parse(&text) {
        Ok(l) => l,
        Err(m) => return error(format!("edits: {m}")),
    };
    let open = |n: &str| -> Result<Arc<myriad_measure::ground::surface::Surface>, String> {
        let encoded: String = (n.bytes())
            .map(|b| match b {
                b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'.' | b'-' | b'_' => {
                    (b as char).to_string()
                }
                _ => format!("%{b:02X}"),
            })
            .collect();
        let source = UrlBytes::open(&format!("{base}{encoded}"), 0).map_err(|e| e.to_string())?;
        myriad_measure::ground::surface::Surface::from_source(source, n, false)
            .map(Arc::new)
            .map_err(|e| e.to_string())
    };
    let set = |ds: &mut Dataset| -> Result<usize, String> {
        if layer.edits.is_empty() {
            ds.set_edits(None);
            let _ = ds.above_ground();
            return Ok(0);
        }
        let c = layer.compile_with(&ds.meta.schema, &open)?;
        ds.set_edits(Some(Arc::new(c)));
        // Its terrain as it is now, for colours above it.
        let _ = ds.above_ground();
        Ok(layer.edits.len())
    };
    let mut done = DATASET.with(|s| s.borrow_mut().as_mut().map(set));
    if done.is_none() {
        done = VIEWER.with(|s| s.borrow_mut().as_mut().map(|v| set(&mut v.dataset)));
    }
    match done {
        Some(Ok(n)) => answer_json(json!({ "edits": n })),
        Some(Err(m)) => error(format!("edits: {m}")),
        None => error("no dataset open"),
    }
}

/// The views of a camera path (JSON at `p`: `{"views": [...]}`, as saved work keeps it) at
/// `fps` frames a second: `{"views": [[ex, ey, ez, tx, ty, tz], ...], "duration": s}`, the
/// curve `render --path` flies, or an error naming the member.
///
/// # Safety
/// `p..p + n` is memory the JavaScript wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_path(p: *const u8, n: u32, fps: f64) -> u32 {
    let v: Value = match serde_json::from_str(&name(p, n)) {
        Ok(v) => v,
        Err(e) => return error(format!("camera path: {e}")),
    };
    let path = match myriad_measure::camera_path::CameraPath::from_json(&v, "") {
        Ok(p) => p,
        Err(e) => return error(format!("camera path: {e}")),
    };
    if !(fps > 0.0 && fps <= 240.0) || path.duration() * fps > 1e6 {
        return error("camera path: too many frames");
    }
    let views: Vec<Value> = (path.frames(fps).iter())
        .map(|v| {
            json!([
                v.position[0],
                v.position[1],
                v.position[2],
                v.target[0],
                v.target[1],
                v.target[2]
            ])
        })
        .collect();
    answer_json(json!({ "views": views, "duration": path.duration() }))
}

/// The contours every `interval` of the terrain the dataset's edits hold (after [`myr_edits`]),
/// sampled on a grid of at most `cells` cells: `{"lines": [{"z", "closed", "points": [x, y,
/// ...]}]}`, or an error saying why there are none.
#[unsafe(no_mangle)]
pub extern "C" fn myr_contours(interval: f64, cells: u32) -> u32 {
    let r = with_dataset(|ds| myriad_measure::contours::of_terrain(ds, interval, cells as usize));
    match r {
        Some(Ok(lines)) => {
            let lines: Vec<Value> = (lines.iter())
                .map(|c| {
                    let pts: Vec<f64> = c.points.iter().flatten().copied().collect();
                    json!({ "z": c.elevation, "closed": c.closed, "points": pts })
                })
                .collect();
            answer_json(json!({ "lines": lines }))
        }
        Some(Err(m)) => error(m),
        None => error("no dataset open"),
    }
}

/// Opens the dataset of `len` bytes for selecting (the selection worker): its information.
#[unsafe(no_mangle)]
pub extern "C" fn myr_open(len: f64, name_ptr: *const u8, name_len: u32) -> u32 {
    match open(len, &name(name_ptr, name_len)).and_then(Viewer::from_dataset) {
        Ok(v) => {
            let info = v.info();
            VIEWER.with(|s| *s.borrow_mut() = Some(v));
            answer_json(info)
        }
        Err(e) => error(e),
    }
}

/// Opens the dataset of `len` bytes for decoding (header and metadata only: decode workers).
#[unsafe(no_mangle)]
pub extern "C" fn myr_open_pages(len: f64, name_ptr: *const u8, name_len: u32) -> u32 {
    match open(len, &name(name_ptr, name_len)) {
        Ok(d) => {
            let files: Vec<&str> = d.meta.files.iter().map(|f| f.path.as_str()).collect();
            let info = json!({ "files": files, "foreign": d.foreign_format() });
            DATASET.with(|s| *s.borrow_mut() = Some(d));
            answer_json(info)
        }
        Err(e) => error(e),
    }
}

fn camera_json(c: &Camera) -> Value {
    json!({ "position": c.position, "target": c.target, "up": c.up, "fov": c.fov_y })
}

/// The camera `myriad render` starts from, for a `width` x `height` view.
#[unsafe(no_mangle)]
pub extern "C" fn myr_camera(width: u32, height: u32, fov: f64) -> u32 {
    VIEWER.with(|s| match &*s.borrow() {
        Some(v) => answer_json(camera_json(&v.default_camera(width, height, fov))),
        None => error("no dataset open"),
    })
}

/// Selects for the camera and options in `args` (f64s: eye, target, up, fov, width, height,
/// budget, threshold in pixels, clip mode (0 none, 1 inside, 2 outside), clip min, clip max)
/// with the nodes drawn (`drawn`: level, x, y, z each) for the point sizes' tree.
///
/// # Safety
/// `args` holds `nargs` f64s and `drawn` `ndrawn` u32s, both written by the JavaScript.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_select(
    args: *const f64,
    nargs: u32,
    drawn: *const u32,
    ndrawn: u32,
) -> u32 {
    if nargs < 21 {
        return error("select: 21 arguments expected");
    }
    // SAFETY: the caller's promise.
    let a = unsafe { std::slice::from_raw_parts(args, nargs as usize) };
    let d = unsafe { bytes(drawn as *const u8, ndrawn * 16) };
    let v3 = |i: usize| [a[i], a[i + 1], a[i + 2]];
    let camera = Camera {
        position: v3(0),
        target: v3(3),
        up: v3(6),
        fov_y: a[9],
        width: a[10] as u32,
        height: a[11] as u32,
        near: 1.0,
        far: 2.0,
    };
    let clip = match a[14] as u32 {
        0 => None,
        mode => Some(Clip {
            bounds: myriad_core::Aabb::new(v3(15), v3(18)),
            inside: mode == 1,
        }),
    };
    let drawn = d
        .chunks_exact(16)
        .map(|c| {
            let u = |i: usize| u32::from_le_bytes(c[i * 4..i * 4 + 4].try_into().unwrap());
            NodeKey {
                level: u(0),
                cell: [u(1), u(2), u(3)],
            }
        })
        .collect();
    let ask = Ask {
        camera,
        options: SelectOptions {
            budget: a[12] as u64,
            min_pixels: a[13],
        },
        clip,
        drawn,
    };
    VIEWER.with(|s| match &mut *s.borrow_mut() {
        Some(v) => answer_json(v.select(&ask)),
        None => error("no dataset open"),
    })
}

/// Runs `f` on the open dataset: the decode worker's, else the selection worker's.
fn with_dataset<R>(f: impl Fn(&Dataset) -> R) -> Option<R> {
    DATASET
        .with(|s| s.borrow().as_ref().map(&f))
        .or_else(|| VIEWER.with(|s| s.borrow().as_ref().map(|v| f(&v.dataset))))
}

const SCHEMES: [&str; 8] = [
    "rgb",
    "intensity",
    "elevation",
    "classification",
    "return",
    "source",
    "level",
    "uniform",
];

/// Checks and decodes a node's page (`page`, as fetched; `key` level, x, y, z; where the page
/// lies, its CRC and point count) into positions relative to `origin` and colours by scheme
/// `scheme` (an index of [`SCHEMES`]) over the elevations `z_lo..z_hi`. The answer: the point
/// count (u32, little-endian), then 3 f32 per point, then 4 bytes of colour per point; or
/// 0xffffffff and an error message.
///
/// # Safety
/// `page` holds `page_len` bytes and `args` 20 f64s (level, x, y, z, offset, length, crc,
/// points, the origin, the hidden classes as 8 words of 32 bits, then the spacing the node's
/// finest level is drawn at (`myriad_lod::point_spacing`) or 0), written by the JavaScript.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_decode(
    page: *const u8,
    page_len: u32,
    args: *const f64,
    scheme: u32,
    z_lo: f64,
    z_hi: f64,
) -> u32 {
    // SAFETY: the caller's promise.
    let (b, a) = unsafe {
        (
            bytes(page, page_len),
            std::slice::from_raw_parts(args, ARGS),
        )
    };
    let e = node_entry(a);
    let colour = colour(scheme);
    let hidden = hidden_classes(a);
    let r = with_dataset(|ds| {
        decode(
            ds,
            &e,
            b,
            [a[8], a[9], a[10]],
            colour,
            (z_lo, z_hi),
            &shown_by(ds, &hidden)?,
        )
    });
    answer_decoded(r)
}

/// A decoded node as [`myr_decode`] answers it.
fn answer_decoded(r: Option<Result<crate::Decoded, String>>) -> u32 {
    match r {
        Some(Ok(d)) => {
            let n = d.colours.len();
            let mut out = Vec::with_capacity(8 + n * 16 + d.classes.len() * 8);
            out.extend_from_slice(&(n as u32).to_le_bytes());
            for v in &d.positions {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend(d.colours.iter().flatten());
            // Then the node's classes: a count, and (class, points) pairs of u32.
            out.extend_from_slice(&(d.classes.len() as u32).to_le_bytes());
            for (c, k) in &d.classes {
                out.extend_from_slice(&(*c as u32).to_le_bytes());
                out.extend_from_slice(&k.to_le_bytes());
            }
            answer(out)
        }
        Some(Err(m)) => {
            let mut out = u32::MAX.to_le_bytes().to_vec();
            out.extend_from_slice(m.as_bytes());
            answer(out)
        }
        None => {
            let mut out = u32::MAX.to_le_bytes().to_vec();
            out.extend_from_slice(b"no dataset open");
            answer(out)
        }
    }
}

/// [`myr_decode`] of a node of a cloud format read in place: its points read by the reader
/// itself (a COPC chunk, an EPT node file, a Potree node's bytes, by range requests), then
/// answered as [`myr_decode`] answers.
///
/// # Safety
/// `args` holds 20 f64s as for [`myr_decode`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_decode_read(
    args: *const f64,
    scheme: u32,
    z_lo: f64,
    z_hi: f64,
) -> u32 {
    // SAFETY: the caller's promise.
    let a = unsafe { std::slice::from_raw_parts(args, ARGS) };
    let e = node_entry(a);
    let colour = colour(scheme);
    let hidden = hidden_classes(a);
    let r = with_dataset(|ds| {
        let b = ds
            .read_node(&e)
            .map_err(|d| ds.damage_error(&d).to_string())?;
        let shown = shown_by(ds, &hidden)?;
        Ok::<_, String>(crate::decoded(
            b,
            &e,
            [a[8], a[9], a[10]],
            colour,
            (z_lo, z_hi),
            &shown,
        ))
    });
    answer_decoded(r)
}

/// f64s of a node's arguments: see [`myr_decode`].
const ARGS: usize = 20;

/// The hidden classes of a node's arguments: 8 words of 32 flags after the origin.
fn hidden_classes(a: &[f64]) -> Hidden {
    hidden_words(&a[11..])
}

/// Hidden classes from 8 words of 32 flags.
fn hidden_words(w: &[f64]) -> Hidden {
    std::array::from_fn(|c| (w[c / 32] as u32) >> (c % 32) & 1 == 1)
}

fn node_entry(a: &[f64]) -> myriad_format::NodeEntry {
    let key = NodeKey {
        level: a[0] as u32,
        cell: [a[1] as u32, a[2] as u32, a[3] as u32],
    };
    let page = PageRef {
        offset: a[4] as u64,
        length: a[5] as u32,
        crc: a[6] as u32,
    };
    let mut e = entry(key, page, a[7] as u32);
    // The spacing the node's finest level is drawn at (which of its points are lone), 0: none
    // known.
    if a[19] > 0.0 {
        e.spacing = vec![a[19]];
    }
    e
}

/// Every attribute of point `index` of a node (its page and `args` as for [`myr_decode`]).
///
/// # Safety
/// As for [`myr_decode`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_point(
    page: *const u8,
    page_len: u32,
    args: *const f64,
    index: u32,
) -> u32 {
    // SAFETY: the caller's promise.
    let (b, a) = unsafe {
        (
            bytes(page, page_len),
            std::slice::from_raw_parts(args, ARGS),
        )
    };
    let e = node_entry(a);
    // The index is into the points shown, as drawn.
    let r = with_dataset(|ds| -> Result<_, String> {
        let read = match ds.foreign_format() {
            Some(_) => ds.read_node(&e),
            None => ds.decode_node_edited(&e, b, &ds.meta.schema),
        };
        let mut batch = read.map_err(|d| ds.damage_error(&d).to_string())?;
        keep_shown(&mut batch, &shown_by(ds, &hidden_classes(a))?);
        Ok(batch)
    });
    match r {
        Some(Ok(batch)) if (index as usize) < batch.len() => {
            answer_json(point_json(&batch, index as usize))
        }
        Some(Ok(batch)) => error(format!("no point {index} in a node of {}", batch.len())),
        Some(Err(m)) => error(m),
        None => error("no dataset open"),
    }
}

/// A measurement through the points at `args` (`n` numbers, x, y, z each) in the dataset's
/// CRS: [`crate::measure_json`].
///
/// # Safety
/// `args` holds `n` f64s the JavaScript wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_measure(kind: u32, args: *const f64, n: u32, units: u32) -> u32 {
    let pts: &[f64] = if n == 0 {
        &[]
    } else {
        // SAFETY: as the caller promises.
        unsafe { std::slice::from_raw_parts(args, n as usize) }
    };
    VIEWER.with(|s| {
        let crs = s.borrow().as_ref().and_then(|v| v.dataset.meta.crs.clone());
        answer_json(crate::measure_json(kind, pts, units, crs.as_deref()))
    })
}

/// A cross-section ([`crate::cut_profile`]) along the line at `args` (`n` numbers, x, y each;
/// then the hidden classes as 8 words of 32 bits), `width` wide, drawn `picture` pixels wide in
/// colour scheme `scheme`: a u32 length and the summary's JSON, then the RGBA picture, then the
/// CSV (lengths in the summary: `rgba`, `csv`).
///
/// # Safety
/// `args` holds `n + 8` f64s the JavaScript wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_profile(
    args: *const f64,
    n: u32,
    width: f64,
    picture: u32,
    scheme: u32,
) -> u32 {
    // SAFETY: the caller's promise.
    let a = unsafe { std::slice::from_raw_parts(args, n as usize + 8) };
    let line: Vec<[f64; 2]> = a[..n as usize]
        .chunks_exact(2)
        .map(|c| [c[0], c[1]])
        .collect();
    let hidden = hidden_words(&a[n as usize..]);
    let colour = colour(scheme);
    let r = with_dataset(|ds| {
        crate::cut_profile(ds, &line, width, picture, colour, &shown_by(ds, &hidden)?)
    });
    let (mut summary, rgba, csv) = match r {
        Some(Ok(x)) => x,
        Some(Err(e)) => (json!({ "error": e }), Vec::new(), Vec::new()),
        None => (
            json!({ "error": "no dataset open" }),
            Vec::new(),
            Vec::new(),
        ),
    };
    summary["rgba"] = rgba.len().into();
    summary["csv"] = csv.len().into();
    let text = summary.to_string().into_bytes();
    let mut out = (text.len() as u32).to_le_bytes().to_vec();
    out.extend(text);
    out.extend(rgba);
    out.extend(csv);
    answer(out)
}

/// What two points of a profile are apart (`myriad_measure::profile::between`), in the
/// dataset's units: a JSON text.
#[unsafe(no_mangle)]
pub extern "C" fn myr_between(a_along: f64, a_z: f64, b_along: f64, b_z: f64) -> u32 {
    let units = with_dataset(|ds| myriad_measure::measurement::crs_units(ds.meta.crs.as_deref()))
        .unwrap_or("units");
    answer_json(json!(myriad_measure::profile::between(
        [a_along, a_z],
        [b_along, b_z],
        units
    )))
}

/// A volume ([`crate::volume_json`]) over the polygon at `args` (`n` numbers, x, y each; then
/// the hidden classes as 8 words of 32 bits) above the rim's plane (`base` 0) or the elevation
/// `z` (`base` 1), on cells of `cell` (0: from the spacing): a JSON text.
///
/// # Safety
/// `args` holds `n + 8` f64s the JavaScript wrote.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn myr_volume(args: *const f64, n: u32, base: u32, z: f64, cell: f64) -> u32 {
    // SAFETY: the caller's promise.
    let a = unsafe { std::slice::from_raw_parts(args, n as usize + 8) };
    let polygon: Vec<[f64; 2]> = a[..n as usize]
        .chunks_exact(2)
        .map(|c| [c[0], c[1]])
        .collect();
    let hidden = hidden_words(&a[n as usize..]);
    let elevation = (base == 1).then_some(z);
    let cell = (cell > 0.0).then_some(cell);
    match with_dataset(|ds| {
        crate::volume_json(ds, &polygon, elevation, cell, &shown_by(ds, &hidden)?)
    }) {
        Some(Ok(v)) => answer_json(v),
        Some(Err(e)) => error(e),
        None => error("no dataset open"),
    }
}
