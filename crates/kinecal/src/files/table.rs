//! CSV tables as the observation files use them: a header naming the columns, `#` comment lines
//! anywhere (also before the header), blank lines ignored, fields trimmed, and the delimiter
//! (`,`, `;` or tab, as tracker software exports) detected from the header line. In a `;` or
//! tab separated file a number may be written with a decimal comma (`12,5`, as spreadsheets in
//! many locales write it); a delimiter ending every data row but not the header is ignored.

use std::borrow::Cow;
use std::hash::BuildHasher;

use hashbrown::HashTable;
use rustc_hash::FxBuildHasher;

use crate::error::{Error, Location, Result};
use crate::observe::Posture;

/// A parsed CSV table with the line of every row.
///
/// A field is a span of a text: the file's own text when it is [`plain`] (nothing copied), else
/// one buffer of the fields the `csv` reader unquoted. No allocation per field or row: reading
/// stays a few hundred nanoseconds per row.
pub(crate) struct Table<'a> {
    pub file: String,
    pub header: Vec<String>,
    /// The header's line.
    pub(crate) header_line: usize,
    /// The text the fields are spans of.
    text: Cow<'a, str>,
    /// Each field's byte range in `text`, trimmed, row after row.
    spans: Vec<(u32, u32)>,
    /// Per row: its line and the index of its first field in `spans`; the row's last field is
    /// before the next row's first.
    starts: Vec<(usize, usize)>,
    /// The delimiter.
    pub delimiter: u8,
}

/// One row of a [`Table`]: `row[i]` is field `i`, trimmed.
#[derive(Clone, Copy)]
pub(crate) struct Fields<'t> {
    text: &'t str,
    /// The byte ranges of this row's fields in `text`.
    spans: &'t [(u32, u32)],
}

impl<'t> Fields<'t> {
    /// The number of fields.
    pub fn len(&self) -> usize {
        self.spans.len()
    }

    /// Field `i`.
    pub fn get(&self, i: usize) -> &'t str {
        let (a, b) = self.spans[i];
        &self.text[a as usize..b as usize]
    }
}

impl std::ops::Index<usize> for Fields<'_> {
    type Output = str;
    fn index(&self, i: usize) -> &str {
        self.get(i)
    }
}

/// Whether `line` is a comment: its first character other than blanks and a byte order mark
/// (a spreadsheet's "CSV UTF-8" starts the file with one) is `#`.
pub(crate) fn is_comment(line: &str) -> bool {
    line.trim_start_matches(|c: char| c == '\u{feff}' || c.is_whitespace())
        .starts_with('#')
}

/// The delimiter of a table: the most frequent of `,`, `;` and tab in its first line that is not
/// blank or a comment (`,` when none occurs).
pub(crate) fn detect_delimiter(text: &str) -> u8 {
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !is_comment(l))
        .unwrap_or("");
    let count = |c: char| first.matches(c).count();
    let (comma, semi, tab) = (count(','), count(';'), count('\t'));
    if semi > comma && semi >= tab {
        b';'
    } else if tab > comma && tab > semi {
        b'\t'
    } else {
        b','
    }
}

/// What a header that lacks kinecal's columns most likely is, as a sentence to add to the error
/// (empty when nothing is recognised): Excel's `sep=` line, a robot file given as data, or joint
/// columns named `j1`, `q1`, `joint1`, `a1`, `axis1` or `theta1` instead of `v1`.
pub(crate) fn header_hint(header: &[impl AsRef<str>]) -> &'static str {
    let first = header.first().map_or("", |h| h.as_ref().trim());
    if first.to_ascii_lowercase().starts_with("sep=") {
        return "; the first line is Excel's `sep=` line (a separator hint): delete it, kinecal \
                finds `,`, `;` or tab itself";
    }
    if first.starts_with('[') || first.contains('=') {
        return "; this looks like a robot file (TOML), not a data file: give it as --robot \
                (robot in a spec)";
    }
    let joint_like = |h: &str| {
        let h = h.trim().to_ascii_lowercase();
        let digits = h.trim_start_matches(|c: char| !c.is_ascii_digit());
        let stem = h[..h.len() - digits.len()].trim_end_matches('_');
        !digits.is_empty()
            && digits.chars().all(|c| c.is_ascii_digit())
            && ["j", "q", "joint", "a", "axis", "theta"].contains(&stem)
    };
    if header.iter().any(|h| joint_like(h.as_ref())) {
        return "; the joint columns are v1..vn or the robot's joint names: rename yours, or map \
                them with --columns v1=j1,v2=j2,... where a command takes it (columns in a spec)";
    }
    ""
}

/// Reads a table. Rows may have any number of fields: check the header first, then
/// [`Table::check_rows`].
///
/// A text without quotes, byte order mark or lone carriage return (what tracker software and
/// `csv.writer` write) is split at its line ends and delimiters directly; any other goes through
/// the `csv` crate's reader. Both give the same table (a test compares them on random texts).
pub(crate) fn read<'a>(text: &'a str, file: &str) -> Result<Table<'a>> {
    if u32::try_from(text.len()).is_err() {
        return Err(Error::input(
            Location::file(file),
            "the file is larger than 4 GiB: split it into several files",
        ));
    }
    if plain(text) {
        read_plain(text, file)
    } else {
        read_quoted(text, file)
    }
}

/// Whether `text` can be split without a CSV parser: no quote character (so no delimiter or line
/// end inside a field), no byte order mark, and every carriage return the first half of a CRLF.
fn plain(text: &str) -> bool {
    let b = text.as_bytes();
    !b.starts_with("\u{feff}".as_bytes())
        && memchr::memchr(b'"', b).is_none()
        && memchr::memchr_iter(b'\r', b).all(|i| b.get(i + 1) == Some(&b'\n'))
}

/// [`read`] of a [`plain`] text: a record per line; comment lines, empty lines and rows whose
/// fields are all blank skipped; the first record the header.
///
/// One scan finds every delimiter and line end of the text (SIMD, in large strides), rather than
/// a search per line and then per field: a file's fields are a few bytes apart, and most of a
/// short search is its start.
fn read_plain<'a>(text: &'a str, file: &str) -> Result<Table<'a>> {
    let loc = Location::file(file);
    let delimiter = detect_delimiter(text);
    let bytes = text.as_bytes();
    let mut header: Option<(Vec<String>, usize)> = None;
    let mut spans: Vec<(u32, u32)> = Vec::new();
    let mut starts = Vec::new();
    // The current line's start and number, its first field's index in `spans`, and where its
    // next field starts.
    let (mut line_start, mut number, mut first, mut field_start) = (0, 1, 0, 0);
    let ends = memchr::memchr2_iter(delimiter, b'\n', bytes).chain(std::iter::once(bytes.len()));
    for end in ends {
        let line_end = end == bytes.len() || bytes[end] == b'\n';
        // A line's carriage return (the first half of a CRLF: `plain`) is not in its last field.
        let field_end = if line_end && end > field_start && bytes[end - 1] == b'\r' {
            end - 1
        } else {
            end
        };
        // Within 4 GiB (checked by `read`).
        spans.push(trimmed(bytes, field_start, field_end));
        field_start = end + 1;
        if !line_end {
            continue;
        }
        let line = &text[line_start..field_end];
        let this = number;
        line_start = end + 1;
        number += 1;
        // Empty lines are no record; comment lines are skipped wherever they are.
        if line.is_empty() || is_comment(line) {
            spans.truncate(first);
            continue;
        }
        let Some((h, _)) = &header else {
            let names: Vec<String> = spans[first..]
                .iter()
                .map(|&(a, b)| text[a as usize..b as usize].to_string())
                .collect();
            spans.truncate(first);
            check_header(&names, this, &loc)?;
            // Room for every row with as many fields as the header, and a trailing delimiter.
            let rest = text.get(line_start..).unwrap_or_default();
            let lines = memchr::memchr_iter(b'\n', rest.as_bytes()).count() + 1;
            spans.reserve(lines * (names.len() + 1));
            starts.reserve(lines);
            header = Some((names, this));
            continue;
        };
        if spans[first..].iter().all(|&(a, b)| a == b) {
            // A row of blank fields is no row.
            spans.truncate(first);
            continue;
        }
        // A trailing delimiter on a data row (some exporters end every row with one): its empty
        // last field is dropped.
        if spans.len() - first == h.len() + 1 && spans.last().is_some_and(|&(a, b)| a == b) {
            spans.pop();
        }
        starts.push((this, first));
        first = spans.len();
    }
    // No header at all: refused as a header of no name.
    let (header, header_line) = match header {
        Some(h) => h,
        None => check_header(&[], 1, &loc).map(|()| (Vec::new(), 1))?,
    };
    Ok(Table {
        file: file.to_string(),
        header,
        header_line,
        text: Cow::Borrowed(text),
        spans,
        starts,
        delimiter,
    })
}

/// The byte range `a..b` of `bytes` trimmed of ASCII white space, as `u32`s.
fn trimmed(bytes: &[u8], mut a: usize, mut b: usize) -> (u32, u32) {
    while a < b && bytes[a].is_ascii_whitespace() {
        a += 1;
    }
    while b > a && bytes[b - 1].is_ascii_whitespace() {
        b -= 1;
    }
    (a as u32, b as u32)
}

/// A header must name a column, and no column twice.
fn check_header(header: &[String], line: usize, loc: &Location) -> Result<()> {
    if header.iter().all(String::is_empty) {
        return Err(Error::input(
            loc.at_line(1),
            "empty file: a header line is required",
        ));
    }
    if let Some(dup) = header
        .iter()
        .enumerate()
        .find(|(i, h)| !h.is_empty() && header[..*i].contains(h))
    {
        return Err(Error::input(
            loc.at_line(line).with_field(dup.1.clone()),
            format!("column `{}` appears twice in the header", dup.1),
        ));
    }
    Ok(())
}

/// [`read`] through the `csv` crate's reader (quoted fields, a byte order mark, lone carriage
/// returns).
fn read_quoted<'a>(text: &str, file: &str) -> Result<Table<'a>> {
    // Comment lines become blank lines, which the reader skips but counts (its own comment
    // handling does not count them, and line numbers after a comment would be off).
    let uncommented: String;
    let text = if text.contains('#') {
        uncommented = text
            .split('\n')
            .map(|l| if is_comment(l) { "" } else { l })
            .collect::<Vec<_>>()
            .join("\n");
        &uncommented
    } else {
        text
    };
    let delimiter = detect_delimiter(text);
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .delimiter(delimiter)
        .from_reader(text.as_bytes());
    let loc = Location::file(file);
    // The reader's positions point just after the previous record, before any blank lines:
    // the real line is the first non-blank one from there. Lines are counted incrementally
    // (records come in order), so reading stays linear in the file's length.
    let counted = std::cell::Cell::new((0usize, 1usize)); // (byte, line number at that byte)
    let line_at = |p: &csv::Position| -> usize {
        let start = (p.byte() as usize).min(text.len());
        let skip = text.as_bytes()[start..]
            .iter()
            .take_while(|b| b.is_ascii_whitespace())
            .count();
        let target = start + skip;
        let (mut at, mut line) = counted.get();
        if target < at {
            (at, line) = (0, 1);
        }
        line += text.as_bytes()[at..target]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        counted.set((target, line));
        line
    };
    let csv_err = |e: csv::Error| {
        let at = match e.position() {
            Some(p) => loc.at_line(line_at(p)),
            None => loc.clone(),
        };
        let what = match e.kind() {
            csv::ErrorKind::Utf8 { .. } => "the file is not UTF-8 text".to_string(),
            _ => format!("invalid CSV: {e}"),
        };
        Error::input(at, what)
    };
    let header: Vec<String> = rdr
        .headers()
        .map_err(csv_err)?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    let header_line = rdr
        .headers()
        .ok()
        .and_then(|h| h.position().map(line_at))
        .unwrap_or(1);
    check_header(&header, header_line, &loc)?;
    let header_fields = header.len();
    let mut fields: Vec<u8> = Vec::with_capacity(text.len());
    let mut spans = Vec::new();
    let mut starts = Vec::new();
    let mut rec = csv::ByteRecord::new();
    loop {
        match rdr.read_byte_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_err(e)),
        }
        let line = rec.position().map_or(0, line_at);
        if rec.iter().all(|f| f.trim_ascii().is_empty()) {
            continue;
        }
        let mut count = rec.len();
        // A trailing delimiter on a data row (some exporters end every row with one).
        if count == header_fields + 1
            && rec
                .get(count - 1)
                .is_some_and(|f| f.trim_ascii().is_empty())
        {
            count -= 1;
        }
        starts.push((line, spans.len()));
        for f in rec.iter().take(count) {
            let a = fields.len() as u32;
            fields.extend_from_slice(f.trim_ascii());
            // The unquoted fields are no longer than the text: within 4 GiB (checked).
            spans.push((a, fields.len() as u32));
        }
    }
    // The text is UTF-8 and fields are cut at ASCII bytes (delimiters, quotes, white space):
    // the fields are UTF-8, and every end is a character boundary.
    let text = String::from_utf8(fields)
        .map_err(|_| Error::input(loc.clone(), "the file is not UTF-8 text"))?;
    Ok(Table {
        file: file.to_string(),
        header,
        header_line,
        text: Cow::Owned(text),
        spans,
        starts,
        delimiter,
    })
}

impl Table<'_> {
    /// The rows: their line and fields.
    pub fn rows(&self) -> impl Iterator<Item = (usize, Fields<'_>)> + '_ {
        (0..self.starts.len()).map(|r| self.row(r))
    }

    /// Row `r`: its line and fields.
    pub fn row(&self, r: usize) -> (usize, Fields<'_>) {
        let (line, first) = self.starts[r];
        let end = self.starts.get(r + 1).map_or(self.spans.len(), |s| s.1);
        (
            line,
            Fields {
                text: &self.text,
                spans: &self.spans[first..end],
            },
        )
    }

    /// The number of rows.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.starts.len()
    }

    /// Every row must have as many fields as the header.
    pub(crate) fn check_rows(&self) -> Result<()> {
        for (line, f) in self.rows() {
            if f.len() != self.header.len() {
                return Err(Error::input(
                    Location::file(&self.file).at_line(line),
                    format!(
                        "expected {} fields ({}), found {}",
                        self.header.len(),
                        self.header.join(","),
                        f.len()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The index of the column called `name` (ASCII case-insensitive).
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
    }

    /// Refuses a column of the header that is not among `known` (ASCII case-insensitive): the
    /// error names the `expected` header.
    pub(crate) fn refuse_unknown(&self, known: &[String], expected: &str) -> Result<()> {
        match self
            .header
            .iter()
            .find(|h| !known.iter().any(|k| k.eq_ignore_ascii_case(h)))
        {
            Some(h) => Err(Error::input(
                self.header_at().with_field(h.clone()),
                format!("unknown column `{h}`: expected {expected}"),
            )),
            None => Ok(()),
        }
    }

    /// The index of the required column `name` (ASCII case-insensitive); an error naming the
    /// `expected` header when there is none.
    pub(crate) fn require(&self, name: &str, expected: &str) -> Result<usize> {
        self.column(name).ok_or_else(|| {
            Error::input(
                self.header_at().with_field(name),
                format!(
                    "no column `{name}` in the header: expected {expected}{}",
                    header_hint(&self.header)
                ),
            )
        })
    }

    /// The location of `field` on `line`.
    pub fn at(&self, line: usize, field: &str) -> Location {
        Location::file(&self.file).at_line(line).with_field(field)
    }

    /// The header's location.
    pub(crate) fn header_at(&self) -> Location {
        Location::file(&self.file).at_line(self.header_line)
    }

    /// Parses a finite number.
    pub fn number(&self, line: usize, field: &str, s: &str) -> Result<f64> {
        let decimal_comma = self.delimiter != b','
            && s.matches(',').count() == 1
            && !s.contains('.')
            && s.replace(',', ".").parse::<f64>().is_ok();
        let parsed = if decimal_comma {
            s.replace(',', ".").parse::<f64>()
        } else {
            s.parse::<f64>()
        };
        let v: f64 = parsed.map_err(|_| {
            let hint = if s.contains(',') && s.replace(',', ".").parse::<f64>().is_ok() {
                " (a decimal comma? write decimal points)"
            } else {
                ""
            };
            Error::input(
                self.at(line, field),
                format!("expected a number, found `{s}`{hint}"),
            )
        })?;
        if !crate::units::plausible(v) {
            return Err(Error::input(
                self.at(line, field),
                format!("expected a finite number within +-1e9, found `{s}`"),
            ));
        }
        Ok(v)
    }

    /// Parses an optional standard deviation: empty is `None`; otherwise a positive number, at
    /// least [`crate::units::MIN_SIGMA`].
    pub fn sigma(&self, line: usize, field: &str, s: &str) -> Result<Option<f64>> {
        if s.is_empty() {
            return Ok(None);
        }
        let v = self.number(line, field, s)?;
        if let Some(why) = crate::units::sigma_problem(v) {
            return Err(Error::input(self.at(line, field), why));
        }
        Ok(Some(v))
    }

    /// Parses an optional length standard deviation (`sigma_position`) in the file's length
    /// unit of `units`, as [`Table::sigma`] does, and converts it to metres: `None` when the
    /// file has no such column (`s` is `None`) or the field is empty.
    pub fn sigma_length(
        &self,
        line: usize,
        s: Option<&str>,
        units: crate::units::Units,
    ) -> Result<Option<f64>> {
        match s {
            Some(s) => Ok(self
                .sigma(line, "sigma_position", s)?
                .map(|s| units.to_si(crate::units::Quantity::Length, s))),
            None => Ok(None),
        }
    }
}

/// Keeps postures unique by label and checks that repeated labels carry the same readings.
pub(crate) struct PostureTable {
    pub postures: Vec<Posture>,
    /// The index of each posture, by the hash of its label (a fast hash: labels come from the
    /// user's own files); the labels themselves are the postures' (not copied).
    index: HashTable<usize>,
    hasher: FxBuildHasher,
}

impl PostureTable {
    pub fn new() -> Self {
        PostureTable::with_capacity(0)
    }

    /// An empty table with room for `n` postures.
    pub fn with_capacity(n: usize) -> Self {
        PostureTable {
            postures: Vec::with_capacity(n),
            index: HashTable::with_capacity(n),
            hasher: FxBuildHasher,
        }
    }

    /// The data set of an observation file: these postures and the file's `observations`,
    /// refused when the file had no rows (`what` names them, as in `no contacts: the file has a
    /// header but no rows`).
    ///
    /// A row's own standard deviation more than [`SIGMA_SPREAD`] times below the median of
    /// its quantity's in the file is refused ([`sigma_spread_problem`]; `units`: the file's).
    pub fn into_dataset(
        self,
        observations: Vec<crate::observe::Observation>,
        file: &str,
        what: &str,
        units: &crate::units::Units,
    ) -> Result<crate::observe::Dataset> {
        if observations.is_empty() {
            return Err(Error::input(
                Location::file(file),
                format!("no {what}: the file has a header but no rows"),
            ));
        }
        sigma_spread_problem(&observations, file, units)?;
        Ok(crate::observe::Dataset::new(self.postures, observations))
    }

    /// The index of the posture called `label`, if there is one.
    fn find(&self, label: &str) -> Option<usize> {
        let postures = &self.postures;
        self.index
            .find(self.hasher.hash_one(label), |&i| postures[i].label == label)
            .copied()
    }

    /// Whether a posture called `label` exists.
    pub fn contains(&self, label: &str) -> bool {
        self.find(label).is_some()
    }

    /// The index of posture `label`, added with `readings` if new; an error at `line` if it
    /// exists with other readings (`field_of(j)` names reading column j).
    pub fn get_or_insert(
        &mut self,
        table: &Table<'_>,
        line: usize,
        label: &str,
        readings: Vec<f64>,
        field_of: &dyn Fn(usize) -> String,
    ) -> Result<usize> {
        if label.is_empty() {
            return Err(Error::input(
                table.at(line, "posture"),
                "empty posture label",
            ));
        }
        if let Some(i) = self.find(label) {
            let known = &self.postures[i].readings;
            if let Some(j) = (0..known.len())
                .find(|&j| (known[j] - readings[j]).abs() > 1e-9 * known[j].abs().max(1.0))
            {
                return Err(Error::input(
                    table.at(line, &field_of(j)),
                    format!(
                        "posture `{label}` appears earlier with reading {} here {}: rows of one \
                         posture must share the same readings",
                        known[j], readings[j]
                    ),
                ));
            }
            return Ok(i);
        }
        let (postures, hasher) = (&self.postures, &self.hasher);
        self.index
            .insert_unique(hasher.hash_one(label), postures.len(), |&i| {
                hasher.hash_one(postures[i].label.as_str())
            });
        self.postures.push(Posture {
            label: label.to_string(),
            readings,
            session: None,
            payload: None,
        });
        Ok(self.postures.len() - 1)
    }
}

/// How far below the median of its quantity's (lengths, angles) in its file a row's own
/// standard deviation may lie: 10^6. A row stated that much more precise than its file's
/// typical row carries 10^12 times its weight in the fit: it alone places the robot, and the
/// rest of the file is bent to it (a row of 1e-15 mm among rows of 0.01 mm left the attitudes
/// ten times worse than the nominal robot's). Anchors that are meant to weigh more (a reference
/// point measured 10^3 times more precisely, see [`crate::solve::estimation::weighting`]) stay
/// three orders of magnitude inside the bound.
pub const SIGMA_SPREAD: f64 = 1e6;

/// Refuses a row whose own standard deviation is more than [`SIGMA_SPREAD`] times below the
/// median (the upper one, for an even count) of the standard deviations its file states for
/// the same quantity (lengths, angles, pixels), naming the file, the line and the column: a typing or
/// unit slip, not a measurement (the fit would follow that row alone). Refused rather than
/// raised: raising it would change what the file says of its instrument by a factor kinecal
/// chose, and the user who fixes the line knows the right value.
pub(crate) fn sigma_spread_problem(
    observations: &[crate::observe::Observation],
    file: &str,
    units: &crate::units::Units,
) -> Result<()> {
    sigma_spread_across(&[FileRows {
        file,
        observations,
        units: *units,
    }])
}

/// One observation file's rows, as the check of the standard deviations' spread sees them.
pub(crate) struct FileRows<'a> {
    /// The file's name, as errors give it.
    pub file: &'a str,
    /// Its observations (`line()`: their line in it).
    pub observations: &'a [crate::observe::Observation],
    /// The units its numbers are in (an error quotes its values in them).
    pub units: crate::units::Units,
}

/// [`sigma_spread_problem`] over the files of one run together (measurements, contacts,
/// distances, pixels: every file fitted at once), per quantity: the median is of every file's
/// standard deviations of that quantity, so that a file of one row stated 10^12 times more
/// precisely than the others' is refused as a row of one file is.
pub(crate) fn sigma_spread_across(files: &[FileRows<'_>]) -> Result<()> {
    use crate::observe::RowQuantity;
    let stated = |o: &crate::observe::Observation, quantity: RowQuantity| -> Vec<(usize, f64)> {
        o.rows()
            .iter()
            .enumerate()
            .filter(|(_, r)| r.quantity == quantity)
            .filter_map(|(k, _)| o.sigma(k).map(|s| (k, s)))
            .collect()
    };
    for quantity in [RowQuantity::Length, RowQuantity::Angle, RowQuantity::Pixel] {
        let mut sigmas: Vec<f64> = files
            .iter()
            .flat_map(|f| f.observations.iter())
            .flat_map(|o| stated(o, quantity).into_iter().map(|(_, s)| s))
            .collect();
        if sigmas.len() < 2 {
            continue;
        }
        sigmas.sort_by(f64::total_cmp);
        let median = sigmas[sigmas.len() / 2];
        if sigmas[0] * SIGMA_SPREAD >= median {
            continue;
        }
        // The files whose rows of this quantity state a standard deviation.
        let stating: Vec<&str> = files
            .iter()
            .filter(|f| {
                f.observations
                    .iter()
                    .any(|o| !stated(o, quantity).is_empty())
            })
            .map(|f| f.file)
            .collect();
        let whose = match stating.as_slice() {
            [_] => "the file's".to_string(),
            many => format!("the run's files' ({})", many.join(", ")),
        };
        for f in files {
            for o in f.observations {
                let Some((k, sigma)) = stated(o, quantity)
                    .into_iter()
                    .find(|&(_, s)| s * SIGMA_SPREAD < median)
                else {
                    continue;
                };
                return Err(spread_error(f, o, k, sigma, median, &whose));
            }
        }
    }
    Ok(())
}

/// The refusal of row `k` of `o` in file `f`: its standard deviation `sigma` (SI) more than
/// [`SIGMA_SPREAD`] below `median`, the median of `whose` standard deviations of its quantity.
fn spread_error(
    f: &FileRows<'_>,
    o: &crate::observe::Observation,
    k: usize,
    sigma: f64,
    median: f64,
    whose: &str,
) -> Error {
    use crate::observe::RowQuantity;
    use crate::units::Quantity;
    let rows = o.rows();
    let row = &rows[k];
    let quantity = row.quantity;
    let q = match quantity {
        RowQuantity::Length => Quantity::Length,
        RowQuantity::Angle => Quantity::Angle,
        RowQuantity::Pixel => Quantity::Pixel,
    };
    // The column: sigma_angle; sigma_x..z where a row's axes differ; else sigma_position.
    let axes: Vec<f64> = (0..rows.len())
        .filter(|&i| rows[i].quantity == RowQuantity::Length)
        .filter_map(|i| o.sigma(i))
        .collect();
    let field = match quantity {
        RowQuantity::Angle => "sigma_angle".to_string(),
        RowQuantity::Pixel => "sigma_px".to_string(),
        RowQuantity::Length
            if axes.len() == 3 && axes.iter().any(|a| a.to_bits() != axes[0].to_bits()) =>
        {
            format!("sigma_{}", row.label)
        }
        RowQuantity::Length => "sigma_position".to_string(),
    };
    let units = &f.units;
    let unit = units.label(q);
    Error::input(
        Location::file(f.file).at_line(o.line()).with_field(field),
        format!(
            "a standard deviation of {} {unit} is {:.1e} times the median of {whose} {} ({} \
             {unit}): expected at most {SIGMA_SPREAD:.0e} times below it (such a row outweighs \
             the rest 10^12 to 1: a slip of the pen or of the unit); correct the value or leave \
             the field empty",
            crate::units::number::format_number(units.from_si(q, sigma)),
            sigma / median,
            match quantity {
                RowQuantity::Length => "length standard deviations",
                RowQuantity::Angle => "angle standard deviations",
                RowQuantity::Pixel => "pixel standard deviations",
            },
            crate::units::number::format_number(units.from_si(q, median)),
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fields<'t>(t: &'t Table<'_>, r: usize) -> Vec<&'t str> {
        let f = t.row(r).1;
        (0..f.len()).map(|i| f.get(i)).collect()
    }

    #[test]
    fn delimiters_comments_and_lines() {
        for (d, text) in [
            (b',', "# exported\n\na,b\n1,2\n# note\n3,4\n"),
            (b';', "a;b\n1;2\n3;4\n"),
            (b'\t', "a\tb\n1\t2\n3\t4\n"),
        ] {
            assert_eq!(detect_delimiter(text), d);
            let t = read(text, "t.csv").unwrap();
            assert_eq!(t.header, vec!["a", "b"]);
            assert_eq!(t.len(), 2);
            assert_eq!(fields(&t, 1), vec!["3", "4"]);
        }
        let t = read("# exported\n\na,b\n1,2\n# note\n\n3,4\n", "t.csv").unwrap();
        assert_eq!(t.header_line, 3);
        assert_eq!(t.row(0).0, 4);
        assert_eq!(t.row(1).0, 7);
        let e = read("a,b\n1,2,3\n", "t.csv")
            .unwrap()
            .check_rows()
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.csv:2:"), "{e}");
        let e = read("a,a\n1,2\n", "t.csv").err().unwrap().to_string();
        assert!(e.contains("twice"), "{e}");
        // A decimal comma is read where the delimiter is not a comma; quoted in a comma
        // separated file, it gets a hint.
        let t = read("a;b\n1,5;2\n", "t.csv").unwrap();
        assert!((t.number(2, "a", "1,5").unwrap() - 1.5).abs() < 1e-15);
        let t = read("a,b\n\"1,5\",2\n", "t.csv").unwrap();
        let e = t.number(2, "a", &t.row(0).1[0]).unwrap_err().to_string();
        assert!(e.contains("decimal comma"), "{e}");
        // A trailing delimiter on data rows only.
        let t = read("a,b\n1,2,\n", "t.csv").unwrap();
        t.check_rows().unwrap();
        assert_eq!(fields(&t, 0), vec!["1", "2"]);
    }

    /// Everything a table says: header, its line, and each row's line and fields.
    type Seen = (Vec<String>, usize, Vec<(usize, Vec<String>)>);

    fn seen(t: Result<Table<'_>>) -> std::result::Result<Seen, String> {
        let t = t.map_err(|e| e.to_string())?;
        let rows = (0..t.starts.len())
            .map(|r| {
                let (line, f) = t.row(r);
                (line, (0..f.len()).map(|i| f.get(i).to_string()).collect())
            })
            .collect();
        Ok((t.header.clone(), t.header_line, rows))
    }

    /// The direct split of plain texts and the `csv` crate's reader give the same table (or the
    /// same error) on random texts over an alphabet that makes every case: delimiters of all
    /// three kinds, blank and white-space-only lines, CRLF, comment lines, trailing
    /// delimiters, repeated header names.
    #[test]
    fn plain_split_matches_the_csv_reader() {
        use rand::{RngExt, SeedableRng};
        let alphabet = [
            "a", "b", "1", "2.5", "-3", ",", ",", ";", "\t", " ", "\n", "\n", "\r\n", "#", "x y",
            "é",
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut plain_texts = 0;
        for _ in 0..20_000 {
            let len = rng.random_range(0..40);
            let text: String = (0..len)
                .map(|_| alphabet[rng.random_range(0..alphabet.len())])
                .collect();
            if !plain(&text) {
                continue;
            }
            plain_texts += 1;
            assert_eq!(
                seen(read_plain(&text, "t.csv")),
                seen(read_quoted(&text, "t.csv")),
                "{text:?}"
            );
        }
        assert!(plain_texts > 10_000, "{plain_texts}");
        // What is not plain.
        assert!(!plain("a,b\n\"1\",2\n"));
        assert!(!plain("\u{feff}a,b\n1,2\n"));
        assert!(!plain("a,b\r1,2\r"));
        assert!(plain("a,b\r\n1,2\r\n"));
    }

    /// A byte order mark before a comment line (a spreadsheet's "CSV UTF-8" of a file that
    /// starts with one, as kinecal's logs, plans and tables do) leaves it a comment: the header
    /// is the next line, the delimiter and format are told from it, and the line numbers count
    /// the comment (before, the comment was read as the header).
    #[test]
    fn a_comment_behind_a_byte_order_mark_is_a_comment() {
        let text = "\u{feff}# measured 2026\nposture;v1;v2\n# a note\n7;1,5;2\n";
        assert!(is_comment("\u{feff}# x") && is_comment("  # x") && !is_comment("\u{feff}a,#"));
        assert_eq!(detect_delimiter(text), b';');
        let (header, line, rows) = seen(read(text, "t.csv")).unwrap();
        assert_eq!(header, ["posture", "v1", "v2"]);
        assert_eq!(line, 2);
        assert_eq!(rows, [(4, vec!["7".into(), "1,5".into(), "2".into()])]);
        let text = "\u{feff}# contacts\nposture;plane;v1;v2\n";
        assert_eq!(
            crate::files::FORMATS[crate::files::detect_format(text)].option,
            "contacts"
        );
    }
}
