//! Sets of values keyed by their type: how the base holds what each feature owns without naming
//! any feature. `Parts` holds values compared and cloned through the set (each feature's
//! settings); `States` holds live state shared behind an `Arc` (each feature's per-session and
//! per-instance state, with its own locks). The registry fills one per feature; a feature reads
//! its own by type.
#![forbid(unsafe_code)]

use std::any::{Any, TypeId};
use std::fmt;

/// A value a `Parts` may hold: comparable and clonable through the set.
pub trait Part: Any + Send + Sync + fmt::Debug {
    fn as_any(&self) -> &dyn Any;
    fn clone_part(&self) -> Box<dyn Part>;
    fn eq_part(&self, other: &dyn Part) -> bool;
}

impl<T: Any + Send + Sync + fmt::Debug + Clone + PartialEq> Part for T {
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn clone_part(&self) -> Box<dyn Part> {
        Box::new(self.clone())
    }
    fn eq_part(&self, other: &dyn Part) -> bool {
        other.as_any().downcast_ref::<T>() == Some(self)
    }
}

/// At most one value per type, in the order they were added (a handful: one per feature, so a
/// lookup is a short scan of type ids).
#[derive(Default)]
pub struct Parts(Vec<(TypeId, Box<dyn Part>)>);

impl Parts {
    /// Adds `part`, replacing a value of its type.
    pub fn with<T: Part>(mut self, part: T) -> Parts {
        self.0.retain(|(t, _)| *t != TypeId::of::<T>());
        self.0.push((TypeId::of::<T>(), Box::new(part)));
        self
    }
    pub fn get<T: Part>(&self) -> Option<&T> {
        self.0.iter().find(|(t, _)| *t == TypeId::of::<T>()).and_then(|(_, p)| p.as_ref().as_any().downcast_ref())
    }
}

impl Clone for Parts {
    fn clone(&self) -> Parts {
        Parts(self.0.iter().map(|(t, p)| (*t, p.clone_part())).collect())
    }
}

impl PartialEq for Parts {
    fn eq(&self, other: &Parts) -> bool {
        self.0.len() == other.0.len() && self.0.iter().all(|(t, p)| other.0.iter().any(|(u, q)| t == u && p.eq_part(q.as_ref())))
    }
}

impl fmt::Debug for Parts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.0.iter().map(|(_, p)| p)).finish()
    }
}

/// Live state, at most one value per type, in the order added: filled once (by the registry, when
/// the session or instance is made) and only read after that, each value guarding its own
/// mutable parts.
#[derive(Default)]
pub struct States(Vec<(TypeId, Box<dyn Any + Send + Sync>)>);

impl States {
    /// Adds `state`, replacing a value of its type.
    pub fn with<T: Any + Send + Sync>(mut self, state: T) -> States {
        self.0.retain(|(t, _)| *t != TypeId::of::<T>());
        self.0.push((TypeId::of::<T>(), Box::new(state)));
        self
    }
    pub fn get<T: Any>(&self) -> Option<&T> {
        self.0.iter().find(|(t, _)| *t == TypeId::of::<T>()).and_then(|(_, s)| s.downcast_ref())
    }
}

impl fmt::Debug for States {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "States({} values)", self.0.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Debug, PartialEq)]
    struct A(u32);
    #[derive(Clone, Debug, PartialEq)]
    struct B(&'static str);

    #[test]
    fn one_value_per_type() {
        let p = Parts::default().with(A(1)).with(B("b")).with(A(2));
        assert_eq!(p.get::<A>(), Some(&A(2)));
        assert_eq!(p.get::<B>(), Some(&B("b")));
        assert_eq!(p.get::<u8>(), None);
        let q = p.clone();
        assert_eq!(p, q);
        assert_ne!(p, q.with(B("c")));
        assert_ne!(Parts::default().with(A(1)), Parts::default().with(A(1)).with(B("b")));
    }

    #[test]
    fn one_state_per_type() {
        let s = States::default().with(std::sync::Mutex::new(1u32)).with(B("b")).with(std::sync::Mutex::new(2u32));
        assert_eq!(*s.get::<std::sync::Mutex<u32>>().unwrap().lock().unwrap(), 2);
        assert_eq!(s.get::<B>(), Some(&B("b")));
        assert!(s.get::<A>().is_none());
    }
}
