//! Mutation fuzzing of every parser and decoder a stranger's file reaches (issue 16): `.vox`,
//! OBJ, ASCII and binary STL, mode JSON, material TOML, WAV, Scala `.scl`/`.kbm` tunings and
//! the `--shape` spec syntax.
//!
//! A small libFuzzer-style mutator (bit flips, random bytes, "interesting" values such as
//! `NaN`, `1e308`, `-1` and `0xFFFFFFFF`, insertions, deletions, duplicated ranges, truncation)
//! works from a valid seed file of each format, deterministically from a seed
//! ([`fuzzing`]; the plugin's persisted state is fuzzed by `plugin/tests/state_fuzz.rs`).
//! Every input must come back as a value or an error: no panic, no hang (an input over
//! [`fuzzing::SLOW_INPUT_S`] fails), and what parses goes on through the path the product
//! takes next
//! (voxelise the mesh, cull the modes, voice the material, rasterise the spec), where a NaN or
//! a huge size would surface. The suite runs [`fuzzing::DEFAULT_ITERATIONS`] inputs per format;
//! `FUZZ_ITERATIONS=1000000 cargo test --release --test fuzz` is the long run (the issue's
//! 10^6 executions), `FUZZ_SEED` another sequence. A failure prints the format, the seed and
//! the iteration, which reproduce the input.

use modalforge::engine::Voicing;
use modalforge::material::Material;
use modalforge::modes::{CullSettings, ModeSet};
use modalforge::shape::spec::ShapeSpec;
use modalforge::shape::{mesh, vox, VoxelGrid};
use std::path::Path;

#[path = "common/fuzzing.rs"]
mod fuzzing;
use fuzzing::fuzz;

/// A path in a fresh temporary directory for the file-based readers.
fn scratch(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join(name);
    (dir, path)
}

/// What the product does with a grid from a file: counts, crops, bounds.
fn use_grid(g: &VoxelGrid) {
    let c = g.cropped();
    assert!(c.count() <= g.count());
    assert!(g.voxel_size_m().is_finite() && g.voxel_size_m() > 0.0);
}

#[test]
fn vox_files() {
    let grid = VoxelGrid::from_fn([5, 4, 3], 0.01, |x, y, z| {
        !((x + y + z) as usize).is_multiple_of(3)
    })
    .unwrap();
    let seed = vox::encode_vox(&grid).unwrap();
    fuzz("vox", &seed, |b| {
        if let Ok(g) = vox::parse_vox(b, "fuzz.vox", 0.01) {
            use_grid(&g);
        }
    });
}

/// A 2 x 1 x 1 box as twelve outward triangles.
fn brick() -> Vec<[[f32; 3]; 3]> {
    let v = [
        [0., 0., 0.],
        [2., 0., 0.],
        [2., 1., 0.],
        [0., 1., 0.],
        [0., 0., 1.],
        [2., 0., 1.],
        [2., 1., 1.],
        [0., 1., 1.],
    ];
    let quads = [
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 1, 5, 4],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 0, 4, 7],
    ];
    quads
        .iter()
        .flat_map(|q| [[v[q[0]], v[q[1]], v[q[2]]], [v[q[0]], v[q[2]], v[q[3]]]])
        .collect()
}

/// Reads a mesh file the way `--shape FILE` does and voxelises what parses (at 8 voxels, to
/// keep the run short; the voxeliser sees the same coordinates at any resolution).
fn mesh_target(path: &Path) -> impl FnMut(&[u8]) + '_ {
    move |b| {
        std::fs::write(path, b).expect("write");
        if let Ok(m) = mesh::read_mesh(path) {
            if let Ok(g) = mesh::voxelize(&m, 8, "fuzz") {
                use_grid(&g);
            }
        }
    }
}

#[test]
fn obj_files() {
    let mut text = String::new();
    let tris = brick();
    for t in &tris {
        for p in t {
            text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
    }
    for i in 0..tris.len() {
        text += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
    }
    let (_dir, path) = scratch("fuzz.obj");
    fuzz("obj", text.as_bytes(), mesh_target(&path));
}

#[test]
fn ascii_stl_files() {
    let mut text = String::from("solid brick\n");
    for t in brick() {
        text += "facet normal 0 0 0\nouter loop\n";
        for p in t {
            text += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        text += "endloop\nendfacet\n";
    }
    text += "endsolid brick\n";
    let (_dir, path) = scratch("fuzz.stl");
    fuzz("ascii stl", text.as_bytes(), mesh_target(&path));
}

#[test]
fn binary_stl_files() {
    let tris = brick();
    let mut bytes = vec![0u8; 80];
    bytes.extend((tris.len() as u32).to_le_bytes());
    for t in &tris {
        bytes.extend([0u8; 12]);
        for p in t {
            for c in p {
                bytes.extend(c.to_le_bytes());
            }
        }
        bytes.extend([0u8; 2]);
    }
    let (_dir, path) = scratch("fuzz.stl");
    fuzz("binary stl", &bytes, mesh_target(&path));
}

#[test]
fn mode_files() {
    let seed = br#"{"modes":[{"freq_hz":440.0,"decay_per_s":3.5,"gain":0.5},
        {"freq_hz":1234.5,"decay_per_s":12.0,"gain":-0.25},
        {"freq_hz":20000.0,"decay_per_s":0.0,"gain":1e-3}]}"#;
    fuzz("mode json", seed, |b| {
        let text = String::from_utf8_lossy(b);
        if let Ok(set) = ModeSet::from_json_str(&text, Path::new("fuzz.json")) {
            if let Ok((p, _)) = set.playable(48_000.0, &CullSettings::default()) {
                assert!(p.freq_hz().iter().all(|f| f.is_finite() && *f > 0.0));
            }
        }
    });
}

#[test]
fn material_files() {
    let seed = Material::preset("steel").unwrap().to_toml().unwrap();
    fuzz("material toml", seed.as_bytes(), |b| {
        let text = String::from_utf8_lossy(b);
        if let Ok(m) = Material::from_toml(&text, "fuzz.toml") {
            if let Some(v) = Voicing::from_material(&m, 0.2) {
                // A material that loads is one the engine accepts.
                v.validate().expect("a loaded material voices");
            }
        }
    });
}

#[test]
fn wav_files() {
    let (_dir, path) = scratch("fuzz.wav");
    let signal: Vec<f64> = (0..400).map(|i| (i as f64 * 0.3).sin() * 0.5).collect();
    modalforge::analysis::wav::write_mono(&path, 8_000.0, &signal).unwrap();
    let seed = std::fs::read(&path).unwrap();
    fuzz("wav", &seed, |b| {
        std::fs::write(&path, b).expect("write");
        if let Ok((samples, rate)) = modalforge::analysis::wav::read_mono(&path) {
            assert!(rate.is_finite() && rate > 0.0);
            assert!(samples.iter().all(|s| s.is_finite()));
        }
    });
}

#[test]
fn shape_specs() {
    for seed in [
        "bowl:d=16,wall=2",
        "bar:l=30,w=3,h=3",
        "cup:d=16,h=24,wall=1",
        "box:x=16,y=12,z=10,hollow=1",
    ] {
        fuzz("shape spec", seed.as_bytes(), |b| {
            let text = String::from_utf8_lossy(b);
            if let Ok(ShapeSpec::Primitive { shape, .. }) = text.parse::<ShapeSpec>() {
                // What `--shape` rasterises; a refused size is an error, not an allocation.
                if let Ok(g) = shape.rasterize(1.0, 0.01) {
                    use_grid(&g);
                }
            }
        });
    }
}

#[test]
fn scala_files() {
    use modalforge::tuning::{Mapping, Scale, Tuning};
    let scl = "! just.scl\nJust major\n7\n9/8\n5/4\n4/3\n3/2\n5/3\n15/8\n2/1\n";
    let kbm = "! white keys\n12\n0\n127\n60\n69\n440.0\n7\n0\nx\n1\nx\n2\n3\nx\n4\nx\n5\nx\n6\n";
    // Every key of what parses is a positive finite frequency or silent.
    let check = |t: &Tuning| {
        assert!(t.table().iter().all(|f| f.is_finite() && *f >= 0.0));
    };
    let mapping = Mapping::parse(kbm, "fuzz.kbm").unwrap();
    fuzz("scl", scl.as_bytes(), |b| {
        if let Ok(scale) = Scale::parse(&String::from_utf8_lossy(b), "fuzz.scl") {
            check(&Tuning {
                scale,
                mapping: mapping.clone(),
            });
        }
    });
    let scale = Scale::parse(scl, "fuzz.scl").unwrap();
    fuzz("kbm", kbm.as_bytes(), |b| {
        if let Ok(mapping) = Mapping::parse(&String::from_utf8_lossy(b), "fuzz.kbm") {
            check(&Tuning {
                scale: scale.clone(),
                mapping,
            });
        }
    });
}

#[test]
fn the_committed_corpus_is_found() {
    // The regression inputs are read from tests/data/fuzz (a wrong path would silently run
    // none of them).
    for (format, at_least) in [("vox", 2), ("wav", 1), ("binary stl", 1), ("shape spec", 3)] {
        let files = fuzzing::corpus(format);
        assert!(files.len() >= at_least, "{format}: {}", files.len());
    }
}
