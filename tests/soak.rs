//! The soak's short version in the suite (issue 16; the hour-long one is
//! `cargo bench --bench soak`): two minutes of real-time blocks with random notes, automation
//! and shape edits through the plugin's solver chain ([`common::soak`]). It checks what does
//! not depend on the machine's speed: no allocation or free on the audio thread, finite and
//! bounded output, every edit solved or superseded, and memory that stays flat. The block
//! times are printed, not asserted (speed belongs to the bench).

mod common;

use common::alloc::Counting;

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Seconds of real time (`SOAK_SECONDS` overrides).
const SECONDS: f64 = 120.0;
/// Heap growth allowed over the run (the same object solved at both ends, the worker idle),
/// bytes: the 1 MB for the hour.
const MAX_GROWTH_BYTES: isize = 1 << 20;

#[test]
fn two_minutes_of_notes_automation_and_edits() {
    let seconds = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(SECONDS);
    let r = common::soak::run(seconds, 64, 1, false);
    println!("{r}");
    assert_eq!(r.audio_allocations, 0, "{r}");
    assert_eq!(r.audio_frees, 0, "{r}");
    assert_eq!(r.non_finite_samples, 0, "{r}");
    // A runaway bound, not a level check: a strike is normalised to peak near 0.5 at the
    // object's own size, but a note played lower is a larger object, whose modes move more
    // for the same force (amplitude ~ 1 / frequency): key 36 (65 Hz) on a 16-voxel glass
    // bowl (2.4 kHz) is 37 times lower, a -48 semitone bend 16 times more, volume 2, 64
    // voices: 0.5 * 37 * 16 * 2 * 64 = 38,000. A runaway grows without bound (or to NaN).
    assert!(r.peak > 0.0 && r.peak <= 1e5, "{r}");
    assert!(r.solve_errors.is_empty(), "{:?}", r.solve_errors);
    // About 3 edits and 40 strikes a second (random).
    assert!(
        r.edits as f64 > 1.5 * seconds && r.strikes as f64 > 20.0 * seconds,
        "{r}"
    );
    assert!(r.last_edit_playing, "{r}");
    let growth = r.heap_end_bytes - r.heap_start_bytes;
    assert!(growth < MAX_GROWTH_BYTES, "{r}");
}
