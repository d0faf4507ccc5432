//! The one-hour soak (issue 16): `cargo bench --bench soak` (`-- SECONDS VOICES` to change the
//! hour and the 64 voices). The engine plays 64-sample blocks at 48 kHz in real time on this
//! thread while random notes, automation of every voicing parameter and random shape edits
//! through the plugin's solver chain (every 150-500 ms) arrive; see `tests/common/soak.rs`.
//! It prints the worst block time against the real-time deadline, the audio thread's
//! allocations, resident memory at the start and the end, and whether every edit was solved or
//! superseded. The audio thread asks for the real-time FIFO scheduler, as hosts run theirs (the
//! report says whether it got it). The suite runs a two-minute version (`tests/soak.rs`).

#[path = "../tests/common/alloc.rs"]
mod alloc;
#[path = "../tests/common/soak.rs"]
mod soak;

#[global_allocator]
static GLOBAL: alloc::Counting = alloc::Counting;

fn main() {
    // `cargo bench` passes `--bench`; numbers are ours.
    let numbers: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let seconds = numbers.first().copied().unwrap_or(3600.0);
    let voices = numbers.get(1).map_or(64, |&v| v as usize);
    println!("soak: {seconds:.0} s of real time, {voices} voices, 64-sample blocks at 48 kHz");
    let report = soak::run(seconds, voices, 1, true);
    println!("{report}");
    let growth = (report.heap_end_bytes - report.heap_start_bytes) as f64;
    let pass = report.deadline_misses == 0
        && report.audio_allocations == 0
        && report.audio_frees == 0
        && growth < 1e6
        && report.solve_errors.is_empty()
        && report.last_edit_playing
        && report.non_finite_samples == 0;
    println!(
        "issue 16's soak goals (0 misses, 0 allocations, growth under 1 MB, every edit solved): {}",
        if pass { "met" } else { "NOT met" }
    );
}
