//! The LAS 1.4 extra-bytes VLR (LASF_Spec / 4, R15 section 2.6): what the extra bytes after
//! each record hold, read into [`ExtraDim`]s and written back.

use myriad_core::{ExtraDim, ExtraType};

/// Parses the extra-bytes VLR (LASF_Spec / 4): 192-byte descriptors, LAS 1.4 R15 table 24.
///
/// | offset | size | field |
/// |---|---|---|
/// | 0 | 2 | reserved |
/// | 2 | 1 | data type (0 = undocumented, 1..10 = u8..f64) |
/// | 3 | 1 | options (bit 3 scale, bit 4 offset; for type 0, the byte count) |
/// | 4 | 32 | name |
/// | 40 | 24 | no data, 64 min, 88 max |
/// | 112 | 24 | scale (f64 first) |
/// | 136 | 24 | offset (f64 first) |
/// | 160 | 32 | description |
pub fn extra_dims(header: &las::Header) -> Vec<ExtraDim> {
    let Some(vlr) = header
        .all_vlrs()
        .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
    else {
        return Vec::new();
    };
    let text = |b: &[u8]| {
        String::from_utf8_lossy(b)
            .trim_end_matches('\0')
            .trim()
            .to_string()
    };
    let mut dims = Vec::new();
    let mut offset = 0;
    for d in vlr.data.chunks_exact(192) {
        let options = d[3];
        let Some(data_type) = ExtraType::from_las_code(d[2], options) else {
            break;
        };
        let f = |o: usize| f64::from_le_bytes(d[o..o + 8].try_into().unwrap());
        dims.push(ExtraDim {
            name: text(&d[4..36]),
            data_type,
            offset,
            description: text(&d[160..192]),
            // A scale or offset that is not finite is dropped: the raw values are kept either
            // way, and metadata (JSON) cannot hold it.
            scale: (options & 0x08 != 0)
                .then(|| f(112))
                .filter(|v| v.is_finite()),
            add_offset: (options & 0x10 != 0)
                .then(|| f(136))
                .filter(|v| v.is_finite()),
        });
        offset += data_type.size();
    }
    dims
}

/// The extra-bytes VLR (LASF_Spec / 4) describing `dims`, in their order: the inverse of
/// [`extra_dims`], with the same 192-byte descriptors.
pub fn extra_bytes_vlr(dims: &[ExtraDim]) -> las::Vlr {
    let mut data = Vec::with_capacity(dims.len() * 192);
    for d in dims {
        let mut b = [0u8; 192];
        let (code, len) = d.data_type.las_code();
        b[2] = code;
        let mut options = len;
        if let Some(s) = d.scale {
            options |= 0x08;
            b[112..120].copy_from_slice(&s.to_le_bytes());
        }
        if let Some(o) = d.add_offset {
            options |= 0x10;
            b[136..144].copy_from_slice(&o.to_le_bytes());
        }
        b[3] = options;
        let name = d.name.as_bytes();
        b[4..4 + name.len().min(32)].copy_from_slice(&name[..name.len().min(32)]);
        let text = d.description.as_bytes();
        b[160..160 + text.len().min(32)].copy_from_slice(&text[..text.len().min(32)]);
        data.extend_from_slice(&b);
    }
    las::Vlr {
        user_id: "LASF_Spec".into(),
        record_id: 4,
        description: "extra bytes".into(),
        data,
    }
}
