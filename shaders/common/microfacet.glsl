// Microfacet distributions (Beckmann and GGX, Walter et al. 2007) with
// Smith's masking and sampling of the visible normals (Heitz and d'Eon
// 2014; Heitz 2018 for GGX), and the Fresnel term of a conductor. Vectors
// are in the local shading frame: x along the tangent (alpha_u), y along
// the bitangent (alpha_v), z along the shading normal.
#ifndef MICROFACET_GLSL
#define MICROFACET_GLSL

const float INV_SQRT_PI = 0.56418958354775628;

// A distribution of microfacet normals: MICROFACET_* and the roughness
struct Microfacet {
    uint type;
    float au;  // roughness along x
    float av;  // roughness along y
};

// Complementary error function; relative error below 1.2e-7 (the Chebyshev
// fit of Numerical Recipes, 2nd ed., section 6.2)
float erfc_approx(float x) {
    float z = abs(x);
    float t = 1.0 / (1.0 + 0.5 * z);
    float poly = -1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418
        + t * (-0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587
        + t * (-0.82215223 + t * 0.17087277))))))));
    float r = t * exp(-z * z + poly);
    return x >= 0.0 ? r : 2.0 - r;
}

// Error function, to about 1.2e-7 absolute
float erf_approx(float x) {
    return 1.0 - erfc_approx(x);
}

// Inverse error function on (-1, 1): the single-precision fit of Giles,
// "Approximating the erfinv function" (GPU Computing Gems, 2011)
float erfinv_approx(float x) {
    float w = -log((1.0 - x) * (1.0 + x));
    float p;
    if (w < 5.0) {
        w -= 2.5;
        p = 2.81022636e-08;
        p = 3.43273939e-07 + p * w;
        p = -3.5233877e-06 + p * w;
        p = -4.39150654e-06 + p * w;
        p = 0.00021858087 + p * w;
        p = -0.00125372503 + p * w;
        p = -0.00417768164 + p * w;
        p = 0.246640727 + p * w;
        p = 1.50140941 + p * w;
    } else {
        w = sqrt(w) - 3.0;
        p = -0.000200214257;
        p = 0.000100950558 + p * w;
        p = 0.00134934322 + p * w;
        p = -0.00367342844 + p * w;
        p = 0.00573950773 + p * w;
        p = -0.0076224613 + p * w;
        p = 0.00943887047 + p * w;
        p = 1.00167406 + p * w;
        p = 2.83297682 + p * w;
    }
    return p * x;
}

// Evaluate the density of microfacet normal m (per solid angle, projected: its
// integral with cos(m) is 1)
float microfacet_d(Microfacet d, vec3 m) {
    float c2 = m.z * m.z;
    vec2 s = m.xy / vec2(d.au, d.av);
    float r;
    if (d.type == MICROFACET_BECKMANN) {
        r = exp(-dot(s, s) / c2) / (PI * d.au * d.av * c2 * c2);
    } else {
        float q = dot(s, s) + c2;
        r = 1.0 / (PI * d.au * d.av * q * q);
    }
    // Drop densities too small to matter, which only breed overflow later
    return r * m.z > 1e-20 ? r : 0.0;
}

// Smith's masking of direction v by microfacets of normal m: 1 / (1 + Lambda);
// Beckmann's Lambda is taken exact, by the error function
float microfacet_g1(Microfacet d, vec3 v, vec3 m) {
    if (dot(v, m) * v.z <= 0.0) {
        // The back of a microfacet is never seen from the front
        return 0.0;
    }
    vec2 s = vec2(d.au * v.x, d.av * v.y);
    float xy2 = dot(s, s);
    if (xy2 == 0.0) {
        return 1.0;
    }
    float tan2 = xy2 / (v.z * v.z);
    if (d.type == MICROFACET_BECKMANN) {
        float a = inversesqrt(tan2);
        if (a > 6.0) {
            return 1.0;
        }
        float lambda = 0.5 * (exp(-a * a) * INV_SQRT_PI / a - erfc_approx(a));
        return 1.0 / (1.0 + max(lambda, 0.0));
    }
    return 2.0 / (1.0 + sqrt(1.0 + tan2));
}

// Sample the slopes (x, y) of Beckmann normals of roughness 1 visible from a
// direction at cos_t from the normal, in the plane of x: x has density
// exp(-x^2) (1 - x tan) for x < cot, y is a standard Gaussian over sqrt(2).
// x solves 1 + e + tan / sqrt(pi) exp(-erfinv(e)^2) = u (1 + erf(cot) + tan /
// sqrt(pi) exp(-cot^2)) for e = erf(x): the function is increasing and
// concave in e, so Newton's method, kept inside a shrinking bracket, finds it
vec2 beckmann_visible_slopes(float cos_t, vec2 u) {
    u = clamp(u, vec2(1e-6), vec2(1.0 - 1e-6));
    float y = erfinv_approx(2.0 * u.y - 1.0);
    float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
    if (sin_t < 1e-6 * cos_t) {
        // Normal incidence: x is Gaussian too
        return vec2(erfinv_approx(2.0 * u.x - 1.0), y);
    }
    float tan_t = sin_t / cos_t;
    float cot_t = cos_t / sin_t;
    float c = tan_t * INV_SQRT_PI;
    float e_max = erf_approx(cot_t);
    float target = u.x * (1.0 + e_max + c * exp(-cot_t * cot_t));
    // Start from the exact answer at grazing incidence, scaled into range
    float e = e_max - (1.0 + e_max) * erf_approx(sqrt(-log(u.x)));
    float lo = -1.0;
    float hi = e_max;
    for (int i = 0; i < 10; ++i) {
        float x = erfinv_approx(clamp(e, -0.9999999, 0.9999999));
        float g = 1.0 + e + c * exp(-x * x) - target;
        if (g > 0.0) {
            hi = e;
        } else {
            lo = e;
        }
        float next = e - g / max(1.0 - x * tan_t, 1e-12);
        e = (next >= lo && next <= hi) ? next : 0.5 * (lo + hi);
    }
    return vec2(erfinv_approx(clamp(e, -0.9999999, 0.9999999)), y);
}

// Sample a microfacet normal visible from v (v.z > 0), with density
// D(m) G1(v, m) max(0, v.m) / v.z
vec3 microfacet_sample_visible(Microfacet d, vec3 v, vec2 u) {
    // Stretch the view to the distribution of roughness 1
    vec3 vs = normalize(vec3(d.au * v.x, d.av * v.y, v.z));
    if (d.type == MICROFACET_GGX) {
        // Heitz 2018: a uniform point of the disc, squeezed onto the visible
        // half, lifted onto the hemisphere about the stretched view
        float len2 = dot(vs.xy, vs.xy);
        vec3 t1 = len2 > 0.0 ? vec3(-vs.y, vs.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
        vec3 t2 = cross(vs, t1);
        float r = sqrt(u.x);
        float phi = 2.0 * PI * u.y;
        float p1 = r * cos(phi);
        float p2 = r * sin(phi);
        float h = 0.5 * (1.0 + vs.z);
        p2 = (1.0 - h) * sqrt(max(0.0, 1.0 - p1 * p1)) + h * p2;
        vec3 n = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vs;
        // Unstretch
        return normalize(vec3(d.au * n.x, d.av * n.y, max(1e-6, n.z)));
    }
    // Beckmann: slopes in the plane of the stretched view, turned to its
    // azimuth, then unstretched
    float len = length(vs.xy);
    vec2 cs = len > 0.0 ? vs.xy / len : vec2(1.0, 0.0);
    vec2 slope = beckmann_visible_slopes(vs.z, u);
    slope = vec2(cs.x * slope.x - cs.y * slope.y, cs.y * slope.x + cs.x * slope.y);
    slope *= vec2(d.au, d.av);
    return normalize(vec3(-slope, 1.0));
}

// Fresnel reflectance of a conductor of complex index eta + i k, per
// channel, for unpolarised light at cos_i >= 0: the exact expression in
// a^2 + b^2 = |(eta + i k)^2 - sin^2| and a, its real root's real part
vec3 fresnel_conductor(float cos_i, vec3 eta, vec3 k) {
    float c2 = cos_i * cos_i;
    float s2 = 1.0 - c2;
    vec3 t0 = eta * eta - k * k - s2;
    vec3 a2b2 = sqrt(max(t0 * t0 + 4.0 * eta * eta * k * k, vec3(0.0)));
    vec3 a = sqrt(max(0.5 * (a2b2 + t0), vec3(0.0)));
    vec3 t1 = a2b2 + c2;
    vec3 t2 = 2.0 * cos_i * a;
    vec3 rs = (t1 - t2) / (t1 + t2);
    vec3 t3 = a2b2 * c2 + s2 * s2;
    vec3 t4 = t2 * s2;
    // t3 + t4 is 0 only at normal incidence on eta = k = 0, where rp = rs
    vec3 ratio = mix((t3 - t4) / (t3 + t4), vec3(1.0), equal(t3 + t4, vec3(0.0)));
    vec3 rp = rs * ratio;
    return 0.5 * (rs + rp);
}

#endif
