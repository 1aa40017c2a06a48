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

/// A flag that overrides the scene is checked with the scene's settings,
/// once, and the message names the flag.
#[test]
fn a_bad_override_names_its_flag() {
    for (flag, value, says) in [
        (
            "--width",
            "0",
            "render.width: must be >= 1, got 0 (the value of --width)",
        ),
        (
            "--spp",
            "0",
            "render.spp: must be >= 1, got 0 (the value of --spp)",
        ),
        (
            "--max-depth",
            "0",
            "render.max_depth: must be >= 1, got 0 (the value of --max-depth)",
        ),
        ("--height", "4194304", "(the value of --height)"),
    ] {
        let o = lancer(
            &[
                "render",
                "tests/scenes/furnace.toml",
                flag,
                value,
                "--out",
                "/tmp/lancer-never.png",
            ],
            &[],
        );
        assert_eq!(o.status.code(), Some(1), "{flag} {value}");
        let e = stderr(&o);
        assert!(
            e.contains("furnace.toml: ") && e.contains(says),
            "{flag} {value}: {e}"
        );
        assert!(!e.contains("RenderOverrides"), "{e}");
    }
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

/// Ctrl-C during a render stops it between waves: exit code 130, and no
/// output or temporary file left in the output folder.
#[test]
fn ctrl_c_stops_a_render_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("long.png");
    let stats = dir.path().join("long.json");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_lancer"))
        .args([
            "render",
            "scenes/cornell.toml",
            "--spp",
            "100000",
            "--wave-size",
            "65536",
        ])
        .arg("--out")
        .arg(&out)
        .arg("--stats-json")
        .arg(&stats)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start lancer");
    std::thread::sleep(std::time::Duration::from_millis(2500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the render ended too soon"
    );
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("run kill");
    assert!(kill.success());
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(
            started.elapsed().as_secs() < 30,
            "no exit 30 s after SIGINT"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "files left: {left:?}");
}

/// Every output path is checked before rendering: a stats file in a folder
/// that does not exist fails at once, and the image is not written.
#[test]
fn output_paths_are_checked_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let bad_stats = dir.path().join("missing/stats.json");
    let o = lancer(
        &[
            "render",
            "scenes/cornell.toml",
            "--spp",
            "1",
            "--out",
            out.to_str().unwrap(),
            "--stats-json",
            bad_stats.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
    assert!(
        !out.exists(),
        "the image was written although the run failed"
    );
    let same = lancer(
        &[
            "render",
            "scenes/cornell.toml",
            "--spp",
            "1",
            "--out",
            out.to_str().unwrap(),
            "--trace",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        stderr(&same).contains("given for two outputs"),
        "{}",
        stderr(&same)
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// A scene too big for the device memory is a clear error that names the
/// buffer that did not fit, its size, the budget and where the budget came
/// from, and what to change (shown with a lowered budget), and writes
/// nothing. Invalid budgets are refused with a message.
#[test]
fn out_of_device_memory_names_what_did_not_fit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let args = [
        "render",
        "scenes/cornell.toml",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = lancer(&args, &[("LANCER_DEVICE_MEMORY_BUDGET", "4000000")]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains(
            "error: the state of 262144 paths in flight (generate.ray_origin) does not fit \
             this device: lower --wave-size: buffer \"generate.ray_origin\" needs 4194304 \
             bytes, more than is left of the device-memory budget of heap 0: 4000000 bytes \
             (set by LANCER_DEVICE_MEMORY_BUDGET), of which lancer's buffers hold "
        ),
        "{e}"
    );
    assert!(
        e.trim_end().ends_with(
            "; raise LANCER_DEVICE_MEMORY_BUDGET or unset it to use the device's budget"
        ),
        "{e}"
    );
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists());
    for (bad, says) in [
        (
            "lots",
            "LANCER_DEVICE_MEMORY_BUDGET=\"lots\" is not a number of bytes",
        ),
        (
            "0",
            "LANCER_DEVICE_MEMORY_BUDGET=0 leaves no device memory at all",
        ),
    ] {
        let o = lancer(&args, &[("LANCER_DEVICE_MEMORY_BUDGET", bad)]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
        assert!(!out.exists());
    }
    // A budget that holds the render changes nothing
    let small = ["--width", "16", "--height", "16", "--spp", "1"];
    let o = lancer(
        &[&args[..], &small].concat(),
        &[("LANCER_DEVICE_MEMORY_BUDGET", "400000000")],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The figure after `key` in `line`, up to the next space.
fn figure_after(line: &str, key: &str) -> u64 {
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("{key} in {line}")) + key.len()..];
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().unwrap_or_else(|_| panic!("{key} in {line}"))
}

/// A field of /proc/meminfo, in bytes.
fn meminfo(field: &str) -> u64 {
    let text = std::fs::read_to_string("/proc/meminfo").unwrap();
    let line = text.lines().find(|l| l.starts_with(field)).unwrap();
    figure_after(&line.replace(' ', ""), ":") * 1024
}

/// `lancer info` prints each memory heap's budget and its source. Unset,
/// the budget is what the device reports: `VK_EXT_memory_budget`'s
/// heapBudget minus heapUsage where it has the extension, else 80% of the
/// heap. On lavapipe the one heap is the machine's RAM (MemTotal) and the
/// budget what is available (MemAvailable, within what other processes
/// change while the test runs). `LANCER_DEVICE_MEMORY_BUDGET` replaces it.
#[test]
fn info_prints_the_device_memory_budget() {
    let args = ["info", "scenes/cornell.toml"];
    let available_before = meminfo("MemAvailable");
    let o = lancer(&args, &[]);
    let available_after = meminfo("MemAvailable");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let heaps: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("memory budget: heap "))
        .collect();
    assert!(!heaps.is_empty(), "{text}");
    let llvmpipe = text.contains("device: llvmpipe");
    for line in &heaps {
        let size = figure_after(line, " (");
        let bytes = figure_after(line, "): ");
        if line.contains("VK_EXT_memory_budget") {
            let budget = figure_after(line, "heapBudget ");
            let usage = figure_after(line, "heapUsage ");
            assert_eq!(bytes, budget.saturating_sub(usage), "{line}");
            assert!(budget <= size, "{line}");
        } else {
            assert!(line.contains("80% of the heap's"), "{line}");
            assert_eq!(bytes, (size as u128 * 80 / 100) as u64, "{line}");
        }
        if llvmpipe {
            assert_eq!(heaps.len(), 1, "{text}");
            assert!(line.contains("VK_EXT_memory_budget"), "{line}");
            assert_eq!(size, meminfo("MemTotal"), "{line}");
            assert_eq!(figure_after(line, "heapBudget "), size, "{line}");
            let slack = 1 << 30;
            let low = available_before.min(available_after).saturating_sub(slack);
            let high = available_before.max(available_after) + slack;
            assert!(
                (low..=high).contains(&bytes),
                "{line}: MemAvailable {available_before}"
            );
        }
    }
    let o = lancer(&args, &[("LANCER_DEVICE_MEMORY_BUDGET", "123456789")]);
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    for line in text.lines().filter(|l| l.starts_with("memory budget: ")) {
        assert!(
            line.ends_with("): 123456789 bytes (set by LANCER_DEVICE_MEMORY_BUDGET)"),
            "{line}"
        );
    }
}
