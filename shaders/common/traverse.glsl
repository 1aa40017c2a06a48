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
    BvhNode root = bvh_node(0u);
    if (!slab_test(o, inv_d, tmax, root.bmin, root.bmax, t_enter)) {
        return false;
    }

    // The node being visited is known by its first child (or primitive) and
    // count, read with its box when its parent was visited; only a deferred
    // node is read again, when it is popped
    uint stack_node[BVH_STACK_SIZE];
    float stack_t[BVH_STACK_SIZE];
    int sp = 0;
    uint first = root.left_or_first;
    uint count = root.count;
    while (true) {
        if (count > 0u) {
            // Test the primitives of a leaf
            for (uint i = first; i < first + count; ++i) {
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
            BvhNode l = bvh_node(first);
            BvhNode r = bvh_node(first + 1u);
            float tl, tr;
            bool hl = slab_test(o, inv_d, hit_t, l.bmin, l.bmax, tl);
            bool hr = slab_test(o, inv_d, hit_t, r.bmin, r.bmax, tr);
            if (hl && hr) {
                bool right_first = tr < tl;
                stack_node[sp] = right_first ? first : first + 1u;
                stack_t[sp] = right_first ? tl : tr;
                ++sp;
                first = right_first ? r.left_or_first : l.left_or_first;
                count = right_first ? r.count : l.count;
                continue;
            } else if (hl) {
                first = l.left_or_first;
                count = l.count;
                continue;
            } else if (hr) {
                first = r.left_or_first;
                count = r.count;
                continue;
            }
        }
        // Pop the next deferred node that is still in reach
        bool found = false;
        while (sp > 0) {
            --sp;
            if (stack_t[sp] <= hit_t) {
                BvhNode n = bvh_node(stack_node[sp]);
                first = n.left_or_first;
                count = n.count;
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
