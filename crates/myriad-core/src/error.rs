//! Typed errors. Every error about a user's file names the file and, where the format allows,
//! the byte offset or line where reading went wrong, so the CLI can print one useful line.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in a file a problem was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// Zero-based byte offset from the start of the file.
    Byte(u64),
    /// One-based line number of a text file.
    Line(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Byte(b) => write!(f, "byte {b}"),
            Location::Line(l) => write!(f, "line {l}"),
        }
    }
}

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The file's content does not follow its format.
    #[error("{}: {location}: {message}", path.display())]
    Format {
        path: PathBuf,
        location: Location,
        message: String,
    },
    /// The operating system refused or failed an operation on the file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A valid file that uses something Myriad cannot read, or a path that is no point cloud.
    #[error("{}: {message}", path.display())]
    Unsupported { path: PathBuf, message: String },
    /// A caller asked for something invalid (bad option value, inconsistent arguments).
    #[error("{0}")]
    Invalid(String),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn format(path: &Path, location: Location, message: impl Into<String>) -> Error {
        Error::Format {
            path: path.to_path_buf(),
            location,
            message: message.into(),
        }
    }
    pub fn at_byte(path: &Path, offset: u64, message: impl Into<String>) -> Error {
        Error::format(path, Location::Byte(offset), message)
    }
    pub fn at_line(path: &Path, line: u64, message: impl Into<String>) -> Error {
        Error::format(path, Location::Line(line), message)
    }
    pub fn io(path: &Path, source: std::io::Error) -> Error {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }
    pub fn unsupported(path: &Path, message: impl Into<String>) -> Error {
        Error::Unsupported {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_file_and_location() {
        let e = Error::at_byte(Path::new("a.las"), 227, "bad magic");
        assert_eq!(e.to_string(), "a.las: byte 227: bad magic");
        let e = Error::at_line(Path::new("b.xyz"), 3, "not a number: \"x\"");
        assert_eq!(e.to_string(), "b.xyz: line 3: not a number: \"x\"");
    }
}
