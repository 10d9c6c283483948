//! Located errors for every file format.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in a file a problem was found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Location {
    /// The whole file (I/O errors, empty files).
    File,
    /// A 1-based line (and optional 1-based column) of a text format.
    Line {
        /// Line number, from 1.
        line: usize,
        /// Column number, from 1, when known.
        column: Option<usize>,
    },
    /// A JSON path into a glTF document, e.g. `/accessors/3/count`.
    JsonPath(String),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::File => Ok(()),
            Location::Line { line, column: Some(c) } => write!(f, ":{line}:{c}"),
            Location::Line { line, column: None } => write!(f, ":{line}"),
            Location::JsonPath(p) => write!(f, " at {p}"),
        }
    }
}

/// What kind of problem a file has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatErrorKind {
    /// The file could not be read or written.
    Io,
    /// The file ends before the data it announces.
    Truncated,
    /// A token is not what the grammar expects here.
    Syntax,
    /// A value is out of range, non-numeric or not finite.
    Value,
    /// The structure is inconsistent (duplicate names, bad indices, cycles, no joints).
    Structure,
    /// Valid by the format, but not something kinegraph handles.
    Unsupported,
}

/// A problem with a file, naming the file and the place in it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}{location}: {message}", file.display())]
pub struct FormatError {
    /// The file concerned.
    pub file: PathBuf,
    /// Where in it.
    pub location: Location,
    /// Category, for callers that react differently.
    pub kind: FormatErrorKind,
    /// Human-readable explanation.
    pub message: String,
}

impl FormatError {
    /// An error at `location` in `file`.
    pub fn new(file: &Path, location: Location, kind: FormatErrorKind, message: impl Into<String>) -> Self {
        FormatError { file: file.to_path_buf(), location, kind, message: message.into() }
    }

    /// An error about the whole of `file`.
    pub fn file(file: &Path, kind: FormatErrorKind, message: impl Into<String>) -> Self {
        Self::new(file, Location::File, kind, message)
    }

    /// An I/O error on `file`.
    pub fn io(file: &Path, err: &std::io::Error) -> Self {
        Self::file(file, FormatErrorKind::Io, err.to_string())
    }
}

/// A loaded value with the oddities found while loading it (an unexpected unit, a clamped
/// weight): not errors, but never silently swallowed.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded<T> {
    /// The value.
    pub value: T,
    /// Human-readable warnings, in the order found.
    pub warnings: Vec<String>,
}
