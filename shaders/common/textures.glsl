// Texture lookups: texels are stored as sRGB RGBA8 (decoded per texel) or
// as linear RGB floats, then filtered bilinearly, and repeated in both
// directions. Mitsuba's textures with other rules (to_uv, wrap modes,
// nearest filtering, checkerboards) have a record of their own
// (TEXELS_MAPPED), compiled in by HAS_TEX_MAPPING; its mesh attributes
// (TEXELS_ATTRIBUTE) hold nine floats per triangle, compiled in by
// HAS_MESH_ATTRIBUTES.
#ifndef TEXTURES_GLSL
#define TEXTURES_GLSL

// Decode one sRGB-encoded channel to linear
float srgb_to_linear(float c) {
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

// Fetch texel (x, y) of a texture, x in [0, w], y in [0, h]; y = 0 is the top row
vec3 texel_fetch(uvec4 header, uint x, uint y) {
    x = x >= header.y ? x - header.y : x;
    y = y >= header.z ? y - header.z : y;
    uint i = y * header.y + x;
    if (header.w == TEXELS_RGB32F) {
        // Read a linear float texel: three words
        uint at = header.x + 3u * i;
        return vec3(uintBitsToFloat(texels[at]), uintBitsToFloat(texels[at + 1u]),
                    uintBitsToFloat(texels[at + 2u]));
    }
    vec4 c = unpackUnorm4x8(texels[header.x + i]);
    return vec3(srgb_to_linear(c.r), srgb_to_linear(c.g), srgb_to_linear(c.b));
}

// Read the four header words of texture `tex`: first texel (or record), width, height, format
uvec4 texture_header(uint tex) {
    return uvec4(texels[4u * tex], texels[4u * tex + 1u], texels[4u * tex + 2u],
                 texels[4u * tex + 3u]);
}

// Wrap whole texel coordinate x into [0, n) by a wrap mode (TEX_WRAP_*), as Dr.Jit's tex_wrap
uint wrap_texel(float x, float n, uint mode) {
    if (mode == TEX_WRAP_CLAMP) {
        // Clamp to the image: the edge texels extend outwards
        return uint(clamp(x, 0.0, n - 1.0));
    }
    // Repeat: x modulo n; mirror: x modulo 2n, the second half reflected
    float period = mode == TEX_WRAP_MIRROR ? 2.0 * n : n;
    float m = clamp(x - period * floor(x / period), 0.0, period - 1.0);
    return uint(m >= n ? period - 1.0 - m : m);
}

// Find the four texel centres around point t (in texels, times size) of
// an image of `size` texels, each wrapped by `wrap`: x0, x1, y0, y1 in
// taps; return the point's fractions between them
vec2 bilinear_taps(vec2 t, vec2 size, uint wrap, out uvec4 taps) {
    vec2 p = t * size - 0.5;
    vec2 base = floor(p);
    taps = uvec4(wrap_texel(base.x, size.x, wrap), wrap_texel(base.x + 1.0, size.x, wrap),
                 wrap_texel(base.y, size.y, wrap), wrap_texel(base.y + 1.0, size.y, wrap));
    return p - base;
}

// Look up the mapped texture (TEXELS_MAPPED) whose record starts at word `at`, at lancer's uv
vec3 mapped_texture_lookup(uint at, vec2 uv) {
    // Apply to_uv in Mitsuba's coordinates, whose v = 0 is the image's top row
    vec2 m = vec2(uv.x, 1.0 - uv.y);
    vec2 t = vec2(uintBitsToFloat(texels[at]) * m.x + uintBitsToFloat(texels[at + 1u]) * m.y
                      + uintBitsToFloat(texels[at + 2u]),
                  uintBitsToFloat(texels[at + 3u]) * m.x + uintBitsToFloat(texels[at + 4u]) * m.y
                      + uintBitsToFloat(texels[at + 5u]));
    if (texels[at + TEX_MAP_PATTERN] == TEX_PATTERN_CHECKERBOARD) {
        // Pick color0 where both fractions are above 1/2 or neither is (Mitsuba's eval)
        bvec2 high = greaterThan(t - floor(t), vec2(0.5));
        uint c = at + (high.x == high.y ? TEX_MAP_COLOR0 : TEX_MAP_COLOR1);
        return vec3(uintBitsToFloat(texels[c]), uintBitsToFloat(texels[c + 1u]),
                    uintBitsToFloat(texels[c + 2u]));
    }
    uint wrap = texels[at + TEX_MAP_WRAP];
    uvec4 header = texture_header(texels[at + TEX_MAP_IMAGE]);
    vec2 size = vec2(float(header.y), float(header.z));
    // A non-finite uv reads the texture's corner
    bvec2 bad = bvec2(isnan(t.x) || isinf(t.x), isnan(t.y) || isinf(t.y));
    t = mix(t, vec2(0.0), bad);
    if (texels[at + TEX_MAP_FILTER] == TEX_FILTER_NEAREST) {
        // Read the texel the point falls in
        vec2 p = floor(t * size);
        return texel_fetch(header, wrap_texel(p.x, size.x, wrap), wrap_texel(p.y, size.y, wrap));
    }
    // Interpolate between the four texel centres around the point, each tap wrapped
    uvec4 k;
    vec2 f = bilinear_taps(t, size, wrap, k);
    vec3 a = mix(texel_fetch(header, k.x, k.z), texel_fetch(header, k.y, k.z), f.x);
    vec3 b = mix(texel_fetch(header, k.x, k.w), texel_fetch(header, k.y, k.w), f.x);
    return mix(a, b, f.y);
}

// Find the gradient of texture `tex`'s first channel at lancer's uv, in
// Mitsuba's texture coordinates (v = 0 at the top row), as Mitsuba's
// bitmap eval_1_grad: the derivative of the bilinear interpolation of the
// four texels around the point, through the transpose of to_uv's 2 x 2
// block, times the image size; 0 under nearest filtering
vec2 texture_gradient(uint tex, vec2 uv) {
    uvec4 header = texture_header(tex);
    vec2 t = vec2(uv.x, 1.0 - uv.y);
    vec4 a = vec4(1.0, 0.0, 0.0, 1.0);
    uint wrap = TEX_WRAP_REPEAT;
    if (HAS_TEX_MAPPING && header.w == TEXELS_MAPPED) {
        // Apply the record's to_uv, and read its wrap mode and image
        uint at = header.x;
        if (texels[at + TEX_MAP_FILTER] == TEX_FILTER_NEAREST) {
            return vec2(0.0);
        }
        a = vec4(uintBitsToFloat(texels[at]), uintBitsToFloat(texels[at + 1u]),
                 uintBitsToFloat(texels[at + 3u]), uintBitsToFloat(texels[at + 4u]));
        t = vec2(a.x * t.x + a.y * t.y + uintBitsToFloat(texels[at + 2u]),
                 a.z * t.x + a.w * t.y + uintBitsToFloat(texels[at + 5u]));
        wrap = texels[at + TEX_MAP_WRAP];
        header = texture_header(texels[at + TEX_MAP_IMAGE]);
    }
    vec2 size = vec2(float(header.y), float(header.z));
    bvec2 bad = bvec2(isnan(t.x) || isinf(t.x), isnan(t.y) || isinf(t.y));
    t = mix(t, vec2(0.0), bad);
    // Difference the four texel centres around the point, each tap wrapped
    uvec4 k;
    vec2 f = bilinear_taps(t, size, wrap, k);
    float f00 = texel_fetch(header, k.x, k.z).r;
    float f10 = texel_fetch(header, k.y, k.z).r;
    float f01 = texel_fetch(header, k.x, k.w).r;
    float f11 = texel_fetch(header, k.y, k.w).r;
    vec2 d = vec2((1.0 - f.y) * (f10 - f00) + f.y * (f11 - f01),
                  (1.0 - f.x) * (f01 - f00) + f.x * (f11 - f10));
    return size * vec2(a.x * d.x + a.z * d.y, a.y * d.x + a.w * d.y);
}

// Look up texture `tex` at uv with bilinear filtering; v = 0 is the bottom row
vec3 texture_lookup(uint tex, vec2 uv) {
    // The buffer opens with four words per texture: first texel, width,
    // height, texel format
    uvec4 header = texture_header(tex);
    if (HAS_TEX_MAPPING && header.w == TEXELS_MAPPED) {
        // Follow the record of a Mitsuba texture with a lookup of its own
        return mapped_texture_lookup(header.x, uv);
    }
    vec2 size = vec2(float(header.y), float(header.z));
    // Repeat: keep the fraction of uv, which stays finite and in [0, 1] for
    // every finite uv (1e7 and beyond have no fraction left in f32); a
    // non-finite uv reads the texture's corner
    bvec2 bad = bvec2(isnan(uv.x) || isinf(uv.x), isnan(uv.y) || isinf(uv.y));
    uv = mix(uv - floor(uv), vec2(0.0), bad);
    // Texel centres sit at half-integers; v runs up the image
    vec2 p = vec2(uv.x * size.x, (1.0 - uv.y) * size.y) - 0.5;
    // Wrap into [0, size) so that the four taps repeat across the edges
    p -= size * floor(p / size);
    vec2 base = clamp(floor(p), vec2(0.0), size - 1.0);
    vec2 f = clamp(p - base, vec2(0.0), vec2(1.0));
    uint x = uint(base.x);
    uint y = uint(base.y);
    vec3 a = mix(texel_fetch(header, x, y), texel_fetch(header, x + 1u, y), f.x);
    vec3 b = mix(texel_fetch(header, x, y + 1u), texel_fetch(header, x + 1u, y + 1u), f.x);
    return mix(a, b, f.y);
}

// Interpolate the mesh attribute whose header (TEXELS_ATTRIBUTE) is
// `header` over the triangle of shading index `tri` by the barycentrics
// of its vertices 1 and 2, times the texture's scale (Mitsuba's
// mesh_attribute; a face attribute holds one value at all three vertices)
vec3 attribute_lookup(uvec4 header, uint tri, vec2 bary) {
    if (tri == NO_TEXTURE) {
        return vec3(0.0);
    }
    uint at = header.x + ATTRIBUTE_WORDS * tri;
    vec3 v[3];
    for (uint k = 0u; k < 3u; ++k) {
        v[k] = vec3(uintBitsToFloat(texels[at + 3u * k]), uintBitsToFloat(texels[at + 3u * k + 1u]),
                    uintBitsToFloat(texels[at + 3u * k + 2u]));
    }
    float b0 = 1.0 - bary.x - bary.y;
    return uintBitsToFloat(header.y) * (b0 * v[0] + bary.x * v[1] + bary.y * v[2]);
}

#endif
