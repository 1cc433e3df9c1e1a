//! E57 files: poses and scaled-integer coordinates in the XML, header fields, truncations.

use super::*;

/// An E57 file of one scan with a pose and scaled-integer coordinates (1 mm), then its XML
/// section rewritten by `xml` (the writer recomputes the page checksums).
pub(super) fn e57_file(
    tmp: &Path,
    name: &str,
    nan_points: bool,
    xml: impl Fn(String) -> String,
) -> Vec<u8> {
    use ::e57::{
        E57Writer, Quaternion, Record, RecordDataType, RecordName, RecordValue, Transform,
        Translation,
    };
    let p = tmp.join(name);
    let coord = |name| Record {
        name,
        data_type: if nan_points {
            RecordDataType::Double {
                min: None,
                max: None,
            }
        } else {
            RecordDataType::ScaledInteger {
                min: -1_000_000,
                max: 1_000_000,
                scale: 0.001,
                offset: 0.0,
            }
        },
    };
    let proto = vec![
        coord(RecordName::CartesianX),
        coord(RecordName::CartesianY),
        coord(RecordName::CartesianZ),
    ];
    let mut w = E57Writer::from_file(&p, "corpus").unwrap();
    let mut pc = w.add_pointcloud("scan", proto).unwrap();
    pc.set_transform(Some(Transform {
        rotation: Quaternion {
            w: 1.0,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        translation: Translation {
            x: 10.0,
            y: 20.0,
            z: 30.0,
        },
    }));
    for i in 0..20 {
        let v = |k: i64| {
            if nan_points {
                RecordValue::Double(if i % 10 == 3 {
                    f64::NAN
                } else {
                    (i * k) as f64 * 0.01
                })
            } else {
                RecordValue::ScaledInteger(i * k * 10)
            }
        };
        pc.add_point(vec![v(1), v(2), v(3)]).unwrap();
    }
    pc.finalize().unwrap();
    w.finalize_customized_xml(|s| Ok(xml(s))).unwrap();
    drop(w);
    std::fs::read(p).unwrap()
}

/// Replaces the text of the first `<tag ...>TEXT</tag>` after `after` with `value`.
pub(super) fn set_xml(s: &str, after: &str, tag: &str, value: &str) -> String {
    let from = s
        .find(after)
        .unwrap_or_else(|| panic!("{after} in the XML"));
    let open = from
        + s[from..]
            .find(&format!("<{tag}"))
            .unwrap_or_else(|| panic!("<{tag}"));
    let text = open + s[open..].find('>').unwrap() + 1;
    let end = text + s[text..].find('<').unwrap();
    format!("{}{value}{}", &s[..text], &s[end..])
}

/// The byte offset of the first `<tag` after `after` in the file's XML section: the offset the
/// reader must name, found in the file itself.
pub(super) fn xml_at(file: &[u8], after: &str, tag: &str) -> usize {
    let from = file
        .windows(after.len())
        .position(|w| w == after.as_bytes())
        .unwrap();
    from + file[from..]
        .windows(tag.len() + 1)
        .position(|w| w == format!("<{tag}").as_bytes())
        .unwrap()
}

pub(super) fn e57(c: &mut Corpus, tmp: &Path) {
    let b = e57_file(tmp, "base.e57", false, |s| s);
    c.reads("e57/valid.e57", &b, INPUT, "\"points\":20");
    let cases: [(&str, &str, &str, &str, &str); 6] = [
        (
            "pose-translation-nan",
            "<translation",
            "x",
            "NaN",
            "pose translation [NaN, 20, 30] is not finite",
        ),
        (
            "pose-rotation-not-unit",
            "<rotation",
            "w",
            "2",
            "pose rotation quaternion has length 2, not 1",
        ),
        (
            "pose-rotation-inf",
            "<rotation",
            "x",
            "inf",
            "pose rotation [1.0, inf, 0.0, 0.0] is not finite",
        ),
        (
            "scale-x-zero",
            "<cartesianX",
            "cartesianX",
            "",
            "cartesianX scale is 0",
        ),
        (
            "scale-y-nan",
            "<cartesianY",
            "cartesianY",
            "",
            "cartesianY scale is NaN",
        ),
        (
            "offset-z-inf",
            "<cartesianZ",
            "cartesianZ",
            "",
            "cartesianZ offset is inf",
        ),
    ];
    for (name, after, tag, value, message) in cases {
        let f = e57_file(tmp, &format!("{name}.e57"), false, |s| {
            if value.is_empty() {
                // The scale or offset attribute of a scaled-integer coordinate.
                let (attr, v) = match name {
                    "scale-x-zero" => ("scale", "0"),
                    "scale-y-nan" => ("scale", "NaN"),
                    _ => ("offset", "inf"),
                };
                let from = s.find(after).unwrap();
                let a = from + s[from..].find(&format!("{attr}=\"")).unwrap() + attr.len() + 2;
                let e = a + s[a..].find('"').unwrap();
                format!("{}{v}{}", &s[..a], &s[e..])
            } else {
                set_xml(&s, after, tag, value)
            }
        });
        // The element named: the pose's rotation/translation, or the prototype's coordinate.
        let element = if value.is_empty() { tag } else { &after[1..] };
        let at = xml_at(
            &f,
            if value.is_empty() {
                "<prototype"
            } else {
                "<pose"
            },
            element,
        );
        c.fails(
            &format!("e57/{name}.e57"),
            &f,
            INPUT,
            &format!("byte {at}: scan 0: {message}"),
        );
    }
    let len = b.len() as u64;
    let with = |at: usize, v: u64| {
        let mut x = b.clone();
        put(&mut x, at, &v.to_le_bytes());
        x
    };
    c.fails(
        "e57/xml-offset-past-end.e57",
        &with(24, len + 10),
        INPUT,
        "byte 24: XML section offset",
    );
    c.fails(
        "e57/xml-length-overflows.e57",
        &with(32, u64::MAX),
        INPUT,
        "byte 32: XML section length",
    );
    c.fails(
        "e57/length-lies.e57",
        &with(16, len + 1000),
        INPUT,
        &format!(
            "byte {len}: file is truncated: header declares {}",
            len + 1000
        ),
    );
    c.fails(
        "e57/page-size-zero.e57",
        &with(40, 0),
        INPUT,
        "byte 40: page size 0",
    );
    c.fails(
        "e57/page-size-huge.e57",
        &with(40, u64::MAX),
        INPUT,
        "byte 40: page size",
    );
    let half = b.len() / 2;
    c.fails(
        "e57/cut-in-half.e57",
        &b[..half],
        INPUT,
        &format!("byte {half}: file is truncated"),
    );
    c.fails(
        "e57/cut-in-header.e57",
        &b[..20],
        INPUT,
        "byte 20: file ends inside the 48-byte E57 header",
    );
    let mut g = b"ASTM-E57".to_vec();
    g.extend(garbage(1000, 3));
    c.fails("e57/garbage-after-magic.e57", &g, INPUT, "error");
    let records = e57_file(tmp, "records-lie.e57", false, |s| {
        s.replace("recordCount=\"20\"", "recordCount=\"5000\"")
    });
    c.fails(
        "e57/record-count-more.e57",
        &records,
        INPUT,
        "invalid E57 data",
    );
    let fewer = e57_file(tmp, "records-fewer.e57", false, |s| {
        s.replace("recordCount=\"20\"", "recordCount=\"10\"")
    });
    c.reads("e57/record-count-fewer.e57", &fewer, INPUT, "\"points\":10");
    let nan = e57_file(tmp, "nan.e57", true, |s| s);
    c.reads("e57/nan-points.e57", &nan, INPUT, "\"points\":18");
}
