//! zstd, which every page is compressed with: the C library in native builds, and ruzstd (pure
//! Rust, decoding only) in WebAssembly, where the web viewer decodes pages and zstd's C sources
//! do not build.

/// Compresses `b` at `level`, with this thread's compression context for that level (made once
/// per thread and level, not per column: making one took 3 % of encoding KY's pages; node pages
/// and splat pages use different levels, so each keeps its own).
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn compress(b: &[u8], level: i32) -> Vec<u8> {
    use std::cell::RefCell;
    thread_local! {
        static CONTEXTS: RefCell<Vec<(i32, zstd::bulk::Compressor<'static>)>> =
            const { RefCell::new(Vec::new()) };
    }
    CONTEXTS.with(|c| {
        let mut c = c.borrow_mut();
        let at = match c.iter().position(|(l, _)| *l == level) {
            Some(at) => at,
            None => {
                c.push((
                    level,
                    zstd::bulk::Compressor::new(level).expect("zstd context"),
                ));
                c.len() - 1
            }
        };
        c[at].1.compress(b).expect("zstd compresses in memory")
    })
}

/// Decompresses `b`, which must hold at most `limit` bytes (more is an error, and no more than
/// `limit` bytes are ever allocated for it).
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn decompress(b: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    zstd::bulk::decompress(b, limit).map_err(|e| e.to_string())
}

/// Decompresses at most `limit + 1` bytes of `b`, streamed: memory follows what `b` really
/// holds, not `limit` (which may come from a damaged count).
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn decompress_streamed(b: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let mut out = Vec::new();
    zstd::stream::read::Decoder::new(b)
        .and_then(|d| d.take(limit as u64 + 1).read_to_end(&mut out))
        .map_err(|e| e.to_string())?;
    Ok(out)
}

#[cfg(target_arch = "wasm32")]
pub(crate) fn decompress_streamed(b: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let mut out = Vec::new();
    ruzstd::decoding::StreamingDecoder::new(b)
        .map_err(|e| e.to_string())?
        .take(limit as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

#[cfg(target_arch = "wasm32")]
pub(crate) fn decompress(b: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    let out = decompress_streamed(b, limit)?;
    if out.len() > limit {
        return Err(format!("more than {limit} bytes"));
    }
    Ok(out)
}
