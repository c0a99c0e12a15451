//! What the integration tests share.

/// The PostgreSQL test server (the store exists with the `postgres` feature only).
#[cfg(feature = "postgres")]
pub mod pg;

/// The GE A4 calibration report the tests store.
pub mod report;
