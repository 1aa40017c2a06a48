//! Large geometry. A floor quad 1e10 across, a huge emitting
//! quad and a ground sphere of radius 1e7 and more each render their
//! analytic value, up to the documented
//! limits (`docs/scene-format.md`, "Coordinates"), and a scene beyond them is
//! refused when it is read.

use crate::common;

use common::{context, load_inline, options, render, scene_header};
use lancer::render::RenderOutput;

/// A scene with a 32 x 32 camera 45 degrees down from `eye_y` above the
/// origin, a white environment of radiance `env`, and the given objects and
/// extra materials (`white` is lambert, albedo 0.5).
fn scene_text(eye_y: f64, env: f64, max_depth: u32, objects: &str) -> String {
    let camera = format!(
        "eye = [0.0, {eye_y:e}, 0.0]\nlook_at = [0.0, 0.0, {:e}]\nvfov = 40",
        -eye_y
    );
    let radiance = format!("[{env}, {env}, {env}]");
    scene_header((32, 32), 16, max_depth, &camera, &radiance)
        + "[materials.white]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
           [materials.lamp]\ntype = \"lambert\"\nalbedo = [0, 0, 0]\nemission = [2, 2, 2]\n"
        + objects
}

/// A square quad of half-size `half` at height `y`, facing +y (or -y).
fn quad(half: f64, y: f64, up: bool, material: &str) -> String {
    let v = if up { -2.0 * half } else { 2.0 * half };
    let z0 = if up { half } else { -half };
    format!(
        "[[objects]]\ntype = \"quad\"\norigin = [{:e}, {y:e}, {z0:e}]\n\
         edge_u = [{:e}, 0.0, 0.0]\nedge_v = [0.0, 0.0, {v:e}]\nmaterial = \"{material}\"\n",
        -half,
        2.0 * half
    )
}

fn render_text(text: &str) -> RenderOutput {
    let scene = load_inline(text).unwrap_or_else(|e| panic!("{e}"));
    render(&context(), &scene, &options(1 << 14))
}

/// Largest |pixel - expected| over the image, all channels.
fn worst_error(out: &RenderOutput, expected: f32) -> f32 {
    out.mean
        .iter()
        .map(|&x| (x - expected).abs())
        .fold(0.0, f32::max)
}

/// A lambert floor (albedo 0.5) under a white sky of radiance 1: a plane is
/// convex, so every camera path hits the floor once and escapes, and every
/// pixel is exactly 0.5. A floor 1e10 across rendered black (the triangle's
/// normal overflowed in normalize, and the watertight test's t cancelled to
/// noise for rays whose dominant axis pointed at the far vertices); up to
/// the coordinate limit of 1e11 it now renders the exact value.
#[test]
fn huge_floor_quad_renders_its_exact_radiance() {
    for half in [1e3, 1e9, 1e10, 1e11] {
        let out = render_text(&scene_text(1.0, 1.0, 3, &quad(half, 0.0, true, "white")));
        let worst = worst_error(&out, 0.5);
        println!("floor of half-size {half:e}: worst pixel error {worst:e}");
        assert!(
            worst < 1e-5,
            "half-size {half:e}: worst pixel error {worst}"
        );
    }
}

/// A floor beyond the coordinate limit is refused when the scene is read,
/// naming the file, the line, the key, the limit and what to change.
#[test]
fn geometry_beyond_the_coordinate_limit_is_refused() {
    let e = load_inline(&scene_text(1.0, 1.0, 3, &quad(1.01e11, 0.0, true, "white"))).unwrap_err();
    assert!(
        e.contains("inline.toml:21: objects[0].origin: the quad reaches [-1.01e11, 0e0, 1.01e11]"),
        "{e}"
    );
    assert!(
        e.contains("lancer renders coordinates up to 1e11") && e.contains("scale the scene down"),
        "{e}"
    );
    let sphere = "[[objects]]\ntype = \"sphere\"\ncenter = [0, -1e11, 0]\nradius = 1e9\n\
                  material = \"white\"\n";
    let e = load_inline(&scene_text(1e7, 1.0, 3, sphere)).unwrap_err();
    assert!(e.contains("objects[0].radius: the sphere reaches"), "{e}");
    let e = load_inline(
        "[render]\nwidth = 8\nheight = 8\nspp = 1\n[camera]\neye = [2e11, 0, 0]\n\
         look_at = [0, 0, 0]\nvfov = 40\n",
    )
    .unwrap_err();
    assert!(
        e.contains("inline.toml:6: camera.eye: the eye with its lens reaches"),
        "{e}"
    );
}

/// A lambert floor (albedo 0.5) under an emitting ceiling (radiance 2,
/// facing down) 1 above it, both squares of half-size 1e10: the ceiling
/// fills the floor's hemisphere (its form factor is 1 - 1e-10), so the floor
/// shows 0.5 x 2 = 1. The huge emitter lit nothing before (its area
/// overflowed to inf on the CPU, and its normal to NaN on the device); next-event
/// estimation now samples it with finite pdfs. The image mean is within
/// 4 sigma of the analytic value at 1024 spp (sigma from the film's own
/// variance; at 64 spp the rare far light samples make it an underestimate),
/// at 1e2 and at 1e10.
#[test]
fn huge_emitting_quad_lights_the_floor() {
    for half in [1e2, 1e10] {
        let objects = format!(
            "{}{}",
            quad(half, 0.0, true, "white"),
            quad(half, 1.0, false, "lamp")
        );
        let mut text = scene_text(0.5, 0.0, 2, &objects);
        text = text.replace("spp = 16", "spp = 1024");
        let out = render_text(&text);
        let n = out.mean.len() as f64;
        let mean = out.mean.iter().map(|&x| x as f64).sum::<f64>() / n;
        let sigma = (out.var_of_mean.iter().map(|&x| x as f64).sum::<f64>()).sqrt() / n;
        // Analytic: albedo x radiance x form factor of the ceiling.
        let a = half / 1.0;
        let form = {
            // Point below the centre of a coaxial square of half-side a at height 1
            // (Howell's catalogue, B-15 for a square made of four rectangles).
            let x = a / (1.0 + a * a).sqrt();
            4.0 / (2.0 * std::f64::consts::PI) * (2.0 * x * x.atan())
        };
        let expected = 0.5 * 2.0 * form;
        let z = (mean - expected) / sigma;
        println!(
            "emitting ceiling of half-size {half:e}: mean {mean:.5}, expected {expected:.5}, \
             sigma {sigma:.2e}, z {z:.2}"
        );
        assert!(sigma < 1e-3, "sigma {sigma}");
        if sigma > 0.0 {
            assert!(z.abs() < 4.0, "half-size {half:e}: z = {z}");
        } else {
            // At 1e10 every light sample lies ~1e10 away and MIS gives the
            // BSDF sample all the weight: every sample is exactly 1.
            assert!(
                (mean - expected).abs() < 1e-5,
                "half-size {half:e}: mean {mean}"
            );
        }
    }
}

/// A lambert ground sphere (albedo 0.5) under a white sky: convex, so every
/// pixel is exactly 0.5. With the eye 1 above a sphere of radius 3e7 (closer
/// than its f32 rounding) the eye landed inside and the image was black:
/// that is now refused. At 2^-15 of |centre| + radius above it, spheres of
/// radius 1e7 to 1e10 render the exact value: the continuation ray from a
/// point near the origin on the sphere is offset by the rounding of the
/// sphere's own coordinates, not of the point's.
#[test]
fn ground_sphere_renders_its_exact_radiance() {
    for radius in [1.0, 1e7, 3e7, 1e9, 5e10] {
        let height = 2.0 * radius / 32768.0;
        let sphere = format!(
            "[[objects]]\ntype = \"sphere\"\ncenter = [0, {:e}, 0]\nradius = {radius:e}\n\
             material = \"white\"\n",
            -radius
        );
        let out = render_text(&scene_text(height, 1.0, 3, &sphere));
        let worst = worst_error(&out, 0.5);
        println!(
            "ground sphere of radius {radius:e}, eye {height:e} above: worst pixel error {worst:e}"
        );
        assert!(worst < 1e-5, "radius {radius:e}: worst pixel error {worst}");
    }
}

/// The eye closer to a sphere's surface than 2^-16 of |centre| + radius is
/// refused, with the figures and what to change.
#[test]
fn eye_within_a_spheres_rounding_is_refused() {
    let sphere = "[[objects]]\ntype = \"sphere\"\ncenter = [0, -3e7, 0]\nradius = 3e7\n\
                  material = \"white\"\n";
    let e = load_inline(&scene_text(1.0, 1.0, 3, sphere)).unwrap_err();
    assert!(
        e.contains("inline.toml:22: objects[0].radius: camera.eye is 1e0 from the surface"),
        "{e}"
    );
    assert!(
        e.contains("must be at least 9.1552734375e2") && e.contains("move the eye away"),
        "{e}"
    );
    // Just outside the clearance it loads.
    load_inline(&scene_text(916.0, 1.0, 3, sphere)).unwrap();
}
