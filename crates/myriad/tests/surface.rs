//! Surfaces (Schiffner et al. 2015) through the CLI: `render --surface` draws them, `mesh` writes
//! them, and an independent reader (a Python script of the standard library, below) reads the files
//! back.

mod common;
use common::*;
use std::path::Path;
use std::process::Command;

/// Reads a binary PLY or a GLB with nothing but Python's standard library and prints what a
/// mesh reader sees: vertices, triangles, the largest index, the bounds of the positions.
const READER: &str = r#"
import json, struct, sys
path = sys.argv[1]
data = open(path, 'rb').read()
if path.endswith('.ply'):
    end = data.index(b'end_header\n') + len(b'end_header\n')
    header = data[:end].decode('ascii').split('\n')
    assert header[0] == 'ply' and header[1] == 'format binary_little_endian 1.0', header[:2]
    nv = nf = 0
    props = []
    element = None
    for line in header:
        w = line.split()
        if w[:1] == ['element']:
            element = w[1]
            if element == 'vertex': nv = int(w[2])
            if element == 'face': nf = int(w[2])
        elif w[:1] == ['property'] and element == 'vertex':
            props.append(w[1])
    sizes = {'double': 'd', 'float': 'f', 'uchar': 'B', 'int': 'i'}
    vfmt = '<' + ''.join(sizes[p] for p in props)
    vsize = struct.calcsize(vfmt)
    lo = [float('inf')] * 3; hi = [float('-inf')] * 3
    at = end
    for i in range(nv):
        v = struct.unpack_from(vfmt, data, at); at += vsize
        for a in range(3):
            lo[a] = min(lo[a], v[a]); hi[a] = max(hi[a], v[a])
    top = -1
    for i in range(nf):
        (n,) = struct.unpack_from('<B', data, at); at += 1
        idx = struct.unpack_from('<%di' % n, data, at); at += 4 * n
        assert n == 3
        top = max(top, max(idx))
    assert at == len(data), (at, len(data))
    print(nv, nf, top, *lo, *hi)
else:
    magic, version, length = struct.unpack_from('<4sII', data, 0)
    assert magic == b'glTF' and version == 2 and length == len(data)
    jlen, jtype = struct.unpack_from('<I4s', data, 12)
    assert jtype == b'JSON'
    doc = json.loads(data[20:20 + jlen])
    blen, btype = struct.unpack_from('<I4s', data, 20 + jlen)
    assert btype == b'BIN\x00'
    bin = data[28 + jlen:28 + jlen + blen]
    prim = doc['meshes'][0]['primitives'][0]
    acc = doc['accessors']
    views = doc['bufferViews']
    pos = acc[prim['attributes']['POSITION']]
    ind = acc[prim['indices']]
    assert ind['componentType'] == 5125
    view = views[ind['bufferView']]
    idx = struct.unpack_from('<%dI' % ind['count'], bin, view['byteOffset'])
    pview = views[pos['bufferView']]
    xyz = struct.unpack_from('<%df' % (3 * pos['count']), bin, pview['byteOffset'])
    t = doc['nodes'][0]['translation']
    # Positions are stored less the centre c; the node turns them from Z-up into Y-up
    # ((x, y, z) -> (x, z, -y)) and moves them by the turned centre (cx, cz, -cy).
    lo = [min(xyz[a::3]) for a in range(3)]
    hi = [max(xyz[a::3]) for a in range(3)]
    assert all(abs(lo[a] - pos['min'][a]) < 1e-3 and abs(hi[a] - pos['max'][a]) < 1e-3 for a in range(3))
    r = doc['nodes'][0]['rotation']
    assert abs(r[0] + 0.5 ** 0.5) < 1e-9 and abs(r[3] - 0.5 ** 0.5) < 1e-9
    c = [t[0], -t[2], t[1]]
    wlo = [lo[a] + c[a] for a in range(3)]
    whi = [hi[a] + c[a] for a in range(3)]
    print(pos['count'], ind['count'] // 3, max(idx), *wlo, *whi)
"#;

fn read_mesh(path: &Path) -> Vec<f64> {
    let out = Command::new("python3")
        .args(["-c", READER, s(path)])
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

/// The number printed just before `what` in `text`.
fn number_before(text: &str, what: &str) -> u64 {
    let at = text.find(what).expect(what);
    let head = text[..at].trim_end();
    head[head.rfind([' ', '(']).unwrap() + 1..]
        .replace(',', "")
        .parse()
        .unwrap()
}

fn lit_pixels(png_path: &Path) -> usize {
    let (_, _, img) = decode_png(png_path);
    img.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count()
}

#[test]
fn mesh_writes_ply_and_glb_that_a_reader_opens_and_render_draws_the_surface() {
    if Command::new("python3").arg("-V").output().is_err() {
        eprintln!("SKIPPED: no python3 to read the meshes back");
        return;
    }
    let d = tempdir("surface");
    let las = synth(&d, "c.las", 200_000);
    let ds = d.join("c.myr");
    ok(&["convert", s(&las), "-o", s(&ds)]);
    let bounds: Vec<f64> = {
        let info = ok(&["info", s(&ds)]);
        // "bounds min X Y Z", then "max X Y Z".
        info.lines()
            .filter(|l| l.contains("bounds min") || l.trim_start().starts_with("max "))
            .flat_map(|l| l.split_whitespace().filter_map(|t| t.parse::<f64>().ok()))
            .collect()
    };
    assert!(bounds.len() >= 6, "{bounds:?}");

    let mut cells = Vec::new();
    for (kind, name, per_cell) in [
        ("quads", "q.ply", (4, 2)),
        ("quads", "q.glb", (4, 2)),
        ("boxes", "b.ply", (24, 12)),
        ("splats", "s.glb", (8, 6)),
    ] {
        let out = d.join(name);
        let text = ok(&[
            "mesh",
            s(&ds),
            "-o",
            s(&out),
            "--surface",
            kind,
            "--grid",
            "60x40x20",
            "--width",
            "320",
            "--height",
            "200",
        ]);
        let n = number_before(&text, " cells from");
        assert!(n > 100, "{text}");
        cells.push(n);
        let m = read_mesh(&out);
        assert_eq!(m[0] as u64, per_cell.0 * n, "{name}: vertices");
        assert_eq!(m[1] as u64, per_cell.1 * n, "{name}: triangles");
        assert_eq!(m[2] as u64, m[0] as u64 - 1, "{name}: largest index");
        // The surface lies where the scan is: within a few cells of its bounds (the cells' boxes
        // are along the eye's axes, and splats reach half a cell beyond them).
        let size = (0..3)
            .map(|a| bounds[3 + a] - bounds[a])
            .fold(0.0, f64::max);
        let slack = 0.05 * size;
        for a in 0..3 {
            assert!(m[3 + a] >= bounds[a] - slack, "{name}: {m:?} {bounds:?}");
            assert!(
                m[6 + a] <= bounds[3 + a] + slack,
                "{name}: {m:?} {bounds:?}"
            );
        }
    }
    // The same view and grid make the same cells whatever is written.
    assert!(cells.iter().all(|&c| c == cells[0]), "{cells:?}");

    // An existing file is kept without --force; other extensions are refused.
    let r = myriad(&["mesh", s(&ds), "-o", s(&d.join("q.ply"))]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains("exists"), "{}", r.stderr);
    let r = myriad(&["mesh", s(&ds), "-o", s(&d.join("q.obj"))]);
    assert_eq!(r.code, 1);
    assert!(r.stderr.contains(".ply or .glb"), "{}", r.stderr);
    let r = myriad(&[
        "mesh",
        s(&ds),
        "-o",
        s(&d.join("x.ply")),
        "--grid",
        "10x0x5",
    ]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert!(!d.join("x.ply").exists());

    // `render --surface`: an image of the surface, covering about what the points cover.
    let points_png = d.join("p.png");
    ok(&[
        "render",
        s(&ds),
        "-o",
        s(&points_png),
        "--width",
        "320",
        "--height",
        "200",
    ]);
    for kind in ["quads", "boxes", "splats"] {
        let png_path = d.join(format!("{kind}.png"));
        let text = ok(&[
            "render",
            s(&ds),
            "-o",
            s(&png_path),
            "--width",
            "320",
            "--height",
            "200",
            "--surface",
            kind,
            "--grid",
            "60x40x20",
        ]);
        assert!(text.contains("surface: "), "{text}");
        let (surface, points) = (lit_pixels(&png_path), lit_pixels(&points_png));
        assert!(
            surface * 10 > points * 7 && surface < points * 13 / 10,
            "{kind}: {surface} pixels lit, the points {points}"
        );
    }
}
