//! Input files as read: their text and a fingerprint of the bytes actually read, so that what a
//! report records is what the calibration used.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Location, Result};

/// SHA-256 of `bytes`, as 64 lowercase hex digits.
pub fn fingerprint(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// A file's text, name and fingerprint.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Source {
    /// The path as the user gave it (or `<built-in ge-a4>`).
    pub name: String,
    /// The text.
    pub text: String,
    /// SHA-256 of the bytes read.
    pub sha256: String,
}

/// A file the calibration read, with the SHA-256 of the bytes read.
// What a report records of a file. Its text is not kept: a data file's is dropped once it is
// parsed, so that a run does not hold every file it read for as long as it works on their data.
// (The report's schema keeps the name it had when the report had a type of its own for it.)
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[schemars(rename = "SourceReport")]
pub struct Fingerprint {
    /// The file name as given.
    // (`<built-in ge-a4>` for a built-in robot.)
    pub name: String,
    /// SHA-256, hex.
    pub sha256: String,
}

impl Source {
    /// Its name and fingerprint, without the text.
    pub fn fingerprint(&self) -> Fingerprint {
        Fingerprint {
            name: self.name.clone(),
            sha256: self.sha256.clone(),
        }
    }

    /// Text that did not come from a file (a built-in robot), named `name`.
    pub fn text(name: impl Into<String>, text: impl Into<String>) -> Source {
        let text = text.into();
        Source {
            name: name.into(),
            sha256: fingerprint(text.as_bytes()),
            text,
        }
    }

    /// Reads a UTF-8 text file; invalid UTF-8 is an error naming the line where it occurs. `-`
    /// is standard input (named `-` in messages); any path is read as a stream, once, to its end,
    /// so `/dev/stdin`, pipes and process substitutions work as files do.
    pub fn read(path: &std::path::Path) -> Result<Source> {
        use std::io::Read as _;
        let name = path.display().to_string();
        let io = |cause| Error::Io {
            path: name.clone(),
            cause,
        };
        let mut bytes = Vec::new();
        if path.as_os_str() == "-" {
            std::io::stdin()
                .lock()
                .read_to_end(&mut bytes)
                .map_err(io)?;
        } else {
            std::fs::File::open(path)
                .and_then(|mut f| f.read_to_end(&mut bytes))
                .map_err(io)?;
        }
        Source::from_bytes(name, bytes)
    }

    /// A file's bytes as read, named `name`: UTF-8 text, else an error naming the line of the
    /// first invalid byte.
    pub fn from_bytes(name: impl Into<String>, bytes: Vec<u8>) -> Result<Source> {
        let name = name.into();
        let sha256 = fingerprint(&bytes);
        let text = String::from_utf8(bytes).map_err(|e| {
            let valid = e.utf8_error().valid_up_to();
            let line = e.as_bytes()[..valid]
                .iter()
                .filter(|&&b| b == b'\n')
                .count()
                + 1;
            Error::input(
                Location::file(&name).at_line(line),
                format!("not UTF-8 text (invalid byte at offset {valid}); save the file as UTF-8"),
            )
        })?;
        Ok(Source { name, text, sha256 })
    }
}
