//! The attribute schema: which per-point fields a source or dataset carries. It covers every point
//! field of LAS 1.4 (formats 0-10), surface normals (PLY, E57, estimated), and LAS extra-bytes
//! dimensions, which are kept as raw bytes and described here.

use std::fmt;

/// One per-point field. Positions are always present and are not listed.
#[derive(Debug, Clone, PartialEq)]
pub enum Attribute {
    Intensity,
    ReturnNumber,
    NumberOfReturns,
    Classification,
    /// LAS synthetic / key-point / withheld / overlap bits.
    ClassificationFlags,
    /// LAS scan direction flag and edge-of-flight-line flag.
    ScanFlags,
    ScannerChannel,
    ScanAngle,
    UserData,
    PointSourceId,
    GpsTime,
    Rgb,
    Nir,
    WavePacket,
    Normal,
    Extra(ExtraDim),
}

impl Attribute {
    pub fn name(&self) -> String {
        match self {
            Attribute::Intensity => "intensity".into(),
            Attribute::ReturnNumber => "return_number".into(),
            Attribute::NumberOfReturns => "number_of_returns".into(),
            Attribute::Classification => "classification".into(),
            Attribute::ClassificationFlags => "classification_flags".into(),
            Attribute::ScanFlags => "scan_flags".into(),
            Attribute::ScannerChannel => "scanner_channel".into(),
            Attribute::ScanAngle => "scan_angle".into(),
            Attribute::UserData => "user_data".into(),
            Attribute::PointSourceId => "point_source_id".into(),
            Attribute::GpsTime => "gps_time".into(),
            Attribute::Rgb => "rgb".into(),
            Attribute::Nir => "nir".into(),
            Attribute::WavePacket => "wave_packet".into(),
            Attribute::Normal => "normal".into(),
            Attribute::Extra(d) => format!("extra:{}", d.name),
        }
    }
}

impl Attribute {
    /// The attribute [`Attribute::name`] names (not `Extra`, whose dimension is described apart).
    pub fn from_name(name: &str) -> Option<Attribute> {
        use Attribute::*;
        [
            Intensity,
            ReturnNumber,
            NumberOfReturns,
            Classification,
            ClassificationFlags,
            ScanFlags,
            ScannerChannel,
            ScanAngle,
            UserData,
            PointSourceId,
            GpsTime,
            Rgb,
            Nir,
            WavePacket,
            Normal,
        ]
        .into_iter()
        .find(|a| a.name() == name)
    }
}

/// Data type of a LAS extra-bytes dimension (LAS 1.4 R15, table 24). `Undocumented(n)` is type 0:
/// n opaque bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExtraType {
    Undocumented(u8),
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl ExtraType {
    /// Maps the LAS `data_type` code (1..=10) and `options` size for type 0.
    pub fn from_las_code(code: u8, undocumented_len: u8) -> Option<ExtraType> {
        Some(match code {
            0 => ExtraType::Undocumented(undocumented_len),
            1 => ExtraType::U8,
            2 => ExtraType::I8,
            3 => ExtraType::U16,
            4 => ExtraType::I16,
            5 => ExtraType::U32,
            6 => ExtraType::I32,
            7 => ExtraType::U64,
            8 => ExtraType::I64,
            9 => ExtraType::F32,
            10 => ExtraType::F64,
            _ => return None,
        })
    }
    /// The LAS `data_type` code and, for type 0, the byte count.
    pub fn las_code(&self) -> (u8, u8) {
        match self {
            ExtraType::Undocumented(n) => (0, *n),
            ExtraType::U8 => (1, 0),
            ExtraType::I8 => (2, 0),
            ExtraType::U16 => (3, 0),
            ExtraType::I16 => (4, 0),
            ExtraType::U32 => (5, 0),
            ExtraType::I32 => (6, 0),
            ExtraType::U64 => (7, 0),
            ExtraType::I64 => (8, 0),
            ExtraType::F32 => (9, 0),
            ExtraType::F64 => (10, 0),
        }
    }
    pub fn size(&self) -> usize {
        match self {
            ExtraType::Undocumented(n) => *n as usize,
            ExtraType::U8 | ExtraType::I8 => 1,
            ExtraType::U16 | ExtraType::I16 => 2,
            ExtraType::U32 | ExtraType::I32 | ExtraType::F32 => 4,
            ExtraType::U64 | ExtraType::I64 | ExtraType::F64 => 8,
        }
    }
}

/// A named extra-bytes dimension, `size` bytes at `offset` inside each point's extra bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraDim {
    pub name: String,
    pub data_type: ExtraType,
    pub offset: usize,
    pub description: String,
    pub scale: Option<f64>,
    pub add_offset: Option<f64>,
}

/// The attributes a source carries, in a stable order, plus the byte stride of its extra bytes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Schema {
    pub attributes: Vec<Attribute>,
    /// Bytes of extra data per point (LAS extra bytes); 0 when there are none.
    pub extra_bytes: usize,
}

impl Schema {
    pub fn new(attributes: Vec<Attribute>) -> Schema {
        Schema {
            attributes,
            extra_bytes: 0,
        }
    }
    pub fn has(&self, a: &Attribute) -> bool {
        self.attributes.iter().any(|x| x == a)
    }
    pub fn names(&self) -> Vec<String> {
        let mut v = vec!["x".to_string(), "y".to_string(), "z".to_string()];
        v.extend(self.attributes.iter().map(Attribute::name));
        if self.extra_bytes > 0
            && !self
                .attributes
                .iter()
                .any(|a| matches!(a, Attribute::Extra(_)))
        {
            v.push(format!("extra_bytes[{}]", self.extra_bytes));
        }
        v
    }
    /// The standard LAS fields carried by point format `format` (0..=10).
    pub fn for_las_format(format: u8) -> Schema {
        use Attribute::*;
        let mut a = vec![
            Intensity,
            ReturnNumber,
            NumberOfReturns,
            Classification,
            ClassificationFlags,
            ScanFlags,
            ScanAngle,
            UserData,
            PointSourceId,
        ];
        if format >= 6 {
            a.push(ScannerChannel);
        }
        if format != 0 && format != 2 {
            a.push(GpsTime);
        }
        if matches!(format, 2 | 3 | 5 | 7 | 8 | 10) {
            a.push(Rgb);
        }
        if matches!(format, 8 | 10) {
            a.push(Nir);
        }
        if matches!(format, 4 | 5 | 9 | 10) {
            a.push(WavePacket);
        }
        Schema::new(a)
    }
}

impl fmt::Display for Schema {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.names().join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn las_formats_carry_their_fields() {
        let check = |fmt: u8, has: &[Attribute], lacks: &[Attribute]| {
            let s = Schema::for_las_format(fmt);
            for a in has {
                assert!(s.has(a), "format {fmt} should have {a:?}");
            }
            for a in lacks {
                assert!(!s.has(a), "format {fmt} should lack {a:?}");
            }
        };
        use Attribute::*;
        check(0, &[Intensity], &[GpsTime, Rgb, ScannerChannel]);
        check(1, &[GpsTime], &[Rgb]);
        check(2, &[Rgb], &[GpsTime]);
        check(3, &[GpsTime, Rgb], &[Nir]);
        check(4, &[WavePacket, GpsTime], &[Rgb]);
        check(6, &[ScannerChannel, GpsTime], &[Rgb]);
        check(8, &[Rgb, Nir], &[WavePacket]);
        check(10, &[Rgb, Nir, WavePacket], &[Normal]);
    }

    #[test]
    fn extra_type_sizes() {
        assert_eq!(ExtraType::from_las_code(10, 0).unwrap().size(), 8);
        assert_eq!(ExtraType::from_las_code(0, 3).unwrap().size(), 3);
        assert!(ExtraType::from_las_code(11, 0).is_none());
    }
}
