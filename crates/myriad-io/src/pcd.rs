//! PCD (the Point Cloud Library's format), v0.5-0.7: ascii, binary and binary_compressed data.
//!
//! Fields are matched by name (case-insensitive): x y z; rgb / rgba (packed 0x00RRGGBB, float or
//! integer); r g b / red green blue; intensity; normal_x normal_y normal_z; classification; gpstime;
//! returnnumber, numberofreturns, pointsourceid, userdata, scananglerank (as PDAL writes them).
//! Organized clouds mark missing points with NaN coordinates; those are skipped and counted.
//!
//! binary_compressed is one LZF block (u32 compressed size, u32 raw size, data) holding the fields
//! column after column, so it is decoded whole on the first read; ascii and binary stream.
//! LZF is decoded here (20 lines) rather than through a C binding so that a corrupt block is a
//! clean error with its byte offset.

use crate::read_util::{OffsetReader, Scalar, parse_f64, quote, to_u16_channel};
use crate::{Format, PointSource, SourceInfo};
use myriad_core::{Attribute, Error, PointBatch, PointRecord, Result, Schema};
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    Pos(usize),
    PackedRgb,
    Rgb(usize),
    Intensity,
    Normal(usize),
    Classification,
    GpsTime,
    ReturnNumber,
    NumberOfReturns,
    PointSourceId,
    UserData,
    ScanAngle,
    Skip,
}

fn target_of(name: &str) -> Target {
    match name.to_ascii_lowercase().as_str() {
        "x" => Target::Pos(0),
        "y" => Target::Pos(1),
        "z" => Target::Pos(2),
        "rgb" | "rgba" => Target::PackedRgb,
        "r" | "red" => Target::Rgb(0),
        "g" | "green" => Target::Rgb(1),
        "b" | "blue" => Target::Rgb(2),
        "intensity" => Target::Intensity,
        "normal_x" => Target::Normal(0),
        "normal_y" => Target::Normal(1),
        "normal_z" => Target::Normal(2),
        "classification" => Target::Classification,
        "gpstime" | "gps_time" => Target::GpsTime,
        "returnnumber" | "return_number" => Target::ReturnNumber,
        "numberofreturns" | "number_of_returns" => Target::NumberOfReturns,
        "pointsourceid" | "point_source_id" => Target::PointSourceId,
        "userdata" | "user_data" => Target::UserData,
        "scananglerank" | "scan_angle" | "scanangle" => Target::ScanAngle,
        _ => Target::Skip,
    }
}

#[derive(Debug, Clone)]
struct Field {
    target: Target,
    ty: Scalar,
    count: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Data {
    Ascii,
    Binary,
    Compressed,
}

pub struct PcdSource {
    info: SourceInfo,
    reader: OffsetReader,
    fields: Vec<Field>,
    data: Data,
    stride: usize,
    total: u64,
    done: u64,
    line: u64,
    skipped: u64,
    /// binary_compressed: the decoded column-major block.
    columns: Option<Vec<u8>>,
}

fn parse_type(path: &Path, line: u64, t: &str, size: &str) -> Result<Scalar> {
    let bad = || {
        Error::at_line(
            path,
            line,
            format!("unsupported field type {t} of size {size}"),
        )
    };
    Ok(match (t, size) {
        ("I", "1") => Scalar::I8,
        ("I", "2") => Scalar::I16,
        ("I", "4") => Scalar::I32,
        ("I", "8") => Scalar::I64,
        ("U", "1") => Scalar::U8,
        ("U", "2") => Scalar::U16,
        ("U", "4") => Scalar::U32,
        ("U", "8") => Scalar::U64,
        ("F", "4") => Scalar::F32,
        ("F", "8") => Scalar::F64,
        _ => return Err(bad()),
    })
}

impl PcdSource {
    pub fn open(path: &Path) -> Result<PcdSource> {
        let mut reader = OffsetReader::open(path)?;
        let mut line = Vec::new();
        let mut line_no = 0;
        let (mut names, mut sizes, mut types, mut counts) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut width, mut height, mut points) = (None, None, None);
        // Lines of the keys checked after the header, so that errors name them.
        let (mut size_line, mut count_line, mut height_line) = (0, 0, 0);
        let data;
        loop {
            if !reader.read_line(&mut line)? {
                return Err(Error::at_line(
                    path,
                    line_no + 1,
                    "file ends before the DATA line of the PCD header",
                ));
            }
            line_no += 1;
            let text = String::from_utf8_lossy(&line).to_string();
            let toks: Vec<String> = text.split_whitespace().map(str::to_string).collect();
            let Some(key) = toks.first() else { continue };
            let rest = &toks[1..];
            let num = |s: &str| -> Result<u64> {
                s.parse().map_err(|_| {
                    Error::at_line(
                        path,
                        line_no,
                        format!("not a number: \"{}\"", quote(s.as_bytes())),
                    )
                })
            };
            match key.to_ascii_uppercase().as_str() {
                k if k.starts_with('#') => {}
                "VERSION" | "VIEWPOINT" => {}
                "FIELDS" | "COLUMNS" => names = rest.to_vec(),
                "SIZE" => {
                    sizes = rest.to_vec();
                    size_line = line_no;
                }
                "TYPE" => types = rest.to_vec(),
                "COUNT" => {
                    counts = rest.iter().map(|s| num(s)).collect::<Result<Vec<_>>>()?;
                    count_line = line_no;
                }
                "WIDTH" => width = Some(num(rest.first().map_or("", |s| s))?),
                "HEIGHT" => {
                    height = Some(num(rest.first().map_or("", |s| s))?);
                    height_line = line_no;
                }
                "POINTS" => points = Some(num(rest.first().map_or("", |s| s))?),
                "DATA" => {
                    data = match rest.first().map(|s| s.as_str()) {
                        Some("ascii") => Data::Ascii,
                        Some("binary") => Data::Binary,
                        Some("binary_compressed") => Data::Compressed,
                        other => {
                            return Err(Error::at_line(
                                path,
                                line_no,
                                format!("unknown DATA kind {:?}", other.unwrap_or("")),
                            ));
                        }
                    };
                    break;
                }
                _ if line_no == 1 => {
                    return Err(Error::at_byte(
                        path,
                        0,
                        "wrong magic number: not a PCD header (expected VERSION or FIELDS)",
                    ));
                }
                other => {
                    return Err(Error::at_line(
                        path,
                        line_no,
                        format!("unknown PCD header key \"{}\"", quote(other.as_bytes())),
                    ));
                }
            }
        }
        if names.is_empty() || sizes.len() != names.len() || types.len() != names.len() {
            return Err(Error::at_line(
                path,
                line_no,
                "FIELDS, SIZE and TYPE lines differ in length or are missing",
            ));
        }
        if counts.is_empty() {
            counts = vec![1; names.len()];
        }
        if counts.contains(&0) {
            return Err(Error::at_line(path, count_line, "a field has COUNT 0"));
        }
        if counts.len() != names.len() {
            return Err(Error::at_line(
                path,
                count_line,
                "COUNT line differs in length from FIELDS",
            ));
        }
        let mut fields = Vec::new();
        for i in 0..names.len() {
            fields.push(Field {
                target: target_of(&names[i]),
                ty: parse_type(path, size_line, &types[i], &sizes[i])?,
                count: counts[i] as usize,
            });
        }
        for a in 0..3 {
            if !fields.iter().any(|f| f.target == Target::Pos(a)) {
                return Err(Error::at_line(
                    path,
                    line_no,
                    format!("no \"{}\" field", ["x", "y", "z"][a]),
                ));
            }
        }
        let total = match (points, width, height) {
            (Some(p), _, _) => p,
            (None, Some(w), Some(h)) => w.checked_mul(h).ok_or_else(|| {
                Error::at_line(path, height_line, "WIDTH x HEIGHT overflows 64 bits")
            })?,
            _ => {
                return Err(Error::at_line(
                    path,
                    line_no,
                    "header gives neither POINTS nor WIDTH and HEIGHT",
                ));
            }
        };
        let has = |f: &dyn Fn(Target) -> bool| fields.iter().any(|x| f(x.target));
        let mut attributes = Vec::new();
        for (pred, a) in [
            (
                &(|t| t == Target::Intensity) as &dyn Fn(Target) -> bool,
                Attribute::Intensity,
            ),
            (&|t| t == Target::ReturnNumber, Attribute::ReturnNumber),
            (
                &|t| t == Target::NumberOfReturns,
                Attribute::NumberOfReturns,
            ),
            (&|t| t == Target::Classification, Attribute::Classification),
            (&|t| t == Target::ScanAngle, Attribute::ScanAngle),
            (&|t| t == Target::UserData, Attribute::UserData),
            (&|t| t == Target::PointSourceId, Attribute::PointSourceId),
            (&|t| t == Target::GpsTime, Attribute::GpsTime),
            (
                &|t| matches!(t, Target::Rgb(_) | Target::PackedRgb),
                Attribute::Rgb,
            ),
            (&|t| matches!(t, Target::Normal(_)), Attribute::Normal),
        ] {
            if has(pred) {
                attributes.push(a);
            }
        }
        let file_size = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        // One point's bytes (binary) and values (ascii: each takes at least two bytes) must fit
        // the file: COUNT comes from the file, and buffers are sized from it.
        let stride = fields
            .iter()
            .try_fold(0usize, |a, f| {
                a.checked_add(f.ty.size().checked_mul(f.count)?)
            })
            .filter(|&b| b as u64 <= file_size);
        let values = fields
            .iter()
            .fold(0u64, |a, f| a.saturating_add(f.count as u64));
        let Some(stride) = stride.filter(|_| values.saturating_mul(2) <= file_size + 1) else {
            return Err(Error::at_line(
                path,
                count_line.max(size_line),
                format!(
                    "SIZE and COUNT make a point larger than the whole file ({file_size} bytes)"
                ),
            ));
        };
        let needed = (stride as u64)
            .checked_mul(total)
            .and_then(|b| b.checked_add(reader.offset));
        if data == Data::Binary && needed.is_none_or(|n| n > file_size) {
            return Err(Error::at_byte(
                path,
                file_size,
                format!("file ends before the {total} points its header declares"),
            ));
        }
        Ok(PcdSource {
            info: SourceInfo {
                path: path.to_path_buf(),
                format: Format::Pcd,
                version: match data {
                    Data::Ascii => "ascii",
                    Data::Binary => "binary",
                    Data::Compressed => "binary_compressed",
                }
                .to_string(),
                points: Some(total),
                bounds: None,
                schema: Schema::new(attributes),
                scale: None,
                offset: None,
                crs: None,
                file_size,
                origins: Vec::new(),
            },
            reader,
            fields,
            data,
            stride,
            total,
            done: 0,
            line: line_no,
            skipped: 0,
            columns: None,
        })
    }

    fn push(&mut self, batch: &mut PointBatch, values: &[f64]) {
        let mut r = PointRecord::default();
        let u8c = |v: f64| v.clamp(0.0, 255.0) as u8;
        for (f, &v) in self.fields.iter().zip(values) {
            match f.target {
                Target::Pos(a) => r.position[a] = v,
                Target::PackedRgb => {
                    let bits = if f.ty == Scalar::F32 {
                        (v as f32).to_bits()
                    } else {
                        v as u32
                    };
                    r.rgb = [(bits >> 16) & 0xFF, (bits >> 8) & 0xFF, bits & 0xFF]
                        .map(|c| c as u16 * 257);
                }
                Target::Rgb(c) => r.rgb[c] = to_u16_channel(v, f.ty),
                Target::Normal(a) => r.normal[a] = v as f32,
                Target::Intensity => r.intensity = to_u16_channel(v, f.ty),
                Target::Classification => r.classification = u8c(v),
                Target::GpsTime => r.gps_time = v,
                Target::ReturnNumber => r.return_number = u8c(v),
                Target::NumberOfReturns => r.number_of_returns = u8c(v),
                Target::PointSourceId => r.point_source_id = v.clamp(0.0, 65535.0) as u16,
                Target::UserData => r.user_data = u8c(v),
                Target::ScanAngle => r.scan_angle = v as f32,
                Target::Skip => {}
            }
        }
        if r.position.iter().all(|c| c.is_finite()) {
            batch.push_record(&r);
        } else {
            self.skipped += 1;
        }
    }

    fn decode_compressed(&mut self) -> Result<()> {
        let mut head = [0u8; 8];
        let at = self.reader.offset;
        self.reader
            .read_exact(&mut head, "the binary_compressed size fields")?;
        let csize = u32::from_le_bytes(head[..4].try_into().unwrap()) as usize;
        let usize_ = u32::from_le_bytes(head[4..].try_into().unwrap()) as usize;
        if Some(usize_ as u64) != (self.stride as u64).checked_mul(self.total) {
            return Err(Error::at_byte(
                &self.info.path,
                at + 4,
                format!(
                    "uncompressed size {usize_} does not match {} points of {} bytes",
                    self.total, self.stride
                ),
            ));
        }
        let left = self.info.file_size.saturating_sub(self.reader.offset);
        if csize as u64 > left {
            return Err(Error::at_byte(
                &self.info.path,
                at,
                format!(
                    "compressed size {csize} runs past the end of the file ({left} bytes left)"
                ),
            ));
        }
        // LZF expands at most ~100:1 (a 3-byte back reference yields 264 bytes).
        if usize_ as u64 > csize as u64 * 100 + 1024 {
            return Err(Error::at_byte(
                &self.info.path,
                at + 4,
                format!("uncompressed size {usize_} is impossible for {csize} compressed bytes"),
            ));
        }
        let mut comp = vec![0u8; csize];
        self.reader
            .read_exact(&mut comp, "the compressed point data")?;
        let raw = lzf_decompress(&comp, usize_).map_err(|(o, m)| {
            Error::at_byte(
                &self.info.path,
                at + 8 + o as u64,
                format!("corrupt LZF data: {m}"),
            )
        })?;
        self.columns = Some(raw);
        Ok(())
    }
}

/// Decodes an LZF block (liblzf's format) of known output size. On error returns the input offset.
pub fn lzf_decompress(
    input: &[u8],
    out_len: usize,
) -> std::result::Result<Vec<u8>, (usize, &'static str)> {
    let mut out = Vec::with_capacity(out_len);
    let mut i = 0;
    while i < input.len() {
        let at = i;
        let ctrl = input[i] as usize;
        i += 1;
        if ctrl < 32 {
            let n = ctrl + 1;
            if i + n > input.len() || out.len() + n > out_len {
                return Err((at, "literal run overruns"));
            }
            out.extend_from_slice(&input[i..i + n]);
            i += n;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += *input.get(i).ok_or((at, "truncated back reference"))? as usize;
                i += 1;
            }
            let low = *input.get(i).ok_or((at, "truncated back reference"))? as usize;
            i += 1;
            let back = ((ctrl & 0x1F) << 8) + low + 1;
            let len = len + 2;
            if back > out.len() || out.len() + len > out_len {
                return Err((at, "back reference out of range"));
            }
            let start = out.len() - back;
            for k in 0..len {
                let b = out[start + k];
                out.push(b);
            }
        }
    }
    if out.len() != out_len {
        return Err((input.len(), "block decodes to fewer bytes than declared"));
    }
    Ok(out)
}

impl PointSource for PcdSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        if self.done >= self.total {
            return Ok(None);
        }
        let n = (self.total - self.done).min(crate::batch_len(max) as u64) as usize;
        let mut batch = PointBatch::with_schema(&self.info.schema, n);
        let width: usize = self.fields.iter().map(|f| f.count).sum();
        let mut values = vec![0.0; self.fields.len()];
        match self.data {
            Data::Ascii => {
                let mut line = Vec::new();
                let mut row = Vec::new();
                for _ in 0..n {
                    if !self.reader.read_line(&mut line)? {
                        return Err(Error::at_line(
                            &self.info.path,
                            self.line + 1,
                            format!("file ends after {} of {} points", self.done, self.total),
                        ));
                    }
                    self.line += 1;
                    row.clear();
                    for t in line
                        .split(|b| b.is_ascii_whitespace())
                        .filter(|t| !t.is_empty())
                    {
                        let v = parse_f64(t);
                        row.push(v.ok_or_else(|| {
                            Error::at_line(
                                &self.info.path,
                                self.line,
                                format!("not a number: \"{}\"", quote(t)),
                            )
                        })?);
                    }
                    if row.len() < width {
                        return Err(Error::at_line(
                            &self.info.path,
                            self.line,
                            format!("{} values, header declares {width}", row.len()),
                        ));
                    }
                    let mut k = 0;
                    for (i, f) in self.fields.iter().enumerate() {
                        values[i] = row[k];
                        k += f.count;
                    }
                    self.done += 1;
                    self.push(&mut batch, &values);
                }
            }
            Data::Binary => {
                let mut buf = vec![0u8; n * self.stride];
                self.reader.read_exact(&mut buf, "point records")?;
                for rec in buf.chunks_exact(self.stride) {
                    let mut o = 0;
                    for (i, f) in self.fields.iter().enumerate() {
                        values[i] = f.ty.decode(&rec[o..], false);
                        o += f.ty.size() * f.count;
                    }
                    self.push(&mut batch, &values);
                }
                self.done += n as u64;
            }
            Data::Compressed => {
                if self.columns.is_none() {
                    self.decode_compressed()?;
                }
                let cols = self.columns.take().expect("decoded above");
                let total = self.total as usize;
                for p in self.done as usize..self.done as usize + n {
                    let mut base = 0;
                    for (i, f) in self.fields.iter().enumerate() {
                        let sz = f.ty.size();
                        values[i] = f.ty.decode(&cols[base + p * sz * f.count..], false);
                        base += sz * f.count * total;
                    }
                    self.push(&mut batch, &values);
                }
                self.columns = Some(cols);
                self.done += n as u64;
            }
        }
        Ok(Some(batch))
    }

    fn skipped_non_finite(&self) -> u64 {
        self.skipped
    }
}

#[cfg(test)]
mod tests {
    use super::lzf_decompress;

    #[test]
    fn lzf_literal_and_back_reference() {
        // "abcabcabc": literal "abc", then a back reference of length 6 at distance 3.
        let block = [2, b'a', b'b', b'c', (4 << 5), 2];
        assert_eq!(lzf_decompress(&block, 9).unwrap(), b"abcabcabc");
        assert!(lzf_decompress(&[(1 << 5), 9], 3).is_err());
        assert!(lzf_decompress(&[5, b'a'], 6).is_err());
    }
}
