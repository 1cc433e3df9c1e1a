//! A terrain surface on disk (`city.ground-1.surface`): a grid of cells cut into square tiles,
//! each stored with a one-cell apron of its neighbours' cells (so that a point's bilinear height
//! and slope read one tile), zstd-compressed with a CRC-32, an index and the grid's placement in
//! JSON at the end. Readers decompress the tiles the points they are given fall in, a few kept.
//!
//! Bytes: `MYRSURF1`, the tiles, the isolated voxels (where the terrain was made with them: the
//! sorted keys of the cubes, a cell a side, whose points have too few neighbours, zstd-compressed,
//! u64 LE each), the JSON, then its offset (u64 LE), its length (u32 LE) and `MYRSURF1` again.

use myriad_core::{Error, Result};
use myriad_format::ByteSource;
use serde_json::Value;
#[cfg(not(target_arch = "wasm32"))]
use serde_json::json;
#[cfg(not(target_arch = "wasm32"))]
use std::fs::File;
#[cfg(not(target_arch = "wasm32"))]
use std::io::{BufWriter, Write};
use std::path::Path;
#[cfg(not(target_arch = "wasm32"))]
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

const MAGIC: &[u8; 8] = b"MYRSURF1";
/// Tiles kept decompressed by a reader.
const CACHED: usize = 16;
/// The largest grid side (in cells) and tile side a file may claim.
const MAX_CELLS: u64 = 1 << 24;
pub const MAX_TILE: usize = 4096;
/// Surfaces up to this size have every tile's checksum checked when they are opened.
const CHECK_WHOLE: u64 = 256 << 20;
/// Most isolated voxels a surface keeps (64 MB of keys).
pub const MAX_ISOLATED: usize = 8 << 20;

/// The key of voxel (i, j, k): 24, 24 and 16 bits.
pub fn voxel_key(i: u64, j: u64, k: u64) -> u64 {
    (i & 0xff_ffff) << 40 | (j & 0xff_ffff) << 16 | (k & 0xffff)
}

/// The voxels (cubes of the grid's cell from its corner and `z0`) whose points are isolated
/// noise, their keys sorted.
#[derive(Debug, Clone, PartialEq)]
pub struct Isolated {
    pub z0: f64,
    pub keys: Vec<u64>,
}

/// Where a grid lies: its lower-left corner, its cell, its size in cells, its tiles' side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub x0: f64,
    pub y0: f64,
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    pub tile: usize,
}

impl Placement {
    pub fn tiles(&self) -> (usize, usize) {
        (self.nx.div_ceil(self.tile), self.ny.div_ceil(self.tile))
    }

    /// The cells of tile `(tx, ty)`'s core: first column, first row, width, height.
    pub fn core(&self, tx: usize, ty: usize) -> (usize, usize, usize, usize) {
        let (x, y) = (tx * self.tile, ty * self.tile);
        (x, y, self.tile.min(self.nx - x), self.tile.min(self.ny - y))
    }
}

/// Writes a surface tile by tile (any order, from any thread), then its index.
#[cfg(not(target_arch = "wasm32"))]
pub struct SurfaceWriter {
    file: myriad_io::atomic::AtomicFile,
    path: PathBuf,
    out: Mutex<(BufWriter<File>, u64)>,
    index: Mutex<Vec<Option<(u64, u32, u32)>>>,
    isolated: Mutex<Option<Isolated>>,
    pub placement: Placement,
}

#[cfg(not(target_arch = "wasm32"))]
impl SurfaceWriter {
    pub fn create(path: &Path, placement: Placement) -> Result<SurfaceWriter> {
        let file = myriad_io::atomic::AtomicFile::create(path, false)?;
        let mut w = BufWriter::new(file.open_write()?);
        w.write_all(MAGIC).map_err(|e| Error::io(path, e))?;
        let (tx, ty) = placement.tiles();
        Ok(SurfaceWriter {
            file,
            path: path.to_path_buf(),
            out: Mutex::new((w, MAGIC.len() as u64)),
            index: Mutex::new(vec![None; tx * ty]),
            isolated: Mutex::new(None),
            placement,
        })
    }

    /// Tile `(tx, ty)`: `cells(x, y)` gives the value of grid cell (x, y), for the core and its
    /// apron (cells outside the grid are NaN whatever it says).
    pub fn write_tile(
        &self,
        tx: usize,
        ty: usize,
        cells: impl Fn(isize, isize) -> f32,
    ) -> Result<()> {
        let p = &self.placement;
        let (x, y, w, h) = p.core(tx, ty);
        let mut raw = Vec::with_capacity((w + 2) * (h + 2) * 4);
        for yy in y as isize - 1..=(y + h) as isize {
            for xx in x as isize - 1..=(x + w) as isize {
                let inside = xx >= 0 && yy >= 0 && (xx as usize) < p.nx && (yy as usize) < p.ny;
                let v = if inside { cells(xx, yy) } else { f32::NAN };
                raw.extend_from_slice(&v.to_le_bytes());
            }
        }
        let packed = zstd::bulk::compress(&raw, 3).map_err(|e| Error::io(&self.path, e))?;
        let crc = crc32fast::hash(&packed);
        let mut out = self.out.lock().expect("surface writer");
        let at = out.1;
        out.0
            .write_all(&packed)
            .map_err(|e| Error::io(&self.path, e))?;
        out.1 += packed.len() as u64;
        self.index.lock().expect("surface index")[ty * p.tiles().0 + tx] =
            Some((at, packed.len() as u32, crc));
        Ok(())
    }

    /// The isolated voxels, written with the index.
    pub fn set_isolated(&self, i: Isolated) {
        *self.isolated.lock().expect("surface writer") = Some(i);
    }

    /// Writes the isolated voxels and the index, and gives the file its name.
    pub fn finish(self) -> Result<u64> {
        let p = self.placement;
        let index = self.index.into_inner().expect("surface index");
        let (mut w, mut at) = self.out.into_inner().expect("surface writer");
        let io = |e| Error::io(&self.path, e);
        let isolated = match self.isolated.into_inner().expect("surface writer") {
            None => Value::Null,
            Some(iso) => {
                let raw: Vec<u8> = iso.keys.iter().flat_map(|k| k.to_le_bytes()).collect();
                let packed = zstd::bulk::compress(&raw, 3).map_err(io)?;
                w.write_all(&packed).map_err(io)?;
                let block = json!({ "z0": iso.z0, "count": iso.keys.len(),
                    "at": [at, packed.len(), crc32fast::hash(&packed)] });
                at += packed.len() as u64;
                block
            }
        };
        let meta = json!({
            "x0": p.x0, "y0": p.y0, "cell": p.cell, "nx": p.nx, "ny": p.ny, "tile": p.tile,
            "tiles": index.iter().map(|t| match t {
                Some((o, l, c)) => json!([o, l, c]),
                None => Value::Null,
            }).collect::<Vec<_>>(),
            "isolated": isolated,
        })
        .to_string();
        w.write_all(meta.as_bytes()).map_err(io)?;
        w.write_all(&at.to_le_bytes()).map_err(io)?;
        w.write_all(&(meta.len() as u32).to_le_bytes())
            .map_err(io)?;
        w.write_all(MAGIC).map_err(io)?;
        w.flush().map_err(io)?;
        let f = w.into_inner().map_err(|e| io(e.into_error()))?;
        f.sync_all().map_err(io)?;
        drop(f);
        self.file.commit()?;
        Ok(at + meta.len() as u64 + 20)
    }
}

/// A surface opened for reading: a file, or (in the web viewer) a URL read by ranges.
pub struct Surface {
    name: String,
    source: Arc<dyn ByteSource>,
    pub placement: Placement,
    tiles: Vec<Option<(u64, u32, u32)>>,
    cache: Mutex<Vec<(usize, Arc<Vec<f32>>)>>,
    /// The isolated voxels, where the terrain was made with them.
    pub isolated: Option<Isolated>,
}

impl std::fmt::Debug for Surface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Surface({})", self.name)
    }
}

/// A point's height on a surface and the surface's slope there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Height {
    pub z: f64,
    pub slope: f64,
}

impl Surface {
    /// Opens a surface; an error names the file and the byte at fault.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn open(path: &Path) -> Result<Surface> {
        let source = Arc::new(myriad_format::FileBytes::open(path)?);
        Surface::from_source(source, &path.display().to_string(), true)
    }

    /// A surface read from `source` (called `name` in errors); `check_whole`: every tile's
    /// checksum checked now where the surface is of ordinary size (a file on disk), else each
    /// tile's as it is read (a URL).
    pub fn from_source(
        source: Arc<dyn ByteSource>,
        name: &str,
        check_whole: bool,
    ) -> Result<Surface> {
        let path = Path::new(name);
        let len = source.len();
        let read = |at: u64, n: usize| source.read_at(at, n).map_err(|e| Error::io(path, e));
        let bad = |at: u64, m: &str| Error::at_byte(path, at, m);
        if len < 28 {
            return Err(bad(0, "not a Myriad surface (too short)"));
        }
        let tail = read(len - 20, 20)?;
        if &tail[12..] != MAGIC {
            return Err(bad(
                len - 8,
                "not a Myriad surface (no MYRSURF1 at its end)",
            ));
        }
        let at = u64::from_le_bytes(tail[..8].try_into().expect("8 bytes"));
        let n = u32::from_le_bytes(tail[8..12].try_into().expect("4 bytes")) as u64;
        if at < 8 || at.checked_add(n) != Some(len - 20) || n > 64 << 20 {
            return Err(bad(len - 20, "its index does not lie before its end"));
        }
        let text = read(at, n as usize)?;
        let v: Value =
            serde_json::from_slice(&text).map_err(|e| bad(at, &format!("its index: {e}")))?;
        let num = |k: &str| v[k].as_f64().filter(|x| x.is_finite());
        let count = |k: &str| v[k].as_u64().filter(|&c| c > 0 && c <= MAX_CELLS);
        let (Some(x0), Some(y0), Some(cell), Some(nx), Some(ny), Some(tile)) = (
            num("x0"),
            num("y0"),
            num("cell").filter(|c| *c > 0.0),
            count("nx"),
            count("ny"),
            count("tile").filter(|&t| t as usize <= MAX_TILE),
        ) else {
            return Err(bad(at, "its index lacks the grid's placement"));
        };
        let placement = Placement {
            x0,
            y0,
            cell,
            nx: nx as usize,
            ny: ny as usize,
            tile: tile as usize,
        };
        let (tx, ty) = placement.tiles();
        let list = v["tiles"].as_array().filter(|l| l.len() == tx * ty);
        let Some(list) = list else {
            return Err(bad(at, "its index lists another number of tiles"));
        };
        let tiles = list
            .iter()
            .map(|t| match t {
                Value::Null => Ok(None),
                _ => match (t[0].as_u64(), t[1].as_u64(), t[2].as_u64()) {
                    (Some(o), Some(l), Some(c))
                        if o >= 8 && o.checked_add(l).is_some_and(|e| e <= at) && l < 1 << 31 =>
                    {
                        Ok(Some((o, l as u32, c as u32)))
                    }
                    _ => Err(bad(at, "its index places a tile outside the file")),
                },
            })
            .collect::<Result<Vec<_>>>()?;
        // A surface of ordinary size is checked whole now (one line at opening, rather than
        // one damaged node after another later); a larger one tile by tile as it is read.
        if check_whole && len <= CHECK_WHOLE {
            let all = read(0, at as usize)?;
            for (t, &(o, l, c)) in tiles
                .iter()
                .enumerate()
                .filter_map(|(t, x)| Some((t, x.as_ref()?)))
            {
                if crc32fast::hash(&all[o as usize..(o + l as u64) as usize]) != c {
                    return Err(bad(o, &format!("tile {t}: checksum mismatch")));
                }
            }
        }
        let isolated = match &v["isolated"] {
            Value::Null => None,
            iso => {
                let (z0, count) = (iso["z0"].as_f64(), iso["count"].as_u64());
                let block = (
                    iso["at"][0].as_u64(),
                    iso["at"][1].as_u64(),
                    iso["at"][2].as_u64(),
                );
                let (Some(z0), Some(count), (Some(o), Some(l), Some(c))) = (z0, count, block)
                else {
                    return Err(bad(at, "its index's isolated voxels lack their place"));
                };
                if count as usize > MAX_ISOLATED || o.checked_add(l).is_none_or(|e| e > at) {
                    return Err(bad(
                        at,
                        "its index places the isolated voxels outside the file",
                    ));
                }
                let packed = read(o, l as usize)?;
                if crc32fast::hash(&packed) != c as u32 {
                    return Err(bad(o, "isolated voxels: checksum mismatch"));
                }
                let raw = myriad_format::decompress_zstd(&packed, count as usize * 8)
                    .map_err(|m| bad(o, &format!("isolated voxels: {m}")))?;
                if raw.len() != count as usize * 8 {
                    return Err(bad(o, "isolated voxels: another number of them"));
                }
                let keys: Vec<u64> = (raw.chunks_exact(8))
                    .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
                    .collect();
                if keys.windows(2).any(|w| w[0] >= w[1]) {
                    return Err(bad(o, "isolated voxels: not in order"));
                }
                Some(Isolated { z0, keys })
            }
        };
        Ok(Surface {
            isolated,
            name: name.to_string(),
            source,
            placement,
            tiles,
            cache: Mutex::new(Vec::new()),
        })
    }

    /// Whether a point lies in an isolated voxel.
    pub fn is_isolated(&self, x: f64, y: f64, z: f64) -> bool {
        let Some(iso) = &self.isolated else {
            return false;
        };
        let p = &self.placement;
        let (i, j, k) = (
            (x - p.x0) / p.cell,
            (y - p.y0) / p.cell,
            (z - iso.z0) / p.cell,
        );
        if !(i >= 0.0 && j >= 0.0 && k >= 0.0) {
            return false;
        }
        let key = voxel_key(i as u64, j as u64, (k as u64).min(0xffff));
        iso.keys.binary_search(&key).is_ok()
    }

    /// The tile a point lies in (`None`: outside the grid).
    pub fn tile_of(&self, x: f64, y: f64) -> Option<usize> {
        let p = &self.placement;
        let (cx, cy) = ((x - p.x0) / p.cell, (y - p.y0) / p.cell);
        if !(cx >= 0.0 && cy >= 0.0 && cx < p.nx as f64 && cy < p.ny as f64) {
            return None;
        }
        let (tx, _) = p.tiles();
        Some((cy as usize / p.tile) * tx + cx as usize / p.tile)
    }

    /// Tile `t`'s cells with their apron (`None`: a tile without a surface).
    pub fn tile(&self, t: usize) -> std::result::Result<Option<Arc<Vec<f32>>>, String> {
        let Some((at, len, crc)) = self.tiles[t] else {
            return Ok(None);
        };
        if let Some((_, c)) = (self.cache.lock().expect("cache").iter()).find(|(i, _)| *i == t) {
            return Ok(Some(c.clone()));
        }
        let name = &self.name;
        let packed = (self.source.read_at(at, len as usize)).map_err(|e| format!("{name}: {e}"))?;
        if crc32fast::hash(&packed) != crc {
            return Err(format!("{name}: byte {at}: tile {t}: checksum mismatch"));
        }
        let p = &self.placement;
        let (tx, _) = p.tiles();
        let (_, _, w, h) = p.core(t % tx, t / tx);
        let n = (w + 2) * (h + 2);
        let raw = myriad_format::decompress_zstd(&packed, n * 4)
            .map_err(|e| format!("{name}: byte {at}: tile {t}: {e}"))?;
        if raw.len() != n * 4 {
            return Err(format!(
                "{name}: byte {at}: tile {t}: {} bytes, not {}",
                raw.len(),
                n * 4
            ));
        }
        let cells: Arc<Vec<f32>> = Arc::new(
            raw.chunks_exact(4)
                .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
                .collect(),
        );
        let mut cache = self.cache.lock().expect("cache");
        if cache.len() >= CACHED {
            cache.remove(0);
        }
        cache.push((t, cells.clone()));
        Ok(Some(cells))
    }

    /// The surface's height and slope under `(x, y)`, in tile `t` (whose cells are `cells`):
    /// bilinear between the four nearest cells' centres; `None` where none of them has a value.
    pub fn height(&self, t: usize, cells: &[f32], x: f64, y: f64) -> Option<Height> {
        let p = &self.placement;
        let (tx, _) = p.tiles();
        let (cx, cy, w, _) = p.core(t % tx, t / tx);
        let stride = w + 2;
        let (u, v) = ((x - p.x0) / p.cell - 0.5, (y - p.y0) / p.cell - 0.5);
        let (i0, j0) = (u.floor(), v.floor());
        let (fu, fv) = (u - i0, v - j0);
        // Into the tile's array, whose first cell is (cx - 1, cy - 1).
        let (a, b) = (i0 as isize - cx as isize + 1, j0 as isize - cy as isize + 1);
        if a < 0 || b < 0 {
            return None;
        }
        let at = |da: usize, db: usize| cells.get((b as usize + db) * stride + a as usize + da);
        let z = [at(0, 0)?, at(1, 0)?, at(0, 1)?, at(1, 1)?].map(|&c| c as f64);
        if z.iter().any(|c| c.is_nan()) {
            let (s, n) = z
                .iter()
                .filter(|c| !c.is_nan())
                .fold((0.0, 0), |(s, n), c| (s + c, n + 1));
            return (n > 0).then(|| Height {
                z: s / n as f64,
                slope: 0.0,
            });
        }
        let zx0 = z[0] + (z[1] - z[0]) * fu;
        let zx1 = z[2] + (z[3] - z[2]) * fu;
        let dx = ((z[1] - z[0]) * (1.0 - fv) + (z[3] - z[2]) * fv) / p.cell;
        let dy = ((z[2] - z[0]) * (1.0 - fu) + (z[3] - z[1]) * fu) / p.cell;
        Some(Height {
            z: zx0 + (zx1 - zx0) * fv,
            slope: (dx * dx + dy * dy).sqrt(),
        })
    }
}

impl myriad_core::ground::GroundHeight for Surface {
    fn height(&self, x: f64, y: f64) -> Option<f64> {
        let t = self.tile_of(x, y)?;
        let cells = self.tile(t).ok()??;
        Surface::height(self, t, &cells, x, y).map(|h| h.z)
    }
}
