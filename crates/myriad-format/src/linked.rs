//! Datasets of several files: a dataset whose node pages stay in other datasets' files (the
//! parts of a partitioned build, which `merge` leaves where they were written). The dataset's
//! metadata lists the files (`files`: a path relative to the dataset, the file's length and
//! its header's CRC-32); file `i` (from 1) occupies the offsets from `i << SLOT_BITS` in the
//! dataset's address space, the dataset's own file slot 0. A reader maps a page reference to
//! its file there, opening each file the first time a page of it is read (a dataset of a
//! thousand parts opens as fast as one of one) and checking that it is the file that was
//! linked (length and header). The byte layout is in docs/format.md.

use crate::ByteSource;
use serde_json::{Value, json};
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// Offsets below `1 << SLOT_BITS` (1 TiB) are the dataset's own file; each linked file has a
/// slot of that size. 40 bits leave 8,191 files below 2^53, where JavaScript's numbers (the
/// web viewer's page offsets) are still exact.
pub const SLOT_BITS: u32 = 40;

/// The most files a dataset links (offsets stay below 2^53).
pub const MAX_FILES: usize = (1 << (53 - SLOT_BITS)) - 1;

/// The first offset of linked file `index` (0-based in `files`).
pub fn base(index: usize) -> u64 {
    (index as u64 + 1) << SLOT_BITS
}

/// A file a dataset's pages lie in, as its metadata records it.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkedFile {
    /// Relative to the dataset's own file (`/`-separated; never absolute).
    pub path: String,
    pub length: u64,
    /// The CRC-32 of its 64-byte header as stored (its header CRC field): a file replaced since
    /// (a part built again) is told apart.
    pub header_crc: u32,
}

impl LinkedFile {
    pub fn to_json(&self) -> Value {
        json!({"path": self.path, "length": self.length, "header_crc": self.header_crc})
    }

    pub fn from_json(v: &Value) -> Result<LinkedFile, String> {
        let path = v["path"].as_str().ok_or("files: an entry lacks \"path\"")?;
        // Relative, as a merge writes them: a dataset names files beside, below or above it,
        // never a place of its own choosing.
        if path.is_empty() || path.starts_with('/') || path.contains(['\\', ':', '\0']) {
            return Err(format!("files: {path:?} is not a relative path"));
        }
        Ok(LinkedFile {
            path: path.to_string(),
            length: v["length"]
                .as_u64()
                .ok_or("files: an entry lacks \"length\"")?,
            header_crc: (v["header_crc"].as_u64())
                .and_then(|c| u32::try_from(c).ok())
                .ok_or("files: an entry lacks \"header_crc\"")?,
        })
    }

    /// Whether `head` (a file's first 64 bytes) and `length` are this file's.
    pub fn check(&self, head: &[u8], length: u64) -> Result<(), String> {
        if length != self.length {
            return Err(format!(
                "{} bytes, {} when the dataset was made (built again or cut short since? merge again)",
                length, self.length
            ));
        }
        let crc = head
            .get(12..16)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()));
        if head.get(..8) != Some(&crate::MAGIC[..]) || crc != Some(self.header_crc) {
            return Err("its header is not the one the dataset was made with (built again since? merge again)".into());
        }
        Ok(())
    }
}

/// Opens linked file `index` (as recorded): how depends on where the dataset is.
pub type Opener =
    Arc<dyn Fn(usize, &LinkedFile) -> std::io::Result<Arc<dyn ByteSource>> + Send + Sync>;

/// The linked files of an open dataset, each opened on first use.
pub(crate) struct Linked {
    pub(crate) files: Vec<LinkedFile>,
    /// Each file's source once opened, or why it could not be (said again at every read).
    open: Vec<OnceLock<Result<Arc<dyn ByteSource>, String>>>,
    opener: Opener,
    /// How a file is named in errors: its path as the opener resolves it.
    name: Arc<dyn Fn(&str) -> String + Send + Sync>,
}

impl Linked {
    pub(crate) fn new(
        files: Vec<LinkedFile>,
        opener: Opener,
        name: Arc<dyn Fn(&str) -> String + Send + Sync>,
    ) -> Linked {
        Linked {
            open: files.iter().map(|_| OnceLock::new()).collect(),
            files,
            opener,
            name,
        }
    }

    /// The name errors give file `i`.
    pub(crate) fn name(&self, i: usize) -> String {
        (self.name)(&self.files[i].path)
    }

    /// File `i`'s bytes, opened and checked the first time (errors without its name).
    pub(crate) fn source(&self, i: usize) -> Result<&Arc<dyn ByteSource>, String> {
        let f = &self.files[i];
        let r = self.open[i].get_or_init(|| {
            let s = (self.opener)(i, f).map_err(|e| e.to_string())?;
            let head = s.read_at(0, crate::HEADER_LEN.min(s.len() as usize));
            let head = head.map_err(|e| e.to_string())?;
            f.check(&head, s.len())?;
            Ok(s)
        });
        r.as_ref().map_err(|m| m.clone())
    }

    /// Every file opened so far: requests and bytes, where they went over a network.
    pub(crate) fn opened(&self) -> impl Iterator<Item = &Arc<dyn ByteSource>> {
        self.open.iter().filter_map(|o| o.get()?.as_ref().ok())
    }
}

/// `rel` resolved against the URL `base` (a file in it), as a browser resolves a relative link:
/// `.` and `..` segments taken out, never above the host (or an S3 bucket).
pub fn join_url(base: &str, rel: &str) -> String {
    let Some(scheme_end) = base.find("://").map(|i| i + 3) else {
        return rel.to_string();
    };
    let root_end = base[scheme_end..]
        .find('/')
        .map_or(base.len(), |i| scheme_end + i);
    let (root, path) = base.split_at(root_end);
    // The base's folder, then the relative path's segments.
    let mut segs: Vec<&str> = path.split('/').filter(|s| !s.is_empty()).collect();
    segs.pop();
    let rel = rel.split(['?', '#']).next().unwrap_or(rel);
    if rel.starts_with('/') {
        segs.clear();
    }
    for s in rel.split('/') {
        match s {
            "" | "." => {}
            ".." => {
                segs.pop();
            }
            s => segs.push(s),
        }
    }
    format!("{root}/{}", segs.join("/"))
}

/// The path of `target` relative to the folder `from` (both absolute), `/`-separated: what a
/// dataset records to find a file beside or below it (or above, with `..`).
pub fn relative_path(from: &Path, target: &Path) -> String {
    use std::path::Component;
    let a: Vec<Component> = from.components().collect();
    let b: Vec<Component> = target.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".to_string(); a.len() - common];
    parts.extend(
        b[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    #[test]
    fn urls_resolve_as_a_browser_resolves_links() {
        let b = "http://host:8080/d/city.myr";
        assert_eq!(
            join_url(b, "city.myr.parts/part-3.myr"),
            "http://host:8080/d/city.myr.parts/part-3.myr"
        );
        assert_eq!(
            join_url(b, "../p/part-0.myr"),
            "http://host:8080/p/part-0.myr"
        );
        assert_eq!(join_url(b, "../../../x.myr"), "http://host:8080/x.myr");
        assert_eq!(join_url(b, "./a/./b.myr"), "http://host:8080/d/a/b.myr");
        assert_eq!(
            join_url("s3://bucket/k/c.myr", "p/1.myr"),
            "s3://bucket/k/p/1.myr"
        );
    }

    #[test]
    fn relative_paths_go_up_where_they_must() {
        let p = |s: &str| PathBuf::from(s);
        assert_eq!(
            relative_path(&p("/a/b"), &p("/a/b/parts/part-1.myr")),
            "parts/part-1.myr"
        );
        assert_eq!(
            relative_path(&p("/a/b"), &p("/a/c/part-1.myr")),
            "../c/part-1.myr"
        );
        assert_eq!(relative_path(&p("/"), &p("/x.myr")), "x.myr");
    }

    #[test]
    fn a_file_built_again_is_told_apart() {
        let f = LinkedFile {
            path: "p.myr".into(),
            length: 100,
            header_crc: 7,
        };
        let mut head = [0u8; 64];
        head[..8].copy_from_slice(crate::MAGIC);
        head[12..16].copy_from_slice(&7u32.to_le_bytes());
        assert!(f.check(&head, 100).is_ok());
        assert!(f.check(&head, 99).unwrap_err().contains("99 bytes, 100"));
        head[12] = 8;
        assert!(f.check(&head, 100).unwrap_err().contains("header"));
        assert_eq!(LinkedFile::from_json(&f.to_json()).unwrap(), f);
        for bad in ["/etc/passwd", "C:x", "a\\b", ""] {
            let v = json!({"path": bad, "length": 1, "header_crc": 1});
            assert!(LinkedFile::from_json(&v).is_err(), "{bad}");
        }
    }
}
