//! Renders split across machines: film files and their merge.
//!
//! `lancer render SCENE --samples A..B --film-out part.film` renders samples
//! A to B-1 of every pixel (the very samples a whole render draws: random
//! numbers depend only on seed, pixel, sample and dimension) and writes the
//! film's raw sums. `lancer merge part*.film --out image.exr` checks that the
//! parts come from one scene, integrator and sampler and cover `0..spp`
//! once, adds their sums in f64 in sample order, and resolves them exactly
//! as a whole render resolves its film ([`crate::render::film::resolve`]).
//!
//! # File format, version 3 (all numbers little-endian)
//!
//! Version 2 added the sampler and the sums of the odd-numbered samples
//! (the second half film of the error estimate). Version 1 files lack
//! them and are refused with a message saying so: render such a part again.
//! Version 3 has the layout of version 2; its parts draw each pixel's Sobol
//! samples as one sequence, where version 2 drew two halves, so a version 2
//! part is not the same samples and is refused likewise.
//!
//! | bytes | what |
//! |---|---|
//! | 8 | magic `LNCRFILM` |
//! | 4 | format version, u32 (3) |
//! | 4 | the sampler, u32 (`SAMPLER_*`: 0 independent, 1 sobol) |
//! | 8 | scene hash, u64 ([`scene_hash`]) |
//! | 4 + 4 | sample range: first, end (u32; the part holds first..end) |
//! | 4 | the scene's spp, u32 (what the parts must cover) |
//! | 4 + 4 | width, height (u32) |
//! | 8 | samples dropped for NaN or infinite radiance, u64 |
//! | 24 w h | radiance sums, f64, per pixel R, G, B, rows top to bottom |
//! | 24 w h | sums of squares, f64, same order |
//! | 24 w h | radiance sums of the odd-numbered samples, f64, same order |
//! | 4 | CRC-32 (IEEE, crc32fast) of every byte before it |

use crate::render::film::{resolve, Resolved};
use crate::render::kernels::{Integrator, Sampler};
use crate::scene::Scene;
use crate::util::text::cut_path;
use anyhow::{bail, ensure, Context as _, Result};
use std::path::{Path, PathBuf};

/// The magic at the start of a film file.
pub const MAGIC: &[u8; 8] = b"LNCRFILM";
/// The format version this build writes and reads.
pub const VERSION: u32 = 3;
/// Bytes before the sums.
const HEADER_BYTES: usize = 8 + 4 + 4 + 8 + 4 + 4 + 4 + 4 + 4 + 8;
/// Bytes of the checksum at the end.
const CRC_BYTES: usize = 4;

/// The raw film of samples `first..end` of every pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct FilmPart {
    /// [`scene_hash`] of the scene rendered.
    pub scene_hash: u64,
    /// The sampler that drew the samples.
    pub sampler: Sampler,
    /// First sample of every pixel held.
    pub first: u32,
    /// One past the last sample held.
    pub end: u32,
    /// The scene's samples per pixel: the parts together cover `0..spp`.
    pub spp: u32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples dropped for a NaN or infinite radiance.
    pub nonfinite: u64,
    /// Radiance sums, RGB per pixel.
    pub sum: Vec<f64>,
    /// Sums of squared radiance, RGB per pixel.
    pub sum_sq: Vec<f64>,
    /// Radiance sums of the odd-numbered samples, RGB per pixel.
    pub sum_odd: Vec<f64>,
}

/// Parses `A..B` (samples A to B-1).
pub fn parse_range(text: &str) -> std::result::Result<(u32, u32), String> {
    let bad = || format!("expected A..B with whole numbers A < B (samples A to B-1), got `{text}`");
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let (a, b) = (
        a.trim().parse::<u32>().map_err(|_| bad())?,
        b.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if a >= b {
        return Err(bad());
    }
    Ok((a, b))
}

/// A stable 64-bit hash (FNV-1a) of everything that decides the image: the
/// flattened scene as `lancer convert` writes it (settings, camera,
/// materials, every sphere and triangle, bit for bit), the bytes of its
/// textures, the integrator and the sampler. The scene file's own path is
/// left out, so parts rendered from copies of a scene in different folders
/// merge.
pub fn scene_hash(scene: &Scene, integrator: Integrator, sampler: Sampler) -> Result<u64> {
    let mut canonical = scene.clone();
    canonical.source = PathBuf::new();
    canonical.warnings.clear();
    let mut h = crate::vk::Fnv::new()
        .bytes(format!("{integrator:?}").as_bytes())
        .bytes(sampler.name().as_bytes());
    for (path, bytes) in crate::scene::to_toml(&canonical, Path::new("scene.toml")) {
        h = h.bytes(path.to_string_lossy().as_bytes()).bytes(&bytes);
    }
    for t in scene.materials.iter().flat_map(|m| m.files()) {
        let bytes = std::fs::read(t).with_context(|| format!("{}: cannot read", cut_path(t)))?;
        h = h.bytes(&bytes);
    }
    if let Some(env) = &scene.envmap {
        let bytes = std::fs::read(&env.file)
            .with_context(|| format!("{}: cannot read", cut_path(&env.file)))?;
        h = h.bytes(&bytes);
    }
    Ok(h.finish())
}

impl FilmPart {
    /// The file's bytes (see the module's table).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(HEADER_BYTES + 24 * self.sum.len() + CRC_BYTES);
        b.extend_from_slice(MAGIC);
        for v in [VERSION, self.sampler.id()] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.scene_hash.to_le_bytes());
        for v in [self.first, self.end, self.spp, self.width, self.height] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.nonfinite.to_le_bytes());
        for v in self.sum.iter().chain(&self.sum_sq).chain(&self.sum_odd) {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    /// Reads and checks a film file; every error names the file and what is
    /// wrong with it.
    ///
    /// The header is read and checked first (its sizes against lancer's
    /// image limit, and the length they imply against the file's), so a
    /// damaged header costs no more than its own bytes: the sums are read
    /// only when the file holds exactly what the header says.
    pub fn read(path: &Path) -> Result<FilmPart> {
        use std::io::Read as _;
        let cannot = || format!("{}: cannot read", cut_path(path));
        let unusable = || format!("{}: not a usable film file", cut_path(path));
        let mut file = std::fs::File::open(path).with_context(cannot)?;
        let len = file.metadata().with_context(cannot)?.len();
        let mut bytes = Vec::new();
        (&mut file)
            .take(HEADER_BYTES as u64)
            .read_to_end(&mut bytes)
            .with_context(cannot)?;
        let expected = check_header(&bytes, len).with_context(unusable)?;
        // One byte more than expected, to tell a file that grew meanwhile.
        let rest = expected - bytes.len() as u64;
        bytes
            .try_reserve_exact(rest as usize + 1)
            .with_context(|| format!("{}: cannot hold its {expected} bytes", cut_path(path)))?;
        file.take(rest + 1)
            .read_to_end(&mut bytes)
            .with_context(cannot)?;
        Self::from_bytes(&bytes).with_context(unusable)
    }

    /// Parses and checks a film file's bytes.
    pub fn from_bytes(b: &[u8]) -> Result<FilmPart> {
        check_header(b, b.len() as u64)?;
        let body = b.len() - CRC_BYTES;
        let stored = u32_at(b, body);
        let actual = crc32fast::hash(&b[..body]);
        ensure!(
            stored == actual,
            "checksum mismatch (stored {stored:08x}, computed {actual:08x}): the file is damaged; render the part again"
        );
        // check_header made sure that the sums fill the body.
        let values = (body - HEADER_BYTES) / 24;
        let floats = |start: usize| -> Vec<f64> {
            b[start..start + 8 * values]
                .chunks_exact(8)
                .map(|c| {
                    let mut a = [0u8; 8];
                    a.copy_from_slice(c);
                    f64::from_le_bytes(a)
                })
                .collect()
        };
        let part = FilmPart {
            scene_hash: u64_at(b, 16),
            sampler: sampler_of(u32_at(b, 12))?,
            first: u32_at(b, 24),
            end: u32_at(b, 28),
            spp: u32_at(b, 32),
            width: u32_at(b, 36),
            height: u32_at(b, 40),
            nonfinite: u64_at(b, 44),
            sum: floats(HEADER_BYTES),
            sum_sq: floats(HEADER_BYTES + 8 * values),
            sum_odd: floats(HEADER_BYTES + 16 * values),
        };
        part.check()?;
        Ok(part)
    }

    /// Checks what the file's bytes do not: the sample range, the count of
    /// dropped samples, the sums' lengths, and every sum (finite; sums of
    /// squares also >= 0), naming the pixel and channel at fault.
    pub fn check(&self) -> Result<()> {
        let pixels = film_pixels(self.width, self.height)?;
        ensure!(
            self.first < self.end && self.end <= self.spp,
            "sample range {}..{} is not inside 0..{} (the scene's spp)",
            self.first,
            self.end,
            self.spp
        );
        // At most 2^31 pixels times 2^32 samples: no overflow in u64.
        let samples = pixels * u64::from(self.end - self.first);
        ensure!(
            self.nonfinite <= samples,
            "its header counts {} samples dropped for NaN or infinite radiance, but the part \
             holds only {samples} (samples {}..{} of {pixels} pixels): the header is damaged; \
             render the part again",
            self.nonfinite,
            self.first,
            self.end
        );
        let values = 3 * pixels;
        ensure!(
            self.sum.len() as u64 == values
                && self.sum_sq.len() as u64 == values
                && self.sum_odd.len() as u64 == values,
            "it holds {} radiance sums, {} sums of squares and {} sums of odd samples; a {}x{} \
             film holds {values} of each",
            self.sum.len(),
            self.sum_sq.len(),
            self.sum_odd.len(),
            self.width,
            self.height
        );
        let at = |i: usize| {
            let pixel = i / 3;
            (
                pixel % self.width as usize,
                pixel / self.width as usize,
                ["R", "G", "B"][i % 3],
            )
        };
        if let Some(i) = self.sum.iter().position(|s| !s.is_finite()) {
            let (x, y, channel) = at(i);
            bail!(
                "pixel ({x}, {y}): the radiance sum of {channel} is {}; a sum must be finite: \
                 the file is damaged; render the part again",
                self.sum[i]
            );
        }
        if let Some(i) = self.sum_odd.iter().position(|s| !s.is_finite()) {
            let (x, y, channel) = at(i);
            bail!(
                "pixel ({x}, {y}): the radiance sum of the odd samples of {channel} is {}; a sum \
                 must be finite: the file is damaged; render the part again",
                self.sum_odd[i]
            );
        }
        if let Some(i) = (self.sum_sq.iter()).position(|q| !(q.is_finite() && *q >= 0.0)) {
            let (x, y, channel) = at(i);
            bail!(
                "pixel ({x}, {y}): the sum of squares of {channel} is {}; a sum of squares must \
                 be finite and >= 0: the file is damaged; render the part again",
                self.sum_sq[i]
            );
        }
        Ok(())
    }
}

/// The sampler whose id (`SAMPLER_*`) a header holds.
fn sampler_of(id: u32) -> Result<Sampler> {
    Sampler::ALL
        .into_iter()
        .find(|s| s.id() == id)
        .with_context(|| {
            format!("its header names sampler {id}, which no lancer has: the header is damaged; render the part again")
        })
}

/// The little-endian u32 at byte `i` of `b`.
fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// The little-endian u64 at byte `i` of `b`.
fn u64_at(b: &[u8], i: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[i..i + 8]);
    u64::from_le_bytes(a)
}

/// The pixel count of a film's `width` x `height`, checked against
/// lancer's image limits ([`MAX_IMAGE_SIDE`], [`MAX_IMAGE_PIXELS`]): no
/// render writes a larger film, so a larger size is a damaged header.
fn film_pixels(width: u32, height: u32) -> Result<u64> {
    use crate::scene::{MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE};
    let damaged = "the header is damaged; render the part again";
    ensure!(
        width > 0 && height > 0,
        "its header claims {width} x {height} pixels; a film has at least one pixel: {damaged}"
    );
    for (what, side) in [("width", width), ("height", height)] {
        ensure!(
            side <= MAX_IMAGE_SIDE,
            "its header claims a {what} of {side} pixels; a film is at most {MAX_IMAGE_SIDE} \
             pixels {} (lancer's image limit): {damaged}",
            if what == "width" { "wide" } else { "high" }
        );
    }
    // Both sides are at most 2^20: the product fits.
    let pixels = u64::from(width) * u64::from(height);
    ensure!(
        pixels <= MAX_IMAGE_PIXELS,
        "its header claims {width} x {height} = {pixels} pixels; a film holds at most \
         {MAX_IMAGE_PIXELS} pixels (lancer's image limit): {damaged}"
    );
    Ok(pixels)
}

/// Checks the header at the start of `b` (at least its magic, then the
/// whole header) against a file of `len` bytes, before anything else is
/// read: the magic, the version, the image size against lancer's limits,
/// and the file's length against the one the size implies, computed in
/// checked arithmetic. Returns that length.
fn check_header(b: &[u8], len: u64) -> Result<u64> {
    ensure!(
        b.len() >= 8 && &b[..8] == MAGIC,
        "it does not start with {:?}: not written by `lancer render --film-out`",
        std::str::from_utf8(MAGIC).unwrap_or_default()
    );
    let smallest = (HEADER_BYTES + CRC_BYTES) as u64;
    ensure!(
        b.len() >= HEADER_BYTES && len >= smallest,
        "it is {len} bytes, shorter than the {smallest} of a header: truncated"
    );
    let version = u32_at(b, 8);
    // An older version this lancer cannot merge, and why
    let older = match version {
        1 => Some(
            "without the error estimate's half films (the sums of the odd samples) or the \
             sampler",
        ),
        2 => Some(
            "whose Sobol sampler drew each pixel's samples in two halves: its samples are not \
             this lancer's",
        ),
        _ => None,
    };
    if let Some(why) = older {
        bail!(
            "format version {version}, written by a lancer {why}; this lancer reads version \
             {VERSION}: render the part again with this lancer, or merge with the lancer that \
             rendered it"
        );
    }
    ensure!(
        version == VERSION,
        "format version {version}; this lancer reads version {VERSION}: merge with the lancer that rendered it"
    );
    let (width, height) = (u32_at(b, 36), u32_at(b, 40));
    let pixels = film_pixels(width, height)?;
    // Three sums of three f64 per pixel.
    let expected = pixels
        .checked_mul(72)
        .and_then(|sums| sums.checked_add(smallest))
        .filter(|&e| usize::try_from(e).is_ok())
        .with_context(|| format!("a {width}x{height} film does not fit in memory"))?;
    ensure!(
        len == expected,
        "it is {len} bytes, but a {width}x{height} film is {expected}: truncated or damaged"
    );
    Ok(expected)
}

/// A merged film: the image of all the parts' samples.
#[derive(Debug, Clone)]
pub struct Merged {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel (the scene's spp).
    pub spp: u32,
    /// The sampler that drew every part's samples.
    pub sampler: Sampler,
    /// Means, variances of the mean and error estimates, RGB per pixel.
    pub image: Resolved,
    /// Samples dropped for a NaN or infinite radiance, over all parts.
    pub nonfinite: u64,
}

/// Merges parts (with the file each came from, for messages): they must
/// share the scene hash and size, and cover `0..spp` exactly once. The sums
/// are added in f64 in sample order, whatever the order of the arguments.
pub fn merge(parts: &[(PathBuf, FilmPart)]) -> Result<Merged> {
    let Some((first_path, first)) = parts.first() else {
        bail!(
            "no film files given: pass the parts, e.g. `lancer merge part*.film --out image.exr`"
        );
    };
    for (path, p) in parts {
        p.check()
            .with_context(|| format!("{}: not a usable film file", cut_path(path)))?;
    }
    for (path, p) in &parts[1..] {
        ensure!(
            p.scene_hash == first.scene_hash,
            "{}: rendered from another scene than {} (scene hash {:016x}, not {:016x}); \
             every part must come from the same scene, settings, integrator and sampler",
            cut_path(path),
            cut_path(first_path),
            p.scene_hash,
            first.scene_hash
        );
        ensure!(
            p.sampler == first.sampler,
            "{}: drawn by the {} sampler, but {} by the {} sampler; render every part with \
             the same --sampler",
            cut_path(path),
            p.sampler,
            cut_path(first_path),
            first.sampler
        );
        ensure!(
            (p.width, p.height, p.spp) == (first.width, first.height, first.spp),
            "{}: {}x{} at {} spp, but {} is {}x{} at {} spp; render every part with the same size and spp",
            cut_path(path),
            p.width,
            p.height,
            p.spp,
            cut_path(first_path),
            first.width,
            first.height,
            first.spp
        );
    }
    let mut order: Vec<&(PathBuf, FilmPart)> = parts.iter().collect();
    order.sort_by_key(|(_, p)| (p.first, p.end));
    let mut next = 0u32;
    let mut previous: Option<&Path> = None;
    for (path, p) in &order {
        if p.first < next {
            bail!(
                "{}: samples {}..{} overlap {} (which ends at {next}); each sample must be in one part",
                cut_path(path),
                p.first,
                p.end,
                previous.map_or_else(String::new, cut_path)
            );
        }
        ensure!(
            p.first == next,
            "samples {next}..{} are missing: no part holds them (the parts must cover 0..{})",
            p.first,
            first.spp
        );
        next = p.end;
        previous = Some(path);
    }
    ensure!(
        next == first.spp,
        "samples {next}..{} are missing: no part holds them (the parts must cover 0..{})",
        first.spp,
        first.spp
    );
    let mut sum = vec![0.0f64; first.sum.len()];
    let mut sum_sq = vec![0.0f64; first.sum.len()];
    let mut sum_odd = vec![0.0f64; first.sum.len()];
    let mut nonfinite = 0;
    for (_, p) in &order {
        for (acc, v) in sum.iter_mut().zip(&p.sum) {
            *acc += v;
        }
        for (acc, v) in sum_sq.iter_mut().zip(&p.sum_sq) {
            *acc += v;
        }
        for (acc, v) in sum_odd.iter_mut().zip(&p.sum_odd) {
            *acc += v;
        }
        nonfinite = p.nonfinite.saturating_add(nonfinite);
    }
    Ok(Merged {
        width: first.width,
        height: first.height,
        spp: first.spp,
        sampler: first.sampler,
        image: resolve(&sum, &sum_sq, &sum_odd, 0, first.spp),
        nonfinite,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(first: u32, end: u32, hash: u64) -> FilmPart {
        let sum: Vec<f64> = (0..12).map(|i| f64::from(i * (end - first))).collect();
        FilmPart {
            scene_hash: hash,
            sampler: Sampler::Sobol,
            first,
            end,
            spp: 8,
            width: 2,
            height: 2,
            nonfinite: 0,
            sum_sq: sum.iter().map(|s| s * s).collect(),
            sum_odd: sum.iter().map(|s| 0.5 * s).collect(),
            sum,
        }
    }

    fn named(parts: &[FilmPart]) -> Vec<(PathBuf, FilmPart)> {
        parts
            .iter()
            .enumerate()
            .map(|(i, p)| (PathBuf::from(format!("p{i}.film")), p.clone()))
            .collect()
    }

    #[test]
    fn bytes_round_trip_and_layout_matches_the_table() {
        let p = part(2, 5, 0xdead_beef_0123_4567);
        let b = p.to_bytes();
        assert_eq!(b.len(), HEADER_BYTES + 24 * 12 + CRC_BYTES);
        assert_eq!(&b[..8], b"LNCRFILM");
        assert_eq!(u32::from_le_bytes(b[12..16].try_into().unwrap()), 1);
        assert_eq!(u32::from_le_bytes(b[24..28].try_into().unwrap()), 2);
        assert_eq!(FilmPart::from_bytes(&b).unwrap(), p);
    }

    #[test]
    fn every_damage_is_refused_with_its_reason() {
        let good = part(0, 8, 1).to_bytes();
        let err = |b: &[u8]| format!("{:#}", FilmPart::from_bytes(b).unwrap_err());
        let mut flipped = good.clone();
        flipped[HEADER_BYTES + 3] ^= 0x10;
        assert!(
            err(&flipped).starts_with("checksum mismatch"),
            "{}",
            err(&flipped)
        );
        assert!(err(&good[..good.len() - 1]).contains("truncated or damaged"));
        assert!(err(&good[..20]).contains("truncated"));
        assert!(err(b"PNG....").contains("does not start with \"LNCRFILM\""));
        let mut v4 = good.clone();
        v4[8] = 4;
        assert!(err(&v4).starts_with("format version 4; this lancer reads version 3"));
        for (version, why) in [
            (
                1,
                "format version 1, written by a lancer without the error estimate",
            ),
            (
                2,
                "format version 2, written by a lancer whose Sobol sampler",
            ),
        ] {
            let mut old = good.clone();
            old[8] = version;
            assert!(err(&old).contains(why), "{}", err(&old));
        }
        let mut sampler = good.clone();
        sampler[12] = 7;
        let crc = crc32fast::hash(&sampler[..sampler.len() - 4]);
        let at = sampler.len() - 4;
        sampler[at..].copy_from_slice(&crc.to_le_bytes());
        assert!(
            err(&sampler).contains("names sampler 7"),
            "{}",
            err(&sampler)
        );
    }

    #[test]
    fn merge_refuses_other_scenes_overlaps_and_gaps() {
        let e = |parts: &[FilmPart]| format!("{:#}", merge(&named(parts)).unwrap_err());
        assert!(e(&[part(0, 4, 1), part(4, 8, 2)])
            .starts_with("p1.film: rendered from another scene than p0.film"));
        let mut independent = part(4, 8, 1);
        independent.sampler = Sampler::Independent;
        assert!(e(&[part(0, 4, 1), independent])
            .starts_with("p1.film: drawn by the independent sampler, but p0.film by the sobol"));
        assert_eq!(
            e(&[part(0, 5, 1), part(4, 8, 1)]),
            "p1.film: samples 4..8 overlap p0.film (which ends at 5); each sample must be in one part"
        );
        assert_eq!(
            e(&[part(0, 3, 1), part(4, 8, 1)]),
            "samples 3..4 are missing: no part holds them (the parts must cover 0..8)"
        );
        assert_eq!(
            e(&[part(0, 4, 1)]),
            "samples 4..8 are missing: no part holds them (the parts must cover 0..8)"
        );
        assert!(e(&[]).starts_with("no film files given"));
        // The order of the arguments does not matter.
        let a = merge(&named(&[part(4, 8, 1), part(0, 4, 1)])).unwrap();
        let b = merge(&named(&[part(0, 4, 1), part(4, 8, 1)])).unwrap();
        assert_eq!(a.image, b.image);
        assert_eq!(a.image.mean[3], 3.0 * 8.0 / 8.0);
    }

    #[test]
    fn ranges_parse() {
        assert_eq!(parse_range("0..16"), Ok((0, 16)));
        assert!(parse_range("4..4").is_err());
        assert!(parse_range("4-8").is_err());
        assert!(parse_range("-1..3").is_err());
    }
}
