//! The intersect kernel's BVH traversal against brute force over every
//! primitive, on random and adversarial rays.

use crate::common;

use common::materials::{lambert, material};
use common::*;
use glam::Vec3;
use lancer::render::Renderer;
use lancer::scene::{Scene, Sphere, Triangle};

/// A small deterministic generator (xorshift64*), so tests need no crate.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32) / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
    fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    fn dir(&mut self) -> Vec3 {
        loop {
            let v = self.vec(-1.0, 1.0);
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// A soup of spheres and triangles, plus an axis-aligned box of quads.
fn soup() -> Scene {
    let mut scene = load("tests/scenes/furnace.toml");
    // Enough samples that one wave holds every test ray.
    scene.render.spp = 64;
    scene.materials = vec![material("grey", lambert(Vec3::splat(0.5)))];
    let mut rng = Rng(0x1234_5678_9abc_def1);
    scene.spheres = (0..60)
        .map(|_| Sphere {
            center: rng.vec(-4.0, 4.0),
            radius: rng.range(0.05, 0.6),
            material: 0,
            mitsuba_frame: None,
        })
        .collect();
    scene.triangles = (0..400)
        .map(|_| {
            let c = rng.vec(-4.0, 4.0);
            Triangle {
                p: [
                    c + rng.vec(-0.7, 0.7),
                    c + rng.vec(-0.7, 0.7),
                    c + rng.vec(-0.7, 0.7),
                ],
                n: None,
                uv: None,
                material: 0,
                attribute: None,
            }
        })
        .collect();
    // An axis-aligned cube from -5 to 5: its faces are BVH box faces too.
    let corners = |x: f32, y: f32, z: f32| Vec3::new(x, y, z) * 5.0;
    let quads = [
        [
            corners(-1., -1., -1.),
            corners(1., -1., -1.),
            corners(1., 1., -1.),
            corners(-1., 1., -1.),
        ],
        [
            corners(-1., -1., 1.),
            corners(1., -1., 1.),
            corners(1., 1., 1.),
            corners(-1., 1., 1.),
        ],
        [
            corners(-1., -1., -1.),
            corners(-1., 1., -1.),
            corners(-1., 1., 1.),
            corners(-1., -1., 1.),
        ],
        [
            corners(1., -1., -1.),
            corners(1., 1., -1.),
            corners(1., 1., 1.),
            corners(1., -1., 1.),
        ],
        [
            corners(-1., -1., -1.),
            corners(1., -1., -1.),
            corners(1., -1., 1.),
            corners(-1., -1., 1.),
        ],
        [
            corners(-1., 1., -1.),
            corners(1., 1., -1.),
            corners(1., 1., 1.),
            corners(-1., 1., 1.),
        ],
    ];
    for q in quads {
        for tri in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            scene.triangles.push(Triangle {
                p: tri,
                n: None,
                uv: None,
                material: 0,
                attribute: None,
            });
        }
    }
    scene
}

/// Random rays, then rays built to break naive slab tests.
fn rays() -> Vec<(Vec3, Vec3, f32)> {
    let mut rng = Rng(42);
    let mut rays = Vec::new();
    for _ in 0..20000 {
        rays.push((rng.vec(-4.5, 4.5), rng.dir(), f32::MAX));
    }
    // Axis-aligned directions, with +0.0 and -0.0 in the other components.
    for _ in 0..2000 {
        let axis = (rng.next() * 3.0) as usize % 3;
        let sign = if rng.next() < 0.5 { -1.0 } else { 1.0 };
        let mut d = Vec3::ZERO;
        if rng.next() < 0.5 {
            d = Vec3::splat(-0.0);
        }
        d[axis] = sign;
        rays.push((rng.vec(-4.5, 4.5), d, f32::MAX));
    }
    // Origins exactly on the faces of the cube (and its BVH boxes), rays along faces.
    for _ in 0..2000 {
        let mut o = rng.vec(-4.5, 4.5);
        let axis = (rng.next() * 3.0) as usize % 3;
        o[axis] = if rng.next() < 0.5 { -5.0 } else { 5.0 };
        let mut d = rng.dir();
        if rng.next() < 0.5 {
            d[axis] = -0.0;
            d = d.normalize();
        }
        rays.push((o, d, f32::MAX));
    }
    // Short rays that must stop before the geometry.
    for _ in 0..1000 {
        rays.push((rng.vec(-4.5, 4.5), rng.dir(), rng.range(0.01, 1.0)));
    }
    rays
}

#[test]
fn kernel_closest_hits_agree_with_brute_force() {
    let ctx = context();
    let scene = soup();
    let rays = rays();
    let mut renderer = Renderer::new(&ctx, &scene, &options(rays.len() as u32)).expect("renderer");
    let gpu = renderer.intersect_rays(&rays).expect("intersect");
    assert_eq!(ctx.validation_errors(), 0);

    let mut mismatches = Vec::new();
    let mut hits = 0;
    for (i, (&(o, d, tmax), g)) in rays.iter().zip(&gpu).enumerate() {
        let cpu = brute_force::closest_hit(&scene, (o, d, tmax));
        hits += cpu.is_some() as usize;
        let agree = match (cpu, g) {
            (None, None) => true,
            // Same primitive, or a tie at the same distance (shared edges).
            (Some(c), Some(g)) => {
                (c.t - g.t).abs() <= 1e-4 * c.t.max(1.0)
                    && (c.prim == g.prim || (c.t - g.t).abs() <= 1e-6 * c.t.max(1.0))
            }
            _ => false,
        };
        if !agree {
            mismatches.push((i, o, d, cpu, *g));
        }
    }
    println!(
        "{} rays, {} hits, {} mismatches",
        rays.len(),
        hits,
        mismatches.len()
    );
    assert!(
        hits > rays.len() / 2,
        "the test scene should be hit by most rays"
    );
    assert!(
        mismatches.is_empty(),
        "{} rays disagree, first: {:?}",
        mismatches.len(),
        &mismatches[..mismatches.len().min(5)]
    );
}
