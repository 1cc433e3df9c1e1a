//! Myriad datasets (.myr): header, metadata, hierarchy and node pages.

use super::*;

/// Fixes the dataset header's checksum (bytes 12..16 over the 64 bytes with them zeroed).
pub(super) fn fix_header_crc(b: &mut [u8]) {
    put(b, 12, &[0; 4]);
    let crc = crc32fast::hash(&b[..64]);
    put(b, 12, &crc.to_le_bytes());
}

pub(super) fn dataset(c: &mut Corpus, tmp: &Path) {
    let src = tmp.join("base-for-myr.las");
    std::fs::write(&src, synth(tmp, "base-myr.las", 2000)).unwrap();
    let out = tmp.join("base.myr");
    let mut options = myriad_build::convert::ConvertOptions::new(&out);
    options.force = true;
    options.params.capacity = 500;
    myriad_build::convert::convert(&[src], &options, &myriad_build::convert::Silent)
        .expect("convert");
    let b = std::fs::read(&out).unwrap();
    let len = b.len();
    c.reads("myr/valid.myr", &b, DATASET, "\"points\":2000");
    let with = |at: usize, v: &[u8]| {
        let mut x = b.clone();
        put(&mut x, at, v);
        x
    };
    c.fails(
        "myr/empty.myr",
        b"",
        DATASET,
        "byte 0: file ends inside the 64-byte dataset header",
    );
    c.fails(
        "myr/cut-in-header.myr",
        &b[..40],
        DATASET,
        "byte 40: file ends inside the 64-byte dataset header",
    );
    c.fails(
        "myr/cut-in-half.myr",
        &b[..len / 2],
        DATASET,
        &format!(
            "byte {}: file has {} bytes, its header says {len}",
            len / 2,
            len / 2
        ),
    );
    c.fails(
        "myr/header-checksum.myr",
        &with(56, &1u64.to_le_bytes()),
        DATASET,
        "byte 12: header checksum mismatch",
    );
    let mut v = with(8, &99u32.to_le_bytes());
    fix_header_crc(&mut v);
    c.fails(
        "myr/version-99.myr",
        &v,
        DATASET,
        "byte 8: format version 99",
    );
    let mut m = with(16, &(u64::MAX - 3).to_le_bytes());
    fix_header_crc(&mut m);
    c.fails(
        "myr/metadata-past-end.myr",
        &m,
        DATASET,
        "byte 16: metadata lies past the end of the file",
    );
    let mut m = with(24, &u32::MAX.to_le_bytes());
    fix_header_crc(&mut m);
    c.fails(
        "myr/metadata-length-huge.myr",
        &m,
        DATASET,
        "byte 16: metadata lies past the end of the file",
    );
    // A metadata number replaced by null (what serde_json writes for NaN), checksums fixed.
    let (moff, mlen) = (u64_at(&b, 16) as usize, u32_at(&b, 24) as usize);
    let json = String::from_utf8(b[moff..moff + mlen].to_vec()).unwrap();
    let key = json.find("\"bounds\"").unwrap();
    let num = key
        + json[key..]
            .find(|ch: char| ch.is_ascii_digit() || ch == '-')
            .unwrap();
    let num_end = num + json[num..].find([',', '\n', ']']).unwrap();
    let mut nulled = json.clone();
    nulled.replace_range(num..num_end, &format!("{:<w$}", "null", w = num_end - num));
    let mut m = b.clone();
    put(&mut m, moff, nulled.as_bytes());
    put(
        &mut m,
        28,
        &crc32fast::hash(nulled.as_bytes()).to_le_bytes(),
    );
    fix_header_crc(&mut m);
    c.fails(
        "myr/metadata-null-number.myr",
        &m,
        DATASET,
        &format!("byte {moff}: metadata: expected a number"),
    );
    // Damage inside the file that only some commands read: the root hierarchy page and the
    // first node page (the point data starts after the header).
    let (hoff, hlen) = (u64_at(&b, 32) as usize, u32_at(&b, 40) as usize);
    let mut h = b.clone();
    h[hoff + hlen / 2] ^= 0x55;
    let name = c.file("myr/hierarchy-damaged.myr", &h);
    c.expect(&name, "info", 0, "\"points\":2000");
    c.expect(&name, "verify", 1, &format!("byte {hoff}: "));
    c.expect(&name, "extract", 1, &format!("byte {hoff}: "));
    c.expect(&name, "render", 1, &format!("byte {hoff}: "));
    let mut n = b.clone();
    n[64 + 100] ^= 0x55;
    let name = c.file("myr/node-damaged.myr", &n);
    c.expect(&name, "info", 0, "\"points\":2000");
    c.expect(&name, "verify", 1, "byte 64: ");
    c.expect(&name, "extract", 1, "byte 64: ");
    c.expect(&name, "render", 0, "");
    let mut g = b"MYRIAD\x00\x1a".to_vec();
    g.extend(garbage(500, 7));
    c.fails(
        "myr/garbage-after-magic.myr",
        &g,
        DATASET,
        "byte 12: header checksum mismatch",
    );
    c.fails(
        "myr/wrong-magic.myr",
        &garbage(500, 8),
        DATASET,
        "byte 0: not a Myriad dataset",
    );
}
