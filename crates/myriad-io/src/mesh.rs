//! Mesh files: binary PLY (MeshLab, CloudCompare, Blender) and binary glTF 2.0 (`.glb`: Blender,
//! three.js, every web viewer). Written here rather than by a crate: both are a header and flat
//! arrays, and the glTF crates are readers first.
//!
//! PLY keeps positions in double precision (survey coordinates lose centimetres in f32). glTF has
//! only f32 vertices, so positions are stored relative to the mesh's centre and the node carries
//! the centre as its translation (JSON numbers are doubles); the node also turns the data's Z-up
//! into glTF's Y-up, so importers that turn Y-up back to Z-up give the original coordinates.

use crate::atomic::AtomicFile;
use myriad_core::{Error, Mesh, Result};
use std::io::Write;
use std::path::Path;

/// The mesh as a binary little-endian PLY: vertices (x, y, z as double, nx, ny, nz as float,
/// red, green, blue, alpha as uchar) and faces (a uchar count and int indices).
pub fn ply_bytes(mesh: &Mesh) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment made by myriad (surface reconstruction)\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )
    .into_bytes();
    out.reserve(mesh.positions.len() * 40 + mesh.triangles.len() * 13);
    for ((p, n), c) in mesh.positions.iter().zip(&mesh.normals).zip(&mesh.colours) {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in n {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(c);
    }
    for t in &mesh.triangles {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}

/// The mesh as a binary glTF 2.0 file: one mesh of indexed triangles with POSITION, NORMAL and
/// COLOR_0, a double-sided unlit-looking material (white, rough, not metallic), one node.
pub fn glb_bytes(mesh: &Mesh) -> Vec<u8> {
    let centre = mesh.bounds().map_or([0.0; 3], |b| b.center());
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    let mut bin = Vec::with_capacity(mesh.positions.len() * 28 + mesh.triangles.len() * 12);
    for p in &mesh.positions {
        for a in 0..3 {
            let v = (p[a] - centre[a]) as f32;
            lo[a] = lo[a].min(v);
            hi[a] = hi[a].max(v);
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let normals_at = bin.len();
    for n in &mesh.normals {
        for v in n {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let colours_at = bin.len();
    for c in &mesh.colours {
        bin.extend_from_slice(c);
    }
    let indices_at = bin.len();
    for t in &mesh.triangles {
        for i in t {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let total = bin.len();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let n = mesh.positions.len();
    if n == 0 {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    let view = |offset: usize, length: usize, target: u32| serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": length, "target": target});
    // Z up to Y up: (x, y, z) -> (x, z, -y), a quarter turn about x.
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "myriad"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{
            "mesh": 0,
            "rotation": [-h, 0.0, 0.0, h],
            "translation": [centre[0], centre[2], -centre[1]],
        }],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2},
            "indices": 3,
            "material": 0,
            "mode": 4,
        }]}],
        "materials": [{
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "doubleSided": true,
        }],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5121, "normalized": true, "count": n,
             "type": "VEC4"},
            {"bufferView": 3, "componentType": 5125, "count": mesh.triangles.len() * 3,
             "type": "SCALAR"},
        ],
        "bufferViews": [
            view(0, normals_at, 34962),
            view(normals_at, colours_at - normals_at, 34962),
            view(colours_at, indices_at - colours_at, 34962),
            view(indices_at, total - indices_at, 34963),
        ],
        "buffers": [{"byteLength": bin.len()}],
    });
    glb(&json, bin)
}

/// A binary glTF (GLB) of `json` and its buffer `bin`: the JSON chunk padded with spaces, the
/// binary one with zeros, each to 4 bytes.
pub(crate) fn glb(json: &serde_json::Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut json = serde_json::to_vec(json).expect("a JSON value serializes");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let length = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(length);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(length as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Writes the mesh atomically, as PLY or glTF by the name's extension (`.ply`, `.glb`).
pub fn write(path: &Path, mesh: &Mesh, force: bool) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let bytes = match ext.as_deref() {
        Some("ply") => ply_bytes(mesh),
        Some("glb") => glb_bytes(mesh),
        _ => {
            return Err(Error::unsupported(
                path,
                "a mesh is written as .ply or .glb",
            ));
        }
    };
    let file = AtomicFile::create(path, force)?;
    let mut f = file.open_write()?;
    f.write_all(&bytes)
        .and_then(|_| f.sync_all())
        .map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))?;
    drop(f);
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mesh {
        let mut m = Mesh::default();
        m.polygon(
            &[
                [500000.0, 4000000.0, 100.0],
                [500001.0, 4000000.0, 100.0],
                [500001.0, 4000001.0, 100.5],
                [500000.0, 4000001.0, 100.5],
            ],
            [0.0, 0.0, 1.0],
            [200, 100, 50, 255],
        );
        m
    }

    #[test]
    fn ply_holds_the_counts_and_exact_coordinates() {
        let b = ply_bytes(&square());
        let text = String::from_utf8_lossy(&b);
        assert!(text.contains("element vertex 4\n") && text.contains("element face 2\n"));
        let body = text.find("end_header\n").unwrap() + "end_header\n".len();
        // 4 vertices of 40 bytes, 2 faces of 13.
        assert_eq!(b.len() - body, 4 * 40 + 2 * 13);
        let x = f64::from_le_bytes(b[body + 40..body + 48].try_into().unwrap());
        assert_eq!(x, 500001.0);
    }

    #[test]
    fn glb_chunks_are_aligned_and_the_node_carries_the_centre() {
        let b = glb_bytes(&square());
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
            b.len()
        );
        let json_len = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        assert_eq!(json_len % 4, 0);
        let json: serde_json::Value = serde_json::from_slice(&b[20..20 + json_len]).unwrap();
        let t = &json["nodes"][0]["translation"];
        assert_eq!(t[0].as_f64(), Some(500000.5));
        assert_eq!(t[2].as_f64(), Some(-4000000.5));
        assert_eq!(json["accessors"][3]["count"], 6);
        let bin_len = u32::from_le_bytes(b[20 + json_len..24 + json_len].try_into().unwrap());
        assert_eq!(bin_len % 4, 0);
        assert_eq!(b.len(), 28 + json_len + bin_len as usize);
    }

    #[test]
    fn other_extensions_are_refused() {
        let e = write(Path::new("/tmp/x.obj"), &square(), true).unwrap_err();
        assert!(e.to_string().contains("x.obj"), "{e}");
    }
}
