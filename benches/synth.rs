//! Synthesis throughput: both banks, every backend, 64 to 100k modes, at 48 kHz on one core.
//!
//! `cargo bench --bench synth` runs criterion over every (bank, backend, mode count) and then
//! prints a table of mode-samples per second and the largest mode count each bank sustains in
//! real time at 48 kHz on one core. `cargo bench --bench synth -- --table` prints only the table.

use criterion::{BenchmarkId, Criterion, Throughput};
use modalforge::modes::{CullSettings, ModeSet, PlayableModes};
use modalforge::synth::{BiquadBank, Excitation, OscillatorBank, SimdBackend};
use std::hint::black_box;
use std::time::{Duration, Instant};

const RATE_HZ: f64 = 48000.0;
const BLOCK: usize = 1024;
const SIZES: [usize; 4] = [64, 1_000, 10_000, 100_000];

/// `n` modes spread log-uniformly over 20 Hz - 20 kHz, decays 0.5 - 20 /s, gains ~ 1/sqrt(i).
fn modes(n: usize) -> PlayableModes {
    let mut rng = modalforge::rng::SplitMix64::new(1);
    let mut rand = || rng.unit();
    let f: Vec<f64> = (0..n).map(|_| 20.0 * 1000f64.powf(rand())).collect();
    let d: Vec<f64> = (0..n).map(|_| 0.5 + 19.5 * rand()).collect();
    let g: Vec<f64> = (0..n).map(|i| 1.0 / (1.0 + i as f64).sqrt()).collect();
    let set = ModeSet::new(f, d, g).unwrap();
    set.playable(
        RATE_HZ,
        &CullSettings {
            min_relative_gain: 0.0,
        },
    )
    .unwrap()
    .0
}

#[derive(Clone, Copy, PartialEq)]
enum Bank {
    Oscillator,
    Biquad,
}

/// Renders one block into its argument.
type BlockRenderer = Box<dyn FnMut(&mut [f32])>;

/// A renderer for one bank, already struck.
fn renderer(bank: Bank, m: &PlayableModes, backend: SimdBackend) -> BlockRenderer {
    match bank {
        Bank::Oscillator => {
            let mut b = OscillatorBank::with_backend(m, backend);
            b.strike(Excitation::Impulse, 1.0).unwrap();
            Box::new(move |out| b.render(out))
        }
        Bank::Biquad => {
            let mut b = BiquadBank::from_modes_with_backend(m, backend);
            let mut x = vec![0f32; BLOCK];
            x[0] = 1.0;
            b.process(&x, &mut vec![0f32; BLOCK]);
            x[0] = 0.0;
            Box::new(move |out| b.process(&x, out))
        }
    }
}

fn name(bank: Bank) -> &'static str {
    match bank {
        Bank::Oscillator => "oscillator",
        Bank::Biquad => "biquad",
    }
}

fn criterion_benches(c: &mut Criterion) {
    for bank in [Bank::Oscillator, Bank::Biquad] {
        let mut group = c.benchmark_group(name(bank));
        group
            .sample_size(10)
            .warm_up_time(Duration::from_millis(300));
        group.measurement_time(Duration::from_secs(2));
        for &n in &SIZES {
            let m = modes(n);
            group.throughput(Throughput::Elements((n * BLOCK) as u64));
            for backend in SimdBackend::all_available() {
                let mut render = renderer(bank, &m, backend);
                let mut out = vec![0f32; BLOCK];
                group.bench_function(BenchmarkId::new(backend.name(), n), |b| {
                    b.iter(|| {
                        render(&mut out);
                        black_box(&out);
                    })
                });
            }
        }
        group.finish();
    }
}

/// Mode-samples per second: median of several timed runs of at least 50 ms each.
fn throughput(bank: Bank, m: &PlayableModes, backend: SimdBackend) -> f64 {
    let mut render = renderer(bank, m, backend);
    let mut out = vec![0f32; BLOCK];
    let blocks = (5_000_000 / (m.len() * BLOCK)).max(1);
    let mut rates: Vec<f64> = (0..7)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..blocks {
                render(&mut out);
                black_box(&out);
            }
            (blocks * BLOCK * m.len()) as f64 / t.elapsed().as_secs_f64()
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    rates[rates.len() / 2]
}

fn table() {
    println!(
        "\nSynthesis throughput at {RATE_HZ} Hz, one core, {BLOCK}-sample blocks (median of 7)"
    );
    println!(
        "{:<11} {:<9} {:>8} {:>14} {:>12}",
        "bank", "backend", "modes", "Mmode-samp/s", "x realtime"
    );
    for bank in [Bank::Oscillator, Bank::Biquad] {
        let mut max_rt: Vec<(SimdBackend, f64)> = vec![];
        for backend in SimdBackend::all_available() {
            let mut worst_large = f64::INFINITY;
            for &n in &SIZES {
                let rate = throughput(bank, &modes(n), backend);
                let realtime = rate / (n as f64 * RATE_HZ);
                println!(
                    "{:<11} {:<9} {:>8} {:>14.1} {:>12.1}",
                    name(bank),
                    backend.name(),
                    n,
                    rate / 1e6,
                    realtime
                );
                if n >= 10_000 {
                    worst_large = worst_large.min(rate);
                }
            }
            max_rt.push((backend, worst_large / RATE_HZ));
        }
        for (backend, modes) in max_rt {
            println!(
                "max modes in real time at 48 kHz on one core: {} {}: {:.0}",
                name(bank),
                backend.name(),
                modes
            );
        }
    }
}

fn main() {
    let table_only = std::env::args().any(|a| a == "--table");
    if !table_only {
        let mut c = Criterion::default().configure_from_args();
        criterion_benches(&mut c);
        c.final_summary();
    }
    table();
}
