//! The instant answer's relaxation near an edit: static local corrections of the carried
//! vectors on a patch of nodes around the edited cells, the patch's own lowest modes with its
//! boundary held, and their images `K D`, `M D` on it.
//!
//! Where it sits: inside [`super::ritz`], after the Gram matrices of the carried block `X`
//! (and its images `K X`, `M X` on the patch) and before the Rayleigh-Ritz step on `[X, D]`. For each
//! column `x` with Rayleigh quotient `theta`, `d = -K_pp^-1 (K x - theta M x)_p` on the patch
//! nodes `p`, the rest held fixed: a Dirichlet problem, one block-Jacobi step of the subdomain
//! around the edit, as in Schwarz methods. A stroke changes the stress near it; without this
//! the carried answer's frequencies were 0.2-0.7 % off (`tests/warm_start.rs`).
//!
//! The corrections are static: they carry the stress a stroke moves, not the motion of what
//! it adds. The patch's lowest modes with its boundary held ([`patch_modes`], a few steps of
//! inverse iteration on the same factor) carry that: with the corrections they are the two
//! ingredients of Craig and Bampton's component mode synthesis (1968: constraint modes and
//! fixed-interface normal modes), here for the one component an edit changed. After several
//! strokes at one spot they cut the carried answer's median error 4-5x
//! (`tests/warm_start.rs`).
//!
//! Cost: the patch's stiffness (a few hundred nodes) is factored sparse, in nested-dissection
//! order, by the solvers' own [`ShiftedCholesky`] with no shift (2-3x faster than the dense
//! factor it replaced); `K_pp D` is the right-hand side itself (`K_pp K_pp^-1 r = r`);
//! `M_pp D` uses the mass's scalars (`M_ab I3`, [`crate::fem::sparse::MassBlocks`]) and reads
//! the corrections by rows, a node's values side by side.

use super::super::factor::ShiftedCholesky;
use super::super::stop::Stop;
use super::super::{from_rows, to_rows, EigenError, Operators};
use crate::fem::sparse::BlockPattern;
use crate::fem::{ordering, FemModel};
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Mat, MatRef, Par};

/// Local corrections near an edit ([`local_correction`]): on the patch DOFs only.
pub(super) struct Correction {
    /// The patch's DOFs, whole nodes in patch order (`3 node + c`).
    pub dofs: Vec<usize>,
    /// One correction per carried column, on the patch DOFs.
    pub delta: Mat<f64>,
    /// `K_pp delta` and `M_pp delta`.
    pub k_delta: Mat<f64>,
    pub m_delta: Mat<f64>,
}

/// The corrections of the columns of `x` (`n x w`) on the nodes `patch`, given their images
/// on the patch's DOF rows (`kx`, `mx`: `3 p x w`, three rows per patch node in patch order)
/// and their Rayleigh quotients `theta`, with the patch's own modes grown as `grow` says
/// ([`patch_modes`]). `Ok(None)` if `K_pp` is not positive definite (the patch is a whole
/// part of the object); [`EigenError::Interrupted`] once `stop` says so, polled after the
/// patch's factorisation and at each step of its modes' iteration.
pub(super) fn local_correction(
    ops: &Operators,
    model: &FemModel,
    patch: &[usize],
    theta: &[f64],
    (kx, mx): (MatRef<'_, f64>, MatRef<'_, f64>),
    grow: bool,
    stop: &Stop,
) -> Result<Option<Correction>, EigenError> {
    let np = patch.len();
    let Some(PatchProblem {
        pattern,
        mpp,
        mut factor,
    }) = patch_problem(ops, model, patch)
    else {
        return Ok(None);
    };
    stop.check()?;
    let dofs: Vec<usize> = patch
        .iter()
        .flat_map(|&node| [3 * node, 3 * node + 1, 3 * node + 2])
        .collect();
    let w = kx.ncols();
    let rhs = Mat::<f64>::from_fn(3 * np, w, |i, j| theta[j] * mx[(i, j)] - kx[(i, j)]);
    let mut delta = rhs.clone();
    factor.solve_in_place(delta.as_mut());
    let mut k_delta = rhs;
    let theta_max = theta.iter().copied().fold(0.0, f64::max);
    let mut m_delta = patch_mass(&pattern, &mpp, delta.as_ref());
    if let Some(modes) = patch_modes(&mut factor, &pattern, &mpp, theta_max, grow, stop)? {
        // The patch's own modes join the corrections: both vanish off the patch.
        delta = side_by_side(&delta, &modes.z);
        k_delta = side_by_side(&k_delta, &modes.kz);
        m_delta = side_by_side(&m_delta, &modes.mz);
    }
    Ok(Some(Correction {
        dofs,
        delta,
        k_delta,
        m_delta,
    }))
}

/// A patch's stiffness and mass with its boundary held, and the stiffness factored.
struct PatchProblem {
    /// The patch's own block pattern (its nodes in patch order, which is node order, so each
    /// row's columns stay sorted).
    pattern: BlockPattern,
    /// Mass scalars on `pattern` (`M_ab I3`).
    mpp: Vec<f64>,
    /// `K_pp`, factored sparse in nested-dissection order.
    factor: ShiftedCholesky,
}

/// The [`PatchProblem`] of the nodes `patch` (ascending) of `model`; `None` if `K_pp` is not
/// positive definite (the patch is a whole part of the object).
fn patch_problem(ops: &Operators, model: &FemModel, patch: &[usize]) -> Option<PatchProblem> {
    let (lattice, order_p) = (|v| model.node_lattice_coords(v), model.kind.order() as i64);
    let mut local = vec![u32::MAX; ops.pattern.nodes()];
    for (i, &node) in patch.iter().enumerate() {
        local[node] = i as u32;
    }
    let mut row_ptr = Vec::with_capacity(patch.len() + 1);
    let (mut col, mut kpp, mut mpp) = (Vec::new(), Vec::new(), Vec::new());
    row_ptr.push(0);
    for &node in patch {
        for b in ops.pattern.row_ptr[node]..ops.pattern.row_ptr[node + 1] {
            let j = local[ops.pattern.col[b] as usize];
            if j != u32::MAX {
                col.push(j);
                kpp.push(ops.k[b]);
                mpp.push(ops.m[b]);
            }
        }
        row_ptr.push(col.len());
    }
    let pattern = BlockPattern { row_ptr, col };
    let coords: Vec<[i64; 3]> = patch.iter().map(|&v| lattice(v)).collect();
    let order = ordering::nested_dissection_of(&coords, order_p);
    let factor = ShiftedCholesky::from_blocks(&pattern, &kpp, &mpp, 0.0, &order).ok()?;
    Some(PatchProblem {
        pattern,
        mpp,
        factor,
    })
}

/// The patch's lowest modes with its boundary held (`K_pp z = mu M_pp z`), approximately:
/// [`PATCH_ITERATIONS`] steps of block inverse iteration from a fixed random block on the
/// patch's factor, each followed by a Rayleigh-Ritz step. Returns them with their images
/// `K_pp Z` and `M_pp Z`, which the iteration knows without more products (`K_pp Y = M_pp Z`
/// for `Y = K_pp^-1 M_pp Z`). `None` if the Rayleigh-Ritz step fails.
///
/// How many: Craig and Bampton keep the fixed-interface modes up to the frequencies the
/// reduced model must reproduce, here `theta_max`, the highest carried Rayleigh quotient.
/// A small patch has few modes below it and [`PATCH_MODES`] serve. A Ritz value bounds its
/// mode from above, so when the block's last is below `theta_max` after a step (a wide patch
/// on a slender object: the steel bar's two-block patch holds 25 modes below), more modes lie
/// below it: on a patch within `WIDE_PATCH_MAX_DOFS`, or at any size where `grow` says so
/// (the wide reach, `super::Reach::Wide`), the block grows to [`PATCH_MODES_MAX`] columns by
/// [`krylov_modes`], which keeps the modes below `theta_max` and [`PATCH_MODES_MARGIN`] more.
/// Polls `stop` before each step.
fn patch_modes(
    factor: &mut ShiftedCholesky,
    pattern: &BlockPattern,
    mpp: &[f64],
    theta_max: f64,
    grow: bool,
    stop: &Stop,
) -> Result<Option<PatchModes>, EigenError> {
    let rows = 3 * pattern.nodes();
    // The grown block costs its patch solves and products (the default object's drag, whose
    // patch grows with the strokes to 1,000-1,450 DOFs: 4-9 ms more a carried answer with
    // stop 68's subspace iteration); the instant answer keeps it to the patches the wide
    // one's budget admits.
    let widest = if grow || rows <= super::patch::WIDE_PATCH_MAX_DOFS {
        PATCH_MODES_MAX.min(rows / 2)
    } else {
        PATCH_MODES
    };
    let mut rng = crate::rng::SplitMix64::new(0x9A7C4);
    let mut z = Mat::<f64>::from_fn(rows, PATCH_MODES.min(widest), |_, _| rng.unit() - 0.5);
    let mut mz = patch_mass(pattern, mpp, z.as_ref());
    let mut kz = Mat::<f64>::zeros(rows, z.ncols());
    for _ in 0..PATCH_ITERATIONS {
        stop.check()?;
        let count = z.ncols();
        let mut y = mz.clone();
        factor.solve_in_place(y.as_mut());
        let my = patch_mass(pattern, mpp, y.as_ref());
        let gk = y.transpose() * &mz;
        let gm = y.transpose() * &my;
        let Ok((mu, c)) = super::super::lobpcg::dense_ritz(&gk, &gm, count) else {
            return Ok(None);
        };
        z = &y * &c;
        kz = &mz * &c;
        // `M Z` for the next step, by linearity instead of another sparse product.
        mz = &my * &c;
        if count + PATCH_MODES <= widest && mu.last().is_some_and(|&m| m < theta_max) {
            let modes = PatchModes { z, kz, mz };
            return krylov_modes(factor, pattern, mpp, modes, widest, theta_max, stop);
        }
    }
    Ok(Some(PatchModes { z, kz, mz }))
}

/// Patch modes and their images on the patch: `Z`, `K_pp Z`, `M_pp Z`.
struct PatchModes {
    z: Mat<f64>,
    kz: Mat<f64>,
    mz: Mat<f64>,
}

/// [`patch_modes`] grown to `widest` columns where more patch modes lie below `theta_max`:
/// the block Krylov space of `K_pp^-1 M_pp` on the Ritz vectors `start` (`[Z, K^-1 M Z,
/// (K^-1 M)^2 Z, ...]`, each block `M`-orthogonalised against the ones before it by classical
/// Gram-Schmidt twice and `M`-orthonormalised within itself by Cholesky QR) and one
/// Rayleigh-Ritz step on it. A block costs one patch solve and one mass product of
/// [`PATCH_MODES`] columns; the images stay known without `K` (`K W = M V_last - (K V) H` for
/// `W = K^-1 M V_last - V H`). Stop 68 grew the
/// block to 32 random columns and ran three more steps of subspace iteration: three times the
/// solves and twice the mass products of six blocks. One stroke each at the presets' Poisson
/// ratios (a temporary harness, worst carried mode), stop 68 against six blocks: the steel
/// bar 3.1e-3 -> 2.2e-3, the wooden slat 2.4e-4 -> 2.2e-4, the iron pipe 1.0e-4 -> 9.8e-5;
/// the carried answer no slower (medians of 11, three interleaved rounds on a noisy hour: the
/// bar 31-36 against 22-29 ms, the slat 25-28 against 20-28). Five blocks gave the slat
/// 3.6e-4 and four the bar 4.0e-3, and blocks left without their own orthonormalisation made
/// the grown basis so ill-conditioned that the bar went to 1.1e-2.
fn krylov_modes(
    factor: &mut ShiftedCholesky,
    pattern: &BlockPattern,
    mpp: &[f64],
    start: PatchModes,
    widest: usize,
    theta_max: f64,
    stop: &Stop,
) -> Result<Option<PatchModes>, EigenError> {
    let b = start.z.ncols();
    let PatchModes {
        z: mut v,
        kz: mut kv,
        mz: mut mv,
    } = start;
    while v.ncols() + b <= widest {
        stop.check()?;
        let last = v.ncols() - b..v.ncols();
        let mut kw = mv.get(.., last).to_owned();
        let mut w = kw.clone();
        factor.solve_in_place(w.as_mut());
        for _ in 0..2 {
            // `V^T M W`, with `M V` known.
            let h = mv.transpose() * &w;
            w -= &v * &h;
            kw -= &kv * &h;
        }
        // `M`-orthonormal within the block too (Cholesky QR: `W L^-T` for `W^T M W = L L^T`);
        // a block that has lost its rank ends the growth.
        let mw = patch_mass(pattern, mpp, w.as_ref());
        let gram = w.transpose() * &mw;
        let Ok(llt) = gram.llt(faer::Side::Lower) else {
            break;
        };
        let l = llt.L();
        let unit = |a: Mat<f64>| {
            let mut t = a.transpose().to_owned();
            solve_lower_triangular_in_place(l, t.as_mut(), Par::Seq);
            t.transpose().to_owned()
        };
        let (w, kw, mw) = (unit(w), unit(kw), unit(mw));
        v = side_by_side(&v, &w);
        kv = side_by_side(&kv, &kw);
        mv = side_by_side(&mv, &mw);
    }
    let count = v.ncols();
    let gk = v.transpose() * &kv;
    let gm = v.transpose() * &mv;
    let Ok((mu, c)) = super::super::lobpcg::dense_ritz(&gk, &gm, count) else {
        return Ok(None);
    };
    let below = mu.iter().filter(|&&m| m < theta_max).count();
    let keep = (below + PATCH_MODES_MARGIN).max(PATCH_MODES).min(count);
    let c = c.get(.., 0..keep);
    Ok(Some(PatchModes {
        z: &v * c,
        kz: &kv * c,
        mz: &mv * c,
    }))
}

/// Patch modes added to the instant answer's Rayleigh-Ritz basis ([`patch_modes`]) when the
/// patch has no more below the carried modes. With 8, on the default object after 4 and 12
/// one-voxel strokes at one spot, the carried modes' median frequency error fell from 1.9e-4
/// to 3.8e-5 and from 7.9e-4 to 2.2e-4 (a temporary harness); 4 did about as well after one
/// stroke, 16 no better.
const PATCH_MODES: usize = 8;

/// The grown block when [`PATCH_MODES`] are all below the carried modes ([`patch_modes`],
/// [`krylov_modes`]: six blocks). On the steel bar's two-block patch (879 DOFs, 25 modes
/// below) the worst carried mode after one stroke was 8.8e-3 with 8 patch modes; stop 68's
/// subspace iteration gave 6.4e-3 with 16 and 3.1e-3 with 32 (3.3e-3 with the 29 kept; the
/// one-block patch with 8: 5.4e-3); the Krylov block 4.0e-3 with 32, 3.0e-3 with 40 and
/// 2.2e-3 with 48.
const PATCH_MODES_MAX: usize = 48;

/// Patch modes kept above the carried modes' range (the reduced model's modes near its top
/// draw on the fixed-interface modes just above it).
const PATCH_MODES_MARGIN: usize = 4;

/// Inverse iteration steps for the patch modes where they are not grown: 1 left them random
/// (no gain), 2 gave about half the gain of 3, and 6 little more than 3 for 1 ms more on a
/// 591-DOF patch.
const PATCH_ITERATIONS: usize = 3;

/// `[a, b]`: the columns of `a`, then those of `b` (the same rows).
fn side_by_side(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let w = a.ncols();
    Mat::from_fn(a.nrows(), w + b.ncols(), |i, j| {
        if j < w {
            a[(i, j)]
        } else {
            b[(i, j - w)]
        }
    })
}

/// `M_pp Z` for `Z` on the patch's DOFs (`3 p x c`, three rows per patch node): `M`'s blocks
/// are `M_ab I3`, read as scalars, and `Z` by rows, a node's values side by side.
fn patch_mass(pattern: &BlockPattern, mpp: &[f64], z: MatRef<'_, f64>) -> Mat<f64> {
    let c = z.ncols();
    let by_rows = to_rows(z);
    let mut out = vec![0.0; z.nrows() * c];
    for (i, dst) in out.chunks_exact_mut(3 * c).enumerate() {
        let row = pattern.row_ptr[i]..pattern.row_ptr[i + 1];
        for (&a, &s) in pattern.col[row.clone()].iter().zip(&mpp[row]) {
            let a = a as usize;
            dst.iter_mut()
                .zip(&by_rows[3 * a * c..3 * (a + 1) * c])
                .for_each(|(o, v)| *o += s * v);
        }
    }
    from_rows(&out, c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::Which;
    use crate::fem::{ElementKind, FemModel};
    use crate::rng::SplitMix64;
    use crate::shape::{ops as shape_ops, primitives::Primitive};

    #[test]
    fn corrections_and_their_images_match_whole_products() {
        // On a hollow sphere (partial voxels): the patch is the nodes of a corner of the
        // lattice. `K_pp D` must equal the product with the patch's stiffness (it is the
        // right-hand side, up to the solve's rounding: 1e-9 of the scale, for a condition
        // number of the patch's `K_pp` near 1e5), `M_pp D` and the images of a combination
        // `D C` the whole block products of `D` padded with zeros (same sums, another order:
        // 1e-12 of the scale).
        let grid = shape_ops::hollow(
            &Primitive::Sphere { diameter: 8.0 }
                .rasterize(1.0, 1.0)
                .unwrap(),
            2,
        );
        for kind in [ElementKind::Hex8Incompatible, ElementKind::Hex27Blocks] {
            let model = FemModel::assemble(&grid, kind, 0.3).unwrap();
            let ops = Operators::new(&model);
            let n = model.dofs();
            let top = (0..model.nodes())
                .map(|v| model.node_lattice_coords(v)[0])
                .max()
                .unwrap();
            let patch: Vec<usize> = (0..model.nodes())
                .filter(|&v| model.node_lattice_coords(v).iter().all(|&c| 2 * c <= top))
                .collect();
            assert!(patch.len() > 10 && patch.len() < model.nodes() / 2);
            let mut rng = SplitMix64::new(3);
            let w = 5;
            let x = Mat::from_fn(n, w, |_, _| rng.unit() - 0.5);
            let (kx, mx) = (
                ops.apply_block(Which::K, x.as_ref()),
                ops.apply_block(Which::M, x.as_ref()),
            );
            let theta = vec![0.1; w];
            let on_patch = |a: &Mat<f64>| {
                Mat::from_fn(3 * patch.len(), w, |i, j| a[(3 * patch[i / 3] + i % 3, j)])
            };
            let (kp, mp) = (on_patch(&kx), on_patch(&mx));
            let cor = local_correction(
                &ops,
                &model,
                &patch,
                &theta,
                (kp.as_ref(), mp.as_ref()),
                false,
                &Stop::NEVER,
            )
            .unwrap()
            .unwrap();
            let pad = |d: &Mat<f64>| {
                let mut full = Mat::<f64>::zeros(n, d.ncols());
                for (i, &dof) in cor.dofs.iter().enumerate() {
                    for j in 0..d.ncols() {
                        full[(dof, j)] = d[(i, j)];
                    }
                }
                full
            };
            let full = pad(&cor.delta);
            let (kd, md) = (
                ops.apply_block(Which::K, full.as_ref()),
                ops.apply_block(Which::M, full.as_ref()),
            );
            let scale = |a: &Mat<f64>| a.norm_max();
            for (i, &dof) in cor.dofs.iter().enumerate() {
                for j in 0..w {
                    assert!((cor.k_delta[(i, j)] - kd[(dof, j)]).abs() <= 1e-9 * scale(&kd));
                    assert!((cor.m_delta[(i, j)] - md[(dof, j)]).abs() <= 1e-12 * scale(&md));
                }
            }
        }
    }

    #[test]
    fn grown_patch_modes_are_the_patchs_lowest_modes_with_their_images() {
        // A slender bar's end (hex27x2): a patch of a few hundred DOFs with many modes below
        // any bound, so the block grows to its widest. Against the patch's dense generalized
        // eigenproblem (an independent solve): the lowest four Ritz values to 1e-9 relative
        // (measured 5e-13 to 3e-11, the rounding of either solve: six Krylov blocks on an
        // inverse-iterated start resolve the bottom of this 351-DOF spectrum), the images
        // `K_pp Z`, `M_pp Z` as whole products of `Z` padded with zeros (1e-9 and 1e-12 of the
        // scale, as above), and `Z` `M`-orthonormal and `K`-diagonal to 1e-10.
        let grid = Primitive::Bar {
            length: 16.0,
            width: 2.0,
            height: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex27Blocks, 0.3).unwrap();
        let ops = Operators::new(&model);
        let n = model.dofs();
        let long = (0..3)
            .max_by_key(|&a| {
                (0..model.nodes())
                    .map(|v| model.node_lattice_coords(v)[a])
                    .max()
            })
            .unwrap();
        let patch: Vec<usize> = (0..model.nodes())
            .filter(|&v| model.node_lattice_coords(v)[long] <= 12)
            .collect();
        let rows = 3 * patch.len();
        assert!(
            (200..=super::super::patch::WIDE_PATCH_MAX_DOFS).contains(&rows),
            "{rows}"
        );
        let PatchProblem {
            pattern,
            mpp,
            mut factor,
        } = patch_problem(&ops, &model, &patch).unwrap();
        let modes = patch_modes(
            &mut factor,
            &pattern,
            &mpp,
            f64::INFINITY,
            false,
            &Stop::NEVER,
        )
        .unwrap()
        .unwrap();
        let count = modes.z.ncols();
        assert_eq!(count, PATCH_MODES_MAX.min(rows / 2));
        // Whole products of the padded columns, read back on the patch.
        let on_patch = |d: &Mat<f64>, which: Which| {
            let mut full = Mat::<f64>::zeros(n, d.ncols());
            for (i, &node) in patch.iter().enumerate() {
                for c in 0..3 {
                    for j in 0..d.ncols() {
                        full[(3 * node + c, j)] = d[(3 * i + c, j)];
                    }
                }
            }
            let image = ops.apply_block(which, full.as_ref());
            Mat::from_fn(rows, d.ncols(), |i, j| image[(3 * patch[i / 3] + i % 3, j)])
        };
        let (kz, mz) = (on_patch(&modes.z, Which::K), on_patch(&modes.z, Which::M));
        let close = |a: &Mat<f64>, b: &Mat<f64>, rel: f64| (a - b).norm_max() <= rel * b.norm_max();
        assert!(close(&modes.kz, &kz, 1e-9) && close(&modes.mz, &mz, 1e-12));
        let (zkz, zmz) = (modes.z.transpose() * &kz, modes.z.transpose() * &mz);
        let mu: Vec<f64> = (0..count).map(|j| zkz[(j, j)]).collect();
        for i in 0..count {
            for j in 0..count {
                let (k_ij, m_ij) = if i == j { (mu[i], 1.0) } else { (0.0, 0.0) };
                assert!((zkz[(i, j)] - k_ij).abs() <= 1e-10 * mu[count - 1]);
                assert!((zmz[(i, j)] - m_ij).abs() <= 1e-10);
            }
        }
        // The dense pencil: `L^-1 K L^-T` for `M = L L^T`.
        let eye = Mat::<f64>::identity(rows, rows);
        let (k_dense, m_dense) = (on_patch(&eye, Which::K), on_patch(&eye, Which::M));
        let l = m_dense.llt(faer::Side::Lower).unwrap().L().to_owned();
        let mut h = k_dense;
        solve_lower_triangular_in_place(l.as_ref(), h.as_mut(), Par::Seq);
        let mut h = h.transpose().to_owned();
        solve_lower_triangular_in_place(l.as_ref(), h.as_mut(), Par::Seq);
        let (exact, _) = crate::eigen::sym_eigen(&h).unwrap();
        for j in 0..4 {
            let tolerance = 1e-9 * exact[j];
            assert!(
                (mu[j] - exact[j]).abs() <= tolerance,
                "{} against {}",
                mu[j],
                exact[j]
            );
        }
    }
}
