//! The rasterizer on every path this machine runs: the CPU always, and where there is a Vulkan
//! driver (lavapipe in CI) the compute path (64-bit atomics) and the quad path, which any adapter
//! runs. Points land on the pixels the camera puts them, the nearest wins, sizes, shapes and
//! eye-dome lighting cover the pixels they should, and the GPU paths draw the CPU's image.

use myriad_lod::Camera;
mod common;

use common::paths;
use myriad_render::{Edl, Gpu, Passes, Path, PointSize, Points, Shape, Style};

/// 200 x 100 pixels, 90 degrees vertically, from (x, -10, 0) towards (x, 0, 0), Z up.
fn looking_along_y(x: f64) -> Camera {
    Camera {
        position: [x, -10.0, 0.0],
        target: [x, 0.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 90.0,
        width: 200,
        height: 100,
        near: 0.5,
        far: 100.0,
    }
}

fn fixed(px: f32, shape: Shape) -> Style {
    Style {
        size: PointSize::Fixed(px),
        shape,
        passes: Passes::default(),
        background: [0, 0, 0, 255],
        clip: None,
    }
}

fn px(img: &[u8], w: usize, x: usize, y: usize) -> [u8; 4] {
    img[(y * w + x) * 4..][..4].try_into().unwrap()
}

#[test]
fn points_land_where_the_camera_puts_them() {
    let cam = looking_along_y(1000.0);
    let red = [255, 0, 0, 255];
    let green = [0, 255, 0, 255];
    let blue = [0, 0, 255, 255];
    let positions = [
        [1000.0, 0.0, 0.0],   // centre, depth 10
        [1000.0, -1.0, 0.0],  // centre, nearer: wins
        [1005.0, 0.0, 0.0],   // depth 10, x = 5 of the ±20 visible: pixel 125
        [1000.0, -20.0, 0.0], // behind the camera
        [1100.0, 0.0, 0.0],   // outside the view
    ];
    let colours = [red, green, blue, red, red];
    let points = |gpu: &Gpu| Points::upload(gpu, [1000.0, 0.0, 0.0], &positions, &colours);
    let rev: Vec<[f64; 3]> = positions.iter().rev().cloned().collect();
    let revc: Vec<[u8; 4]> = colours.iter().rev().cloned().collect();
    let points2 = |gpu: &Gpu| Points::upload(gpu, [1000.0, 0.0, 0.0], &rev, &revc);
    let style = Style {
        background: [10, 20, 30, 255],
        ..fixed(1.0, Shape::Square)
    };
    for (gpu, r) in &paths() {
        let points = points(gpu);
        let points2 = points2(gpu);
        let img = r.render(gpu, &cam, &[points.all(0.0)], &[], &style);
        assert_eq!(img.len(), 200 * 100 * 4);
        assert_eq!(px(&img, 200, 100, 50), green, "{:?}: nearer wins", r.path);
        assert_eq!(px(&img, 200, 125, 50), blue, "{:?}", r.path);
        let drawn = img
            .chunks_exact(4)
            .filter(|p| *p != style.background)
            .count();
        assert_eq!(
            drawn, 2,
            "{:?}: two pixels drawn, the rest background",
            r.path
        );
        // Order of submission does not matter: the same image with the points reversed.
        assert_eq!(r.render(gpu, &cam, &[points2.all(0.0)], &[], &style), img);
        // A prefix draws only its points: the first is red at the centre.
        let img = r.render(gpu, &cam, &[points.prefix(1, 0.0)], &[], &style);
        assert_eq!(px(&img, 200, 100, 50), red, "{:?}: prefix of one", r.path);
        assert_eq!(px(&img, 200, 125, 50), style.background);
    }
}

#[test]
fn many_points_fill_a_plane() {
    // A 512 x 512 grid seen straight on fills the view where it covers it.
    let n = 512;
    let mut positions = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            positions.push([
                i as f64 / n as f64 * 2.0 - 1.0,
                0.0,
                j as f64 / n as f64 * 2.0 - 1.0,
            ]);
        }
    }
    let colours = vec![[200, 100, 50, 255]; positions.len()];
    let points = |gpu: &Gpu| Points::upload(gpu, [0.0; 3], &positions, &colours);
    let cam = Camera {
        position: [0.0, -1.0, 0.0],
        target: [0.0, 0.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 90.0,
        width: 128,
        height: 128,
        near: 0.1,
        far: 10.0,
    };
    for (gpu, r) in &paths() {
        let points = points(gpu);
        let img = r.render(
            gpu,
            &cam,
            &[points.all(0.0)],
            &[],
            &fixed(1.0, Shape::Square),
        );
        let drawn = img.chunks_exact(4).filter(|p| p[0] == 200).count();
        // The plane covers the whole view (±1 at depth 1 with 90 degrees), 4 points per pixel.
        assert_eq!(drawn, 128 * 128, "{:?}", r.path);
    }
}

#[test]
fn point_sizes_and_shapes() {
    let cam = looking_along_y(0.0);
    let white = [255, 255, 255, 255];
    let lit = |img: &[u8]| img.chunks_exact(4).filter(|p| *p == white).count();
    let p = |gpu: &Gpu| Points::upload(gpu, [0.0; 3], &[[0.0, 0.0, 0.0]], &[white]);
    for (gpu, r) in &paths() {
        let p = p(gpu);
        let path = r.path;
        let render =
            |spacing: f64, style: Style| lit(&r.render(gpu, &cam, &[p.all(spacing)], &[], &style));
        // Fixed: 5 x 5 pixels; round: without the 4 corners (their centres are 2.83 px out).
        assert_eq!(render(0.0, fixed(5.0, Shape::Square)), 25, "{path:?}");
        assert_eq!(render(0.0, fixed(5.0, Shape::Round)), 21, "{path:?}");
        assert_eq!(render(0.0, fixed(5.0, Shape::Paraboloid)), 21, "{path:?}");
        // 9 px round: the pixels within 4.5 px of the centre.
        let disc = (-4i32..=4)
            .flat_map(|y| (-4i32..=4).map(move |x| x * x + y * y))
            .filter(|&d2| d2 as f64 <= 20.25)
            .count();
        assert_eq!(render(0.0, fixed(9.0, Shape::Round)), disc, "{path:?}");
        // Adaptive: spacing 0.8 at depth 10 is 0.8 * 50 / 10 = 4 pixels (focal 50 for 100 px).
        let adaptive = |max| Style {
            size: PointSize::Adaptive { scale: 1.0, max },
            ..fixed(1.0, Shape::Square)
        };
        assert_eq!(render(0.8, adaptive(64.0)), 16, "{path:?}");
        // Capped.
        assert_eq!(render(100.0, adaptive(3.0)), 9, "{path:?}");
        // Scaled: 0.8 * 1.5 at depth 10 is 6 pixels.
        let scaled = Style {
            size: PointSize::adaptive(),
            ..fixed(1.0, Shape::Square)
        };
        assert_eq!(render(0.8, scaled), 36, "{path:?}");
    }
}

#[test]
fn adaptive_sizes_come_from_the_finest_drawn_node_around_each_point() {
    let cam = looking_along_y(0.0);
    let (red, green) = ([255, 0, 0, 255], [0, 255, 0, 255]);
    // A root node (cube -8..8, spacing 1.6) with one drawn child, octant 0 (spacing 0.4). Both
    // points belong to the root, at depth 9: one inside the child's cube takes its spacing
    // (0.4 * 50 / 9 = 2.2: 2 px), the other keeps the root's (1.6 * 50 / 9 = 8.9: 9 px).
    let p = |gpu: &Gpu| {
        Points::upload(
            gpu,
            [0.0; 3],
            &[[-4.0, -1.0, -4.0], [4.0, -1.0, 4.0]],
            &[red, green],
        )
    };
    let tree = [[1, 1, 1.6f32.to_bits(), 0], [0, 0, 0.4f32.to_bits(), 0]];
    let cube = myriad_core::Aabb::new([-8.0; 3], [8.0; 3]);
    let style = Style {
        size: PointSize::Adaptive {
            scale: 1.0,
            max: 64.0,
        },
        ..fixed(1.0, Shape::Square)
    };
    let count = |img: &[u8], c: [u8; 4]| img.chunks_exact(4).filter(|p| *p == c).count();
    for (gpu, r) in &paths() {
        let p = p(gpu);
        let mut d = p.all(1.6);
        d.node = Some((0, cube));
        let img = r.render(gpu, &cam, &[d], &tree, &style);
        assert_eq!(
            (count(&img, red), count(&img, green)),
            (4, 81),
            "{:?}",
            r.path
        );
        // Without the tree: both 9 px.
        let img = r.render(gpu, &cam, &[p.all(1.6)], &[], &style);
        assert_eq!(
            (count(&img, red), count(&img, green)),
            (81, 81),
            "{:?}",
            r.path
        );
    }
}

#[test]
fn the_clipping_box_keeps_the_inside_or_the_outside() {
    let cam = looking_along_y(1000.0);
    let white = [255, 255, 255, 255];
    // Five points across the view at depth 10, x = 990, 995, 1000, 1005, 1010.
    let positions: Vec<[f64; 3]> = (0..5).map(|i| [990.0 + 5.0 * i as f64, 0.0, 0.0]).collect();
    let lit = |img: &[u8]| img.chunks_exact(4).filter(|p| *p == white).count();
    let box_ = myriad_core::Aabb::new([994.0, -1.0, -1.0], [1006.0, 1.0, 1.0]);
    for (gpu, r) in &paths() {
        let p = Points::upload(gpu, [1000.0, 0.0, 0.0], &positions, &[white; 5]);
        let style = |clip| Style {
            clip,
            ..fixed(1.0, Shape::Square)
        };
        let render = |clip| lit(&r.render(gpu, &cam, &[p.all(0.0)], &[], &style(clip)));
        assert_eq!(render(None), 5, "{:?}", r.path);
        let inside = myriad_render::Clip {
            bounds: box_,
            inside: true,
        };
        assert_eq!(render(Some(inside)), 3, "{:?}: 995, 1000, 1005", r.path);
        let outside = myriad_render::Clip {
            inside: false,
            ..inside
        };
        assert_eq!(render(Some(outside)), 2, "{:?}: 990 and 1010", r.path);
    }
}

#[test]
fn paraboloids_meet_halfway() {
    let cam = looking_along_y(0.0);
    // Two 15-pixel points at the same depth, 8 pixels apart (1.6 units at 5 px per unit).
    let (a, b) = ([255, 0, 0, 255], [0, 0, 255, 255]);
    let p =
        |gpu: &Gpu| Points::upload(gpu, [0.0; 3], &[[-0.8, 0.0, 0.0], [0.8, 0.0, 0.0]], &[a, b]);
    for (gpu, r) in &paths() {
        let p = p(gpu);
        let img = r.render(
            gpu,
            &cam,
            &[p.all(0.0)],
            &[],
            &fixed(15.0, Shape::Paraboloid),
        );
        // Centres at pixels 96 and 104: each point owns the overlap on its own side.
        for x in 97..100 {
            assert_eq!(px(&img, 200, x, 50), a, "{:?}: x {x}", r.path);
        }
        for x in 101..104 {
            assert_eq!(px(&img, 200, x, 50), b, "{:?}: x {x}", r.path);
        }
        // Flat discs at the same depth: one of them takes the whole overlap.
        let img = r.render(gpu, &cam, &[p.all(0.0)], &[], &fixed(15.0, Shape::Round));
        let overlap: Vec<[u8; 4]> = (97..104).map(|x| px(&img, 200, x, 50)).collect();
        assert!(overlap.iter().all(|c| *c == overlap[0]), "{:?}", r.path);
    }
}

#[test]
fn eye_dome_lighting_darkens_behind_edges_only() {
    let cam = looking_along_y(0.0);
    // A near plane (depth 8) on the left half, a far plane (depth 12) on the right half.
    // Both fill their half of the view without gaps at 2 px a point (6.25 and 4.17 px per unit).
    let mut positions = Vec::new();
    for i in 0..200 {
        for j in 0..200 {
            positions.push([i as f64 * 0.1 - 20.0, -2.0, j as f64 * 0.1 - 10.0]);
        }
    }
    for i in 0..100 {
        for j in 0..100 {
            positions.push([i as f64 * 0.4, 2.0, j as f64 * 0.4 - 20.0]);
        }
    }
    let grey = [200, 200, 200, 255];
    let p = |gpu: &Gpu| Points::upload(gpu, [0.0; 3], &positions, &vec![grey; positions.len()]);
    for (gpu, r) in &paths() {
        let p = p(gpu);
        let plain = r.render(gpu, &cam, &[p.all(0.0)], &[], &fixed(2.0, Shape::Square));
        let lit = r.render(
            gpu,
            &cam,
            &[p.all(0.0)],
            &[],
            &Style {
                passes: Passes {
                    edl: Some(Edl::default()),
                    ..Passes::default()
                },
                ..fixed(2.0, Shape::Square)
            },
        );
        let path = r.path;
        assert_eq!(px(&plain, 200, 101, 50), grey, "{path:?}");
        // Just right of the step (x = 100), behind its neighbours: darker.
        assert!(
            px(&lit, 200, 101, 50)[0] < 150,
            "{path:?}: {:?}",
            px(&lit, 200, 101, 50)
        );
        // In front of the step and away from it: unchanged.
        for x in [20, 98, 99, 150, 180] {
            assert_eq!(px(&lit, 200, x, 50), grey, "{path:?}: x {x}");
        }
    }
}

#[test]
fn every_path_draws_the_cpus_image() {
    // Random points in a box, random colours, seen at an angle: every path agrees with the CPU
    // on almost every pixel (they may differ where two points reach a pixel at the same depth,
    // which the quad path's depth test breaks by order, or by the last bit of depth).
    let mut next = common::random(0x2545f4914f6cdd1d);
    let n = 20000;
    let positions: Vec<[f64; 3]> = (0..n)
        .map(|_| [next() * 10.0 - 5.0, next() * 10.0 - 5.0, next() * 4.0])
        .collect();
    let colours: Vec<[u8; 4]> = (0..n)
        .map(|_| [(next() * 255.0) as u8, (next() * 255.0) as u8, 99, 255])
        .collect();
    let cam = Camera {
        position: [3.0, -14.0, 9.0],
        target: [0.0, 0.0, 1.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 50.0,
        width: 320,
        height: 240,
        near: 1.0,
        far: 40.0,
    };
    let paths = paths();
    // The last run draws the points as splats of random normals and radii.
    let normals: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            let v = [next() - 0.5, next() - 0.5, next() - 0.5].map(|x| x as f32);
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-3);
            v.map(|x| x / l)
        })
        .collect();
    let radii: Vec<f32> = (0..n).map(|_| (0.02 + next() * 0.1) as f32).collect();
    let splats: Vec<Points> = paths
        .iter()
        .map(|(gpu, _)| {
            Points::upload_splats(gpu, [0.0; 3], &positions, &colours, &normals, &radii)
        })
        .collect();
    let uploaded: Vec<Points> = paths
        .iter()
        .map(|(gpu, _)| Points::upload(gpu, [0.0; 3], &positions, &colours))
        .collect();
    for (style, uploaded) in [
        fixed(3.0, Shape::Square),
        fixed(6.0, Shape::Round),
        fixed(6.0, Shape::Paraboloid),
        Style {
            size: PointSize::Adaptive {
                scale: 1.0,
                max: 16.0,
            },
            passes: Passes::parse("edl").unwrap(),
            ..fixed(1.0, Shape::Round)
        },
    ]
    .into_iter()
    .map(|s| (s, &uploaded))
    .chain([(
        Style {
            size: PointSize::adaptive(),
            ..fixed(1.0, Shape::Square)
        },
        &splats,
    )]) {
        let images: Vec<Vec<u8>> = paths
            .iter()
            .zip(uploaded)
            .map(|((gpu, r), p)| r.render(gpu, &cam, &[p.all(0.15)], &[], &style))
            .collect();
        let a = &images[0];
        let pixels = a.len() / 4;
        let drawn = a.chunks_exact(4).filter(|c| *c != [0, 0, 0, 255]).count();
        // (Eye-dome lighting turns most of a random cloud nearly black.)
        assert!(
            style.passes.edl.is_some() || drawn > pixels / 4,
            "{style:?}: only {drawn} pixels drawn"
        );
        for ((_, r), b) in paths.iter().zip(&images).skip(1) {
            let differ = a
                .chunks_exact(4)
                .zip(b.chunks_exact(4))
                .filter(|(x, y)| x.iter().zip(y.iter()).any(|(p, q)| p.abs_diff(*q) > 2))
                .count();
            // The compute path does what the CPU does, bit for bit but for rounding.
            let allowed = if r.path == Path::Compute { 1000 } else { 100 };
            assert!(
                differ * allowed < pixels,
                "{:?}, {style:?}: {differ} of {pixels} pixels differ from the CPU's",
                r.path
            );
        }
    }
}

#[test]
fn splats_are_oriented_discs_on_every_path() {
    // One splat of radius 1 at depth 10 (focal 50 pixels: a disc of 5 pixels' radius), seen
    // face-on, tilted by 60 degrees about the vertical (an ellipse half as wide), and edge-on.
    let cam = looking_along_y(0.0);
    let white = [[255, 255, 255, 255]];
    let adaptive = Style {
        size: PointSize::adaptive(),
        ..fixed(1.0, Shape::Square)
    };
    let paths = paths();
    let t = 60f32.to_radians();
    for (normal, want) in [
        ([0.0, -1.0, 0.0], std::f32::consts::PI * 25.0),
        ([t.sin(), -t.cos(), 0.0], std::f32::consts::PI * 25.0 * 0.5),
    ] {
        for (gpu, r) in &paths {
            let p = Points::upload_splats(gpu, [0.0; 3], &[[0.0; 3]], &white, &[normal], &[1.0]);
            let img = r.render(gpu, &cam, &[p.all(0.0)], &[], &adaptive);
            let drawn = img.chunks_exact(4).filter(|c| c[0] == 255).count() as f32;
            assert!(
                (drawn - want).abs() < want * 0.2 + 4.0,
                "{:?} {normal:?}: {drawn} pixels, about {want} expected",
                r.path
            );
            // Tilted about the vertical: narrower than high.
            let row = |y: usize| (0..200).filter(|&x| px(&img, 200, x, y)[0] == 255).count();
            let col = |x: usize| (0..100).filter(|&y| px(&img, 200, x, y)[0] == 255).count();
            if normal[0] != 0.0 {
                assert!(
                    row(50) * 3 < col(100) * 2,
                    "{:?}: {} {}",
                    r.path,
                    row(50),
                    col(100)
                );
            } else {
                assert_eq!(row(50), col(100), "{:?}", r.path);
            }
        }
    }
    // A tilted splat's depth follows its plane: two splats crossing at right angles at the
    // same centre, each wins on the side where it is nearer.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    for (gpu, r) in &paths {
        let p = Points::upload_splats(
            gpu,
            [0.0; 3],
            &[[0.0; 3], [0.0; 3]],
            &[[255, 0, 0, 255], [0, 0, 255, 255]],
            &[[s, -s, 0.0], [-s, -s, 0.0]],
            &[1.0, 1.0],
        );
        let img = r.render(gpu, &cam, &[p.all(0.0)], &[], &adaptive);
        // The first lies in the plane y = x (farther to the right), the second in y = -x
        // (nearer to the right): blue on the right, red on the left.
        assert_eq!(px(&img, 200, 102, 50), [0, 0, 255, 255], "{:?}", r.path);
        assert_eq!(px(&img, 200, 97, 50), [255, 0, 0, 255], "{:?}", r.path);
    }
    // Fixed sizes ignore the splats: one pixel.
    for (gpu, r) in &paths {
        let p = Points::upload_splats(
            gpu,
            [0.0; 3],
            &[[0.0; 3]],
            &white,
            &[[0.0, -1.0, 0.0]],
            &[1.0],
        );
        let img = r.render(gpu, &cam, &[p.all(0.0)], &[], &fixed(1.0, Shape::Square));
        assert_eq!(img.chunks_exact(4).filter(|c| c[0] == 255).count(), 1);
    }
}

/// A room's corner: a floor and two walls of jittered grid points, a few left out, so that
/// there are holes to fill, edges, corners and slopes for every pass.
fn corner_room(gpu: &Gpu, splats: bool) -> Points {
    let mut next = common::random(0x9e3779b97f4a7c15);
    let (mut positions, mut colours, mut normals) = (Vec::new(), Vec::new(), Vec::new());
    for plane in 0..3 {
        for i in 0..120 {
            for j in 0..120 {
                if next() < 0.05 {
                    continue;
                }
                let (a, b) = (
                    (i as f64 + next() * 0.5) / 12.0,
                    (j as f64 + next() * 0.5) / 12.0,
                );
                let (p, n) = match plane {
                    0 => ([a, b, 0.0], [0.0, 0.0, 1.0]),
                    1 => ([a, 10.0, b], [0.0, -1.0, 0.0]),
                    _ => ([10.0, a, b], [-1.0, 0.0, 0.0]),
                };
                positions.push(p);
                normals.push(n);
                let c = (120 + plane * 50 + (next() * 30.0) as usize) as u8;
                colours.push([c, 200 - c / 2, 90, 255]);
            }
        }
    }
    if splats {
        let radii = vec![0.06f32; positions.len()];
        Points::upload_splats(gpu, [0.0; 3], &positions, &colours, &normals, &radii)
    } else {
        Points::upload(gpu, [0.0; 3], &positions, &colours)
    }
}

#[test]
fn every_pass_agrees_between_the_cpu_and_the_gpu_paths() {
    let cam = Camera {
        position: [-4.0, -6.0, 7.0],
        target: [6.0, 6.0, 2.0],
        up: [0.0, 0.0, 1.0],
        fov_y: 60.0,
        width: 240,
        height: 160,
        near: 0.5,
        far: 60.0,
    };
    let paths = paths();
    for splats in [false, true] {
        let points: Vec<Points> = paths.iter().map(|(g, _)| corner_room(g, splats)).collect();
        for chain in [
            "none",
            "fill",
            "shade",
            "ssao",
            "edl",
            "blur",
            "aa",
            "blend",
            "blend,fill,shade,edl,aa",
            "fill,shade,ssao,edl,blur,aa",
        ] {
            let style = Style {
                size: if splats {
                    PointSize::adaptive()
                } else {
                    PointSize::Fixed(1.0)
                },
                passes: Passes::parse(chain).unwrap(),
                background: [20, 30, 40, 255],
                ..fixed(1.0, Shape::Square)
            };
            let images: Vec<Vec<u8>> = paths
                .iter()
                .zip(&points)
                .map(|((gpu, r), p)| r.render(gpu, &cam, &[p.all(1.0 / 12.0)], &[], &style))
                .collect();
            let cpu = &images[0];
            assert_eq!(cpu.len(), 240 * 160 * 4, "{chain}: the image's size");
            let drawn = cpu
                .chunks_exact(4)
                .filter(|c| *c != style.background)
                .count();
            assert!(drawn > 240 * 160 / 3, "{chain}: {drawn} pixels drawn");
            for ((_, r), img) in paths.iter().zip(&images).skip(1) {
                let differ = cpu
                    .chunks_exact(4)
                    .zip(img.chunks_exact(4))
                    .filter(|(x, y)| x.iter().zip(y.iter()).any(|(p, q)| p.abs_diff(*q) > 3))
                    .count();
                // Depth from the quad path's depth buffer, and normals through an 8-bit target,
                // differ in the last bits: a few pixels may round the other way.
                eprintln!(
                    "{:?} splats {splats} {chain}: {differ} pixels differ",
                    r.path
                );
                assert!(
                    differ <= drawn / 200,
                    "{:?}, splats {splats}, passes {chain}: {differ} of {drawn} pixels differ from the CPU's",
                    r.path
                );
            }
        }
    }
}

#[test]
fn splat_normals_reach_the_shading_pass() {
    // A plane of splats facing the eye, with normals tilted 60 degrees: shading by the splats'
    // normals darkens it; normals from depth would light it fully.
    let cam = looking_along_y(0.0);
    let mut positions = Vec::new();
    for i in 0..80 {
        for j in 0..80 {
            positions.push([i as f64 * 0.25 - 10.0, 0.0, j as f64 * 0.25 - 10.0]);
        }
    }
    let n = positions.len();
    let tilt = [0.866f32, -0.5, 0.0];
    let grey = vec![[200u8, 200, 200, 255]; n];
    let style = Style {
        size: PointSize::adaptive(),
        passes: Passes::parse("shade").unwrap(),
        ..fixed(1.0, Shape::Square)
    };
    for (gpu, r) in &paths() {
        let p = Points::upload_splats(
            gpu,
            [0.0; 3],
            &positions,
            &grey,
            &vec![tilt; n],
            &vec![0.3; n],
        );
        let img = r.render(gpu, &cam, &[p.all(0.25)], &[], &style);
        let v = px(&img, 200, 100, 50)[0] as f32;
        // ambient 0.2 + headlight 0.8 x cos 60 = 0.6 of 200.
        assert!((v - 120.0).abs() <= 6.0, "{:?}: {v}", r.path);
    }
}

#[test]
fn blended_points_mix_where_they_overlap_and_not_through_a_surface() {
    // A red and a blue 5-pixel square side by side at depth 10 (5 pixels a unit): red centred
    // at column 100.0 covers 98-102, blue at 102.5 covers 100-104; and a green one 2 units
    // behind them, beyond the blend's reach (one point's size, 1 unit there), hidden by them.
    let cam = looking_along_y(0.0);
    let positions = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.2, 2.0, 0.0]];
    let colours = [[255, 0, 0, 255], [0, 0, 255, 255], [0, 255, 0, 255]];
    let plain = fixed(5.0, Shape::Square);
    let blended = Style {
        passes: Passes::parse("blend").unwrap(),
        ..plain
    };
    for (gpu, r) in &paths() {
        let p = Points::upload(gpu, [0.0; 3], &positions, &colours);
        let img = r.render(gpu, &cam, &[p.all(0.0)], &[], &plain);
        // Without blending the nearest wins, one colour a pixel.
        for x in 98..104 {
            let c = px(&img, 200, x, 50);
            assert!(c[0] == 0 || c[2] == 0, "{:?}: {x}: {c:?}", r.path);
        }
        let img = r.render(gpu, &cam, &[p.all(0.0)], &[], &blended);
        // Outside the overlap each square keeps its own colour; inside, both, each the more
        // where its centre is nearer (100: 0.5 px from red's centre, 2 from blue's; 101: 1.5
        // and 1).
        assert_eq!(px(&img, 200, 99, 50), [255, 0, 0, 255], "{:?}", r.path);
        assert_eq!(px(&img, 200, 103, 50), [0, 0, 255, 255], "{:?}", r.path);
        let (a, b) = (px(&img, 200, 100, 50), px(&img, 200, 101, 50));
        assert!(a[0] > a[2] && a[2] > 30, "{:?}: {a:?}", r.path);
        assert!(b[2] > b[0] && b[0] > 30, "{:?}: {b:?}", r.path);
        // Red and blue add up to the whole: a mean of the two colours.
        assert!((a[0] as i32 + a[2] as i32 - 255).abs() <= 1, "{a:?}");
        // Nothing of the green point behind them.
        assert!(
            img.chunks_exact(4).all(|c| c[1] == 0),
            "{:?}: green shows through",
            r.path
        );
    }
}
