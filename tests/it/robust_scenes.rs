//! Scene inputs that could render a silently wrong image render right, or
//! are refused before rendering with the real figure.

use crate::common;

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
             the width or height (the value of --width)"
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

/// A mesh file is read up to the length the file system gives it, never
/// more: a file that never ends (a device such as /dev/zero, a pipe) was
/// read into memory until the process aborted.
#[test]
fn mesh_files_that_never_end_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_header(
        (8, 8),
        1,
        2,
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40",
        "[0, 0, 0]",
    ) + "[materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
           [[objects]]\ntype = \"mesh\"\nfile = \"/dev/zero\"\nmaterial = \"m\"\n";
    let toml = dir.path().join("scene.toml");
    let e = lancer::scene::load_str(&scene, &toml)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        format!(
            "{}:17: objects[0].file: cannot read OBJ file /dev/zero: not a regular file \
             (a device or a pipe); give a mesh file",
            toml.display()
        )
    );
    let xml = r#"<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/></sensor>
  <shape type="ply"><string name="filename" value="/dev/zero"/><boolean name="face_normals" value="true"/></shape>
</scene>"#;
    let path = dir.path().join("scene.xml");
    let e = lancer::scene::load_str(xml, &path).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "{}:3: <string name=\"filename\">: attribute `value`: cannot read PLY file \
             /dev/zero: not a regular file (a device or a pipe); give a mesh file",
            path.display()
        )
    );
}

/// User text of any length is cut wherever a message echoes it: in the
/// location part (the dotted key), in backticks and quotes, in XML tag and
/// attribute names, in `.mtl` statements and material names, and in file
/// paths built from it. A key of 3 MB was echoed whole before the colon.
#[test]
fn long_user_text_is_cut_wherever_a_message_echoes_it() {
    const BIG: usize = 3_000_000;
    let a40 = "a".repeat(40);
    let long = |c: char| c.to_string().repeat(BIG);
    let cut = |c: char| format!("{}...", c.to_string().repeat(40));
    let inline = common::repo("tests/scenes/inline.toml");
    let inline = inline.display();
    let mut seen = Vec::new();
    let mut check = |got: String, expected: String| {
        assert!(got.len() < 600, "{} bytes: {}...", got.len(), &got[..600]);
        assert_eq!(got, expected);
        seen.push(got);
    };
    // The TOML key, top level and nested.
    check(
        load_inline(&format!("{} = 1\n", long('a'))).unwrap_err(),
        format!(
            "{inline}:1: {a40}...: unknown key `{a40}...` at the top level; expected one of: \
             render, camera, environment, materials, objects, lights"
        ),
    );
    let header = scene_header(
        (8, 8),
        1,
        2,
        "eye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40",
        "[0, 0, 0]",
    );
    check(
        load_inline(&format!(
            "{header}[materials.{}]\ntype = \"lambert\"\n",
            long('m')
        ))
        .unwrap_err(),
        format!(
            "{inline}:12: materials.{m}.albedo: missing required key in [materials.{m}] (a \
             lambert material): give albedo = [r, g, b] or albedo_texture = \"file.png\"",
            m = cut('m')
        ),
    );
    // A file path built from a long file name: its head and its tail.
    let file = format!("{}.obj", long('b'));
    let e = load_inline(&format!(
        "{header}[materials.m]\ntype = \"lambert\"\nalbedo = [1, 1, 1]\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"{file}\"\nmaterial = \"m\"\n"
    ))
    .unwrap_err();
    let path = common::repo("tests/scenes")
        .join(&file)
        .display()
        .to_string();
    let chars: Vec<char> = path.chars().collect();
    let shown: String = chars[..120]
        .iter()
        .chain(['.', '.', '.'].iter())
        .chain(&chars[chars.len() - 120..])
        .collect();
    check(
        e,
        format!("{inline}:17: objects[0].file: cannot read OBJ file {shown}: File name too long (os error 36)"),
    );
    // XML tag and attribute names, and a value echoed in quotes.
    let xml = |body: String| {
        let text = format!(
            "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/></sensor>\n{body}\n</scene>\n"
        );
        lancer::scene::load_str(&text, std::path::Path::new("case.xml"))
            .unwrap_err()
            .to_string()
    };
    check(
        xml(format!("<{}/>", long('c'))),
        format!(
            "case.xml:3: <{c}>: unsupported element <{c}> in <scene>; lancer reads: default, \
             path, texture, integrator, sensor, sampler, bsdf, shape, emitter",
            c = cut('c')
        ),
    );
    check(
        xml(format!("<shape type=\"sphere\" {}=\"1\"/>", long('d'))),
        format!(
            "case.xml:3: <shape type=\"sphere\">: attribute `{}`: unsupported attribute of \
             <shape>; lancer reads: type, id, name",
            cut('d')
        ),
    );
    check(
        xml(format!(
            "<shape type=\"sphere\"><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"-1,{}0,0\"/></bsdf></shape>",
            " ".repeat(BIG)
        )),
        format!(
            "case.xml:3: <rgb name=\"reflectance\">: attribute `value`: colour components must \
             be >= 0, got \"-1,{}...\"",
            " ".repeat(37)
        ),
    );
    // A `.mtl` statement's text, and a material's name.
    let dir = tempfile::tempdir().unwrap();
    let obj = "mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
    let mtl_path = dir.path().join("mesh.mtl");
    let scene = dir.path().join("scene.toml");
    check(
        load_obj_mtl(dir.path(), obj, &format!("newmtl red\nKd {}\n", long('e'))).unwrap_err(),
        format!(
            "{}:14: objects[0].file: {}:2: `Kd`: expected `r g b` (three numbers), got `{}`",
            scene.display(),
            mtl_path.display(),
            cut('e')
        ),
    );
    let name = long('f');
    check(
        load_obj_mtl(
            dir.path(),
            &obj.replace("usemtl red", &format!("usemtl {name}")),
            &format!("newmtl {name}\nKd -1 0 0\n"),
        )
        .unwrap_err(),
        format!(
            "{}:14: objects[0].file: {}:2: `Kd` of material `{}` must be finite and >= 0, got -1 0 0",
            scene.display(),
            mtl_path.display(),
            cut('f')
        ),
    );
    assert_eq!(seen.len(), 8);
}
