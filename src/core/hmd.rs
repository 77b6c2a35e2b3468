//! The headset a runtime's system name names: the HMD profiles the project knows (their published
//! lens outlines and FOVs), matched exactly for the mock runtime's names and by product for real
//! headsets.
#![forbid(unsafe_code)]

use hmd_profiles::profile::{HmdProfile, HMD_NAMES};

/// The profile `system_name` names, if any.
pub fn profile_for(system_name: &str) -> Option<&'static HmdProfile> {
    if let Some(p) = HMD_NAMES.iter().filter_map(|n| HmdProfile::by_name(n)).find(|p| p.system_name == system_name) {
        return Some(p);
    }
    let lower = system_name.to_lowercase();
    [("index", "index"), ("vive", "vive"), ("quest 3", "quest3"), ("pimax", "pimax")].iter().find(|(k, _)| lower.contains(k)).and_then(|(_, n)| HmdProfile::by_name(n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_find_their_profiles() {
        assert_eq!(profile_for("Mock HMD (Valve Index)").map(|p| p.name), Some("index"));
        assert_eq!(profile_for("Valve Index").map(|p| p.name), Some("index"));
        assert_eq!(profile_for("Meta Quest 3 (WiVRn)").map(|p| p.name), Some("quest3"));
        assert!(profile_for("Simulated HMD").is_none());
    }
}
