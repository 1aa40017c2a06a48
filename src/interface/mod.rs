//! The one home of every constant shared between Rust and GLSL, but the
//! binding numbers, which the device interface table declares with their
//! buffers (`src/gpu/bindings.rs`).
//!
//! `build.rs` includes this file and passes each entry of [`SHADER_DEFINES`]
//! to shaderc as a macro, so kernels never repeat a number written here. One
//! macro writes both the Rust constant and its shader define, so the two
//! lists cannot drift apart. This file must stay free of `use` items and
//! crate paths: `build.rs` compiles it as a module of its own.

/// Threads per workgroup of every 1-D kernel. Kernels get it as a
/// specialisation constant (`SPEC_WORKGROUP_SIZE`) when their pipeline is
/// built, so the local size and the Rust dispatch sizes cannot disagree. It
/// is not a shader macro: GLSL reads it back as `gl_WorkGroupSize.x`.
pub const WORKGROUP_SIZE: u32 = 64;

/// Writes each `NAME = value;` entry as a documented `pub const NAME: u32`
/// and collects them all, in order, into [`SHADER_DEFINES`].
macro_rules! shader_constants {
    ($($(#[$doc:meta])* $name:ident = $value:expr;)*) => {
        $($(#[$doc])* pub const $name: u32 = $value;)*

        /// Every constant above, as `(macro name, value)` for the shader compiler.
        pub const SHADER_DEFINES: &[(&str, u32)] = &[$((stringify!($name), $name)),*];
    };
}

shader_constants! {
    /// Depth of the per-thread BVH traversal stack.
    BVH_STACK_SIZE = 32;

    /// Primitives per BVH leaf at most.
    BVH_MAX_LEAF_PRIMS = 4;
    /// Low bits of a device node reference that hold a leaf's primitive
    /// count (0 for an interior node); the index is in the bits above.
    BVH_REF_COUNT_BITS = 3;
    /// Node pairs or primitives a device node reference can index.
    BVH_REF_INDEX_LIMIT = 1 << (32 - 3);

    /// Most samples of one pixel in one wave. The accumulate kernel runs one
    /// thread per pixel that loops over them, and that loop must stay short:
    /// llvmpipe stops any shader loop after 65,535 iterations, and a GPU
    /// watchdog dislikes long-running threads.
    MAX_WAVE_SAMPLES_PER_PIXEL = 1024;

    /// Primitive kind tag: sphere.
    PRIM_SPHERE = 0;
    /// Primitive kind tag: triangle.
    PRIM_TRIANGLE = 1;
    /// Bits of `Primitive.meta.x` below the flags: the kind tag (`PRIM_*`)
    /// lives in the low bits, the flags (`PRIM_FLAG_*`) above them.
    PRIM_KIND_BITS = 8;
    /// Primitive flag: the triangle has vertex normals.
    PRIM_FLAG_NORMALS = 1;
    /// Primitive flag: the triangle has texture coordinates.
    PRIM_FLAG_UVS = 2;
    /// Primitive flag: the sphere takes Mitsuba's texture coordinates and
    /// tangent in its own frame, whose local x and y axes are `Primitive.b`
    /// and `.c` (xyz), local z being `b.w` (±1, a mirror) times x × y.
    PRIM_FLAG_MITSUBA_FRAME = 4;

    /// Index of the shadow queue among the queue headers (after the ray queues).
    SHADOW_QUEUE = 2;
    /// Number of queue headers: the ray queues and the shadow queue.
    QUEUE_HEADER_COUNT = 3;
    /// Sampler id (`SAMPLER`, set by `SPEC_SAMPLER`): independent uniform
    /// numbers, a hash of (seed, pixel, sample, dimension).
    SAMPLER_INDEPENDENT = 0;
    /// Sampler id: shuffled, Owen-scrambled Sobol points (Burley 2020).
    SAMPLER_SOBOL = 1;
    /// Sobol dimensions the Sobol sampler draws from: 0 (van der Corput)
    /// and 1 (Pascal's triangle mod 2), which the kernels compute in closed
    /// form (`shaders/common/sampler.glsl`), then 2 and 3, which a pair
    /// draw takes to make one 4D point with the pair it is partnered with,
    /// from their direction numbers ([`SOBOL_POLYNOMIALS`]).
    SOBOL_DIMENSIONS = 4;
    /// Random dimensions that the generate kernel uses (pixel jitter, lens).
    RNG_DIMS_CAMERA = 4;
    /// Dimension of the camera's pixel position, a pair.
    RNG_DIM_PIXEL = 0;
    /// Dimension of the camera's lens position, a pair: partnered with the
    /// pixel position (one 4D point) when the camera has a lens.
    RNG_DIM_LENS = 2;
    /// Random dimensions each bounce of the shade kernel uses: the
    /// `RNG_DIM_*` offsets below, from the bounce's first dimension.
    RNG_DIMS_PER_BOUNCE = 6;
    /// Offset of a bounce's light sample, a pair: its first number picks
    /// the emitter and is then reused, rescaled, with the second for the
    /// point on it (`sample_light`), so one pair stays one stratified pair.
    /// It is partnered (one 4D point) with the BSDF direction of the bounce
    /// before, which chose the point it lights; at the first hit, with the
    /// pixel position unless the lens has taken that.
    RNG_DIM_LIGHT = 0;
    /// Offset of a bounce's BSDF direction, a pair.
    RNG_DIM_BSDF = 2;
    /// Offset of a bounce's BSDF lobe choice, one number.
    RNG_DIM_LOBE = 4;
    /// Offset of a bounce's Russian roulette decision, one number.
    RNG_DIM_ROULETTE = 5;
    /// Texture index meaning "no texture".
    NO_TEXTURE = 0xFFFF_FFFF;
    /// Texel format (fourth header word of a texture): sRGB-encoded RGBA8,
    /// one word per texel, decoded to linear per texel.
    TEXELS_SRGB8 = 0;
    /// Texel format: linear RGB as three 32-bit floats, three words per
    /// texel (EXR and HDR files).
    TEXELS_RGB32F = 1;
    /// Texel format: a Mitsuba texture with a lookup of its own (compiled
    /// in by `SPEC_HAS_TEX_MAPPING`); the header's first word is the word
    /// offset of its record of `TEX_MAP_WORDS` words: the `to_uv` affine
    /// map (six floats, row by row, in Mitsuba's coordinates, v = 0 at the
    /// top), the pattern (`TEX_PATTERN_*`), the wrap mode (`TEX_WRAP_*`),
    /// the filter (`TEX_FILTER_*`), the bitmap's texture index, then the
    /// checkerboard's `color0` and `color1` (three floats each).
    TEXELS_MAPPED = 2;
    /// Words of a mapped texture's record (see `TEXELS_MAPPED`).
    TEX_MAP_WORDS = 16;
    /// Texel format: a mesh attribute (Mitsuba's `mesh_attribute`,
    /// compiled in by `SPEC_HAS_MESH_ATTRIBUTES`); the header's first word
    /// is the word offset of the attribute values, `ATTRIBUTE_WORDS` per
    /// triangle by its shading index, its second the texture's scale (f32
    /// bits).
    TEXELS_ATTRIBUTE = 3;
    /// Words of a triangle's mesh attribute values: linear RGB at its
    /// three vertices, nine floats.
    ATTRIBUTE_WORDS = 9;
    /// Word of a mapped texture's record that holds its pattern
    /// (`TEX_PATTERN_*`); words 0 to 5 hold `to_uv`.
    TEX_MAP_PATTERN = 6;
    /// Word of the record that holds the wrap mode (`TEX_WRAP_*`).
    TEX_MAP_WRAP = 7;
    /// Word of the record that holds the filter (`TEX_FILTER_*`).
    TEX_MAP_FILTER = 8;
    /// Word of the record that holds the bitmap's texture index.
    TEX_MAP_IMAGE = 9;
    /// First of the three words of the record that hold a checkerboard's `color0`.
    TEX_MAP_COLOR0 = 10;
    /// First of the three words of the record that hold a checkerboard's `color1`.
    TEX_MAP_COLOR1 = 13;
    /// Mapped texture pattern: an image (the record's texture index).
    TEX_PATTERN_BITMAP = 0;
    /// Mapped texture pattern: Mitsuba's checkerboard.
    TEX_PATTERN_CHECKERBOARD = 1;
    /// Wrap mode of a mapped bitmap: the image repeats.
    TEX_WRAP_REPEAT = 0;
    /// Wrap mode: the image repeats mirrored every other period.
    TEX_WRAP_MIRROR = 1;
    /// Wrap mode: the edge texels extend outwards.
    TEX_WRAP_CLAMP = 2;
    /// Filter of a mapped bitmap: bilinear between texel centres.
    TEX_FILTER_BILINEAR = 0;
    /// Filter of a mapped bitmap: the texel the point falls in.
    TEX_FILTER_NEAREST = 1;

    /// Hit record value of `prim` for a ray that escaped the scene.
    NO_HIT = 0xFFFF_FFFF;

    /// Material type tag: Lambertian.
    MAT_LAMBERT = 0;
    /// Material type tag: normalised Phong.
    MAT_PHONG = 1;
    /// Material type tag: mirror.
    MAT_MIRROR = 2;
    /// Material type tag: glossy cone reflection.
    MAT_GLOSSY = 3;
    /// Material type tag: dielectric.
    MAT_DIELECTRIC = 4;
    /// Material type tag: smooth conductor (complex Fresnel).
    MAT_CONDUCTOR = 5;
    /// Material type tag: rough conductor (microfacet).
    MAT_ROUGHCONDUCTOR = 6;
    /// Material type tag: rough dielectric (microfacet reflection and
    /// refraction, Mitsuba's `roughdielectric`).
    MAT_ROUGHDIELECTRIC = 7;
    /// Material type tag: smooth plastic (a diffuse base under a smooth
    /// dielectric coating, Mitsuba's `plastic`).
    MAT_PLASTIC = 8;
    /// Material type tag: rough plastic (a diffuse base under a rough
    /// dielectric coating, Mitsuba's `roughplastic`).
    MAT_ROUGHPLASTIC = 9;
    /// Material type tag: thin dielectric (mirror reflection by a thin
    /// slab's summed Fresnel term, the rest straight through, Mitsuba's
    /// `thindielectric`).
    MAT_THINDIELECTRIC = 10;
    /// Material type tag: a blend of two materials (Mitsuba's
    /// `blendbsdf`), its components two further entries of the material
    /// table.
    MAT_BLEND = 11;
    /// Material type tag: Mitsuba's `principled` (the Disney BRDF: diffuse
    /// with retro-reflection, sheen, GGX specular, GTR1 clearcoat).
    MAT_PRINCIPLED = 12;
    /// Entries of a rough plastic's transmittance table (Mitsuba's
    /// `MI_ROUGH_TRANSMITTANCE_RES`): the coating's transmittance at
    /// cosines evenly spaced over [0, 1], four to a material texel.
    ROUGH_TRANSMITTANCE_RES = 64;
    /// Texels of one material (`Material` in GLSL); the rough plastics'
    /// coating tables follow the materials in the same binding.
    MATERIAL_TEXELS = 6;
    /// Microfacet distribution id (`Material.params.w`): Beckmann.
    MICROFACET_BECKMANN = 0;
    /// Microfacet distribution id: GGX (Trowbridge-Reitz).
    MICROFACET_GGX = 1;
    /// Material flag (`Material.info.z`): the shading normal gives the side
    /// a viewer is on (`Sides::Shading`); nothing is scattered where it and
    /// the geometric normal disagree.
    MAT_FLAG_SHADING_SIDE = 1;
    /// Material flag: scatters on the front side only (`Sides::Front`).
    MAT_FLAG_FRONT_ONLY = 2;
    /// Material flag: a `mask` (`Material.mask`): light meets the surface
    /// with the probability of its opacity, and passes straight through
    /// otherwise.
    MAT_FLAG_MASKED = 4;
    /// Material flag: a normal map tilts the shading normal
    /// (`Material.layers.z`, Mitsuba's `normalmap`).
    MAT_FLAG_NORMAL_MAP = 8;
    /// Material flag: the normal map wraps a two-sided material, so seen
    /// from behind its tilt is mirrored through the surface.
    MAT_FLAG_NORMAL_MAP_MIRRORED = 16;
    /// Material flag: the normal map's response is weighed by Mitsuba's
    /// shadowing term for tilted normals.
    MAT_FLAG_NORMAL_MAP_SHADOWING = 32;
    /// Material flag: the normal map is a bump map (Mitsuba's `bumpmap`):
    /// `Material.layers.z` holds heights (their luminance in every
    /// channel), and `layers.w` the scale of their gradient.
    MAT_FLAG_BUMP_MAP = 64;
    /// Material flag: a principled material's weights are read from the
    /// three texels after its parameter texel (`Material.info.w`), where
    /// some are textures: nine weights in the order of
    /// `Principled::WEIGHT_NAMES`, each a constant's f32 bits or
    /// `WEIGHT_TEXTURE` with a texture index, then the three sampling
    /// rates' bits.
    MAT_FLAG_WEIGHT_TEXTURES = 128;
    /// The bit of a principled weight's word that marks the rest as a
    /// texture index (`MAT_FLAG_WEIGHT_TEXTURES`); a constant weight in
    /// [0, 1] is a positive float, whose bits never have it.
    WEIGHT_TEXTURE = 0x8000_0000;

    /// Number of ray queues (current and next bounce).
    RAY_QUEUE_COUNT = 2;

    /// Specialisation constant id: scene has spheres.
    SPEC_HAS_SPHERES = 0;
    /// Specialisation constant id: scene has triangles.
    SPEC_HAS_TRIANGLES = 1;
    /// Specialisation constant id: next-event estimation is on (scene has emitters).
    SPEC_NEE = 2;
    /// Specialisation constant id: environment is not black.
    SPEC_HAS_ENVIRONMENT = 3;
    /// Specialisation constant id: bit mask of material types present (1 << MAT_*).
    SPEC_MATERIAL_MASK = 4;
    /// Specialisation constant id: textures are used.
    SPEC_HAS_TEXTURES = 5;
    /// Specialisation constant id: thin-lens depth of field.
    SPEC_HAS_DOF = 6;
    /// Specialisation constant id: the shadow kernel runs in occlusion mode.
    SPEC_OCCLUSION = 7;
    /// Specialisation constant id: emission anywhere (MIS weights needed).
    SPEC_HAS_EMISSION = 8;

    /// Specialisation constant id: threads per workgroup (`WORKGROUP_SIZE`).
    SPEC_WORKGROUP_SIZE = 9;
    /// Specialisation constant id: the sampler (`SAMPLER_*`).
    SPEC_SAMPLER = 10;
    /// Specialisation constant id: a pixel filter other than the box
    /// (`Frame.filter_kind`, filter importance sampling).
    SPEC_HAS_FILTER = 11;
    /// Specialisation constant id: the camera has near or far clip planes.
    SPEC_HAS_CLIP = 12;

    /// Pixel filter kind (`Frame.filter_kind`): the pixel's box; the
    /// camera jitters inside the pixel as without a filter.
    FILTER_BOX = 0;
    /// Pixel filter kind: tent (`Frame.filter_params`: radius, 1 / radius).
    FILTER_TENT = 1;
    /// Pixel filter kind: Gaussian (`Frame.filter_params`: radius,
    /// -1 / (2 stddev^2), the value subtracted at the radius).
    FILTER_GAUSSIAN = 2;
    /// Pixel filter kind: Mitchell-Netravali cubic (`Frame.filter_params`: radius, B, C).
    FILTER_MITCHELL = 3;
    /// Pixel filter kind: Lanczos windowed sinc (`Frame.filter_params`: radius = lobes).
    FILTER_LANCZOS = 4;
    /// Segments of the pixel filter's inverse-CDF table (`Frame.filter_table`
    /// holds its `FILTER_TABLE_SEGMENTS + 1` ends, padded to whole vec4s).
    FILTER_TABLE_SEGMENTS = 128;
    /// Whole vec4s of `Frame.filter_table`: the table's ends, padded.
    FILTER_TABLE_VEC4S = (128u32 + 1).div_ceil(4);
    /// Specialisation constant id: the emitter table holds delta lights
    /// (point, spot, directional).
    SPEC_HAS_DELTA_LIGHTS = 13;
    /// Specialisation constant id: the frame's path flags (`PATH_FLAG_*`)
    /// may be set.
    SPEC_HAS_PATH_FLAGS = 14;

    /// Emitter-table entry flag in `Emitter.prim`: the entry is delta light
    /// number `prim & !DELTA_LIGHT_FLAG`, not a primitive.
    DELTA_LIGHT_FLAG = 0x8000_0000;
    /// Texels of one delta light's data (`DeltaLight` in GLSL), stored in
    /// the emitter texels after the table.
    DELTA_LIGHT_TEXELS = 6;
    /// Delta light kind: a point light (intensity, position).
    LIGHT_POINT = 0;
    /// Delta light kind: a spot light (intensity, position, Mitsuba's
    /// linear falloff between beam width and cutoff angle).
    LIGHT_SPOT = 1;
    /// Delta light kind: a directional light (irradiance, direction).
    LIGHT_DIRECTIONAL = 2;
    /// Delta light kind: a projector (Mitsuba's `projector`: a pinhole
    /// projecting its irradiance image).
    LIGHT_PROJECTOR = 3;

    /// Path flag (`Frame.path_flags`): camera rays pass through area
    /// emitters and see no environment (Mitsuba's `hide_emitters`).
    PATH_FLAG_HIDE_EMITTERS = 1;
    /// Path flag: light is found by emitter sampling only, with MIS weight
    /// 1, and paths end after it (Mitsuba's `direct` with `bsdf_samples` 0).
    PATH_FLAG_EMITTER_SAMPLING_ONLY = 2;
    /// Camera rays pass through at most this many area emitters when they
    /// are hidden.
    MAX_HIDDEN_EMITTER_SKIPS = 64;
    /// Specialisation constant id: some material takes its side from the
    /// shading normal (`MAT_FLAG_SHADING_SIDE`, Mitsuba's rules).
    SPEC_HAS_SHADING_SIDES = 15;

    /// Specialisation constant id: the scene has an environment map
    /// (Mitsuba's `envmap`).
    SPEC_HAS_ENVMAP = 16;
    /// Specialisation constant id: the wave's pixels come from the pixel
    /// list (`BINDING_PIXEL_LIST`), not a run of consecutive pixels: an
    /// adaptive render samples only the pixels still short of their share.
    SPEC_PIXEL_LIST = 17;
    /// Specialisation constant id: film positions stay inside the image
    /// (Mitsuba's `sample_border` false): at the edge, the pixel filter is
    /// sampled cut to the film (`Frame.filter_edge`).
    SPEC_HAS_FILM_EDGE = 18;
    /// Entries of `Frame.filter_edge`: one per pixel 0 to 15 whole pixels
    /// from the image's edge (a filter's radius is at most 16 pixels), then
    /// the uncut filter's ends.
    FILTER_EDGE_ENTRIES = 17;
    /// Specialisation constant id: the image's centre is off the optical
    /// axis (a Mitsuba crop window or principal point offset):
    /// `Frame.cam_shift` is added to every camera ray's direction.
    SPEC_HAS_CAM_SHIFT = 19;
    /// Specialisation constant id: some texture is looked up by Mitsuba's
    /// rules other than lancer's plain one (a `to_uv` transform, a wrap mode
    /// other than repeat, nearest filtering, a checkerboard): its texture
    /// header has the format `TEXELS_MAPPED`.
    SPEC_HAS_TEX_MAPPING = 20;
    /// Specialisation constant id: the camera may be orthographic
    /// (Mitsuba's `orthographic` sensor; `Frame.clip.w` says whether it is).
    SPEC_HAS_ORTHO = 21;
    /// Specialisation constant id: some material is a `mask`
    /// (`MAT_FLAG_MASKED`).
    SPEC_HAS_MASK = 22;
    /// Specialisation constant id: some material has a normal map
    /// (`MAT_FLAG_NORMAL_MAP`).
    SPEC_HAS_NORMAL_MAP = 23;
    /// Specialisation constant id: some material reads a mesh attribute
    /// (a texture of format `TEXELS_ATTRIBUTE`).
    SPEC_HAS_MESH_ATTRIBUTES = 24;
    /// `Emitter.prim` of the emitter-table entry that is the environment
    /// map: no primitive index reaches it (`BVH_REF_INDEX_LIMIT`), and it
    /// has no `DELTA_LIGHT_FLAG`.
    ENVMAP_EMITTER = 0x7FFF_FFFF;
    /// Words of the environment map's header (`EnvmapHeader` in GLSL) at
    /// the start of its buffer; its texels follow.
    ENVMAP_HEADER_WORDS = 20;

    /// Test-kernel item flag: wo lies on the front side of the surface.
    TEST_BSDF_FRONT = 1;
    /// Test-kernel item flag: evaluate at the given direction, do not sample.
    TEST_BSDF_EVALUATE = 2;
    /// Test-kernel result flag: `bsdf_sample` returned true.
    TEST_BSDF_OK = 1;
    /// Test-kernel result flag: the sample came from a delta lobe.
    TEST_BSDF_DELTA = 2;

    /// Light test-kernel item flag: evaluate at the given direction, do
    /// not sample.
    TEST_LIGHT_EVALUATE = 1;
    /// Sampler test-kernel item partner meaning none: the pair is drawn
    /// alone (`sample_2d`), not partnered (`sample_2d_partnered`).
    TEST_SAMPLER_ALONE = 0xFFFF_FFFF;

    /// Counter slot: samples dropped because their radiance was NaN or infinite.
    COUNTER_NONFINITE = 0;
    /// Number of counter slots.
    COUNTER_COUNT = 4;
}

/// Mitsuba 3's luminance of a linear RGB colour (its `luminance()`: the
/// Rec. 709 weights to six places), which its BSDFs use to tint.
pub const MITSUBA_LUMINANCE: [f32; 3] = [0.212_671, 0.715_160, 0.072_169];

/// The least roughness (alpha) of a microfacet distribution: Mitsuba's
/// `MicrofacetDistribution` clamps it likewise (a smooth surface is a
/// `conductor` or `dielectric`). Applied to constants on the CPU and to
/// roughness textures in the kernels.
pub const MIN_MICROFACET_ALPHA: f32 = 1e-4;

/// Floating-point constants shared with GLSL, as `(macro name, value)`:
/// `build.rs` writes each as a float literal.
pub const SHADER_FLOAT_DEFINES: &[(&str, f32)] = &[
    ("LUMINANCE_R", MITSUBA_LUMINANCE[0]),
    ("LUMINANCE_G", MITSUBA_LUMINANCE[1]),
    ("LUMINANCE_B", MITSUBA_LUMINANCE[2]),
    ("MIN_MICROFACET_ALPHA", MIN_MICROFACET_ALPHA),
];

/// A Sobol dimension's generator as Joe and Kuo list it ("Constructing
/// Sobol sequences with better two-dimensional projections", SIAM J. Sci.
/// Comput. 30, 2008): the primitive polynomial over GF(2)
/// x^s + a_1 x^(s-1) + ... + a_(s-1) x + 1 and the initial numbers
/// m_1..m_s (m_k odd, below 2^k).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SobolPolynomial {
    /// The degree s; 0 stands for dimension 0, the van der Corput sequence,
    /// whose numbers m_k are all 1.
    pub degree: u32,
    /// The inner coefficients a_1..a_(s-1) as bits, a_1 the most significant.
    pub coefficients: u32,
    /// m_1..m_s.
    pub initial: &'static [u32],
}

/// The generators of the Sobol dimensions the sampler draws from, in
/// order: dimension 0 is the van der Corput sequence, then Joe and Kuo's
/// `new-joe-kuo-6.21201` from its first entry (x + 1; x^2 + x + 1, m = 1,
/// 3; x^3 + x + 1, m = 1, 3, 1). `build.rs` gives the kernels the
/// direction numbers of dimensions 2 and up as `SOBOL_DIRECTIONS`.
pub const SOBOL_POLYNOMIALS: [SobolPolynomial; SOBOL_DIMENSIONS as usize] = [
    SobolPolynomial {
        degree: 0,
        coefficients: 0,
        initial: &[],
    },
    SobolPolynomial {
        degree: 1,
        coefficients: 0,
        initial: &[1],
    },
    SobolPolynomial {
        degree: 2,
        coefficients: 0b1,
        initial: &[1, 3],
    },
    SobolPolynomial {
        degree: 3,
        coefficients: 0b01,
        initial: &[1, 3, 1],
    },
];

/// The direction numbers of a Sobol dimension from its generator: entry k
/// is v_(k+1), the 32-bit fraction that bit k of the index adds (xor) to
/// the point, by the recurrence m_k = 2 a_1 m_(k-1) ^ 4 a_2 m_(k-2) ^ ...
/// ^ 2^(s-1) a_(s-1) m_(k-s+1) ^ 2^s m_(k-s) ^ m_(k-s), and v_k = m_k / 2^k.
pub const fn sobol_directions(p: &SobolPolynomial) -> [u32; 32] {
    let s = p.degree as usize;
    let mut m = [0u64; 32];
    let mut v = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        m[k] = if s == 0 {
            1
        } else if k < s {
            p.initial[k] as u64
        } else {
            let mut x = m[k - s] ^ (m[k - s] << s);
            let mut j = 1;
            while j < s {
                if (p.coefficients >> (s - 1 - j)) & 1 != 0 {
                    x ^= m[k - j] << j;
                }
                j += 1;
            }
            x
        };
        v[k] = (m[k] << (31 - k)) as u32;
        k += 1;
    }
    v
}

/// Packs a primitive's kind tag (`PRIM_*`) and flags (`PRIM_FLAG_*`) into
/// `Primitive.meta.x`; GLSL unpacks them with `prim_kind()` and `prim_flags()`.
pub const fn pack_prim_kind(kind: u32, flags: u32) -> u32 {
    kind | (flags << PRIM_KIND_BITS)
}

/// Kernels whose film sums come in two encodings, compiled twice from their
/// one source by `build.rs`: with `FILM_FP64 = 1` (f64 sums, devices with
/// `shaderFloat64`) to `NAME.spv`, and with `FILM_FP64 = 0` (Neumaier-
/// compensated f32 sums) to `NAME_f32.spv`.
pub const FILM_F32_KERNELS: &[&str] = &["accumulate", "megakernel"];
