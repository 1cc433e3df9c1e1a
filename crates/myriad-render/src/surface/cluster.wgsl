// Cluster, move and reduce (Schiffner et al. 2015) on the GPU, mirrored by cluster.rs on the CPU:
// the grid in the view frustum, per cell sums by 32-bit integer atomics (WebGPU has no float
// atomics; the paper converts floats to integers the same way): each point's offset from its cell's
// centre, in cell sides, times SCALE, its extremes and colour; then, once the means are known, the
// products of the offsets from the mean (the point distribution tensor) times SCALE2. Dispatched
// per point (first, moved, spread) or per cell (clear, density, reduce).

struct Params {
    // columns, rows, layers, neighbours (0, 1, 3)
    dims: vec4<u32>,
    // width, height, focal length in pixels, nearest depth
    view: vec4<f32>,
    // farthest depth, gamma, lb, ln(far / near)
    more: vec4<f32>,
    // points in this dispatch, density (0 count, 1 planarity), normals (0 tensor, 1 cells),
    // cells; reconstruct: reduced cells, kind (0 quads, 1 boxes, 2 splats)
    flags: vec4<u32>,
    // The camera's right, up and forward (reconstruct: eye to world axes).
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
}

@group(0) @binding(0) var<uniform> P: Params;
// Eye coordinates (x right, y up, z depth) and the colour's bits.
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> cell_of: array<u32>;
@group(0) @binding(3) var<storage, read_write> acc: array<atomic<i32>>;
@group(0) @binding(4) var<storage, read_write> dens: array<f32>;
@group(0) @binding(5) var<storage, read_write> counter: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> cells: array<u32>;

const OUTSIDE: u32 = 0xffffffffu;
// Offsets in 1/1024 of a cell side, their products about the mean in 1/65536: a cell holds
// some 300 000 points before a sum overflows.
const SCALE: f32 = 1024.0;
const SCALE2: f32 = 65536.0;
// cluster.rs's TENSOR_SIGMA.
const TENSOR_SIGMA: f32 = 0.5;
// Words per cell: count, sums (3), minima (3), maxima (3), colour (4), products (6).
const STRIDE: u32 = 20u;
// Words per reduced cell: key, count, mean (3), min (3), max (3), normal (3), has normal, colour.
const CELL_WORDS: u32 = 16u;
const WG: u32 = 128u;

fn thread(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.y * groups.x * WG + id.x;
}

// Grid coordinates of an eye point (the cell is their floor); x < 0 outside the grid.
fn coords(e: vec3<f32>) -> vec3<f32> {
    if (e.z < P.view.w) {
        return vec3<f32>(-1.0);
    }
    let px = P.view.x * 0.5 + e.x * P.view.z / e.z;
    let py = P.view.y * 0.5 - e.y * P.view.z / e.z;
    let d = vec3<f32>(P.dims.xyz);
    let g = vec3<f32>(px / P.view.x * d.x, py / P.view.y * d.y, log(e.z / P.view.w) / P.more.w * d.z);
    if (any(g < vec3<f32>(0.0)) || any(g >= d)) {
        return vec3<f32>(-1.0);
    }
    return g;
}

fn key_of(c: vec3<u32>) -> u32 {
    return c.x + P.dims.x * (c.y + P.dims.y * c.z);
}

fn cell_index(k: u32) -> vec3<u32> {
    return vec3<u32>(k % P.dims.x, (k / P.dims.x) % P.dims.y, k / (P.dims.x * P.dims.y));
}

// The centre of a cell in eye coordinates (Grid::centre).
fn centre(c: vec3<u32>) -> vec3<f32> {
    let g = vec3<f32>(c) + vec3<f32>(0.5);
    let d = vec3<f32>(P.dims.xyz);
    let z = P.view.w * exp(P.more.w * g.z / d.z);
    let x = g.x / d.x * P.view.x;
    let y = g.y / d.y * P.view.y;
    return vec3<f32>((x - P.view.x * 0.5) * z / P.view.z, (P.view.y * 0.5 - y) * z / P.view.z, z);
}

// A cell's sides at depth z (Grid::extent).
fn extent(z: f32) -> vec3<f32> {
    let d = vec3<f32>(P.dims.xyz);
    return vec3<f32>(
        P.view.x / d.x * z / P.view.z,
        P.view.y / d.y * z / P.view.z,
        z * (exp(P.more.w / d.z) - 1.0),
    );
}

fn offset(k: u32, e: vec3<f32>) -> vec3<f32> {
    let c = centre(cell_index(k));
    return (e - c) / extent(c.z);
}

fn accumulate(k: u32, e: vec3<f32>, colour: u32) {
    let base = k * STRIDE;
    atomicAdd(&acc[base], 1);
    let q = vec3<i32>(round(offset(k, e) * SCALE));
    atomicAdd(&acc[base + 1u], q.x);
    atomicAdd(&acc[base + 2u], q.y);
    atomicAdd(&acc[base + 3u], q.z);
    atomicMin(&acc[base + 4u], q.x);
    atomicMin(&acc[base + 5u], q.y);
    atomicMin(&acc[base + 6u], q.z);
    atomicMax(&acc[base + 7u], q.x);
    atomicMax(&acc[base + 8u], q.y);
    atomicMax(&acc[base + 9u], q.z);
    atomicAdd(&acc[base + 10u], i32(colour & 0xffu));
    atomicAdd(&acc[base + 11u], i32((colour >> 8u) & 0xffu));
    atomicAdd(&acc[base + 12u], i32((colour >> 16u) & 0xffu));
    atomicAdd(&acc[base + 13u], i32(colour >> 24u));
}

// The mean offset of a cell's points, in cell sides.
fn mean_offset(k: u32) -> vec3<f32> {
    let base = k * STRIDE;
    let n = f32(atomicLoad(&acc[base]));
    return vec3<f32>(
        f32(atomicLoad(&acc[base + 1u])),
        f32(atomicLoad(&acc[base + 2u])),
        f32(atomicLoad(&acc[base + 3u])),
    ) / (SCALE * n);
}

// The tensor's weight of a point `d` (eye units) from its cell's mean in a cell of sides `e`
// (tensor_weight in cluster.rs): a Gaussian of the distance in the cell's mean side, sigma 0.5.
fn tensor_weight(d: vec3<f32>, e: vec3<f32>) -> f32 {
    let r2 = dot(d, d) / max(dot(e, e) / 3.0, 1e-30);
    return exp(-r2 / (2.0 * TENSOR_SIGMA * TENSOR_SIGMA));
}

// The tensor: products of each point's offset from its cell's mean (after first or moved),
// weighted by its distance.
@compute @workgroup_size(128)
fn spread(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread(id, groups);
    if (i >= P.flags.x) {
        return;
    }
    let k = cell_of[i];
    if (k == OUTSIDE) {
        return;
    }
    let d = offset(k, points[i].xyz) - mean_offset(k);
    let e = extent(centre(cell_index(k)).z);
    let w = tensor_weight(d * e, e) * SCALE2;
    let base = k * STRIDE + 14u;
    atomicAdd(&acc[base], i32(round(d.x * d.x * w)));
    atomicAdd(&acc[base + 1u], i32(round(d.x * d.y * w)));
    atomicAdd(&acc[base + 2u], i32(round(d.x * d.z * w)));
    atomicAdd(&acc[base + 3u], i32(round(d.y * d.y * w)));
    atomicAdd(&acc[base + 4u], i32(round(d.y * d.z * w)));
    atomicAdd(&acc[base + 5u], i32(round(d.z * d.z * w)));
}

@compute @workgroup_size(128)
fn clear(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = thread(id, groups);
    if (k >= P.flags.w) {
        return;
    }
    let base = k * STRIDE;
    for (var w = 0u; w < STRIDE; w++) {
        var v = 0;
        if (w >= 4u && w < 7u) {
            v = 2147483647;
        } else if (w >= 7u && w < 10u) {
            v = -2147483647;
        }
        atomicStore(&acc[base + w], v);
    }
}

// Point i's grid coordinates; outside the grid (x < 0) it is marked so.
fn locate(i: u32) -> vec3<f32> {
    let g = coords(points[i].xyz);
    if (g.x < 0.0) {
        cell_of[i] = OUTSIDE;
    }
    return g;
}

// The first clustering: each point into the cell it falls in.
@compute @workgroup_size(128)
fn first(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread(id, groups);
    if (i >= P.flags.x) {
        return;
    }
    let p = points[i];
    let g = locate(i);
    if (g.x < 0.0) {
        return;
    }
    let k = key_of(vec3<u32>(floor(g)));
    cell_of[i] = k;
    accumulate(k, p.xyz, bitcast<u32>(p.w));
}

struct Moments {
    n: f32,
    mean: vec3<f32>,
    cov: mat3x3<f32>,
}

// Mean (in cell sides from the centre) and covariance (in eye units) of a cell's points.
fn moments(k: u32, e: vec3<f32>) -> Moments {
    let base = k * STRIDE + 14u;
    let n = f32(atomicLoad(&acc[k * STRIDE]));
    let s = array<f32, 6>(
        f32(atomicLoad(&acc[base])), f32(atomicLoad(&acc[base + 1u])),
        f32(atomicLoad(&acc[base + 2u])), f32(atomicLoad(&acc[base + 3u])),
        f32(atomicLoad(&acc[base + 4u])), f32(atomicLoad(&acc[base + 5u])),
    );
    let w = 1.0 / (SCALE2 * n);
    let xx = s[0] * w * e.x * e.x;
    let xy = s[1] * w * e.x * e.y;
    let xz = s[2] * w * e.x * e.z;
    let yy = s[3] * w * e.y * e.y;
    let yz = s[4] * w * e.y * e.z;
    let zz = s[5] * w * e.z * e.z;
    return Moments(n, mean_offset(k), mat3x3<f32>(vec3<f32>(xx, xy, xz), vec3<f32>(xy, yy, yz), vec3<f32>(xz, yz, zz)));
}

struct Eigen {
    // by decreasing value
    values: vec3<f32>,
    // the eigenvector of the smallest
    minor: vec3<f32>,
}

// Cyclic Jacobi rotations, as symmetric_eigen in myriad-core's pca.rs.
fn eigen(m: mat3x3<f32>) -> Eigen {
    var a = array<array<f32, 3>, 3>(
        array<f32, 3>(m[0].x, m[0].y, m[0].z),
        array<f32, 3>(m[1].x, m[1].y, m[1].z),
        array<f32, 3>(m[2].x, m[2].y, m[2].z),
    );
    var v = array<array<f32, 3>, 3>(
        array<f32, 3>(1.0, 0.0, 0.0), array<f32, 3>(0.0, 1.0, 0.0), array<f32, 3>(0.0, 0.0, 1.0),
    );
    var pairs = array<vec2<u32>, 3>(vec2<u32>(0u, 1u), vec2<u32>(0u, 2u), vec2<u32>(1u, 2u));
    for (var sweep = 0; sweep < 12; sweep++) {
        let off = abs(a[0][1]) + abs(a[0][2]) + abs(a[1][2]);
        let scale = abs(a[0][0]) + abs(a[1][1]) + abs(a[2][2]);
        if (off <= 1e-7 * max(scale, 1e-30)) {
            break;
        }
        for (var t = 0u; t < 3u; t++) {
            let p = pairs[t].x;
            let q = pairs[t].y;
            if (a[p][q] == 0.0) {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            var tn = sign(theta) / (abs(theta) + sqrt(theta * theta + 1.0));
            if (theta == 0.0) {
                tn = 1.0;
            }
            let c = 1.0 / sqrt(tn * tn + 1.0);
            let s = tn * c;
            for (var k = 0u; k < 3u; k++) {
                let akp = a[k][p];
                let akq = a[k][q];
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for (var k = 0u; k < 3u; k++) {
                let apk = a[p][k];
                let aqk = a[q][k];
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for (var k = 0u; k < 3u; k++) {
                let vkp = v[k][p];
                let vkq = v[k][q];
                v[k][p] = c * vkp - s * vkq;
                v[k][q] = s * vkp + c * vkq;
            }
        }
    }
    let d = vec3<f32>(a[0][0], a[1][1], a[2][2]);
    var lo = 0u;
    if (d.y < d[lo]) {
        lo = 1u;
    }
    if (d.z < d[lo]) {
        lo = 2u;
    }
    let hi = max(max(d.x, d.y), d.z);
    let low = d[lo];
    let mid = d.x + d.y + d.z - hi - low;
    return Eigen(vec3<f32>(max(hi, 0.0), max(mid, 0.0), max(low, 0.0)), normalize(vec3<f32>(v[0][lo], v[1][lo], v[2][lo])));
}

// Each cell's density for the move: its point count, or the planarity of its tensor.
@compute @workgroup_size(128)
fn density(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = thread(id, groups);
    if (k >= P.flags.w) {
        return;
    }
    let n = atomicLoad(&acc[k * STRIDE]);
    if (P.flags.y == 0u || n < 3) {
        dens[k] = select(0.0, f32(n), P.flags.y == 0u);
        return;
    }
    let c = centre(cell_index(k));
    let ev = eigen(moments(k, extent(c.z)).cov).values;
    dens[k] = select(0.0, (ev.y - ev.z) / ev.x, ev.x > 0.0);
}

fn weight(dc: f32, dn: f32) -> f32 {
    let total = dc + dn;
    var f = 1.0;
    if (total > 0.0) {
        f = 2.0 * dc / total;
    }
    return clamp(pow(f, P.more.y), P.more.z, 1.0 - P.more.z);
}

// Equation 9 (moved_cell in cluster.rs), then each point into its new cell.
@compute @workgroup_size(128)
fn moved(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread(id, groups);
    if (i >= P.flags.x) {
        return;
    }
    let p = points[i];
    let g = locate(i);
    if (g.x < 0.0) {
        return;
    }
    let c = vec3<u32>(floor(g));
    // In half cells, the unit of the weight (moved_cell's).
    let d = 2.0 * (g - (vec3<f32>(c) + vec3<f32>(0.5)));
    var largest = 0u;
    if (abs(d.y) > abs(d[largest])) {
        largest = 1u;
    }
    if (abs(d.z) > abs(d[largest])) {
        largest = 2u;
    }
    let dc = dens[key_of(c)];
    var out = c;
    for (var a = 0u; a < 3u; a++) {
        if (P.dims.w == 0u || (P.dims.w == 1u && a != largest)) {
            continue;
        }
        let up = d[a] >= 0.0;
        if ((up && c[a] + 1u >= P.dims[a]) || (!up && c[a] == 0u)) {
            continue;
        }
        var n = c;
        if (up) {
            n[a] = c[a] + 1u;
        } else {
            n[a] = c[a] - 1u;
        }
        if (abs(d[a]) > weight(dc, dens[key_of(n)])) {
            out[a] = n[a];
        }
    }
    let k = key_of(out);
    cell_of[i] = k;
    accumulate(k, p.xyz, bitcast<u32>(p.w));
}

// The cells' normal (empty_neighbours_normal in cluster.rs).
fn cells_normal(c: vec3<u32>, ctr: vec3<f32>, e: vec3<f32>) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                if (dx == 0 && dy == 0 && dz == 0) {
                    continue;
                }
                let dd = vec3<i32>(dx, dy, dz);
                let n = vec3<i32>(c) + dd;
                if (any(n < vec3<i32>(0)) || any(n >= vec3<i32>(P.dims.xyz))) {
                    continue;
                }
                if (atomicLoad(&acc[key_of(vec3<u32>(n)) * STRIDE]) > 0) {
                    continue;
                }
                sum += vec3<f32>(dd) / length(vec3<f32>(dd));
            }
        }
    }
    if (dot(sum, sum) < 1e-12) {
        return vec3<f32>(0.0);
    }
    let x = sum.x / e.x;
    let y = -sum.y / e.y;
    return normalize(vec3<f32>(x, y, sum.z / e.z - ctr.x / ctr.z * x - ctr.y / ctr.z * y));
}

// One representative per occupied cell, appended in any order.
@compute @workgroup_size(128)
fn reduce(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = thread(id, groups);
    if (k >= P.flags.w) {
        return;
    }
    let base = k * STRIDE;
    let count = atomicLoad(&acc[base]);
    if (count == 0) {
        return;
    }
    let c = cell_index(k);
    let ctr = centre(c);
    let e = extent(ctr.z);
    let m = moments(k, e);
    let mean = ctr + m.mean * e;
    let lo = ctr + vec3<f32>(
        f32(atomicLoad(&acc[base + 4u])), f32(atomicLoad(&acc[base + 5u])),
        f32(atomicLoad(&acc[base + 6u])),
    ) / SCALE * e;
    let hi = ctr + vec3<f32>(
        f32(atomicLoad(&acc[base + 7u])), f32(atomicLoad(&acc[base + 8u])),
        f32(atomicLoad(&acc[base + 9u])),
    ) / SCALE * e;
    var normal = vec3<f32>(0.0);
    if (P.flags.z == 1u) {
        normal = cells_normal(c, ctr, e);
    } else if (count >= 3) {
        let ev = eigen(m.cov);
        if (ev.values.x > 0.0) {
            normal = ev.minor;
        }
    }
    if (dot(normal, mean) > 0.0) {
        normal = -normal;
    }
    let half = u32(count) / 2u;
    let colour = vec4<u32>(
        (u32(atomicLoad(&acc[base + 10u])) + half) / u32(count),
        (u32(atomicLoad(&acc[base + 11u])) + half) / u32(count),
        (u32(atomicLoad(&acc[base + 12u])) + half) / u32(count),
        (u32(atomicLoad(&acc[base + 13u])) + half) / u32(count),
    );
    let slot = atomicAdd(&counter[0], 1u);
    let o = slot * CELL_WORDS;
    cells[o] = k;
    cells[o + 1u] = u32(count);
    cells[o + 2u] = bitcast<u32>(mean.x);
    cells[o + 3u] = bitcast<u32>(mean.y);
    cells[o + 4u] = bitcast<u32>(mean.z);
    cells[o + 5u] = bitcast<u32>(lo.x);
    cells[o + 6u] = bitcast<u32>(lo.y);
    cells[o + 7u] = bitcast<u32>(lo.z);
    cells[o + 8u] = bitcast<u32>(hi.x);
    cells[o + 9u] = bitcast<u32>(hi.y);
    cells[o + 10u] = bitcast<u32>(hi.z);
    cells[o + 11u] = bitcast<u32>(normal.x);
    cells[o + 12u] = bitcast<u32>(normal.y);
    cells[o + 13u] = bitcast<u32>(normal.z);
    cells[o + 14u] = select(0u, 1u, dot(normal, normal) > 0.0);
    cells[o + 15u] = colour.x | (colour.y << 8u) | (colour.z << 16u) | (colour.w << 24u);
}
