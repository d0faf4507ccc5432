//! The pitch an object sounds: the reference of the "pitch" key mapping.
//!
//! Where it sits: [`super::audio::AudioEngine::fundamental_hz`] asks it for the playing
//! object's pitch at its own size, and a strike in pitch mode scales the object by the played
//! note's frequency over it. An axisymmetric object's lowest modes come in near-degenerate
//! pairs (a bowl's, bell's or cup's n = 2 pair; exactly degenerate in theory, split by any
//! asymmetry, the voxel lattice's included); the ear hears such a cluster as one tone between
//! its partials, beating slowly, not as its lowest member. So the reference is the
//! energy-weighted centre, in log frequency, of the partials within [`PITCH_CLUSTER_CENTS`] of
//! the lowest one: `f_ref = exp(sum w_i ln f_i / sum w_i)`, with `w_i` the energy a strike puts
//! into mode `i` (its modal force squared, for mass-normalised modes). A lone lowest mode is
//! its own reference, as before.

/// Partials within this many cents above the lowest form its cluster: one semitone. Two
/// partials a semitone or more apart are heard as two notes, closer ones as one beating tone.
pub const PITCH_CLUSTER_CENTS: f64 = 100.0;

/// The energy-weighted log-frequency centre of the lowest cluster of `partials` (frequency in
/// Hz, energy weight), given in ascending frequency. Weights that are all zero (a strike on
/// the cluster's nodal lines) count equally. `None` when there is no partial. Never allocates.
pub fn cluster_pitch_hz(partials: impl Iterator<Item = (f64, f64)>) -> Option<f64> {
    let mut lowest = None;
    let (mut sum_w, mut sum_wl, mut sum_l, mut n) = (0.0, 0.0, 0.0, 0usize);
    for (f, w) in partials {
        if !(f.is_finite() && f > 0.0) {
            continue;
        }
        let f0 = *lowest.get_or_insert(f);
        if 1200.0 * (f / f0).log2() > PITCH_CLUSTER_CENTS {
            break;
        }
        let w = if w.is_finite() { w.max(0.0) } else { 0.0 };
        sum_w += w;
        sum_wl += w * f.ln();
        sum_l += f.ln();
        n += 1;
    }
    let f0 = lowest?;
    if n == 1 {
        // A lone lowest mode is its own pitch, exactly.
        return Some(f0);
    }
    let centre = if sum_w > 0.0 {
        sum_wl / sum_w
    } else {
        sum_l / n as f64
    };
    Some(centre.exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cluster_centre_is_energy_weighted_in_log_frequency() {
        // 100 Hz (weight 1) and 102 Hz (weight 3) cluster; 110 Hz is 165 cents up: not in it.
        let got = cluster_pitch_hz([(100.0, 1.0), (102.0, 3.0), (110.0, 100.0)].into_iter());
        let want = ((100f64.ln() + 3.0 * 102f64.ln()) / 4.0).exp();
        assert!((got.unwrap() / want - 1.0).abs() < 1e-15);
        // A lone lowest mode is its own pitch.
        assert_eq!(
            cluster_pitch_hz([(100.0, 1.0), (120.0, 1.0)].into_iter()),
            Some(100.0)
        );
        // No energy anywhere in the cluster: the plain log centre.
        let got = cluster_pitch_hz([(100.0, 0.0), (104.0, 0.0)].into_iter()).unwrap();
        assert!((got - (100.0f64 * 104.0).sqrt()).abs() < 1e-12);
        assert_eq!(cluster_pitch_hz(std::iter::empty()), None);
    }
}
