//! The predictor's answer above its band range: a compact shape's lowest modes by Rayleigh-Ritz
//! over global polynomials, computed from the moments of its fills in a few milliseconds.
//!
//! Where it sits: [`super::Predictor::predict`] runs [`RitzModes::above_bands`] on the
//! network's input after the network. The network answers in 32 bands up to
//! [`HIGH_HZ`] at the reference (Deep-Modal's range), so a compact solid, whose spectrum
//! starts at the top of that range or above it (a 32-voxel steel sphere at the reference rings
//! from 9.9 kHz), got no band at all and the predictor played silence. For those shapes the
//! Ritz modes take over from their lowest mode up (the network's bands from there up are
//! dropped: the same modes, or none), placed at their own frequencies and voiced by their own
//! mode shapes ([`RitzModes::displacement`]), as FEM modes are.
//!
//! The method (Rayleigh-Ritz, the classical energy method for plates and solids): each
//! displacement component is a combination of the monomials `xi^i eta^j zeta^k`,
//! `i + j + k <= degree`, in coordinates centred on the fills' centroid and scaled by its
//! half-extent. The stiffness and mass matrices in that basis are sums of the fills' moments
//! `int xi^a eta^b zeta^c dV` (isotropic elasticity, `E = rho = 1`, voxel edge 1: the
//! reference units of [`super::bands::reference_hz`]; a voxel's fill fraction weights it), and
//! the moments of a voxel grid are separable: three passes over the grid. The generalised
//! eigenproblem is solved dense after whitening the basis' Gram matrix (near-dependent
//! monomials, as across a thin plate, are dropped). Ritz values bound the continuum's
//! eigenvalues from above.
//!
//! Where it is worth playing, measured (stop 64, temporary harnesses, against hex27x2 FEM):
//! - compact solids, degree 5: the lowest 15-20 modes of a sphere, a cube, a cylinder, an
//!   ellipsoid and a 24 x 16 x 12 box within 0-2.2 % (a few modes at 3-4 %), in 5-7 ms;
//! - not thin walls: global polynomials cannot bend a thin curved wall without stretching it,
//!   nor move a handle on its own. The lowest mode, octaves above FEM (degree 4, median): solids
//!   +0.02, plates with holes +0.04, differences +0.07, blobs +0.16, shells +0.82, unions
//!   +0.83, cups with handles +1.33. Hence the gate on the mean wall ([`MIN_WALL_VOXELS`]).
//! - As an input to the network (its lowest modes and per-band counts fed to the global
//!   branch, fine-tuned from the shipped weights) it moved the held-out figures by under a
//!   point (ARCHITECTURE.md, "Measured and not kept: the Ritz modes as the network's
//!   input").

use super::bands::{band_edges_hz, reference_hz, HIGH_HZ};
use super::dataset::REFERENCE_POISSON;
use crate::shape::{ops, VoxelGrid};
use faer::Mat;

/// Highest total degree of the monomials in each displacement component: 56 monomials, a
/// 168 x 168 eigenproblem. Degree 4 missed a cube's and a box's 12th-20th modes by 6-17 %.
pub const RITZ_DEGREE: usize = 5;
/// The degree of the cheap first look (20 monomials, under a millisecond): its lowest value
/// bounds degree 5's from above, so a shape it puts below [`TAKEOVER_BAND`] is left to the
/// network without the full solve.
pub const SCREEN_DEGREE: usize = 3;
/// The highest degree [`RitzModes::solve`] takes (its monomials fit a stack buffer).
pub const MAX_DEGREE: usize = 6;
/// Ritz modes played: degree 5 keeps about this many within a few percent on compact solids.
pub const RITZ_MODES: usize = 16;
/// The Ritz modes take over where their lowest lies in this band or above (its lower edge,
/// 7.0 kHz at the reference): the top of the network's range, where it predicts least
/// surely (measured on 1,650 objects' labels, stop 64, with degree 4's lowest 12 modes: from
/// there up Ritz's bands scored within 2 points of the network's, and past the range the
/// network has none).
pub const TAKEOVER_BAND: usize = 28;
/// The mean wall, `2 V / A` in voxels of the network's input, below which the Ritz modes are
/// not trusted (thin walls come out stiff, above). The training set's solids and blobs looked
/// at measure 3.3-6, its shells 0.8-0.9, a 2-voxel plate 2.
pub const MIN_WALL_VOXELS: f64 = 3.0;

/// Monomials of total degree up to [`MAX_DEGREE`].
const MAX_MONOMIALS: usize = (MAX_DEGREE + 1) * (MAX_DEGREE + 2) * (MAX_DEGREE + 3) / 6;

/// Why the Ritz modes could not be computed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RitzError {
    /// The grid holds no material.
    #[error("the shape is empty: fill some voxels")]
    Empty,
    /// The degree is above [`MAX_DEGREE`].
    #[error("Ritz degree {0} is above {MAX_DEGREE}")]
    Degree(usize),
    /// The dense eigensolver failed (non-finite fills).
    #[error("the Ritz eigenproblem did not converge")]
    NoConvergence,
}

/// The monomials' exponents, by total degree.
fn monomials(degree: usize) -> Vec<[usize; 3]> {
    let mut v = Vec::new();
    for d in 0..=degree {
        for i in (0..=d).rev() {
            for j in (0..=d - i).rev() {
                v.push([i, j, d - i - j]);
            }
        }
    }
    v
}

/// A grid's fill fractions, dense, x fastest ([`crate::shape::lattice_index`]).
struct Fills {
    dims: [usize; 3],
    values: Vec<f64>,
}

impl Fills {
    fn of(grid: &VoxelGrid) -> Self {
        Fills {
            dims: grid.dims(),
            values: ops::fill_fractions(grid),
        }
    }
}

/// The moments `int xi^a eta^b zeta^c dV` of a grid's fills (voxel units), `a, b, c <= 2 degree`.
struct Moments {
    order: usize,
    values: Vec<f64>,
    centre: [f64; 3],
    /// Half the largest extent from the centroid: the coordinate scale.
    scale: f64,
}

impl Moments {
    fn of(fills: &Fills, degree: usize) -> Result<Self, RitzError> {
        let [nx, ny, nz] = fills.dims;
        let q = 2 * degree + 1;
        let (mut volume, mut centre) = (0.0, [0.0; 3]);
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for (i, &f) in fills.values.iter().enumerate() {
            if f > 0.0 {
                let c = crate::shape::lattice_coords(i, fills.dims);
                volume += f;
                for a in 0..3 {
                    centre[a] += f * (c[a] as f64 + 0.5);
                    lo[a] = lo[a].min(c[a] as f64);
                    hi[a] = hi[a].max(c[a] as f64 + 1.0);
                }
            }
        }
        if volume <= 0.0 {
            return Err(RitzError::Empty);
        }
        centre = centre.map(|c| c / volume);
        let scale = (0..3)
            .map(|a| (hi[a] - centre[a]).max(centre[a] - lo[a]))
            .fold(0.0, f64::max);
        // Per axis and slice, the exact integrals of xi^k over the slice.
        let slices = |n: usize, c: f64| -> Vec<f64> {
            let mut t = vec![0.0; n * q];
            for i in 0..n {
                let (u0, u1) = ((i as f64 - c) / scale, (i as f64 + 1.0 - c) / scale);
                let (mut p0, mut p1) = (u0, u1);
                for k in 0..q {
                    t[i * q + k] = scale * (p1 - p0) / (k + 1) as f64;
                    p0 *= u0;
                    p1 *= u1;
                }
            }
            t
        };
        let (ix, iy, iz) = (
            slices(nx, centre[0]),
            slices(ny, centre[1]),
            slices(nz, centre[2]),
        );
        // Separable sums, the moment index innermost: over x, then y, then z.
        let mut by_x = vec![0.0; nz * ny * q];
        for (row, line) in fills.values.chunks_exact(nx).enumerate() {
            let out = &mut by_x[row * q..(row + 1) * q];
            for (x, &f) in line.iter().enumerate().filter(|(_, &f)| f > 0.0) {
                for (o, w) in out.iter_mut().zip(&ix[x * q..(x + 1) * q]) {
                    *o += f * w;
                }
            }
        }
        let mut by_y = vec![0.0; nz * q * q];
        for z in 0..nz {
            for y in 0..ny {
                let from = &by_x[(z * ny + y) * q..(z * ny + y + 1) * q];
                let wy = &iy[y * q..(y + 1) * q];
                for (a, &v) in from.iter().enumerate() {
                    let out = &mut by_y[(z * q + a) * q..(z * q + a + 1) * q];
                    for (o, w) in out.iter_mut().zip(wy) {
                        *o += v * w;
                    }
                }
            }
        }
        let mut values = vec![0.0; q * q * q];
        for z in 0..nz {
            let wz = &iz[z * q..(z + 1) * q];
            for ab in 0..q * q {
                let v = by_y[z * q * q + ab];
                for (o, w) in values[ab * q..(ab + 1) * q].iter_mut().zip(wz) {
                    *o += v * w;
                }
            }
        }
        Ok(Moments {
            order: q,
            values,
            centre,
            scale,
        })
    }

    fn get(&self, e: [usize; 3]) -> f64 {
        let q = self.order;
        self.values[(e[0] * q + e[1]) * q + e[2]]
    }
}

/// A shape's lowest Ritz modes (see the module docs), in the grid's own voxel units.
#[derive(Clone, Debug)]
pub struct RitzModes {
    /// Eigenvalues `omega^2`, reference units (`E = rho = 1`, the grid's voxel edge 1),
    /// ascending; the six rigid motions left out.
    pub eigenvalues: Vec<f64>,
    /// Per mode, the monomials' coefficients of the x, then y, then z displacement
    /// (mass-normalised: `int rho u . u dV = 1` over the fills).
    coefficients: Vec<f64>,
    exponents: Vec<[usize; 3]>,
    centre: [f64; 3],
    scale: f64,
}

impl RitzModes {
    /// The lowest `count` non-rigid modes of `grid` over monomials up to `degree`, for
    /// Poisson's ratio `poisson_ratio` (fewer where the basis holds fewer).
    pub fn solve(
        grid: &VoxelGrid,
        degree: usize,
        poisson_ratio: f64,
        count: usize,
    ) -> Result<Self, RitzError> {
        Self::solve_fills(&Fills::of(grid), degree, poisson_ratio, count)
    }

    fn solve_fills(
        fills: &Fills,
        degree: usize,
        poisson_ratio: f64,
        count: usize,
    ) -> Result<Self, RitzError> {
        if degree > MAX_DEGREE {
            return Err(RitzError::Degree(degree));
        }
        let moments = Moments::of(fills, degree)?;
        let mono = monomials(degree);
        let n = mono.len();
        let s = moments.scale;
        let add = |a: [usize; 3], b: [usize; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
        let derivative = |e: [usize; 3], axis: usize| -> Option<(f64, [usize; 3])> {
            (e[axis] > 0).then(|| {
                let mut d = e;
                d[axis] -= 1;
                (e[axis] as f64 / s, d)
            })
        };
        // int d_a phi_i d_b phi_j dV
        let grad = |i: usize, a: usize, j: usize, b: usize| -> f64 {
            match (derivative(mono[i], a), derivative(mono[j], b)) {
                (Some((ca, ea)), Some((cb, eb))) => ca * cb * moments.get(add(ea, eb)),
                _ => 0.0,
            }
        };
        let nu = poisson_ratio;
        let lame = nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let shear = 0.5 / (1.0 + nu);
        // Strain energy lambda (div u)^2 / 2 + mu eps : eps, component blocks (c, d).
        let stiffness = Mat::<f64>::from_fn(3 * n, 3 * n, |row, col| {
            let (c, i, d, j) = (row / n, row % n, col / n, col % n);
            let mut v = lame * grad(i, c, j, d) + shear * grad(i, d, j, c);
            if c == d {
                v += shear * (0..3).map(|t| grad(i, t, j, t)).sum::<f64>();
            }
            v
        });
        // The mass matrix is the scalar Gram matrix on each component: whiten it once.
        let gram = Mat::<f64>::from_fn(n, n, |i, j| moments.get(add(mono[i], mono[j])));
        let evd = gram
            .self_adjoint_eigen(faer::Side::Lower)
            .map_err(|_| RitzError::NoConvergence)?;
        let (u, sv) = (evd.U(), evd.S());
        let top = (0..n).map(|i| sv[i]).fold(0.0, f64::max);
        let kept: Vec<usize> = (0..n).filter(|&i| sv[i] > 1e-11 * top).collect();
        let r = kept.len();
        // The whitening is the same on each component: T = U S^-1/2 (n x r), and the reduced
        // stiffness is T^T K_cd T block by block.
        let whiten = Mat::<f64>::from_fn(n, r, |row, col| {
            u[(row, kept[col])] * sv[kept[col]].sqrt().recip()
        });
        let mut reduced = Mat::<f64>::zeros(3 * r, 3 * r);
        for c in 0..3 {
            for d in c..3 {
                let block = stiffness.as_ref().submatrix(c * n, d * n, n, n);
                let kd = whiten.transpose() * block * &whiten;
                reduced
                    .as_mut()
                    .submatrix_mut(c * r, d * r, r, r)
                    .copy_from(&kd);
                if d != c {
                    reduced
                        .as_mut()
                        .submatrix_mut(d * r, c * r, r, r)
                        .copy_from(kd.transpose());
                }
            }
        }
        let modes = reduced
            .self_adjoint_eigen(faer::Side::Lower)
            .map_err(|_| RitzError::NoConvergence)?;
        let values = modes.S();
        let all: Vec<f64> = (0..3 * r).map(|i| values[i]).collect();
        if all.iter().any(|v| !v.is_finite()) {
            return Err(RitzError::NoConvergence);
        }
        // The six rigid motions are in the basis (degree >= 1): eigenvalues at rounding level.
        let largest = all.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let chosen: Vec<usize> = (0..all.len())
            .filter(|&i| all[i] > 1e-9 * largest)
            .take(count)
            .collect();
        let y = modes.U();
        let mut coefficients = Vec::with_capacity(chosen.len() * 3 * n);
        for &m in &chosen {
            for c in 0..3 {
                let part = &whiten * y.submatrix(c * r, m, r, 1);
                coefficients.extend((0..n).map(|row| part[(row, 0)]));
            }
        }
        Ok(RitzModes {
            eigenvalues: chosen.iter().map(|&i| all[i]).collect(),
            coefficients,
            exponents: mono,
            centre: moments.centre,
            scale: s,
        })
    }

    /// The Ritz modes the predictor plays for its input `grid` (the network's, at the
    /// reference: voxel edge [`super::bands::REFERENCE_BOX_M`] / 32), or `None` where the
    /// network answers alone: a shape whose mean wall is under [`MIN_WALL_VOXELS`], or whose
    /// lowest Ritz mode lies below [`TAKEOVER_BAND`] (found by a [`SCREEN_DEGREE`] solve
    /// first, so most shapes cost under a millisecond here).
    pub fn above_bands(grid: &VoxelGrid) -> Option<Self> {
        let from_hz = band_edges_hz()[TAKEOVER_BAND];
        let starts_high = |m: &Self| {
            m.eigenvalues
                .first()
                .is_some_and(|&l| reference_hz(l) >= from_hz)
        };
        let fills = Fills::of(grid);
        if ops::mean_wall_of(fills.dims, &fills.values) < MIN_WALL_VOXELS {
            return None;
        }
        let screen = Self::solve_fills(&fills, SCREEN_DEGREE, REFERENCE_POISSON, 1).ok()?;
        if !starts_high(&screen) {
            return None;
        }
        let modes = Self::solve_fills(&fills, RITZ_DEGREE, REFERENCE_POISSON, RITZ_MODES).ok()?;
        starts_high(&modes).then_some(modes)
    }

    /// The band of the lowest mode at the reference (where the Ritz modes take over), or
    /// [`super::bands::BANDS`] above the range.
    pub fn first_band(&self) -> usize {
        let hz = self
            .eigenvalues
            .first()
            .map_or(HIGH_HZ, |&l| reference_hz(l));
        super::bands::band_of(hz).unwrap_or(super::bands::BANDS)
    }

    /// Number of modes.
    pub fn len(&self) -> usize {
        self.eigenvalues.len()
    }

    /// Whether there is no mode.
    pub fn is_empty(&self) -> bool {
        self.eigenvalues.is_empty()
    }

    /// Mode `mode`'s displacement at `point` (the grid's voxel units, origin at its corner).
    pub fn displacement(&self, mode: usize, point: [f64; 3]) -> [f64; 3] {
        let values = self.monomials_at(point);
        let n = self.exponents.len();
        let c = &self.coefficients[mode * 3 * n..(mode + 1) * 3 * n];
        [0, 1, 2].map(|d| (0..n).map(|i| c[d * n + i] * values[i]).sum())
    }

    /// Each mode's displacement at `point` along `unit` into `out` (`phi_i(p) . f`, the modal
    /// force of a unit impulse). Never allocates (the engine voices strikes with it on the
    /// audio thread).
    pub fn forces_into(&self, point: [f64; 3], unit: [f64; 3], out: &mut [f64]) {
        let values = self.monomials_at(point);
        let n = self.exponents.len();
        for (o, c) in out.iter_mut().zip(self.coefficients.chunks_exact(3 * n)) {
            *o = (0..3)
                .map(|d| unit[d] * (0..n).map(|i| c[d * n + i] * values[i]).sum::<f64>())
                .sum();
        }
    }

    fn monomials_at(&self, point: [f64; 3]) -> [f64; MAX_MONOMIALS] {
        let xi = [0, 1, 2].map(|a| (point[a] - self.centre[a]) / self.scale);
        let mut values = [0.0f64; MAX_MONOMIALS];
        for (v, e) in values.iter_mut().zip(&self.exponents) {
            *v = xi[0].powi(e[0] as i32) * xi[1].powi(e[1] as i32) * xi[2].powi(e[2] as i32);
        }
        values
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::ModeBasis;
    use crate::eigen::{EigenOptions, ModeCount, SolverKind};
    use crate::fem::ElementKind;

    fn fem(grid: &VoxelGrid, count: usize) -> Vec<f64> {
        let options = EigenOptions {
            count: ModeCount::First(count),
            ..EigenOptions::default()
        };
        ModeBasis::solve(grid, ElementKind::Hex27, 0.3, SolverKind::Lanczos, &options)
            .unwrap()
            .solution
            .eigenvalues
    }

    fn ritz(grid: &VoxelGrid, degree: usize, count: usize) -> Vec<f64> {
        RitzModes::solve(grid, degree, 0.3, count)
            .unwrap()
            .eigenvalues
    }

    #[test]
    fn a_slender_bar_bends_at_euler_bernoulli_s_frequency_from_above() {
        // A free 32 x 3 x 3 bar (E = rho = 1): Euler-Bernoulli's first bending frequency is
        // omega = 4.7300^2 sqrt(E I / (rho A L^4)), I = a^4 / 12, A = a^2, doubly degenerate.
        // Timoshenko's shear and rotary inertia take the 3D answer about 1 % below it at
        // L/a = 10.7, and a quartic cannot follow the beam's cosh/cos shape exactly: both
        // within 3 %. Ritz stays above converged FEM (hex27 on the voxels).
        let bar = VoxelGrid::from_fn([32, 3, 3], 1.0, |_, _, _| true).unwrap();
        let values = ritz(&bar, 4, 2);
        let (l, a) = (32.0f64, 3.0f64);
        let euler = 4.7300f64.powi(2) * (a * a / 12.0 / l.powi(4)).sqrt();
        for v in &values {
            let ratio = v.sqrt() / euler;
            assert!((ratio - 1.0).abs() < 0.03, "{ratio}");
        }
        for (r, e) in values.iter().zip(fem(&bar, 2)) {
            assert!(*r >= e * (1.0 - 1e-9), "Ritz {r} below FEM {e}");
        }
    }

    #[test]
    fn a_compact_solid_s_lowest_modes_are_within_a_few_percent_of_fem() {
        // A 12 x 9 x 7 block: degree 5 gives its lowest ten modes within 3 % of hex27 FEM
        // (the 24 x 16 x 12 box of the module docs: 0-3.2 %), never below it; degree 3
        // bounds degree 5 from above (the screen's premise).
        let block = VoxelGrid::from_fn([12, 9, 7], 1.0, |_, _, _| true).unwrap();
        let (five, three) = (ritz(&block, RITZ_DEGREE, 10), ritz(&block, 3, 10));
        let exact = fem(&block, 10);
        for (k, (r, e)) in five.iter().zip(&exact).enumerate() {
            let ratio = (r / e).sqrt();
            assert!(
                (1.0 - 1e-6..1.03).contains(&ratio),
                "{k}: {five:?} vs {exact:?}"
            );
        }
        assert!(three[0] >= five[0] * (1.0 - 1e-12));
    }

    #[test]
    fn the_modes_are_mass_orthonormal_over_the_fills() {
        // Identity check: int u_i . u_j dV = delta_ij over the filled voxels, summed by
        // 5-point Gauss-Legendre in each (exact for the degree-8 products of quartics), so to
        // rounding: 1e-10, about 1e4 eps for sums over a hundred voxels of 125 points.
        let grid = VoxelGrid::from_fn([7, 5, 4], 1.0, |x, y, _| x + y < 10.0).unwrap();
        let modes = RitzModes::solve(&grid, 4, 0.3, 6).unwrap();
        let (a, b) = (0.538_469_310_105_683_1, 0.906_179_845_938_664);
        let g = [-b, -a, 0.0, a, b];
        let w = [
            0.236_926_885_056_189_1,
            0.478_628_670_499_366_5,
            0.568_888_888_888_888_9,
            0.478_628_670_499_366_5,
            0.236_926_885_056_189_1,
        ];
        let mut gram = [[0.0; 6]; 6];
        let [nx, ny, nz] = grid.dims();
        for i in 0..nx * ny * nz {
            let [x, y, z] = [i % nx, (i / nx) % ny, i / (nx * ny)];
            if !grid.get(x as isize, y as isize, z as isize) {
                continue;
            }
            for q in 0..125 {
                let [qa, qb, qc] = [q % 5, (q / 5) % 5, q / 25];
                let p = [
                    x as f64 + 0.5 + 0.5 * g[qa],
                    y as f64 + 0.5 + 0.5 * g[qb],
                    z as f64 + 0.5 + 0.5 * g[qc],
                ];
                let weight = w[qa] * w[qb] * w[qc] / 8.0;
                let u: Vec<[f64; 3]> = (0..6).map(|m| modes.displacement(m, p)).collect();
                for (r, row) in gram.iter_mut().enumerate() {
                    for (c, v) in row.iter_mut().enumerate() {
                        *v += weight * (0..3).map(|d| u[r][d] * u[c][d]).sum::<f64>();
                    }
                }
            }
        }
        for (i, row) in gram.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 1e-10, "({i}, {j}): {v}");
            }
        }
        // The strike's path (every mode at once, along a force) agrees with the displacements.
        let (p, unit) = ([2.3, 1.7, 4.0], [0.6, 0.0, 0.8]);
        let mut forces = [0.0; 6];
        modes.forces_into(p, unit, &mut forces);
        for (m, f) in forces.iter().enumerate() {
            let u = modes.displacement(m, p);
            let want: f64 = (0..3).map(|d| u[d] * unit[d]).sum();
            assert!(
                (f - want).abs() < 1e-12 * want.abs().max(1.0),
                "{m}: {f} vs {want}"
            );
        }
    }

    #[test]
    fn only_compact_shapes_ringing_at_the_top_get_ritz_modes() {
        // A 32-voxel sphere at the reference rings from about 9.9 kHz (band 31): Ritz takes
        // over with its 16 modes. A plate (walls under 3 voxels) and a long bar (walls 3.6
        // voxels, its lowest mode near 5 kHz) are left to the network. An empty grid is an error.
        let sphere = VoxelGrid::from_fn([32, 32, 32], 1.0, |x, y, z| {
            (x - 16.0).powi(2) + (y - 16.0).powi(2) + (z - 16.0).powi(2) < 256.0
        })
        .unwrap();
        let modes = RitzModes::above_bands(&sphere).expect("a sphere");
        assert_eq!(modes.len(), RITZ_MODES);
        assert_eq!(modes.first_band(), 31);
        let plate = VoxelGrid::from_fn([32, 32, 2], 1.0, |_, _, _| true).unwrap();
        assert!(RitzModes::above_bands(&plate).is_none());
        let bar = VoxelGrid::from_fn([32, 8, 8], 1.0, |_, _, _| true).unwrap();
        assert!(RitzModes::above_bands(&bar).is_none());
        let empty = VoxelGrid::new([4, 4, 4], 1.0).unwrap();
        assert_eq!(
            RitzModes::solve(&empty, 3, 0.3, 1).unwrap_err(),
            RitzError::Empty
        );
        assert!(RitzModes::above_bands(&empty).is_none());
    }
}
