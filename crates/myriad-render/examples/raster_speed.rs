//! Frame time of the compute rasterizer: N random points on a terrain-like sheet, 1280 x 720,
//! frame including the readback; median of 9 frames. The compute path unless `quads` (or `cpu`) is given;
//! the points in one buffer, or in PARTS buffers (environment) as a frame's nodes are; positions
//! quantized (two words: 20 bits an axis), or f32 with POSITIONS=f32, or read with the first
//! word alone with PRECISION=1000 (pixels).
//! `cargo run --release -p myriad-render --example raster_speed [POINTS] [quads|cpu]`

use myriad_lod::Camera;
use myriad_render::{Encoding, Gpu, Path, PointSize, Points, Rasterizer, Style};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(5_000_000);
    let path = std::env::args().nth(2);
    let gpu = match std::env::args().nth(2).as_deref() {
        Some("cpu") => Gpu::cpu(),
        _ => Gpu::headless().expect("a GPU adapter"),
    };
    let mut s = 0x9e3779b97f4a7c15u64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut positions = Vec::with_capacity(n);
    let mut colours = Vec::with_capacity(n);
    for _ in 0..n {
        let (x, y) = (next() * 1000.0, next() * 1000.0);
        let z = 20.0 * ((x * 0.01).sin() + (y * 0.013).cos());
        positions.push([x, y, z]);
        colours.push([(x / 4.0) as u8, (y / 4.0) as u8, 128, 255]);
    }
    let bounds = myriad_core_bounds(&positions);
    // In as many buffers as PARTS says (a frame draws one per node).
    let parts: usize = std::env::var("PARTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let chunk = n.div_ceil(parts.max(1));
    let sets: Vec<Points> = positions
        .chunks(chunk)
        .zip(colours.chunks(chunk))
        .map(|(p, c)| match std::env::var("POSITIONS").as_deref() {
            Ok("f32") => Points::encode(&gpu, Encoding::F32 { origin: [500.0; 3] }, p, c),
            _ => Points::upload(&gpu, [500.0, 500.0, 0.0], p, c),
        })
        .collect();
    let cam = Camera::framing(&bounds, 1280, 720, 60.0);
    let mut r = match path.as_deref() {
        Some("quads") => Rasterizer::with_path(&gpu, Path::Quads),
        _ => Rasterizer::new(&gpu),
    };
    if let Some(px) = std::env::var("PRECISION").ok().and_then(|v| v.parse().ok()) {
        r.precision = px;
    }
    let style = Style {
        size: PointSize::Fixed(1.0),
        ..Style::default()
    };
    let mut times = Vec::new();
    for _ in 0..9 {
        let t = std::time::Instant::now();
        let draws: Vec<_> = sets.iter().map(|p| p.all(0.0)).collect();
        let img = r.render(&gpu, &cam, &draws, &[], &style);
        times.push(t.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(img);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{}, {:?} path: {n} points, 1280x720: median frame {:.1} ms (min {:.1}, max {:.1})",
        gpu.name, r.path, times[4], times[0], times[8]
    );
}

fn myriad_core_bounds(p: &[[f64; 3]]) -> myriad_core::Aabb {
    let mut b = myriad_core::Aabb::EMPTY;
    for &q in p {
        b.extend(q);
    }
    b
}
