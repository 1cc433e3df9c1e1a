//! Outputs that appear atomically: written under a hidden temporary name in the destination's
//! folder, renamed over the final name only when complete, removed if dropped before that.

use myriad_core::{Error, Result};
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};

pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    committed: bool,
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
        temp_name.push(format!(".{}.partial", std::process::id()));
        let temp = target.with_file_name(temp_name);
        Ok(AtomicFile {
            target: target.to_path_buf(),
            temp,
            committed: false,
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
}
