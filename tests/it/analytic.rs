//! Renders whose right answer is known exactly.

use crate::common;

use common::*;
use lancer::render::kernels::Sampler;

/// A Lambertian sphere of albedo 1 under uniform radiance 1 gives every
/// pixel exactly 1: the white furnace test. No material gains or loses
/// energy, and nothing is lost at the silhouette. Under every sampler.
#[test]
fn white_furnace_lambert_sphere_gives_one() {
    let ctx = context();
    let scene = load("tests/scenes/furnace.toml");
    for sampler in Sampler::ALL {
        let opts = lancer::render::RenderOptions {
            sampler,
            ..options(1 << 14)
        };
        let out = render(&ctx, &scene, &opts);
        let worst = out
            .mean
            .iter()
            .map(|v| (v - 1.0).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst < 1e-5,
            "{sampler}: furthest pixel from 1 is off by {worst}"
        );
    }
}

/// Summing 65,536 samples of 0.1 (not representable in binary) per pixel
/// keeps the mean exact to float precision, in one wave and across many.
#[test]
fn film_stays_accurate_over_65536_spp() {
    let ctx = context();
    let scene = load("tests/scenes/empty_env.toml");
    let expect = [0.1f32, 0.3, 0.7];
    for (wave_size, f32_film) in [
        (1 << 18, false),
        (1 << 11, false),
        (1 << 18, true),
        (1 << 11, true),
    ] {
        let opts = lancer::render::RenderOptions {
            f32_film,
            ..options(wave_size)
        };
        let out = render(&ctx, &scene, &opts);
        assert_eq!(out.spp, 65536);
        for (i, v) in out.mean.iter().enumerate() {
            let e = expect[i % 3];
            let rel = ((v - e) / e).abs();
            assert!(rel <= 1.2e-7, "wave {wave_size}, f32 film {f32_film}: pixel channel {i} = {v}, expected {e} (rel err {rel:e})");
        }
        // A plain f32 running sum drifts far past that: show the test can fail.
        let naive = (0..65536).fold(0f32, |s, _| s + 0.1f32) / 65536.0;
        assert!(
            ((naive - 0.1) / 0.1).abs() > 1e-5,
            "the naive sum should drift: {naive}"
        );
    }
}

/// The same scene, seed and spp give a bit-identical image.
#[test]
fn repeated_renders_are_bit_identical() {
    let ctx = context();
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 32;
    scene.render.height = 32;
    scene.render.spp = 4;
    let a = render(&ctx, &scene, &options(1 << 12));
    let b = render(&ctx, &scene, &options(1 << 12));
    let differing = differing_bits(&a.mean, &b.mean);
    assert_eq!(
        differing, 0,
        "{differing} channels differ between two identical renders"
    );
    // A different seed must change the image, or the check above means nothing.
    scene.render.seed = 1;
    let c = render(&ctx, &scene, &options(1 << 12));
    assert!(a.mean.iter().zip(&c.mean).any(|(x, y)| x != y));
}

/// A 1920x1080 render at 4 spp fits the device's limits (lavapipe: 128 MiB
/// per binding): buffers are sized by the wave, not by the image.
#[test]
fn full_hd_render_at_4_spp_fits_the_device() {
    let ctx = context();
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 1920;
    scene.render.height = 1080;
    scene.render.spp = 4;
    scene.render.max_depth = 2;
    let out = render(&ctx, &scene, &options(lancer::render::CPU_WAVE_SIZE));
    assert_eq!(out.mean.len(), 1920 * 1080 * 3);
    assert!(out.stats.waves > 1, "the image must take several waves");
    let lit = out
        .mean
        .chunks(3)
        .filter(|p| p[0] + p[1] + p[2] > 0.0)
        .count();
    // At 16:9 the box fills the middle of the frame; the sides see the void.
    assert!(lit > 1920 * 1080 / 4, "only {lit} pixels lit");
}

/// Self-intersection at any scale: in a white furnace with max_depth 2, a
/// camera ray hits the sphere and its bounce must escape, giving exactly 1.
/// A bounce that hits its own surface again uses up the last segment and
/// the pixel loses energy. The scene is scaled from 1e-4 to 1e4 and moved
/// far from the origin, where float spacing is coarse.
#[test]
fn no_self_intersection_at_extreme_scales() {
    let ctx = context();
    let base = load("tests/scenes/furnace.toml");
    for (scale, offset) in [
        (1e-4f32, 0.0f32),
        (1.0, 0.0),
        (1e4, 0.0),
        (1.0, 1e4),
        (1e-2, 1e3),
    ] {
        let mut scene = base.clone();
        scene.render.max_depth = 2;
        scene.render.spp = 16;
        let shift = glam::Vec3::splat(offset);
        let place = |p: glam::Vec3| p * scale + shift;
        scene.camera.eye = place(scene.camera.eye);
        scene.camera.look_at = place(scene.camera.look_at);
        scene.camera.focus_distance *= scale;
        for s in &mut scene.spheres {
            s.center = place(s.center);
            s.radius *= scale;
        }
        let out = render(&ctx, &scene, &options(1 << 16));
        let lost = out.mean.iter().filter(|&&v| (v - 1.0).abs() > 1e-5).count();
        let worst = out
            .mean
            .iter()
            .map(|v| (v - 1.0).abs())
            .fold(0.0f32, f32::max);
        println!("scale {scale:e}, offset {offset:e}: {lost} channels off 1, worst {worst:e}");
        assert_eq!(
            lost, 0,
            "scale {scale:e}, offset {offset:e}: self-intersections cost energy (worst {worst:e})"
        );
    }
}

/// `max_depth = 1,000,000` (valid per the format) renders, records only the
/// bounces paths reach, and gives the same image, bit for bit, as a depth
/// no path reaches (Russian roulette ends every path long before).
#[test]
fn huge_max_depth_costs_only_the_bounces_paths_reach() {
    let ctx = context();
    let mut scene = load("tests/scenes/furnace.toml");
    scene.render.max_depth = 1_000_000;
    let deep = render(&ctx, &scene, &options(1 << 14));
    scene.render.max_depth = 2000;
    let shallow = render(&ctx, &scene, &options(1 << 14));
    let differing = differing_bits(&deep.mean, &shallow.mean);
    assert_eq!(differing, 0, "{differing} channels differ");
    let deepest = deep
        .stats
        .records
        .iter()
        .filter_map(|r| r.bounce)
        .max()
        .unwrap();
    let per_wave = lancer::render::BOUNCES_PER_SUBMIT;
    println!("deepest bounce recorded: {deepest}");
    assert!(deepest < 1000, "bounce {deepest} was recorded");
    assert_eq!(
        (deepest + 1) % per_wave,
        0,
        "bounces stop at a command buffer's end"
    );
}

/// Float textures (EXR, HDR) hold linear values and are read as 32-bit
/// floats: a sphere whose albedo texture is (0.5, 0.25, 0.75) everywhere,
/// in the white furnace, is exactly that colour wherever it covers a
/// pixel (one bounce off a convex sphere), where reading the file as 8-bit
/// sRGB would give (0.214, 0.051, 0.522).
#[test]
fn float_textures_are_read_as_linear_floats() {
    let dir = scratch("float_textures");
    let albedo = [0.5f32, 0.25, 0.75];
    let ctx = context();
    for ext in ["exr", "hdr"] {
        let file = dir.join(format!("albedo.{ext}"));
        let img = image::Rgb32FImage::from_pixel(8, 4, image::Rgb(albedo));
        image::DynamicImage::ImageRgb32F(img)
            .save(&file)
            .expect("write float texture");
        let decoded = lancer::internal::gpu::load_texture(&file, false).unwrap();
        assert!(
            matches!(decoded, lancer::internal::gpu::TextureImage::Linear(_)),
            "{ext}: {decoded:?}"
        );
        let text = std::fs::read_to_string(repo("tests/scenes/furnace.toml"))
            .unwrap()
            .replace(
                "albedo = [1.0, 1.0, 1.0]",
                &format!("albedo_texture = {:?}", file.display().to_string()),
            )
            .replace("width = 64", "width = 16")
            .replace("height = 64", "height = 16");
        let scene = load_inline(&text).unwrap_or_else(|e| panic!("{ext}: {e}"));
        let out = render(&ctx, &scene, &options(1 << 12));
        // The middle pixel sees the sphere face on
        let mid = 3 * (8 * 16 + 8);
        for (c, (&v, &a)) in out.mean[mid..mid + 3].iter().zip(&albedo).enumerate() {
            assert!(
                (v - a).abs() < 1e-5,
                "{ext}: channel {c} is {v}, the texture holds {a}"
            );
        }
    }
}

/// A point light and a spot light (Mitsuba's falloff: full within the beam
/// width, linear in angle to zero at the cutoff) over a Lambertian plane,
/// seen straight down: each pixel is the exact irradiance I cos / d²
/// (times the spot's falloff) times albedo / pi, averaged over the pixel
/// (a 32 x 32 midpoint rule). The plane sees nothing else, so there is no
/// indirect light; only the pixel jitter is random, stratified 32 x 32.
#[test]
fn delta_lights_over_a_lambert_plane_give_the_exact_radiance() {
    let header = "[render]\nwidth = 32\nheight = 32\nspp = 1024\nmax_depth = 4\n\
                  [camera]\neye = [0, 3, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\nvfov = 60\n\
                  [materials.floor]\ntype = \"lambert\"\nalbedo = [0.5, 0.6, 0.7]\n\
                  [[objects]]\ntype = \"quad\"\norigin = [-10, 0, -10]\nedge_u = [20, 0, 0]\n\
                  edge_v = [0, 0, 20]\nmaterial = \"floor\"\n";
    let albedo = [0.5, 0.6, 0.7];
    // (TOML light, position, intensity, falloff of the angle from straight down)
    let point = |_: f64| 1.0;
    let spot = |theta: f64| {
        let (cutoff, beam) = (40f64.to_radians(), 15f64.to_radians());
        if theta <= beam {
            1.0
        } else if theta < cutoff {
            (cutoff - theta) / (cutoff - beam)
        } else {
            0.0
        }
    };
    type Falloff<'a> = &'a dyn Fn(f64) -> f64;
    let cases: [(&str, [f64; 3], [f64; 3], Falloff); 2] = [
        (
            "type = \"point\"\nposition = [0.3, 1.0, -0.2]\nintensity = [2, 3, 4]",
            [0.3, 1.0, -0.2],
            [2.0, 3.0, 4.0],
            &point,
        ),
        (
            "type = \"spot\"\nposition = [0.2, 1.2, 0.1]\ndirection = [0, -1, 0]\n\
             intensity = [5, 4, 3]\ncutoff_angle = 40\nbeam_width = 15",
            [0.2, 1.2, 0.1],
            [5.0, 4.0, 3.0],
            &spot,
        ),
    ];
    let ctx = context();
    for (light, pos, intensity, falloff) in cases {
        let scene = load_inline(&format!("{header}[[lights]]\n{light}\n")).unwrap();
        let out = render(&ctx, &scene, &options(1 << 16));
        // Pixel (x, y) sees the plane point (3 t ndc_x, 0, -3 t ndc_y).
        let t = 30f64.to_radians().tan();
        let radiance = |px: f64, py: f64, c: usize| {
            let (ndc_x, ndc_y) = (2.0 * px / 32.0 - 1.0, 1.0 - 2.0 * py / 32.0);
            let p = [3.0 * t * ndc_x, 0.0, -3.0 * t * ndc_y];
            let d = [pos[0] - p[0], pos[1] - p[1], pos[2] - p[2]];
            let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let cos = pos[1] / d2.sqrt();
            albedo[c] / std::f64::consts::PI * intensity[c] * falloff(cos.acos()) * cos / d2
        };
        let exact: Vec<f64> = (0..32 * 32 * 3)
            .map(|i| {
                let (x, y, c) = ((i / 3) % 32, i / 96, i % 3);
                (0..1024)
                    .map(|k| {
                        let (sx, sy) = ((k % 32) as f64 + 0.5, (k / 32) as f64 + 0.5);
                        radiance(x as f64 + sx / 32.0, y as f64 + sy / 32.0, c) / 1024.0
                    })
                    .sum()
            })
            .collect();
        // Relative error, with a floor of 1% of the brightest pixel where the
        // falloff reaches zero (the jitter's error stays absolute there)
        let floor = 0.01 * exact.iter().copied().fold(0.0, f64::max);
        let worst = exact
            .iter()
            .zip(&out.mean)
            .map(|(&e, &got)| (got as f64 - e).abs() / (e + floor))
            .fold(0.0, f64::max);
        println!("{light}: worst relative error {worst:.2e}");
        assert!(
            worst < 3e-3,
            "{light}: a pixel is off by {worst:.2e} (relative)"
        );
    }
}

/// The white furnace under an environment map whose every texel is
/// (0.75, 0.5, 0.25), read from EXR and from HDR (RGBE holds these values
/// exactly), turned by an oblique rotation: a Lambertian sphere of albedo
/// 1 is the map's radiance wherever it covers a pixel. With BSDF sampling
/// alone every sample is that radiance (one bounce off a convex sphere,
/// then the map), to f32 rounding. With next-event estimation each sample
/// is a MIS-weighted sum of a light sample and a BSDF sample, exact only
/// in expectation: each pixel, and the image's mean, must lie within its
/// estimated error of the radiance. Counting the light twice (MIS weights
/// of 1) would make the sphere up to twice as bright.
#[test]
fn white_furnace_under_a_constant_environment_map() {
    let dir = scratch("furnace_envmap");
    let radiance = [0.75f32, 0.5, 0.25];
    let ctx = context();
    for ext in ["exr", "hdr"] {
        let file = dir.join(format!("constant.{ext}"));
        let img = image::Rgb32FImage::from_pixel(16, 8, image::Rgb(radiance));
        image::DynamicImage::ImageRgb32F(img)
            .save(&file)
            .expect("write the environment map");
        let mut scene = load("tests/scenes/furnace.toml");
        scene.environment = glam::Vec3::ZERO;
        scene.render.spp = 256;
        let to_world =
            glam::Mat3::from_axis_angle(glam::Vec3::new(0.3, 1.0, -0.4).normalize(), 1.1);
        scene.envmap = Some(lancer::scene::EnvMap {
            file,
            scale: 1.0,
            to_local: to_world.transpose(),
        });
        let bsdf = lancer::render::RenderOptions {
            integrator: lancer::render::kernels::Integrator::Bsdf,
            ..options(1 << 16)
        };
        let out = render(&ctx, &scene, &bsdf);
        let worst = (out.mean.iter().enumerate())
            .map(|(i, v)| (v - radiance[i % 3]).abs() / radiance[i % 3])
            .fold(0.0f32, f32::max);
        println!("{ext}, BSDF sampling: furthest pixel off by {worst:e} (relative)");
        assert!(
            worst < 1e-5,
            "{ext}, BSDF sampling: a pixel is off by {worst} (relative)"
        );

        let out = render(&ctx, &scene, &options(1 << 16));
        let mut beyond = 0;
        let mut sums = [0.0f64; 3];
        let mut vars = [0.0f64; 3];
        for (i, (&v, &var)) in out.mean.iter().zip(&out.var_of_mean).enumerate() {
            let c = i % 3;
            let d = f64::from(v - radiance[c]);
            sums[c] += d;
            vars[c] += f64::from(var);
            if d * d > 25.0 * f64::from(var).max(1e-14) {
                beyond += 1;
            }
        }
        let pixels = (out.mean.len() / 3) as f64;
        for c in 0..3 {
            let (bias, sigma) = (sums[c] / pixels, vars[c].sqrt() / pixels);
            println!(
                "{ext}, NEE: channel {c}: mean off by {bias:e} ({:.2} sigma; sigma {sigma:e})",
                bias / sigma
            );
            assert!(
                bias.abs() < 4.0 * sigma,
                "{ext}, NEE: channel {c}'s mean is off by {bias:e}, {:.1} times its error {sigma:e}",
                bias / sigma
            );
        }
        println!("{ext}, NEE: {beyond} pixel channels beyond 5 sigma");
        assert!(
            beyond <= 2,
            "{ext}, NEE: {beyond} pixel channels lie beyond 5 sigma of the radiance"
        );
    }
}

/// Light selection: by power (the default) or uniform (the pick
/// probabilities are checked in `gpu::pack`'s unit tests) changes the noise,
/// never the expected image: the delta-light scene's two renders agree
/// within their noise (a z-test of the image means, per channel).
#[test]
fn light_selection_by_power_or_uniform_changes_the_noise_not_the_image() {
    use lancer::render::LightSelection;
    let mut scene = load("tests/scenes/delta_lights.toml");
    scene.render.width = 32;
    scene.render.height = 32;
    scene.render.spp = 256;
    let ctx = context();
    let means = |selection| {
        let out = render(
            &ctx,
            &scene,
            &lancer::render::RenderOptions {
                light_selection: selection,
                ..options(1 << 16)
            },
        );
        check_finite(&out);
        // Per channel: the image mean and the variance of that mean
        let px = out.mean.len() / 3;
        let mut m = [0.0f64; 3];
        let mut v = [0.0f64; 3];
        for i in 0..px {
            for c in 0..3 {
                m[c] += out.mean[3 * i + c] as f64 / px as f64;
                v[c] += out.var_of_mean[3 * i + c] as f64 / (px * px) as f64;
            }
        }
        (m, v)
    };
    let (ma, va) = means(LightSelection::Power);
    let (mb, vb) = means(LightSelection::Uniform);
    for c in 0..3 {
        let z = (ma[c] - mb[c]) / (va[c] + vb[c]).sqrt();
        println!(
            "channel {c}: power {:.6} uniform {:.6} z {z:.2}",
            ma[c], mb[c]
        );
        assert!(
            z.abs() < 4.0,
            "channel {c}: the two rules disagree, z = {z:.2}"
        );
    }
}

/// A light sample is one stratified pair: its first number picks the
/// emitter and is reused, rescaled, for the point on it (as Mitsuba's
/// `sample_reuse`). So the cell centres of a 64 x 64 grid, drawn through
/// the shade kernel's `sample_light` towards a 0.5 x 0.5 quad light (two
/// triangles), estimate the irradiance it gives three points (normal +y)
/// to within a few 1e-4 of the exact value (a 2000 x 2000 midpoint sum in
/// f64). Picking the triangle with a number of its own, as lancer once
/// did, splits the grid between the triangles at random: its rms error at
/// these points is 4e-3, 7e-3 and 1.2e-2, which these bounds catch at
/// least 99% of the time.
#[test]
fn a_stratified_grid_of_light_samples_gives_the_exact_irradiance_of_a_quad() {
    let scene = load_inline(
        "[render]\nwidth = 8\nheight = 8\nspp = 1\nmax_depth = 2\n\
         [camera]\neye = [0, 1, 3]\nlook_at = [0, 1, 0]\nup = [0, 1, 0]\nvfov = 60\n\
         [materials.lamp]\ntype = \"lambert\"\nalbedo = [0, 0, 0]\nemission = [1, 1, 1]\n\
         [[objects]]\ntype = \"quad\"\norigin = [-0.25, 1.98, -0.25]\nedge_u = [0.5, 0, 0]\n\
         edge_v = [0, 0, 0.5]\nmaterial = \"lamp\"\n",
    )
    .unwrap();
    let ctx = context();
    let mut renderer =
        lancer::render::Renderer::new(&ctx, &scene, &options(1 << 16)).expect("renderer");
    let n = 64;
    let grid: Vec<glam::Vec2> = (0..n * n)
        .map(|i| {
            glam::Vec2::new(
                ((i % n) as f32 + 0.5) / n as f32,
                ((i / n) as f32 + 0.5) / n as f32,
            )
        })
        .collect();
    // (point, largest relative error allowed)
    for (from, bound) in [
        ([0.9, 1.0, -0.8], 1e-3),
        ([0.5, 1.5, 0.5], 3e-3),
        ([0.3, 1.7, 0.0], 2e-3),
    ] {
        // Exact: the integral of cos at the point times cos at the light over r^2
        let m = 2000;
        let mut exact = 0.0;
        for j in 0..m {
            for i in 0..m {
                let q = [
                    -0.25 + 0.5 * (i as f64 + 0.5) / m as f64,
                    1.98,
                    -0.25 + 0.5 * (j as f64 + 0.5) / m as f64,
                ];
                let d = [q[0] - from[0], q[1] - from[1], q[2] - from[2]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                exact += d[1] * d[1] / (r2 * r2);
            }
        }
        exact *= 0.25 / (m * m) as f64;
        let samples = renderer
            .sample_lights(glam::Vec3::from_array(from.map(|x| x as f32)), &grid)
            .expect("sampling on the device");
        let estimate = samples
            .iter()
            .filter(|s| s.ok)
            .map(|s| s.le.x as f64 * s.wi.y.max(0.0) as f64 / s.pdf as f64)
            .sum::<f64>()
            / samples.len() as f64;
        let error = estimate / exact - 1.0;
        println!(
            "from {from:?}: exact {exact:.6e}, estimate {estimate:.6e}, relative error {error:.2e}"
        );
        assert!(
            error.abs() < bound,
            "from {from:?}: the grid's estimate is off by {error:.2e} (bound {bound:.0e})"
        );
    }
}
