//! Small process-wide caches of results that cost far more to make than to keep, so that a
//! study's repeats and a gallery's methods make them once: the simplified meshes and what the
//! plan derives from them (`crate::simplify::speed`, `crate::plan`); and the hashes that key
//! them, and the study's converged references on disk, by content.

use std::hash::{BuildHasher, Hash, Hasher};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// The last few results made, the oldest dropped first past the capacity.
pub(crate) struct Recent<K, V> {
    entries: Mutex<Vec<(K, V)>>,
    capacity: usize,
}

impl<K, V: Clone> Recent<K, V> {
    /// An empty cache that keeps at most `capacity` entries.
    pub const fn new(capacity: usize) -> Self {
        Recent {
            entries: Mutex::new(Vec::new()),
            capacity,
        }
    }

    /// The value of the first entry whose key `matches`, if any.
    pub fn find(&self, matches: impl Fn(&K) -> bool) -> Option<V> {
        self.lock()
            .iter()
            .find(|(k, _)| matches(k))
            .map(|(_, v)| v.clone())
    }

    /// Keep `value` under `key`, dropping the oldest entry if the cache is full.
    pub fn keep(&self, key: K, value: V) {
        let mut entries = self.lock();
        if entries.len() >= self.capacity.max(1) {
            entries.remove(0);
        }
        entries.push((key, value));
    }

    fn lock(&self) -> MutexGuard<'_, Vec<(K, V)>> {
        // A panic elsewhere while holding the lock leaves the entries still valid to read.
        self.entries.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Hash `words` a run of [`HASH_RUN`] at a time, and their count. Long runs, which foldhash
/// takes many bytes at a time: element by element, SipHash (std's default) took three times as
/// long over a mesh.
pub(crate) fn hash_words(hasher: &mut impl Hasher, words: impl Iterator<Item = u64>) {
    let mut run = [0u64; HASH_RUN];
    let (mut filled, mut count) = (0, 0usize);
    for word in words {
        run[filled] = word;
        filled += 1;
        if filled == HASH_RUN {
            run.hash(hasher);
            (filled, count) = (0, count + HASH_RUN);
        }
    }
    run[..filled].hash(hasher);
    hasher.write_usize(count + filled);
}

/// Words hashed at a time by [`hash_words`].
const HASH_RUN: usize = 1024;

/// The hasher of content keys: fixed, so that a key made in one run of a build
/// names a file for the next.
pub(crate) fn hasher() -> impl Hasher {
    foldhash::quality::FixedState::default().build_hasher()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_newest_entries_up_to_its_capacity() {
        let cache: Recent<u32, &str> = Recent::new(2);
        cache.keep(1, "one");
        cache.keep(2, "two");
        assert_eq!(cache.find(|&k| k == 1), Some("one"));
        cache.keep(3, "three");
        assert_eq!(cache.find(|&k| k == 1), None);
        assert_eq!(cache.find(|&k| k == 2), Some("two"));
        assert_eq!(cache.find(|&k| k == 3), Some("three"));
    }
}
