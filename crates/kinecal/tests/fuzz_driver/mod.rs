//! The mutation driver shared by the fuzz targets of the workspace (see `tests/fuzz.rs`).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The repository's root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Inputs per target: `KINECAL_FUZZ_ITERS`, default 300.
pub fn iterations() -> usize {
    std::env::var("KINECAL_FUZZ_ITERS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300)
}

/// The run's seed: `KINECAL_FUZZ_SEED` (0 to 2^64-1), default 0, the inputs the test suite
/// has always drawn. Another seed draws other mutations: a long run that repeats an earlier
/// one's seed repeats its inputs, so each long run should take a seed of its own.
pub fn run_seed() -> u64 {
    match std::env::var("KINECAL_FUZZ_SEED") {
        Ok(s) => s
            .parse()
            .unwrap_or_else(|_| panic!("KINECAL_FUZZ_SEED={s}: expected an integer 0 to 2^64-1")),
        Err(_) => 0,
    }
}

const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e400",
    "-1e308",
    "1e308",
    "1e9",
    "1e10",
    "0",
    "-0",
    "",
    ",",
    ";",
    "\t",
    "\n",
    "\r\n",
    "\"",
    "'",
    "#",
    "=",
    "[[links]]",
    "[[joints]]",
    "[[sites]]",
    "[[planes]]",
    "[",
    "]",
    "{",
    "}",
    "<",
    ">",
    "</joint>",
    "<joint name=\"j\" type=\"revolute\">",
    "<origin xyz=\"0 0 1e400\"/>",
    "<axis xyz=\"0 nan 0\"/>",
    "<!--",
    "-->",
    "<![CDATA[",
    "\u{0}",
    "\u{feff}",
    "é",
    "99999999999999999999999",
    "0x10",
    "1_000",
    "true",
    "posture",
    "site",
    "ee",
    "v1",
    "sigma_position",
    "coupling = { joint = 2, factor = 1.0 }",
    "length_unit = \"mm\"",
    "angle_unit = \"rad\"",
    "kind = \"prismatic\"",
    "min = 10",
    "max = -10",
];

/// Mutates `seed` with 1 to 4 random operations.
pub fn mutate(rng: &mut ChaCha8Rng, seed: &[u8]) -> Vec<u8> {
    let mut b = seed.to_vec();
    let ops = rng.random_range(1..=4);
    for _ in 0..ops {
        let at = |rng: &mut ChaCha8Rng, b: &[u8]| {
            if b.is_empty() {
                0
            } else {
                rng.random_range(0..=b.len())
            }
        };
        match rng.random_range(0..11) {
            0 if !b.is_empty() => {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random();
            }
            1 => {
                let i = at(rng, &b);
                let t = TOKENS[rng.random_range(0..TOKENS.len())];
                b.splice(i..i, t.bytes());
            }
            2 if !b.is_empty() => {
                let i = rng.random_range(0..b.len());
                let n = rng.random_range(1..=16).min(b.len() - i);
                b.drain(i..i + n);
            }
            3 => {
                // Duplicate a line.
                let lines: Vec<&[u8]> = b.split(|&c| c == b'\n').collect();
                let k = rng.random_range(0..lines.len());
                let line = lines[k].to_vec();
                let i = at(rng, &b);
                let mut ins = line;
                ins.push(b'\n');
                b.splice(i..i, ins);
            }
            4 => {
                let i = at(rng, &b);
                b.truncate(i);
            }
            5 => {
                // A number replaced by a special token.
                let starts: Vec<usize> = (0..b.len())
                    .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit()))
                    .collect();
                if let Some(&i) = starts.get(rng.random_range(0..starts.len().max(1))) {
                    let mut j = i;
                    while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.') {
                        j += 1;
                    }
                    let t = [
                        "nan", "inf", "1e400", "-1e308", "1e300", "", "-", "1e9", "12,5",
                    ][rng.random_range(0..9)];
                    b.splice(i..j, t.bytes());
                }
            }
            6 => {
                let (from, to) = [(b',', b';'), (b',', b'\t'), (b' ', b','), (b'\n', b'\r')]
                    [rng.random_range(0..4)];
                for c in b.iter_mut() {
                    if *c == from {
                        *c = to;
                    }
                }
            }
            7 => {
                let i = at(rng, &b);
                let bad: &[u8] = [&[0xff, 0xfe][..], &[0xc3][..], &[0xef, 0xbb, 0xbf][..]]
                    [rng.random_range(0..3)];
                b.splice(i..i, bad.iter().copied());
            }
            8 if !b.is_empty() => {
                // Repeat a chunk (size blow-up, bounded at 256 KB).
                let i = rng.random_range(0..b.len());
                let n = rng.random_range(1..=64).min(b.len() - i);
                let chunk = b[i..i + n].to_vec();
                let times = rng.random_range(2..200);
                let mut ins = Vec::new();
                for _ in 0..times {
                    ins.extend_from_slice(&chunk);
                }
                if b.len() + ins.len() < 256 * 1024 {
                    b.splice(i..i, ins);
                }
            }
            9 => {
                // Deep nesting.
                let i = at(rng, &b);
                let (open, n) = [("[", 3000), ("{a=", 500), ("<link>", 3000), ("\"", 1)]
                    [rng.random_range(0..4)];
                let ins: Vec<u8> = open.repeat(n).into_bytes();
                b.splice(i..i, ins);
            }
            _ => {
                // Swap two lines.
                let mut lines: Vec<Vec<u8>> =
                    b.split(|&c| c == b'\n').map(<[u8]>::to_vec).collect();
                if lines.len() > 1 {
                    let (i, j) = (
                        rng.random_range(0..lines.len()),
                        rng.random_range(0..lines.len()),
                    );
                    lines.swap(i, j);
                    b = lines.join(&b'\n');
                }
            }
        }
    }
    b
}

/// What a reader made of an input.
#[allow(dead_code)] // each test binary uses its own variants
pub enum Outcome {
    /// Accepted; the check of its result (`Err` says what is wrong).
    Accepted(Result<(), String>),
    /// Refused with this message.
    Refused(String),
}

/// Runs `read` on `inputs` mutated from `seeds` (after the corpus of `target`), checking every
/// outcome; panics with a reproducible report on the first failure.
pub fn fuzz(target: &str, file: &str, seeds: &[Vec<u8>], read: &dyn Fn(&[u8]) -> Outcome) {
    assert!(!seeds.is_empty(), "{target}: no seeds");
    let corpus_dir = repo().join("crates/kinecal/tests/fuzz-corpus").join(target);
    let mut corpus: Vec<(String, Vec<u8>)> = Vec::new();
    if let Ok(dir) = std::fs::read_dir(&corpus_dir) {
        for e in dir.flatten() {
            corpus.push((
                e.path().display().to_string(),
                std::fs::read(e.path()).unwrap(),
            ));
        }
    }
    let n = iterations();
    let run = run_seed();
    // Each target its own stream: the run's seed mixed with the target's name (a seed of 0
    // and a name's length alone gave the seed of the test suite's runs, kept).
    let mut rng = ChaCha8Rng::seed_from_u64(0x6b69_6e65 ^ target.len() as u64 ^ mix(run, target));
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let (mut accepted, mut slowest) = (0usize, Duration::ZERO);
    let total = corpus.len() + seeds.len() + n;
    let start = Instant::now();
    for k in 0..total {
        let (what, input) = if k < corpus.len() {
            corpus[k].clone()
        } else if k < corpus.len() + seeds.len() {
            (
                format!("seed {}", k - corpus.len()),
                seeds[k - corpus.len()].clone(),
            )
        } else {
            let seed = &seeds[rng.random_range(0..seeds.len())];
            (format!("mutation {k}"), mutate(&mut rng, seed))
        };
        let t = Instant::now();
        let result = catch_unwind(AssertUnwindSafe(|| read(&input)));
        let took = t.elapsed();
        slowest = slowest.max(took);
        let failure = match result {
            Err(p) => Some(format!(
                "panicked: {}",
                p.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            )),
            Ok(_) if took > Duration::from_secs(1) => Some(format!("took {took:?}")),
            Ok(Outcome::Accepted(Err(why))) => Some(format!("accepted, but {why}")),
            Ok(Outcome::Accepted(Ok(()))) => {
                accepted += 1;
                None
            }
            Ok(Outcome::Refused(msg)) if !msg.starts_with(file) => {
                Some(format!("refused without naming {file}: {msg}"))
            }
            Ok(Outcome::Refused(_)) => None,
        };
        if let Some(f) = failure {
            std::panic::set_hook(hook);
            let dump = std::env::temp_dir().join(format!("kinecal-fuzz-{target}-{k}"));
            std::fs::write(&dump, &input).unwrap();
            panic!(
                "{target}, {what} (KINECAL_FUZZ_SEED={run}): {f}\ninput saved to {} (copy it \
                 into {} to keep it)\n{}",
                dump.display(),
                corpus_dir.display(),
                String::from_utf8_lossy(&input[..input.len().min(2000)])
            );
        }
    }
    std::panic::set_hook(hook);
    eprintln!(
        "{target}: {total} inputs ({} corpus, {} seeds, {n} mutations, KINECAL_FUZZ_SEED={run}) \
         in {:.1?}: {accepted} \
         accepted, the rest refused with the file named; slowest {slowest:?}; 0 panics, 0 \
         hangs, 0 non-finite",
        corpus.len(),
        seeds.len(),
        start.elapsed()
    );
}

/// 0 for the run seed 0 (the test suite's inputs, as before there was a run seed); otherwise
/// the seed and the target's name hashed (FNV-1a, then a SplitMix64 finaliser), so that
/// targets whose names are as long draw different streams.
fn mix(run: u64, target: &str) -> u64 {
    if run == 0 {
        return 0;
    }
    let mut h = 0xcbf2_9ce4_8422_2325_u64 ^ run;
    for b in target.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}
