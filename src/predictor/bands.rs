//! Deep-Modal's band representation of a shape's modes (Jin et al. 2020, sec. 3-4),
//! with exact band frequencies: the predictor's labels and its output.
//!
//! Where it sits: [`BandEncoding::encode`] turns a FEM [`ModeBasis`] of a shape in the 32^3
//! input box into the network's targets; [`BandEncoding::strike`] turns an encoding (FEM's or
//! the network's) back into the modes a strike plays, at the reference; [`reference_eigenvalue`]
//! maps them to reference-unit eigenvalues, from which the voicing path every FEM object takes
//! ([`crate::engine::voicing::tune`], the scaling laws of Deep-Modal eq. 10-12) gives any
//! material, size and damping.
//!
//! The representation:
//! - **Reference**: steel ([`REFERENCE_YOUNGS_PA`], [`REFERENCE_DENSITY_KG_M3`]) with the
//!   32-voxel box [`REFERENCE_BOX_M`] across. A 32-voxel bowl with a 2-voxel wall rings near
//!   1 kHz there, a solid 32^3 sphere near 10 kHz, a thin 32x32x1 plate near 100 Hz.
//! - **Bands**: [`BANDS`] mel-spaced bands from [`LOW_HZ`] to [`HIGH_HZ`] at the reference.
//! - **Strikes**: each cell of a 16^3 grid over the box (2x2x2 voxels) that holds surface,
//!   struck at its centre (snapped to the nearest exposed face) along +x, +y and +z.
//! - **Per strike and band**: a mask (the band holds a mode whose gain at that strike is within
//!   [`MASK_RANGE_DB`] of the strike's loudest mode) and the band's strongest gain there as a
//!   normalised log-amplitude, `1 + log10(g / g_max) / 3` (0 at -60 dB, 1 for the loudest).
//!   A mode's gain is its modal force over its angular frequency (Deep-Modal eq. 7), relative
//!   within a strike, so it does not depend on the material or the size.
//! - **Per band, beyond Deep-Modal**: the frequency of its strongest mode (most energy summed
//!   over every strike), stored exactly as `log10(Hz)`. A band is about 15 % wide at 1 kHz, so
//!   playing band centres would be up to a semitone off; this keeps a predicted mode in tune.

use crate::basis::{Hit, HitError, ModeBasis};
use crate::shape::VoxelGrid;
use std::f64::consts::TAU;

/// Mel bands.
pub const BANDS: usize = 32;
/// Lower edge of the lowest band at the reference, Hz.
pub const LOW_HZ: f64 = 100.0;
/// Upper edge of the highest band at the reference, Hz.
pub const HIGH_HZ: f64 = 10_000.0;
/// Voxels along each side of the input box.
pub const INPUT_SIDE: usize = 32;
/// Strike cells along each side of the input box (2x2x2 voxels each).
pub const CELLS_PER_AXIS: usize = 16;
/// Strike directions: +x, +y, +z.
pub const DIRECTIONS: usize = 3;
/// A band is masked in when one of its modes is within this range of the strike's loudest.
pub const MASK_RANGE_DB: f64 = 60.0;
/// Reference Young's modulus (steel), Pa.
pub const REFERENCE_YOUNGS_PA: f64 = 2.0e11;
/// Reference density (steel), kg/m^3.
pub const REFERENCE_DENSITY_KG_M3: f64 = 7850.0;
/// The input box's side at the reference, m.
pub const REFERENCE_BOX_M: f64 = 0.25;

/// Why a shape cannot be encoded.
#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    /// The grid does not fit the input box.
    #[error(
        "the shape is {0:?} voxels; the predictor's box is {INPUT_SIDE}^3: resample it to fit"
    )]
    TooLarge([usize; 3]),
    /// A strike could not be evaluated.
    #[error(transparent)]
    Hit(#[from] HitError),
}

fn mel(hz: f64) -> f64 {
    2595.0 * (1.0 + hz / 700.0).log10()
}

fn mel_to_hz(m: f64) -> f64 {
    700.0 * (10f64.powf(m / 2595.0) - 1.0)
}

/// The band edges at the reference, Hz: `BANDS + 1` values equally spaced in mel.
pub fn band_edges_hz() -> [f64; BANDS + 1] {
    let (lo, hi) = (mel(LOW_HZ), mel(HIGH_HZ));
    std::array::from_fn(|i| match i {
        0 => LOW_HZ,
        BANDS => HIGH_HZ,
        _ => mel_to_hz(lo + (hi - lo) * i as f64 / BANDS as f64),
    })
}

/// The band holding `hz` (at the reference), if any.
pub fn band_of(hz: f64) -> Option<usize> {
    if !(LOW_HZ..HIGH_HZ).contains(&hz) {
        return None;
    }
    let (lo, hi) = (mel(LOW_HZ), mel(HIGH_HZ));
    Some((((mel(hz) - lo) / (hi - lo) * BANDS as f64) as usize).min(BANDS - 1))
}

/// The voxel edge at the reference, m.
fn reference_voxel_m() -> f64 {
    REFERENCE_BOX_M / INPUT_SIDE as f64
}

/// Frequency at the reference, Hz, of a reference-unit eigenvalue (`E = rho = h = 1`).
pub fn reference_hz(eigenvalue: f64) -> f64 {
    let h = reference_voxel_m();
    (eigenvalue.max(0.0) * REFERENCE_YOUNGS_PA / (REFERENCE_DENSITY_KG_M3 * h * h)).sqrt() / TAU
}

/// The reference-unit eigenvalue of a frequency at the reference (inverse of [`reference_hz`]).
pub fn reference_eigenvalue(hz: f64) -> f64 {
    let h = reference_voxel_m();
    (TAU * hz).powi(2) * REFERENCE_DENSITY_KG_M3 * h * h / REFERENCE_YOUNGS_PA
}

/// A shape's modes in the band representation.
#[derive(Clone, Debug, PartialEq)]
pub struct BandEncoding {
    /// Whether each strike cell (x fastest) holds surface.
    pub struck: Vec<bool>,
    /// Mask per cell, direction and band: index `(cell * DIRECTIONS + dir) * BANDS + band`.
    pub mask: Vec<bool>,
    /// Normalised log-amplitude, same layout; 0 where the mask is off.
    pub log_amplitude: Vec<f32>,
    /// `log10(Hz)` at the reference of each band's strongest mode; `None` for an empty band.
    pub band_log_hz: [Option<f32>; BANDS],
}

/// One mode a strike plays, at the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BandMode {
    /// Band.
    pub band: usize,
    /// Frequency at the reference, Hz.
    pub freq_hz: f64,
    /// Gain relative to the strike's loudest mode (1 for it).
    pub gain: f64,
}

/// Index of a strike cell.
fn cell_index(c: [usize; 3]) -> usize {
    c[0] + CELLS_PER_AXIS * (c[1] + CELLS_PER_AXIS * c[2])
}

/// Whether voxel `v` is solid with an empty face neighbour.
fn on_surface(grid: &VoxelGrid, v: [usize; 3]) -> bool {
    let p = v.map(|c| c as isize);
    grid.get(p[0], p[1], p[2])
        && crate::shape::ops::FACE_NEIGHBOURS
            .iter()
            .any(|n| !grid.get(p[0] + n[0], p[1] + n[1], p[2] + n[2]))
}

/// The gain of one band for a force along the unit vector `direction`, from its three axis
/// strikes' normalised log-amplitudes (`None` where the mask is off): the axis gains
/// `10^(3 (a - 1))` combined as `sqrt(sum (d_k g_k)^2)` (their signs are not kept).
pub fn band_gain(direction: [f64; 3], log_amplitude: [Option<f32>; DIRECTIONS]) -> f64 {
    (0..DIRECTIONS)
        .map(|k| {
            let g = log_amplitude[k].map_or(0.0, |a| 10f64.powf(3.0 * (a as f64 - 1.0)));
            (direction[k] * g).powi(2)
        })
        .sum::<f64>()
        .sqrt()
}

/// Which strike cells (x fastest) hold surface: a solid voxel with an empty face neighbour.
pub fn struck_cells(grid: &VoxelGrid) -> Vec<bool> {
    let mut struck = vec![false; CELLS_PER_AXIS.pow(3)];
    for v in grid.solid_voxels() {
        if v.iter().all(|&c| c < INPUT_SIDE) && on_surface(grid, v) {
            struck[cell_index(v.map(|c| c / 2))] = true;
        }
    }
    struck
}

impl BandEncoding {
    /// Encodes the modes of `basis`, solved for `grid` (at most 32^3; voxel edge 1 in
    /// reference units, as [`ModeBasis::solve`] takes it).
    pub fn encode(basis: &ModeBasis, grid: &VoxelGrid) -> Result<Self, EncodeError> {
        let dims = grid.dims();
        if dims.iter().any(|&d| d > INPUT_SIDE) {
            return Err(EncodeError::TooLarge(dims));
        }
        let cells = CELLS_PER_AXIS.pow(3);
        let struck = struck_cells(grid);
        let eigenvalues = &basis.solution.eigenvalues;
        let bands: Vec<Option<usize>> = eigenvalues
            .iter()
            .map(|&l| band_of(reference_hz(l)))
            .collect();
        let mut mask = vec![false; cells * DIRECTIONS * BANDS];
        let mut log_amplitude = vec![0.0f32; cells * DIRECTIONS * BANDS];
        let mut energy = vec![0.0f64; eigenvalues.len()];
        let mut forces = vec![0.0; basis.mode_count()];
        let floor = 10f64.powf(-MASK_RANGE_DB / 20.0);
        for (cell, _) in struck.iter().enumerate().filter(|(_, &s)| s) {
            let c = [
                cell % CELLS_PER_AXIS,
                (cell / CELLS_PER_AXIS) % CELLS_PER_AXIS,
                cell / (CELLS_PER_AXIS * CELLS_PER_AXIS),
            ];
            for dir in 0..DIRECTIONS {
                let mut direction = [0.0; 3];
                direction[dir] = 1.0;
                let hit = Hit {
                    point_m: c.map(|c| 2.0 * c as f64 + 1.0),
                    direction: Some(direction),
                };
                basis.reference_forces_into(&hit, 1.0, &mut forces)?;
                let gains: Vec<f64> = forces
                    .iter()
                    .zip(eigenvalues)
                    .map(|(f, l)| (f / l.sqrt()).abs())
                    .collect();
                let loudest = gains
                    .iter()
                    .zip(&bands)
                    .filter(|(_, b)| b.is_some())
                    .fold(0.0f64, |m, (g, _)| m.max(*g));
                if loudest <= 0.0 {
                    continue;
                }
                let mut strongest = [0.0f64; BANDS];
                for (i, (&g, band)) in gains.iter().zip(&bands).enumerate() {
                    if let Some(b) = *band {
                        strongest[b] = strongest[b].max(g);
                        energy[i] += g * g;
                    }
                }
                let base = (cell * DIRECTIONS + dir) * BANDS;
                for (b, &g) in strongest.iter().enumerate() {
                    if g >= loudest * floor {
                        mask[base + b] = true;
                        log_amplitude[base + b] = (1.0 + (g / loudest).log10() / 3.0) as f32;
                    }
                }
            }
        }
        let mut band_log_hz = [None; BANDS];
        let mut best = [0.0f64; BANDS];
        for (i, band) in bands.iter().enumerate() {
            if let Some(b) = *band {
                if energy[i] > best[b] {
                    best[b] = energy[i];
                    band_log_hz[b] = Some(reference_hz(eigenvalues[i]).log10() as f32);
                }
            }
        }
        Ok(Self {
            struck,
            mask,
            log_amplitude,
            band_log_hz,
        })
    }

    /// The modes a strike at `cell` (16^3 grid coordinates) along `direction` plays, at the
    /// reference: one per masked band, at the band's frequency, with the gain of the three
    /// axis strikes combined as `sqrt(sum (d_k g_k)^2)` (their signs are not kept). Empty for
    /// a cell without surface. Gains are relative to the loudest axis strike's loudest mode.
    pub fn strike(&self, cell: [usize; 3], direction: [f64; 3]) -> Vec<BandMode> {
        if cell.iter().any(|&c| c >= CELLS_PER_AXIS) || !self.struck[cell_index(cell)] {
            return Vec::new();
        }
        let norm = direction.iter().map(|d| d * d).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return Vec::new();
        }
        let cell = cell_index(cell);
        (0..BANDS)
            .filter_map(|b| {
                let freq_hz = 10f64.powf(self.band_log_hz[b]? as f64);
                let entries = std::array::from_fn(|dir| {
                    let i = (cell * DIRECTIONS + dir) * BANDS + b;
                    self.mask[i].then_some(self.log_amplitude[i])
                });
                let gain = band_gain(direction.map(|d| d / norm), entries);
                (gain > 0.0).then_some(BandMode {
                    band: b,
                    freq_hz,
                    gain,
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::{EigenOptions, ModeCount, SolverKind};
    use crate::fem::ElementKind;

    #[test]
    fn bands_are_mel_spaced_from_100_hz_to_10_khz() {
        let e = band_edges_hz();
        assert_eq!((e[0], e[BANDS]), (LOW_HZ, HIGH_HZ));
        let widths: Vec<f64> = e.windows(2).map(|w| mel(w[1]) - mel(w[0])).collect();
        assert!(widths.iter().all(|w| (w / widths[0] - 1.0).abs() < 1e-9));
        for b in 0..BANDS {
            assert_eq!(band_of((e[b] * e[b + 1]).sqrt()), Some(b));
        }
        assert_eq!(band_of(99.0), None);
        assert_eq!(band_of(10_000.0), None);
        // At 1 kHz a band is about 15 % wide: band centres alone can be a semitone off.
        let b = band_of(1000.0).unwrap();
        assert!((0.13..0.16).contains(&(e[b + 1] / e[b] - 1.0)));
        let l = reference_eigenvalue(1234.5);
        assert!((reference_hz(l) / 1234.5 - 1.0).abs() < 1e-14);
    }

    #[test]
    fn a_fem_basis_encodes_in_tune_and_decodes_to_its_strikes() {
        // Truth: the FEM basis itself. A 32x8x2 bar's modes land in the bands at the
        // reference (its first bending mode near 1.3 kHz); every band frequency is one of its
        // modes, exactly (f32 log10: 1e-6);
        // a strike's loudest band decodes at gain 1 and its masks are the bands whose
        // strongest mode at that strike is within 60 dB of the loudest, recomputed here.
        let grid = VoxelGrid::from_fn([32, 8, 2], 1.0, |_, _, _| true).unwrap();
        let options = EigenOptions {
            count: ModeCount::First(30),
            ..EigenOptions::default()
        };
        let basis = ModeBasis::solve(
            &grid,
            ElementKind::Hex8Incompatible,
            0.29,
            SolverKind::Lanczos,
            &options,
        )
        .unwrap();
        let enc = BandEncoding::encode(&basis, &grid).unwrap();
        let freqs: Vec<f64> = basis
            .solution
            .eigenvalues
            .iter()
            .map(|&l| reference_hz(l))
            .collect();
        let mut bands_used = 0;
        for (b, f) in enc.band_log_hz.iter().enumerate() {
            if let Some(lf) = f {
                let hz = 10f64.powf(*lf as f64);
                let nearest = freqs
                    .iter()
                    .map(|m| (m / hz - 1.0).abs())
                    .fold(f64::INFINITY, f64::min);
                assert!(nearest < 1e-6, "band {b}: {hz} Hz is no mode");
                assert_eq!(band_of(hz), Some(b));
                bands_used += 1;
            }
        }
        assert!(bands_used >= 5, "{bands_used} bands");
        // The end cell (0, 1, 0) struck along z (across the bar): recompute its gains.
        let cell = [0, 1, 0];
        let hit = Hit {
            point_m: cell.map(|c| 2.0 * c as f64 + 1.0),
            direction: Some([0.0, 0.0, 1.0]),
        };
        let mut forces = vec![0.0; basis.mode_count()];
        basis.reference_forces_into(&hit, 1.0, &mut forces).unwrap();
        let mut strongest = [0.0f64; BANDS];
        for (f, l) in forces.iter().zip(&basis.solution.eigenvalues) {
            if let Some(b) = band_of(reference_hz(*l)) {
                strongest[b] = strongest[b].max((f / l.sqrt()).abs());
            }
        }
        let loudest = strongest.iter().copied().fold(0.0, f64::max);
        let played = enc.strike(cell, [0.0, 0.0, 1.0]);
        let max_gain = played.iter().map(|m| m.gain).fold(0.0, f64::max);
        assert!((max_gain - 1.0).abs() < 1e-6, "{max_gain}");
        for (b, &g) in strongest.iter().enumerate() {
            let want = g >= loudest * 1e-3 && enc.band_log_hz[b].is_some();
            let got = played.iter().find(|m| m.band == b);
            assert_eq!(got.is_some(), want, "band {b}");
            if let Some(m) = got {
                // f32 log-amplitudes: 1e-6 relative.
                assert!((m.gain / (g / loudest) - 1.0).abs() < 1e-5, "band {b}");
            }
        }
        // Outside the surface, or with no direction, nothing plays.
        assert!(enc.strike([15, 15, 15], [0.0, 0.0, 1.0]).is_empty());
        assert!(enc.strike(cell, [0.0; 3]).is_empty());
        // Too large for the box: a clear error.
        let big = VoxelGrid::from_fn([40, 2, 2], 1.0, |_, _, _| true).unwrap();
        assert!(BandEncoding::encode(&basis, &big)
            .unwrap_err()
            .to_string()
            .contains("resample"));
    }
}
