//! The instant answer's Ritz vectors in factored form: any row of them, on demand.
//!
//! Where it sits: the last step of [`super::ritz_factored`], for the engine's carried answer
//! ([`crate::basis::ModeBasis::carried_ritz_factored`]). The Ritz vectors are
//! `V = [R | T | Delta] C`: the rigid fields `R`, the previous columns carried to the new mesh
//! `T` ([`super::transfer_rows`]), the corrections near the edit `Delta` and the Rayleigh-Ritz
//! coefficients `C`. Forming `V` over the whole mesh is one dense product of the whole carried
//! block (10 ms of the ceramic cup's 45 ms answer, 29.5k rows by 74 columns by 60 modes), and
//! a strike reads a few dozen of its rows ([`crate::basis::ModeBasis::reference_forces_into`]).
//! [`RitzRows`] keeps the factors instead and gives row `d` of `[R | T | Delta]` from the
//! previous solution in place: a struck face's rows weighted by the strike, times `C`, are
//! its forces, a few thousand multiply-adds and no allocation (the audio thread calls it).

use super::transfer::{previous_parts, NodeSources, Source};
use crate::eigen::lobpcg::rigid_row;
use crate::eigen::EigenSolution;
use crate::fem::FemModel;
use faer::Mat;

/// The factors of a carried answer's Ritz vectors (see the module docs).
#[derive(Clone, Debug)]
pub struct RitzRows {
    /// `C`: one row per column of `[R | T | Delta]`, one column per kept mode.
    pub coefficients: Mat<f64>,
    /// Rigid fields leading the block (6, or 0 where the previous extra rigid modes are
    /// carried instead).
    pub(super) fields: usize,
    /// The centroid the rigid fields rotate about.
    pub(super) centre: [f64; 3],
    /// Guard vectors carried ([`previous_parts`]).
    pub(super) guards: usize,
    /// Where each node's carried values come from.
    pub(super) sources: NodeSources,
    /// The corrections' DOFs, ascending, and their values there (one row per DOF).
    pub(super) correction: Option<(Vec<usize>, Mat<f64>)>,
}

impl RitzRows {
    /// Columns of `[R | T | Delta]` (rows of [`RitzRows::coefficients`]).
    pub fn width(&self) -> usize {
        self.coefficients.nrows()
    }

    /// Row `dof` of `[R | T | Delta]` on `next` (the edited model), reading the carried
    /// columns of `previous` (the solution the answer was carried from) in place, into `out`
    /// ([`RitzRows::width`] long). Never allocates.
    pub fn row_into(&self, previous: &EigenSolution, next: &FemModel, dof: usize, out: &mut [f64]) {
        let (node, c) = (dof / 3, dof % 3);
        let f = self.fields;
        if f > 0 {
            out[..f].copy_from_slice(&rigid_row(next.node_position(node), self.centre, c)[..f]);
        }
        let parts = previous_parts(previous, self.guards);
        let cc: usize = parts.iter().map(|p| p.ncols()).sum();
        let carried = &mut out[f..f + cc];
        // The carried columns at previous node `o`, added to `carried` or written over it.
        let fill = |carried: &mut [f64], o: usize, add: bool| {
            let values = parts
                .iter()
                .flat_map(|part| (0..part.ncols()).map(move |k| part[(3 * o + c, k)]));
            for (slot, v) in carried.iter_mut().zip(values) {
                *slot = if add { *slot + v } else { v };
            }
        };
        match self.sources.source(node) {
            Source::Kept(o) => fill(carried, o, false),
            Source::Fresh(sources) => {
                // A new node: the mean of its persisting neighbours, as it was carried.
                carried.fill(0.0);
                for &o in sources {
                    fill(carried, o, true);
                }
                if !sources.is_empty() {
                    let count = sources.len() as f64;
                    carried.iter_mut().for_each(|v| *v /= count);
                }
            }
        }
        let rest = &mut out[f + cc..self.width()];
        rest.fill(0.0);
        if let Some((dofs, delta)) = &self.correction {
            if let Ok(r) = dofs.binary_search(&dof) {
                for (i, v) in rest.iter_mut().enumerate() {
                    *v = delta[(r, i)];
                }
            }
        }
    }
}
