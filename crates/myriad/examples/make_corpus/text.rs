//! Text scans (XYZ, CSV, PTS) and placement files.

use super::*;

pub(super) fn text(c: &mut Corpus) {
    c.reads(
        "text/valid.xyz",
        b"1 2 3\n4 5 6\n7 8 9\n",
        INPUT,
        "\"points\":3",
    );
    c.fails(
        "text/not-a-number.xyz",
        b"1 2 3\n4 5 6\n7 8 abc\n",
        INPUT,
        "line 3: not a number: \"abc\"",
    );
    c.reads(
        "text/nan-inf.xyz",
        b"1 2 3\nnan 5 6\n7 inf 9\n1e999 1 1\n4 4 4\n",
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "text/short-row.csv",
        b"x,y,z,intensity\n1,2,3,4\n5,6\n",
        INPUT,
        "line 3: expected 4 values",
    );
    c.reads(
        "text/count-lies.pts",
        b"1000\n1 2 3 10 1 2 3\n4 5 6 20 4 5 6\n",
        INPUT,
        "\"points\":2",
    );
    c.fails(
        "text/binary.txt",
        &[0xFF, 0xFE, 0x00, 0x41, b'\n'],
        INPUT,
        "line 1",
    );
    c.fails("text/garbage.xyz", &garbage(300, 6), INPUT, "line 1");
}

pub(super) fn placement(c: &mut Corpus) {
    let scan = b"1 2 3\n4 5 6\n7 8 9\n";
    let mut case = |name: &str, text: &str, line: &str| {
        c.file(&format!("placement/{name}.xyz"), scan);
        let p = format!("placement/{name}.xyz.placement");
        c.file(&p, text.as_bytes());
        for cmd in INPUT {
            let file = format!("placement/{name}.xyz");
            c.expect(&file, cmd, 1, &format!("{p}: {line}"));
        }
    };
    case(
        "not-invertible",
        "# flattens z\nTRANSFORM 1 0 0 0  0 1 0 0  0 0 0 0\n",
        "line 2: TRANSFORM is not invertible",
    );
    case(
        "nan",
        "TRANSLATE nan 0 0\n",
        "line 1: not a number: \"nan\"",
    );
    case(
        "inf",
        "ROTATE-DEG 0 0 inf\n",
        "line 1: not a number: \"inf\"",
    );
    case(
        "combined",
        "TRANSLATE 1 2 3\nTRANSFORM 1 0 0 0 0 1 0 0 0 0 1 0\n",
        "line 2: TRANSFORM cannot be combined",
    );
    case(
        "overflows",
        "TRANSFORM 1e300 0 0 0  0 1e300 0 0  0 0 1e300 0\n",
        "line 1: TRANSFORM is not invertible (determinant inf",
    );
    case(
        "negative-box",
        "OBB-ANGLES SOCS 0 0 0 -1 1 1 0 0 0\n",
        "line 1: half lengths must not be negative",
    );
}
