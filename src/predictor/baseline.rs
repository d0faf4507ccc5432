//! Deep-Modal's comparison method: shape matching (Jin et al. 2020, sec. 5.2). A
//! shape's answer is the FEM labels of the training shape nearest to it by an embedding.
//!
//! Where it sits: `modalforge predictor eval` scores it beside the network, so the network's
//! figures have a floor to beat. The embedding is the shape's filled volume per 4x4x4-voxel
//! block of the input box (8^3 = 512 numbers, in voxels); nearness is Euclidean.

use super::bands::{BandEncoding, INPUT_SIDE};
use super::dataset::Record;
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
