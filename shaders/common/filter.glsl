// Pixel reconstruction filters, as Mitsuba 3 defines them, sampled by
// importance (src/scene/filter.rs holds the same functions in f64 and
// builds the table): a camera path's film offset is drawn from |f| through
// the inverse-CDF table in frame.filter_table, and its weight
// f(x) / (p(x) * integral of f) corrects for the table and the sign.
#ifndef FILTER_GLSL
#define FILTER_GLSL

#include "common/bindings.glsl"

// Evaluate the pixel filter at offset x (pixels from the pixel's centre)
float filter_eval(float x) {
    float r = frame.filter_params.x;
    x = abs(x);
    if (frame.filter_kind == FILTER_TENT) {
        return max(0.0, 1.0 - x * frame.filter_params.y);
    }
    if (frame.filter_kind == FILTER_GAUSSIAN) {
        // A Gaussian lowered to reach zero at its radius (4 standard deviations)
        return max(0.0, exp(frame.filter_params.y * x * x) - frame.filter_params.z);
    }
    if (frame.filter_kind == FILTER_MITCHELL) {
        // The Mitchell-Netravali cubic with B, C; radius 2
        float b = frame.filter_params.y;
        float c = frame.filter_params.z;
        float x2 = x * x;
        float x3 = x2 * x;
        float v = x < 1.0
            ? (12.0 - 9.0 * b - 6.0 * c) * x3 + (-18.0 + 12.0 * b + 6.0 * c) * x2 + (6.0 - 2.0 * b)
            : (-b - 6.0 * c) * x3 + (6.0 * b + 30.0 * c) * x2 + (-12.0 * b - 48.0 * c) * x + (8.0 * b + 24.0 * c);
        return x < 2.0 ? v * (1.0 / 6.0) : 0.0;
    }
    if (frame.filter_kind == FILTER_LANCZOS) {
        // The sinc windowed by a sinc as wide as the radius (the lobes)
        if (x < 5.9604645e-8) {
            return 1.0;
        }
        if (x > r) {
            return 0.0;
        }
        float x1 = PI * x;
        float x2 = x1 / r;
        return sin(x1) * sin(x2) / (x1 * x2);
    }
    return x < 0.5 ? 1.0 : 0.0;
}

// Read entry j of the filter's inverse-CDF table
float filter_table_at(uint j) {
    return frame.filter_table[j >> 2u][j & 3u];
}

// Map u in [0, 1) to a film offset (x) drawn from the filter and its weight (y)
vec2 sample_filter(float u) {
    // Find the table segment of u and move linearly across it
    float s = u * float(FILTER_TABLE_SEGMENTS);
    uint j = min(uint(s), FILTER_TABLE_SEGMENTS - 1u);
    float t = s - float(j);
    float x0 = filter_table_at(j);
    float width = filter_table_at(j + 1u) - x0;
    float x = x0 + t * width;

    // Weigh by f(x) / (p(x) * integral), p(x) = 1 / (segments * width)
    return vec2(x, filter_eval(x) * (float(FILTER_TABLE_SEGMENTS) * width) * frame.filter_params.w);
}

// Map u in [0, 1) to a film offset and its weight for pixel i of a film n
// pixels wide along this axis, with the filter cut to the film where it
// reaches past its edge (Mitsuba's sample_border false): u moves into the
// table's CDF range of the cut, [CDF(a), CDF(b)], and the weight is
// f(x) / (p(x) * integral of f over [a, b]), p the table's density over
// CDF(b) - CDF(a); frame.filter_edge holds (CDF, integral of f from -r) at
// the cut of a pixel k whole pixels from the edge
vec2 sample_filter_cut(float u, uint i, uint n) {
    uint last = FILTER_EDGE_ENTRIES - 1u;
    vec2 lo = frame.filter_edge[min(i, last)].xy;
    vec2 hi = frame.filter_edge[min(n - 1u - i, last)].zw;
    if (lo.x <= 0.0 && hi.x >= 1.0) {
        return sample_filter(u);
    }
    float mass = hi.x - lo.x;
    float s = (lo.x + u * mass) * float(FILTER_TABLE_SEGMENTS);
    uint j = min(uint(s), FILTER_TABLE_SEGMENTS - 1u);
    float t = s - float(j);
    float x0 = filter_table_at(j);
    float width = filter_table_at(j + 1u) - x0;
    float x = x0 + t * width;
    return vec2(x, filter_eval(x) * (float(FILTER_TABLE_SEGMENTS) * width) * mass / (hi.y - lo.y));
}

#endif
