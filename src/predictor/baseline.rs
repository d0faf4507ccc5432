//! The methods the network is compared with, scored by the same metrics:
//! - Deep-Modal's shape matching (Jin et al. 2020, sec. 5.2): a shape's answer is the FEM
//!   labels of the training shape nearest to it by an embedding, the shape's filled volume per
//!   4x4x4-voxel block of the input box (8^3 = 512 numbers, in voxels); nearness is Euclidean.
//! - The product's own progressive first answer ([`coarse_fem`]): FEM on the shape at half the
//!   resolution, fills kept and its thin-wall stiffening divided out
//!   ([`crate::engine::solve_coarse`]), encoded like the labels.
//!
//! Where it sits: `modalforge predictor eval` scores both beside the network, so the network's
//! figures have a floor to beat (shape matching) and a physics answer of known cost to be
//! measured against (the coarse FEM, tens of milliseconds where the network takes a few).

use super::bands::{self, BandEncoding, EncodeError, INPUT_SIDE};
use super::dataset::{Record, REFERENCE_POISSON};
use crate::basis::{BasisError, ModeBasis};
use crate::eigen::{EigenOptions, ModeCount, SolverKind};
use crate::engine::{coarse_grid, coarse_stiffening};
use crate::fem::ElementKind;
use crate::shape::VoxelGrid;

/// Voxels per embedding block along an axis.
const BLOCK: usize = 4;
/// Blocks along an axis.
const BLOCKS: usize = INPUT_SIDE / BLOCK;

/// The shape's embedding (see the module docs).
pub fn embed(grid: &VoxelGrid) -> Vec<f32> {
    let mut e = vec![0.0f32; BLOCKS.pow(3)];
    for v in grid.solid_voxels() {
        if v.iter().all(|&c| c < INPUT_SIDE) {
            let b = v.map(|c| c / BLOCK);
            e[b[0] + BLOCKS * (b[1] + BLOCKS * b[2])] +=
                grid.fraction(v[0] as isize, v[1] as isize, v[2] as isize) as f32;
        }
    }
    e
}

/// The nearest-shape predictor over a set of labelled shapes.
pub struct ShapeMatch<'a> {
    shapes: Vec<(Vec<f32>, &'a BandEncoding)>,
}

impl<'a> ShapeMatch<'a> {
    /// Indexes the training records.
    pub fn new(train: &'a [Record]) -> Self {
        Self {
            shapes: train.iter().map(|r| (embed(&r.grid), &r.labels)).collect(),
        }
    }

    /// The labels of the training shape nearest to `grid` (`None` with no training shapes).
    pub fn predict(&self, grid: &VoxelGrid) -> Option<&'a BandEncoding> {
        let e = embed(grid);
        self.shapes
            .iter()
            .map(|(s, labels)| {
                let d: f32 = s.iter().zip(&e).map(|(a, b)| (a - b) * (a - b)).sum();
                (d, *labels)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, labels)| labels)
    }
}

/// Why [`coarse_fem`] gave no answer.
#[derive(Debug, thiserror::Error)]
pub enum CoarseFemError {
    /// Halving the grid would join parts the shape keeps apart, or leave nothing.
    #[error("the shape has no half-resolution grid (halving it joins its parts)")]
    NoCoarseGrid,
    /// The coarse solve failed.
    #[error(transparent)]
    Solve(#[from] BasisError),
    /// Its modes could not be encoded.
    #[error(transparent)]
    Encode(#[from] EncodeError),
}

/// The progressive first answer for `grid` (a record's shape, voxel edge 1) in the band
/// representation: every mode of the half-resolution grid below the top band, solved with
/// `element` at the labels' Poisson's ratio, its eigenvalues divided by the thin-wall
/// stiffening squared ([`coarse_stiffening`]) and by the coarse voxel's area in the shape's
/// voxels (the labels' unit is the shape's voxel edge), then encoded like the labels (struck at
/// the same points, which the coarse grid spans in the same metres).
///
/// # Errors
/// [`CoarseFemError`].
pub fn coarse_fem(grid: &VoxelGrid, element: ElementKind) -> Result<BandEncoding, CoarseFemError> {
    let coarse = coarse_grid(grid).ok_or(CoarseFemError::NoCoarseGrid)?;
    let to_shape = (coarse.voxel_size_m() / grid.voxel_size_m() * coarse_stiffening(grid)).powi(2);
    let options = EigenOptions {
        count: ModeCount::Below(bands::reference_eigenvalue(bands::HIGH_HZ) * to_shape),
        ..EigenOptions::default()
    };
    let mut basis = ModeBasis::solve(
        &coarse,
        element,
        REFERENCE_POISSON,
        SolverKind::Auto,
        &options,
    )?;
    for lambda in &mut basis.solution.eigenvalues {
        *lambda /= to_shape;
    }
    Ok(BandEncoding::encode(&basis, grid)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predictor::dataset::Family;
    use crate::predictor::metrics::{score, summarise};
    use crate::shape::primitives::Primitive;

    /// The coarse answer against the labels of the same plate (FEM at full resolution): its
    /// lowest modes are within 1.4 % of the exact ones on the plate preset (`cargo bench
    /// --bench interactive`, the coarse column), under a sixth of a band, so most mask entries
    /// agree (measured: recall 87.7 %, precision 88.7 %, 15.7 cents); the bounds leave room
    /// for the modes near a band edge and fail if the eigenvalues are not brought back to the
    /// shape's voxel (a factor of 4: an octave off, no band in common).
    #[test]
    fn the_coarse_answer_agrees_with_the_labels_of_a_plate() {
        let grid = Primitive::Plate {
            length: 24.0,
            width: 16.0,
            thickness: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let element = ElementKind::Hex27Blocks;
        let labels = Record::label(Family::Solid, grid.clone(), element)
            .unwrap()
            .labels;
        let coarse = coarse_fem(&grid, element).unwrap();
        let m = summarise(&[score(&coarse, &labels)]);
        assert!(m.mask_recall > 0.8 && m.mask_precision > 0.8, "{m}");
        assert!(m.pitch_median_cents < 40.0, "{m}");
        // Two bars one voxel apart are two objects; halved, the gap closes: no coarse answer.
        let two = VoxelGrid::from_fn([9, 3, 3], 1.0, |x, _, _| x.floor() as usize != 4).unwrap();
        assert!(matches!(
            coarse_fem(&two, element),
            Err(CoarseFemError::NoCoarseGrid)
        ));
    }
}
