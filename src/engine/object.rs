//! A solved object as the audio side holds it: the [`ModeBasis`] plus the scratch a strike
//! needs, allocated by the worker so that the audio thread never allocates.
//!
//! Where it sits: built by [`super::worker`], moved to [`super::audio::AudioEngine`] through an
//! `rtrb` ring (a pointer move), and moved back through the retire ring when replaced, to be
//! freed on the worker.

use super::recorded::RecordedObject;
use super::voicing::HitPoint;
use crate::basis::{Hit, HitError, ModeBasis};
use crate::predictor::object::PredictedObject;
use std::sync::Arc;

/// A shape's modes from either source: what the audio side strikes and the editor's spectrum
/// draws. Eigenvalues and forces are in reference units with the shape's voxel edge as the
/// unit, whichever solver made them.
#[derive(Debug)]
pub enum ObjectModes {
    /// Finite elements: exact to the solver tolerance (shared: the chain keeps the last exact
    /// answer and [`super::answers`] the recent ones).
    Fem(Arc<ModeBasis>),
    /// The neural predictor: one mode per predicted band, in milliseconds.
    Predicted(Box<PredictedObject>),
    /// A recording's own modes ([`super::recorded`]): played as recorded.
    Recorded(RecordedObject),
}

impl ObjectModes {
    /// Reference-unit eigenvalues, ascending.
    pub fn eigenvalues(&self) -> &[f64] {
        match self {
            ObjectModes::Fem(b) => &b.solution.eigenvalues,
            ObjectModes::Predicted(p) => &p.eigenvalues,
            ObjectModes::Recorded(r) => &r.eigenvalues,
        }
    }

    /// Modes held.
    pub fn mode_count(&self) -> usize {
        self.eigenvalues().len()
    }

    /// The shape's grid dimensions, voxels.
    pub fn grid_dims(&self) -> [usize; 3] {
        match self {
            ObjectModes::Fem(b) => b.grid_dims(),
            ObjectModes::Predicted(p) => p.grid_dims,
            ObjectModes::Recorded(_) => [1, 1, 1],
        }
    }

    /// Reference-unit modal forces at `hit`, one per mode, into `out`
    /// ([`ModeBasis::reference_forces_into`], [`PredictedObject::reference_forces_into`]).
    /// Never allocates.
    pub fn reference_forces_into(
        &self,
        hit: &Hit,
        voxel_size_m: f64,
        out: &mut [f64],
    ) -> Result<(), HitError> {
        match self {
            ObjectModes::Fem(b) => b.reference_forces_into(hit, voxel_size_m, out),
            ObjectModes::Predicted(p) => {
                p.reference_forces_into(hit, voxel_size_m, out);
                Ok(())
            }
            ObjectModes::Recorded(r) => {
                r.reference_forces_into(out);
                Ok(())
            }
        }
    }

    /// The FEM basis, when FEM made these modes.
    pub fn fem(&self) -> Option<&ModeBasis> {
        match self {
            ObjectModes::Fem(b) => Some(b.as_ref()),
            ObjectModes::Predicted(_) | ObjectModes::Recorded(_) => None,
        }
    }

    /// Mode `i`'s decay over the damping law's: 1 for solved shapes, a recorded mode's own
    /// ratio ([`super::recorded`]). Never allocates.
    pub fn decay_ratio(&self, i: usize) -> f64 {
        match self {
            ObjectModes::Recorded(r) => r.decay_ratios.get(i).copied().unwrap_or(1.0),
            _ => 1.0,
        }
    }
}

/// A shape's modes ready to be struck.
pub struct SolvedObject {
    /// The solved shape (reference units), shared with the editor's spectrum view (the last
    /// reference is dropped on the worker: retired objects travel back through a ring).
    pub basis: Arc<ObjectModes>,
    /// Increases with every solved edit; modes keep it so a voice knows which object they are.
    pub generation: u64,
    /// Name of the solver that produced it.
    pub solver: &'static str,
    /// Time the solve took, ms.
    pub solve_ms: f64,
    /// The grid's longest side in voxels (the size parameter spans it).
    pub extent: usize,
    /// Reference-unit modal forces at `forces_hit`, one per mode.
    pub(crate) forces: Vec<f64>,
    forces_hit: Option<HitPoint>,
}

impl SolvedObject {
    /// Wraps a solved basis. Allocates.
    pub fn new(
        basis: Arc<ObjectModes>,
        generation: u64,
        solver: &'static str,
        solve_ms: f64,
    ) -> Self {
        let modes = basis.mode_count();
        let extent = basis.grid_dims().into_iter().max().unwrap_or(1);
        Self {
            basis,
            generation,
            solver,
            solve_ms,
            extent,
            forces: vec![0.0; modes],
            forces_hit: None,
        }
    }

    /// Modes computed.
    pub fn mode_count(&self) -> usize {
        self.forces.len()
    }

    /// Makes `forces` hold the modal forces for `hit` (cached: recomputed when the hit moves).
    /// Never allocates.
    pub fn update_forces(&mut self, hit: &HitPoint) -> Result<(), HitError> {
        if self.forces_hit.as_ref() == Some(hit) {
            return Ok(());
        }
        // Reference units: voxel edge 1, so the point is the fraction times the grid's extent.
        let h = hit.reference_hit(self.basis.grid_dims());
        self.forces_hit = None;
        self.basis
            .reference_forces_into(&h, 1.0, &mut self.forces)?;
        self.forces_hit = Some(*hit);
        Ok(())
    }
}
