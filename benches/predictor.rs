//! The neural predictor's cost on one core (issue 12): the network on a shape (resampled to
//! the box, trunk, features back to the CPU) and one strike's decode (the struck cell found, its head evaluated, the
//! modal forces written: what the engine does per hit).
//!
//! `cargo bench --bench predictor` (criterion). Shapes: the plugin's default glass bowl
//! (`bowl:d=16,wall=2`, resampled to 32) and a 32-voxel solid sphere; the shipped weights.

use criterion::Criterion;
use modalforge::modal::Hit;
use modalforge::predictor::Predictor;
use modalforge::shape::spec::ShapeSpec;
use std::hint::black_box;

fn grid(spec: &str) -> modalforge::shape::VoxelGrid {
    let ShapeSpec::Primitive { shape, .. } = spec.parse::<ShapeSpec>().expect("shape") else {
        panic!("{spec}: not a primitive")
    };
    shape.rasterize(1.0, 0.01).expect("rasterises")
}

fn main() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("one thread");
    let predictor = Predictor::shipped().expect("shipped weights");
    let mut c = Criterion::default().configure_from_args();
    {
        for spec in ["bowl:d=16,wall=2", "sphere:d=32"] {
            let g = grid(spec);
            // burn's flex backend runs on the calling thread's rayon pool: one thread.
            c.bench_function(&format!("predict {spec} (one core)"), |b| {
                b.iter(|| pool.install(|| predictor.predict(black_box(&g)).expect("predicts")))
            });
            let p = predictor.predict(&g).expect("predicts");
            let [nx, ny, nz] = g.dims();
            let h = g.voxel_size_m();
            let hit = Hit {
                point_m: [0.37 * nx as f64 * h, 0.41 * ny as f64 * h, nz as f64 * h],
                direction: None,
            };
            let mut forces = vec![0.0; p.mode_count()];
            c.bench_function(&format!("strike decode {spec}"), |b| {
                b.iter(|| p.reference_forces_into(black_box(&hit), h, &mut forces))
            });
        }
    }
    c.final_summary();
}
