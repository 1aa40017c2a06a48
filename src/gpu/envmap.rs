//! The environment map for the device: its texels, and the 2D
//! piecewise-constant distribution by which next-event estimation samples
//! directions from it.
//!
//! The map is read as Mitsuba 3's `envmap` reads it (see
//! [`EnvMap`](crate::scene::EnvMap)): the radiance is bilinear between
//! texel centres at `u = (i + 1/2) / W` and `v = j / (H - 1)`. The sampling
//! grid has one cell per such bilinear patch: `W` columns (the last wraps
//! from texel `W - 1` to texel 0) by `H - 1` rows. A cell's weight is the
//! mean luminance of its four corner texels times the mean of sin(theta)
//! over its row, an estimate of its share of the power; a cell whose
//! radiance is anywhere above zero has a corner above zero, so every
//! direction with radiance can be sampled. Inside a cell, (u, v) is
//! uniform; the solid-angle density of a direction is then the cell's
//! density in (u, v) over `2 pi^2 sin(theta)`.

use glam::UVec4;

use super::structs::GpuEnvmap;
use super::textures::{load_texture, TextureImage};
use crate::interface::ENVMAP_HEADER_WORDS;
use crate::scene::EnvMap;

/// The environment map's buffer, and what light selection needs of it.
#[derive(Debug, Clone)]
pub struct GpuEnvironment {
    /// The header ([`GpuEnvmap`]; zero when the scene has no map), texels,
    /// marginal CDF, conditional CDFs and cell densities, as words.
    pub words: Vec<u32>,
    /// The integral of the map's luminance over all directions, estimated
    /// from the cell weights; 0 without a map.
    pub luminance_integral: f64,
    /// The largest radiance component of any texel (scale applied).
    pub max_radiance: f32,
}

/// Rec. 709 luminance, as the emitters are weighed.
fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The sRGB transfer function, inverted: encoded [0, 1] to linear.
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl GpuEnvironment {
    /// The buffer of a scene without an environment map: a zero header,
    /// which the kernels read as "no map".
    pub fn none() -> GpuEnvironment {
        GpuEnvironment {
            words: vec![0; ENVMAP_HEADER_WORDS as usize],
            luminance_integral: 0.0,
            max_radiance: 0.0,
        }
    }

    /// The map's weight in the emitter table, in the unit the other
    /// emitters are weighed in (power over pi): `r^2` times the integral
    /// of its luminance over all directions, `r` the radius of the scene's
    /// bounding sphere. That is what a directional light of irradiance `E`
    /// gets (`E r^2`): the map is a directional light from every direction
    /// `w` with irradiance `L(w) dw`. (pbrt weighs its infinite lights
    /// likewise.)
    pub fn power(&self, scene_radius: f32) -> f32 {
        (f64::from(scene_radius).powi(2) * self.luminance_integral) as f32
    }

    /// Loads `env`'s image, checks it and lays out its buffer, in at most
    /// `max_bytes` bytes (one device binding). `pmf` is filled in later by
    /// [`GpuEnvironment::set_pick_probability`].
    pub fn pack(env: &EnvMap, max_bytes: u64) -> anyhow::Result<GpuEnvironment> {
        let path = crate::util::text::cut_path(&env.file);
        let img = load_texture(&env.file, false)?;
        let (w, h) = img.dimensions();
        anyhow::ensure!(
            w >= 2 && h >= 3,
            "environment map {path} is {w} x {h} pixels; it must be at least 2 x 3 (Mitsuba \
             refuses smaller ones too)"
        );
        let (wu, hu) = (w as usize, h as usize);
        // Linear RGB texels, scale applied, rows from the top
        let scale = f64::from(env.scale);
        let texels: Vec<[f64; 3]> = match &img {
            TextureImage::Linear(im) => im
                .pixels()
                .map(|p| p.0.map(|c| f64::from(c) * scale))
                .collect(),
            TextureImage::Srgb8(im) => im
                .pixels()
                .map(|p| {
                    let c = |k: usize| srgb_to_linear(f64::from(p.0[k]) / 255.0) * scale;
                    [c(0), c(1), c(2)]
                })
                .collect(),
        };
        let limit = crate::scene::limits::MAX_RADIANCE;
        if let Some((k, t)) = texels.iter().enumerate().find(|(_, t)| {
            t.iter()
                .any(|c| !(c.is_finite() && *c >= 0.0 && *c <= limit))
        }) {
            anyhow::bail!(
                "environment map {path}: texel ({}, {}) times the scale is ({}, {}, {}); every \
                 component must be finite, >= 0 and <= {limit:e}: fix the image (or lower `scale`)",
                k % wu,
                k / wu,
                t[0],
                t[1],
                t[2]
            );
        }
        let max_radiance = texels
            .iter()
            .flat_map(|t| t.iter())
            .fold(0.0f64, |a, &b| a.max(b)) as f32;

        // Cell weights: mean corner luminance times the row's mean sin(theta)
        let rows = hu - 1;
        let lum: Vec<f64> = texels.iter().map(|&t| luminance(t)).collect();
        let d_theta = std::f64::consts::PI / rows as f64;
        let mut weights = vec![0.0f64; rows * wu];
        for j in 0..rows {
            let (t0, t1) = (j as f64 * d_theta, (j + 1) as f64 * d_theta);
            let sin_mean = (t0.cos() - t1.cos()) / d_theta;
            for i in 0..wu {
                let i1 = (i + 1) % wu;
                let corners = lum[j * wu + i]
                    + lum[j * wu + i1]
                    + lum[(j + 1) * wu + i]
                    + lum[(j + 1) * wu + i1];
                weights[j * wu + i] = 0.25 * corners * sin_mean;
            }
        }
        let row_sums: Vec<f64> = weights.chunks(wu).map(|r| r.iter().sum()).collect();
        let total: f64 = row_sums.iter().sum();
        // Each cell spans du dv = 1 / (W (H - 1)), and dw = 2 pi^2 sin(theta) du dv
        let cell_area = 1.0 / (wu * rows) as f64;
        let two_pi2 = 2.0 * std::f64::consts::PI * std::f64::consts::PI;
        let luminance_integral = total * cell_area * two_pi2;

        let header_words = ENVMAP_HEADER_WORDS as usize;
        let marginal_at = header_words + 3 * wu * hu;
        let conditional_at = marginal_at + rows;
        let density_at = conditional_at + rows * wu;
        let end = density_at + rows * wu;
        let bytes = end as u64 * 4;
        anyhow::ensure!(
            bytes <= max_bytes && u32::try_from(end).is_ok(),
            "environment map {path} ({w} x {h}) needs {bytes} bytes on the device, more than the \
             {max_bytes} bytes one binding holds: give a smaller image"
        );
        let mut words = vec![0u32; end];
        for (k, t) in texels.iter().enumerate() {
            for c in 0..3 {
                words[header_words + 3 * k + c] = (t[c] as f32).to_bits();
            }
        }
        // Running sums in f64, written as f32, the last exactly 1
        let mut cdf = |at: usize, values: &[f64]| {
            let sum: f64 = values.iter().sum();
            let n = values.len();
            let mut acc = 0.0;
            for (k, v) in values.iter().enumerate() {
                acc += v;
                let c = if sum > 0.0 {
                    acc / sum
                } else {
                    (k + 1) as f64 / n as f64
                };
                words[at + k] = (c as f32).to_bits();
            }
            words[at + n - 1] = 1.0f32.to_bits();
        };
        cdf(marginal_at, &row_sums);
        for j in 0..rows {
            cdf(conditional_at + j * wu, &weights[j * wu..(j + 1) * wu]);
        }
        if total > 0.0 {
            for (k, wgt) in weights.iter().enumerate() {
                let density = wgt / total / cell_area / two_pi2;
                words[density_at + k] = (density as f32).to_bits();
            }
        }
        let m = env.to_local;
        let header = GpuEnvmap {
            to_local_x: m.row(0).extend(0.0),
            to_local_y: m.row(1).extend(0.0),
            to_local_z: m.row(2).extend(0.0),
            grid: UVec4::new(w, h, marginal_at as u32, conditional_at as u32),
            tables: UVec4::new(density_at as u32, 0, 0, 0),
        };
        words[..header_words].copy_from_slice(bytemuck::cast_slice(&[header]));
        Ok(GpuEnvironment {
            words,
            luminance_integral,
            max_radiance,
        })
    }

    /// Records the map's pick probability in the emitter table (header
    /// `to_local_x.w`), which the kernels need for the MIS weight of a
    /// path that escapes.
    pub fn set_pick_probability(&mut self, pmf: f32) {
        let mut header: GpuEnvmap = bytemuck::pod_read_unaligned(bytemuck::cast_slice(
            &self.words[..ENVMAP_HEADER_WORDS as usize],
        ));
        header.to_local_x.w = pmf;
        self.words[..ENVMAP_HEADER_WORDS as usize].copy_from_slice(bytemuck::cast_slice(&[header]));
    }
}
