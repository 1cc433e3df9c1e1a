//! Images out: a frame as a PNG file, written atomically (`atomic`).

use crate::atomic::AtomicFile;
use myriad_core::{Error, Result};
use std::path::Path;

/// Writes `rgba` (8-bit RGBA, `w` x `h`, rows top to bottom) to `path` as a PNG, replacing it.
pub fn write_png(path: &Path, w: u32, h: u32, rgba: &[u8]) -> Result<()> {
    let file = AtomicFile::create(path, true)?;
    {
        let f = file.open_write()?;
        let failed = |what: &str, e: png::EncodingError| {
            Error::io(
                file.temp_path(),
                std::io::Error::other(format!("{what}: {e}")),
            )
        };
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), w, h);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(|e| failed("PNG header", e))?;
        writer
            .write_image_data(rgba)
            .map_err(|e| failed("PNG data", e))?;
        writer.finish().map_err(|e| failed("PNG end", e))?;
    }
    file.commit()
}
