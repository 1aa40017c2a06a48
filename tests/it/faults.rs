//! Faults outside lancer's control end in a clear error and
//! leave nothing behind.

use std::process::Command;

/// A full disk while the image is written: the render runs on a 16 KiB
/// tmpfs (mounted in a private user and mount namespace with `unshare`, so
/// no root is needed), the 64 x 64 EXR does not fit. Exit code 1, the error
/// names the file and ENOSPC, and the folder is empty afterwards: the
/// temporary file is gone and no partial image is left.
#[test]
fn full_disk_while_writing_leaves_no_file() {
    let lancer = env!("CARGO_BIN_EXE_lancer");
    let dir = tempfile::tempdir().unwrap();
    let mnt = dir.path().join("tiny");
    std::fs::create_dir(&mnt).unwrap();
    let script = format!(
        "mount -t tmpfs -o size=16k tmpfs '{m}' || exit 99; \
         '{lancer}' render tests/scenes/furnace.toml --width 64 --height 64 --spp 1 \
         --out '{m}/x.exr' --quiet; code=$?; echo \"left: [$(ls -A '{m}')]\"; exit $code",
        m = mnt.display()
    );
    let o = Command::new("unshare")
        .args(["--user", "--map-root-user", "--mount", "sh", "-c", &script])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run unshare (util-linux)");
    let out = String::from_utf8_lossy(&o.stdout);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_ne!(
        o.status.code(),
        Some(99),
        "could not mount a tmpfs in a user namespace: {err}"
    );
    assert_eq!(o.status.code(), Some(1), "stdout: {out}\nstderr: {err}");
    assert!(err.contains("x.exr"), "{err}");
    assert!(err.contains("No space left on device"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.contains("left: []"), "{out}");
}
