//! What lancer writes into its image files, and reads back: the render's
//! settings as EXR attributes and PNG text chunks, `--out -` for pipes, and
//! `compare` and `converge` taking spp from the files.

use crate::common;
use common::*;

use lancer::io::image_file::{read_metadata, Metadata};

/// `lancer render` on a 16 x 16 Cornell box with the given extra flags.
fn render_small(extra: &[&str]) -> std::process::Output {
    let base = [
        "render",
        "scenes/cornell.toml",
        "--width",
        "16",
        "--height",
        "16",
    ];
    let o = lancer(&[base.as_slice(), extra].concat(), &[]);
    assert!(o.status.success(), "render failed: {}", stderr(&o));
    o
}

/// Every setting given on the command line comes back from the EXR, its
/// variance EXR and the PNG; the render seconds equal `--stats-json`'s
/// `wall_seconds` to the last bit, and the version is this build's.
#[test]
fn render_records_its_settings_in_exr_and_png() {
    let dir = scratch("metadata");
    let (exr, var, png, json) = (
        dir.join("a.exr"),
        dir.join("a.var.exr"),
        dir.join("a.png"),
        dir.join("a.json"),
    );
    let settings = [
        "--spp",
        "4",
        "--seed",
        "7",
        "--max-depth",
        "5",
        "--integrator",
        "bsdf",
    ];
    render_small(
        &[
            settings.as_slice(),
            &[
                "-q",
                "--out",
                exr.to_str().unwrap(),
                "--var-out",
                var.to_str().unwrap(),
                "--stats-json",
                json.to_str().unwrap(),
            ],
        ]
        .concat(),
    );
    render_small(&[settings.as_slice(), &["-q", "--out", png.to_str().unwrap()]].concat());
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let device = stats["device"].as_str().unwrap().to_string();
    let driver = stats["driver"].as_str().unwrap().to_string();
    let seconds = stats["wall_seconds"].as_f64().unwrap();
    assert!(seconds > 0.0);
    for path in [&exr, &var, &png] {
        let meta = read_metadata(path).unwrap_or_else(|e| panic!("{e:#}"));
        let expected = Metadata {
            spp: Some(4),
            seed: Some(7),
            max_depth: Some(5),
            integrator: Some("bsdf".into()),
            sampler: Some("sobol".into()),
            render_seconds: if path == &png {
                meta.render_seconds
            } else {
                Some(seconds)
            },
            device: Some(device.clone()),
            driver: Some(driver.clone()),
            version: Some(lancer::VERSION.into()),
        };
        assert_eq!(meta, expected, "{}", path.display());
        assert!(meta.render_seconds.unwrap() > 0.0);
    }
    // The pixels are what they always were: the EXR reads back as rendered
    let (w, h, rgb) = lancer::io::image_file::read_image(&exr).unwrap();
    assert_eq!((w, h), (16, 16));
    assert_eq!(lancer::util::metrics::count_nonfinite(&rgb), 0);
    assert!(rgb.iter().any(|&v| v > 0.0));
}

/// `--out -` writes one PNG to standard output and nothing else: the bytes
/// start with the PNG signature, end with its IEND chunk, decode to the
/// image a file render gives (same pixels) and carry the metadata; the
/// table goes to standard error.
#[test]
fn out_dash_writes_only_the_png_to_stdout() {
    let dir = scratch("stdout");
    let file = dir.join("file.png");
    let piped = dir.join("piped.png");
    let o = render_small(&["--spp", "4", "--out", "-"]);
    let bytes = &o.stdout;
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(
        bytes.ends_with(&[0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82]),
        "standard output holds more than the PNG"
    );
    let err = stderr(&o);
    assert!(
        err.contains("generate") && err.contains("samples/s"),
        "{err}"
    );
    std::fs::write(&piped, bytes).unwrap();
    render_small(&["--spp", "4", "-q", "--out", file.to_str().unwrap()]);
    let a = image::open(&piped).expect("decode").to_rgb8();
    let b = image::open(&file).expect("decode").to_rgb8();
    assert_eq!(a.dimensions(), (16, 16));
    assert_eq!(a.as_raw(), b.as_raw(), "piped and file PNGs differ");
    assert_eq!(read_metadata(&piped).unwrap().spp, Some(4));

    // -q with --out -: standard error holds no table either
    let quiet = render_small(&["--spp", "1", "-q", "--out", "-"]);
    assert!(!stderr(&quiet).contains("generate"), "{}", stderr(&quiet));
}

/// `compare` shows each image's spp from its metadata (and puts them in its
/// JSON); `converge --reference` takes the reference's spp from the file,
/// records it in converge.json and warns when it is no more than the spp
/// measured.
#[test]
fn compare_and_converge_read_spp_back() {
    let dir = scratch("spp-back");
    let (image, reference) = (dir.join("image.exr"), dir.join("ref.exr"));
    render_small(&["--spp", "4", "-q", "--out", image.to_str().unwrap()]);
    render_small(&[
        "--spp",
        "16",
        "-q",
        "--seed",
        "9",
        "--out",
        reference.to_str().unwrap(),
    ]);

    let json = dir.join("compare.json");
    let o = lancer(
        &[
            "compare",
            image.to_str().unwrap(),
            reference.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("(16x16, 4 spp)"), "{stdout}");
    assert!(stdout.contains("ref.exr (16 spp)"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["image_spp"], 4);
    assert_eq!(report["reference_spp"], 16);

    let out = dir.join("study");
    let o = lancer(
        &[
            "converge",
            "scenes/cornell.toml",
            "--width",
            "16",
            "--height",
            "16",
            "--max-spp",
            "16",
            "--reference",
            reference.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("the reference has 16 spp, no more than the 16 spp measured"),
        "{err}"
    );
    let study: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("converge.json")).unwrap()).unwrap();
    let meta = &study["meta"]["reference"];
    assert_eq!(meta["spp"], 16, "{study:#}");
    assert_eq!(meta["seed"], 9, "{study:#}");
}
