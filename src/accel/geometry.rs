//! CPU reference geometry: rays, boxes and the primitive tests.
//!
//! Every function here has a twin of the same name in
//! `shaders/common/geometry.glsl`, written statement for statement the same
//! way, so the CPU traversal in [`crate::accel::bvh`] is a reference for the GPU
//! intersect and shadow kernels.
//!
//! Conventions:
//! - A ray is `o + t d` for `t` in `(0, tmax]`.
//! - Triangles are two-sided; [`intersect_triangle`] is the watertight test
//!   of Woop, Benthin and Wald, "Watertight Ray/Triangle Intersection"
//!   (JCGT 2013), without the double-precision fallback.
//! - Spheres use the stable quadratic of Haines et al., "Precision
//!   Improvements for Ray/Sphere Intersection" (Ray Tracing Gems, ch. 7).
//! - Boxes use the slab test with the exit scaling of Ize, "Robust BVH Ray
//!   Traversal" (JCGT 2013), as in pbrt.
//! - New rays leave surfaces from [`offset_ray_origin`], Wächter and Binder,
//!   "A Fast and Robust Method for Avoiding Self-Intersection" (Ray Tracing
//!   Gems, ch. 6).

use glam::Vec3;

/// Direction components smaller than this in magnitude count as zero in
/// [`safe_inverse`] and [`slab_test`]. Mirrored as `GEOM_MIN_DIR` in GLSL.
const MIN_DIR: f32 = 1.0e-30;

/// An inverse direction component at least this large marks an axis the ray
/// runs parallel to (see [`safe_inverse`]). Mirrored as `GEOM_PARALLEL_INV`.
const PARALLEL_INV: f32 = 1.0e29;

/// `1 + 2 gamma(3)` with `gamma(n) = n u / (1 - n u)`, `u = 2^-24`: widens a
/// slab exit distance by more than the rounding of its computation.
/// Mirrored as `GEOM_SLAB_EXIT_SCALE`.
const SLAB_EXIT_SCALE: f32 = 1.0 + 2.0 * GAMMA3;

/// `gamma(3)` of Higham's error analysis, for single precision.
const GAMMA3: f32 = (3.0 * HALF_ULP) / (1.0 - 3.0 * HALF_ULP);

/// Unit roundoff of `f32`, `2^-24`.
const HALF_ULP: f32 = f32::EPSILON * 0.5;

/// Offset of [`offset_ray_origin`] along the normal, per unit of the
/// magnitude of the coordinates a point was computed from and of `|n|_1`:
/// `2^-21`, 4 ulps at 1 (between 4 and 8 ulps of the magnitude). Mirrored as
/// `GEOM_OFFSET_REL`.
pub const OFFSET_REL: f32 = 1.0 / 2_097_152.0;

/// Vertices this many times farther out than a hit make the watertight
/// test's `t` cancel (a sum of terms as large as the vertices' distance);
/// [`intersect_triangle`] then takes `t` from the triangle's plane. Mirrored
/// as `GEOM_FAR_RATIO`.
pub const FAR_RATIO: f32 = 1024.0;

/// Largest absolute component (`max_abs` in GLSL).
pub fn max_abs(v: Vec3) -> f32 {
    v.abs().max_element()
}

/// The cross product of a triangle's edges from `p0`, each edge first scaled
/// to a largest component of 1 so nothing overflows or underflows, and the
/// scale that gives the true cross product (`triangle_cross_scaled`).
pub fn triangle_cross_scaled(p0: Vec3, p1: Vec3, p2: Vec3) -> (Vec3, f32) {
    // Scale each edge to a largest component of 1, then cross
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let s1 = max_abs(e1);
    let s2 = max_abs(e2);
    ((e1 / s1).cross(e2 / s2), s1 * s2)
}

/// Unit normal along `(p1 - p0) x (p2 - p0)` for edges of any length a scene
/// may hold (`triangle_normal`); NaN for a degenerate triangle.
pub fn triangle_normal(p0: Vec3, p1: Vec3, p2: Vec3) -> Vec3 {
    // Normalise the scaled cross product
    triangle_cross_scaled(p0, p1, p2).0.normalize()
}

/// Area of a triangle for edges of any length a scene may hold (`triangle_area`).
pub fn triangle_area(p0: Vec3, p1: Vec3, p2: Vec3) -> f32 {
    // Half the length of the cross product, scaled back
    let (c, scale) = triangle_cross_scaled(p0, p1, p2);
    0.5 * c.length() * scale
}

/// The offset of a triangle's plane, `n . x` for points `x` on it, with `n`
/// its unit normal; computed in f64 from the f32 vertices, so it is exact to
/// the rounding of the result whatever the vertices' magnitude. The GPU gets
/// it in `Primitive.a.w`.
pub fn plane_offset(p0: Vec3, p1: Vec3, p2: Vec3) -> f32 {
    let (p0, p1, p2) = (p0.as_dvec3(), p1.as_dvec3(), p2.as_dvec3());
    let n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
    n.dot(p0) as f32
}

/// A ray `o + t d`, valid for `t` in `(0, tmax]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Direction; need not be normalised, must not be zero.
    pub d: Vec3,
    /// Largest `t` a hit may have (may be `f32::INFINITY`).
    pub tmax: f32,
}

impl Ray {
    /// A ray from `o` along `d`, hits accepted up to `tmax`.
    pub fn new(o: Vec3, d: Vec3, tmax: f32) -> Self {
        Self { o, d, tmax }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + t * self.d
    }
}

/// A ray/triangle hit: distance and the barycentrics of `p1` and `p2`
/// (the hit point is `(1 - b1 - b2) p0 + b1 p1 + b2 p2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit, in `(0, tmax]`.
    pub t: f32,
    /// Barycentric weight of `p1`.
    pub b1: f32,
    /// Barycentric weight of `p2`.
    pub b2: f32,
}

/// Index of the largest component, first one on ties (pbrt's `MaxDimension`).
fn max_dim(v: Vec3) -> usize {
    if v.x > v.y {
        if v.x > v.z {
            0
        } else {
            2
        }
    } else if v.y > v.z {
        1
    } else {
        2
    }
}

/// Watertight, two-sided ray/triangle test (Woop, Benthin and Wald 2013).
///
/// The edge functions of an edge shared by two triangles come out exactly
/// negated (the products are the same and `a - b == -(b - a)` in IEEE
/// arithmetic), so a ray through a shared edge or vertex never slips between
/// the triangles. A point exactly on an edge counts as inside, so a ray
/// through a shared edge may hit both triangles (at `t` equal to a few ulps).
/// Degenerate triangles (zero determinant) and triangles seen edge-on miss.
pub fn intersect_triangle(ray: &Ray, p0: Vec3, p1: Vec3, p2: Vec3) -> Option<TriHit> {
    // Make the largest-magnitude direction axis z
    let d = ray.d;
    let kz = max_dim(d.abs());
    let mut kx = if kz == 2 { 0 } else { kz + 1 };
    let mut ky = if kx == 2 { 0 } else { kx + 1 };

    // Swap x and y when d points down z to keep the winding
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let dz = d[kz];
    if dz == 0.0 {
        return None;
    }

    // Translate vertices to the ray origin
    let a = p0 - ray.o;
    let b = p1 - ray.o;
    let c = p2 - ray.o;

    // Shear and scale vertices so the ray runs along +z
    let sx = -d[kx] / dz;
    let sy = -d[ky] / dz;
    let sz = 1.0 / dz;
    let ax = a[kx] + sx * a[kz];
    let ay = a[ky] + sy * a[kz];
    let bx = b[kx] + sx * b[kz];
    let by = b[ky] + sy * b[kz];
    let cx = c[kx] + sx * c[kz];
    let cy = c[ky] + sy * c[kz];

    // Evaluate the edge functions
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;

    // Reject when the edge functions differ in sign
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }

    // Compute the scaled hit distance and reject it outside (0, tmax]
    let az = sz * a[kz];
    let bz = sz * b[kz];
    let cz = sz * c[kz];
    let tt = u * az + v * bz + w * cz;
    let mut t = tt / det;

    // Take t from the plane when far vertices make tt cancel and the plane is more precise
    let zmax = az.abs().max(bz.abs()).max(cz.abs());
    if zmax > FAR_RATIO * t.abs() {
        let n = triangle_normal(p0, p1, p2);
        let cos_d = n.dot(d);
        let plane_d = plane_offset(p0, p1, p2);
        if plane_d.abs() + max_abs(ray.o) < zmax * cos_d.abs() {
            t = (plane_d - n.dot(ray.o)) / cos_d;
        }
    }
    if !(t > 0.0 && t <= ray.tmax) {
        return None;
    }

    // Return t and the barycentrics of p1 and p2
    let inv_det = 1.0 / det;
    Some(TriHit {
        t,
        b1: v * inv_det,
        b2: w * inv_det,
    })
}

/// Nearest ray/sphere hit in `(0, tmax]`, numerically stable.
///
/// Uses the form of Haines et al. (Ray Tracing Gems, ch. 7): with
/// `f = o - c` and unit `d`, `b = f.d`, discriminant `r^2 - |f - b d|^2`,
/// `q = -b - sign(b) sqrt(disc)`, roots `(|f|^2 - r^2) / q` and `q`. The
/// direction need not be normalised: it is normalised here and `t` is
/// rescaled to the ray's own parameter. Origins inside the sphere hit the
/// far side.
pub fn intersect_sphere(ray: &Ray, center: Vec3, radius: f32) -> Option<f32> {
    // Normalise the direction, remembering its length
    let len = ray.d.length();
    if !len.is_finite() || len <= 0.0 {
        return None;
    }
    let d = ray.d / len;

    // Project the centre offset onto the ray
    let f = ray.o - center;
    let b = f.dot(d);

    // Compute the discriminant from the perpendicular distance
    let perp = f - b * d;
    let disc = radius * radius - perp.dot(perp);
    if disc < 0.0 {
        return None;
    }

    // Form both roots without cancellation
    let cc = f.dot(f) - radius * radius;
    let sign_b = if b >= 0.0 { 1.0 } else { -1.0 };
    let q = -b - sign_b * disc.sqrt();
    if q == 0.0 {
        return None;
    }
    let t0 = cc / q;
    let t1 = q;

    // Take the nearest root in (0, tmax]
    let t_near = t0.min(t1);
    let t_far = t0.max(t1);
    let tn = if t_near > 0.0 { t_near } else { t_far };
    if tn.is_nan() || tn <= 0.0 {
        return None;
    }
    let t = tn / len;
    if t <= ray.tmax {
        Some(t)
    } else {
        None
    }
}

/// Moves an approximate sphere hit point (such as `o + t d`) onto the
/// sphere: `center + radius * normalize(p - center)`.
///
/// Use it before [`offset_ray_origin`] for spheres: `o + t d` carries the
/// rounding of the ray origin's magnitude, which can exceed the offset when
/// the origin is far from the hit; the reprojected point is accurate to a
/// few ulps of `|center| + radius`. `p` must differ from `center`.
pub fn sphere_surface_point(p: Vec3, center: Vec3, radius: f32) -> Vec3 {
    // Push p radially onto the surface
    center + radius * (p - center).normalize()
}

/// Componentwise `1 / d`, with components below `1e-30` in magnitude
/// (including `+0.0` and `-0.0`) first replaced by `±1e-30` of the same sign.
///
/// The result is finite, so [`slab_test`] never forms `0 * inf`. Inverse
/// components of `1e29` or more in magnitude mark axes the ray is parallel
/// to, which [`slab_test`] treats exactly.
pub fn safe_inverse(d: Vec3) -> Vec3 {
    // Replace tiny components by a same-signed tiny value, then invert
    let fix = |x: f32| {
        if x.abs() < MIN_DIR {
            MIN_DIR.copysign(x)
        } else {
            x
        }
    };
    Vec3::new(1.0 / fix(d.x), 1.0 / fix(d.y), 1.0 / fix(d.z))
}

/// Ray/box slab test; returns the entry distance (clamped to 0) when the ray
/// meets the closed box `[bmin, bmax]` for some `t` in `[0, tmax]`.
///
/// `inv_d` must come from [`safe_inverse`]. The exit distance, `tmax`
/// included, is widened by `1 + 2 gamma(3)` (Ize 2013, pbrt) so rounding
/// never culls a box that the ray touches, nor a box whose entry rounds just
/// above an exact tie with the closest hit so far (so closest-hit traversal
/// resolves ties like a brute-force loop). For an axis the ray is parallel to (`|d_i| < 1e-30`,
/// including `±0.0`), the slab is the whole line when `o_i` lies in
/// `[bmin_i, bmax_i]` (faces included, whatever the sign of the zero), so
/// rays running inside a box face or along a box edge are not culled.
pub fn slab_test(o: Vec3, inv_d: Vec3, tmax: f32, bmin: Vec3, bmax: Vec3) -> Option<f32> {
    // Intersect the ray with the three pairs of slabs
    let t0 = (bmin - o) * inv_d;
    let t1 = (bmax - o) * inv_d;
    let mut tn = t0.min(t1);
    let mut tf = t0.max(t1);

    // Open slabs parallel to the ray that hold its origin to the whole line
    for i in 0..3 {
        if inv_d[i].abs() >= PARALLEL_INV && tn[i] <= 0.0 && tf[i] >= 0.0 {
            tn[i] = -f32::MAX;
            tf[i] = f32::MAX;
        }
    }

    // Clip the interval to [0, tmax], widening the exit for rounding
    let tenter = tn.x.max(tn.y).max(tn.z.max(0.0));
    let texit = tf.x.min(tf.y).min(tf.z).min(tmax) * SLAB_EXIT_SCALE;
    if tenter <= texit {
        Some(tenter)
    } else {
        None
    }
}

/// Moves a surface point off the surface along `n` so a ray leaving it does
/// not hit the same surface again.
///
/// The point moves by the rounding it can carry, projected on `n`, as
/// pbrt-v4's `OffsetRayOrigin` does with its error bounds: by
/// [`OFFSET_REL`]` * max(mag, |p|) * |n|_1` along `n`. `mag` is the
/// magnitude of the coordinates `p` was computed from: a triangle's largest
/// vertex coordinate, a sphere's largest centre coordinate plus its radius
/// (a point near the origin on a ground sphere of radius 1e8 is only as
/// precise as 1e8). `n` is the geometric normal, unit length, flipped by the
/// caller to the side the new ray leaves from.
///
/// An offset in ulps of `p`'s own coordinates (Wächter and Binder, Ray
/// Tracing Gems ch. 6, which lancer used before) scales with the largest
/// coordinate rather than with the surface's rounding: 256 ulps moved a point
/// of a Cornell box 1e-3 across and 30 units from the origin by a quarter of
/// the box.
pub fn offset_ray_origin(p: Vec3, n: Vec3, mag: f32) -> Vec3 {
    // Move by the coordinates' rounding, projected on n
    let m = mag.max(max_abs(p));
    let d = OFFSET_REL * m * (n.x.abs() + n.y.abs() + n.z.abs());
    p + d * n
}

/// An axis-aligned bounding box; empty when any `min` exceeds `max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box: the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box with corners `min` and `max`.
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The smallest box holding both boxes.
    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Grows the box to hold point `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// Whether the box holds no point.
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Centre of the box (computed without overflow).
    pub fn centroid(&self) -> Vec3 {
        self.min * 0.5 + self.max * 0.5
    }

    /// `max - min`, zero for an empty box.
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Surface area, zero for an empty or degenerate box.
    pub fn surface_area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Whether `other` lies inside this box (faces included).
    pub fn contains(&self, other: &Aabb) -> bool {
        self.min.cmple(other.min).all() && self.max.cmpge(other.max).all()
    }

    /// The bounds of a triangle (exact: the corners are vertex coordinates).
    pub fn of_triangle(p0: Vec3, p1: Vec3, p2: Vec3) -> Aabb {
        Aabb {
            min: p0.min(p1).min(p2),
            max: p0.max(p1).max(p2),
        }
    }

    /// The bounds of a sphere, widened by a few ulps of `|c| + r` so rounding
    /// in `c ± r` and in [`intersect_sphere`] never leaves a hit outside.
    pub fn of_sphere(center: Vec3, radius: f32) -> Aabb {
        let r = radius.abs();
        let pad = (center.abs() + Vec3::splat(r)) * (4.0 * f32::EPSILON);
        Aabb {
            min: center - Vec3::splat(r) - pad,
            max: center + Vec3::splat(r) + pad,
        }
    }
}

/// Deterministic random numbers and meshes shared by the geometry and BVH
/// tests (the crate has no `rand`).
#[cfg(test)]
pub(crate) mod test_util {
    use glam::Vec3;
    use std::collections::HashMap;

    /// PCG32 (O'Neill), XSH-RR output.
    pub struct Pcg32 {
        state: u64,
        inc: u64,
    }

    impl Pcg32 {
        /// A generator for `seed`.
        pub fn new(seed: u64) -> Self {
            let mut r = Pcg32 {
                state: 0,
                inc: (seed << 1) | 1,
            };
            r.next_u32();
            r.state = r.state.wrapping_add(0x853c_49e6_748f_ea9b ^ seed);
            r.next_u32();
            r
        }

        /// Next 32 random bits.
        pub fn next_u32(&mut self) -> u32 {
            let old = self.state;
            self.state = old
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(self.inc);
            let x = (((old >> 18) ^ old) >> 27) as u32;
            x.rotate_right((old >> 59) as u32)
        }

        /// Uniform in `[0, 1)`.
        pub fn f32(&mut self) -> f32 {
            (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
        }

        /// Uniform in `[lo, hi)`.
        pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.f32()
        }

        /// Uniform integer in `0..n`.
        pub fn below(&mut self, n: usize) -> usize {
            ((self.next_u32() as u64 * n as u64) >> 32) as usize
        }

        /// Uniform point in `[lo, hi)^3`.
        pub fn in_cube(&mut self, lo: f32, hi: f32) -> Vec3 {
            Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
        }

        /// Uniform unit vector.
        pub fn unit(&mut self) -> Vec3 {
            let z = self.range(-1.0, 1.0);
            let phi = self.range(0.0, std::f32::consts::TAU);
            let s = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(s * phi.cos(), s * phi.sin(), z)
        }

        /// Cosine-distributed unit vector around unit `n`, and its cosine.
        pub fn cosine_around(&mut self, n: Vec3) -> (Vec3, f32) {
            let (t, b) = n.any_orthonormal_pair();
            let r = self.f32().sqrt();
            let phi = self.range(0.0, std::f32::consts::TAU);
            let (x, y) = (r * phi.cos(), r * phi.sin());
            let z = (1.0 - x * x - y * y).max(0.0).sqrt();
            ((x * t + y * b + z * n).normalize(), z)
        }
    }

    /// An icosphere of `subdiv` subdivisions with shared vertices.
    pub fn icosphere(subdiv: u32, center: Vec3, radius: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = (1.0 + 5.0f64.sqrt()) / 2.0;
        let base = [
            [-1.0, p, 0.0],
            [1.0, p, 0.0],
            [-1.0, -p, 0.0],
            [1.0, -p, 0.0],
            [0.0, -1.0, p],
            [0.0, 1.0, p],
            [0.0, -1.0, -p],
            [0.0, 1.0, -p],
            [p, 0.0, -1.0],
            [p, 0.0, 1.0],
            [-p, 0.0, -1.0],
            [-p, 0.0, 1.0],
        ];
        let mut unit: Vec<[f64; 3]> = base
            .iter()
            .map(|v| {
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                [v[0] / l, v[1] / l, v[2] / l]
            })
            .collect();
        let mut tris: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..subdiv {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut next = Vec::with_capacity(tris.len() * 4);
            for t in &tris {
                let mut m = [0u32; 3];
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    let key = (a.min(b), a.max(b));
                    m[k] = *mid.entry(key).or_insert_with(|| {
                        let (va, vb) = (unit[a as usize], unit[b as usize]);
                        let s = [va[0] + vb[0], va[1] + vb[1], va[2] + vb[2]];
                        let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                        unit.push([s[0] / l, s[1] / l, s[2] / l]);
                        (unit.len() - 1) as u32
                    });
                }
                next.push([t[0], m[0], m[2]]);
                next.push([t[1], m[1], m[0]]);
                next.push([t[2], m[2], m[1]]);
                next.push([m[0], m[1], m[2]]);
            }
            tris = next;
        }
        let verts = unit
            .iter()
            .map(|v| {
                Vec3::new(
                    (center.x as f64 + radius as f64 * v[0]) as f32,
                    (center.y as f64 + radius as f64 * v[1]) as f32,
                    (center.z as f64 + radius as f64 * v[2]) as f32,
                )
            })
            .collect();
        (verts, tris)
    }

    /// The unique edges of an indexed mesh.
    pub fn edges(tris: &[[u32; 3]]) -> Vec<(u32, u32)> {
        let mut e: Vec<(u32, u32)> = tris
            .iter()
            .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }

    /// Point `a + s (b - a)` computed in `f32`, as a renderer would.
    pub fn lerp(a: Vec3, b: Vec3, s: f32) -> Vec3 {
        a + s * (b - a)
    }
}

#[cfg(test)]
mod tests {
    use super::test_util::{edges, icosphere, lerp, Pcg32};
    use super::*;

    #[test]
    fn triangle_basic_hits_both_windings() {
        let (p0, p1, p2) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let ray = Ray::new(Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0), 10.0);
        let h = intersect_triangle(&ray, p0, p1, p2).expect("front hit");
        assert_eq!(h.t, 2.0);
        assert_eq!((h.b1, h.b2), (0.25, 0.5));
        let h2 = intersect_triangle(&ray, p0, p2, p1).expect("back-wound hit");
        assert_eq!((h2.t, h2.b1, h2.b2), (2.0, 0.5, 0.25));
        // From below, with -0.0 components.
        let up = Ray::new(Vec3::new(0.25, 0.5, -3.0), Vec3::new(-0.0, 0.0, 2.0), 10.0);
        assert_eq!(intersect_triangle(&up, p0, p1, p2).unwrap().t, 1.5);
        // Outside, behind, beyond tmax, degenerate, edge-on.
        let miss = Ray::new(Vec3::new(0.75, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0), 10.0);
        assert!(intersect_triangle(&miss, p0, p1, p2).is_none());
        let behind = Ray::new(Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, 1.0), 10.0);
        assert!(intersect_triangle(&behind, p0, p1, p2).is_none());
        let short = Ray::new(ray.o, ray.d, 1.999);
        assert!(intersect_triangle(&short, p0, p1, p2).is_none());
        assert!(intersect_triangle(&ray, p0, p1, Vec3::new(2.0, 0.0, 0.0)).is_none());
        let edge_on = Ray::new(Vec3::new(-1.0, 0.25, 0.0), Vec3::new(1.0, 0.0, 0.0), 10.0);
        assert!(intersect_triangle(&edge_on, p0, p1, p2).is_none());
        // tmax is inclusive.
        let exact = Ray::new(ray.o, ray.d, 2.0);
        assert!(intersect_triangle(&exact, p0, p1, p2).is_some());
    }

    #[test]
    fn triangle_barycentrics_reconstruct_point() {
        let mut rng = Pcg32::new(7);
        let mut worst = 0.0f32;
        for _ in 0..10_000 {
            let (p0, p1, p2) = (
                rng.in_cube(-1.0, 1.0),
                rng.in_cube(-1.0, 1.0),
                rng.in_cube(-1.0, 1.0),
            );
            let (s, u) = (rng.f32(), rng.f32());
            let (b1, b2) = if s + u > 1.0 {
                (1.0 - s, 1.0 - u)
            } else {
                (s, u)
            };
            let target = p0 * (1.0 - b1 - b2) + p1 * b1 + p2 * b2;
            let o = rng.in_cube(-3.0, 3.0);
            let ray = Ray::new(o, target - o, f32::INFINITY);
            if let Some(h) = intersect_triangle(&ray, p0, p1, p2) {
                let q = p0 * (1.0 - h.b1 - h.b2) + p1 * h.b1 + p2 * h.b2;
                worst = worst.max((q - ray.at(h.t)).length());
            }
        }
        assert!(worst < 1e-4, "worst barycentric mismatch {worst}");
    }

    /// Rays from inside closed meshes, aimed at vertices and edge points.
    #[test]
    fn watertight_closed_meshes() {
        let mut rng = Pcg32::new(11);
        let configs = [
            (Vec3::new(0.3, -0.2, 0.1), 1.0f32),
            (Vec3::new(1.0e2, -3.0e2, 7.0), 1.0e-2),
            (Vec3::new(-2.0e3, 5.0e3, 1.0e4), 1.0e3),
        ];
        let mut rays = 0usize;
        let mut misses = 0usize;
        for (center, radius) in configs {
            let (verts, tris) = icosphere(3, center, radius);
            let mut targets: Vec<Vec3> = verts.clone();
            for (a, b) in edges(&tris) {
                let (va, vb) = (verts[a as usize], verts[b as usize]);
                targets.push(lerp(va, vb, 0.5));
                targets.push(lerp(va, vb, rng.f32()));
            }
            for k in 0..3 {
                let o = if k == 0 {
                    center
                } else {
                    center + rng.unit() * (radius * rng.range(0.0, 0.8))
                };
                for &target in &targets {
                    let ray = Ray::new(o, target - o, f32::INFINITY);
                    rays += 1;
                    let hit = tris.iter().any(|t| {
                        intersect_triangle(
                            &ray,
                            verts[t[0] as usize],
                            verts[t[1] as usize],
                            verts[t[2] as usize],
                        )
                        .is_some()
                    });
                    misses += usize::from(!hit);
                }
            }
        }
        // A cube of 12 triangles with shared corners: rays at corners and edges.
        let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let verts = [
            c(-1.0, -1.0, -1.0),
            c(1.0, -1.0, -1.0),
            c(1.0, 1.0, -1.0),
            c(-1.0, 1.0, -1.0),
            c(-1.0, -1.0, 1.0),
            c(1.0, -1.0, 1.0),
            c(1.0, 1.0, 1.0),
            c(-1.0, 1.0, 1.0),
        ];
        let quads = [
            [0, 3, 2, 1],
            [4, 5, 6, 7],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 4, 7, 3],
            [1, 2, 6, 5],
        ];
        let tris: Vec<[u32; 3]> = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let mut targets: Vec<Vec3> = verts.to_vec();
        for (a, b) in edges(&tris) {
            for _ in 0..20 {
                targets.push(lerp(verts[a as usize], verts[b as usize], rng.f32()));
            }
        }
        for k in 0..50 {
            let o = if k == 0 {
                Vec3::ZERO
            } else {
                rng.in_cube(-0.9, 0.9)
            };
            for &target in &targets {
                let ray = Ray::new(o, target - o, f32::INFINITY);
                rays += 1;
                let hit = tris.iter().any(|t| {
                    intersect_triangle(
                        &ray,
                        verts[t[0] as usize],
                        verts[t[1] as usize],
                        verts[t[2] as usize],
                    )
                    .is_some()
                });
                misses += usize::from(!hit);
            }
        }
        println!("watertight: {rays} rays from inside at vertices and edges, {misses} misses");
        assert!(rays > 50_000);
        assert_eq!(misses, 0);
    }

    /// Rays through the shared diagonal of a quad split into two triangles.
    #[test]
    fn quad_diagonal_never_missed() {
        let mut rng = Pcg32::new(5);
        let mut rays = 0usize;
        let mut zero = 0usize;
        let mut double = 0usize;
        let mut grazing = 0usize;
        let mut worst_double_dt = 0.0f32;
        for q in 0..200 {
            // An axis-aligned unit quad first, then random parallelograms (planar
            // up to the rounding of their f32 corners).
            let (p0, p1, p2, p3) = if q == 0 {
                (
                    Vec3::new(0.0, 0.0, 0.0),
                    Vec3::new(1.0, 0.0, 0.0),
                    Vec3::new(1.0, 1.0, 0.0),
                    Vec3::new(0.0, 1.0, 0.0),
                )
            } else {
                let base = rng.in_cube(-100.0, 100.0);
                let (u, v) = (
                    rng.unit() * rng.range(0.01, 10.0),
                    rng.unit() * rng.range(0.01, 10.0),
                );
                (base, base + u, base + u + v, base + v)
            };
            let normal = (p1 - p0).cross(p3 - p0).normalize();
            for _ in 0..500 {
                let target = lerp(p0, p2, rng.range(0.01, 0.99));
                let o = target + rng.unit() * rng.range(0.1, 100.0);
                let ray = Ray::new(o, target - o, f32::INFINITY);
                // Skip grazing rays: f32 corners fold the quad by ~1e-7 rad, and a
                // ray that grazes the fold misses both triangles in exact arithmetic.
                if ray.d.normalize().dot(normal).abs() < 1.0e-3 {
                    grazing += 1;
                    continue;
                }
                let h1 = intersect_triangle(&ray, p0, p1, p2);
                let h2 = intersect_triangle(&ray, p0, p2, p3);
                rays += 1;
                match (h1, h2) {
                    (None, None) => zero += 1,
                    (Some(a), Some(b)) => {
                        double += 1;
                        worst_double_dt = worst_double_dt.max((a.t - b.t).abs() / a.t);
                    }
                    _ => {}
                }
            }
        }
        println!(
            "quad diagonal: {rays} rays ({grazing} grazing skipped), {zero} with no hit, \
             {double} hitting both triangles (edge function exactly 0; t differs by at most \
             {worst_double_dt:.2e} relative)"
        );
        assert!(rays > 90_000);
        assert_eq!(zero, 0);
        assert!(worst_double_dt < 1.0e-5);
    }

    /// Triangle and sphere hit points at many scales and offsets: rays leaving
    /// from `offset_ray_origin` never hit the same primitive again.
    #[test]
    fn offset_origin_prevents_self_hits() {
        let mut rng = Pcg32::new(3);
        let scales = [1.0e-4f32, 1.0e-3, 1.0e-2, 1.0, 1.0e2, 1.0e3, 1.0e5];
        let (mut tested, mut self_hits, mut raw_self_hits) = (0usize, 0usize, 0usize);
        let (mut tri_tests, mut sph_tests) = (0usize, 0usize);
        for &scale in &scales {
            for far in [0.0f32, 1.0e4] {
                for _ in 0..1500 {
                    let center = rng.unit() * far + rng.in_cube(-scale, scale);
                    // Triangle: a ray from a random point hits it, then leaves.
                    let (p0, p1, p2) = (
                        center + rng.unit() * scale,
                        center + rng.unit() * scale,
                        center + rng.unit() * scale,
                    );
                    let o = center + rng.unit() * (scale * rng.range(1.0, 10.0));
                    let target = lerp(lerp(p0, p1, rng.f32()), p2, rng.f32() * 0.9);
                    let ray = Ray::new(o, target - o, f32::INFINITY);
                    if let Some(h) = intersect_triangle(&ray, p0, p1, p2) {
                        let p = p0 * (1.0 - h.b1 - h.b2) + p1 * h.b1 + p2 * h.b2;
                        let ng = (p1 - p0).cross(p2 - p0).normalize_or_zero();
                        if ng != Vec3::ZERO {
                            // Leave on either side: reflection and transmission.
                            for side in [-1.0f32, 1.0] {
                                let n = if ng.dot(ray.d) < 0.0 { ng } else { -ng } * side;
                                let (d, _) = rng.cosine_around(n);
                                let mag = max_abs(p0).max(max_abs(p1)).max(max_abs(p2));
                                let o2 = offset_ray_origin(p, n, mag);
                                let r2 = Ray::new(o2, d, f32::INFINITY);
                                tested += 1;
                                tri_tests += 1;
                                self_hits +=
                                    usize::from(intersect_triangle(&r2, p0, p1, p2).is_some());
                            }
                        }
                    }
                    // Sphere: outgoing rays above the tangent plane, from the hit
                    // point reprojected onto the surface (and, for the record, from
                    // the raw o + t d).
                    let radius = scale * rng.range(0.5, 1.0);
                    let o = center + rng.unit() * (radius * rng.range(1.5, 10.0));
                    let target = center + rng.unit() * (radius * 0.5);
                    let ray = Ray::new(o, (target - o).normalize(), f32::INFINITY);
                    if let Some(t) = intersect_sphere(&ray, center, radius) {
                        let raw = ray.at(t);
                        let p = sphere_surface_point(raw, center, radius);
                        let n = (p - center).normalize_or_zero();
                        if n != Vec3::ZERO {
                            let (d, _) = rng.cosine_around(n);
                            let mag = max_abs(center) + radius;
                            let r2 = Ray::new(offset_ray_origin(p, n, mag), d, f32::INFINITY);
                            tested += 1;
                            sph_tests += 1;
                            self_hits +=
                                usize::from(intersect_sphere(&r2, center, radius).is_some());
                            let raw_ray =
                                Ray::new(offset_ray_origin(raw, n, mag), d, f32::INFINITY);
                            raw_self_hits +=
                                usize::from(intersect_sphere(&raw_ray, center, radius).is_some());
                        }
                    }
                }
            }
        }
        println!(
            "offset origin: {tested} outgoing rays ({tri_tests} triangle, {sph_tests} sphere), \
             {self_hits} self-hits; sphere rays from the raw o + t d instead: {raw_self_hits} \
             self-hits"
        );
        assert!(tri_tests > 15_000 && sph_tests > 15_000);
        assert_eq!(self_hits, 0);
    }

    /// Ground spheres of radius 1e4 to 1e11 centred below the origin, hit
    /// near their top (coordinates near 0, the sphere's rounding that of its
    /// radius) from eyes at 2^-15 of |centre| + radius above: rays leaving
    /// the offset point never hit the sphere again. Without the magnitude
    /// floor (`mag` = 0) some do; the count is printed.
    #[test]
    fn offset_covers_huge_sphere_rounding_near_the_origin() {
        let mut rng = Pcg32::new(11);
        let (mut tested, mut self_hits, mut self_hits_without) = (0usize, 0usize, 0usize);
        for exp in 4..=11 {
            for _ in 0..4000 {
                let radius = 10f32.powi(exp) * rng.range(1.0, 5.0);
                let center = Vec3::new(0.0, -radius, 0.0);
                let mag = max_abs(center) + radius;
                let height = mag / 32768.0 * rng.range(1.0, 4.0);
                let o = Vec3::new(0.0, height, 0.0);
                let target =
                    Vec3::new(rng.range(-1.0, 1.0), 0.0, rng.range(-1.0, 1.0)) * height * 4.0;
                let ray = Ray::new(o, (target - o).normalize(), f32::INFINITY);
                let Some(t) = intersect_sphere(&ray, center, radius) else {
                    continue;
                };
                let p = sphere_surface_point(ray.at(t), center, radius);
                let n = (p - center).normalize();
                let (d, _) = rng.cosine_around(n);
                tested += 1;
                let r2 = Ray::new(offset_ray_origin(p, n, mag), d, f32::INFINITY);
                self_hits += usize::from(intersect_sphere(&r2, center, radius).is_some());
                let r0 = Ray::new(offset_ray_origin(p, n, 0.0), d, f32::INFINITY);
                self_hits_without += usize::from(intersect_sphere(&r0, center, radius).is_some());
            }
        }
        println!(
            "ground spheres: {tested} outgoing rays, {self_hits} self-hits; without the \
             magnitude floor: {self_hits_without}"
        );
        assert!(tested > 30_000);
        assert_eq!(self_hits, 0);
    }

    /// f64 reference for the nearest sphere hit from the same f32 inputs, and
    /// the ray's distance from the centre in units of the radius (infinite
    /// when the origin lies within 1% of the radius from the surface).
    fn sphere_t_f64(o: Vec3, d: Vec3, c: Vec3, r: f32) -> Option<(f64, f64)> {
        let o = o.as_dvec3();
        let d = d.as_dvec3();
        let c = c.as_dvec3();
        let r = r as f64;
        let dl = d.length();
        let dn = d / dl;
        let f = o - c;
        let b = f.dot(dn);
        let perp = f - b * dn;
        let disc = r * r - perp.dot(perp);
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        let (t0, t1) = (-b - s, -b + s);
        let t = if t0 > 0.0 { t0 } else { t1 };
        // Origins within 1% of the radius from the surface give ill-posed
        // near roots; report them as tangent so they are not judged.
        let surface_gap = (f.length() - r).abs() / r;
        let impact = if surface_gap < 0.01 {
            f64::INFINITY
        } else {
            perp.length() / r
        };
        (t > 0.0 && dl > 0.0).then_some((t / dl, impact))
    }

    #[test]
    fn sphere_accuracy_tiny_and_huge() {
        let mut rng = Pcg32::new(13);
        let mut worst = [0.0f64; 3];
        let mut rays = 0usize;
        let radii = [1.0e-4f32, 1.0, 1.0e6];
        for (ri, &radius) in radii.iter().enumerate() {
            for far in [0.0f32, 1.0e4, 1.0e7] {
                for k in 0..10_000 {
                    let center = rng.unit() * far + rng.in_cube(-radius, radius);
                    // Outside at 1.5r..100r, or inside; aimed within 0.9r of the centre.
                    let o = if k % 4 == 0 {
                        center + rng.unit() * (radius * rng.range(0.0, 0.9))
                    } else {
                        center + rng.unit() * (radius * rng.range(1.5, 100.0))
                    };
                    let target = center + rng.unit() * (radius * rng.range(0.0, 0.9));
                    // Not normalised on purpose: t must be rescaled.
                    let d = (target - o) * rng.range(0.1, 10.0);
                    let ray = Ray::new(o, d, f32::INFINITY);
                    // Judge well-conditioned hits only: near tangency t is ill-posed.
                    let Some((reference, impact)) = sphere_t_f64(o, d, center, radius) else {
                        continue;
                    };
                    if impact > 0.95 {
                        continue;
                    }
                    let t = intersect_sphere(&ray, center, radius).expect("reference hit missed");
                    let rel = ((t as f64 - reference) / reference).abs();
                    worst[ri] = worst[ri].max(rel);
                    rays += 1;
                }
            }
        }
        println!(
            "sphere accuracy: {rays} rays, worst relative t error r=1e-4: {:.3e}, r=1: {:.3e}, \
             r=1e6: {:.3e}",
            worst[0], worst[1], worst[2]
        );
        assert!(rays > 60_000);
        for w in worst {
            assert!(w < 1.0e-5, "worst relative error {w}");
        }
    }

    #[test]
    fn sphere_basic() {
        let c = Vec3::new(0.0, 0.0, 5.0);
        let ray = Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0), 100.0);
        assert_eq!(intersect_sphere(&ray, c, 1.0), Some(2.0));
        let inside = Ray::new(c, Vec3::new(0.0, -0.0, 1.0), 100.0);
        assert_eq!(intersect_sphere(&inside, c, 1.0), Some(1.0));
        let away = Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), 100.0);
        assert_eq!(intersect_sphere(&away, c, 1.0), None);
        let short = Ray::new(Vec3::ZERO, Vec3::Z, 3.9);
        assert_eq!(intersect_sphere(&short, c, 1.0), None);
        let zero_dir = Ray::new(Vec3::ZERO, Vec3::ZERO, 100.0);
        assert_eq!(intersect_sphere(&zero_dir, c, 1.0), None);
    }

    #[test]
    fn slab_zero_and_negative_zero_components() {
        let (bmin, bmax) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
        let inv = |d: Vec3| {
            let i = safe_inverse(d);
            assert!(i.is_finite(), "{d:?}");
            i
        };
        for zx in [0.0f32, -0.0] {
            for zy in [0.0f32, -0.0] {
                // Along +z from below, inside the box's footprint.
                let d = Vec3::new(zx, zy, 1.0);
                let t = slab_test(Vec3::new(0.5, 0.5, -2.0), inv(d), 10.0, bmin, bmax);
                assert_eq!(t, Some(2.0));
                // Origin on the faces x = 0 and y = 1 (a box edge), either zero sign.
                let t = slab_test(Vec3::new(0.0, 1.0, -2.0), inv(d), 10.0, bmin, bmax);
                assert_eq!(t, Some(2.0), "edge ray {d:?}");
                let t = slab_test(Vec3::new(1.0, 0.0, 3.0), inv(-d), 10.0, bmin, bmax);
                assert_eq!(t, Some(2.0), "edge ray {:?}", -d);
                // Just outside the face: culled.
                let t = slab_test(Vec3::new(-1.0e-7, 0.5, -2.0), inv(d), 10.0, bmin, bmax);
                assert_eq!(t, None);
                // Beyond tmax.
                assert_eq!(
                    slab_test(Vec3::new(0.5, 0.5, -2.0), inv(d), 1.5, bmin, bmax),
                    None
                );
                // Flat box (a z = 0 quad's bounds) met by a ray lying in its plane.
                let flat_max = Vec3::new(1.0, 1.0, 0.0);
                let along = Vec3::new(1.0, zx, zy);
                let t = slab_test(Vec3::new(-1.0, 0.5, 0.0), inv(along), 10.0, bmin, flat_max);
                assert_eq!(t, Some(1.0));
                let t = slab_test(Vec3::new(-1.0, 1.0, 0.0), inv(along), 10.0, bmin, flat_max);
                assert_eq!(t, Some(1.0));
            }
        }
        // Origin inside: entry clamps to 0.
        let t = slab_test(
            Vec3::splat(0.5),
            inv(Vec3::new(1.0, -2.0, 0.5)),
            10.0,
            bmin,
            bmax,
        );
        assert_eq!(t, Some(0.0));
        // Box behind the ray.
        let t = slab_test(Vec3::new(0.5, 0.5, 3.0), inv(Vec3::Z), 10.0, bmin, bmax);
        assert_eq!(t, None);
    }

    #[test]
    fn offset_moves_along_normal() {
        let p = Vec3::new(1.0e4, -1.0e4, 1.0e-3);
        let n = Vec3::new(1.0, 1.0, 1.0).normalize();
        let q = offset_ray_origin(p, n, 0.0);
        assert!(q.x > p.x && q.y > p.y && q.z > p.z);
        let q = offset_ray_origin(p, -n, 0.0);
        assert!(q.x < p.x && q.y < p.y && q.z < p.z);
        // A point at the origin moves by the magnitude it was computed from.
        let q = offset_ray_origin(Vec3::splat(-0.0), Vec3::Z, 1.0);
        assert_eq!(q, Vec3::new(0.0, 0.0, OFFSET_REL));
    }

    #[test]
    fn aabb_basics() {
        let mut b = Aabb::EMPTY;
        assert!(b.is_empty());
        assert_eq!(b.surface_area(), 0.0);
        b.grow(Vec3::new(1.0, 2.0, 3.0));
        assert!(!b.is_empty());
        assert_eq!(b.surface_area(), 0.0);
        b = b.union(Aabb::new(Vec3::ZERO, Vec3::ONE));
        assert_eq!(b.extent(), Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(b.surface_area(), 2.0 * (2.0 + 6.0 + 3.0));
        assert_eq!(b.centroid(), Vec3::new(0.5, 1.0, 1.5));
        let t = Aabb::of_triangle(Vec3::X, Vec3::Y, -Vec3::Z);
        assert_eq!(
            t,
            Aabb::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 1.0, 0.0))
        );
        let s = Aabb::of_sphere(Vec3::new(1.0e6, 0.0, 0.0), 1.0);
        assert!(s.contains(&Aabb::new(
            Vec3::new(1.0e6 - 1.0, -1.0, -1.0),
            Vec3::new(1.0e6 + 1.0, 1.0, 1.0)
        )));
        let huge = Aabb::new(Vec3::splat(-f32::MAX), Vec3::splat(f32::MAX));
        assert!(huge.centroid().is_finite());
    }
}
