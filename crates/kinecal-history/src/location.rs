//! Where a history is: a SQLite file, or a PostgreSQL server named by a `postgres://` URL; the
//! default file; and a location as shown to the user (a URL without its password).

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// Where a history is: what [`Database::open`](crate::Database::open) and
/// [`Database::open_read_only`](crate::Database::open_read_only) take. A location given as text
/// or a path is a server when it is a `postgres://` or `postgresql://` URL, else a SQLite file.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Location {
    /// A SQLite file.
    File(PathBuf),
    /// A PostgreSQL server: `postgres://USER[:PASSWORD]@HOST[:PORT]/DBNAME`.
    Server(String),
}

impl Location {
    /// The location `given` names: a server for a `postgres://` or `postgresql://` URL, else a
    /// SQLite file.
    pub fn parse(given: &(impl AsRef<OsStr> + ?Sized)) -> Location {
        let given = given.as_ref();
        match given.to_str() {
            Some(s) if is_postgres_url(s) => Location::Server(s.to_string()),
            _ => Location::File(PathBuf::from(given)),
        }
    }

    /// The file, for a SQLite history.
    pub fn file(&self) -> Option<&Path> {
        match self {
            Location::File(p) => Some(p),
            Location::Server(_) => None,
        }
    }
}

/// A location as shown: the path, or the URL without its password.
impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Location::File(p) => write!(f, "{}", p.display()),
            Location::Server(url) => f.write_str(&redact(url)),
        }
    }
}

impl<T: AsRef<OsStr> + ?Sized> From<&T> for Location {
    fn from(given: &T) -> Location {
        Location::parse(given)
    }
}

impl From<PathBuf> for Location {
    fn from(given: PathBuf) -> Location {
        Location::parse(&given)
    }
}

impl From<String> for Location {
    fn from(given: String) -> Location {
        Location::parse(&given)
    }
}

/// Where the history lives by default: `$XDG_DATA_HOME/kinecal/history.sqlite`, else
/// `~/.local/share/kinecal/history.sqlite` (`%APPDATA%\kinecal` on Windows).
pub fn default_db_path() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("APPDATA").map(PathBuf::from))
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")))?;
    Some(base.join("kinecal").join("history.sqlite"))
}

/// Whether `location` names a PostgreSQL server (`postgres://` or `postgresql://`).
fn is_postgres_url(location: &str) -> bool {
    let l = location.trim_start().to_ascii_lowercase();
    l.starts_with("postgres://") || l.starts_with("postgresql://")
}

/// The location as shown: the URL without its password (in the user part or a `password=`
/// parameter).
pub(crate) fn redact(url: &str) -> String {
    let (scheme, rest) = match url.find("://") {
        Some(i) => (&url[..i + 3], &url[i + 3..]),
        None => ("", url),
    };
    let authority_end = rest.find(['/', '?']).unwrap_or(rest.len());
    let (authority, tail) = rest.split_at(authority_end);
    let authority = match authority.rfind('@') {
        Some(at) => {
            let user = &authority[..at];
            let user = user.split_once(':').map_or(user, |(u, _)| u);
            format!("{user}@{}", &authority[at + 1..])
        }
        None => authority.to_string(),
    };
    let tail = match tail.split_once('?') {
        Some((path, query)) => {
            let kept: Vec<&str> = query
                .split('&')
                .filter(|kv| !kv.to_ascii_lowercase().starts_with("password="))
                .collect();
            if kept.is_empty() {
                path.to_string()
            } else {
                format!("{path}?{}", kept.join("&"))
            }
        }
        None => tail.to_string(),
    };
    format!("{scheme}{authority}{tail}")
}

#[cfg(test)]
mod tests {
    use super::{redact, Location};
    use std::path::Path;

    #[test]
    fn passwords_are_never_shown() {
        assert_eq!(
            redact("postgres://alice:s3cr%40t@db.plant:5432/kinecal?sslmode=disable&password=x"),
            "postgres://alice@db.plant:5432/kinecal?sslmode=disable"
        );
        assert_eq!(
            redact("postgresql://db.plant/kinecal"),
            "postgresql://db.plant/kinecal"
        );
        assert_eq!(redact("postgres://a:b@h/d?password=x"), "postgres://a@h/d");
        assert_eq!(
            Location::parse("postgres://a:b@h/d").to_string(),
            "postgres://a@h/d"
        );
    }

    #[test]
    fn a_location_is_a_server_url_or_a_file() {
        for url in ["postgres://a@h/d", "PostgreSQL://a@h/d", " postgres://h"] {
            assert_eq!(Location::parse(url), Location::Server(url.to_string()));
        }
        for file in ["h.sqlite", "postgres/h.sqlite", "/tmp/postgres:/x"] {
            let l = Location::from(Path::new(file));
            assert_eq!(l.file(), Some(Path::new(file)));
        }
    }
}
