//! The film in bands of rows, and the waves that render a band.
//!
//! A film pixel is three sums of 32 bytes, so the film of a 7680 x 4320
//! image is 3 GiB: far above one storage binding (`maxStorageBufferRange`,
//! 128 MiB on lavapipe). The renderer splits the image into bands of whole
//! rows, each a run of consecutive pixels whose film fits one binding. The
//! device holds one band's film at a time, so device memory is bounded by
//! the wave and one band. When there are several, a render that visits
//! each band once resolves it when it is done; one that comes back to the
//! bands has the host keep every band's film between visits, bit for bit.
//!
//! A wave renders a rectangle of (pixel, sample) pairs: samples
//! `sample_base..+samples` of pixels `pixel_base..+pixels` of one band. The
//! samples of a wave are a chunk of `samples_per_wave` samples that depends
//! only on the image and the wave capacity, never on the band, and the
//! accumulate pass sums a pixel's chunk in sample order before adding it to
//! the film. So a pixel's film gets the same additions in the same order
//! whatever the bands: the image is bit-identical with any band height.

use std::ops::Range;

/// A band of whole rows of the image: pixels `first_pixel..first_pixel +
/// pixels` in row-major order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tile {
    /// First row of the band.
    pub first_row: u32,
    /// Rows in the band.
    pub rows: u32,
    /// Row-major index of the band's first pixel.
    pub first_pixel: u32,
    /// Pixels in the band: `rows` times the image width.
    pub pixels: u32,
}

impl Tile {
    /// The band's pixels as a range of row-major indices.
    pub fn pixel_range(&self) -> Range<usize> {
        self.first_pixel as usize..(self.first_pixel + self.pixels) as usize
    }
}

/// Rows per band of a `width` x `height` image whose film may hold at most
/// `film_pixels` pixels per binding, lowered to `requested` when given (at
/// least 1 row; a binding holds at least one row, see
/// [`crate::scene::MAX_IMAGE_SIDE`]).
pub fn rows_per_tile(width: u32, height: u32, film_pixels: u64, requested: Option<u32>) -> u32 {
    let fit = (film_pixels / u64::from(width.max(1))).min(u64::from(height)) as u32;
    requested.map_or(fit, |r| r.min(fit)).max(1)
}

/// The bands of at most `rows_per_tile` rows that cover a `width` x
/// `height` image, top to bottom.
pub fn bands(width: u32, height: u32, rows_per_tile: u32) -> Vec<Tile> {
    let rows_per_tile = rows_per_tile.max(1);
    (0..height)
        .step_by(rows_per_tile as usize)
        .map(|first_row| {
            let rows = rows_per_tile.min(height - first_row);
            Tile {
                first_row,
                rows,
                first_pixel: first_row * width,
                pixels: rows * width,
            }
        })
        .collect()
}

/// One wave: samples `sample_base..sample_base + samples` of pixels
/// `pixel_base..pixel_base + pixels`. Path slot `s` renders pixel
/// `pixel_base + s % pixels`, sample `sample_base + s / pixels`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wave {
    /// Row-major index of the wave's first pixel.
    pub pixel_base: u32,
    /// Pixels of the wave.
    pub pixels: u32,
    /// First sample of every pixel of the wave.
    pub sample_base: u32,
    /// Samples of every pixel of the wave.
    pub samples: u32,
}

impl Wave {
    /// Paths of the wave: one per pixel and sample.
    pub fn paths(&self) -> u32 {
        self.pixels * self.samples
    }
}

/// The waves that render `samples` of every pixel of `tile`, at most
/// `capacity` paths each: chunks of `samples_per_wave` samples (the last
/// may be shorter), each over runs of pixels of the band. Every (pixel,
/// sample) pair comes once, and a pixel's samples are chunked the same
/// way whatever the band.
pub fn waves(
    tile: Tile,
    samples: Range<u32>,
    samples_per_wave: u32,
    capacity: u32,
) -> impl Iterator<Item = Wave> {
    let per_wave = samples_per_wave.max(1);
    let run = (capacity / per_wave).max(1);
    let pixels = tile.first_pixel..tile.first_pixel + tile.pixels;
    let end = samples.end;
    samples.step_by(per_wave as usize).flat_map(move |first| {
        let chunk = per_wave.min(end - first);
        pixels
            .clone()
            .step_by(run as usize)
            .map(move |pixel_base| Wave {
                pixel_base,
                pixels: run.min(pixels.end - pixel_base),
                sample_base: first,
                samples: chunk,
            })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    #[test]
    fn bands_cover_the_image_once_top_to_bottom() {
        let b = bands(7, 10, 4);
        assert_eq!(b.iter().map(|t| t.rows).collect::<Vec<_>>(), [4, 4, 2]);
        let mut next = 0;
        for t in &b {
            assert_eq!(t.first_pixel, next);
            assert_eq!(t.pixels, t.rows * 7);
            next += t.pixels;
        }
        assert_eq!(next, 70);
        assert_eq!(bands(7, 10, 100).len(), 1);
    }

    #[test]
    fn rows_per_tile_fits_the_binding_and_the_request() {
        // 128 MiB of 32-byte film pixels, a 7680-pixel row: 546 rows.
        assert_eq!(rows_per_tile(7680, 4320, 1 << 22, None), 546);
        assert_eq!(rows_per_tile(7680, 4320, 1 << 22, Some(100)), 100);
        assert_eq!(rows_per_tile(7680, 4320, 1 << 22, Some(1000)), 546);
        assert_eq!(rows_per_tile(64, 64, 1 << 22, None), 64);
        assert_eq!(rows_per_tile(64, 64, 1 << 22, Some(0)), 1);
    }

    /// Every (pixel, sample) of the image once; per pixel, the chunks of
    /// samples its waves hold, in order.
    fn chunks(
        width: u32,
        height: u32,
        rows: u32,
        spp: u32,
        per_wave: u32,
        capacity: u32,
    ) -> BTreeMap<u32, Vec<Range<u32>>> {
        let mut seen = BTreeMap::<u32, Vec<Range<u32>>>::new();
        for tile in bands(width, height, rows) {
            for w in waves(tile, 0..spp, per_wave, capacity) {
                assert!(
                    w.paths() <= capacity,
                    "{w:?} holds more than {capacity} paths"
                );
                assert!(w.pixel_base >= tile.first_pixel);
                assert!(w.pixel_base + w.pixels <= tile.first_pixel + tile.pixels);
                for p in w.pixel_base..w.pixel_base + w.pixels {
                    seen.entry(p)
                        .or_default()
                        .push(w.sample_base..w.sample_base + w.samples);
                }
            }
        }
        assert_eq!(seen.len() as u32, width * height);
        for c in seen.values() {
            let flat: Vec<u32> = c.iter().cloned().flatten().collect();
            assert_eq!(flat, (0..spp).collect::<Vec<_>>());
        }
        seen
    }

    #[test]
    fn a_pixel_gets_the_same_sample_chunks_whatever_the_bands() {
        // One sample per wave (a wave smaller than the image) and several.
        for (per_wave, capacity) in [(1, 1000), (3, 3 * 64 * 64), (5, 5 * 64 * 64 + 17)] {
            let whole = chunks(64, 64, 64, 16, per_wave, capacity);
            for rows in [1, 7, 24, 63] {
                assert_eq!(
                    chunks(64, 64, rows, 16, per_wave, capacity),
                    whole,
                    "rows {rows}"
                );
            }
        }
    }
}
