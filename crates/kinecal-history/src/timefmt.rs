//! Timestamps: RFC 3339 in UTC, stored as text and as Unix seconds.

use time::format_description::well_known::Rfc3339;
use time::{Date, OffsetDateTime, PrimitiveDateTime, Time};

use crate::error::{Error, Result};

/// Parses `2026-11-22T08:00:00Z`, `2026-11-22T08:00:00+01:00` or `2026-11-22` (midnight UTC)
/// into Unix seconds.
pub fn parse_time(s: &str) -> Result<i64> {
    if let Ok(t) = OffsetDateTime::parse(s, &Rfc3339) {
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

/// The current time, Unix seconds.
pub(crate) fn now() -> i64 {
    OffsetDateTime::now_utc().unix_timestamp()
}
