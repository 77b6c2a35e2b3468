//! Makes the Vulkan loader find stereoshim's Vulkan half without the user installing anything: the
//! OpenXR half writes a layer manifest that points at the very library file it was loaded from
//! (so both halves are one loaded image and share state) and adds its folder to
//! `VK_ADD_LAYER_PATH`. The manifest text comes from `manifests`, like every other manifest.

use crate::manifests::{self as manifest, Kind};
use crate::manifests::private_fs;
use std::path::{Path, PathBuf};

pub use crate::manifests::VK_LAYER_NAME;

/// The manifest text for a library at `library_path`.
pub fn manifest_json(library_path: &Path) -> String {
    manifest::json(Kind::Vulkan, library_path)
}

/// The file a loaded code address belongs to, from `/proc/self/maps` text.
pub fn library_containing(maps: &str, address: usize) -> Option<PathBuf> {
    maps.lines().find_map(|line| {
        let mut fields = line.split_whitespace();
        let (start, end) = fields.next()?.split_once('-')?;
        let (start, end) = (usize::from_str_radix(start, 16).ok()?, usize::from_str_radix(end, 16).ok()?);
        let path = fields.nth(4)?;
        ((start..end).contains(&address) && path.starts_with('/')).then(|| PathBuf::from(path))
    })
}

/// `VK_ADD_LAYER_PATH` with `dir` added, unless it is already there.
pub fn add_layer_path(current: Option<&str>, dir: &Path) -> Option<String> {
    let dir = dir.to_str()?;
    match current.filter(|c| !c.is_empty()) {
        Some(c) if c.split(':').any(|p| p == dir) => None,
        Some(c) => Some(format!("{dir}:{c}")),
        None => Some(dir.to_string()),
    }
}

/// `VK_INSTANCE_LAYERS` with the layer added first (the loader puts the first-named layer closest
/// to the app, so layers the user listed, which may wrap handles, sit below it), unless it is
/// already there.
pub fn add_instance_layer(current: Option<&str>) -> Option<String> {
    match current.filter(|c| !c.is_empty()) {
        Some(c) if c.split(':').any(|p| p == VK_LAYER_NAME) => None,
        Some(c) => Some(format!("{VK_LAYER_NAME}:{c}")),
        None => Some(VK_LAYER_NAME.to_string()),
    }
}

/// Writes the manifest for `library` into a folder of the user's own (`private_fs`: under
/// `$XDG_RUNTIME_DIR`, else `$XDG_STATE_HOME`; 0700 folders, a 0600 file written atomically) and
/// returns that folder. A folder on the way that another user owns or can write to is refused:
/// the loader would load whatever library a manifest there names.
pub fn write_manifest(library: &Path) -> std::io::Result<PathBuf> {
    let env = |k: &str| std::env::var(k).ok();
    let base = private_fs::private_base(&env).ok_or_else(|| std::io::Error::other("none of XDG_RUNTIME_DIR, XDG_STATE_HOME, HOME is set"))?;
    // One folder per library file, so two builds of stereoshim never point at each other.
    let tag = library.to_string_lossy().bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3));
    let dir = private_fs::private_dir(&base, Path::new(&format!("stereoshim/vulkan-{tag:016x}")))?;
    private_fs::write_private(&dir.join(manifest::MANIFEST_FILE), manifest_json(library).as_bytes())?;
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_mapping_of_an_address() {
        let maps = "7f0000000000-7f0000001000 r-xp 00000000 08:01 123 /usr/lib/libstereoshim.so\n\
                    7f0000001000-7f0000002000 rw-p 00000000 00:00 0 \n\
                    7f0000002000-7f0000003000 r-xp 00000000 00:00 0 [vdso]\n";
        assert_eq!(library_containing(maps, 0x7f00_0000_0800), Some(PathBuf::from("/usr/lib/libstereoshim.so")));
        assert_eq!(library_containing(maps, 0x7f00_0000_1800), None);
        assert_eq!(library_containing(maps, 0x7f00_0000_2800), None);
    }

    #[test]
    fn paths_are_added_once() {
        let d = Path::new("/run/s");
        assert_eq!(add_layer_path(None, d).as_deref(), Some("/run/s"));
        assert_eq!(add_layer_path(Some("/a"), d).as_deref(), Some("/run/s:/a"));
        assert_eq!(add_layer_path(Some("/a:/run/s"), d), None);
        assert_eq!(add_instance_layer(Some("VK_LAYER_KHRONOS_validation")).as_deref(), Some("VK_LAYER_STEREOSHIM_stereoshim:VK_LAYER_KHRONOS_validation"));
        assert_eq!(add_instance_layer(Some(VK_LAYER_NAME)), None);
    }
}
