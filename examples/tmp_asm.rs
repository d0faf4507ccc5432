use modalforge::fem::{ElementKind, FemModel};
use modalforge::shape::spec::ShapeSpec;
use std::time::Instant;
fn main() {
    faer::set_global_parallelism(faer::Par::Seq);
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map(String::as_str).unwrap_or("partial");
    let d = args.get(2).map(String::as_str).unwrap_or("32");
    let spec = format!("bowl:d={d},wall=2");
    let ShapeSpec::Primitive { shape, .. } = spec.parse::<ShapeSpec>().unwrap() else {
        unreachable!()
    };
    let grid = if which == "partial" {
        shape.rasterize(1.0, 1.0).unwrap()
    } else {
        shape.rasterize_staircase(1.0, 1.0).unwrap()
    };
    let mut best = f64::INFINITY;
    for _ in 0..40 {
        let t = Instant::now();
        let m = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.24).unwrap();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(m);
    }
    println!("{which} {spec} best {best:.2} ms");
}
