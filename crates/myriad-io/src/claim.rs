//! Scratch names and folders that belong to one process, so that builds running at once in one
//! folder (parts of a plan on other nodes of a cluster, or in containers where every process is
//! PID 1) never take or remove each other's work.
//!
//! A name carries [`tag`]: the host, the process id and a random number, unique across machines
//! and PID namespaces. A folder or temporary file is held by an exclusive lock (`flock`, which
//! Linux's NFS client maps onto server-side locks) on a file of its own for as long as its
//! process runs; the kernel drops the lock when the process ends, however it ends. Something
//! left behind is stale, and may be removed, only when its lock can be taken *and* it was made
//! before this process started (the second condition closes the moment between a file's creation
//! and its locking). A folder of the old naming (no lock file) is stale only when older than
//! [`OLD_UNLOCKED`].

use myriad_core::{Error, Result};
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, SystemTime};

/// The lock file inside a claimed folder.
pub const LOCK_FILE: &str = ".lock";
/// A folder without a lock file (made by an older version, or killed between making the folder
/// and its lock) is removed only when older than this.
pub const OLD_UNLOCKED: Duration = Duration::from_secs(24 * 3600);

fn started() -> SystemTime {
    static START: OnceLock<SystemTime> = OnceLock::new();
    *START.get_or_init(SystemTime::now)
}

/// `HOST-PID-RANDOM` for this process (letters, digits, `.` and `-` only).
pub fn tag() -> &'static str {
    static TAG: OnceLock<String> = OnceLock::new();
    TAG.get_or_init(|| {
        started();
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .or_else(|_| std::fs::read_to_string("/etc/hostname"))
            .unwrap_or_default();
        let mut host: String = host
            .trim()
            .chars()
            .filter(|c| c.is_ascii_alphanumeric() || *c == '.' || *c == '-')
            .take(40)
            .collect();
        if host.is_empty() {
            host.push_str("host");
        }
        // The standard library's hasher keys come from the operating system's random source.
        use std::hash::{BuildHasher, Hasher};
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u128(
            SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        format!("{host}-{}-{:016x}", std::process::id(), h.finish())
    })
}

/// Opens `path` and takes its lock without waiting: true when no running process holds it.
fn lock_is_free(path: &Path) -> bool {
    match OpenOptions::new().read(true).write(true).open(path) {
        Ok(f) => f.try_lock().is_ok(),
        Err(_) => false,
    }
}

fn made_before_start(path: &Path) -> bool {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .is_ok_and(|t| t < started())
}

fn older_than(path: &Path, age: Duration) -> bool {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .is_ok_and(|t| t.elapsed().is_ok_and(|e| e > age))
}

/// Creates `path` (truncating it) and holds an exclusive lock on it until the handle is dropped.
pub fn create_locked(path: &Path) -> Result<File> {
    started();
    let f = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    f.try_lock().map_err(|e| {
        Error::io(
            path,
            std::io::Error::other(format!(
                "cannot lock it ({e}): is another process using it?"
            )),
        )
    })?;
    Ok(f)
}

/// Whether a temporary file left by [`create_locked`] is stale: its lock is free and it is
/// older than this process.
pub fn is_stale_file(path: &Path) -> bool {
    made_before_start(path) && lock_is_free(path)
}

/// Whether a folder made by [`Folder::create`] is stale (see the module's text).
pub fn is_stale_folder(dir: &Path) -> bool {
    let lock = dir.join(LOCK_FILE);
    if lock.exists() {
        made_before_start(&lock) && lock_is_free(&lock)
    } else {
        older_than(dir, OLD_UNLOCKED)
    }
}

/// A folder of this process's own, `PARENT/PREFIX` + [`tag`], locked while it lives and removed
/// with everything in it when dropped.
#[derive(Debug)]
pub struct Folder {
    path: PathBuf,
    _lock: File,
}

impl Folder {
    pub fn create(parent: &Path, prefix: &str) -> Result<Folder> {
        let path = parent.join(format!("{prefix}{}", tag()));
        // Not `create_dir_all`: a parent that does not exist is the caller's error to report.
        match std::fs::create_dir(&path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && path.is_dir() => {}
            Err(e) => return Err(Error::io(&path, e)),
        }
        let lock = create_locked(&path.join(LOCK_FILE))?;
        Ok(Folder { path, _lock: lock })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for Folder {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// Removes the stale folders `PARENT/PREFIX*` that other processes left (never this one's).
pub fn remove_stale_folders(parent: &Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    let ours = format!("{prefix}{}", tag());
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(n) = name.to_str() else { continue };
        if n.starts_with(prefix) && n != ours && e.path().is_dir() && is_stale_folder(&e.path()) {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_held_by_a_lock_are_not_stale() {
        let dir = std::env::temp_dir().join(format!("myriad-claim-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let t = tag();
        assert!(t.contains(&format!("-{}-", std::process::id())), "{t}");
        assert!(
            t.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '.' || c == '-')
        );
        // Our own folder, held: not removed.
        let ours = Folder::create(&dir, ".scratch-").unwrap();
        remove_stale_folders(&dir, ".scratch-");
        assert!(ours.path().join(LOCK_FILE).exists());
        // Another process's folder, held by its lock (a second open file description stands
        // for the other process: flock locks conflict between descriptions).
        let other = dir.join(".scratch-otherhost-1-0");
        std::fs::create_dir_all(&other).unwrap();
        let held = create_locked(&other.join(LOCK_FILE)).unwrap();
        let old = SystemTime::now() - Duration::from_secs(3600);
        File::open(other.join(LOCK_FILE))
            .unwrap()
            .set_modified(old)
            .unwrap();
        remove_stale_folders(&dir, ".scratch-");
        assert!(other.exists(), "a held folder was removed");
        // Its process gone (the lock dropped): removed.
        drop(held);
        remove_stale_folders(&dir, ".scratch-");
        assert!(!other.exists(), "a stale folder was kept");
        // A folder of the old naming: kept while young.
        let unlocked = dir.join(".scratch-1234");
        std::fs::create_dir_all(&unlocked).unwrap();
        remove_stale_folders(&dir, ".scratch-");
        assert!(unlocked.exists());
        drop(ours);
        assert!(!dir.join(format!(".scratch-{t}")).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
