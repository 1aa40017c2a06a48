//! Textures for the device: each material's image decoded (header checked
//! first), shrunk to fit the one texel binding when needed, and packed
//! behind a small header: integer images as sRGB RGBA8 texels, float images
//! (EXR, HDR) as linear RGB floats; after them, when a material reads a
//! mesh attribute, the attribute values of every triangle.

use crate::interface::{
    ATTRIBUTE_WORDS, NO_TEXTURE, TEXELS_ATTRIBUTE, TEXELS_MAPPED, TEXELS_RGB32F, TEXELS_SRGB8,
    TEX_FILTER_BILINEAR, TEX_FILTER_NEAREST, TEX_MAP_COLOR0, TEX_MAP_FILTER, TEX_MAP_IMAGE,
    TEX_MAP_PATTERN, TEX_MAP_WORDS, TEX_MAP_WRAP, TEX_PATTERN_BITMAP, TEX_PATTERN_CHECKERBOARD,
    TEX_WRAP_CLAMP, TEX_WRAP_MIRROR, TEX_WRAP_REPEAT,
};
use crate::scene::{
    ColorSource, MappedTexture, MaterialKind, Principled, Scene, TextureFilter, TexturePattern,
    TextureWrap,
};
use glam::Vec3;
use image::{Rgb32FImage, RgbaImage};

/// The key that names a material's diffuse texture in messages.
fn diffuse_key(m: &crate::scene::Material) -> &'static str {
    // OBJ materials are named `file.mtl:name` and take `map_Kd`
    if m.name.contains(".mtl:") {
        return "map_Kd";
    }
    match m.kind {
        MaterialKind::Phong { .. } => "diffuse_texture",
        MaterialKind::RoughPlastic { .. } => "diffuse_reflectance",
        MaterialKind::Principled(_) => "base_color",
        _ => "albedo_texture",
    }
}

/// One image as the device holds it: the file, whether its values are
/// used as stored (`raw`) rather than decoded from sRGB, and whether each
/// texel holds its colour's luminance in all three channels (an opacity,
/// Mitsuba's one-channel lookup).
type ImageKey<'a> = (&'a std::path::Path, bool, bool);

/// A colour of a material that may read an image: the colour, the key
/// that names it in messages, and whether it is read as one channel, its
/// luminance (Mitsuba's `eval_1`).
type Slot<'a> = (&'a ColorSource, &'a str, bool);

/// The texture slots a material has: diffuse colour, opacity, normal or
/// bump map, roughness along the bitangent, then a principled material's
/// weights (from [`LAYER_WEIGHTS`]).
pub const LAYERS: usize = LAYER_WEIGHTS + Principled::WEIGHTS;

/// The slot of a rough material's roughness along the bitangent.
const LAYER_ROUGHNESS_V: usize = 3;

/// The first slot of a principled material's weights, in the order of
/// [`Principled::WEIGHT_NAMES`].
pub const LAYER_WEIGHTS: usize = 4;

/// A material's slots: the four above, then a principled material's
/// weights.
fn layers<'a>(
    fixed: [Option<Slot<'a>>; LAYER_WEIGHTS],
    kind: &'a MaterialKind,
) -> [Option<Slot<'a>>; LAYERS] {
    let weights = match kind {
        MaterialKind::Principled(p) => p.weight_textures.as_deref(),
        _ => None,
    };
    std::array::from_fn(|k| match k.checked_sub(LAYER_WEIGHTS) {
        None => fixed[k],
        Some(w) => weights
            .and_then(|t| t[w].as_ref())
            .map(|c| (c, Principled::WEIGHT_NAMES[w], true)),
    })
}

/// The slots a material's kind fills: the first (its diffuse colour named
/// `diffuse`, a blend's weight, or a rough material's roughness along the
/// tangent) and the last (a rough material's roughness along the
/// bitangent).
fn kind_slots<'a>(kind: &'a MaterialKind, diffuse: &'a str) -> [Option<Slot<'a>>; 2] {
    if let MaterialKind::Blend { weight, .. } = kind {
        return [Some((weight, "weight", true)), None];
    }
    if let Some(t) = kind.alpha_textures() {
        return [
            t.u.as_ref().map(|c| (c, "alpha_u", true)),
            t.v.as_ref().map(|c| (c, "alpha_v", true)),
        ];
    }
    [kind.diffuse_source().map(|c| (c, diffuse, false)), None]
}

/// The image a colour reads, if any; `luminance` for an opacity.
fn image_of(c: &ColorSource, luminance: bool) -> Option<ImageKey<'_>> {
    match c {
        ColorSource::Constant(_) => None,
        ColorSource::Texture(p) => Some((p, false, luminance)),
        ColorSource::Mapped(m) => match &m.pattern {
            TexturePattern::Bitmap(p) => Some((p, m.raw, luminance)),
            TexturePattern::Checkerboard { .. } => None,
        },
        ColorSource::Attribute(_) => None,
    }
}

/// A texture with a header of its own after the images': a mapped
/// texture (its record, and the image it reads) or a mesh attribute (its
/// scale).
enum Extra {
    Mapped(MappedTexture, u32),
    Attribute(f32),
}

/// A texture read as an opacity: each texel's colour replaced by its
/// luminance in all three channels, in linear floats (so that the
/// bilinear lookup of any channel is the luminance of the lookup).
fn luminance_image(img: TextureImage) -> TextureImage {
    let linear = match img {
        TextureImage::Linear(img) => img,
        TextureImage::Srgb8(img) => {
            let decode = crate::gpu::texture_fit::srgb_to_linear;
            Rgb32FImage::from_fn(img.width(), img.height(), |x, y| {
                let p = img.get_pixel(x, y).0;
                image::Rgb([decode(p[0]), decode(p[1]), decode(p[2])])
            })
        }
    };
    let mut out = linear;
    for p in out.pixels_mut() {
        let l = crate::scene::mitsuba_luminance(glam::Vec3::from_array(p.0));
        p.0 = [l; 3];
    }
    TextureImage::Linear(out)
}

/// A mapped texture read as an opacity, by Mitsuba's one-channel lookup
/// (`eval_1`): a checkerboard's colours become the mean of their channels
/// (their own `eval_1`) and change places, since its `eval_1` puts
/// `color0` where the fractions of u and v disagree, the opposite of its
/// colour lookup (a bitmap's image is converted with the images).
fn luminance_mapping(t: &MappedTexture) -> MappedTexture {
    let mut t = t.clone();
    if let TexturePattern::Checkerboard { color0, color1 } = &mut t.pattern {
        let value = |c: glam::Vec3| glam::Vec3::splat(crate::scene::mitsuba_constant_value(c));
        (*color0, *color1) = (value(*color1), value(*color0));
    }
    t
}

/// The device record of a mapped texture (`TEXELS_MAPPED`): `to_uv`, the
/// pattern, wrap mode, filter and image index (`image`, of a bitmap), then
/// a checkerboard's two colours.
pub fn map_record(t: &MappedTexture, image: u32) -> [u32; TEX_MAP_WORDS as usize] {
    let mut r = [0u32; TEX_MAP_WORDS as usize];
    for (w, a) in r.iter_mut().zip(t.to_uv) {
        *w = a.to_bits();
    }
    r[TEX_MAP_WRAP as usize] = match t.wrap {
        TextureWrap::Repeat => TEX_WRAP_REPEAT,
        TextureWrap::Mirror => TEX_WRAP_MIRROR,
        TextureWrap::Clamp => TEX_WRAP_CLAMP,
    };
    r[TEX_MAP_FILTER as usize] = match t.filter {
        TextureFilter::Bilinear => TEX_FILTER_BILINEAR,
        TextureFilter::Nearest => TEX_FILTER_NEAREST,
    };
    match &t.pattern {
        TexturePattern::Bitmap(_) => {
            r[TEX_MAP_PATTERN as usize] = TEX_PATTERN_BITMAP;
            r[TEX_MAP_IMAGE as usize] = image;
        }
        TexturePattern::Checkerboard { color0, color1 } => {
            r[TEX_MAP_PATTERN as usize] = TEX_PATTERN_CHECKERBOARD;
            r[TEX_MAP_IMAGE as usize] = NO_TEXTURE;
            for (w, c) in r[TEX_MAP_COLOR0 as usize..]
                .iter_mut()
                .zip(color0.to_array().into_iter().chain(color1.to_array()))
            {
                *w = c.to_bits();
            }
        }
    }
    r
}

/// Textures packed into one `uint` buffer: a header of four words per
/// texture (first word of its texels, width, height, texel format), then
/// every texel: sRGB RGBA8 in one word ([`TEXELS_SRGB8`]), or linear RGB in
/// three 32-bit floats ([`TEXELS_RGB32F`]).
#[derive(Debug, Clone, Default)]
pub struct GpuTextures {
    /// Headers then texels.
    pub words: Vec<u32>,
    /// Texture indices of each material: its diffuse colour (a blend's
    /// weight, a rough material's roughness along the tangent), its
    /// opacity (a `mask`), its normal or bump map, a rough material's
    /// roughness along the bitangent and a principled material's weights
    /// (from [`LAYER_WEIGHTS`]), each `NO_TEXTURE` where constant or
    /// absent.
    pub material_layers: Vec<[u32; LAYERS]>,
    /// The same for each component of a blend, in the order of
    /// [`crate::scene::blend_components`] (its colour, roughness and
    /// weights only).
    pub component_layers: Vec<[u32; LAYERS]>,
    /// The texture index of each delta light (a spot's texture, a
    /// projector's irradiance image), `NO_TEXTURE` where it has none.
    pub light_textures: Vec<u32>,
    /// The mean linear colour of each delta light's texture, as the kernels
    /// read it (a checkerboard's two colours averaged; a bitmap's texels,
    /// whatever its `to_uv` and wrap mode); white where it has none. Light
    /// selection by power weighs the light by it.
    pub light_means: Vec<Vec3>,
    /// One line per texture shrunk to fit the binding, naming it, the
    /// material key, both sizes and the limit.
    pub warnings: Vec<String>,
}

/// The size of a texture file from its header, checked against
/// [`MAX_TEXTURE_TEXELS`](crate::scene::MAX_TEXTURE_TEXELS) before any
/// pixel is decoded. An EXR's data window (the pixels it stores, all of
/// which are decoded) is checked as well as its display window (the image).
pub fn texture_size(path: &std::path::Path) -> anyhow::Result<(u32, u32)> {
    use crate::scene::MAX_TEXTURE_TEXELS;
    use anyhow::Context as _;
    let cannot = || format!("cannot read texture {}", crate::util::text::cut_path(path));
    let (width, height) = image::ImageReader::open(path)
        .with_context(cannot)?
        .into_dimensions()
        .with_context(cannot)?;
    let texels = u64::from(width) * u64::from(height);
    anyhow::ensure!(
        texels <= MAX_TEXTURE_TEXELS,
        "texture {} is {width} x {height} = {texels} texels; lancer reads textures of at \
         most {MAX_TEXTURE_TEXELS} texels (4096 x 4096): downscale it",
        crate::util::text::cut_path(path)
    );
    if is_exr(path) {
        // The header was read once above; reading it again costs as little.
        let meta = exr::meta::MetaData::read_from_file(path, false).with_context(cannot)?;
        crate::util::exr_file::check_exr_blocks(
            &meta,
            &format!("texture {}", crate::util::text::cut_path(path)),
        )?;
        for header in &meta.headers {
            let (w, h) = (header.layer_size.width(), header.layer_size.height());
            let stored = (w as u64).checked_mul(h as u64);
            anyhow::ensure!(
                stored.is_some_and(|n| n <= MAX_TEXTURE_TEXELS),
                "texture {} stores a data window of {w} x {h} = {} texels (its image is \
                 {width} x {height}); lancer reads textures of at most {MAX_TEXTURE_TEXELS} \
                 texels (4096 x 4096): crop it to its display window, or downscale it",
                crate::util::text::cut_path(path),
                stored.map_or_else(|| String::from("more than 2^64"), |n| n.to_string())
            );
        }
    }
    Ok((width, height))
}

/// Whether a texture file is an OpenEXR image, by its extension (as the
/// decoder picks its format).
fn is_exr(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// A decoded texture: what its file stores, as the device reads it.
#[derive(Debug, Clone, PartialEq)]
pub enum TextureImage {
    /// An integer image (PNG, JPEG, ...; 8 or 16 bits), sRGB-encoded: kept
    /// as sRGB RGBA8, decoded per texel on the device.
    Srgb8(RgbaImage),
    /// A float image (EXR, HDR): linear RGB, kept as 32-bit floats.
    Linear(Rgb32FImage),
}

impl TextureImage {
    /// Width and height in texels.
    pub fn dimensions(&self) -> (u32, u32) {
        match self {
            TextureImage::Srgb8(img) => img.dimensions(),
            TextureImage::Linear(img) => img.dimensions(),
        }
    }

    /// Device words per texel.
    fn words_per_texel(float: bool) -> u64 {
        if float {
            3
        } else {
            1
        }
    }

    /// The mean linear colour of the texels (an sRGB texel decoded first).
    fn mean(&self) -> Vec3 {
        use crate::gpu::texture_fit::srgb_to_linear;
        let (w, h) = self.dimensions();
        let sum: glam::DVec3 = match self {
            TextureImage::Srgb8(img) => {
                let lut: [f64; 256] = std::array::from_fn(|v| f64::from(srgb_to_linear(v as u8)));
                img.pixels()
                    .map(|p| glam::DVec3::from_array([0, 1, 2].map(|k| lut[usize::from(p.0[k])])))
                    .sum()
            }
            TextureImage::Linear(img) => img
                .pixels()
                .map(|p| glam::DVec3::new(p.0[0].into(), p.0[1].into(), p.0[2].into()))
                .sum(),
        };
        (sum / (f64::from(w) * f64::from(h)).max(1.0)).as_vec3()
    }

    /// The texture shrunk to `width` x `height`, keeping its mean colour.
    fn downscaled(&self, width: u32, height: u32) -> TextureImage {
        use crate::gpu::texture_fit::{downscale, downscale_linear};
        match self {
            TextureImage::Srgb8(img) => TextureImage::Srgb8(downscale(img, width, height)),
            TextureImage::Linear(img) => TextureImage::Linear(downscale_linear(img, width, height)),
        }
    }

    /// The texel format word and the texels as device words, taking the
    /// image: float texels become words in place, without a copy.
    fn into_words(self) -> (u32, Vec<u32>) {
        match self {
            TextureImage::Srgb8(img) => (
                TEXELS_SRGB8,
                img.pixels().map(|p| u32::from_le_bytes(p.0)).collect(),
            ),
            TextureImage::Linear(img) => (
                TEXELS_RGB32F,
                bytemuck::allocation::cast_vec::<f32, u32>(img.into_raw()),
            ),
        }
    }
}

/// Whether a texture file holds floats (EXR, HDR): read from its header
/// alone, before anything is decoded.
fn holds_floats(path: &std::path::Path) -> anyhow::Result<bool> {
    use anyhow::Context as _;
    let cannot = || format!("cannot read texture {}", crate::util::text::cut_path(path));
    let decoder = image::ImageReader::open(path)
        .with_context(cannot)?
        .with_guessed_format()
        .with_context(cannot)?
        .into_decoder()
        .with_context(cannot)?;
    use image::ImageDecoder as _;
    Ok(matches!(
        decoder.color_type(),
        image::ColorType::Rgb32F | image::ColorType::Rgba32F
    ))
}

/// Decodes one texture file (the format by its content): an integer image
/// to sRGB RGBA8, a float image (EXR, HDR) to linear RGB floats, never
/// squeezed to 8 bits.
///
/// A `raw` integer image keeps its values as stored, scaled to [0, 1] and
/// never decoded from sRGB (Mitsuba's `raw`), as linear RGB floats.
///
/// The size in the file's header is checked by [`texture_size`] before any
/// pixel is decoded, and the decoder may allocate no more than such a
/// texture needs, so a small file claiming a huge image is refused at once.
pub fn load_texture(path: &std::path::Path, raw: bool) -> anyhow::Result<TextureImage> {
    use crate::scene::MAX_TEXTURE_TEXELS;
    use anyhow::Context as _;
    texture_size(path)?;
    if is_exr(path) {
        // Decoded straight into linear RGB, so the texture is held once
        let (width, height, rgb) = crate::util::exr_file::read_exr(path).with_context(|| {
            format!("cannot read texture {}", crate::util::text::cut_path(path))
        })?;
        let img = Rgb32FImage::from_raw(width, height, rgb)
            .context("the EXR reader returns 3 floats per pixel")?;
        return Ok(TextureImage::Linear(img));
    }
    // Decoded pixels take at most 16 bytes each (RGBA, 32-bit floats).
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_TEXTURE_TEXELS * 16);
    let mut reader = image::ImageReader::open(path)
        .with_context(|| format!("cannot read texture {}", crate::util::text::cut_path(path)))?;
    reader.limits(limits);
    let decoded = reader
        .decode()
        .with_context(|| format!("cannot read texture {}", crate::util::text::cut_path(path)))?;
    // Converted by value: the decoded image is freed as soon as the
    // converted one exists (and not copied at all when it is already RGB
    // floats or RGBA8), so a texture at the size limit is held at most twice.
    Ok(match decoded {
        image::DynamicImage::ImageRgb32F(img) => TextureImage::Linear(img),
        image::DynamicImage::ImageRgba32F(_) => TextureImage::Linear(decoded.into_rgb32f()),
        _ if raw => TextureImage::Linear(decoded.into_rgb32f()),
        _ => TextureImage::Srgb8(decoded.into_rgba8()),
    })
}

/// Loads every texture the materials and lights use, each file once, into at most
/// `max_bytes` bytes (the device binding's limit): when they do not fit,
/// the largest are shrunk to fit (by an area-weighted box filter in linear
/// light), each with a warning.
pub fn pack_textures(scene: &Scene, max_bytes: u64) -> anyhow::Result<GpuTextures> {
    use crate::gpu::texture_fit::{fitted_size, texel_cap, HEADER_WORDS, WORD_BYTES};
    // The colours that may read an image, in the device's slots: each
    // material's diffuse colour (a blend's weight, a rough material's
    // roughness along the tangent), opacity, normal or bump map, a rough
    // material's roughness along the bitangent, and a principled
    // material's textured weights, with the key that
    // names it and whether it is read as one channel, its luminance
    // (Mitsuba's `eval_1`: an opacity, a bump map's heights, a weight, a
    // roughness). A blend's components follow the materials, each with
    // its own colour and roughness
    let components = crate::scene::blend_components(&scene.materials);
    let mut sources: Vec<[Option<Slot>; LAYERS]> = (scene.materials.iter())
        .map(|m| {
            let [first, roughness_v] = kind_slots(&m.kind, diffuse_key(m));
            let fixed = [
                first,
                m.opacity.as_ref().map(|c| (c, "opacity", true)),
                (m.normal_map.as_ref()).map(|n| match n.bump_scale {
                    Some(_) => (&n.texture, "bumpmap", true),
                    None => (&n.texture, "normalmap", false),
                }),
                roughness_v,
            ];
            layers(fixed, &m.kind)
        })
        .collect();
    sources.extend(components.iter().map(|kind| {
        let [first, roughness_v] = kind_slots(kind, "blend component's diffuse colour");
        layers([first, None, None, roughness_v], kind)
    }));
    // The lights' images follow, one slot each
    sources.extend(scene.lights.iter().map(|l| {
        let mut slots = [None; LAYERS];
        slots[0] = l.texture().map(|c| (c, "texture", false));
        slots
    }));
    // The material each slot belongs to, by name (a component by its
    // blend's), then the lights, by number
    let light_names: Vec<String> = (0..scene.lights.len())
        .map(|k| format!("light {k}"))
        .collect();
    let owners: Vec<&str> = (scene.materials.iter().map(|m| m.name.as_str()))
        .chain(scene.materials.iter().flat_map(|m| match m.kind {
            MaterialKind::Blend { .. } => [m.name.as_str(); 2].to_vec(),
            _ => Vec::new(),
        }))
        .chain(light_names.iter().map(String::as_str))
        .collect();
    // Each image once (a file, raw or decoded), with the first material
    // (and key) that uses it
    let mut used: Vec<(ImageKey, String)> = Vec::new();
    let mut images: Vec<[u32; LAYERS]> = Vec::with_capacity(sources.len());
    for (name, slots) in owners.iter().zip(&sources) {
        let mut index = [NO_TEXTURE; LAYERS];
        for (slot, source) in index.iter_mut().zip(slots) {
            let Some(image) = source.and_then(|(c, _, lum)| image_of(c, lum)) else {
                continue;
            };
            *slot = match used.iter().position(|q| q.0 == image) {
                Some(i) => i as u32,
                None => {
                    let key = source.map_or("", |s| s.1);
                    used.push((image, format!("material {name:?}, {key}")));
                    used.len() as u32 - 1
                }
            };
        }
        images.push(index);
    }
    // A mapped texture gets a header of its own after the images', and a
    // record; a mesh attribute a header; a plain texture is its image
    let mut extras: Vec<Extra> = Vec::new();
    let mut texture_index = |c: Option<Slot>, image: u32| match c {
        Some((ColorSource::Mapped(t), _, lum)) => {
            extras.push(Extra::Mapped(
                if lum {
                    luminance_mapping(t)
                } else {
                    (**t).clone()
                },
                image,
            ));
            (used.len() + extras.len() - 1) as u32
        }
        Some((ColorSource::Attribute(a), _, _)) => {
            extras.push(Extra::Attribute(a.scale));
            (used.len() + extras.len() - 1) as u32
        }
        _ => image,
    };
    // A roughness with one texture for both directions (Mitsuba's `alpha`)
    // reads it once: its second slot repeats the first's index
    let mut material_layers: Vec<[u32; LAYERS]> = (sources.iter().zip(&images))
        .map(|(slots, image)| {
            let mut layers = [NO_TEXTURE; LAYERS];
            for k in 0..LAYERS {
                let same_roughness = k == LAYER_ROUGHNESS_V
                    && slots[k].is_some()
                    && slots[k].map(|s| s.0) == slots[0].map(|s| s.0);
                layers[k] = if same_roughness {
                    layers[0]
                } else {
                    texture_index(slots[k], image[k])
                };
            }
            layers
        })
        .collect();
    let light_textures: Vec<u32> = (material_layers.split_off(sources.len() - scene.lights.len()))
        .into_iter()
        .map(|layers| layers[0])
        .collect();
    let component_layers = material_layers.split_off(scene.materials.len());
    // Every header is checked before any texture is decoded, and before
    // the sizes are added: each is then at most MAX_TEXTURE_TEXELS, so the
    // sums below cannot overflow.
    let sizes = (used.iter())
        .map(|((path, _, _), _)| texture_size(path))
        .collect::<anyhow::Result<Vec<(u32, u32)>>>()?;
    let texels = (used.iter().zip(&sizes))
        .map(|(((path, raw, lum), _), &(w, h))| {
            let words = TextureImage::words_per_texel(*raw || *lum || holds_floats(path)?);
            Ok((u64::from(w) * u64::from(h), words))
        })
        .collect::<anyhow::Result<Vec<(u64, u64)>>>()?;
    // Texels are addressed by 32-bit word offsets on the device
    let max_words = (max_bytes / WORD_BYTES).min(u64::from(u32::MAX));
    let mapped = (extras.iter())
        .filter(|e| matches!(e, Extra::Mapped(..)))
        .count();
    let header_words = (used.len() + extras.len()) as u64 * HEADER_WORDS
        + mapped as u64 * u64::from(TEX_MAP_WORDS);
    // A mesh attribute's values: ATTRIBUTE_WORDS per triangle, by its
    // shading index, when any texture reads them
    let attribute_words = if extras.iter().any(|e| matches!(e, Extra::Attribute(_))) {
        scene.triangles.len() as u64 * u64::from(ATTRIBUTE_WORDS)
    } else {
        0
    };
    anyhow::ensure!(
        attribute_words == 0 || header_words + attribute_words <= max_words,
        "the mesh attributes of the scene's {} triangles take {} bytes, more than the {max_bytes} \
         bytes one device binding holds: read attributes on fewer triangles",
        scene.triangles.len(),
        attribute_words * WORD_BYTES
    );
    let room = max_words.saturating_sub(header_words + attribute_words);
    let cap = texel_cap(&texels, room);
    let total_bytes = (header_words + texels.iter().map(|&(t, w)| t * w).sum::<u64>()) * WORD_BYTES;
    anyhow::ensure!(
        cap != Some(0),
        "the scene's {} textures cannot fit in {max_bytes} bytes, the most one device binding \
         holds, even at one texel each: use fewer textures",
        used.len()
    );
    // Room for every texel from the start: growing the vector by doubling
    // would hold two copies of the largest texture at once
    let fitted_words: u64 = (sizes.iter().zip(&texels))
        .map(|(&(width, height), &(_, per_texel))| {
            let (w, h) = cap.map_or((width, height), |cap| fitted_size(width, height, cap));
            u64::from(w) * u64::from(h) * per_texel
        })
        .sum();
    let mut words = Vec::with_capacity((header_words + fitted_words + attribute_words) as usize);
    words.resize(header_words as usize, 0u32);
    let mut at = (used.len() + extras.len()) * HEADER_WORDS as usize;
    for (j, extra) in extras.iter().enumerate() {
        let entry = (used.len() + j) * 4;
        if let Extra::Mapped(t, image) = extra {
            words[entry..entry + 4].copy_from_slice(&[at as u32, 0, 0, TEXELS_MAPPED]);
            words[at..at + TEX_MAP_WORDS as usize].copy_from_slice(&map_record(t, *image));
            at += TEX_MAP_WORDS as usize;
        }
    }
    // The image each light reads (its one slot, last among the owners):
    // the only images whose mean colour is needed (light selection by power)
    let light_images: Vec<u32> = images[images.len() - scene.lights.len()..]
        .iter()
        .map(|slots| slots[0])
        .collect();
    let mut warnings = Vec::new();
    let mut means = vec![Vec3::ONE; used.len()];
    for (i, (((path, raw, lum), key), &(width, height))) in used.iter().zip(&sizes).enumerate() {
        let mut img = load_texture(path, *raw)?;
        if *lum {
            img = luminance_image(img);
        }
        if light_images.contains(&(i as u32)) {
            means[i] = img.mean();
        }
        if let Some(cap) = cap {
            let (w, h) = fitted_size(width, height, cap);
            if (w, h) != (width, height) {
                img = img.downscaled(w, h);
                warnings.push(format!(
                    "texture {} ({key}) downscaled from {width} x {height} to {w} x {h} texels, \
                     keeping its mean colour: the scene's textures need {total_bytes} bytes, more \
                     than the {max_bytes} bytes one device binding holds; give a smaller image \
                     to choose the filtering yourself",
                    crate::util::text::cut_path(path)
                ));
            }
        }
        let (w, h) = img.dimensions();
        let (format, texel_words) = img.into_words();
        words[i * 4] = words.len() as u32;
        words[i * 4 + 1] = w;
        words[i * 4 + 2] = h;
        words[i * 4 + 3] = format;
        words.extend(texel_words);
    }
    // The mesh attributes' values follow the images: the values at the
    // three vertices of each triangle (zero where it has none), by its
    // shading index; each attribute texture's header holds their first
    // word and its scale
    let first_attribute_word = words.len() as u32;
    if attribute_words > 0 {
        for t in &scene.triangles {
            let values = t
                .attribute
                .map_or([Vec3::ZERO; 3], |a| scene.mesh_attributes[a as usize]);
            words.extend(values.iter().flat_map(|v| v.to_array()).map(f32::to_bits));
        }
    }
    for (j, extra) in extras.iter().enumerate() {
        if let Extra::Attribute(scale) = extra {
            let entry = (used.len() + j) * 4;
            words[entry..entry + 4].copy_from_slice(&[
                first_attribute_word,
                scale.to_bits(),
                0,
                TEXELS_ATTRIBUTE,
            ]);
        }
    }
    // A light's mean is its image's, or its checkerboard's two colours
    // averaged
    let light_means = (scene.lights.iter().zip(&light_images))
        .map(|(light, &image)| match light.texture() {
            _ if image != NO_TEXTURE => means[image as usize],
            Some(ColorSource::Mapped(t)) => match &t.pattern {
                TexturePattern::Checkerboard { color0, color1 } => 0.5 * (*color0 + *color1),
                TexturePattern::Bitmap(_) => Vec3::ONE,
            },
            _ => Vec3::ONE,
        })
        .collect();
    Ok(GpuTextures {
        words,
        material_layers,
        component_layers,
        light_textures,
        light_means,
        warnings,
    })
}
