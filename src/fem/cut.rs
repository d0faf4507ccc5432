//! Partially filled voxels: element matrices integrated over the filled part of the cube (the
//! finite cell method of Parvizian, Düster and Rank 2007, in its voxel form).
//!
//! Where it sits: [`super::FemModel::assemble`] uses the unit element ([`super::UnitElement`])
//! for every full voxel, and this for every partial one ([`crate::shape::SubFill`]). The unit
//! cube is split into `s^3` sub-cells; the uncondensed stiffness and the mass of each sub-cell
//! are integrated once (`element::integrate_box`), and a partial element's matrices are
//! the fill-weighted sums `K_e = sum_c max(f_c, alpha) K_c`, `M_e = sum_c max(f_c, alpha) M_c`
//! (exact for a fill that is constant on each sub-cell), followed by the static condensation
//! of the incompatible modes for hex8i. `alpha` ([`EMPTY_SUBCELL_FLOOR`]) keeps the bubble block
//! positive definite when sub-cells are empty, as the finite cell method's `alpha` does.

use super::element::{
    bubble_solve, elasticity, integrate_box, BoxIntegrals, ElementKind, BUBBLE_DOFS, BUBBLE_FULL,
    NODAL_DOFS,
};
use super::sparse::ElementBlocks;
use crate::fma::mul_add;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

pub mod symmetry;
mod tensor;

/// Partial voxels evaluated together: their fill-weighted sums are one matrix product per
/// batch (`[entries x sub-cells] x [sub-cells x batch]`), which runs at matrix-product speed
/// instead of one axpy per sub-cell per element.
pub const CUT_BATCH: usize = 64;

/// Stiffness and mass kept in an empty sub-cell of a partial voxel, relative to a full one. It
/// changes a bowl's frequencies by far less than the solver tolerance but keeps every element
/// matrix positive definite on its non-rigid motions.
pub const EMPTY_SUBCELL_FLOOR: f64 = 1e-3;

/// The weight a sub-cell filled to `fill` carries in a cut element's sums: the fill in
/// `[0, 1]`, at least [`EMPTY_SUBCELL_FLOOR`].
#[inline]
pub fn subcell_weight(fill: f64) -> f64 {
    fill.clamp(0.0, 1.0).max(EMPTY_SUBCELL_FLOOR)
}

/// Sub-cells per voxel axis the FEM integrates a partial voxel of `kind` over, chosen by
/// measurement (the lowest mode pair of `bowl:d=16,wall=2` and `bowl:d=32,wall=2`, glass, and
/// their frequencies against the smooth reference; ARCHITECTURE.md, "Partial voxels"). The
/// quadratic elements: 8, the stored 4 refined by the fill's plane in each cut sub-cell
/// ([`crate::shape::refine`]; hex27's fundamental on the 16-voxel bowl is 2.4 / 0.9 / 0.2 %
/// sharp at 2 / 4 / 8, and hex27x2's worst frequency on the 32-voxel bowl 1.86 % at 4, 0.98 %
/// refined to 8). Hex8 with incompatible modes is best at 2 (split 0.74 % / 0.37 %; 1.6 % /
/// 1.0 % at 4, 1.9 % / 1.2 % at 8: its bubbles follow the lattice, so the finer the cut
/// geometry, the more its lattice anisotropy shows), and so is plain hex8.
pub fn subcells_per_axis(kind: ElementKind) -> usize {
    match kind {
        ElementKind::Hex27 | ElementKind::Hex27Blocks => crate::shape::refine::REFINED_PER_AXIS,
        ElementKind::Hex8 | ElementKind::Hex8Incompatible => 2,
    }
}

/// The sub-cell matrices of one element kind and Poisson's ratio.
#[derive(Clone, Debug)]
pub struct CutElement {
    kind: ElementKind,
    per_axis: usize,
    integrals: Integrals,
}

/// How a cut element's fill-weighted sums are evaluated.
#[derive(Clone, Debug)]
enum Integrals {
    /// Linear elements: a table of sub-cell matrices times the batch's fills (one matrix
    /// product per batch; the table is small).
    Table(Box<SubcellTable>),
    /// hex27: sum factorisation on the 1D sub-cell integrals ([`tensor`]).
    Tensor(Box<tensor::Hex27Subcells>),
}

/// Every sub-cell's matrices, one column per sub-cell, in the layout the scatter takes
/// ([`ElementBlocks`]): the nodal stiffness as one 3x3 block per node pair `b >= a`, and the
/// mass as one scalar per node pair (it is `m_ab delta_cd`). So the batch product writes the
/// element's blocks directly (hex8), or the blocks and the bubble terms the condensation reads
/// (hex8i), and nothing is unpacked.
#[derive(Clone, Debug)]
struct SubcellTable {
    /// Uncondensed stiffness of each sub-cell (x fastest) as the columns of one matrix: the
    /// nodal blocks (`9 node_pairs(n)` rows, [`ElementBlocks`] order), then for hex8i the
    /// bubble rows `K_bu` (9 x 24, row-major), the bubble block `K_bb` (9 x 9) and the Taylor
    /// correction's sums: `int B dV` of the 9 bubble DOFs and the 24 nodal DOFs (Voigt, 6
    /// each) and the sub-cell's volume.
    stiffness: Mat<f64>,
    /// Scalar mass of each sub-cell, one row per node pair.
    mass: Mat<f64>,
    /// Elasticity matrix (E = 1).
    elasticity: [[f64; 6]; 6],
}

/// Rows of [`SubcellTable::stiffness`] past the nodal blocks (hex8i): `K_bu`, `K_bb`, the
/// bubble strains, the nodal strains, the volume.
const KBU_ROWS: usize = BUBBLE_DOFS * NODAL_DOFS;
const KBB_ROWS: usize = BUBBLE_DOFS * BUBBLE_DOFS;
const SUM_ROWS: usize = 6 * (BUBBLE_DOFS + NODAL_DOFS) + 1;

/// Reusable buffers for [`CutElement::matrices_batch`].
#[derive(Clone, Debug)]
pub struct CutScratch {
    /// Sub-cell weights of the batch, one column per element.
    weights: Mat<f64>,
    /// Uncondensed stiffness of the batch, one column per element.
    kfull: Mat<f64>,
    /// Mass of the batch, one column per element.
    mass: Mat<f64>,
    /// One element's matrices.
    blocks: ElementBlocks,
    tensor: tensor::TensorScratch,
}

impl CutElement {
    /// [`CutElement::new`], integrated once per process for each `kind`, `nu` and `per_axis`
    /// that is in use ([`super::memo`]).
    pub fn shared(kind: ElementKind, nu: f64, per_axis: usize) -> std::sync::Arc<Self> {
        static KEPT: super::memo::Memo<(ElementKind, u64, usize), CutElement> =
            super::memo::Memo::new();
        KEPT.get_or_make((kind, nu.to_bits(), per_axis), || {
            Self::new(kind, nu, per_axis)
        })
    }

    /// Integrates the `per_axis^3` sub-cells of `kind` for Poisson's ratio `nu`: the matrices
    /// of one element in voxel units, like the assembly's unit element (scaled by
    /// [`ElementKind::voxel_scales`] for an element over several voxels).
    pub fn new(kind: ElementKind, nu: f64, per_axis: usize) -> Self {
        let per_axis = per_axis.max(1);
        let integrals = if kind.order() == 2 {
            let scales = kind.voxel_scales();
            Integrals::Tensor(Box::new(tensor::Hex27Subcells::new(per_axis, nu, scales)))
        } else {
            assert_eq!(
                kind.voxels_per_element(),
                1,
                "linear elements span one voxel"
            );
            Integrals::Table(Box::new(SubcellTable::new(kind, nu, per_axis)))
        };
        Self {
            kind,
            per_axis,
            integrals,
        }
    }
}

impl SubcellTable {
    /// Integrates every sub-cell of `kind` (hex8, hex8i) over `per_axis^3` sub-cells.
    fn new(kind: ElementKind, nu: f64, per_axis: usize) -> Self {
        let step = 2.0 / per_axis as f64;
        let nodes = kind.nodes();
        let ndof = 3 * nodes;
        let subcell_volume = (1.0 / per_axis as f64).powi(3);
        let mut stiffness: Vec<Vec<f64>> = Vec::new();
        let mut mass: Vec<Vec<f64>> = Vec::new();
        for cz in 0..per_axis {
            for cy in 0..per_axis {
                for cx in 0..per_axis {
                    let c = [cx, cy, cz];
                    let lo = c.map(|i| -1.0 + step * i as f64);
                    let hi = c.map(|i| -1.0 + step * (i + 1) as f64);
                    let BoxIntegrals {
                        kfull,
                        mass: m,
                        strain,
                    } = integrate_box(kind, nu, lo, hi);
                    let n = (kfull.len() as f64).sqrt() as usize;
                    // The Gauss sums leave rounding asymmetry: read the upper triangle.
                    let sym = |i: usize, j: usize| kfull[i.min(j) * n + i.max(j)];
                    let mut column = Vec::new();
                    for a in 0..nodes {
                        for b in a..nodes {
                            column.extend((0..9).map(|e| sym(3 * a + e / 3, 3 * b + e % 3)));
                        }
                    }
                    if kind == ElementKind::Hex8Incompatible {
                        let bubbles = NODAL_DOFS..BUBBLE_FULL;
                        for i in bubbles.clone() {
                            column.extend((0..NODAL_DOFS).map(|j| sym(i, j)));
                        }
                        for i in bubbles.clone() {
                            column.extend(bubbles.clone().map(|j| sym(i, j)));
                        }
                        column.extend(strain[ndof..].iter().flatten());
                        column.extend(strain[..ndof].iter().flatten());
                        column.push(subcell_volume);
                    }
                    stiffness.push(column);
                    // `m_ab`: the first component's entry of each node pair's block.
                    let pairs = (0..nodes).flat_map(|a| (a..nodes).map(move |b| (a, b)));
                    mass.push(pairs.map(|(a, b)| m[3 * a * ndof + 3 * b]).collect());
                }
            }
        }
        let table = |cols: &[Vec<f64>]| Mat::from_fn(cols[0].len(), cols.len(), |i, j| cols[j][i]);
        Self {
            stiffness: table(&stiffness),
            mass: table(&mass),
            elasticity: elasticity(nu),
        }
    }
}

impl CutElement {
    /// Sub-cells per axis.
    pub fn per_axis(&self) -> usize {
        self.per_axis
    }

    /// Buffers for [`CutElement::matrices_batch`].
    pub fn scratch(&self) -> CutScratch {
        let (table_rows, mass_rows, subcells, batch) = match &self.integrals {
            Integrals::Table(t) => (
                t.stiffness.nrows(),
                t.mass.nrows(),
                t.stiffness.ncols(),
                CUT_BATCH,
            ),
            Integrals::Tensor(_) => (0, 0, 0, 0),
        };
        CutScratch {
            weights: Mat::zeros(subcells, batch),
            kfull: Mat::zeros(table_rows, batch),
            mass: Mat::zeros(mass_rows, batch),
            blocks: ElementBlocks::zeros(self.kind.nodes()),
            tensor: match &self.integrals {
                Integrals::Table(_) => tensor::TensorScratch::default(),
                Integrals::Tensor(t) => t.scratch(),
            },
        }
    }

    /// The element matrices of up to [`CUT_BATCH`] partial voxels whose sub-cells (x fastest)
    /// are filled to the fractions `fills[j]` (each in `[0, 1]`): calls `each(j, blocks)`
    /// with each element's matrices, like the unit element's ([`ElementBlocks`]).
    pub fn matrices_batch(
        &self,
        fills: &[&[f64]],
        scratch: &mut CutScratch,
        mut each: impl FnMut(usize, &ElementBlocks),
    ) {
        let count = fills.len();
        assert!(count <= CUT_BATCH, "at most CUT_BATCH elements per batch");
        let table = match &self.integrals {
            Integrals::Tensor(tensor) => {
                for (j, fill) in fills.iter().enumerate() {
                    tensor.matrices(fill, &mut scratch.blocks, &mut scratch.tensor);
                    each(j, &scratch.blocks);
                }
                return;
            }
            Integrals::Table(table) => table,
        };
        let subcells = table.stiffness.ncols();
        for (j, fill) in fills.iter().enumerate() {
            assert_eq!(fill.len(), subcells, "one fraction per sub-cell");
            for (c, f) in fill.iter().enumerate() {
                scratch.weights[(c, j)] = subcell_weight(*f);
            }
        }
        let weights = scratch.weights.as_ref().subcols(0, count);
        for (table, out) in [
            (&table.stiffness, &mut scratch.kfull),
            (&table.mass, &mut scratch.mass),
        ] {
            matmul(
                out.as_mut().subcols_mut(0, count),
                Accum::Replace,
                table.as_ref(),
                weights,
                1.0,
                Par::Seq,
            );
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above), the only requirement
            // of the `target_feature` function; it is the same safe code compiled for them.
            unsafe { self.finish_batch_avx2(table, count, scratch, &mut each) };
            return;
        }
        self.finish_batch::<false>(table, count, scratch, &mut each);
    }

    /// [`CutElement::finish_batch`] compiled for AVX2 and FMA: the Taylor correction and the
    /// condensation run on 24-wide rows, 4 lanes at a time, with fused multiply-adds.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn finish_batch_avx2(
        &self,
        table: &SubcellTable,
        count: usize,
        scratch: &mut CutScratch,
        each: &mut impl FnMut(usize, &ElementBlocks),
    ) {
        self.finish_batch::<true>(table, count, scratch, each);
    }

    /// The Taylor correction and the condensation (hex8i) of each summed element of a batch;
    /// `FMA`: with fused multiply-adds (only where the CPU has them: otherwise they are a
    /// library call).
    #[inline(always)]
    fn finish_batch<const FMA: bool>(
        &self,
        table: &SubcellTable,
        count: usize,
        scratch: &mut CutScratch,
        each: &mut impl FnMut(usize, &ElementBlocks),
    ) {
        let blocks = &mut scratch.blocks;
        let block_rows = 9 * blocks.k.len();
        for j in 0..count {
            let (kuu, bubbles) = scratch.kfull.col_as_slice(j).split_at(block_rows);
            blocks.m.copy_from_slice(scratch.mass.col_as_slice(j));
            if self.kind == ElementKind::Hex8Incompatible {
                let k: &mut [[f64; 9]; 36] = (&mut blocks.k[..]).try_into().expect("36 pairs");
                condense_corrected::<FMA>(&table.elasticity, kuu, bubbles, k);
            } else {
                for (out, v) in blocks.k.iter_mut().zip(kuu.chunks_exact(9)) {
                    out.copy_from_slice(v);
                }
            }
            symmetrise_diagonal(&mut blocks.k, self.kind.nodes());
            each(j, blocks);
        }
    }

    /// The element matrices of one partial voxel (see [`CutElement::matrices_batch`]), dense
    /// (`3 n` square, row-major, DOFs node-major).
    pub fn matrices(&self, fill: &[f64], k: &mut [f64], m: &mut [f64], scratch: &mut CutScratch) {
        let nodes = self.kind.nodes();
        self.matrices_batch(&[fill], scratch, |_, blocks| blocks.to_dense(nodes, k, m));
    }
}

/// Makes the diagonal blocks of an element's stiffness blocks exactly symmetric (they are
/// sums of the same numbers in each triangle; this rules out rounding that a product kernel
/// might order differently).
#[inline(always)]
fn symmetrise_diagonal(k: &mut [[f64; 9]], nodes: usize) {
    let mut pair = 0;
    for a in 0..nodes {
        let b = &mut k[pair];
        for (i, j) in [(1, 3), (2, 6), (5, 7)] {
            let v = 0.5 * (b[i] + b[j]);
            (b[i], b[j]) = (v, v);
        }
        pair += nodes - a;
    }
}

/// The condensed stiffness blocks of a cut hex8i element from its fill-weighted nodal blocks
/// `kuu` ([`ElementBlocks`] order) and the `bubbles` rows of [`SubcellTable::stiffness`]
/// (`K_bu`, `K_bb` and the Taylor sums), with the incompatible modes' strains made to average
/// to zero over the filled part of the cell (Taylor, Beresford and Wilson 1976):
/// `B_b -> B_b - G`, `G = int_f B_b dV / V_f`. On a full cube the bubbles' strains already
/// average to zero (`G = 0`); on a cut cell they do not, and the uncorrected element fails the
/// constant-strain patch test and locks.
///
/// The sums are the fill-weighted `int_f B_b dV` (9 x 6), `S_u = int_f B_u dV` (24 x 6) and
/// `V_f`; with `int_f B_b dV = V_f G`: `K_bu -= G^T D S_u` (and `K_ub` likewise, which the
/// condensation reads as `K_bu^T`), `K_bb -= V_f G^T D G`.
#[inline(always)]
fn condense_corrected<const FMA: bool>(
    d: &[[f64; 6]; 6],
    kuu: &[f64],
    bubbles: &[f64],
    k: &mut [[f64; 9]; 36],
) {
    const NB: usize = BUBBLE_DOFS;
    const NU: usize = NODAL_DOFS;
    let (kbu_rows, rest) = bubbles.split_at(KBU_ROWS);
    let (kbb_rows, sums) = rest.split_at(KBB_ROWS);
    debug_assert_eq!(sums.len(), SUM_ROWS);
    let volume = sums[6 * (NB + NU)];
    let mut g = [[0.0f64; 6]; NB];
    for (gj, s) in g.iter_mut().zip(sums.chunks_exact(6)) {
        gj.iter_mut().zip(s).for_each(|(g, s)| *g = s / volume);
    }
    // D G_j once per bubble DOF; S_u transposed to 6 rows of 24 for row operations.
    let mut dg = [[0.0f64; 6]; NB];
    for (dgj, gj) in dg.iter_mut().zip(&g) {
        for (r, out) in dgj.iter_mut().enumerate() {
            *out = (0..6).map(|s| d[r][s] * gj[s]).sum();
        }
    }
    let mut su_t = [[0.0f64; NU]; 6];
    for (i, s) in sums[6 * NB..6 * (NB + NU)].chunks_exact(6).enumerate() {
        for (r, &v) in s.iter().enumerate() {
            su_t[r][i] = v;
        }
    }
    let mut kbu = [[0.0f64; NU]; NB];
    for ((row, src), dgj) in kbu.iter_mut().zip(kbu_rows.chunks_exact(NU)).zip(&dg) {
        row.copy_from_slice(src);
        for (su, &c) in su_t.iter().zip(dgj) {
            row.iter_mut()
                .zip(su)
                .for_each(|(r, s)| *r = mul_add::<FMA, _>(-c, *s, *r));
        }
    }
    let mut kbb = [[0.0f64; NB]; NB];
    for (i, (row, src)) in kbb.iter_mut().zip(kbb_rows.chunks_exact(NB)).enumerate() {
        for (j, (out, &v)) in row.iter_mut().zip(src).enumerate() {
            let gdg: f64 = (0..6).map(|r| g[i][r] * dg[j][r]).sum();
            *out = v - volume * gdg;
        }
    }
    // K = K_uu - Y^T Y on the blocks b >= a: row 3a + c of the correction in 4-wide chunks
    // from the one holding column 3a.
    let y = bubble_solve(&kbb, &kbu);
    let mut first_pair = 0;
    for a in 0..8 {
        let from = 3 * a / 4;
        for c in 0..3 {
            let i = 3 * a + c;
            let mut corr = [[0.0f64; 4]; NU / 4];
            for (chunk, o) in corr.iter_mut().enumerate().skip(from) {
                // One chunk's sum over the 9 rows of Y stays in a register.
                let mut acc = [0.0f64; 4];
                for yp in &y {
                    let s = yp[i];
                    let v = &yp[4 * chunk..4 * chunk + 4];
                    for (acc, v) in acc.iter_mut().zip(v) {
                        *acc = mul_add::<FMA, _>(s, *v, *acc);
                    }
                }
                *o = acc;
            }
            let corr = corr.as_flattened();
            for (pair, b) in (first_pair..).zip(a..8) {
                for e in 0..3 {
                    k[pair][3 * c + e] = kuu[9 * pair + 3 * c + e] - corr[3 * b + e];
                }
            }
        }
        first_pair += 8 - a;
    }
}

#[cfg(test)]
mod tests;
