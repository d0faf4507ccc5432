//! The rigid fields' mass products with an exact answer's carried columns, kept per answer so
//! that the engine's carried answer reads nothing of the mesh away from the edit.
//!
//! Where it sits: beside `warm/grams.rs`, for the factored instant answer
//! ([`super::ritz_factored`]). Its Gram matrices are the previous solve's updated near the
//! edit, except the rows of the six rigid fields: those are not eigenvectors of the previous
//! shape, so before stop 72 they were multiplied out over the whole mesh (`M R` and
//! `X^T M R`), which needed the carried block `X` on every node, the whole transfer. On the
//! ceramic cup (29.5k DOFs) those were 13-14 of the answer's 42 ms.
//!
//! The rigid fields are linear in a node's position: about a centre `c`, `R_c = R_0 A(c)`,
//! with `R_0` the fields about the origin and `A(c)` the identity with `-(e_q x c)` in the
//! translation rows of rotation `q` ([`about`]). So the whole-mesh products an edited shape
//! needs are those of the shape it was carried from, `A^T (R_0'^T M' R_0') A` and
//! `A^T (R_0'^T M' X')`, plus the same local update as for the carried modes
//! (`warm/grams.rs`: the rows near the edit on the new mesh, less those on the previous one).
//! [`RigidMoments`] keeps `R_0'^T M' R_0'` and `R_0'^T M' X'` for one exact answer: one pass
//! over its mesh, on the first stroke carried from it.
//!
//! The rigid modes' own M-orthogonality to the previous modes is not used: it holds only to
//! the previous solve's residual over its lowest eigenvalue, far looser than these products.

use super::transfer::{previous_columns, previous_parts};
use super::RITZ_GUARDS;
use crate::eigen::lobpcg::rigid_row;
use crate::eigen::{EigenSolution, Operators, Which};
use crate::fem::FemModel;
use faer::{Mat, MatRef};

/// `R_0^T M R_0` and `R_0^T M X` of one exact answer (see the module docs).
#[derive(Clone, Debug)]
pub struct RigidMoments {
    /// `R_0^T M R_0` (6 x 6), the fields about the origin of the model's positions.
    fields: Mat<f64>,
    /// `R_0^T M X` (6 x the carried columns of [`previous_columns`] with [`RITZ_GUARDS`]).
    carried: Mat<f64>,
    /// The mesh's DOFs.
    dofs: usize,
}

impl RigidMoments {
    /// The moments of `solution`'s carried columns on `model` (the mesh they were solved on):
    /// one product of `M` with the six fields, and their dot products with each column.
    pub fn new(model: &FemModel, solution: &EigenSolution) -> Self {
        Self::with_guards(model, solution, RITZ_GUARDS)
    }

    /// [`RigidMoments::new`] with at most `guards` guard vectors among the columns.
    pub(super) fn with_guards(model: &FemModel, solution: &EigenSolution, guards: usize) -> Self {
        let n = model.dofs();
        let mut fields_rows = vec![0.0; 6 * n];
        for (d, row) in fields_rows.chunks_exact_mut(6).enumerate() {
            row.copy_from_slice(&rigid_row(model.node_position(d / 3), [0.0; 3], d % 3));
        }
        let mr = Operators::without_norms(model).rows_product(Which::M, &fields_rows, 6);
        let (r, mr) = (
            MatRef::from_row_major_slice(&fields_rows, n, 6),
            MatRef::from_row_major_slice(&mr, n, 6),
        );
        let fields = r.transpose() * mr;
        // The carried columns part by part (the columns of each are contiguous): one general
        // product each.
        let parts = previous_parts(solution, guards);
        let mut carried = Mat::zeros(6, parts.iter().map(|p| p.ncols()).sum());
        let mut at = 0;
        for part in parts {
            let w = part.ncols();
            carried
                .get_mut(.., at..at + w)
                .copy_from(mr.transpose() * part);
            at += w;
        }
        RigidMoments {
            fields,
            carried,
            dofs: n,
        }
    }

    /// Whether these can be the moments of `solution`, as far as the sizes tell (a basis
    /// whose solution was replaced after they were kept would not be).
    pub fn fits(&self, solution: &EigenSolution) -> bool {
        self.carried.ncols() == previous_columns(solution, RITZ_GUARDS).len()
            && solution.vectors.nrows() == self.dofs
    }

    /// The moments of the fields about `centre` (in the previous mesh's positions).
    pub(super) fn about(&self, centre: [f64; 3]) -> Moved {
        let a = about(centre);
        let at = a.transpose();
        Moved {
            fields: at * &self.fields * &a,
            carried: at * &self.carried,
            centre,
        }
    }
}

/// [`RigidMoments`] for the fields about a centre.
pub(super) struct Moved {
    /// `R_c^T M R_c`.
    pub fields: Mat<f64>,
    /// `R_c^T M X`.
    pub carried: Mat<f64>,
    /// `c`, in the previous mesh's positions.
    pub centre: [f64; 3],
}

/// `A(c)` with `R_c = R_0 A(c)`: a rotation about `c` is the rotation about the origin less
/// the translation `e_q x c` ([`rigid_row`]'s columns: three translations, three rotations).
fn about(c: [f64; 3]) -> Mat<f64> {
    let mut a = Mat::identity(6, 6);
    for t in 0..3 {
        // Component `t` of each `e_q x c`: the rotations' part of the fields' row at `c`.
        let row = rigid_row(c, [0.0; 3], t);
        (0..3).for_each(|q| a[(t, 3 + q)] = -row[3 + q]);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{self, random_block, EigenOptions, ModeCount, SolverKind};
    use crate::fem::ElementKind;
    use crate::shape::primitives::Primitive;

    #[test]
    fn moved_moments_are_the_products_of_the_fields_about_the_centre() {
        // Against `R_c^T M R_c` and `R_c^T M X` multiplied out, for columns that are not
        // eigenvectors (random ones, not orthogonal to the translations, so that a moment
        // left unmoved shows) and a centre off the origin: rounding of sums over the mesh,
        // 1e-12 of the products' scale (`||R|| ||M R||`, `||R|| ||M X||`).
        let grid = Primitive::Bowl {
            diameter: 8.0,
            wall: 2.0,
        }
        .rasterize(1.0, 1.0)
        .unwrap();
        let model = FemModel::assemble(&grid, ElementKind::Hex8Incompatible, 0.3).unwrap();
        let options = EigenOptions {
            count: ModeCount::First(4),
            ..Default::default()
        };
        let mut solution = eigen::solve(&model, SolverKind::Lanczos, &options).unwrap();
        let n = model.dofs();
        solution.vectors = random_block(n, 4, 11);
        solution.guard_vectors = random_block(n, 3, 12);
        let moments = RigidMoments::new(&model, &solution);
        assert!(moments.fits(&solution));
        let centre = [3.25, 4.0, 1.5];
        let moved = moments.about(centre);
        let fields = Mat::from_fn(n, 6, |d, j| {
            rigid_row(model.node_position(d / 3), centre, d % 3)[j]
        });
        let ops = Operators::new(&model);
        let mr = ops.apply_block(Which::M, fields.as_ref());
        let columns = previous_columns(&solution, RITZ_GUARDS);
        assert_eq!(columns.len(), 7);
        let x = Mat::from_fn(n, columns.len(), |d, j| columns[j][d]);
        let (want_fields, want_carried) = (mr.transpose() * &fields, mr.transpose() * &x);
        let mr_norm = mr.norm_l2();
        for (got, want, scale) in [
            (&moved.fields, &want_fields, mr_norm * fields.norm_l2()),
            (&moved.carried, &want_carried, mr_norm * x.norm_l2()),
        ] {
            assert_eq!((got.nrows(), got.ncols()), (want.nrows(), want.ncols()));
            for i in 0..got.nrows() {
                for j in 0..got.ncols() {
                    let d = (got[(i, j)] - want[(i, j)]).abs();
                    assert!(d <= 1e-12 * scale, "({i}, {j}): {d:e} of {scale:e}");
                }
            }
        }
    }

    #[test]
    fn fields_about_a_centre_are_the_fields_about_the_origin_moved() {
        // The identity R_c = R_0 A(c), row by row, at a few points and centres: exact up to
        // the rounding of a difference of positions under 100 (1e-12).
        for (p, c) in [
            ([1.0, 2.0, 3.0], [0.5, -1.0, 2.5]),
            ([31.5, 0.25, 7.0], [16.0, 16.0, 12.0]),
        ] {
            let a = about(c);
            for comp in 0..3 {
                let (r0, rc) = (rigid_row(p, [0.0; 3], comp), rigid_row(p, c, comp));
                for j in 0..6 {
                    let moved: f64 = (0..6).map(|i| r0[i] * a[(i, j)]).sum();
                    assert!((moved - rc[j]).abs() < 1e-12, "{p:?} {c:?} {comp} {j}");
                }
            }
        }
    }
}
