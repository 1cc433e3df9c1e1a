use super::*;
use myriad_core::Aabb;

fn camera(eye: [f64; 3], target: [f64; 3]) -> Camera {
    let mut c = Camera::framing(&Aabb::new([-1.0; 3], [1.0; 3]), 400, 300, 60.0);
    c.position = eye;
    c.target = target;
    c.up = [0.0, 0.0, 1.0];
    c.near = 0.01;
    c.far = 1000.0;
    c
}

/// A regular lattice on the plane z = a x + b y over [-s, s]^2, `n` x `n` points.
fn plane(a: f64, b: f64, s: f64, n: usize) -> Vec<[f64; 3]> {
    let mut p = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let x = -s + 2.0 * s * (i as f64 + 0.5) / n as f64;
            let y = -s + 2.0 * s * (j as f64 + 0.5) / n as f64;
            p.push([x, y, a * x + b * y]);
        }
    }
    p
}

fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let l = (a.iter().map(|v| v * v).sum::<f64>() * b.iter().map(|v| v * v).sum::<f64>()).sqrt();
    (d / l).clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn the_tensor_weights_points_by_distance_by_hand() {
    use super::cluster::{TENSOR_SIGMA, tensor_weight};
    let e = [2.0, 2.0, 2.0];
    // At the mean: 1; half a side away: exp(-0.5^2 / (2 * 0.5^2)) = exp(-0.5); a side: exp(-2).
    assert_eq!(tensor_weight([0.0; 3], e), 1.0);
    assert!((tensor_weight([1.0, 0.0, 0.0], e) - (-0.5f64).exp()).abs() < 1e-12);
    assert!((tensor_weight([0.0, 0.0, 2.0], e) - (-2.0f64).exp()).abs() < 1e-12);
    // In the cell's mean side: a cell twice as deep as wide counts depth alike.
    let tall = [1.0, 1.0, 2.0f64];
    let side = ((1.0 + 1.0 + 4.0) / 3.0f64).sqrt();
    assert!((tensor_weight([side, 0.0, 0.0], tall) - (-2.0f64).exp()).abs() < 1e-12);
    // The shader's constant is this one.
    let wgsl = include_str!("cluster.wgsl");
    assert!(wgsl.contains(&format!("const TENSOR_SIGMA: f32 = {TENSOR_SIGMA:?};")));
}

#[test]
fn equation_8_weights_by_hand() {
    // Equal densities: 2c/(c+n) = 1, clamped to 1 - lb.
    assert_eq!(weight(5.0, 5.0, 1.0, 0.1), 0.9);
    // A sparse cell beside a dense one: 2 * 1 / 10 = 0.2.
    assert!((weight(1.0, 9.0, 1.0, 0.1) - 0.2).abs() < 1e-12);
    // gamma 2: 0.2^2 = 0.04, clamped up to lb.
    assert_eq!(weight(1.0, 9.0, 2.0, 0.1), 0.1);
    // An empty neighbour: 2^gamma, clamped to 1 - lb.
    assert_eq!(weight(3.0, 0.0, 1.0, 0.1), 0.9);
}

#[test]
fn equation_9_moves_a_point_by_hand() {
    let dims = [10, 10, 10];
    // Cell (4, 4, 4) holds 1 point; its +x neighbour 9, every other cell 1.
    let dens = |c: [u32; 3]| if c == [5, 4, 4] { 9.0 } else { 1.0 };
    // The boundary towards the dense neighbour: w = 2 * 1 / 10 = 0.2 of the half cell, 0.1
    // cells from the centre (x = 4.6). Seen from the dense cell: 2 * 9 / 10 = 1.8, clamped to
    // 0.9: 0.45 cells from its centre (5.05). Unclamped the two meet at 4.6 (0.2 + 1.8 = 2 half
    // cells, the distance between the centres).
    // At 4.65 (0.15 cells = 0.3 half cells > 0.2): moves.
    assert_eq!(
        moved_cell([4.65, 4.5, 4.5], dims, 1, 1.0, 0.1, &dens),
        [5, 4, 4]
    );
    // At 4.58 (0.16 half cells): stays.
    assert_eq!(
        moved_cell([4.58, 4.5, 4.5], dims, 1, 1.0, 0.1, &dens),
        [4, 4, 4]
    );
    // Towards (3, 4, 4), as dense as its own cell: w = 1 clamped to 0.9: at 4.2 (0.6 half
    // cells) it stays, at 4.04 (0.92) it crosses.
    assert_eq!(
        moved_cell([4.2, 4.5, 4.5], dims, 1, 1.0, 0.1, &dens),
        [4, 4, 4]
    );
    assert_eq!(
        moved_cell([4.04, 4.5, 4.5], dims, 1, 1.0, 0.1, &dens),
        [3, 4, 4]
    );
    // No move asked.
    assert_eq!(
        moved_cell([4.8, 4.5, 4.5], dims, 0, 1.0, 0.1, &dens),
        [4, 4, 4]
    );
    // The dense cell keeps a point 0.4 cells towards the sparse one (0.8 half cells < 0.9).
    assert_eq!(
        moved_cell([5.1, 4.5, 4.5], dims, 3, 1.0, 0.1, &dens),
        [5, 4, 4]
    );
    // Two dense neighbours, along x and y; the point is off-centre on both, more along y.
    let dens2 = |c: [u32; 3]| {
        if c == [5, 4, 4] || c == [4, 5, 4] {
            9.0
        } else {
            1.0
        }
    };
    let g = [4.8, 4.9, 4.5];
    // One neighbour: along the largest offset (y) only.
    assert_eq!(moved_cell(g, dims, 1, 1.0, 0.1, &dens2), [4, 5, 4]);
    // Three: along both, a diagonal move (equation 9 sums the offsets).
    assert_eq!(moved_cell(g, dims, 3, 1.0, 0.1, &dens2), [5, 5, 4]);
    // Never beyond the grid.
    assert_eq!(
        moved_cell([9.95, 4.5, 4.5], dims, 3, 1.0, 0.1, &|_| 1.0),
        [9, 4, 4]
    );
}

#[test]
fn tensor_normals_on_a_plane_are_within_two_degrees() {
    let (a, b) = (0.3, -0.2);
    let points = plane(a, b, 5.0, 400);
    let colours = vec![[255; 4]; points.len()];
    let cam = camera([2.0, -12.0, 9.0], [0.0, 0.0, 0.0]);
    let truth = [-a, -b, 1.0];
    for neighbours in [0, 3] {
        let s = Surface {
            grid: [60, 45, 20],
            neighbours,
            ..Surface::default()
        };
        let built = Built::new(&cam, &points, &colours, &s);
        let cells = &built.clustering.cells;
        assert!(cells.len() > 800, "{} cells", cells.len());
        let (r, u, f) = cam.basis();
        let mut worst: f64 = 0.0;
        for c in cells.iter().filter(|c| c.count >= 8) {
            let n = c.normal.expect("a tensor normal from 8 points");
            let w = std::array::from_fn(|k| n[0] * r[k] + n[1] * u[k] + n[2] * f[k]);
            worst = worst.max(angle(w, truth).min(angle(w, truth.map(|v| -v))));
            // Turned towards the eye.
            assert!(n[0] * c.mean[0] + n[1] * c.mean[1] + n[2] * c.mean[2] <= 0.0);
        }
        assert!(worst < 2.0, "worst normal {worst} degrees off");
    }
}

#[test]
fn quads_lie_within_half_a_cell_of_a_sphere() {
    // A sphere of radius 2 sampled by a Fibonacci spiral.
    let n = 200_000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            [2.0 * r * t.cos(), 2.0 * r * t.sin(), 2.0 * z]
        })
        .collect();
    let colours = vec![[200; 4]; n];
    let cam = camera([0.0, -8.0, 3.0], [0.0, 0.0, 0.0]);
    let s = Surface {
        grid: [80, 60, 20],
        ..Surface::default()
    };
    let built = Built::new(&cam, &points, &colours, &s);
    let grid = built.grid.expect("points in view");
    let mesh = &built.mesh;
    assert_eq!(mesh.triangles.len(), 2 * built.clustering.cells.len());
    // Half a cell: half its longest side at that depth (along the view where the sphere turns
    // away). The quads' centres lie within it, and their corners, at the cell's sides on the
    // tangent plane, mostly: where the sphere turns away from the eye within a deep layer, a
    // quad kept within its cell's box leaves the sphere (the "misplaced patches" of
    // Schiffner et al. 2015).
    let off = |p: [f64; 3]| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 2.0).abs();
    let half = |p: [f64; 3]| {
        0.5 * grid
            .extent(cam.to_eye(p)[2])
            .into_iter()
            .fold(0.0, f64::max)
    };
    let (mut corners_in, mut centres_in) = (0, 0);
    for quad in mesh.positions.chunks(4) {
        let c: [f64; 3] = std::array::from_fn(|a| quad.iter().map(|p| p[a]).sum::<f64>() / 4.0);
        centres_in += (off(c) < half(c)) as usize;
        corners_in += quad.iter().filter(|&&p| off(p) < half(p)).count();
    }
    assert!(
        centres_in * 100 >= mesh.positions.len() / 4 * 95,
        "{centres_in} centres"
    );
    assert!(
        corners_in * 100 >= mesh.positions.len() * 85,
        "{corners_in} of {}",
        mesh.positions.len()
    );
    // The quality measure agrees: points lie close to their cell's quad.
    let d = distances(&cam, &grid, &built.clustering, &points, Kind::Quads);
    assert_eq!(d.len(), built.clustering.inside);
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
    assert!(rms < 0.02, "rms {rms}");
}

#[test]
fn a_step_edge_keeps_both_levels_and_the_move_follows_density() {
    // Two half-planes at z = 0 and z = 1, the upper one four times as dense.
    let mut points = Vec::new();
    for i in 0..300 {
        for j in 0..300 {
            let (x, y) = (i as f64 / 30.0 - 5.0, j as f64 / 30.0 - 5.0);
            if x < 0.0 && (i + j) % 4 == 0 {
                points.push([x, y, 0.0]);
            } else if x >= 0.0 {
                points.push([x, y, 1.0]);
            }
        }
    }
    let colours = vec![[255; 4]; points.len()];
    let cam = camera([0.0, -14.0, 10.0], [0.0, 0.0, 0.5]);
    let s = Surface {
        grid: [60, 45, 20],
        ..Surface::default()
    };
    let moved = Built::new(&cam, &points, &colours, &s);
    let still = Built::new(&cam, &points, &colours, &Surface { neighbours: 0, ..s });
    assert_eq!(still.clustering.moved, 0);
    assert!(moved.clustering.moved > 0);
    // Points only move from a sparser cell to a denser one: the dense side never loses any.
    let grid = moved.grid.unwrap();
    let cells_of = |b: &Built, i: usize| b.clustering.cells[b.clustering.of_point[i] as usize];
    for (i, p) in points.iter().enumerate() {
        if p[2] == 1.0 && still.clustering.of_point[i] != u32::MAX {
            let a = cells_of(&still, i).index;
            let e = cluster::to_eye(&cam, &[*p])[0];
            let g = grid.coords(*p, e).unwrap().map(|v| v.floor() as u32);
            assert_eq!(a, g);
        }
    }
    // Both levels are kept: quads over each side lie at their side's height.
    for b in [&moved, &still] {
        let d = distances(&cam, &grid, &b.clustering, &points, Kind::Quads);
        let mut sorted = d.clone();
        sorted.sort_by(f64::total_cmp);
        let p95 = sorted[sorted.len() * 95 / 100];
        assert!(p95 < 0.1, "95th percentile {p95}, the step 1");
    }
}

#[test]
fn a_square_facing_the_eye_covers_its_pixels() {
    let cam = camera([0.0, -10.0, 0.0], [0.0, 0.0, 0.0]);
    // A square 2 x 2 at depth 10, facing the eye.
    let mut mesh = Mesh::default();
    mesh.polygon(
        &[
            [-1.0, 0.0, -1.0],
            [1.0, 0.0, -1.0],
            [1.0, 0.0, 1.0],
            [-1.0, 0.0, 1.0],
        ],
        [0.0, -1.0, 0.0],
        [255, 0, 0, 255],
    );
    let g = gbuffer(&cam, &mesh);
    // Its side on screen: 2 / 10 of the focal length.
    let side = 2.0 / 10.0 * cam.focal();
    let covered = g.depth.iter().filter(|&&d| d > 0.0).count() as f64;
    assert!(
        (covered - side * side).abs() < 4.0 * side,
        "{covered} pixels, {}",
        side * side
    );
    assert!(
        g.depth
            .iter()
            .filter(|&&d| d > 0.0)
            .all(|&d| (d - 10.0).abs() < 1e-4)
    );
    // The normal faces the eye: the headlight lights it fully.
    let n = crate::unpack_normal(g.normal[(150 * 400 + 200) as usize]);
    assert!(n[2] < -0.99, "{n:?}");
    let style = crate::Style {
        passes: crate::Passes::default(),
        ..Default::default()
    };
    let img = draw(&cam, &mesh, &style);
    let centre = (150 * 400 + 200) * 4;
    // ambient 0.2 + headlight 0.8 on a red face.
    assert_eq!(&img[centre..centre + 3], &[255, 0, 0]);
    assert_eq!(&img[0..3], &[0, 0, 0]);
}

#[test]
fn boxes_and_splats_make_their_primitives() {
    let points = plane(0.0, 0.0, 5.0, 100);
    let colours = vec![[255; 4]; points.len()];
    let cam = camera([0.0, -12.0, 9.0], [0.0, 0.0, 0.0]);
    for (kind, triangles) in [(Kind::Boxes, 12), (Kind::Splats, 6), (Kind::Quads, 2)] {
        let s = Surface {
            kind,
            grid: [40, 30, 10],
            ..Surface::default()
        };
        let b = Built::new(&cam, &points, &colours, &s);
        assert_eq!(b.mesh.triangles.len(), triangles * b.clustering.cells.len());
        assert_eq!(b.clustering.inside, points.len());
        let total: u32 = b.clustering.cells.iter().map(|c| c.count).sum();
        assert_eq!(total as usize, points.len());
    }
    // The cells' normals point up on a flat ground seen from above.
    let s = Surface {
        normals: Normals::Cells,
        grid: [40, 30, 10],
        ..Surface::default()
    };
    let b = Built::new(&cam, &points, &colours, &s);
    let (r, u, f) = cam.basis();
    let world = |e: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|k| cam.position[k] + e[0] * r[k] + e[1] * u[k] + e[2] * f[k])
    };
    // Away from the plane's edges (where the empty cells beside it tilt the normal).
    let inner: Vec<_> = b
        .clustering
        .cells
        .iter()
        .filter(|c| world(c.mean)[0].abs() < 4.0 && world(c.mean)[1].abs() < 4.0)
        .collect();
    let normals: Vec<[f64; 3]> = inner
        .iter()
        .filter_map(|c| c.normal)
        .map(|n| std::array::from_fn(|k| n[0] * r[k] + n[1] * u[k] + n[2] * f[k]))
        .collect();
    // The rough method (Schiffner et al. 2015: the tensor's is smoother; a 26-neighbourhood knows
    // 13 directions): most of the normals within 60 degrees of up, and their mean within 20. A
    // cell with no empty neighbour has none ("which is correct", Schiffner et al., section 3.2):
    // since the move fills the cells' faces (half cells, December 4) about a quarter of the inner
    // cells (88 of 324 here), before almost none.
    let up = normals.iter().filter(|n| n[2] > 0.5).count();
    assert!(
        normals.len() * 2 >= inner.len(),
        "{} of {}",
        normals.len(),
        inner.len()
    );
    assert!(up * 4 >= normals.len() * 3, "{up} of {}", normals.len());
    let mean = normals
        .iter()
        .fold([0.0; 3], |a, n| [a[0] + n[0], a[1] + n[1], a[2] + n[2]]);
    assert!(angle(mean, [0.0, 0.0, 1.0]) < 20.0, "{mean:?}");
}
