//! Renders split into sample ranges (`render --samples A..B --film-out`)
//! and merged (`lancer merge`) give the image of one render of all samples,
//! and `merge` refuses parts of another scene, overlapping or missing
//! ranges and damaged files, each with its message. (tests/slurm.sh runs
//! the same split as a Slurm job array.)

mod common;

use common::*;
use std::path::Path;

const SCENE: &str = "scenes/cornell.toml";
const SIZE: [&str; 6] = ["--width", "48", "--height", "40", "--spp", "16"];

/// Runs lancer and asserts success.
fn ok(args: &[&str]) {
    let out = lancer(args, &[]);
    assert!(out.status.success(), "lancer {args:?}: {}", stderr(&out));
}

/// Renders samples `range` of the test scene into `film`.
fn part(range: &str, film: &Path, extra: &[&str]) {
    let mut args = vec![
        "render",
        SCENE,
        "--samples",
        range,
        "--film-out",
        film.to_str().unwrap(),
        "-q",
    ];
    args.extend(SIZE);
    args.extend(extra);
    ok(&args);
}

fn read(path: &Path) -> Vec<f32> {
    lancer::io::image_file::read_exr(path).expect("read EXR").2
}

/// Largest |a - b| in units of the f32 spacing at max(|a|, |b|).
fn max_ulps(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let m = x.abs().max(y.abs());
            let ulp = f32::from_bits(m.to_bits() + 1) - m;
            f64::from((x - y).abs()) / f64::from(ulp)
        })
        .fold(0.0, f64::max)
}

#[test]
fn four_parts_merge_into_the_single_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name);
    // Uneven ranges, given to merge out of order.
    let ranges = ["0..3", "3..8", "8..13", "13..16"];
    for (i, r) in ranges.iter().enumerate() {
        part(r, &d(&format!("p{i}.film")), &[]);
    }
    let films: Vec<String> = [2, 0, 3, 1]
        .iter()
        .map(|i| d(&format!("p{i}.film")).to_string_lossy().into_owned())
        .collect();
    let mut args: Vec<&str> = vec!["merge"];
    args.extend(films.iter().map(String::as_str));
    let (merged, merged_var) = (d("merged.exr"), d("merged_var.exr"));
    args.extend([
        "--out",
        merged.to_str().unwrap(),
        "--var-out",
        merged_var.to_str().unwrap(),
    ]);
    ok(&args);
    let (single, single_var) = (d("single.exr"), d("single_var.exr"));
    let mut args = vec![
        "render",
        SCENE,
        "-q",
        "--out",
        single.to_str().unwrap(),
        "--var-out",
        single_var.to_str().unwrap(),
    ];
    args.extend(SIZE);
    ok(&args);

    let (a, b) = (read(&merged), read(&single));
    let (va, vb) = (read(&merged_var), read(&single_var));
    assert!(b.iter().any(|&v| v > 0.0), "a black image");
    assert_eq!(lancer::util::metrics::count_nonfinite(&a), 0);
    // The merge adds the parts' f64 sums in another grouping than the
    // single render's waves; after rounding to f32 the two agree to the
    // last bit here, and must agree within f32 rounding always.
    let (diff_mean, diff_var) = (differing_bits(&a, &b), differing_bits(&va, &vb));
    let (ulps_mean, ulps_var) = (max_ulps(&a, &b), max_ulps(&va, &vb));
    println!(
        "merge vs single: {diff_mean} of {} means differ (max {ulps_mean} f32 ulps), \
         {diff_var} variances differ (max {ulps_var} ulps)",
        a.len()
    );
    assert!(ulps_mean <= 1.0, "means differ by {ulps_mean} ulps");
    assert!(ulps_var <= 1.0, "variances differ by {ulps_var} ulps");
}

#[test]
fn merge_refuses_other_scenes_overlaps_gaps_and_damage() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    part("0..8", Path::new(&d("a.film")), &[]);
    part("8..16", Path::new(&d("b.film")), &[]);
    part("6..16", Path::new(&d("overlap.film")), &[]);
    part("8..16", Path::new(&d("seed.film")), &["--seed", "7"]);
    let merge = |films: &[&str]| {
        let paths: Vec<String> = films.iter().map(|f| d(f)).collect();
        let mut args: Vec<&str> = vec!["merge"];
        args.extend(paths.iter().map(String::as_str));
        let out = d("out.exr");
        args.extend(["--out", out.as_str()]);
        let o = lancer(&args, &[]);
        assert!(!o.status.success(), "merge {films:?} succeeded");
        assert!(!Path::new(&out).exists(), "a refused merge wrote an image");
        stderr(&o)
    };
    let e = merge(&["a.film", "seed.film"]);
    assert!(
        e.contains(&format!(
            "error: {}: rendered from another scene than {}",
            d("seed.film"),
            d("a.film")
        )),
        "{e}"
    );
    let e = merge(&["a.film", "overlap.film"]);
    assert!(
        e.contains(&format!(
            "error: {}: samples 6..16 overlap {} (which ends at 8)",
            d("overlap.film"),
            d("a.film")
        )),
        "{e}"
    );
    let e = merge(&["b.film"]);
    assert!(
        e.contains(
            "error: samples 0..8 are missing: no part holds them (the parts must cover 0..16)"
        ),
        "{e}"
    );
    // One flipped bit in the sums, and a truncated file.
    let mut bytes = std::fs::read(d("b.film")).unwrap();
    bytes[1000] ^= 1;
    std::fs::write(d("flipped.film"), &bytes).unwrap();
    std::fs::write(d("short.film"), &bytes[..bytes.len() / 2]).unwrap();
    let e = merge(&["a.film", "flipped.film"]);
    assert!(
        e.contains(&format!(
            "error: {}: not a usable film file: checksum mismatch",
            d("flipped.film")
        )),
        "{e}"
    );
    let e = merge(&["a.film", "short.film"]);
    assert!(e.contains("truncated or damaged"), "{e}");
    // And the good pair merges.
    ok(&["merge", &d("b.film"), &d("a.film"), "--out", &d("ok.exr")]);
    // --samples beyond the scene's spp is refused before rendering.
    let o = lancer(
        &[
            "render",
            SCENE,
            "--spp",
            "16",
            "--samples",
            "8..17",
            "--film-out",
            &d("x.film"),
        ],
        &[],
    );
    assert!(
        stderr(&o).contains("--samples 8..17: the scene has 16 spp"),
        "{}",
        stderr(&o)
    );
}
