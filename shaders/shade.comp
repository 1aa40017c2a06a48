#version 450
// shade: one thread per ray of the current queue. Add the emission or the
// environment, sample a light for next-event estimation (to the shadow
// queue), sample the material, apply Russian roulette, and put the path
// that goes on onto the next ray queue.
#extension GL_GOOGLE_include_directive : require
#include "common/bindings.glsl"
#include "common/random.glsl"
#include "common/sampling.glsl"
#include "common/geometry.glsl"
#include "common/bsdf.glsl"
#include "common/lights.glsl"

// Rebuild the surface at a hit: position, oriented normals, uv; mag is the
// magnitude of the coordinates the position was computed from
Surface surface_at(Primitive p, vec3 o, vec3 d, Hit hit, out vec3 ng_front, out float mag) {
    Surface s;
    s.uv = vec2(0.0);
    if (prim_kind(p) == PRIM_SPHERE) {
        // Project the hit back onto the sphere for an accurate position
        vec3 n = normalize(o + hit.t * d - p.a.xyz);
        s.p = p.a.xyz + p.a.w * n;
        mag = max_abs(p.a.xyz) + p.a.w;
        ng_front = n;
        s.ns = n;
        s.uv = vec2(0.5 + atan(n.z, n.x) / (2.0 * PI), 0.5 + asin(clamp(n.y, -1.0, 1.0)) / PI);
    } else {
        // Interpolate the triangle with the barycentrics of the hit
        float b0 = 1.0 - hit.bary.x - hit.bary.y;
        s.p = b0 * p.a.xyz + hit.bary.x * p.b.xyz + hit.bary.y * p.c.xyz;
        ng_front = triangle_normal(p.a.xyz, p.b.xyz, p.c.xyz);
        mag = max(max_abs(p.a.xyz), max(max_abs(p.b.xyz), max_abs(p.c.xyz)));
        float ray_mag = max_abs(o) + hit.t;
        if (mag > GEOM_FAR_RATIO * ray_mag) {
            // Far vertices round the interpolated point: take it from the ray, on the plane
            vec3 q = o + hit.t * d;
            s.p = q - (dot(ng_front, q) - p.a.w) * ng_front;
            mag = ray_mag + abs(p.a.w);
        }
        s.ns = ng_front;
        uint flags = prim_flags(p);
        if ((flags & (PRIM_FLAG_NORMALS | PRIM_FLAG_UVS)) != 0u) {
            TriShading ts = tri_shading(p.meta.z);
            if ((flags & PRIM_FLAG_NORMALS) != 0u) {
                vec3 n = b0 * ts.n0.xyz + hit.bary.x * ts.n1.xyz + hit.bary.y * ts.n2.xyz;
                float len = length(n);
                s.ns = len > 0.0 ? n / len : ng_front;
            }
            if ((flags & PRIM_FLAG_UVS) != 0u) {
                s.uv = b0 * vec2(ts.n0.w, ts.v.x) + hit.bary.x * vec2(ts.n1.w, ts.v.y) + hit.bary.y * vec2(ts.n2.w, ts.v.z);
            }
        }
    }

    // Orient both normals towards the incoming ray; two-sided shading
    s.front = dot(ng_front, d) < 0.0;
    s.ng = s.front ? ng_front : -ng_front;
    if (dot(s.ns, s.ng) < 0.0) {
        s.ns = -s.ns;
    }
    // A shading normal facing away from the ray falls back to the geometric one
    if (dot(s.ns, -d) <= 0.0) {
        s.ns = s.ng;
    }
    return s;
}

void main() {
    uint slot;
    if (!queue_item(ray_queue_of(pc.bounce), slot)) {
        return;
    }

    vec4 o = read_state(ray_origin_texels, slot);
    vec3 d = read_state(ray_dir_texels, slot).xyz;
    vec4 throughput = read_state(throughput_texels, slot);
    Hit hit = read_hit(slot);
    uint prim = hit.prim;
    vec3 radiance = vec3(0.0);

    if (prim == NO_HIT) {
        // Add the environment to an escaped path
        if (HAS_ENVIRONMENT) {
            path_radiance[slot] = read_state(radiance_texels, slot) + vec4(throughput.rgb * frame.environment.rgb, 0.0);
        }
        return;
    }

    Primitive p = primitive(prim);
    Material m = material(p.meta.y);
    vec3 ng_front;
    float mag;
    Surface s = surface_at(p, o.xyz, d, hit, ng_front, mag);
    vec3 wo = -d;

    // Add emission leaving the front side, MIS-weighted against NEE
    if (HAS_EMISSION && m.emission.w > 0.0 && s.front) {
        float w = 1.0;
        if (NEE && throughput.w > 0.0) {
            w = power_heuristic(throughput.w, light_pdf(p, o.xyz, s.p, ng_front, hit.t));
        }
        radiance += throughput.rgb * m.emission.rgb * w;
    }

    // Stop when the next segment would pass max_depth
    uint segments = pc.bounce + 1u;
    if (segments >= frame.max_depth) {
        path_radiance[slot] = read_state(radiance_texels, slot) + vec4(radiance, 0.0);
        return;
    }
    uint dim = RNG_DIMS_CAMERA + pc.bounce * RNG_DIMS_PER_BOUNCE;
    uvec2 ps = path_pixel_sample(slot);
    uint key = rng_key(frame.seed, ps.x, ps.y);

    // Sample a light and queue its shadow ray
    if (NEE && !material_is_delta(m)) {
        LightSample ls;
        vec3 u = vec3(rng_uniform(key, dim), rng_uniform2(key, dim + 1u));
        if (sample_light(s.p, u, ls)) {
            float bsdf_pdf;
            vec3 f = bsdf_eval(m, s, wo, ls.wi, bsdf_pdf);
            vec3 contribution = throughput.rgb * f * ls.le * (power_heuristic(ls.pdf, bsdf_pdf) / ls.pdf);
            if (any(greaterThan(contribution, vec3(0.0)))) {
                vec3 from = offset_ray_origin(s.p, s.ng, mag);
                vec3 to = offset_ray_origin(ls.p, ls.n, ls.mag);
                vec3 dir = to - from;
                float len = length(dir);
                shadow_origin[slot] = vec4(from, len * (1.0 - 1e-5));
                shadow_dir[slot] = vec4(dir / len, 0.0);
                shadow_radiance[slot] = vec4(contribution, 0.0);
                queue_push(SHADOW_QUEUE, slot);
            }
        }
    }

    // Sample the material for the next segment
    BsdfSample bs;
    vec3 u = vec3(rng_uniform2(key, dim + 3u), rng_uniform(key, dim + 5u));
    bool goes_on = bsdf_sample(m, s, wo, u, bs);
    if (goes_on) {
        throughput.rgb *= bs.weight;
        throughput.w = bs.delta ? 0.0 : bs.pdf;

        // Apply Russian roulette to long paths
        if (segments >= RR_MIN_SEGMENTS) {
            // Judge survival without the 1 / ior^2 a path carries while inside
            // a dielectric (pbrt's etaScale), or glass paths die needlessly
            float rr_scale = 1.0;
            if (material_present(MAT_DIELECTRIC) && m.info.x == MAT_DIELECTRIC && dot(bs.wi, ng_front) < 0.0) {
                rr_scale = m.color.w * m.color.w;
            }
            float survive = min(max(throughput.r, max(throughput.g, throughput.b)) * rr_scale, 0.95);
            if (rng_uniform(key, dim + 6u) >= survive) {
                goes_on = false;
            } else {
                throughput.rgb /= survive;
            }
        }
        goes_on = goes_on && any(greaterThan(throughput.rgb, vec3(0.0)));
    }

    if (goes_on) {
        // Enqueue the continuation ray
        vec3 side = dot(bs.wi, s.ng) > 0.0 ? s.ng : -s.ng;
        ray_origin[slot] = vec4(offset_ray_origin(s.p, side, mag), FLT_MAX);
        ray_dir[slot] = vec4(bs.wi, 0.0);
        path_throughput[slot] = throughput;
        queue_push(ray_queue_of(pc.bounce + 1u), slot);
    }
    path_radiance[slot] = read_state(radiance_texels, slot) + vec4(radiance, 0.0);
}
