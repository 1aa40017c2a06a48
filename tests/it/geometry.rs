//! Geometry and the structure of Mitsuba 3 scenes (docs/mitsuba.md): smooth
//! vertex normals computed as Mitsuba computes them (against Mitsuba's own
//! normals and a hand computation), the TOML switch, disks, flip_normals,
//! spheres under a non-uniform scale, scenes of version 2 and older,
//! `<path>` search folders, textures by `<ref>`, and the sides materials
//! scatter on: no light through a smooth-shaded closed mesh, no NaN, and
//! both schedules bit for bit. (The z-tests against Mitsuba are in
//! tests/it/reference.rs.)

use crate::common;

use common::reference;
use common::*;
use glam::Vec3;
use lancer::render::kernels::{Features, Integrator, Schedule};
use lancer::render::RenderOptions;
use lancer::scene::{load_str, MaterialKind, Scene, Sides};
use std::path::Path;

/// The lines every XML case starts with (the body starts on line 6).
const HEAD: &str = r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>"#;

/// A scene of `HEAD`, then `body` (line 6), read as `tests/scenes/mitsuba/case.xml`.
fn xml(body: &str) -> Result<Scene, String> {
    let text = format!("{HEAD}\n  {body}\n</scene>\n");
    load_str(&text, &repo("tests/scenes/mitsuba/case.xml")).map_err(|e| e.to_string())
}

fn xml_ok(body: &str) -> Scene {
    xml(body).unwrap_or_else(|e| panic!("{e}\n{body}"))
}

/// The message of a scene that must not load, with the repo's path cut off.
fn xml_err(body: &str) -> String {
    match xml(body) {
        Ok(_) => panic!("loaded: {body}"),
        Err(e) => e.replace(concat!(env!("CARGO_MANIFEST_DIR"), "/"), ""),
    }
}

/// Mitsuba 3.9.1's vertex normals of `tests/scenes/meshes/smooth_seam.obj`
/// under the transform of [`SEAM_TRANSFORM`], per corner of its six
/// triangles, read once with `mi.load_file` and `mi.traverse(shape)`
/// (`faces`, `vertex_normals`), scalar_rgb variant.
const MITSUBA_SEAM_NORMALS: [[[f64; 3]; 3]; 6] = [
    [
        [-0.0837021, -0.2837460, 0.9552393],
        [0.2872986, -0.4948595, 0.8201059],
        [0.1102852, -0.0785602, 0.9907904],
    ],
    [
        [-0.0837021, -0.2837460, 0.9552393],
        [0.1102852, -0.0785602, 0.9907904],
        [-0.2761070, -0.3867176, 0.8798946],
    ],
    [
        [-0.0837021, -0.2837460, 0.9552393],
        [-0.2761070, -0.3867176, 0.8798946],
        [-0.0976788, -0.7861213, 0.6103050],
    ],
    [
        [0.1738165, -0.7946365, 0.5816706],
        [-0.0976788, -0.7861213, 0.6103050],
        [0.2443954, -0.6966182, 0.6745325],
    ],
    [
        [0.1738165, -0.7946365, 0.5816706],
        [0.2443954, -0.6966182, 0.6745325],
        [0.2822162, -0.6332981, 0.7206160],
    ],
    [
        [-0.0837021, -0.2837460, 0.9552393],
        [0.2822162, -0.6332981, 0.7206160],
        [0.2872986, -0.4948595, 0.8201059],
    ],
];

/// The `to_world` the Mitsuba normals above were read under: a non-uniform
/// scale (which changes the angles, so the normals are computed in world
/// space), a rotation and a translation.
const SEAM_TRANSFORM: &str = r#"<transform name="to_world"><scale x="2" y="1" z="0.5"/><rotate x="1" angle="30"/><translate x="1" y="2" z="3"/></transform>"#;

#[test]
fn smooth_obj_normals_match_mitsuba() {
    // Corners with the same `v` and another `vt` are other vertices (the
    // texture seam is a crease), groups share vertices, the quad is split
    // into a fan, and faces weigh by their angle at the vertex.
    let s = xml_ok(&format!(
        r#"<shape type="obj"><string name="filename" value="../meshes/smooth_seam.obj"/>{SEAM_TRANSFORM}</shape>"#
    ));
    assert_eq!(s.triangles.len(), MITSUBA_SEAM_NORMALS.len());
    let mut worst = 0f32;
    for (t, expected) in s.triangles.iter().zip(&MITSUBA_SEAM_NORMALS) {
        let n = t.n.expect("smooth normals");
        for (got, want) in n.iter().zip(expected) {
            worst = worst.max((got.as_dvec3() - glam::DVec3::from_array(*want)).length() as f32);
        }
    }
    println!("largest difference from Mitsuba's normals: {worst:e}");
    assert!(worst < 2e-6, "{worst}");
    // Without the seam (one vertex per `v`), the first corner of the first
    // and the fourth triangle would share a normal; in Mitsuba they do not.
    assert!((s.triangles[0].n.unwrap()[0] - s.triangles[3].n.unwrap()[0]).length() > 0.1);
}

#[test]
fn smooth_ply_normals_of_a_cube_are_its_corner_diagonals() {
    // Hand computation: at each corner of the cube three faces meet at
    // right angles, and a face's triangles there add up to the angle pi/2
    // whichever way its diagonal runs: the normal is (+-1, +-1, +-1) / sqrt 3.
    let s = xml_ok(
        r#"<shape type="ply"><string name="filename" value="../meshes/tri_cube.ply"/></shape>"#,
    );
    assert_eq!(s.triangles.len(), 12);
    for t in &s.triangles {
        for (p, n) in t.p.iter().zip(t.n.expect("smooth normals")) {
            let want = p.signum() / 3f32.sqrt();
            assert!((n - want).length() < 1e-6, "{p} {n}");
        }
    }
    // face_normals = true: flat, as in Mitsuba.
    let flat = xml_ok(
        r#"<shape type="ply"><string name="filename" value="../meshes/tri_cube.ply"/><boolean name="face_normals" value="true"/></shape>"#,
    );
    assert!(flat.triangles.iter().all(|t| t.n.is_none()));
}

#[test]
fn toml_smooth_normals_switch_gives_the_same_normals_as_the_xml() {
    let toml = |extra: &str| {
        let text = format!(
            "{}[materials.white]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
             [[objects]]\ntype = \"mesh\"\nfile = \"meshes/lowpoly_sphere.obj\"\nmaterial = \"white\"\n\
             scale = [1.2, 1, 1]\n{extra}",
            scene_header((8, 8), 1, 4, "eye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40", "[0, 0, 0]")
        );
        load_inline(&text).unwrap_or_else(|e| panic!("{e}"))
    };
    // The contract's default: the geometric normal.
    assert!(toml("").triangles.iter().all(|t| t.n.is_none()));
    assert!(toml("smooth_normals = false\n")
        .triangles
        .iter()
        .all(|t| t.n.is_none()));
    let smooth = toml("smooth_normals = true\n");
    let from_xml = xml_ok(
        r#"<shape type="obj"><string name="filename" value="../meshes/lowpoly_sphere.obj"/><transform name="to_world"><scale x="1.2" y="1" z="1"/></transform></shape>"#,
    );
    let normals =
        |s: &Scene| -> Vec<[Vec3; 3]> { s.triangles.iter().map(|t| t.n.unwrap()).collect() };
    assert_eq!(normals(&smooth), normals(&from_xml));
    // Smooth normals of a sphere scaled by (1.2, 1, 1) lean towards its
    // outward normal (x / 1.44, y, z), and are unit vectors.
    for t in &smooth.triangles {
        for (p, n) in t.p.iter().zip(t.n.unwrap()) {
            let ellipsoid = Vec3::new(p.x / 1.44, p.y, p.z).normalize();
            assert!((n.length() - 1.0).abs() < 1e-6);
            assert!(n.dot(ellipsoid) > 0.97, "{p} {n}");
        }
    }
    let bad = load_inline(&format!(
        "{}[materials.white]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"meshes/lowpoly_sphere.obj\"\nmaterial = \"white\"\nsmooth_normals = 1\n",
        scene_header((8, 8), 1, 4, "eye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40", "[0, 0, 0]")
    ))
    .unwrap_err();
    assert!(
        bad.ends_with("objects[0].smooth_normals: expected true or false, got an integer 1"),
        "{bad}"
    );
}

#[test]
fn disk_is_the_unit_disk_with_its_area_and_front_side() {
    let s = xml_ok(
        r#"<shape type="disk"><transform name="to_world"><scale x="2" y="0.5" z="1"/><translate z="1"/></transform></shape>"#,
    );
    let area: f64 = s
        .triangles
        .iter()
        .map(|t| 0.5 * ((t.p[1] - t.p[0]).cross(t.p[2] - t.p[0])).length() as f64)
        .sum();
    // An ellipse of half-axes 2 and 0.5: area pi.
    let rel = area / std::f64::consts::PI - 1.0;
    println!("disk area relative error {rel:e}");
    assert!(rel.abs() < 1e-6, "{rel}");
    for t in &s.triangles {
        let n = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
        assert!(n.z > 0.0 && t.p.iter().all(|p| p.z == 1.0));
        // The centre, or on the ellipse to 6e-5 of its size.
        for p in t.p {
            let r = ((p.x / 2.0).powi(2) + (p.y / 0.5).powi(2)).sqrt();
            assert!(r == 0.0 || (r - 1.0).abs() < 6e-5, "{r}");
        }
    }
    // flip_normals turns the front side to -z.
    let flipped =
        xml_ok(r#"<shape type="disk"><boolean name="flip_normals" value="true"/></shape>"#);
    for t in &flipped.triangles {
        assert!((t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).z < 0.0);
    }
}

#[test]
fn flip_normals_reverses_meshes_and_refuses_what_a_sphere_cannot_do() {
    let plain = xml_ok(
        r#"<shape type="ply"><string name="filename" value="../meshes/tri_cube.ply"/></shape>"#,
    );
    let flipped = xml_ok(
        r#"<shape type="ply"><string name="filename" value="../meshes/tri_cube.ply"/><boolean name="flip_normals" value="true"/></shape>"#,
    );
    for (a, b) in plain.triangles.iter().zip(&flipped.triangles) {
        assert_eq!([a.p[0], a.p[2], a.p[1]], b.p);
        let (na, nb) = (a.n.unwrap(), b.n.unwrap());
        assert_eq!([-na[0], -na[2], -na[1]], nb);
    }
    // A twosided, dark sphere looks the same inside out.
    let s = xml_ok(
        r#"<shape type="sphere"><boolean name="flip_normals" value="true"/><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>"#,
    );
    assert_eq!(s.spheres.len(), 1);
    assert_eq!(
        xml_err(r#"<shape type="sphere"><boolean name="flip_normals" value="true"/></shape>"#),
        "tests/scenes/mitsuba/case.xml:6: <shape type=\"sphere\">: property `flip_normals` (or a mirroring to_world) turns the sphere's front side inward, which lancer's spheres cannot do for a one-sided, emitting or dielectric material; use a twosided BSDF without an emitter, or a sphere mesh (obj/ply) with flip_normals"
    );
}

#[test]
fn sphere_under_a_non_uniform_scale_is_round_as_in_mitsuba() {
    // Mitsuba warns and takes the radius from to_world * (1, 0, 0).
    let s = xml_ok(
        r#"<shape type="sphere"><float name="radius" value="0.5"/><transform name="to_world"><scale x="3" y="1" z="2"/><translate y="1"/></transform></shape>"#,
    );
    assert_eq!(s.spheres[0].radius, 1.5);
    assert_eq!(s.spheres[0].center, Vec3::new(0.0, 1.0, 0.0));
    assert_eq!(s.warnings.len(), 1);
    assert!(
        s.warnings[0].ends_with(
            "case.xml:6: property `to_world` of <shape type=\"sphere\"> scales non-uniformly or shears: Mitsuba warns and renders a round sphere of radius |to_world * (1, 0, 0)| = 1.5, and so does lancer; use an obj or ply mesh for an ellipsoid"
        ),
        "{}",
        s.warnings[0]
    );
}

#[test]
fn old_scene_versions_load_with_mitsubas_upgrade_of_names() {
    let text = |version: &str, body: &str| {
        format!(
            "<scene version=\"{version}\">\n  <sensor type=\"perspective\">\n    <float name=\"fov\" value=\"40\"/>\n    \
             <sampler type=\"independent\"><integer name=\"sampleCount\" value=\"9\"/></sampler>\n    \
             <film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/><integer name=\"height\" value=\"8\"/></film>\n  \
             </sensor>\n  {body}\n</scene>\n"
        )
    };
    let body = r#"<shape type="sphere"><bsdf type="diffuse"><rgb name="diffuseReflectance" value="0.25"/></bsdf></shape>
  <shape type="sphere"><bsdf type="dielectric"><float name="intIOR" value="1.5"/><float name="extIOR" value="1"/></bsdf></shape>"#;
    for version in ["0.5.0", "1.9.9"] {
        let s =
            load_str(&text(version, body), Path::new("old.xml")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(s.render.spp, 9);
        assert_eq!(
            s.materials[0].kind,
            MaterialKind::Lambert {
                albedo: lancer::scene::ColorSource::Constant(Vec3::splat(0.25))
            }
        );
        assert_eq!(
            s.materials[1].kind,
            MaterialKind::Dielectric {
                ior: 1.5,
                tint: Vec3::ONE
            }
        );
    }
    // From 2.0.0 on, names are read as written: camelCase is unknown.
    let err = load_str(&text("2.0.0", body), Path::new("new.xml"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "new.xml:4: <integer name=\"sampleCount\">: property `sampleCount` of <sampler type=\"independent\"> is outside the subset lancer reads (docs/mitsuba.md); remove it"
    );
    let ok_v2 = load_str(
        &text("2.1.0", "<shape type=\"sphere\"/>").replace("sampleCount", "sample_count"),
        Path::new("v2.xml"),
    );
    assert!(ok_v2.is_ok(), "{ok_v2:?}");
}

#[test]
fn path_folders_are_searched_before_the_scene_folder() {
    let dir = scratch("path_folders");
    for folder in ["scenes", "common/meshes", "other/meshes", "scenes/meshes"] {
        std::fs::create_dir_all(dir.join(folder)).unwrap();
    }
    let tri = |z: f32| format!("v 0 0 {z}\nv 1 0 {z}\nv 0 1 {z}\nf 1 2 3\n");
    // The same name in three places: the last <path> wins, then the first,
    // then the scene's folder.
    std::fs::write(dir.join("common/meshes/a.obj"), tri(1.0)).unwrap();
    std::fs::write(dir.join("other/meshes/a.obj"), tri(2.0)).unwrap();
    std::fs::write(dir.join("scenes/meshes/a.obj"), tri(3.0)).unwrap();
    std::fs::write(dir.join("scenes/meshes/b.obj"), tri(4.0)).unwrap();
    let scene = |paths: &str| {
        let text = format!(
            "<scene version=\"2.0.0\">\n  {paths}\n  <sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/></sensor>\n  \
             <shape type=\"obj\"><string name=\"filename\" value=\"meshes/a.obj\"/></shape>\n  \
             <shape type=\"obj\"><string name=\"filename\" value=\"meshes/b.obj\"/></shape>\n</scene>\n"
        );
        let path = dir.join("scenes/scene.xml");
        std::fs::write(&path, text).unwrap();
        lancer::scene::load(&path).map_err(|e| e.to_string())
    };
    let z = |s: &Scene| -> Vec<f32> { s.triangles.iter().map(|t| t.p[0].z).collect() };
    assert_eq!(z(&scene("").unwrap()), [3.0, 4.0]);
    assert_eq!(
        z(&scene(r#"<path value="../common"/>"#).unwrap()),
        [1.0, 4.0]
    );
    assert_eq!(
        z(&scene(r#"<path value="../common"/><path value="../other"/>"#).unwrap()),
        [2.0, 4.0]
    );
    let err = scene(r#"<path value="../nowhere"/>"#).unwrap_err();
    let shown = dir.join("scenes/scene.xml");
    assert_eq!(
        err,
        format!(
            "{}:2: <path>: attribute `value`: folder {} not found (a <path> is relative to the scene file)",
            shown.display(),
            dir.join("scenes/../nowhere").display()
        )
    );
}

#[test]
fn textures_and_bsdfs_by_ref() {
    let checker = "../../../scenes/tex/checker.png";
    let s = xml_ok(&format!(
        r#"<texture type="bitmap" id="tex"><string name="filename" value="{checker}"/></texture>
  <shape type="sphere"><bsdf type="diffuse" id="inner"><ref name="reflectance" id="tex"/></bsdf></shape>
  <shape type="sphere"><ref id="inner"/></shape>"#
    ));
    let MaterialKind::Lambert {
        albedo: lancer::scene::ColorSource::Texture(path),
    } = &s.materials[0].kind
    else {
        panic!("{:?}", s.materials[0]);
    };
    assert!(
        path.ends_with("scenes/tex/checker.png"),
        "{}",
        path.display()
    );
    // The nested <bsdf id> is one material, used twice.
    assert_eq!((s.spheres[0].material, s.spheres[1].material), (0, 0));
    assert_eq!(
        xml_err(r#"<shape type="sphere"><bsdf type="diffuse"><ref name="reflectance" id="nope"/></bsdf></shape>"#),
        "tests/scenes/mitsuba/case.xml:6: <ref name=\"reflectance\" id=\"nope\">: attribute `id`: no <texture id=\"nope\"> in the scene; defined: none"
    );
    assert_eq!(
        xml_err(
            r#"<bsdf type="diffuse" id="d"/>
  <shape type="sphere"><bsdf type="diffuse"><ref name="reflectance" id="d"/></bsdf></shape>"#
        ),
        "tests/scenes/mitsuba/case.xml:7: <ref name=\"reflectance\" id=\"d\">: attribute `id`: \"d\" is a <bsdf> (line 6), where a <texture> is expected"
    );
    assert_eq!(
        xml_err(
            r#"<texture type="bitmap" id="t"><string name="filename" value="x.png"/></texture>
  <shape type="sphere"><bsdf type="diffuse" id="t"/></shape>"#
        ),
        "tests/scenes/mitsuba/case.xml:7: <bsdf type=\"diffuse\" id=\"t\">: attribute `id`: a second <bsdf>, <texture>, <sampler>, area <emitter> or shapegroup with this id; ids must be unique"
    );
    assert_eq!(
        xml_err(r#"<texture type="bitmap"><string name="filename" value="x.png"/></texture>"#),
        "tests/scenes/mitsuba/case.xml:6: <texture type=\"bitmap\">: a top-level <texture> needs an `id` for <ref id=\"...\"/>"
    );
}

#[test]
fn sides_of_xml_and_toml_materials_and_their_features() {
    let s = load("tests/scenes/mitsuba/one_sided.xml");
    let sides: Vec<Sides> = s.materials.iter().map(|m| m.sides).collect();
    assert_eq!(
        sides,
        [Sides::Front, Sides::Shading, Sides::Front, Sides::Front]
    );
    assert!(Features::detect(&s, Integrator::Nee).shading_sides);
    // Every TOML scene of the project keeps lancer's rule, and so its kernels.
    for file in example_and_test_scenes() {
        let scene = load(&file);
        assert!(
            scene.materials.iter().all(|m| m.sides == Sides::Both),
            "{file}"
        );
        assert!(
            !Features::detect(&scene, Integrator::Nee).shading_sides,
            "{file}"
        );
    }
    // TOML can ask for either of Mitsuba's rules.
    let text =
        format!(
        "{}[materials.front]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\nsides = \"front\"\n\
         [materials.bad]\ntype = \"mirror\"\nreflectance = [1, 1, 1]\nsides = \"back\"\n",
        scene_header((8, 8), 1, 4, "eye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40", "[0, 0, 0]")
    );
    let err = load_inline(&text).unwrap_err();
    assert!(
        err.ends_with(
            "materials.bad.sides: expected \"both\", \"shading\" or \"front\", got \"back\""
        ),
        "{err}"
    );
}

/// Renders `scene` small with `schedule`.
fn render_small(scene: &Scene, schedule: Schedule, spp: u32) -> lancer::render::RenderOutput {
    let mut scene = scene.clone();
    (scene.render.width, scene.render.height, scene.render.spp) = (32, 32, spp);
    let ctx = context();
    render(
        &ctx,
        &scene,
        &RenderOptions {
            schedule,
            ..options(1 << 14)
        },
    )
}

#[test]
fn one_sided_panels_are_black_from_behind_and_schedules_agree() {
    let s = load("tests/scenes/mitsuba/one_sided.xml");
    let a = render_small(&s, Schedule::Wavefront, 16);
    let b = render_small(&s, Schedule::Megakernel, 16);
    let ctx = context();
    for (x, y) in [(&a.mean, &b.mean), (&a.var_of_mean, &b.var_of_mean)] {
        assert_eq!(kernels_disagree(&ctx, x, y), None);
    }
    // The plain diffuse panel facing away (upper right) is black: the
    // pixel at its centre sees it from behind. The one facing the camera
    // (upper left) is lit.
    let px = |x: usize, y: usize| Vec3::from_slice(&a.mean[3 * (y * 32 + x)..]);
    let (left, right) = (px(9, 7), px(22, 7));
    println!("upper left {left}, upper right {right}");
    assert!(left.min_element() > 0.05, "{left}");
    assert_eq!(right, Vec3::ZERO);
}

#[test]
fn no_light_passes_through_a_smooth_shaded_closed_mesh() {
    // A camera inside a closed, coarse, smooth-shaded sphere mesh, lit only
    // by the environment outside: every pixel must stay exactly black,
    // under each of the three rules for sides (shading normals bend up to
    // 20 degrees from the facets here, so directions sampled around them
    // often point through the surface). Outside, in a furnace of
    // radiance 1, an albedo of 0.8 gives no pixel above 1.
    for sides in Sides::ALL {
        let inside = format!(
            "{}[materials.white]\ntype = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]\nsides = \"{}\"\n\
             [[objects]]\ntype = \"mesh\"\nfile = \"meshes/lowpoly_sphere.obj\"\nmaterial = \"white\"\nsmooth_normals = true\nscale = 3\n",
            scene_header((32, 32), 64, 16, "eye = [0.3, 0.2, 0.5]\nlook_at = [1, 0, -1]\nvfov = 100", "[1, 1, 1]"),
            sides.name()
        );
        let scene = load_inline(&inside).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.triangles.iter().all(|t| t.n.is_some()));
        let out = render_small(&scene, Schedule::Wavefront, 64);
        let max = out.mean.iter().fold(0f32, |m, &v| m.max(v));
        println!("{}: inside, largest pixel {max}", sides.name());
        assert_eq!(max, 0.0, "light leaked in ({})", sides.name());

        let outside = inside.replace(
            "eye = [0.3, 0.2, 0.5]\nlook_at = [1, 0, -1]\nvfov = 100",
            "eye = [0, 0, 12]\nlook_at = [0, 0, 0]\nvfov = 35",
        );
        let scene = load_inline(&outside).unwrap_or_else(|e| panic!("{e}"));
        let out = render_small(&scene, Schedule::Wavefront, 64);
        let max = out.mean.iter().fold(0f32, |m, &v| m.max(v));
        let min = out.mean.iter().fold(f32::MAX, |m, &v| m.min(v));
        println!("{}: furnace, pixels from {min} to {max}", sides.name());
        assert!(max <= 1.0 + 1e-6 && min > 0.0, "{min} {max}");
    }
}

/// Renders `tests/scenes/mitsuba/{name}.xml` at its reference's size with
/// `spp`, z-tests it against Mitsuba's `tests/reference/xml/{name}`, checks
/// that a mirrored image and a 5% brighter light fail, and returns the
/// scene for further checks.
fn xml_matches_mitsuba(name: &str, spp: u32) -> (Scene, reference::Estimate) {
    let reference = reference::reference(&format!("xml/{name}"));
    let mut scene = load(&format!("tests/scenes/mitsuba/{name}.xml"));
    scene.render.width = reference.width as u32;
    scene.render.height = reference.height as u32;
    scene.render.spp = spp;
    let ctx = context();
    let out = reference::estimate(&render(&ctx, &scene, &options(1 << 18)));
    reference::assert_matches(name, &out, &reference);
    reference::assert_wrong_images_fail(name, &out, &reference);
    (scene, reference)
}

/// Asserts that `scene`, rendered, fails the z-test against `reference`.
fn assert_fails(label: &str, scene: &Scene, reference: &reference::Estimate) {
    let ctx = context();
    let out = reference::estimate(&render(&ctx, scene, &options(1 << 18)));
    let (z, _) = reference::compare(&out, reference);
    println!("{label}: {z}");
    assert!(!reference::passes(&z), "{label} passed: {z}");
}

/// A coarse OBJ sphere and a PLY cube without normals, smooth-shaded by
/// Mitsuba's rule; the same meshes shaded flat must fail.
#[test]
fn smooth_meshes_match_mitsuba() {
    let (mut scene, reference) = xml_matches_mitsuba("smooth_mesh", 1024);
    for t in &mut scene.triangles {
        t.n = None;
    }
    assert_fails("smooth_mesh shaded flat", &scene, &reference);
}

/// An emitting disk and an elliptic disk (non-uniform scale).
#[test]
fn disks_match_mitsuba() {
    xml_matches_mitsuba("disk", 1024);
}

/// Plain diffuse and conductor panels seen from behind are black, twosided
/// ones are not; with lancer's two-sided rule the image must fail.
#[test]
fn one_sided_materials_match_mitsuba() {
    let (mut scene, reference) = xml_matches_mitsuba("one_sided", 1024);
    for m in &mut scene.materials {
        m.sides = Sides::Both;
    }
    assert_fails("one_sided shaded on both sides", &scene, &reference);
}

#[test]
fn rotate_axis_is_not_normalised_as_in_mitsuba() {
    // Mitsuba builds the rotation from the axis as written: (0, 1, 1) also
    // scales. Its matrix for 15 degrees (ScalarTransform4f().rotate), by
    // columns, read once from Mitsuba 3.9.1.
    let mitsuba = [
        Vec3::new(0.965926, 0.258819, -0.258819),
        Vec3::new(-0.258819, 1.0, 0.0340742),
        Vec3::new(0.258819, 0.0340742, 1.0),
    ];
    let s = xml_ok(
        r#"<shape type="rectangle"><transform name="to_world"><rotate x="0" y="1" z="1" angle="15"/></transform></shape>"#,
    );
    // The rectangle's corners (+-1, +-1, 0) go to +-col0 +- col1.
    for t in &s.triangles {
        for p in t.p {
            let found = [-1.0f32, 1.0].iter().any(|&a| {
                [-1.0f32, 1.0]
                    .iter()
                    .any(|&b| (p - (a * mitsuba[0] + b * mitsuba[1])).length() < 1e-6)
            });
            assert!(found, "{p}");
        }
    }
}
