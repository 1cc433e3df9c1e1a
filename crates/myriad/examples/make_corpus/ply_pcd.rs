//! PLY and PCD files: counts, types, sizes, NaN coordinates, truncations.

use super::*;

pub(super) const PLY_HEAD: &str = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n";

pub(super) fn ply_binary(head: &str, points: &[[f32; 3]]) -> Vec<u8> {
    let mut b = head.as_bytes().to_vec();
    for p in points {
        for v in p {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

pub(super) fn ply(c: &mut Corpus) {
    let pts = [
        [1.0, 2.0, 3.0],
        [4.0, 5.0, 6.0],
        [7.0, 8.0, 9.0],
        [1.5, 2.5, 3.5],
    ];
    let ok = ply_binary(PLY_HEAD, &pts);
    c.reads("ply/valid.ply", &ok, INPUT, "\"points\":4");
    let end = PLY_HEAD.len() + 36;
    c.fails(
        "ply/count-more.ply",
        &ply_binary(PLY_HEAD, &pts[..3]),
        INPUT,
        &format!("byte {end}: file ends before the 4 vertices"),
    );
    c.reads(
        "ply/count-fewer.ply",
        &ply_binary(&PLY_HEAD.replace("vertex 4", "vertex 2"), &pts),
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "ply/count-u64-max.ply",
        &ply_binary(
            &PLY_HEAD.replace("vertex 4", "vertex 18446744073709551615"),
            &pts,
        ),
        INPUT,
        "byte 182: file ends before the 18446744073709551615 vertices its header declares",
    );
    c.fails(
        "ply/count-overflows-u64.ply",
        &ply_binary(
            &PLY_HEAD.replace("vertex 4", "vertex 99999999999999999999"),
            &pts,
        ),
        INPUT,
        "line 3: ",
    );
    c.fails(
        "ply/count-negative.ply",
        &ply_binary(&PLY_HEAD.replace("vertex 4", "vertex -1"), &pts),
        INPUT,
        "line 3: ",
    );
    let mut nan = pts;
    nan[1][0] = f32::NAN;
    nan[2][2] = f32::INFINITY;
    c.reads(
        "ply/nan-inf-binary.ply",
        &ply_binary(PLY_HEAD, &nan),
        INPUT,
        "\"points\":2",
    );
    let ascii = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    c.reads(
        "ply/nan-inf-ascii.ply",
        format!("{ascii}1 2 3\nnan 5 6\n7 8 inf\n").as_bytes(),
        INPUT,
        "\"points\":1",
    );
    c.fails(
        "ply/not-a-number.ply",
        format!("{ascii}1 2 3\n4 five 6\n7 8 9\n").as_bytes(),
        INPUT,
        "line 9: not a number: \"five\"",
    );
    c.reads(
        "ply/huge-number.ply",
        format!("{ascii}1 2 3\n4 1e999999999999 6\n7 8 9\n").as_bytes(),
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "ply/no-end-header.ply",
        b"ply\nformat ascii 1.0\nelement vertex 3\n",
        INPUT,
        "file ends before \"end_header\"",
    );
    c.fails(
        "ply/unknown-type.ply",
        PLY_HEAD
            .replace("property float x", "property float128 x")
            .as_bytes(),
        INPUT,
        "line 4: ",
    );
    c.fails(
        "ply/no-z.ply",
        &ply_binary(&PLY_HEAD.replace("property float z\n", ""), &pts),
        INPUT,
        "line ",
    );
    c.fails(
        "ply/list-coordinate.ply",
        &ply_binary(
            &PLY_HEAD.replace("property float x", "property list uchar float x"),
            &pts,
        ),
        INPUT,
        "line 4: list property in a binary PLY vertex element",
    );
    // Elements before the vertices are skipped: one of no properties takes no bytes however
    // many it declares (found by fuzzing: counting 1.7e15 of them took minutes); one whose
    // records run past the end is an error.
    let empty = PLY_HEAD.replace(
        "element vertex 4",
        "element nothing 1744073709551616\nelement vertex 4",
    );
    c.reads(
        "ply/empty-element-huge-count.ply",
        &ply_binary(&empty, &pts),
        INPUT,
        "\"points\":4",
    );
    let before = PLY_HEAD.replace(
        "element vertex 4",
        "element face 1000000\nproperty int a\nelement vertex 4",
    );
    let end = before.len() + 48;
    c.fails(
        "ply/element-past-end.ply",
        &ply_binary(&before, &pts),
        INPUT,
        &format!("byte {end}: file ends inside element \"face\" (1000000 declared)"),
    );
    let cut = PLY_HEAD.len() + 12 + 5;
    c.fails(
        "ply/cut-in-record.ply",
        &ok[..cut],
        INPUT,
        &format!("byte {cut}: file ends before the 4 vertices"),
    );
    c.fails("ply/empty.ply", b"", INPUT, "byte 0: wrong magic number");
    let mut g = b"ply\n".to_vec();
    g.extend(garbage(500, 4));
    c.fails("ply/garbage-after-magic.ply", &g, INPUT, "line 2: ");
}

pub(super) const PCD_HEAD: &str = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n";

pub(super) fn pcd(c: &mut Corpus) {
    let pts = [
        [1.0f32, 2.0, 3.0],
        [4.0, 5.0, 6.0],
        [7.0, 8.0, 9.0],
        [1.5, 2.5, 3.5],
    ];
    let bin = |head: &str, pts: &[[f32; 3]]| ply_binary(head, pts);
    c.reads("pcd/valid.pcd", &bin(PCD_HEAD, &pts), INPUT, "\"points\":4");
    c.fails(
        "pcd/points-more.pcd",
        &bin(PCD_HEAD, &pts[..2]),
        INPUT,
        &format!(
            "byte {}: file ends before the 4 points",
            PCD_HEAD.len() + 24
        ),
    );
    let fewer = PCD_HEAD
        .replace("WIDTH 4", "WIDTH 2")
        .replace("POINTS 4", "POINTS 2");
    c.reads(
        "pcd/points-fewer.pcd",
        &bin(&fewer, &pts),
        INPUT,
        "\"points\":2",
    );
    let max = PCD_HEAD
        .replace("WIDTH 4", "WIDTH 18446744073709551615")
        .replace("POINTS 4", "POINTS 18446744073709551615");
    c.fails(
        "pcd/points-u64-max.pcd",
        &bin(&max, &pts),
        INPUT,
        "byte 207: file ends before the 18446744073709551615 points its header declares",
    );
    let over = PCD_HEAD.replace("POINTS 4", "POINTS 99999999999999999999");
    c.fails(
        "pcd/points-overflow-u64.pcd",
        &bin(&over, &pts),
        INPUT,
        "line 9: ",
    );
    let wh = PCD_HEAD.replace("HEIGHT 1", "HEIGHT 3");
    // WIDTH x HEIGHT is only the organization: POINTS counts.
    c.reads(
        "pcd/width-height-lie.pcd",
        &bin(&wh, &pts),
        INPUT,
        "\"points\":4",
    );
    let count = PCD_HEAD.replace("COUNT 1 1 1", "COUNT 1 1 4294967295");
    c.fails(
        "pcd/count-huge.pcd",
        &bin(&count, &pts),
        INPUT,
        "line 5: SIZE and COUNT make a point larger than the whole file",
    );
    // Found by fuzzing: an ascii file whose COUNT asked for a 222-billion-value row buffer.
    let ascii_count = PCD_HEAD
        .replace("COUNT 1 1 1", "COUNT 1 222222222221 1")
        .replace("DATA binary", "DATA ascii");
    c.fails(
        "pcd/count-huge-ascii.pcd",
        format!("{ascii_count}1 2 3\n4 5 6\n7 8 9\n1 1 1\n").as_bytes(),
        INPUT,
        "line 5: SIZE and COUNT make a point larger than the whole file",
    );
    let size = PCD_HEAD.replace("SIZE 4 4 4", "SIZE 4 4 3");
    c.fails(
        "pcd/size-3.pcd",
        &bin(&size, &pts),
        INPUT,
        "line 3: unsupported field type F of size 3",
    );
    let wh = PCD_HEAD
        .replace("WIDTH 4", "WIDTH 4294967296")
        .replace("HEIGHT 1", "HEIGHT 8589934592")
        .replace("POINTS 4\n", "");
    c.fails(
        "pcd/width-height-overflow.pcd",
        &bin(&wh, &pts),
        INPUT,
        "line 7: WIDTH x HEIGHT overflows 64 bits",
    );
    let mut nan = pts;
    nan[0][1] = f32::NAN;
    c.reads(
        "pcd/nan-binary.pcd",
        &bin(PCD_HEAD, &nan),
        INPUT,
        "\"points\":3",
    );
    let ascii = PCD_HEAD.replace("DATA binary", "DATA ascii");
    c.reads(
        "pcd/nan-ascii.pcd",
        format!("{ascii}1 2 3\nnan nan nan\n4 inf 6\n7 8 9\n").as_bytes(),
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "pcd/not-a-number.pcd",
        format!("{ascii}1 2 3\n4 x 6\n7 8 9\n1 1 1\n").as_bytes(),
        INPUT,
        "line 12: not a number: \"x\"",
    );
    // binary_compressed: u32 compressed size, u32 uncompressed size, then LZF data.
    let comp = PCD_HEAD.replace("DATA binary", "DATA binary_compressed");
    let at = comp.len();
    let lzf = |csize: u32, usize_: u32| {
        let mut b = comp.as_bytes().to_vec();
        b.extend_from_slice(&csize.to_le_bytes());
        b.extend_from_slice(&usize_.to_le_bytes());
        b.extend_from_slice(&[0x02, 1, 2, 3]);
        b
    };
    c.fails(
        "pcd/compressed-size-past-end.pcd",
        &lzf(1_000_000_000, 48),
        INPUT,
        &format!("byte {at}: "),
    );
    c.fails(
        "pcd/uncompressed-size-lies.pcd",
        &lzf(4, u32::MAX),
        INPUT,
        &format!("byte {}: ", at + 4),
    );
    let mut bad = comp.as_bytes().to_vec();
    bad.extend_from_slice(&5u32.to_le_bytes());
    bad.extend_from_slice(&48u32.to_le_bytes());
    bad.extend_from_slice(&[0xE0, 0xFF, 0xFF, 0x00, 0x00]);
    c.fails(
        "pcd/lzf-corrupt.pcd",
        &bad,
        INPUT,
        &format!("byte {}: corrupt LZF data", at + 8),
    );
    c.fails(
        "pcd/no-data-line.pcd",
        PCD_HEAD.replace("DATA binary\n", "").as_bytes(),
        INPUT,
        "",
    );
    c.fails(
        "pcd/cut-in-header.pcd",
        &PCD_HEAD.as_bytes()[..40],
        INPUT,
        "",
    );
    c.fails(
        "pcd/garbage.pcd",
        &garbage(300, 5),
        INPUT,
        "byte 0: wrong magic number",
    );
}
