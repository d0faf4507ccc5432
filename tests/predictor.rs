//! The shipped neural predictor (issue 12): its weights load, and on held-out objects (shape
//! families training never saw) it predicts FEM's band representation within stated bounds.
//! The truth is the product's FEM, solved here for each object; no training runs in the tests.

mod common;

use modalforge::predictor::dataset::{self, Record};
use modalforge::predictor::{metrics, Predictor, SHIPPED_LABEL_ELEMENT};

/// Held-out objects scored (a plate with holes, a handled cup, alternately).
const OBJECTS: usize = 4;
/// Bounds on the four objects' figures. The shipped weights, band network and pitch index
/// measure recall 56.1 %, precision 68.4 %, amplitude MSE 0.118 and a median pitch error of
/// 44.6 cents on them (`modalforge predictor eval --weights assets/predictor/modenet.bpk
/// --band-weights assets/predictor/bandnet.bpk` on a `modalforge dataset --count 1 --held-out
/// 4 --seed 1 --element hex27x2`, masks at `MASK_LOGIT_THRESHOLD` with the pitch index's
/// presence shift; the band centres 45.3 cents; stop 77's band network and operating point:
/// 61.2 %, 64.0 %, 0.105; stop 76's predictor, the cell network's own presence: 56.1 %,
/// 70.3 %, 0.107). The mask and amplitude bounds sit a fifth away. The plates' holes go
/// through them since stop 76, so no indexed shape is a near twin of these four and their
/// bands play at the network's frequencies: the pitch bound is the band centres' median plus
/// a little, which bands played off their places (a decode or pitch index fault) exceed; the
/// computation itself is deterministic. A regression of the weights, the band network, the
/// input layout, the decode, the threshold or the pitch index fails them. (These are interim
/// figures, short of the goals: assets/predictor/README.md.)
const RECALL_BOUND: f64 = 0.44;
const PRECISION_BOUND: f64 = 0.54;
const MSE_BOUND: f64 = 0.141;
const CENTS_BOUND: f64 = 46.0;

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

/// How far each of FEM's lowest ten modes of a compact solid may be from the nearest partial
/// the predictor plays. Measured at most 2.3 % (the sphere) and 2.2 % (the block): Ritz over
/// quintics bounds the modes from above, by a few percent on the higher ones (the module docs
/// of `predictor::ritz`), and the sphere's 16 voxels are resampled to the box's 32, a
/// slightly different staircase than FEM's. A semitone is 6 %.
const COMPACT_PERCENT: f64 = 3.0;

#[test]
fn a_compact_solid_sounds_at_fem_s_frequencies_not_silence() {
    // Compact solids ring at the top of the network's bands or above them: before the Ritz
    // modes (stop 64) the predictor played nothing for them. Each of FEM's (hex27x2) lowest
    // ten modes must have a played partial (non-zero gain at the default hit) within
    // COMPACT_PERCENT.
    use modalforge::basis::{Hit, ModeBasis};
    use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
    use modalforge::material::Material;
    use modalforge::shape::VoxelGrid;
    let predictor = Predictor::shipped().expect("the shipped weights load");
    let steel = Material::parse("steel").unwrap();
    let h = 0.0125;
    let sphere = VoxelGrid::from_fn([16, 16, 16], h, |x, y, z| {
        (x - 8.0).powi(2) + (y - 8.0).powi(2) + (z - 8.0).powi(2) < 64.0
    })
    .unwrap();
    let block = VoxelGrid::from_fn([16, 12, 10], h, |_, _, _| true).unwrap();
    for (name, grid) in [("sphere", sphere), ("block", block)] {
        let hit = Hit {
            point_m: [
                0.3 * 16.0 * h,
                0.4 * grid.dims()[1] as f64 * h,
                grid.dims()[2] as f64 * h,
            ],
            direction: Some([0.3, 0.2, -0.93]),
        };
        let played: Vec<f64> = predictor
            .predict(&grid)
            .expect("predicts")
            .strike(&steel, h, &hit)
            .into_iter()
            .filter(|m| m.gain != 0.0 && m.gain.is_finite())
            .map(|m| m.natural_hz)
            .collect();
        assert!(!played.is_empty(), "{name}: the predictor plays nothing");
        let options = EigenOptions {
            count: ModeCount::First(10),
            ..EigenOptions::default()
        };
        let fem = ModeBasis::solve(
            &grid,
            SHIPPED_LABEL_ELEMENT,
            steel.poisson_ratio,
            SolverKind::Auto,
            &options,
        )
        .expect("FEM");
        let scale = steel.youngs_modulus_pa / (steel.density_kg_m3 * h * h);
        let mut worst = 0.0f64;
        for l in &fem.solution.eigenvalues {
            let f = (l * scale).sqrt() / std::f64::consts::TAU;
            let off = played
                .iter()
                .map(|p| 100.0 * (p - f).abs() / f)
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(off);
            assert!(
                off < COMPACT_PERCENT,
                "{name}: FEM {f:.0} Hz, nearest played {off:.2} % off: {played:?}"
            );
        }
        println!("{name}: FEM's lowest ten modes at most {worst:.2} % from a played partial");
    }
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
