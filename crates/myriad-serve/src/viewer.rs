//! The web viewer's own files (`viewer/`: the page, its scripts (the WebGL2 and WebGPU renderers
//! among them) and the WebAssembly built by
//! `crates/myriad-web/build.sh`), compiled into the server and sent gzip-compressed where the
//! browser takes it (compressed once, on first use).

use std::sync::OnceLock;

pub(crate) struct Asset {
    pub(crate) bytes: &'static [u8],
    pub(crate) content_type: &'static str,
    gzip: OnceLock<Vec<u8>>,
}

impl Asset {
    const fn new(bytes: &'static [u8], content_type: &'static str) -> Asset {
        Asset {
            bytes,
            content_type,
            gzip: OnceLock::new(),
        }
    }

    pub(crate) fn gzip(&self) -> &[u8] {
        self.gzip.get_or_init(|| gzip(self.bytes))
    }
}

pub(crate) fn gzip(b: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(b).expect("to memory");
    z.finish().expect("to memory")
}

static PAGE: Asset = Asset::new(
    include_bytes!("../viewer/index.html"),
    "text/html; charset=utf-8",
);
static FILES: [(&str, Asset); 14] = [
    // The native renderer's point shader: the WebGPU renderer takes its point_pixels.
    (
        "draw.wgsl",
        Asset::new(
            include_bytes!("../../myriad-render/src/draw.wgsl"),
            "text/plain; charset=utf-8",
        ),
    ),
    (
        "viewer.js",
        Asset::new(include_bytes!("../viewer/viewer.js"), "text/javascript"),
    ),
    (
        "webgl2.js",
        Asset::new(include_bytes!("../viewer/webgl2.js"), "text/javascript"),
    ),
    (
        "webgpu.js",
        Asset::new(include_bytes!("../viewer/webgpu.js"), "text/javascript"),
    ),
    (
        "worker.js",
        Asset::new(include_bytes!("../viewer/worker.js"), "text/javascript"),
    ),
    (
        "work.js",
        Asset::new(include_bytes!("../viewer/work.js"), "text/javascript"),
    ),
    (
        "profile.js",
        Asset::new(include_bytes!("../viewer/profile.js"), "text/javascript"),
    ),
    (
        "volume.js",
        Asset::new(include_bytes!("../viewer/volume.js"), "text/javascript"),
    ),
    (
        "edit.js",
        Asset::new(include_bytes!("../viewer/edit.js"), "text/javascript"),
    ),
    (
        "contours.js",
        Asset::new(include_bytes!("../viewer/contours.js"), "text/javascript"),
    ),
    (
        "photos.js",
        Asset::new(include_bytes!("../viewer/photos.js"), "text/javascript"),
    ),
    (
        "map.js",
        Asset::new(include_bytes!("../viewer/map.js"), "text/javascript"),
    ),
    (
        "path.js",
        Asset::new(include_bytes!("../viewer/path.js"), "text/javascript"),
    ),
    (
        "myriad_web.wasm",
        Asset::new(
            include_bytes!("../viewer/myriad_web.wasm"),
            "application/wasm",
        ),
    ),
];

/// The viewer's page (the same for every dataset: it reads the name from its address).
pub(crate) fn page() -> &'static Asset {
    &PAGE
}

/// The file `/viewer/NAME`.
pub(crate) fn file(name: &str) -> Option<&'static Asset> {
    FILES.iter().find(|(n, _)| *n == name).map(|(_, a)| a)
}

/// Writes the viewer as a static site into `dir` (`myriad export --to web`): `index.html` (the
/// page, its files named relative to it, `window.MYRIAD_SITE` listing `datasets`: URLs relative
/// to the page or absolute; the first opens, `?d=URL` opens another) and `viewer/` (the
/// scripts, the shader and the WebAssembly). Any static server that answers range requests
/// serves it; nothing in it needs `myriad serve`.
pub fn write_site(dir: &std::path::Path, datasets: &[String]) -> std::io::Result<()> {
    let page = String::from_utf8_lossy(PAGE.bytes).replace("src=\"/viewer/", "src=\"viewer/");
    let site = serde_json::json!({ "datasets": datasets });
    // `</` never appears inside the script: a dataset's name cannot end it.
    let config = format!(
        "<script>window.MYRIAD_SITE = {};</script>\n",
        site.to_string().replace("</", "<\\/")
    );
    let at = page.find("<script").unwrap_or(page.len());
    let page = format!("{}{config}{}", &page[..at], &page[at..]);
    std::fs::write(dir.join("index.html"), page)?;
    let files = dir.join("viewer");
    std::fs::create_dir_all(&files)?;
    for (name, asset) in &FILES {
        std::fs::write(files.join(name), asset.bytes)?;
    }
    Ok(())
}

/// Whether `dir` is a site [`write_site`] wrote (what `--force` may replace).
pub fn is_site(dir: &std::path::Path) -> bool {
    dir.join("index.html").is_file() && dir.join("viewer").join("myriad_web.wasm").is_file()
}
