//! Renders split across machines: film files and their merge.
//!
//! `lancer render SCENE --samples A..B --film-out part.film` renders samples
//! A to B-1 of every pixel (the very samples a whole render draws: random
//! numbers depend only on seed, pixel, sample and dimension) and writes the
//! film's raw sums. `lancer merge part*.film --out image.exr` checks that the
//! parts come from one scene and cover `0..spp` once, adds their sums in f64
//! in sample order, and resolves them exactly as a whole render resolves its
//! film ([`resolve`](crate::render::film::resolve)).
//!
//! # File format, version 1 (all numbers little-endian)
//!
//! | bytes | what |
//! |---|---|
//! | 8 | magic `LNCRFILM` |
//! | 4 | format version, u32 (1) |
//! | 4 | reserved, u32 (0) |
//! | 8 | scene hash, u64 ([`scene_hash`]) |
//! | 4 + 4 | sample range: first, end (u32; the part holds first..end) |
//! | 4 | the scene's spp, u32 (what the parts must cover) |
//! | 4 + 4 | width, height (u32) |
//! | 8 | samples dropped for NaN or infinite radiance, u64 |
//! | 24 w h | radiance sums, f64, per pixel R, G, B, rows top to bottom |
//! | 24 w h | sums of squares, f64, same order |
//! | 4 | CRC-32 (IEEE, crc32fast) of every byte before it |

use crate::render::film::resolve;
use crate::render::kernels::Integrator;
use crate::scene::Scene;
use anyhow::{bail, ensure, Context as _, Result};
use std::path::{Path, PathBuf};

/// The magic at the start of a film file.
pub const MAGIC: &[u8; 8] = b"LNCRFILM";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;
/// Bytes before the sums.
const HEADER_BYTES: usize = 8 + 4 + 4 + 8 + 4 + 4 + 4 + 4 + 4 + 8;
/// Bytes of the checksum at the end.
const CRC_BYTES: usize = 4;

/// The raw film of samples `first..end` of every pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct FilmPart {
    /// [`scene_hash`] of the scene rendered.
    pub scene_hash: u64,
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
/// textures, and the integrator. The scene file's own path is left out, so
/// parts rendered from copies of a scene in different folders merge.
pub fn scene_hash(scene: &Scene, integrator: Integrator) -> Result<u64> {
    let mut canonical = scene.clone();
    canonical.source = PathBuf::new();
    canonical.warnings.clear();
    let mut h = crate::vk::Fnv::new().bytes(format!("{integrator:?}").as_bytes());
    for (path, bytes) in crate::scene::to_toml(&canonical, Path::new("scene.toml")) {
        h = h.bytes(path.to_string_lossy().as_bytes()).bytes(&bytes);
    }
    for m in &scene.materials {
        if let crate::scene::MaterialKind::Lambert {
            albedo: crate::scene::ColorSource::Texture(t),
        }
        | crate::scene::MaterialKind::Phong {
            diffuse: crate::scene::ColorSource::Texture(t),
            ..
        } = &m.kind
        {
            let bytes =
                std::fs::read(t).with_context(|| format!("{}: cannot read", t.display()))?;
            h = h.bytes(&bytes);
        }
    }
    Ok(h.finish())
}

impl FilmPart {
    /// The file's bytes (see the module's table).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(HEADER_BYTES + 16 * self.sum.len() + CRC_BYTES);
        b.extend_from_slice(MAGIC);
        for v in [VERSION, 0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.scene_hash.to_le_bytes());
        for v in [self.first, self.end, self.spp, self.width, self.height] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.nonfinite.to_le_bytes());
        for v in self.sum.iter().chain(&self.sum_sq) {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    /// Reads and checks a film file; every error names the file and what is
    /// wrong with it.
    pub fn read(path: &Path) -> Result<FilmPart> {
        let bytes =
            std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        Self::from_bytes(&bytes)
            .with_context(|| format!("{}: not a usable film file", path.display()))
    }

    /// Parses and checks a film file's bytes.
    pub fn from_bytes(b: &[u8]) -> Result<FilmPart> {
        ensure!(
            b.len() >= 8 && &b[..8] == MAGIC,
            "it does not start with {:?}: not written by `lancer render --film-out`",
            std::str::from_utf8(MAGIC).unwrap_or_default()
        );
        ensure!(
            b.len() >= HEADER_BYTES + CRC_BYTES,
            "it is {} bytes, shorter than the {} of a header: truncated",
            b.len(),
            HEADER_BYTES + CRC_BYTES
        );
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let u64_at = |i: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[i..i + 8]);
            u64::from_le_bytes(a)
        };
        let version = u32_at(8);
        ensure!(
            version == VERSION,
            "format version {version}; this lancer reads version {VERSION}: merge with the lancer that rendered it"
        );
        let (width, height) = (u32_at(36), u32_at(40));
        let values = width as u64 * height as u64 * 3;
        let expected = HEADER_BYTES as u64 + 16 * values + CRC_BYTES as u64;
        ensure!(
            b.len() as u64 == expected,
            "it is {} bytes, but a {width}x{height} film is {expected}: truncated or damaged",
            b.len()
        );
        let body = b.len() - CRC_BYTES;
        let stored = u32_at(body);
        let actual = crc32fast::hash(&b[..body]);
        ensure!(
            stored == actual,
            "checksum mismatch (stored {stored:08x}, computed {actual:08x}): the file is damaged; render the part again"
        );
        let floats = |start: usize| -> Vec<f64> {
            b[start..start + 8 * values as usize]
                .chunks_exact(8)
                .map(|c| {
                    let mut a = [0u8; 8];
                    a.copy_from_slice(c);
                    f64::from_le_bytes(a)
                })
                .collect()
        };
        let part = FilmPart {
            scene_hash: u64_at(16),
            first: u32_at(24),
            end: u32_at(28),
            spp: u32_at(32),
            width,
            height,
            nonfinite: u64_at(44),
            sum: floats(HEADER_BYTES),
            sum_sq: floats(HEADER_BYTES + 8 * values as usize),
        };
        ensure!(
            part.first < part.end && part.end <= part.spp,
            "sample range {}..{} is not inside 0..{} (the scene's spp)",
            part.first,
            part.end,
            part.spp
        );
        Ok(part)
    }
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
    /// Mean radiance, RGB per pixel.
    pub mean: Vec<f32>,
    /// Variance of the mean, RGB per pixel.
    pub var_of_mean: Vec<f32>,
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
    for (path, p) in &parts[1..] {
        ensure!(
            p.scene_hash == first.scene_hash,
            "{}: rendered from another scene than {} (scene hash {:016x}, not {:016x}); \
             every part must come from the same scene, settings and integrator",
            path.display(),
            first_path.display(),
            p.scene_hash,
            first.scene_hash
        );
        ensure!(
            (p.width, p.height, p.spp) == (first.width, first.height, first.spp),
            "{}: {}x{} at {} spp, but {} is {}x{} at {} spp; render every part with the same size and spp",
            path.display(),
            p.width,
            p.height,
            p.spp,
            first_path.display(),
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
                path.display(),
                p.first,
                p.end,
                previous.map_or_else(String::new, |q| q.display().to_string())
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
    let mut nonfinite = 0;
    for (_, p) in &order {
        for (acc, v) in sum.iter_mut().zip(&p.sum) {
            *acc += v;
        }
        for (acc, v) in sum_sq.iter_mut().zip(&p.sum_sq) {
            *acc += v;
        }
        nonfinite += p.nonfinite;
    }
    let (mean, var_of_mean) = resolve(&sum, &sum_sq, first.spp);
    Ok(Merged {
        width: first.width,
        height: first.height,
        spp: first.spp,
        mean,
        var_of_mean,
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
            first,
            end,
            spp: 8,
            width: 2,
            height: 2,
            nonfinite: 0,
            sum_sq: sum.iter().map(|s| s * s).collect(),
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
        assert_eq!(b.len(), HEADER_BYTES + 16 * 12 + CRC_BYTES);
        assert_eq!(&b[..8], b"LNCRFILM");
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
        let mut v2 = good.clone();
        v2[8] = 2;
        assert!(err(&v2).starts_with("format version 2; this lancer reads version 1"));
    }

    #[test]
    fn merge_refuses_other_scenes_overlaps_and_gaps() {
        let e = |parts: &[FilmPart]| format!("{:#}", merge(&named(parts)).unwrap_err());
        assert!(e(&[part(0, 4, 1), part(4, 8, 2)])
            .starts_with("p1.film: rendered from another scene than p0.film"));
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
        assert_eq!(a.mean, b.mean);
        assert_eq!(a.mean[3], 3.0 * 8.0 / 8.0);
    }

    #[test]
    fn ranges_parse() {
        assert_eq!(parse_range("0..16"), Ok((0, 16)));
        assert!(parse_range("4..4").is_err());
        assert!(parse_range("4-8").is_err());
        assert!(parse_range("-1..3").is_err());
    }
}
