//! Typed handle → state maps shared by the entry points. Lookups never insert (a lookup of a
//! handle the layer never saw succeed must not invent state), values are `Arc`s so no lock is held
//! while the caller works with them or calls down the chain.

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::{Arc, RwLock};

#[derive(Debug)]
pub struct HandleMap<K, V> {
    map: RwLock<HashMap<K, Arc<V>>>,
}

impl<K, V> Default for HandleMap<K, V> {
    fn default() -> Self {
        HandleMap { map: RwLock::new(HashMap::new()) }
    }
}

impl<K: Eq + Hash + Copy, V> HandleMap<K, V> {
    pub fn get(&self, key: K) -> Option<Arc<V>> {
        self.read().get(&key).cloned()
    }
    /// Records state for a handle the call down just created; replaces stale state of a reused
    /// handle value (drivers may reuse handle values after destruction).
    pub fn insert(&self, key: K, value: Arc<V>) {
        self.write().insert(key, value);
    }
    pub fn remove(&self, key: K) -> Option<Arc<V>> {
        self.write().remove(&key)
    }
    /// Removes every entry matching `pred` (children of a destroyed parent).
    pub fn retain(&self, mut keep: impl FnMut(&K, &Arc<V>) -> bool) {
        self.write().retain(|k, v| keep(k, v));
    }
    pub fn len(&self) -> usize {
        self.read().len()
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// A snapshot, so callers iterate without holding the lock.
    pub fn values(&self) -> Vec<(K, Arc<V>)> {
        self.read().iter().map(|(k, v)| (*k, v.clone())).collect()
    }

    // A poisoned lock only means another thread panicked inside the layer (already caught and
    // reported); the map itself is still consistent, since no operation leaves it half-done.
    fn read(&self) -> std::sync::RwLockReadGuard<'_, HashMap<K, Arc<V>>> {
        self.map.read().unwrap_or_else(|e| e.into_inner())
    }
    fn write(&self) -> std::sync::RwLockWriteGuard<'_, HashMap<K, Arc<V>>> {
        self.map.write().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_never_inserts() {
        let m: HandleMap<u64, u32> = HandleMap::default();
        assert!(m.get(1).is_none());
        assert!(m.is_empty());
        m.insert(1, Arc::new(10));
        assert_eq!(*m.get(1).unwrap(), 10);
        m.insert(2, Arc::new(20));
        m.retain(|_, v| **v > 10);
        assert_eq!(m.len(), 1);
        assert_eq!(m.remove(2).map(|v| *v), Some(20));
    }
}
