//! Small process-wide caches of results that cost far more to make than to keep, so that a
//! study's repeats and a gallery's methods make them once: the simplified meshes and what the
//! plan derives from them (`crate::simplify::speed`, `crate::plan`).

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
