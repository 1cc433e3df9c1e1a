//! Single-pass stereo on the GPU paths (the compute path: one dispatch for both eyes; the quad
//! path: one instanced draw) against the CPU's and against two passes.

mod common;
use common::random;
use myriad_render::stereo::Stereo;
use myriad_render::{Gpu, Passes, Path, PointSize, Points, Rasterizer, Style};

#[test]
fn the_gpu_paths_draw_both_eyes_in_one_pass_as_the_cpu_does() {
    let Some(gpu) = common::gpu_or_skip() else {
        return;
    };
    let mut paths = vec![Path::Quads];
    if gpu.atomics {
        paths.push(Path::Compute);
    } else {
        eprintln!("the adapter has no 64-bit atomics: the quad path alone");
    }
    for path in paths {
        eyes_in_one_pass(&gpu, path);
    }
}

fn eyes_in_one_pass(gpu: &Gpu, path: Path) {
    let cam = myriad_lod::Camera {
        position: [0.0, 0.0, 0.0],
        target: [0.0, 1.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 60.0,
        width: 120,
        height: 90,
        near: 0.1,
        far: 100.0,
    };
    let mut r = random(3);
    let positions: Vec<[f64; 3]> = (0..30_000)
        .map(|_| [r() * 16.0 - 8.0, 4.0 + r() * 10.0, r() * 8.0 - 4.0])
        .collect();
    let colours: Vec<[u8; 4]> = (0..positions.len())
        .map(|i| [(i % 251) as u8, (i % 13) as u8 * 19, 200, 255])
        .collect();
    let cpu = Gpu::cpu();
    let on_cpu = Points::upload(&cpu, [0.0; 3], &positions, &colours);
    let on_gpu = Points::upload(gpu, [0.0; 3], &positions, &colours);
    let style = Style {
        size: PointSize::Fixed(3.0),
        passes: Passes::default(),
        ..Style::default()
    };
    let eyes = cam.eyes(1.5);
    let mut cpu_raster = Rasterizer::new(&cpu);
    let mut gpu_raster = Rasterizer::with_path(gpu, path);
    cpu_raster.precision = 0.0;
    gpu_raster.precision = 0.0;
    // With no pass and with every pass (which must not read across the eyes' border, and must
    // place each eye's pixels from its own centre, as the CPU's per-eye passes do).
    let every = Style {
        passes: Passes::parse("fill,shade,ssao,edl,blur").unwrap(),
        ..style
    };
    for (style, hidden_area) in [(style, false), (style, true), (every, false), (every, true)] {
        let s = Stereo {
            ipd: 1.5,
            single_pass: true,
            hidden_area,
        };
        let a = cpu_raster.render_stereo(&cpu, &eyes, &[on_cpu.all(1.0)], &[], &style, &s, None);
        let b = gpu_raster.render_stereo(gpu, &eyes, &[on_gpu.all(1.0)], &[], &style, &s, None);
        let two = Stereo {
            single_pass: false,
            ..s
        };
        let c = gpu_raster.render_stereo(gpu, &eyes, &[on_gpu.all(1.0)], &[], &style, &two, None);
        let differ =
            |x: &[u8], y: &[u8]| x.chunks(4).zip(y.chunks(4)).filter(|(p, q)| p != q).count();
        let lit = a.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(lit > 240 * 90 / 4, "{lit}");
        // f32 on the GPU against f32 on the CPU: without passes the same pixels but for a rare
        // rounding; with every pass as close as the GPU's two passes are (lavapipe: 831 of
        // 21,600 pixels differ both ways, each post pass's float rounding).
        let (single, two_passes) = (differ(&a, &b), differ(&a, &c));
        let bound = if style.passes.normals() {
            two_passes
        } else {
            0
        };
        assert!(
            (single - bound.min(single)) * 1000 <= 240 * 90,
            "{path:?}: {single} pixels differ from the CPU's (two passes: {two_passes})"
        );
        // One dispatch draws what two passes do.
        assert!(
            differ(&b, &c) * 1000 <= 240 * 90,
            "{path:?}: {} pixels differ from two passes",
            differ(&b, &c)
        );
    }
}

#[test]
fn every_path_skips_the_hidden_pixels_in_the_point_and_post_passes() {
    // A grey wall with a red patch exactly under each eye's hidden square: hidden, the patch
    // leaves no trace, not even in the blur of the pixels around it (one surface: the blur
    // would mix them).
    let size = 64u32;
    let eyes = facing_a_wall(size).eyes(0.0);
    // One point a pixel at depth 10, a quarter pixel up and left of its centre (so that
    // supersampled twice it covers its own pixel's samples); the patch over pixels 24..40.
    let pixel = 2.0 * 10.0 * (30f64.to_radians().tan()) / size as f64;
    let mut positions = Vec::new();
    let mut colours = Vec::new();
    for y in 0..size {
        for x in 0..size {
            let at = |d: f64| {
                [
                    (x as f64 + 0.25 - size as f64 / 2.0) * pixel * d / 10.0,
                    d,
                    (size as f64 / 2.0 - y as f64 - 0.25) * pixel * d / 10.0,
                ]
            };
            positions.push(at(10.0));
            let patch = (24..40).contains(&x) && (24..40).contains(&y);
            colours.push(if patch {
                [255, 0, 0, 255]
            } else {
                [128, 128, 128, 255]
            });
        }
    }
    let square: Vec<bool> = (0..size * size)
        .map(|i| (24..40).contains(&(i % size)) && (24..40).contains(&(i / size)))
        .collect();
    let masks = [square.clone(), square];
    let style = Style {
        size: PointSize::Fixed(1.0),
        passes: Passes::parse("fill,blur").unwrap(),
        ..Style::default()
    };
    let mut paths = vec![(Gpu::cpu(), Path::Cpu)];
    if let Some(gpu) = common::gpu_or_skip() {
        if gpu.atomics {
            paths.push((common::gpu_or_skip().unwrap(), Path::Compute));
        }
        paths.push((gpu, Path::Quads));
    }
    for (gpu, path) in &paths {
        let points = Points::upload(gpu, [0.0; 3], &positions, &colours);
        let mut raster = Rasterizer::with_path(gpu, *path);
        raster.precision = 0.0;
        // Supersampled too: each hidden pixel's samples are hidden.
        for (aa, single_pass) in [(0, true), (0, false), (2, true), (2, false)] {
            let s = Stereo {
                ipd: 0.0,
                single_pass,
                hidden_area: true,
            };
            let style = Style {
                passes: Passes { aa, ..style.passes },
                ..style
            };
            let img = raster.render_stereo(
                gpu,
                &eyes,
                &[points.all(1.0)],
                &[],
                &style,
                &s,
                Some(&masks),
            );
            for (i, p) in img.chunks(4).enumerate() {
                let (x, y) = ((i as u32 % (2 * size)) % size, i as u32 / (2 * size));
                let hidden = (24..40).contains(&x) && (24..40).contains(&y);
                let want: &[u8] = if hidden { &[0, 0, 0] } else { &[128, 128, 128] };
                assert_eq!(
                    &p[..3],
                    want,
                    "{path:?} aa {aa}, single pass {single_pass}: ({x}, {y})"
                );
            }
        }
    }
}

#[test]
fn points_dropped_in_the_hidden_area_change_no_pixel_outside_it() {
    // Squares of 7 pixels every 8, each its own colour, on a wall; the left 30 columns of each
    // eye hidden. The quad path drops the points whose squares lie in the hidden area whole:
    // the frame equals the one drawn without the mask, its hidden pixels then made black, on
    // every path (a square centred 2 pixels inside the hidden area still shows its edge).
    let size = 64u32;
    let eyes = facing_a_wall(size).eyes(0.0);
    let pixel = 2.0 * 10.0 * (30f64.to_radians().tan()) / size as f64;
    let (mut positions, mut colours) = (Vec::new(), Vec::new());
    for y in (4..size).step_by(8) {
        for x in (4..size).step_by(8) {
            let at = |v: u32| (v as f64 + 0.5 - size as f64 / 2.0) * pixel;
            positions.push([at(x), 10.0, -at(y)]);
            colours.push([(x * 4) as u8, (y * 4) as u8, 200, 255]);
        }
    }
    let hidden: Vec<bool> = (0..size * size).map(|i| i % size < 30).collect();
    let masks = [hidden.clone(), hidden.clone()];
    let style = Style {
        size: PointSize::Fixed(7.0),
        passes: Passes::default(),
        ..Style::default()
    };
    for (gpu, mut raster) in common::paths() {
        let gpu = &gpu;
        let path = raster.path;
        let points = Points::upload(gpu, [0.0; 3], &positions, &colours);
        raster.precision = 0.0;
        for single_pass in [true, false] {
            let s = Stereo {
                ipd: 0.0,
                single_pass,
                hidden_area: false,
            };
            let draws = [points.all(1.0)];
            let open = raster.render_stereo(gpu, &eyes, &draws, &[], &style, &s, None);
            let masked = raster.render_stereo(gpu, &eyes, &draws, &[], &style, &s, Some(&masks));
            let mut lit_at_edge = 0;
            for (i, (p, q)) in open.chunks(4).zip(masked.chunks(4)).enumerate() {
                let x = (i as u32 % (2 * size)) % size;
                let want: &[u8] = if x < 30 { &[0, 0, 0, 255] } else { p };
                assert_eq!(q, want, "{path:?}, single pass {single_pass}: pixel {i}");
                lit_at_edge += usize::from(x == 30 && q[..3] != [0, 0, 0]);
            }
            // The squares centred at column 28 reach columns 30 and 31.
            assert!(lit_at_edge >= 2 * 7 * 8, "{path:?}: {lit_at_edge}");
        }
    }
}

/// Looking along +y from the origin, `size` pixels square: a wall at y = 10 fills the view.
fn facing_a_wall(size: u32) -> myriad_lod::Camera {
    myriad_lod::Camera {
        position: [0.0, 0.0, 0.0],
        target: [0.0, 1.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 60.0,
        width: size,
        height: size,
        near: 0.1,
        far: 100.0,
    }
}
