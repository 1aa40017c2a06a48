// BVH traversal for closest hits and for occlusion, over spheres and
// triangles together. Mirrors `Bvh::closest_hit` in src/bvh.rs.
#ifndef TRAVERSE_GLSL
#define TRAVERSE_GLSL

#include "common/geometry.glsl"

// Intersect one primitive; on a hit closer than tmax, shorten tmax
bool intersect_primitive(uint index, vec3 o, vec3 d, TriangleRay tri_ray, inout float tmax, out vec2 bary) {
    Primitive p = primitive(index);
    float t;
    bary = vec2(0.0);
    uint kind = prim_kind(p);
    if (HAS_SPHERES && kind == PRIM_SPHERE) {
        if (intersect_sphere(o, d, tmax, p.a.xyz, p.a.w, t)) {
            tmax = t;
            return true;
        }
    } else if (HAS_TRIANGLES && kind == PRIM_TRIANGLE) {
        if (intersect_triangle_prepared(tri_ray, tmax, p.a.xyz, p.b.xyz, p.c.xyz, p.a.w, t, bary)) {
            tmax = t;
            return true;
        }
    }
    return false;
}

// Interior nodes and primitives the traces of this invocation visited,
// counted only where the kernel defines TRACE_COUNT_VISITS (the probe test
// hook): the production kernels do not carry the counter
#ifdef TRACE_COUNT_VISITS
uint trace_visits;
#endif

// Deferred nodes of the trace in progress: references and entry distances
uint stack_ref[BVH_STACK_SIZE];
float stack_t[BVH_STACK_SIZE];

// Split a node reference into its index (pair or first primitive) and count
void open_ref(uint ref, out uint index, out uint count) {
    index = ref >> BVH_REF_COUNT_BITS;
    count = ref & ((1u << BVH_REF_COUNT_BITS) - 1u);
}

// Pop the next deferred node that is still in reach; false when none is left
bool pop_node(inout int sp, float hit_t, out uint ref) {
    while (sp > 0) {
        --sp;
        if (stack_t[sp] <= hit_t) {
            ref = stack_ref[sp];
            return true;
        }
    }
    return false;
}

// Decode a child's quantised box and slab-test it; t is its entry distance
bool child_test(uvec4 c, BvhGrid g, vec3 o, vec3 inv_d, float tmax, out float t) {
    // Corners as grid steps; multiply and add unfused, as bvh_grid.rs checks
    precise vec3 bmin = g.origin + vec3(c.x & 0xFFFFu, c.x >> 16, c.y & 0xFFFFu) * g.scale;
    precise vec3 bmax = g.origin + vec3(c.y >> 16, c.z & 0xFFFFu, c.z >> 16) * g.scale;
    return slab_test(o, inv_d, tmax, bmin, bmax, t);
}

// Trace a ray through the BVH; any_hit stops at the first hit found
bool trace(vec3 o, vec3 d, float tmax, bool any_hit, out uint hit_prim, out float hit_t, out vec2 hit_bary) {
    hit_prim = NO_HIT;
    hit_t = tmax;
    hit_bary = vec2(0.0);
    if (frame.primitive_count == 0u) {
        return false;
    }
    // Miss a ray with a NaN or infinite component, a zero direction or no
    // reach: its slab tests would not cull (NaN compares false), so it
    // would visit every node, and a zero direction from inside a sphere
    // would "hit" it
    bool finite_ray = all(lessThanEqual(abs(o), vec3(GEOM_FLT_MAX))) && all(lessThanEqual(abs(d), vec3(GEOM_FLT_MAX)));
    if (!finite_ray || dot(d, d) == 0.0 || !(tmax > 0.0)) {
        return false;
    }
    vec3 inv_d = safe_inverse(d);
    TriangleRay tri_ray = triangle_ray(o, d);
    BvhGrid grid = bvh_grid();

    // Cull the ray against the scene's box: the top of the grid. The flat
    // axes of a scene are exact here, which keeps grazing rays that leave a
    // large axis-aligned plane from hitting it again
    float t_enter;
    precise vec3 scene_max = grid.origin + 65535.0 * grid.scale;
    if (!slab_test(o, inv_d, tmax, grid.origin, scene_max, t_enter)) {
        return false;
    }

    // The node being visited is its reference: an interior node's children
    // are read and tested together, and the farther one is pushed as its
    // reference, so a pop reads nothing.
    int sp = 0;
    uint first, count;
    open_ref(grid.root_ref, first, count);
    // Each round descends to a leaf, tests it, and pops. Descending in a loop
    // of its own ("while-while", Aila and Laine 2009) lets the lanes of a
    // SIMD group test their leaves together instead of taking turns.
    bool done = false;
    while (!done) {
        // Descend through interior nodes until this ray holds a leaf
        while (count == 0u) {
            // Visit the nearer child first and defer the farther one
#ifdef TRACE_COUNT_VISITS
            ++trace_visits;
#endif
            uvec4 l = bvh_child(first, 0u);
            uvec4 r = bvh_child(first, 1u);
            float tl, tr;
            bool hl = child_test(l, grid, o, inv_d, hit_t, tl);
            bool hr = child_test(r, grid, o, inv_d, hit_t, tr);
            uint ref;
            if (hl && hr) {
                bool right_first = tr < tl;
                stack_ref[sp] = right_first ? l.w : r.w;
                stack_t[sp] = right_first ? tl : tr;
                ++sp;
                ref = right_first ? r.w : l.w;
            } else if (hl || hr) {
                ref = hl ? l.w : r.w;
            } else if (!pop_node(sp, hit_t, ref)) {
                done = true;
                break;
            }
            open_ref(ref, first, count);
        }
        if (done) {
            break;
        }

        // Test the primitives of the leaf
        for (uint i = first; i < first + count; ++i) {
#ifdef TRACE_COUNT_VISITS
            ++trace_visits;
#endif
            vec2 bary;
            if (intersect_primitive(i, o, d, tri_ray, hit_t, bary)) {
                hit_prim = i;
                hit_bary = bary;
                if (any_hit) {
                    return true;
                }
            }
        }
        uint ref;
        done = !pop_node(sp, hit_t, ref);
        if (!done) {
            open_ref(ref, first, count);
        }
    }
    return hit_prim != NO_HIT;
}

#endif
