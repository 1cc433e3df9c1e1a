//! PTS and XYZ/CSV/TXT text. Values are separated by white space, commas or semicolons. The column
//! layout is taken from `--columns` when given, else from a header line of names when the file
//! has one, else from the number of values on the first data line:
//!
//! | values | layout |
//! |---|---|
//! | 3 | x y z |
//! | 4 | x y z intensity |
//! | 6 | x y z r g b |
//! | 7 | x y z intensity r g b (the PTS layout) |
//! | 9 | x y z r g b nx ny nz |
//! | other | x y z, the rest skipped |
//!
//! A PTS file (or any text file) may start with a line holding only the point count; it is used as
//! the header count. Lines starting with `#` or `//` are comments. PTS intensities (-2048..2047)
//! are stretched to 0..65535; colours 0..255 are widened to 16 bits.

use crate::read_util::{OffsetReader, Scalar, parse_f64, quote, to_u16_channel};
use crate::{Format, PointSource, SourceInfo};
use myriad_core::{Attribute, Error, PointBatch, PointRecord, Result, Schema};
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Col {
    Pos(usize),
    Intensity,
    Rgb(usize),
    Normal(usize),
    Classification,
    GpsTime,
    Skip,
}

fn col_of(name: &str) -> Option<Col> {
    Some(
        match name
            .trim()
            .trim_start_matches("//")
            .to_ascii_lowercase()
            .as_str()
        {
            "x" => Col::Pos(0),
            "y" => Col::Pos(1),
            "z" => Col::Pos(2),
            "i" | "intensity" | "scalar_intensity" => Col::Intensity,
            "r" | "red" => Col::Rgb(0),
            "g" | "green" => Col::Rgb(1),
            "b" | "blue" => Col::Rgb(2),
            "nx" | "normal_x" => Col::Normal(0),
            "ny" | "normal_y" => Col::Normal(1),
            "nz" | "normal_z" => Col::Normal(2),
            "c" | "class" | "classification" => Col::Classification,
            "t" | "time" | "gps_time" | "gpstime" => Col::GpsTime,
            "_" | "skip" | "-" => Col::Skip,
            _ => return None,
        },
    )
}

fn layout_for(n: usize) -> Vec<Col> {
    use Col::*;
    match n {
        4 => vec![Pos(0), Pos(1), Pos(2), Intensity],
        6 => vec![Pos(0), Pos(1), Pos(2), Rgb(0), Rgb(1), Rgb(2)],
        7 => vec![Pos(0), Pos(1), Pos(2), Intensity, Rgb(0), Rgb(1), Rgb(2)],
        9 => vec![
            Pos(0),
            Pos(1),
            Pos(2),
            Rgb(0),
            Rgb(1),
            Rgb(2),
            Normal(0),
            Normal(1),
            Normal(2),
        ],
        _ => {
            let mut v = vec![Pos(0), Pos(1), Pos(2)];
            v.resize(n.max(3), Skip);
            v
        }
    }
}

fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace() || *b == b',' || *b == b';')
        .filter(|t| !t.is_empty())
}

fn is_comment(line: &[u8]) -> bool {
    let t = line.trim_ascii_start();
    t.is_empty()
        || t.starts_with(b"#")
        || (t.starts_with(b"//")
            && !t[2..]
                .trim_ascii_start()
                .first()
                .is_some_and(|c| c.is_ascii_alphabetic()))
}

pub struct TextSource {
    info: SourceInfo,
    reader: OffsetReader,
    cols: Vec<Col>,
    pts_intensity: bool,
    line: u64,
    pending: Option<Vec<u8>>,
    skipped: u64,
}

impl TextSource {
    pub fn open(path: &Path, columns: Option<&str>) -> Result<TextSource> {
        let mut reader = OffsetReader::open(path)?;
        let is_pts = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("pts"));
        let mut line = Vec::new();
        let mut line_no = 0u64;
        let mut count = None;
        let mut header_cols = None;
        // Find the first data line, reading past comments, a count line and a names line.
        let first = loop {
            if !reader.read_line(&mut line)? {
                break None;
            }
            line_no += 1;
            if is_comment(&line) {
                continue;
            }
            let toks: Vec<&[u8]> = tokens(&line).collect();
            if std::str::from_utf8(&line).is_err() {
                return Err(Error::at_line(
                    path,
                    line_no,
                    "not text: invalid UTF-8 (is this a binary file?)",
                ));
            }
            if toks.len() == 1
                && count.is_none()
                && header_cols.is_none()
                && let Ok(n) = std::str::from_utf8(toks[0]).unwrap_or("").parse::<u64>()
            {
                count = Some(n);
                continue;
            }
            if let Some(bad) = toks.iter().find(|t| parse_f64(t).is_none()) {
                // A line of column names is a header (skipped when --columns overrides it).
                let names: Option<Vec<Col>> = toks
                    .iter()
                    .map(|t| col_of(std::str::from_utf8(t).unwrap_or("")))
                    .collect();
                if let (None, Some(names)) = (&header_cols, names) {
                    header_cols = Some(names);
                    continue;
                }
                return Err(Error::at_line(
                    path,
                    line_no,
                    format!("not a number: \"{}\"", quote(bad)),
                ));
            }
            break Some(toks.len());
        };
        let cols = match columns {
            Some(spec) => spec
                .split(',')
                .map(|n| {
                    col_of(n).ok_or_else(|| {
                        Error::Invalid(format!("--columns: unknown column name \"{n}\""))
                    })
                })
                .collect::<Result<Vec<_>>>()?,
            None => match header_cols {
                Some(c) => c,
                None => layout_for(first.unwrap_or(3)),
            },
        };
        for a in 0..3 {
            if !cols.contains(&Col::Pos(a)) {
                return Err(Error::Invalid(format!(
                    "{}: column layout has no {}",
                    path.display(),
                    ["x", "y", "z"][a]
                )));
            }
        }
        let mut attributes = Vec::new();
        for (pred, a) in [
            (
                &(|c: &Col| *c == Col::Intensity) as &dyn Fn(&Col) -> bool,
                Attribute::Intensity,
            ),
            (
                &|c: &Col| *c == Col::Classification,
                Attribute::Classification,
            ),
            (&|c: &Col| *c == Col::GpsTime, Attribute::GpsTime),
            (&|c: &Col| matches!(c, Col::Rgb(_)), Attribute::Rgb),
            (&|c: &Col| matches!(c, Col::Normal(_)), Attribute::Normal),
        ] {
            if cols.iter().any(pred) {
                attributes.push(a);
            }
        }
        let file_size = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        Ok(TextSource {
            info: SourceInfo {
                path: path.to_path_buf(),
                format: Format::Text,
                version: if is_pts { "PTS".into() } else { "XYZ".into() },
                points: count,
                bounds: None,
                schema: Schema::new(attributes),
                scale: None,
                offset: None,
                crs: None,
                file_size,
                origins: Vec::new(),
            },
            reader,
            cols,
            pts_intensity: is_pts,
            line: line_no - first.is_some() as u64,
            pending: first.map(|_| line.clone()),
            skipped: 0,
        })
    }

    fn parse_line(&mut self, line: &[u8], batch: &mut PointBatch) -> Result<()> {
        let mut r = PointRecord::default();
        let mut toks = tokens(line);
        for c in &self.cols {
            let t = toks.next().ok_or_else(|| {
                Error::at_line(
                    &self.info.path,
                    self.line,
                    format!("expected {} values", self.cols.len()),
                )
            })?;
            if *c == Col::Skip {
                continue;
            }
            let v = parse_f64(t).ok_or_else(|| {
                Error::at_line(
                    &self.info.path,
                    self.line,
                    format!("not a number: \"{}\"", quote(t)),
                )
            })?;
            match *c {
                Col::Pos(a) => r.position[a] = v,
                Col::Intensity if self.pts_intensity => {
                    r.intensity = ((v + 2048.0) * (65535.0 / 4095.0))
                        .round()
                        .clamp(0.0, 65535.0) as u16
                }
                Col::Intensity => r.intensity = to_u16_channel(v, Scalar::F64),
                Col::Rgb(k) => {
                    r.rgb[k] = if v <= 255.0 {
                        to_u16_channel(v, Scalar::U8)
                    } else {
                        to_u16_channel(v, Scalar::U16)
                    }
                }
                Col::Normal(k) => r.normal[k] = v as f32,
                Col::Classification => r.classification = v.clamp(0.0, 255.0) as u8,
                Col::GpsTime => r.gps_time = v,
                Col::Skip => {}
            }
        }
        if r.position.iter().all(|c| c.is_finite()) {
            batch.push_record(&r);
        } else {
            self.skipped += 1;
        }
        Ok(())
    }
}

impl PointSource for TextSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        let max = crate::batch_len(max);
        let mut batch = PointBatch::with_schema(&self.info.schema, max.min(1 << 16));
        let mut line = Vec::new();
        let mut lines = 0;
        while lines < max {
            if let Some(p) = self.pending.take() {
                line = p;
            } else if !self.reader.read_line(&mut line)? {
                break;
            }
            self.line += 1;
            if is_comment(&line) {
                continue;
            }
            self.parse_line(&line, &mut batch)?;
            lines += 1;
        }
        Ok((lines > 0).then_some(batch))
    }

    fn skipped_non_finite(&self) -> u64 {
        self.skipped
    }
}
