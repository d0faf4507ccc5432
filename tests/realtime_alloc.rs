//! The banks' strike/render/process/reset never allocate (the audio-thread contract), checked
//! with a counting global allocator around a session of strikes and renders.

use modalforge::modes::{CullSettings, ModeSet};
use modalforge::synth::{
    BiquadBank, Excitation, ForcePulse, NoiseForce, OscillatorBank, SimdBackend,
};
mod common;

use common::alloc::{self, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn strikes_renders_and_processing_do_not_allocate() {
    let n = 500;
    let f: Vec<f64> = (0..n).map(|i| 60.0 + 40.0 * i as f64).collect();
    let modes = ModeSet::new(f, vec![3.0; n], vec![0.5; n]).unwrap();
    let (playable, _) = modes.playable(48000.0, &CullSettings::default()).unwrap();
    let gains = vec![0.25; playable.len()];
    for backend in [
        SimdBackend::detect(),
        SimdBackend::Portable,
        SimdBackend::Scalar,
    ] {
        // Preparation may allocate.
        let mut osc = OscillatorBank::with_backend(&playable, backend);
        let mut biquad = BiquadBank::from_modes_with_backend(&playable, backend);
        let mut pulse = ForcePulse::new(Excitation::mallet(1e-3).unwrap(), 1.0, 48000.0);
        let mut noise = NoiseForce::new(0.1, 3000.0, 48000.0, 7);
        let mut out = vec![0f32; 4096];
        let mut force = vec![0f32; 4096];
        let mallet = Excitation::mallet(0.7e-3).unwrap();

        let (allocs, frees) = (alloc::allocations(), alloc::frees());
        alloc::marked(|| {
            for round in 0..20 {
                let len = 37 + 61 * round;
                osc.strike(mallet, 0.5).unwrap();
                osc.render(&mut out[..len]);
                osc.strike_with_gains(Excitation::Impulse, 1.0, &gains)
                    .unwrap();
                osc.render(&mut out[len..]);
                force.fill(0.0);
                pulse.add_to(&mut force[..len]);
                noise.add_to(&mut force[len..]);
                biquad.process(&force, &mut out);
            }
            osc.reset();
            biquad.reset();
        });
        assert_eq!(
            alloc::allocations() - allocs,
            0,
            "{backend:?}: the real-time path allocated"
        );
        assert_eq!(
            alloc::frees() - frees,
            0,
            "{backend:?}: the real-time path freed"
        );
        assert!(out.iter().all(|x| x.is_finite()));
    }
}
