//! A small process-wide memo of what every solve of the same kind would otherwise compute
//! again: the unit element ([`super::UnitElement`]) and the cut elements' sub-cell integrals
//! ([`super::cut::CutElement`]), which depend only on the element kind, Poisson's ratio and
//! the sub-cell count (hex27's unit element took 0.5 ms, hex8i's sub-cell table 0.3 ms: a
//! tenth of the default bowl's hex8i assembly, `cargo bench --bench partial_voxels --
//! --assembly`), and the symbolic factorisation of a pattern factored before.
//!
//! Where it sits: [`super::FemModel::assemble`] and the multigrid ask it for their tables, and
//! the shifted Cholesky factor for the symbolic factorisation of a pattern it factored before
//! ([`crate::eigen::factor`]); the worker threads share it (a lock held while a value is
//! made, never on the audio thread). Each memo keeps its `N` most recently used values
//! ([`CAPACITY`] by default).

use std::sync::{Arc, Mutex, PoisonError};

/// Tables kept per type: a plugin session uses one or two element kinds and a few materials
/// (Poisson's ratio is the material's).
pub const CAPACITY: usize = 8;

/// The most recently used values by key, most recent last; at most `N` of them.
pub struct Memo<K, V, const N: usize = CAPACITY> {
    entries: Mutex<Vec<(K, Arc<V>)>>,
}

impl<K: PartialEq, V, const N: usize> Memo<K, V, N> {
    /// An empty memo (for a `static`).
    pub const fn new() -> Self {
        Memo {
            entries: Mutex::new(Vec::new()),
        }
    }

    /// The value for `key`, computed by `make` if it is not kept (then kept, dropping the
    /// least recently used beyond `N`).
    pub fn get_or_make(&self, key: K, make: impl FnOnce() -> V) -> Arc<V> {
        match self.try_get_or_make(key, || Ok::<V, std::convert::Infallible>(make())) {
            Ok(value) => value,
        }
    }

    /// [`Memo::get_or_make`] for a `make` that can fail: an error is returned, not kept.
    pub fn try_get_or_make<E>(
        &self,
        key: K,
        make: impl FnOnce() -> Result<V, E>,
    ) -> Result<Arc<V>, E> {
        // A panic while a value was made leaves the list as it was: nothing to repair.
        let mut entries = self.entries.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(at) = entries.iter().position(|(k, _)| *k == key) {
            let entry = entries.remove(at);
            let value = Arc::clone(&entry.1);
            entries.push(entry);
            return Ok(value);
        }
        let value = Arc::new(make()?);
        if entries.len() == N {
            entries.remove(0);
        }
        entries.push((key, Arc::clone(&value)));
        Ok(value)
    }
}

impl<K: PartialEq, V, const N: usize> Default for Memo<K, V, N> {
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
