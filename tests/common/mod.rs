//! Independent references shared by the integration tests.
#![allow(dead_code)]

pub mod alloc;
pub mod eigen;
pub mod smooth;
pub mod soak;

/// Runs the `modalforge` binary with `args`; its exit status and output.
pub fn modalforge(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_modalforge"))
        .args(args)
        .output()
        .expect("the modalforge binary runs")
}

/// 4x4 matrix exponential by scaling and squaring with a Taylor series.
fn expm(a: [[f64; 4]; 4]) -> [[f64; 4]; 4] {
    let norm = a
        .iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let s = (norm / 0.25).log2().ceil().max(0.0) as i32;
    let scale = 0.5f64.powi(s);
    let b = a.map(|r| r.map(|v| v * scale));
    let mul = |x: &[[f64; 4]; 4], y: &[[f64; 4]; 4]| {
        let mut z = [[0.0; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                z[i][j] = (0..4).map(|k| x[i][k] * y[k][j]).sum();
            }
        }
        z
    };
    let mut result = [[0.0; 4]; 4];
    let mut term = [[0.0; 4]; 4];
    for i in 0..4 {
        result[i][i] = 1.0;
        term[i][i] = 1.0;
    }
    for k in 1..30 {
        term = mul(&term, &b).map(|r| r.map(|v| v / k as f64));
        for i in 0..4 {
            for j in 0..4 {
                result[i][j] += term[i][j];
            }
        }
    }
    for _ in 0..s {
        result = mul(&result, &result);
    }
    result
}

/// Free-free Timoshenko beam bending frequencies (rad/s), from the transfer matrix of the
/// state (w, psi, M, V): roots of the free-end determinant, found by scanning and bisection.
pub fn timoshenko(e: f64, rho: f64, nu: f64, l: f64, b: f64, h: f64, count: usize) -> Vec<f64> {
    let (area, inertia) = (b * h, b * h.powi(3) / 12.0);
    let g = e / (2.0 * (1.0 + nu));
    let kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu); // Cowper, rectangle
    let det = |w: f64| {
        let a = [
            [0.0, 1.0, 0.0, 1.0 / (kappa * g * area)],
            [0.0, 0.0, 1.0 / (e * inertia), 0.0],
            [0.0, -rho * inertia * w * w, 0.0, -1.0],
            [-rho * area * w * w, 0.0, 0.0, 0.0],
        ];
        let t = expm(a.map(|r| r.map(|v| v * l)));
        t[2][0] * t[3][1] - t[2][1] * t[3][0]
    };
    // Euler-Bernoulli first root sets the scan scale.
    let w1 = 22.373 * (e * inertia / (rho * area * l.powi(4))).sqrt();
    let mut roots = Vec::new();
    let step = w1 * 0.01;
    let mut w = w1 * 0.3;
    let mut prev = det(w);
    while roots.len() < count {
        let next = det(w + step);
        if prev.signum() != next.signum() {
            let (mut lo, mut hi) = (w, w + step);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if det(mid).signum() == det(lo).signum() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            roots.push(0.5 * (lo + hi));
        }
        w += step;
        prev = next;
    }
    roots
}

/// Two 2x2x2 cubes in a 5x5x5 grid, the second moved by `offset` voxels: sharing a face
/// (`[2, 0, 0]`), an edge (`[2, 2, 0]`), a corner (`[2, 2, 2]`) or apart (`[3, 3, 3]`).
pub fn two_cubes(offset: [usize; 3]) -> modalforge::shape::VoxelGrid {
    let mut g = modalforge::shape::VoxelGrid::new([5, 5, 5], 1.0).unwrap();
    for z in 0..2 {
        for y in 0..2 {
            for x in 0..2 {
                g.set(x, y, z, true);
                g.set(x + offset[0], y + offset[1], z + offset[2], true);
            }
        }
    }
    g
}
