//! Small shared pieces for the hand-written readers: a buffered reader that knows its byte offset,
//! and fixed-size little/big-endian scalar decoding; small files a user names (a token file, a
//! certificate, an import) read whole with a bound.

use myriad_core::{Error, Result};
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// What a file that is not one is (a device, a socket), by its type.
#[cfg(unix)]
fn special(kind: &std::fs::FileType) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_char_device() || kind.is_block_device() {
        Some("a device")
    } else if kind.is_socket() {
        Some("a socket")
    } else {
        None
    }
}

#[cfg(not(unix))]
fn special(_: &std::fs::FileType) -> Option<&'static str> {
    None
}

/// The whole of a small file a user names (a token file, a certificate, an import), read with a
/// bound: a device (such as `/dev/zero` or `/dev/urandom`), a folder or a socket is refused by
/// what it is, and a file or pipe of more than `max` bytes by its size, after at most `max + 1`
/// bytes were read.
pub fn read_small(path: &Path, max: u64) -> Result<Vec<u8>> {
    let f = File::open(path).map_err(|e| Error::io(path, e))?;
    let kind = f.metadata().map_err(|e| Error::io(path, e))?.file_type();
    let what = if kind.is_dir() {
        Some("a folder")
    } else {
        special(&kind)
    };
    if let Some(what) = what {
        return Err(Error::Invalid(format!(
            "{}: {what}, not a file",
            path.display()
        )));
    }
    let mut out = Vec::new();
    (f.take(max + 1).read_to_end(&mut out)).map_err(|e| Error::io(path, e))?;
    if out.len() as u64 > max {
        return Err(Error::Invalid(format!(
            "{}: larger than {max} bytes",
            path.display()
        )));
    }
    Ok(out)
}

pub fn read_prefix(path: &Path, buf: &mut [u8]) -> Result<usize> {
    let mut f = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut n = 0;
    while n < buf.len() {
        match f.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) => return Err(Error::io(path, e)),
        }
    }
    Ok(n)
}

/// Most bytes of one line of a text format (PLY and PCD headers, text and ASCII records).
pub const MAX_LINE: usize = 64 << 10;

/// At most 80 bytes of `bytes` as text for an error message, with "..." where cut.
pub fn quote(bytes: &[u8]) -> String {
    const MOST: usize = 80;
    let cut = bytes.len() > MOST;
    let mut t = String::from_utf8_lossy(&bytes[..bytes.len().min(MOST)]).into_owned();
    t = t.escape_debug().to_string();
    if cut {
        t.push_str(&format!("... ({} bytes)", bytes.len()));
    }
    t
}

/// A buffered file reader that tracks the byte offset of the next byte it returns.
pub struct OffsetReader {
    pub path: PathBuf,
    inner: BufReader<File>,
    pub offset: u64,
}

impl OffsetReader {
    pub fn open(path: &Path) -> Result<OffsetReader> {
        let f = File::open(path).map_err(|e| Error::io(path, e))?;
        Ok(OffsetReader {
            path: path.to_path_buf(),
            inner: BufReader::with_capacity(1 << 20, f),
            offset: 0,
        })
    }

    /// Reads one line including its terminator into `line`; returns false at end of file. A
    /// line longer than [`MAX_LINE`] bytes is an error naming where it starts (a binary file
    /// named as text, or `/dev/zero`, would otherwise grow one line without end).
    pub fn read_line(&mut self, line: &mut Vec<u8>) -> Result<bool> {
        line.clear();
        let n = (&mut self.inner)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', line)
            .map_err(|e| Error::io(&self.path, e))?;
        if n > MAX_LINE && line.last() != Some(&b'\n') {
            return Err(Error::at_byte(
                &self.path,
                self.offset,
                format!(
                    "a line longer than {MAX_LINE} bytes, the most a line of text or a header \
                     may hold (is this a binary file?)"
                ),
            ));
        }
        self.offset += n as u64;
        Ok(n > 0)
    }

    /// Fills `buf` completely, or fails naming the offset where the file ended.
    pub fn read_exact(&mut self, buf: &mut [u8], what: &str) -> Result<()> {
        let mut got = 0;
        while got < buf.len() {
            match self.inner.read(&mut buf[got..]) {
                Ok(0) => {
                    return Err(Error::at_byte(
                        &self.path,
                        self.offset + got as u64,
                        format!("unexpected end of file in {what}"),
                    ));
                }
                Ok(k) => got += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::io(&self.path, e)),
            }
        }
        self.offset += buf.len() as u64;
        Ok(())
    }

    /// Skips `n` bytes, or fails naming the offset where the file ended.
    pub fn skip(&mut self, n: u64) -> Result<()> {
        let got = std::io::copy(&mut (&mut self.inner).take(n), &mut std::io::sink())
            .map_err(|e| Error::io(&self.path, e))?;
        self.offset += got;
        if got < n {
            return Err(Error::at_byte(
                &self.path,
                self.offset,
                "unexpected end of file in a skipped element",
            ));
        }
        Ok(())
    }

    /// Reads up to `buf.len()` bytes, fewer only at end of file.
    pub fn read_up_to(&mut self, buf: &mut [u8]) -> Result<usize> {
        let mut got = 0;
        while got < buf.len() {
            match self.inner.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(k) => got += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::io(&self.path, e)),
            }
        }
        self.offset += got as u64;
        Ok(got)
    }
}

/// Scalar types that appear in PLY and PCD records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    /// Decodes one value from the start of `b` (which holds at least `size()` bytes).
    pub fn decode(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap();
                (if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2),
            Scalar::U16 => get!(u16, 2),
            Scalar::I32 => get!(i32, 4),
            Scalar::U32 => get!(u32, 4),
            Scalar::I64 => get!(i64, 8),
            Scalar::U64 => get!(u64, 8),
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8),
        }
    }
}

/// Scales a colour or intensity channel to 16 bits: 8-bit integers are widened (v * 257), 16-bit
/// integers kept, floats in 0..1 stretched, anything else clamped.
pub fn to_u16_channel(v: f64, ty: Scalar) -> u16 {
    let x = match ty {
        Scalar::U8 => v * 257.0,
        Scalar::F32 | Scalar::F64 if v <= 1.0 => v * 65535.0,
        _ => v,
    };
    x.round().clamp(0.0, 65535.0) as u16
}

pub fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A token file, a certificate or an import given as /dev/zero grew to gigabytes: devices
    /// and folders are refused by what they are, files past the bound by their size.
    #[test]
    fn small_files_are_read_with_a_bound() {
        let dir = std::env::temp_dir().join(format!("myriad-read-small-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("token");
        std::fs::write(&f, b"0123456789abcdef\n").unwrap();
        assert_eq!(read_small(&f, 17).unwrap(), b"0123456789abcdef\n");
        let e = read_small(&f, 16).unwrap_err().to_string();
        assert!(e.contains("larger than 16 bytes"), "{e}");
        let e = read_small(&dir, 1 << 20).unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
        for dev in ["/dev/zero", "/dev/urandom"] {
            if Path::new(dev).exists() {
                let e = read_small(Path::new(dev), 1 << 20).unwrap_err().to_string();
                assert!(e.contains("a device, not a file"), "{e}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
