//! Tables read and written row by row, so that files of any length pass through in flat
//! memory (`fk`, `compensate`).

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use crate::error::{Error, Location, Result};
use crate::model::robot::Payload;
use crate::units::{Quantity, Units};

/// An error at `line` of `file`.
fn at(file: &str, line: u64, message: impl Into<String>) -> Error {
    Error::input(Location::file(file).at_line(line as usize), message)
}

/// An I/O error reading `file`.
/// The reader's error as an input error at its line: text that is not UTF-8 (a file saved
/// as UTF-16, say) said in words, not as the parser's.
fn csv_error(file: &str, e: csv::Error) -> Error {
    let at = match e.position() {
        Some(p) => Location::file(file).at_line(p.line() as usize),
        None => Location::file(file),
    };
    match e.kind() {
        csv::ErrorKind::Utf8 { .. } => Error::input(at, "not UTF-8 text; save the file as UTF-8"),
        csv::ErrorKind::Io(_) => Error::input(at, e.to_string()),
        _ => Error::input(at, format!("invalid CSV: {e}")),
    }
}

fn io(file: &str, cause: std::io::Error) -> Error {
    Error::Io {
        path: file.to_string(),
        cause,
    }
}

/// A CSV table read one row at a time: `,`, `;` or tab delimited (told by the header line),
/// `#` comment lines, fields trimmed, a byte-order mark ignored.
pub struct Rows {
    reader: csv::Reader<Box<dyn Read>>,
    /// The header, lower case.
    pub header: Vec<String>,
    /// The header as the file spells it (for messages).
    pub spelled: Vec<String>,
    /// The file's name, for messages.
    pub file: String,
    record: csv::StringRecord,
    /// `;` or tab delimited: a decimal comma (`0,25`) is read as a decimal point.
    decimal_comma: bool,
}

impl Rows {
    /// Opens `path` (`-`: standard input) and reads its header. The file is opened once and
    /// read as a stream: the lines up to the header are kept and read again by the CSV reader,
    /// so `/dev/stdin` and pipes work as files do.
    pub fn open(path: &Path) -> Result<Rows> {
        let file = path.display().to_string();
        let source: Box<dyn Read> = if path.as_os_str() == "-" {
            Box::new(std::io::stdin())
        } else {
            Box::new(File::open(path).map_err(|e| io(&file, e))?)
        };
        let mut input = BufReader::new(source);
        // Skip a byte-order mark.
        if input
            .fill_buf()
            .map_err(|e| io(&file, e))?
            .starts_with(&[0xef, 0xbb, 0xbf])
        {
            input.consume(3);
        }
        // The delimiter from the first line that is not blank or a comment; the lines read to
        // find it are read again by the CSV reader.
        let mut head = Vec::new();
        let mut first = String::new();
        loop {
            let mut line = Vec::new();
            if input
                .read_until(b'\n', &mut line)
                .map_err(|e| io(&file, e))?
                == 0
            {
                break;
            }
            head.extend_from_slice(&line);
            let text = String::from_utf8_lossy(&line);
            let t = text.trim();
            if !t.is_empty() && !super::table::is_comment(t) {
                first = t.to_string();
                break;
            }
        }
        let count = |c: char| first.matches(c).count();
        let delimiter = if count(';') > count(',') && count(';') >= count('\t') {
            b';'
        } else if count('\t') > count(',') {
            b'\t'
        } else {
            b','
        };
        let reader: Box<dyn Read> = Box::new(std::io::Cursor::new(head).chain(input));
        let mut reader = csv::ReaderBuilder::new()
            .delimiter(delimiter)
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .flexible(true)
            .from_reader(reader);
        let spelled: Vec<String> = reader
            .headers()
            .map_err(|e| csv_error(&file, e))?
            .iter()
            .map(String::from)
            .collect();
        let header: Vec<String> = spelled.iter().map(|h| h.to_ascii_lowercase()).collect();
        if header.iter().all(String::is_empty) {
            return Err(at(&file, 1, "empty file: a header line is required"));
        }
        Ok(Rows {
            reader,
            header,
            spelled,
            file,
            record: csv::StringRecord::new(),
            decimal_comma: delimiter != b',',
        })
    }

    /// The index of the column called `name` (ASCII case ignored, as in every header: a
    /// joint named `L_S1` heads a column `l_s1` or `L_S1`).
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
    }

    /// Field `i` of the current row (after [`Rows::advance`]).
    pub fn field(&self, i: usize) -> &str {
        &self.record[i]
    }

    /// Moves to the next row that is not blank: its line; `None` at the end.
    pub fn advance(&mut self) -> Result<Option<u64>> {
        loop {
            if !self
                .reader
                .read_record(&mut self.record)
                .map_err(|e| csv_error(&self.file, e))?
            {
                return Ok(None);
            }
            if self.record.iter().all(str::is_empty) {
                continue;
            }
            let line = self.record.position().map_or(0, |p| p.line());
            if self.record.len() != self.header.len() {
                return Err(at(
                    &self.file,
                    line,
                    format!(
                        "{} fields, the header has {}",
                        self.record.len(),
                        self.header.len()
                    ),
                ));
            }
            return Ok(Some(line));
        }
    }
}

/// A finite number in field `field` of line `line`.
pub fn number(file: &str, line: u64, field: &str, s: &str) -> Result<f64> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 1e9 => Ok(v),
        // Named as written: `1e308`, not its 309 digits.
        Ok(_) => Err(Error::input(
            Location::file(file)
                .at_line(line as usize)
                .with_field(field),
            format!("{s} is not a finite number within +-1e9"),
        )),
        Err(_) => Err(Error::input(
            Location::file(file)
                .at_line(line as usize)
                .with_field(field),
            format!("expected a number, found `{s}`"),
        )),
    }
}

/// A finite number in column `c` of the current row.
pub fn cell(rows: &Rows, line: u64, c: usize) -> Result<f64> {
    let s = rows.field(c);
    if rows.decimal_comma && s.contains(',') && !s.contains('.') {
        return number(&rows.file, line, &rows.header[c], &s.replace(',', "."));
    }
    number(&rows.file, line, &rows.header[c], s)
}

/// Where a file's payload columns are ([`super::PAYLOAD_COLUMNS`]); an error when a centre of
/// mass comes without `payload_mass`.
pub(crate) fn payload_columns(rows: &Rows) -> Result<[Option<usize>; 4]> {
    let cols = super::PAYLOAD_COLUMNS.map(|c| rows.column(c));
    if cols[0].is_none() {
        if let Some(i) = cols[1..].iter().flatten().next() {
            return Err(Error::input(
                Location::file(&rows.file)
                    .at_line(1)
                    .with_field(&rows.header[*i]),
                "a payload's centre of mass without `payload_mass` (kg)",
            ));
        }
    }
    Ok(cols)
}

/// The payload of the current row: none without a `payload_mass` column or with its cell
/// empty; else the mass (kg, 0 to 1e6) and the centre of mass in the end-effector frame (the
/// robot file's length unit, converted; 0 where a column is absent or empty).
pub(crate) fn payload_at(
    rows: &Rows,
    line: u64,
    cols: &[Option<usize>; 4],
    units: &Units,
) -> Result<Option<Payload>> {
    let Some(m) = cols[0] else {
        return Ok(None);
    };
    if rows.field(m).trim().is_empty() {
        if let Some(c) = cols[1..]
            .iter()
            .flatten()
            .find(|&&c| !rows.field(c).trim().is_empty())
        {
            return Err(Error::input(
                Location::file(&rows.file)
                    .at_line(line as usize)
                    .with_field(&rows.header[*c]),
                "a payload's centre of mass without its mass (`payload_mass` is empty)",
            ));
        }
        return Ok(None);
    }
    let mass = cell(rows, line, m)?;
    if let Some(problem) = Payload::mass_problem(mass) {
        return Err(Error::input(
            Location::file(&rows.file)
                .at_line(line as usize)
                .with_field("payload_mass"),
            problem,
        ));
    }
    let mut com = nalgebra::Vector3::zeros();
    for (k, c) in cols[1..].iter().enumerate() {
        if let Some(c) = c {
            if !rows.field(*c).trim().is_empty() {
                com[k] = units.to_si(Quantity::Length, cell(rows, line, *c)?);
            }
        }
    }
    Ok(Some(Payload { mass, com }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A program saved as UTF-16 (a text editor's "Unicode") is refused in words, at its line,
    /// with the remedy (before: the CSV parser's `invalid utf-8: ... record 0 (line 1, field: 0,
    /// byte: 0)`); so is a file whose later line is not UTF-8.
    #[test]
    fn text_that_is_not_utf8_is_refused_in_words() {
        let dir = tempfile::tempdir().unwrap();
        let utf16: Vec<u8> = "posture,v1\n1,0\n"
            .encode_utf16()
            .flat_map(u16::to_le_bytes)
            .collect();
        let p = dir.path().join("u16.csv");
        std::fs::write(&p, [&[0xff, 0xfe][..], &utf16].concat()).unwrap();
        let e = Rows::open(&p).err().expect("refused").to_string();
        assert!(
            e.ends_with("u16.csv:1: not UTF-8 text; save the file as UTF-8"),
            "{e}"
        );
        let p = dir.path().join("late.csv");
        std::fs::write(&p, b"posture,v1\n1,0\n2,\xe9\n").unwrap();
        let mut rows = Rows::open(&p).unwrap();
        assert!(rows.advance().unwrap().is_some());
        let e = rows.advance().expect_err("refused").to_string();
        assert!(
            e.ends_with("late.csv:3: not UTF-8 text; save the file as UTF-8"),
            "{e}"
        );
    }
}
