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
static FILES: [(&str, Asset); 9] = [
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
