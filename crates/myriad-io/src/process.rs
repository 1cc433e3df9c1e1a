//! What the process knows of itself.

/// Peak resident memory of this process so far, from /proc (Linux); None elsewhere.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// CPU seconds (user and system, all threads) this process has used so far (`getrusage`).
#[cfg(unix)]
pub fn cpu_seconds() -> Option<f64> {
    // SAFETY: getrusage only fills `u`, which is plain data.
    let u = unsafe {
        let mut u: libc::rusage = std::mem::zeroed();
        (libc::getrusage(libc::RUSAGE_SELF, &mut u) == 0).then_some(u)
    }?;
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    Some(t(u.ru_utime) + t(u.ru_stime))
}

/// Bytes that an unprivileged process may still write on the file system holding `dir`
/// (`statvfs`); None where it cannot be read.
#[cfg(unix)]
pub fn free_bytes(dir: &std::path::Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    // SAFETY: `c` is a NUL-terminated path; statvfs only fills `s`, which is plain data.
    let s = unsafe {
        let mut s: libc::statvfs = std::mem::zeroed();
        (libc::statvfs(c.as_ptr(), &mut s) == 0).then_some(s)
    }?;
    Some(s.f_bavail as u64 * s.f_frsize as u64)
}

/// Not known outside Unix (the web viewer's WebAssembly).
#[cfg(not(unix))]
pub fn cpu_seconds() -> Option<f64> {
    None
}

/// Not known outside Unix (the web viewer's WebAssembly).
#[cfg(not(unix))]
pub fn free_bytes(_: &std::path::Path) -> Option<u64> {
    None
}

#[cfg(test)]
mod tests {
    #[test]
    fn cpu_seconds_grow_with_work() {
        let before = super::cpu_seconds().unwrap();
        let mut x = 0u64;
        let start = std::time::Instant::now();
        while start.elapsed().as_millis() < 50 {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(std::hint::black_box(1));
        }
        std::hint::black_box(x);
        assert!(super::cpu_seconds().unwrap() > before);
    }

    #[test]
    fn free_bytes_of_a_folder_and_none_of_nothing() {
        let free = super::free_bytes(&std::env::temp_dir()).unwrap();
        assert!(free > 0);
        assert_eq!(
            super::free_bytes(std::path::Path::new("/no/such/folder")),
            None
        );
    }
}
