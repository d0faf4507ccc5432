//! Glide tests. Truths: the exact path (`retune_in_place`, itself held to the analytic damped
//! sine in `oscillator/tests.rs`) given the same tunings block by block, and a Rayleigh
//! damping law evaluated exactly at every ratio.

use super::super::tests::{carried, fresh};
use super::super::*;
use super::MAX_DECAY_SLOPE;

const FS: f64 = 48000.0;
/// Rayleigh damping `c = A1 + A2 omega^2`, decay `c / 2`: 5 /s at low frequencies, ~25 /s at
/// 10 kHz (glass-like); the slope `d ln d / d ln r` runs from 0 to ~1.6 across the band.
const A1: f64 = 10.0;
const A2: f64 = 1e-8;

fn law_decay(wn2: f64) -> f64 {
    0.5 * (A1 + A2 * wn2)
}

/// Twenty-four modes from 20 Hz to 0.45 fs (a third of them mirrored): their undamped
/// eigenvalues at ratio 1.
fn eigenvalues() -> Vec<f64> {
    (0..24)
        .map(|i| {
            let f = 20.0 * (0.45 * FS / 20.0f64).powf(i as f64 / 23.0);
            (TAU * f).powi(2)
        })
        .collect()
}

/// The law's tuning of every mode at frequency ratio `r` with `extra` decay: (Hz, 1/s).
fn exact(wn2: &[f64], r: f64, extra: f64) -> (Vec<f64>, Vec<f64>) {
    wn2.iter()
        .map(|&w2| {
            let w2 = w2 * r * r;
            let d = law_decay(w2);
            ((w2 - d * d).sqrt() / TAU, d + extra)
        })
        .unzip()
}

/// The largest sample-by-sample difference of two renders.
fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max)
}

/// A bank of `eigenvalues()` at ratio `r0`, struck, with a glide key there.
fn keyed_bank(backend: SimdBackend, r0: f64) -> OscillatorBank {
    let wn2: Vec<f64> = eigenvalues().iter().map(|w| w * r0 * r0).collect();
    let (f, d) = exact(&wn2, 1.0, 0.0);
    let mut bank = OscillatorBank::with_capacity(32, FS, backend);
    let tunings: Vec<Tuning> = fresh(&f, &d);
    bank.retune(&tunings).unwrap();
    bank.strike(Excitation::Impulse, 1.0).unwrap();
    let slope: Vec<f64> = wn2.iter().map(|&w2| A2 * w2 / law_decay(w2)).collect();
    bank.set_glide_reference(&wn2, &d, &slope).unwrap();
    bank
}

/// The glide of issue 15's test: up a semitone in 75 blocks while the pressure's extra decay
/// rises to 20 /s, then back down in 40, starting off the anchor grid (an odd sample, where
/// the mirrored slots' state carries a sign).
fn path(b: usize) -> (f64, f64) {
    let t = if b <= 75 {
        b as f64 / 75.0
    } else {
        1.0 - (b - 75) as f64 / 40.0
    };
    (2f64.powf(t / 12.0), 20.0 * t)
}

#[test]
fn a_glide_plays_what_exact_retunes_of_the_same_tunings_play() {
    // Budget: the glide's f32 constants (series rounded in f32) are within a few 1e-7 of
    // the exact path's, which restarts from f64 anchors every 64 samples; without anchors
    // that grows as a phase error, at most ~1e-7 of a mode's angle per sample (3e-4 rad for
    // the top mode over the 115 blocks), and the state transfer adds ~1e-7 of the amplitude
    // per block. Measured 1.7-2.2e-5 on 24 modes of peak 1 (a sum peaking at 9.5); budget
    // 1e-4.
    for backend in SimdBackend::all_available() {
        let mut glide = keyed_bank(backend, 1.0);
        let mut exact = keyed_bank(backend, 1.0);
        let start = 7_013;
        let mut a = vec![0f32; start + 115 * 64];
        let mut b = a.clone();
        glide.render(&mut a[..start]);
        exact.render(&mut b[..start]);
        for blk in 1..=115 {
            let (r, extra) = path(blk);
            glide.glide(r, extra).unwrap();
            assert!(glide.is_gliding());
            let (f, d): (Vec<f64>, Vec<f64>) = (0..glide.len()).map(|i| glide.tuning(i)).unzip();
            // A full re-tune: mode 21 (11.8 kHz) crosses fs/4, where the exact path moves
            // it to the other kernel half and the glide does not.
            exact.retune(&carried(&f, &d)).unwrap();
            let at = start + (blk - 1) * 64;
            glide.render(&mut a[at..at + 64]);
            exact.render(&mut b[at..at + 64]);
        }
        let peak = b.iter().fold(0f32, |m, x| m.max(x.abs()));
        let worst = max_diff(&a, &b);
        assert!(peak > 1.0, "{backend:?}: peak {peak}");
        assert!(worst < 1e-4, "{backend:?}: glide differs by {worst:e}");
        // The amplitudes read from the glide's f32 state are the exact path's.
        let (mut ga, mut ea) = (vec![0.0; 24], vec![0.0; 24]);
        glide.amplitudes(&mut ga);
        exact.amplitudes(&mut ea);
        for (g, e) in ga.iter().zip(&ea) {
            assert!((g - e).abs() < 1e-3 * ea[0].max(1e-3), "{g} vs {e}");
        }
        // Settling hands the state back to the anchors without a click: the next blocks of
        // the two banks still agree.
        glide.settle();
        assert!(!glide.is_gliding());
        let (mut a2, mut b2) = (vec![0f32; 640], vec![0f32; 640]);
        glide.render(&mut a2);
        exact.render(&mut b2);
        let worst = max_diff(&a2, &b2);
        assert!(worst < 1e-4, "{backend:?}: after settling {worst:e}");
    }
}

#[test]
fn a_glide_tunes_every_mode_by_the_damping_law() {
    // The reported tuning (what the kernel is given) against the law at every step: the
    // frequency within 1e-6 (0.002 cent; only the decay's share in sqrt(w^2 - d^2) is
    // approximated), the decay within 0.5 % (a local power law's curvature over a
    // 1.5-semitone glide, bounded by (ln r)^2 / 2 = 0.37 % for Rayleigh).
    let mut bank = keyed_bank(SimdBackend::detect(), 1.0);
    let wn2 = eigenvalues();
    let top = GLIDE_MAX_LN_RATIO.exp() * 0.999;
    for r in [1.0, 1.01, 1.0 / 1.02, 1.05, top, 1.0 / top] {
        for extra in [0.0, 3.0] {
            bank.glide(r, extra).unwrap();
            let (f, d) = exact(&wn2, r, extra);
            for i in 0..24 {
                let (gf, gd) = bank.tuning(i);
                assert!(
                    (gf / f[i] - 1.0).abs() < 1e-6,
                    "r {r}, mode {i}: {gf} vs {}",
                    f[i]
                );
                assert!(
                    (gd / d[i] - 1.0).abs() < 5e-3,
                    "r {r}, mode {i}: {gd} vs {}",
                    d[i]
                );
            }
        }
    }
}

#[test]
fn glides_outside_the_key_are_refused_and_change_nothing() {
    let backend = SimdBackend::detect();
    let mut bank = keyed_bank(backend, 1.0);
    let mut twin = keyed_bank(backend, 1.0);
    let wide = (1.01 * GLIDE_MAX_LN_RATIO).exp();
    for (r, extra) in [
        (wide, 0.0),
        (1.0 / wide, 0.0),
        (1.0, -1.0),
        (f64::NAN, 0.0),
        (1.0, 1e9),
    ] {
        assert!(matches!(
            bank.glide(r, extra),
            Err(GlideError::OutOfRange { .. })
        ));
    }
    // A mode at 0.49 fs: a glide that would push it past Nyquist is refused even inside the
    // 1.5 semitones.
    let mut top = OscillatorBank::with_capacity(4, FS, backend);
    let (f, d) = (0.49 * FS, 1.0);
    let tuning = Tuning {
        freq_hz: f,
        decay_per_s: d,
        gain: 1.0,
        from: None,
    };
    top.retune(&[tuning]).unwrap();
    top.set_glide_reference(&[(TAU * f).powi(2) + d * d], &[d], &[0.0])
        .unwrap();
    assert!(top.glide(1.03, 0.0).is_err());
    top.glide(1.01, 0.0).unwrap();
    let (mut a, mut b) = (vec![0f32; 256], vec![0f32; 256]);
    bank.render(&mut a);
    twin.render(&mut b);
    assert_eq!(a, b);
    assert!(!bank.is_gliding());
    // An exact re-tune ends the key.
    let (f, d): (Vec<f64>, Vec<f64>) = (0..bank.len()).map(|i| bank.tuning(i)).unzip();
    bank.retune_in_place(&f, &d).unwrap();
    assert_eq!(bank.glide(1.0, 0.0), Err(GlideError::NotKeyed));
    // Invalid keys: NaN, a negative decay, a law too steep, a length mismatch.
    let wn2 = eigenvalues();
    let good = vec![1.0; 24];
    for (w, dd, p) in [
        (f64::NAN, 1.0, 0.0),
        (1.0, -1.0, 0.0),
        (1.0, 1.0, MAX_DECAY_SLOPE * 1.5),
    ] {
        let mut w2 = wn2.clone();
        w2[3] *= w;
        let (mut ds, mut ps) = (good.clone(), vec![0.0; 24]);
        ds[3] = dd;
        ps[3] = p;
        assert_eq!(
            bank.set_glide_reference(&w2, &ds, &ps),
            Err(GlideError::BadKey { index: 3 })
        );
    }
    assert!(bank.set_glide_reference(&wn2[..3], &good, &good).is_err());
    assert_eq!(bank.glide(1.0, 0.0), Err(GlideError::NotKeyed));
}

#[test]
fn a_drop_moves_the_kept_modes_without_touching_them() {
    // Truth: a twin bank whose dropped modes were never struck (gain 0), so they add nothing;
    // the drop lands off the anchor grid (an odd sample) and, in the second case, mid-glide,
    // with modes dropped from both kernel halves. Only the order of the f32 sums differs:
    // budget 1e-6 of a peak near 10.
    let keep: Vec<bool> = (0..24).map(|i| i % 3 != 1 && i != 22).collect();
    for gliding in [false, true] {
        for backend in SimdBackend::all_available() {
            let mut bank = keyed_bank(backend, 1.0);
            let mut twin = keyed_bank(backend, 1.0);
            twin.reset();
            let gains: Vec<f64> = keep.iter().map(|&k| f64::from(u8::from(k))).collect();
            twin.strike_with_gains(Excitation::Impulse, 1.0, &gains)
                .unwrap();
            twin.set_glide_reference(
                &eigenvalues(),
                &exact(&eigenvalues(), 1.0, 0.0).1,
                &eigenvalues()
                    .iter()
                    .map(|&w2| A2 * w2 / law_decay(w2))
                    .collect::<Vec<_>>(),
            )
            .unwrap();
            let (mut a, mut b) = (vec![0f32; 3_001], vec![0f32; 3_001]);
            bank.render(&mut a);
            twin.render(&mut b);
            let mut worst = 0f32;
            for blk in 1..=40 {
                if gliding {
                    let (r, extra) = path(blk);
                    bank.glide(r, extra).unwrap();
                    twin.glide(r, extra).unwrap();
                }
                if blk == 20 {
                    bank.retain(&keep).unwrap();
                    assert_eq!(bank.len(), keep.iter().filter(|&&k| k).count());
                    assert_eq!(bank.is_gliding(), gliding);
                }
                let (mut x, mut y) = (vec![0f32; 64], vec![0f32; 64]);
                bank.render(&mut x);
                twin.render(&mut y);
                if blk >= 20 {
                    worst = worst.max(max_diff(&x, &y));
                }
            }
            assert!(worst < 1e-5, "{backend:?} gliding {gliding}: {worst:e}");
            // The kept modes keep their tunings (and a glide its key).
            let kept: Vec<usize> = (0..24).filter(|&i| keep[i]).collect();
            for (n, &i) in kept.iter().enumerate() {
                assert_eq!(bank.tuning(n), twin.tuning(i));
            }
            if gliding {
                bank.glide(1.0, 0.0).unwrap();
            }
        }
    }
    let mut bank = keyed_bank(SimdBackend::detect(), 1.0);
    assert_eq!(
        bank.retain(&keep[..5]),
        Err(RetuneError::KeepCount { got: 5, len: 24 })
    );
    assert_eq!(bank.len(), 24);
}
