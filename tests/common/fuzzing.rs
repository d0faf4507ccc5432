//! The mutation fuzzer behind `tests/fuzz.rs` and `plugin/tests/state_fuzz.rs` (included by
//! path in both): libFuzzer-style mutations of a valid seed input, deterministic from
//! `FUZZ_SEED`, `FUZZ_ITERATIONS` inputs per format (or as many as `FUZZ_SECONDS` of wall
//! time allow: the "10^6 executions or 30 minutes" for the slow formats); every input
//! must come back without a panic or a hang. Each format prints how many inputs it ran.
//!
//! The committed corpus: `tests/data/fuzz/<format>/` (the format's name with `_` for spaces)
//! holds inputs that once broke a reader (each file's name says how) and seeds worth
//! keeping. Every file there is run first, and the mutations start from it as often as from
//! the built-in seed. (An allocation failure aborts the process rather than panicking: the run
//! then dies, which fails the test as loudly.)

use modalforge::rng::SplitMix64;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Instant;

/// Inputs per format in the test suite (about a second in all on one core).
pub const DEFAULT_ITERATIONS: usize = 600;

/// An input that takes longer than this is a hang. The slowest legitimate inputs are shape
/// specs at the 256-voxel limit: a 216-voxel bowl rasterises with partial voxels in 2.2 s
/// (which a 2 s bound called a hang in the 10^5-input run), so 256 takes about 4 s.
pub const SLOW_INPUT_S: f64 = 10.0;

/// Byte strings a parser may treat specially: limits, signs, non-numbers, separators.
const INTERESTING: &[&[u8]] = &[
    b"NaN",
    b"nan",
    b"inf",
    b"-inf",
    b"1e308",
    b"-1",
    b"0",
    b"-0",
    b"4294967295",
    b"18446744073709551615",
    b"99999999",
    b"\xff\xff\xff\xff",
    b"\x00\x00\x00\x00",
    b"\x7f\xff\xff\xff",
    b"\x00\x00\x80\x7f",
    b"\"",
    b"[",
    b"{",
    b"}",
    b",",
    b"=",
    b"\n",
];

struct Mutator(SplitMix64);

impl Mutator {
    fn below(&mut self, n: usize) -> usize {
        (self.0.next_u64() % n.max(1) as u64) as usize
    }

    /// One to four random mutations of `seed`.
    fn mutate(&mut self, seed: &[u8]) -> Vec<u8> {
        let mut b = seed.to_vec();
        for _ in 0..1 + self.below(4) {
            let len = b.len();
            match self.below(7) {
                0 if len > 0 => {
                    let i = self.below(len);
                    b[i] ^= 1 << self.below(8);
                }
                1 if len > 0 => {
                    let i = self.below(len);
                    b[i] = self.0.next_u64() as u8;
                }
                2 => {
                    let v = INTERESTING[self.below(INTERESTING.len())];
                    let i = self.below(len + 1);
                    if self.below(2) == 0 && i + v.len() <= len {
                        b[i..i + v.len()].copy_from_slice(v);
                    } else {
                        b.splice(i..i, v.iter().copied());
                    }
                }
                3 if len > 0 => {
                    let i = self.below(len);
                    let n = 1 + self.below((len - i).min(64));
                    b.drain(i..i + n);
                }
                4 if len > 0 => {
                    let i = self.below(len);
                    let n = 1 + self.below((len - i).min(256));
                    let copy = b[i..i + n].to_vec();
                    let at = self.below(len + 1);
                    b.splice(at..at, copy);
                }
                5 if len > 0 => b.truncate(self.below(len)),
                _ => {
                    let i = self.below(len + 1);
                    let n = 1 + self.below(8);
                    let bytes: Vec<u8> = (0..n).map(|_| self.0.next_u64() as u8).collect();
                    b.splice(i..i, bytes);
                }
            }
        }
        b
    }
}

/// The committed corpus of `format` (see the module docs): file names and contents.
pub fn corpus(format: &str) -> Vec<(String, Vec<u8>)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/fuzz")
        .join(format.replace(' ', "_"));
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .into_iter()
        .flatten()
        .filter_map(|e| {
            let path = e.ok()?.path();
            let bytes = std::fs::read(&path).ok()?;
            Some((path.file_name()?.to_string_lossy().into_owned(), bytes))
        })
        .collect();
    files.sort();
    files
}

fn iterations() -> usize {
    std::env::var("FUZZ_ITERATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(DEFAULT_ITERATIONS)
}

/// The wall-time budget per format, if `FUZZ_SECONDS` sets one.
fn time_budget() -> Option<std::time::Duration> {
    std::env::var("FUZZ_SECONDS")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .map(std::time::Duration::from_secs_f64)
}

/// Runs `target` on mutations of `seed`; panics listing every input that panicked or hung.
pub fn fuzz(format: &str, seed: &[u8], mut target: impl FnMut(&[u8])) {
    let base: u64 = std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    // One sequence per format (FNV-1a of its name), moved by the seed.
    let name = format.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, c| {
        (h ^ c as u64).wrapping_mul(0x100_0000_01b3)
    });
    let mut m = Mutator(SplitMix64::new(base ^ name));
    // The seed and the committed corpus must go through.
    target(seed);
    let corpus = corpus(format);
    for (file, bytes) in &corpus {
        let result = catch_unwind(AssertUnwindSafe(|| target(bytes)));
        assert!(result.is_ok(), "{format} corpus file {file} panicked");
    }
    let mut failures = Vec::new();
    let (started, budget) = (Instant::now(), time_budget());
    let mut ran = 0;
    for i in 0..iterations() {
        if budget.is_some_and(|b| started.elapsed() > b) {
            break;
        }
        ran += 1;
        let base_input = match m.below(2 * corpus.len() + 1) {
            k if k < corpus.len() => &corpus[k].1[..],
            _ => seed,
        };
        let input = m.mutate(base_input);
        let t0 = Instant::now();
        let result = catch_unwind(AssertUnwindSafe(|| target(&input)));
        let s = t0.elapsed().as_secs_f64();
        if result.is_err() || s > SLOW_INPUT_S {
            let what = if result.is_err() { "panicked" } else { "hung" };
            failures.push(format!(
                "{format} input {i} (FUZZ_SEED={base}) {what} after {s:.2} s, {} bytes: {:?}",
                input.len(),
                String::from_utf8_lossy(&input[..input.len().min(120)])
            ));
        }
        if failures.len() >= 5 {
            break;
        }
    }
    eprintln!(
        "{format}: {ran} mutated inputs and {} corpus files in {:.0} s",
        corpus.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
