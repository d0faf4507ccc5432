//! Mirror-symmetric objects solved one symmetry class at a time.
//!
//! Where it sits: [`super::solve_until`] offers every Lanczos solve here first. Most objects a
//! sound designer starts from are mirror-symmetric (the default bowl about two planes, a bar, a
//! plate or a sphere about three); their `K` and `M` commute with the mirrors, so the DOF space
//! splits into `2^m` classes (one per character `chi` of the mirror group `Z2^m`) that neither
//! matrix couples, and each class is an eigenproblem of about `1/2^m` the size. Its factor is
//! far smaller than the whole one (the default bowl's quarter: 0.40M nonzeros against 2.1M
//! with the lattice dissection, 0.23M by minimum degree since stop 54, [`crate::fem::ordering`];
//! ~10 ms to factor against ~60), its Krylov vectors a quarter as long and its modes a quarter
//! as many. This is the symmetry-adapted basis of group representation theory (Bossavit 1986,
//! "Symmetry, groups and boundary value problems"; Zienkiewicz, Taylor and Zhu, sec. 9.16).
//!
//! The mirrors are those of the model's node bounding box, checked numerically on every block
//! of `K` and `M` (to [`SYMMETRY_TOLERANCE`] of the largest entry, since refined fills are
//! symmetric only to rounding; a quarter of the blocks are compared, standing for the rest by
//! the matrices' symmetry: [`check`]). For a mirror `g` along axis `a`, `(g u)(p) = R_g
//! u(g p)` with `R_g` flipping component `a`. A node orbit `O` with representative `o` gives class `chi` one
//! basis vector per component `c`, `b = |O|^-1/2 sum_{q in O} sigma_q(c) e_{q,c}` with
//! `sigma_q(c) = chi(g_q) [R_{g_q}]_cc` (`g_q` maps `o` to `q`); it vanishes where a mirror
//! fixing `o` would have to flip it (a node on the plane `x = 0` has no `u_x` in the classes
//! even in `x`): such a DOF is *absent*, kept as a decoupled massless row. By the invariance
//! of `K`, `b_O^T K b_P = sqrt(|O|/|P|) sum_{q in P} sigma_q(d) K(o, c; q, d)`: one pass over
//! the representatives' rows. The basis is orthonormal and `M`-orthogonal across classes, so a
//! class's `M`-orthonormal eigenvectors lift to the whole model's.
//!
//! A swap of two mirrored axes that is a symmetry too maps the classes odd in one of them onto
//! those odd in the other: their modes are images, not solved (the bowl solves three classes
//! of four, a sphere four of eight). A class it maps onto itself (even in both mirrors, or odd
//! in both) it splits in two, each solved on its own ([`split`]): the bowl's three problems of
//! a quarter of the model become one quarter and four eighths.
//!
//! Which classes hold the lowest `k` modes is not known in advance (a bowl's paired modes fill
//! the classes odd in one mirror, its others spread over every class). The first class asks for
//! 1.5 times its share `k / 2^m`; the others for the modes below where the first held 1.25
//! times its share (classes have about equal mode densities), or below the `k`-th lowest found
//! once `k` are found, which bounds the whole model's `k`-th from above; a class whose answer
//! stops below the final bound is asked again, its Lanczos iteration going on from where it
//! stopped ([`Iteration`]: on the aluminium plate preset, 4-8 ms a class where a new solve
//! took 14-23). The residuals are the whole model's (the classes' operators carry its norms,
//! and `||B r|| = ||r||`).

mod check;
mod mirrors;
mod reduced;
mod split;

pub use mirrors::{ClassProblem, Mirrors, SYMMETRY_TOLERANCE};

use mirrors::Lifting;
use reduced::ReducedPattern;
use split::Split;

use super::factor::ShiftedCholesky;
use super::lanczos::{FirstRoom, Iteration, SHIFT_RELATIVE};
use super::{
    warm_guard, EigenError, EigenOptions, EigenSolution, ModeCount, Operators, SolveTimings,
    SolverKind, Stop,
};
use crate::fem::{ordering, FemModel};
use faer::{ColMut, ColRef, Mat, MatRef};
use std::time::Instant;

/// Models below this many DOFs are solved whole: their classes are too small for a block
/// Krylov method to gain. Measured (stop 46, best of 5, whole against classes): a 6x5x4 box
/// (630 DOFs, hex8i) 8.5 against 14.6 ms for 20 modes; a 30x3x3 bar (1,488 DOFs, hex8i)
/// 12.4 against 11.0 ms for 20 modes and 61.5 against 17.2 ms for 60; a 10-voxel bowl (1,608
/// DOFs) 76 against 37 ms for 60.
pub const MIN_DOFS: usize = 1000;

/// Models above this many DOFs are solved whole (or refused there, with the way out): the
/// classes' factors are kept together for the rounds that ask a class again, and at this size
/// the eight classes of a solid's factors already take gigabytes.
pub const MAX_DOFS: usize = 200_000;

/// A class solved: its pairs and vectors, still on the representatives.
struct ClassAnswer {
    chi: u8,
    /// The half of the class it is, where a swap splits it.
    split: Option<Split>,
    /// The swaps mapping it onto each class that is an image of it.
    images: Vec<Vec<usize>>,
    /// What it was asked for.
    asked: ModeCount,
    solution: EigenSolution,
}

/// Solves `model` class by class when it has a mirror and is between [`MIN_DOFS`] and
/// [`MAX_DOFS`], else `None` (the caller solves it whole). A class too small for the request also gives `None`.
pub fn solve_until(
    model: &FemModel,
    options: &EigenOptions,
    stop: Stop,
) -> Option<Result<EigenSolution, EigenError>> {
    if !(MIN_DOFS..=MAX_DOFS).contains(&model.dofs()) {
        return None;
    }
    let t0 = Instant::now();
    let mirrors = Mirrors::detect(model)?;
    match solve_classes(model, &mirrors, options, stop, t0) {
        Err(EigenError::TooFewDofs { .. }) => None,
        answer => Some(answer),
    }
}

/// The class-by-class solve (see the module docs).
fn solve_classes(
    model: &FemModel,
    mirrors: &Mirrors,
    options: &EigenOptions,
    stop: Stop,
    t0: Instant,
) -> Result<EigenSolution, EigenError> {
    let whole = Operators::new(model);
    let shift = -SHIFT_RELATIVE * whole.scale;
    let class_count = mirrors.classes().len();
    let p = model.kind.order() as i64;
    let coords: Vec<[i64; 3]> = (mirrors.reps.iter())
        .map(|&n| model.node_lattice_coords(n))
        .collect();
    // The problems to solve: the first class of each group of classes that swaps map onto
    // one another (the others are images of it), or both halves of it where a swap maps it
    // onto itself and it is large enough ([`split`]).
    let mut parts = Vec::new();
    for group in mirrors.groups() {
        let chi = group[0].0;
        let images: Vec<Vec<usize>> = group[1..].iter().map(|(_, path)| path.clone()).collect();
        let swap = (mirrors.splitting_swap(chi))
            .filter(|_| model.dofs() / class_count >= MIN_SPLIT_CLASS_DOFS);
        match swap {
            Some(swap) => {
                for tau in [1.0, -1.0] {
                    let split = Split::new(mirrors, chi, swap, tau, &coords);
                    parts.push((chi, Some((swap, split)), images.clone()));
                }
            }
            None => parts.push((chi, None, images)),
        }
    }
    // A part's share of a request: a class holds about `1 / class_count` of the modes, a
    // half of one about half that (mode densities go with dimensions).
    let share_of = |halved: bool, of: usize| of.div_ceil(class_count * (1 + usize::from(halved)));
    let first_halved = parts.first().is_some_and(|p| p.1.is_some());
    // The first part makes room for 1.5 times its share of the request; the others ask for
    // the modes below what that share reached in it (parts have about equal densities of
    // modes per DOF), or below the k-th lowest found so far once that is known.
    let first = match options.count {
        ModeCount::First(k) => {
            ModeCount::First((share_of(first_halved, 3 * k).div_ceil(2)).min(k) + 2)
        }
        below => below,
    };
    let share = |halved: bool| match options.count {
        ModeCount::First(k) => share_of(halved, k),
        ModeCount::Below(_) => share_of(halved, BELOW_SHARE),
    };
    // Elimination orders (whichever of dissection and minimum degree fills less): the
    // classes' on the orbit representatives, a half's on its own (one per swap that splits).
    let mut orders: Vec<Option<Vec<usize>>> = vec![None; 1 + mirrors.swaps().len()];
    // And the halves' pattern, one per swap that splits.
    let mut half_patterns: Vec<Option<ReducedPattern>> =
        (0..mirrors.swaps().len()).map(|_| None).collect();
    let (mut iterate_ms, mut iterations) = (0.0, 0);
    let mut solved: Vec<ClassAnswer> = Vec::with_capacity(parts.len());
    let mut problems = Vec::with_capacity(parts.len());
    let mut estimate = None;
    // The class a split part was reduced from, kept for its other half.
    let mut class_of_halves: Option<ClassProblem> = None;
    for (chi, split, images) in parts {
        let halved = split.is_some();
        let (class, slot) = match &split {
            None => (mirrors.reduce(model, chi), 0),
            Some((swap, half)) => {
                if class_of_halves.as_ref().is_none_or(|c| c.chi != chi) {
                    class_of_halves = Some(mirrors.reduce(model, chi));
                }
                let class = class_of_halves.as_ref().expect("reduced above");
                let plan = half_patterns[*swap].get_or_insert_with(|| half.pattern(&class.pattern));
                (half.reduce(class, plan), 1 + swap)
            }
        };
        // Every class has the same pattern, and so have the halves of one swap: one order each.
        let nodes = &*orders[slot].get_or_insert_with(|| match &split {
            None => ordering::fill_reducing(&class.pattern, &coords, p),
            Some((_, half)) => {
                let at: Vec<[i64; 3]> = half.reps().iter().map(|&o| coords[o as usize]).collect();
                ordering::fill_reducing(&class.pattern, &at, p)
            }
        });
        let mut llt = ShiftedCholesky::for_class(
            &class.pattern,
            &class.k,
            &class.m,
            &class.mass_extra,
            shift,
            nodes,
            stop,
        )?;
        stop.check()?;
        let count = match (kth_lowest(&solved, options.count), estimate) {
            (Some(bound), _) => ModeCount::Below(bound * (1.0 + BOUND_MARGIN)),
            (None, Some(e)) => ModeCount::Below(e),
            (None, None) => first,
        };
        let ops = class.operators(&whole);
        // A part asked below the estimate is expected to hold about 1.25 times its share.
        let expected = (5 * share(halved)).div_ceil(4);
        let (solution, iteration) =
            solve_class(&ops, &mut llt, shift, options, count, expected, stop)?;
        if estimate.is_none() && matches!(options.count, ModeCount::First(_)) {
            // Where this part holds 1.25 times its share.
            let e = &solution.eigenvalues;
            estimate = e
                .get((5 * share(halved) / 4).min(e.len().saturating_sub(1)))
                .copied();
        }
        iterate_ms += solution.timings.iterate_ms;
        iterations += solution.iterations;
        solved.push(ClassAnswer {
            chi,
            split: split.map(|(_, half)| half),
            images,
            asked: count,
            solution,
        });
        problems.push((class, llt, iteration));
    }
    // Until every class holds every mode below the k-th lowest found: a class whose request
    // stopped below that bound is asked again (or, while fewer than k modes are found at
    // all, the classes asked below a bound are asked below a higher one).
    let asks_first = matches!(options.count, ModeCount::First(_));
    for _ in 0..MAX_ROUNDS {
        let bound = kth_lowest(&solved, options.count);
        let raise = raise_factor(&solved, options.count);
        let mut again = Vec::new();
        for (i, answer) in solved.iter().enumerate() {
            let found = &answer.solution.eigenvalues;
            let top = found.last().copied().unwrap_or(0.0);
            let limit = match (answer.asked, bound) {
                (ModeCount::First(asked), Some(b)) if found.len() >= asked && top <= b => Some(b),
                (ModeCount::Below(l), Some(b)) if l < b => Some(b),
                (ModeCount::Below(l), None) if asks_first => Some(l * raise),
                _ => None,
            };
            if let Some(limit) = limit {
                again.push((i, limit * (1.0 + BOUND_MARGIN)));
            }
        }
        if again.is_empty() {
            let total_ms = t0.elapsed().as_secs_f64() * 1e3;
            return Ok(combine(
                mirrors,
                &solved,
                options.count,
                SolveTimings {
                    setup_ms: total_ms - iterate_ms,
                    iterate_ms,
                },
                iterations,
            ));
        }
        for (i, limit) in again {
            let (class, llt, iteration) = &mut problems[i];
            let ops = class.operators(&whole);
            let count = ModeCount::Below(limit);
            let found = solved[i].solution.eigenvalues.len();
            // The class's basis goes on from where its last request was met, for a few more
            // modes than it found (the bound rose to the k-th lowest of all classes).
            iteration.make_room(&ops, room_pairs(found * 3 / 2), found + 2 + RIGID_EXPECTED);
            let class_options = EigenOptions { count, ..*options };
            let solution = iteration.run(&ops, llt, shift, &class_options, stop)?;
            iterate_ms += solution.timings.iterate_ms;
            iterations += solution.iterations;
            solved[i].asked = count;
            solved[i].solution = solution;
        }
    }
    // Not met in the tests (each round raises a bound or settles the classes at it); the
    // caller then solves the model whole, as it does for a class too small for its request.
    Err(EigenError::TooFewDofs {
        dofs: model.dofs(),
        wanted: match options.count {
            ModeCount::First(k) => k,
            ModeCount::Below(_) => 0,
        },
    })
}

/// One class's Lanczos solve for `count`, with room for about `expected` modes below a bound;
/// the iteration is returned with the answer, to be asked again for more.
fn solve_class(
    ops: &Operators,
    llt: &mut ShiftedCholesky,
    shift: f64,
    options: &EigenOptions,
    count: ModeCount,
    expected: usize,
    stop: Stop,
) -> Result<(EigenSolution, Iteration), EigenError> {
    // Room for six rigid modes whichever the class holds: the basis needs the slack.
    let room = FirstRoom {
        rigid: RIGID_ROOM,
        below: room_pairs(expected),
        rigid_expected: RIGID_EXPECTED,
        below_expected: expected + RIGID_EXPECTED,
    };
    // The pairs its checks aim at, as `Iteration::start` reckons them from the room.
    let aim = match count {
        ModeCount::First(k) => k + room.rigid_expected,
        ModeCount::Below(_) => room.below_expected,
    };
    let block_size = if aim <= TINY_BLOCK_MAX_PAIRS {
        options.block_size.min(TINY_BLOCK_SIZE)
    } else if aim <= SMALL_BLOCK_MAX_PAIRS {
        options.block_size.min(SMALL_BLOCK_SIZE)
    } else {
        options.block_size
    };
    let class_options = EigenOptions {
        count,
        block_size,
        ..*options
    };
    let mut iteration = Iteration::start(ops, &class_options, room)?;
    let solution = iteration.run(ops, llt, shift, &class_options, stop)?;
    Ok((solution, iteration))
}

/// Pairs a class's "below" request checks when it expects about `expected` modes.
fn room_pairs(expected: usize) -> usize {
    2 * expected + RIGID_ROOM
}

/// The k-th lowest mode the classes found, for a "first k" request that has found k: an upper
/// bound on the whole model's k-th.
fn kth_lowest(solved: &[ClassAnswer], count: ModeCount) -> Option<f64> {
    let ModeCount::First(k) = count else {
        return None;
    };
    let mut all: Vec<f64> = solved
        .iter()
        .flat_map(|s| {
            let copies = 1 + s.images.len();
            s.solution
                .eigenvalues
                .iter()
                .flat_map(move |&l| std::iter::repeat_n(l, copies))
        })
        .collect();
    (all.len() >= k).then(|| *all.select_nth_unstable_by(k - 1, f64::total_cmp).1)
}

/// Classes of at least this many DOFs are split in two by a swap that maps them onto
/// themselves ([`split`]). Measured (best of 3 cold solves, 60 modes, hex27x2, interleaved
/// rounds): see ARCHITECTURE.md, "Classes a swap maps onto themselves are split".
pub const MIN_SPLIT_CLASS_DOFS: usize = 1000;

/// Rounds of asking classes again before giving up on the class-by-class solve.
const MAX_ROUNDS: usize = 8;

/// The most a class's bound is raised while fewer than k modes are found.
const RAISE: f64 = 1.5;

/// The margin of [`raise_factor`] over the ratio of the modes wanted to those found.
const RAISE_MARGIN: f64 = 1.1;

/// How much the classes' bounds are raised while they hold fewer than the k modes a "first
/// k" request wants: the ratio of k to the modes found (with their images), as the count of
/// modes below a bound grows about in proportion to it on the shells and plates that fall
/// short (two-dimensional: `N ~ omega^2 ~ lambda`; a solid's grows faster, so the ratio
/// overshoots it a little), with a margin of [`RAISE_MARGIN`] and at most [`RAISE`]. The tin
/// can preset's ten parts found 58 of 60 below the first class's estimate; raised by the
/// flat 1.5 they all went on to half as many modes again as they needed.
fn raise_factor(solved: &[ClassAnswer], count: ModeCount) -> f64 {
    let ModeCount::First(k) = count else {
        return RAISE;
    };
    let found: usize = (solved.iter())
        .map(|s| s.solution.eigenvalues.len() * (1 + s.images.len()))
        .sum();
    if found == 0 {
        return RAISE;
    }
    (k as f64 / found as f64 * RAISE_MARGIN).clamp(RAISE_MARGIN, RAISE)
}

/// A "below" bound is widened by this relative margin, so a mode at the bound itself (its
/// twin in another class, rounded differently) is not missed.
const BOUND_MARGIN: f64 = 1e-9;

/// Modes a "below f_max" request is expected to hold, for the first room of its classes.
const BELOW_SHARE: usize = 20;

/// Pairs of room a class's basis first keeps beyond its modes (a class holds one to three of
/// the six rigid motions): with six, the whole solve's room, the default bowl's first classes
/// filled their bases and restarted once; with twelve none did.
const RIGID_ROOM: usize = 12;

/// Lanczos block size of a class that expects more than [`TINY_BLOCK_MAX_PAIRS`] and at most
/// [`SMALL_BLOCK_MAX_PAIRS`] pairs (the whole model's, and a larger class's, is
/// [`EigenOptions::block_size`], 8). A block Krylov
/// space of `j` blocks holds polynomials of degree `j` only, so a block method needs a few
/// blocks beyond its wanted pairs whatever their number: with blocks of 4 the default bowl's
/// three classes (25 and 15 pairs) converged in 252 vectors against 344 with blocks of 8, the
/// tin can's six in 300 against 400. Cold class solves (best of 3, five interleaved rounds,
/// median), blocks of 4 against 8: the default bowl 0.83x, the tin can 0.81x, the brass gong
/// 0.79x, the aluminium plate 0.89x, the plastic crate 0.87x; blocks of 6 were 1.14-1.28x
/// slower than 4 (the packed triangular solves take six right-hand sides as chunks of four
/// and two, two passes over the factor), and whole 60-mode solves stay faster with 8 (the
/// default bowl solved whole with 4: 1.23x).
const SMALL_BLOCK_SIZE: usize = 4;

/// Lanczos block size of a class that expects at most [`TINY_BLOCK_MAX_PAIRS`] pairs: a
/// 20-mode request's classes. There a convergence check (the projected matrix's band
/// eigenvalues, ~`len^2` times the block size) costs more than a block of triangular solves on
/// a class factor of a few hundred DOFs, and a narrower block checks a shorter, narrower band
/// and overshoots the last pair by fewer vectors. Measured (hex8i, 20 modes, cold class solves,
/// best of 5, interleaved rounds), blocks of 2 against 4: the SciPy comparison's 1.5k-DOF bar
/// (classes of 192 DOFs) 0.75x, the 9.9k-DOF sphere 0.95x, the 4.6k-DOF bowl 1.01x. Classes
/// that expect 13 pairs (60-mode requests on the small presets, ~450 DOFs) were mixed (the
/// iron pipe 0.91x, the wooden slat and block 1.03x) and keep blocks of 4.
const TINY_BLOCK_SIZE: usize = 2;

/// Pairs (rigid ones included) up to which a class iterates in blocks of [`TINY_BLOCK_SIZE`].
const TINY_BLOCK_MAX_PAIRS: usize = 10;

/// Pairs (rigid ones included) up to which a class iterates in blocks of
/// [`SMALL_BLOCK_SIZE`]: between the default bowl's first class (28, faster with 4) and the
/// whole model's 66 (faster with 8). The classes of the one-mirror presets ask for more (the
/// ceramic cup's two, 15k DOFs each: 50 and 41) and keep blocks of 8; measured on the cup,
/// blocks of 4 were 0.98-1.10x the time of 8 over several interleaved runs, within this
/// machine's spread.
const SMALL_BLOCK_MAX_PAIRS: usize = 32;

/// Rigid motions a class holds at most (one mirror splits the six into three and three):
/// the convergence checks are scheduled for a class's modes and these, not for its room.
const RIGID_EXPECTED: usize = 3;

/// Where columns of the whole model's answer come from: a class's answer, lifted onto the
/// whole model as that class's vectors or as their images in a class a swap maps it onto.
struct Source<'a> {
    solution: &'a EigenSolution,
    lifting: &'a Lifting,
}

impl Source<'_> {
    /// Writes class vector `x`, lifted, into the whole model's column `out`.
    fn write(&self, x: ColRef<'_, f64>, out: ColMut<'_, f64>) {
        let out = out
            .try_as_col_major_mut()
            .expect("the answer's columns are contiguous")
            .as_slice_mut();
        self.lifting.column(x, out);
    }
}

/// Lifts each source's block of class vectors into consecutive columns of `out`, from column
/// `at`.
fn write_blocks<'a>(
    out: &mut Mat<f64>,
    mut at: usize,
    blocks: impl Iterator<Item = (&'a Source<'a>, MatRef<'a, f64>)>,
) {
    for (source, x) in blocks {
        for j in 0..x.ncols() {
            source.write(x.col(j), out.col_mut(at + j));
        }
        at += x.ncols();
    }
}

/// The whole model's answer from its classes': the lowest pairs of all (or those below the
/// bound), lifted, the solved classes' and their images'; rigid modes of every class; the next
/// pairs above as guards. Only the columns kept are lifted, each straight into the answer.
fn combine(
    mirrors: &Mirrors,
    solved: &[ClassAnswer],
    count: ModeCount,
    timings: SolveTimings,
    iterations: usize,
) -> EigenSolution {
    // Each source's lifting: a solved class's, and its images' (the same, mapped by their
    // swaps), so that a column is lifted straight to where it belongs.
    let mut liftings: Vec<(&EigenSolution, Lifting)> = Vec::new();
    for s in solved {
        let lifting = Lifting::new(mirrors, s.chi);
        let lifting = match &s.split {
            Some(half) => half.compose(lifting),
            None => lifting,
        };
        for path in &s.images {
            liftings.push((&s.solution, lifting.mapped(mirrors, path)));
        }
        liftings.push((&s.solution, lifting));
    }
    let sources: Vec<Source> = (liftings.iter())
        .map(|(solution, lifting)| Source { solution, lifting })
        .collect();
    // (eigenvalue, source, column, residual)
    let mut pairs: Vec<(f64, usize, usize, f64)> = sources
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            let sol = l.solution;
            (0..sol.eigenvalues.len()).map(move |j| (sol.eigenvalues[j], i, j, sol.residuals[j]))
        })
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let keep = match count {
        ModeCount::First(k) => k.min(pairs.len()),
        ModeCount::Below(l) => pairs.iter().take_while(|p| p.0 <= l).count(),
    };
    let n = 3 * mirrors.orbit_of.len();
    let write_pairs = |pairs: &[(f64, usize, usize, f64)], out: &mut Mat<f64>| {
        for (j, &(_, i, col, _)) in pairs.iter().enumerate() {
            let source = &sources[i];
            source.write(source.solution.vectors.col(col), out.col_mut(j));
        }
    };
    let mut vectors = Mat::zeros(n, keep);
    write_pairs(&pairs[..keep], &mut vectors);
    // Guards: the next pairs above, then the classes' own guards.
    let rigid_modes: usize = sources.iter().map(|l| l.solution.rigid_modes).sum();
    let guard_count = warm_guard(rigid_modes + keep);
    let extra = &pairs[keep..pairs.len().min(keep + guard_count)];
    let from_guards: Vec<usize> = sources
        .iter()
        .scan(extra.len(), |have, l| {
            let take = l.solution.guard_vectors.ncols().min(guard_count - *have);
            *have += take;
            Some(take)
        })
        .collect();
    let mut guard_vectors = Mat::zeros(n, extra.len() + from_guards.iter().sum::<usize>());
    write_pairs(extra, &mut guard_vectors);
    let own_guards = (sources.iter().zip(&from_guards))
        .map(|(l, &take)| (l, l.solution.guard_vectors.get(.., 0..take)));
    write_blocks(&mut guard_vectors, extra.len(), own_guards);
    // Their eigenvalues and residuals: the pairs above the request are converged; a class's
    // own guards are where its solve says.
    let (mut guard_eigenvalues, mut guard_residuals): (Vec<f64>, Vec<f64>) =
        extra.iter().map(|p| (p.0, p.3)).unzip();
    for (l, &take) in sources.iter().zip(&from_guards) {
        guard_eigenvalues.extend_from_slice(&l.solution.guard_eigenvalues[..take]);
        guard_residuals.extend_from_slice(&l.solution.guard_residuals[..take]);
    }
    let rigid_count = sources
        .iter()
        .map(|l| l.solution.rigid_vectors.ncols())
        .sum();
    let mut rigid_vectors = Mat::zeros(n, rigid_count);
    let rigid = sources
        .iter()
        .map(|l| (l, l.solution.rigid_vectors.as_ref()));
    write_blocks(&mut rigid_vectors, 0, rigid);
    EigenSolution {
        eigenvalues: pairs[..keep].iter().map(|p| p.0).collect(),
        vectors,
        residuals: pairs[..keep].iter().map(|p| p.3).collect(),
        rigid_modes,
        timings,
        iterations,
        solver: SolverKind::Lanczos,
        warm_start: false,
        guard_vectors,
        guard_eigenvalues,
        guard_residuals,
        rigid_vectors,
    }
}
