//! Scene inputs that could render a silently wrong image render right, or
//! are refused before rendering with the real figure.

mod common;

use common::{context, lancer, load_inline, options, render, scene_header, stderr};

/// A lit sphere in front of a camera at the origin looking down -z, with
/// `look_at` and `up` as given.
fn camera_scene(look_at: &str, up: &str) -> lancer::scene::Scene {
    let camera = format!("eye = [0, 0, 0]\nlook_at = {look_at}\nup = {up}\nvfov = 50");
    let text = scene_header((16, 12), 4, 3, &camera, "[0.2, 0.3, 0.4]")
        + "[materials.white]\ntype = \"lambert\"\nalbedo = [0.7, 0.7, 0.7]\n\
         [materials.lamp]\ntype = \"lambert\"\nalbedo = [0, 0, 0]\nemission = [4, 3, 2]\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [0.4, 0, -3]\nradius = 0.8\nmaterial = \"white\"\n\
         [[objects]]\ntype = \"sphere\"\ncenter = [-0.8, 0.5, -2.5]\nradius = 0.3\nmaterial = \"lamp\"\n";
    load_inline(&text).unwrap_or_else(|e| panic!("{e}"))
}

/// `look_at` 1e-30 from `eye` and an `up` of length 1e-30 built a NaN
/// camera basis in f32 (a black image). Built in f64, they give the same
/// image, bit for bit, as the same camera with unit vectors.
#[test]
fn camera_vectors_of_length_1e30_render_like_unit_ones() {
    let ctx = context();
    let unit = render(
        &ctx,
        &camera_scene("[0, 0, -1]", "[1, 0, 0]"),
        &options(1 << 12),
    );
    let tiny = render(
        &ctx,
        &camera_scene("[0, 0, -1e-30]", "[1e-30, 0, 0]"),
        &options(1 << 12),
    );
    let mean: f64 = unit.mean.iter().map(|&x| x as f64).sum::<f64>() / unit.mean.len() as f64;
    assert!(mean > 0.1, "the reference image is dark: mean {mean}");
    assert_eq!(unit.mean, tiny.mean);
}

/// 65536 x 65536 wraps a u32 pixel count to 0: refused when the scene is
/// read, and when --width / --height set it after reading.
#[test]
fn image_size_overflow_is_refused_with_the_real_figure() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let o = lancer(
        &[
            "render",
            "tests/bad_scenes/huge_image.toml",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("huge_image.toml:3: render.width: 65536 x 65536 = 4294967296 pixels"),
        "{e}"
    );
    let o = lancer(
        &[
            "render",
            "tests/scenes/furnace.toml",
            "--width",
            "100000",
            "--height",
            "100000",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains(
            "render.width: 100000 x 100000 = 10000000000 pixels; lancer renders at most \
             2147483648 pixels (2^31: the kernels index pixels in 32-bit integers); lower \
             the width or height (in the scene, or --width / --height)"
        ),
        "{e}"
    );
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists());
}

/// A scene of one OBJ mesh `mesh.obj` with its `.mtl` `mesh.mtl`, written
/// with the texture `checker.png` into `dir`: its materials and triangles,
/// or the message.
fn load_obj_mtl(
    dir: &std::path::Path,
    obj: &str,
    mtl: &str,
) -> Result<lancer::scene::Scene, String> {
    std::fs::write(dir.join("mesh.obj"), obj).unwrap();
    std::fs::write(dir.join("mesh.mtl"), mtl).unwrap();
    std::fs::copy(
        common::repo("tests/scenes/tex/checker.png"),
        dir.join("checker.png"),
    )
    .unwrap();
    let text = scene_header(
        (8, 8),
        1,
        2,
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40",
        "[0, 0, 0]",
    ) + "[[objects]]\ntype = \"mesh\"\nfile = \"mesh.obj\"\n";
    lancer::scene::load_str(&text, &dir.join("scene.toml")).map_err(|e| e.to_string())
}

/// OBJ and MTL separate their tokens with any white space: a tab after
/// `mtllib` or `usemtl` made the name empty (tobj splits those at one
/// space), and the message blamed a missing file. Tabs, several spaces,
/// white space at the start of a line and CR LF line ends all load the
/// same scene.
#[test]
fn obj_and_mtl_tokens_split_on_any_white_space() {
    let dir = tempfile::tempdir().unwrap();
    let obj = "mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
               usemtl red\nf 1/1 2/2 3/3\nusemtl wood\nf 2/2 4/1 3/3\n";
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl wood\nKd 0.5 0.5 0.5\nmap_Kd checker.png\n";
    let expected = load_obj_mtl(dir.path(), obj, mtl).unwrap();
    assert_eq!(expected.materials.len(), 2);
    assert_eq!(expected.triangles.len(), 2);
    let variants = |text: &str| {
        [
            ("tabs", text.replace(' ', "\t")),
            ("several spaces", text.replace(' ', "  \t ")),
            ("CRLF", text.replace('\n', "\r\n")),
            ("indented", text.replace('\n', "\n \t")),
            ("trailing white space", text.replace('\n', " \t\r\n")),
        ]
    };
    for (what, obj) in variants(obj) {
        let loaded = load_obj_mtl(dir.path(), &obj, mtl).map_err(|e| format!("OBJ {what}: {e}"));
        let loaded = loaded.map(|s| (s.materials, s.triangles));
        assert_eq!(
            loaded,
            Ok((expected.materials.clone(), expected.triangles.clone())),
            "OBJ {what}"
        );
    }
    for (what, mtl) in variants(mtl) {
        let loaded = load_obj_mtl(dir.path(), obj, &mtl).map_err(|e| format!("MTL {what}: {e}"));
        let loaded = loaded.map(|s| (s.materials, s.triangles));
        assert_eq!(
            loaded,
            Ok((expected.materials.clone(), expected.triangles.clone())),
            "MTL {what}"
        );
    }
}

/// An OBJ face index is a count of the `v`, `vt` or `vn` before it (or in
/// the file): one beyond every integer type is refused naming it, as a
/// smaller one out of range is, rather than as tobj's bare "face parse
/// error".
#[test]
fn obj_face_indices_beyond_any_count_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\n";
    let head = "mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\n";
    let obj = dir.path().join("mesh.obj");
    let cases = [
        (
            "f 1 2 99999999999999999999",
            "face index `99999999999999999999` refers to no `v` (3 defined)",
        ),
        (
            "f 1 2/-99999999999999999999 3",
            "face index `-99999999999999999999` refers to no `vt` (0 defined before this line)",
        ),
        (
            "f 1 2 9223372036854775807",
            "face index `9223372036854775807` refers to no `v` (3 defined)",
        ),
    ];
    for (face, reason) in cases {
        let e = load_obj_mtl(dir.path(), &format!("{head}{face}\n"), mtl).unwrap_err();
        assert_eq!(
            e,
            format!(
                "{}:14: objects[0].file: {}:6: {reason}",
                dir.path().join("scene.toml").display(),
                obj.display()
            )
        );
    }
}
