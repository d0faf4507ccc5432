//! The check that a mirror or an axis swap is a symmetry of the assembled `K` and `M`
//! ([`super::mirrors::Mirrors::detect`]): every mapped block matches its image to
//! [`SYMMETRY_TOLERANCE`] of the largest entry.

use super::mirrors::SYMMETRY_TOLERANCE;
use crate::fem::FemModel;

/// How a symmetry acts on a displacement's components: component `c` goes to `to[c]`, times
/// `sign[c]`.
#[derive(Clone, Copy)]
pub(super) struct Components {
    pub(super) to: [usize; 3],
    sign: [f64; 3],
}

impl Components {
    /// The mirror along `axis`: that component flips.
    pub(super) fn mirror(axis: usize) -> Self {
        let mut sign = [1.0; 3];
        sign[axis] = -1.0;
        Components {
            to: [0, 1, 2],
            sign,
        }
    }

    /// The swap of axes `a` and `b`.
    pub(super) fn swap(a: usize, b: usize) -> Self {
        let mut to = [0, 1, 2];
        to.swap(a, b);
        Components { to, sign: [1.0; 3] }
    }
}

/// Whether the symmetry (nodes by `map`, components by `comp`) maps every block of `K` and `M`
/// onto its image: `K(map a, map b)[to c][to d] = sign c sign d K(a, b)[c][d]`. `at` is scratch
/// of one entry per node, all `u32::MAX`, and is left so.
pub(super) fn maps_matrices(
    model: &FemModel,
    map: &[u32],
    comp: Components,
    (k_max, m_max): (f64, f64),
    at: &mut [u32],
) -> bool {
    let p = &model.pattern;
    // Entry `e = 3c + d` of a block goes to `to[e]`, times `sign[e]`.
    let to: [usize; 9] = std::array::from_fn(|e| 3 * comp.to[e / 3] + comp.to[e % 3]);
    let sign: [f64; 9] = std::array::from_fn(|e| comp.sign[e / 3] * comp.sign[e % 3]);
    let (k_tol, m_tol) = (SYMMETRY_TOLERANCE * k_max, SYMMETRY_TOLERANCE * m_max);
    // The symmetries are involutions, and `K` and `M` are symmetric (a block's transpose is
    // stored at the transposed place), so a block, its image, its transpose and its image's
    // transpose are all right when one of them is: the one with the largest row or column,
    // which is a block of row `a` at or before the diagonal, where `map[a] <= a`. Only those
    // are compared (about a quarter of the blocks: a half from each row of half the rows).
    (0..p.nodes()).all(|a| {
        if map[a] as usize > a {
            return true;
        }
        let image_row = p.row_ptr[map[a] as usize]..p.row_ptr[map[a] as usize + 1];
        let row = p.row_ptr[a]..p.row_ptr[a + 1];
        if row.len() != image_row.len() {
            return false;
        }
        for blk in image_row.clone() {
            at[p.col[blk] as usize] = blk as u32;
        }
        let lower = row.start..row.start + p.col[row].partition_point(|&b| b as usize <= a);
        // The image row's blocks by column, so each block's image is one lookup; they are
        // visited in the order of row `a`'s mapped columns, which the hardware does not
        // prefetch, so they are asked for first (the tin can's four passes over every row
        // and its whole image: 12.4 -> 7.1 ms).
        let image_of = |blk: usize| at[map[p.col[blk] as usize] as usize];
        for blk in lower.clone() {
            if let Some(block) = model.k().get(image_of(blk) as usize) {
                prefetch(block);
            }
        }
        let same = lower.into_iter().all(|blk| {
            let image = image_of(blk);
            if image == u32::MAX {
                return false;
            }
            let (k, ki) = (&model.k()[blk], &model.k()[image as usize]);
            // Branch-free over the block: one comparison per block, not per entry.
            let worst = (0..9).fold(0.0f64, |w, e| w.max((ki[to[e]] - sign[e] * k[e]).abs()));
            worst <= k_tol && (model.m()[image as usize] - model.m()[blk]).abs() <= m_tol
        });
        for blk in image_row {
            at[p.col[blk] as usize] = u32::MAX;
        }
        same
    })
}

/// Asks the cache for `block` ahead of its use.
#[inline(always)]
fn prefetch(block: &[f64; 9]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let start = block.as_ptr().cast::<i8>();
        // SAFETY: a prefetch is a hint that never faults or changes memory; both addresses
        // lie within the 72-byte block (its first byte and the first of the next cache line
        // it may span).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(start);
            _mm_prefetch::<_MM_HINT_T0>(start.add(64));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = block;
}

#[cfg(test)]
mod tests {
    use crate::eigen::symmetric::Mirrors;
    use crate::fem::ElementKind;

    /// The check compares about a quarter of the blocks (`maps_matrices`), standing for the
    /// rest by the symmetry of `K`. Independent truth: a box with three mirrors and the x-y
    /// swap, every pair of transposed blocks changed in turn (one entry off the diagonal, and
    /// its transpose, by 1e-8 of the largest entry: far above the 1e-11 tolerance, so no
    /// mirror holds it exactly), and each time some mirror or swap must be refused. A check
    /// that skipped any block's orbit would keep all of them for that block.
    #[test]
    fn a_change_in_any_block_breaks_a_symmetry() {
        let model = crate::fem::test_model("box:x=4,y=4,z=3", ElementKind::Hex8Incompatible, 0.3);
        let before = Mirrors::detect(&model).expect("mirrors");
        assert_eq!((before.axes(), before.swaps()), (0b111, vec![(0, 1)]));
        let k_max = model
            .k()
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let p = &model.pattern;
        let mut changed = model.clone();
        for a in 0..p.nodes() {
            for blk in p.row_ptr[a]..p.row_ptr[a + 1] {
                let b = p.col[blk] as usize;
                if b > a {
                    continue;
                }
                let transposed = p.find(b, a as u32).expect("a symmetric pattern");
                let delta = 1e-8 * k_max;
                changed.k_mut()[blk][1] += delta;
                changed.k_mut()[transposed][3] += delta;
                let after = Mirrors::detect(&changed);
                let kept = after
                    .as_ref()
                    .map_or((0, vec![]), |m| (m.axes(), m.swaps()));
                assert_ne!(kept, (0b111, vec![(0, 1)]), "block ({a}, {b}) changed");
                changed.k_mut()[blk] = model.k()[blk];
                changed.k_mut()[transposed] = model.k()[transposed];
            }
        }
    }
}
