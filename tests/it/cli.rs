//! The `lancer` binary as a user meets it: exit codes, messages, files.

use crate::common;

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

/// Every file below `dir`, with its bytes (links read through), so that a
/// test can tell that a refused run changed nothing.
fn snapshot(dir: &Path) -> std::collections::BTreeMap<std::path::PathBuf, Vec<u8>> {
    let mut files = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                todo.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap_or_default();
                files.insert(path, bytes);
            }
        }
    }
    files
}

/// A 16 x 16 white furnace in `dir` that reads a mesh (`m.obj`) and a
/// texture (`tex.png`): `dir/scene.toml`.
fn scene_with_files(dir: &Path) -> std::path::PathBuf {
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 16\nheight = 16\nspp = 2\nmax_depth = 4\n\
         [camera]\neye = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 40\n\
         [environment]\nradiance = [1.0, 1.0, 1.0]\n\
         [materials.white]\ntype = \"lambert\"\nalbedo = [1.0, 1.0, 1.0]\n\
         [materials.wood]\ntype = \"lambert\"\nalbedo_texture = \"tex.png\"\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"m.obj\"\nmaterial = \"white\"\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, -3.0]\nradius = 1.0\nmaterial = \"wood\"\n",
    )
    .unwrap();
    std::fs::write(dir.join("m.obj"), "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::copy(
        common::repo("tests/scenes/tex/checker.png"),
        dir.join("tex.png"),
    )
    .unwrap();
    scene
}

/// Issue 18 §2: in every command, no output may name another output or an
/// input (the scene and the files it reads, film parts, images, the
/// reference and its variance, a baseline), however the path is spelled:
/// `./`, `..` or a symbolic link. The run is refused with a message that
/// names the file and both of its uses, and every file stays as it was.
#[test]
fn no_output_names_another_output_or_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = scene_with_files(d);
    let p = |name: &str| d.join(name).to_str().unwrap().to_string();
    // Valid inputs made by lancer itself
    for (args, made) in [
        (
            vec!["--film-out", &p("a.film"), "--samples", "0..1"],
            "a.film",
        ),
        (
            vec!["--film-out", &p("b.film"), "--samples", "1..2"],
            "b.film",
        ),
        (
            vec!["--out", &p("img.exr"), "--var-out", &p("img.var.exr")],
            "img.exr",
        ),
        (
            vec![
                "--out",
                &p("ref.exr"),
                "--var-out",
                &p("ref.var.exr"),
                "--seed",
                "9",
            ],
            "ref.exr",
        ),
    ] {
        let o = lancer(
            &[&["render", &p("scene.toml"), "-q"], &args[..]].concat(),
            &[],
        );
        assert!(o.status.success(), "making {made}: {}", stderr(&o));
    }
    std::fs::write(d.join("baseline.json"), "{}").unwrap();
    std::fs::create_dir(d.join("cv")).unwrap();
    std::fs::create_dir(d.join("sub")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&scene, d.join("link.json")).unwrap();
    let scene = scene.to_str().unwrap().to_string();
    // The files converge writes in its folder are outputs: a reference
    // there would be overwritten by the plot of the same name
    let o = lancer(
        &["render", &scene, "-q", "--out", &p("cv/relmse_spp.png")],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // A part named like an image, so that merge --out may name it
    std::fs::copy(d.join("b.film"), d.join("b.film.png")).unwrap();

    let owned = |args: &[&str]| args.iter().map(|a| a.to_string()).collect::<Vec<_>>();
    let cases: Vec<(Vec<String>, [&str; 2])> = vec![
        (
            owned(&[
                "merge",
                &p("a.film"),
                &p("b.film"),
                "--out",
                &p("x.exr"),
                "--var-out",
                &p("x.exr"),
            ]),
            ["given for two outputs", "(--out and --var-out)"],
        ),
        (
            owned(&[
                "merge",
                &p("a.film"),
                &p("b.film.png"),
                "--out",
                &p("sub/../b.film.png"),
            ]),
            ["--out would overwrite a film part", "is the same file"],
        ),
        (
            owned(&["render", &scene, "--film-out", &scene]),
            ["--film-out would overwrite the scene file", ""],
        ),
        (
            owned(&[
                "render",
                &scene,
                "--out",
                &p("o.png"),
                "--stats-json",
                &p("m.obj"),
            ]),
            ["--stats-json would overwrite a mesh of the scene", ""],
        ),
        (
            owned(&[
                "render",
                &scene,
                "--out",
                &p("o.png"),
                "--trace",
                &p("./tex.png"),
            ]),
            [
                "--trace would overwrite the texture of material \"wood\"",
                "",
            ],
        ),
        (
            owned(&[
                "render",
                &scene,
                "--out",
                &p("o.exr"),
                "--var-out",
                &p("sub/../o.exr"),
            ]),
            [
                "given for two outputs (--out and --var-out)",
                "is the same file",
            ],
        ),
        (
            owned(&[
                "render",
                &scene,
                "--film-out",
                &p("f.film"),
                "--samples",
                "0..1",
                "--stats-json",
                &p("f.film"),
            ]),
            ["given for two outputs (--film-out and --stats-json)", ""],
        ),
        (
            owned(&[
                "compare",
                &p("img.exr"),
                &p("ref.exr"),
                "--var",
                &p("img.var.exr"),
                "--json",
                &p("ref.var.exr"),
            ]),
            ["would overwrite the reference's variance", ""],
        ),
        (
            owned(&["convert", &scene, "--out", &scene]),
            ["--out would overwrite the scene file", ""],
        ),
        (
            owned(&[
                "bench",
                "--baseline",
                &p("baseline.json"),
                "--json",
                &p("./baseline.json"),
            ]),
            ["--json would overwrite --baseline", ""],
        ),
        (
            owned(&[
                "converge",
                &scene,
                "--reference",
                &p("cv/relmse_spp.png"),
                "--out",
                &p("cv"),
                "--max-spp",
                "2",
            ]),
            ["relmse_spp.png of --out would overwrite --reference", ""],
        ),
    ];
    #[cfg(unix)]
    let cases = [
        cases,
        vec![(
            owned(&[
                "render",
                &scene,
                "--out",
                &p("o.png"),
                "--stats-json",
                &p("link.json"),
            ]),
            [
                "--stats-json would overwrite the scene file",
                "is the same file",
            ],
        )],
    ]
    .concat();
    // A file a Mitsuba scene <include>s is an input of the scene too
    std::fs::write(
        d.join("part.xml"),
        "<scene version=\"3.0.0\">\n  <shape type=\"sphere\"/>\n</scene>\n",
    )
    .unwrap();
    std::fs::write(
        d.join("main.xml"),
        "<scene version=\"3.0.0\">\n  <sensor type=\"perspective\"><film type=\"hdrfilm\">\
         <integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/></film>\
         </sensor>\n  <include filename=\"part.xml\"/>\n</scene>\n",
    )
    .unwrap();
    let cases = [
        cases,
        vec![(
            owned(&[
                "render",
                &p("main.xml"),
                "--out",
                &p("o.png"),
                "--stats-json",
                &p("./part.xml"),
            ]),
            ["--stats-json would overwrite a file the scene includes", ""],
        )],
    ]
    .concat();
    let before = snapshot(d);
    for (args, says) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = lancer(&args, &[]);
        let e = stderr(&o);
        assert_ne!(o.status.code(), Some(0), "{args:?} ran: {e}");
        for s in says {
            assert!(e.contains(s), "{args:?}: {e}");
        }
        assert!(!e.contains("panicked"), "{e}");
        assert_eq!(snapshot(d), before, "{args:?} changed the files: {e}");
    }
}

/// Issue 18: the caches are outputs under the same rule. converge's
/// reference, rendered and cached in its folder under a name of the
/// scene's hash, would overwrite a texture that is that file through a
/// link; bench's generated scenes would be overwritten by `--json`. On
/// main converge wrote the variance over the texture and only then failed,
/// reading it; bench ran its whole suite and wrote the JSON over the scene.
/// Each is refused before any work, naming both uses, and every file stays
/// as it was.
#[test]
#[cfg(unix)]
fn caches_are_outputs_under_the_collision_rule() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = scene_with_files(d);
    let p = |name: &str| d.join(name).to_str().unwrap().to_string();
    let converge = [
        "converge",
        scene.to_str().unwrap(),
        "--out",
        &p("cv"),
        "--max-spp",
        "1",
        "--reference-spp",
        "1",
        "-q",
    ];
    // A first run names the cached reference; take it away, and make the
    // texture its variance through a link (the scene's bytes, hence the
    // name, unchanged)
    let o = lancer(&converge, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cached: Vec<std::path::PathBuf> = std::fs::read_dir(d.join("cv"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|f| {
            f.file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .starts_with("reference-")
        })
        .collect();
    assert_eq!(cached.len(), 2, "{cached:?}");
    let var = cached
        .iter()
        .find(|f| f.to_str().unwrap().ends_with(".var.exr"))
        .expect("the cached variance");
    for f in &cached {
        std::fs::remove_file(f).unwrap();
    }
    std::fs::rename(d.join("tex.png"), var).unwrap();
    std::os::unix::fs::symlink(var, d.join("tex.png")).unwrap();
    // bench's scene folder, with the folder --json would be written in
    std::fs::create_dir_all(d.join("scenes/examples")).unwrap();

    let owned = |args: &[&str]| args.iter().map(|a| a.to_string()).collect::<Vec<String>>();
    let cases = [
        (
            owned(&converge),
            [
                "the variance of the reference cached in --out would overwrite the texture of material \"wood\"",
                "is the same file",
            ],
        ),
        (
            owned(&[
                "bench",
                "--scene-dir",
                &p("scenes"),
                "--json",
                &p("scenes/examples/./cornell.toml"),
            ]),
            [
                "given for two outputs (--json and a scene generated in the scene folder)",
                "",
            ],
        ),
        (
            owned(&[
                "bench",
                "--scale",
                "--scene-dir",
                &p("scenes"),
                "--json",
                &p("scenes/bumpy_sphere_9.obj"),
            ]),
            [
                "given for two outputs (--json and a scene generated in the scene folder)",
                "",
            ],
        ),
    ];
    let before = snapshot(d);
    for (args, says) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = lancer(&args, &[]);
        let e = stderr(&o);
        assert_ne!(o.status.code(), Some(0), "{args:?} ran: {e}");
        for s in says {
            assert!(e.contains(s), "{args:?}: {e}");
        }
        assert!(!e.contains("panicked"), "{e}");
        assert_eq!(snapshot(d), before, "{args:?} changed the files: {e}");
    }
}

/// Issue 18 §3: each output option in each mode of `render` (a fixed spp,
/// a split render with `--samples`/`--film-out`, the budgets
/// `--time-limit` and `--target-error`, which render progressively) is
/// either written as documented or refused with a message that names both
/// options, writing nothing.
#[test]
fn every_render_output_works_in_every_mode_or_is_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |name: &str| d.join(name).to_str().unwrap().to_string();
    let base = [
        "render",
        "tests/scenes/furnace.toml",
        "--width",
        "16",
        "--height",
        "16",
        "-q",
    ];
    let film = p("part.film");
    let modes: [(&str, Vec<&str>); 5] = [
        ("fixed spp", vec!["--spp", "2"]),
        (
            "split",
            vec!["--spp", "4", "--samples", "0..2", "--film-out", &film],
        ),
        ("time limit", vec!["--time-limit", "0.2", "--max-spp", "2"]),
        (
            "target error",
            vec!["--target-error", "0.5", "--max-spp", "2"],
        ),
        (
            "adaptive",
            vec!["--adaptive", "--target-error", "0.5", "--max-spp", "2"],
        ),
    ];
    let image = p("image.png");
    let (png, exr, var, stats, trace) =
        (p("o.png"), p("o.exr"), p("v.exr"), p("s.json"), p("t.json"));
    let counts = p("n.exr");
    let outputs: [(&str, &str); 6] = [
        ("--out", &png),
        ("--out", &exr),
        ("--var-out", &var),
        ("--spp-out", &counts),
        ("--stats-json", &stats),
        ("--trace", &trace),
    ];
    for (mode, mode_args) in &modes {
        for (flag, path) in outputs {
            let _ = std::fs::remove_dir_all(d);
            std::fs::create_dir(d).unwrap();
            let mut args = [&base[..], mode_args, &[flag, path]].concat();
            // An image is written somewhere in the folder, never in the
            // current one
            if *mode != "split" && flag != "--out" {
                args.extend(["--out", &image]);
            }
            let o = lancer(&args, &[]);
            let e = stderr(&o);
            // The split render writes a film, not an image
            let refused = *mode == "split" && ["--out", "--var-out", "--spp-out"].contains(&flag);
            if refused {
                assert_eq!(o.status.code(), Some(2), "{mode} {flag}: {e}");
                assert!(
                    e.contains("--film-out") && e.contains(flag),
                    "{mode} {flag}: {e}"
                );
                assert_eq!(snapshot(d).len(), 0, "{mode} {flag}");
                continue;
            }
            assert!(o.status.success(), "{mode} {flag}: {e}");
            assert!(Path::new(path).is_file(), "{mode} {flag}: no {path}");
            if *mode == "split" {
                assert!(Path::new(&film).is_file(), "{mode} {flag}: no film");
            }
            let json = |path: &str| -> serde_json::Value {
                serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
            };
            match flag {
                "--stats-json" => {
                    assert!(json(path)["passes"].is_array(), "{mode}")
                }
                "--trace" => assert!(
                    json(path)
                        .as_array()
                        .is_some_and(|events| !events.is_empty())
                        || json(path)["traceEvents"].is_array(),
                    "{mode}"
                ),
                _ => {}
            }
        }
    }
    // Options that cannot go together, each refused naming both
    for (args, both) in [
        (
            vec!["--spp", "4", "--target-error", "0.1"],
            ["--spp", "--target-error"],
        ),
        (
            vec!["--samples", "0..1", "--time-limit", "1"],
            ["--samples", "--time-limit"],
        ),
        (
            vec!["--samples", "0..1", "--target-error", "0.1"],
            ["--samples", "--target-error"],
        ),
        (
            vec!["--film-out", &film, "--time-limit", "1"],
            ["--film-out", "--time-limit"],
        ),
        (
            vec!["--film-out", &film, "--target-error", "0.1"],
            ["--film-out", "--target-error"],
        ),
        (vec!["--max-spp", "4"], ["--max-spp", "--time-limit"]),
        (
            vec!["--time-limit", "1", "--target-error", "0.1"],
            ["--time-limit", "--target-error"],
        ),
    ] {
        let _ = std::fs::remove_dir_all(d);
        std::fs::create_dir(d).unwrap();
        let args = [&base[..], &args, &["--out", &png, "--stats-json", &stats]].concat();
        let o = lancer(&args, &[]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{args:?} ran");
        for flag in both {
            assert!(e.contains(flag), "{args:?}: {e}");
        }
        assert_eq!(snapshot(d).len(), 0, "{args:?}");
    }
}

/// Issue 18 §4: every command checks everything it can before it renders
/// or writes: a run refused for a bad option leaves its output folder
/// absent, or as it was.
#[test]
fn a_refused_run_leaves_its_outputs_as_they_were() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |name: &str| d.join(name).to_str().unwrap().to_string();
    let furnace = "tests/scenes/furnace.toml";
    let small = ["--width", "16", "--height", "16"];
    // Something in the folder that must stay as it is
    std::fs::create_dir(d.join("old")).unwrap();
    std::fs::write(d.join("old/converge.csv"), "earlier run\n").unwrap();
    std::fs::write(d.join("bad.film"), "not a film").unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["converge", furnace, "--seeds", "0", "--out", &p("cv")],
            "--seeds must be at least 1",
        ),
        (
            vec![
                "converge",
                furnace,
                "--reference-spp",
                "0",
                "--out",
                &p("cv"),
            ],
            "--reference-spp must be at least 1",
        ),
        (
            vec!["converge", furnace, "--seeds", "0", "--out", &p("old")],
            "--seeds must be at least 1",
        ),
        (
            vec!["converge", furnace, "--max-spp", "0", "--out", &p("cv")],
            "--max-spp must be at least 1",
        ),
        (
            vec!["converge", furnace, "--out", &p("bad.film")],
            "--out names a file",
        ),
        (
            vec!["render", furnace, "--time-limit", "0", "--out", &p("x.png")],
            "--time-limit must be",
        ),
        (
            vec![
                "render",
                furnace,
                "--target-error",
                "0.1",
                "--max-spp",
                "0",
                "--out",
                &p("x.png"),
            ],
            "--max-spp must be at least 1",
        ),
        (
            vec![
                "render",
                furnace,
                "--spp",
                "4",
                "--samples",
                "2..9",
                "--film-out",
                &p("x.film"),
            ],
            "B must be at most",
        ),
        (
            vec!["merge", &p("bad.film"), "--out", &p("x.png")],
            "not a usable film file",
        ),
        (
            vec!["merge", &p("bad.film"), "--out", &p("x.bmp")],
            "unsupported image extension",
        ),
        (
            vec![
                "compare",
                "docs/gallery/cornell.png",
                "docs/gallery/cornell.png",
                "--max-relmse=-1",
                "--json",
                &p("r.json"),
                "--heatmap",
                &p("h.png"),
            ],
            "--max-relmse must be",
        ),
        (
            vec![
                "convert",
                "tests/bad_scenes/no_such.toml",
                "--out",
                &p("s.toml"),
            ],
            "no_such.toml",
        ),
        (
            vec![
                "bench",
                "--baseline",
                &p("none.json"),
                "--json",
                &p("b.json"),
            ],
            "none.json",
        ),
    ]
    .into_iter()
    .map(|(args, says)| {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        (args, says)
    })
    .collect();
    let before = snapshot(d);
    for (args, says) in &cases {
        let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
        if args[0] == "converge" || args[0] == "render" {
            args.extend(small);
        }
        let o = lancer(&args, &[]);
        let e = stderr(&o);
        assert_ne!(o.status.code(), Some(0), "{args:?} ran: {e}");
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert_eq!(snapshot(d), before, "{args:?} wrote or changed files: {e}");
        assert!(!d.join("cv").exists(), "{args:?} made the folder");
    }
}
