// Warping functions from the unit square, with their pdfs.
#ifndef SAMPLING_GLSL
#define SAMPLING_GLSL

// The largest float below 1, where a rescaled uniform number is clamped
const float ONE_MINUS_EPSILON = 0.99999994;

// Map the unit square to the unit disc (Shirley-Chiu concentric mapping);
// radius is the point's distance from the centre, exact in f32
vec2 sample_disk_concentric_radius(vec2 u, out float radius) {
    vec2 o = 2.0 * u - 1.0;
    radius = 0.0;
    if (o.x == 0.0 && o.y == 0.0) {
        return vec2(0.0);
    }
    float r, theta;
    if (abs(o.x) > abs(o.y)) {
        r = o.x;
        theta = (PI / 4.0) * (o.y / o.x);
    } else {
        r = o.y;
        theta = (PI / 2.0) - (PI / 4.0) * (o.x / o.y);
    }
    radius = abs(r);
    return r * vec2(cos(theta), sin(theta));
}

// Map the unit square to the unit disc (Shirley-Chiu concentric mapping)
vec2 sample_disk_concentric(vec2 u) {
    float radius;
    return sample_disk_concentric_radius(u, radius);
}

// Build an orthonormal basis around unit n (Duff et al. 2017)
void orthonormal_basis(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// Express local direction d in the frame around n
vec3 to_world(vec3 d, vec3 n) {
    vec3 t, b;
    orthonormal_basis(n, t, b);
    return d.x * t + d.y * b + d.z * n;
}

// Give log(1 - y) for y in [0, 1), to full precision where y is small
// (log(1.0 - y) keeps only the bits of y that survive 1.0 - y)
float log_one_minus(float y) {
    if (y < 0.01) {
        return -y * (1.0 + y * (0.5 + y * (1.0 / 3.0 + y * (0.25 + y * 0.2))));
    }
    return log(1.0 - y);
}

// Give 1 - exp(x) for x <= 0, to full precision where x is small
float one_minus_exp(float x) {
    if (x > -0.01) {
        return -x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0)))));
    }
    return 1.0 - exp(x);
}

// Give 1 - cos of the angle between unit a and b (cos > 0), to full
// precision near 0: sin^2 / (1 + cos), with sin from the cross product
float one_minus_cos_between(vec3 a, vec3 b) {
    vec3 c = cross(a, b);
    return dot(c, c) / (1.0 + dot(a, b));
}

// Sample a cosine-weighted direction around unit n; pdf = cos / pi
vec3 sample_cosine_hemisphere(vec2 u, vec3 n) {
    float r;
    vec2 d = sample_disk_concentric_radius(u, r);
    // The height sqrt(1 - r^2) as (1 - r)(1 + r), exact near the rim, where
    // 1 - dot(d, d) cancels to a few ulps. The edge u = 0 of the unit
    // square maps onto the rim itself (r = 1): lift it off the tangent
    // plane to the smallest height f32 gives any other point (sqrt of
    // 2^-24), so that the path goes on with the exact weight
    float z = sqrt(max(5.9604645e-8, (1.0 - r) * (1.0 + r)));
    return normalize(to_world(vec3(d, z), n));
}

// Sample a direction uniformly in the cone of half-angle acos(cos_max) around n
vec3 sample_uniform_cone(vec2 u, float one_minus_cos_max, vec3 n) {
    float one_minus_cos = u.x * one_minus_cos_max;
    float cos_t = 1.0 - one_minus_cos;
    float sin_t = sqrt(max(0.0, one_minus_cos * (2.0 - one_minus_cos)));
    float phi = 2.0 * PI * u.y;
    return normalize(to_world(vec3(cos(phi) * sin_t, sin(phi) * sin_t, cos_t), n));
}

// Sample a point uniformly on a triangle (barycentrics b1, b2)
vec2 sample_triangle(vec2 u) {
    float s = sqrt(u.x);
    return vec2(1.0 - s, u.y * s);
}

// Weigh two strategies by the power heuristic (beta = 2)
float power_heuristic(float pdf_a, float pdf_b) {
    float a = pdf_a * pdf_a;
    float b = pdf_b * pdf_b;
    return a + b > 0.0 ? a / (a + b) : 0.0;
}

#endif
