//! Renders that stop at a budget instead of a fixed sample count: a time
//! limit (`--time-limit`) or a predicted error (`--target-error`).
//!
//! Both render progressively (see [`Renderer::render_to`]) and always stop
//! at a whole number of samples per pixel.

use anyhow::{ensure, Result};

use crate::render::{OnWave, RenderOutput, Renderer};
use crate::util::metrics::predicted_rel_mse;

/// Fewest samples per pixel before [`render_with_budget`] with
/// [`Budget::Error`] trusts the film's error estimate: below it the two
/// half films rest on too few samples to predict the error.
pub const MIN_SPP_FOR_PREDICTION: u32 = 16;

/// Each step of [`render_to_error`] grows the sample count by at least this
/// factor, so that the film is read back O(log spp) times.
const ERROR_STEP_GROWTH: f64 = 1.25;

/// When to stop a progressive render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Budget {
    /// Render until this many seconds of rendering are spent.
    Time(f64),
    /// Render until the relMSE the film predicts is at most this.
    Error(f64),
}

impl Budget {
    /// Checks the budget's value, with a message that names the setting
    /// (`Budget::Time`, `Budget::Error`).
    pub fn validate(&self) -> Result<()> {
        match *self {
            Budget::Time(s) => ensure!(
                s.is_finite() && s > 0.0,
                "Budget::Time must be a number of seconds above 0, got {s}"
            ),
            Budget::Error(e) => ensure!(
                e.is_finite() && e > 0.0,
                "Budget::Error must be a relMSE above 0 (e.g. 0.01), got {e}"
            ),
        }
        Ok(())
    }
}

/// Renders until `budget` is met or `max_spp` samples per pixel are done,
/// from an empty film, and reads the film back.
pub fn render_with_budget(
    renderer: &mut Renderer,
    budget: Budget,
    max_spp: u32,
    progress: OnWave<'_>,
) -> Result<RenderOutput> {
    budget.validate()?;
    ensure!(
        max_spp >= 1,
        "render_with_budget(max_spp) must be at least 1"
    );
    renderer.restart()?;
    match budget {
        Budget::Time(seconds) => render_for(renderer, seconds, max_spp, progress),
        Budget::Error(target) => render_to_error(renderer, target, max_spp, progress),
    }
}

/// Renders one wave's worth of whole samples at a time while the next step,
/// at the time per sample measured so far, still fits `seconds`. The first
/// step always runs (an image needs one sample), so the render overshoots
/// the budget by at most one step's misestimate; when even one step does
/// not fit, the result says so through its render seconds.
fn render_for(
    renderer: &mut Renderer,
    seconds: f64,
    max_spp: u32,
    progress: OnWave<'_>,
) -> Result<RenderOutput> {
    let step = renderer.spp_per_wave();
    while renderer.spp_done() < max_spp {
        let done = renderer.spp_done();
        let next = done.saturating_add(step).min(max_spp);
        if renderer.seconds_at(next).is_some_and(|t| t > seconds) {
            break;
        }
        renderer.render_to(next, progress)?;
    }
    renderer.output()
}

/// Renders until the relMSE that the film's own error estimate predicts
/// for the image against the truth, mean(error / (mean² + 0.01)) with the
/// two half films' estimate ([`crate::render::film`]), is at most
/// `target`, reading the film back every ~25% more samples and never before
/// [`MIN_SPP_FOR_PREDICTION`] samples.
fn render_to_error(
    renderer: &mut Renderer,
    target: f64,
    max_spp: u32,
    progress: OnWave<'_>,
) -> Result<RenderOutput> {
    let mut next = MIN_SPP_FOR_PREDICTION.min(max_spp);
    loop {
        renderer.render_to(next, progress)?;
        let out = renderer.output()?;
        let done = renderer.spp_done();
        if done >= max_spp || predicted_rel_mse(&out.error_estimate, &out.mean) <= target {
            return Ok(out);
        }
        // Not rounded up to whole waves: on a small image one wave holds
        // hundreds of samples per pixel, and the render would stop far
        // below the target
        let grown = (done as f64 * ERROR_STEP_GROWTH).ceil() as u32;
        next = grown.max(done.saturating_add(1)).min(max_spp);
    }
}
