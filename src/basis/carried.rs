//! The engine's carried answer to a brush stroke, its vectors kept as factors.
//!
//! Where it sits: [`ModeBasis::carried_ritz_factored`] is what the worker's
//! [`crate::engine::CarriedRitzSolver`] plays after every stroke. It is
//! [`ModeBasis::carried_ritz`] without the last step, the dense product that forms the Ritz
//! vectors over the whole mesh (on the presets 15-25 % of that answer: 10 ms of the ceramic
//! cup's 45, 29.5k rows by 74 columns by 60 modes). A strike reads the vectors at one face's
//! nodes, so the basis keeps the factors ([`RitzRows`], over the exact answer the stroke was
//! carried from) and a strike forms the weighted sum of the face's rows first and multiplies
//! it by the coefficients once: a few thousand multiply-adds, no allocation, as the audio
//! thread needs ([`ModeBasis::reference_forces_into`]).

use super::voicing::FaceWeights;
use super::{BasisError, ModeBasis};
use crate::eigen::warm::{ExactGrams, Reach, RitzRows};
use crate::eigen::Stop;
use crate::fem::{ElementCache, ElementKind, FemModel};
use crate::shape::VoxelGrid;
use std::sync::Arc;

/// Widest factored block (rows of the coefficients) a carried answer keeps as factors: a
/// strike sums its rows into a buffer on the stack. The presets' answers are 150-190 wide
/// (74 carried columns, as many corrections and up to 36 patch modes); a wider one has its
/// vectors formed.
pub(super) const MAX_FACTORED_WIDTH: usize = 320;

/// The answer a stroke is carried from, and whether the carried answer's vectors are formed
/// over the whole mesh or kept as factors over it.
pub(super) enum CarriedFrom<'a> {
    /// Formed ([`ModeBasis::carried_ritz`]).
    Formed(&'a ModeBasis),
    /// Factored ([`ModeBasis::carried_ritz_factored`], [`ModeBasis::carried_ritz_wide`]),
    /// relaxed as far as `reach` says and polling `stop` between its phases.
    Factored {
        from: &'a Arc<ModeBasis>,
        reach: Reach,
        stop: Stop<'a>,
    },
}

impl CarriedFrom<'_> {
    pub(super) fn basis(&self) -> &ModeBasis {
        match self {
            CarriedFrom::Formed(b) => b,
            CarriedFrom::Factored { from, .. } => from,
        }
    }
}

/// A carried answer's vectors: the factors, and the answer they were carried from (whose
/// vectors they read in place).
#[derive(Debug)]
pub(super) struct Factored {
    previous: Arc<ModeBasis>,
    rows: RitzRows,
}

impl Factored {
    pub(super) fn new(previous: &Arc<ModeBasis>, rows: RitzRows) -> Self {
        Factored {
            previous: previous.clone(),
            rows,
        }
    }

    /// Turns mode `j` over.
    pub(super) fn negate(&mut self, j: usize) {
        self.rows
            .coefficients
            .col_mut(j)
            .iter_mut()
            .for_each(|v| *v = -*v);
    }

    /// Each mode's value at the struck face, dotted with `dir`, into `out`: the face's rows of
    /// the factored block weighted and summed, times the coefficients. Never allocates.
    pub(super) fn forces_into(
        &self,
        model: &FemModel,
        face: &FaceWeights,
        dir: [f64; 3],
        out: &mut [f64],
    ) {
        let s = self.rows.width();
        let (mut sum, mut row) = ([0.0; MAX_FACTORED_WIDTH], [0.0; MAX_FACTORED_WIDTH]);
        let previous = &self.previous.solution;
        for &(node, w) in &face.nodes[..face.len] {
            for (c, &d) in dir.iter().enumerate() {
                let a = w * d;
                if a != 0.0 {
                    self.rows
                        .row_into(previous, model, 3 * node + c, &mut row[..s]);
                    for (acc, v) in sum[..s].iter_mut().zip(&row[..s]) {
                        *acc += a * v;
                    }
                }
            }
        }
        let coefficients = &self.rows.coefficients;
        for (j, o) in out.iter_mut().take(coefficients.ncols()).enumerate() {
            *o = coefficients
                .col(j)
                .iter()
                .zip(&sum[..s])
                .map(|(c, y)| c * y)
                .sum();
        }
    }
}

impl ModeBasis {
    /// [`ModeBasis::carried_ritz`] with the Ritz vectors kept as factors over `previous`
    /// (see the module docs): the same eigenvalues and the same strikes, to rounding
    /// (`tests/warm_start.rs`), without the dense product that forms the vectors. Its
    /// `solution.vectors` has no columns (nothing but a strike reads a carried answer's
    /// vectors: it is never the start of another), except where the factors are wider than
    /// a strike's buffer, when they are formed as by [`ModeBasis::carried_ritz`]. Its model
    /// holds `K` and `M` only near the edit ([`FemModel::assemble_near_edit`]; the whole
    /// model where the answer needs more, [`crate::eigen::EigenError::RowsNotHeld`]).
    pub fn carried_ritz_factored(
        grid: &VoxelGrid,
        element: ElementKind,
        poisson_ratio: f64,
        count: usize,
        previous: &Arc<ModeBasis>,
        cache: Option<&mut ElementCache>,
    ) -> Option<Result<Self, BasisError>> {
        let from = CarriedFrom::Factored {
            from: previous,
            reach: Reach::Sized,
            stop: Stop::NEVER,
        };
        Self::carried_with(grid, (element, poisson_ratio), count, from, cache)
    }

    /// The second answer to a stroke: [`ModeBasis::carried_ritz_factored`] relaxing the wide
    /// patch at any size ([`Reach::Wide`]), where the first kept to the narrow one for its
    /// size ([`ModeBasis::carried_widens`]). Several times closer after the strokes of a drag
    /// (ARCHITECTURE.md, "a second, wide carried answer"), for 1.7-3.4x the time. It gives up
    /// with [`crate::eigen::EigenError::Interrupted`] once `stop` says so, polled between its
    /// phases (the assembly, the Gram matrices, the relaxation, the dense problem).
    pub fn carried_ritz_wide(
        grid: &VoxelGrid,
        element: ElementKind,
        poisson_ratio: f64,
        count: usize,
        previous: &Arc<ModeBasis>,
        cache: Option<&mut ElementCache>,
        stop: Stop,
    ) -> Option<Result<Self, BasisError>> {
        let from = CarriedFrom::Factored {
            from: previous,
            reach: Reach::Wide,
            stop,
        };
        Self::carried_with(grid, (element, poisson_ratio), count, from, cache)
    }

    /// Whether this carried answer kept to the narrow patch for its size, where the wide
    /// reach would relax a wider one ([`ModeBasis::carried_ritz_wide`] is worth computing).
    /// False for any other answer.
    pub fn carried_widens(&self) -> bool {
        self.widens
    }

    /// The whole Gram columns a stroke carried from this answer cannot relate, which let its
    /// carried answer read the mesh only near the edit ([`ExactGrams`]; `None` for a shape
    /// of several parts): a few products over the mesh on the first call, kept for the
    /// later ones.
    pub fn exact_grams(&self) -> Option<&ExactGrams> {
        self.exact_grams
            .get_or_init(|| ExactGrams::new(&self.model, &self.solution))
            .as_ref()
    }

    /// Whether the vectors are kept as factors ([`ModeBasis::carried_ritz_factored`]).
    pub fn is_factored(&self) -> bool {
        self.factored.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{EigenOptions, ModeCount, SolverKind};

    /// The factored answer to `edit` of `grid` (hex27x2, the lowest `modes`), made with NaN
    /// in the kept buffers its model takes, after checking it against the formed answer on
    /// the whole model: the same eigenvalues to 1e-10, as `tests/warm_start.rs` bounds the
    /// factored answer (rounding of sums in another order, 1e-11 measured).
    fn factored_as_formed(
        spec: &str,
        modes: usize,
        edit: impl FnOnce(&mut VoxelGrid),
    ) -> ModeBasis {
        let kind = ElementKind::Hex27Blocks;
        let grid = crate::fem::test_grid(spec);
        let options = EigenOptions {
            count: ModeCount::First(modes),
            ..Default::default()
        };
        let before =
            Arc::new(ModeBasis::solve(&grid, kind, 0.3, SolverKind::Auto, &options).unwrap());
        before.exact_grams().expect("one part");
        let mut edited = grid;
        edit(&mut edited);
        let formed = ModeBasis::carried_ritz(&edited, kind, 0.3, modes, &before, None)
            .unwrap()
            .unwrap();
        crate::buffer::poison_kept(formed.model.k().len());
        let factored = ModeBasis::carried_ritz_factored(&edited, kind, 0.3, modes, &before, None)
            .unwrap()
            .unwrap();
        let (a, b) = (&factored.solution.eigenvalues, &formed.solution.eigenvalues);
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-10 * y.abs(), "{x} against {y}");
        }
        factored
    }

    #[test]
    fn a_carried_answer_reads_k_and_m_only_near_the_edit() {
        // The engine's carried answer assembles only the rows of `K` and `M` near the stroke
        // (`FemModel::assemble_near_edit`); the others keep what the kept buffer held: NaN
        // here. Any of them read would turn its eigenvalues NaN or move them off the formed
        // answer's. A voxel added on the rim of a cup.
        let factored = factored_as_formed("cup:d=12,h=12,wall=1", 20, |grid| {
            let d = grid.dims();
            let top = d[2] as isize - 1;
            let (x, y) = (0..d[0])
                .flat_map(|x| (0..d[1]).map(move |y| (x, y)))
                .find(|&(x, y)| grid.get(x as isize, y as isize, top))
                .expect("a rim voxel");
            let beside = grid.get(x as isize, y as isize + 1, top);
            grid.set(x, y + 1, d[2] - 1, !beside);
        });
        assert!(!factored.model.is_whole() && factored.is_factored());
    }

    #[test]
    fn a_carried_answer_that_reads_beyond_the_edit_assembles_the_whole_model() {
        // On a small bar a stroke's neighbourhood is over a quarter of the nodes, which the
        // local Gram sums refuse (`grams::touched_nodes`) although the assembly near the edit
        // is planned (one changed cell of 32): the answer reads the whole model instead of
        // rows that are not held, and is the formed answer's.
        let factored = factored_as_formed("bar:l=16,w=4,h=4", 10, |grid| grid.set(1, 1, 3, false));
        assert!(factored.model.is_whole());
    }
}
