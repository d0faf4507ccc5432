//! The cheap part of a [`ModeBasis`]: a material, a size and a strike applied to the modes
//! solved in reference units.
//!
//! Where it sits: after the solve (`basis.rs`, `basis/carried.rs`), before
//! [`crate::modes::ModeSet`]; the engine's voicing and every CLI command read a basis through
//! these methods. The scaling laws are Deep-Modal's (Jin et al. 2020, eq. 10-12) and the gains
//! its eq. 7 (see `basis.rs`'s module docs); a strike is snapped to the nearest exposed face
//! (`basis/surface.rs`) and the mode read there with the element's own shape functions.

use super::surface::{nearest_face, point_on_face, Face};
use super::{strike_align_unisons, BasisError, ModeBasis};
use crate::material::{DampedMode, Material};
use crate::modes::ModeSet;
use crate::shape::lattice_index;

/// The nodes of a struck face with their interpolation weights (2x2 for hex8, 3x3 for
/// hex27, up to 3x3x3 for hex27x2, whose element can hold the face inside it), and the face's
/// inward normal.
pub(super) struct FaceWeights {
    pub(super) nodes: [(usize, f64); 27],
    pub(super) len: usize,
    pub(super) normal: [f64; 3],
}

/// What is wrong with a hit (a `Copy` error, so the audio thread can handle it without
/// allocating).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum HitError {
    /// A coordinate of the hit point is NaN or infinite.
    #[error("hit point {0:?} must be finite")]
    Point([f64; 3]),
    /// The force direction is zero or not finite.
    #[error("force direction {0:?} must be a non-zero finite vector")]
    Direction([f64; 3]),
    /// The shape has no exposed face.
    #[error("the shape has no surface")]
    NoSurface,
}

/// A strike: where and in which direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Point in metres from the grid's minimum corner; snapped to the nearest exposed face.
    pub point_m: [f64; 3],
    /// Force direction (normalised internally); `None` pushes into the struck face.
    pub direction: Option<[f64; 3]>,
}

impl Hit {
    /// The default hit of a grid of `dims` voxels of edge `voxel_size_m`: `(0.37, 0.41, 1.0)`
    /// of its bounding box (the top face, off-centre, so that few modes sit on a nodal line;
    /// a solve snaps it to the nearest exposed face), along the face's inward normal.
    pub fn default_for(dims: [usize; 3], voxel_size_m: f64) -> Hit {
        let [nx, ny, nz] = dims;
        Hit {
            point_m: [
                0.37 * nx as f64 * voxel_size_m,
                0.41 * ny as f64 * voxel_size_m,
                nz as f64 * voxel_size_m,
            ],
            direction: None,
        }
    }
}

/// One mode of a struck basis, with everything a caller may report.
#[derive(Clone, Debug, PartialEq)]
pub struct StruckMode {
    /// Undamped natural frequency, Hz.
    pub natural_hz: f64,
    /// Damping outcome.
    pub damped: DampedMode,
    /// Impulse amplitude for the strike.
    pub gain: f64,
    /// Residual of the eigenpair (Jin et al. 2022, eq. 6); `NaN` for an approximate answer
    /// that does not compute it (a predicted or carried one).
    pub residual: f64,
}

impl ModeBasis {
    /// Eigenvalue bound in reference units for "every mode below `fmax_hz`" of this material
    /// and voxel size (inverse of the scaling law).
    pub fn reference_bound(material: &Material, voxel_size_m: f64, fmax_hz: f64) -> f64 {
        let w = std::f64::consts::TAU * fmax_hz;
        w * w * material.density_kg_m3 * voxel_size_m * voxel_size_m / material.youngs_modulus_pa
    }

    /// Physical eigenvalues `omega^2` for a material and voxel size (Jin et al. 2020, eq. 12).
    pub fn eigenvalues(&self, material: &Material, voxel_size_m: f64) -> Vec<f64> {
        let s = material.youngs_modulus_pa / (material.density_kg_m3 * voxel_size_m * voxel_size_m);
        self.solution.eigenvalues.iter().map(|l| l * s).collect()
    }

    /// Mass-normalised physical mode values at the hit, dotted with the force direction
    /// (Jin et al. 2020, eq. 7, 10-11), one per mode.
    pub fn modal_forces(
        &self,
        material: &Material,
        voxel_size_m: f64,
        hit: &Hit,
    ) -> Result<Vec<f64>, BasisError> {
        let mut out = vec![0.0; self.mode_count()];
        self.reference_forces_into(hit, voxel_size_m, &mut out)
            .map_err(|e| BasisError::BadHit(e.to_string()))?;
        let scale = 1.0 / (material.density_kg_m3 * voxel_size_m.powi(3)).sqrt();
        out.iter_mut().for_each(|f| *f *= scale);
        Ok(out)
    }

    /// Reference-unit mode values at the hit dotted with the force direction, one per mode,
    /// into `out` (at least as long as the mode count). Multiply by `1 / sqrt(rho h^3)` for
    /// physical units. Never allocates: the engine calls it on the audio thread.
    ///
    /// Modes in unison (eigenvalues within [`UNISON_REL`]: a degenerate pair or multiplet of a
    /// symmetric object) are reported in the basis aligned with the strike
    /// ([`strike_align_unisons`]), so the sound does not depend on which basis of their
    /// eigenspace the solver happened to return.
    pub fn reference_forces_into(
        &self,
        hit: &Hit,
        voxel_size_m: f64,
        out: &mut [f64],
    ) -> Result<(), HitError> {
        self.projected_forces_into(hit, voxel_size_m, out, true)
    }

    /// [`ModeBasis::reference_forces_into`], with unisons merged or (`merge_unisons` false)
    /// each mode's own projection `phi_i(p) . f` in the solver's basis.
    pub(super) fn projected_forces_into(
        &self,
        hit: &Hit,
        voxel_size_m: f64,
        out: &mut [f64],
        merge_unisons: bool,
    ) -> Result<(), HitError> {
        let face = self.face_weights(hit, voxel_size_m)?;
        let dir = match hit.direction {
            Some(d) => {
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if !(n.is_finite() && n > 0.0) {
                    return Err(HitError::Direction(d));
                }
                [d[0] / n, d[1] / n, d[2] / n]
            }
            None => face.normal,
        };
        let count = self.mode_count().min(out.len());
        match &self.factored {
            Some(factored) => factored.forces_into(&self.model, &face, dir, &mut out[..count]),
            None => {
                let v = &self.solution.vectors;
                for (i, o) in out.iter_mut().take(count).enumerate() {
                    let col = v.col_as_slice(i);
                    *o = face.nodes[..face.len]
                        .iter()
                        .map(|&(node, w)| {
                            w * (0..3).map(|c| col[3 * node + c] * dir[c]).sum::<f64>()
                        })
                        .sum::<f64>();
                }
            }
        }
        if merge_unisons {
            strike_align_unisons(&self.solution.eigenvalues, &mut out[..count]);
        }
        Ok(())
    }

    /// Number of computed (non-rigid) modes.
    pub fn mode_count(&self) -> usize {
        self.solution.eigenvalues.len()
    }

    /// The grid's extent in voxels.
    pub fn grid_dims(&self) -> [usize; 3] {
        self.model.grid_dims()
    }

    /// Applies a material, a voxel size and a strike: every computed mode, damped, with gains.
    pub fn strike(
        &self,
        material: &Material,
        voxel_size_m: f64,
        hit: &Hit,
    ) -> Result<Vec<StruckMode>, BasisError> {
        if (material.poisson_ratio - self.model.poisson_ratio).abs() > 1e-12 {
            return Err(BasisError::PoissonMismatch {
                basis: self.model.poisson_ratio,
                material: material.poisson_ratio,
            });
        }
        let lambdas = self.eigenvalues(material, voxel_size_m);
        let forces = self.modal_forces(material, voxel_size_m, hit)?;
        Ok(lambdas
            .iter()
            .zip(&forces)
            .zip(&self.solution.residuals)
            .map(|((&l, &f), &r)| {
                let damped = material.damping.damp(l);
                let gain = match damped {
                    DampedMode::Oscillating { freq_hz, .. } => {
                        f / (std::f64::consts::TAU * freq_hz)
                    }
                    DampedMode::Overdamped { .. } => 0.0,
                };
                StruckMode {
                    natural_hz: l.sqrt() / std::f64::consts::TAU,
                    damped,
                    gain,
                    residual: r,
                }
            })
            .collect())
    }

    /// The oscillating modes as a [`ModeSet`] for the banks (overdamped ones are left out).
    pub fn mode_set(
        &self,
        material: &Material,
        voxel_size_m: f64,
        hit: &Hit,
    ) -> Result<ModeSet, BasisError> {
        let (mut f, mut d, mut g) = (Vec::new(), Vec::new(), Vec::new());
        for m in self.strike(material, voxel_size_m, hit)? {
            if let DampedMode::Oscillating {
                freq_hz,
                decay_per_s,
            } = m.damped
            {
                f.push(freq_hz);
                d.push(decay_per_s);
                g.push(m.gain);
            }
        }
        Ok(ModeSet::new(f, d, g)?)
    }

    /// Default hit: the exposed face nearest to `(0.37, 0.41, 1.0)` of the bounding box (top,
    /// off-centre, so that few modes sit on a nodal line), struck along its inward normal.
    pub fn default_hit(&self, voxel_size_m: f64) -> Hit {
        Hit::default_for(self.grid_dims(), voxel_size_m)
    }

    /// Nodes and interpolation weights of the exposed face nearest to the hit, and the face's
    /// inward normal. Never allocates.
    fn face_weights(&self, hit: &Hit, voxel_size_m: f64) -> Result<FaceWeights, HitError> {
        if hit.point_m.iter().any(|c| !c.is_finite()) {
            return Err(HitError::Point(hit.point_m));
        }
        let p = hit.point_m.map(|c| c / voxel_size_m);
        let face = nearest_face(&self.surface, p).ok_or(HitError::NoSurface)?;
        let Face {
            voxel: v,
            axis,
            normal,
            ..
        } = face;
        let order = self.model.kind.order();
        let others = [(axis + 1) % 3, (axis + 2) % 3];
        // The struck point on the face, and its coordinates in the element holding the face's
        // voxel (one voxel, or a block of them: then the face may cross the element's inside
        // and every node of the element can carry weight).
        let block = self.model.kind.voxels_per_element();
        let q = point_on_face(&face, p);
        let cell = v.map(|c| c / block);
        let local = |a: usize| ((q[a] - (cell[a] * block) as f64) / block as f64).clamp(0.0, 1.0);
        // Lagrange shape functions along an edge: linear (hex8) or quadratic (hex27).
        let basis = |t: f64| -> [f64; 3] {
            if order == 1 {
                [1.0 - t, t, 0.0]
            } else {
                let x = 2.0 * t - 1.0;
                [x * (x - 1.0) / 2.0, 1.0 - x * x, x * (x + 1.0) / 2.0]
            }
        };
        let (bu, bw, bn) = (
            basis(local(others[0])),
            basis(local(others[1])),
            basis(local(axis)),
        );
        let lattice = self.model.lattice;
        let mut face = FaceWeights {
            nodes: [(0, 0.0); 27],
            len: 0,
            normal: [0.0; 3],
        };
        for (i, &wu) in bu.iter().take(order + 1).enumerate() {
            for (j, &ww) in bw.iter().take(order + 1).enumerate() {
                for (k, &wn) in bn.iter().take(order + 1).enumerate() {
                    if wn == 0.0 {
                        continue;
                    }
                    let mut l = cell.map(|c| order * c);
                    l[others[0]] += i;
                    l[others[1]] += j;
                    l[axis] += k;
                    let node = self.model.lattice_node[lattice_index(l, lattice)];
                    face.nodes[face.len] = (node as usize, wu * ww * wn);
                    face.len += 1;
                }
            }
        }
        face.normal = normal;
        Ok(face)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{self, EigenOptions, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::VoxelGrid;

    #[test]
    fn a_strike_inside_a_block_reads_the_element_field_there() {
        // hex27x2: the top face of a one-voxel layer lies halfway up its 2x2x2 block, inside
        // the element. The quadratic shape functions reproduce any linear field exactly, so a
        // "mode" that is the position field (u_c = x_c) read along axis c at a hit gives the
        // struck point's coordinate c: on the face inside the block, and on the bottom face.
        let grid = VoxelGrid::from_fn([4, 4, 3], 1.0, |_, _, z| z < 1.0).unwrap();
        let options = EigenOptions {
            count: eigen::ModeCount::First(3),
            ..Default::default()
        };
        let mut basis = ModeBasis::solve(
            &grid,
            ElementKind::Hex27Blocks,
            0.3,
            SolverKind::Lanczos,
            &options,
        )
        .unwrap();
        let n = basis.model.nodes();
        let mut field = faer::Mat::<f64>::zeros(3 * n, 3);
        for node in 0..n {
            let p = basis.model.node_position(node);
            (0..3).for_each(|c| field[(3 * node + c, c)] = p[c]);
        }
        basis.solution.vectors = field;
        for (aim, lands) in [
            ([1.3, 2.6, 1.7], [1.3, 2.6, 1.0]),
            ([0.7, 3.1, 0.2], [0.7, 3.1, 0.0]),
        ] {
            for c in 0..3 {
                let mut direction = [0.0; 3];
                direction[c] = 1.0;
                let hit = Hit {
                    point_m: aim,
                    direction: Some(direction),
                };
                let mut out = [0.0; 3];
                basis
                    .projected_forces_into(&hit, 1.0, &mut out, false)
                    .unwrap();
                assert!(
                    (out[c] - lands[c]).abs() < 1e-12,
                    "{aim:?} axis {c}: {out:?}"
                );
            }
        }
    }
}
