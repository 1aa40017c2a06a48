//! Renders split into sample ranges (`render --samples A..B --film-out`)
//! and merged (`lancer merge`) give the image of one render of all samples,
//! and `merge` refuses parts of another scene, overlapping or missing
//! ranges and damaged files, each with its message. (tests/slurm.sh runs
//! the same split as a Slurm job array.)

use crate::common;

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
    part(
        "8..16",
        Path::new(&d("independent.film")),
        &["--sampler", "independent"],
    );
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
    // Another sampler draws other samples: its films must not merge (the
    // scene hash covers the sampler, and the header names it)
    let e = merge(&["a.film", "independent.film"]);
    assert!(
        e.contains(&format!(
            "error: {}: rendered from another scene than {}",
            d("independent.film"),
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
    // And the good pair merges, recording the sampler.
    ok(&["merge", &d("b.film"), &d("a.film"), "--out", &d("ok.exr")]);
    let meta = lancer::io::image_file::read_metadata(Path::new(&d("ok.exr"))).unwrap();
    assert_eq!(meta.sampler.as_deref(), Some("sobol"));
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

/// A 2 x 2 film part of samples `first..end` of 8 with scene hash 1 (the
/// library's writer: a valid file, checksum and all).
fn film_part(first: u32, end: u32) -> lancer::io::film::FilmPart {
    let sum: Vec<f64> = (0..12).map(|i| f64::from(i * (end - first))).collect();
    lancer::io::film::FilmPart {
        scene_hash: 1,
        sampler: lancer::render::kernels::Sampler::Sobol,
        first,
        end,
        spp: 8,
        width: 2,
        height: 2,
        nonfinite: 0,
        sum_sq: sum.iter().map(|s| s * s).collect(),
        sum_odd: sum.iter().map(|s| 0.5 * s).collect(),
        sum,
    }
}

/// Every size in a film header is checked, in checked arithmetic, against
/// lancer's image limit and the file's length, before the sums are read:
/// a header of 2^30 x 2^30 pixels made the length check wrap to the bytes
/// of an empty film, and `merge` panicked on a slice index.
#[test]
fn film_header_sizes_are_checked_before_the_sums_are_read() {
    use lancer::io::film::FilmPart;
    let dir = tempfile::tempdir().unwrap();
    let refused = |name: &str, part: &FilmPart| {
        let path = dir.path().join(name);
        std::fs::write(&path, part.to_bytes()).unwrap();
        let e = format!("{:#}", FilmPart::read(&path).unwrap_err());
        let prefix = format!("{}: not a usable film file: ", path.display());
        e.strip_prefix(&prefix)
            .unwrap_or_else(|| panic!("{e}"))
            .to_string()
    };
    let empty = |width, height| FilmPart {
        width,
        height,
        sum: Vec::new(),
        sum_sq: Vec::new(),
        sum_odd: Vec::new(),
        ..film_part(0, 8)
    };
    // 2^30 x 2^30 x 48 bytes is 3 x 2^64: it wrapped to 0 (format version 1).
    assert_eq!(
        refused("wrap.film", &empty(1 << 30, 1 << 30)),
        "its header claims a width of 1073741824 pixels; a film is at most 1048576 pixels wide \
         (lancer's image limit): the header is damaged; render the part again"
    );
    assert_eq!(
        refused("large.film", &empty(1 << 20, 1 << 12)),
        "its header claims 1048576 x 4096 = 4294967296 pixels; a film holds at most \
         2147483648 pixels (lancer's image limit): the header is damaged; render the part again"
    );
    assert_eq!(
        refused("wide.film", &empty(u32::MAX, 1)),
        "its header claims a width of 4294967295 pixels; a film is at most 1048576 pixels wide \
         (lancer's image limit): the header is damaged; render the part again"
    );
    assert_eq!(
        refused("zero.film", &empty(0, 5)),
        "its header claims 0 x 5 pixels; a film has at least one pixel: the header is damaged; \
         render the part again"
    );
    assert_eq!(
        refused("short.film", &empty(2, 2)),
        "it is 56 bytes, but a 2x2 film is 344: truncated or damaged"
    );
    // More dropped samples than the part holds.
    let dropped = FilmPart {
        nonfinite: 33,
        ..film_part(0, 8)
    };
    assert_eq!(
        refused("dropped.film", &dropped),
        "its header counts 33 samples dropped for NaN or infinite radiance, but the part holds \
         only 32 (samples 0..8 of 4 pixels): the header is damaged; render the part again"
    );
    // The sums' lengths must match the header (a part built in code).
    let long = FilmPart {
        sum: vec![0.0; 13],
        ..film_part(0, 8)
    };
    let e = format!(
        "{:#}",
        lancer::io::film::merge(&[("long.film".into(), long)]).unwrap_err()
    );
    assert_eq!(
        e,
        "long.film: not a usable film file: it holds 13 radiance sums, 12 sums of squares and 12 \
         sums of odd samples; a 2x2 film holds 12 of each"
    );
}

/// `merge` refuses a part whose sums are NaN or infinite, or whose sums of
/// squares are negative, naming the part, the pixel and the channel; it
/// used to merge them into an image of NaN pixels and exit 0.
#[test]
fn merge_refuses_nan_sums_and_negative_squares_naming_part_and_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    std::fs::write(d("a.film"), film_part(0, 4).to_bytes()).unwrap();
    let mut nan = film_part(4, 8);
    nan.sum[4] = f64::NAN; // pixel 1 (x 1, y 0), G
    std::fs::write(d("nan.film"), nan.to_bytes()).unwrap();
    let mut inf = film_part(4, 8);
    inf.sum_sq[9] = f64::INFINITY; // pixel 3 (x 1, y 1), R
    std::fs::write(d("inf.film"), inf.to_bytes()).unwrap();
    let mut negative = film_part(4, 8);
    negative.sum_sq[8] = -1.0; // pixel 2 (x 0, y 1), B
    std::fs::write(d("negative.film"), negative.to_bytes()).unwrap();
    let merge = |film: &str| {
        let out = d("out.exr");
        let o = lancer(&["merge", &d("a.film"), &d(film), "--out", &out], &[]);
        assert_eq!(o.status.code(), Some(1), "merge {film}: {}", stderr(&o));
        assert!(!Path::new(&out).exists(), "a refused merge wrote an image");
        stderr(&o)
    };
    assert_eq!(
        merge("nan.film"),
        format!(
            "error: {}: not a usable film file: pixel (1, 0): the radiance sum of G is NaN; \
             a sum must be finite: the file is damaged; render the part again\n",
            d("nan.film")
        )
    );
    assert_eq!(
        merge("inf.film"),
        format!(
            "error: {}: not a usable film file: pixel (1, 1): the sum of squares of R is inf; \
             a sum of squares must be finite and >= 0: the file is damaged; render the part \
             again\n",
            d("inf.film")
        )
    );
    assert_eq!(
        merge("negative.film"),
        format!(
            "error: {}: not a usable film file: pixel (0, 1): the sum of squares of B is -1; \
             a sum of squares must be finite and >= 0: the file is damaged; render the part \
             again\n",
            d("negative.film")
        )
    );
}
