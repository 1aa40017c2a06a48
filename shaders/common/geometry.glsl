// Ray/primitive geometry shared by the intersect and shadow kernels.
//
// Pure functions, no buffer access. Each one mirrors the function of the same
// name in src/geometry.rs statement for statement; see that file for the
// references (Woop et al. 2013, Haines et al. and Wachter and Binder in Ray
// Tracing Gems, Ize 2013 / pbrt). A ray is o + t d for t in (0, tmax].
#ifndef GEOMETRY_GLSL
#define GEOMETRY_GLSL

// Direction components below this magnitude count as zero (MIN_DIR).
const float GEOM_MIN_DIR = 1.0e-30;
// Inverse direction components at least this large mark parallel axes (PARALLEL_INV).
const float GEOM_PARALLEL_INV = 1.0e29;
// 1 + 2 gamma(3) for single precision: widens slab exits past rounding (SLAB_EXIT_SCALE).
const float GEOM_SLAB_EXIT_SCALE = 1.0000004;
// Largest finite float.
const float GEOM_FLT_MAX = 3.402823466e38;
// Offset along the normal per unit of coordinate magnitude and of |n|_1 (OFFSET_REL).
const float GEOM_OFFSET_REL = 1.0 / 2097152.0;
// Vertices this many times farther than the hit make Woop's t cancel (FAR_RATIO).
const float GEOM_FAR_RATIO = 1024.0;

// Largest absolute component of v
float max_abs(vec3 v)
{
    return max(max(abs(v.x), abs(v.y)), abs(v.z));
}

// Cross product of the two edges of a triangle from p0, each edge first
// scaled by its largest component so that nothing overflows or underflows;
// the true cross product is this times `scale`.
vec3 triangle_cross_scaled(vec3 p0, vec3 p1, vec3 p2, out float scale)
{
    // Scale each edge to a largest component of 1, then cross
    vec3 e1 = p1 - p0;
    vec3 e2 = p2 - p0;
    float s1 = max_abs(e1);
    float s2 = max_abs(e2);
    scale = s1 * s2;
    return cross(e1 / s1, e2 / s2);
}

// Unit geometric normal of a triangle, along (p1 - p0) x (p2 - p0), for
// edges of any length a scene may hold
vec3 triangle_normal(vec3 p0, vec3 p1, vec3 p2)
{
    // Normalise the scaled cross product
    float scale;
    return normalize(triangle_cross_scaled(p0, p1, p2, scale));
}

// Area of a triangle, for edges of any length a scene may hold
float triangle_area(vec3 p0, vec3 p1, vec3 p2)
{
    // Half the length of the cross product, scaled back
    float scale;
    return 0.5 * length(triangle_cross_scaled(p0, p1, p2, scale)) * scale;
}

// A ray prepared once for many watertight triangle tests: the axis
// permutation and shear of Woop, Benthin and Wald (2013) folded into three
// rows, so that a vertex v (relative to o) maps to (dot(rx, v), dot(ry, v),
// dot(rz, v)). Each row has at most two non-zero entries, 1 and the shear,
// so the dot products equal the paper's a[kx] + sx * a[kz] exactly, and
// no vector is indexed by a per-ray variable inside the loop.
struct TriangleRay {
    vec3 o;
    vec3 d;
    vec3 rx;
    vec3 ry;
    vec3 rz;
    bool valid;
};

// Prepare a ray for watertight triangle tests
TriangleRay triangle_ray(vec3 o, vec3 d) {
    TriangleRay r;
    r.o = o;
    r.d = d;

    // Make the largest-magnitude direction axis z
    vec3 ad = abs(d);
    int kz = ad.x > ad.y ? (ad.x > ad.z ? 0 : 2) : (ad.y > ad.z ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;

    // Swap x and y when d points down z to keep the winding
    float dz = d[kz];
    if (dz < 0.0) {
        int tmp = kx;
        kx = ky;
        ky = tmp;
    }
    r.valid = dz != 0.0;

    // Fold the permutation and the shear into three rows
    vec3 ex = vec3(kx == 0 ? 1.0 : 0.0, kx == 1 ? 1.0 : 0.0, kx == 2 ? 1.0 : 0.0);
    vec3 ey = vec3(ky == 0 ? 1.0 : 0.0, ky == 1 ? 1.0 : 0.0, ky == 2 ? 1.0 : 0.0);
    vec3 ez = vec3(kz == 0 ? 1.0 : 0.0, kz == 1 ? 1.0 : 0.0, kz == 2 ? 1.0 : 0.0);
    float sx = -d[kx] / dz;
    float sy = -d[ky] / dz;
    float sz = 1.0 / dz;
    r.rx = ex + sx * ez;
    r.ry = ey + sy * ez;
    r.rz = sz * ez;
    return r;
}

// Watertight two-sided ray/triangle test on a prepared ray. On a hit, t is
// in (0, tmax] and bary holds the weights of p1 and p2. `precise` keeps the
// edge functions free of fused multiply-adds, so an edge shared by two
// triangles gets exactly negated values in both. plane_d is the triangle's
// plane offset (dot(triangle_normal, x) = plane_d on the plane, computed on
// the CPU in f64): when the vertices lie far beyond the hit, t comes from
// the plane, whose rounding scales with the ray origin, not the vertices.
bool intersect_triangle_prepared(TriangleRay r, float tmax, vec3 p0, vec3 p1, vec3 p2,
                                 float plane_d, out float t, out vec2 bary)
{
    t = 0.0;
    bary = vec2(0.0);
    if (!r.valid) {
        return false;
    }

    // Translate vertices to the ray origin
    precise vec3 a = p0 - r.o;
    precise vec3 b = p1 - r.o;
    precise vec3 c = p2 - r.o;

    // Shear and scale vertices so the ray runs along +z
    precise float ax = dot(r.rx, a);
    precise float ay = dot(r.ry, a);
    precise float bx = dot(r.rx, b);
    precise float by = dot(r.ry, b);
    precise float cx = dot(r.rx, c);
    precise float cy = dot(r.ry, c);

    // Evaluate the edge functions
    precise float u = cx * by - cy * bx;
    precise float v = ax * cy - ay * cx;
    precise float w = bx * ay - by * ax;

    // Reject when the edge functions differ in sign
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return false;
    }
    precise float det = u + v + w;
    if (det == 0.0) {
        return false;
    }

    // Compute the scaled hit distance and reject it outside (0, tmax]
    precise float az = dot(r.rz, a);
    precise float bz = dot(r.rz, b);
    precise float cz = dot(r.rz, c);
    precise float tt = u * az + v * bz + w * cz;
    float th = tt / det;

    // Take t from the plane when far vertices make tt cancel and the plane is more precise
    float zmax = max(max(abs(az), abs(bz)), abs(cz));
    if (zmax > GEOM_FAR_RATIO * abs(th)) {
        vec3 n = triangle_normal(p0, p1, p2);
        float cos_d = dot(n, r.d);
        if (abs(plane_d) + max_abs(r.o) < zmax * abs(cos_d)) {
            th = (plane_d - dot(n, r.o)) / cos_d;
        }
    }
    if (!(th > 0.0 && th <= tmax)) {
        return false;
    }

    // Return t and the barycentrics of p1 and p2
    float inv_det = 1.0 / det;
    t = th;
    bary = vec2(v, w) * inv_det;
    return true;
}

// Watertight two-sided ray/triangle test (Woop, Benthin and Wald 2013) for
// a single ray: prepares it, then tests.
bool intersect_triangle(vec3 o, vec3 d, float tmax, vec3 p0, vec3 p1, vec3 p2,
                        float plane_d, out float t, out vec2 bary)
{
    return intersect_triangle_prepared(triangle_ray(o, d), tmax, p0, p1, p2, plane_d, t, bary);
}

// |o - c|^2 - r^2: positive when o lies outside the sphere (c, r). The one
// computation of it, so that intersect_sphere's choice of root and the side
// a hit is on (sphere_hit_from_outside) always agree.
float sphere_origin_power(vec3 o, vec3 c, float r)
{
    precise vec3 f = o - c;
    precise float cc = dot(f, f) - r * r;
    return cc;
}

// Whether intersect_sphere's hit from o is on the outside of the sphere (c,
// r): the ray starts outside and meets the near root. Not the sign of
// dot(n, d) at the hit, which rounding flips for rays that graze it
bool sphere_hit_from_outside(vec3 o, vec3 c, float r)
{
    return sphere_origin_power(o, c, r) > 0.0;
}

// Nearest ray/sphere hit in (0, tmax], stable for tiny and huge radii and far
// origins (Haines et al., Ray Tracing Gems ch. 7). d must be normalised.
bool intersect_sphere(vec3 o, vec3 d, float tmax, vec3 c, float r, out float t)
{
    t = 0.0;

    // Project the centre offset onto the ray
    precise vec3 f = o - c;
    precise float b = dot(f, d);

    // Compute the discriminant from the perpendicular distance
    precise vec3 perp = f - b * d;
    precise float disc = r * r - dot(perp, perp);
    if (disc < 0.0) {
        return false;
    }

    // Form both roots without cancellation
    precise float cc = sphere_origin_power(o, c, r);
    float sign_b = b >= 0.0 ? 1.0 : -1.0;
    precise float q = -b - sign_b * sqrt(disc);
    if (q == 0.0) {
        return false;
    }
    float t0 = cc / q;
    float t1 = q;

    // Take the nearest root in (0, tmax]
    float t_near = min(t0, t1);
    float t_far = max(t0, t1);
    float th = t_near > 0.0 ? t_near : t_far;
    if (!(th > 0.0 && th <= tmax)) {
        return false;
    }
    t = th;
    return true;
}

// Moves an approximate sphere hit point (such as o + t d) onto the sphere.
// Use it before offset_ray_origin for spheres: o + t d carries the rounding of
// the ray origin's magnitude, which can exceed the offset. p must differ from c.
vec3 sphere_surface_point(vec3 p, vec3 c, float r)
{
    // Push p radially onto the surface
    return c + r * normalize(p - c);
}

// Componentwise 1 / d with components below GEOM_MIN_DIR in magnitude
// (+0.0 and -0.0 included) first replaced by a same-signed GEOM_MIN_DIR, so
// the result is finite and slab_test never forms 0 * inf.
vec3 safe_inverse(vec3 d)
{
    // Replace tiny components by a same-signed tiny value, then invert
    vec3 tiny = uintBitsToFloat((floatBitsToUint(d) & 0x80000000u) | floatBitsToUint(vec3(GEOM_MIN_DIR)));
    vec3 safe = mix(d, tiny, lessThan(abs(d), vec3(GEOM_MIN_DIR)));
    return 1.0 / safe;
}

// Ray/box slab test over [0, tmax]; tenter is the entry distance clamped to 0.
// inv_d must come from safe_inverse. The exit, tmax included, is widened by
// 1 + 2 gamma(3) so rounding never culls a touched box or an exact tie. Slabs the ray runs parallel to are the
// whole line when the origin lies between them, faces included.
bool slab_test(vec3 o, vec3 inv_d, float tmax, vec3 bmin, vec3 bmax, out float tenter)
{
    // Intersect the ray with the three pairs of slabs
    vec3 t0 = (bmin - o) * inv_d;
    vec3 t1 = (bmax - o) * inv_d;
    vec3 tn = min(t0, t1);
    vec3 tf = max(t0, t1);

    // Open slabs parallel to the ray that hold its origin to the whole line
    uvec3 par = uvec3(greaterThanEqual(abs(inv_d), vec3(GEOM_PARALLEL_INV)));
    uvec3 holds = uvec3(lessThanEqual(tn, vec3(0.0))) & uvec3(greaterThanEqual(tf, vec3(0.0)));
    bvec3 open = bvec3(par & holds);
    tn = mix(tn, vec3(-GEOM_FLT_MAX), open);
    tf = mix(tf, vec3(GEOM_FLT_MAX), open);

    // Clip the interval to [0, tmax], widening the exit for rounding
    tenter = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float texit = min(min(min(tf.x, tf.y), tf.z), tmax) * GEOM_SLAB_EXIT_SCALE;
    return tenter <= texit;
}

// Moves surface point p off the surface along n (geometric normal, flipped by
// the caller to the side the new ray leaves) so the new ray does not hit the
// same surface again. The offset is the rounding p can carry, projected on n
// (pbrt-v4's OffsetRayOrigin with an error bound proportional to the
// coordinates): mag is the magnitude of the coordinates p was computed from
// (a triangle's largest vertex coordinate, a sphere's |centre| + radius), and
// p moves GEOM_OFFSET_REL * max(mag, |p|) * |n|_1 along n. An offset in ulps
// of p's own coordinates (Wachter and Binder) is as large as the rounding of
// the largest coordinate, not of the surface: a box 1e-3 across 30 units from
// the origin was offset by a quarter of its size.
vec3 offset_ray_origin(vec3 p, vec3 n, float mag)
{
    // Move by the coordinates' rounding, projected on n
    float m = max(mag, max_abs(p));
    float d = GEOM_OFFSET_REL * m * (abs(n.x) + abs(n.y) + abs(n.z));
    return p + d * n;
}

#endif // GEOMETRY_GLSL
