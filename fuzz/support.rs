/// Writes `data` to a file in RAM with extension `ext`, opens it with myriad-io and reads every
/// point (capped, so a header that claims billions of points in a tiny file stays cheap).
pub fn read_all(data: &[u8], ext: &str) {
    let dir = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm" } else { "/tmp" };
    let path = std::path::PathBuf::from(format!("{dir}/myriad-fuzz-{}.{ext}", std::process::id()));
    std::fs::write(&path, data).unwrap();
    if let Ok(mut src) = myriad_io::open(&path, &myriad_io::OpenOptions::default()) {
        let mut n = 0usize;
        while let Ok(Some(b)) = src.read_batch(1 << 14) {
            assert!(b.is_consistent());
            n += b.len();
            if n > 2_000_000 {
                break;
            }
        }
    }
}
