//! Mutation fuzzing of what the plugin reads from outside (issue 16): the persisted object
//! (`#[persist = "object"]`, JSON in the DAW project), the persisted recording (`#[persist =
//! "recording"]`) and preset files. Same harness as the root crate's `tests/fuzz.rs`
//! (`FUZZ_ITERATIONS`, `FUZZ_SEED`): no input may panic or hang, and what loads goes on
//! through the path the plugin takes next (the grid the worker solves, the recording the
//! engine plays, the preset's object).

use modalforge::engine::recorded::RecordedObject;
use modalforge::engine::Voicing;
use modalforge::material::Material;
use modalforge::modes::ModeRecord;
use modalforge_plugin::presets::Preset;
use modalforge_plugin::sculpt::Sculpt;

#[path = "../../tests/common/fuzzing.rs"]
mod fuzzing;
use fuzzing::fuzz;

#[test]
fn persisted_objects() {
    let seed = serde_json::to_vec(&Sculpt::from_spec("bowl:d=8,wall=2").unwrap()).unwrap();
    fuzz("persisted object", &seed, |b| {
        if let Ok(s) = serde_json::from_slice::<Sculpt>(b) {
            if let Ok(g) = s.to_grid() {
                assert!(g.count() > 0 && g.dims().iter().all(|&d| d <= 32));
            }
        }
    });
}

#[test]
fn persisted_recordings() {
    let voicing = Voicing::from_material(&Material::preset("brass").unwrap(), 0.2).unwrap();
    let modes: Vec<ModeRecord> = (1..6)
        .map(|i| ModeRecord {
            freq_hz: 300.0 * i as f64 * 1.07f64.powi(i),
            decay_per_s: 2.0 * i as f64,
            gain: 1.0 / i as f64,
        })
        .collect();
    let object = RecordedObject::new("bell", &modes, &voicing).unwrap();
    let seed = serde_json::to_vec(&Some(object)).unwrap();
    fuzz("persisted recording", &seed, |b| {
        if let Ok(Some(r)) = serde_json::from_slice::<Option<RecordedObject>>(b) {
            if r.validate().is_ok() {
                // What the engine reads of a valid one is finite.
                assert!(r.eigenvalues.iter().all(|l| l.is_finite() && *l > 0.0));
                assert!(r
                    .forces
                    .iter()
                    .chain(&r.decay_ratios)
                    .all(|x| x.is_finite()));
            }
        }
    });
}

#[test]
fn preset_files() {
    let seed = Preset::builtin()[0].to_toml();
    fuzz("preset toml", seed.as_bytes(), |b| {
        let text = String::from_utf8_lossy(b);
        if let Ok(p) = Preset::from_toml(&text, "fuzz.toml") {
            if let Ok(s) = p.sculpt() {
                let _ = s.to_grid();
            }
        }
    });
}
