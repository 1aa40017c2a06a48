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
        if (intersect_triangle_prepared(tri_ray, tmax, p.a.xyz, p.b.xyz, p.c.xyz, t, bary)) {
            tmax = t;
            return true;
        }
    }
    return false;
}

// Trace a ray through the BVH; any_hit stops at the first hit found
bool trace(vec3 o, vec3 d, float tmax, bool any_hit, out uint hit_prim, out float hit_t, out vec2 hit_bary) {
    hit_prim = NO_HIT;
    hit_t = tmax;
    hit_bary = vec2(0.0);
    if (frame.primitive_count == 0u) {
        return false;
    }
    vec3 inv_d = safe_inverse(d);
    TriangleRay tri_ray = triangle_ray(o, d);

    // Cull the ray against the root box
    float t_enter;
    if (!slab_test(o, inv_d, tmax, bvh_node(0).bmin, bvh_node(0).bmax, t_enter)) {
        return false;
    }

    uint stack_node[BVH_STACK_SIZE];
    float stack_t[BVH_STACK_SIZE];
    int sp = 0;
    uint node = 0u;
    while (true) {
        BvhNode n = bvh_node(node);
        if (n.count > 0u) {
            // Test the primitives of a leaf
            for (uint i = n.left_or_first; i < n.left_or_first + n.count; ++i) {
                vec2 bary;
                if (intersect_primitive(i, o, d, tri_ray, hit_t, bary)) {
                    hit_prim = i;
                    hit_bary = bary;
                    if (any_hit) {
                        return true;
                    }
                }
            }
        } else {
            // Visit the nearer child first and defer the farther one
            uint l = n.left_or_first;
            uint r = l + 1u;
            float tl, tr;
            bool hl = slab_test(o, inv_d, hit_t, bvh_node(l).bmin, bvh_node(l).bmax, tl);
            bool hr = slab_test(o, inv_d, hit_t, bvh_node(r).bmin, bvh_node(r).bmax, tr);
            if (hl && hr) {
                bool right_first = tr < tl;
                node = right_first ? r : l;
                stack_node[sp] = right_first ? l : r;
                stack_t[sp] = right_first ? tl : tr;
                ++sp;
                continue;
            } else if (hl) {
                node = l;
                continue;
            } else if (hr) {
                node = r;
                continue;
            }
        }
        // Pop the next deferred node that is still in reach
        bool found = false;
        while (sp > 0) {
            --sp;
            if (stack_t[sp] <= hit_t) {
                node = stack_node[sp];
                found = true;
                break;
            }
        }
        if (!found) {
            break;
        }
    }
    return hit_prim != NO_HIT;
}

#endif
