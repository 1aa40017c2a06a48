//! The film: sums, sums of squares and sums of the odd-numbered samples
//! per pixel on the device, the bands of rows the host keeps between their
//! visits to the device, and the one resolve of sums into means, variances
//! of the mean and error estimates.
//!
//! # The error estimate: two half films
//!
//! The film keeps, beside the sums of all samples, the sums of the
//! odd-numbered ones, so that it holds two half films: the even samples
//! and the odd ones. In a progressive render (`RenderOptions::progressive`,
//! which budgets, adaptive renders and `converge` use) every sampler draws
//! the two halves independently (the independent sampler trivially; the
//! Sobol sampler as two sequences with seeds of their own,
//! [`crate::render::sobol`]), so the half means m_e
//! (n_e samples) and m_o (n_o samples) are two independent estimates of the
//! pixel, and (m_e - m_o)^2 n_e n_o / n^2 is an unbiased estimate of the
//! expected squared error of the whole mean, (n_e m_e + n_o m_o) / n,
//! whatever the sampler: exactly so when the error falls as 1/n, and an
//! overestimate by at most 2^(a-1) when it falls as n^-a faster than that
//! (each half is a sequence of n/2). The sample variance / n, which the film
//! also gives, is exact only for independent samples: it overstates the
//! error of stratified and low-discrepancy samples. The half estimate has
//! one degree of freedom per value, so it is meaningful averaged over many
//! pixels (the predicted relMSE), where the sample variance stays the
//! per-pixel variance of the variance EXR and its z-tests.
//!
//! A fixed-spp render draws each pixel's Sobol samples as one sequence,
//! whose error is lower, and stratifies the independent sampler's camera
//! jitter on an N x N grid when spp = N^2: its two half films are then
//! stratified against each other, and the half estimate overstates its
//! error. No fixed-spp render reports it.

use anyhow::{Context as _, Result};
use bytemuck::Zeroable;

use super::stats::PassRecord;
use super::tiles::Tile;
use super::Renderer;
use crate::gpu::bindings::*;
use crate::gpu::GpuFilmPixel;

/// The film bindings, in the order of [`FilmSums`]' fields.
const FILM_BINDINGS: [u32; 3] = [BINDING_FILM, BINDING_FILM_SQ, BINDING_FILM_ODD];

/// A film resolved: per value (RGB per pixel, row-major from the top-left).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Resolved {
    /// Mean radiance.
    pub mean: Vec<f32>,
    /// Variance of the mean: sample variance / n (exact for independent
    /// samples, an overestimate for stratified and low-discrepancy ones).
    pub var_of_mean: Vec<f32>,
    /// The two half films' estimate of the mean's expected squared error
    /// (see the module's documentation), under every sampler.
    pub error: Vec<f32>,
}

/// Samples `first..end` of a pixel counted by half: (even, odd).
pub fn half_counts(first: u32, end: u32) -> (u32, u32) {
    let odd = end / 2 - first / 2;
    (end - first - odd, odd)
}

/// Means, variances of the mean and error estimates from per-value sums of
/// samples `first..end`: all samples, their squares, and the odd-numbered
/// samples. The one resolve of a film, for whole renders and merges alike.
pub fn resolve(sum: &[f64], sum_sq: &[f64], sum_odd: &[f64], first: u32, end: u32) -> Resolved {
    resolve_pixels(sum, sum_sq, sum_odd, first, |_| end)
}

/// [`resolve`] where each pixel has samples of its own: pixel `i` (values
/// `3i..3i + 3`) holds samples `first..end(i)`. An adaptive render's film.
pub fn resolve_pixels(
    sum: &[f64],
    sum_sq: &[f64],
    sum_odd: &[f64],
    first: u32,
    end: impl Fn(usize) -> u32,
) -> Resolved {
    let mut out = Resolved {
        mean: Vec::with_capacity(sum.len()),
        var_of_mean: Vec::with_capacity(sum.len()),
        error: Vec::with_capacity(sum.len()),
    };
    for (i, ((&s, &q), &o)) in sum.iter().zip(sum_sq).zip(sum_odd).enumerate() {
        let (even, odd) = half_counts(first, end(i / 3).max(first));
        let (ne, no) = (f64::from(even), f64::from(odd));
        let n = (ne + no).max(1.0);
        let m = s / n;
        let sample_var = if n > 1.0 {
            ((q - n * m * m) / (n - 1.0)).max(0.0)
        } else {
            0.0
        };
        let error = if even > 0 && odd > 0 {
            let d = (s - o) / ne - o / no;
            d * d * ne * no / (n * n)
        } else {
            0.0
        };
        out.mean.push(m as f32);
        out.var_of_mean.push((sample_var / n) as f32);
        out.error.push(error as f32);
    }
    out
}

/// A film's raw sums, per value (RGB per pixel), in f64.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FilmSums {
    /// Radiance sums.
    pub sum: Vec<f64>,
    /// Sums of squared radiance.
    pub sum_sq: Vec<f64>,
    /// Radiance sums of the odd-numbered samples.
    pub sum_odd: Vec<f64>,
}

/// Words of a film pixel's 8 that the host keeps: the f64 film uses the
/// first six (r, g, b), the compensated f32 film words 0..3 and 4..7 (sum
/// and compensation); the kernels write the others as zero.
const HOST_WORDS: usize = 6;

/// A film pixel as the host keeps it: its [`HOST_WORDS`] used words.
type HostPixel = [u32; HOST_WORDS];

/// The words of `p` the host keeps.
fn to_host(p: &GpuFilmPixel, fp64: bool) -> HostPixel {
    let (lo, hi) = (p.lo, p.hi);
    if fp64 {
        [lo.x, lo.y, lo.z, lo.w, hi.x, hi.y]
    } else {
        [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]
    }
}

/// The film pixel whose kept words are `w`, the others zero.
fn from_host(w: &HostPixel, fp64: bool) -> GpuFilmPixel {
    use glam::UVec4;
    if fp64 {
        GpuFilmPixel {
            lo: UVec4::new(w[0], w[1], w[2], w[3]),
            hi: UVec4::new(w[4], w[5], 0, 0),
        }
    } else {
        GpuFilmPixel {
            lo: UVec4::new(w[0], w[1], w[2], 0),
            hi: UVec4::new(w[3], w[4], w[5], 0),
        }
    }
}

/// The film of every band on the host, between the band's visits to the
/// device: the very bits of the device's film buffers, less the words the
/// kernels keep at zero (24 bytes of 32 per sum), so that a band continues
/// where it stopped, as if it had stayed on the device. Only renders that
/// come back to a band need it (progressive renders, budgets, parts of a
/// split render); [`Renderer::render`] resolves each band once its samples
/// are done and keeps none.
pub(super) struct HostFilm {
    /// Per binding of [`FILM_BINDINGS`]: radiance sums, sums of squares and
    /// sums of the odd samples, per pixel of the image.
    films: [Vec<HostPixel>; 3],
}

impl HostFilm {
    /// An empty film of `pixels` pixels, or a message with the bytes it
    /// needs when the host cannot hold it.
    pub(super) fn new(pixels: usize, width: u32, height: u32) -> Result<HostFilm> {
        let zeroed = || -> Result<Vec<HostPixel>> {
            let mut v = Vec::new();
            v.try_reserve_exact(pixels).with_context(|| {
                format!(
                    "the film of a {width}x{height} image needs {} bytes of host memory \
                     ({} per pixel), which could not be allocated; render a smaller image",
                    FILM_BINDINGS.len() as u64 * pixels as u64 * HOST_PIXEL_BYTES,
                    FILM_BINDINGS.len() as u64 * HOST_PIXEL_BYTES
                )
            })?;
            v.resize(pixels, [0; HOST_WORDS]);
            Ok(v)
        };
        Ok(HostFilm {
            films: [zeroed()?, zeroed()?, zeroed()?],
        })
    }

    /// Bytes the film holds.
    pub(super) fn bytes(&self) -> u64 {
        self.films.iter().map(|f| f.len() as u64).sum::<u64>() * HOST_PIXEL_BYTES
    }

    /// Empties the film.
    pub(super) fn clear(&mut self) {
        for v in &mut self.films {
            v.fill([0; HOST_WORDS]);
        }
    }
}

/// Bytes of one film pixel of one binding on the host.
const HOST_PIXEL_BYTES: u64 = std::mem::size_of::<HostPixel>() as u64;

/// Where the film of an image of several bands is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) enum BandFilm {
    /// Nothing rendered since the last clear: every band's film is zero.
    #[default]
    Empty,
    /// On the host, every band's ([`HostFilm`]).
    Host,
    /// Resolved band by band by [`Renderer::render`] and not kept.
    Resolved,
}

impl<'c> Renderer<'c> {
    /// The film of the pixels of `tile`, per binding of [`FILM_BINDINGS`]:
    /// from the host when it holds the bands, else read from the device.
    fn film_of(&self, tile: Tile) -> Result<[Vec<GpuFilmPixel>; 3]> {
        let pixels = tile.pixels as usize;
        if self.tiles.len() > 1 {
            match (self.band_film, &self.host_film) {
                (BandFilm::Empty, _) => {
                    return Ok(std::array::from_fn(|_| {
                        vec![GpuFilmPixel::zeroed(); pixels]
                    }))
                }
                (BandFilm::Host, Some(host)) => {
                    return Ok(host.films.each_ref().map(|f| {
                        f[tile.pixel_range()]
                            .iter()
                            .map(|w| from_host(w, self.film_fp64))
                            .collect()
                    }))
                }
                _ => anyhow::bail!(
                    "the film was resolved band by band by render() and not kept: \
                     restart and render_to to keep it"
                ),
            }
        }
        self.device_film(pixels)
    }

    /// The first `pixels` pixels of the device's film, per binding of
    /// [`FILM_BINDINGS`].
    fn device_film(&self, pixels: usize) -> Result<[Vec<GpuFilmPixel>; 3]> {
        let read = |binding| -> Result<Vec<GpuFilmPixel>> {
            let mut film: Vec<GpuFilmPixel> = self.ctx.read(self.buffers.get(binding))?;
            film.truncate(pixels);
            Ok(film)
        };
        let [a, b, c] = FILM_BINDINGS;
        Ok([read(a)?, read(b)?, read(c)?])
    }

    /// Film pixels as f64 totals, RGB interleaved.
    pub(super) fn totals(&self, film: &[GpuFilmPixel]) -> Vec<f64> {
        film.iter().flat_map(|p| p.total(self.film_fp64)).collect()
    }

    /// The film's raw sums in f64, a band at a time.
    pub(super) fn sums(&self) -> Result<FilmSums> {
        let mut out = FilmSums::default();
        for &tile in &self.tiles {
            let [sum, sum_sq, sum_odd] = self.film_of(tile)?;
            out.sum.extend(self.totals(&sum));
            out.sum_sq.extend(self.totals(&sum_sq));
            out.sum_odd.extend(self.totals(&sum_odd));
        }
        Ok(out)
    }

    /// Puts the film of `tile` on the device, when the host holds the bands.
    pub(super) fn load_tile(&self, tile: Tile) -> Result<()> {
        if self.tiles.len() == 1 {
            return Ok(());
        }
        let films = self.film_of(tile)?;
        for (binding, film) in FILM_BINDINGS.iter().zip(&films) {
            self.ctx
                .write(self.buffers.get(*binding), 0, film)
                .with_context(|| format!("loading the film of rows {}..", tile.first_row))?;
        }
        Ok(())
    }

    /// Keeps the film of `tile` on the host, when the host holds the bands
    /// (made on the first band kept).
    pub(super) fn store_tile(&mut self, tile: Tile) -> Result<()> {
        if self.tiles.len() == 1 {
            return Ok(());
        }
        if self.host_film.is_none() {
            let f = &self.frame;
            self.host_film = Some(HostFilm::new(f.pixel_count as usize, f.width, f.height)?);
        }
        let fp64 = self.film_fp64;
        let mut bands = Vec::with_capacity(FILM_BINDINGS.len());
        for binding in FILM_BINDINGS {
            let band: Vec<GpuFilmPixel> = self
                .ctx
                .read(self.buffers.get(binding))
                .with_context(|| format!("reading the film of rows {}..", tile.first_row))?;
            bands.push(band);
        }
        let host = self.host_film.as_mut().expect("made above");
        if self.band_film == BandFilm::Empty {
            host.clear();
        }
        for (film, band) in host.films.iter_mut().zip(&bands) {
            for (w, p) in film[tile.pixel_range()].iter_mut().zip(band) {
                *w = to_host(p, fp64);
            }
        }
        self.band_film = BandFilm::Host;
        Ok(())
    }

    /// Zeroes the film of the device (the band it holds).
    pub(super) fn clear_device_film(&mut self) -> Result<()> {
        let mut rec = self.ctx.begin("clear_band", 0)?;
        for binding in FILM_BINDINGS {
            let buf = self.buffers.get(binding);
            rec.fill_buffer(buf, 0, buf.size(), 0);
        }
        self.ctx.submit(rec)?;
        Ok(())
    }

    /// Zeroes the film and the counters before the first wave.
    pub(super) fn clear_film(&mut self) -> Result<()> {
        let mut rec = self.ctx.begin("clear_film", 0)?;
        for binding in FILM_BINDINGS.into_iter().chain([BINDING_COUNTERS]) {
            let buf = self.buffers.get(binding);
            rec.fill_buffer(buf, 0, buf.size(), 0);
        }
        self.ctx.submit(rec)?;
        self.band_film = BandFilm::Empty;
        Ok(())
    }

    /// Resolves the film the device holds of `tile`, samples `first..end`
    /// of each pixel, and appends it to `out`.
    pub(super) fn resolve_device_band(
        &self,
        tile: Tile,
        first: u32,
        end: u32,
        out: &mut Resolved,
    ) -> Result<()> {
        let film = self.device_film(tile.pixels as usize)?;
        self.resolve_into(film, first, |_| end, out);
        Ok(())
    }

    /// Resolves `film` (per binding of [`FILM_BINDINGS`]), samples
    /// `first..end(i)` of its pixel `i`, and appends it to `out`.
    fn resolve_into(
        &self,
        film: [Vec<GpuFilmPixel>; 3],
        first: u32,
        end: impl Fn(usize) -> u32,
        out: &mut Resolved,
    ) {
        let [sum, sum_sq, sum_odd] = film;
        let r = resolve_pixels(
            &self.totals(&sum),
            &self.totals(&sum_sq),
            &self.totals(&sum_odd),
            first,
            end,
        );
        out.mean.extend(r.mean);
        out.var_of_mean.extend(r.var_of_mean);
        out.error.extend(r.error);
    }

    /// Reads the film and resolves it, a band at a time so that the f64
    /// totals of a large image are never all held at once.
    pub(super) fn resolve_film(&self) -> Result<Resolved> {
        let mut out = Resolved::with_capacity(3 * self.frame.pixel_count as usize);
        let counts = self.progress.pixel_spp.as_deref();
        for &tile in &self.tiles {
            let film = self.film_of(tile)?;
            let first_pixel = tile.first_pixel as usize;
            let end = |i: usize| counts.map_or(self.progress.spp, |c| c[first_pixel + i]);
            self.resolve_into(film, self.progress.first, end, &mut out);
        }
        Ok(out)
    }
}

impl Resolved {
    /// An empty film resolved, with room for `values` values.
    pub fn with_capacity(values: usize) -> Resolved {
        Resolved {
            mean: Vec::with_capacity(values),
            var_of_mean: Vec::with_capacity(values),
            error: Vec::with_capacity(values),
        }
    }
}

/// What the film holds since the last [`Renderer::restart`].
#[derive(Debug, Clone, Default)]
pub(super) struct Progress {
    /// First sample of every pixel the film holds (0 but for
    /// [`Renderer::render_samples`]).
    pub(super) first: u32,
    /// End of the samples accumulated: the film holds samples
    /// `first..spp` of every pixel (unless `pixel_spp` says otherwise).
    pub(super) spp: u32,
    /// Each pixel's end of samples, row-major, once an adaptive render
    /// ([`Renderer::render_pixels`]) has given pixels different counts.
    pub(super) pixel_spp: Option<Vec<u32>>,
    /// Waves rendered.
    pub(super) waves: u32,
    /// Every timed dispatch.
    pub(super) records: Vec<PassRecord>,
    /// Wall-clock seconds spent rendering (readbacks excluded).
    pub(super) seconds: f64,
}

impl Progress {
    /// Each of `pixels` pixels' end of samples.
    pub(super) fn pixel_counts(&self, pixels: usize) -> Vec<u32> {
        self.pixel_spp
            .clone()
            .unwrap_or_else(|| vec![self.spp; pixels])
    }

    /// Records each pixel's end of samples: per pixel when they differ,
    /// else as the one `spp`.
    pub(super) fn set_pixel_counts(&mut self, counts: Vec<u32>) {
        match counts.first() {
            Some(&n) if counts.iter().all(|&c| c == n) => {
                self.spp = n;
                self.pixel_spp = None;
            }
            _ => self.pixel_spp = Some(counts),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sobol::SobolSampler;

    /// A pixel's integrand over two draws: a quarter disc of radius² 0.6 in
    /// the pair at dimension 0, times 0.5 + the number at dimension 4. Its
    /// integral is π 0.6 / 4.
    fn integrand(pair: [f32; 2], one: f32) -> f64 {
        let inside = pair[0] * pair[0] + pair[1] * pair[1] < 0.6;
        f64::from(u8::from(inside)) * (0.5 + f64::from(one))
    }

    /// Mean squared error of 4096 pixels' means and the mean of their half
    /// film estimates, when sample i of a pixel is `draw(pixel, i)`.
    fn error_and_estimate(n: u32, draw: impl Fn(u32, u32) -> f64) -> (f64, f64) {
        let exact = std::f64::consts::PI * 0.6 / 4.0;
        let (mut mse, mut estimate) = (0.0, 0.0);
        let pixels = 4096;
        for pixel in 0..pixels {
            let (mut s, mut q, mut o) = (0.0, 0.0, 0.0);
            for i in 0..n {
                let f = draw(pixel, i);
                s += f;
                q += f * f;
                if i % 2 == 1 {
                    o += f;
                }
            }
            let r = resolve(&[s], &[q], &[o], 0, n);
            mse += (f64::from(r.mean[0]) - exact).powi(2) / f64::from(pixels);
            estimate += f64::from(r.error[0]) / f64::from(pixels);
        }
        (mse, estimate)
    }

    /// Under the Sobol sampler in halves (a progressive render) the two
    /// half films estimate the error (the halves are independent
    /// sequences), where the sample variance overstates it. One sequence
    /// per pixel (a fixed-spp render) has less error, and its two halves
    /// overstate it, by their stratification against each other.
    #[test]
    fn half_films_estimate_the_error_of_sobol_samples() {
        let halves = SobolSampler::in_halves(11);
        let one = SobolSampler::new(11);
        for n in [64u32, 256] {
            let draw = |s: &SobolSampler, pixel, i| {
                integrand(s.sample_2d(pixel, i, 0), s.sample_1d(pixel, i, 4))
            };
            let (mse, estimate) = error_and_estimate(n, |p, i| draw(&halves, p, i));
            let ratio = estimate / mse;
            let (one_mse, one_estimate) = error_and_estimate(n, |p, i| draw(&one, p, i));
            let one_ratio = one_estimate / one_mse;
            println!(
                "{n} spp: halves: error {mse:.3e}, half films {estimate:.3e} (ratio {ratio:.2}); \
                 one sequence: error {one_mse:.3e} ({:.2} of the halves'), ratio {one_ratio:.2}",
                one_mse / mse
            );
            assert!((0.8..1.25).contains(&ratio), "{n} spp: ratio {ratio}");
            assert!(one_ratio > 1.5, "{n} spp: one sequence ratio {one_ratio}");
            assert!(
                one_mse < 0.95 * mse,
                "{n} spp: one sequence {one_mse}, halves {mse}"
            );
        }
    }

    #[test]
    fn half_counts_split_any_range_by_parity() {
        assert_eq!(half_counts(0, 8), (4, 4));
        assert_eq!(half_counts(0, 7), (4, 3));
        assert_eq!(half_counts(3, 8), (2, 3));
        assert_eq!(half_counts(3, 4), (0, 1));
        // Parts add up to the whole
        let (a, b) = (half_counts(0, 5), half_counts(5, 12));
        assert_eq!((a.0 + b.0, a.1 + b.1), half_counts(0, 12));
    }

    #[test]
    fn resolve_gives_the_half_estimate_and_the_sample_variance() {
        // Samples 1, 2, 3, 6: even (1, 3) mean 2, odd (2, 6) mean 4
        let r = resolve(&[12.0], &[50.0], &[8.0], 0, 4);
        assert_eq!(r.mean, [3.0]);
        // (2 - 4)² 2 · 2 / 16 = 1
        assert_eq!(r.error, [1.0]);
        // Sample variance (50 - 4 · 9) / 3, over 4
        assert!((r.var_of_mean[0] - 14.0 / 12.0).abs() < 1e-6);
        // One sample: no estimate
        assert_eq!(resolve(&[2.0], &[4.0], &[0.0], 0, 1).error, [0.0]);
    }
}
