//! Exact answers kept between requests: a request solved before is answered at once.
//!
//! Where it sits: [`super::solvers::IncrementalFemSolver`] looks a request up in its chain's
//! [`KeptAnswers`] before it solves, and keeps what it solves; while the exact answer is there,
//! the chain's faster answers (coarse, carried, neural) step aside, since the exact one costs
//! nothing. The plugin gives every instance's chain the same `KeptAnswers` (one per process):
//! a second instance with the same object (a project that loads several), an undo back to an
//! earlier shape, a preset chosen again, or a solver parameter flipped back all get their
//! exact modes without a solve.
//!
//! **A hit is the same request**: the same element, Poisson's ratio, solver and options, and the
//! same shape, compared voxel by voxel (occupancy and partial fills; the voxel size does not
//! enter a reference-unit solve). The 64-bit shape hash only picks candidates. The answer is
//! the one a solve would give (solves are deterministic), shared, not copied.
//!
//! **Memory** is bounded: at most [`MAX_ANSWERS`] answers and [`MAX_BYTES`] of their matrices
//! and vectors, the least recently used dropped first (an answer the audio side still plays
//! stays alive there until it is replaced).

use super::worker::ObjectRequest;
use crate::basis::ModeBasis;
use crate::eigen::{EigenOptions, SolverKind};
use crate::fem::ElementKind;
use crate::shape::VoxelGrid;
use std::sync::{Arc, Mutex, MutexGuard};

/// Most answers kept.
pub const MAX_ANSWERS: usize = 8;

/// Most bytes of answers kept (the default bowl's hex27x2 answer, matrices included, is about
/// 12 MB).
pub const MAX_BYTES: usize = 96 << 20;

/// What a request asks beyond its shape.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Question {
    shape_hash: u64,
    element: ElementKind,
    poisson_ratio_bits: u64,
    solver: SolverKind,
    options: EigenOptions,
}

impl Question {
    fn of(r: &ObjectRequest) -> Self {
        Self {
            shape_hash: r.grid.shape_hash(),
            element: r.element,
            poisson_ratio_bits: r.poisson_ratio.to_bits(),
            solver: r.solver,
            options: r.options,
        }
    }
}

struct Answer {
    question: Question,
    grid: VoxelGrid,
    basis: Arc<ModeBasis>,
    bytes: usize,
}

/// Exact answers kept for the chains that share this handle (cloning shares them), least
/// recently used first.
#[derive(Clone, Default)]
pub struct KeptAnswers(Arc<Mutex<Vec<Answer>>>);

/// Whether two grids hold the same shape (the voxel size aside).
fn same_shape(a: &VoxelGrid, b: &VoxelGrid) -> bool {
    a.dims() == b.dims()
        && a.occupancy() == b.occupancy()
        && a.partial_records() == b.partial_records()
}

fn position(list: &[Answer], r: &ObjectRequest) -> Option<usize> {
    let question = Question::of(r);
    list.iter()
        .position(|a| a.question == question && same_shape(&a.grid, &r.grid))
}

impl KeptAnswers {
    /// An empty store.
    pub fn new() -> Self {
        Self::default()
    }

    fn list(&self) -> MutexGuard<'_, Vec<Answer>> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The kept exact answer to `r`, if any (it becomes the most recently used).
    pub fn find(&self, r: &ObjectRequest) -> Option<Arc<ModeBasis>> {
        let mut list = self.list();
        let i = position(&list, r)?;
        let answer = list.remove(i);
        let basis = answer.basis.clone();
        list.push(answer);
        Some(basis)
    }

    /// Whether an exact answer to `r` is kept.
    pub fn has(&self, r: &ObjectRequest) -> bool {
        position(&self.list(), r).is_some()
    }

    /// Keeps `basis` as the exact answer to `r`, dropping the least recently used answers
    /// beyond the limits. An answer larger than [`MAX_BYTES`] alone is not kept.
    pub fn keep(&self, r: &ObjectRequest, basis: &Arc<ModeBasis>) {
        let bytes = approximate_bytes(basis);
        if bytes > MAX_BYTES {
            return;
        }
        let mut list = self.list();
        if let Some(i) = position(&list, r) {
            list.remove(i);
        }
        list.push(Answer {
            question: Question::of(r),
            grid: r.grid.clone(),
            basis: basis.clone(),
            bytes,
        });
        while list.len() > MAX_ANSWERS || list.iter().map(|a| a.bytes).sum::<usize>() > MAX_BYTES {
            list.remove(0);
        }
    }

    /// Drops every kept answer (for measurements that compare the heap at two moments).
    pub fn clear(&self) {
        self.list().clear();
    }

    /// Answers kept now, and their bytes.
    pub fn usage(&self) -> (usize, usize) {
        let list = self.list();
        (list.len(), list.iter().map(|a| a.bytes).sum())
    }
}

impl std::fmt::Debug for KeptAnswers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (answers, bytes) = self.usage();
        write!(f, "KeptAnswers({answers} answers, {bytes} bytes)")
    }
}

/// The bytes of a basis's large arrays: the matrices, the node tables and the vectors.
fn approximate_bytes(b: &ModeBasis) -> usize {
    let m = &b.model;
    let s = &b.solution;
    let vectors = [&s.vectors, &s.guard_vectors, &s.rigid_vectors]
        .iter()
        .map(|v| v.nrows() * v.ncols() * 8)
        .sum::<usize>();
    let (k, mass) = m.rows_held();
    k.len() * 72
        + mass.len() * 8
        + m.pattern.col.len() * 4
        + m.pattern.row_ptr.len() * 8
        + m.elements.len() * 4
        + m.node_lattice.len() * 8
        + m.lattice_node.len() * 4
        + m.voxels.len() * 24
        + vectors
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::ModeCount;

    fn request(grid: VoxelGrid, nu: f64) -> ObjectRequest {
        ObjectRequest {
            grid,
            element: ElementKind::Hex8Incompatible,
            poisson_ratio: nu,
            solver: SolverKind::Auto,
            options: EigenOptions {
                count: ModeCount::First(8),
                ..EigenOptions::default()
            },
            recording: None,
        }
    }

    fn cube(side: usize, voxel_size_m: f64) -> VoxelGrid {
        VoxelGrid::from_fn([side, side, side], voxel_size_m, |_, _, _| true).unwrap()
    }

    fn solved(r: &ObjectRequest) -> Arc<ModeBasis> {
        Arc::new(
            ModeBasis::solve(&r.grid, r.element, r.poisson_ratio, r.solver, &r.options).unwrap(),
        )
    }

    #[test]
    fn only_the_same_question_on_the_same_shape_finds_an_answer() {
        let kept = KeptAnswers::new();
        let r = request(cube(3, 0.01), 0.3);
        let basis = solved(&r);
        assert!(kept.find(&r).is_none());
        kept.keep(&r, &basis);
        // Shared, not copied; the voxel size does not enter a reference-unit solve.
        assert!(Arc::ptr_eq(&kept.find(&r).unwrap(), &basis));
        assert!(kept.has(&request(cube(3, 0.5), 0.3)));
        // Another ratio, element, mode count or shape is another question.
        assert!(!kept.has(&request(cube(3, 0.01), 0.31)));
        let mut other = r.clone();
        other.element = ElementKind::Hex27;
        assert!(!kept.has(&other));
        let mut other = r.clone();
        other.options.count = ModeCount::First(9);
        assert!(!kept.has(&other));
        let mut dented = cube(3, 0.01);
        dented.set(0, 0, 0, false);
        assert!(!kept.has(&request(dented, 0.3)));
    }

    #[test]
    fn the_least_recently_used_answer_goes_first() {
        let kept = KeptAnswers::new();
        let basis = solved(&request(cube(2, 1.0), 0.3));
        let question = |i: usize| request(cube(2, 1.0), 0.2 + 0.01 * i as f64);
        for i in 0..MAX_ANSWERS {
            kept.keep(&question(i), &basis);
        }
        assert!(
            kept.find(&question(0)).is_some(),
            "0 becomes the most recent"
        );
        kept.keep(&question(MAX_ANSWERS), &basis);
        assert_eq!(kept.usage().0, MAX_ANSWERS);
        assert!(kept.has(&question(0)));
        assert!(!kept.has(&question(1)), "1 was the least recently used");
        assert!(kept.has(&question(MAX_ANSWERS)));
        kept.clear();
        assert_eq!(kept.usage(), (0, 0));
    }
}
