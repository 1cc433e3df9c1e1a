//! Writing LAS/LAZ ([`LasSink`]): records encoded column by column (`las_records`), LAZ
//! compressed by the `las` crate, the file appearing whole through an [`AtomicFile`].

use crate::atomic::AtomicFile;
use crate::las_records::{self, Layout, Quantization};
use myriad_core::{Aabb, Attribute, Error, PointBatch, Result, Schema};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// What to write: point format, version, scaling, VLRs.
#[derive(Debug, Clone)]
pub struct LasWriteOptions {
    pub header: las::Header,
}

impl LasWriteOptions {
    /// The same point format, scaling, VLRs and version as `header` (a source's).
    pub fn like(header: &las::Header) -> LasWriteOptions {
        LasWriteOptions {
            header: header.clone(),
        }
    }

    /// The smallest LAS 1.4 point format that holds every attribute of `schema`, with `scale` and
    /// `offset` for positions.
    pub fn for_schema(
        schema: &Schema,
        scale: [f64; 3],
        offset: [f64; 3],
    ) -> Result<LasWriteOptions> {
        let has = |a: Attribute| schema.has(&a);
        let wave = has(Attribute::WavePacket);
        let format = if has(Attribute::Nir) {
            if wave { 10 } else { 8 }
        } else if has(Attribute::ScannerChannel) {
            match (has(Attribute::Rgb), wave) {
                (true, true) => 10,
                (true, false) => 7,
                (false, true) => 9,
                (false, false) => 6,
            }
        } else {
            match (has(Attribute::Rgb), wave) {
                (true, true) => 5,
                (true, false) => {
                    if has(Attribute::GpsTime) {
                        3
                    } else {
                        2
                    }
                }
                (false, true) => 4,
                (false, false) => {
                    if has(Attribute::GpsTime) {
                        1
                    } else {
                        0
                    }
                }
            }
        };
        let mut b = las::Builder::from((1, 4));
        b.point_format =
            las::point::Format::new(format).map_err(|e| Error::Invalid(e.to_string()))?;
        b.point_format.extra_bytes = schema.extra_bytes as u16;
        b.generating_software = "myriad".into();
        let header = b.into_header().map_err(|e| Error::Invalid(e.to_string()))?;
        LasWriteOptions { header }.with_transforms(scale, offset)
    }

    /// Sets the scale and offset of positions.
    pub fn with_transforms(self, scale: [f64; 3], offset: [f64; 3]) -> Result<LasWriteOptions> {
        let mut b = las::Builder::from(self.header);
        for (i, t) in [
            &mut b.transforms.x,
            &mut b.transforms.y,
            &mut b.transforms.z,
        ]
        .into_iter()
        .enumerate()
        {
            t.scale = scale[i];
            t.offset = offset[i];
        }
        let header = b.into_header().map_err(|e| Error::Invalid(e.to_string()))?;
        Ok(LasWriteOptions { header })
    }

    /// Sets the coordinate reference system as OGC WKT (stored in a LAS 1.4 WKT VLR).
    pub fn with_wkt_crs(mut self, wkt: &str) -> Result<LasWriteOptions> {
        self.header
            .set_wkt_crs(wkt.as_bytes().to_vec())
            .map_err(|e| Error::Invalid(e.to_string()))?;
        Ok(self)
    }
}

/// The point stream of a [`LasSink`]: raw records, or LAZ chunks compressed on all cores.
enum PointOut {
    Las(BufWriter<File>),
    Laz(laz::ParLasZipCompressor<BufWriter<File>>),
}

/// Streams batches into a LAS or LAZ file (LAZ when `path` ends in .laz), atomically.
///
/// The `las` crate encodes the header and VLRs; records and the final header (counts, counts per
/// return, bounds, EVLRs) are written here. The crate's own `Writer` refuses to close a legacy
/// (1.0-1.3) file that holds return numbers 6 or 7, which the 3-bit field allows and real scans
/// contain, and panics when dropped after an error; this writer does neither.
pub struct LasSink {
    out: Option<PointOut>,
    file: AtomicFile,
    header: las::Header,
    layout: Layout,
    quant: Quantization,
    record_len: usize,
    bytes: Vec<u8>,
    written: u64,
    by_return: [u64; 15],
    bounds: Aabb,
    path: PathBuf,
}

impl LasSink {
    pub fn create(path: &Path, options: LasWriteOptions, force: bool) -> Result<LasSink> {
        let compressed = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
        let invalid = |e: las::Error| Error::Invalid(format!("{}: {e}", path.display()));
        let mut b = las::Builder::from(options.header);
        b.point_format.is_compressed = compressed;
        b.vlrs
            .retain(|v| !(v.user_id == "laszip encoded" || v.user_id == "copc"));
        b.evlrs.retain(|v| v.user_id != "copc");
        let mut header = b.into_header().map_err(invalid)?;
        if compressed {
            header.add_laz_vlr().map_err(invalid)?;
        }
        let fmt = *header.point_format();
        let format_id = fmt.to_u8().map_err(invalid)?;
        let layout = Layout::new(format_id).expect("las crate accepted the format");
        let quant = Quantization::of(&header);
        let file = AtomicFile::create(path, force)?;
        let mut w = BufWriter::with_capacity(1 << 20, file.open_write()?);
        header
            .write_to(&mut w)
            .map_err(|e| las_write_error(path, e))?;
        let out = if compressed {
            let vlr = header.laz_vlr().map_err(invalid)?;
            PointOut::Laz(
                laz::ParLasZipCompressor::new(w, vlr)
                    .map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))?,
            )
        } else {
            PointOut::Las(w)
        };
        Ok(LasSink {
            out: Some(out),
            file,
            header,
            layout,
            quant,
            record_len: fmt.len() as usize,
            bytes: Vec::new(),
            written: 0,
            by_return: [0; 15],
            bounds: Aabb::EMPTY,
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
        self.bytes.clear();
        las_records::encode(
            batch,
            self.record_len,
            &self.layout,
            &self.quant,
            &mut self.bytes,
            &mut self.bounds,
        )
        .map_err(|e| {
            Error::Invalid(format!(
                "{}: point {}: {}",
                self.path.display(),
                self.written + e.point as u64,
                e.message
            ))
        })?;
        if let Some(r) = &batch.return_number {
            for &n in r {
                if (1..=15).contains(&n) {
                    self.by_return[n as usize - 1] += 1;
                }
            }
        }
        let io = |e| Error::io(&self.path, e);
        match self.out.as_mut().expect("write after finish") {
            PointOut::Las(w) => std::io::Write::write_all(w, &self.bytes).map_err(io)?,
            PointOut::Laz(c) => c.compress_many(&self.bytes).map_err(io)?,
        }
        self.written += batch.len() as u64;
        Ok(())
    }

    /// Writes EVLRs and the final header, then moves the file to its name. Returns the points.
    pub fn finish(mut self) -> Result<u64> {
        use std::io::Write;
        let path = self.path.clone();
        let io = |e| Error::io(&path, e);
        let mut w = match self.out.take().expect("finish twice") {
            PointOut::Las(w) => w,
            PointOut::Laz(mut c) => {
                c.done()
                    .map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))?;
                c.into_inner()
            }
        };
        let mut raw = self
            .header
            .clone()
            .into_raw()
            .map_err(|e| las_write_error(&path, e))?;
        let legacy_ok = self.layout.format < 6 && self.written <= u32::MAX as u64;
        let version = self.header.version();
        let v14 = version >= las::Version::new(1, 4);
        if !legacy_ok && !v14 {
            return Err(Error::Invalid(format!(
                "{}: {} points do not fit a LAS {}.{} file",
                path.display(),
                self.written,
                version.major,
                version.minor
            )));
        }
        if !self.header.evlrs().is_empty() {
            let start = w.stream_position().map_err(io)?;
            for v in self.header.evlrs() {
                v.clone()
                    .into_raw(true)
                    .and_then(|r| r.write_to(&mut w))
                    .map_err(|e| las_write_error(&path, e))?;
            }
            raw.evlr = Some(las::raw::header::Evlr {
                start_of_first_evlr: start,
                number_of_evlrs: self.header.evlrs().len() as u32,
            });
        }
        raw.number_of_point_records = if legacy_ok { self.written as u32 } else { 0 };
        raw.number_of_points_by_return = std::array::from_fn(|i| {
            if legacy_ok {
                self.by_return[i] as u32
            } else {
                0
            }
        });
        if v14 {
            raw.large_file = Some(las::raw::header::LargeFile {
                number_of_point_records: self.written,
                number_of_points_by_return: self.by_return,
            });
        }
        let b = if self.written > 0 {
            self.bounds
        } else {
            Aabb::new([0.0; 3], [0.0; 3])
        };
        (raw.min_x, raw.min_y, raw.min_z) = (b.min[0], b.min[1], b.min[2]);
        (raw.max_x, raw.max_y, raw.max_z) = (b.max[0], b.max[1], b.max[2]);
        w.seek(SeekFrom::Start(0)).map_err(io)?;
        raw.write_to(&mut w)
            .map_err(|e| las_write_error(&path, e))?;
        w.flush().map_err(io)?;
        w.into_inner()
            .map_err(|e| Error::io(&path, e.into_error()))?
            .sync_all()
            .map_err(io)?;
        self.file.commit()?;
        Ok(self.written)
    }
}

fn las_write_error(path: &Path, e: las::Error) -> Error {
    match e {
        las::Error::Io(io) => Error::io(path, io),
        e => Error::Invalid(format!("{}: {e}", path.display())),
    }
}
