//! Mode extraction from recordings (issue 14), one core: accuracy on 100 synthetic strikes
//! with known modes, and the time to analyse a 3 s recording.
//!
//! `cargo bench --bench analysis` prints, over 100 random sets of 5-60 modes (60 Hz-18 kHz,
//! a fifth in pairs 0.5-2 Hz apart, decays 0.5-200 /s) at 20-40 dB SNR
//! ([`modalforge::analysis::synthetic`]): the share of resolvable modes 20 dB above the noise
//! found to 0.1 % in frequency, the worst decay and amplitude errors among them, the share of
//! spurious modes; then the median time of `extract` on a 3 s, 48 kHz strike of 60 modes.
//! Both methods ([`Method`]) in turn; `-- --method NAME` runs one.

use modalforge::analysis::synthetic::{case, score, Score};
use modalforge::analysis::{extract, AnalysisOptions, Method};
use std::time::Instant;

fn main() {
    faer::set_global_parallelism(faer::Par::Seq);
    let args: Vec<String> = std::env::args().collect();
    let only = args
        .iter()
        .position(|a| a == "--method")
        .and_then(|i| args.get(i + 1));
    for method in [Method::Pencil, Method::Peaks] {
        if only.is_some_and(|m| *m != method.to_string()) {
            continue;
        }
        println!("method: {method}");
        run(AnalysisOptions {
            method,
            ..AnalysisOptions::default()
        });
    }
}

/// The figures for one method.
fn run(options: AnalysisOptions) {
    let mut total = Score::default();
    let mut times = Vec::new();
    for seed in 0..100u64 {
        let count = 5 + (seed as usize * 37) % 56;
        let snr = 20.0 + 20.0 * ((seed * 7) % 11) as f64 / 10.0;
        let c = case(1000 + seed, count, snr, 2.0);
        let t = Instant::now();
        let a = extract(&c.signal, c.fs, &options).expect("analyses");
        times.push(t.elapsed().as_secs_f64());
        total.add(&score(&c, &a.modes));
    }
    println!(
        "100 synthetic strikes (5-60 modes, 20-40 dB SNR): {} of {} resolvable modes found to 0.1 % ({:.1} %), worst decay error {:.1} %, worst amplitude error {:.2} dB, {} of {} reported modes spurious ({:.1} %)",
        total.found,
        total.visible,
        100.0 * total.found as f64 / total.visible.max(1) as f64,
        100.0 * total.worst_decay,
        total.worst_db,
        total.spurious,
        total.reported,
        100.0 * total.spurious as f64 / total.reported.max(1) as f64
    );
    let (d95, db95) = total.quantile(0.95);
    let (d50, db50) = total.quantile(0.5);
    println!(
        "  found modes: decay error median {:.2} %, 95th percentile {:.1} %; amplitude error median {:.2} dB, 95th percentile {:.2} dB",
        100.0 * d50, 100.0 * d95, db50, db95
    );
    times.sort_by(f64::total_cmp);
    println!(
        "  extract on these 2 s strikes: median {:.0} ms",
        1e3 * times[50]
    );
    // A 3 s recording of 60 modes.
    let c = case(7, 60, 40.0, 3.0);
    let mut t3 = Vec::new();
    for _ in 0..5 {
        let t = Instant::now();
        extract(&c.signal, c.fs, &options).expect("analyses");
        t3.push(t.elapsed().as_secs_f64());
    }
    t3.sort_by(f64::total_cmp);
    println!(
        "  a {:.1} s recording of 60 modes: median {:.0} ms (one core)",
        c.signal.len() as f64 / c.fs,
        1e3 * t3[2]
    );
}
