//! The compute rasterizer on whatever adapter the machine has (lavapipe in CI): points land on
//! the pixels the camera puts them, the nearest wins, the rest is background.

use myriad_lod::Camera;
use myriad_render::{Gpu, PointSize, Points, Rasterizer};

fn gpu() -> Option<Gpu> {
    match Gpu::headless() {
        Ok(g) => Some(g),
        Err(e) => {
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED: {e}; rendering tests need a Vulkan driver (CI installs lavapipe)"
            );
            None
        }
    }
}

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

#[test]
fn points_land_where_the_camera_puts_them() {
    let Some(gpu) = gpu() else { return };
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
    let points = Points::upload(&gpu, [1000.0, 0.0, 0.0], &positions, &colours);
    let r = Rasterizer::new(&gpu);
    let bg = [10, 20, 30, 255];
    let img = r.render(&gpu, &cam, &[&points], bg, PointSize::Fixed(1.0));
    assert_eq!(img.len(), 200 * 100 * 4);
    let px = |x: usize, y: usize| -> [u8; 4] { img[(y * 200 + x) * 4..][..4].try_into().unwrap() };
    assert_eq!(px(100, 50), green, "the nearer point wins the centre pixel");
    assert_eq!(px(125, 50), blue);
    let drawn = img.chunks_exact(4).filter(|p| *p != bg).count();
    assert_eq!(drawn, 2, "two pixels drawn, the rest background");
    // Order of submission does not matter: the same image with the points reversed.
    let rev: Vec<[f64; 3]> = positions.iter().rev().cloned().collect();
    let revc: Vec<[u8; 4]> = colours.iter().rev().cloned().collect();
    let points2 = Points::upload(&gpu, [1000.0, 0.0, 0.0], &rev, &revc);
    assert_eq!(
        r.render(&gpu, &cam, &[&points2], bg, PointSize::Fixed(1.0)),
        img
    );
    eprintln!(
        "adapter: {} ({:?})",
        gpu.adapter.name, gpu.adapter.device_type
    );
}

#[test]
fn many_points_fill_a_plane() {
    let Some(gpu) = gpu() else { return };
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
    let points = Points::upload(&gpu, [0.0; 3], &positions, &colours);
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
    let img = Rasterizer::new(&gpu).render(
        &gpu,
        &cam,
        &[&points],
        [0, 0, 0, 255],
        PointSize::Fixed(1.0),
    );
    let drawn = img.chunks_exact(4).filter(|p| p[0] == 200).count();
    // The plane covers the whole view (±1 at depth 1 with 90 degrees), 4 points per pixel.
    assert_eq!(drawn, 128 * 128);
}

#[test]
fn point_sizes() {
    let Some(gpu) = gpu() else { return };
    let cam = looking_along_y(0.0);
    let white = [255, 255, 255, 255];
    let bg = [0, 0, 0, 255];
    let lit = |img: &[u8]| img.chunks_exact(4).filter(|p| *p == white).count();
    let r = Rasterizer::new(&gpu);
    let mut p = Points::upload(&gpu, [0.0; 3], &[[0.0, 0.0, 0.0]], &[white]);
    // Fixed: 5 x 5 pixels.
    assert_eq!(
        lit(&r.render(&gpu, &cam, &[&p], bg, PointSize::Fixed(5.0))),
        25
    );
    // Adaptive: spacing 0.8 at depth 10 is 0.8 * 50 / 10 = 4 pixels (focal 50 for 100 px at 90°).
    p.spacing = 0.8;
    let adaptive = PointSize::Adaptive { max: 64.0 };
    assert_eq!(lit(&r.render(&gpu, &cam, &[&p], bg, adaptive)), 16);
    // Capped.
    p.spacing = 100.0;
    assert_eq!(
        lit(&r.render(&gpu, &cam, &[&p], bg, PointSize::Adaptive { max: 3.0 })),
        9
    );
}
