//! Harder numerical cases, each asserting a measured figure.
//!
//! - ray-origin offsets over coordinates from 1e-8 to 1e8 (no spawned ray
//!   re-hits its surface, no shadow ray to a visible point is blocked);
//! - the Cornell box scaled down a thousandfold and moved tens of units
//!   from the origin renders the unit box's image;
//! - a closed mesh far from the origin leaks no ray aimed at its edges and
//!   vertices;
//! - rays with NaN, Inf or zero components are clean misses;
//! - 100,000 overlapping triangles and sliver triangles: the kernel's
//!   closest hit agrees with brute force.

use crate::common;

use common::materials::{lambert, material};
use common::*;
use glam::DVec3;
use glam::Vec3;
use lancer::analysis::ztest::z_test;
use lancer::internal::geometry::{intersect_triangle, Ray};
use lancer::render::{KernelHit, Probe, ProbeResult, RenderOutput, Renderer};
use lancer::scene::{Scene, Sphere, Triangle};
use rayon::prelude::*;

/// A small deterministic generator (xorshift64*), so tests need no crate.
struct Rng(u64);

impl Rng {
    /// Uniform in [0, 1).
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    /// Log-uniform in [lo, hi).
    fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        10f64.powf(self.range(lo.log10(), hi.log10()))
    }
    /// Uniform unit vector.
    fn unit(&mut self) -> DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let s = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(s * phi.cos(), s * phi.sin(), z)
    }
}

/// A scene of the given primitives, one grey Lambert material, no light,
/// with room in one wave for `rays` rays.
fn primitives_scene(spheres: Vec<Sphere>, triangles: Vec<Triangle>, rays: usize) -> Scene {
    let mut scene = load("scenes/cornell.toml");
    let side = (rays as f64).sqrt().ceil() as u32;
    scene.render.width = side.max(1);
    scene.render.height = side.max(1);
    scene.render.spp = 1;
    scene.materials = vec![material("grey", lambert(Vec3::splat(0.5)))];
    scene.spheres = spheres;
    scene.triangles = triangles;
    scene
}

/// A triangle of the given vertices (f64, rounded to f32).
fn triangle(p: [DVec3; 3]) -> Triangle {
    Triangle {
        p: p.map(|v| v.as_vec3()),
        n: None,
        uv: None,
        material: 0,
        attribute: None,
    }
}

/// A ray from `o` towards `target`, both rounded to f32, with unbounded tmax.
fn ray_to(o: DVec3, target: DVec3) -> (Vec3, Vec3, f32) {
    let o = o.as_vec3();
    (o, (target.as_vec3() - o).normalize(), f32::INFINITY)
}

/// The Cornell box at 64 x 64 with `spp` samples and `seed`, its geometry
/// and camera moved by `p -> p * scale + offset`. Emission is unchanged, so
/// the radiance of every pixel is the unit box's.
fn cornell_moved(scale: f32, offset: Vec3, spp: u32, seed: u32) -> Scene {
    let mut scene = load("scenes/cornell.toml");
    scene.render.width = 64;
    scene.render.height = 64;
    scene.render.spp = spp;
    scene.render.seed = seed;
    let moved = |p: Vec3| p * scale + offset;
    for t in &mut scene.triangles {
        t.p = t.p.map(moved);
    }
    for s in &mut scene.spheres {
        s.center = moved(s.center);
        s.radius *= scale;
    }
    let cam = &mut scene.camera;
    cam.eye = moved(cam.eye);
    cam.look_at = moved(cam.look_at);
    cam.focus_distance *= scale;
    cam.aperture_radius *= scale;
    scene
}

/// z-score of the difference of two images' means (all pixels and
/// channels), from each image's per-value variance of the mean.
fn image_mean_z(a: &RenderOutput, b: &RenderOutput) -> (f64, f64) {
    let n = a.mean.len() as f64;
    let sum = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>();
    let (ma, mb) = (sum(&a.mean) / n, sum(&b.mean) / n);
    let var = (sum(&a.var_of_mean) + sum(&b.var_of_mean)) / (n * n);
    ((ma - mb) / mb, (ma - mb) / var.sqrt())
}

/// The Cornell box scaled by 1e-3 and moved about 30 units from the origin
/// (and, for comparison, scaled in place) renders the unit box's image: the
/// per-pixel z-test (Šidák, alpha 0.01) passes, and the image means differ
/// by less than 4 standard errors.
#[test]
fn small_cornell_box_far_from_the_origin_renders_the_unit_box() {
    let ctx = context();
    let spp = 128;
    let unit = render(
        &ctx,
        &cornell_moved(1.0, Vec3::ZERO, spp, 1),
        &options(1 << 18),
    );
    for (scale, offset) in [(1e-3, Vec3::ZERO), (1e-3, Vec3::new(-17.0, 23.0, 29.0))] {
        let out = render(
            &ctx,
            &cornell_moved(scale, offset, spp, 2),
            &options(1 << 18),
        );
        let z = z_test(
            &out.mean,
            &out.var_of_mean,
            &unit.mean,
            &unit.var_of_mean,
            0.01,
        );
        let (rel, z_mean) = image_mean_z(&out, &unit);
        println!(
            "Cornell box x{scale:e} at {offset}: mean relative difference {:.3}%, \
             image-mean z {z_mean:.2}; {z}",
            100.0 * rel
        );
        assert!(
            z.all_passed() && z_mean.abs() < 4.0,
            "Cornell box x{scale:e} at {offset} differs from the unit box: image-mean \
             z {z_mean:.2}, {z}"
        );
    }
}

/// Fails with `what`, the count and the first five items unless `items` is empty.
fn assert_empty<T: std::fmt::Debug>(items: &[T], what: &str) {
    assert!(
        items.is_empty(),
        "{} {what}, first: {:?}",
        items.len(),
        &items[..items.len().min(5)]
    );
}

/// A primitive of the offset test, in f64 from its f32 data.
enum Shape {
    Triangle([DVec3; 3]),
    Sphere(DVec3, f64),
}

impl Shape {
    /// Unit normal at `p` facing the point `from`.
    fn normal_towards(&self, p: DVec3, from: DVec3) -> DVec3 {
        let n = match self {
            Shape::Triangle(v) => (v[1] - v[0]).cross(v[2] - v[0]).normalize(),
            Shape::Sphere(c, _) => (p - *c).normalize(),
        };
        if n.dot(from - p) < 0.0 {
            -n
        } else {
            n
        }
    }
    /// Whether `o` lies inside (a sphere).
    fn holds(&self, o: DVec3) -> bool {
        matches!(self, Shape::Sphere(c, r) if (o - *c).length() < *r)
    }
    /// Longest edge of a triangle, radius of a sphere.
    fn extent(&self) -> f64 {
        match self {
            Shape::Triangle(v) => (0..3)
                .map(|k| (v[(k + 1) % 3] - v[k]).length())
                .fold(0.0, f64::max),
            Shape::Sphere(_, r) => *r,
        }
    }
    /// Whether a ray from `o` resolves the primitive at `p`: its extent is
    /// at least 1e-4 of the magnitude of the ray's coordinates there (about
    /// 800 units in their last place). A smaller one collapses to a few
    /// points of the f32 grid around the ray origin, and the hit point is
    /// that of the collapsed shape.
    fn resolved_from(&self, o: DVec3, p: DVec3) -> bool {
        self.extent() > 1e-4 * (o.abs().max_element() + (p - o).length())
    }
    /// Largest coordinate magnitude the primitive's points come from.
    fn magnitude(&self) -> f64 {
        match self {
            Shape::Triangle(v) => v.iter().map(|p| p.abs().max_element()).fold(0.0, f64::max),
            Shape::Sphere(c, r) => c.abs().max_element() + r,
        }
    }
}

/// Clusters of a triangle and a sphere (size log-uniform 1e-8 to 1e8, at
/// least 1e-3 of their distance from the origin), translated log-uniformly
/// up to 1e8, each probed from outside: a ray to a point of one primitive,
/// a random direction to leave it by, and a ray to a point of the other.
fn offset_probes(clusters: usize, rng: &mut Rng) -> (Scene, Vec<Probe>) {
    let (mut spheres, mut triangles, mut probes) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..clusters {
        let t = if rng.next() < 0.1 {
            0.0
        } else {
            rng.log_range(1e-8, 1e8)
        };
        let c = rng.unit() * t;
        let s = rng.log_range((t * 1e-3).max(1e-8), (1e8f64).max(t * 1e-3));
        let tri = [0; 3].map(|_| c + rng.unit() * s);
        let (sc, r) = (c + rng.unit() * (2.5 * s), s * rng.range(0.2, 1.0));
        triangles.push(triangle(tri));
        spheres.push(Sphere {
            center: sc.as_vec3(),
            radius: r as f32,
            material: 0,
            mitsuba_frame: None,
        });
        for _ in 0..8 {
            let o = c + rng.unit() * (s * rng.range(4.0, 8.0));
            let (u, v) = (rng.next(), rng.next());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let on_tri = tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * v;
            let on_sphere = sc + (o - sc).normalize().lerp(rng.unit(), 0.5).normalize() * r;
            let (a, b) = if rng.next() < 0.5 {
                (on_tri, on_sphere)
            } else {
                (on_sphere, on_tri)
            };
            probes.push(Probe {
                to_a: ray_to(o, a),
                leave: rng.unit().as_vec3(),
                to_b: ray_to(o, b),
            });
        }
    }
    (primitives_scene(spheres, triangles, probes.len()), probes)
}

/// The primitive of scene index `prim` (spheres first) in f64.
fn shape(scene: &Scene, prim: u32) -> Shape {
    let i = prim as usize;
    match scene.spheres.get(i) {
        Some(s) => Shape::Sphere(s.center.as_dvec3(), f64::from(s.radius)),
        None => Shape::Triangle(
            scene.triangles[i - scene.spheres.len()]
                .p
                .map(|p| p.as_dvec3()),
        ),
    }
}

/// Whether the self-hit the kernel reports for a ray leaving `shape` at `p`
/// along `wi` is wrong: a triangle is never hit again; a sphere only at
/// the far end of its chord (a hit at less than half the chord is the ray's
/// own start). `None` when the sphere's chord is too short to judge
/// (within 1% of tangent).
fn wrong_self_hit(shape: &Shape, p: DVec3, wi: DVec3, hit: Option<f32>) -> Option<bool> {
    match shape {
        Shape::Triangle(_) => Some(hit.is_some()),
        Shape::Sphere(c, r) => {
            let cos = (p - *c).normalize().dot(wi);
            if cos.abs() < 0.01 {
                return None;
            }
            let chord = -2.0 * r * cos;
            Some(match hit {
                None => chord > 0.0,
                Some(t) => f64::from(t) < 0.5 * chord,
            })
        }
    }
}

/// Ray-origin offsets (pbrt-v4's Triangle reintersection test, Mitsuba's
/// offset tests), on the device: triangles and spheres of sizes from 1e-8 to
/// 1e8 translated up to 1e8. A ray spawned from a hit, as the shade kernel
/// spawns it, never hits its own surface again; the shadow segment the
/// shade kernel builds between two surface points that see each other is
/// never blocked by either surface.
#[test]
fn spawned_rays_never_rehit_their_surface_and_shadow_rays_reach_visible_points() {
    let ctx = context();
    let mut rng = Rng(0x0ff5_e75e);
    let (scene, probes) = offset_probes(4000, &mut rng);
    let mut renderer =
        Renderer::new(&ctx, &scene, &options(probes.len() as u32)).expect("renderer");
    let results = renderer.probe_rays(&probes).expect("probe");
    assert_eq!(ctx.validation_errors(), 0);

    let (mut spawned, mut tangent, mut self_hits) = (0usize, 0usize, Vec::new());
    let mut unresolved = 0usize;
    let (mut shadow, mut blocked) = (0usize, Vec::new());
    for (probe, r) in probes.iter().zip(&results) {
        let ProbeResult { a: Some(a), .. } = *r else {
            continue;
        };
        let sa = shape(&scene, a);
        let oa = probe.to_a.0.as_dvec3();
        let (pa, wi) = (r.pa.as_dvec3(), probe.leave.as_dvec3());
        if sa.holds(oa) || !sa.resolved_from(oa, pa) {
            unresolved += usize::from(!sa.holds(oa));
            continue;
        }
        match wrong_self_hit(&sa, pa, wi, r.self_hit) {
            None => tangent += 1,
            Some(wrong) => {
                spawned += 1;
                if wrong {
                    self_hits.push((a, pa, wi, r.self_hit));
                }
            }
        }
        // Judge segments between points that clearly see each other
        let Some(b) = r.b.filter(|&b| b != a) else {
            continue;
        };
        let sb = shape(&scene, b);
        let ob = probe.to_b.0.as_dvec3();
        let pb = r.pb.as_dvec3();
        let v = pb - pa;
        let len = v.length();
        let visible = !sb.holds(ob)
            && sb.resolved_from(ob, pb)
            && sa.normal_towards(pa, oa).dot(v) > 0.05 * len
            && sb.normal_towards(pb, ob).dot(-v) > 0.05 * len
            && len > 1e-4 * sa.magnitude().max(sb.magnitude());
        if visible {
            shadow += 1;
            if r.shadow_blocked {
                blocked.push((a, b, pa, pb));
            }
        }
    }
    println!(
        "offsets: {spawned} spawned rays ({tangent} within 1% of a sphere's tangent and \
         {unresolved} from surfaces too small for their ray's origin not judged), \
         {} self-hits; {shadow} shadow segments between visible points, {} blocked",
        self_hits.len(),
        blocked.len()
    );
    assert!(spawned > 25_000 && shadow > 4_000, "too few judged rays");
    assert_empty(&self_hits, "spawned rays hit their own surface");
    assert_empty(&blocked, "shadow segments blocked by their own ends");
}

/// A closed mesh: a cube of `n` x `n` quads per face pushed onto a sphere of
/// `radius` around `center`. Vertices shared by faces are computed once
/// (from integer grid coordinates), so neighbouring triangles share exact
/// f32 corners. Returns the vertices and the triangles as index triples.
fn cube_sphere(n: i32, center: DVec3, radius: f64) -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let mut index = std::collections::HashMap::new();
    let mut verts = Vec::new();
    let mut id = |g: [i32; 3], verts: &mut Vec<Vec3>| {
        *index.entry(g).or_insert_with(|| {
            let p = DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64).normalize();
            verts.push((center + p * radius).as_vec3());
            verts.len() - 1
        })
    };
    let mut tris = Vec::new();
    for axis in 0..3 {
        for side in [-n, n] {
            // Grid point (i, j) of this face, as integer cube coordinates
            let g = |i: i32, j: i32| {
                let mut v = [0; 3];
                v[axis] = side;
                v[(axis + 1) % 3] = i;
                v[(axis + 2) % 3] = j;
                v
            };
            for i in (-n..n).step_by(2) {
                for j in (-n..n).step_by(2) {
                    let q = [g(i, j), g(i + 2, j), g(i + 2, j + 2), g(i, j + 2)]
                        .map(|c| id(c, &mut verts));
                    tris.push([q[0], q[1], q[2]]);
                    tris.push([q[0], q[2], q[3]]);
                }
            }
        }
    }
    (verts, tris)
}

/// Watertightness far from the origin: a closed cube-sphere mesh centred at
/// (1.5e5, 1e3, -2.2e5), where one ulp is 1/64, with radii 100 and 2 (its
/// vertices then 30 ulps apart). Rays aimed exactly at its vertices and at
/// points of its shared edges (f32 interpolations of the two corners) from
/// many directions outside it, where every triangle around the target faces
/// the ray, and from inside it, all hit the mesh in the intersect kernel.
#[test]
fn closed_mesh_far_from_the_origin_leaks_no_ray_at_its_edges_and_vertices() {
    let ctx = context();
    let center = DVec3::new(1.5e5, 1e3, -2.2e5);
    let mut rng = Rng(0x000e_d9e5);
    let (mut outside, mut inside, mut misses) = (0usize, 0usize, Vec::new());
    for radius in [100.0, 2.0] {
        let (verts, tris) = cube_sphere(8, center, radius);
        // Targets: each vertex and two points of each edge, with the
        // triangles around them
        let mut around: std::collections::BTreeMap<(usize, usize), Vec<usize>> = Default::default();
        for (k, t) in tris.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                around.entry((a.min(b), a.max(b))).or_default().push(k);
                around.entry((t[e], t[e])).or_default().push(k);
            }
        }
        let normal = |k: usize| {
            let p = tris[k].map(|i| verts[i].as_dvec3());
            (p[1] - p[0]).cross(p[2] - p[0]).normalize()
        };
        let mut rays = Vec::new();
        for (&(a, b), faces) in &around {
            let (va, vb) = (verts[a], verts[b]);
            let targets = if a == b {
                vec![va]
            } else {
                vec![va.lerp(vb, 0.5), va.lerp(vb, rng.next() as f32)]
            };
            for target in targets {
                let t = target.as_dvec3();
                for _ in 0..8 {
                    let o = center + rng.unit() * (radius * rng.range(1.5, 20.0));
                    // Every triangle around the target faces the ray, and
                    // the ray goes deep into the mesh (its line passes
                    // within 0.8 radius of the centre), so it must hit
                    let w = (t - o).normalize();
                    let front = faces.iter().all(|&k| normal(k).dot(-w) > 0.05);
                    let deep = (center - o).reject_from_normalized(w).length() < 0.8 * radius;
                    if front && deep {
                        rays.push(ray_to(o, t));
                        outside += 1;
                    }
                }
                let o = center + rng.unit() * (radius * rng.range(0.0, 0.5));
                rays.push(ray_to(o, t));
                inside += 1;
            }
        }
        let triangles = tris
            .iter()
            .map(|t| triangle(t.map(|i| verts[i].as_dvec3())))
            .collect();
        let scene = primitives_scene(Vec::new(), triangles, rays.len());
        let mut renderer =
            Renderer::new(&ctx, &scene, &options(rays.len() as u32)).expect("renderer");
        let hits = renderer.intersect_rays(&rays).expect("intersect");
        misses.extend(
            rays.iter()
                .zip(&hits)
                .enumerate()
                .filter(|(_, (_, h))| h.is_none())
                .map(|(i, (r, _))| (radius, i, *r)),
        );
    }
    assert_eq!(ctx.validation_errors(), 0);
    println!(
        "watertight at (1.5e5, 1e3, -2.2e5): {outside} rays from outside and {inside} from \
         inside aimed at vertices and edges, {} misses",
        misses.len()
    );
    assert!(outside > 7_000 && inside > 5_000, "too few rays");
    assert_empty(&misses, "rays slipped through");
}

/// A soup of 2,000 triangles and 100 spheres in [-4, 4]^3.
fn soup(rng: &mut Rng, rays: usize) -> Scene {
    let mut p = |s: f64| DVec3::new(rng.range(-s, s), rng.range(-s, s), rng.range(-s, s));
    let spheres = (0..100)
        .map(|_| Sphere {
            center: p(4.0).as_vec3(),
            radius: 0.2,
            material: 0,
            mitsuba_frame: None,
        })
        .collect();
    let triangles = (0..2000)
        .map(|_| {
            let c = p(4.0);
            triangle([c + p(0.5), c + p(0.5), c + p(0.5)])
        })
        .collect();
    primitives_scene(spheres, triangles, rays)
}

/// Rays with NaN or Inf components in the origin or the direction, zero
/// directions of either sign, and tmax of 0, -1 or NaN are clean misses of
/// the intersect kernel, and their traces visit no more BVH nodes and
/// primitives than the most any of 4,000 ordinary rays visits; an ordinary
/// ray with tmax = Inf hits what it hits with tmax = f32::MAX.
#[test]
fn degenerate_rays_are_clean_misses_and_visit_no_more_than_ordinary_rays() {
    let ctx = context();
    let mut rng = Rng(0x0dea_d0a7);
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let mut ordinary = Vec::new();
    for _ in 0..4000 {
        let o = DVec3::new(
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
        );
        let (o, d, _) = ray_to(o, o + rng.unit());
        ordinary.push((o, d, f32::MAX));
    }
    let origins = [
        Vec3::new(nan, 0.0, 0.0),
        Vec3::splat(nan),
        Vec3::new(0.0, inf, 0.0),
        Vec3::new(0.0, 0.0, -inf),
        Vec3::new(inf, -inf, nan),
        Vec3::splat(f32::MAX),
    ];
    let dirs = [
        Vec3::new(nan, 0.0, 0.0),
        Vec3::splat(nan),
        Vec3::new(inf, 0.0, 0.0),
        Vec3::new(0.0, -inf, 1.0),
        Vec3::splat(inf),
        Vec3::ZERO,
        Vec3::splat(-0.0),
    ];
    let mut degenerate = Vec::new();
    for &(o, d, _) in ordinary.iter().take(200) {
        degenerate.extend(origins.iter().map(|&bad| (bad, d, f32::MAX)));
        degenerate.extend(dirs.iter().map(|&bad| (o, bad, f32::MAX)));
        degenerate.extend([0.0, -1.0, nan].map(|tmax| (o, d, tmax)));
    }
    let infinite: Vec<_> = ordinary.iter().map(|&(o, d, _)| (o, d, inf)).collect();
    let all: Vec<_> = [&ordinary[..], &degenerate, &infinite].concat();
    let scene = soup(&mut rng, all.len());
    let mut renderer = Renderer::new(&ctx, &scene, &options(all.len() as u32)).expect("renderer");
    let hits = renderer.intersect_rays(&all).expect("intersect");
    let probes: Vec<Probe> = all
        .iter()
        .map(|&r| Probe {
            to_a: r,
            leave: Vec3::Y,
            to_b: r,
        })
        .collect();
    let visits: Vec<u32> = renderer
        .probe_rays(&probes)
        .expect("probe")
        .iter()
        .map(|r| r.visits)
        .collect();
    assert_eq!(ctx.validation_errors(), 0);

    let (n, m) = (ordinary.len(), degenerate.len());
    let most_ordinary = visits[..n].iter().copied().max().unwrap_or(0);
    let mean = |v: &[u32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
    let bad = &visits[n..n + m];
    let most_degenerate = bad.iter().copied().max().unwrap_or(0);
    let degenerate_hits: Vec<_> = degenerate
        .iter()
        .zip(&hits[n..n + m])
        .filter(|(_, h)| h.is_some())
        .collect();
    let changed = (0..n).filter(|&i| hits[i] != hits[n + m + i]).count();
    println!(
        "degenerate rays: {m} rays, {} hits; BVH visits per ray: degenerate mean {:.1}, most \
         {most_degenerate}; ordinary mean {:.1}, most {most_ordinary}; tmax = Inf changed {changed} \
         of {n} ordinary hits ({} ordinary rays hit)",
        degenerate_hits.len(),
        mean(bad),
        mean(&visits[..n]),
        hits[..n].iter().filter(|h| h.is_some()).count()
    );
    assert_empty(&degenerate_hits, "degenerate rays hit");
    assert!(
        most_degenerate <= most_ordinary,
        "a degenerate ray visited {most_degenerate} nodes"
    );
    assert_eq!(changed, 0, "tmax = Inf changed the hits");
}

/// What the user can write never starts a NaN ray: a camera grazing a
/// floor from its plane with a 179-degree field of view, a mirror sphere
/// resting on the floor, a tiny emitting sphere touching a wall, Phong of
/// exponent 1e6, glossy at 89.9 degrees and glass of ior 100 render with
/// zero NaN or Inf pixels and no non-finite sample dropped.
#[test]
fn extreme_valid_scene_renders_no_nan_pixel() {
    let camera = "eye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 179.0";
    let text = scene_header((64, 64), 16, 12, camera, "[0.5, 0.5, 0.5]")
        + "[materials.white]\ntype = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]\n\
        [materials.chrome]\ntype = \"mirror\"\nreflectance = [1.0, 1.0, 1.0]\n\
        [materials.shiny]\ntype = \"phong\"\ndiffuse = [0.0, 0.0, 0.0]\nspecular = [1.0, 1.0, 1.0]\nexponent = 1e6\n\
        [materials.brushed]\ntype = \"glossy\"\nreflectance = [1.0, 1.0, 1.0]\ncone_angle = 89.9\n\
        [materials.glass]\ntype = \"dielectric\"\nior = 100.0\n\
        [materials.lamp]\ntype = \"lambert\"\nalbedo = [0.0, 0.0, 0.0]\nemission = [1e6, 1e6, 1e6]\n\
        [[objects]]\ntype = \"quad\"\norigin = [-50.0, 0.0, 50.0]\nedge_u = [100.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, -100.0]\nmaterial = \"white\"\n\
        [[objects]]\ntype = \"quad\"\norigin = [-5.0, 0.0, -2.0]\nedge_u = [10.0, 0.0, 0.0]\nedge_v = [0.0, 5.0, 0.0]\nmaterial = \"brushed\"\n\
        [[objects]]\ntype = \"sphere\"\ncenter = [-1.0, 1.0, 0.0]\nradius = 1.0\nmaterial = \"chrome\"\n\
        [[objects]]\ntype = \"sphere\"\ncenter = [1.0, 0.5, 0.0]\nradius = 0.5\nmaterial = \"glass\"\n\
        [[objects]]\ntype = \"sphere\"\ncenter = [2.0, 1.0, -1.0]\nradius = 1.0\nmaterial = \"shiny\"\n\
        [[objects]]\ntype = \"sphere\"\ncenter = [0.0, 1.0, -1.999999]\nradius = 1e-6\nmaterial = \"lamp\"\n";
    let scene = load_inline(&text).unwrap_or_else(|e| panic!("{e}"));
    let out = render(&context(), &scene, &options(1 << 16));
    let nan = lancer::util::metrics::count_nonfinite(&out.mean);
    println!(
        "extreme scene: {nan} non-finite pixels, {} non-finite samples",
        out.stats.nonfinite_samples
    );
    assert_eq!(nan, 0);
    assert_eq!(out.stats.nonfinite_samples, 0);
}

/// 100,000 overlapping triangles and slivers around the unit square
/// [0, 1]^2 at z = 0: 25,000 identical copies of one triangle, 25,000
/// random triangles in the plane z = 0, 25,000 in planes stacked 1e-5
/// apart above it, 15,000 random triangles crossing it, 5,000 needles (edge
/// ratio 1e-6) and 5,000 zero-area triangles (collinear or repeated corners).
fn overlapping_triangles(rng: &mut Rng) -> Vec<Triangle> {
    let mut p = |z: f64| DVec3::new(rng.next(), rng.next(), z);
    let copy = [
        DVec3::new(0.1, 0.1, 0.0),
        DVec3::new(0.9, 0.2, 0.0),
        DVec3::new(0.4, 0.9, 0.0),
    ];
    let mut tris = vec![triangle(copy); 25_000];
    tris.extend((0..25_000).map(|_| triangle([p(0.0), p(0.0), p(0.0)])));
    tris.extend((0..25_000).map(|k| {
        let z = 1e-5 * (1 + k % 100) as f64;
        triangle([p(z), p(z), p(z)])
    }));
    tris.extend((0..15_000).map(|_| {
        let mut q = || {
            let xy = p(0.0);
            p(0.0).x * 0.2 - 0.1 + xy
        };
        triangle([q(), q(), q()])
    }));
    for k in 0..5_000 {
        let (a, b) = (p(0.0), p(0.0));
        let side = (b - a).cross(DVec3::Z).normalize() * (1e-6 * (b - a).length());
        let lift = DVec3::Z * (1e-3 * (k % 7) as f64);
        tris.push(triangle([a + lift, b + lift, a + side + lift]));
    }
    for k in 0..5_000 {
        let (a, b) = (p(0.0), p(0.0));
        let c = if k % 2 == 0 { a.lerp(b, 0.25) } else { a };
        tris.push(triangle([a, b, c]));
    }
    tris
}

/// 100,000 overlapping triangles and slivers: the BVH builds, and the
/// intersect kernel's closest hit agrees with brute force on 3,000 rays:
/// the same distance within 1e-6 relative (or four ulps of the ray origin's
/// largest coordinate, for the hits closest to the origin), and either the same triangle or
/// one the brute force hits at that same distance (a tie: identical copies
/// and coplanar triangles are hit at equal t). No ray hits a zero-area
/// triangle.
#[test]
fn overlapping_and_sliver_triangles_agree_with_brute_force() {
    let ctx = context();
    let mut rng = Rng(0x0051_17e5);
    let triangles = overlapping_triangles(&mut rng);
    let zero_area = triangles.len() - 5_000..triangles.len();
    let mut rays = Vec::new();
    for k in 0..3_000 {
        let target = DVec3::new(
            rng.range(-0.1, 1.1),
            rng.range(-0.1, 1.1),
            rng.range(-0.02, 0.02),
        );
        let o = if k % 10 == 0 {
            // Grazing: nearly in the plane
            target
                + DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    1e-3 * rng.range(-1.0, 1.0),
                ) * 3.0
        } else {
            target + rng.unit() * rng.range(0.5, 3.0)
        };
        rays.push(ray_to(o, target));
    }
    let scene = primitives_scene(Vec::new(), triangles, rays.len());
    let mut renderer = Renderer::new(&ctx, &scene, &options(rays.len() as u32)).expect("renderer");
    let info = renderer.scene_info.clone();
    let gpu = renderer.intersect_rays(&rays).expect("intersect");
    assert_eq!(ctx.validation_errors(), 0);

    let cpu: Vec<_> = rays
        .par_iter()
        .map(|&ray| brute_force::closest_hit(&scene, ray))
        .collect();
    let (mut hits, mut ties, mut wrong) = (0usize, 0usize, Vec::new());
    for ((&ray, g), &cpu) in rays.iter().zip(&gpu).zip(&cpu) {
        let agree = match (cpu, g) {
            (None, None) => true,
            (Some(KernelHit { prim, t }), Some(g)) => {
                hits += 1;
                // Within 1e-6 relative, or within a few ulps of the origin's
                // coordinates, which bound how well any f32 arithmetic can
                // place the hit: a GPU rounds the kernel's plane distance
                // (for far origins) otherwise than the CPU (NVIDIA H200: 3 of
                // 2,668 hits at t < 3e-4 differed by 3e-9 to 8e-8, origins
                // of size about 1)
                let origin_ulps = 4.0 * f32::EPSILON * ray.0.abs().max_element();
                let close =
                    |a: f32, b: f32| (a - b).abs() <= 1e-6 * a.abs().max(b.abs()) + origin_ulps;
                // A tie: the brute force hits the kernel's triangle at the same t
                let tie = g.prim != prim && {
                    let p = scene.triangles[g.prim as usize].p;
                    let (o, d, tmax) = ray;
                    intersect_triangle(&Ray { o, d, tmax }, p[0], p[1], p[2])
                        .is_some_and(|h| close(h.t, t))
                };
                ties += usize::from(tie);
                close(g.t, t) && (g.prim == prim || tie) && !zero_area.contains(&(g.prim as usize))
            }
            _ => false,
        };
        if !agree {
            wrong.push((ray, cpu, *g));
        }
    }
    println!(
        "overlapping: {} triangles, BVH of {} nodes (depth {}, SAH cost {:.1}) built in {:.3} s; \
         {} rays, {hits} hits ({ties} ties at an equal distance), {} disagree",
        scene.triangles.len(),
        info.bvh_nodes,
        info.bvh_depth,
        info.bvh_sah_cost,
        info.bvh_seconds,
        rays.len(),
        wrong.len()
    );
    assert!(hits > 2_000, "too few hits");
    assert_empty(&wrong, "kernel and brute force disagree");
}

/// Issue 18 §8, the white furnace's zero samples at 8K: a camera ray that
/// grazes a sphere from outside meets its outside, even where the rounded
/// normal at the hit turns away from the ray. The side had been the sign of
/// dot(n, d), which rounding flipped for about half of the rays within a
/// few ulps of tangent: the path then scattered into the sphere, stayed
/// inside it and came back black (2 pixels of a 7680 x 4320 furnace under
/// the Sobol sampler). Now the side is where the ray starts, as the
/// intersection chose its root. Rays from inside still meet the inside.
#[test]
fn rays_grazing_a_sphere_meet_the_side_they_come_from() {
    let ctx = context();
    let scene = load("tests/scenes/furnace.toml");
    let (c, r) = (
        scene.spheres[0].center.as_dvec3(),
        f64::from(scene.spheres[0].radius),
    );
    let mut rng = Rng(0x067a_21e5);
    let mut probes = Vec::new();
    let mut outside = Vec::new();
    for i in 0..16_000 {
        let d = DVec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5).normalize();
        let across = d
            .any_orthonormal_pair()
            .0
            .rotate_towards(d.any_orthonormal_pair().1, rng.next() * 6.3);
        // Tangent to within a few ulps of the radius, from far outside;
        // every tenth ray from inside, crossing the sphere's middle
        let from_outside = i % 10 != 0;
        let origin = if from_outside {
            let rho = r * (1.0 - (i % 16) as f64 * f64::from(f32::EPSILON) / 2.0);
            c + rho * across - 10.0 * d
        } else {
            c + 0.5 * r * rng.next() * across
        };
        let o = origin.as_vec3();
        probes.push(Probe {
            to_a: (o, d.as_vec3(), f32::MAX),
            leave: -d.as_vec3(),
            to_b: (o, d.as_vec3(), f32::MAX),
        });
        outside.push(from_outside);
    }
    let mut renderer =
        Renderer::new(&ctx, &scene, &options(probes.len() as u32)).expect("renderer");
    let results = renderer.probe_rays(&probes).expect("probe");
    assert_eq!(ctx.validation_errors(), 0);
    let (mut grazing, mut wrong) = (0usize, Vec::new());
    for ((probe, r), &from_outside) in probes.iter().zip(&results).zip(&outside) {
        if r.a.is_none() {
            continue;
        }
        grazing += usize::from(from_outside);
        if r.front != from_outside {
            wrong.push((probe.to_a, r.pa));
        }
    }
    println!(
        "{grazing} grazing hits from outside, {} on the wrong side",
        wrong.len()
    );
    assert!(
        grazing > 4000,
        "only {grazing} rays hit: the test grazes nothing"
    );
    assert!(
        wrong.is_empty(),
        "{} of {grazing} hits on the wrong side; the first (ray, hit): {:?}",
        wrong.len(),
        wrong[0]
    );
}
