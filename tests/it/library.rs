//! lancer as a library: the program in `examples/render_in_code.rs` (which
//! the crate-level documentation shows) builds its scene in code, and that
//! scene renders the same image, bit for bit, as its TOML twin; the
//! version names the commit.

use crate::common;
use common::*;

#[allow(dead_code)]
#[path = "../../examples/render_in_code.rs"]
mod example;

use lancer::scene::BUILT_SOURCE;

/// The builder's scene and `tests/scenes/builder_twin.toml` hold the same
/// materials, spheres and triangles, and render the same mean and variance
/// in every bit, with the same seed and spp; the image is not black, so the
/// comparison has something to compare.
#[test]
fn builder_scene_renders_the_same_image_as_its_toml_twin() {
    let built = example::scene().expect("the example's scene builds");
    let file = load("tests/scenes/builder_twin.toml");
    assert_eq!(built.source.to_str(), Some(BUILT_SOURCE));
    assert_eq!(built.render, file.render);
    assert_eq!(built.camera, file.camera);
    assert_eq!(built.environment, file.environment);
    assert_eq!(built.materials, file.materials);
    assert_eq!(built.spheres, file.spheres);
    assert_eq!(built.triangles, file.triangles);

    let ctx = context();
    let a = render(&ctx, &built, &options(1 << 12));
    let b = render(&ctx, &file, &options(1 << 12));
    assert_eq!((a.width, a.height, a.spp), (64, 64, 16));
    assert_eq!(differing_bits(&a.mean, &b.mean), 0, "means differ");
    assert_eq!(
        differing_bits(&a.var_of_mean, &b.var_of_mean),
        0,
        "variances differ"
    );
    // Every camera ray ends on the sky or the lit floor: no value is 0
    let lit = a.mean.iter().filter(|&&v| v > 0.0).count();
    assert_eq!(lit, a.mean.len(), "unlit values");
    // A different seed changes the image, so equality above is not vacuous
    let mut reseeded = built.clone();
    reseeded.render.seed = 1;
    let c = render(&ctx, &reseeded, &options(1 << 12));
    // Pixels whose every path ends in the sky (the sky itself, and the glass
    // sphere where both reflection and refraction reach it before any
    // roulette) are 0.25 under every seed: about half the values. Of the
    // rest, nearly all change (5,337 of 12,288 values at rr_depth 5).
    let changed = differing_bits(&a.mean, &c.mean);
    assert!(changed > a.mean.len() / 3, "{changed} values changed");
}

/// `lancer --version` gives the package version and the commit that
/// `git rev-parse` names for this checkout (or `unknown commit` outside one).
#[test]
fn version_names_the_version_and_the_commit() {
    let o = lancer(&["--version"], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let head = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    let commit = match head {
        Some(hash) => format!("commit {hash}"),
        None => String::from("unknown commit"),
    };
    let expected = format!("lancer {} ({commit})", env!("CARGO_PKG_VERSION"));
    assert_eq!(stdout.trim(), expected);
    assert_eq!(lancer::VERSION, &expected["lancer ".len()..]);
}
