//! Fitting the scene's textures into the one device binding that holds all
//! their texels. When they do not fit, the largest are shrunk to one common
//! texel count (so the smaller ones keep their size), each by an
//! area-weighted box filter in linear light, which keeps the texture's mean
//! colour: what a surface covered by many texels reflects on average does
//! not change, only detail is lost. Each shrunk texture is named in a
//! warning.

use image::{Rgb32FImage, RgbaImage};

use crate::util::color::to_srgb8;

/// Bytes per word of the texel binding (`uint`); an sRGB RGBA8 texel takes
/// one word, a linear float RGB texel three.
pub(crate) const WORD_BYTES: u64 = 4;

/// Words of header per texture: first texel, width, height, unused.
pub(crate) const HEADER_WORDS: u64 = 4;

/// The largest texel count `cap` such that textures of `texels` texels
/// (each with its words per texel), each shrunk to at most `cap` texels,
/// take at most `room` words; `None` when they fit as they are. `Some(0)`
/// means not even one texel each fits.
pub(crate) fn texel_cap(texels: &[(u64, u64)], room: u64) -> Option<u64> {
    let total = |cap: u64| texels.iter().map(|&(t, w)| t.min(cap) * w).sum::<u64>();
    let largest = texels.iter().map(|&(t, _)| t).max().unwrap_or(0);
    if total(largest) <= room {
        return None;
    }
    // total() grows with cap: the largest cap that fits lies in [0, largest)
    let (mut fits, mut too_big) = (0, largest);
    while too_big - fits > 1 {
        let mid = fits + (too_big - fits) / 2;
        if total(mid) <= room {
            fits = mid;
        } else {
            too_big = mid;
        }
    }
    Some(fits)
}

/// The largest size with the aspect ratio of `width` x `height` (as close
/// as whole texels allow) that has at most `cap` texels, at least 1 x 1.
pub(crate) fn fitted_size(width: u32, height: u32, cap: u64) -> (u32, u32) {
    let texels = u64::from(width) * u64::from(height);
    if texels <= cap {
        return (width, height);
    }
    let scale = (cap as f64 / texels as f64).sqrt();
    let side = |s: u32| ((f64::from(s) * scale).floor() as u32).clamp(1, s);
    let (mut w, mut h) = (side(width), side(height));
    // Rounding may leave one row or column too many
    while u64::from(w) * u64::from(h) > cap.max(1) {
        if w >= h {
            w -= 1;
        } else {
            h -= 1;
        }
    }
    (w, h)
}

/// sRGB-encoded 8-bit value to linear, as the kernels decode texels.
pub(crate) fn srgb_to_linear(c: u8) -> f32 {
    crate::util::color::srgb_decode(f32::from(c) / 255.0)
}

/// The input texels that output cell `i` of `to` cells covers along an
/// axis of `from` input texels, and the share of the cell each covers
/// (summing to 1): the weights of an area-weighted box filter. Computed
/// where they are used, not stored: a table of them for a long axis (16.8
/// million texels) took more memory than the texture.
fn box_taps(from: u32, to: u32, i: u32) -> impl Iterator<Item = (u32, f32)> {
    let step = f64::from(from) / f64::from(to);
    let (a, b) = (f64::from(i) * step, f64::from(i + 1) * step);
    let first = a.floor() as u32;
    let last = (b.ceil() as u32).min(from);
    (first..last)
        .map(move |x| {
            let x0 = f64::from(x).max(a);
            let x1 = f64::from(x + 1).min(b);
            (x, ((x1 - x0) / step) as f32)
        })
        .filter(|&(_, w)| w > 0.0)
}

/// A `from_w` x `from_h` image of `N` channels (`texel(x, y)`, linear)
/// shrunk to `width` x `height` by an area-weighted box filter: every
/// output texel is the mean of the input area it covers, in f32. Each
/// input row is filtered across and added into its output row, which is
/// all the memory the filter holds besides its output.
fn box_filter<const N: usize>(
    (from_w, from_h): (u32, u32),
    texel: impl Fn(u32, u32) -> [f32; N],
    (width, height): (u32, u32),
) -> Vec<[f32; N]> {
    let mut out = vec![[0f32; N]; width as usize * height as usize];
    for (j, row) in (0..height).zip(out.chunks_mut(width as usize)) {
        for (y, wy) in box_taps(from_h, height, j) {
            for (i, sum) in (0..width).zip(row.iter_mut()) {
                let mut across = [0f32; N];
                for (x, wx) in box_taps(from_w, width, i) {
                    let p = texel(x, y);
                    for c in 0..N {
                        across[c] += wx * p[c];
                    }
                }
                for c in 0..N {
                    sum[c] += wy * across[c];
                }
            }
        }
    }
    out
}

/// `img` shrunk to `width` x `height` by an area-weighted box filter in
/// linear light: every output texel is the mean of the linear colour of
/// the input area it covers, so the image's mean colour is kept (up to
/// 8-bit rounding). Alpha is averaged as it is stored.
pub(crate) fn downscale(img: &RgbaImage, width: u32, height: u32) -> RgbaImage {
    let lut: Vec<f32> = (0..=255u8).map(srgb_to_linear).collect();
    let texel = |x, y| {
        let p = img.get_pixel(x, y).0;
        let c = |i: usize| lut[p[i] as usize];
        [c(0), c(1), c(2), f32::from(p[3]) / 255.0]
    };
    let texels = box_filter(img.dimensions(), texel, (width, height));
    let bytes = texels.iter().flat_map(|s| {
        let alpha = (s[3].clamp(0.0, 1.0) * 255.0).round() as u8;
        [to_srgb8(s[0]), to_srgb8(s[1]), to_srgb8(s[2]), alpha]
    });
    RgbaImage::from_vec(width, height, bytes.collect()).expect("4 bytes per texel")
}

/// A linear float image shrunk to `width` x `height` by the same
/// area-weighted box filter: its mean is kept (up to f32 rounding).
pub(crate) fn downscale_linear(img: &Rgb32FImage, width: u32, height: u32) -> Rgb32FImage {
    let texels = box_filter(
        img.dimensions(),
        |x, y| img.get_pixel(x, y).0,
        (width, height),
    );
    Rgb32FImage::from_vec(width, height, texels.into_flattened()).expect("3 floats per texel")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap shrinks only the largest textures, as little as the room
    /// allows.
    #[test]
    fn cap_shrinks_only_the_largest_textures() {
        let one = |t: &[u64]| t.iter().map(|&t| (t, 1)).collect::<Vec<_>>();
        assert_eq!(texel_cap(&one(&[100, 50]), 150), None);
        // 100 + 50 into 120: the 100 shrinks to 70, the 50 stays
        assert_eq!(texel_cap(&one(&[100, 50]), 120), Some(70));
        // Two equal textures share the room
        assert_eq!(texel_cap(&one(&[100, 100]), 101), Some(50));
        assert_eq!(texel_cap(&one(&[100, 100, 100]), 2), Some(0));
        // One texture over the room alone
        assert_eq!(texel_cap(&one(&[33_640_000]), 33_554_428), Some(33_554_428));
        // A float texture takes three words a texel: 3 * 100 + 50 into 200
        // words caps both at 50 texels (3 * 50 + 50)
        assert_eq!(texel_cap(&[(100, 3), (50, 1)], 350), None);
        assert_eq!(texel_cap(&[(100, 3), (50, 1)], 200), Some(50));
    }

    /// The fitted size keeps the aspect ratio and stays within the cap.
    #[test]
    fn fitted_size_keeps_the_aspect_and_the_cap() {
        assert_eq!(fitted_size(64, 32, 2048), (64, 32));
        assert_eq!(fitted_size(64, 32, 512), (32, 16));
        assert_eq!(fitted_size(5800, 5800, 33_554_428), (5792, 5792));
        assert_eq!(fitted_size(1000, 1, 10), (10, 1));
        assert_eq!(fitted_size(3, 3, 0), (1, 1));
        for (w, h, cap) in [(997, 313, 1000), (5, 7, 34), (1, 1000, 7)] {
            let (a, b) = fitted_size(w, h, cap);
            assert!(u64::from(a) * u64::from(b) <= cap, "{w}x{h} -> {a}x{b}");
        }
    }

    /// The box filter's weights cover each input texel once in all.
    #[test]
    fn box_taps_cover_every_texel_once() {
        for (from, to) in [(8, 4), (7, 3), (5800, 5792), (10, 1)] {
            let mut cover = vec![0f64; from as usize];
            let step = f64::from(from) / f64::from(to);
            for i in 0..to {
                let cell: Vec<(u32, f32)> = box_taps(from, to, i).collect();
                let total: f32 = cell.iter().map(|w| w.1).sum();
                assert!((total - 1.0).abs() < 1e-5, "{from}->{to}: {total}");
                for (x, w) in cell {
                    cover[x as usize] += f64::from(w) * step;
                }
            }
            assert!(cover.iter().all(|c| (c - 1.0).abs() < 1e-4), "{from}->{to}");
        }
    }

    /// Shrinking keeps the mean linear colour of a noisy texture within
    /// 8-bit rounding (under 1%, at one texel), where averaging the sRGB
    /// codes would shift it by several percent.
    #[test]
    fn downscale_keeps_the_mean_linear_colour() {
        let mut state = 12345u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as u8
        };
        let img = RgbaImage::from_fn(97, 61, |_, _| image::Rgba([next(), next(), next(), 255]));
        let mean = |im: &RgbaImage| {
            let mut m = [0f64; 3];
            for p in im.pixels() {
                for (m, &code) in m.iter_mut().zip(&p.0[..3]) {
                    *m += f64::from(srgb_to_linear(code));
                }
            }
            m.map(|v| v / (im.width() * im.height()) as f64)
        };
        let before = mean(&img);
        for (w, h) in [(48, 30), (13, 7), (1, 1)] {
            let small = downscale(&img, w, h);
            assert_eq!(small.dimensions(), (w, h));
            let after = mean(&small);
            for c in 0..3 {
                let rel = (after[c] - before[c]).abs() / before[c];
                assert!(rel < 1e-2, "{w}x{h} channel {c}: {after:?} vs {before:?}");
            }
        }
        // A uniform texture stays exactly uniform
        let flat = RgbaImage::from_pixel(9, 9, image::Rgba([200, 100, 50, 255]));
        assert!(downscale(&flat, 4, 4)
            .pixels()
            .all(|p| p.0 == [200, 100, 50, 255]));
    }

    /// A linear float texture keeps its mean when shrunk, values above 1
    /// included.
    #[test]
    fn downscale_linear_keeps_the_mean() {
        let img = Rgb32FImage::from_fn(31, 17, |x, y| {
            image::Rgb([x as f32 * 0.25, y as f32 * 3.0, ((x * y) % 7) as f32])
        });
        let mean = |im: &Rgb32FImage| {
            let mut m = [0f64; 3];
            for p in im.pixels() {
                for (m, &v) in m.iter_mut().zip(&p.0) {
                    *m += f64::from(v);
                }
            }
            m.map(|v| v / f64::from(im.width() * im.height()))
        };
        let before = mean(&img);
        for (w, h) in [(16, 9), (5, 3), (1, 1)] {
            let after = mean(&downscale_linear(&img, w, h));
            for c in 0..3 {
                assert!(
                    (after[c] - before[c]).abs() < 1e-5 * before[c],
                    "{after:?} {before:?}"
                );
            }
        }
    }
}
