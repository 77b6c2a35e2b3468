//! What the layer writes to disk, and where (issue 11, "secrets and files"): generated manifests
//! make a loader map a library into the app, so they live only in the user's own folders, with
//! user-only permissions, and a folder someone else could write to is refused.

use crate::common;

use common::{output_dir, Half, Run};
use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// Every file and folder under `dir`, recursively.
fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                todo.push(p.clone());
            }
            out.push(p);
        }
    }
    out
}

/// A run with the layer writes its Vulkan manifest under `$XDG_RUNTIME_DIR` (0700 folders, a 0600
/// file, nothing temporary left) and nothing into the shared temporary folder.
#[test]
fn manifests_are_private_and_only_in_the_users_folders() {
    let tmp = output_dir("files-private-tmpdir");
    let run = Run::new("files-private").with_layer().env("TMPDIR", tmp.to_str().unwrap()).run();
    run.assert_ok().assert_layer_loaded(Half::Both);
    assert_eq!(tree(&tmp), Vec::<PathBuf>::new(), "the layer wrote into TMPDIR");
    let runtime = run.capture.parent().unwrap().join("run");
    let ours = runtime.join("stereoshim");
    let manifests: Vec<PathBuf> = tree(&ours).into_iter().filter(|p| p.is_file()).collect();
    assert_eq!(manifests.len(), 1, "one manifest and no temporary file: {manifests:?}");
    assert!(manifests[0].ends_with("stereoshim.json"), "{manifests:?}");
    assert_eq!(std::fs::metadata(&manifests[0]).unwrap().mode() & 0o777, 0o600);
    for d in tree(&ours).into_iter().filter(|p| p.is_dir()).chain([ours.clone()]) {
        assert_eq!(std::fs::metadata(&d).unwrap().mode() & 0o777, 0o700, "{}", d.display());
    }
}

/// Without `$XDG_RUNTIME_DIR` the manifest goes to `$XDG_STATE_HOME`, not to a temporary folder.
#[test]
fn without_a_runtime_folder_the_state_folder_is_used() {
    let tmp = output_dir("files-no-runtime-tmpdir");
    let run = Run::new("files-no-runtime").with_layer().env("TMPDIR", tmp.to_str().unwrap()).env("XDG_RUNTIME_DIR", "").run();
    run.assert_ok().assert_layer_loaded(Half::Both);
    assert_eq!(tree(&tmp), Vec::<PathBuf>::new(), "the layer wrote into TMPDIR");
    let state = run.capture.parent().unwrap().join("state");
    let manifests: Vec<PathBuf> = tree(&state.join("stereoshim")).into_iter().filter(|p| p.ends_with("stereoshim.json")).collect();
    assert_eq!(manifests.len(), 1, "{:?}", tree(&state));
    assert!(!run.capture.parent().unwrap().join("run").exists(), "nothing under an unset runtime folder");
}

/// A manifest folder that others can write to, or that another user owns, is refused: one clear
/// log line, the Vulkan half stays off (the loader is never pointed there), the app runs on.
#[test]
fn open_or_foreign_manifest_folders_are_refused() {
    let runtime = output_dir("files-refused-runtime");
    let ours = runtime.join("stereoshim");
    std::fs::create_dir(&ours).unwrap();
    std::fs::set_permissions(&ours, std::fs::Permissions::from_mode(0o777)).unwrap();
    let run = Run::new("files-refused-open").with_layer().env("XDG_RUNTIME_DIR", runtime.to_str().unwrap()).run();
    run.assert_ok().assert_layer_loaded(Half::OpenXr);
    let refused = run.log_lines("refusing to write a manifest");
    assert_eq!(refused.len(), 1, "{}", run.log);
    assert!(refused[0].contains("writable by group or others"), "{}", refused[0]);
    assert!(common::layer_loaded(&run.log, Half::Vulkan).is_err(), "the Vulkan half must stay off:\n{}", run.log);
    assert_eq!(tree(&ours), Vec::<PathBuf>::new(), "nothing written into the refused folder");

    // Another user's folder, closed to others: refused as well. Making it needs root (chown), as
    // in CI; elsewhere the rule is covered by `private_fs`'s unit tests.
    std::fs::set_permissions(&ours, std::fs::Permissions::from_mode(0o700)).unwrap();
    if std::os::unix::fs::chown(&ours, Some(54321), None).is_ok() {
        let run = Run::new("files-refused-foreign").with_layer().env("XDG_RUNTIME_DIR", runtime.to_str().unwrap()).run();
        run.assert_ok();
        let refused = run.log_lines("refusing to write a manifest");
        assert_eq!(refused.len(), 1, "{}", run.log);
        assert!(refused[0].contains("owned by another user"), "{}", refused[0]);
        assert!(common::layer_loaded(&run.log, Half::Vulkan).is_err(), "the Vulkan half must stay off:\n{}", run.log);
    }
}
