//! The film: sums and sums of squares per pixel on the device, the bands of
//! rows the host keeps between their visits to the device, and the one
//! resolve of sums into means and variances of the mean.

use std::borrow::Cow;

use anyhow::{Context as _, Result};
use bytemuck::Zeroable;

use super::stats::PassRecord;
use super::tiles::Tile;
use super::Renderer;
use crate::gpu::bindings::*;
use crate::gpu::GpuFilmPixel;

/// Means and variances of the mean from per-value sums of `n` samples:
/// the one resolve of a film, for whole renders and merges alike.
pub fn resolve(sum: &[f64], sum_sq: &[f64], n: u32) -> (Vec<f32>, Vec<f32>) {
    let n = f64::from(n).max(1.0);
    sum.iter()
        .zip(sum_sq)
        .map(|(&s, &q)| {
            let m = s / n;
            let sample_var = if n > 1.0 {
                ((q - n * m * m) / (n - 1.0)).max(0.0)
            } else {
                0.0
            };
            (m as f32, (sample_var / n) as f32)
        })
        .unzip()
}

/// The film of every band on the host, between the band's visits to the
/// device: the very bits of the device's film buffers, so that a band
/// continues where it stopped, as if it had stayed on the device.
pub(super) struct HostFilm {
    /// Radiance sums, per pixel of the image.
    sum: Vec<GpuFilmPixel>,
    /// Sums of squared radiance, per pixel of the image.
    sum_sq: Vec<GpuFilmPixel>,
}

impl HostFilm {
    /// An empty film of `pixels` pixels, or a message with the bytes it
    /// needs when the host cannot hold it.
    pub(super) fn new(pixels: usize, width: u32, height: u32) -> Result<HostFilm> {
        let zeroed = || -> Result<Vec<GpuFilmPixel>> {
            let mut v = Vec::new();
            v.try_reserve_exact(pixels).with_context(|| {
                format!(
                    "the film of a {width}x{height} image needs {} bytes of host memory \
                     ({} per pixel), which could not be allocated; render a smaller image",
                    2 * pixels as u64 * std::mem::size_of::<GpuFilmPixel>() as u64,
                    2 * std::mem::size_of::<GpuFilmPixel>()
                )
            })?;
            v.resize(pixels, GpuFilmPixel::zeroed());
            Ok(v)
        };
        Ok(HostFilm {
            sum: zeroed()?,
            sum_sq: zeroed()?,
        })
    }

    /// Empties the film.
    pub(super) fn clear(&mut self) {
        for v in [&mut self.sum, &mut self.sum_sq] {
            v.fill(GpuFilmPixel::zeroed());
        }
    }
}

impl<'c> Renderer<'c> {
    /// The film of every pixel: from the host when it holds the bands,
    /// else read from the device.
    #[allow(clippy::type_complexity)]
    pub(super) fn film(&self) -> Result<(Cow<'_, [GpuFilmPixel]>, Cow<'_, [GpuFilmPixel]>)> {
        if let Some(host) = &self.host_film {
            return Ok((Cow::Borrowed(&host.sum), Cow::Borrowed(&host.sum_sq)));
        }
        let pixels = self.frame.pixel_count as usize;
        let read = |binding| -> Result<Cow<'_, [GpuFilmPixel]>> {
            let mut film: Vec<GpuFilmPixel> = self.ctx.read(self.buffers.get(binding))?;
            film.truncate(pixels);
            Ok(Cow::Owned(film))
        };
        Ok((read(BINDING_FILM)?, read(BINDING_FILM_SQ)?))
    }

    /// Film pixels as f64 totals, RGB interleaved.
    pub(super) fn totals(&self, film: &[GpuFilmPixel]) -> Vec<f64> {
        film.iter().flat_map(|p| p.total(self.film_fp64)).collect()
    }

    /// Puts the film of `tile` on the device, when the host holds the bands.
    pub(super) fn load_tile(&self, tile: Tile) -> Result<()> {
        let Some(host) = &self.host_film else {
            return Ok(());
        };
        for (binding, film) in [(BINDING_FILM, &host.sum), (BINDING_FILM_SQ, &host.sum_sq)] {
            self.ctx
                .write(self.buffers.get(binding), 0, &film[tile.pixel_range()])
                .with_context(|| format!("loading the film of rows {}..", tile.first_row))?;
        }
        Ok(())
    }

    /// Keeps the film of `tile` on the host, when the host holds the bands.
    pub(super) fn store_tile(&mut self, tile: Tile) -> Result<()> {
        let Some(host) = &mut self.host_film else {
            return Ok(());
        };
        for (binding, film) in [
            (BINDING_FILM, &mut host.sum),
            (BINDING_FILM_SQ, &mut host.sum_sq),
        ] {
            let band: Vec<GpuFilmPixel> = self
                .ctx
                .read(self.buffers.get(binding))
                .with_context(|| format!("reading the film of rows {}..", tile.first_row))?;
            film[tile.pixel_range()].copy_from_slice(&band[..tile.pixels as usize]);
        }
        Ok(())
    }

    /// Zeroes the film and the counters before the first wave.
    pub(super) fn clear_film(&mut self) -> Result<()> {
        let mut rec = self.ctx.begin("clear_film", 0)?;
        for binding in [BINDING_FILM, BINDING_FILM_SQ, BINDING_COUNTERS] {
            let buf = self.buffers.get(binding);
            rec.fill_buffer(buf, 0, buf.size(), 0);
        }
        self.ctx.submit(rec)?;
        if let Some(host) = &mut self.host_film {
            host.clear();
        }
        Ok(())
    }

    /// Reads the film and turns sums into means and variances of the mean,
    /// a band at a time so that the f64 totals of a large image are never
    /// all held at once.
    pub(super) fn resolve_film(&self) -> Result<(Vec<f32>, Vec<f32>)> {
        let (film, film_sq) = self.film()?;
        let band = self.tile_rows().max(1) as usize * self.frame.width as usize;
        let mut mean = Vec::with_capacity(3 * film.len());
        let mut var_of_mean = Vec::with_capacity(3 * film.len());
        for (sum, sum_sq) in film.chunks(band).zip(film_sq.chunks(band)) {
            let (m, v) = resolve(&self.totals(sum), &self.totals(sum_sq), self.spp_done());
            mean.extend(m);
            var_of_mean.extend(v);
        }
        Ok((mean, var_of_mean))
    }
}

/// What the film holds since the last [`Renderer::restart`].
#[derive(Debug, Clone, Default)]
pub(super) struct Progress {
    /// First sample of every pixel the film holds (0 but for
    /// [`Renderer::render_samples`]).
    pub(super) first: u32,
    /// End of the samples accumulated: the film holds samples
    /// `first..spp` of every pixel.
    pub(super) spp: u32,
    /// Waves rendered.
    pub(super) waves: u32,
    /// Every timed dispatch.
    pub(super) records: Vec<PassRecord>,
    /// Wall-clock seconds spent rendering (readbacks excluded).
    pub(super) seconds: f64,
}
