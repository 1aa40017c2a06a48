// Next-event estimation: pick an emitter by power, sample a point on it,
// and give the solid-angle pdf of reaching it, for MIS; or, for a delta
// light (point, spot, directional), the one direction it lights a point by;
// or, for the environment map, a direction drawn from it.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL

#include "common/sampling.glsl"
#include "common/geometry.glsl"
#include "common/envmap.glsl"
#include "common/textures.glsl"

// A point sampled on an emitter, seen from a shading point
struct LightSample {
    vec3 p;       // point on the emitter
    vec3 n;       // emitter normal at p, facing the shading point
    vec3 wi;      // unit direction from the shading point to p
    float dist;   // distance to p
    vec3 le;      // emitted radiance towards the shading point
    float pdf;    // solid-angle pdf, pick probability included; a delta light's pick probability
    float mag;    // magnitude of the coordinates p was computed from (offset_ray_origin)
    bool delta;   // a delta light: no BSDF sample finds it, so no MIS
                  // dist is FLT_MAX for a directional light and the environment map
};

// Compute 1 - cos(theta_max) of the cone a sphere subtends, accurately
float sphere_cone_one_minus_cos(float dist2, float r) {
    float sin2 = min(1.0, (r * r) / dist2);
    return sin2 / (1.0 + sqrt(max(0.0, 1.0 - sin2)));
}

// Give the solid-angle pdf with which NEE samples a hit on emitter `prim`
float light_pdf(Primitive p, vec3 from, vec3 hit_p, vec3 ng, float dist) {
    float pmf = uintBitsToFloat(p.meta.w);
    if (pmf <= 0.0) {
        return 0.0;
    }
    if (prim_kind(p) == PRIM_SPHERE) {
        vec3 dc = p.a.xyz - from;
        float d2 = dot(dc, dc);
        if (d2 <= p.a.w * p.a.w) {
            return 0.0;
        }
        return pmf / (2.0 * PI * sphere_cone_one_minus_cos(d2, p.a.w));
    }
    vec3 wi = (hit_p - from) / dist;
    float cos_l = abs(dot(ng, wi));
    float area = triangle_area(p.a.xyz, p.b.xyz, p.c.xyz);
    return cos_l > 0.0 ? pmf * dist * dist / (cos_l * area) : 0.0;
}

// Read a delta light's image (a spot's texture, a projector's irradiance) at
// Mitsuba's uv, whose v = 0 is the image's top row; 1 without one
vec3 delta_light_texture(DeltaLight l, vec2 uv) {
    uint tex = floatBitsToUint(l.extra.w);
    if (!HAS_TEXTURES || tex == NO_TEXTURE) {
        return vec3(1.0);
    }
    return texture_lookup(tex, vec2(uv.x, 1.0 - uv.y));
}

// Light `from` by delta light `l`, picked with probability pmf: intensity over
// the squared distance (times a spot's falloff and texture), a projector's
// image, or a directional light's irradiance from infinitely far
bool sample_delta_light(DeltaLight l, float pmf, vec3 from, inout LightSample ls) {
    ls.delta = true;
    // Divide by the gain, not multiply the light: the same bits when it is 1
    ls.pdf = pmf / frame.delta_light_gain;
    uint kind = floatBitsToUint(l.p.w);
    if (kind == LIGHT_DIRECTIONAL) {
        // Light arrives against its direction of travel
        ls.wi = -l.p.xyz;
        ls.p = from;
        ls.dist = FLT_MAX;
        ls.le = l.intensity.rgb;
        return pmf > 0.0;
    }
    vec3 to = l.p.xyz - from;
    float d2 = dot(to, to);
    if (!(d2 > 0.0)) {
        return false;
    }
    ls.p = l.p.xyz;
    ls.mag = max_abs(l.p.xyz);
    ls.dist = sqrt(d2);
    ls.wi = to / ls.dist;
    ls.le = l.intensity.rgb / d2;
    if (kind == LIGHT_PROJECTOR) {
        // Project the point onto the image plane at distance 1 in light
        // space, as Mitsuba's perspective mapping of its film does:
        // u = 1/2 - cot_x x / (2 z), v = 1/2 - cot_y y / (2 z)
        vec3 v = from - l.p.xyz;
        vec3 q = vec3(dot(l.local_x.xyz, v), dot(l.local_y.xyz, v), dot(l.local_z.xyz, v));
        if (!(q.z > 0.0)) {
            return false;
        }
        vec2 uv = vec2(0.5) - vec2(l.intensity.w, l.local_x.w) * q.xy / q.z;
        if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) {
            return false;
        }
        // pi scale E(uv) over q.z^2 times the cosine to the axis: the
        // irradiance on the image plane at distance 1 is pi scale E
        float cos_axis = -dot(l.extra.xyz, ls.wi);
        ls.le = l.intensity.rgb * delta_light_texture(l, uv) / (q.z * q.z * cos_axis);
        return pmf > 0.0 && cos_axis > 0.0;
    }
    if (kind == LIGHT_SPOT) {
        // Scale by Mitsuba's falloff: full inside the beam width, linear in
        // angle to zero at the cutoff, measured in light space about +z
        vec3 local = vec3(dot(l.local_x.xyz, -ls.wi), dot(l.local_y.xyz, -ls.wi), dot(l.local_z.xyz, -ls.wi));
        float len = length(local);
        float cos_t = local.z / len;
        if (!(cos_t > l.intensity.w)) {
            return false;
        }
        if (cos_t < l.local_x.w) {
            // The angle left to the cutoff, by atan of its sine and cosine:
            // acos is too coarse near the cutoff on some drivers
            float sin_t = length(local.xy) / len;
            float cos_c = l.intensity.w;
            float sin_c = l.local_y.w;
            float left = atan(sin_c * cos_t - cos_c * sin_t, cos_c * cos_t + sin_c * sin_t);
            ls.le *= left * l.local_z.w;
        }
        if (HAS_TEXTURES && floatBitsToUint(l.extra.w) != NO_TEXTURE) {
            // Scale by the texture, projected as Mitsuba's falloff_curve
            // does: uv = 1/2 + d.xy / (2 d.z tan(cutoff)), d the unit light-space direction
            vec3 d = local / len;
            float tan_cutoff = l.local_y.w / l.intensity.w;
            ls.le *= delta_light_texture(l, vec2(0.5) + 0.5 * d.xy / (d.z * tan_cutoff));
        }
    }
    return pmf > 0.0;
}

// Pick an emitter by power and sample a point on its front side. u.x picks
// the emitter and is then rescaled to [0, 1) within the emitter's share of
// the CDF, as Mitsuba's sample_reuse does, so that the points a pixel's
// stratified pairs give stay stratified over each emitter (over both
// triangles of a quad, say) instead of being split among the emitters at
// random by a number of their own
bool sample_light(vec3 from, vec2 u, out LightSample ls) {
    ls.p = vec3(0.0);
    ls.n = vec3(0.0);
    ls.wi = vec3(0.0);
    ls.dist = 0.0;
    ls.le = vec3(0.0);
    ls.pdf = 0.0;
    ls.mag = 0.0;
    ls.delta = false;

    if (frame.emitter_count == 0u) {
        return false;
    }

    // Pick an entry of the emitter table by binary search over the CDF
    uint lo = 0u;
    uint hi = frame.emitter_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (emitter(mid).cdf <= u.x) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    Emitter e = emitter(lo);

    // Reuse u.x within the picked entry's share: [below, e.cdf) holds it and is not empty
    float below = lo > 0u ? emitter(lo - 1u).cdf : 0.0;
    u.x = min((u.x - below) / (e.cdf - below), ONE_MINUS_EPSILON);
    if (HAS_DELTA_LIGHTS && (e.prim & DELTA_LIGHT_FLAG) != 0u) {
        return sample_delta_light(delta_light(e.prim & ~DELTA_LIGHT_FLAG), e.pmf, from, ls);
    }
    if (HAS_ENVMAP && e.prim == ENVMAP_EMITTER) {
        // Sample a direction from the environment map: the shadow ray runs to infinity
        ls.p = from;
        ls.dist = FLT_MAX;
        bool ok = envmap_sample(envmap_header(), u, ls.wi, ls.le, ls.pdf);
        ls.n = -ls.wi;
        return ok;
    }
    Primitive p = primitive(e.prim);
    Material m = material(p.meta.y);

    if (prim_kind(p) == PRIM_SPHERE) {
        // Sample the cone of directions the sphere subtends
        vec3 dc = p.a.xyz - from;
        float d2 = dot(dc, dc);
        float r = p.a.w;
        if (d2 <= r * r) {
            return false;
        }
        float omc = sphere_cone_one_minus_cos(d2, r);
        vec3 w = sample_uniform_cone(u, omc, dc * inversesqrt(d2));
        float t;
        if (!intersect_sphere(from, w, FLT_MAX, p.a.xyz, r, t)) {
            return false;
        }
        ls.p = from + t * w;
        ls.n = normalize(ls.p - p.a.xyz);
        ls.p = p.a.xyz + r * ls.n;
        ls.mag = max_abs(p.a.xyz) + r;
        ls.wi = w;
        ls.dist = t;
        ls.pdf = e.pmf / (2.0 * PI * omc);
    } else {
        // Sample the triangle uniformly by area
        vec2 b = sample_triangle(u);
        ls.p = (1.0 - b.x - b.y) * p.a.xyz + b.x * p.b.xyz + b.y * p.c.xyz;
        ls.n = triangle_normal(p.a.xyz, p.b.xyz, p.c.xyz);
        ls.mag = max(max_abs(p.a.xyz), max(max_abs(p.b.xyz), max_abs(p.c.xyz)));
        if (ls.mag > GEOM_FAR_RATIO * max_abs(ls.p)) {
            // Far vertices round the interpolated point: move it onto the plane
            ls.p -= (dot(ls.n, ls.p) - p.a.w) * ls.n;
            ls.mag = max_abs(ls.p) + abs(p.a.w);
        }
        vec3 to = ls.p - from;
        float d2 = dot(to, to);
        ls.dist = sqrt(d2);
        ls.wi = to / ls.dist;
        float cos_l = -dot(ls.n, ls.wi);
        // Emission leaves the front side only
        if (cos_l <= 0.0 || !(ls.dist > 0.0)) {
            return false;
        }
        ls.pdf = e.pmf * d2 / (cos_l * e.area);
    }
    ls.le = m.emission.rgb;
    return ls.pdf > 0.0 && !isinf(ls.pdf);
}

#endif
