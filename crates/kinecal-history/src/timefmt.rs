//! Timestamps: RFC 3339 in UTC, stored as text and as Unix seconds.

use time::format_description::well_known::Rfc3339;
use time::{Date, OffsetDateTime, PrimitiveDateTime, Time};

use crate::error::{Error, Result};

/// Parses `2026-11-22T08:00:00Z`, `2026-11-22T08:00:00+01:00` or `2026-11-22` (midnight UTC)
/// into Unix seconds.
/// A leap second (`23:59:60`) is refused: Unix seconds have none, and it would be stored as
/// the second before it.
pub fn parse_time(s: &str) -> Result<i64> {
    if let Ok(t) = OffsetDateTime::parse(s, &Rfc3339) {
        // The parser reads second 60 as 59.999999999 (RFC 3339 allows it; Unix time cannot
        // hold it): nothing else written as whole seconds ends there.
        if t.nanosecond() == 999_999_999 && s.get(17..19) == Some("60") {
            return Err(Error::Input(format!(
                "time `{s}`: a leap second (second 60) has no Unix time, and the history stores \
                 Unix seconds: give the second before it (:59) or the next minute (:00)"
            )));
        }
        return Ok(t.unix_timestamp());
    }
    let fmt = time::format_description::parse_borrowed::<2>("[year]-[month]-[day]")
        .expect("valid format description");
    if let Ok(d) = Date::parse(s, &fmt) {
        return Ok(PrimitiveDateTime::new(d, Time::MIDNIGHT)
            .assume_utc()
            .unix_timestamp());
    }
    Err(Error::Input(format!(
        "time `{s}`: expected RFC 3339 (2026-11-22T08:00:00Z) or a date (2026-11-22)"
    )))
}

/// Formats Unix seconds as RFC 3339 UTC.
pub fn format_time(unix: i64) -> String {
    OffsetDateTime::from_unix_timestamp(unix)
        .ok()
        .and_then(|t| t.format(&Rfc3339).ok())
        .unwrap_or_else(|| unix.to_string())
}

/// The first and last Unix seconds [`format_time`] writes as RFC 3339: from
/// 0000-01-01T00:00:00Z to 9999-12-31T23:59:59Z (RFC 3339 has four-digit years).
pub(crate) const TIME_RANGE: std::ops::RangeInclusive<i64> = -62_167_219_200..=253_402_300_799;

/// Why `unix` cannot be a time of the history, if it cannot: outside [`TIME_RANGE`] (a time
/// that would be printed as raw seconds, not as a date).
pub(crate) fn time_problem(unix: i64) -> Option<String> {
    (!TIME_RANGE.contains(&unix)).then(|| {
        format!(
            "{unix} Unix seconds is not a time of years 0000 to 9999; expected a time between \
             {} ({}) and {} ({})",
            TIME_RANGE.start(),
            format_time(*TIME_RANGE.start()),
            TIME_RANGE.end(),
            format_time(*TIME_RANGE.end())
        )
    })
}

/// The current time, Unix seconds.
pub(crate) fn now() -> i64 {
    OffsetDateTime::now_utc().unix_timestamp()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_leap_second_is_refused_and_its_neighbours_are_read() {
        let e = parse_time("2016-12-31T23:59:60Z").unwrap_err().to_string();
        assert!(
            e.contains("leap second") && e.contains("2016-12-31T23:59:60Z"),
            "{e}"
        );
        let before = parse_time("2016-12-31T23:59:59Z").unwrap();
        assert_eq!(parse_time("2017-01-01T00:00:00Z").unwrap(), before + 1);
        assert_eq!(format_time(before), "2016-12-31T23:59:59Z");
        // A fraction of a second below 60 is not a leap second.
        assert_eq!(
            parse_time("2016-12-31T23:59:59.999999999Z").unwrap(),
            before
        );
        assert_eq!(
            parse_time("2026-11-22").unwrap(),
            parse_time("2026-11-22T00:00:00Z").unwrap()
        );
    }

    #[test]
    fn the_time_range_is_what_format_time_writes_as_a_date() {
        let (first, last) = (*TIME_RANGE.start(), *TIME_RANGE.end());
        assert_eq!(format_time(first), "0000-01-01T00:00:00Z");
        assert_eq!(format_time(last), "9999-12-31T23:59:59Z");
        assert_eq!(format_time(first - 1), (first - 1).to_string());
        assert_eq!(format_time(last + 1), (last + 1).to_string());
        assert!(time_problem(first).is_none() && time_problem(last).is_none());
        assert!(time_problem(1_000_000_000_000_000).is_some());
        assert!(time_problem(-1_000_000_000_000).is_some());
    }
}
