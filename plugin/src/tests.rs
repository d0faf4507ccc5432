//! Plugin-side logic without a host: the persisted object, the key mappings, parameters to
//! voicing. (The host test, `plugin/tests/host_test.py`, covers the plugin in a real host.)

use super::*;
use keymap::KeyMap;
use materials::MaterialChoice;
use sculpt::Sculpt;

mod mpe;

#[test]
fn the_persisted_object_round_trips_and_rejects_bad_states() {
    let s = Sculpt::default();
    let grid = s.to_grid().unwrap();
    assert_eq!(Sculpt::from_grid(&grid), s);
    assert!(grid.count() > 0);
    // A truncated or oversized state is refused with a one-line reason, never a panic.
    let short = Sculpt {
        bits: s.bits[..s.bits.len() - 1].to_vec(),
        ..s.clone()
    };
    assert!(short
        .to_grid()
        .unwrap_err()
        .to_string()
        .contains("malformed"));
    let huge = Sculpt {
        dims: [64, 64, 64],
        bits: vec![0xFF; 64 * 64 * 8],
        fill: Vec::new(),
    };
    assert!(huge.to_grid().is_err());
    assert!(Sculpt::from_spec("teapot").is_err());
    // The default bowl keeps its partial voxels through a save and load.
    assert!(!grid.is_binary(), "the default bowl has partial voxels");
    assert_eq!(s.to_grid().unwrap(), grid);
    // A state from before partial voxels (no `fill`) still loads, as a binary object.
    let old = serde_json::to_string(&Sculpt {
        fill: Vec::new(),
        ..s.clone()
    })
    .unwrap();
    assert!(!old.contains("fill"));
    let loaded: Sculpt = serde_json::from_str(&old).unwrap();
    assert!(loaded.to_grid().unwrap().is_binary());
    // A fill record that is cut short or names an empty voxel is refused.
    let cut = Sculpt {
        fill: s.fill[..s.fill.len() - 1].to_vec(),
        ..s.clone()
    };
    assert!(cut.to_grid().unwrap_err().to_string().contains("multiple"));
    let mut stray = s.clone();
    stray.fill[..4].copy_from_slice(&0u32.to_le_bytes());
    assert!(stray
        .to_grid()
        .unwrap_err()
        .to_string()
        .contains("not an occupied voxel"));
}

#[test]
fn positions_cover_the_top_face_and_stay_inside_it() {
    let mut seen = std::collections::HashSet::new();
    for key in 0..=127u8 {
        let p = KeyMap::position_of(key);
        assert!(p.iter().all(|c| (0.0..=1.0).contains(c)), "{key}: {p:?}");
        assert_eq!(p[2], 1.0);
        seen.insert([(p[0] * 1e6) as i64, (p[1] * 1e6) as i64]);
    }
    // 12 columns x 5 rows of distinct points.
    assert_eq!(seen.len(), 60);
}

#[test]
fn presets_and_custom_knobs_reach_the_voicing() {
    let params = ModalForgeParams::default();
    let table = MaterialTable::new();
    let v = params.voicing(&table, 1.0, 1.0);
    let glass = modalforge::material::Material::preset("glass").unwrap();
    assert_eq!(params.material.preset.value(), MaterialChoice::Glass);
    assert_eq!(v.youngs_modulus_pa, glass.youngs_modulus_pa);
    assert_eq!(v.density_kg_m3, glass.density_kg_m3);
    assert!(v.validate().is_ok() && v.normalise);
    // Every preset gives a valid voicing and its own Poisson's ratio.
    for (i, _) in MaterialChoice::variants().iter().enumerate() {
        let choice = MaterialChoice::from_index(i);
        let row = table.get(choice);
        assert!(row.youngs_modulus_pa > 0.0 && row.density_kg_m3 > 0.0);
        assert!((0.0..0.5).contains(&row.poisson_ratio));
    }
    // Pitch bend and the mod wheel scale damping and contact time.
    let v2 = params.voicing(&table, 2.0, 3.0);
    assert!((v2.hardness_s / v.hardness_s - 3.0).abs() < 1e-9);
    match (v.damping, v2.damping) {
        (
            modalforge::engine::DampingParams::Rayleigh { alpha1: a, .. },
            modalforge::engine::DampingParams::Rayleigh { alpha1: b, .. },
        ) => assert!((b / a - 2.0).abs() < 1e-12),
        other => panic!("glass is Rayleigh: {other:?}"),
    }
}

#[test]
fn the_solve_source_asks_once_per_change() {
    let params = Arc::new(ModalForgeParams::default());
    let table = Arc::new(MaterialTable::new());
    let mut source = solve_source(
        params.clone(),
        table,
        modalforge::engine::AnswerSwitch::default(),
    );
    let first = source().expect("the first poll asks for the object");
    assert_eq!(first.grid.dims(), Sculpt::default().dims);
    assert!(source().is_none(), "nothing changed");
    let bar = modalforge::shape::VoxelGrid::from_fn([8, 2, 2], 1.0, |_, _, _| true).unwrap();
    *params.object.write().unwrap() = Sculpt::from_grid(&bar);
    assert!(source().is_some(), "a new object is solved");
    assert!(source().is_none());
}

#[test]
fn parameter_ids_are_frozen_and_hosts_see_seven_groups() {
    // The ids and order as shipped before the groups existed: a project saved then stores
    // its values under these ids, so they must never change (the groups only add a path).
    const FROZEN: [(&str, &str); 27] = [
        ("mat", "Material"),
        ("e", "Material"),
        ("rho", "Material"),
        ("nu", "Material"),
        ("size", "Material"),
        ("dmod", "Damping"),
        ("a1", "Damping"),
        ("a2", "Damping"),
        ("mu1", "Damping"),
        ("mu2", "Damping"),
        ("hard", "Strike"),
        ("velh", "Strike"),
        ("hx", "Strike"),
        ("hy", "Strike"),
        ("hz", "Strike"),
        ("fnrm", "Strike"),
        ("faz", "Strike"),
        ("fel", "Strike"),
        ("gain", "Play"),
        ("budget", "Play"),
        ("map", "Play"),
        ("mute", "Play"),
        ("mdec", "Play"),
        ("solver", "Solver"),
        ("answer", "Solver"),
        ("elem", "Solver"),
        ("modes", "Solver"),
    ];
    // Added later, after every frozen one.
    // Hosts address parameters by id (a hash of it), not by position, so a later one may
    // join its group in the middle.
    const ADDED: [(&str, &str); 9] = [
        ("expr", "Expression"),
        ("bendr", "Expression"),
        ("pdec", "Expression"),
        ("brt", "Expression"),
        ("rin", "Resonator"),
        ("rmix", "Resonator"),
        ("rlow", "Resonator"),
        ("rhigh", "Resonator"),
        ("held", "Resonator"),
    ];
    let params = ModalForgeParams::default();
    let map: Vec<(String, String)> = params
        .param_map()
        .into_iter()
        .map(|(id, _, group)| (id, group))
        .collect();
    let want: Vec<(String, String)> = FROZEN
        .iter()
        .chain(&ADDED)
        .map(|(id, group)| (id.to_string(), group.to_string()))
        .collect();
    assert_eq!(map, want);
}
