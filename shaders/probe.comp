#version 450
// probe: a test hook, not a pass (Renderer::probe_rays). One thread per
// ray of queue 0. Find the surface point A the ray hits, counting the BVH
// nodes and primitives the trace visits; leave A along a given direction
// from the origin shade would spawn, and test the new ray against A itself;
// find the surface point B a second ray hits, and test the shadow segment
// shade would build from A to B against A and B.
//
// In, per slot: ray_origin (o, tmax) and ray_dir (d) of the ray to A;
// path_throughput.xyz, the direction leaving A; shadow_origin (o, tmax) and
// shadow_dir (d) of the ray to B. Out: path_radiance = bits of (A's
// primitive, B's primitive, flags, visits), flags bit 0 the spawned ray hit
// A, bit 1 the shadow segment hit A or B, bit 2 A was hit on its front
// side (as shade sees it); hits = the spawned ray's hit on A
// (t, primitive); path_throughput.xyz = A's position, shadow_origin.xyz =
// B's position.
#extension GL_GOOGLE_include_directive : require
#define TRACE_COUNT_VISITS
#include "common/path.glsl"

// Test a ray against one primitive only; on a hit t is its distance
bool hits_primitive(uint prim, vec3 o, vec3 d, float tmax, out float t) {
    float reach = tmax;
    vec2 bary;
    bool hit = intersect_primitive(prim, o, d, triangle_ray(o, d), reach, bary);
    t = reach;
    return hit;
}

void main() {
    uint slot;
    if (!queue_item(ray_queue_of(0u), slot)) {
        return;
    }

    // Find A, counting the visits of its trace
    vec4 o = ray_origin[slot];
    vec3 d = ray_dir[slot].xyz;
    vec3 wi = path_throughput[slot].xyz;
    vec4 ob = shadow_origin[slot];
    vec3 db = shadow_dir[slot].xyz;
    trace_visits = 0u;
    Hit a = closest_hit(o, d);
    uint visits = trace_visits;
    uint b_prim = NO_HIT;
    uint flags = 0u;
    Hit self_hit = Hit(0.0, NO_HIT, vec2(0.0));
    vec3 pa = vec3(0.0);
    vec3 pb = vec3(0.0);

    if (a.prim != NO_HIT) {
        // Leave A along wi from shade's spawned origin; does the ray hit A again?
        vec3 nga;
        float maga;
        Surface sa = surface_at(primitive(a.prim), o.xyz, d, a, nga, maga);
        pa = sa.p;
        if (sa.front) {
            flags |= 4u;
        }
        vec3 o2 = spawn_origin(sa, maga, wi);
        float t;
        if (hits_primitive(a.prim, o2, wi, FLT_MAX, t)) {
            flags |= 1u;
            self_hit = Hit(t, a.prim, vec2(0.0));
        }

        // Find B, and test shade's shadow segment from A to B against both
        Hit b = closest_hit(ob, db);
        b_prim = b.prim;
        if (b.prim != NO_HIT && b.prim != a.prim) {
            vec3 ngb;
            float magb;
            Surface sb = surface_at(primitive(b.prim), ob.xyz, db, b, ngb, magb);
            pb = sb.p;
            ShadowRay sr = shadow_segment(sa.p, sa.ng, maga, sb.p, sb.ng, magb, vec3(0.0));
            float ts;
            if (hits_primitive(a.prim, sr.origin.xyz, sr.dir.xyz, sr.origin.w, ts)
                || hits_primitive(b.prim, sr.origin.xyz, sr.dir.xyz, sr.origin.w, ts)) {
                flags |= 2u;
            }
        }
    }

    // Write what was found
    hits[slot] = self_hit;
    path_radiance[slot] = uintBitsToFloat(uvec4(a.prim, b_prim, flags, visits));
    path_throughput[slot] = vec4(pa, 0.0);
    shadow_origin[slot] = vec4(pb, 0.0);
}
