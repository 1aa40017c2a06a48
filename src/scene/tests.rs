//! Scene loader tests: one per bad-scene case (exact messages), and the good
//! cases of docs/scene-format.md. Fixtures live in `tests/scenes/` and
//! `tests/bad_scenes/`.

use super::*;
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

/// The repository root, whether this file is compiled as `src/scene/tests.rs`
/// of the crate (relative `file!()`) or by absolute path from elsewhere.
fn repo_root() -> PathBuf {
    let here = Path::new(file!());
    let root = here
        .parent()
        .and_then(Path::parent)
        .and_then(Path::parent)
        .unwrap_or(Path::new(""));
    if root.is_absolute() {
        root.to_path_buf()
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(root)
    }
}

fn fixture(rel: &str) -> PathBuf {
    repo_root().join("tests").join(rel)
}

/// The error of loading a fixture, and its path.
fn bad_file(rel: &str) -> (String, String) {
    let path = fixture(rel);
    let err = load(&path).expect_err("scene should be rejected");
    (path.display().to_string(), err.to_string())
}

/// Lines 1-8: a minimal valid scene; its [camera] table is still open.
const BASE: &str = "[render]
width = 4
height = 4
spp = 1
[camera]
eye = [0, 0, 5]
look_at = [0, 0, 0]
vfov = 40
";

fn with(extra: &str) -> String {
    format!("{BASE}{extra}")
}

fn replaced(from: &str, to: &str) -> String {
    assert!(BASE.contains(from), "{from}");
    BASE.replace(from, to)
}

/// Loads text as `t.toml` in the fixtures folder.
fn load_all(text: &str) -> Result<Scene, SceneError> {
    load_str(text, Path::new("t.toml"))
}

fn err(text: &str) -> String {
    match load_all(text) {
        Ok(_) => panic!("scene should be rejected:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn ok(text: &str) -> Scene {
    load_all(text).unwrap_or_else(|e| panic!("{e}"))
}

/// Loads text placed in `tests/scenes/` (so `meshes/...` resolves).
fn in_scenes(text: &str) -> Result<Scene, SceneError> {
    load_str(text, &fixture("scenes/inline.toml"))
}

macro_rules! bad {
    ($name:ident, $text:expr, $expected:expr) => {
        #[test]
        fn $name() {
            assert_eq!(err(&$text), $expected);
        }
    };
}

// ---------------------------------------------------------------- files --

#[test]
fn file_unknown_top_level_key() {
    let (p, e) = bad_file("bad_scenes/unknown_top_key.toml");
    assert_eq!(
        e,
        format!(
            "{p}:12: lamps: unknown key `lamps` at the top level; \
             expected one of: render, camera, environment, materials, objects, lights"
        )
    );
}

#[test]
fn file_unknown_nested_key() {
    let (p, e) = bad_file("bad_scenes/unknown_camera_key.toml");
    assert_eq!(
        e,
        format!(
            "{p}:11: camera.fov: unknown key `fov` in [camera]; expected one of: eye, \
             look_at, up, vfov, aperture_radius, focus_distance, near_clip, far_clip (did you mean `vfov`?)"
        )
    );
}

#[test]
fn file_wrong_type() {
    let (p, e) = bad_file("bad_scenes/wrong_type.toml");
    assert_eq!(
        e,
        format!("{p}:10: camera.vfov: expected a number, got a string \"40\"")
    );
}

#[test]
fn file_missing_required_key() {
    let (p, e) = bad_file("bad_scenes/missing_width.toml");
    assert_eq!(
        e,
        format!("{p}:2: render.width: missing required key in [render]: an integer >= 1")
    );
}

#[test]
fn file_negative_radius() {
    let (p, e) = bad_file("bad_scenes/negative_radius.toml");
    assert_eq!(e, format!("{p}:31: objects[2].radius: must be > 0, got -1"));
}

#[test]
fn file_colour_and_texture() {
    let (p, e) = bad_file("bad_scenes/colour_and_texture.toml");
    assert_eq!(
        e,
        format!(
            "{p}:15: materials.white.albedo_texture: `albedo` is also given (line 14); \
             a material gives a colour or a texture, not both: remove one"
        )
    );
}

#[test]
fn file_unknown_material() {
    let (p, e) = bad_file("bad_scenes/unknown_material.toml");
    assert_eq!(
        e,
        format!(
            "{p}:20: objects[0].material: no material named `glas`; defined materials: \
             glass (did you mean `glass`?)"
        )
    );
}

#[test]
fn file_missing_obj() {
    let (p, e) = bad_file("bad_scenes/missing_obj.toml");
    let obj = fixture("bad_scenes/meshes/no_such_mesh.obj");
    let prefix = format!(
        "{p}:18: objects[0].file: cannot read OBJ file {}: ",
        obj.display()
    );
    assert!(e.starts_with(&prefix), "{e}\n{prefix}");
}

#[test]
fn file_missing_texture() {
    let (p, e) = bad_file("bad_scenes/missing_texture.toml");
    let tex = fixture("bad_scenes/tex/no_such_texture.png");
    let prefix = format!(
        "{p}:14: materials.wood.albedo_texture: cannot read texture file {}: ",
        tex.display()
    );
    assert!(e.starts_with(&prefix), "{e}\n{prefix}");
}

#[test]
fn file_bad_scale() {
    let (p, e) = bad_file("bad_scenes/bad_scale.toml");
    assert_eq!(
        e,
        format!("{p}:20: objects[0].scale: every scale component must be > 0, got [1.0, 0.0, 1.0]")
    );
}

#[test]
fn file_syntax_error() {
    let (p, e) = bad_file("bad_scenes/syntax_error.toml");
    assert!(e.starts_with(&format!("{p}:11: invalid TOML: ")), "{e}");
}

#[test]
fn file_degenerate_camera() {
    let (p, e) = bad_file("bad_scenes/degenerate_camera.toml");
    assert_eq!(
        e,
        format!(
            "{p}:9: camera.look_at: equals camera.eye, so the camera has no direction to \
             look in; move look_at or eye"
        )
    );
}

#[test]
fn file_zero_area_quad() {
    let (p, e) = bad_file("bad_scenes/zero_area_quad.toml");
    assert_eq!(
        e,
        format!(
            "{p}:20: objects[0].edge_v: the quad has zero area: edge_u and edge_v must be \
             non-zero and not parallel"
        )
    );
}

#[test]
fn file_unknown_object_type() {
    let (p, e) = bad_file("bad_scenes/unknown_object_type.toml");
    assert_eq!(
        e,
        format!(
            "{p}:13: objects[0].type: unknown object type `cylinder`; expected one of: \
             sphere, quad, mesh"
        )
    );
}

#[test]
fn file_phong_energy() {
    let (p, e) = bad_file("bad_scenes/phong_energy.toml");
    assert_eq!(
        e,
        format!(
            "{p}:15: materials.plastic.specular: diffuse + specular must be <= 1 in every \
             channel (the material would create energy), got 0.7 + 0.4 = 1.1 in green; \
             lower diffuse or specular"
        )
    );
}

#[test]
fn missing_scene_file() {
    let path = fixture("bad_scenes/no_such_scene.toml");
    let e = load(&path).expect_err("missing").to_string();
    assert!(
        e.starts_with(&format!("{}: cannot read scene file: ", path.display())),
        "{e}"
    );
}

// --------------------------------------------------------------- render --

bad!(
    width_zero,
    replaced("width = 4", "width = 0"),
    "t.toml:2: render.width: must be >= 1, got 0"
);
bad!(
    height_zero,
    replaced("height = 4", "height = 0"),
    "t.toml:3: render.height: must be >= 1, got 0"
);
bad!(
    spp_zero,
    replaced("spp = 1", "spp = 0"),
    "t.toml:4: render.spp: must be >= 1, got 0"
);
bad!(
    max_depth_zero,
    replaced("spp = 1", "spp = 1\nmax_depth = 0"),
    "t.toml:5: render.max_depth: must be >= 1, got 0"
);
bad!(
    seed_negative,
    replaced("spp = 1", "spp = 1\nseed = -1"),
    "t.toml:5: render.seed: must be >= 0, got -1"
);
bad!(
    seed_too_large,
    replaced("spp = 1", "spp = 1\nseed = 4_294_967_296"),
    "t.toml:5: render.seed: must be <= 4294967295, got 4_294_967_296"
);
bad!(
    width_float,
    replaced("width = 4", "width = 4.0"),
    "t.toml:2: render.width: expected an integer, got a float 4.0"
);
bad!(
    render_not_a_table,
    "render = 5\n[camera]\n",
    "t.toml:1: render: expected a table [render], got an integer 5"
);
bad!(
    missing_render,
    "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40\n",
    "t.toml: render: missing required table [render] (with width, height and spp)"
);
bad!(
    unknown_render_key,
    replaced("spp = 1", "spp = 1\nsamples = 4"),
    "t.toml:5: render.samples: unknown key `samples` in [render]; expected one of: \
     width, height, spp, max_depth, seed, filter, rr_depth"
);

// --------------------------------------------------------------- camera --

bad!(
    missing_camera,
    "[render]\nwidth = 4\nheight = 4\nspp = 1\n",
    "t.toml: camera: missing required table [camera] (with eye, look_at and vfov)"
);
bad!(
    missing_vfov,
    replaced("vfov = 40\n", ""),
    "t.toml:5: camera.vfov: missing required key in [camera]: a number of degrees, \
     0 < vfov < 180"
);
bad!(
    vfov_zero,
    replaced("vfov = 40", "vfov = 0"),
    "t.toml:8: camera.vfov: must be > 0 and < 180 (degrees), got 0"
);
bad!(
    vfov_180,
    replaced("vfov = 40", "vfov = 180.0"),
    "t.toml:8: camera.vfov: must be > 0 and < 180 (degrees), got 180.0"
);
bad!(
    vfov_nan,
    replaced("vfov = 40", "vfov = nan"),
    "t.toml:8: camera.vfov: must be a finite number, got nan"
);
bad!(
    aperture_negative,
    with("aperture_radius = -0.1\n"),
    "t.toml:9: camera.aperture_radius: must be >= 0, got -0.1"
);
bad!(
    focus_distance_zero,
    with("focus_distance = 0\n"),
    "t.toml:9: camera.focus_distance: must be > 0, got 0"
);
bad!(
    eye_two_numbers,
    replaced("eye = [0, 0, 5]", "eye = [0, 5]"),
    "t.toml:6: camera.eye: expected 3 numbers [x, y, z], got 2 values [0, 5]"
);
bad!(
    eye_element_wrong_type,
    replaced("eye = [0, 0, 5]", "eye = [0, \"up\", 5]"),
    "t.toml:6: camera.eye[1]: expected a number, got a string \"up\""
);
bad!(
    eye_not_an_array,
    replaced("eye = [0, 0, 5]", "eye = 5"),
    "t.toml:6: camera.eye: expected an array of 3 numbers [x, y, z], got an integer 5"
);
bad!(
    eye_infinite,
    replaced("eye = [0, 0, 5]", "eye = [0, 0, inf]"),
    "t.toml:6: camera.eye[2]: must be a finite number, got inf"
);
bad!(
    default_up_parallel,
    replaced("eye = [0, 0, 5]", "eye = [0, 5, 0]"),
    "t.toml:5: camera.up: the default up [0, 1, 0] is parallel to the view direction \
     (look_at - eye); set camera.up to a direction that is not, e.g. [0, 0, 1] or [1, 0, 0]"
);
bad!(
    up_parallel,
    with("up = [0, 0, -2]\n"),
    "t.toml:9: camera.up: camera.up is parallel to the view direction (look_at - eye); \
     set camera.up to a direction that is not, e.g. [0, 0, 1] or [1, 0, 0]"
);
bad!(
    up_zero,
    with("up = [0, 0, 0]\n"),
    "t.toml:9: camera.up: must not be [0, 0, 0]; give the direction that should point \
     up in the image"
);

// ---------------------------------------------------------- environment --

bad!(
    environment_negative,
    with("[environment]\nradiance = [-1, 0, 0]\n"),
    "t.toml:10: environment.radiance: colour components must be >= 0, got [-1, 0, 0]"
);
bad!(
    environment_unknown_key,
    with("[environment]\ncolor = [1, 0, 0]\n"),
    "t.toml:10: environment.color: unknown key `color` in [environment]; expected one \
     of: radiance"
);

// ------------------------------------------------------------ materials --

bad!(
    material_unknown_type,
    with("[materials.m]\ntype = \"lambertian\"\n"),
    "t.toml:10: materials.m.type: unknown material type `lambertian`; expected one of: \
     lambert, phong, mirror, glossy, dielectric, conductor, roughconductor (did you mean \
     `lambert`?)"
);
bad!(
    material_missing_type,
    with("[materials.m]\nalbedo = [1, 1, 1]\n"),
    "t.toml:9: materials.m.type: missing required key in [materials.m]: one of lambert, \
     phong, mirror, glossy, dielectric, conductor, roughconductor"
);
bad!(
    material_key_of_other_type,
    with("[materials.m]\ntype = \"lambert\"\nalbedo = [1, 1, 1]\nior = 1.5\n"),
    "t.toml:12: materials.m.ior: unknown key `ior` in [materials.m] (a lambert material); \
     expected one of: type, albedo, albedo_texture, emission, sides"
);
bad!(
    material_not_a_table,
    with("[materials]\nm = 3\n"),
    "t.toml:10: materials.m: expected a table [materials.m], got an integer 3"
);
bad!(
    lambert_missing_albedo,
    with("[materials.m]\ntype = \"lambert\"\n"),
    "t.toml:9: materials.m.albedo: missing required key in [materials.m] (a lambert \
     material): give albedo = [r, g, b] or albedo_texture = \"file.png\""
);
bad!(
    albedo_negative,
    with("[materials.m]\ntype = \"lambert\"\nalbedo = [0.5, -0.1, 0.2]\n"),
    "t.toml:11: materials.m.albedo: colour components must be >= 0, got [0.5, -0.1, 0.2]"
);
bad!(
    albedo_wrong_type,
    with("[materials.m]\ntype = \"lambert\"\nalbedo = \"white\"\n"),
    "t.toml:11: materials.m.albedo: expected a colour [r, g, b], got a string \"white\""
);
bad!(
    emission_infinite,
    with("[materials.m]\ntype = \"lambert\"\nalbedo = [1, 1, 1]\nemission = [inf, 1, 1]\n"),
    "t.toml:12: materials.m.emission[0]: must be a finite number, got inf"
);
bad!(
    phong_exponent_negative,
    with(
        "[materials.m]\ntype = \"phong\"\ndiffuse = [0.5, 0.5, 0.5]\n\
         specular = [0.1, 0.1, 0.1]\nexponent = -1\n"
    ),
    "t.toml:13: materials.m.exponent: must be >= 0, got -1"
);
bad!(
    phong_missing_specular,
    with("[materials.m]\ntype = \"phong\"\ndiffuse = [0.5, 0.5, 0.5]\nexponent = 10\n"),
    "t.toml:9: materials.m.specular: missing required key in [materials.m] (a phong \
     material): a colour [r, g, b]"
);
bad!(
    mirror_missing_reflectance,
    with("[materials.m]\ntype = \"mirror\"\n"),
    "t.toml:9: materials.m.reflectance: missing required key in [materials.m] (a mirror \
     material): a colour [r, g, b]"
);
bad!(
    glossy_cone_90,
    with("[materials.m]\ntype = \"glossy\"\nreflectance = [1, 1, 1]\ncone_angle = 90\n"),
    "t.toml:12: materials.m.cone_angle: must be >= 0 and < 90 (degrees), got 90"
);
bad!(
    glossy_cone_negative,
    with("[materials.m]\ntype = \"glossy\"\nreflectance = [1, 1, 1]\ncone_angle = -1.5\n"),
    "t.toml:12: materials.m.cone_angle: must be >= 0 and < 90 (degrees), got -1.5"
);
bad!(
    glossy_missing_cone,
    with("[materials.m]\ntype = \"glossy\"\nreflectance = [1, 1, 1]\n"),
    "t.toml:9: materials.m.cone_angle: missing required key in [materials.m] (a glossy \
     material): a number of degrees, 0 <= cone_angle < 90"
);
bad!(
    dielectric_ior_zero,
    with("[materials.glass]\ntype = \"dielectric\"\nior = 0\n"),
    "t.toml:11: materials.glass.ior: must be > 0, got 0"
);
bad!(
    dielectric_tint_negative,
    with("[materials.glass]\ntype = \"dielectric\"\nior = 1.5\ntint = [1, 1, -1]\n"),
    "t.toml:12: materials.glass.tint: colour components must be >= 0, got [1, 1, -1]"
);
bad!(
    quoted_material_name,
    with("[materials.\"my glass\"]\ntype = \"dielectric\"\nior = -1\n"),
    "t.toml:11: materials.\"my glass\".ior: must be > 0, got -1"
);

// -------------------------------------------------------------- objects --

const WHITE: &str = "[materials.white]\ntype = \"lambert\"\nalbedo = [1, 1, 1]\n";

fn with_white(objects: &str) -> String {
    with(&format!("{WHITE}{objects}"))
}

bad!(
    objects_not_an_array,
    with("[objects]\ntype = \"sphere\"\n"),
    "t.toml:9: objects: expected an array of tables [[objects]], got a table"
);
bad!(
    object_missing_type,
    with_white("[[objects]]\ncenter = [0, 0, 0]\n"),
    "t.toml:12: objects[0].type: missing required key in objects[0]: one of sphere, quad, mesh"
);
bad!(
    sphere_unknown_key,
    with_white(
        "[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"white\"\n\
         scale = 2\n"
    ),
    "t.toml:17: objects[0].scale: unknown key `scale` in objects[0] (a sphere); expected \
     one of: type, center, radius, material"
);
bad!(
    sphere_missing_center,
    with_white("[[objects]]\ntype = \"sphere\"\nradius = 1\nmaterial = \"white\"\n"),
    "t.toml:12: objects[0].center: missing required key in objects[0] (a sphere): \
     a point [x, y, z]"
);
bad!(
    sphere_radius_zero,
    with_white(
        "[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.0\nmaterial = \"white\"\n"
    ),
    "t.toml:15: objects[0].radius: must be > 0, got 0.0"
);
bad!(
    sphere_radius_string,
    with_white(
        "[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = \"1\"\nmaterial = \"white\"\n"
    ),
    "t.toml:15: objects[0].radius: expected a number, got a string \"1\""
);
bad!(
    sphere_missing_material,
    with_white("[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n"),
    "t.toml:12: objects[0].material: missing required key in objects[0] (a sphere): the \
     name of a [materials.NAME] table"
);
bad!(
    material_name_not_string,
    with_white("[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = 1\n"),
    "t.toml:16: objects[0].material: expected a string, got an integer 1"
);
bad!(
    no_materials_defined,
    with("[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"x\"\n"),
    "t.toml:13: objects[0].material: no material named `x`: the scene defines no \
     materials; add a [materials.x] table"
);
bad!(
    quad_missing_edge,
    with_white("[[objects]]\ntype = \"quad\"\norigin = [0, 0, 0]\nedge_u = [1, 0, 0]\n"),
    "t.toml:12: objects[0].edge_v: missing required key in objects[0] (a quad): a vector \
     [x, y, z]"
);
bad!(
    quad_zero_edge,
    with_white(
        "[[objects]]\ntype = \"quad\"\norigin = [0, 0, 0]\nedge_u = [0, 0, 0]\n\
         edge_v = [0, 1, 0]\nmaterial = \"white\"\n"
    ),
    "t.toml:16: objects[0].edge_v: the quad has zero area: edge_u and edge_v must be \
     non-zero and not parallel"
);
bad!(
    mesh_missing_file,
    with_white("[[objects]]\ntype = \"mesh\"\nmaterial = \"white\"\n"),
    "t.toml:12: objects[0].file: missing required key in objects[0] (a mesh): the OBJ \
     file, relative to the scene file"
);
bad!(
    mesh_scale_zero,
    with_white("[[objects]]\ntype = \"mesh\"\nfile = \"x.obj\"\nscale = 0\n"),
    "t.toml:15: objects[0].scale: every scale component must be > 0, got 0"
);
bad!(
    mesh_scale_negative_component,
    with_white("[[objects]]\ntype = \"mesh\"\nfile = \"x.obj\"\nscale = [1, -1, 1]\n"),
    "t.toml:15: objects[0].scale: every scale component must be > 0, got [1, -1, 1]"
);
bad!(
    mesh_scale_wrong_type,
    with_white("[[objects]]\ntype = \"mesh\"\nfile = \"x.obj\"\nscale = \"big\"\n"),
    "t.toml:15: objects[0].scale: expected a number or an array of 3 numbers [x, y, z], \
     got a string \"big\""
);
bad!(
    mesh_rotate_wrong_length,
    with_white("[[objects]]\ntype = \"mesh\"\nfile = \"x.obj\"\nrotate = [0, 90]\n"),
    "t.toml:15: objects[0].rotate: expected 3 numbers [x, y, z], got 2 values [0, 90]"
);
bad!(
    mesh_unknown_key,
    with_white("[[objects]]\ntype = \"mesh\"\nfile = \"x.obj\"\nrotation = [0, 90, 0]\n"),
    "t.toml:15: objects[0].rotation: unknown key `rotation` in objects[0] (a mesh); \
     expected one of: type, file, material, translate, rotate, scale, smooth_normals (did you \
     mean `rotate`?)"
);
bad!(
    inline_object_table_unknown_key,
    format!(
        "objects = [{{ type = \"sphere\", center = [0, 0, 0], radius = 1, material = \"white\" }},\n\
         {{ type = \"sphere\", centre = [0, 0, 0] }}]\n{BASE}{WHITE}"
    ),
    "t.toml:2: objects[1].centre: unknown key `centre` in objects[1] (a sphere); expected \
     one of: type, center, radius, material (did you mean `center`?)"
);

// ---------------------------------------------------------------- meshes --

fn mesh_scene(obj: &str, extra: &str) -> String {
    with_white(&format!(
        "[[objects]]\ntype = \"mesh\"\nfile = \"meshes/{obj}\"\n{extra}"
    ))
}

fn mesh_err(obj: &str, extra: &str) -> String {
    match in_scenes(&mesh_scene(obj, extra)) {
        Ok(_) => panic!("{obj} should be rejected"),
        Err(e) => e.to_string(),
    }
}

fn scenes_path(rel: &str) -> String {
    fixture("scenes").join(rel).display().to_string()
}

#[test]
fn mesh_faces_without_material() {
    let e = mesh_err("no_material.obj", "");
    assert_eq!(
        e,
        format!(
            "{}:14: objects[0].file: faces of object `unnamed_object` in {} have no \
             material (no `usemtl`, or a `usemtl` naming a material that no `mtllib` \
             defines); fix the OBJ or give the mesh a `material` key",
            scenes_path("inline.toml"),
            scenes_path("meshes/no_material.obj")
        )
    );
}

#[test]
fn mesh_missing_mtl() {
    let e = mesh_err("missing_mtl.obj", "");
    let prefix = format!(
        "{}:14: objects[0].file: cannot read material library {} (named by `mtllib` in {}): ",
        scenes_path("inline.toml"),
        scenes_path("meshes/does_not_exist.mtl"),
        scenes_path("meshes/missing_mtl.obj")
    );
    assert!(e.starts_with(&prefix), "{e}\n{prefix}");
}

#[test]
fn mesh_missing_mtl_is_fine_with_a_material_key() {
    let scene = in_scenes(&mesh_scene("missing_mtl.obj", "material = \"white\"\n")).unwrap();
    assert_eq!(scene.triangles.len(), 1);
    assert_eq!(scene.triangles[0].material, 0);
}

#[test]
fn mesh_mtl_missing_texture() {
    let e = mesh_err("missing_texture.obj", "");
    let prefix = format!(
        "{}:14: objects[0].file: {}:3: `map_Kd` of material `painted`: cannot read texture {}: ",
        scenes_path("inline.toml"),
        scenes_path("meshes/missing_texture.mtl"),
        scenes_path("meshes/no_such_texture.png")
    );
    assert!(e.starts_with(&prefix), "{e}\n{prefix}");
}

#[test]
fn mesh_bad_mtl_line() {
    let e = mesh_err("bad_mtl.obj", "");
    assert_eq!(
        e,
        format!(
            "{}:14: objects[0].file: {}:2: `Kd`: expected `r g b` (three numbers), got `0.5 0.5`",
            scenes_path("inline.toml"),
            scenes_path("meshes/bad_mtl.mtl")
        )
    );
}

#[test]
fn mesh_bad_face_line() {
    let e = mesh_err("bad_face.obj", "material = \"white\"\n");
    assert_eq!(
        e,
        format!(
            "{}:14: objects[0].file: cannot load OBJ file {}:4: face parse error",
            scenes_path("inline.toml"),
            scenes_path("meshes/bad_face.obj")
        )
    );
}

#[test]
fn mesh_missing_obj_inline() {
    let e = mesh_err("nope.obj", "material = \"white\"\n");
    let prefix = format!(
        "{}:14: objects[0].file: cannot read OBJ file {}: ",
        scenes_path("inline.toml"),
        scenes_path("meshes/nope.obj")
    );
    assert!(e.starts_with(&prefix), "{e}");
}

#[test]
fn mesh_drops_bad_triangles_and_counts_them() {
    let scene = in_scenes(&mesh_scene("bad_numbers.obj", "material = \"white\"\n")).unwrap();
    assert_eq!(scene.triangles.len(), 2);
    let good = &scene.triangles[0];
    assert_eq!(good.n, Some([Vec3::Z; 3]));
    assert_eq!(scene.triangles[1].n, None, "NaN normal falls back to none");
    for t in &scene.triangles {
        assert!(t.p.iter().all(|p| p.is_finite()));
    }
    let here = format!(
        "{}:14: objects[0].file: {}: ",
        scenes_path("inline.toml"),
        scenes_path("meshes/bad_numbers.obj")
    );
    assert_eq!(
        scene.warnings,
        vec![
            format!("{here}dropped 2 triangle(s) with a NaN or infinite vertex"),
            format!("{here}dropped 2 degenerate (zero-area) triangle(s)"),
            format!(
                "{here}1 triangle(s) with NaN, infinite or zero vertex normals use the \
                 geometric normal"
            ),
        ]
    );
}

#[test]
fn mesh_keeps_normals_and_uvs() {
    let scene = in_scenes(&mesh_scene("bunny.obj", "material = \"white\"\n")).unwrap();
    assert_eq!(scene.triangles.len(), 4);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    for t in &scene.triangles {
        let n = t.n.expect("normals");
        for n in n {
            assert!((n.length() - 1.0).abs() < 1e-5);
        }
        assert!(t.uv.is_some());
    }
    // Face 1 is `1/1/1 3/3/3 2/2/2`: its uvs are as given.
    assert_eq!(
        scene.triangles[0].uv,
        Some([
            Vec2::new(0.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 0.0)
        ])
    );
    // Counter-clockwise from outside: the first face (z = 0) faces -z.
    let t = &scene.triangles[0];
    let n = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
    assert!(n.z < 0.0);
}

#[test]
fn mesh_without_normals_has_none() {
    let scene = in_scenes(&mesh_scene("no_material.obj", "material = \"white\"\n")).unwrap();
    assert_eq!(scene.triangles[0].n, None);
    assert_eq!(scene.triangles[0].uv, None);
}

fn assert_close(a: Vec3, b: Vec3) {
    assert!((a - b).length() < 1e-4, "{a} != {b}");
}

#[test]
fn transform_order_is_translate_rz_ry_rx_scale() {
    let scene = in_scenes(&mesh_scene(
        "triangle.obj",
        "material = \"white\"\ntranslate = [10, 20, 30]\nrotate = [90, 0, 90]\n\
             scale = [2, 3, 4]\n",
    ))
    .unwrap();
    let t = &scene.triangles[0];
    // (1,0,0) -> scale (2,0,0) -> Rx (2,0,0) -> Rz (0,2,0) -> + t.
    assert_close(t.p[0], Vec3::new(10.0, 22.0, 30.0));
    // (0,1,0) -> (0,3,0) -> Rx (0,0,3) -> Rz (0,0,3) -> + t.
    assert_close(t.p[1], Vec3::new(10.0, 20.0, 33.0));
    // (0,0,1) -> (0,0,4) -> Rx (0,-4,0) -> Rz (4,0,0) -> + t.
    assert_close(t.p[2], Vec3::new(14.0, 20.0, 30.0));
    // The vertex normal (the face's own, (1,1,1)/sqrt 3) stays
    // perpendicular to the transformed face: inverse-transpose.
    let geometric = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).normalize();
    for n in t.n.expect("normals") {
        assert_close(n, geometric);
    }
}

#[test]
fn rotate_y_90_turns_x_into_minus_z() {
    let scene = in_scenes(&mesh_scene(
        "triangle.obj",
        "material = \"white\"\nrotate = [0, 90, 0]\n",
    ))
    .unwrap();
    assert_close(scene.triangles[0].p[0], Vec3::new(0.0, 0.0, -1.0));
}

#[test]
fn mesh_uniform_scale_and_integers() {
    let scene = in_scenes(&mesh_scene(
        "triangle.obj",
        "material = \"white\"\nscale = 3\n",
    ))
    .unwrap();
    assert_close(scene.triangles[0].p[0], Vec3::new(3.0, 0.0, 0.0));
}

fn mtl_scene() -> Result<Scene, SceneError> {
    // Loading the mesh twice must not duplicate its materials.
    in_scenes(&format!(
        "{}{}",
        mesh_scene("mtl_kinds.obj", ""),
        "[[objects]]\ntype = \"mesh\"\nfile = \"meshes/mtl_kinds.obj\"\n"
    ))
}

#[test]
fn mtl_mapping_of_each_kind() {
    let scene = mtl_scene().unwrap();
    let find = |name: &str| -> &Material {
        scene
            .materials
            .iter()
            .find(|m| m.name == format!("mtl_kinds.mtl:{name}"))
            .unwrap_or_else(|| panic!("{name} in {:?}", scene.materials))
    };
    let c = |r, g, b| ColorSource::Constant(Vec3::new(r, g, b));
    assert_eq!(
        find("matte").kind,
        MaterialKind::Lambert {
            albedo: c(0.5, 0.25, 0.125)
        }
    );
    assert_eq!(
        find("shiny").kind,
        MaterialKind::Phong {
            diffuse: c(0.5, 0.5, 0.5),
            specular: Vec3::splat(0.25),
            exponent: 40.0
        }
    );
    let lamp = find("lamp");
    assert_eq!(
        lamp.kind,
        MaterialKind::Lambert {
            albedo: c(0.0, 0.0, 0.0)
        }
    );
    assert_eq!(lamp.emission, Vec3::new(4.0, 3.0, 2.0));
    assert_eq!(find("matte").emission, Vec3::ZERO);
    assert_eq!(
        find("chrome").kind,
        MaterialKind::Mirror {
            reflectance: Vec3::new(0.9, 0.8, 0.7)
        }
    );
    assert_eq!(
        find("chrome_default").kind,
        MaterialKind::Mirror {
            reflectance: Vec3::ONE
        }
    );
    assert_eq!(
        find("glass").kind,
        MaterialKind::Dielectric {
            ior: 1.5,
            tint: Vec3::new(0.9, 1.0, 0.8)
        }
    );
    assert_eq!(
        find("water").kind,
        MaterialKind::Dielectric {
            ior: 1.33,
            tint: Vec3::ONE
        }
    );
    let checker = fixture("scenes/meshes").join("../tex/checker.png");
    assert_eq!(
        find("textured").kind,
        MaterialKind::Lambert {
            albedo: ColorSource::Texture(checker)
        }
    );
    // Kd 0.8 + Ks 0.5 > 1: scaled down by 1.3, with a warning.
    match &find("hot").kind {
        MaterialKind::Phong {
            diffuse: ColorSource::Constant(d),
            specular,
            exponent,
        } => {
            assert_close(*d, Vec3::splat(0.8 / 1.3));
            assert_close(*specular, Vec3::splat(0.5 / 1.3));
            assert_eq!(*exponent, 250.0);
        }
        other => panic!("{other:?}"),
    }
    // "white" plus 9 used .mtl materials, each once; `unused` is left out.
    assert_eq!(scene.materials.len(), 10);
    assert!(!scene.materials.iter().any(|m| m.name.ends_with(":unused")));
    assert_eq!(scene.triangles.len(), 20);
    let matte = scene
        .materials
        .iter()
        .position(|m| m.name == "mtl_kinds.mtl:matte")
        .unwrap() as u32;
    assert_eq!(scene.triangles[0].material, matte);
    assert_eq!(scene.triangles[9].material, matte);
    assert_eq!(scene.triangles[10].material, matte);
    assert!(scene
        .warnings
        .iter()
        .any(|w| w.contains("mtl_kinds.mtl:36: material `hot`: Kd + Ks exceeds 1")));
}

#[test]
fn validation_error_names_the_key_and_line() {
    let text = with("[materials.d]\ntype = \"dielectric\"\nior = -1\n");
    assert_eq!(
        load_str(&text, Path::new("t.toml"))
            .unwrap_err()
            .to_string(),
        "t.toml:11: materials.d.ior: must be > 0, got -1"
    );
}

// ----------------------------------------------------------------- good --

#[test]
fn format_example_loads_with_all_features() {
    let path = fixture("scenes/format_example.toml");
    let scene = load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        scene.render,
        RenderSettings {
            width: 256,
            height: 256,
            spp: 64,
            max_depth: 8,
            seed: 0,
            filter: PixelFilter::Box,
            filter_inside_film: false,
            hide_emitters: false,
            emitter_sampling_only: false,
            bsdf_sampling_only: false,
            delta_light_gain: 1,
            rr_depth: DEFAULT_RR_DEPTH,
        }
    );
    assert_eq!(scene.camera.eye, Vec3::new(0.0, 1.0, 3.9));
    assert_eq!(scene.camera.focus_distance, 3.9);
    assert_eq!(scene.camera.vfov_deg, 40.0);
    assert_eq!(scene.environment, Vec3::ZERO);
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        ["white", "plastic", "chrome", "brushed", "glass", "lamp"]
    );
    assert_eq!(
        scene.materials[3].kind,
        MaterialKind::Glossy {
            reflectance: Vec3::splat(0.8),
            cone_angle_deg: 10.0
        }
    );
    assert_eq!(
        scene.materials[4].kind,
        MaterialKind::Dielectric {
            ior: 1.5,
            tint: Vec3::ONE
        }
    );
    assert_eq!(scene.materials[5].emission, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!(scene.spheres.len(), 1);
    assert_eq!(scene.spheres[0].material, 4);
    // Quad (2 triangles) + the 4-triangle stand-in bunny.
    assert_eq!(scene.triangles.len(), 6);
    assert_eq!(scene.triangles[0].material, 5);
    assert_eq!(scene.triangles[2].material, 0);
    assert!(scene.warnings.is_empty());
    assert_eq!(scene.source, path);
}

#[test]
fn format_example_with_textures_loads() {
    let path = fixture("scenes/format_example_textures.toml");
    let scene = load(&path).unwrap_or_else(|e| panic!("{e}"));
    let tex = |f: &str| ColorSource::Texture(fixture("scenes").join(f));
    assert_eq!(
        scene.materials[0].kind,
        MaterialKind::Lambert {
            albedo: tex("tex/checker.png")
        }
    );
    assert!(matches!(
        &scene.materials[1].kind,
        MaterialKind::Phong { diffuse, .. } if *diffuse == tex("tex/wood.png")
    ));
}

#[test]
fn defaults() {
    let scene = ok(&with(&format!(
        "{WHITE}[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n"
    )));
    assert_eq!(scene.render.max_depth, 8);
    assert_eq!(scene.render.seed, 0);
    assert_eq!(scene.camera.up, Vec3::Y);
    assert_eq!(scene.camera.aperture_radius, 0.0);
    assert_eq!(scene.camera.focus_distance, 5.0, "|look_at - eye|");
    assert_eq!(scene.environment, Vec3::ZERO);
    assert_eq!(scene.materials[0].emission, Vec3::ZERO);
    assert_eq!(
        scene.materials[1].kind,
        MaterialKind::Dielectric {
            ior: 1.5,
            tint: Vec3::ONE
        }
    );
    assert!(scene.spheres.is_empty() && scene.triangles.is_empty());
}

#[test]
fn default_focus_distance_is_eye_to_look_at() {
    let scene = ok(&replaced("eye = [0, 0, 5]", "eye = [3, 4, 12]"));
    assert_eq!(scene.camera.focus_distance, 13.0);
    let scene = ok(&with("focus_distance = 2.5\n"));
    assert_eq!(scene.camera.focus_distance, 2.5);
}

#[test]
fn integers_where_floats_are_expected() {
    let scene = ok(&with_white(
        "[[objects]]\ntype = \"sphere\"\ncenter = [1, -2, 3]\nradius = 2\nmaterial = \"white\"\n",
    ));
    assert_eq!(scene.camera.vfov_deg, 40.0);
    assert_eq!(scene.camera.eye, Vec3::new(0.0, 0.0, 5.0));
    assert_eq!(scene.spheres[0].center, Vec3::new(1.0, -2.0, 3.0));
    assert_eq!(scene.spheres[0].radius, 2.0);
    assert_eq!(
        scene.materials[0].kind,
        MaterialKind::Lambert {
            albedo: ColorSource::Constant(Vec3::ONE)
        }
    );
}

#[test]
fn render_settings_and_environment() {
    let text = "[render]\nwidth = 320\nheight = 0x10\nspp = 1_024\nmax_depth = 3\n\
                seed = 4294967295\n[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                up = [0, 2, 0]\nvfov = 179.5\n[environment]\nradiance = [0.25, 0.5, 1]\n";
    let scene = ok(text);
    assert_eq!(
        scene.render,
        RenderSettings {
            width: 320,
            height: 16,
            spp: 1024,
            max_depth: 3,
            seed: u32::MAX,
            filter: PixelFilter::Box,
            filter_inside_film: false,
            hide_emitters: false,
            emitter_sampling_only: false,
            bsdf_sampling_only: false,
            delta_light_gain: 1,
            rr_depth: DEFAULT_RR_DEPTH,
        }
    );
    assert_eq!(scene.camera.up, Vec3::new(0.0, 2.0, 0.0));
    assert_eq!(scene.environment, Vec3::new(0.25, 0.5, 1.0));
}

#[test]
fn quad_winding_and_uvs() {
    let scene = ok(&with_white(
        "[[objects]]\ntype = \"quad\"\norigin = [1, 2, 3]\nedge_u = [2, 0, 0]\n\
         edge_v = [0, 0, -3]\nmaterial = \"white\"\n",
    ));
    assert_eq!(scene.triangles.len(), 2);
    let front = Vec3::new(2.0, 0.0, 0.0)
        .cross(Vec3::new(0.0, 0.0, -3.0))
        .normalize();
    assert_eq!(front, Vec3::Y);
    let origin = Vec3::new(1.0, 2.0, 3.0);
    let (u, v) = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -3.0));
    for t in &scene.triangles {
        let n = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).normalize();
        assert_close(n, front);
        assert_eq!(t.n, None);
        // Every vertex sits at origin + uv.x * edge_u + uv.y * edge_v.
        let uv = t.uv.expect("quad uvs");
        for (p, uv) in t.p.iter().zip(uv) {
            assert_close(*p, origin + uv.x * u + uv.y * v);
        }
    }
    let corners: Vec<Vec2> = scene.triangles.iter().flat_map(|t| t.uv.unwrap()).collect();
    for c in [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE] {
        assert!(corners.contains(&c));
    }
}

#[test]
fn material_indices_follow_file_order() {
    let scene = ok(&with(
        "[materials.zeta]\ntype = \"lambert\"\nalbedo = [1, 0, 0]\n\
         [materials.alpha]\ntype = \"lambert\"\nalbedo = [0, 1, 0]\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"alpha\"\n",
    ));
    assert_eq!(scene.materials[0].name, "zeta");
    assert_eq!(scene.spheres[0].material, 1);
}

#[test]
fn phong_sum_of_exactly_one_is_fine() {
    let scene = ok(&with(
        "[materials.p]\ntype = \"phong\"\ndiffuse = [0.6, 0.7, 0.9]\n\
         specular = [0.4, 0.3, 0.1]\nexponent = 0\nemission = [1, 2, 3]\n",
    ));
    assert_eq!(scene.materials[0].emission, Vec3::new(1.0, 2.0, 3.0));
}

#[test]
fn glossy_cone_zero_is_fine() {
    ok(&with(
        "[materials.g]\ntype = \"glossy\"\nreflectance = [1, 1, 1]\ncone_angle = 0\n",
    ));
}

#[test]
fn hostile_obj_is_an_error_not_a_crash() {
    let e = mesh_err("hostile_index.obj", "material = \"white\"\n");
    assert_eq!(
        e,
        format!(
            "{}:14: objects[0].file: {}:6: face index `-5` refers to no `vt` (1 defined \
             before this line)",
            scenes_path("inline.toml"),
            scenes_path("meshes/hostile_index.obj")
        )
    );
}

#[test]
fn odd_documents_are_errors_not_crashes() {
    let cases = [
        "",
        "\u{feff}",
        "[render]\nwidth = 99999999999999999999999\n",
        "objects = [[1]]\n",
        "[[materials]]\ntype = \"lambert\"\n",
        "materials = []\n",
        "[camera]\neye = [[1, 2, 3]]\n",
        "[render.width]\n",
        "x = 1979-05-27T07:32:00Z\n",
        "[render]\nwidth = 0x7fffffffffffffff\nheight = -0o7\n",
    ];
    for text in cases {
        assert!(load_all(text).is_err(), "{text:?}");
    }
    let deep = format!(
        "{BASE}[environment]\nradiance = {}1{}\n",
        "[".repeat(200),
        "]".repeat(200)
    );
    assert!(load_all(&deep).is_err());
    let huge = replaced("vfov = 40", "vfov = 1e39");
    assert_eq!(
        err(&huge),
        "t.toml:8: camera.vfov: is too large for a 32-bit float, got 1e39"
    );
}

// ------------------------------------------- robustness (issue 8): sizes --

#[test]
fn file_huge_image_names_the_real_pixel_count() {
    let (p, e) = bad_file("bad_scenes/huge_image.toml");
    assert_eq!(
        e,
        format!(
            "{p}:3: render.width: 65536 x 65536 = 4294967296 pixels; lancer renders at \
             most 2147483648 pixels (2^31: the kernels index pixels in 32-bit integers); \
             lower the width or height"
        )
    );
}

bad!(
    image_of_ten_billion_pixels_does_not_wrap,
    replaced("width = 4\nheight = 4", "width = 100000\nheight = 100000"),
    "t.toml:2: render.width: 100000 x 100000 = 10000000000 pixels; lancer renders at \
     most 2147483648 pixels (2^31: the kernels index pixels in 32-bit integers); lower the \
     width or height"
);
bad!(
    image_side_above_the_limit,
    replaced("height = 4", "height = 1048577"),
    "t.toml:3: render.height: 1048577 pixels is above the limit of 1048576 per side \
     (pixel positions are 32-bit floats on the device); lower the height"
);

#[test]
fn image_size_limits_in_u64() {
    assert_eq!(image_pixels(46340, 46340), Ok(2147395600));
    assert_eq!(image_pixels(1 << 20, 1 << 11), Ok(1 << 31));
    assert!(image_pixels(1 << 20, (1 << 11) + 1).is_err());
    // 100000 * 100000 wraps u32 to 1410065408, below the limit: the check
    // must see the real figure.
    assert_eq!(100000u32.wrapping_mul(100000), 1410065408);
    assert!(image_pixels(100000, 100000).is_err());
}

/// The packed frame refuses a size the command line set after reading.
#[test]
fn pack_frame_checks_the_size_again() {
    let mut scene = ok(BASE);
    scene.render.width = 65536;
    scene.render.height = 65536;
    let e = crate::gpu::GpuScene::pack(&scene, &Default::default())
        .expect_err("2^32 pixels")
        .to_string();
    assert_eq!(
        e,
        "t.toml: render.width: 65536 x 65536 = 4294967296 pixels; lancer renders at most \
         2147483648 pixels (2^31: the kernels index pixels in 32-bit integers); lower the \
         width or height (render.width, render.height)"
    );
    scene.render.width = 1920;
    scene.render.height = 1080;
    let frame = crate::gpu::GpuScene::pack(&scene, &Default::default())
        .unwrap()
        .frame;
    assert_eq!(frame.pixel_count, 1920 * 1080);
}

// ------------------------------------------ robustness (issue 8): camera --

/// The frame's camera vectors, as the device gets them.
fn frame_basis(scene: &Scene) -> [Vec3; 3] {
    let f = crate::gpu::GpuScene::pack(scene, &Default::default())
        .unwrap()
        .frame;
    [f.cam_u.truncate(), f.cam_v.truncate(), f.cam_w.truncate()]
}

#[test]
fn camera_vectors_of_length_1e30_build_the_same_basis() {
    // Before: f32 normalize of a 1e-30 vector squares to 1e-60 = 0: NaN.
    let reference = ok(&replaced(
        "look_at = [0, 0, 0]",
        "look_at = [0, 0, 4]\nup = [1, 0, 0]",
    ));
    let near = ok(
        "[render]\nwidth = 4\nheight = 4\nspp = 1\n[camera]\neye = [0, 0, 0]\n\
         look_at = [0, 0, -1e-30]\nup = [1e-30, 0, 0]\nvfov = 40\n",
    );
    let want = frame_basis(&reference);
    for b in want {
        assert!(b.is_finite() && (b.length() - 1.0).abs() < 1e-6, "{want:?}");
    }
    assert_eq!(want, [Vec3::NEG_Y, Vec3::X, Vec3::Z]);
    assert_eq!(frame_basis(&near), want);
}

#[test]
fn file_camera_that_collapses_in_f32() {
    let (p, e) = bad_file("bad_scenes/camera_collapses_in_f32.toml");
    assert_eq!(
        e,
        format!(
            "{p}:10: camera.look_at: is 1.0000000028043132e-7 from camera.eye: is the same point as \
             camera.eye in 32-bit floats, so the camera has no direction to look in; \
             move look_at away from eye (at least a few units in the last place of eye's \
             largest coordinate)"
        )
    );
}

bad!(
    look_at_1e30_from_eye_off_the_origin,
    replaced("look_at = [0, 0, 0]", "look_at = [0, 0, 5.000000000000001]"),
    "t.toml:7: camera.look_at: is 8.881784197001252e-16 from camera.eye: is the same point \
     as camera.eye in 32-bit floats, so the camera has no direction to look in; move \
     look_at away from eye (at least a few units in the last place of eye's largest \
     coordinate)"
);
bad!(
    up_below_f32_range,
    replaced(
        "look_at = [0, 0, 0]",
        "look_at = [0, 0, 0]\nup = [1e-50, 0, 0]"
    ),
    "t.toml:8: camera.up: is [0, 0, 0] in 32-bit floats; give the direction that should \
     point up in the image, with a length of about 1 (it is [0, 0, 0])"
);
bad!(
    view_direction_turned_by_f32_rounding,
    replaced("width = 4\nheight = 4", "width = 1024\nheight = 1024").replace(
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]",
        "eye = [0.3, 1.7, 3.9]\nlook_at = [0.3001, 1.7001, 3.8999]"
    ),
    "t.toml:7: camera.look_at: is only 1.7320508075674047e-4 from camera.eye: in 32-bit \
     floats (what the device uses) the view direction turns by 5.634e-2 degrees, 1.38 \
     pixels; move look_at farther from eye along the same direction"
);
bad!(
    up_nearly_parallel_rolls_the_image_in_f32,
    replaced("width = 4\nheight = 4", "width = 1024\nheight = 1024").replace(
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]",
        "eye = [0, 0, 0]\nlook_at = [1, 3, 7]\nup = [0.1, 0.3, 0.70001]"
    ),
    "t.toml:8: camera.up: camera.up is only 3.071e-4 degrees from the view direction: in \
     32-bit floats (what the device uses) the image would turn by 3.287e-2 degrees, about \
     0.81 pixels; choose an up further from look_at - eye"
);
bad!(
    focus_below_eye_precision,
    replaced(
        "eye = [0, 0, 5]",
        "eye = [0, 0, 5000]\naperture_radius = 0.1\nfocus_distance = 1e-4"
    ),
    "t.toml:8: camera.focus_distance: the focus distance 1e-4 is below what 32-bit floats \
     resolve at eye (largest coordinate 5e3): with aperture_radius > 0 it must be at least \
     1.25e-1; set a larger focus_distance or move the scene nearer the origin"
);
bad!(
    vfov_that_rounds_to_180,
    replaced("vfov = 40", "vfov = 179.999999999"),
    "t.toml:8: camera.vfov: must be > 0 and < 180 (degrees), got 179.999999999, which is \
     180 in 32-bit floats (what the device uses)"
);

#[test]
fn camera_a_millimetre_from_its_target_works() {
    // Representable cases stay valid: 1e-3 from the target, off the axes.
    let scene = ok(&replaced(
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]",
        "eye = [0.3, 1.7, 3.9]\nlook_at = [0.301, 1.701, 3.899]",
    ));
    let [u, v, w] = frame_basis(&scene);
    let expect_w = Vec3::new(-1.0, -1.0, 1.0).normalize();
    assert!((w - expect_w).length() < 2e-4, "{w}");
    assert!(u.dot(v).abs() < 1e-6 && u.dot(w).abs() < 1e-6 && v.dot(w).abs() < 1e-6);
    // And a tiny camera near the origin, with a thin lens.
    let scene = ok(&replaced(
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]",
        "eye = [0, 0, 1e-12]\nlook_at = [0, 0, 0]\naperture_radius = 1e-13",
    ));
    assert_eq!(frame_basis(&scene), [Vec3::X, Vec3::Y, Vec3::Z]);
}

// ---------------------------------------- robustness (issue 8): radiance --

#[test]
fn file_emission_near_the_float_limit() {
    let (p, e) = bad_file("bad_scenes/too_bright.toml");
    assert_eq!(
        e,
        format!(
            "{p}:15: materials.sun.emission: radiance components must be <= 1e12 (sums of \
             radiance and its square over many samples must stay inside 32-bit floats), \
             got [3e38, 3e38, 3e38]; scale every emission and the environment down by the \
             same factor"
        )
    );
}

bad!(
    environment_above_the_radiance_limit,
    with("[environment]\nradiance = [1, 1.1e12, 1]\n"),
    "t.toml:10: environment.radiance: radiance components must be <= 1e12 (sums of \
     radiance and its square over many samples must stay inside 32-bit floats), got \
     [1, 1.1e12, 1]; scale every emission and the environment down by the same factor"
);
bad!(
    environment_infinite,
    with("[environment]\nradiance = [1, inf, 1]\n"),
    "t.toml:10: environment.radiance[1]: must be a finite number, got inf"
);

#[test]
fn radiance_at_the_limit_is_fine() {
    let scene = ok(&with("[environment]\nradiance = [1e12, 0, 0]\n"));
    assert_eq!(scene.environment, Vec3::new(1e12, 0.0, 0.0));
}

// ------------------------------ robustness (issue 8): light that grows --

/// The base scene at `max_depth` with a white environment and one material.
fn gain_scene(max_depth: u32, material: &str) -> String {
    let base = replaced("spp = 1", &format!("spp = 1\nmax_depth = {max_depth}"));
    format!("{base}[environment]\nradiance = [1, 1, 1]\n[materials.m]\n{material}\n")
}

bad!(
    albedo_above_one_too_deep,
    gain_scene(47, "type = \"lambert\"\nalbedo = [0.5, 2, 0.5]"),
    "t.toml:14: materials.m.albedo: a component of 2 amplifies light at every bounce: over \
     max_depth 47 bounces, with the brightest emission 1 (environment.radiance), a path could \
     carry radiance up to 1.41e14, above lancer's limit of 1e14 for a path (radiance and its \
     square are summed in 32-bit floats; see \"Light that grows along a path\" in \
     docs/scene-format.md); lower it to at most 1, or render.max_depth to at most 46"
);
bad!(
    mirror_reflectance_far_above_one,
    gain_scene(8, "type = \"mirror\"\nreflectance = [1e6, 1, 1]"),
    "t.toml:14: materials.m.reflectance: a component of 1000000 amplifies light at every \
     bounce: over max_depth 8 bounces, with the brightest emission 1 (environment.radiance), a \
     path could carry radiance up to 1.00e48, above lancer's limit of 1e14 for a path \
     (radiance and its square are summed in 32-bit floats; see \"Light that grows along a \
     path\" in docs/scene-format.md); lower it to at most 1, or render.max_depth to at most 2"
);
bad!(
    dielectric_ior_too_large,
    gain_scene(8, "type = \"dielectric\"\nior = 2e7"),
    "t.toml:14: materials.m.ior: a path crossing this dielectric's surface has its radiance \
     scaled by up to max(ior, 1/ior)^2 = 4.00e14; with the brightest emission 1 \
     (environment.radiance), a path could carry radiance up to 4.00e14, above lancer's limit \
     of 1e14 for a path; keep max(ior, 1/ior) at most 1.00e7, or lower the emission"
);
bad!(
    dielectric_ior_too_small,
    gain_scene(8, "type = \"dielectric\"\nior = 5e-8"),
    "t.toml:14: materials.m.ior: a path crossing this dielectric's surface has its radiance \
     scaled by up to max(ior, 1/ior)^2 = 4.00e14; with the brightest emission 1 \
     (environment.radiance), a path could carry radiance up to 4.00e14, above lancer's limit \
     of 1e14 for a path; keep max(ior, 1/ior) at most 1.00e7, or lower the emission"
);

#[test]
fn light_that_cannot_grow_past_the_limit_is_fine() {
    // Albedo 2 for 46 bounces: 2^46 = 7.0e13 <= 1e14.
    ok(&gain_scene(46, "type = \"lambert\"\nalbedo = [2, 2, 2]"));
    // Albedos at most 1 bound a path by its emission at any depth, even the
    // brightest emission over a million bounces, through glass (x 1.5^2).
    let deep = gain_scene(1_000_000, "type = \"dielectric\"\nior = 1.5")
        .replace("radiance = [1, 1, 1]", "radiance = [1e12, 1e12, 1e12]");
    ok(&deep);
    ok(&gain_scene(8, "type = \"dielectric\"\nior = 9.9e6"));
    // Without light nothing can grow.
    let dark = gain_scene(100, "type = \"lambert\"\nalbedo = [1e30, 0, 0]")
        .replace("radiance = [1, 1, 1]", "radiance = [0, 0, 0]");
    ok(&dark);
}

#[test]
fn a_deeper_max_depth_from_the_command_line_is_checked_when_packed() {
    let mut scene = ok(&gain_scene(8, "type = \"lambert\"\nalbedo = [2, 2, 2]"));
    crate::gpu::GpuScene::pack(&scene, &Default::default()).expect("depth 8 packs");
    scene.render.max_depth = 100;
    let e =
        crate::gpu::GpuScene::pack(&scene, &Default::default()).expect_err("depth 100 is refused");
    let e = format!("{e:#}");
    assert!(
        e.contains("materials.m.albedo: a component of 2 amplifies light")
            && e.contains("up to 1.27e30")
            && e.contains("or render.max_depth to at most 46"),
        "{e}"
    );
}

#[test]
fn mtl_emission_above_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl hot\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl hot\nKd 0 0 0\nKe 2e12 1 1\n",
    )
    .unwrap();
    let scene = dir.path().join("s.toml");
    let text = format!("{BASE}[[objects]]\ntype = \"mesh\"\nfile = \"m.obj\"\n");
    let e = load_str(&text, &scene).unwrap_err().to_string();
    let d = dir.path().display();
    assert_eq!(
        e,
        format!(
            "{d}/s.toml:11: objects[0].file: {d}/m.mtl:3: `Ke` of material `hot` must be <= \
             1e12 in every component (sums of radiance and its square over many samples \
             must stay inside 32-bit floats), got 2000000000000 1 1; scale every emission \
             down by the same factor"
        )
    );
}

// ---------------------------------------- robustness (issue 8): messages --

#[test]
fn long_unknown_key_is_cut() {
    let key = "k".repeat(10_000);
    let e = err(&with(&format!("{key} = 1\n")));
    assert_eq!(
        e,
        format!(
            "t.toml:9: camera.{}...: unknown key `{}...` in [camera]; expected one of: eye, \
             look_at, up, vfov, aperture_radius, focus_distance, near_clip, far_clip",
            "k".repeat(40),
            "k".repeat(40)
        )
    );
    assert!(e.len() < 250, "{}", e.len());
}

bad!(
    long_unknown_material_name_is_cut,
    with(&format!(
        "[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"{}\"\n",
        "m".repeat(5000)
    )),
    format!(
        "t.toml:13: objects[0].material: no material named `{}...`: the scene defines no \
         materials; add a [materials.{}...] table",
        "m".repeat(40),
        "m".repeat(40)
    )
);

#[test]
fn file_duplicate_key_is_named() {
    let (p, e) = bad_file("bad_scenes/duplicate_key.toml");
    assert_eq!(
        e,
        format!(
            "{p}:6: invalid TOML: duplicate key `spp`: a key may be given once per table; \
             remove one"
        )
    );
}

// ------------------------------------------- robustness (issue 8): OBJ --

#[test]
fn mesh_with_latin1_comments_and_names_loads() {
    let scene = in_scenes(&mesh_scene("latin1.obj", "")).unwrap();
    assert_eq!(scene.triangles.len(), 1);
    let m = &scene.materials[scene.triangles[0].material as usize];
    assert_eq!(m.name, "latin1.mtl:matériau");
    assert_eq!(
        m.kind,
        MaterialKind::Lambert {
            albedo: ColorSource::Constant(Vec3::new(0.5, 0.25, 0.125))
        }
    );
    let here = format!(
        "{}:14: objects[0].file: {}",
        scenes_path("inline.toml"),
        scenes_path("meshes/latin1.obj")
    );
    assert_eq!(
        scene.warnings,
        vec![
            format!("{here}:10: face with 2 vertex(es) dropped; a face needs at least 3"),
            format!("{here}:11: face with 1 vertex(es) dropped; a face needs at least 3"),
        ]
    );
}

#[test]
fn mesh_with_latin1_in_a_vertex_names_the_line() {
    let e = mesh_err("latin1_vertex.obj", "material = \"white\"\n");
    assert_eq!(
        e,
        format!(
            "{}:14: objects[0].file: {}:3: byte 0xB7 (column 4) is not UTF-8 text, in a `v` \
             statement where every byte matters; save the file as UTF-8 (other bytes are \
             accepted only in comments and names)",
            scenes_path("inline.toml"),
            scenes_path("meshes/latin1_vertex.obj")
        )
    );
}

/// Overrides replace the file's `[render]` values before the one check:
/// a file's value that an override replaces is never judged, and an
/// override at fault is named as such, with no line of the file.
#[test]
fn overrides_are_checked_once_after_they_apply() {
    let path = Path::new("t.toml");
    let over = |o: RenderOverrides| load_str_with(BASE, path, &o);
    let s = over(RenderOverrides {
        width: Some(640),
        spp: Some(9),
        max_depth: Some(2),
        seed: Some(4),
        ..RenderOverrides::default()
    })
    .unwrap();
    assert_eq!(
        (
            s.render.width,
            s.render.height,
            s.render.spp,
            s.render.max_depth,
            s.render.seed
        ),
        (640, 4, 9, 2, 4)
    );
    let e = over(RenderOverrides {
        spp: Some(0),
        ..RenderOverrides::default()
    })
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.toml: render.spp: must be >= 1, got 0 (the value of RenderOverrides::spp)"
    );
    assert_eq!(e.line(), None);
    let e = over(RenderOverrides {
        width: Some(1 << 20),
        height: Some(1 << 12),
        ..RenderOverrides::default()
    })
    .unwrap_err();
    assert_eq!(e.key(), Some("render.width"));
    assert!(e.to_string().contains("RenderOverrides::width"), "{e}");
    // The file's own value at fault still names its line.
    let big = replaced("width = 4", "width = 1048576").replace("height = 4", "height = 4096");
    let e = load_str_with(&big, path, &RenderOverrides::default()).unwrap_err();
    assert_eq!((e.key(), e.line()), (Some("render.width"), Some(2)));
    // ... unless an override replaces it.
    let s = load_str_with(
        &big,
        path,
        &RenderOverrides {
            width: Some(8),
            ..RenderOverrides::default()
        },
    )
    .unwrap();
    assert_eq!((s.render.width, s.render.height), (8, 4096));
}

// ------------------------------------------------------------ conductors --

/// A scene whose one material `m` has the given body (after `[materials.m]`).
fn metal(body: &str) -> String {
    with(&format!(
        "[materials.m]\n{body}\n[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n"
    ))
}

#[test]
fn conductors_read_presets_eta_k_and_mitsubas_defaults() {
    let kind = |body: &str| ok(&metal(body)).materials[0].kind.clone();
    assert_eq!(
        kind("type = \"roughconductor\""),
        MaterialKind::RoughConductor {
            distribution: Microfacet::Beckmann,
            alpha_u: 0.1,
            alpha_v: 0.1,
            alpha_textures: None,
            ior: ComplexIor::PERFECT,
            specular_reflectance: Vec3::ONE,
        }
    );
    assert_eq!(
        kind("type = \"roughconductor\"\ndistribution = \"ggx\"\nmaterial = \"Au\"\nalpha_u = 0.05\nalpha_v = 0.3\nspecular_reflectance = [0.5, 0.5, 0.5]"),
        MaterialKind::RoughConductor {
            distribution: Microfacet::Ggx,
            alpha_u: 0.05,
            alpha_v: 0.3,
            alpha_textures: None,
            ior: conductor_preset("Au").unwrap(),
            specular_reflectance: Vec3::splat(0.5),
        }
    );
    assert_eq!(
        kind("type = \"conductor\"\neta = [0.2, 0.9, 1.1]\nk = [3.9, 2.4, 2.1]"),
        MaterialKind::Conductor {
            ior: ComplexIor {
                eta: Vec3::new(0.2, 0.9, 1.1),
                k: Vec3::new(3.9, 2.4, 2.1),
            },
            specular_reflectance: Vec3::ONE,
        }
    );
}

#[test]
fn conductor_mistakes_are_named() {
    let cases = [
        (
            "type = \"conductor\"\nmaterial = \"Au\"\neta = [1, 1, 1]",
            "materials.m.eta: `material` is also given: give a preset or eta and k, not both",
        ),
        (
            "type = \"conductor\"\nmaterial = \"Gold\"",
            "materials.m.material: unknown conductor preset `Gold`; Mitsuba's presets are: none, Ag, Al,",
        ),
        (
            "type = \"roughconductor\"\nalpha_u = 0.1",
            "materials.m.alpha_u: `alpha_v` is missing: an anisotropic roughness needs both alpha_u and alpha_v",
        ),
        (
            "type = \"roughconductor\"\nalpha = 0.1\nalpha_v = 0.2",
            "materials.m.alpha_v: `alpha` is also given: give alpha (isotropic) or alpha_u and alpha_v, not both",
        ),
        (
            "type = \"roughconductor\"\ndistribution = \"phong\"",
            "materials.m.distribution: unknown distribution `phong`; use beckmann or ggx",
        ),
        (
            "type = \"roughconductor\"\nalpha = -1",
            "materials.m.alpha: must be >= 0, got -1",
        ),
        ("type = \"conductor\"\nalpha = 0.1", "alpha"),
    ];
    for (body, expected) in cases {
        let e = err(&metal(body));
        assert!(
            e.contains(expected),
            "{body}:\n{e}\nshould contain\n{expected}"
        );
    }
}

// ------------------------------------------- pixel filter and clip planes --

#[test]
fn filters_read_by_name_or_table_with_mitsubas_defaults() {
    let filter = |value: &str| {
        ok(&replaced("spp = 1", &format!("spp = 1\nfilter = {value}")))
            .render
            .filter
    };
    assert_eq!(ok(BASE).render.filter, PixelFilter::Box);
    assert_eq!(filter("\"box\""), PixelFilter::Box);
    assert_eq!(filter("\"tent\""), PixelFilter::Tent { radius: 1.0 });
    assert_eq!(
        filter("\"gaussian\""),
        PixelFilter::Gaussian { stddev: 0.5 }
    );
    assert_eq!(filter("\"mitchell\""), PixelFilter::MITCHELL);
    assert_eq!(filter("\"catmullrom\""), PixelFilter::CATMULL_ROM);
    assert_eq!(filter("\"lanczos\""), PixelFilter::Lanczos { lobes: 3 });
    assert_eq!(
        filter("{ type = \"tent\", radius = 1.25 }"),
        PixelFilter::Tent { radius: 1.25 }
    );
    assert_eq!(
        filter("{ type = \"gaussian\", stddev = 0.25 }"),
        PixelFilter::Gaussian { stddev: 0.25 }
    );
    assert_eq!(
        filter("{ type = \"mitchell\", B = 0.25, C = 0.5 }"),
        PixelFilter::Mitchell { b: 0.25, c: 0.5 }
    );
    assert_eq!(
        filter("{ type = \"lanczos\", lobes = 2 }"),
        PixelFilter::Lanczos { lobes: 2 }
    );
    let table = ok(&with("").replace(
        "[camera]",
        "[render.filter]\ntype = \"tent\"\nradius = 2\n[camera]",
    ))
    .render
    .filter;
    assert_eq!(table, PixelFilter::Tent { radius: 2.0 });
}

bad!(
    unknown_filter_name,
    replaced("spp = 1", "spp = 1\nfilter = \"sinc\""),
    "t.toml:5: render.filter: unknown pixel filter \"sinc\"; expected one of: box, tent, \
     gaussian, mitchell, catmullrom, lanczos"
);
bad!(
    filter_parameter_of_another_filter,
    replaced(
        "spp = 1",
        "spp = 1\nfilter = { type = \"tent\", stddev = 1 }"
    ),
    "t.toml:5: render.filter.stddev: unknown key `stddev` in [render.filter]; expected one \
     of: type, radius"
);
bad!(
    filter_parameter_out_of_range,
    replaced(
        "spp = 1",
        "spp = 1\nfilter = { type = \"gaussian\", stddev = -1 }"
    ),
    "t.toml:5: render.filter.stddev: stddev must be > 0 and at most 4 pixels, got -1"
);
bad!(
    filter_of_the_wrong_type,
    replaced("spp = 1", "spp = 1\nfilter = 3"),
    "t.toml:5: render.filter: expected a filter name such as \"gaussian\" or a table \
     { type = \"gaussian\", stddev = 0.5 }, got an integer 3"
);
bad!(
    negative_near_clip,
    with("near_clip = -1\n"),
    "t.toml:9: camera.near_clip: must be >= 0 and finite, got -1"
);
bad!(
    far_clip_before_near_clip,
    with("near_clip = 2\nfar_clip = 1\n"),
    "t.toml:10: camera.far_clip: must be above near_clip (2), got 1"
);

#[test]
fn clip_planes_are_optional_and_read_as_given() {
    let c = ok(BASE).camera;
    assert_eq!((c.near_clip, c.far_clip), (0.0, f32::INFINITY));
    assert!(!c.has_clip());
    let c = ok(&with("near_clip = 0.5\nfar_clip = 20\n")).camera;
    assert_eq!((c.near_clip, c.far_clip), (0.5, 20.0));
    assert!(c.has_clip());
    assert!(ok(&with("far_clip = 20\n")).camera.has_clip());
}
// --------------------------------------------------------------- lights --

#[test]
fn lights_read_with_their_defaults() {
    let scene = ok(&with(
        "[[lights]]\ntype = \"point\"\nposition = [1, 2, 3]\nintensity = [4, 5, 6]\n\
         [[lights]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -2, 0]\n\
         intensity = [1, 1, 1]\n\
         [[lights]]\ntype = \"directional\"\ndirection = [0, 0, -3]\nirradiance = [1, 1, 1]\n",
    ));
    assert_eq!(
        scene.lights[0],
        DeltaLight::Point {
            position: Vec3::new(1.0, 2.0, 3.0),
            intensity: Vec3::new(4.0, 5.0, 6.0)
        }
    );
    let DeltaLight::Spot {
        to_local,
        cutoff_deg,
        beam_width_deg,
        ..
    } = scene.lights[1]
    else {
        panic!("not a spot: {:?}", scene.lights[1]);
    };
    assert_eq!((cutoff_deg, beam_width_deg), (20.0, 15.0));
    // The axis maps to local +z.
    assert!((to_local * Vec3::NEG_Y - Vec3::Z).length() < 1e-6);
    assert_eq!(
        scene.lights[2],
        DeltaLight::Directional {
            direction: Vec3::NEG_Z,
            irradiance: Vec3::ONE
        }
    );
}

bad!(
    light_unknown_type,
    with("[[lights]]\ntype = \"area\"\n"),
    "t.toml:10: lights[0].type: unknown light type `area`; expected one of: point, spot, \
     directional"
);
bad!(
    light_unknown_key,
    with("[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nradius = 2\n"),
    "t.toml:13: lights[0].radius: unknown key `radius` in lights[0] (a point light); \
     expected one of: type, position, intensity"
);
bad!(
    light_beam_wider_than_cutoff,
    with(
        "[[lights]]\ntype = \"spot\"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\n\
         intensity = [1, 1, 1]\ncutoff_angle = 10\nbeam_width = 12\n"
    ),
    "t.toml:15: lights[0].beam_width: must be >= 0 and at most cutoff_angle (10 degrees), got 12"
);
bad!(
    light_zero_direction,
    with("[[lights]]\ntype = \"directional\"\ndirection = [0, 0, 0]\nirradiance = [1, 1, 1]\n"),
    "t.toml:11: lights[0].direction: must be a non-zero vector, got [0, 0, 0]"
);
bad!(
    lights_as_a_table,
    with("[lights]\ntype = \"point\"\n"),
    "t.toml:9: lights: expected an array of tables [[lights]], got a table"
);

// ------------------------------------ the files a scene reads (issue 18) --

/// `Scene::input_files` names every file the loader read: the scene, each
/// mesh with its `.mtl` libraries, PLY meshes of a Mitsuba scene, and each
/// material's texture, once each.
#[test]
fn input_files_name_every_file_the_scene_reads() {
    let scene = in_scenes(&mesh_scene("latin1.obj", "")).unwrap();
    let files: Vec<(PathBuf, String)> = scene.input_files();
    let meshes = fixture("scenes/meshes");
    assert_eq!(
        files[1..],
        [
            (meshes.join("latin1.obj"), "a mesh of the scene".to_string()),
            (
                meshes.join("latin1.mtl"),
                "a material library of the scene".to_string()
            ),
        ]
    );
    assert_eq!(files[0].1, "the scene file");

    let xml = load(&fixture("scenes/mitsuba/smooth_mesh.xml")).unwrap();
    let names: Vec<String> = (xml.input_files().iter())
        .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        ["smooth_mesh.xml", "lowpoly_sphere.obj", "icosphere.ply"]
    );

    let textured = load(&fixture("scenes/textured.toml")).unwrap();
    let files = textured.input_files();
    let textures: Vec<&PathBuf> = (files.iter())
        .filter(|(_, what)| what.starts_with("the texture of material"))
        .map(|(p, _)| p)
        .collect();
    assert!(!textures.is_empty());
    assert!(textures.iter().all(|p| p.is_file()), "{textures:?}");
    let unique: std::collections::HashSet<_> = files.iter().map(|(p, _)| p).collect();
    assert_eq!(unique.len(), files.len(), "a file listed twice");

    let sky = load(&fixture("scenes/mitsuba/envmap.xml")).unwrap();
    let files = sky.input_files();
    assert!(
        (files.iter())
            .any(|(p, what)| what == "the environment map" && p.ends_with("textures/sky.exr")),
        "{files:?}"
    );
}

/// `render.rr_depth`: lancer's default when absent, the value when given,
/// and 0 refused with the key and line.
#[test]
fn rr_depth_defaults_reads_and_refuses_zero() {
    assert_eq!(ok(BASE).render.rr_depth, DEFAULT_RR_DEPTH);
    assert_eq!(
        ok(&replaced("spp = 1\n", "spp = 1\nrr_depth = 6\n"))
            .render
            .rr_depth,
        6
    );
    let e = err(&replaced("spp = 1\n", "spp = 1\nrr_depth = 0\n"));
    assert!(e.contains("render.rr_depth") && e.contains(">= 1"), "{e}");
}
