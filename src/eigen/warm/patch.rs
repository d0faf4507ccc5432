//! The patch a carried answer relaxes: which cells an edit changed and which nodes around them
//! are freed.
//!
//! Where it sits: [`super::ritz_with`] asks [`edited_cells`] what a stroke (or a drag's strokes
//! since the last exact answer) changed and [`edit_patch`] which nodes to relax for its
//! [`Reach`]; `correction.rs` then relaxes them (the static correction and the patch's own
//! modes, Craig and Bampton's two ingredients) and `grams.rs` reads the rows around them.

use super::Reach;
use crate::fem::FemModel;
use faer::Mat;
use std::collections::HashSet;

/// Voxels (Chebyshev distance) around an edited voxel whose nodes are relaxed by
/// [`super::correction::local_correction`].
pub(super) const PATCH_RADIUS: i64 = 2;

/// The relaxed patch's radius where it stays within [`WIDE_PATCH_MAX_DOFS`]: twice
/// [`PATCH_RADIUS`]. One stroke on each of the smaller presets' shapes, the worst carried
/// mode's error with the one-block patch against the two-block one (with the extra patch
/// modes a wide patch can need, `correction::patch_modes`; a temporary harness): the brass
/// gong 5.9e-3 -> 1.7e-3, the steel bar 5.4e-3 -> 3.3e-3, the wooden slat 7.0e-4 -> 1.2e-4,
/// the iron pipe 8.2e-4 -> 1.1e-4.
pub(super) const WIDE_PATCH_RADIUS: i64 = 2 * PATCH_RADIUS;

/// Largest wide patch, in DOFs. The carried answer's time, one-block patch against two
/// (medians of 10, two rounds): the iron pipe (429 DOFs) and the brass gong (603) 2-3 ms
/// more, the wooden slat (693) 7 ms more (11-13 -> 19 ms), the steel bar (879, 32 patch
/// modes) 11 ms more (13 -> 24 ms). Measured and not kept: the tin can's and the glass vase's
/// 1,281-DOF wide patches took 5.2e-3 -> 2.9e-3 and 4.9e-3 -> 2.2e-3 for 15-16 ms more (28
/// -> 44 and 34 -> 49 ms), the aluminium plate's 1,089 5.4e-5 -> 2.4e-5 for 5 ms more, and
/// the default object's 2,055 4.9e-3 -> 4.5e-3 for 25 ms more. Stop 69's Krylov growth of
/// the patch modes (`correction::krylov_modes`: the bar 24-25 -> 21-24 ms, the slat 22-25 ->
/// 17-19) left the tin can's wide patch 20-25 ms over its narrow one (58-62 against 31-37 ms,
/// three rounds): most of it is the wide patch's own factor, corrections and Gram rows.
pub(super) const WIDE_PATCH_MAX_DOFS: usize = 1000;

/// Largest relaxed patch, in DOFs (a brush stroke's is a few hundred; beyond this the edit is no
/// stroke and its factor would cost more than the carried answer saves).
pub(super) const MAX_PATCH_DOFS: usize = 1500;

/// Largest wide patch of [`Reach::Wide`], in DOFs. A drag's edit (the cells changed since
/// the last exact answer) grows with its strokes, and so does its wide patch: on the ceramic
/// cup, the glass vase and the default object 1,400-2,500 DOFs after 4-12 strokes
/// (ARCHITECTURE.md, stop 73); beyond 12 strokes the second answer keeps to the narrow patch
/// and is not computed ([`super::RitzAnswer::widens`]).
pub(super) const WIDEST_PATCH_DOFS: usize = 3000;

/// The new model's nodes near the edit for `reach` ([`Reach`]): within [`WIDE_PATCH_RADIUS`]
/// voxels of a voxel that was added, removed or refilled where those are at most
/// [`WIDE_PATCH_MAX_DOFS`] ([`WIDEST_PATCH_DOFS`] on the wide reach), else within
/// [`PATCH_RADIUS`] (for [`crate::fem::ElementKind::Hex27Blocks`]: within two blocks or one
/// of such a block), the `edited` cells of [`edited_cells`]. `None` if nothing changed or the
/// patch is too large to relax. Also whether the wide reach would take a wider patch than
/// this one ([`super::RitzAnswer::widens`]).
pub(super) fn edit_patch(
    next: &FemModel,
    edited: &HashSet<[i64; 3]>,
    reach: Reach,
) -> (Option<Patch>, bool) {
    if edited.is_empty() {
        return (None, false);
    }
    let block = next.kind.voxels_per_element() as i64;
    let near = |radius: i64| nodes_near(next, edited, (radius + block - 1) / block);
    let fits =
        |nodes: &Vec<usize>, most: usize| 3 * nodes.len() <= most && nodes.len() < next.nodes();
    let (wide, narrow) = (near(WIDE_PATCH_RADIUS), near(PATCH_RADIUS));
    let wider = wide.len() > narrow.len();
    let (sized, widest) = (
        wider && fits(&wide, WIDE_PATCH_MAX_DOFS),
        wider && fits(&wide, WIDEST_PATCH_DOFS),
    );
    let take_wide = match reach {
        Reach::Sized => sized,
        Reach::Wide => widest,
    };
    if take_wide {
        let patch = Patch {
            nodes: wide,
            narrow: Some(narrow),
        };
        (Some(patch), false)
    } else {
        let patch = fits(&narrow, MAX_PATCH_DOFS).then_some(Patch {
            nodes: narrow,
            narrow: None,
        });
        let widens = widest && patch.is_some();
        (patch, widens)
    }
}

/// The relaxed patch of [`edit_patch`].
pub(super) struct Patch {
    /// Its nodes, ascending.
    pub(super) nodes: Vec<usize>,
    /// Where `nodes` is the wide patch, the narrow one inside it (ascending) to fall back on:
    /// a wide patch can hold a whole part of the object hinged to the rest, whose stiffness
    /// with the patch's boundary held is singular (`tests/warm_start.rs`, two cubes sharing
    /// an edge).
    pub(super) narrow: Option<Vec<usize>>,
}

impl Patch {
    /// The rows of `rows` (three per node of [`Patch::nodes`], in that order) at `subset`, a
    /// subset of those nodes, ascending.
    pub(super) fn rows_of(&self, subset: &[usize], rows: &Mat<f64>) -> Mat<f64> {
        let mut at = Vec::with_capacity(subset.len());
        let mut i = 0;
        for &node in subset {
            while self.nodes[i] != node {
                i += 1;
            }
            at.push(i);
        }
        Mat::from_fn(3 * subset.len(), rows.ncols(), |r, j| {
            rows[(3 * at[r / 3] + r % 3, j)]
        })
    }
}

/// Element cells around an edit whose rows of `K` and `M` a carried answer reads
/// ([`super::ritz_factored`]): the wide patch's ([`WIDE_PATCH_RADIUS`] voxels, in cells) and one
/// more, for the rows next to the patch's that its Gram sums read (`grams::rows_read`). What
/// the engine's carried answer assembles ([`FemModel::assemble_near_edit`]).
pub fn rows_read_radius_cells(kind: crate::fem::ElementKind) -> usize {
    let block = kind.voxels_per_element() as i64;
    ((WIDE_PATCH_RADIUS + block - 1) / block + 1) as usize
}

/// The nodes of `next` on the elements within `radius` cells (Chebyshev distance) of an
/// `edited` cell: the lattice points of the closed box around each.
pub(super) fn nodes_near(next: &FemModel, edited: &HashSet<[i64; 3]>, radius: i64) -> Vec<usize> {
    let p = next.kind.order() as i64;
    (0..next.nodes())
        .filter(|&node| {
            let q = next.node_lattice_coords(node);
            edited.iter().any(|v| {
                (0..3).all(|a| q[a] >= p * (v[a] - radius) && q[a] <= p * (v[a] + 1 + radius))
            })
        })
        .collect()
}

/// The cells (in `next`'s cell coordinates) that an edit added, removed or refilled: the
/// symmetric difference of the two models' cells with their fills' fingerprints
/// ([`FemModel::cell_fills`]; `previous`'s cells moved by `offset`). `None` when more than
/// [`MAX_EDITED_CELLS`] changed (not a brush stroke).
pub(super) fn edited_cells(
    previous: &FemModel,
    next: &FemModel,
    offset: [i64; 3],
) -> Option<HashSet<[i64; 3]>> {
    // A cell and its fill's fingerprint (0 where the model keeps none).
    let fingerprint = |m: &FemModel, e: usize| m.cell_fills.get(e).copied().unwrap_or(0);
    let old: HashSet<([i64; 3], u64)> = previous
        .voxels
        .iter()
        .enumerate()
        .map(|(e, v)| {
            let c = [0, 1, 2].map(|a| v[a] as i64 - offset[a]);
            (c, fingerprint(previous, e))
        })
        .collect();
    let new: HashSet<([i64; 3], u64)> = next
        .voxels
        .iter()
        .enumerate()
        .map(|(e, v)| (v.map(|c| c as i64), fingerprint(next, e)))
        .collect();
    let edited: HashSet<[i64; 3]> = old.symmetric_difference(&new).map(|(c, _)| *c).collect();
    (edited.len() <= MAX_EDITED_CELLS).then_some(edited)
}

/// The most cells a stroke may change for the instant answer to treat it locally.
pub(super) const MAX_EDITED_CELLS: usize = 64;
