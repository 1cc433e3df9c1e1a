//! A single-band 32-bit float GeoTIFF laid out as a Cloud-Optimized GeoTIFF: tiled (512 x 512,
//! DEFLATE), the image file directory and its arrays at the start of the file, the tiles after
//! it in order, the raster placed by a pixel scale and a tie point, its CRS by EPSG code
//! (GeoKeys), no-data named for GDAL. Written by hand: the `tiff` crate writes strips (no tiles)
//! and places its directories after the data, which a COG may not.
//!
//! Tiles are given in any order, from any thread, compressed as they come and spilled to a
//! scratch file beside the output; [`GeoTiffWriter::finish`] writes the header and directory, then
//! the tiles in row order, and moves the file to its name. Memory: a tile at a time per writer,
//! and the tiles' sizes. Classic TIFF (offsets of 32 bits): an image whose compressed tiles pass
//! 4 GB is refused.

use crate::atomic::AtomicFile;
use myriad_core::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The side of a tile, in pixels.
pub const TILE: usize = 512;
/// The value of pixels without one.
pub const NODATA: f32 = -9999.0;

/// Where the raster lies and in what.
#[derive(Debug, Clone, PartialEq)]
pub struct Georef {
    /// The upper-left corner of the upper-left pixel.
    pub x0: f64,
    pub y_top: f64,
    /// A pixel's side.
    pub cell: f64,
    /// The CRS's EPSG code, and whether it is geographic (`None`: no CRS written).
    pub epsg: Option<(u32, bool)>,
}

pub struct GeoTiffWriter {
    out: PathBuf,
    file: AtomicFile,
    spill: Mutex<(BufWriter<File>, u64)>,
    spill_path: PathBuf,
    /// Per tile: where in the spill file, and its length.
    tiles: Mutex<Vec<Option<(u64, u32)>>>,
    pub width: usize,
    pub height: usize,
    georef: Georef,
    /// Removes the spill file however the writer ends.
    _spilled: Spilled,
}

struct Spilled(PathBuf);

impl Drop for Spilled {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

impl GeoTiffWriter {
    /// A writer of a `width` x `height` image to `out` (which must not exist unless `force`).
    pub fn create(
        out: &Path,
        force: bool,
        width: usize,
        height: usize,
        georef: Georef,
    ) -> Result<GeoTiffWriter> {
        if width == 0 || height == 0 || width > u32::MAX as usize || height > u32::MAX as usize {
            return Err(Error::Invalid(format!(
                "{}: an image of {width} x {height} pixels",
                out.display()
            )));
        }
        let file = AtomicFile::create(out, force)?;
        let spill_path = file.temp_path().with_extension("tiles");
        let spill = File::options()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&spill_path)
            .map_err(|e| Error::io(&spill_path, e))?;
        let n = width.div_ceil(TILE) * height.div_ceil(TILE);
        Ok(GeoTiffWriter {
            out: out.to_path_buf(),
            file,
            spill: Mutex::new((BufWriter::new(spill), 0)),
            _spilled: Spilled(spill_path.clone()),
            spill_path,
            tiles: Mutex::new(vec![None; n]),
            width,
            height,
            georef,
        })
    }

    /// Tiles across and down.
    pub fn tiles(&self) -> (usize, usize) {
        (self.width.div_ceil(TILE), self.height.div_ceil(TILE))
    }

    /// Tile `(tx, ty)` (row 0 at the top): `TILE` x `TILE` values, row by row (NaN: no data).
    pub fn write_tile(&self, tx: usize, ty: usize, values: &[f32]) -> Result<()> {
        assert_eq!(values.len(), TILE * TILE, "a whole tile");
        let mut raw = Vec::with_capacity(TILE * TILE * 4);
        for &v in values {
            let v = if v.is_nan() { NODATA } else { v };
            raw.extend_from_slice(&v.to_le_bytes());
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(6));
        z.write_all(&raw).map_err(|e| Error::io(&self.out, e))?;
        let packed = z.finish().map_err(|e| Error::io(&self.out, e))?;
        let mut s = self.spill.lock().expect("spill");
        let at = s.1;
        s.0.write_all(&packed)
            .map_err(|e| Error::io(&self.spill_path, e))?;
        s.1 += packed.len() as u64;
        let (across, _) = self.tiles();
        self.tiles.lock().expect("tiles")[ty * across + tx] = Some((at, packed.len() as u32));
        Ok(())
    }

    /// Writes the header, the directory and the tiles (a tile never given is no data), and
    /// gives the file its name. Its size.
    pub fn finish(self) -> Result<u64> {
        let (mut spill, _) = self.spill.into_inner().expect("spill");
        spill.flush().map_err(|e| Error::io(&self.spill_path, e))?;
        let mut spill = spill
            .into_inner()
            .map_err(|e| Error::io(&self.spill_path, e.into_error()))?;
        // A tile never given: one of no data, compressed once.
        let mut blank = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(6));
        let raw: Vec<u8> = (0..TILE * TILE)
            .flat_map(|_| NODATA.to_le_bytes())
            .collect();
        blank.write_all(&raw).map_err(|e| Error::io(&self.out, e))?;
        let blank = blank.finish().map_err(|e| Error::io(&self.out, e))?;
        let tiles = self.tiles.into_inner().expect("tiles");
        let lengths: Vec<u32> = tiles
            .iter()
            .map(|t| t.map_or(blank.len() as u32, |(_, l)| l))
            .collect();
        let directory = directory(self.width, self.height, &self.georef, &lengths)?;
        let mut w = BufWriter::new(self.file.open_write()?);
        let io = |e| Error::io(&self.out, e);
        w.write_all(&directory).map_err(io)?;
        let mut buf = Vec::new();
        for t in &tiles {
            match t {
                None => w.write_all(&blank).map_err(io)?,
                Some((at, len)) => {
                    buf.resize(*len as usize, 0);
                    spill
                        .seek(SeekFrom::Start(*at))
                        .map_err(|e| Error::io(&self.spill_path, e))?;
                    spill
                        .read_exact(&mut buf)
                        .map_err(|e| Error::io(&self.spill_path, e))?;
                    w.write_all(&buf).map_err(io)?;
                }
            }
        }
        w.flush().map_err(io)?;
        let f = w.into_inner().map_err(|e| io(e.into_error()))?;
        f.sync_all().map_err(io)?;
        drop(f);
        drop(spill);
        let _ = std::fs::remove_file(&self.spill_path);
        let size = directory.len() as u64 + lengths.iter().map(|&l| l as u64).sum::<u64>();
        self.file.commit()?;
        Ok(size)
    }
}

/// TIFF field types.
const SHORT: u16 = 3;
const LONG: u16 = 4;
const ASCII: u16 = 2;
const DOUBLE: u16 = 12;

/// The header and the image file directory, with the arrays it points to, for tiles of these
/// compressed lengths placed right after it in order.
fn directory(width: usize, height: usize, g: &Georef, lengths: &[u32]) -> Result<Vec<u8>> {
    let n = lengths.len();
    // GeoKeys: the model (projected or geographic), pixels as areas, the CRS by EPSG code (a
    // code past 16 bits cannot be written: the raster is then placed without a CRS).
    let mut keys: Vec<[u16; 4]> = Vec::new();
    if let Some((code, geographic)) = g.epsg.filter(|e| e.0 <= u16::MAX as u32) {
        keys.push([1024, 0, 1, if geographic { 2 } else { 1 }]);
        keys.push([1025, 0, 1, 1]);
        keys.push([if geographic { 2048 } else { 3072 }, 0, 1, code as u16]);
    }
    let mut geokeys: Vec<u16> = vec![1, 1, 0, keys.len() as u16];
    for k in &keys {
        geokeys.extend_from_slice(k);
    }
    // (tag, type, values as bytes, count)
    let shorts = |v: &[u16]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let longs = |v: &[u32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let doubles = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let nodata = format!("{NODATA}\0");
    let mut fields: Vec<(u16, u16, Vec<u8>, u32)> = vec![
        (256, LONG, longs(&[width as u32]), 1),
        (257, LONG, longs(&[height as u32]), 1),
        (258, SHORT, shorts(&[32]), 1),
        (259, SHORT, shorts(&[8]), 1),
        (262, SHORT, shorts(&[1]), 1),
        (277, SHORT, shorts(&[1]), 1),
        (284, SHORT, shorts(&[1]), 1),
        (322, SHORT, shorts(&[TILE as u16]), 1),
        (323, SHORT, shorts(&[TILE as u16]), 1),
        (324, LONG, vec![0; 4 * n], n as u32),
        (325, LONG, longs(lengths), n as u32),
        (339, SHORT, shorts(&[3]), 1),
        (33550, DOUBLE, doubles(&[g.cell, g.cell, 0.0]), 3),
        (
            33922,
            DOUBLE,
            doubles(&[0.0, 0.0, 0.0, g.x0, g.y_top, 0.0]),
            6,
        ),
        (
            42113,
            ASCII,
            nodata.as_bytes().to_vec(),
            nodata.len() as u32,
        ),
    ];
    if !keys.is_empty() {
        fields.push((34735, SHORT, shorts(&geokeys), geokeys.len() as u32));
    }
    fields.sort_by_key(|f| f.0);
    // Header, the directory, then the arrays that do not fit in an entry.
    let dir_len = 2 + 12 * fields.len() + 4;
    let mut extra_at = 8 + dir_len;
    let mut placed = Vec::new();
    for f in &fields {
        if f.2.len() > 4 {
            placed.push(Some(extra_at));
            extra_at += f.2.len() + (f.2.len() & 1);
        } else {
            placed.push(None);
        }
    }
    let data_at = extra_at as u64;
    let total = data_at + lengths.iter().map(|&l| l as u64).sum::<u64>();
    if total > u32::MAX as u64 {
        return Err(Error::Invalid(format!(
            "a GeoTIFF of {total} bytes: past the 4 GB of a classic TIFF (a larger --cell)"
        )));
    }
    // The tiles' offsets, now that the directory's size is known.
    let mut at = data_at as u32;
    let offsets: Vec<u32> = lengths
        .iter()
        .map(|&l| {
            let o = at;
            at += l;
            o
        })
        .collect();
    for f in &mut fields {
        if f.0 == 324 {
            f.2 = longs(&offsets);
        }
    }
    let mut out = Vec::with_capacity(extra_at);
    out.extend_from_slice(b"II");
    out.extend_from_slice(&42u16.to_le_bytes());
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&(fields.len() as u16).to_le_bytes());
    for (f, p) in fields.iter().zip(&placed) {
        out.extend_from_slice(&f.0.to_le_bytes());
        out.extend_from_slice(&f.1.to_le_bytes());
        out.extend_from_slice(&f.3.to_le_bytes());
        match p {
            Some(o) => out.extend_from_slice(&(*o as u32).to_le_bytes()),
            None => {
                let mut v = f.2.clone();
                v.resize(4, 0);
                out.extend_from_slice(&v);
            }
        }
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    for (f, p) in fields.iter().zip(&placed) {
        if p.is_some() {
            out.extend_from_slice(&f.2);
            if f.2.len() & 1 == 1 {
                out.push(0);
            }
        }
    }
    debug_assert_eq!(out.len() as u64, data_at);
    Ok(out)
}
