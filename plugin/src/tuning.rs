//! The plugin's microtuning: the Scala scale and keyboard mapping a project uses (persisted
//! as their texts, `#[persist = "tuning"]`), and the per-key frequency table the audio thread
//! reads without a lock.
//!
//! Where it sits: the editor's "Tuning" button loads the files ([`TuningState`]); the table
//! ([`KeyTable`]) is rebuilt from the persisted state off the audio thread (by the editor at
//! once, and by the worker's poll after a host restores a project, [`crate::solve_source`]);
//! [`crate::keymap`] reads a key's frequency from it in the "pitch" mapping. The formats and
//! the key arithmetic are the library's ([`modalforge::tuning`]).

use modalforge::tuning::{Mapping, Scale, Tuning, TuningError, KEYS};
use serde::{Deserialize, Serialize};
use std::hash::{Hash, Hasher};
use std::sync::atomic::{AtomicU64, Ordering};

/// A project's tuning as loaded: the files' names and texts (so it reloads exactly).
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct TuningState {
    /// The `.scl` file's name.
    pub scale_file: String,
    /// Its text.
    pub scale: String,
    /// The `.kbm` file's name and text, if one was loaded.
    pub mapping: Option<(String, String)>,
}

impl TuningState {
    /// The tuning the texts describe.
    pub fn tuning(&self) -> Result<Tuning, TuningError> {
        Ok(Tuning {
            scale: Scale::parse(&self.scale, &self.scale_file)?,
            mapping: match &self.mapping {
                Some((file, text)) => Mapping::parse(text, file)?,
                None => Mapping::default(),
            },
        })
    }

    fn fingerprint(state: Option<&Self>) -> u64 {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        state.hash(&mut h);
        h.finish()
    }
}

/// Every key's frequency in Hz as `f64` bits (0: the key is silent), written off the audio
/// thread and read on it with relaxed atomics (a key read mid-update plays the old or the new
/// tuning, both valid).
pub struct KeyTable {
    hz: [AtomicU64; KEYS],
    /// Fingerprint of the state the table was built from.
    built_from: AtomicU64,
}

impl Default for KeyTable {
    /// 12-tone equal temperament, A4 = 440 Hz.
    fn default() -> Self {
        let table = Self {
            hz: std::array::from_fn(|_| AtomicU64::new(0)),
            built_from: AtomicU64::new(TuningState::fingerprint(None)),
        };
        table.set(&Self::equal_tempered());
        table
    }
}

impl KeyTable {
    /// The standard tuning: `440 * 2^((k - 69) / 12)`.
    pub fn equal_tempered() -> [f64; KEYS] {
        std::array::from_fn(|k| 440.0 * 2f64.powf((k as f64 - 69.0) / 12.0))
    }

    fn set(&self, hz: &[f64; KEYS]) {
        for (a, f) in self.hz.iter().zip(hz) {
            a.store(f.to_bits(), Ordering::Relaxed);
        }
    }

    /// Key `key`'s frequency, Hz; 0 where it is silent. Never blocks.
    pub fn hz(&self, key: u8) -> f64 {
        f64::from_bits(self.hz[key as usize % KEYS].load(Ordering::Relaxed))
    }

    /// Rebuilds the table from `state` if it changed since the last build (12-TET for none).
    /// A state that does not parse (a damaged project) keeps 12-TET and says why.
    pub fn sync(&self, state: Option<&TuningState>) -> Result<(), TuningError> {
        let print = TuningState::fingerprint(state);
        if self.built_from.swap(print, Ordering::Relaxed) == print {
            return Ok(());
        }
        match state.map(TuningState::tuning).transpose() {
            Ok(Some(t)) => self.set(&t.table()),
            Ok(None) => self.set(&Self::equal_tempered()),
            Err(e) => {
                self.set(&Self::equal_tempered());
                return Err(e);
            }
        }
        Ok(())
    }
}
