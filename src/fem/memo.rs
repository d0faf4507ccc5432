//! A small process-wide memo of element tables: the unit element ([`super::UnitElement`]) and
//! the cut elements' sub-cell integrals ([`super::cut::CutElement`]) depend only on the element
//! kind, Poisson's ratio and the sub-cell count, yet every assembly integrated them again
//! (hex27's unit element 0.5 ms, hex8i's sub-cell table 0.3 ms: a tenth of the default bowl's
//! hex8i assembly, measured with `cargo bench --bench partial_voxels -- --assembly`).
//!
//! Where it sits: [`super::FemModel::assemble`] and the multigrid ask it for their tables; the
//! worker threads that assemble share it (a lock held while a table is integrated, never on
//! the audio thread). It keeps the [`CAPACITY`] most recently used tables of each type.

use std::sync::{Arc, Mutex, PoisonError};

/// Tables kept per type: a plugin session uses one or two element kinds and a few materials
/// (Poisson's ratio is the material's).
pub const CAPACITY: usize = 8;

/// The most recently used values by key, most recent last.
pub struct Memo<K, V> {
    entries: Mutex<Vec<(K, Arc<V>)>>,
}

impl<K: PartialEq, V> Memo<K, V> {
    /// An empty memo (for a `static`).
    pub const fn new() -> Self {
        Memo {
            entries: Mutex::new(Vec::new()),
        }
    }

    /// The value for `key`, computed by `make` if it is not kept (then kept, dropping the
    /// least recently used beyond [`CAPACITY`]).
    pub fn get_or_make(&self, key: K, make: impl FnOnce() -> V) -> Arc<V> {
        // A panic while a table was made leaves the list as it was: nothing to repair.
        let mut entries = self.entries.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(at) = entries.iter().position(|(k, _)| *k == key) {
            let entry = entries.remove(at);
            let value = Arc::clone(&entry.1);
            entries.push(entry);
            return value;
        }
        let value = Arc::new(make());
        if entries.len() == CAPACITY {
            entries.remove(0);
        }
        entries.push((key, Arc::clone(&value)));
        value
    }
}

impl<K: PartialEq, V> Default for Memo<K, V> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kept_value_is_shared_and_the_least_recently_used_is_dropped() {
        let memo: Memo<usize, usize> = Memo::new();
        let made = std::cell::Cell::new(0);
        let get = |k: usize| {
            *memo.get_or_make(k, || {
                made.set(made.get() + 1);
                10 * k
            })
        };
        assert_eq!(get(1), 10);
        assert_eq!(get(1), 10);
        assert_eq!(made.get(), 1);
        for k in 2..=CAPACITY {
            get(k);
        }
        assert_eq!(get(1), 10); // kept: CAPACITY keys so far
        assert_eq!(made.get(), CAPACITY);
        get(CAPACITY + 1); // drops 2, now the least recently used
        get(2);
        assert_eq!(made.get(), CAPACITY + 2);
        get(1); // still kept
        assert_eq!(made.get(), CAPACITY + 2);
    }
}
