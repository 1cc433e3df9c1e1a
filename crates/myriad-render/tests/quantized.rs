//! Quantized positions on every path this machine runs: the images of f32 positions near and
//! far (where only the first position word is read), and points at UTM and ECEF coordinates on
//! exactly the pixels the camera puts them, with no crack where two nodes meet.

mod common;

use common::paths;
use myriad_format::page::Quantization;
use myriad_lod::Camera;
use myriad_render::{Encoding, Passes, PointSize, Points, Shape, Style};

const MM: Quantization = Quantization {
    scale: [0.001; 3],
    offset: [0.0; 3],
};

fn style(size: PointSize) -> Style {
    Style {
        size,
        shape: Shape::Square,
        passes: Passes::default(),
        background: [0, 0, 0, 255],
        clip: None,
    }
}

/// A 320 x 240 camera at `position` looking at `target`, Z up.
fn looking(position: [f64; 3], target: [f64; 3]) -> Camera {
    Camera {
        position,
        target,
        up: [0.0, 0.0, 1.0],
        fov_y: 50.0,
        width: 320,
        height: 240,
        near: 1.0,
        far: 5000.0,
    }
}

/// Pixels (of RGBA8 images) whose channels differ by more than 2.
fn differing(a: &[u8], b: &[u8]) -> usize {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(x, y)| x.iter().zip(y.iter()).any(|(p, q)| p.abs_diff(*q) > 2))
        .count()
}

#[test]
fn quantized_points_draw_the_images_of_f32_points_near_and_far() {
    // A wavy terrain of 100 x 100 m on a millimetre grid at UTM coordinates, coloured by place
    // as scans are, in four nodes of 50 x 50 m (16 bits an axis: two words each).
    let o = [500_000.0, 4_000_000.0, 200.0];
    let mut next = common::random(0x9e3779b97f4a7c15);
    type Node = (Vec<[f64; 3]>, Vec<[u8; 4]>);
    let mut nodes: Vec<Node> = vec![Default::default(); 4];
    for _ in 0..60_000 {
        let (x, y) = (next() * 100.0, next() * 100.0);
        let z = 5.0 + 3.0 * (x / 10.0).sin() * (y / 13.0).cos() + next() * 0.05;
        let p = [x, y, z].map(|v| (v * 1000.0).round() / 1000.0);
        let c = [(x * 2.55) as u8, (y * 2.55) as u8, (z * 25.0) as u8, 255];
        let n = &mut nodes[(x >= 50.0) as usize + 2 * (y >= 50.0) as usize];
        n.0.push([o[0] + p[0], o[1] + p[1], o[2] + p[2]]);
        n.1.push(c);
    }
    let centre = [o[0] + 50.0, o[1] + 50.0, o[2] + 5.0];
    let at = |distance: f64| {
        let position = [
            centre[0] - distance * 0.3,
            centre[1] - distance * 0.8,
            centre[2] + distance * 0.5,
        ];
        looking(position, centre)
    };
    // Near: every word is read; far (the terrain about 80 pixels wide; the first word's step,
    // 64 mm, under a tenth of a pixel): the first alone.
    let (near, far) = (at(60.0), at(300.0));
    for (gpu, r) in &paths() {
        let upload = |e: Encoding| -> Vec<Points> {
            nodes
                .iter()
                .map(|(p, c)| Points::encode(gpu, e, p, c))
                .collect()
        };
        let exact = upload(Encoding::F32 { origin: centre });
        let quantized = upload(Encoding::Grid(MM));
        assert!(quantized.iter().all(|p| p.words == 2));
        assert!(
            quantized
                .iter()
                .all(|p| p.read_words(&near, r.precision) == 2)
        );
        assert!(
            quantized
                .iter()
                .all(|p| p.read_words(&far, r.precision) == 1)
        );
        // Less than half the bytes of f32 on the GPU read far away, three quarters near.
        let bytes = |ps: &[Points], cam: &Camera| -> u32 {
            ps.iter()
                .map(|p| p.len * p.read_bytes(p.read_words(cam, r.precision)))
                .sum()
        };
        assert_eq!(bytes(&exact, &far), 16 * 60_000);
        assert_eq!(bytes(&quantized, &near), 12 * 60_000);
        assert_eq!(bytes(&quantized, &far), 8 * 60_000);
        // Far away, a sixteenth of the points (about one a pixel), as the level of detail
        // would draw them.
        for (name, cam, size, share) in [
            ("near, 3 px", near, PointSize::Fixed(3.0), 1),
            ("near, 1 px", near, PointSize::Fixed(1.0), 1),
            ("far, 1 px", far, PointSize::Fixed(1.0), 16),
            ("far, 2 px", far, PointSize::Fixed(2.0), 16),
        ] {
            let draw = |ps: &[Points]| {
                let draws: Vec<_> = ps.iter().map(|p| p.prefix(p.len / share, 0.5)).collect();
                r.render(gpu, &cam, &draws, &[], &style(size))
            };
            let (a, b) = (draw(&exact), draw(&quantized));
            let drawn = a.chunks_exact(4).filter(|c| *c != [0, 0, 0, 255]).count();
            assert!(drawn > 1000, "{:?} {name}: {drawn} pixels drawn", r.path);
            let differ = differing(&a, &b);
            // What f32 points change when the camera moves by half the precision (the most a
            // point read with its first word alone moves), sideways.
            let mut moved = cam;
            let shift = 0.5 * r.precision as f64 / cam.pixels_per_unit(cam.to_eye(centre)[2]);
            let (right, _, _) = cam.basis();
            for (a, r) in right.iter().enumerate() {
                moved.position[a] += r * shift;
                moved.target[a] += r * shift;
            }
            let draws: Vec<_> = exact.iter().map(|p| p.prefix(p.len / share, 0.5)).collect();
            let jitter = differing(&a, &r.render(gpu, &moved, &draws, &[], &style(size)));
            eprintln!(
                "{:?} {name}: {differ} of {drawn} pixels differ from f32's; {jitter} when f32's \
                 camera moves by half the precision",
                r.path
            );
            // Near, where every word is read, as the paths' own agreement (headless.rs): at
            // most 1 % of the pixels; far, no more than that camera move changes.
            assert!(
                differ * 100 < drawn || (share > 1 && differ <= jitter),
                "{:?} {name}: {differ} of {drawn} drawn pixels differ from f32's ({jitter})",
                r.path
            );
        }
    }
}

#[test]
fn utm_and_ecef_coordinates_land_on_their_pixels_without_cracks_between_nodes() {
    // 64 x 64 points 1 cm apart in two nodes of 32 columns, seen from above at 4 pixels per
    // centimetre, a quarter of a pixel off the pixel borders: every point on the pixel the
    // camera puts it (computed in f64), none elsewhere, the columns on both sides of the nodes'
    // border 4 pixels apart as everywhere; the same with the camera a hundredth of a pixel away.
    for corner in [
        [5_170_845.29, 3_964_547.02, 452.07],
        [6_378_137.0, 0.0, 0.0],
        [-2_694_045.0, -4_293_642.0, 3_857_878.0],
    ] {
        let (red, green) = ([255, 0, 0, 255], [0, 255, 0, 255]);
        let node = |columns: std::ops::Range<i32>| -> Vec<[f64; 3]> {
            columns
                .flat_map(|i| {
                    (0..64).map(move |j| {
                        [
                            corner[0] + i as f64 * 0.01,
                            corner[1] + j as f64 * 0.01,
                            corner[2],
                        ]
                    })
                })
                .collect()
        };
        let (left, right) = (node(0..32), node(32..64));
        // 4 px per cm: the camera 1/400 of the focal length above the points, its centre
        // between the 32nd and 33rd column and row, 1/8 px off.
        let focal = 128.0 / 30f64.to_radians().tan();
        let off = 0.125 / 400.0;
        let camera = |dx: f64| {
            let c = [corner[0] + 0.315 + off + dx, corner[1] + 0.315 + off];
            Camera {
                position: [c[0], c[1], corner[2] + focal / 400.0],
                target: [c[0], c[1], corner[2]],
                up: [0.0, 1.0, 0.0],
                fov_y: 60.0,
                width: 256,
                height: 256,
                near: 0.01,
                far: 10.0,
            }
        };
        let cam = camera(0.0);
        let mut expected = std::collections::HashMap::new();
        for (points, colour) in [(&left, red), (&right, green)] {
            for &p in points {
                let e = cam.to_eye(p);
                let x = (128.0 + e[0] * focal / e[2]).floor() as usize;
                let y = (128.0 - e[1] * focal / e[2]).floor() as usize;
                assert!(expected.insert((x, y), colour).is_none());
            }
        }
        for (gpu, r) in &paths() {
            let a = Points::encode(gpu, Encoding::Grid(MM), &left, &vec![red; left.len()]);
            let b = Points::encode(gpu, Encoding::Grid(MM), &right, &vec![green; right.len()]);
            let draws = [a.all(0.01), b.all(0.01)];
            let img = r.render(gpu, &cam, &draws, &[], &style(PointSize::Fixed(1.0)));
            let mut lit = std::collections::HashMap::new();
            for (i, px) in img.chunks_exact(4).enumerate() {
                if px != [0, 0, 0, 255] {
                    lit.insert((i % 256, i / 256), [px[0], px[1], px[2], px[3]]);
                }
            }
            assert_eq!(lit.len(), 4096, "{:?} at {corner:?}", r.path);
            assert_eq!(lit, expected, "{:?} at {corner:?}", r.path);
            let columns = |c: [u8; 4]| -> Vec<usize> {
                let mut xs: Vec<usize> = lit
                    .iter()
                    .filter(|(_, v)| **v == c)
                    .map(|(k, _)| k.0)
                    .collect();
                xs.sort();
                xs.dedup();
                xs
            };
            let (l, g) = (columns(red), columns(green));
            assert_eq!(
                g[0] - l[l.len() - 1],
                4,
                "{:?}: the border at {corner:?}",
                r.path
            );
            let moved = r.render(
                gpu,
                &camera(0.01 / 400.0),
                &draws,
                &[],
                &style(PointSize::Fixed(1.0)),
            );
            assert_eq!(moved, img, "{:?}: jitter at {corner:?}", r.path);
        }
    }
}

#[test]
fn points_drawn_behind_cover_their_own_pixels_and_lose_to_points_in_place() {
    // A wall of red points 10 x 10 m and, in the same plane, a blue one twice as wide over it
    // (an mwkd stand-in and a loaded node beside it: the same surface at two levels).
    let o = [500_000.0, 4_000_000.0, 200.0];
    let wall = |width: f64| -> Vec<[f64; 3]> {
        let n = (width * 10.0) as usize;
        (0..n * 100)
            .map(|i| {
                let (x, z) = ((i % n) as f64 * 0.1, (i / n) as f64 * 0.1);
                [o[0] + x, o[1], o[2] + z]
            })
            .collect()
    };
    let (red_at, blue_at) = (wall(10.0), wall(20.0));
    let camera = looking(
        [o[0] + 10.0, o[1] - 30.0, o[2] + 5.0],
        [o[0] + 10.0, o[1], o[2] + 5.0],
    );
    let (red, blue) = ([255u8, 0, 0, 255], [0u8, 0, 255, 255]);
    // The default share stand-ins are drawn behind by: 0.3 m at 30 m.
    const BEHIND: f32 = myriad_render::scene::STAND_INS_BEHIND;
    let count = |img: &[u8], c: [u8; 4]| img.chunks_exact(4).filter(|p| *p == c).count();
    for (gpu, r) in &paths() {
        let style = style(PointSize::Fixed(2.0));
        let reds = Points::encode(gpu, Encoding::Grid(MM), &red_at, &vec![red; red_at.len()]);
        let blues = Points::encode(
            gpu,
            Encoding::Grid(MM),
            &blue_at,
            &vec![blue; blue_at.len()],
        );
        fn draw(p: &Points, behind: f32) -> myriad_render::Draw<'_> {
            let mut d = p.all(0.1);
            d.behind = behind;
            d
        }
        // Alone, behind or not, the blue wall covers the same pixels.
        let in_place = r.render(gpu, &camera, &[draw(&blues, 0.0)], &[], &style);
        let pushed = r.render(gpu, &camera, &[draw(&blues, BEHIND)], &[], &style);
        let (a, b) = (count(&in_place, blue), count(&pushed, blue));
        assert!(a > 10_000, "{:?}: {a} blue pixels", r.path);
        assert!(
            differing(&in_place, &pushed) * 100 < a,
            "{:?}: {} of {a} pixels differ drawn behind ({b} blue)",
            r.path,
            differing(&in_place, &pushed)
        );
        // With the red wall in place, in either order: red wherever it is, blue beside it.
        let red_alone = count(
            &r.render(gpu, &camera, &[draw(&reds, 0.0)], &[], &style),
            red,
        );
        for order in [[true, false], [false, true]] {
            let draws: Vec<_> = order
                .iter()
                .map(|&is_red| {
                    if is_red {
                        draw(&reds, 0.0)
                    } else {
                        draw(&blues, BEHIND)
                    }
                })
                .collect();
            let img = r.render(gpu, &camera, &draws, &[], &style);
            let (rs, bs) = (count(&img, red), count(&img, blue));
            assert!(
                rs * 100 >= red_alone * 99,
                "{:?} {order:?}: {rs} red pixels of {red_alone}",
                r.path
            );
            assert!(
                (rs + bs) * 100 >= a * 99 && bs * 100 >= (a - red_alone) * 99,
                "{:?} {order:?}: {bs} blue, {rs} red, of {a}",
                r.path
            );
        }
    }
}
