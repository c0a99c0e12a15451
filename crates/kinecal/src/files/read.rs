//! Which observation files a job reads and how: the kind of each, its column mapping, units and
//! measurement session ([`ReadSettings`], [`ObservationFile`]), and the one reader behind every
//! front end ([`read_files`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{detect_format, read_observations_as, ColumnMap, ReadOptions, FORMATS};
use crate::error::{Error, Result, Setting};
use crate::model::robot::Robot;
use crate::observe::Dataset;
use crate::source::{Fingerprint, Source};

fn is_default<T: Default + PartialEq>(t: &T) -> bool {
    *t == T::default()
}

fn invalid(setting: Setting, message: impl Into<String>) -> Error {
    Error::InvalidOption {
        setting,
        message: message.into(),
    }
}

/// How observation files are read (`[read]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadSettings {
    /// Column mappings of measurement files written by another tool (`["v1=J1,x=X", ...]`,
    /// as [`ColumnMap::parse`] reads them); files of the other kinds are read by their own
    /// headers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub columns: Vec<String>,
    /// The files' length unit (`m`, `mm`, `in`), when not the robot file's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// The files' angle unit (`rad`, `deg`), when not the robot file's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_unit: Option<String>,
    /// Read poses as positions (their attitudes left out).
    #[serde(default, skip_serializing_if = "is_default")]
    pub position_only: bool,
    /// Each file a measurement session of its own (an instrument moved between files),
    /// named after the file (`session_name`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub session_per_file: bool,
}

/// One observation file (`[[observations]]`, `[[validation.files]]`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObservationFile {
    /// The file.
    pub file: String,
    /// Its kind, named as [`FORMATS`] names them (`data`, `distances`, `contacts`); told by
    /// its header when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<String>,
    /// The measurement session of its postures (those without a `session` column value).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub session: Option<String>,
    /// Its column mappings, instead of `read.columns` (measurement files only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub columns: Vec<String>,
    /// Its length unit, instead of `read.length_unit`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// Its angle unit, instead of `read.angle_unit`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_unit: Option<String>,
}

impl ObservationFile {
    /// A file of the kind its header tells, read as `[read]` says.
    pub fn new(file: impl Into<String>) -> ObservationFile {
        ObservationFile {
            file: file.into(),
            ..ObservationFile::default()
        }
    }
}

/// A unit: the file's own, else the shared one, parsed.
fn unit<U: std::str::FromStr<Err = String>>(
    own: &Option<String>,
    shared: &Option<String>,
    setting: Setting,
) -> Result<Option<U>> {
    own.as_ref()
        .or(shared.as_ref())
        .map(|u| u.parse().map_err(|m: String| invalid(setting, m)))
        .transpose()
}

/// How `file` is read: its own mapping and units, else `read`'s (the shared mapping applies to
/// measurement files only).
pub(crate) fn read_options(
    read: &ReadSettings,
    file: &ObservationFile,
    kind: usize,
) -> Result<ReadOptions> {
    let own = !file.columns.is_empty();
    let specs: Vec<&str> = if own { &file.columns } else { &read.columns }
        .iter()
        .map(String::as_str)
        .collect();
    let mut columns = ColumnMap::parse(&specs, "columns").map_err(|e| match e {
        Error::Input { message, .. } => invalid(Setting::Columns, message),
        e => e,
    })?;
    if kind != 0 && !own {
        // The shared mapping's pairs name measurement columns; its units apply to every file.
        columns = ColumnMap {
            length_unit: columns.length_unit,
            angle_unit: columns.angle_unit,
            ..ColumnMap::default()
        };
    }
    Ok(ReadOptions {
        columns,
        length_unit: unit(&file.length_unit, &read.length_unit, Setting::LengthUnit)?,
        angle_unit: unit(&file.angle_unit, &read.angle_unit, Setting::AngleUnit)?,
        position_only: read.position_only,
    })
}

/// Reads the observation files `list` for `robot`, as `read` says, into one dataset, and
/// their fingerprints (each file's text is dropped once it is parsed); with
/// `read.session_per_file`, each file's session is named to tell it from the files `all`
/// (`session_name`). The files are fitted together, so a row's own standard deviation is
/// checked against the median of every file's for its quantity (`table::sigma_spread_across`),
/// as each file's reader checks it against its own.
pub fn read_files(
    read: &ReadSettings,
    list: &[ObservationFile],
    robot: &Robot,
    all: &[&Path],
) -> Result<(Dataset, Vec<Fingerprint>)> {
    let mut parts = Vec::with_capacity(list.len());
    let mut sources = Vec::with_capacity(list.len());
    for f in list {
        let source = Source::read(Path::new(&f.file))?;
        let kind = match &f.kind {
            Some(k) => kind_index(k)?,
            None => detect_format(&source.text),
        };
        let opts = read_options(read, f, kind)?;
        let session = match (&f.session, read.session_per_file) {
            (Some(s), _) => Some(s.clone()),
            (None, true) => Some(session_name(Path::new(&f.file), all)),
            (None, false) => None,
        };
        let d = read_observation_file(&source, kind, &opts, robot, session.as_deref())?;
        parts.push((d, opts.units(robot, &source.name)?));
        sources.push(source.fingerprint());
    }
    if parts.len() > 1 {
        let files: Vec<super::table::FileRows<'_>> = parts
            .iter()
            .zip(&sources)
            .map(|((d, units), source)| super::table::FileRows {
                file: &source.name,
                observations: &d.observations,
                units: *units,
            })
            .collect();
        super::table::sigma_spread_across(&files)?;
    }
    let data = parts
        .into_iter()
        .fold(Dataset::default(), |data, (d, _)| data.merge(d));
    Ok((data, sources))
}

/// The index into [`FORMATS`] of an observation file kind named `name`.
pub(crate) fn kind_index(name: &str) -> Result<usize> {
    FORMATS
        .iter()
        .position(|f| f.option == name)
        .ok_or_else(|| {
            invalid(
                Setting::ObservationKind,
                format!(
                    "`{name}`: expected one of {}",
                    FORMATS
                        .iter()
                        .map(|f| f.option)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
        })
}

/// Reads one observation file, `source`, as a file of the kind `FORMATS[kind]` for `robot`,
/// through `opts`; its postures without a session of their own go in `session`. The one reader
/// of observation files behind every front end.
pub(crate) fn read_observation_file(
    source: &Source,
    kind: usize,
    opts: &ReadOptions,
    robot: &Robot,
    session: Option<&str>,
) -> Result<Dataset> {
    let mut data = read_observations_as(&source.text, &source.name, robot, opts, kind)?;
    if let Some(s) = session {
        data.set_session(s);
    }
    Ok(data)
}

/// The session of a file read one session per file: its name without the extension, with as
/// many parent folders as it takes to tell it from the other files `all`.
pub(crate) fn session_name(path: &Path, all: &[&Path]) -> String {
    let parts = |p: &Path| -> Vec<String> {
        let mut v: Vec<String> = p
            .with_extension("")
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect();
        v.reverse();
        v
    };
    let mine = parts(path);
    let others: Vec<Vec<String>> = all
        .iter()
        .filter(|p| **p != path)
        .map(|p| parts(p))
        .collect();
    for k in 1..=mine.len() {
        let tail = &mine[..k];
        if others.iter().all(|o| o.len() < k || o[..k] != *tail) {
            let mut t = tail.to_vec();
            t.reverse();
            return t.join("/");
        }
    }
    path.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn session_names_tell_files_apart() {
        let (a, b) = (Path::new("x/run1/p.csv"), Path::new("x/run2/p.csv"));
        assert_eq!(session_name(a, &[a, b]), "run1/p");
        let (a, b) = (Path::new("A.csv"), Path::new("B.csv"));
        assert_eq!(session_name(a, &[a, b]), "A");
    }

    #[test]
    fn a_kind_is_named_as_the_formats_name_it() {
        assert_eq!(kind_index("distances").unwrap(), 1);
        let e = kind_index("distance").unwrap_err();
        assert!(e.to_string().contains("data, distances, contacts"), "{e}");
    }
}
