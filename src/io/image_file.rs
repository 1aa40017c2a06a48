//! Image files: PNG (sRGB, 8-bit) and OpenEXR (linear, 32-bit float).
//!
//! Every file is written to a temporary file in the destination's own folder
//! and then renamed over the destination, so a failed or interrupted run never
//! leaves half a file behind (see [`write_atomically`]).

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};

use crate::render::kernels::Integrator;
use crate::render::stats::RenderStats;
use crate::render::RenderOutput;
use crate::util::color::{srgb_decode, to_srgb8};

/// The output extensions [`write_image`] understands, for error messages.
const SUPPORTED: &str = ".png (8-bit sRGB) and .exr (32-bit float linear RGB)";

/// The output formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Png,
    Exr,
}

/// Picks the format from the extension of `path`, case-insensitively.
fn format_of(path: &Path) -> Result<Format> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => Ok(Format::Png),
        Some("exr") => Ok(Format::Exr),
        Some(other) => bail!(
            "{}: unsupported image extension \".{other}\"; supported are {SUPPORTED}",
            path.display()
        ),
        None => bail!(
            "{}: the output file has no extension; supported are {SUPPORTED}",
            path.display()
        ),
    }
}

/// Writes a file atomically: `write` fills a temporary file created in the
/// same folder as `path`, which is then flushed, synced and renamed over
/// `path`.
///
/// If `write` or anything after it fails, the temporary file is removed and
/// `path` is left as it was (absent, or its previous contents). A missing
/// destination folder is reported as such. Errors name `path`.
pub fn write_atomically<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<&mut File>) -> Result<()>,
{
    persist(write_temp(path, write)?, path)
}

/// Fills a temporary file beside `path` with `write`, flushed and synced;
/// the file is removed when dropped unless [`persist`]ed.
fn write_temp<F>(path: &Path, write: F) -> Result<tempfile::NamedTempFile>
where
    F: FnOnce(&mut BufWriter<&mut File>) -> Result<()>,
{
    let mut tmp = temp_file_for(path)?;
    {
        let mut w = BufWriter::new(tmp.as_file_mut());
        write(&mut w).with_context(|| format!("{}: write failed", path.display()))?;
        w.flush()
            .with_context(|| format!("{}: write failed", path.display()))?;
    }
    tmp.as_file()
        .sync_all()
        .with_context(|| format!("{}: write failed", path.display()))?;
    Ok(tmp)
}

/// Renames a finished temporary file over `path`.
fn persist(tmp: tempfile::NamedTempFile, path: &Path) -> Result<()> {
    tmp.persist(path).map_err(|e| e.error).with_context(|| {
        format!(
            "{}: cannot rename the finished file into place",
            path.display()
        )
    })?;
    Ok(())
}

/// A temporary file in the folder of `path`, named after it, with the mode a
/// plain `File::create` would give; removed when dropped unless persisted.
fn temp_file_for(path: &Path) -> Result<tempfile::NamedTempFile> {
    check_destination(path, false)?;
    let dir = folder_of(path);
    let name = path
        .file_name()
        .with_context(|| format!("{}: not a file name", path.display()))?;
    let mut builder = tempfile::Builder::new();
    let prefix = format!(".{}.", name.to_string_lossy());
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        // NamedTempFile defaults to 0600; give the result the same mode a
        // plain File::create would (0666 less the umask).
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder
        .tempfile_in(dir)
        .with_context(|| format!("{}: cannot create a temporary file", path.display()))
}

/// Writes a linear RGB image to `path`, in the format its extension names
/// (case-insensitive).
///
/// `rgb` is row-major, top row first, 3 floats per pixel, so its length must
/// be `width * height * 3`.
///
/// - `.png`: each value is clamped to [0, 1], sRGB-encoded with the exact
///   piecewise curve, and rounded to the nearest of 256 levels (NaN gives 0).
/// - `.exr`: 32-bit float linear RGB, bit-exact (NaN and infinities are
///   stored as they are).
///
/// Any other extension is an error that lists the supported ones. The file is
/// written atomically (see [`write_atomically`]); errors name `path`.
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[f32]) -> Result<()> {
    write_image_with(path, width, height, rgb, &Metadata::default())
}

/// Encodes a linear RGB image in the format the extension of `path` names,
/// as [`write_image`] writes it.
pub fn encode_image(path: &Path, width: u32, height: u32, rgb: &[f32]) -> Result<Vec<u8>> {
    encode_image_with(path, width, height, rgb, &Metadata::default())
}

/// Writes a render's image to `path` as [`write_image`] does, with its
/// settings ([`Metadata::of_stats`]) recorded in the file.
pub fn write_render(path: &Path, render: &RenderOutput) -> Result<()> {
    let meta = Metadata::of_stats(&render.stats);
    write_image_with(path, render.width, render.height, &render.mean, &meta)
}

/// Writes a linear RGB image as [`write_image`] does, with `meta` recorded
/// in the file (see [`encode_image_with`]).
pub fn write_image_with(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[f32],
    meta: &Metadata,
) -> Result<()> {
    let bytes = encode_image_with(path, width, height, rgb, meta)?;
    write_atomically(path, |w| Ok(w.write_all(&bytes)?))
}

/// Encodes a linear RGB image as [`encode_image`] does, with `meta` stored
/// in the file: as header attributes of type `string` in an EXR, as `tEXt`
/// chunks in a PNG, each named `lancer.KEY` (see [`Metadata`]).
pub fn encode_image_with(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[f32],
    meta: &Metadata,
) -> Result<Vec<u8>> {
    let format = format_of(path)?;
    ensure!(
        width > 0 && height > 0,
        "{}: cannot write an empty image ({width}x{height})",
        path.display()
    );
    let expected = width as usize * height as usize * 3;
    ensure!(
        rgb.len() == expected,
        "{}: {width}x{height} RGB image needs {expected} floats, got {}",
        path.display(),
        rgb.len()
    );
    let mut out = Vec::new();
    match format {
        Format::Png => encode_png(&mut out, width, height, rgb, meta)
            .with_context(|| format!("{}: PNG encoding failed", path.display()))?,
        Format::Exr => encode_exr(&mut out, width, height, rgb, meta)
            .with_context(|| format!("{}: EXR encoding failed", path.display()))?,
    }
    Ok(out)
}

/// 8-bit sRGB PNG with one `tEXt` chunk per metadata entry.
fn encode_png(
    out: &mut Vec<u8>,
    width: u32,
    height: u32,
    rgb: &[f32],
    meta: &Metadata,
) -> Result<()> {
    let bytes: Vec<u8> = rgb.iter().map(|&x| to_srgb8(x)).collect();
    let mut encoder = png::Encoder::new(out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    for (key, value) in meta.entries() {
        encoder.add_text_chunk(key, value)?;
    }
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&bytes)?;
    writer.finish()?;
    Ok(())
}

/// 32-bit float linear RGB EXR with one `string` attribute per metadata
/// entry.
fn encode_exr(
    out: &mut Vec<u8>,
    width: u32,
    height: u32,
    rgb: &[f32],
    meta: &Metadata,
) -> Result<()> {
    use exr::prelude::{AttributeValue, Image, SpecificChannels, Text, WritableImage};
    let w = width as usize;
    let mut image = Image::from_channels(
        (w, height as usize),
        SpecificChannels::rgb(|p: exr::math::Vec2<usize>| {
            let i = (p.y() * w + p.x()) * 3;
            (rgb[i], rgb[i + 1], rgb[i + 2])
        }),
    );
    for (key, value) in meta.entries() {
        // `entries` gives Latin-1 text only, which is what EXR text holds
        let (Some(key), Some(value)) = (Text::new_or_none(key), Text::new_or_none(value)) else {
            continue;
        };
        image
            .attributes
            .other
            .insert(key, AttributeValue::Text(value));
    }
    image.write().to_buffered(std::io::Cursor::new(out))?;
    Ok(())
}

/// The settings of a render, as lancer records them in the images it writes
/// and reads them back ([`read_metadata`]). Each set field is one entry
/// named `lancer.` and the field's name (`lancer.spp`, `lancer.seed`,
/// `lancer.max_depth`, `lancer.integrator`, `lancer.sampler`, `lancer.render_seconds`,
/// `lancer.device`, `lancer.driver`, `lancer.version`), its value as text.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Metadata {
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Seed of every random number.
    pub seed: Option<u32>,
    /// Longest path in segments from the camera.
    pub max_depth: Option<u32>,
    /// The estimator: `nee` or `bsdf`.
    pub integrator: Option<String>,
    /// The sampler: `independent` or `sobol`.
    pub sampler: Option<String>,
    /// Wall-clock seconds of rendering.
    pub render_seconds: Option<f64>,
    /// The Vulkan device.
    pub device: Option<String>,
    /// The driver and its version.
    pub driver: Option<String>,
    /// lancer's version and commit ([`crate::util::VERSION`]).
    pub version: Option<String>,
}

/// What every metadata entry's name starts with.
pub const METADATA_PREFIX: &str = "lancer.";

impl Metadata {
    /// The settings and figures of a finished render, with this lancer's
    /// [`VERSION`](crate::util::VERSION).
    pub fn of_stats(stats: &RenderStats) -> Metadata {
        let integrator = match stats.integrator {
            Integrator::Nee => "nee",
            Integrator::Bsdf => "bsdf",
        };
        Metadata {
            spp: Some(stats.spp),
            seed: Some(stats.seed),
            max_depth: Some(stats.max_depth),
            integrator: Some(integrator.to_string()),
            sampler: Some(stats.sampler.name().to_string()),
            render_seconds: Some(stats.wall_seconds),
            device: Some(stats.device.clone()),
            driver: Some(stats.driver.clone()),
            version: Some(crate::util::VERSION.to_string()),
        }
    }

    /// The set fields as `(name, value)` entries, in a fixed order. Text
    /// outside Latin-1 (which EXR and PNG `tEXt` hold) becomes `?`.
    pub fn entries(&self) -> Vec<(String, String)> {
        let number = |v: Option<u32>| v.map(|v| v.to_string());
        let fields = [
            ("spp", number(self.spp)),
            ("seed", number(self.seed)),
            ("max_depth", number(self.max_depth)),
            ("integrator", self.integrator.clone()),
            ("sampler", self.sampler.clone()),
            // `{}` of an f64 is its shortest exact form, so it reads back equal
            ("render_seconds", self.render_seconds.map(|s| s.to_string())),
            ("device", self.device.clone()),
            ("driver", self.driver.clone()),
            ("version", self.version.clone()),
        ];
        fields
            .into_iter()
            .filter_map(|(name, value)| {
                let latin1 = value?
                    .chars()
                    .map(|c| if u32::from(c) < 256 { c } else { '?' })
                    .collect();
                Some((format!("{METADATA_PREFIX}{name}"), latin1))
            })
            .collect()
    }

    /// Reads the fields back from `(name, value)` entries. Entries without
    /// the `lancer.` prefix, or with a name lancer does not know, are
    /// ignored; a number that does not parse is an error naming the entry.
    pub fn from_entries(entries: impl IntoIterator<Item = (String, String)>) -> Result<Metadata> {
        let mut meta = Metadata::default();
        for (key, value) in entries {
            let Some(name) = key.strip_prefix(METADATA_PREFIX) else {
                continue;
            };
            let uint = |v: &str| {
                v.parse::<u32>()
                    .with_context(|| format!("{key} = {v:?} is not a whole number"))
            };
            match name {
                "spp" => meta.spp = Some(uint(&value)?),
                "seed" => meta.seed = Some(uint(&value)?),
                "max_depth" => meta.max_depth = Some(uint(&value)?),
                "integrator" => meta.integrator = Some(value),
                "sampler" => meta.sampler = Some(value),
                "render_seconds" => {
                    meta.render_seconds = Some(
                        value
                            .parse()
                            .with_context(|| format!("{key} = {value:?} is not a number"))?,
                    )
                }
                "device" => meta.device = Some(value),
                "driver" => meta.driver = Some(value),
                "version" => meta.version = Some(value),
                _ => {}
            }
        }
        Ok(meta)
    }
}

/// Reads the [`Metadata`] lancer stored in a PNG or EXR file (see
/// [`encode_image_with`]). A file without it (written by another program)
/// gives an empty [`Metadata`]; errors name `path`.
pub fn read_metadata(path: &Path) -> Result<Metadata> {
    let entries = match format_of(path)? {
        Format::Exr => {
            let meta = exr::meta::MetaData::read_from_file(path, false)
                .with_context(|| format!("{}: not a readable OpenEXR file", path.display()))?;
            let mut entries = Vec::new();
            for header in &meta.headers {
                let attributes = header
                    .shared_attributes
                    .other
                    .iter()
                    .chain(&header.own_attributes.other);
                for (key, value) in attributes {
                    if let exr::meta::attribute::AttributeValue::Text(text) = value {
                        entries.push((key.to_string(), text.to_string()));
                    }
                }
            }
            entries
        }
        Format::Png => {
            let file =
                File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
            let reader = png::Decoder::new(BufReader::new(file))
                .read_info()
                .with_context(|| format!("{}: not a readable PNG file", path.display()))?;
            let info = reader.info();
            let latin1 = info
                .uncompressed_latin1_text
                .iter()
                .map(|c| (c.keyword.clone(), c.text.clone()));
            let utf8 = info
                .utf8_text
                .iter()
                .filter_map(|c| Some((c.keyword.clone(), c.get_text().ok()?)));
            latin1.chain(utf8).collect()
        }
    };
    Metadata::from_entries(entries)
        .with_context(|| format!("{}: bad lancer metadata", path.display()))
}

/// Checks, before any work, that `path` can be an output file: a file name
/// in a folder that exists, not a folder itself, and, for an image
/// (`image = true`), a supported extension. Errors name `path` and say what
/// to change.
pub fn check_destination(path: &Path, image: bool) -> Result<()> {
    if image {
        format_of(path)?;
    }
    ensure!(
        !path.is_dir(),
        "{}: is a folder; give a file name",
        path.display()
    );
    path.file_name()
        .with_context(|| format!("{}: not a file name", path.display()))?;
    let dir = folder_of(path);
    ensure!(
        dir.is_dir(),
        "{}: output directory {} does not exist; create it first",
        path.display(),
        dir.display()
    );
    Ok(())
}

/// The folder a file `path` lies in (`.` for a bare file name).
pub fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// The output files of one command, written together: each goes to a
/// temporary file beside its destination, and all are renamed into place
/// only once every one of them was written, so a run that fails (a full
/// disk, a bad path) leaves none of its files behind.
#[derive(Debug, Default)]
pub struct Outputs {
    files: Vec<(PathBuf, Vec<u8>)>,
}

impl Outputs {
    /// Adds a file to write at [`Outputs::commit`].
    pub fn add(&mut self, path: &Path, bytes: Vec<u8>) {
        self.files.push((path.to_path_buf(), bytes));
    }

    /// Adds an image with its metadata, encoded as [`encode_image_with`]
    /// encodes it.
    pub fn add_image(
        &mut self,
        path: &Path,
        width: u32,
        height: u32,
        rgb: &[f32],
        meta: &Metadata,
    ) -> Result<()> {
        let bytes = encode_image_with(path, width, height, rgb, meta)?;
        self.add(path, bytes);
        Ok(())
    }

    /// Writes every file to a temporary name, flushed and synced, then
    /// renames them all into place. When a write fails, every temporary file
    /// is removed and no destination is touched.
    pub fn commit(self) -> Result<()> {
        let mut staged = Vec::with_capacity(self.files.len());
        for (path, bytes) in &self.files {
            staged.push((write_temp(path, |w| Ok(w.write_all(bytes)?))?, path));
        }
        for (tmp, path) in staged {
            persist(tmp, path)?;
        }
        Ok(())
    }
}

pub use crate::util::exr_file::{check_exr_blocks, read_exr, MAX_EXR_BLOCK_BYTES};

/// The image files [`read_image`] understands, for error messages.
const READABLE: &str = ".png (8- or 16-bit, sRGB) and .exr (linear)";

/// Reads an image file as linear RGB: returns `(width, height, rgb)` with
/// `rgb` row-major, top row first, 3 floats per pixel. The format comes from
/// the extension, case-insensitively:
///
/// - `.exr`: read as it is stored, linear (see [`read_exr`]).
/// - `.png`, 8 or 16 bits per channel, grey or RGB, with or without alpha:
///   each code is scaled to [0, 1] (divided by 255 or 65535) and decoded to
///   linear with [`srgb_decode`]. Grey is copied to all three channels; alpha
///   is dropped, not multiplied in.
///
/// Errors name `path` and say what is wrong: a missing file, an extension
/// other than the supported ones (which the message lists), or a file that
/// cannot be decoded.
pub fn read_image(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    ensure!(path.exists(), "{}: no such file", path.display());
    ensure!(
        !path.is_dir(),
        "{}: is a directory, not an image",
        path.display()
    );
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => read_exr(path),
        Some("png") => read_png(path),
        Some(other) => bail!(
            "{}: cannot read images with the extension \".{other}\"; supported are {READABLE}",
            path.display()
        ),
        None => bail!(
            "{}: the file has no extension, so its format is unknown; supported are {READABLE}",
            path.display()
        ),
    }
}

/// Reads a PNG as linear RGB (see [`read_image`]).
fn read_png(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let image = image::ImageReader::with_format(BufReader::new(file), image::ImageFormat::Png)
        .decode()
        .with_context(|| format!("{}: not a readable PNG file", path.display()))?;
    let (w, h) = (image.width(), image.height());
    let sixteen_bit = image.color().bytes_per_pixel() / image.color().channel_count() > 1;
    let rgb = if sixteen_bit {
        image
            .into_rgb16()
            .into_raw()
            .into_iter()
            .map(|v| srgb_decode(f32::from(v) / 65535.0))
            .collect()
    } else {
        let lut: Vec<f32> = (0..=255u8)
            .map(|v| srgb_decode(f32::from(v) / 255.0))
            .collect();
        image
            .into_rgb8()
            .into_raw()
            .into_iter()
            .map(|v| lut[usize::from(v)])
            .collect()
    };
    Ok((w, h, rgb))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::util::color::srgb_encode;
    use image::codecs::openexr::OpenExrEncoder;
    use image::codecs::png::PngEncoder;
    use image::{ExtendedColorType, ImageEncoder};

    /// A small image with values across the interesting range.
    fn sample_image() -> (u32, u32, Vec<f32>) {
        let vals = [0.0, 0.001, 0.003_130_8, 0.18, 0.5, 1.0, 2.0, -1.0, 0.05];
        (3, 1, vals.to_vec())
    }

    /// The names in `dir`, sorted.
    pub(crate) fn dir_entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    /// An EXR whose data window is part of its display window reads as the
    /// display window, the stored pixels in their place and black around
    /// them, alpha dropped: the image crate's decoder gives the same.
    #[test]
    fn exr_data_window_lands_in_its_display_window() {
        use exr::prelude::*;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("window.exr");
        let layer = Layer::new(
            Vec2(2, 2),
            LayerAttributes {
                layer_position: Vec2(1, 1),
                ..LayerAttributes::named("")
            },
            Encoding::UNCOMPRESSED,
            SpecificChannels::rgba(|p: Vec2<usize>| {
                let v = (1 + p.x() + 2 * p.y()) as f32;
                (v, 10.0 * v, 100.0 * v, 0.5f32)
            }),
        );
        let mut image = Image::from_layer(layer);
        image.attributes.display_window = IntegerBounds::new(Vec2(0, 0), Vec2(4, 3));
        image.write().to_file(&path).unwrap();

        let (w, h, rgb) = read_exr(&path).unwrap();
        assert_eq!((w, h), (4, 3));
        let at = |x: usize, y: usize| &rgb[3 * (4 * y + x)..3 * (4 * y + x) + 3];
        assert_eq!(at(0, 0), [0.0, 0.0, 0.0]);
        assert_eq!(at(1, 1), [1.0, 10.0, 100.0]);
        assert_eq!(at(2, 1), [2.0, 20.0, 200.0]);
        assert_eq!(at(1, 2), [3.0, 30.0, 300.0]);
        assert_eq!(at(2, 2), [4.0, 40.0, 400.0]);
        assert_eq!(at(3, 2), [0.0, 0.0, 0.0]);
        let general = image::open(&path).unwrap().into_rgb32f();
        assert_eq!(general.dimensions(), (4, 3));
        assert_eq!(general.into_raw(), rgb);
    }

    #[test]
    fn png_round_trip_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.PNG"); // extension is case-insensitive
        let (w, h, rgb) = sample_image();
        write_image(&path, w, h, &rgb).unwrap();
        let img = image::open(&path).unwrap();
        assert_eq!(img.color(), image::ColorType::Rgb8);
        let bytes = img.into_rgb8().into_raw();
        // 0 -> 0; 0.001 -> 12.92e-3*255 = 3.29 -> 3; knee -> 0.04045*255 =
        // 10.31 -> 10; 0.18 -> 117.65 -> 118; 0.5 -> 187.52 -> 188; 1 -> 255;
        // 2 clamps to 255; -1 clamps to 0; 0.05 -> 0.2478*255 = 63.19 -> 63.
        assert_eq!(bytes, vec![0, 3, 10, 118, 188, 255, 255, 0, 63]);
        assert_eq!(dir_entries(dir.path()), vec!["a.PNG".to_string()]);
    }

    #[test]
    fn png_nonfinite_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nf.png");
        let rgb = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        write_image(&path, 1, 1, &rgb).unwrap();
        let bytes = image::open(&path).unwrap().into_rgb8().into_raw();
        assert_eq!(bytes, vec![0, 255, 0]);
    }

    #[test]
    fn exr_exact_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.exr");
        let (w, h) = (7u32, 5u32);
        let mut rgb: Vec<f32> = (0..w * h * 3)
            .map(|i| (i as f32 * 0.123_456_7).sin() * 1000.0 + 1e-7 * i as f32)
            .collect();
        rgb[0] = 1e30;
        rgb[1] = 1e-30; // denormal-ish small value
        rgb[2] = -3.5;
        rgb[3] = f32::INFINITY;
        write_image(&path, w, h, &rgb).unwrap();
        let (rw, rh, back) = read_exr(&path).unwrap();
        assert_eq!((rw, rh), (w, h));
        assert_eq!(back.len(), rgb.len());
        for (a, b) in rgb.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        // Top row first: pixel (0,0) is the first triple, (6,0) the 7th.
        assert_eq!(back[18].to_bits(), rgb[18].to_bits());
    }

    #[test]
    fn exr_read_drops_alpha() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rgba.exr");
        let rgba: Vec<f32> = vec![0.1, 0.2, 0.3, 0.5, 4.0, 5.0, 6.0, 1.0];
        let bytes: Vec<u8> = rgba.iter().flat_map(|x| x.to_ne_bytes()).collect();
        write_atomically(&path, |w| {
            OpenExrEncoder::new(w).write_image(&bytes, 2, 1, ExtendedColorType::Rgba32F)?;
            Ok(())
        })
        .unwrap();
        let (w, h, rgb) = read_exr(&path).unwrap();
        assert_eq!((w, h), (2, 1));
        assert_eq!(rgb, vec![0.1, 0.2, 0.3, 4.0, 5.0, 6.0]);
    }

    #[test]
    fn bad_extension_is_an_error_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["c.jpg", "noext", "d.png.bak"] {
            let path = dir.path().join(name);
            let err = write_image(&path, 1, 1, &[0.5; 3]).unwrap_err();
            let msg = format!("{err:#}");
            assert!(msg.contains(".png") && msg.contains(".exr"), "{msg}");
            assert!(msg.contains(name), "{msg}");
        }
        assert!(dir_entries(dir.path()).is_empty());
    }

    #[test]
    fn wrong_length_is_an_error_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.exr");
        let err = write_image(&path, 2, 2, &[0.5; 11]).unwrap_err();
        assert!(format!("{err:#}").contains("12"), "{err:#}");
        assert!(write_image(&path, 0, 2, &[]).is_err());
        assert!(dir_entries(dir.path()).is_empty());
    }

    #[test]
    fn missing_directory_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/x.png");
        let msg = format!("{:#}", write_image(&path, 1, 1, &[0.5; 3]).unwrap_err());
        assert!(msg.contains("does not exist"), "{msg}");
        assert!(msg.contains("x.png"), "{msg}");
    }

    #[test]
    fn failed_write_leaves_no_partial_file() {
        // The rename fails because the destination is a non-empty directory;
        // this works even when the tests run as root.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("taken.exr");
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("keep"), b"x").unwrap();
        let err = write_image(&path, 1, 1, &[0.5; 3]).unwrap_err();
        assert!(format!("{err:#}").contains("taken.exr"), "{err:#}");
        assert_eq!(dir_entries(dir.path()), vec!["taken.exr".to_string()]);

        // A failing writer: the temporary file goes, an old file survives.
        let old = dir.path().join("old.png");
        std::fs::write(&old, b"previous").unwrap();
        let err = write_atomically(&old, |w| {
            w.write_all(&[0u8; 100_000])?;
            bail!("simulated failure")
        })
        .unwrap_err();
        assert!(format!("{err:#}").contains("simulated failure"));
        assert_eq!(std::fs::read(&old).unwrap(), b"previous");
        assert_eq!(
            dir_entries(dir.path()),
            vec!["old.png".to_string(), "taken.exr".to_string()]
        );
    }

    #[cfg(unix)]
    #[test]
    fn read_only_directory_fails_cleanly() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let ro = dir.path().join("ro");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        let path = ro.join("x.png");
        let result = write_image(&path, 1, 1, &[0.5; 3]);
        let writable = result.is_ok(); // root ignores directory permissions
        if !writable {
            let msg = format!("{:#}", result.unwrap_err());
            assert!(msg.contains("x.png"), "{msg}");
            assert!(dir_entries(&ro).is_empty());
        }
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn file_mode_matches_plain_create() {
        // Not tempfile's 0600: the same mode File::create gives (umask applied).
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let path = dir.path().join("m.png");
        write_image(&path, 1, 1, &[0.5; 3]).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&path), mode(&plain));
    }

    #[test]
    fn overwrites_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("o.exr");
        write_image(&path, 1, 1, &[1.0, 2.0, 3.0]).unwrap();
        write_image(&path, 1, 1, &[4.0, 5.0, 6.0]).unwrap();
        assert_eq!(read_exr(&path).unwrap().2, vec![4.0, 5.0, 6.0]);
        assert_eq!(dir_entries(dir.path()), vec!["o.exr".to_string()]);
    }

    #[test]
    fn read_image_png_8bit_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.png");
        let (w, h) = (4u32, 3u32);
        let rgb: Vec<f32> = (0..w * h * 3).map(|i| i as f32 / 30.0).collect();
        write_image(&path, w, h, &rgb).unwrap();
        let (rw, rh, back) = read_image(&path).unwrap();
        assert_eq!((rw, rh), (w, h));
        // Each value comes back as the decoded 8-bit code it was stored as.
        for (x, y) in rgb.iter().zip(&back) {
            let want = srgb_decode(f32::from(to_srgb8(*x)) / 255.0);
            assert_eq!(y.to_bits(), want.to_bits(), "{x} -> {y}");
            // And that is within half an 8-bit sRGB step of the input,
            // clamped to [0, 1].
            let x = x.min(1.0);
            assert!((srgb_encode(*y) - srgb_encode(x)).abs() <= 0.5 / 255.0 + 1e-6);
        }
        // 1 and above read back as exactly 1; 0 as 0.
        assert_eq!(back[0], 0.0);
        assert_eq!(back[30], 1.0);
        assert!(back[30..].iter().all(|&v| v == 1.0), "{back:?}");
    }

    #[test]
    fn read_image_png_16bit_grey_and_alpha() {
        let dir = tempfile::tempdir().unwrap();
        // 16-bit RGBA: alpha is dropped, codes are divided by 65535.
        let path = dir.path().join("deep.png");
        let codes: [u16; 8] = [0, 32768, 65535, 1000, 65535, 1, 2, 3];
        let bytes: Vec<u8> = codes.iter().flat_map(|v| v.to_ne_bytes()).collect();
        write_atomically(&path, |w| {
            PngEncoder::new(w).write_image(&bytes, 2, 1, ExtendedColorType::Rgba16)?;
            Ok(())
        })
        .unwrap();
        let (w, h, rgb) = read_image(&path).unwrap();
        assert_eq!((w, h), (2, 1));
        let want: Vec<f32> = [0u16, 32768, 65535, 65535, 1, 2]
            .iter()
            .map(|&c| srgb_decode(f32::from(c) / 65535.0))
            .collect();
        assert_eq!(rgb, want);
        assert!((rgb[1] - 0.214_04).abs() < 1e-4, "{}", rgb[1]);

        // 8-bit grey: copied to the three channels.
        let grey = dir.path().join("grey.png");
        write_atomically(&grey, |w| {
            PngEncoder::new(w).write_image(&[0, 128, 255], 3, 1, ExtendedColorType::L8)?;
            Ok(())
        })
        .unwrap();
        let (_, _, rgb) = read_image(&grey).unwrap();
        let mid = srgb_decode(128.0 / 255.0);
        assert_eq!(rgb, vec![0.0, 0.0, 0.0, mid, mid, mid, 1.0, 1.0, 1.0]);
    }

    #[test]
    fn read_image_exr_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lin.EXR");
        let rgb = vec![0.25, -1.5, 1e6, f32::NAN, 0.0, 7.0];
        write_image(&path, 1, 2, &rgb).unwrap();
        let (w, h, back) = read_image(&path).unwrap();
        assert_eq!((w, h), (1, 2));
        for (a, b) in rgb.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }

    #[test]
    fn read_image_errors_name_the_file_and_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.exr");
        let msg = format!("{:#}", read_image(&missing).unwrap_err());
        assert!(
            msg.contains("missing.exr") && msg.contains("no such file"),
            "{msg}"
        );

        for name in ["pic.jpg", "noext"] {
            let path = dir.path().join(name);
            std::fs::write(&path, b"data").unwrap();
            let msg = format!("{:#}", read_image(&path).unwrap_err());
            assert!(msg.contains(name), "{msg}");
            assert!(msg.contains(".png") && msg.contains(".exr"), "{msg}");
        }

        let junk = dir.path().join("junk.png");
        std::fs::write(&junk, b"not a png at all").unwrap();
        let msg = format!("{:#}", read_image(&junk).unwrap_err());
        assert!(msg.contains("junk.png") && msg.contains("PNG"), "{msg}");

        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"not an exr").unwrap();
        let msg = format!("{:#}", read_image(&junk).unwrap_err());
        assert!(msg.contains("junk.exr") && msg.contains("OpenEXR"), "{msg}");

        let sub = dir.path().join("sub.png");
        std::fs::create_dir(&sub).unwrap();
        let msg = format!("{:#}", read_image(&sub).unwrap_err());
        assert!(
            msg.contains("sub.png") && msg.contains("directory"),
            "{msg}"
        );
    }

    /// Every field comes back from both formats as written; f64 seconds
    /// to the last bit, text outside Latin-1 as `?`; the EXR's pixels stay
    /// bit-exact; a file without metadata reads as empty; a malformed
    /// number is an error naming its entry.
    #[test]
    fn metadata_round_trips_through_exr_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h, rgb) = sample_image();
        let meta = Metadata {
            spp: Some(4096),
            seed: Some(u32::MAX),
            max_depth: Some(1_000_000),
            integrator: Some("nee".into()),
            sampler: Some("sobol".into()),
            render_seconds: Some(0.1 + 0.2),
            device: Some("llvmpipe (LLVM 15.0.7, 256 bits)".into()),
            driver: Some("Mesa 25.0.7 \u{2013} d\u{e9}j\u{e0} vu".into()),
            version: Some(crate::util::VERSION.into()),
        };
        let expected = Metadata {
            driver: Some("Mesa 25.0.7 ? d\u{e9}j\u{e0} vu".into()),
            ..meta.clone()
        };
        for name in ["m.exr", "m.png"] {
            let path = dir.path().join(name);
            write_image_with(&path, w, h, &rgb, &meta).unwrap();
            assert_eq!(read_metadata(&path).unwrap(), expected, "{name}");
            let plain = dir.path().join(format!("plain-{name}"));
            write_image(&plain, w, h, &rgb).unwrap();
            assert_eq!(
                read_metadata(&plain).unwrap(),
                Metadata::default(),
                "{name}"
            );
        }
        let (_, _, back) = read_exr(&dir.path().join("m.exr")).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&rgb));

        let bad = Metadata::from_entries([("lancer.spp".to_string(), "many".to_string())]);
        let err = format!("{:#}", bad.unwrap_err());
        assert!(
            err.contains("lancer.spp = \"many\" is not a whole number"),
            "{err}"
        );
        let foreign = Metadata::from_entries([
            ("Software".to_string(), "GIMP".to_string()),
            ("lancer.future_key".to_string(), "1".to_string()),
        ]);
        assert_eq!(foreign.unwrap(), Metadata::default());
    }

    #[test]
    fn outputs_are_written_together_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h, rgb) = sample_image();
        let mut outputs = Outputs::default();
        outputs
            .add_image(&dir.path().join("a.exr"), w, h, &rgb, &Metadata::default())
            .unwrap();
        outputs.add(&dir.path().join("b.json"), b"{}\n".to_vec());
        outputs.commit().unwrap();
        assert_eq!(dir_entries(dir.path()), ["a.exr", "b.json"]);
        assert_eq!(std::fs::read(dir.path().join("b.json")).unwrap(), b"{}\n");
        let (_, _, back) = read_exr(&dir.path().join("a.exr")).unwrap();
        assert_eq!(back, rgb);

        // A file whose folder is gone fails the whole set: nothing new appears
        let mut outputs = Outputs::default();
        outputs.add(&dir.path().join("c.json"), b"1".to_vec());
        outputs.add(&dir.path().join("gone/d.json"), b"2".to_vec());
        let e = format!("{:#}", outputs.commit().unwrap_err());
        assert!(e.contains("does not exist"), "{e}");
        assert_eq!(dir_entries(dir.path()), ["a.exr", "b.json"]);
    }

    #[test]
    fn destinations_are_checked_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        assert!(check_destination(&dir.path().join("x.png"), true).is_ok());
        assert!(check_destination(&dir.path().join("x.json"), false).is_ok());
        let e = format!(
            "{:#}",
            check_destination(&dir.path().join("x.bmp"), true).unwrap_err()
        );
        assert!(e.contains("unsupported image extension"), "{e}");
        let e = format!(
            "{:#}",
            check_destination(&dir.path().join("no/x.png"), true).unwrap_err()
        );
        assert!(e.contains("does not exist"), "{e}");
        let e = format!("{:#}", check_destination(dir.path(), false).unwrap_err());
        assert!(e.contains("is a folder"), "{e}");
    }
}
