//! `stairbench bench fuzz`: the device parsers on millions of seeded inputs (mutations of valid
//! streams, arbitrary bytes, fed in pieces of one byte to a whole stream), on the stable
//! toolchain. Every input runs under `catch_unwind`; a panic or a reader that loops is a
//! failure, its input written to `out/fuzz/` and the command's exit status non-zero. The speed
//! is per byte, against the same parser on its valid stream in the same process.

use anyhow::Result;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use stairbench::sensor::dynamixel::packet::Protocol;
use stairbench::sensor::fuzz::{self, Looped};
use std::fmt::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// Inputs drawn from one random stream (a chunk is reproducible alone).
const CHUNK: u64 = 4096;

/// One parser under test.
#[derive(Clone, Copy)]
enum Target {
    Scip,
    Dynamixel(Protocol),
}

impl Target {
    fn name(self) -> &'static str {
        match self {
            Target::Scip => "SCIP 2.0 replies (reader, MD/ME scan and PP decoders)",
            Target::Dynamixel(Protocol::One) => "Dynamixel 1.0 packets (status and instruction readers)",
            Target::Dynamixel(Protocol::Two) => {
                "Dynamixel 2.0 packets (status and instruction readers, byte stuffing)"
            }
        }
    }

    fn key(self) -> &'static str {
        match self {
            Target::Scip => "scip",
            Target::Dynamixel(Protocol::One) => "dxl1",
            Target::Dynamixel(Protocol::Two) => "dxl2",
        }
    }

    /// A valid stream (Dynamixel: with parameters drawn from `rng`).
    fn valid(self, rng: &mut impl Rng) -> Vec<u8> {
        match self {
            Target::Scip => fuzz::scip_stream(),
            Target::Dynamixel(p) => {
                let n = rng.random_range(0..48);
                let params: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                fuzz::dynamixel_stream(p, &params)
            }
        }
    }

    fn drain(self, bytes: &[u8], piece: usize) -> Result<usize, Looped> {
        match self {
            Target::Scip => fuzz::scip_drain(bytes, piece),
            Target::Dynamixel(p) => fuzz::dynamixel_drain(p, bytes, piece),
        }
    }
}

/// A failing input.
struct Failure {
    chunk: u64,
    index: u64,
    bytes: Vec<u8>,
    piece: usize,
    panicked: bool,
}

/// Totals of one parser's run.
#[derive(Default)]
struct Tally {
    inputs: u64,
    bytes: u64,
}

/// Runs every parser on `inputs` inputs from `seed`; the table, and whether all passed.
pub fn run(inputs: u64, seed: u64) -> Result<(String, bool)> {
    let mut t = String::new();
    writeln!(t, "Machine: {}. {inputs} inputs per parser, seed {seed}.\n", super::machine())?;
    writeln!(
        t,
        "Inputs: 7 in 8 are a valid stream with 1 to 8 edits (flip, insert, delete, truncate, \
         repeat a span), 1 in 8 arbitrary bytes; fed in pieces of 1 byte, 1-15, 16-255 or the \
         whole input. A failure is a panic or a reader giving more messages than its bytes could \
         hold.\n"
    )?;
    writeln!(t, "| parser | inputs | MB | failures | inputs/s | ns/byte | valid ns/byte | ratio |")?;
    writeln!(t, "|---|---:|---:|---:|---:|---:|---:|---:|")?;
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut all_passed = true;
    let targets = [Target::Scip, Target::Dynamixel(Protocol::One), Target::Dynamixel(Protocol::Two)];
    let mut outcome = Ok(());
    for target in targets {
        let valid_ns = valid_ns_per_byte(target, seed);
        let failures = Mutex::new(Vec::new());
        let t0 = Instant::now();
        let chunks = inputs.div_ceil(CHUNK);
        let tally = (0..chunks)
            .into_par_iter()
            .map(|chunk| fuzz_chunk(target, seed, chunk, inputs, &failures))
            .reduce(Tally::default, |a, b| Tally { inputs: a.inputs + b.inputs, bytes: a.bytes + b.bytes });
        let wall_s = t0.elapsed().as_secs_f64();
        let failures = failures.into_inner().unwrap_or_default();
        // Per byte and per thread, as the valid baseline is measured.
        let ns = wall_s * 1e9 * rayon::current_num_threads() as f64 / tally.bytes.max(1) as f64;
        writeln!(
            t,
            "| {} | {} | {:.0} | {} | {:.0} | {:.2} | {:.2} | {:.2} |",
            target.name(),
            tally.inputs,
            tally.bytes as f64 / 1e6,
            failures.len(),
            tally.inputs as f64 / wall_s,
            ns,
            valid_ns,
            ns / valid_ns
        )?;
        if !failures.is_empty() {
            all_passed = false;
            if let Err(e) = keep_failures(target, &failures) {
                outcome = Err(e);
            }
        }
    }
    std::panic::set_hook(previous_hook);
    outcome?;
    writeln!(
        t,
        "\nns/byte is wall time x threads per byte fed; the ratio is that against the same parser \
         on its valid stream, whole, in the same process (above 1: mutated input costs more per \
         byte, e.g. the resynchronisation after a bad byte)."
    )?;
    Ok((t, all_passed))
}

/// The inputs of chunk `chunk`, each run under `catch_unwind`.
fn fuzz_chunk(target: Target, seed: u64, chunk: u64, inputs: u64, failures: &Mutex<Vec<Failure>>) -> Tally {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(chunk);
    let mut tally = Tally::default();
    for index in 0..CHUNK.min(inputs - chunk * CHUNK) {
        let valid = target.valid(&mut rng);
        let (bytes, piece) = fuzz::draw(&mut rng, &valid);
        let result = catch_unwind(AssertUnwindSafe(|| target.drain(&bytes, piece)));
        tally.inputs += 1;
        tally.bytes += bytes.len() as u64;
        let failed = match result {
            Ok(Ok(_)) => None,
            Ok(Err(Looped)) => Some(false),
            Err(_) => Some(true),
        };
        if let Some(panicked) = failed {
            if let Ok(mut f) = failures.lock() {
                f.push(Failure { chunk, index, bytes, piece, panicked });
            }
        }
    }
    tally
}

/// The parser's time per byte on its valid stream, whole, on one thread, nanoseconds.
fn valid_ns_per_byte(target: Target, seed: u64) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let streams: Vec<Vec<u8>> = (0..64).map(|_| target.valid(&mut rng)).collect();
    let bytes: usize = streams.iter().map(Vec::len).sum();
    let rounds = (20_000_000 / bytes.max(1)).max(1);
    let s = super::median_s(5, || {
        for _ in 0..rounds {
            for v in &streams {
                std::hint::black_box(target.drain(std::hint::black_box(v), v.len()).ok());
            }
        }
    });
    s * 1e9 / (rounds * bytes) as f64
}

/// Writes the failing inputs to `out/fuzz/` and names them on stderr.
fn keep_failures(target: Target, failures: &[Failure]) -> Result<()> {
    let dir = PathBuf::from("out/fuzz");
    std::fs::create_dir_all(&dir)?;
    for f in failures.iter().take(20) {
        let path = dir.join(format!("{}-{}-{}-piece{}.bin", target.key(), f.chunk, f.index, f.piece));
        std::fs::write(&path, &f.bytes)?;
        eprintln!(
            "{}: {} on input {} of chunk {} (pieces of {} bytes), written to {}",
            target.name(),
            if f.panicked { "a panic" } else { "a loop" },
            f.index,
            f.chunk,
            f.piece,
            path.display()
        );
    }
    Ok(())
}
