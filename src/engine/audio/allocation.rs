//! Which voice a strike plays in, and how many modes ring: a strike's modes and gains, a
//! free voice or a stolen one (the quietest, faded out over [`STEAL_FADE_SAMPLES`] in a
//! spare), and the mode budget across all voices.
//!
//! Where it sits: methods of [`AudioEngine`] that its event handling calls on the audio
//! thread; like the rest of `process` they never allocate (the struck-mode list and the
//! amplitude scratch are sized at start-up, [`AudioEngine::new`]).

use super::{AudioEngine, STEAL_FADE_SAMPLES};
use crate::engine::voice::{SlotMode, Voice};
use crate::engine::voicing::{tune, HitPoint};
use crate::synth::excitation::MAX_HARDNESS_S;
use crate::synth::Excitation;
use std::sync::atomic::Ordering;

/// A strike skips modes it excites less than this fraction of its loudest (-80 dB), as the
/// offline culling does ([`crate::modes::CullSettings`]).
const STRIKE_CULL_RATIO: f64 = 1e-4;

impl AudioEngine {
    /// The voice sounding `key`, not fading out: at most one (a strike on a sounding key
    /// reuses its voice or fades it out). Tries the key's hint first, else scans and
    /// refreshes the hint.
    pub(super) fn sounding_voice(&mut self, key: u8) -> Option<usize> {
        let sounding = |v: &Voice| v.key == Some(key) && v.fade_left == 0;
        let hint = usize::from(self.key_hint[usize::from(key)]);
        if self.voices.get(hint).is_some_and(sounding) {
            return Some(hint);
        }
        let found = self.voices.iter().position(sounding)?;
        self.key_hint[usize::from(key)] = found as u16;
        Some(found)
    }

    pub(super) fn strike(
        &mut self,
        key: u8,
        pitch: f64,
        velocity: f64,
        hit: Option<HitPoint>,
        hardness_s: Option<f64>,
    ) {
        let hardness = hardness_s.unwrap_or(self.voicing.hardness_s);
        let ok = pitch.is_finite()
            && pitch > 0.0
            && velocity.is_finite()
            && (0.0..=crate::synth::oscillator::MAX_VELOCITY).contains(&velocity)
            && (0.0..=MAX_HARDNESS_S).contains(&hardness);
        let excitation = if hardness > 0.0 {
            Excitation::mallet(hardness)
        } else {
            Ok(Excitation::Impulse)
        };
        let hit = hit.unwrap_or(self.voicing.hit);
        let forces_ready = self
            .object
            .as_mut()
            .is_some_and(|o| o.update_forces(&hit).is_ok());
        let (true, true, Ok(excitation)) = (ok, forces_ready, excitation) else {
            self.stats.dropped_strikes.fetch_add(1, Ordering::Relaxed);
            return;
        };
        // The struck voice: the key's own at the same pitch; else a free one (a key re-pitched
        // fades out like a stolen voice, so nothing clicks).
        let v = match self.sounding_voice(key) {
            Some(v) if (self.voices[v].pitch - pitch).abs() <= 1e-12 * pitch => Some(v),
            Some(v) => {
                self.voices[v].fade_left = STEAL_FADE_SAMPLES;
                self.take_voice()
            }
            None => self.take_voice(),
        };
        let (Some(v), Some(obj)) = (v, self.object.as_ref()) else {
            self.stats.dropped_strikes.fetch_add(1, Ordering::Relaxed);
            return;
        };
        self.last_pitch = pitch;
        let voice = &mut self.voices[v];
        if voice.key != Some(key) {
            voice.release();
            voice.key = Some(key);
            voice.pitch = pitch;
        }
        voice.muted = false;
        // The modes this strike excites, with their gains (Jin et al. 2020, eq. 7).
        let h = self.voicing.voxel_size_m(obj.extent, pitch);
        self.struck.clear();
        let mut loudest: f64 = 0.0;
        for (i, &lambda) in obj.basis.eigenvalues().iter().enumerate() {
            if self.struck.len() == self.struck.capacity() {
                break;
            }
            let decay_ratio = obj.basis.decay_ratio(i);
            let Some((f, d)) = tune(
                &self.voicing,
                lambda,
                h,
                decay_ratio,
                0.0,
                self.sample_rate_hz,
            ) else {
                continue;
            };
            let gain = self.voicing.modal_gain(obj.forces[i], h, f);
            let l = num_complex::Complex64::new(-d, std::f64::consts::TAU * f);
            let level = (gain * velocity * excitation.modal_factor(l).norm()).abs();
            if !level.is_finite() {
                continue;
            }
            loudest = loudest.max(level);
            self.struck.push(SlotMode {
                generation: obj.generation,
                index: i,
                unit_eigenvalue: lambda * (obj.extent * obj.extent) as f64,
                decay_ratio,
                gain,
                level,
            });
        }
        // Drop what this strike barely excites; a voice too small keeps the loudest modes.
        self.struck
            .retain(|m| m.level > 0.0 && m.level >= STRIKE_CULL_RATIO * loudest);
        if self.struck.len() > self.config.modes_per_voice {
            self.struck
                .sort_unstable_by(|a, b| b.level.total_cmp(&a.level));
            self.struck.truncate(self.config.modes_per_voice);
            self.struck.sort_unstable_by_key(|m| m.index);
        }
        self.voices[v].strike(
            &self.struck,
            &self.voicing,
            excitation,
            velocity,
            &mut self.gains,
        );
        self.enforce_budget();
    }

    /// A free voice; when `voices` keys already play, the quietest is stolen (it fades out in
    /// place while a spare plays). `None` only if every spare is busy fading.
    pub(super) fn take_voice(&mut self) -> Option<usize> {
        let playing = self
            .voices
            .iter()
            .filter(|v| v.key.is_some() && v.fade_left == 0)
            .count();
        if playing >= self.config.voices {
            let quietest = self
                .voices
                .iter_mut()
                .enumerate()
                .filter(|(_, v)| v.key.is_some() && v.fade_left == 0)
                .map(|(i, v)| {
                    v.measure();
                    let loud = v.amps[..v.modes.len()].iter().cloned().fold(0.0, f64::max);
                    (i, loud)
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))?
                .0;
            // The stolen voice fades out in place; it takes no more strikes.
            self.voices[quietest].fade_left = STEAL_FADE_SAMPLES;
        }
        self.voices.iter().position(|v| v.key.is_none())
    }

    /// Drops the quietest modes across all voices until at most `mode_budget` ring.
    pub(super) fn enforce_budget(&mut self) {
        let budget = self.config.mode_budget;
        let total = self.active_modes();
        if total <= budget {
            return;
        }
        let mut n = 0;
        for v in self.voices.iter_mut().filter(|v| !v.modes.is_empty()) {
            v.measure();
            let m = v.modes.len();
            self.all_amps[n..n + m].copy_from_slice(&v.amps[..m]);
            n += m;
        }
        // The budget-th loudest amplitude is the threshold (ties may keep a few more).
        let (_, threshold, _) =
            self.all_amps[..n].select_nth_unstable_by(total - budget, |a, b| a.total_cmp(b));
        let threshold = *threshold;
        #[cfg(test)]
        {
            let kept = self.all_amps[..n].iter().filter(|&&a| a >= threshold);
            let gone = self.all_amps[..n].iter().filter(|&&a| a < threshold);
            self.budget_split = (
                kept.cloned().fold(f64::INFINITY, f64::min),
                gone.cloned().fold(0.0, f64::max),
            );
        }
        let mut dropped = 0;
        for v in self.voices.iter_mut().filter(|v| !v.modes.is_empty()) {
            dropped += v.drop_below(threshold);
            if v.modes.is_empty() {
                v.release();
            }
        }
        self.stats
            .dropped_modes
            .fetch_add(dropped as u64, Ordering::Relaxed);
    }
}
