//! Outputs that appear atomically: written under a hidden temporary name in the destination's
//! folder, renamed over the final name only when complete, removed if dropped before that. The
//! temporary name carries the process's [`crate::claim::tag`] and the file is locked while it is
//! written, so that a later run removes it only once its writer is gone.

use myriad_core::{Error, Result};
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};

pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    committed: bool,
    /// Holds the temporary file's lock until it is renamed or removed.
    _lock: File,
}

impl AtomicFile {
    /// Reserves `target`; fails if it exists and `force` is false.
    pub fn create(target: &Path, force: bool) -> Result<AtomicFile> {
        if !force && target.exists() {
            return Err(Error::Invalid(format!(
                "{}: output exists (use --force to replace it)",
                target.display()
            )));
        }
        if target.is_dir() {
            return Err(Error::unsupported(target, "output is a directory"));
        }
        let name = target
            .file_name()
            .ok_or_else(|| Error::unsupported(target, "output has no file name"))?;
        let mut temp_name = std::ffi::OsString::from(".");
        temp_name.push(name);
        temp_name.push(format!(".{}.partial", crate::claim::tag()));
        let temp = target.with_file_name(temp_name);
        let lock = crate::claim::create_locked(&temp)?;
        Ok(AtomicFile {
            target: target.to_path_buf(),
            temp,
            committed: false,
            _lock: lock,
        })
    }

    /// Opens the temporary file for writing (created or truncated).
    pub fn open_write(&self) -> Result<File> {
        OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&self.temp)
            .map_err(|e| Error::io(&self.temp, e))
    }

    pub fn temp_path(&self) -> &Path {
        &self.temp
    }

    /// Renames the temporary file to the target.
    pub fn commit(mut self) -> Result<()> {
        std::fs::rename(&self.temp, &self.target).map_err(|e| Error::io(&self.target, e))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// A folder that appears under its name only when complete: written as a hidden folder beside
/// it (`.NAME.partial-` and the process's [`crate::claim::tag`], held by a lock while its
/// process runs), renamed at the end; the one it replaces is removed only then. Such folders
/// that killed processes left are removed when the next one for the same name starts.
pub struct AtomicDir {
    target: PathBuf,
    temp: crate::claim::Folder,
}

impl AtomicDir {
    /// Reserves `target`; fails if it exists and `force` is false, or if it exists and is not
    /// `what` (`ours` says which folders are: anything else is never replaced, `force` or not).
    pub fn create(
        target: &Path,
        force: bool,
        ours: fn(&Path) -> bool,
        what: &str,
    ) -> Result<AtomicDir> {
        if target.exists() {
            if !force {
                return Err(Error::Invalid(format!(
                    "{}: output exists (use --force to replace it)",
                    target.display()
                )));
            }
            if !target.is_dir() || !ours(target) {
                return Err(Error::unsupported(
                    target,
                    format!("exists and is not {what}: not replaced"),
                ));
            }
        }
        let name = target
            .file_name()
            .ok_or_else(|| Error::unsupported(target, "output has no folder name"))?;
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let prefix = format!(".{}.partial-", name.to_string_lossy());
        crate::claim::remove_stale_folders(parent, &prefix);
        let temp = crate::claim::Folder::create(parent, &prefix)?;
        Ok(AtomicDir {
            target: target.to_path_buf(),
            temp,
        })
    }

    /// The folder being written.
    pub fn temp(&self) -> &Path {
        self.temp.path()
    }

    /// Moves the folder to its name (the one it replaces removed only then).
    pub fn commit(self) -> Result<()> {
        let temp = self.temp.path();
        // The lock file stays out of the output (the lock itself is held until `self` goes).
        let _ = std::fs::remove_file(temp.join(crate::claim::LOCK_FILE));
        let old = temp.with_file_name(format!(
            ".{}.old-{}",
            self.target
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            crate::claim::tag()
        ));
        let replaced = self.target.exists();
        if replaced {
            std::fs::rename(&self.target, &old).map_err(|e| Error::io(&self.target, e))?;
        }
        std::fs::rename(temp, &self.target).map_err(|e| Error::io(&self.target, e))?;
        if replaced {
            let _ = std::fs::remove_dir_all(&old);
        }
        // Dropping the claim now removes nothing: its folder has its final name.
        Ok(())
    }
}

/// The same file by device and inode (however it is spelled: `a.las`, `dir/../a.las`, a link).
#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

/// No files to compare where there are no inodes (the web viewer's WebAssembly writes none).
#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    false
}

/// Refuses an output that is one of the inputs, or a folder holding one (`--force` included):
/// nothing the user gave is replaced.
pub fn refuse_input_as_output<P: AsRef<Path>>(output: &Path, inputs: &[P]) -> Result<()> {
    let Ok(out) = std::fs::metadata(output) else {
        return Ok(());
    };
    for input in inputs {
        let input = input.as_ref();
        let Ok(m) = std::fs::metadata(input) else {
            continue;
        };
        let inside = out.is_dir()
            && input
                .canonicalize()
                .ok()
                .zip(output.canonicalize().ok())
                .is_some_and(|(i, o)| i.starts_with(o));
        if same_file(&out, &m) || inside {
            return Err(Error::Invalid(format!(
                "{}: the output is the input {} (it would be replaced): choose another output",
                output.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// Refuses an input given twice (the same file by device and inode): its points would count
/// twice.
pub fn refuse_repeated_inputs<P: AsRef<Path>>(inputs: &[P]) -> Result<()> {
    let mut seen: Vec<(&Path, std::fs::Metadata)> = Vec::new();
    for input in inputs {
        let input = input.as_ref();
        let Ok(m) = std::fs::metadata(input) else {
            continue;
        };
        if m.is_file()
            && let Some((first, _)) = seen.iter().find(|(_, s)| same_file(s, &m))
        {
            return Err(Error::Invalid(format!(
                "{}: given twice (also as {}); each input is read once, give it once",
                input.display(),
                first.display()
            )));
        }
        seen.push((input, m));
    }
    Ok(())
}

/// Refuses an output whose folder does not exist (rather than making folders up to the root
/// from a mistyped path).
pub fn require_folder(output: &Path) -> Result<()> {
    match output.parent() {
        Some(d) if !d.as_os_str().is_empty() && !d.is_dir() => Err(Error::Invalid(format!(
            "{}: the folder {} does not exist (make it first)",
            output.display(),
            d.display()
        ))),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn appears_only_on_commit_and_refuses_overwrite() {
        let dir = std::env::temp_dir().join(format!("myriad-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("out.bin");
        let _ = std::fs::remove_file(&target);
        {
            let a = AtomicFile::create(&target, false).unwrap();
            a.open_write().unwrap().write_all(b"half").unwrap();
            assert!(!target.exists());
            // dropped without commit
        }
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            0,
            "temp file left behind"
        );
        let a = AtomicFile::create(&target, false).unwrap();
        a.open_write().unwrap().write_all(b"done").unwrap();
        a.commit().unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"done");
        assert!(AtomicFile::create(&target, false).is_err());
        assert!(AtomicFile::create(&target, true).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_input_is_never_the_output_nor_given_twice() {
        let dir = std::env::temp_dir().join(format!("myriad-inout-{}", std::process::id()));
        let sub = dir.join("sub");
        std::fs::create_dir_all(&sub).unwrap();
        let a = dir.join("a.las");
        std::fs::write(&a, b"scan").unwrap();
        let b = dir.join("b.las");
        std::fs::write(&b, b"scan").unwrap();
        let spelled = sub.join("..").join("a.las");
        let e = refuse_input_as_output(&spelled, &[&b, &a])
            .unwrap_err()
            .to_string();
        assert!(e.contains("is the input") && e.contains("a.las"), "{e}");
        assert!(
            refuse_input_as_output(&dir, &[&a]).is_err(),
            "a folder holding the input"
        );
        assert!(refuse_input_as_output(&dir.join("c.myr"), &[&a, &b]).is_ok());
        assert!(refuse_input_as_output(&b, &[&a]).is_ok());
        let e = refuse_repeated_inputs(&[&a, &b, &spelled])
            .unwrap_err()
            .to_string();
        assert!(e.contains("given twice"), "{e}");
        assert!(refuse_repeated_inputs(&[&a, &b]).is_ok());
        let e = require_folder(&dir.join("no/such/x.myr"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not exist"), "{e}");
        assert!(require_folder(&sub.join("x.myr")).is_ok());
        assert!(require_folder(Path::new("x.myr")).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_killed_writers_folder_goes_when_the_next_starts_and_a_live_ones_stays() {
        use std::time::{Duration, SystemTime};
        let dir = std::env::temp_dir().join(format!("myriad-atomicdir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("cloud");
        let any = |_: &Path| true;
        // Left by a process that is gone (its lock free, made before this one started) and by
        // one still running (its lock held: another open description stands for it).
        let gone = dir.join(".cloud.partial-otherhost-1-0");
        let live = dir.join(".cloud.partial-otherhost-2-0");
        for f in [&gone, &live] {
            std::fs::create_dir_all(f).unwrap();
            std::fs::write(f.join("octree.bin"), b"half").unwrap();
        }
        let held = crate::claim::create_locked(&live.join(crate::claim::LOCK_FILE)).unwrap();
        let old = SystemTime::now() - Duration::from_secs(3600);
        for f in [&gone, &live] {
            let lock = f.join(crate::claim::LOCK_FILE);
            if !lock.exists() {
                std::fs::write(&lock, b"").unwrap();
            }
            std::fs::File::open(&lock)
                .unwrap()
                .set_modified(old)
                .unwrap();
        }
        let a = AtomicDir::create(&target, false, any, "a folder").unwrap();
        assert!(!gone.exists(), "a dead writer's folder stayed");
        assert!(live.exists(), "a live writer's folder was removed");
        std::fs::write(a.temp().join("metadata.json"), b"{}").unwrap();
        a.commit().unwrap();
        let names: Vec<String> = std::fs::read_dir(&target)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            vec!["metadata.json".to_string()],
            "no lock file in the output"
        );
        // Replaced with --force; nothing of ours left beside it.
        let b = AtomicDir::create(&target, true, any, "a folder").unwrap();
        b.commit().unwrap();
        assert!(std::fs::read_dir(&target).unwrap().next().is_none());
        drop(held);
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".cloud") && !n.ends_with("otherhost-2-0"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
