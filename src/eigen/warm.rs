//! Warm starts: the modes of a sculpting edit, from the modes of the shape before it.
//!
//! Where it sits: beside [`super::lanczos`] and [`super::lobpcg`], behind the same contract
//! ([`EigenOptions`] in, [`EigenSolution`] out, the residual criterion of NeuralSound, Jin et al.
//! 2022 eq. 6). Two answers start from the previous shape's solution:
//! - [`ritz`], the instant one ([`crate::basis::ModeBasis::carried_ritz`], played by the
//!   engine's [`crate::engine::CarriedRitzSolver`] after every brush stroke): the carried modes
//!   relaxed near the edit (`warm/correction.rs`: only that small patch is factored, never
//!   the object) and re-balanced by one Rayleigh-Ritz step, whose Gram matrices are the previous
//!   solve's updated near the edit (`warm/grams.rs`). The engine's, [`ritz_factored`], reads
//!   nothing of the mesh away from the edit: its vectors stay factors (`warm/rows.rs`) and
//!   the Gram columns it cannot relate (the rigid fields, unconverged guards) come from the
//!   previous answer's whole ones (`warm/exact_grams.rs`). How far the relaxation reaches is
//!   a [`Reach`]: the instant answer's patch is sized for its time, and where that kept it
//!   narrow the engine plays a second answer over the wide patch
//!   ([`crate::engine::CarriedRitzSolver::wide`]), which stays in tune through a drag's
//!   strokes;
//! - [`solve`], the exact one ([`crate::basis::ModeBasis::solve_warm`]): the carried block
//!   refined by LOBPCG to the solver tolerance. Measured slower than a cold Lanczos solve on
//!   most objects (ARCHITECTURE.md), so the engine's exact answer is solved cold.
//!
//! [`solve`] step by step (the "mixed solver" idea of NeuralSound, Jin et al. 2022, sec. 4: a good
//! start block makes an iterative eigensolver converge in a few steps):
//! 1. [`transfer`] (`warm/transfer.rs`) carries the previous eigenvectors to the new mesh: a node that persists
//!    keeps its values, a new node takes the mean of its persisting lattice neighbours. The
//!    two voxel sets are aligned first ([`align`]: a brush stroke at the edge of the object
//!    moves the cropped grid's origin).
//! 2. The start block is the six rigid-body fields, the carried modes, the carried guard
//!    vectors (the previous solve's next Ritz vectors, [`EigenSolution::guard_vectors`]: with
//!    random guards instead the highest wanted modes took 7-8 iterations) and a few random
//!    columns (they let a mode the old shape did not have, say a loose voxel's flapping,
//!    grow in).
//! 3. LOBPCG (`lobpcg::iterate`) refines the block with the exact shift-invert
//!    preconditioner, a sparse Cholesky factor of the new `K - sigma M`: 2-5 iterations on
//!    one-voxel strokes of the presets (8 on the steel bar).
//! 4. A start that does not converge within [`WARM_ITERATIONS`], or that finds a different
//!    number of rigid-body modes (the edit split the object), falls back to shift-invert
//!    Lanczos on the same factor: a cold solve, no slower than without the warm start but for
//!    the iterations spent.

mod correction;
mod exact_grams;
mod grams;
mod patch;
mod rows;
mod transfer;

pub use exact_grams::ExactGrams;
pub use patch::rows_read_radius_cells;
use patch::{edit_patch, edited_cells};
pub use rows::RitzRows;
pub use transfer::{align, align_voxels, transfer, Transferred};
use transfer::{previous_columns, transfer_rows, NodeSources, Source};

use super::factor::ShiftedCholesky;
use super::lanczos::{self, SHIFT_RELATIVE};
use super::lobpcg::{self, rigid_centre, rigid_fields, rigid_row};
use super::stop::Stop;
use super::{
    random_block, select, solution, EigenError, EigenOptions, EigenSolution, ModeCount, Operators,
    SolveTimings, SolverKind,
};
use crate::fem::FemModel;
use faer::{Mat, MatRef};
use std::time::Instant;

/// LOBPCG iterations a warm start may take before the solve falls back to Lanczos. Measured
/// (`cargo bench --bench interactive`): one-voxel edits of the presets converge in 2-8.
pub const WARM_ITERATIONS: usize = 10;

/// Random columns at the end of the start block: a mode the previous shape did not have
/// (a loose voxel's flapping) grows in from them.
const RANDOM_GUARDS: usize = 4;

/// Solves `next` for `options.count` (the lowest `k` modes; "modes below a bound" is solved
/// cold) starting from `previous`'s solution carried over by [`transfer`] (see the module
/// docs). `offset` comes from [`align`].
pub fn solve(
    next: &FemModel,
    previous: &FemModel,
    previous_solution: &EigenSolution,
    offset: [i64; 3],
    options: &EigenOptions,
) -> Result<EigenSolution, EigenError> {
    let options = &EigenOptions {
        tolerance: options.tolerance.min(lobpcg::MAX_TOLERANCE),
        ..*options
    };
    let ops = Operators::new(next);
    let n = ops.dofs();
    let ModeCount::First(k) = options.count else {
        return super::solve(next, SolverKind::Lanczos, options);
    };
    let t0 = Instant::now();
    let need = previous_solution.rigid_modes + k;
    let m = need + super::warm_guard(need) + RANDOM_GUARDS;
    if 4 * m > n || previous.kind != next.kind {
        return super::solve(next, SolverKind::Lanczos, options);
    }
    let shift = -SHIFT_RELATIVE * ops.scale;
    let mut llt = ShiftedCholesky::new(next, shift, Stop::NEVER)?;
    let columns = previous_columns(previous_solution, usize::MAX);
    let sources = NodeSources::new(previous, next, offset);
    let carried = transfer_rows(&columns, next, &sources, 0);
    let fields = extra_rigid(previous_solution).ncols() == 0;
    let start = start_block(next, &carried, m, fields);
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = Instant::now();
    let warm_options = EigenOptions {
        max_iterations: WARM_ITERATIONS,
        ..*options
    };
    let mut iterations = 0;
    if let Ok(done) = lobpcg::iterate(
        &ops,
        &mut llt,
        &start,
        need,
        &warm_options,
        &mut iterations,
        super::Stop::NEVER,
    ) {
        let pairs = done.converged_pairs(options.tolerance);
        let sel = select(&ops, &pairs, options.count);
        if sel.complete && sel.rigid == previous_solution.rigid_modes {
            let timings = SolveTimings {
                setup_ms,
                iterate_ms: t1.elapsed().as_secs_f64() * 1e3,
            };
            let mut out = solution(
                &pairs,
                &sel,
                done.vectors(),
                timings,
                iterations,
                SolverKind::Lobpcg,
            );
            out.warm_start = true;
            return Ok(out);
        }
    }
    // Slow or different (a split object, a new soft mode): cold Lanczos on the same factor.
    let mut out = lanczos::run(&ops, &mut llt, shift, options)?;
    out.timings.setup_ms = setup_ms;
    out.timings.iterate_ms = t1.elapsed().as_secs_f64() * 1e3;
    out.iterations += iterations;
    Ok(out)
}

/// The instant answer to an edit: Rayleigh-Ritz of the new `K`, `M` on the previous modes
/// carried to the new mesh (with the rigid fields and the carried guard vectors), with no
/// factorisation and no iteration: Gram matrices mostly known from the previous solve
/// (`warm/grams.rs`), one product of the block with the Ritz coefficients, and a dense
/// eigenproblem the size of the block. A Ritz value's error is second order in its vector's error (Parlett, *The
/// Symmetric Eigenvalue Problem*, Thm. 11.7.1), so after a brush stroke the frequencies are
/// within about 1e-5 of exact (`cargo bench --bench interactive`); the vectors' residuals
/// are far above the solver tolerance (1e-4 measured, `tests/warm_start.rs`), so this answer
/// is for playing while [`solve`] computes the exact one, and it reports them as `NaN` (not
/// computed: they would cost two more products over the whole block).
pub fn ritz(
    next: &FemModel,
    previous: &FemModel,
    previous_solution: &EigenSolution,
    offset: [i64; 3],
    count: usize,
) -> Result<EigenSolution, EigenError> {
    ritz_with(next, previous, previous_solution, offset, count, None).map(|a| a.solution)
}

/// How far a carried answer relaxes the mesh around an edit ([`patch::edit_patch`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reach {
    /// The instant answer: the wide patch ([`patch::WIDE_PATCH_RADIUS`]) where it stays
    /// within [`patch::WIDE_PATCH_MAX_DOFS`], else the narrow one ([`patch::PATCH_RADIUS`]);
    /// patch modes grown only on a patch within that budget.
    Sized,
    /// The second answer ([`crate::engine::CarriedRitzSolver::wide`]): the wide patch up to
    /// [`patch::WIDEST_PATCH_DOFS`], its patch modes grown at any size. 2-20x closer after
    /// several strokes of a drag, at 1.7-3.4x the instant answer's time (ARCHITECTURE.md, "a
    /// second, wide carried answer").
    Wide,
}

/// How [`ritz_factored`] answers.
#[derive(Debug)]
pub struct Carrying<'a> {
    /// Widest factored block kept as factors; a wider one has its vectors formed.
    pub max_width: usize,
    /// The previous answer's whole Gram columns ([`ExactGrams`]): given, a local edit reads
    /// the carried block only near the edit.
    pub kept: Option<&'a ExactGrams>,
    /// How far the relaxation reaches.
    pub reach: Reach,
    /// Polled between the answer's phases (the Gram matrices, the relaxation, the dense
    /// problem): [`EigenError::Interrupted`] once it says stop.
    pub stop: Stop<'a>,
}

/// A carried answer ([`ritz_factored`]).
#[derive(Debug)]
pub struct RitzAnswer {
    /// The modes; `vectors` and `rigid_vectors` have no columns where `rows` holds them.
    pub solution: EigenSolution,
    /// The Ritz vectors as factors, where they were at most [`Carrying::max_width`] wide.
    pub rows: Option<RitzRows>,
    /// Whether [`Reach::Wide`] would relax a wider patch than this answer did (this answer
    /// kept to the narrow one for its size): the second, wide answer is worth computing.
    pub widens: bool,
}

/// [`ritz`] with the Ritz vectors left in factored form where they are at most
/// `how.max_width` factors wide ([`RitzRows`]: any row of them on demand): the solution's
/// `vectors` and `rigid_vectors` then have no columns. Wider (a large correction), they are
/// formed as by [`ritz`] and the rows are `None`. The engine's carried answers, which a
/// strike reads a few rows of ([`crate::basis::ModeBasis::carried_ritz_factored`]). Given the
/// previous answer's [`ExactGrams`], a local edit reads the carried block only near the edit.
pub fn ritz_factored(
    next: &FemModel,
    previous: &FemModel,
    previous_solution: &EigenSolution,
    offset: [i64; 3],
    count: usize,
    how: &Carrying,
) -> Result<RitzAnswer, EigenError> {
    ritz_with(next, previous, previous_solution, offset, count, Some(how))
}

/// [`ritz`], its vectors factored as `how` says ([`ritz_factored`]; `None`: formed, the
/// [`Reach::Sized`] patch, never interrupted).
fn ritz_with(
    next: &FemModel,
    previous: &FemModel,
    previous_solution: &EigenSolution,
    offset: [i64; 3],
    count: usize,
    how: Option<&Carrying>,
) -> Result<RitzAnswer, EigenError> {
    let t0 = Instant::now();
    let factored = how.map(|h| h.max_width);
    let kept = how.and_then(|h| h.kept);
    let reach = how.map_or(Reach::Sized, |h| h.reach);
    let stop = how.map_or(&Stop::NEVER, |h| &h.stop);
    // No norms: this answer reports no residuals. `next` may hold `K` and `M` only near the
    // edit (`FemModel::assemble_near_edit`): the local path below checks that it holds every
    // row it reads, and the whole path needs a whole model.
    let ops = Operators::held_without_norms(next);
    let columns = previous_columns(previous_solution, RITZ_GUARDS);
    let cc = columns.len();
    let n = ops.dofs();
    // The exact rigid fields, unless the previous rigid modes (more than six) are carried.
    let fields = if extra_rigid(previous_solution).ncols() > 0 {
        0
    } else {
        6
    };
    let w = fields + cc;
    if w > n {
        return Err(EigenError::TooFewDofs {
            dofs: n,
            wanted: count,
        });
    }
    let sources = NodeSources::new(previous, next, offset);
    let edited = edited_cells(previous, next, offset);
    let (patch, widens) = edited
        .as_ref()
        .map_or((None, false), |e| edit_patch(next, e, reach));
    let rows_at = patch.as_ref().map_or(&[][..], |p| &p.nodes[..]);
    let touched = edited.as_ref().and_then(|e| grams::touched_nodes(next, e));
    let extra = extra_rigid(previous_solution).ncols();
    let lambda = grams::relations(previous_solution, extra, cc);
    let old = grams::Previous {
        model: previous,
        columns: &columns,
        lambda: &lambda,
    };
    let centre = rigid_centre(next);
    // The factored answer reads no row of the carried block away from the edit where the
    // previous answer's whole Gram columns stand for those of the columns it cannot relate
    // (`warm/exact_grams.rs`) and the edit is local.
    let moved = kept
        .filter(|g| factored.is_some() && fields == 6 && g.fits(previous_solution))
        .map(|g| {
            // The same centre in the previous mesh's positions (voxel units).
            let shift = offset.map(|d| (d * next.kind.voxels_per_element() as i64) as f64);
            g.about([0, 1, 2].map(|a| centre[a] + shift[a]))
        });
    let local = moved.as_ref().zip(touched.as_ref()).and_then(|(mv, t)| {
        let read = grams::rows_read(next, rows_at, t);
        if !next.holds_rows(&read) {
            return None;
        }
        let mut slot = vec![u32::MAX; next.nodes()];
        (read.iter().enumerate()).for_each(|(i, &v)| slot[v] = i as u32);
        let rows = block_rows_on(next, &columns, &sources, fields, centre, &read);
        let x = grams::BlockRows {
            rows: &rows,
            w,
            slot: Some(&slot),
        };
        let map = &sources.map;
        grams::grams(
            &ops,
            next,
            Some(t),
            &old,
            map,
            x,
            fields,
            &[],
            rows_at,
            Some(mv),
        )
    });
    // Else the block on every node: the carried columns after `fields` leading ones, which
    // take the rigid fields.
    let whole_block = || {
        let mut x_rows = transfer_rows(&columns, next, &sources, fields).block;
        let rigid = if fields > 0 {
            rigid_fields(next)
        } else {
            Vec::new()
        };
        if fields > 0 {
            for (i, row) in x_rows.chunks_exact_mut(w).enumerate() {
                row[..fields].copy_from_slice(&rigid[i * 6..i * 6 + fields]);
            }
        }
        (x_rows, rigid)
    };
    let mut whole = None;
    let grams = match local {
        Some(g) => g,
        None if !next.is_whole() => return Err(EigenError::RowsNotHeld),
        None => {
            let (x_rows, rigid) = whole.insert(whole_block());
            grams::grams(
                &ops,
                next,
                touched.as_deref(),
                &old,
                &sources.map,
                grams::BlockRows::whole(x_rows, w),
                fields,
                rigid,
                rows_at,
                None,
            )
            .expect("a whole block")
        }
    };
    stop.check()?;
    let grams::Grams {
        k: mut gk,
        m: mut gm,
        mut k_rows,
        mut m_rows,
    } = grams;
    let correction = match &patch {
        None => None,
        Some(p) => {
            let theta: Vec<f64> = (0..w).map(|j| gk[(j, j)] / gm[(j, j)]).collect();
            // Patch modes grown at any size on the wide reach; else within the wide budget.
            let grow = reach == Reach::Wide;
            let relax = |nodes: &[usize], k: &Mat<f64>, m: &Mat<f64>| {
                let images = (k.as_ref(), m.as_ref());
                correction::local_correction(&ops, next, nodes, &theta, images, grow, stop)
            };
            match (relax(&p.nodes, &k_rows, &m_rows)?, &p.narrow) {
                (None, Some(narrow)) => {
                    // The wide patch held a whole part (hinged to the rest): the narrow one,
                    // whose rows are among the wide one's.
                    (k_rows, m_rows) = (p.rows_of(narrow, &k_rows), p.rows_of(narrow, &m_rows));
                    relax(narrow, &k_rows, &m_rows)?
                }
                (found, _) => found,
            }
        }
    };
    if let Some(cor) = &correction {
        // Rayleigh-Ritz on [X, Delta], Delta zero off the patch: every Gram block involving
        // it needs only the patch rows (`X^T K Delta = (K X)_p^T Delta_p`).
        let grow = |g: &Mat<f64>, a_rows: &Mat<f64>, ad: &Mat<f64>| {
            let cross = a_rows.transpose() * &cor.delta;
            let dd = cor.delta.transpose() * ad;
            let s = w + cor.delta.ncols();
            Mat::from_fn(s, s, |i, j| match (i < w, j < w) {
                (true, true) => g[(i, j)],
                (true, false) => cross[(i, j - w)],
                (false, true) => cross[(j, i - w)],
                (false, false) => dd[(i - w, j - w)],
            })
        };
        gk = grow(&gk, &k_rows, &cor.k_delta);
        gm = grow(&gm, &m_rows, &cor.m_delta);
    }
    stop.check()?;
    let want = (previous_solution.rigid_modes + count).min(w);
    let (theta, c) = lobpcg::dense_ritz_by_cholesky(&gk, &gm, want)?;
    let pairs: Vec<(f64, usize, f64)> = (0..want).map(|j| (theta[j], j, f64::NAN)).collect();
    let sel = select(&ops, &pairs, ModeCount::First(count));
    if sel.rigid != previous_solution.rigid_modes {
        // The stroke joined or split parts: the carried modes cannot describe it.
        return Err(EigenError::BadRequest(format!(
            "the edit changed the rigid-body mode count from {} to {}",
            previous_solution.rigid_modes, sel.rigid
        )));
    }
    // The Ritz vectors, `V = X C_x + Delta C_d`, the answer's kept columns and then its rigid
    // ones in one product: the product transposes `X` (by rows) into its panels on each call,
    // 5 ms of the ceramic cup's answer for a second call with the 6 rigid columns (29.5k
    // rows, 74 columns). An answer that is not exact keeps no guards: it is never a warm start
    // itself. Their residuals are not computed (`NaN`, as for a predicted answer): `K V` and
    // `M V` would cost two more dense products over the whole block, as long as the rest of
    // this answer on a large object, for a figure nothing reads (the answer plays until the
    // exact one lands; its error is the status line's).
    let kept: Vec<usize> = sel.keep.iter().map(|&i| pairs[i].1).collect();
    let eigenvalues: Vec<f64> = sel.keep.iter().map(|&i| pairs[i].0).collect();
    let answer = |vectors: Mat<f64>, rigid_vectors: Mat<f64>| EigenSolution {
        eigenvalues: eigenvalues.clone(),
        vectors,
        residuals: vec![f64::NAN; kept.len()],
        rigid_modes: sel.rigid,
        rigid_vectors,
        guard_vectors: Mat::zeros(n, 0),
        guard_eigenvalues: Vec::new(),
        guard_residuals: Vec::new(),
        timings: SolveTimings {
            setup_ms: 0.0,
            iterate_ms: t0.elapsed().as_secs_f64() * 1e3,
        },
        iterations: 0,
        solver: SolverKind::Lobpcg,
        warm_start: true,
    };
    let s = c.nrows();
    if factored.is_some_and(|max_width| s <= max_width) {
        // The factors instead (`warm/rows.rs`): the rigid modes are not kept either (a warm
        // start reads them only where they are more than a whole's six, [`extra_rigid`], and
        // this answer is never one).
        let rows = RitzRows {
            coefficients: Mat::from_fn(s, kept.len(), |i, j| c[(i, kept[j])]),
            fields,
            centre: if fields > 0 { centre } else { [0.0; 3] },
            guards: previous_solution.guard_vectors.ncols().min(RITZ_GUARDS),
            sources,
            correction: correction.map(|cor| (cor.dofs, cor.delta)),
        };
        return Ok(RitzAnswer {
            solution: answer(Mat::zeros(n, 0), Mat::zeros(n, 0)),
            rows: Some(rows),
            widens,
        });
    }
    // Pairs are ascending, so the rigid ones (eigenvalue ~0) come first.
    let cols: Vec<usize> = (kept.iter())
        .chain(pairs.iter().take(sel.rigid).map(|p| &p.1))
        .copied()
        .collect();
    let c_x = Mat::from_fn(w, cols.len(), |i, j| c[(i, cols[j])]);
    let (x_rows, _) = whole.get_or_insert_with(whole_block);
    let x = MatRef::from_row_major_slice(x_rows, n, w);
    let mut v = x * &c_x;
    if let Some(cor) = &correction {
        let c_d = Mat::from_fn(cor.delta.ncols(), cols.len(), |i, j| c[(w + i, cols[j])]);
        let local = &cor.delta * &c_d;
        for (i, &d) in cor.dofs.iter().enumerate() {
            for j in 0..cols.len() {
                v[(d, j)] += local[(i, j)];
            }
        }
    }
    let rigid_vectors = v.get(.., kept.len()..).to_owned();
    v.truncate(n, kept.len());
    Ok(RitzAnswer {
        solution: answer(v, rigid_vectors),
        rows: None,
        widens,
    })
}

/// Carried guard vectors in the instant answer (the exact warm solve carries them all): enough
/// to keep the highest wanted modes apart from the ones above them.
const RITZ_GUARDS: usize = 8;

/// The previous rigid-body modes when there are more than the six motions of a whole (parts
/// touching along edges or corners); empty otherwise (the exact rigid fields serve).
fn extra_rigid(previous: &EigenSolution) -> MatRef<'_, f64> {
    let r = &previous.rigid_vectors;
    if r.ncols() > 6 {
        r.as_ref()
    } else {
        r.get(.., 0..0)
    }
}

/// The carried block's rows on the nodes `read` (ascending) only, in that order: the rigid
/// fields about `centre` in the first `fields` columns, then each carried column's value as
/// [`transfer_rows`] carries it (a persisting node's own, a new node's the mean of its
/// persisting neighbours').
fn block_rows_on(
    next: &FemModel,
    columns: &[&[f64]],
    sources: &NodeSources,
    fields: usize,
    centre: [f64; 3],
    read: &[usize],
) -> Vec<f64> {
    let w = fields + columns.len();
    let mut rows = vec![0.0; 3 * read.len() * w];
    for (&v, node_rows) in read.iter().zip(rows.chunks_exact_mut(3 * w)) {
        let p = next.node_position(v);
        for (c, row) in node_rows.chunks_exact_mut(w).enumerate() {
            row[..fields].copy_from_slice(&rigid_row(p, centre, c)[..fields]);
            let carried = &mut row[fields..];
            match sources.source(v) {
                Source::Kept(o) => {
                    for (r, column) in carried.iter_mut().zip(columns) {
                        *r = column[3 * o + c];
                    }
                }
                Source::Fresh(from) => {
                    for &o in from {
                        for (r, column) in carried.iter_mut().zip(columns) {
                            *r += column[3 * o + c];
                        }
                    }
                    if !from.is_empty() {
                        let count = from.len() as f64;
                        carried.iter_mut().for_each(|r| *r /= count);
                    }
                }
            }
        }
    }
    rows
}

/// `[rigid fields (if `fields`) | carried modes and guards | random guards]`, row-major
/// `n x m`.
fn start_block(model: &FemModel, carried: &Transferred, m: usize, fields: bool) -> Vec<f64> {
    let n = model.dofs();
    let rigid = rigid_fields(model);
    let f = if fields { 6 } else { 0 };
    let take = carried.columns.min(m.saturating_sub(f + RANDOM_GUARDS));
    let random_cols = m - f - take;
    let random = random_block(n, random_cols, 0x5EED);
    let mut block = vec![0.0; n * m];
    for i in 0..n {
        let row = &mut block[i * m..(i + 1) * m];
        row[..f].copy_from_slice(&rigid[i * 6..i * 6 + f]);
        row[f..f + take]
            .copy_from_slice(&carried.block[i * carried.columns..i * carried.columns + take]);
        for j in 0..random_cols {
            row[f + take + j] = random[(i, j)];
        }
    }
    block
}
