//! The sculpted voxel object as the plugin persists it (`#[persist = "object"]`): dimensions,
//! packed occupancy bits and the partial voxels' sub-cell fill, serialised with the DAW
//! project. States saved before partial voxels existed have no `fill` and load as binary.

use crate::error::PluginError;
use modalforge::fem::ElementKind;
use modalforge::shape::spec::{self, ShapeSpec};
use modalforge::shape::VoxelGrid;
use serde::{Deserialize, Serialize};

/// Largest grid side the editor allows (issue #4: resolution up to 32^3).
pub const MAX_SIDE: usize = 32;

/// Voxels along an element of the plugin's default element, hex27x2: built-in shapes are
/// rasterised centred on its blocks ([`spec::primitive_voxels`]), so a mirror-symmetric
/// shape gives a mirror-symmetric mesh (with the other elements, whose elements are single
/// voxels, the padded faces are partial voxels like a curved shape's).
pub const BLOCK_VOXELS: usize = ElementKind::Hex27Blocks.voxels_per_element();

/// A voxel object: dimensions and one bit per voxel, x fastest.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sculpt {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Occupancy, 8 voxels per byte, x fastest, then y, then z.
    pub bits: Vec<u8>,
    /// The partial voxels as [`VoxelGrid::partial_records`] (per voxel its linear index and
    /// its sub-cell fills); empty for a binary object.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fill: Vec<u8>,
}

impl Sculpt {
    /// From a grid (its voxel size is not kept: the Size parameter sets it).
    pub fn from_grid(grid: &VoxelGrid) -> Self {
        let dims = grid.dims();
        let mut bits = vec![0u8; grid.occupancy().len().div_ceil(8)];
        for (i, &solid) in grid.occupancy().iter().enumerate() {
            if solid {
                bits[i / 8] |= 1 << (i % 8);
            }
        }
        let fill = grid.partial_records();
        Self { dims, bits, fill }
    }

    /// The grid in reference units (voxel edge 1), or why it cannot be one.
    pub fn to_grid(&self) -> Result<VoxelGrid, PluginError> {
        let n = self.dims.iter().product::<usize>();
        if self.dims.iter().any(|&d| d == 0 || d > MAX_SIDE) || self.bits.len() != n.div_ceil(8) {
            return Err(PluginError::Malformed {
                dims: self.dims,
                bytes: self.bits.len(),
            });
        }
        let occupancy = (0..n)
            .map(|i| self.bits[i / 8] >> (i % 8) & 1 == 1)
            .collect();
        let mut grid = VoxelGrid::from_occupancy(self.dims, 1.0, occupancy)?;
        grid.set_partial_records(&self.fill)?;
        Ok(grid)
    }

    /// A built-in shape spec (see the CLI's `--shape` syntax) at scale 1.
    pub fn from_spec(spec: &str) -> Result<Self, PluginError> {
        match spec.parse::<ShapeSpec>()? {
            ShapeSpec::Primitive { shape, hollow } => {
                let grid = spec::primitive_voxels(&shape, hollow, 1.0, BLOCK_VOXELS)?;
                Ok(Self::from_grid(&grid))
            }
            _ => Err(PluginError::FileSpec(spec.into())),
        }
    }
}

impl Default for Sculpt {
    /// A small hemispherical bowl, 16 voxels across with a 2-voxel wall.
    fn default() -> Self {
        Self::from_spec("bowl:d=16,wall=2").expect("the default shape is valid")
    }
}
