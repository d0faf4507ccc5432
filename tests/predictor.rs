//! The shipped neural predictor (issue 12): its weights load, and on held-out objects (shape
//! families training never saw) it predicts FEM's band representation within stated bounds.
//! The truth is the product's FEM, solved here for each object; no training runs in the tests.

mod common;

use modalforge::predictor::dataset::{self, Record};
use modalforge::predictor::{metrics, Predictor, SHIPPED_LABEL_ELEMENT};

/// Held-out objects scored (a plate with holes, a handled cup, alternately).
const OBJECTS: usize = 4;
/// Bounds on the four objects' figures. The shipped weights and pitch index measure recall
/// 63.8 %, precision 69.0 %, amplitude MSE 0.0833 and a median pitch error of 37.5 cents on
/// them (`modalforge predictor eval --limit 4` on a `modalforge dataset --count 1 --held-out
/// 4 --seed 1 --element hex27x2`, masks at `MASK_LOGIT_THRESHOLD`; the network alone: 56.0 %,
/// 50.2 %, 0.092, 44.9 cents; the band centres 40.7 cents). The mask and amplitude bounds sit
/// a fifth away; the pitch bound is the band centres' median less a little, so a pitch index
/// that stops finding these objects' twins (or bands played at their centres) fails it, while
/// the computation itself is deterministic. A regression of the weights, the input layout,
/// the decode, the threshold or the pitch index fails them. (These are interim figures, short
/// of the goals: assets/predictor/README.md.)
const RECALL_BOUND: f64 = 0.51;
const PRECISION_BOUND: f64 = 0.55;
const MSE_BOUND: f64 = 0.100;
const CENTS_BOUND: f64 = 40.0;

#[test]
fn the_shipped_weights_predict_held_out_objects_within_bounds() {
    let predictor = Predictor::shipped().expect("the shipped weights load");
    let mut scores = Vec::new();
    for index in 0..OBJECTS {
        let (family, grid) = dataset::object(1, true, index);
        let truth = Record::label(family, grid.clone(), SHIPPED_LABEL_ELEMENT).expect("FEM labels");
        // The objects are 16-30 voxels long, within the training sizes: the network sees them
        // as it saw its training input (no resample), as `predictor eval` does.
        let p = predictor.predict(&grid).expect("predicts");
        scores.push(metrics::score(&p.prediction.to_encoding(), &truth.labels));
    }
    let m = metrics::summarise(&scores);
    assert!(m.mask_recall > RECALL_BOUND, "{m}");
    assert!(m.mask_precision > PRECISION_BOUND, "{m}");
    assert!(m.amplitude_mse < MSE_BOUND, "{m}");
    assert!(m.pitch_median_cents < CENTS_BOUND, "{m}");
}

#[test]
fn the_cli_predicts_and_bad_weights_are_one_clear_line() {
    let run = common::modalforge;
    let out = run(&[
        "modes",
        "--shape",
        "bowl:d=12,wall=2",
        "--material",
        "glass",
        "--size",
        "0.2",
        "--solver",
        "neural",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["solver"], "neural");
    let modes = report["modes"].as_array().unwrap();
    // The modes the library predicts for the same grid and strike (`modes` prints the same).
    assert!(
        !modes.is_empty(),
        "the masks play nothing at the default hit"
    );
    for m in modes {
        let f = m["freq_hz"].as_f64().unwrap();
        assert!(f.is_finite() && f > 0.0 && m["gain"].as_f64().unwrap().is_finite());
    }
    // The resample (a 12-voxel bowl is under the training sizes) is said on stderr.
    assert!(String::from_utf8_lossy(&out.stderr).contains("resampled"));
    let bad = run(&[
        "modes",
        "--shape",
        "bar:16x2x2",
        "--solver",
        "neural",
        "--weights",
        "/nonexistent.bpk",
    ]);
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("/nonexistent.bpk"), "{err}");
    let garbage = std::env::temp_dir().join("modalforge-garbage.bpk");
    std::fs::write(&garbage, b"not weights").unwrap();
    let bad = run(&[
        "modes",
        "--shape",
        "bar:16x2x2",
        "--solver",
        "neural",
        "--weights",
        garbage.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    assert_eq!(
        String::from_utf8_lossy(&bad.stderr).trim().lines().count(),
        1
    );
}
