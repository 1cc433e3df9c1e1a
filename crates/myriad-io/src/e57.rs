//! E57 through the `e57` crate: every scan in the file, its pose applied, spherical coordinates
//! converted, intensity and colour normalized by the file's limits and stored as 16 bits. Where
//! every scan was taken from one place (spherical coordinates or a row/column grid), each
//! point's source ID is its scan's number (1, 2, ...) and `SourceInfo::origins` holds where the
//! scanner stood (the poses' translations).
//!
//! The crate's point iterator borrows its reader, so decoding runs on a producer thread that sends
//! batches through a channel of depth 2: memory stays bounded and the caller's thread is free.
//!
//! The 48-byte file header is checked here first, so that the common failures name a byte offset:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | "ASTM-E57" |
//! | 8 | 8 | major, minor version (u32 each) |
//! | 16 | 8 | physical file length (u64) |
//! | 24 | 8 | XML section offset (u64) |
//! | 32 | 8 | XML section length (u64) |
//! | 40 | 8 | page size (u64; each page ends in a 4-byte CRC) |
//!
//! Each scan's pose and the scale and offset of scaled-integer coordinates are checked too
//! (`check_scans`), named at their XML element's byte offset.

use crate::{Format, PointSource, SourceInfo};
use myriad_core::{Attribute, Error, PointBatch, Result, Schema};
use std::path::Path;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

pub struct E57Source {
    info: SourceInfo,
    rx: Option<Receiver<Result<PointBatch>>>,
    skipped: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

fn check_header(path: &Path, file_size: u64) -> Result<u64> {
    let mut h = [0u8; 48];
    let n = crate::read_util::read_prefix(path, &mut h)?;
    if n < 8 || &h[..8] != b"ASTM-E57" {
        return Err(Error::at_byte(
            path,
            0,
            "wrong magic number: E57 files start with \"ASTM-E57\"",
        ));
    }
    if n < 48 {
        return Err(Error::at_byte(
            path,
            n as u64,
            "file ends inside the 48-byte E57 header",
        ));
    }
    let u = |o: usize| u64::from_le_bytes(h[o..o + 8].try_into().unwrap());
    let (len, xml_off, xml_len, page) = (u(16), u(24), u(32), u(40));
    if len > file_size {
        return Err(Error::at_byte(
            path,
            file_size,
            format!("file is truncated: header declares {len} bytes"),
        ));
    }
    if xml_off >= file_size {
        return Err(Error::at_byte(
            path,
            24,
            format!("XML section offset {xml_off} lies outside the file ({file_size} bytes)"),
        ));
    }
    if xml_off
        .checked_add(xml_len)
        .is_none_or(|end| end > file_size)
    {
        return Err(Error::at_byte(
            path,
            32,
            format!("XML section length {xml_len} runs past the end of the file"),
        ));
    }
    // Pages end in a 4-byte checksum; the e57 crate reads pages of at most 1 MiB.
    if !(8..=1 << 20).contains(&page) || !file_size.is_multiple_of(page) {
        return Err(Error::at_byte(
            path,
            40,
            format!(
                "page size {page} (must be 8 bytes to 1 MiB and divide the file's {file_size} bytes)"
            ),
        ));
    }
    Ok(xml_off)
}

/// How far a pose's rotation quaternion may be from unit length: files write each component to
/// 6-17 significant digits, and a quaternion of another length also scales the scan.
const QUATERNION_TOLERANCE: f64 = 1e-4;

/// Checks, scan by scan, the XML values that coordinates are computed from: the pose (finite
/// translation, finite unit rotation quaternion) and the scale and offset of scaled-integer
/// coordinates (finite, scale non-zero). A bad value is named at its element's byte offset.
fn check_scans(path: &Path, clouds: &[e57::PointCloud], xml_off: u64) -> Result<()> {
    for (i, pc) in clouds.iter().enumerate() {
        let bad = |element: &[&str], m: String| {
            let at = xml_element_offset(path, i, element).unwrap_or(xml_off);
            Error::at_byte(path, at, format!("scan {i}: {m}"))
        };
        if let Some(t) = &pc.transform {
            let (q, v) = (&t.rotation, &t.translation);
            let quat = [q.w, q.x, q.y, q.z];
            if quat.iter().any(|c| !c.is_finite()) {
                return Err(bad(
                    &["pose", "rotation"],
                    format!("pose rotation {quat:?} is not finite"),
                ));
            }
            let norm = quat.iter().map(|c| c * c).sum::<f64>().sqrt();
            if (norm - 1.0).abs() > QUATERNION_TOLERANCE {
                return Err(bad(
                    &["pose", "rotation"],
                    format!("pose rotation quaternion has length {norm}, not 1 (not a rotation)"),
                ));
            }
            if [v.x, v.y, v.z].iter().any(|c| !c.is_finite()) {
                return Err(bad(
                    &["pose", "translation"],
                    format!("pose translation [{}, {}, {}] is not finite", v.x, v.y, v.z),
                ));
            }
        }
        for r in &pc.prototype {
            use e57::RecordName as N;
            let name = match r.name {
                N::CartesianX => "cartesianX",
                N::CartesianY => "cartesianY",
                N::CartesianZ => "cartesianZ",
                N::SphericalRange => "sphericalRange",
                N::SphericalAzimuth => "sphericalAzimuth",
                N::SphericalElevation => "sphericalElevation",
                _ => continue,
            };
            if let e57::RecordDataType::ScaledInteger { scale, offset, .. } = r.data_type {
                if !scale.is_finite() || scale == 0.0 {
                    return Err(bad(
                        &["points", "prototype", name],
                        format!("{name} scale is {scale}: no coordinate can be computed from it"),
                    ));
                }
                if !offset.is_finite() {
                    return Err(bad(
                        &["points", "prototype", name],
                        format!("{name} offset is {offset}"),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The byte offset in the file of an element of scan `scan`'s description (`element`: the tag
/// path below the scan's node in `data3D`), from its position in the XML text. The XML section
/// is stored in pages whose last 4 bytes are a checksum, so positions are mapped page by page.
fn xml_element_offset(path: &Path, scan: usize, element: &[&str]) -> Option<u64> {
    let mut h = [0u8; 48];
    crate::read_util::read_prefix(path, &mut h).ok()?;
    let u = |o: usize| u64::from_le_bytes(h[o..o + 8].try_into().unwrap());
    let (xml_off, page) = (u(24), u(40));
    let data = page.checked_sub(4).filter(|d| *d > 0)?;
    let file = std::fs::File::open(path).ok()?;
    let xml = e57::E57Reader::raw_xml(std::io::BufReader::new(file)).ok()?;
    let text = std::str::from_utf8(&xml).ok()?;
    let doc = roxmltree::Document::parse(text).ok()?;
    let data3d = doc.descendants().find(|n| n.has_tag_name("data3D"))?;
    let mut node = data3d.children().filter(|n| n.is_element()).nth(scan)?;
    for tag in element {
        node = node.children().find(|n| n.has_tag_name(*tag))?;
    }
    let logical = xml_off / page * data + xml_off % page + node.range().start as u64;
    Some(logical / data * page + logical % data)
}

/// A scan taken from one place: spherical coordinates, or a row/column grid.
fn stationary(c: &e57::PointCloud) -> bool {
    c.has_spherical() || c.has_row_column()
}

fn e57_error(path: &Path, at: u64, e: e57::Error) -> Error {
    Error::at_byte(path, at, format!("invalid E57 data: {e}"))
}

impl E57Source {
    pub fn open(path: &Path) -> Result<E57Source> {
        let file_size = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        let xml_off = check_header(path, file_size)?;
        let reader = e57::E57Reader::from_file(path).map_err(|e| e57_error(path, xml_off, e))?;
        let clouds = reader.pointclouds();
        check_scans(path, &clouds, xml_off)?;
        let points = clouds.iter().map(|c| c.records).sum();
        let mut attributes = Vec::new();
        if clouds.iter().any(|c| c.has_intensity()) {
            attributes.push(Attribute::Intensity);
        }
        if clouds.iter().any(|c| c.has_color()) {
            attributes.push(Attribute::Rgb);
        }
        // Scans taken from one place (spherical coordinates or a row/column grid: a terrestrial
        // scanner) have the scanner at their own origin: where their poses put it. Their points
        // carry their scan's number as the source ID, so that normals can face the scanner.
        let origins: Vec<[f64; 3]> = if clouds.iter().all(stationary) {
            clouds
                .iter()
                .map(|c| {
                    c.transform.as_ref().map_or([0.0; 3], |t| {
                        [t.translation.x, t.translation.y, t.translation.z]
                    })
                })
                .collect()
        } else {
            Vec::new()
        };
        if !origins.is_empty() {
            attributes.push(Attribute::PointSourceId);
        }
        let crs = reader
            .coordinate_metadata()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_string);
        let h = reader.header();
        Ok(E57Source {
            info: SourceInfo {
                path: path.to_path_buf(),
                format: Format::E57,
                version: format!(
                    "{}.{}, {} scan{}",
                    h.major,
                    h.minor,
                    clouds.len(),
                    if clouds.len() == 1 { "" } else { "s" }
                ),
                points: Some(points),
                bounds: None,
                schema: Schema::new(attributes),
                scale: None,
                offset: None,
                crs,
                file_size,
                origins,
            },
            rx: None,
            skipped: Default::default(),
        })
    }

    fn start(&mut self, batch: usize) {
        let (tx, rx) = sync_channel(2);
        let path = self.info.path.clone();
        let schema = self.info.schema.clone();
        let skipped = self.skipped.clone();
        std::thread::Builder::new()
            .name("e57-reader".into())
            .spawn(move || {
                if let Err(e) = produce(&path, &schema, batch, &tx, &skipped) {
                    let _ = tx.send(Err(e));
                }
            })
            .expect("spawn E57 reader thread");
        self.rx = Some(rx);
    }
}

fn produce(
    path: &Path,
    schema: &Schema,
    batch_size: usize,
    tx: &SyncSender<Result<PointBatch>>,
    skipped: &std::sync::atomic::AtomicU64,
) -> Result<()> {
    let mut reader = e57::E57Reader::from_file(path).map_err(|e| e57_error(path, 0, e))?;
    for (scan, pc) in reader.pointclouds().into_iter().enumerate() {
        let at = pc.file_offset;
        let mut it = reader
            .pointcloud_simple(&pc)
            .map_err(|e| e57_error(path, at, e))?;
        it.apply_pose(true);
        it.spherical_to_cartesian(true);
        it.normalize_intensity(true);
        it.normalize_color(true);
        it.intensity_to_color(false);
        let mut batch = PointBatch::with_schema(schema, batch_size);
        for p in it {
            let p = p.map_err(|e| e57_error(path, at, e))?;
            let e57::CartesianCoordinate::Valid { x, y, z } = p.cartesian else {
                skipped.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                continue;
            };
            if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                skipped.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                continue;
            }
            let u16n = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
            batch.positions.push([x, y, z]);
            if let Some(c) = &mut batch.intensity {
                c.push(p.intensity.map_or(0, u16n));
            }
            if let Some(c) = &mut batch.point_source_id {
                c.push((scan + 1).min(u16::MAX as usize) as u16);
            }
            if let Some(c) = &mut batch.rgb {
                c.push(
                    p.color
                        .map_or([0; 3], |c| [u16n(c.red), u16n(c.green), u16n(c.blue)]),
                );
            }
            if batch.len() == batch_size {
                let full =
                    std::mem::replace(&mut batch, PointBatch::with_schema(schema, batch_size));
                if tx.send(Ok(full)).is_err() {
                    return Ok(()); // the consumer went away
                }
            }
        }
        if !batch.is_empty() && tx.send(Ok(batch)).is_err() {
            return Ok(());
        }
    }
    Ok(())
}

impl PointSource for E57Source {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>> {
        if self.rx.is_none() {
            self.start(crate::batch_len(max));
        }
        match self.rx.as_ref().expect("started").recv() {
            Ok(r) => r.map(Some),
            Err(_) => Ok(None), // producer finished
        }
    }

    fn skipped_non_finite(&self) -> u64 {
        self.skipped.load(std::sync::atomic::Ordering::Relaxed)
    }
}
