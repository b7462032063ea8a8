//! Typed errors for reading and writing meshes. Every error names the file and, where it
//! can, the line or element index and the offending value.

use super::files::SpecialKind;
use super::limits::Limit;
use std::fmt;
use std::path::PathBuf;

/// Where in a file something was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// 1-based line of a text file.
    Line(u64),
    /// The n-th (0-based) element of a kind, e.g. `vertex 41` in a binary PLY.
    Element { element: String, index: u64 },
    /// The header of the file.
    Header,
    /// Byte offset in a binary file.
    Byte(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::Element { element, index } => write!(f, "{element} {index}"),
            Location::Header => write!(f, "header"),
            Location::Byte(n) => write!(f, "byte {n}"),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {at}: {message}")]
    Malformed {
        path: PathBuf,
        at: Location,
        message: String,
    },
    #[error("{path}: {at}: coordinate is not a finite number: {value}")]
    NonFinite {
        path: PathBuf,
        at: Location,
        value: String,
    },
    #[error("{path}: {at}: {kind} index {index} is out of range (the file has {count})")]
    IndexOutOfRange {
        path: PathBuf,
        at: Location,
        kind: &'static str,
        index: i64,
        count: usize,
    },
    #[error("{path}: texture {texture}: {message}")]
    Texture {
        path: PathBuf,
        texture: String,
        message: String,
    },
    /// A file the scan names (`mtllib`, `map_*`, PLY `TextureFile`) that lies outside the
    /// scan's folder once `..` and symlinks are resolved; `resolved` is where it leads.
    #[error(
        "{path}: texture path {texture:?} resolves outside the scan's folder ({resolved}); refusing"
    )]
    PathEscapes {
        path: PathBuf,
        texture: String,
        resolved: PathBuf,
    },
    /// A FIFO, device, socket or folder where a file was expected; never opened for reading.
    #[error("{path} is {kind}; refusing to read it")]
    SpecialFile { path: PathBuf, kind: SpecialKind },
    /// The input is above one of the configured [`InputLimits`](super::limits::InputLimits).
    #[error("{path}: {what} exceeds {limit} = {value}")]
    TooLarge {
        path: PathBuf,
        what: String,
        limit: Limit,
        value: u64,
    },
    /// Writing an output file failed (full disk, permissions, ...): the output's fault, not
    /// the input's.
    #[error("{path}: cannot write: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// `reason` says why, e.g. "the file has no face element" or which repair rules dropped
    /// every face.
    #[error("{path}: the file holds no usable triangles: {reason}")]
    NoTriangles { path: PathBuf, reason: String },
    #[error("{path}: not a mesh file scanmill reads (expected .obj, .ply, optionally .gz)")]
    UnknownFormat { path: PathBuf },
}

impl MeshError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        MeshError::Io {
            path: path.into(),
            source,
        }
    }

    pub fn write(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        MeshError::Write {
            path: path.into(),
            source,
        }
    }

    pub fn malformed(path: impl Into<PathBuf>, at: Location, message: impl Into<String>) -> Self {
        MeshError::Malformed {
            path: path.into(),
            at,
            message: message.into(),
        }
    }
}

pub type Result<T, E = MeshError> = std::result::Result<T, E>;
