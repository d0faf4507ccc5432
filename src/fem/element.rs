//! Element matrices of the voxel cube: plain trilinear hex8, hex8 with incompatible modes, and
//! triquadratic hex27.
//!
//! Every voxel is the same axis-aligned cube, so each element matrix is computed once, for a unit
//! cube with `E = 1` and `rho = 1`, and scaled: `K_e = E h K_unit(nu)`, `M_e = rho h^3 M_unit`
//! (the Jacobian is `h/2 I`, so `B ~ 1/h` and `dV ~ h^3`). Local node `a` sits at lattice offset
//! `(ax, ay, az) / p` in the cube, `a = ax + (p+1) (ay + (p+1) az)`; local DOF `3 a + c`.
//!
//! - **hex8** (`p = 1`, 2x2x2 Gauss): the papers' ground truth (Jin et al. 2022, sec. 3.1); it
//!   shear-locks in bending, badly where walls are 1-4 voxels thick.
//! - **hex8 with incompatible modes** (Wilson, Taylor, Doherty and Ghaboussi 1973; Taylor, Beresford
//!   and Wilson 1976): three bubble modes `1 - xi_i^2` per displacement component enrich the strain
//!   field so pure bending is represented exactly; the 9 internal DOFs are condensed out
//!   statically, so the element has hex8's nodes and cost. On a cube (constant Jacobian) it
//!   passes the patch test without Taylor's correction.
//! - **hex27** (`p = 2`, 3x3x3 Gauss, exact for the mass and stiffness integrands): quadratic
//!   Lagrange; higher-order elements are much more accurate than linear ones (Jin et al. 2024, sec.
//!   3.3).

/// The finite element used on every voxel. Its command-line names (`hex8`, `hex8i`, `hex27`)
/// come from the `clap::ValueEnum` derive; `Display` prints the same name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum)]
pub enum ElementKind {
    /// Plain trilinear 8-node hexahedron, full integration (the papers' reference; stiff).
    Hex8,
    /// Trilinear hexahedron with condensed incompatible (bubble) modes: no shear locking.
    #[value(name = "hex8i")]
    Hex8Incompatible,
    /// Triquadratic 27-node hexahedron (most accurate).
    Hex27,
    /// Triquadratic 27-node hexahedron on blocks of 2x2x2 voxels, integrated over the voxels'
    /// fills (the finite cell method): hex27's bending on curved thin walls at about hex8i's
    /// DOFs (ARCHITECTURE.md, "Partial voxels").
    #[value(name = "hex27x2")]
    Hex27Blocks,
}

impl std::fmt::Display for ElementKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        crate::cli_name(self, f)
    }
}

impl ElementKind {
    /// Polynomial order of the nodal interpolation.
    pub fn order(self) -> usize {
        match self {
            ElementKind::Hex27 | ElementKind::Hex27Blocks => 2,
            _ => 1,
        }
    }

    /// Voxels along each edge of one element: 2 for [`ElementKind::Hex27Blocks`], else 1.
    pub const fn voxels_per_element(self) -> usize {
        match self {
            ElementKind::Hex27Blocks => 2,
            _ => 1,
        }
    }

    /// The factors from the unit cube's matrices to one element's in voxel units,
    /// `(stiffness, mass)`: `K = E h K_unit` and `M = rho h^3 M_unit` for an element edge of
    /// `h` = [`ElementKind::voxels_per_element`] voxels.
    pub fn voxel_scales(self) -> (f64, f64) {
        let h = self.voxels_per_element() as f64;
        (h, h * h * h)
    }

    /// Nodes per element.
    pub fn nodes(self) -> usize {
        (self.order() + 1).pow(3)
    }

    /// Every kind, cheapest first.
    pub const ALL: [ElementKind; 4] = [
        ElementKind::Hex8,
        ElementKind::Hex8Incompatible,
        ElementKind::Hex27Blocks,
        ElementKind::Hex27,
    ];
}

/// Element matrices of the unit cube with `E = 1`, `rho = 1`; dense, row-major, `3 n` square.
#[derive(Clone, Debug)]
pub struct UnitElement {
    /// The element kind.
    pub kind: ElementKind,
    /// Poisson's ratio they were computed for.
    pub poisson_ratio: f64,
    /// Stiffness, `(3n)^2` entries.
    pub stiffness: Vec<f64>,
    /// Consistent mass, `(3n)^2` entries.
    pub mass: Vec<f64>,
}

/// Gauss-Legendre points and weights on [-1, 1].
pub(crate) fn gauss(n: usize) -> (&'static [f64], &'static [f64]) {
    const P2: [f64; 2] = [-0.577_350_269_189_625_8, 0.577_350_269_189_625_8];
    const W2: [f64; 2] = [1.0, 1.0];
    const P3: [f64; 3] = [-0.774_596_669_241_483_4, 0.0, 0.774_596_669_241_483_4];
    const W3: [f64; 3] = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    match n {
        2 => (&P2, &W2),
        _ => (&P3, &W3),
    }
}

/// 1D Lagrange basis of order `p` on nodes equally spaced in [-1, 1]: values and derivatives.
pub(crate) fn basis_1d(p: usize, xi: f64) -> ([f64; 3], [f64; 3]) {
    if p == 1 {
        ([(1.0 - xi) / 2.0, (1.0 + xi) / 2.0, 0.0], [-0.5, 0.5, 0.0])
    } else {
        (
            [xi * (xi - 1.0) / 2.0, 1.0 - xi * xi, xi * (xi + 1.0) / 2.0],
            [xi - 0.5, -2.0 * xi, xi + 0.5],
        )
    }
}

/// Isotropic elasticity matrix (Voigt: xx, yy, zz, xy, yz, zx; engineering shear) for `E = 1`.
pub fn elasticity(nu: f64) -> [[f64; 6]; 6] {
    let lambda = nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = 1.0 / (2.0 * (1.0 + nu));
    let mut d = [[0.0; 6]; 6];
    for i in 0..3 {
        d[i][..3].fill(lambda);
        d[i][i] = lambda + 2.0 * mu;
        d[i + 3][i + 3] = mu;
    }
    d
}

/// The strain (Voigt, engineering shear) of a unit displacement of component `c` times a field
/// whose gradient is `g`: one column of the strain-displacement matrix `B`.
pub(crate) fn strain_column(g: [f64; 3], c: usize) -> [f64; 6] {
    let mut b = [0.0; 6];
    b[c] = g[c];
    // Shear: xy (3) = du/dy + dv/dx, yz (4) = dv/dz + dw/dy, zx (5) = dw/dx + du/dz.
    match c {
        0 => {
            b[3] = g[1];
            b[5] = g[2];
        }
        1 => {
            b[3] = g[0];
            b[4] = g[2];
        }
        _ => {
            b[4] = g[1];
            b[5] = g[0];
        }
    }
    b
}

/// Adds `w B^T D B` for a set of shape-function gradients `grad[a] = dN_a/dx` (physical) into a
/// dense `ndof x ndof` matrix.
fn add_btdb(k: &mut [f64], ndof: usize, grad: &[[f64; 3]], d: &[[f64; 6]; 6], w: f64) {
    let bcol = |a: usize, c: usize| strain_column(grad[a], c);
    let n = grad.len();
    let cols: Vec<[f64; 6]> = (0..3 * n).map(|i| bcol(i / 3, i % 3)).collect();
    let db: Vec<[f64; 6]> = cols
        .iter()
        .map(|b| {
            let mut out = [0.0; 6];
            for (r, o) in out.iter_mut().enumerate() {
                *o = (0..6).map(|s| d[r][s] * b[s]).sum();
            }
            out
        })
        .collect();
    for i in 0..3 * n {
        for j in 0..3 * n {
            let v: f64 = (0..6).map(|s| cols[i][s] * db[j][s]).sum();
            k[i * ndof + j] += w * v;
        }
    }
}

/// The uncondensed matrices of `kind` integrated over the box `lo..hi` of the reference cube
/// `[-1, 1]^3` (in `xi` coordinates), for `E = 1`, `rho = 1` and a unit-cube element: the
/// stiffness over the nodal DOFs plus, for [`ElementKind::Hex8Incompatible`], its 9 bubble DOFs
/// (`3 (n + 3)` square), and the consistent mass over the nodal DOFs (`3 n` square). The Gauss
/// rule of [`UnitElement`] is exact on any box, so the whole cube gives exactly the unit
/// element's integrals and sub-boxes sum to them (the finite cell method's sub-cells,
/// [`super::cut`]).
pub(crate) fn integrate_box(
    kind: ElementKind,
    nu: f64,
    lo: [f64; 3],
    hi: [f64; 3],
) -> BoxIntegrals {
    let p = kind.order();
    let n1 = p + 1;
    let nn = kind.nodes();
    let ndof = 3 * nn;
    let (pts, wts) = gauss(p + 1);
    let d = elasticity(nu);
    // Unit cube: x = (xi + 1) / 2, so d/dx = 2 d/dxi and dV = dxi^3 / 8.
    let det_j = 0.125;
    let mut m = vec![0.0; ndof * ndof];
    // Incompatible modes: 3 bubbles x 3 components, coupled to the nodal DOFs.
    let incompatible = kind == ElementKind::Hex8Incompatible;
    let nall = if incompatible { nn + 3 } else { nn };
    let mut kfull = vec![0.0; 9 * nall * nall];
    let mut strain = vec![[0.0; 6]; 3 * nall];
    // The Gauss points mapped into the box; for the whole cube the map is the identity, bit
    // for bit (centre 0, half-width 1).
    let map = |axis: usize, t: f64| 0.5 * (lo[axis] + hi[axis]) + 0.5 * (hi[axis] - lo[axis]) * t;
    let half: f64 = (0..3).map(|a| 0.5 * (hi[a] - lo[a])).product();
    for (iz, &tz) in pts.iter().enumerate() {
        for (iy, &ty) in pts.iter().enumerate() {
            for (ix, &tx) in pts.iter().enumerate() {
                let (x, y, z) = (map(0, tx), map(1, ty), map(2, tz));
                let w = wts[ix] * wts[iy] * wts[iz] * det_j * half;
                let (nx, dx) = basis_1d(p, x);
                let (ny, dy) = basis_1d(p, y);
                let (nz, dz) = basis_1d(p, z);
                let mut val = vec![0.0; nn];
                let mut grad = vec![[0.0; 3]; nall];
                for az in 0..n1 {
                    for ay in 0..n1 {
                        for ax in 0..n1 {
                            let a = ax + n1 * (ay + n1 * az);
                            val[a] = nx[ax] * ny[ay] * nz[az];
                            grad[a] = [
                                2.0 * dx[ax] * ny[ay] * nz[az],
                                2.0 * nx[ax] * dy[ay] * nz[az],
                                2.0 * nx[ax] * ny[ay] * dz[az],
                            ];
                        }
                    }
                }
                if incompatible {
                    // Bubbles 1 - xi^2, 1 - eta^2, 1 - zeta^2; gradients in x.
                    grad[nn] = [2.0 * -2.0 * x, 0.0, 0.0];
                    grad[nn + 1] = [0.0, 2.0 * -2.0 * y, 0.0];
                    grad[nn + 2] = [0.0, 0.0, 2.0 * -2.0 * z];
                }
                add_btdb(&mut kfull, 3 * nall, &grad, &d, w);
                for (i, col) in strain.iter_mut().enumerate() {
                    let b = strain_column(grad[i / 3], i % 3);
                    col.iter_mut().zip(b).for_each(|(s, b)| *s += w * b);
                }
                for a in 0..nn {
                    for b in 0..nn {
                        // `val[a] * val[b]` first: the same product for (a, b) and (b, a), so
                        // the mass is symmetric bit for bit.
                        let v = w * (val[a] * val[b]);
                        for c in 0..3 {
                            m[(3 * a + c) * ndof + 3 * b + c] += v;
                        }
                    }
                }
            }
        }
    }
    BoxIntegrals {
        kfull,
        mass: m,
        strain,
    }
}

/// What [`integrate_box`] integrates over a box of the unit cube.
#[derive(Clone, Debug)]
pub(crate) struct BoxIntegrals {
    /// Uncondensed stiffness, `(3 (n + bubbles))^2`, row-major.
    pub kfull: Vec<f64>,
    /// Consistent mass over the nodal DOFs, `(3 n)^2`, row-major.
    pub mass: Vec<f64>,
    /// `int B dV`: the integrated strain of each DOF (nodal, then bubble), Voigt.
    pub strain: Vec<[f64; 6]>,
}

/// The nodal stiffness of `kind` from its uncondensed integral `kfull` ([`integrate_box`]):
/// the incompatible modes condensed out statically (`K = Kuu - Kua Kaa^-1 Kau`), then
/// symmetrised. Writes `3 n` square into `k`.
pub(crate) fn condense(kind: ElementKind, kfull: &[f64], k: &mut [f64]) {
    let ndof = 3 * kind.nodes();
    if kind == ElementKind::Hex8Incompatible {
        let kfull: &[f64; BUBBLE_FULL * BUBBLE_FULL] = kfull.try_into().expect("33 x 33");
        let k: &mut [f64; 24 * 24] = k.try_into().expect("24 x 24");
        condense_bubbles(kfull, k);
    } else {
        k.copy_from_slice(&kfull[..ndof * ndof]);
    }
    // The Gauss sums leave rounding asymmetry in `kfull`.
    symmetrise(k, ndof);
}

/// Replaces the `n x n` row-major `k` by `(k + k^T) / 2`: symmetric away from rounding.
#[inline(always)]
pub(crate) fn symmetrise(k: &mut [f64], n: usize) {
    for i in 0..n {
        for j in 0..i {
            let s = 0.5 * (k[i * n + j] + k[j * n + i]);
            k[i * n + j] = s;
            k[j * n + i] = s;
        }
    }
}

/// DOFs of hex8i before condensation: 24 nodal, 9 bubble.
pub(crate) const BUBBLE_FULL: usize = 24 + 9;

/// Nodal and bubble DOFs of hex8i.
pub(crate) const NODAL_DOFS: usize = 24;
pub(crate) const BUBBLE_DOFS: usize = 9;

/// `K = Kuu - Kub Kbb^-1 Kbu` for hex8i from the blocks of its uncondensed stiffness `kfull`,
/// as `Kuu - Y^T Y` ([`bubble_solve`]).
pub(crate) fn condense_bubbles(kfull: &[f64; BUBBLE_FULL * BUBBLE_FULL], k: &mut [f64; 24 * 24]) {
    const NU: usize = NODAL_DOFS;
    const FULL: usize = BUBBLE_FULL;
    let kbb: [[f64; BUBBLE_DOFS]; BUBBLE_DOFS] =
        std::array::from_fn(|i| std::array::from_fn(|j| kfull[(NU + i) * FULL + NU + j]));
    let kbu: [[f64; NU]; BUBBLE_DOFS] =
        std::array::from_fn(|i| std::array::from_fn(|j| kfull[(NU + i) * FULL + j]));
    let y = bubble_solve(&kbb, &kbu);
    for i in 0..NU {
        let mut corr = [0.0f64; NU];
        for yp in &y {
            let a = yp[i];
            corr.iter_mut().zip(yp).for_each(|(c, y)| *c += a * y);
        }
        let out = &mut k[i * NU..(i + 1) * NU];
        let kuu = &kfull[i * FULL..i * FULL + NU];
        for ((o, kv), c) in out.iter_mut().zip(kuu).zip(corr) {
            *o = kv - c;
        }
    }
}

/// `Y = L^-1 Kbu` with `Kbb = L L^T` (Cholesky of hex8i's 9 x 9 bubble block): the static
/// condensation's correction `Kub Kbb^-1 Kbu` is `Y^T Y`, one triangular solve instead of two,
/// and symmetric bit for bit. Inlined so that callers compiled for wider vectors
/// ([`super::cut`]) vectorise it with them.
#[inline(always)]
pub(crate) fn bubble_solve(
    kbb: &[[f64; BUBBLE_DOFS]; BUBBLE_DOFS],
    kbu: &[[f64; NODAL_DOFS]; BUBBLE_DOFS],
) -> [[f64; NODAL_DOFS]; BUBBLE_DOFS] {
    const NU: usize = NODAL_DOFS;
    const NB: usize = BUBBLE_DOFS;
    let mut l = [[0.0f64; NB]; NB];
    for j in 0..NB {
        let lj = l[j];
        let d = (kbb[j][j] - lj[..j].iter().map(|v| v * v).sum::<f64>()).sqrt();
        l[j][j] = d;
        for i in j + 1..NB {
            let dot: f64 = l[i][..j].iter().zip(&lj[..j]).map(|(a, b)| a * b).sum();
            l[i][j] = (kbb[i][j] - dot) / d;
        }
    }
    // Y = L^-1 Kbu, a row (24 wide) at a time.
    let mut y = [[0.0f64; NU]; NB];
    for i in 0..NB {
        let mut row = kbu[i];
        for p in 0..i {
            let lip = l[i][p];
            row.iter_mut().zip(&y[p]).for_each(|(r, y)| *r -= lip * y);
        }
        let inv = 1.0 / l[i][i];
        row.iter_mut().for_each(|r| *r *= inv);
        y[i] = row;
    }
    y
}

impl UnitElement {
    /// [`UnitElement::new`], integrated once per process for each `kind` and `nu` that is in
    /// use ([`super::memo`]).
    pub fn shared(kind: ElementKind, nu: f64) -> std::sync::Arc<Self> {
        static KEPT: super::memo::Memo<(ElementKind, u64), UnitElement> = super::memo::Memo::new();
        KEPT.get_or_make((kind, nu.to_bits()), || Self::new(kind, nu))
    }

    /// Computes the unit-cube matrices of `kind` for Poisson's ratio `nu`.
    pub fn new(kind: ElementKind, nu: f64) -> Self {
        let ndof = 3 * kind.nodes();
        let BoxIntegrals { kfull, mass, .. } = integrate_box(kind, nu, [-1.0; 3], [1.0; 3]);
        let mut stiffness = vec![0.0; ndof * ndof];
        condense(kind, &kfull, &mut stiffness);
        UnitElement {
            kind,
            poisson_ratio: nu,
            stiffness,
            mass,
        }
    }

    /// Local DOFs per element.
    pub fn dofs(&self) -> usize {
        3 * self.kind.nodes()
    }

    /// Position of local node `a` in the unit cube.
    pub fn node_position(&self, a: usize) -> [f64; 3] {
        let p = self.kind.order();
        let n1 = p + 1;
        [
            (a % n1) as f64 / p as f64,
            ((a / n1) % n1) as f64 / p as f64,
            (a / (n1 * n1)) as f64 / p as f64,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(e: &UnitElement, mat: &[f64], u: &[f64]) -> Vec<f64> {
        let n = e.dofs();
        (0..n)
            .map(|i| (0..n).map(|j| mat[i * n + j] * u[j]).sum())
            .collect()
    }

    fn field(e: &UnitElement, f: impl Fn([f64; 3]) -> [f64; 3]) -> Vec<f64> {
        (0..e.kind.nodes())
            .flat_map(|a| f(e.node_position(a)))
            .collect()
    }

    #[test]
    fn unit_elements_are_symmetric_and_their_mass_is_scalar_blocks_bit_for_bit() {
        // The assembly scatters an element's upper node blocks and mirrors them
        // (`sparse::ElementBlocks`), and the assembled mass keeps one number per block
        // (`sparse::MassBlocks`): both need these identities exactly, not to rounding.
        for kind in ElementKind::ALL {
            let e = UnitElement::new(kind, 0.3);
            let n = e.dofs();
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(e.stiffness[i * n + j], e.stiffness[j * n + i], "{kind:?}");
                    assert_eq!(e.mass[i * n + j], e.mass[j * n + i], "{kind:?}");
                    let scalar = e.mass[(i / 3 * 3) * n + j / 3 * 3];
                    let want = if i % 3 == j % 3 { scalar } else { 0.0 };
                    assert_eq!(e.mass[i * n + j], want, "{kind:?}");
                }
            }
        }
    }

    #[test]
    fn rigid_motions_have_no_energy_and_mass_is_the_volume() {
        for kind in ElementKind::ALL {
            let e = UnitElement::new(kind, 0.3);
            let scale = e.stiffness.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for f in [
                (|_: [f64; 3]| [1.0, 0.0, 0.0]) as fn([f64; 3]) -> [f64; 3],
                |_| [0.0, 0.0, 1.0],
                |p| [-p[1], p[0], 0.0],
                |p| [0.0, -p[2], p[1]],
                |p| [p[2], 0.0, -p[0]],
            ] {
                let u = field(&e, f);
                let ku = apply(&e, &e.stiffness, &u);
                let worst = ku.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                // eps * (number of terms) * scale.
                assert!(worst < 1e-13 * scale * e.dofs() as f64, "{kind:?}: {worst}");
            }
            // Translation x: u^T M u = rho * volume = 1.
            let u = field(&e, |_| [1.0, 0.0, 0.0]);
            let mu = apply(&e, &e.mass, &u);
            let mass: f64 = u.iter().zip(&mu).map(|(a, b)| a * b).sum();
            assert!((mass - 1.0).abs() < 1e-14, "{kind:?}: {mass}");
        }
    }

    #[test]
    fn uniform_strain_energy_is_exact() {
        // Patch test on one element: u = eps x gives energy vol/2 eps^T D eps for every element.
        let nu = 0.3;
        let d = elasticity(nu);
        // eps_xx = 1e-3, gamma_xy = 2e-3 (u = (1e-3 x + 1e-3 y, 1e-3 x, 0)).
        let eps = [1e-3, 0.0, 0.0, 2e-3, 0.0, 0.0];
        let want: f64 = (0..6)
            .map(|i| (0..6).map(|j| eps[i] * d[i][j] * eps[j]).sum::<f64>())
            .sum();
        for kind in ElementKind::ALL {
            let e = UnitElement::new(kind, nu);
            let u = field(&e, |p| [1e-3 * p[0] + 1e-3 * p[1], 1e-3 * p[0], 0.0]);
            let ku = apply(&e, &e.stiffness, &u);
            let got: f64 = u.iter().zip(&ku).map(|(a, b)| a * b).sum();
            assert!(
                (got - want).abs() < 1e-12 * want,
                "{kind:?}: {got} vs {want}"
            );
        }
    }
}
