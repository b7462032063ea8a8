//! Typed errors for reading and writing meshes. Every error names the file and, where it
//! can, the line or element index and the offending value.

use super::files::SpecialKind;
use super::limits::Limit;
use super::texture::Referenced;
use std::fmt;
use std::path::{Path, PathBuf};

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

/// Longest piece of input (a token, a name, a header keyword) an error repeats: an error is
/// one line, and a hostile file must not turn it into megabytes of log.
const MAX_ECHO: usize = 256;

/// Input-derived text as an error shows it: control characters escaped, cut at [`MAX_ECHO`].
fn shown(text: &str) -> String {
    crate::text::bounded(text, MAX_ECHO)
}

/// A path as an error shows it: escaped byte for byte, cut at four times [`MAX_ECHO`].
fn shown_path(path: &Path) -> String {
    crate::text::bounded(&crate::text::escape_path(path), 4 * MAX_ECHO)
}

#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("{}: {source}", shown_path(.path))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {at}: {}", shown_path(.path), shown(.message))]
    Malformed {
        path: PathBuf,
        at: Location,
        message: String,
    },
    #[error("{}: {at}: coordinate is not a finite number: {}", shown_path(.path), shown(.value))]
    NonFinite {
        path: PathBuf,
        at: Location,
        value: String,
    },
    #[error(
        "{}: {at}: {kind} index {index} is out of range (the file has {count})",
        shown_path(.path)
    )]
    IndexOutOfRange {
        path: PathBuf,
        at: Location,
        kind: &'static str,
        index: i64,
        count: usize,
    },
    #[error("{}: texture {}: {}", shown_path(.path), shown(.texture), shown(.message))]
    Texture {
        path: PathBuf,
        texture: String,
        message: String,
    },
    /// A file the scan names (`mtllib`, `map_*`, PLY `TextureFile`) that lies outside the
    /// scan's folder once `..` and symlinks are resolved; `resolved` is where it leads.
    #[error(
        "{}: {role} path \"{}\" resolves outside the scan's folder ({}); refusing",
        shown_path(.path),
        shown(.name),
        shown_path(.resolved)
    )]
    PathEscapes {
        path: PathBuf,
        /// What `path` names the file as.
        role: Referenced,
        name: String,
        resolved: PathBuf,
    },
    /// A file the scan names (as for [`MeshError::PathEscapes`]) that does not exist.
    #[error(
        "{}: {role} {}: file not found (looked for {})",
        shown_path(.path),
        shown(.name),
        shown_path(.looked)
    )]
    MissingFile {
        path: PathBuf,
        role: Referenced,
        name: String,
        looked: PathBuf,
    },
    /// A FIFO, device, socket or folder where a file was expected; never opened for reading.
    #[error("{} is {kind}; refusing to read it", shown_path(.path))]
    SpecialFile { path: PathBuf, kind: SpecialKind },
    /// The input is above one of the configured [`InputLimits`](super::limits::InputLimits).
    #[error("{}: {} exceeds {limit} = {value}", shown_path(.path), shown(.what))]
    TooLarge {
        path: PathBuf,
        what: String,
        limit: Limit,
        value: u64,
    },
    /// Writing an output file failed (full disk, permissions, ...): the output's fault, not
    /// the input's.
    #[error("{}: cannot write: {source}", shown_path(.path))]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// `reason` says why, e.g. "the file has no face element" or which repair rules dropped
    /// every face.
    #[error("{}: the file holds no usable triangles: {}", shown_path(.path), shown(.reason))]
    NoTriangles { path: PathBuf, reason: String },
    #[error(
        "{}: not a mesh file scanmill reads (expected .obj, .ply, .stl, .gltf or .glb, optionally .gz)",
        shown_path(.path)
    )]
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
