// Texture lookups: texels are stored as sRGB RGBA8 (decoded per texel) or
// as linear RGB floats, then filtered bilinearly, and repeated in both
// directions.
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

// Look up texture `tex` at uv with bilinear filtering; v = 0 is the bottom row
vec3 texture_lookup(uint tex, vec2 uv) {
    // The buffer opens with four words per texture: first texel, width,
    // height, texel format
    uvec4 header = uvec4(texels[4u * tex], texels[4u * tex + 1u], texels[4u * tex + 2u],
                         texels[4u * tex + 3u]);
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

#endif
