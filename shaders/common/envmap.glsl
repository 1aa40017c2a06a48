// The environment map (Mitsuba's envmap): radiance by direction from a
// latitude-longitude image, looked up as Mitsuba's src/emitters/envmap.cpp
// maps it (+y up, v = 0 the top row at theta = 0, rows evenly spaced to
// theta = pi; u = 0 towards -z, texel centres at u = (i + 1/2) / width,
// bilinear, wrapping in u), and sampled for next-event estimation from
// the piecewise-constant distribution src/gpu/envmap.rs builds.
#ifndef ENVMAP_GLSL
#define ENVMAP_GLSL

// Read word `i` of the environment map's buffer as a float
float envmap_float(uint i) {
    return uintBitsToFloat(envmap_words[i]);
}

// Read the environment map's header; grid.x is 0 when the scene has none
EnvmapHeader envmap_header() {
    vec4 v[3];
    [[unroll]] for (uint k = 0u; k < 3u; ++k) {
        v[k] = vec4(envmap_float(4u * k), envmap_float(4u * k + 1u), envmap_float(4u * k + 2u),
                    envmap_float(4u * k + 3u));
    }
    uvec4 grid = uvec4(envmap_words[12], envmap_words[13], envmap_words[14], envmap_words[15]);
    uvec4 tables = uvec4(envmap_words[16], envmap_words[17], envmap_words[18], envmap_words[19]);
    return EnvmapHeader(v[0], v[1], v[2], grid, tables);
}

// Tell whether the scene has an environment map
bool envmap_present(EnvmapHeader h) {
    return HAS_ENVMAP && h.grid.x != 0u;
}

// Turn world direction d into the map's (u, v) in [0, 1)^2 x [0, 1], and
// give sin(theta) of the direction in the map's frame
vec2 envmap_uv(EnvmapHeader h, vec3 d, out float sin_theta) {
    vec3 l = vec3(dot(h.to_local_x.xyz, d), dot(h.to_local_y.xyz, d), dot(h.to_local_z.xyz, d));
    float r2 = l.x * l.x + l.z * l.z;
    sin_theta = sqrt(r2);
    // atan(0, 0) is undefined: at a pole every u is the same point
    float u = r2 > 0.0 ? atan(l.x, -l.z) * (0.5 * INV_PI) : 0.0;
    float v = acos(clamp(l.y / sqrt(r2 + l.y * l.y), -1.0, 1.0)) * INV_PI;
    return vec2(u - floor(u), v);
}

// Read texel (x, y) of the map, linear RGB with the scale applied
vec3 envmap_texel(EnvmapHeader h, uint x, uint y) {
    uint at = ENVMAP_HEADER_WORDS + 3u * (y * h.grid.x + x);
    return vec3(envmap_float(at), envmap_float(at + 1u), envmap_float(at + 2u));
}

// Look up the map's radiance at (u, v): bilinear between texel centres,
// wrapping in u, rows from v = 0 (top) to v = 1 (bottom)
vec3 envmap_lookup(EnvmapHeader h, vec2 uv) {
    float w = float(h.grid.x);
    float x = uv.x * w - 0.5;
    x -= w * floor(x / w);
    float y = uv.y * float(h.grid.y - 1u);
    uint ix = min(uint(x), h.grid.x - 1u);
    uint iy = min(uint(y), h.grid.y - 2u);
    float fx = x - float(ix);
    float fy = y - float(iy);
    uint ix1 = ix + 1u == h.grid.x ? 0u : ix + 1u;
    vec3 a = mix(envmap_texel(h, ix, iy), envmap_texel(h, ix1, iy), fx);
    vec3 b = mix(envmap_texel(h, ix, iy + 1u), envmap_texel(h, ix1, iy + 1u), fx);
    return mix(a, b, fy);
}

// Give the radiance arriving from world direction d (a ray escaping along d)
vec3 envmap_radiance(EnvmapHeader h, vec3 d) {
    float sin_theta;
    vec2 uv = envmap_uv(h, d, sin_theta);
    return envmap_lookup(h, uv);
}

// Give the cell density (over 2 pi^2) of the sampling grid's cell at (u, v)
float envmap_cell_density(EnvmapHeader h, vec2 uv) {
    float w = float(h.grid.x);
    // Cells are the bilinear patches: shifted by half a texel in u
    float x = uv.x * w - 0.5;
    x -= w * floor(x / w);
    uint i = min(uint(x), h.grid.x - 1u);
    uint j = min(uint(uv.y * float(h.grid.y - 1u)), h.grid.y - 2u);
    return envmap_float(h.tables.x + j * h.grid.x + i);
}

// Give the solid-angle pdf with which next-event estimation samples world
// direction d from the map, its pick probability included
float envmap_pdf(EnvmapHeader h, vec3 d) {
    float sin_theta;
    vec2 uv = envmap_uv(h, d, sin_theta);
    if (!(sin_theta > 0.0)) {
        return 0.0;
    }
    return h.to_local_x.w * envmap_cell_density(h, uv) / sin_theta;
}

// Find the first of the n CDF entries at word `at` that exceeds x (x < 1,
// the last entry is 1): the index of the cell x falls in
uint envmap_search(uint at, uint n, float x) {
    uint lo = 0u;
    uint hi = n - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (envmap_float(at + mid) <= x) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// Pick a cell of the CDF at word `at` (n entries) with x and give the
// fraction of the way through it that x lies
uint envmap_pick(uint at, uint n, float x, out float frac) {
    uint k = envmap_search(at, n, x);
    float lo = k == 0u ? 0.0 : envmap_float(at + k - 1u);
    float hi = envmap_float(at + k);
    frac = clamp((x - lo) / (hi - lo), 0.0, 0.99999994);
    return k;
}

// Sample a direction from the map by its luminance times sin(theta):
// a row of cells by the marginal CDF, a cell by the row's conditional CDF,
// then (u, v) uniform in the cell; gives the world direction, the map's
// radiance there and the solid-angle pdf (the pick probability, in the
// header, included)
bool envmap_sample(EnvmapHeader h, vec2 u, out vec3 wi, out vec3 le, out float pdf) {
    uint rows = h.grid.y - 1u;
    float fv;
    uint j = envmap_pick(h.grid.z, rows, u.y, fv);
    float fu;
    uint i = envmap_pick(h.grid.w + j * h.grid.x, h.grid.x, u.x, fu);
    float w = float(h.grid.x);
    // Cells begin half a texel into u
    float su = (float(i) + fu + 0.5) / w;
    su = su >= 1.0 ? su - 1.0 : su;
    float sv = (float(j) + fv) / float(rows);
    float theta = sv * PI;
    float phi = su * (2.0 * PI);
    float sin_theta = sin(theta);
    vec3 l = vec3(sin(phi) * sin_theta, cos(theta), -cos(phi) * sin_theta);
    // The map's frame is orthogonal: world = transpose(to_local) * l
    wi = normalize(l.x * h.to_local_x.xyz + l.y * h.to_local_y.xyz + l.z * h.to_local_z.xyz);
    // Look the direction up as an escaped path would, not at (su, sv): f32
    // turns it by up to ~1e-4 radians on its way back, and the two MIS
    // weights of one direction must come from the same pdf
    le = envmap_radiance(h, wi);
    pdf = envmap_pdf(h, wi);
    return pdf > 0.0 && !isinf(pdf);
}

#endif
