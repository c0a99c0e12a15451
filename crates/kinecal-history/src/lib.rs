//! # kinecal-history: every calibration of every robot, and drift of what the data determines
//!
//! The thesis's purpose (sections 1.1-1.3, 5.3) is predictive maintenance: calibrate a robot at
//! regular intervals, keep the optimal parameters, and flag the physical quantities that change
//! more than expected. The trap it documents (Table 4.8) is that redundant parameters wander
//! from run to run with no physical change; so this crate tracks only *determined* quantities:
//! individually determined parameters and the combinations of identically redundant groups.
//!
//! One history, two back ends behind the [`Store`] trait, chosen by the [`Location`] given to
//! [`Database::open`] (or [`Database::open_read_only`]): a SQLite file (bundled, nothing to
//! install; the default, for one engineer and one cell) or a PostgreSQL server
//! (`postgres://...`, for a fleet: many writers on many machines, roles, backups; built with the
//! `postgres` cargo feature, on by default). On both: a versioned schema migrated on open (a
//! newer one refused with the version it needs), every write in one transaction, an
//! idempotency key per calibration so that a retried write never records it twice
//! ([`idempotency_key`]), maintenance events ([`Event`]) that split a robot's history into
//! segments, and a lossless [`Dump`] that moves a history between back ends. SQLite uses the
//! WAL journal and a busy timeout, so that concurrent writers wait for each other instead of
//! failing.
//!
//! Nothing is written to a file until it is known to be a kinecal history: an existing file is
//! first opened read-only and inspected (schema version, tables and columns); a database from a
//! newer kinecal and a file that is not a kinecal database are refused and never written to.
//! A write costs what its rows cost, not what the file holds: a small file (up to 4 MiB) is
//! checked whole (`PRAGMA quick_check`) when opened for writing and refused when it fails; in a
//! larger one every page a write reads is checked as it is read, and a damaged one refuses the
//! write. [`Database::check`] checks a whole history on demand. Readers ([`Database::open_read_only`]) never
//! create a file and work on read-only files and folders; a record with a damaged field is
//! reported by id ([`Records::damaged`]) while the others are served.
//!
//! A history is one robot model: a record whose model (joints, joint kinds, parameter names)
//! differs from the robot's earlier records is refused unless forced ([`AddOptions`]). Its unit
//! system may change: [`drift()`] converts every value to the units of the robot's first record.
//!
//! ## Layout
//!
//! The data flows from the model to the stores and back to the analyses; each module uses only
//! those above it in this list:
//!
//! - `error`: [`Error`], naming the database and what was or was not written.
//! - `text`, `timefmt`, `units`: printable text, RFC 3339 times, unit labels.
//! - `model`: the records every store reads and writes ([`Calibration`], [`StoredRecord`],
//!   [`Event`], [`Records`], [`Dump`], ...), knowing nothing of any store.
//! - `record`: a calibration report made into a stored record (its [`idempotency_key`]), and a
//!   stored record read back as a [`Calibration`].
//! - `robot_model`: the check that a history is one robot model, run by every store.
//! - `store`: the [`Store`] trait every back end implements, and the [`SCHEMA_VERSION`] they
//!   share.
//! - `sqlite` and `postgres`: the two stores (the second with the `postgres` feature only); each
//!   depends on the model and the store trait, never on the other.
//! - `location`: where a history is ([`Location`]: a file or a server URL; the
//!   [`default_db_path`]).
//! - `database`: [`Database`], the handle front ends use: the one way to open a location, and
//!   what is the same on every back end (validation, keys, dumps and imports).
//! - `drift` and `fleet`: the analyses of what was read: [`drift()`] of a robot's determined
//!   quantities, the state of a whole [`fleet()`].
//! - [`jobs`]: the history jobs of the library's door (`kinecal::spec::history`) run: the
//!   [`Historian`](jobs::Historian) front ends hand to `kinecal::spec::run`, and the typed
//!   [`Document`](jobs::Document) of each job.

mod database;
mod drift;
mod error;
mod fleet;
pub mod jobs;
mod location;
mod model;
#[cfg(feature = "postgres")]
mod postgres;
mod record;
mod robot_model;
mod sqlite;
mod store;
mod text;
mod timefmt;
mod units;

pub use database::{check_dump, Database};
pub use drift::{
    all_samples, drift, samples, Baseline, DriftOptions, DriftReport, LeftOut, Quantity, Sample,
    Tolerances, UnusedTolerance,
};
pub use error::{Error, Result};
pub use fleet::{
    current_segment, fleet, segment_of, FleetOptions, RobotState, Segment, Trend, Verdict,
};
pub use kinecal::source::fingerprint;
pub use location::{default_db_path, Location};
pub use model::{
    AddOptions, Added, Calibration, Combination, DamagedRecord, Dump, Event, ImportSummary,
    Parameter, Records, RmsError, StoredCombination, StoredParameter, StoredRecord, DUMP_FORMAT,
};
pub use record::idempotency_key;
pub use robot_model::ModelChange;
pub use store::{Backend, Store, Write, SCHEMA_VERSION};
pub use text::printable;
pub use timefmt::{format_time, parse_time};
