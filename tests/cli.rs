//! The `lancer` binary as a user meets it: exit codes, messages, files.

mod common;

use std::path::Path;

use common::{lancer, stderr};

#[test]
fn render_writes_png_and_stats_json() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("cornell.png");
    let json = dir.path().join("stats.json");
    let o = lancer(
        &[
            "render",
            "scenes/cornell.toml",
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "4",
            "--out",
            png.to_str().unwrap(),
            "--stats-json",
            json.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "render failed: {}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for pass in [
        "generate",
        "intersect",
        "shade",
        "shadow",
        "accumulate",
        "Mrays/s",
        "samples/s",
    ] {
        assert!(stdout.contains(pass), "table lacks {pass}:\n{stdout}");
    }
    let img = image::open(&png).expect("png").to_rgb8();
    assert_eq!(img.dimensions(), (32, 24));
    assert!(img.pixels().any(|p| p.0 != [0, 0, 0]), "image is all black");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(
        stats.to_string().contains("llvmpipe") || std::env::var("LANCER_DEVICE").is_ok(),
        "{stats}"
    );
    // Nothing but the two outputs is left in the folder: no temporary files.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn bad_scene_is_a_clear_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(&scene, "[render]\nwidth = 64\nheight = 64\nspp = 4\n\n[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\nvfov = 400\n").unwrap();
    let o = lancer(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            dir.path().join("x.png").to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("bad.toml") && e.contains("camera.vfov") && e.contains(":9"),
        "{e}"
    );
    assert!(!e.contains("panicked"), "{e}");
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn missing_scene_and_bad_output_are_clear_errors() {
    let o = lancer(&["render", "no/such/scene.toml"], &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no/such/scene.toml"), "{}", stderr(&o));

    let o = lancer(
        &[
            "render",
            "tests/scenes/furnace.toml",
            "--spp",
            "1",
            "--out",
            "/tmp/lancer-out.bmpx",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains(".png") && stderr(&o).contains(".exr"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn no_vulkan_device_names_the_packages_to_install() {
    let empty = tempfile::tempdir().unwrap();
    let icd = empty.path().join("none.json");
    let o = lancer(
        &["render", "tests/scenes/furnace.toml"],
        &[
            ("VK_ICD_FILENAMES", icd.to_str().unwrap()),
            ("VK_DRIVER_FILES", icd.to_str().unwrap()),
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("mesa-vulkan-drivers") && e.contains("libvulkan1"),
        "{e}"
    );
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn devices_lists_lavapipe() {
    let o = lancer(&["devices"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.starts_with("0: "), "{out}");
    assert!(
        out.contains("llvmpipe") || Path::new("/dev/nvidia0").exists(),
        "{out}"
    );
}

#[test]
fn device_flag_that_matches_nothing_lists_the_devices() {
    let o = lancer(
        &[
            "render",
            "tests/scenes/furnace.toml",
            "--device",
            "no-such-gpu",
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("no-such-gpu") && e.contains("llvmpipe"), "{e}");
}

#[test]
fn oversized_wave_is_clamped_to_the_device() {
    // 256x256x64 paths would be one wave of 4,194,304: more workgroups than
    // one dispatch may have on lavapipe (65,535 x 64 threads).
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("stats.json");
    let o = lancer(
        &[
            "render",
            "scenes/cornell.toml",
            "--max-depth",
            "1",
            "--wave-size",
            "16777216",
            "--out",
            dir.path().join("x.png").to_str().unwrap(),
            "--stats-json",
            json.to_str().unwrap(),
            "-q",
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let wave = stats["wave_size"].as_u64().unwrap();
    assert!((1 << 20..=65535 * 64).contains(&wave), "wave {wave}");
    assert_eq!(
        stats["waves"].as_u64().unwrap(),
        (256u64 * 256 * 64).div_ceil(wave)
    );
}
