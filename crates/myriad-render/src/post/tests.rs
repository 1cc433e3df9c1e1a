//! Each pass on synthetic g-buffers with known answers (the CPU mirror; tests/headless.rs checks
//! that the GPU paths agree with it).

use super::*;

const W: u32 = 64;
const H: u32 = 48;
const FOCAL: f32 = 60.0;

fn view(factor: u32) -> View {
    View {
        width: W * factor,
        height: H * factor,
        factor,
        focal: FOCAL * factor as f32,
        sun: [0.0, 0.0, -1.0],
        background: [0, 0, 255, 255],
        eye_width: 0,
    }
}

const GREY: u32 = u32::from_le_bytes([200, 200, 200, 255]);

/// A g-buffer of the surface `depth(x, y)` (0: nothing) in grey.
fn surface(depth: impl Fn(i32, i32) -> f32) -> GBuffer {
    let mut g = GBuffer::new(W, H);
    for y in 0..H as i32 {
        for x in 0..W as i32 {
            let i = (y * W as i32 + x) as usize;
            g.depth[i] = depth(x, y);
            g.colour[i] = if g.depth[i] > 0.0 { GREY } else { 0 };
        }
    }
    g
}

fn pixel(img: &[u8], x: u32, y: u32) -> [u8; 4] {
    let i = ((y * W + x) * 4) as usize;
    img[i..i + 4].try_into().unwrap()
}

fn only(p: &str) -> Passes {
    Passes::parse(p).unwrap()
}

#[test]
fn passes_parse_in_any_order_and_reject_unknown_names() {
    let p = Passes::parse("aa,blur, edl,ssao,shade,fill,blend").unwrap();
    assert_eq!(p, Passes::parse(&PASS_NAMES.join(",")).unwrap());
    assert!(p.blend && !Passes::parse("fill").unwrap().blend);
    assert!(p.fill.is_some() && p.shade.is_some() && p.ssao.is_some());
    assert!(p.edl.is_some() && p.blur.is_some() && p.factor() == 2);
    // The pipeline's order, whatever the order given; normals for shade and ssao.
    assert_eq!(
        p.steps(),
        [
            "fill_rows",
            "fill_columns",
            "normals",
            "shade",
            "ssao",
            "edl",
            "blur"
        ]
    );
    assert_eq!(
        Passes::parse("blur,fill").unwrap().steps(),
        ["fill_rows", "fill_columns", "blur"]
    );
    assert_eq!(Passes::parse("none").unwrap(), Passes::default());
    assert!(Passes::parse("none").unwrap().steps().is_empty());
    assert!(Passes::parse("fill,glow").unwrap_err().contains("glow"));
}

#[test]
fn normals_round_trip_through_their_code() {
    for n in [[0.0, 0.0, -1.0], [0.6, -0.8, 0.0], [-0.36, 0.48, -0.8]] {
        let m = unpack_normal(pack_normal(n));
        assert!((0..3).all(|k| (m[k] - n[k]).abs() < 0.01), "{n:?} {m:?}");
        assert_ne!(pack_normal(n), 0, "0 means no normal");
    }
}

#[test]
fn no_pass_shows_the_colours_and_the_background() {
    let g = surface(|x, _| if x < 32 { 10.0 } else { 0.0 });
    let img = run(g, &Passes::default(), &view(1));
    assert_eq!(pixel(&img, 5, 5), [200, 200, 200, 255]);
    assert_eq!(pixel(&img, 40, 5), [0, 0, 255, 255]);
}

#[test]
fn a_flat_plane_lit_head_on_is_uniform() {
    let g = surface(|_, _| 10.0);
    let img = run(g, &only("shade"), &view(1));
    let first = pixel(&img, 0, 0);
    // ambient + headlight = 1: the colour as it was.
    assert_eq!(first, [200, 200, 200, 255]);
    for y in 0..H {
        for x in 0..W {
            assert_eq!(pixel(&img, x, y), first, "({x}, {y})");
        }
    }
}

#[test]
fn shading_shows_a_tilted_plane_darker_than_a_facing_one() {
    // Left half faces the eye; right half recedes to the right (depth grows with x).
    let g = surface(|x, _| {
        if x < 32 {
            10.0
        } else {
            10.0 + (x - 32) as f32 * 0.3
        }
    });
    let img = run(g, &only("shade"), &view(1));
    let facing = pixel(&img, 10, 20)[0];
    let tilted = pixel(&img, 50, 20)[0];
    assert_eq!(facing, 200);
    assert!(tilted < 180, "tilted {tilted}");
}

#[test]
fn ssao_darkens_an_inner_corner_and_not_an_open_plane() {
    // An open plane facing the eye.
    let plane = run(surface(|_, _| 10.0), &only("ssao"), &view(1));
    assert!(
        plane.chunks(4).all(|p| p[0] == 200),
        "an open plane is not occluded"
    );
    // An inner corner: two planes (1 / depth linear across the image) meeting at x = 32 at the
    // far end, each receding towards it (a V seen from its open side).
    let corner = |x: i32, _| 1.0 / (0.1 - (32 - (x - 32).abs()) as f32 * 0.0015);
    let img = run(surface(corner), &only("ssao"), &view(1));
    // An open wall away from the corner: its own plane does not occlude it.
    let open = |x: i32, _| 1.0 / (0.1 - x as f32 * 0.0015);
    let tilted = run(surface(open), &only("ssao"), &view(1));
    assert!(
        (12..20).all(|x| pixel(&tilted, x, 24)[0] >= 195),
        "a tilted open plane is not occluded"
    );
    let at_corner = pixel(&img, 32, 24)[0];
    let away = pixel(&img, 8, 24)[0];
    assert!(at_corner <= 175, "the corner is darkened: {at_corner}");
    assert!(away >= 195, "the open wall is not: {away}");
}

#[test]
fn fill_closes_a_one_pixel_hole_and_leaves_a_depth_edge_alone() {
    let mut g = surface(|x, _| if x < 40 { 10.0 } else { 20.0 });
    // A hole (nothing drawn) and a pixel where the far surface shows through the near one.
    let hole = (10 * W + 10) as usize;
    g.depth[hole] = 0.0;
    let through = (20 * W + 20) as usize;
    g.depth[through] = 20.0;
    g.colour[through] = u32::from_le_bytes([0, 255, 0, 255]);
    // The far surface's colour differs, so that a bleed would show.
    for y in 0..H as usize {
        for x in 40..W as usize {
            g.colour[y * W as usize + x] = u32::from_le_bytes([255, 0, 0, 255]);
        }
    }
    let before = run(g.clone(), &Passes::default(), &view(1));
    assert_eq!(pixel(&before, 10, 10), [0, 0, 255, 255], "a hole");
    let img = run(g, &only("fill"), &view(1));
    assert_eq!(pixel(&img, 10, 10), [200, 200, 200, 255], "the hole filled");
    assert_eq!(
        pixel(&img, 20, 20),
        [200, 200, 200, 255],
        "the far pixel covered"
    );
    // The edge: the far surface's first columns keep their colour.
    for y in 0..H {
        for x in 40..W {
            assert_eq!(pixel(&img, x, y), [255, 0, 0, 255], "({x}, {y}) bled over");
        }
        assert_eq!(pixel(&img, 39, y), [200, 200, 200, 255]);
    }
}

#[test]
fn every_pass_skips_the_hidden_pixels() {
    // A hole amid a surface: fill closes it, unless the hole is hidden (a headset's lens does
    // not show it); then no pass touches it, its neighbours see it empty, and it is black.
    let mut g = surface(|_, _| 10.0);
    let hole = (10 * W + 10) as usize;
    g.depth[hole] = 0.0;
    let mut mask = vec![false; (W * H) as usize];
    mask[hole] = true;
    let all = only("fill,shade,ssao,edl,blur");
    let open = run(g.clone(), &all, &view(1));
    assert_ne!(pixel(&open, 10, 10), [0, 0, 255, 255], "filled");
    let masked = run_masked(g.clone(), &all, &view(1), Some(&mask));
    // Left empty by the passes, black in the image (not the background: the lens's edge).
    assert_eq!(pixel(&masked, 10, 10), [0, 0, 0, 255], "hidden: black");
    // Away from it, the same image.
    assert_eq!(pixel(&masked, 40, 30), pixel(&open, 40, 30));
    // No mask, or nothing hidden: `run`.
    assert_eq!(run_masked(g.clone(), &all, &view(1), None), open);
    let none = vec![false; (W * H) as usize];
    assert_eq!(run_masked(g, &all, &view(1), Some(&none)), open);
}

#[test]
fn fill_leaves_the_silhouette_against_the_background() {
    // A disc on nothing: no pixel outside it is filled.
    let disc = |x: i32, y: i32| {
        if (x - 32).pow(2) + (y - 24).pow(2) <= 100 {
            10.0
        } else {
            0.0
        }
    };
    let plain = run(surface(disc), &Passes::default(), &view(1));
    let filled = run(surface(disc), &only("fill"), &view(1));
    assert_eq!(plain, filled);
}

#[test]
fn blur_smooths_within_a_surface_and_not_across_an_edge() {
    let mut g = surface(|x, _| if x < 32 { 10.0 } else { 30.0 });
    // A checkerboard on the near surface; the far one white.
    for y in 0..H as usize {
        for x in 0..W as usize {
            g.colour[y * W as usize + x] = if x >= 32 {
                u32::from_le_bytes([255, 255, 255, 255])
            } else if (x + y) % 2 == 0 {
                u32::from_le_bytes([0, 0, 0, 255])
            } else {
                u32::from_le_bytes([200, 200, 200, 255])
            };
        }
    }
    let img = run(g, &only("blur"), &view(1));
    // Inside the checkerboard: near the mean (100), both parities.
    for x in [10, 11] {
        let v = pixel(&img, x, 10)[0] as i32;
        assert!((v - 100).abs() <= 15, "({x}, 10): {v}");
    }
    // The far surface next to the edge stays white.
    assert_eq!(pixel(&img, 32, 10), [255, 255, 255, 255]);
}

#[test]
fn edl_darkens_the_far_side_of_an_edge_only() {
    let g = surface(|x, _| if x < 32 { 10.0 } else { 20.0 });
    let e = run(g, &only("edl"), &view(1));
    assert_eq!(pixel(&e, 10, 10)[0], 200);
    assert_eq!(pixel(&e, 31, 10)[0], 200, "the near side is not darkened");
    assert!(pixel(&e, 32, 10)[0] < 100, "the far side is");
    assert_eq!(pixel(&e, 50, 10)[0], 200);
}

#[test]
fn supersampling_averages_each_block() {
    // At twice the size: the left half of each block drawn, the right half empty.
    let v = view(2);
    let mut g = GBuffer::new(v.width, v.height);
    for y in 0..v.height as usize {
        for x in (0..v.width as usize).step_by(2) {
            g.depth[y * v.width as usize + x] = 10.0;
            g.colour[y * v.width as usize + x] = u32::from_le_bytes([200, 100, 0, 255]);
        }
    }
    let img = run(g, &only("aa"), &v);
    assert_eq!(img.len(), (W * H * 4) as usize);
    // Half drawn, half background (0, 0, 255).
    assert_eq!(pixel(&img, 3, 3), [100, 50, 128, 255]);
}
