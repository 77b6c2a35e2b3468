//! Where and how stereoshim writes files that make loaders load code: generated layer manifests.
//!
//! A manifest names a library that the Vulkan or OpenXR loader maps into the app. Whoever can put
//! a file where the layer points the loader can therefore run code in the app. So:
//! - the layer writes only under the user's own folders: `$XDG_RUNTIME_DIR`, else
//!   `$XDG_STATE_HOME` (or `~/.local/state`), never a shared temporary folder;
//! - the folders it makes are the user's only (0700) and the files 0600, written to a fresh
//!   temporary name (`O_EXCL`, never through a planted symlink) and renamed into place, so no
//!   process ever reads half a manifest;
//! - a folder of the path that is a symlink, owned by another user, or writable by group or others
//!   is refused with a clear error: the caller logs it and leaves the loader alone.

use std::io::{Error, ErrorKind, Write};
use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// What the checks need to know of a folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DirFacts {
    pub is_symlink: bool,
    pub is_dir: bool,
    pub uid: u32,
    pub mode: u32,
}

/// Why a folder is not trusted with a manifest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    Symlink,
    NotAFolder,
    ForeignOwner { uid: u32 },
    Writable { mode: u32 },
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Symlink => write!(f, "is a symbolic link"),
            Refusal::NotAFolder => write!(f, "is not a folder"),
            Refusal::ForeignOwner { uid } => write!(f, "is owned by another user (uid {uid})"),
            Refusal::Writable { mode } => write!(f, "is writable by group or others (mode {:o})", mode & 0o7777),
        }
    }
}

/// Whether a folder the layer made (or found where it would make it) may hold a manifest.
pub fn check_dir(facts: DirFacts, euid: u32) -> Result<(), Refusal> {
    if facts.is_symlink {
        return Err(Refusal::Symlink);
    }
    if !facts.is_dir {
        return Err(Refusal::NotAFolder);
    }
    if facts.uid != euid {
        return Err(Refusal::ForeignOwner { uid: facts.uid });
    }
    if facts.mode & 0o022 != 0 {
        return Err(Refusal::Writable { mode: facts.mode });
    }
    Ok(())
}

/// The effective uid from `/proc/self/status` text (its `Uid:` line: real, effective, saved, fs).
pub fn euid_from_status(status: &str) -> Option<u32> {
    let line = status.lines().find(|l| l.starts_with("Uid:"))?;
    line.split_whitespace().nth(2)?.parse().ok()
}

fn euid() -> std::io::Result<u32> {
    let status = std::fs::read_to_string("/proc/self/status")?;
    euid_from_status(&status).ok_or_else(|| Error::other("no Uid line in /proc/self/status"))
}

/// The folder generated manifests go under: `$XDG_RUNTIME_DIR`, else `$XDG_STATE_HOME`, else
/// `$HOME/.local/state` (relative values are ignored, as the XDG spec says). None without any.
pub fn private_base(env: &dyn Fn(&str) -> Option<String>) -> Option<PathBuf> {
    let absolute = |k: &str| env(k).map(PathBuf::from).filter(|p| p.is_absolute());
    absolute("XDG_RUNTIME_DIR").or_else(|| absolute("XDG_STATE_HOME")).or_else(|| absolute("HOME").map(|h| h.join(".local/state")))
}

/// Makes `base/sub` (each component of `sub` 0700, made if missing) and checks every component of
/// `sub`: none may be a symlink, another user's, or group- / world-writable. `base` itself must
/// exist and belong to the user (an XDG folder).
pub fn private_dir(base: &Path, sub: &Path) -> std::io::Result<PathBuf> {
    let euid = euid()?;
    let refuse = |p: &Path, r: Refusal| Error::new(ErrorKind::PermissionDenied, format!("{} {r}: refusing to write a manifest there", p.display()));
    let facts = |p: &Path| -> std::io::Result<DirFacts> {
        let m = std::fs::symlink_metadata(p)?;
        Ok(DirFacts { is_symlink: m.file_type().is_symlink(), is_dir: m.is_dir(), uid: m.uid(), mode: m.mode() })
    };
    if std::fs::symlink_metadata(base).is_err() {
        // An XDG folder that does not exist yet (a fresh home): made as the spec asks, 0700.
        std::fs::DirBuilder::new().recursive(true).mode(0o700).create(base)?;
    }
    let b = facts(base)?;
    // The base may be a symlink to the user's folder (a common home layout); what it points at
    // must still be the user's.
    let b = if b.is_symlink { std::fs::metadata(base).map(|m| DirFacts { is_symlink: false, is_dir: m.is_dir(), uid: m.uid(), mode: m.mode() })? } else { b };
    // `/tmp`-like bases (sticky, world-writable) would let anyone pre-create our folder; the
    // checks below catch that, but a base owned by someone else is refused outright.
    if let Err(r @ (Refusal::ForeignOwner { .. } | Refusal::NotAFolder)) = check_dir(b, euid) {
        return Err(refuse(base, r));
    }
    let mut dir = base.to_path_buf();
    for part in sub.components() {
        dir.push(part);
        match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
            Ok(()) => {}
            Err(e) if e.kind() == ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
        check_dir(facts(&dir)?, euid).map_err(|r| refuse(&dir, r))?;
    }
    Ok(dir)
}

/// Writes `bytes` to `path` (in a folder checked by `private_dir`) with mode 0600: to a fresh
/// temporary name first (`create_new`, so a planted symlink is never followed), then renamed.
pub fn write_private(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().ok_or_else(|| Error::other("no parent folder"))?;
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    // A stale temporary of an earlier process with our pid: ours to replace.
    let _ = std::fs::remove_file(&tmp);
    let result = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).mode(0o600).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(uid: u32, mode: u32) -> DirFacts {
        DirFacts { is_symlink: false, is_dir: true, uid, mode: 0o040000 | mode }
    }

    #[test]
    fn only_the_users_own_closed_folders_are_trusted() {
        assert_eq!(check_dir(dir(1000, 0o700), 1000), Ok(()));
        assert_eq!(check_dir(dir(1000, 0o755), 1000), Ok(()));
        assert_eq!(check_dir(dir(1000, 0o777), 1000), Err(Refusal::Writable { mode: 0o040777 }));
        assert_eq!(check_dir(dir(1000, 0o770), 1000), Err(Refusal::Writable { mode: 0o040770 }));
        assert_eq!(check_dir(dir(0, 0o700), 1000), Err(Refusal::ForeignOwner { uid: 0 }));
        assert_eq!(check_dir(DirFacts { is_symlink: true, ..dir(1000, 0o700) }, 1000), Err(Refusal::Symlink));
        assert_eq!(check_dir(DirFacts { is_dir: false, ..dir(1000, 0o600) }, 1000), Err(Refusal::NotAFolder));
    }

    #[test]
    fn effective_uid_is_the_second_field() {
        assert_eq!(euid_from_status("Name:\tx\nUid:\t1000\t1001\t1000\t1000\nGid:\t5\t5\t5\t5\n"), Some(1001));
        assert_eq!(euid_from_status("Name:\tx\n"), None);
        assert_eq!(euid_from_status("Uid:\tx\ty\n"), None);
    }

    #[test]
    fn base_is_runtime_then_state_then_home_and_absolute_only() {
        let env = |pairs: &'static [(&'static str, &'static str)]| move |k: &str| pairs.iter().find(|(a, _)| *a == k).map(|(_, v)| v.to_string());
        assert_eq!(private_base(&env(&[("XDG_RUNTIME_DIR", "/run/user/1"), ("HOME", "/h")])), Some(PathBuf::from("/run/user/1")));
        assert_eq!(private_base(&env(&[("XDG_RUNTIME_DIR", "rel"), ("XDG_STATE_HOME", "/s")])), Some(PathBuf::from("/s")));
        assert_eq!(private_base(&env(&[("HOME", "/h")])), Some(PathBuf::from("/h/.local/state")));
        assert_eq!(private_base(&env(&[])), None);
    }

    #[test]
    fn writes_private_files_in_checked_folders_and_refuses_open_ones() {
        let base = std::env::temp_dir().join(format!("stereoshim-private-fs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        std::fs::DirBuilder::new().mode(0o700).create(&base).unwrap();
        let d = private_dir(&base, Path::new("a/b")).unwrap();
        assert_eq!(std::fs::metadata(&d).unwrap().mode() & 0o777, 0o700);
        let file = d.join("m.json");
        write_private(&file, b"{}").unwrap();
        write_private(&file, b"{\"x\":1}").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"{\"x\":1}");
        assert_eq!(std::fs::metadata(&file).unwrap().mode() & 0o777, 0o600);
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "no temporary left behind");
        // A folder others can write to is refused, also when it already existed.
        let open = base.join("open");
        std::fs::create_dir(&open).unwrap();
        std::fs::set_permissions(&open, std::os::unix::fs::PermissionsExt::from_mode(0o777)).unwrap();
        let e = private_dir(&base, Path::new("open/x")).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::PermissionDenied, "{e}");
        // A symlink planted where our folder goes is refused, not followed.
        std::os::unix::fs::symlink(&d, base.join("link")).unwrap();
        assert_eq!(private_dir(&base, Path::new("link")).unwrap_err().kind(), ErrorKind::PermissionDenied);
        std::fs::remove_dir_all(&base).unwrap();
    }
}
