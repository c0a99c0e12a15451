//! The PostgreSQL server of the tests: `KINECAL_TEST_PG` (a superuser's URL, e.g. from
//! `scripts/pg-test-server.sh`). Without it the PostgreSQL tests say that they are skipped, unless
//! `CI` is set: then they fail (CI must run them).

#![allow(dead_code)]

use std::sync::atomic::{AtomicUsize, Ordering};

/// The server's URL, or `None` (after saying so) when there is none outside CI.
pub fn server() -> Option<String> {
    match std::env::var("KINECAL_TEST_PG") {
        Ok(url) if !url.is_empty() => Some(url),
        _ => {
            if std::env::var_os("CI").is_some_and(|v| !v.is_empty()) {
                panic!(
                    "CI is set but KINECAL_TEST_PG is not: the PostgreSQL tests must run in CI \
                     (start a server with scripts/pg-test-server.sh)"
                );
            }
            eprintln!(
                "skipped: this PostgreSQL test needs KINECAL_TEST_PG=postgres://... \
                 (eval \"$(bash scripts/pg-test-server.sh start)\" starts a throw-away server)"
            );
            None
        }
    }
}

/// `url` with its database name replaced by `db`.
pub fn with_database(url: &str, db: &str) -> String {
    let (head, query) = match url.split_once('?') {
        Some((h, q)) => (h, format!("?{q}")),
        None => (url, String::new()),
    };
    let scheme_end = head.find("://").map_or(0, |i| i + 3);
    let base = match head[scheme_end..].find('/') {
        Some(i) => &head[..scheme_end + i],
        None => head,
    };
    format!("{base}/{db}{query}")
}

/// `url` with its user and password replaced.
pub fn with_user(url: &str, user: &str, password: &str) -> String {
    let scheme_end = url.find("://").map_or(0, |i| i + 3);
    let rest = &url[scheme_end..];
    let host = rest.rfind('@').map_or(rest, |i| &rest[i + 1..]);
    format!("{}{user}:{password}@{host}", &url[..scheme_end])
}

/// A fresh database on the test server, dropped at the end.
pub struct TestDb {
    /// Its URL (the superuser's).
    pub url: String,
    admin: String,
    name: String,
}

static COUNTER: AtomicUsize = AtomicUsize::new(0);

impl TestDb {
    /// A new, empty database named after `tag`; `None` when there is no server (skipped).
    pub fn new(tag: &str) -> Option<TestDb> {
        let admin = server()?;
        let name = format!(
            "kt_{}_{}_{}",
            tag.chars()
                .filter(|c| c.is_ascii_alphanumeric() || *c == '_')
                .take(30)
                .collect::<String>()
                .to_ascii_lowercase(),
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        );
        let mut c = postgres::Client::connect(&admin, postgres::NoTls).expect("the test server");
        c.batch_execute(&format!("CREATE DATABASE {name}"))
            .expect("create a test database");
        Some(TestDb {
            url: with_database(&admin, &name),
            admin,
            name,
        })
    }

    /// A client of this database, as the superuser.
    pub fn client(&self) -> postgres::Client {
        postgres::Client::connect(&self.url, postgres::NoTls).expect("the test database")
    }

    /// The superuser's URL (any database).
    pub fn admin(&self) -> &str {
        &self.admin
    }
}

impl Drop for TestDb {
    fn drop(&mut self) {
        if let Ok(mut c) = postgres::Client::connect(&self.admin, postgres::NoTls) {
            let _ = c.batch_execute(&format!(
                "DROP DATABASE IF EXISTS {} WITH (FORCE)",
                self.name
            ));
        }
    }
}
