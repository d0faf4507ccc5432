//! The soak (issue 16): the engine as a plugin drives it, for a long time, in real time.
//!
//! Shared by `benches/soak.rs` (the one-hour run, `cargo bench --bench soak`) and
//! `tests/soak.rs` (a two-minute version in the suite); both declare the counting allocator of
//! [`super::alloc`]. The calling thread is the audio thread: it processes 64-sample blocks
//! at 48 kHz paced to the wall clock (it sleeps until each block is due, as a host's callback
//! is called), with:
//! - random MIDI: strikes at random keys, velocities, hit points and mallets (about 40 a
//!   second), pitch-mapped as the plugin's pitch mode, mutes, and per-note expression (tuning,
//!   pressure and volume, about 100 changes a second, as an MPE controller sends them);
//! - random automation of every voicing parameter (size, material, damping, hit, hardness, the
//!   mode budget) every block;
//! - random shape edits every 150-500 ms through the plugin's solver chain (predictor, carried
//!   answer, exact FEM): one-voxel strokes on the object, and now and then a new object.
//!
//! It measures each block's `process` time against the block's real-time deadline
//! (64 / 48 kHz = 1.33 ms), counts the audio thread's allocations and frees, reads the
//! process's resident memory at the start and the end, and checks that every edit was solved
//! or superseded by a newer one (no solver error, and the last edit's object is the one that
//! plays at the end).

use super::alloc;
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::engine::{
    interactive_solvers, AnswerSwitch, DampingParams, Engine, EngineConfig, Event, Expression,
    HitPoint, KeptAnswers, ObjectRequest, Pitch, SolveState, TimedEvent, Voicing,
};
use modalforge::fem::ElementKind;
use modalforge::material::Material;
use modalforge::rng::SplitMix64;
use modalforge::shape::primitives::Primitive;
use modalforge::shape::VoxelGrid;
use std::time::{Duration, Instant};

/// Sample rate, Hz.
pub const RATE_HZ: f64 = 48000.0;
/// Samples per block.
pub const BLOCK: usize = 64;

/// What a soak measured.
#[derive(Clone, Debug, Default)]
pub struct SoakReport {
    /// Blocks processed.
    pub blocks: u64,
    /// Blocks whose `process` took longer than the block lasts (wall clock).
    pub deadline_misses: u64,
    /// Of those, the blocks whose thread CPU time was over the deadline too: at most the
    /// misses the engine's own work caused (on a virtual machine, the hypervisor's steal
    /// counts as the thread's CPU time as well). The rest were misses in which the thread was
    /// not running for part of the block.
    pub cpu_misses: u64,
    /// The most CPU time one block's `process` took, µs.
    pub worst_block_cpu_us: f64,
    /// The slowest block, µs.
    pub worst_block_us: f64,
    /// The 99.9th percentile block, µs.
    pub p999_block_us: f64,
    /// The block's deadline, µs.
    pub deadline_us: f64,
    /// Allocations and frees on the audio thread.
    pub audio_allocations: usize,
    /// Frees on the audio thread.
    pub audio_frees: usize,
    /// Heap in use (every thread) after a warm-up of a dozen edits, the first object solved
    /// and the worker idle, bytes.
    pub heap_start_bytes: isize,
    /// Heap in use at the end, the first object solved again and the worker idle, bytes.
    pub heap_end_bytes: isize,
    /// Resident memory at the start (as `heap_start_bytes`), bytes.
    pub rss_start_bytes: u64,
    /// Resident memory at the end, bytes.
    pub rss_end_bytes: u64,
    /// Shape edits sent.
    pub edits: u64,
    /// Solver runs finished.
    pub solves: u64,
    /// Solver runs given up because a newer edit made them obsolete.
    pub interrupted: u64,
    /// Solver errors (each one a failed edit).
    pub solve_errors: Vec<String>,
    /// Whether the last edit's object is the one playing at the end.
    pub last_edit_playing: bool,
    /// Strikes sent.
    pub strikes: u64,
    /// Per-note expression changes sent.
    pub expressions: u64,
    /// Samples that were not finite.
    pub non_finite_samples: u64,
    /// The loudest sample.
    pub peak: f32,
    /// Whether the audio thread ran on the real-time FIFO scheduler (asked for by the bench).
    pub realtime: bool,
}

impl std::fmt::Display for SoakReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "blocks {} ({:.0} s of audio), strikes {}, expression changes {}, edits {}, solver runs {} \
             finished and {} interrupted by a newer edit",
            self.blocks,
            self.blocks as f64 * BLOCK as f64 / RATE_HZ,
            self.strikes,
            self.expressions,
            self.edits,
            self.solves,
            self.interrupted
        )?;
        writeln!(
            f,
            "block time: worst {:.0} us, 99.9th percentile {:.0} us, deadline {:.0} us, {} misses ({})",
            self.worst_block_us,
            self.p999_block_us,
            self.deadline_us,
            self.deadline_misses,
            if self.realtime {
                "audio thread on SCHED_FIFO, as hosts run it"
            } else {
                "audio thread at normal priority"
            }
        )?;
        writeln!(
            f,
            "thread CPU time: worst {:.0} us; misses with the CPU time over the deadline too: {} \
             (the other {} lost the CPU mid-block)",
            self.worst_block_cpu_us,
            self.cpu_misses,
            self.deadline_misses - self.cpu_misses
        )?;
        writeln!(
            f,
            "audio thread: {} allocations, {} frees; heap in use {:.2} MB -> {:.2} MB ({:+.3} MB); resident {:.1} MB -> {:.1} MB ({:+.2} MB)",
            self.audio_allocations,
            self.audio_frees,
            self.heap_start_bytes as f64 / 1e6,
            self.heap_end_bytes as f64 / 1e6,
            (self.heap_end_bytes - self.heap_start_bytes) as f64 / 1e6,
            self.rss_start_bytes as f64 / 1e6,
            self.rss_end_bytes as f64 / 1e6,
            (self.rss_end_bytes as f64 - self.rss_start_bytes as f64) / 1e6
        )?;
        write!(
            f,
            "solver errors {}, last edit playing at the end: {}, non-finite samples {}, peak {:.3}",
            self.solve_errors.len(),
            self.last_edit_playing,
            self.non_finite_samples,
            self.peak
        )
    }
}

/// Puts the calling thread on the real-time FIFO scheduler at `priority` (1-99), as hosts run
/// their audio threads (JACK, CoreAudio, WASAPI's pro-audio class), so that other work on the
/// machine cannot preempt a block. Whether it was granted (it needs root, `CAP_SYS_NICE` or an
/// `rtprio` limit; Linux only).
pub fn realtime_priority(priority: i32) -> bool {
    #[cfg(target_os = "linux")]
    {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: `pthread_self()` is the calling thread's own live handle, and `param` is a
        // valid `sched_param` that outlives the call.
        unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) == 0 }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = priority;
        false
    }
}

/// The calling thread's CPU time (Linux `CLOCK_THREAD_CPUTIME_ID`; `None` elsewhere).
pub fn thread_cpu_time() -> Option<Duration> {
    #[cfg(target_os = "linux")]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `t` is a valid, writable `timespec` that outlives the call.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0;
        ok.then(|| Duration::new(t.tv_sec as u64, t.tv_nsec as u32))
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// Resident memory of this process, bytes (Linux `/proc/self/statm`; 0 elsewhere), after
/// glibc has returned its free memory to the system (`malloc_trim`): freed blocks the
/// allocator keeps cached are not growth.
pub fn resident_bytes() -> u64 {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only walks glibc's own arenas under their locks; any thread may call it.
    unsafe {
        libc::malloc_trim(0);
    }
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1)?.parse::<u64>().ok())
        .map_or(0, |pages| pages * 4096)
}

/// The objects a soak sculpts from (the plugin's 16-voxel default and shapes like the presets).
fn base_object(rng: &mut SplitMix64) -> VoxelGrid {
    let p = match rng.int(0, 3) {
        0 => Primitive::Bowl {
            diameter: 16.0,
            wall: 2.0,
        },
        1 => Primitive::Bar {
            length: rng.range(12.0, 28.0),
            width: 4.0,
            height: 3.0,
        },
        2 => Primitive::Plate {
            length: 20.0,
            width: rng.range(10.0, 20.0),
            thickness: 2.0,
        },
        _ => Primitive::Bell {
            diameter: 14.0,
            height: 14.0,
            wall: 2.0,
        },
    };
    p.rasterize(1.0, 0.01).expect("a soak object fits")
}

/// A one-voxel stroke: an exposed voxel removed, or an empty face neighbour of a solid voxel
/// filled (inside the grid), whichever the dice pick; the grid keeps at least 27 voxels.
fn stroke(grid: &VoxelGrid, rng: &mut SplitMix64) -> VoxelGrid {
    let solid = grid.solid_voxels();
    let mut next = grid.clone();
    let v = solid[rng.below(solid.len())];
    if rng.int(0, 1) == 0 && solid.len() > 27 {
        next.set(v[0], v[1], v[2], false);
    } else {
        let d = grid.dims();
        let axis = rng.below(3);
        let mut n = v;
        if rng.int(0, 1) == 0 {
            n[axis] = (n[axis] + 1).min(d[axis] - 1);
        } else {
            n[axis] = n[axis].saturating_sub(1);
        }
        next.set(n[0], n[1], n[2], true);
    }
    next
}

fn request(grid: VoxelGrid) -> ObjectRequest {
    ObjectRequest {
        grid,
        element: ElementKind::Hex8Incompatible,
        poisson_ratio: 0.24,
        solver: SolverKind::Auto,
        options: EigenOptions {
            count: ModeCount::First(60),
            ..EigenOptions::default()
        },
        recording: None,
    }
}

/// Requests of the first object at the start and the end, before the heap is measured, each
/// with the kept answers dropped first (so that each solves and assembles it): the element
/// cache keeps what the last `KEEP_ASSEMBLIES` assemblies used, so after this many it holds
/// the first object's cut elements only, and the kept answers the first object's, at both
/// ends. (Both stores are bounded on their own; their tests check the bounds.)
const SETTLE_REQUESTS: u64 = modalforge::fem::cache::KEEP_ASSEMBLIES;

/// Lets the worker finish while the host keeps calling `process` (which takes delivered
/// objects from the ring), then one more block so the last answer is the one playing.
fn settle(
    audio: &mut modalforge::engine::AudioEngine,
    control: &modalforge::engine::EngineControl,
    out: &mut [f32],
) {
    let give_up = Instant::now() + Duration::from_secs(60);
    while !control.wait_idle(Duration::from_millis(5)) && Instant::now() < give_up {
        audio.process(out, &[]);
    }
    audio.process(out, &[]);
}

/// Runs a soak of `seconds` of real time with `voices` voices; `seed` makes the session. With
/// `realtime`, the calling thread (the audio thread) asks for the FIFO scheduler once the
/// engine's worker is started (so the worker stays at normal priority).
pub fn run(seconds: f64, voices: usize, seed: u64, realtime: bool) -> SoakReport {
    let mut rng = SplitMix64::new(seed);
    let glass = Material::preset("glass").expect("glass");
    let mut base_voicing = Voicing::from_material(&glass, 0.2).expect("glass voices");
    // The plugin's level normalisation (the CLI's physical units would be ~1e-5).
    base_voicing.normalise = true;
    let config = EngineConfig {
        voices,
        ..EngineConfig::default()
    };
    let predictor = modalforge::predictor::Predictor::shipped()
        .ok()
        .map(std::sync::Arc::new);
    // The chain's kept exact answers (the plugin shares one store per process).
    let kept = KeptAnswers::new();
    let (mut audio, control) = Engine::start(
        RATE_HZ,
        config,
        base_voicing,
        interactive_solvers(predictor, AnswerSwitch::default(), &kept),
    )
    .expect("the engine starts");
    let first = base_object(&mut rng);
    let mut object = first.clone();
    control.request(request(object.clone()));
    control.wait_for_solves(1, Duration::from_secs(60));
    let mut out = vec![0f32; BLOCK];
    settle(&mut audio, &control, &mut out);
    // Warm-up: a dozen edits of every kind fill the caches that live as long as the engine
    // (the solver threads' matrix-product workspaces, the warm-start state); then the first
    // object again (`SETTLE_REQUESTS` times), whose heap is the baseline.
    let mut warm_rng = SplitMix64::new(seed ^ 0x5EED);
    let mut warm = first.clone();
    for k in 0..12 {
        warm = if k % 4 == 3 {
            base_object(&mut warm_rng)
        } else {
            stroke(&warm, &mut warm_rng)
        };
        control.request(request(warm.clone()));
        settle(&mut audio, &control, &mut out);
    }
    for _ in 0..SETTLE_REQUESTS {
        kept.clear();
        control.request(request(first.clone()));
        settle(&mut audio, &control, &mut out);
    }

    let deadline = Duration::from_secs_f64(BLOCK as f64 / RATE_HZ);
    let total_blocks = (seconds * RATE_HZ / BLOCK as f64) as u64;
    let mut events: Vec<TimedEvent> = Vec::with_capacity(16);
    let mut times_us: Vec<f32> = Vec::with_capacity(total_blocks as usize);
    let mut report = SoakReport {
        deadline_us: deadline.as_secs_f64() * 1e6,
        realtime: realtime && realtime_priority(80),
        ..SoakReport::default()
    };
    let mut voicing = base_voicing;
    let mut next_edit_block = 0u64;
    let mut solves_seen = 0u64;
    let (allocs0, frees0) = (alloc::allocations(), alloc::frees());
    modalforge::eigen::free_kept_buffers();
    report.heap_start_bytes = alloc::live_bytes();
    report.rss_start_bytes = resident_bytes();
    let start = Instant::now();
    for block in 0..total_blocks {
        // The editor thread's part, done here between blocks (it never runs inside
        // `process`): a shape edit every 150-500 ms.
        if block >= next_edit_block {
            object = if rng.int(0, 9) == 0 {
                base_object(&mut rng)
            } else {
                stroke(&object, &mut rng)
            };
            control.request(request(object.clone()));
            report.edits += 1;
            next_edit_block = block + (rng.range(0.15, 0.5) * RATE_HZ / BLOCK as f64) as u64;
        }
        // The editor also reads the worker's status (as the plugin's status line does), which
        // is where a failed solve shows.
        if block % 4 == 0 {
            let status = control.status();
            if status.solves != solves_seen {
                solves_seen = status.solves;
                if let Some(e) = status.last.and_then(|l| l.error) {
                    report.solve_errors.push(e);
                }
            }
        }
        // The host's part: MIDI and automation for this block.
        events.clear();
        if rng.range(0.0, 1.0) < 40.0 * BLOCK as f64 / RATE_HZ {
            let key = rng.int(36, 96) as u8;
            events.push(TimedEvent {
                offset: rng.below(BLOCK),
                event: Event::Strike {
                    key,
                    pitch: Pitch::Fundamental(440.0 * 2f64.powf((key as f64 - 69.0) / 12.0)),
                    velocity: rng.range(0.05, 1.0),
                    hit: Some(HitPoint {
                        position: [rng.range(0.0, 1.0), rng.range(0.0, 1.0), 1.0],
                        direction: None,
                    }),
                    hardness_s: Some(rng.range(0.0, 2e-3)),
                },
            });
            report.strikes += 1;
        }
        if rng.range(0.0, 1.0) < 10.0 * BLOCK as f64 / RATE_HZ {
            events.push(TimedEvent {
                offset: rng.below(BLOCK),
                event: Event::Mute {
                    key: rng.int(36, 96) as u8,
                },
            });
        }
        if rng.range(0.0, 1.0) < 100.0 * BLOCK as f64 / RATE_HZ {
            let expression = match rng.below(3) {
                0 => Expression::TuningSemitones(rng.range(-48.0, 48.0)),
                1 => Expression::Pressure(rng.range(0.0, 1.0)),
                _ => Expression::Volume(rng.range(0.0, 2.0)),
            };
            events.push(TimedEvent {
                offset: rng.below(BLOCK),
                event: Event::Expression {
                    key: rng.int(36, 96) as u8,
                    expression,
                },
            });
            report.expressions += 1;
        }
        events.sort_by_key(|e| e.offset);
        voicing.size_m = (voicing.size_m * rng.range(0.99, 1.01)).clamp(0.05, 1.0);
        voicing.youngs_modulus_pa =
            (voicing.youngs_modulus_pa * rng.range(0.99, 1.01)).clamp(1e9, 3e11);
        voicing.damping = DampingParams::Rayleigh {
            alpha1: rng.range(0.5, 5.0),
            alpha2: rng.range(1e-8, 1e-7),
        };
        voicing.hit.position = [
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
        ];
        let budget = rng.int(64, 2048);

        let cpu0 = thread_cpu_time();
        let t0 = Instant::now();
        alloc::marked(|| {
            // A voicing the engine refuses keeps the previous one (as the plugin does).
            let _ = audio.set_voicing(voicing);
            audio.set_mode_budget(budget);
            audio.process(&mut out, &events);
        });
        let us = t0.elapsed().as_secs_f64() * 1e6;
        let cpu_us = match (cpu0, thread_cpu_time()) {
            (Some(a), Some(b)) => b.saturating_sub(a).as_secs_f64() * 1e6,
            // No thread clock: every miss counts as the engine's.
            _ => us,
        };
        times_us.push(us as f32);
        report.worst_block_cpu_us = report.worst_block_cpu_us.max(cpu_us);
        if us > report.deadline_us {
            report.deadline_misses += 1;
            if cpu_us > report.deadline_us {
                report.cpu_misses += 1;
            }
        }
        report.worst_block_us = report.worst_block_us.max(us);
        for x in &out {
            if x.is_finite() {
                report.peak = report.peak.max(x.abs());
            } else {
                report.non_finite_samples += 1;
            }
        }
        // Wait for the block's slot in real time, as a host's audio callback would.
        let due = start + deadline.mul_f64((block + 1) as f64);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
    report.blocks = total_blocks;
    report.audio_allocations = alloc::allocations() - allocs0;
    report.audio_frees = alloc::frees() - frees0;
    // Every edit solved or superseded: the last one's answer arrives and plays.
    settle(&mut audio, &control, &mut out);
    let status = control.status();
    report.solves = status.solves;
    report.interrupted = status.interrupted;
    if status.solves != solves_seen {
        if let Some(e) = status.last.as_ref().and_then(|l| l.error.clone()) {
            report.solve_errors.push(e);
        }
    }
    report.last_edit_playing = control
        .latest_object()
        .is_some_and(|o| o.basis.grid_dims() == object.cropped().dims())
        && status.state == SolveState::Idle
        && audio.object_generation().map(|(g, _)| g)
            == status.playing.as_ref().map(|p| p.generation);
    // Memory: the first object again, as at the start, so that the worker's caches (the last
    // answers, kept for warm starts, and the cut elements of the last assemblies) hold the
    // same objects as at the start.
    for _ in 0..SETTLE_REQUESTS {
        kept.clear();
        control.request(request(first.clone()));
        settle(&mut audio, &control, &mut out);
    }
    modalforge::eigen::free_kept_buffers();
    report.heap_end_bytes = alloc::live_bytes();
    report.rss_end_bytes = resident_bytes();
    times_us.sort_by(f32::total_cmp);
    if !times_us.is_empty() {
        report.p999_block_us = times_us[(times_us.len() - 1) * 999 / 1000] as f64;
    }
    report
}
