//! The surface's cluster, move and reduce on the GPU (cluster.wgsl) against the CPU
//! (cluster.rs): the same cells with the same counts, means, boxes and normals.

mod common;
use common::random;
use myriad_core::Aabb;
use myriad_lod::Camera;
use myriad_render::surface::{self, Density, Grid, Normals, Surface};

fn camera() -> Camera {
    let mut c = Camera::framing(&Aabb::new([-1.0; 3], [1.0; 3]), 320, 240, 60.0);
    c.position = [3.0, -14.0, 9.0];
    c.target = [0.0, 0.0, 0.5];
    c.up = [0.0, 0.0, 1.0];
    c.near = 0.01;
    c.far = 1000.0;
    c
}

/// A wavy ground with a box standing on it, sampled at random, with colours.
fn scene() -> (Vec<[f64; 3]>, Vec<[u8; 4]>) {
    let mut r = random(7);
    let mut points = Vec::new();
    let mut colours = Vec::new();
    for i in 0..300_000 {
        let (x, y) = (r() * 10.0 - 5.0, r() * 10.0 - 5.0);
        let p = if i % 5 == 0 && x.abs() < 1.5 && y.abs() < 1.5 {
            // The box's top at height 2.
            [x, y, 2.0]
        } else {
            [x, y, 0.3 * (x * 0.8).sin() * (y * 0.6).cos()]
        };
        points.push(p);
        colours.push([
            (128.0 + 100.0 * r()) as u8,
            90,
            (p[2] * 50.0 + 100.0) as u8,
            255,
        ]);
    }
    (points, colours)
}

#[test]
fn gpu_and_cpu_make_the_same_cells() {
    let Some(gpu) = common::gpu_or_skip() else {
        return;
    };
    let cam = camera();
    let (points, colours) = scene();
    for s in [
        Surface::default(),
        Surface {
            neighbours: 0,
            ..Surface::default()
        },
        Surface {
            neighbours: 1,
            normals: Normals::Cells,
            ..Surface::default()
        },
        Surface {
            density: Density::Planarity,
            ..Surface::default()
        },
    ] {
        let s = Surface {
            grid: [64, 48, 24],
            ..s
        };
        let grid = Grid::frustum(&cam, s.grid, &points).expect("in view");
        let cpu = surface::cluster(&cam, &grid, &points, &colours, &s);
        let gpu = surface::gpu::cluster(&gpu, &cam, &grid, &points, &colours, &s).unwrap();
        assert_eq!(cpu.inside, points.len());
        // f32 against f64 at the cells' borders: a point in ten thousand may fall on the other
        // side of one.
        assert!(
            gpu.inside.abs_diff(cpu.inside) * 10_000 <= points.len(),
            "{s:?}"
        );
        let same_cell = cpu
            .of_point
            .iter()
            .zip(&gpu.of_point)
            .filter(|&(&a, &b)| {
                a != u32::MAX
                    && b != u32::MAX
                    && cpu.cells[a as usize].index == gpu.cells[b as usize].index
            })
            .count();
        assert!(
            same_cell * 1000 >= points.len() * 999,
            "{s:?}: {same_cell} of {} points in the same cell",
            points.len()
        );
        assert!(
            gpu.moved.abs_diff(cpu.moved) * 1000 <= points.len(),
            "{s:?}: moved {} against {}",
            gpu.moved,
            cpu.moved
        );
        assert!(
            gpu.cells.len().abs_diff(cpu.cells.len()) * 200 <= cpu.cells.len(),
            "{s:?}"
        );
        // Cell by cell where both have the cell with the same count.
        let mut compared = 0;
        let mut apart = Vec::new();
        let mut dots = Vec::new();
        let mut j = 0;
        // Both lists are in key order: layer, row, column.
        let key = |c: &surface::Cell| [c.index[2], c.index[1], c.index[0]];
        for c in &cpu.cells {
            while j < gpu.cells.len() && key(&gpu.cells[j]) < key(c) {
                j += 1;
            }
            let Some(g) = gpu
                .cells
                .get(j)
                .filter(|g| g.index == c.index && g.count == c.count)
            else {
                continue;
            };
            compared += 1;
            let side = grid.extent(c.mean[2]);
            // The mean within a thousandth of a cell; the box within two 1024ths (its quantum).
            // A cell may hold the same count of other points: one point moved out by f32 at a
            // move boundary, another in (since the move works in half cells, December 4, about
            // 40 % of the points move, and a few cells in a thousand do so).
            let near = (0..3).all(|a| {
                (g.mean[a] - c.mean[a]).abs() < 1e-3 * side[a] + 1e-5
                    && (g.min[a] - c.min[a]).abs() < 2e-3 * side[a] + 1e-5
                    && (g.max[a] - c.max[a]).abs() < 2e-3 * side[a] + 1e-5
            });
            if !near {
                apart.push(format!("{c:?} {g:?}"));
                continue;
            }
            for k in 0..4 {
                assert!(g.colour[k].abs_diff(c.colour[k]) <= 1, "{c:?} {g:?}");
            }
            if c.count >= 8 || s.normals == Normals::Cells {
                match (c.normal, g.normal) {
                    (Some(n), Some(m)) => {
                        let dot: f64 = (0..3).map(|a| n[a] * m[a]).sum();
                        dots.push(dot);
                    }
                    (None, None) => {}
                    other => panic!("{s:?}: normals {other:?}"),
                }
            }
        }
        assert!(
            compared * 100 >= cpu.cells.len() * 95,
            "{s:?}: {compared} compared"
        );
        assert!(
            apart.len() * 200 <= compared,
            "{s:?}: {} of {compared} cells apart, as {:?}",
            apart.len(),
            apart.first()
        );
        // f32 and quantized sums against f64: 99 % of the normals within 0.8 degrees, every
        // one within 6 (a cell whose two smaller eigenvalues are close turns on little).
        dots.sort_by(f64::total_cmp);
        assert!(
            dots.len() * 100 >= compared * 80,
            "{s:?}: {} normals",
            dots.len()
        );
        assert!(dots[0] > 0.995, "{s:?}: {:?}", &dots[..3]);
        assert!(
            dots[dots.len() / 100] > 0.9999,
            "{s:?}: {}",
            dots[dots.len() / 100]
        );
    }
}

#[test]
fn gpu_and_cpu_draw_the_same_surface() {
    let Some(gpu) = common::gpu_or_skip() else {
        return;
    };
    let cam = camera();
    let (points, colours) = scene();
    let drawer = surface::Drawer::new(&gpu);
    for kind in [
        surface::Kind::Quads,
        surface::Kind::Boxes,
        surface::Kind::Splats,
    ] {
        let s = Surface {
            kind,
            grid: [64, 48, 24],
            ..Surface::default()
        };
        let built = surface::Built::new(&cam, &points, &colours, &s);
        let style = myriad_render::Style::default();
        let cpu = surface::draw(&cam, &built.mesh, &style);
        let gpu_image = drawer.draw(&gpu, &cam, &built.mesh, &style);
        assert_eq!(cpu.len(), gpu_image.len());
        // Hardware rasterization and the CPU's edge functions may part ways at a triangle's
        // edge, and the normals go through 8 bits on the GPU: all but a few pixels in a
        // thousand agree to a few levels (lavapipe: 6 to 156 of 76,800 differ).
        let pixels = cpu.len() / 4;
        let covered = |img: &[u8]| img.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        let differ = cpu
            .chunks(4)
            .zip(gpu_image.chunks(4))
            .filter(|(a, b)| (0..3).any(|k| a[k].abs_diff(b[k]) > 6))
            .count();
        assert!(covered(&cpu) > pixels / 10, "{kind:?}");
        assert!(
            covered(&cpu).abs_diff(covered(&gpu_image)) * 100 <= covered(&cpu),
            "{kind:?}"
        );
        assert!(
            differ * 200 <= pixels,
            "{kind:?}: {differ} of {pixels} pixels differ"
        );
    }
}

#[test]
fn the_gpu_reconstructs_the_triangles_the_cpu_makes_of_its_cells() {
    let Some(gpu) = common::gpu_or_skip() else {
        return;
    };
    let cam = camera();
    let (points, colours) = scene();
    let drawer = surface::Drawer::new(&gpu);
    let style = myriad_render::Style::default();
    for kind in [
        surface::Kind::Quads,
        surface::Kind::Boxes,
        surface::Kind::Splats,
    ] {
        let s = Surface {
            kind,
            grid: [64, 48, 24],
            ..Surface::default()
        };
        let built = surface::Built::on(&gpu, &cam, &points, &colours, &s).unwrap();
        // The CPU's triangles are made from the cells the GPU read back: the same count...
        let on_gpu = built.gpu_mesh.as_ref().expect("built on the GPU");
        assert_eq!(
            on_gpu.vertices as usize,
            3 * built.mesh.triangles.len(),
            "{kind:?}"
        );
        // ...and the same picture (f32 corners on the GPU, f64 on the CPU).
        let from_gpu = drawer.draw_built(&gpu, &cam, &built, &style);
        let from_cpu = drawer.draw(&gpu, &cam, &built.mesh, &style);
        let differ = from_gpu
            .chunks(4)
            .zip(from_cpu.chunks(4))
            .filter(|(a, b)| (0..3).any(|k| a[k].abs_diff(b[k]) > 6))
            .count();
        let covered = from_cpu.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(covered > from_cpu.len() / 40, "{kind:?}: {covered}");
        // Where splats overlap, an f32 corner against an f64 one may change which one is in
        // front (lavapipe: 127 of 76,800 pixels for splats).
        assert!(
            differ * 200 <= from_cpu.len() / 4,
            "{kind:?}: {differ} pixels differ"
        );
    }
}
