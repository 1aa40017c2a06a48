// The life of one path, shared by both schedules: the wavefront kernels
// (generate, intersect, shade, shadow, accumulate) call these functions on
// path state they read from and write to the path-state buffers and queues;
// the megakernel calls the very same functions on path state it keeps in
// registers. Same code, same arithmetic, same order: the same image.
#ifndef PATH_GLSL
#define PATH_GLSL

#include "common/bindings.glsl"
#include "common/sampler.glsl"
#include "common/sampling.glsl"
#include "common/geometry.glsl"
#include "common/bsdf.glsl"
#include "common/lights.glsl"
#include "common/traverse.glsl"
#include "common/filter.glsl"

// The state a path carries from one bounce to the next
struct PathState {
    vec4 origin;      // xyz ray origin, w tmax
    vec4 dir;         // xyz unit ray direction
    vec4 throughput;  // rgb path throughput, w pdf of the last BSDF sample (0 if delta)
    vec4 radiance;    // rgb radiance gathered so far
};

// A next-event estimation sample: the segment to the light and what it adds
struct ShadowRay {
    vec4 origin;    // xyz start, w length to the light
    vec4 dir;       // xyz unit direction
    vec4 radiance;  // rgb radiance the path gains when nothing is in the way
};

// What shading one hit decided
struct Shading {
    bool adds;             // the path's radiance gains `emitted`
    vec4 emitted;          // emission or environment, to add to the radiance now
    bool shadow;           // a light sample to test for occlusion
    ShadowRay shadow_ray;  // that sample
    bool goes_on;          // the path state holds the continuation ray
};

// The magnitude of a throughput or contribution: a pixel filter with
// negative lobes starts some paths with a negative weight
vec3 signless(vec3 v) {
    return HAS_FILTER ? abs(v) : v;
}

// Tell whether the camera has a lens (a thin lens of radius above 0), whose
// position then takes a pair of the path's numbers
bool camera_has_lens() {
    return HAS_DOF && frame.eye.w > 0.0;
}

// Draw the light sample of bounce `bounce`, whose first dimension is dim,
// as one 4D point with the pair that chose the point it lights: the BSDF
// direction of the bounce before, or at the first hit the pixel position,
// unless the lens has taken that (render::sobol)
vec2 light_sample_numbers(SampleStream st, uint bounce, uint dim) {
    if (bounce > 0u) {
        return sample_2d_partnered(st, dim + RNG_DIM_LIGHT, dim - RNG_DIMS_PER_BOUNCE + RNG_DIM_BSDF);
    }
    if (camera_has_lens()) {
        return sample_2d(st, dim + RNG_DIM_LIGHT);
    }
    return sample_2d_partnered(st, dim + RNG_DIM_LIGHT, RNG_DIM_PIXEL);
}

// Start the path of wave slot `slot`: its camera ray through its pixel and sample
PathState start_path(uint slot) {
    // Locate the pixel and sample this path slot renders
    uvec2 ps = path_pixel_sample(slot);
    uint pixel = ps.x;
    uint sample_index = ps.y;
    SampleStream st = sample_stream(frame.seed, pixel, sample_index, frame.halves != 0u);
    vec2 pixel_xy = vec2(float(pixel % frame.width), float(pixel / frame.width));

    // Jitter the sample inside its stratum of the pixel; the Sobol sampler's
    // pairs are stratified already, at every power of two
    vec2 jitter = sample_2d(st, RNG_DIM_PIXEL);
    if (SAMPLER == SAMPLER_INDEPENDENT && frame.strata > 0u) {
        uint cell = sample_index % (frame.strata * frame.strata);
        vec2 stratum = vec2(float(cell % frame.strata), float(cell / frame.strata));
        jitter = (stratum + jitter) / float(frame.strata);
    }
    vec2 film = (pixel_xy + jitter) / vec2(float(frame.width), float(frame.height));
    float weight = 1.0;
    if (HAS_FILTER && frame.filter_kind != FILTER_BOX) {
        // Draw the film offset from the pixel filter, stratified as the
        // jitter was, and start the path with the filter's weight
        vec2 fx, fy;
        if (HAS_FILM_EDGE) {
            // Keep the film position inside the image (sample_border false)
            fx = sample_filter_cut(jitter.x, pixel % frame.width, frame.width);
            fy = sample_filter_cut(jitter.y, pixel / frame.width, frame.height);
        } else {
            fx = sample_filter(jitter.x);
            fy = sample_filter(jitter.y);
        }
        film = (pixel_xy + 0.5 + vec2(fx.x, fy.x)) / vec2(float(frame.width), float(frame.height));
        weight = fx.y * fy.y;
    }

    // Shoot a ray through the film point
    vec2 ndc = vec2(2.0 * film.x - 1.0, 1.0 - 2.0 * film.y);
    if (HAS_ORTHO && frame.clip.w != 0.0) {
        // Start an orthographic ray on the near plane at the film point, along
        // the optical axis, for far - near (Mitsuba's orthographic sensor).
        // The crop window's shift (zero without one) is added whatever
        // HAS_CAM_SHIFT says, so that no other effect changes how this
        // sum rounds: --all-features keeps the image bit for bit
        vec3 offset = ndc.x * frame.cam_u.w * frame.cam_u.xyz + ndc.y * frame.cam_v.w * frame.cam_v.xyz
            + frame.cam_shift.xyz;
        return PathState(vec4(frame.eye.xyz + offset, frame.clip.y - frame.clip.x),
                         vec4(-frame.cam_w.xyz, 0.0), vec4(weight, weight, weight, 0.0), vec4(0.0));
    }
    vec3 dir = ndc.x * frame.cam_u.w * frame.cam_u.xyz + ndc.y * frame.cam_v.w * frame.cam_v.xyz
        - frame.cam_w.xyz;
    if (HAS_CAM_SHIFT) {
        // Move the image off the optical axis (crop window, principal point)
        dir += frame.cam_shift.xyz;
    }
    vec3 origin = frame.eye.xyz;
    if (camera_has_lens()) {
        // Move the origin across the thin lens and aim at the plane in focus,
        // relative to the eye: (eye + dir f) - (eye + lens) would cancel far
        // from the origin. The lens position and the pixel position are one 4D point
        vec2 lens = frame.eye.w * sample_disk_concentric(sample_2d_partnered(st, RNG_DIM_LENS, RNG_DIM_PIXEL));
        vec3 lens_offset = lens.x * frame.cam_u.xyz + lens.y * frame.cam_v.xyz;
        origin += lens_offset;
        dir = dir * frame.cam_w.w - lens_offset;
    }

    dir = normalize(dir);
    float tmax = FLT_MAX;
    if (HAS_CLIP && frame.clip.z != 0.0) {
        // Clip the ray to the near and far planes, distances along the optical axis
        float inv_z = 1.0 / dot(dir, -frame.cam_w.xyz);
        float near_t = frame.clip.x * inv_z;
        float far_t = frame.clip.y * inv_z;
        origin += dir * near_t;
        tmax = min(far_t - near_t, FLT_MAX);
    }

    // Start with the filter's weight as throughput and no radiance
    return PathState(vec4(origin, tmax), vec4(dir, 0.0), vec4(weight, weight, weight, 0.0), vec4(0.0));
}

// Find the closest hit of the ray (origin, tmax in w; direction)
Hit closest_hit(vec4 o, vec3 d) {
    uint prim;
    float t;
    vec2 bary;
    trace(o.xyz, d, o.w, false, prim, t, bary);
    return Hit(t, prim, bary);
}

// Tell whether nothing blocks the segment of a shadow ray (origin, length in w)
bool unoccluded(vec4 o, vec3 d) {
    uint prim;
    float t;
    vec2 bary;
    return !trace(o.xyz, d, o.w, true, prim, t, bary);
}

// The local z axis of a Mitsuba sphere's frame (PRIM_FLAG_MITSUBA_FRAME)
vec3 sphere_axis_z(Primitive p) { return p.b.w * cross(p.b.xyz, p.c.xyz); }

// The local coordinates of world direction v in a Mitsuba sphere's frame
// (PRIM_FLAG_MITSUBA_FRAME)
vec3 sphere_local(Primitive p, vec3 v) {
    return vec3(dot(v, p.b.xyz), dot(v, p.c.xyz), dot(v, sphere_axis_z(p)));
}

// Rebuild the surface at a hit: position, oriented normals, uv; mag is the
// magnitude of the coordinates the position was computed from
Surface surface_at(Primitive p, vec3 o, vec3 d, Hit hit, out vec3 ng_front, out float mag) {
    Surface s;
    s.uv = vec2(0.0);
    s.dpdu = vec3(0.0);
    bool sphere = prim_kind(p) == PRIM_SPHERE;
    s.tri = sphere ? NO_TEXTURE : p.meta.z;
    s.bary = hit.bary;
    if (sphere) {
        // Project the hit back onto the sphere for an accurate position
        vec3 n = normalize(o + hit.t * d - p.a.xyz);
        s.p = p.a.xyz + p.a.w * n;
        mag = max_abs(p.a.xyz) + p.a.w;
        ng_front = n;
        s.ns = n;
        if ((prim_flags(p) & PRIM_FLAG_MITSUBA_FRAME) == 0u) {
            s.uv = vec2(0.5 + atan(n.z, n.x) / (2.0 * PI), 0.5 + asin(clamp(n.y, -1.0, 1.0)) / PI);
        } else {
            // Take Mitsuba's: the angle about local z from local x, and the
            // angle from local +z, v turned to lancer's orientation
            vec3 l = sphere_local(p, n);
            float u = atan(l.y, l.x) / (2.0 * PI);
            s.uv = vec2(u < 0.0 ? u + 1.0 : u, 1.0 - acos(clamp(l.z, -1.0, 1.0)) / PI);
        }
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

    // Orient both normals towards the incoming ray; two-sided shading. A
    // sphere's side is where the ray starts, as intersect_sphere chose its
    // root: a ray from outside that grazes it meets the outside, even where
    // the rounded normal turns away from the ray
    s.front = sphere ? sphere_hit_from_outside(o, p.a.xyz, p.a.w) : dot(ng_front, d) < 0.0;
    s.ns_front = s.ns;
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

// The tangent dp/du at surface s of primitive p, as Mitsuba's shapes define
// it: on a sphere along its parallels about its local z axis (the world's
// z for lancer's own spheres, which are not rotated); on a triangle from
// its texture coordinates, or its first edge (p1 - p0) when it has none;
// where that is degenerate, the tangent of the orthonormal basis about the
// front-side normal
vec3 surface_dpdu(Primitive p, Surface s, vec3 ng_front) {
    vec3 dpdu = vec3(0.0);
    vec3 n_front = ng_front;
    if (prim_kind(p) == PRIM_SPHERE) {
        vec3 local = s.p - p.a.xyz;
        dpdu = vec3(-local.y, local.x, 0.0);
        if ((prim_flags(p) & PRIM_FLAG_MITSUBA_FRAME) != 0u) {
            // Turn the local 2 pi (-y, x, 0) into the world, as Mitsuba scales it
            vec3 l = sphere_local(p, local);
            dpdu = 2.0 * PI * (-l.y * p.b.xyz + l.x * p.c.xyz);
        }
    } else {
        vec3 dp0 = p.b.xyz - p.a.xyz;
        vec3 dp1 = p.c.xyz - p.a.xyz;
        dpdu = dp0;
        if ((prim_flags(p) & PRIM_FLAG_UVS) != 0u) {
            TriShading ts = tri_shading(p.meta.z);
            vec2 duv0 = vec2(ts.n1.w - ts.n0.w, ts.v.y - ts.v.x);
            vec2 duv1 = vec2(ts.n2.w - ts.n0.w, ts.v.z - ts.v.x);
            float det = duv0.x * duv1.y - duv0.y * duv1.x;
            vec3 t, b;
            orthonormal_basis(ng_front, t, b);
            dpdu = det != 0.0 ? (duv1.y * dp0 - duv0.y * dp1) / det : t;
        }
        n_front = s.front ? s.ns : -s.ns;
    }
    if (all(equal(dpdu, vec3(0.0)))) {
        vec3 t, b;
        orthonormal_basis(n_front, t, b);
        dpdu = t;
    }
    return dpdu;
}

// The tangent dp/dv at surface s of primitive p in Mitsuba's texture
// coordinates, whose v runs opposite to lancer's (a bump map's second
// axis): on a triangle from its texture coordinates, or its second edge
// (p2 - p0) when it has none or they are degenerate; on a sphere (whose
// texture coordinates are lancer's own) the normal times dp/du; on a
// sphere in Mitsuba's frame, Mitsuba's pi (z cos phi, z sin phi, -r_xy)
// along the meridian, in the world
vec3 surface_dpdv(Primitive p, Surface s) {
    if (prim_kind(p) == PRIM_SPHERE) {
        if ((prim_flags(p) & PRIM_FLAG_MITSUBA_FRAME) != 0u) {
            vec3 l = sphere_local(p, s.p - p.a.xyz);
            float rd = length(l.xy);
            vec3 z = sphere_axis_z(p);
            // At a pole, Mitsuba takes local x
            vec3 dv = rd > 0.0 ? l.z * (l.x * p.b.xyz + l.y * p.c.xyz) / rd - rd * z : p.a.w * p.b.xyz;
            return PI * dv;
        }
        return cross(s.ns_front, s.dpdu);
    }
    vec3 dp0 = p.b.xyz - p.a.xyz;
    vec3 dp1 = p.c.xyz - p.a.xyz;
    if ((prim_flags(p) & PRIM_FLAG_UVS) != 0u) {
        TriShading ts = tri_shading(p.meta.z);
        vec2 duv0 = vec2(ts.n1.w - ts.n0.w, ts.v.y - ts.v.x);
        vec2 duv1 = vec2(ts.n2.w - ts.n0.w, ts.v.z - ts.v.x);
        float det = duv0.x * duv1.y - duv0.y * duv1.x;
        if (det != 0.0) {
            return -(duv0.x * dp1 - duv1.x * dp0) / det;
        }
    }
    return dp1;
}

// Find the closest hit of the ray of bounce `bounce` (origin, tmax in w;
// direction). When emitters are hidden, a camera ray passes through area
// emitters, as Mitsuba's hide_emitters does; the hit's t stays measured
// from the camera ray's origin.
Hit first_hit(vec4 o, vec3 d, uint bounce) {
    Hit hit = closest_hit(o, d);
    if (HAS_EMISSION && bounce == 0u && path_flag(PATH_FLAG_HIDE_EMITTERS)) {
        for (uint i = 0u; i < MAX_HIDDEN_EMITTER_SKIPS && hit.prim != NO_HIT; ++i) {
            Primitive p = primitive(hit.prim);
            if (material(p.meta.y).emission.w <= 0.0) {
                break;
            }
            // Go on from just behind the emitter
            vec3 ng_front;
            float mag;
            Surface s = surface_at(p, o.xyz, d, hit, ng_front, mag);
            vec3 behind = offset_ray_origin(s.p, -s.ng, mag);
            hit = closest_hit(vec4(behind, FLT_MAX), d);
            if (hit.prim != NO_HIT) {
                hit.t += dot(behind - o.xyz, d);
            }
        }
    }
    return hit;
}

// The origin of a ray leaving surface s (position computed from coordinates
// of magnitude mag) along wi: on the side of the surface wi leaves by
vec3 spawn_origin(Surface s, float mag, vec3 wi) {
    // Offset to the side wi points to
    vec3 side = dot(wi, s.ng) > 0.0 ? s.ng : -s.ng;
    return offset_ray_origin(s.p, side, mag);
}

// The shadow ray from surface point p (normal n on the side of the segment,
// coordinates of magnitude mag) to the light point lp (normal ln facing p,
// magnitude lmag), both ends offset off their surfaces and the length
// shortened by a relative 1e-5, carrying `radiance`
ShadowRay shadow_segment(vec3 p, vec3 n, float mag, vec3 lp, vec3 ln, float lmag, vec3 radiance) {
    // Offset both ends, then aim from one to the other
    vec3 from = offset_ray_origin(p, n, mag);
    vec3 to = offset_ray_origin(lp, ln, lmag);
    vec3 dir = to - from;
    float len = length(dir);
    return ShadowRay(vec4(from, len * (1.0 - 1e-5)), vec4(dir / len, 0.0), vec4(radiance, 0.0));
}

// Shade the hit of bounce `bounce` of the path in slot `slot`: add the
// emission or the environment, sample a light for next-event estimation,
// sample the material and apply Russian roulette. On return the path
// state holds the continuation ray and throughput when `goes_on`; its
// radiance is left alone: the caller adds `emitted`, then the light sample
// if unoccluded, in that order.
Shading shade_hit(uint slot, uint bounce, Hit hit, inout PathState path) {
    Shading sh;
    sh.adds = false;
    sh.emitted = vec4(0.0);
    sh.shadow = false;
    sh.goes_on = false;
    vec4 o = path.origin;
    vec3 d = path.dir.xyz;
    vec4 throughput = path.throughput;
    uint prim = hit.prim;
    vec3 radiance = vec3(0.0);

    // Camera rays see no environment and no emitter when emitters are hidden
    bool hidden = bounce == 0u && path_flag(PATH_FLAG_HIDE_EMITTERS);
    if (prim == NO_HIT) {
        EnvmapHeader env;
        if (HAS_ENVMAP && envmap_present(env = envmap_header())) {
            // Add the environment map's radiance, MIS-weighted against NEE
            if (!hidden) {
                float w = 1.0;
                if (NEE && throughput.w > 0.0) {
                    w = power_heuristic(throughput.w, envmap_pdf(env, d));
                }
                sh.adds = true;
                sh.emitted = vec4(throughput.rgb * envmap_radiance(env, d) * w, 0.0);
            }
            return sh;
        }
        // Add the environment to an escaped path
        if (HAS_ENVIRONMENT && !hidden) {
            sh.adds = true;
            sh.emitted = vec4(throughput.rgb * frame.environment.rgb, 0.0);
        }
        return sh;
    }

    Primitive p = primitive(prim);
    Material m = material(p.meta.y);
    vec3 ng_front;
    float mag;
    Surface s = surface_at(p, o.xyz, d, hit, ng_front, mag);
    m = surface_material(m, s);
    vec3 wo = -d;
    // Find the tangent where the material or its normal map needs one, once
    if ((material_present(MAT_ROUGHCONDUCTOR) && m.info.x == MAT_ROUGHCONDUCTOR)
        || (material_present(MAT_ROUGHDIELECTRIC) && m.info.x == MAT_ROUGHDIELECTRIC)
        || (material_present(MAT_PRINCIPLED) && m.info.x == MAT_PRINCIPLED)
        || (HAS_NORMAL_MAP && (m.info.z & MAT_FLAG_NORMAL_MAP) != 0u) || material_is_blend(m)) {
        s.dpdu = surface_dpdu(p, s, ng_front);
    }

    // Add emission leaving the front side, MIS-weighted against NEE
    if (HAS_EMISSION && m.emission.w > 0.0 && s.front && !hidden) {
        float w = 1.0;
        if (NEE && throughput.w > 0.0) {
            w = power_heuristic(throughput.w, light_pdf(p, o.xyz, s.p, ng_front, hit.t));
        }
        radiance += throughput.rgb * m.emission.rgb * w;
    }
    sh.adds = true;

    // Find how likely light is to meet a masked surface here (Mitsuba's
    // mask); where it does not, it passes straight through
    bool masked = HAS_MASK && (m.info.z & MAT_FLAG_MASKED) != 0u;
    float opacity = masked ? material_opacity(m, s) : 1.0;

    // Take the side from the shading normal, as Mitsuba does (directions
    // below the geometric surface still carry nothing: no light leaks)
    bool scatters = true;
    if (HAS_SHADING_SIDES && (m.info.z & MAT_FLAG_SHADING_SIDE) != 0u && m.info.x != MAT_DIELECTRIC) {
        bool front_shading = dot(s.ns_front, wo) > 0.0;
        if ((m.info.z & MAT_FLAG_FRONT_ONLY) != 0u && !front_shading) {
            // End the path behind a front-only material, which scatters
            // nothing there, unless a mask may let it through
            if (!masked) {
                sh.emitted = vec4(radiance, 0.0);
                return sh;
            }
            scatters = false;
        }
        s.ns = front_shading ? s.ns_front : -s.ns_front;
    }

    // Tilt the shading normal by a normal map; nothing scatters where the
    // viewer is behind the tilted normal
    bool tilted = HAS_NORMAL_MAP && scatters && (m.info.z & MAT_FLAG_NORMAL_MAP) != 0u;
    vec3 n_base = s.ns;
    if (tilted) {
        vec3 dpdv = (m.info.z & MAT_FLAG_BUMP_MAP) != 0u ? surface_dpdv(p, s) : vec3(0.0);
        tilt_shading_normal(m, s, wo, dpdv, ng_front);
        scatters = dot(wo, s.ns) > 0.0;
    }

    // Stop when the next segment would pass max_depth
    uint segments = bounce + 1u;
    if (segments >= frame.max_depth) {
        sh.emitted = vec4(radiance, 0.0);
        return sh;
    }
    uint dim = RNG_DIMS_CAMERA + bounce * RNG_DIMS_PER_BOUNCE;
    uvec2 ps = path_pixel_sample(slot);
    SampleStream st = sample_stream(frame.seed, ps.x, ps.y, frame.halves != 0u);

    // Sample a light for a shadow ray
    if (NEE && scatters && !material_is_delta(m)) {
        LightSample ls;
        if (sample_light(s.p, light_sample_numbers(st, bounce, dim), ls)) {
            float bsdf_pdf;
            vec3 f = bsdf_eval(m, s, wo, ls.wi, bsdf_pdf);
            if (masked) {
                // Scatter only where the surface is met, as Mitsuba's mask evaluates
                f *= opacity;
                bsdf_pdf *= opacity;
            }
            if (tilted) {
                // Take light only from the side of both normals, shadowed by the tilt
                float k = tilt_factor(m, n_base, s.ns, ls.wi);
                f *= k;
                bsdf_pdf = k > 0.0 ? bsdf_pdf : 0.0;
            }
            // No BSDF sample finds a delta light, nor any light when emitter sampling runs alone
            bool alone = (HAS_DELTA_LIGHTS && ls.delta) || path_flag(PATH_FLAG_EMITTER_SAMPLING_ONLY);
            float w = alone ? 1.0 : power_heuristic(ls.pdf, bsdf_pdf);
            vec3 contribution = throughput.rgb * f * ls.le * (w / ls.pdf);
            if (any(greaterThan(signless(contribution), vec3(0.0)))) {
                sh.shadow = true;
                // Leave by the side the light is on: behind a rough dielectric when it refracts
                vec3 n_side = s.ng;
                if (material_present(MAT_ROUGHDIELECTRIC) && dot(ls.wi, s.ng) < 0.0) {
                    n_side = -s.ng;
                }
                if ((HAS_DELTA_LIGHTS || HAS_ENVMAP) && ls.dist == FLT_MAX) {
                    // Aim at a directional light or the environment map: the shadow ray runs to infinity
                    sh.shadow_ray = ShadowRay(vec4(offset_ray_origin(s.p, n_side, mag), FLT_MAX), vec4(ls.wi, 0.0),
                                              vec4(contribution, 0.0));
                } else {
                    sh.shadow_ray = shadow_segment(s.p, n_side, mag, ls.p, ls.n, ls.mag, contribution);
                }
            }
        }
    }

    // End the path after the light sample when emitter sampling runs alone
    if (path_flag(PATH_FLAG_EMITTER_SAMPLING_ONLY)) {
        sh.emitted = vec4(radiance, 0.0);
        return sh;
    }

    // Sample the material for the next segment
    BsdfSample bs;
    vec3 u = vec3(sample_2d(st, dim + RNG_DIM_BSDF), sample_1d(st, dim + RNG_DIM_LOBE));
    bool goes_on;
    bool passes = masked && u.z >= opacity;
    if (passes) {
        // Pass straight through where the surface is not met: a null event
        // of probability 1 - opacity and weight 1, which counts as a
        // bounce and, like a delta lobe, takes no MIS weight (Mitsuba's mask)
        bs = BsdfSample(d, vec3(1.0), 1.0 - opacity, true, false);
        goes_on = true;
    } else {
        if (masked) {
            // Reuse the lobe number inside the share where the surface is met
            u.z /= opacity;
        }
        goes_on = scatters && bsdf_sample(m, s, wo, u, bs);
        if (masked) {
            bs.pdf *= opacity;
        }
        if (goes_on && tilted) {
            // Leave only to the side of both normals, shadowed by the tilt
            float k = tilt_factor(m, n_base, s.ns, bs.wi);
            bs.weight *= k;
            goes_on = k > 0.0;
        }
    }
    if (goes_on) {
        throughput.rgb *= bs.weight;
        throughput.w = bs.delta ? 0.0 : bs.pdf;

        // Apply Russian roulette to long paths
        if (segments >= frame.rr_depth) {
            // Judge survival without the 1 / ior^2 a path carries while inside
            // a dielectric (pbrt's etaScale), or glass paths die needlessly
            float rr_scale = 1.0;
            if (material_present(MAT_DIELECTRIC) && m.info.x == MAT_DIELECTRIC && dot(bs.wi, ng_front) < 0.0
                && !passes) {
                rr_scale = m.color.w * m.color.w;
            }
            if (material_present(MAT_ROUGHDIELECTRIC) && m.info.x == MAT_ROUGHDIELECTRIC
                && dot(bs.wi, ng_front) < 0.0 && !passes) {
                rr_scale = m.params.x * m.params.x;
            }
            vec3 size = signless(throughput.rgb);
            float survive = min(max(size.r, max(size.g, size.b)) * rr_scale, 0.95);
            if (sample_1d(st, dim + RNG_DIM_ROULETTE) >= survive) {
                goes_on = false;
            } else {
                throughput.rgb /= survive;
            }
        }
        goes_on = goes_on && any(greaterThan(signless(throughput.rgb), vec3(0.0)));
    }

    if (goes_on) {
        // Continue from the side of the surface the sample leaves by
        path.origin = vec4(spawn_origin(s, mag, bs.wi), FLT_MAX);
        path.dir = vec4(bs.wi, 0.0);
        path.throughput = throughput;
    }
    sh.goes_on = goes_on;
    sh.emitted = vec4(radiance, 0.0);
    return sh;
}

// Follow the path of slot `slot` from its camera ray to its end, the
// shadow rays traced inline, and return its radiance: the wavefront's
// passes in the same order, with the path state in registers
vec3 trace_path(uint slot) {
    PathState path = start_path(slot);
    for (uint bounce = 0u; bounce < frame.max_depth; ++bounce) {
        Hit hit = first_hit(path.origin, path.dir.xyz, bounce);
        Shading sh = shade_hit(slot, bounce, hit, path);
        // Emission first, then the light sample, as shade and shadow add them
        if (sh.adds) {
            path.radiance = path.radiance + sh.emitted;
        }
        if (sh.shadow && unoccluded(sh.shadow_ray.origin, sh.shadow_ray.dir.xyz)) {
            path.radiance = path.radiance + sh.shadow_ray.radiance;
        }
        if (!sh.goes_on) {
            break;
        }
    }
    return path.radiance.rgb;
}

#endif
