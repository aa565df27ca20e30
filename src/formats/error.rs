//! The error type shared by the JSON readers.

use std::path::{Path, PathBuf};

/// A file could not be read, or its content is malformed.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The file could not be opened or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The content is malformed at `location` (a JSON path such as `images[3].meta.latitude`,
    /// or `line N`).
    #[error("{}: at {location}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Where in the file.
        location: String,
        /// What is wrong.
        message: String,
    },
}

impl FormatError {
    /// An [`FormatError::Invalid`] for `path` at `location`.
    pub fn invalid(path: &Path, location: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.to_path_buf(),
            location: location.into(),
            message: message.into(),
        }
    }
}

/// Reads and deserialises a JSON file, reporting the JSON path and line of any error.
pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, FormatError> {
    let file = super::input::open(path, super::input::InputKind::Json).map_err(|source| {
        FormatError::Io {
            path: path.to_path_buf(),
            source,
        }
    })?;
    let reader = std::io::BufReader::new(file);
    let mut de = serde_json::Deserializer::from_reader(reader);
    deserialize_json(&mut de, path)
}

/// Deserialises JSON held in memory as [`read_json`] reads a file; `path` only names it in
/// errors.
pub(crate) fn parse_json<T: serde::de::DeserializeOwned>(
    bytes: &[u8],
    path: &Path,
) -> Result<T, FormatError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    deserialize_json(&mut de, path)
}

/// Deserialises from `de`, reporting the JSON path and line of any error.
fn deserialize_json<'de, T, R>(
    de: &mut serde_json::Deserializer<R>,
    path: &Path,
) -> Result<T, FormatError>
where
    T: serde::de::DeserializeOwned,
    R: serde_json::de::Read<'de>,
{
    serde_path_to_error::deserialize(de).map_err(|e| {
        let location = e.path().to_string();
        let inner = e.into_inner();
        let location = if location == "." || location.is_empty() {
            format!("line {} column {}", inner.line(), inner.column())
        } else {
            format!(
                "{location} (line {} column {})",
                inner.line(),
                inner.column()
            )
        };
        FormatError::invalid(path, location, inner.to_string())
    })
}
