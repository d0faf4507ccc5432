//! What an exact answer keeps for the strokes carried from it: the whole Gram columns of the
//! carried block's columns that no eigen-relation gives, so that the engine's carried answer
//! reads nothing of the mesh away from the edit.
//!
//! Where it sits: beside `warm/grams.rs`, for the factored instant answer
//! ([`super::ritz_factored`]). Its Gram matrices are the previous solve's updated near the
//! edit (`X'^T M' X' = I`, `X'^T K' X' = Lambda` for its converged modes and guards), except
//! the columns of the six rigid fields and of the guards that did not converge (the last few
//! Ritz vectors of a Lanczos solve): those are no eigenvectors, so before stop 72 they were
//! multiplied out over the whole mesh with the carried block `X` on every node, the whole
//! transfer. On the ceramic cup (29.5k DOFs) that was 13-14 of the answer's 42 ms.
//!
//! A Gram entry is a sum over rows, and the rows the edit left alone are the same in both
//! shapes, so any Gram column of the edited shape is the previous shape's plus the same local
//! update as for the carried modes (`warm/grams.rs`: the rows near the edit on the new mesh,
//! less those on the previous one). [`ExactGrams`] keeps the previous shape's whole columns,
//! `Y'^T M' Y'_o` and `Y'^T K' Y'_o` with `Y' = [R_0 | X']` and `o` those columns: one
//! product of `M` with the fields and of `K` and `M` with the unconverged guards, over the
//! mesh once per exact answer. The rigid fields are linear in a node's position: about a
//! centre `c`, `R_c = R_0 A(c)`, with `R_0` the fields about the origin and `A(c)` the
//! identity with `-(e_q x c)` in the translation rows of rotation `q` ([`about`]), so the
//! kept columns serve the fields about any centre ([`ExactGrams::about`]).
//!
//! The rigid modes' own M-orthogonality to the previous modes is not used: it holds only to
//! the previous solve's residual over its lowest eigenvalue, far looser than these products.

use super::grams::relations;
use super::transfer::{previous_columns, previous_parts};
use super::{extra_rigid, RITZ_GUARDS};
use crate::eigen::lobpcg::rigid_row;
use crate::eigen::{EigenSolution, Operators, Which};
use crate::fem::FemModel;
use faer::{Mat, MatRef};

/// The rigid fields leading the carried block `Y = [R | X]`.
const FIELDS: usize = 6;

/// An exact answer's whole Gram columns for the columns its carried answers cannot relate
/// (see the module docs).
#[derive(Clone, Debug)]
pub struct ExactGrams {
    /// The columns kept, as columns of `Y = [R_0 | X]`: the six fields, then the carried
    /// columns (of [`previous_columns`] with [`RITZ_GUARDS`]) that are not related
    /// ([`relations`]), each at `6 +` its carried index. Ascending.
    others: Vec<usize>,
    /// `Y^T M Y_o` (`6 + carried` x `others`).
    m: Mat<f64>,
    /// `Y^T K Y_o`.
    k: Mat<f64>,
    /// The mesh's DOFs.
    dofs: usize,
}

impl ExactGrams {
    /// The kept columns of `solution` on `model` (the mesh it was solved on); `None` where
    /// the solution carries extra rigid modes (a shape of several parts), whose carried
    /// block has no rigid fields.
    pub fn new(model: &FemModel, solution: &EigenSolution) -> Option<Self> {
        if extra_rigid(solution).ncols() > 0 {
            return None;
        }
        let n = model.dofs();
        let parts = previous_parts(solution, RITZ_GUARDS);
        let columns = previous_columns(solution, RITZ_GUARDS);
        let lambda = relations(solution, 0, columns.len());
        let unrelated: Vec<usize> = (0..columns.len())
            .filter(|&j| lambda[j].is_none())
            .collect();
        let others: Vec<usize> = (0..FIELDS)
            .chain(unrelated.iter().map(|j| FIELDS + j))
            .collect();
        let no = others.len();
        // `Y_o` by rows: the fields about the origin, then the unrelated columns.
        let mut y_o = vec![0.0; n * no];
        for (d, row) in y_o.chunks_exact_mut(no).enumerate() {
            row[..FIELDS].copy_from_slice(&rigid_row(model.node_position(d / 3), [0.0; 3], d % 3));
            for (r, &j) in row[FIELDS..].iter_mut().zip(&unrelated) {
                *r = columns[j][d];
            }
        }
        let ops = Operators::without_norms(model);
        let fields = MatRef::from_row_major_slice(&y_o, n, no).subcols(0, FIELDS);
        // `Y^T B` for a block `B` by rows: the fields' rows, then the carried columns' part by
        // part (each part's columns are contiguous: one general product each).
        let gram = |b: &[f64], width: usize| {
            let b = MatRef::from_row_major_slice(b, n, width);
            let mut g = Mat::zeros(FIELDS + columns.len(), width);
            g.get_mut(..FIELDS, ..).copy_from(fields.transpose() * b);
            let mut at = FIELDS;
            for part in parts {
                let w = part.ncols();
                g.get_mut(at..at + w, ..).copy_from(part.transpose() * b);
                at += w;
            }
            g
        };
        let m = gram(&ops.rows_product(Which::M, &y_o, no), no);
        // `K R = 0` (the elements hold rigid motions exactly): only the rest are multiplied,
        // their columns beside the fields' zeros.
        let mut k = Mat::zeros(FIELDS + columns.len(), no);
        if no > FIELDS {
            let nu = no - FIELDS;
            let x_u: Vec<f64> = (0..n * nu)
                .map(|i| y_o[i / nu * no + FIELDS + i % nu])
                .collect();
            let k_x_u = ops.rows_product(Which::K, &x_u, nu);
            k.get_mut(.., FIELDS..).copy_from(gram(&k_x_u, nu));
        }
        Some(ExactGrams {
            others,
            m,
            k,
            dofs: n,
        })
    }

    /// Whether these can be the kept columns of `solution`, as far as the sizes tell (a
    /// basis whose solution was replaced after they were kept would not be).
    pub fn fits(&self, solution: &EigenSolution) -> bool {
        self.m.nrows() == FIELDS + previous_columns(solution, RITZ_GUARDS).len()
            && solution.vectors.nrows() == self.dofs
    }

    /// The kept columns for the fields about `centre` (in the previous mesh's positions):
    /// `Y_c = Y_0 T` with `T = diag(A(c), I)`, so `Y_c^T A Y_c,o = T^T (Y_0^T A Y_0,o) T_o`.
    pub(super) fn about(&self, centre: [f64; 3]) -> Moved {
        let a = about(centre);
        let moved = |g: &Mat<f64>| {
            let (w, no) = (g.nrows(), g.ncols());
            // `T^T G`: only the fields' rows change; then `(.) T_o`: the fields' columns.
            let mut out = g.clone();
            out.get_mut(..FIELDS, ..)
                .copy_from(a.transpose() * g.get(..FIELDS, ..));
            let right = out.get(.., ..FIELDS) * &a;
            out.get_mut(.., ..FIELDS).copy_from(&right);
            debug_assert_eq!((out.nrows(), out.ncols()), (w, no));
            out
        };
        Moved {
            others: self.others.clone(),
            m: moved(&self.m),
            k: moved(&self.k),
            centre,
        }
    }
}

/// [`ExactGrams`] for the fields about a centre.
pub(super) struct Moved {
    /// The kept columns of `Y_c = [R_c | X]` ([`ExactGrams`]' `others`).
    pub others: Vec<usize>,
    /// `Y_c^T M Y_c,o`.
    pub m: Mat<f64>,
    /// `Y_c^T K Y_c,o`.
    pub k: Mat<f64>,
    /// `c`, in the previous mesh's positions.
    pub centre: [f64; 3],
}

/// `A(c)` with `R_c = R_0 A(c)`: a rotation about `c` is the rotation about the origin less
/// the translation `e_q x c` ([`rigid_row`]'s columns: three translations, three rotations).
fn about(c: [f64; 3]) -> Mat<f64> {
    let mut a = Mat::identity(FIELDS, FIELDS);
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
    fn moved_columns_are_the_products_of_the_fields_about_the_centre() {
        // Against `Y_c^T M Y_c` and `Y_c^T K Y_c` multiplied out on the kept columns, for a
        // centre off the origin and columns that are not all eigenvectors: two modes made
        // random and the guards' residuals marked unconverged (random columns are not
        // orthogonal to the translations, so a field moment left unmoved shows). Rounding of
        // sums over the mesh: 1e-12 of the products' scale (`||Y|| ||A Y_o||`).
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
        let random = random_block(n, 2, 11);
        for j in [1, 3] {
            solution.vectors.col_mut(j).copy_from(random.col(j / 2));
            solution.residuals[j] = 1.0;
        }
        solution.guard_residuals.iter_mut().for_each(|r| *r = 1.0);
        let grams = ExactGrams::new(&model, &solution).expect("one part");
        assert!(grams.fits(&solution));
        let guards = solution.guard_vectors.ncols().min(RITZ_GUARDS);
        assert!(guards > 0);
        let centre = [3.25, 4.0, 1.5];
        let moved = grams.about(centre);
        let columns = previous_columns(&solution, RITZ_GUARDS);
        let w = FIELDS + columns.len();
        let want_others: Vec<usize> = (0..FIELDS)
            .chain([FIELDS + 1, FIELDS + 3])
            .chain((0..guards).map(|g| FIELDS + 4 + g))
            .collect();
        assert_eq!(moved.others, want_others);
        let y = Mat::from_fn(n, w, |d, j| match j.checked_sub(FIELDS) {
            None => rigid_row(model.node_position(d / 3), centre, d % 3)[j],
            Some(c) => columns[c][d],
        });
        let y_o = Mat::from_fn(n, want_others.len(), |d, c| y[(d, want_others[c])]);
        let ops = Operators::new(&model);
        for (which, got) in [(Which::M, &moved.m), (Which::K, &moved.k)] {
            let a_y_o = ops.apply_block(which, y_o.as_ref());
            let want = y.transpose() * &a_y_o;
            let scale = y.norm_l2() * a_y_o.norm_l2();
            assert_eq!((got.nrows(), got.ncols()), (want.nrows(), want.ncols()));
            for i in 0..got.nrows() {
                for j in 0..got.ncols() {
                    let d = (got[(i, j)] - want[(i, j)]).abs();
                    assert!(
                        d <= 1e-12 * scale,
                        "{which:?} ({i}, {j}): {d:e} of {scale:e}"
                    );
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
