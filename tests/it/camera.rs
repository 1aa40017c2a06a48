//! The camera's clip planes and pixel filters on the device: near and far
//! planes measured along the optical axis, cutting objects away and
//! hiding walls with exact pixel values; pixel filters that keep every
//! pixel finite and the film an exact sum (split renders add up bit for
//! bit), and a box filter that is today's code path. (The filters' z-tests
//! against Mitsuba are in tests/it/reference.rs, their sampling tables'
//! tests in src/scene/filter.rs.)

use crate::common;

use common::*;
use lancer::render::Renderer;
use lancer::scene::{PixelFilter, Scene};

/// A black sphere of radius 0.5 two units in front of the eye, a wall
/// that emits 1 ten units away (filling the view), and an environment of
/// 0.25; the camera looks along -z with a 90 degree field of view, and
/// `clip` adds `near_clip`/`far_clip` lines to `[camera]`.
fn clip_scene(clip: &str) -> Scene {
    let camera = format!("eye = [0, 0, 0]\nlook_at = [0, 0, -1]\nvfov = 90\n{clip}");
    let text = scene_header((16, 16), 4, 2, camera.trim_end(), "[0.25, 0.25, 0.25]")
        + r#"
[materials.black]
type = "lambert"
albedo = [0, 0, 0]
[materials.wall]
type = "lambert"
albedo = [0, 0, 0]
emission = [1, 1, 1]
[[objects]]
type = "sphere"
center = [0, 0, -2]
radius = 0.5
material = "black"
[[objects]]
type = "quad"
origin = [-100, -100, -10]
edge_u = [200, 0, 0]
edge_v = [0, 200, 0]
material = "wall"
"#;
    load_inline(&text).unwrap_or_else(|e| panic!("{e}"))
}

/// The red channel of pixel (x, y).
fn pixel(out: &lancer::render::RenderOutput, x: u32, y: u32) -> f32 {
    out.mean[3 * (y * out.width + x) as usize]
}

/// Every pixel's red channel.
fn reds(out: &lancer::render::RenderOutput) -> Vec<f32> {
    out.mean.chunks(3).map(|p| p[0]).collect()
}

#[test]
fn clip_planes_cut_objects_and_hide_walls_along_the_optical_axis() {
    let ctx = context();
    let opts = options(1 << 12);
    // No clip planes: the sphere is black in the middle, the wall emits 1
    // in the corners.
    let plain = render(&ctx, &clip_scene(""), &opts);
    assert_eq!(pixel(&plain, 8, 8), 0.0);
    assert_eq!(pixel(&plain, 0, 0), 1.0);

    // A near plane 3 units out cuts the sphere away: every pixel sees the wall
    let near = render(&ctx, &clip_scene("near_clip = 3"), &opts);
    assert!(
        reds(&near).iter().all(|&v| v == 1.0),
        "near plane: {:?}",
        reds(&near)
    );

    // A far plane before the wall hides it: the rays end and see the
    // environment, everywhere but where the sphere is
    let far = render(&ctx, &clip_scene("near_clip = 3\nfar_clip = 9.8"), &opts);
    assert!(
        reds(&far).iter().all(|&v| v == 0.25),
        "far plane: {:?}",
        reds(&far)
    );
    let far_only = render(&ctx, &clip_scene("far_clip = 9.8"), &opts);
    assert_eq!(pixel(&far_only, 8, 8), 0.0);
    assert_eq!(pixel(&far_only, 0, 0), 0.25);

    // The planes are distances along the optical axis, not along each ray:
    // a far plane just past the wall keeps it in the corners, where the
    // rays reach it after about 17 units
    let past = render(&ctx, &clip_scene("near_clip = 3\nfar_clip = 10.2"), &opts);
    assert!(
        reds(&past).iter().all(|&v| v == 1.0),
        "far plane past the wall: {:?}",
        reds(&past)
    );

    // A near plane that would hide nothing leaves the image as it was, up
    // to the rounding of the moved ray origins
    let tiny = render(
        &ctx,
        &clip_scene("near_clip = 0.01\nfar_clip = 10000"),
        &opts,
    );
    let differ = reds(&tiny)
        .iter()
        .zip(reds(&plain))
        .filter(|(a, b)| (*a - b).abs() > 1e-6)
        .count();
    assert!(
        differ <= 2,
        "{differ} pixels moved under a near plane of 0.01"
    );
}

/// The Cornell box with `filter`, 32 x 32 at 16 spp.
fn cornell_with(filter: PixelFilter) -> Scene {
    let mut scene = load("scenes/cornell.toml");
    (scene.render.width, scene.render.height, scene.render.spp) = (32, 32, 16);
    scene.render.filter = filter;
    scene
}

/// The film's sums of samples `first..end` under `scene`.
fn sums(ctx: &lancer::Context, scene: &Scene, first: u32, end: u32) -> (Vec<f64>, Vec<f64>) {
    let mut r = Renderer::new(ctx, scene, &options(1 << 12)).expect("renderer");
    r.render_samples(first, end, None).expect("render");
    let (film, nonfinite) = r.film_sums().expect("film");
    assert_eq!(nonfinite, 0, "non-finite samples");
    (film.sum, film.sum_sq)
}

#[test]
fn every_filter_keeps_pixels_finite_and_the_film_a_sum_of_its_parts() {
    let ctx = context();
    for filter in [
        PixelFilter::Tent { radius: 1.0 },
        PixelFilter::MITSUBA_DEFAULT,
        PixelFilter::MITCHELL,
        PixelFilter::CATMULL_ROM,
        PixelFilter::Lanczos { lobes: 3 },
    ] {
        let scene = cornell_with(filter);
        // No NaN or infinite pixel (the z-tests against Mitsuba check the
        // values: tests/it/reference.rs)
        render(&ctx, &scene, &options(1 << 12));
        // Samples 0..7 and 7..16 add up to the film of 0..16: each sample
        // counts in its own pixel only, with its weight in its radiance
        let (all, all_sq) = sums(&ctx, &scene, 0, 16);
        let (p, p_sq) = sums(&ctx, &scene, 0, 7);
        let (q, q_sq) = sums(&ctx, &scene, 7, 16);
        for (whole, (x, y)) in all
            .iter()
            .chain(&all_sq)
            .zip(p.iter().chain(&p_sq).zip(q.iter().chain(&q_sq)))
        {
            assert!(
                (x + y - whole).abs() <= 1e-9 * whole.abs().max(1e-6),
                "{filter:?}: parts {x} + {y} against the whole {whole}"
            );
        }
    }
}

#[test]
fn the_box_filter_is_the_default_and_its_code_is_compiled_out() {
    let scene = load("scenes/cornell.toml");
    assert_eq!(scene.render.filter, PixelFilter::Box);
    let f =
        lancer::render::kernels::Features::detect(&scene, lancer::render::kernels::Integrator::Nee);
    assert!(!f.pixel_filter && !f.clip, "{f:?}");
    let filtered = cornell_with(PixelFilter::MITCHELL);
    let f = lancer::render::kernels::Features::detect(
        &filtered,
        lancer::render::kernels::Integrator::Nee,
    );
    assert!(f.pixel_filter && !f.clip, "{f:?}");
}
