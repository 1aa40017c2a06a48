//! Helpers shared by the GPU tests. Every GPU test needs a Vulkan device:
//! when none is found the test fails with the install hint, never skips.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use lancer::render::{RenderOptions, RenderOutput, Renderer};
use lancer::scene::Scene;
use lancer::vk::{Context, ContextOptions};

/// Path of a file under the crate root.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// Opens the default device (lavapipe in CI), under validation when
/// LANCER_VALIDATION=1. Fails the test when there is no device.
pub fn context() -> Context {
    match Context::new(&ContextOptions {
        device: std::env::var("LANCER_DEVICE").ok(),
        validation: false,
    }) {
        Ok(ctx) => ctx,
        Err(e) => panic!("GPU tests need a Vulkan device: {e}"),
    }
}

/// Loads a scene from the repo, with every effect allowed.
pub fn load(path: &str) -> Scene {
    lancer::scene::load_with(&repo(path), &lancer::scene::Supported::ALL)
        .unwrap_or_else(|e| panic!("loading {path}: {e}"))
}

/// Renders `scene` and checks the things every render must satisfy: no
/// NaN or Inf in the output, no non-finite sample dropped, and no
/// validation error.
pub fn render(ctx: &Context, scene: &Scene, options: &RenderOptions) -> RenderOutput {
    let mut renderer = Renderer::new(ctx, scene, options).expect("renderer");
    let out = renderer.render(false).expect("render");
    check_finite(&out);
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
    out
}

/// Asserts that an output holds no NaN or Inf and dropped no sample.
pub fn check_finite(out: &RenderOutput) {
    assert_eq!(
        lancer::compare::count_nonfinite(&out.mean),
        0,
        "non-finite pixels in the mean"
    );
    assert_eq!(
        lancer::compare::count_nonfinite(&out.var_of_mean),
        0,
        "non-finite variances"
    );
    assert_eq!(
        out.stats.nonfinite_samples, 0,
        "samples with NaN or Inf radiance were dropped"
    );
}

/// Default options with a given wave size.
pub fn options(wave_size: u32) -> RenderOptions {
    RenderOptions {
        wave_size,
        ..RenderOptions::default()
    }
}
