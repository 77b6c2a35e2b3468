//! Handles are opaque non-zero u64s, unique across all object types and never reused, so a
//! stale or foreign handle is always detected (XR_ERROR_HANDLE_INVALID) instead of aliasing.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use openxr_sys as xr;

static NEXT_HANDLE: AtomicU64 = AtomicU64::new(1);

/// A typed table of live objects of one kind.
pub struct Registry<T> {
    map: Mutex<BTreeMap<u64, Arc<T>>>,
}

impl<T> Registry<T> {
    pub const fn new() -> Self {
        Registry { map: Mutex::new(BTreeMap::new()) }
    }

    /// Allocates a fresh handle and stores the object built for it.
    pub fn insert_with(&self, make: impl FnOnce(u64) -> T) -> (u64, Arc<T>) {
        let h = NEXT_HANDLE.fetch_add(1, Ordering::Relaxed);
        let obj = Arc::new(make(h));
        self.map.lock().unwrap().insert(h, obj.clone());
        (h, obj)
    }

    pub fn get(&self, h: u64) -> Result<Arc<T>, xr::Result> {
        if h == 0 {
            return Err(xr::Result::ERROR_HANDLE_INVALID);
        }
        self.map.lock().unwrap().get(&h).cloned().ok_or(xr::Result::ERROR_HANDLE_INVALID)
    }

    pub fn remove(&self, h: u64) -> Option<Arc<T>> {
        self.map.lock().unwrap().remove(&h)
    }

    /// Removes and returns every object `pred` selects (children of a destroyed parent).
    pub fn remove_where(&self, mut pred: impl FnMut(&T) -> bool) -> Vec<Arc<T>> {
        let mut map = self.map.lock().unwrap();
        let keys: Vec<u64> = map.iter().filter(|(_, v)| pred(v)).map(|(k, _)| *k).collect();
        keys.iter().filter_map(|k| map.remove(k)).collect()
    }

    pub fn find(&self, mut pred: impl FnMut(&T) -> bool) -> Vec<Arc<T>> {
        self.map.lock().unwrap().values().filter(|v| pred(v)).cloned().collect()
    }
}

impl<T> Default for Registry<T> {
    fn default() -> Self {
        Self::new()
    }
}
