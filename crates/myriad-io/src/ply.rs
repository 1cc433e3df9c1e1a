//! PLY, ascii and binary (both byte orders). Only the `vertex` element is read; elements before it
//! are skipped, elements after it are never touched. Properties are matched by name:
//! x y z; red green blue (also diffuse_*, r g b); intensity (also scalar_intensity, i);
//! nx ny nz (also normal_x ...); classification (also scalar_classification). Other properties
//! are skipped. Vertex records are read in blocks, so memory does not grow with the file.

use crate::atomic::AtomicFile;
use crate::read_util::{OffsetReader, Scalar, parse_f64, quote, to_u16_channel};
use crate::{Format, PointSource, SourceInfo};
use myriad_core::{Attribute, Error, PointBatch, PointRecord, Result, Schema};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    ty: Scalar,
    /// For list properties, the type of the count.
    list_count: Option<Scalar>,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

/// Which output column a vertex property feeds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    Pos(usize),
    Rgb(usize),
    Intensity,
    Normal(usize),
    Classification,
    Skip,
}

fn target_of(name: &str) -> Target {
    match name.to_ascii_lowercase().as_str() {
        "x" => Target::Pos(0),
        "y" => Target::Pos(1),
        "z" => Target::Pos(2),
        "red" | "diffuse_red" | "r" => Target::Rgb(0),
        "green" | "diffuse_green" | "g" => Target::Rgb(1),
        "blue" | "diffuse_blue" | "b" => Target::Rgb(2),
        "intensity" | "scalar_intensity" | "i" => Target::Intensity,
        "nx" | "normal_x" => Target::Normal(0),
        "ny" | "normal_y" => Target::Normal(1),
        "nz" | "normal_z" => Target::Normal(2),
        "classification" | "scalar_classification" => Target::Classification,
        _ => Target::Skip,
    }
}

fn scalar_of(t: &str) -> Option<Scalar> {
    Some(match t {
        "char" | "int8" => Scalar::I8,
        "uchar" | "uint8" => Scalar::U8,
        "short" | "int16" => Scalar::I16,
        "ushort" | "uint16" => Scalar::U16,
        "int" | "int32" => Scalar::I32,
        "uint" | "uint32" => Scalar::U32,
        "float" | "float32" => Scalar::F32,
        "double" | "float64" => Scalar::F64,
        _ => return None,
    })
}

pub struct PlySource {
    info: SourceInfo,
    reader: OffsetReader,
    encoding: Encoding,
    vertex: Element,
    targets: Vec<Target>,
    /// Byte size of one vertex record (binary, no list properties).
    stride: usize,
    remaining: u64,
    /// Lines read so far (ascii), for error messages.
    line: u64,
    skipped: u64,
    buf: Vec<u8>,
}

impl PlySource {
    pub fn open(path: &Path) -> Result<PlySource> {
        let mut reader = OffsetReader::open(path)?;
        let mut line = Vec::new();
        let mut line_no = 0u64;
        let mut encoding = None;
        let mut elements: Vec<Element> = Vec::new();
        let mut vertex_list_line = None;
        loop {
            let start = reader.offset;
            if !reader.read_line(&mut line)? {
                return Err(Error::at_byte(
                    path,
                    start,
                    "file ends before \"end_header\"",
                ));
            }
            line_no += 1;
            let text = String::from_utf8_lossy(&line);
            let toks: Vec<&str> = text.split_whitespace().collect();
            let bad = |m: String| Error::at_line(path, line_no, m);
            match toks.as_slice() {
                ["ply"] if line_no == 1 => {}
                _ if line_no == 1 => {
                    return Err(Error::at_byte(
                        path,
                        0,
                        "wrong magic number: PLY files start with \"ply\"",
                    ));
                }
                ["format", f, _v] => {
                    encoding = Some(match *f {
                        "ascii" => Encoding::Ascii,
                        "binary_little_endian" => Encoding::BinaryLe,
                        "binary_big_endian" => Encoding::BinaryBe,
                        other => {
                            return Err(bad(format!(
                                "unknown PLY format \"{}\"",
                                quote(other.as_bytes())
                            )));
                        }
                    })
                }
                ["comment", ..] | ["obj_info", ..] | [] => {}
                ["element", name, count] => {
                    let count = count.parse::<u64>().map_err(|_| {
                        bad(format!("bad element count \"{}\"", quote(count.as_bytes())))
                    })?;
                    elements.push(Element {
                        name: name.to_string(),
                        count,
                        props: Vec::new(),
                    });
                }
                ["property", "list", ct, it, name] => {
                    let e = elements
                        .last_mut()
                        .ok_or_else(|| bad("property before any element".into()))?;
                    let list_count =
                        scalar_of(ct).ok_or_else(|| bad(format!("unknown type \"{ct}\"")))?;
                    let ty = scalar_of(it).ok_or_else(|| bad(format!("unknown type \"{it}\"")))?;
                    if e.name == "vertex" {
                        vertex_list_line.get_or_insert(line_no);
                    }
                    e.props.push(Property {
                        name: name.to_string(),
                        ty,
                        list_count: Some(list_count),
                    });
                }
                ["property", t, name] => {
                    let e = elements
                        .last_mut()
                        .ok_or_else(|| bad("property before any element".into()))?;
                    let ty = scalar_of(t).ok_or_else(|| bad(format!("unknown type \"{t}\"")))?;
                    e.props.push(Property {
                        name: name.to_string(),
                        ty,
                        list_count: None,
                    });
                }
                ["end_header"] => break,
                _ => {
                    let shown: String = text.trim().chars().take(40).collect();
                    return Err(bad(format!(
                        "unexpected header line \"{}\"",
                        shown.escape_debug()
                    )));
                }
            }
        }
        let encoding = encoding
            .ok_or_else(|| Error::at_line(path, line_no, "header has no \"format\" line"))?;
        let vi = elements
            .iter()
            .position(|e| e.name == "vertex")
            .ok_or_else(|| Error::at_line(path, line_no, "header has no \"vertex\" element"))?;
        let vertex = elements[vi].clone();
        let targets: Vec<Target> = vertex.props.iter().map(|p| target_of(&p.name)).collect();
        for axis in 0..3 {
            if !targets.contains(&Target::Pos(axis)) {
                return Err(Error::at_line(
                    path,
                    line_no,
                    format!(
                        "vertex element has no \"{}\" property",
                        ["x", "y", "z"][axis]
                    ),
                ));
            }
        }
        if let Some(at) = vertex_list_line.filter(|_| encoding != Encoding::Ascii) {
            return Err(Error::at_line(
                path,
                at,
                "list property in a binary PLY vertex element (not supported)",
            ));
        }
        let stride = vertex.props.iter().map(|p| p.ty.size()).sum();
        let mut attributes = Vec::new();
        if targets.contains(&Target::Intensity) {
            attributes.push(Attribute::Intensity);
        }
        if targets.contains(&Target::Classification) {
            attributes.push(Attribute::Classification);
        }
        if targets.iter().any(|t| matches!(t, Target::Rgb(_))) {
            attributes.push(Attribute::Rgb);
        }
        if targets.iter().any(|t| matches!(t, Target::Normal(_))) {
            attributes.push(Attribute::Normal);
        }
        let file_size = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        let version = format!(
            "{} 1.0",
            match encoding {
                Encoding::Ascii => "ascii",
                Encoding::BinaryLe => "binary_little_endian",
                Encoding::BinaryBe => "binary_big_endian",
            }
        );
        let mut src = PlySource {
            info: SourceInfo {
                path: path.to_path_buf(),
                format: Format::Ply,
                version,
                points: Some(vertex.count),
                bounds: None,
                schema: Schema::new(attributes),
                scale: None,
                offset: None,
                crs: None,
                file_size,
                origins: Vec::new(),
            },
            reader,
            encoding,
            remaining: vertex.count,
            vertex,
            targets,
            stride,
            line: line_no,
            skipped: 0,
            buf: Vec::new(),
        };
        if encoding != Encoding::Ascii {
            let needed = (src.stride as u64)
                .checked_mul(src.vertex.count)
                .and_then(|b| b.checked_add(src.reader.offset));
            if elements[..vi].is_empty() && needed.is_none_or(|n| n > file_size) {
                return Err(Error::at_byte(
                    path,
                    file_size,
                    format!(
                        "file ends before the {} vertices its header declares",
                        src.vertex.count
                    ),
                ));
            }
        }
        for e in &elements[..vi] {
            src.skip_element(e)?;
        }
        Ok(src)
    }

    fn skip_element(&mut self, e: &Element) -> Result<()> {
        let mut line = Vec::new();
        let mut scratch = [0u8; 8];
        if self.encoding != Encoding::Ascii && e.props.iter().all(|p| p.list_count.is_none()) {
            // Fixed-size records: skipped at once (an element of no properties takes no bytes,
            // however many it declares; found by fuzzing: 1.7e15 of them took minutes).
            let size: u64 = e.props.iter().map(|p| p.ty.size() as u64).sum();
            let left = self.info.file_size.saturating_sub(self.reader.offset);
            let bytes = size
                .checked_mul(e.count)
                .filter(|&b| b <= left)
                .ok_or_else(|| {
                    Error::at_byte(
                        &self.info.path,
                        self.info.file_size,
                        format!(
                            "file ends inside element \"{}\" ({} declared)",
                            e.name, e.count
                        ),
                    )
                })?;
            return self.reader.skip(bytes);
        }
        for _ in 0..e.count {
            if self.encoding == Encoding::Ascii {
                if !self.reader.read_line(&mut line)? {
                    return Err(Error::at_line(
                        &self.info.path,
                        self.line + 1,
                        format!("file ends inside element \"{}\"", e.name),
                    ));
                }
                self.line += 1;
                continue;
            }
            for p in &e.props {
                let n = match p.list_count {
                    Some(ct) => {
                        self.reader
                            .read_exact(&mut scratch[..ct.size()], "a PLY list count")?;
                        ct.decode(&scratch, self.encoding == Encoding::BinaryBe) as u64
                    }
                    None => 1,
                };
                for _ in 0..n {
                    self.reader
                        .read_exact(&mut scratch[..p.ty.size()], "a PLY element")?;
                }
            }
        }
        Ok(())
    }

    fn push(&mut self, batch: &mut PointBatch, values: &[f64]) {
        let mut r = PointRecord::default();
        for ((t, p), &v) in self.targets.iter().zip(&self.vertex.props).zip(values) {
            match *t {
                Target::Pos(a) => r.position[a] = v,
                Target::Rgb(c) => r.rgb[c] = to_u16_channel(v, p.ty),
                Target::Intensity => r.intensity = to_u16_channel(v, p.ty),
                Target::Normal(a) => r.normal[a] = v as f32,
                Target::Classification => r.classification = v.clamp(0.0, 255.0) as u8,
                Target::Skip => {}
            }
        }
        if r.position.iter().all(|c| c.is_finite()) {
            batch.push_record(&r);
        } else {
            self.skipped += 1;
        }
    }

    fn read_ascii(&mut self, n: u64, batch: &mut PointBatch) -> Result<()> {
        let mut line = Vec::new();
        let mut values = vec![0.0; self.vertex.props.len()];
        for _ in 0..n {
            if !self.reader.read_line(&mut line)? {
                return Err(Error::at_line(
                    &self.info.path,
                    self.line + 1,
                    format!(
                        "file ends after {} of {} vertices",
                        self.vertex.count - self.remaining,
                        self.vertex.count
                    ),
                ));
            }
            self.line += 1;
            let mut toks = line
                .split(|b| b.is_ascii_whitespace())
                .filter(|t| !t.is_empty());
            for (i, p) in self.vertex.props.iter().enumerate() {
                let mut next = |what: &str| -> Result<f64> {
                    let t = toks.next().ok_or_else(|| {
                        Error::at_line(
                            &self.info.path,
                            self.line,
                            format!("missing value for \"{what}\""),
                        )
                    })?;
                    parse_f64(t).ok_or_else(|| {
                        Error::at_line(
                            &self.info.path,
                            self.line,
                            format!("not a number: \"{}\"", quote(t)),
                        )
                    })
                };
                let v = next(&p.name)?;
                values[i] = v;
                if p.list_count.is_some() {
                    for _ in 0..(v.max(0.0) as u64) {
                        next(&p.name)?;
                    }
                }
            }
            self.remaining -= 1;
            self.push(batch, &values);
        }
        Ok(())
    }

    fn read_binary(&mut self, n: u64, batch: &mut PointBatch) -> Result<()> {
        let big = self.encoding == Encoding::BinaryBe;
        let bytes = n as usize * self.stride;
        let mut buf = std::mem::take(&mut self.buf);
        buf.resize(bytes, 0);
        let start = self.reader.offset;
        let got = self.reader.read_up_to(&mut buf)?;
        if got < bytes {
            return Err(Error::at_byte(
                &self.info.path,
                start + got as u64,
                format!(
                    "file ends after {} of {} vertices",
                    self.vertex.count - self.remaining + (got / self.stride) as u64,
                    self.vertex.count
                ),
            ));
        }
        let mut values = vec![0.0; self.vertex.props.len()];
        for rec in buf.chunks_exact(self.stride) {
            let mut o = 0;
            for (i, p) in self.vertex.props.iter().enumerate() {
                values[i] = p.ty.decode(&rec[o..], big);
                o += p.ty.size();
            }
            self.push(batch, &values);
        }
        self.remaining -= n;
        self.buf = buf;
        Ok(())
    }
}

impl PointSource for PlySource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }
    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        if self.remaining == 0 {
            return Ok(None);
        }
        let n = self.remaining.min(crate::batch_len(max) as u64);
        let mut batch = PointBatch::with_schema(&self.info.schema, n as usize);
        match self.encoding {
            Encoding::Ascii => self.read_ascii(n, &mut batch)?,
            _ => self.read_binary(n, &mut batch)?,
        }
        Ok(Some(batch))
    }
    fn skipped_non_finite(&self) -> u64 {
        self.skipped
    }
}

/// Writes binary little-endian PLY: double x y z, then whichever of ushort intensity,
/// uchar classification, uchar red green blue (the usual 8-bit PLY colour, from the top byte of
/// 16-bit colour), float nx ny nz the schema carries. The vertex count goes in a fixed-width
/// header field that is patched when the file is finished.
pub struct PlySink {
    out: BufWriter<std::fs::File>,
    file: AtomicFile,
    schema: Schema,
    written: u64,
    count_at: u64,
    path: PathBuf,
}

const COUNT_WIDTH: usize = 20;

impl PlySink {
    pub fn create(path: &Path, schema: &Schema, force: bool) -> Result<PlySink> {
        let file = AtomicFile::create(path, force)?;
        let mut out = BufWriter::with_capacity(1 << 20, file.open_write()?);
        let mut header = String::from(
            "ply\nformat binary_little_endian 1.0\ncomment written by myriad\nelement vertex ",
        );
        let count_at = header.len() as u64;
        header.push_str(&format!("{:<COUNT_WIDTH$}\n", 0));
        header.push_str("property double x\nproperty double y\nproperty double z\n");
        let mut kept = Vec::new();
        for a in &schema.attributes {
            let props: &[&str] = match a {
                Attribute::Intensity => &["ushort intensity"],
                Attribute::Classification => &["uchar classification"],
                Attribute::Rgb => &["uchar red", "uchar green", "uchar blue"],
                Attribute::Normal => &["float nx", "float ny", "float nz"],
                _ => continue,
            };
            kept.push(a.clone());
            for p in props {
                header.push_str(&format!("property {p}\n"));
            }
        }
        header.push_str("end_header\n");
        out.write_all(header.as_bytes())
            .map_err(|e| Error::io(path, e))?;
        Ok(PlySink {
            out,
            file,
            schema: Schema::new(kept),
            written: 0,
            count_at,
            path: path.to_path_buf(),
        })
    }

    pub fn write(&mut self, batch: &PointBatch) -> Result<()> {
        if !batch.is_consistent() {
            return Err(Error::Invalid(format!(
                "{}: a column's length differs from the point count",
                self.path.display()
            )));
        }
        let mut rec = Vec::with_capacity(64);
        for i in 0..batch.len() {
            rec.clear();
            for c in batch.positions[i] {
                rec.extend_from_slice(&c.to_le_bytes());
            }
            for a in &self.schema.attributes {
                match a {
                    Attribute::Intensity => rec.extend_from_slice(
                        &batch.intensity.as_ref().map_or(0, |v| v[i]).to_le_bytes(),
                    ),
                    Attribute::Classification => {
                        rec.push(batch.classification.as_ref().map_or(0, |v| v[i]))
                    }
                    Attribute::Rgb => {
                        let c = batch.rgb.as_ref().map_or([0; 3], |v| v[i]);
                        rec.extend(c.iter().map(|x| (x >> 8) as u8));
                    }
                    Attribute::Normal => {
                        for n in batch.normal.as_ref().map_or([0.0; 3], |v| v[i]) {
                            rec.extend_from_slice(&n.to_le_bytes());
                        }
                    }
                    _ => {}
                }
            }
            self.out
                .write_all(&rec)
                .map_err(|e| Error::io(&self.path, e))?;
        }
        self.written += batch.len() as u64;
        Ok(())
    }

    pub fn finish(mut self) -> Result<u64> {
        use std::io::{Seek, SeekFrom};
        self.out.flush().map_err(|e| Error::io(&self.path, e))?;
        let f = self.out.get_mut();
        f.seek(SeekFrom::Start(self.count_at))
            .map_err(|e| Error::io(&self.path, e))?;
        f.write_all(format!("{:<COUNT_WIDTH$}", self.written).as_bytes())
            .map_err(|e| Error::io(&self.path, e))?;
        f.sync_all().map_err(|e| Error::io(&self.path, e))?;
        self.file.commit()?;
        Ok(self.written)
    }
}
