//! No code: this crate exists for its `Cargo.toml`, which makes `cargo run -p kinecal-cli` and
//! `cargo test --workspace` resolve the dependencies' features alike (see there).
