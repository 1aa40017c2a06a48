//! The reference the BVH traversal tests compare the intersect kernel with.

use glam::Vec3;
use lancer::internal::geometry::{intersect_sphere, intersect_triangle, Ray};
use lancer::render::KernelHit;
use lancer::scene::Scene;

/// Closest hit of the ray `(o, d, tmax)` by testing every primitive of
/// `scene` with the CPU's mirror of the kernel's intersection functions.
/// Primitives are numbered as the kernel numbers them: spheres first, then
/// triangles.
pub fn closest_hit(scene: &Scene, (o, d, tmax): (Vec3, Vec3, f32)) -> Option<KernelHit> {
    let mut best = None;
    let mut ray = Ray { o, d, tmax };
    for (i, s) in scene.spheres.iter().enumerate() {
        if let Some(t) = intersect_sphere(&ray, s.center, s.radius) {
            best = Some(KernelHit { prim: i as u32, t });
            ray.tmax = t;
        }
    }
    for (i, tri) in scene.triangles.iter().enumerate() {
        if let Some(hit) = intersect_triangle(&ray, tri.p[0], tri.p[1], tri.p[2]) {
            best = Some(KernelHit {
                prim: (scene.spheres.len() + i) as u32,
                t: hit.t,
            });
            ray.tmax = hit.t;
        }
    }
    best
}
