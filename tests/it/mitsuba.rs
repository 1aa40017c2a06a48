//! Mitsuba 3 XML scenes (docs/mitsuba.md): every unsupported element or
//! attribute gets its own message naming the element, the attribute and the
//! line; `<default>` and `$name`; the conversions of Mitsuba's shapes,
//! camera and BSDFs to lancer's; a PLY mesh renders bit for bit like its OBJ
//! twin; `lancer convert` writes a TOML scene that renders bit for bit like
//! the XML. (The z-test of scenes/cornell.xml against Mitsuba is in
//! tests/it/reference.rs.)

use crate::common;

use common::*;
use glam::Vec3;
use lancer::scene::{
    conductor_preset, conductor_preset_names, load_str, load_str_with, ColorSource, ComplexIor,
    MaterialKind, Microfacet, RenderOverrides, Scene, Sides,
};
use std::path::Path;

/// The lines every case starts with (the body starts on line 6).
const HEAD: &str = r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>"#;

/// A scene of `HEAD`, then `body` (line 6).
fn doc(body: &str) -> String {
    format!("{HEAD}\n  {body}\n</scene>\n")
}

fn load_xml(text: &str) -> Result<Scene, String> {
    load_str(text, Path::new("case.xml")).map_err(|e| e.to_string())
}

fn load_ok(text: &str) -> Scene {
    load_xml(text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// `rr_depth` of the path integrator starts lancer's roulette at the same
/// hit as Mitsuba's (Mitsuba's default 5 when unstated), and `lancer
/// convert` keeps it: stated in the TOML it writes where it is not the
/// TOML default (5 too), and the same after reading it back.
#[test]
fn rr_depth_is_read_and_kept_by_convert() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (integrator, rr_depth) in [
        (
            r#"<integrator type="path"><integer name="rr_depth" value="2"/></integrator>"#,
            2,
        ),
        ("", 5),
    ] {
        let s = load_ok(&doc(integrator));
        assert_eq!(s.render.rr_depth, rr_depth);
        let out = dir.path().join(format!("rr{rr_depth}.toml"));
        for (path, bytes) in lancer::scene::to_toml(&s, &out) {
            std::fs::write(&path, bytes).unwrap();
        }
        let text = std::fs::read_to_string(&out).unwrap();
        let stated = text.contains(&format!("rr_depth = {rr_depth}\n"));
        assert_eq!(
            stated,
            rr_depth != lancer::scene::DEFAULT_RR_DEPTH,
            "{text}"
        );
        let back = lancer::scene::load(&out).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back.render.rr_depth, rr_depth);
    }
}

/// The other path tracers of Mitsuba 3.9.1 load as `path` with their own
/// defaults: `prb` and `prb_projective` stop at 6 segments unless told,
/// and all four start the roulette one vertex after `path` for the same
/// `rr_depth`, since they test it before counting the vertex; their
/// derivative settings are read and ignored; `hide_emitters` is kept where
/// it hides no area emitter.
#[test]
fn other_path_tracers_load_as_path_with_their_defaults() {
    for (integrator, max_depth, rr_depth) in [
        (r#"<integrator type="prb"/>"#, 6, 6),
        (
            r#"<integrator type="prb"><integer name="max_depth" value="-1"/><integer name="rr_depth" value="2"/></integrator>"#,
            1_000_000,
            3,
        ),
        (
            r#"<integrator type="prb_projective"><integer name="sppc" value="8"/><integer name="sppp" value="8"/><integer name="sppi" value="8"/><string name="guiding" value="grid"/><boolean name="guiding_proj" value="false"/><integer name="guiding_rounds" value="2"/><string name="project_seed" value="bsdf"/></integrator>"#,
            6,
            6,
        ),
        (r#"<integrator type="volpath"/>"#, 1_000_000, 6),
        (
            r#"<integrator type="volpathmis"><integer name="max_depth" value="9"/></integrator>"#,
            9,
            6,
        ),
        (
            r#"<integrator type="volpath"><integer name="sampling_mode" value="0"/><integer name="rr_depth" value="1"/></integrator>"#,
            1_000_000,
            2,
        ),
        (
            r#"<integrator type="direct_projective"><integer name="max_depth" value="-1"/><string name="project_seed" value="emitter"/></integrator>"#,
            2,
            6,
        ),
        (r#"<integrator type="path"/>"#, 1_000_000, 5),
    ] {
        let s = load_ok(&doc(integrator));
        assert_eq!(
            (
                s.render.max_depth,
                s.render.rr_depth,
                s.render.hide_emitters
            ),
            (max_depth, rr_depth, false),
            "{integrator}"
        );
    }
    for kind in ["volpath", "prb_projective", "prb", "direct_projective"] {
        let s = load_ok(&doc(&format!(
            r#"<integrator type="{kind}"><boolean name="hide_emitters" value="true"/></integrator><emitter type="constant"/>"#
        )));
        assert!(s.render.hide_emitters, "{kind}");
    }
    let s = load_ok(&doc(
        r#"<integrator type="prb"><boolean name="hide_emitters" value="true"/></integrator><shape type="sphere"><emitter type="area"/></shape>"#,
    ));
    assert!(s.render.hide_emitters);
}

/// `direct`'s sample counts: without emitter samples the scene asks for
/// BSDF sampling alone, without BSDF samples for emitter sampling alone, and
/// delta lights count `emitter_samples` times, as Mitsuba counts them.
#[test]
fn direct_sample_counts_choose_the_estimator() {
    for (counts, bsdf_only, emitter_only, gain) in [
        ("", false, false, 1),
        (
            r#"<integer name="emitter_samples" value="0"/>"#,
            true,
            false,
            1,
        ),
        (
            r#"<integer name="emitter_samples" value="0"/><integer name="bsdf_samples" value="3"/>"#,
            true,
            false,
            1,
        ),
        (
            r#"<integer name="bsdf_samples" value="0"/>"#,
            false,
            true,
            1,
        ),
        (
            r#"<integer name="emitter_samples" value="4"/>"#,
            false,
            false,
            4,
        ),
        (
            r#"<integer name="shading_samples" value="2"/>"#,
            false,
            false,
            2,
        ),
    ] {
        let s = load_ok(&doc(&format!(
            r#"<integrator type="direct">{counts}</integrator>"#
        )));
        let r = &s.render;
        assert_eq!(
            (
                r.bsdf_sampling_only,
                r.emitter_sampling_only,
                r.delta_light_gain,
                r.max_depth
            ),
            (bsdf_only, emitter_only, gain, 2),
            "{counts}"
        );
    }
}

/// A BSDF or texture that no shape uses cannot change the image: what
/// lancer cannot read in it is a warning (as in the tutorials' Lego scene,
/// whose unused `main-bsdf` holds a volume texture), while the same BSDF
/// used by a shape is refused. `name` is read and ignored on every plugin,
/// as Mitsuba does outside a nested property.
#[test]
fn unused_plugins_warn_where_used_ones_are_refused() {
    let unused = r#"<bsdf type="diffuse" id="main-bsdf"><texture type="volume" name="reflectance"/></bsdf>
  <texture type="volume" id="vol"/>
  <shape type="sphere" name="ball"><bsdf type="diffuse" name="bsdf"/></shape>"#;
    let s = load_ok(&doc(unused));
    assert_eq!(s.spheres.len(), 1);
    assert_eq!(s.warnings.len(), 2, "{:?}", s.warnings);
    for (w, tag) in s.warnings.iter().zip(["bsdf", "texture"]) {
        assert!(
            w.contains(r#"unsupported texture type "volume""#)
                && w.ends_with(&format!(
                    "(no shape uses this <{tag}>, so lancer leaves it out)"
                )),
            "{w}"
        );
    }
    let used = format!(r#"{unused}<shape type="sphere"><ref id="main-bsdf"/></shape>"#);
    let e = load_xml(&doc(&used)).expect_err("a used BSDF with a volume texture");
    assert!(
        e.contains(r#"case.xml:6: <texture type="volume" name="reflectance">: attribute `type`: unsupported texture type "volume""#),
        "{e}"
    );
    let named = load_ok(&doc(
        r#"<integrator type="direct_projective" name="integrator" id="integrator"/><emitter type="point" name="light"/>"#,
    ));
    assert_eq!((named.render.max_depth, named.lights.len()), (2, 1));
}

/// Mitsuba's `moment` integrator renders the image of the one it nests
/// (its second moments go to extra channels), as Mitsuba's render tests
/// use it; a top-level `<sampler id>` is read where the sensor refers to
/// it, as Mitsuba's plugin gallery writes it.
#[test]
fn moment_integrators_and_sampler_refs_are_read() {
    let s = load_ok(&doc(
        r#"<integrator type="moment"><integrator type="path"><integer name="max_depth" value="3"/></integrator></integrator>"#,
    ));
    assert_eq!(s.render.max_depth, 3);
    let s = load_ok(&doc(
        r#"<integrator type="moment"><integrator type="moment"><integrator type="prb"/></integrator></integrator>"#,
    ));
    assert_eq!(s.render.max_depth, 6);
    for (body, message) in [
        (
            r#"<integrator type="moment"/>"#,
            r#"case.xml:6: <integrator type="moment">: a moment integrator with no nested <integrator>; nest the one to render"#,
        ),
        (
            r#"<integrator type="moment"><integrator type="path"/><integrator type="direct"/></integrator>"#,
            r#"case.xml:6: <integrator type="direct">: a second integrator in moment: Mitsuba renders each into channels of its own, lancer renders one image; keep one"#,
        ),
    ] {
        assert_eq!(load_xml(&doc(body)).expect_err(body), message);
    }
    let scene = |sensor_extra: &str| {
        format!(
            r#"<scene version="3.0.0">
  <sampler type="independent" id="my_sampler"><integer name="sample_count" value="16"/><integer name="seed" value="7"/></sampler>
  <sensor type="perspective">
    <ref id="my_sampler"/>{sensor_extra}
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
</scene>
"#
        )
    };
    let s = load_ok(&scene(""));
    assert_eq!((s.render.spp, s.render.seed), (16, 7));
    assert_eq!(
        load_xml(&scene(r#"<sampler type="independent"/>"#)).expect_err("two samplers"),
        r#"case.xml:4: <sampler type="independent">: a second <sampler> for the sensor; give one"#
    );
}

/// A top-level `<emitter type="area" id>` that a shape names by `<ref id>`
/// is that shape's emitter, as if nested (Mitsuba's plugin gallery writes
/// its lights so); one no shape names, or two shapes name, is refused as
/// Mitsuba refuses it.
#[test]
fn area_emitters_by_reference_are_the_shapes_own() {
    let nested = load_ok(&doc(r#"<bsdf type="diffuse" id="white"/>
  <shape type="rectangle"><ref id="white"/><emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter></shape>"#));
    let by_ref = load_ok(&doc(r#"<bsdf type="diffuse" id="white"/>
  <shape type="rectangle"><ref id="white"/><ref id="light"/></shape>
  <emitter type="area" id="light"><rgb name="radiance" value="3, 2, 1"/></emitter>"#));
    let look = |s: &Scene| {
        (s.materials.iter())
            .map(|m| format!("{:?} {:?} {:?}", m.kind, m.emission, m.sides))
            .collect::<Vec<_>>()
    };
    assert_eq!(look(&nested), look(&by_ref));
    assert_eq!(
        format!("{:?}", nested.triangles),
        format!("{:?}", by_ref.triangles)
    );
    assert_eq!(
        nested
            .materials
            .iter()
            .filter(|m| m.emission.max_element() > 0.0)
            .count(),
        1
    );
    for (body, message) in [
        (
            r#"<emitter type="area" id="light"/><shape type="sphere"/>"#,
            r#"case.xml:6: <emitter type="area" id="light">: a top-level area emitter that no shape refers to; Mitsuba attaches an area emitter to a shape: add <ref id="..."/> to one shape, or nest the emitter in it"#,
        ),
        (
            r#"<emitter type="area" id="light"/><shape type="sphere"><ref id="light"/></shape><shape type="disk"><ref id="light"/></shape>"#,
            r#"case.xml:6: <emitter type="area" id="light">: an area emitter that several shapes refer to; Mitsuba attaches an area emitter to one shape only: give each shape its own"#,
        ),
        (
            r#"<emitter type="area" id="light"/><shape type="sphere"><ref id="light"/><emitter type="area"/></shape>"#,
            r#"case.xml:6: <emitter type="area">: a second <emitter> for a shape; give one"#,
        ),
    ] {
        assert_eq!(load_xml(&doc(body)).expect_err(body), message);
    }
}

/// A cylinder is the open tube of `radius` from `p0` to `p1` as a prism
/// whose area is the tube's, its corners' normals Mitsuba's (outwards,
/// across the axis), u running once round it from the x axis of Mitsuba's
/// frame about p1 - p0 and v along it.
#[test]
fn cylinders_are_prisms_of_the_tubes_area() {
    let scene = load_ok(&doc(
        r#"<shape type="cylinder"><float name="radius" value="0.5"/><point name="p0" x="1" y="0" z="0"/><point name="p1" x="1" y="2" z="0"/></shape>"#,
    ));
    let area: f64 = (scene.triangles.iter())
        .map(|t| {
            let [a, b, c] = t.p.map(|p| p.as_dvec3());
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    let tube = std::f64::consts::TAU * 0.5 * 2.0;
    assert!((area / tube - 1.0).abs() < 1e-6, "area {area}, tube {tube}");
    for t in &scene.triangles {
        let n = t.n.expect("the corners' normals");
        for (p, n) in t.p.iter().zip(n) {
            // Outwards from the axis x = 1, z = 0, across it
            let radial = glam::Vec3::new(p.x - 1.0, 0.0, p.z).normalize();
            assert!(n.dot(radial) > 1.0 - 1e-6 && n.y.abs() < 1e-6, "{p} {n}");
        }
        // The front side is outwards
        let [a, b, c] = t.p;
        assert!((b - a).cross(c - a).dot(n[0]) > 0.0);
        for uv in t.uv.expect("texture coordinates") {
            assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y));
        }
    }
    // Mitsuba's frame about +y (its coordinate_system) has its x axis
    // along +x: u = 0 lies there
    for t in &scene.triangles {
        for (p, uv) in t.p.iter().zip(t.uv.unwrap()) {
            if uv.x == 0.0 {
                assert!(p.x > 1.4 && p.z.abs() < 1e-6, "u = 0 at {p}");
            }
        }
    }
    assert_eq!(scene.triangles.len(), 2 * 256);
}

#[test]
fn every_unsupported_element_or_attribute_has_its_message() {
    let checker = repo("scenes/tex/checker.png");
    let checker = checker.display();
    let cases: Vec<(String, String)> = [
        (r#"<shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="x.png"/><string name="format" value="half"/></texture></bsdf></shape>"#, r#"case.xml:6: <string name="format">: attribute `value`: unknown bitmap format "half"; Mitsuba reads: auto, variant, float16, fp16, uint8"#),
        (r#"<shape type="sphere"><bsdf type="pplastic"/></shape>"#, r#"case.xml:6: <bsdf type="pplastic">: attribute `type`: unsupported bsdf type "pplastic"; lancer reads: diffuse, conductor, roughconductor, dielectric, roughdielectric, thindielectric, plastic, roughplastic, twosided, mask, normalmap, bumpmap, blendbsdf, principled"#),
        (r#"<shape type="sphere"><bsdf type="principled"><float name="spec_trans" value="0.4"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="principled">: a principled BSDF's specular transmission (`spec_trans` other than 0) is outside the subset lancer reads; give spec_trans 0, or use a roughdielectric"#),
        (r#"<shape type="sphere"><bsdf type="principled"><float name="eta" value="1.4"/><float name="specular" value="0.5"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="principled">: give either `eta` or `specular`, not both (Mitsuba refuses it too: "either use eta or specular")"#),
        (r#"<shape type="sphere"><bsdf type="principled"><texture type="checkerboard" name="spec_trans"/></bsdf></shape>"#, r#"case.xml:6: <texture type="checkerboard" name="spec_trans">: a textured `spec_trans` is outside the subset lancer reads; give a <float>"#),
        (r#"<shape type="sphere"><bsdf type="principled"><texture type="checkerboard" name="metallic"/><float name="main_specular_sampling_rate" value="0"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="principled">: every lobe of this principled BSDF has sampling rate 0 (or weight 0): give one a rate > 0"#),
        (r#"<shape type="sphere"><bsdf type="principled"><float name="metallic" value="1.5"/></bsdf></shape>"#, r#"case.xml:6: <float name="metallic">: attribute `value`: `metallic` must be a number from 0 to 1, got "1.5""#),
        (r#"<shape type="sphere"><bsdf type="principled"><float name="metallic" value="1"/><float name="main_specular_sampling_rate" value="0"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="principled">: every lobe of this principled BSDF has sampling rate 0 (or weight 0): give one a rate > 0"#),
        (r#"<shape type="sphere"><bsdf type="twosided"><bsdf type="principled"><rgb name="base_color" value="0.5"/><float name="eta" value="0"/></bsdf></bsdf></shape>"#, r#"case.xml:6: <bsdf type="principled">: `eta` must be > 0, got 0"#),
        (r#"<shape type="sphere"><bsdf type="blendbsdf"><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="blendbsdf">: a blendbsdf needs its `weight` (<float name="weight">, or a texture); Mitsuba has no default"#),
        (r#"<shape type="sphere"><bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="blendbsdf">: a blendbsdf needs two nested <bsdf> or <ref> (Mitsuba: "Two child BSDFs must be specified"), got 1"#),
        (r#"<shape type="sphere"><bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/><bsdf type="roughdielectric"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughdielectric">: a transmitting BSDF inside a blendbsdf is outside the subset lancer reads"#),
        (r#"<shape type="sphere"><bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/><bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf></bsdf></shape>"#, r#"case.xml:6: <bsdf type="blendbsdf">: a blendbsdf inside a blendbsdf is outside the subset lancer reads"#),
        (r#"<shape type="sphere"><bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/><bsdf type="mask"><bsdf type="diffuse"/></bsdf></bsdf></shape>"#, r#"case.xml:6: <bsdf type="mask">: a mask, normalmap or bumpmap inside a blendbsdf is outside the subset lancer reads; put it around the blendbsdf"#),
        (r#"<shape type="sphere"><bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></bsdf></shape>"#, r#"case.xml:6: <bsdf type="blendbsdf">: one component of the blendbsdf is twosided and the other is not, so the blend is half two-sided, which lancer does not copy; wrap both in twosided, or put one twosided around the blendbsdf"#),
        (r#"<shape type="sphere"><bsdf type="twosided"><bsdf type="thindielectric"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="thindielectric">: a dielectric cannot be two-sided (Mitsuba refuses it too); remove the twosided wrapper"#),
        (r#"<shape type="sphere"><bsdf type="roughplastic"><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.2"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughplastic">: a roughplastic's roughness is isotropic (Mitsuba refuses alpha_u != alpha_v too); give one `alpha`"#),
        (r#"<shape type="sphere"><bsdf type="roughplastic"><float name="int_ior" value="1.2"/><float name="ext_ior" value="1.2"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughplastic">: int_ior and ext_ior must be > 0 and differ (Mitsuba refuses it too), got 1.2 and 1.2"#),
        (r#"<shape type="sphere"><bsdf type="plastic"><texture type="bitmap" name="diffuse_reflectance"/></bsdf></shape>"#, r#"case.xml:6: <texture type="bitmap" name="diffuse_reflectance">: missing property <string name="filename">"#),
        (r#"<shape type="sphere"><bsdf type="roughdielectric"><float name="int_ior" value="1.2"/><float name="ext_ior" value="1.2"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughdielectric">: int_ior and ext_ior must be > 0 and differ (Mitsuba refuses it too), got 1.2 and 1.2"#),
        (r#"<shape type="sphere"><bsdf type="roughdielectric"><string name="int_ior" value="glass"/></bsdf></shape>"#, r#"case.xml:6: <string name="int_ior">: attribute `value`: unknown index of refraction "glass"; give a number or one of Mitsuba's names: vacuum, helium, hydrogen, air, carbon dioxide, water, acetone, ethanol, carbon tetrachloride, glycerol, benzene, silicone oil, bromine, water ice, fused quartz, pyrex, acrylic glass, polypropylene, bk7, sodium chloride, amber, pet, diamond"#),
        (r#"<shape type="sphere"><bsdf type="twosided"><bsdf type="roughdielectric"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughdielectric">: a dielectric cannot be two-sided (Mitsuba refuses it too); remove the twosided wrapper"#),
        (r#"<shape type="sphere"><bsdf type="roughplastic"><texture type="checkerboard" name="alpha"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughplastic">: a roughplastic's roughness is a plain number (Mitsuba reads no texture there either); give a <float name="alpha">"#),
        (r#"<shape type="sphere"><bsdf type="conductor"><string name="material" value="Au"/><rgb name="eta" value="1"/></bsdf></shape>"#, r#"case.xml:6: <rgb name="eta">: the BSDF also names a `material` preset; give either eta and k or material, not both (Mitsuba refuses it too)"#),
        (r#"<shape type="sphere"><bsdf type="roughconductor"><float name="alpha_u" value="0.1"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughconductor">: an anisotropic roughness needs both `alpha_u` and `alpha_v` (Mitsuba refuses one alone)"#),
        (r#"<shape type="sphere"><bsdf type="roughconductor"><float name="alpha" value="0.1"/><float name="alpha_v" value="0.1"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughconductor">: give either `alpha` or `alpha_u` and `alpha_v`, not both (Mitsuba refuses it too)"#),
        (r#"<shape type="sphere"><bsdf type="roughconductor"><string name="distribution" value="phong"/></bsdf></shape>"#, r#"case.xml:6: <string name="distribution">: attribute `value`: unknown distribution "phong"; Mitsuba has "beckmann" and "ggx""#),
        (r#"<shape type="sphere"><bsdf type="roughconductor"><texture type="checkerboard" name="alpha"/><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.1"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="roughconductor">: give either `alpha` or `alpha_u` and `alpha_v`, not both (Mitsuba refuses it too)"#),
        (r#"<shape type="cone"/>"#, r#"case.xml:6: <shape type="cone">: attribute `type`: unsupported shape type "cone"; lancer reads: sphere, rectangle, cube, disk, cylinder, obj, ply, serialized, shapegroup, instance"#),
        (r#"<shape type="cylinder"><point name="p1" x="0" y="0" z="0"/></shape>"#, r#"case.xml:6: <shape type="cylinder">: a cylinder needs p0 and p1 apart and a radius other than 0, got length 0 and radius 1"#),
        (r#"<shape type="instance"><shape type="shapegroup"><shape type="cube"/></shape></shape>"#, r#"case.xml:6: <shape type="shapegroup">: a shapegroup nested in an instance, which Mitsuba 3.9.1 fails to load ("Couldn't find key"); make it a top-level <shape type="shapegroup" id="..."> and name it here by <ref id="..."/>"#),
        (r#"<shape type="shapegroup" id="g"><shape type="instance"><ref id="g"/></shape></shape><shape type="instance"><ref id="g"/></shape>"#, r#"case.xml:6: <shape type="instance">: an instance ("Nested instancing is not permitted") inside a shapegroup: Mitsuba refuses it; keep shapegroups and instances at the top level"#),
        (r#"<shape type="shapegroup" id="g"><shape type="cube"><emitter type="area"/></shape></shape><shape type="instance"><ref id="g"/></shape>"#, r#"case.xml:6: <emitter type="area">: an area emitter on a shape of a shapegroup (line 6): Mitsuba instances no emitter ("Instancing of emitters is not supported"); move this shape out of the group, and place a copy of it per instance"#),
        (r#"<shape type="instance"/>"#, r#"case.xml:6: <shape type="instance">: an instance without a shapegroup: add <ref id="..."/> naming a <shape type="shapegroup" id="...">"#),
        (r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/><bsdf type="diffuse"/></shape>"#, r#"case.xml:6: <bsdf type="diffuse">: a <bsdf> on an instance: Mitsuba takes an instance's materials and emitters from the shapes of its group ("Only a shapegroup can be specified in an instance"); put it on the group's shapes"#),
        (r#"<shape type="shapegroup" id="g"><shape type="sphere"/></shape><shape type="instance"><ref id="g"/><transform name="to_world"><scale x="2"/></transform></shape>"#, r#"case.xml:6: <shape type="instance">: property `to_world` of the instance scales non-uniformly or shears, and its group holds a sphere: Mitsuba intersects the sphere in the group's space, which makes it an ellipsoid, and lancer's spheres are round; scale the instance uniformly, or use a sphere mesh (obj or ply) in the group"#),
        (r#"<shape type="shapegroup" id="g"><shape type="cube"><bsdf type="roughconductor" id="brushed"><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/></bsdf></shape></shape><shape type="instance"><ref id="g"/><transform name="to_world"><rotate z="1" angle="10"/></transform></shape>"#, r#"case.xml:6: <shape type="instance">: the instance turns or stretches an anisotropic material (`brushed`): Mitsuba 3.9.1 orients its tangent by the group's unmoved dp/du, which lancer does not copy; use alpha_u = alpha_v, or place the shape outside a shapegroup"#),
        (r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/><transform name="to_world"><scale x="0"/></transform></shape>"#, r#"case.xml:6: <shape type="instance">: property `to_world` of the instance is singular or not finite; give it an invertible transform"#),
        (r#"<bsdf type="diffuse" id="d"/><shape type="instance"><ref id="d"/></shape>"#, r#"case.xml:6: <ref id="d">: attribute `id`: "d" is a <bsdf> (line 6), where a <shape> is expected"#),
        (r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/><ref id="g"/></shape>"#, r#"case.xml:6: <ref id="g">: a second shapegroup in one instance; an instance places one group"#),
        (r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape><shape type="instance"><ref id="g"/><shape type="cube"/></shape>"#, r#"case.xml:6: <shape type="cube">: an instance holds one shapegroup and no other shape (Mitsuba: "Only a shapegroup can be specified in an instance"); put this shape in a <shape type="shapegroup" id="..."> and name it by <ref id="..."/>"#),
        (r#"<shape type="sphere"><float name="radiuss" value="1"/></shape>"#, r#"case.xml:6: <float name="radiuss">: property `radiuss` of <shape type="sphere"> is outside the subset lancer reads (docs/mitsuba.md); remove it"#),
        (r#"<shape type="sphere" foo="1"/>"#, r#"case.xml:6: <shape type="sphere">: attribute `foo`: unsupported attribute of <shape>; lancer reads: type, id, name"#),
        (r#"<include filename="other.xml"/>"#, r#"case.xml:6: <include>: included file "other.xml" not found (looked for other.xml)"#),
        (r#"<include file="other.xml"/>"#, r#"case.xml:6: <include>: attribute `file`: unsupported attribute of <include>; lancer reads: filename, name"#),
        (r#"<include filename="$part.xml"/>"#, r#"case.xml:6: <include>: attribute `filename`: `$part` has no value: add <default name="part" value="..."/> at the top of the scene (before this element: an <include> or <path> sees the <default>s above it, as in Mitsuba)"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.5, 400:0.2"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="reflectance">: attribute `value`: the wavelengths of a spectrum must increase, got 400 nm after 400 nm"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.5"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="reflectance">: attribute `value`: a spectrum of wavelength:value pairs needs at least two pairs"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.5, 500:-1"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="reflectance">: attribute `value`: a spectrum must be >= 0, got -1 at 500 nm"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.5, 500:x"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="reflectance">: attribute `value`: expected wavelength:value pairs of finite numbers separated by commas, got "500:x""#),
        (r#"<shape type="sphere"><bsdf type="conductor"><spectrum name="eta" filename="Cu.eta.spd"/><float name="k" value="2"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="eta">: attribute `filename`: a spectrum read from a file is outside the subset lancer reads; write it as wavelength:value pairs or as <rgb name="eta" value="r, g, b"/>"#),
        (r#"<shape type="sphere"><emitter type="area"><spectrum name="radiance" wavelengths="400, 700" values="1, 2"/></emitter></shape>"#, r#"case.xml:6: <spectrum name="radiance">: attribute `wavelengths`: a spectrum given by wavelengths and values is outside the subset lancer reads; write it as wavelength:value pairs or as <rgb name="radiance" value="r, g, b"/>"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="0.5, 0.6"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="reflectance">: attribute `value`: a spectrum of more than one number is outside the subset lancer reads; write it as wavelength:value pairs or as <rgb name="reflectance" value="r, g, b"/>"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="-0.5"/></bsdf></shape>"#, r#"case.xml:6: <spectrum name="reflectance">: attribute `value`: a spectrum must be >= 0, got "-0.5""#),
        (r#"<shape type="sphere"><spectrum name="center" value="1"/></shape>"#, r#"case.xml:6: <spectrum name="center">: property `center` of <shape> must be given as <point> or <vector>"#),
        (r#"<shape type="sphere"><bsdf type="conductor"><string name="material" value="Gold"/></bsdf></shape>"#, &format!(r#"case.xml:6: <string name="material">: attribute `value`: unknown conductor material "Gold"; Mitsuba's presets are: {}"#, conductor_preset_names().collect::<Vec<_>>().join(", "))),
        (r#"<emitter type="area"/>"#, r#"case.xml:6: <emitter type="area">: a top-level area emitter that no shape refers to; Mitsuba attaches an area emitter to a shape: add <ref id="..."/> to one shape, or nest the emitter in it"#),
        (r#"<emitter type="envmap"/>"#, r#"case.xml:6: <emitter type="envmap">: missing property <string name="filename"> (the latitude-longitude image)"#),
        (&format!(r#"<emitter type="envmap"><string name="filename" value="{checker}"/><transform name="to_world"><scale value="2"/></transform></emitter>"#), r#"case.xml:6: <emitter type="envmap">: property `to_world` of <emitter type="envmap"> scales or shears directions; Mitsuba reads the map with the transformed direction as if it had unit length, which lancer does not reproduce: keep to rotations (remove <scale> and non-orthogonal <matrix> steps)"#),
        (&format!(r#"<emitter type="envmap"><string name="filename" value="{checker}"/><float name="scale" value="-1"/></emitter>"#), r#"case.xml:6: <emitter type="envmap">: property `scale` must be >= 0 and finite, got -1"#),
        (&format!(r#"<emitter type="constant"><rgb name="radiance" value="1"/></emitter><emitter type="envmap"><string name="filename" value="{checker}"/></emitter>"#), r#"case.xml:6: <emitter type="envmap">: a second environment emitter (the first is on line 6); Mitsuba allows one constant or envmap emitter per scene, and so does lancer: remove one"#),
        (r#"<emitter type="envmap"><string name="filename" value="no_such_map.exr"/></emitter>"#, r#"case.xml:6: <string name="filename">: attribute `value`: cannot read the environment map no_such_map.exr: No such file or directory (os error 2)"#),
        (r#"<emitter type="point"><point name="position" value="0, 1, 0"/><transform name="to_world"><translate x="1"/></transform></emitter>"#, r#"case.xml:6: <point name="position">: give either `position` or `to_world`, not both (Mitsuba refuses both too)"#),
        (r#"<emitter type="spot"><float name="cutoff_angle" value="10"/><float name="beam_width" value="20"/></emitter>"#, r#"case.xml:6: <emitter type="spot">: beam_width: must be >= 0 and at most cutoff_angle (10 degrees), got 20"#),
        (r#"<integrator type="direct"><integer name="emitter_samples" value="0"/><integer name="bsdf_samples" value="0"/></integrator>"#, r#"case.xml:6: <integer name="emitter_samples">: emitter_samples and bsdf_samples are both 0: give at least one sample (Mitsuba refuses this too)"#),
        (r#"<integrator type="direct"><integer name="shading_samples" value="2"/><integer name="bsdf_samples" value="0"/></integrator>"#, r#"case.xml:6: <integer name="shading_samples">: give either shading_samples or emitter_samples and bsdf_samples, not both (Mitsuba refuses both too)"#),
        (r#"<emitter type="spot"><rgb name="texture" value="0.5"/></emitter>"#, r#"case.xml:6: <emitter type="spot">: a spot light's `texture` must be an image (a <texture>), as Mitsuba requires; scale its `intensity` instead"#),
        (r#"<emitter type="projector"><float name="fov" value="180"/></emitter>"#, r#"case.xml:6: <emitter type="projector">: fov must be > 0 and < 180 degrees, got 180"#),
        (r#"<emitter type="projector"><float name="fov" value="30"/><string name="focal_length" value="50mm"/></emitter>"#, r#"case.xml:6: <string name="focal_length">: give either a focal length (focal_length) or a field of view (fov), not both"#),
        (r#"<shape type="sphere"><emitter type="spot"/></shape>"#, r#"case.xml:6: <emitter type="spot">: attribute `type`: unsupported emitter type "spot"; lancer reads: area"#),
        (r#"<integrator type="ptracer"/>"#, r#"case.xml:6: <integrator type="ptracer">: attribute `type`: unsupported integrator type "ptracer"; lancer reads: path, direct, volpath, volpathmis, prb, prb_projective, direct_projective"#),
        (r#"<integrator type="volpath"><integer name="sampling_mode" value="1"/></integrator>"#, r#"case.xml:6: <integer name="sampling_mode">: attribute `value`: sampling_mode 1 is not read: lancer samples emitters and BSDFs by MIS (sampling_mode 0, the default); remove it"#),
        (r#"<integrator type="prb_projective"><string name="guiding" value="tree"/></integrator>"#, r#"case.xml:6: <string name="guiding">: attribute `value`: unknown guiding "tree"; Mitsuba has "none", "grid" and "octree""#),
        (r#"<integrator type="volpath"><boolean name="hide_emitters" value="true"/></integrator><shape type="sphere"><emitter type="area"/></shape>"#, r#"case.xml:6: <integrator type="volpath">: hide_emitters with an area emitter in the scene is not supported here: volpath's hide_emitters stops a camera ray at an area emitter and shows its surface without the emission, where lancer follows path, which shows what lies behind it; use <integrator type="path"> (the same image where no emitter is hidden), or remove hide_emitters"#),
        (r#"<integrator type="prb"><integer name="rr_depth" value="4294967295"/></integrator>"#, r#"case.xml:6: <integer name="rr_depth">: attribute `value`: rr_depth must be from 1 to 4294967294, got 4294967295"#),
        (r#"<shape type="sphere"><transform name="to_world"><matrix value="1 2 3"/></transform></shape>"#, "case.xml:6: <matrix>: attribute `value`: expected 16 (4x4, row by row) or 9 (3x3) finite numbers"),
        (r#"<shape type="sphere"><float name="radius" value="$r"/></shape>"#, r#"case.xml:6: <float name="radius">: attribute `value`: `$r` has no value: add <default name="r" value="..."/> at the top of the scene"#),
        (r#"<shape type="sphere"><bsdf type="twosided"><bsdf type="dielectric"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="dielectric">: a dielectric cannot be two-sided (Mitsuba refuses it too); remove the twosided wrapper"#),
        (r#"<shape type="obj"><string name="filename" value="cube.obj"/><boolean name="flip_tex_coords" value="false"/></shape>"#, r#"case.xml:6: <shape type="obj">: flip_tex_coords = false is not supported: lancer reads OBJ texture coordinates as OBJ defines them"#),
        (r#"<integrator type="path"><integer name="max_depth" value="0"/></integrator>"#, r#"case.xml:6: <integer name="max_depth">: attribute `value`: max_depth must be -1 (no limit) or from 1 to 4294967295, got 0"#),
        (r#"<integrator type="path"><integer name="rr_depth" value="0"/></integrator>"#, r#"case.xml:6: <integer name="rr_depth">: attribute `value`: rr_depth must be from 1 to 4294967295, got 0"#),
        (r#"<shape type="sphere"><ref id="nope"/></shape>"#, r#"case.xml:6: <ref id="nope">: attribute `id`: no <bsdf id="nope"> in the scene; defined: none"#),
        (r#"<shape type="sphere"><transform name="to_world"><shear value="1"/></transform></shape>"#, "case.xml:6: <shear>: unsupported transform step <shear>; lancer reads: translate, rotate, scale, matrix, lookat"),
        (r#"<shape type="sphere"><float name="radius" value="abc"/></shape>"#, r#"case.xml:6: <float name="radius">: attribute `value`: expected a finite number, got "abc""#),
        (r#"<shape type="sphere"><integer name="radius" value="2"/><float name="radius" value="1"/></shape>"#, r#"case.xml:6: <float name="radius">: property `radius` is given twice; give it once"#),
        (r#"<shape type="sphere"><string name="radius" value="1"/></shape>"#, "case.xml:6: <string name=\"radius\">: property `radius` of <shape> must be given as <float> or <integer>"),
        (&format!(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{checker}"/><string name="filter_type" value="bicubic"/></texture></bsdf></shape>"#), r#"case.xml:6: <string name="filter_type">: attribute `value`: unknown filter_type "bicubic"; Mitsuba has "bilinear" and "nearest""#),
        (&format!(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{checker}"/><string name="wrap_mode" value="border"/></texture></bsdf></shape>"#), r#"case.xml:6: <string name="wrap_mode">: attribute `value`: unknown wrap_mode "border"; Mitsuba has "repeat", "mirror" and "clamp""#),
        (&format!(r#"<shape type="sphere"><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"><texture type="bitmap" name="color0"><string name="filename" value="{checker}"/></texture></texture></bsdf></shape>"#), r#"case.xml:6: <texture type="bitmap" name="color0">: a textured `color0` of a checkerboard is outside the subset lancer reads; give an <rgb> or a <float>"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><texture type="volume" name="reflectance"/></bsdf></shape>"#, r#"case.xml:6: <texture type="volume" name="reflectance">: attribute `type`: unsupported texture type "volume"; lancer reads: bitmap, checkerboard, mesh_attribute"#),
        (r#"<shape type="sphere"><bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"/></bsdf></shape>"#, r#"case.xml:6: <texture type="mesh_attribute" name="reflectance">: missing property <string name="name">"#),
        (r#"<shape type="sphere"><emitter type="area"><rgb name="radiance" value="1, 2"/></emitter></shape>"#, r#"case.xml:6: <rgb name="radiance">: attribute `value`: expected "r, g, b" or one number, got "1, 2""#),
        (r#"<shape type="sphere"><bsdf type="dielectric"><rgb name="specular_reflectance" value="0.5"/></bsdf></shape>"#, r#"case.xml:6: <bsdf type="dielectric">: specular_reflectance other than 1 is not supported: lancer's dielectric reflects by exact Fresnel only"#),
        (r#"<sensor type="perspective"><float name="fov" value="30"/></sensor>"#, r#"case.xml:6: <sensor type="perspective">: a second <sensor>; lancer renders one camera"#),
        (r#"<bsdf type="diffuse"/>"#, r#"case.xml:6: <bsdf type="diffuse">: a top-level <bsdf> needs an `id` for <ref id="..."/>"#),
    ]
    .iter()
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    // Cases in the sensor (lines 2 to 5) and the scene element itself.
    let sensor = |extra: &str, film: &str| {
        format!(
            "<scene version=\"3.0.0\">\n  <sensor type=\"perspective\">\n    <float name=\"fov\" value=\"40\"/>\n    {extra}\n    <film type=\"hdrfilm\">{film}</film>\n  </sensor>\n</scene>\n"
        )
    };
    let whole: Vec<(String, String)> = vec![
        (sensor(r#"<float name="near_clip" value="0"/>"#, ""), r#"case.xml:2: <sensor type="perspective">: near_clip must be > 0 and below far_clip (a finite number), got 0 and 10000"#.into()),
        (sensor(r#"<float name="near_clip" value="5"/><float name="far_clip" value="4"/>"#, ""), r#"case.xml:2: <sensor type="perspective">: near_clip must be > 0 and below far_clip (a finite number), got 5 and 4"#.into()),
        (sensor(r#"<float name="principal_point_offset_x" value="1e300"/>"#, ""), r#"case.xml:2: <sensor type="perspective">: principal_point_offset (1e300, 0e0) must move the image by less than a million image widths"#.into()),
        (sensor(r#"<string name="focal_length" value="35mm"/>"#, ""), r#"case.xml:4: <string name="focal_length">: give either a focal length (focal_length) or a field of view (fov), not both"#.into()),
        (sensor(r#"<float name="shutter_open" value="1"/>"#, ""), r#"case.xml:2: <sensor type="perspective">: shutter_close must be >= shutter_open, got 0 and 1"#.into()),
        (sensor("", r#"<rfilter type="box"><float name="radius" value="2"/></rfilter>"#), r#"case.xml:5: <float name="radius">: property `radius` of <rfilter type="box"> is outside the subset lancer reads (docs/mitsuba.md); remove it"#.into()),
        (sensor(r#"<ref id="my_sampler"/>"#, ""), r#"case.xml:4: <ref id="my_sampler">: attribute `id`: no element with id "my_sampler" in the scene, which <sensor type="perspective"> refers to; define it (e.g. <sampler id="my_sampler"> for a sensor's sampler) or remove the <ref>"#.into()),
        (sensor("", r#"<rfilter type="gaussian"><float name="stddev" value="0"/></rfilter>"#), r#"case.xml:5: <rfilter type="gaussian">: stddev must be > 0 and at most 4 pixels, got 0"#.into()),
        (sensor("", r#"<rfilter type="lanczos"><integer name="lobes" value="0"/></rfilter>"#), r#"case.xml:5: <rfilter type="lanczos">: lobes must be an integer from 1 to 16, got 0"#.into()),
        (sensor("", r#"<integer name="crop_offset_x" value="766"/><integer name="crop_width" value="4"/>"#), r#"case.xml:5: <film type="hdrfilm">: the crop window (4 x 576 at 766, 0) reaches past the film (768 x 576); Mitsuba refuses it too"#.into()),
        (sensor("", r#"<integer name="crop_height" value="0"/>"#), r#"case.xml:5: <integer name="crop_height">: attribute `value`: must be an integer from 1 to 4294967295, got 0"#.into()),
        (sensor("", r#"<string name="pixel_format" value="luminance"/>"#), r#"case.xml:5: <string name="pixel_format">: attribute `value`: pixel_format must be rgb or rgba, got "luminance""#.into()),
        (sensor(r#"<string name="fov_axis" value="z"/>"#, ""), r#"case.xml:4: <string name="fov_axis">: attribute `value`: fov_axis must be x, y, diagonal, smaller or larger, got "z""#.into()),
        (sensor(r#"<float name="aperture_radius" value="0.1"/>"#, ""), r#"case.xml:4: <float name="aperture_radius">: property `aperture_radius` of <sensor type="perspective"> is outside the subset lancer reads (docs/mitsuba.md); remove it"#.into()),
        (sensor("", r#"<rfilter type="sinc"/>"#), r#"case.xml:5: <rfilter type="sinc">: attribute `type`: unsupported rfilter type "sinc"; lancer reads: box, tent, gaussian, mitchell, catmullrom, lanczos"#.into()),
        (sensor("", r#"<string name="pixel_format" value="xyz"/>"#), r#"case.xml:5: <string name="pixel_format">: attribute `value`: pixel_format must be rgb or rgba, got "xyz""#.into()),
        (sensor(r#"<sampler type="independent"><integer name="sample_count" value="-4"/></sampler>"#, ""), r#"case.xml:4: <integer name="sample_count">: attribute `value`: must be an integer from 1 to 4294967295, got -4"#.into()),
        (sensor(r#"<transform name="to_world"><scale value="2"/></transform>"#, ""), r#"case.xml:2: <sensor type="perspective">: the sensor's to_world must be a rotation and a translation (no scale or mirror); use <lookat>"#.into()),
        (sensor(r#"<transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 0"/></transform>"#, ""), r#"case.xml:4: <lookat>: origin equals target, or up is parallel to target - origin; move target or change up"#.into()),
        ("<scene version=\"3.0.0\">\n  <sensor type=\"radiancemeter\"/>\n</scene>\n".into(), r#"case.xml:2: <sensor type="radiancemeter">: attribute `type`: unsupported sensor type "radiancemeter"; lancer reads: perspective, thinlens, orthographic"#.into()),
        ("<scene version=\"3.0.0\">\n  <sensor type=\"orthographic\"><transform name=\"to_world\"><scale x=\"0\"/></transform></sensor>\n</scene>\n".into(), r#"case.xml:2: <sensor type="orthographic">: the orthographic sensor's to_world is singular (a scale of 0?): give it a scale that is not 0 on any axis"#.into()),
        ("<scene version=\"3.0.0\">\n  <sensor type=\"thinlens\">\n    <float name=\"fov\" value=\"40\"/>\n    <float name=\"focus_distance\" value=\"2\"/>\n  </sensor>\n</scene>\n".into(), r#"case.xml:2: <sensor type="thinlens">: missing property <float name="aperture_radius">"#.into()),
        ("<scene version=\"3.0\">\n</scene>\n".into(), r#"case.xml:1: <scene>: attribute `version`: expected three numbers separated by periods (e.g. "3.0.0"), got "3.0""#.into()),
        ("<scene version=\"3.0.0\">\n</scene>\n".into(), "case.xml:1: <scene>: the scene has no <sensor>; add a perspective or thinlens sensor".into()),
        ("<scene version=\"3.0.0\">\n  <shape type=\"sphere\">\n</scene>\n".into(), "case.xml:3: invalid XML: expected 'shape' tag, not 'scene' at 3:1".into()),
    ];
    let mut failures = Vec::new();
    for (xml, expected) in cases.iter().map(|(b, e)| (doc(b), e.clone())).chain(whole) {
        match load_xml(&xml) {
            Ok(_) => failures.push(format!("loaded, expected: {expected}\n{xml}")),
            Err(got) if got != expected => {
                failures.push(format!("got:      {got}\nexpected: {expected}\n{xml}"))
            }
            Err(_) => {}
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn defaults_fill_dollar_names_and_mitsuba_defaults_apply() {
    let text = r#"<scene version="3.0.0">
  <default name="spp" value="9"/>
  <default name="w" value="32"/>
  <default name="seed" value="5"/>
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <sampler type="stratified"><integer name="sample_count" value="$spp"/><integer name="seed" value="$seed"/></sampler>
    <film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="16"/></film>
  </sensor>
  <shape type="sphere"/>
</scene>
"#;
    let s = load_ok(text);
    assert_eq!((s.render.spp, s.render.seed), (9, 5));
    assert_eq!((s.render.width, s.render.height), (32, 16));
    // No integrator: Mitsuba's path tracer with no depth limit, roulette from
    // Mitsuba's default depth.
    assert_eq!(s.render.max_depth, 1_000_000);
    assert_eq!(s.render.rr_depth, 5);
    // fov_axis defaults to x: vfov = 2 atan(tan(30 deg) * 16 / 32).
    let vfov = 2.0 * ((30f64).to_radians().tan() * 0.5).atan().to_degrees();
    assert!(
        (s.camera.vfov_deg as f64 - vfov).abs() < 1e-4,
        "{}",
        s.camera.vfov_deg
    );
    // A shape without a BSDF is diffuse 0.5; the default sphere is the unit
    // sphere at the origin; the identity camera looks along +z.
    assert_eq!(s.materials.len(), 1);
    assert_eq!(
        s.materials[0].kind,
        MaterialKind::Lambert {
            albedo: ColorSource::Constant(Vec3::splat(0.5))
        }
    );
    assert_eq!(
        (s.spheres[0].center, s.spheres[0].radius),
        (Vec3::ZERO, 1.0)
    );
    assert_eq!(s.camera.eye, Vec3::ZERO);
    assert_eq!(s.camera.look_at, Vec3::Z);
    assert_eq!(s.camera.up, Vec3::Y);
    // `$name` anywhere in a value, several times.
    let two = load_ok(&doc(
        r#"<default name="c" value="0.25"/><shape type="sphere"><point name="center" value="$c, 1, $c"/></shape>"#,
    ));
    assert_eq!(two.spheres[0].center, Vec3::new(0.25, 1.0, 0.25));
}

#[test]
fn shapes_transforms_and_bsdfs_map_to_lancer() {
    let s = load_ok(&doc(
        r#"<bsdf type="dielectric" id="glass"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1.25"/><rgb name="specular_transmittance" value="0.9, 0.8, 0.7"/></bsdf>
  <shape type="sphere">
    <point name="center" x="1" y="0" z="0"/><float name="radius" value="0.5"/>
    <transform name="to_world"><scale value="2"/><rotate z="1" angle="90"/><translate x="10"/></transform>
    <ref id="glass"/>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><matrix value="2 0 0 1  0 3 0 2  0 0 1 3  0 0 0 1"/></transform>
    <bsdf type="conductor"/>
    <emitter type="area"><rgb name="radiance" value="4"/></emitter>
  </shape>
  <shape type="cube"/>"#,
    ));
    // Sphere: to_world * translate(center) * scale(radius); scale 2, then
    // +90 degrees about z turns +x into +y, then +10 in x.
    let sp = s.spheres[0];
    assert!(
        (sp.center - Vec3::new(10.0, 2.0, 0.0)).length() < 1e-6,
        "{}",
        sp.center
    );
    assert!((sp.radius - 1.0).abs() < 1e-6);
    assert_eq!(
        s.materials[sp.material as usize].kind,
        MaterialKind::Dielectric {
            ior: 1.2,
            tint: Vec3::new(0.9, 0.8, 0.7)
        }
    );
    // Rectangle: [-1, 1]^2 at z = 0, through the row-major matrix: x in
    // [-1, 3], y in [-1, 5], z = 3, front side +z, with Mitsuba's texture
    // coordinates flipped to lancer's (v = 0 at the bottom row: Mitsuba's
    // v = 0 row is the top, at y = -1).
    let rect = &s.triangles[..2];
    for t in rect {
        let n = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
        assert!(n.z > 0.0 && n.x == 0.0 && n.y == 0.0, "front side {n}");
        for (p, uv) in t.p.iter().zip(t.uv.unwrap()) {
            assert_eq!(p.z, 3.0);
            assert_eq!(uv.x, (p.x + 1.0) / 4.0);
            assert_eq!(uv.y, 1.0 - (p.y + 1.0) / 6.0);
        }
    }
    let lamp = &s.materials[rect[0].material as usize];
    assert_eq!(lamp.emission, Vec3::splat(4.0));
    assert_eq!(
        lamp.kind,
        MaterialKind::Mirror {
            reflectance: Vec3::ONE
        }
    );
    // Cube: 12 outward-facing triangles covering [-1, 1]^3 (area 24).
    let cube = &s.triangles[2..];
    assert_eq!(cube.len(), 12);
    let mut area = 0.0;
    for t in cube {
        let n = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
        let centre = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        assert!(n.dot(centre) > 0.0, "inward face {t:?}");
        area += 0.5 * n.length();
    }
    assert_eq!(area, 24.0);
    // Plain diffuse or conductor: Mitsuba shades the front only, and so
    // does lancer; a dielectric scatters on both sides.
    assert_eq!(lamp.sides, Sides::Front);
    assert_eq!(s.materials[cube[0].material as usize].sides, Sides::Front);
    assert_eq!(s.materials[sp.material as usize].sides, Sides::Both);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

/// The scene of `tests/scenes/` with one mesh shape `shape`.
fn mesh_scene(shape: &str) -> Scene {
    let text = format!(
        r#"<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="4"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="2, 1.5, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1, 0.9, 0.8"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><scale value="4"/><rotate x="1" angle="-90"/><translate y="-0.5"/></transform>
    <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>
  </shape>
  {shape}
</scene>
"#
    );
    load_str(&text, &repo("tests/scenes/twin.xml")).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn ply_mesh_renders_bit_for_bit_like_its_obj_twin() {
    let transform = r#"<transform name="to_world"><rotate y="1" angle="30"/><scale value="1.2"/></transform>
    <boolean name="face_normals" value="true"/>
    <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.3, 0.2"/></bsdf></bsdf>"#;
    // cube.ply is binary, with quad faces; split into fans they are
    // cube.obj's triangles in its order.
    let ply = mesh_scene(&format!(
        r#"<shape type="ply"><string name="filename" value="meshes/cube.ply"/>{transform}</shape>"#
    ));
    let obj = mesh_scene(&format!(
        r#"<shape type="obj"><string name="filename" value="../../scenes/meshes/cube.obj"/>{transform}</shape>"#
    ));
    assert_eq!(ply.triangles.len(), 2 + 12);
    assert_eq!(ply.triangles, obj.triangles);
    let ctx = context();
    let a = render(&ctx, &ply, &options(1 << 12));
    let b = render(&ctx, &obj, &options(1 << 12));
    assert!(a.mean.iter().any(|&v| v > 0.0), "a black image");
    assert_eq!(differing_bits(&a.mean, &b.mean), 0);
    assert_eq!(differing_bits(&a.var_of_mean, &b.var_of_mean), 0);
}

/// A scene of one sphere whose sensor holds `sensor` and whose film holds
/// `film` (8 x 6 pixels).
fn sensor_scene(kind: &str, sensor: &str, film: &str) -> Scene {
    load_ok(&format!(
        "<scene version=\"3.0.0\">\n  <sensor type=\"{kind}\">\n    {sensor}\n    <film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/><integer name=\"height\" value=\"6\"/>{film}</film>\n  </sensor>\n  <shape type=\"sphere\"/>\n</scene>\n"
    ))
}

/// Vertical field of view, in degrees, of a horizontal one on an 8 x 6 film.
fn vfov_of_diagonal(fov_deg: f64) -> f64 {
    let half = (fov_deg.to_radians() * 0.5).tan() * 6.0 / 10.0;
    2.0 * half.atan().to_degrees()
}

#[test]
fn sensor_and_film_follow_mitsubas_definitions_and_defaults() {
    use lancer::scene::PixelFilter;
    // A film without <rfilter> gets Mitsuba's Gaussian; each rfilter its
    // properties, with Mitsuba's defaults
    let s = sensor_scene("perspective", r#"<float name="fov" value="40"/>"#, "");
    assert_eq!(s.render.filter, PixelFilter::Gaussian { stddev: 0.5 });
    let filter = |xml: &str| {
        sensor_scene("perspective", r#"<float name="fov" value="40"/>"#, xml)
            .render
            .filter
    };
    assert_eq!(filter(r#"<rfilter type="box"/>"#), PixelFilter::Box);
    assert_eq!(
        filter(r#"<rfilter type="tent"/>"#),
        PixelFilter::Tent { radius: 1.0 }
    );
    assert_eq!(
        filter(r#"<rfilter type="tent"><float name="radius" value="1.25"/></rfilter>"#),
        PixelFilter::Tent { radius: 1.25 }
    );
    assert_eq!(
        filter(r#"<rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>"#),
        PixelFilter::Gaussian { stddev: 0.25 }
    );
    assert_eq!(
        filter(r#"<rfilter type="mitchell"/>"#),
        PixelFilter::MITCHELL
    );
    assert_eq!(
        filter(
            r#"<rfilter type="mitchell"><float name="B" value="0.25"/><float name="C" value="0.55"/></rfilter>"#
        ),
        PixelFilter::Mitchell { b: 0.25, c: 0.55 }
    );
    assert_eq!(
        filter(r#"<rfilter type="catmullrom"/>"#),
        PixelFilter::Mitchell { b: 0.0, c: 0.5 }
    );
    assert_eq!(
        filter(r#"<rfilter type="lanczos"/>"#),
        PixelFilter::Lanczos { lobes: 3 }
    );
    assert_eq!(
        filter(r#"<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>"#),
        PixelFilter::Lanczos { lobes: 2 }
    );

    // Clip planes: Mitsuba's defaults, or as given
    assert_eq!((s.camera.near_clip, s.camera.far_clip), (0.01, 10000.0));
    let c = sensor_scene(
        "perspective",
        r#"<float name="fov" value="40"/><float name="near_clip" value="0.5"/><float name="far_clip" value="20"/>"#,
        "",
    );
    assert_eq!((c.camera.near_clip, c.camera.far_clip), (0.5, 20.0));

    // No fov: a 50 mm lens on 36 x 24 mm film, measured on the diagonal
    let close = |a: f32, b: f64| assert!((a as f64 - b).abs() < 1e-4, "{a} vs {b}");
    let diag_50 = 2.0 * (1296f64 + 576.0).sqrt().atan2(100.0).to_degrees();
    close(
        sensor_scene("perspective", "", "").camera.vfov_deg,
        vfov_of_diagonal(diag_50),
    );
    let diag_35 = 2.0 * (1296f64 + 576.0).sqrt().atan2(70.0).to_degrees();
    close(
        sensor_scene(
            "perspective",
            r#"<string name="focal_length" value="35mm"/>"#,
            "",
        )
        .camera
        .vfov_deg,
        vfov_of_diagonal(diag_35),
    );
    // fov_axis in any case, as Mitsuba lowers it
    let y = sensor_scene(
        "perspective",
        r#"<float name="fov" value="40"/><string name="fov_axis" value="Y"/>"#,
        "",
    );
    close(y.camera.vfov_deg, 40.0);

    // What does not change the image is read past: focus_distance on a
    // pinhole (Mitsuba ignores it there), the shutter, the file's format,
    // the banner, a full crop window, sample_border
    let quiet = sensor_scene(
        "perspective",
        r#"<float name="fov" value="40"/><float name="focus_distance" value="3"/><float name="shutter_open" value="0"/><float name="shutter_close" value="0.5"/><float name="principal_point_offset_y" value="0"/>"#,
        r#"<string name="file_format" value="OpenEXR"/><string name="pixel_format" value="rgba"/><string name="component_format" value="uint32"/><boolean name="banner" value="false"/><boolean name="sample_border" value="true"/><boolean name="compensate" value="true"/><integer name="crop_offset_x" value="0"/><integer name="crop_width" value="8"/><integer name="crop_height" value="6"/>"#,
    );
    assert_eq!(quiet.camera.aperture_radius, 0.0);
    assert_eq!(quiet.camera, s.camera);

    // A thin lens without focus_distance focuses on the far plane
    let lens = sensor_scene(
        "thinlens",
        r#"<float name="fov" value="40"/><float name="aperture_radius" value="0.1"/><float name="far_clip" value="50"/>"#,
        "",
    );
    assert_eq!(
        (lens.camera.aperture_radius, lens.camera.focus_distance),
        (0.1, 50.0)
    );
}

#[test]
fn converted_toml_renders_bit_for_bit_like_the_xml() {
    let dir = tempfile::tempdir().expect("temp dir");
    let toml = dir.path().join("cornell.toml");
    let out = lancer(
        &[
            "convert",
            "scenes/cornell.xml",
            "--out",
            toml.to_str().unwrap(),
        ],
        &[],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&toml).unwrap();
    assert!(
        text.contains("file = \"cornell_meshes/part0.obj\""),
        "{text}"
    );
    let xml = load("scenes/cornell.xml");
    let converted = lancer::scene::load(&toml).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(converted.triangles, xml.triangles);
    assert_eq!(converted.materials, xml.materials);
    assert_eq!(converted.camera, xml.camera);
    assert_eq!(converted.render, xml.render);
    let ctx = context();
    let small = |s: &Scene| {
        let mut s = s.clone();
        (s.render.width, s.render.height, s.render.spp) = (32, 32, 4);
        s
    };
    let a = render(&ctx, &small(&xml), &options(1 << 12));
    let b = render(&ctx, &small(&converted), &options(1 << 12));
    assert!(a.mean.iter().any(|&v| v > 0.0), "a black image");
    assert_eq!(differing_bits(&a.mean, &b.mean), 0);
    assert_eq!(differing_bits(&a.var_of_mean, &b.var_of_mean), 0);
}

/// A TOML scene cannot state an environment map (SCENE_FORMAT.md has a
/// constant environment only): `lancer convert` refuses one by name, and
/// writes nothing.
#[test]
fn convert_refuses_an_environment_map() {
    let dir = tempfile::tempdir().expect("temp dir");
    let toml = dir.path().join("envmap.toml");
    let out = lancer(
        &[
            "convert",
            "tests/scenes/mitsuba/envmap.xml",
            "--out",
            toml.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!out.status.success(), "convert wrote an envmap scene");
    let err = stderr(&out);
    assert!(
        err.contains("the scene has an environment map")
            && err.contains("which a TOML scene cannot state"),
        "{err}"
    );
    assert!(!toml.exists(), "a TOML file was written");
}

/// Loads a scene whose one shape is the PLY file `bytes`, written as
/// `mesh.ply` beside the scene `case.xml` in `dir`: its triangles, or the
/// message.
fn load_ply(dir: &Path, bytes: &[u8]) -> Result<Vec<lancer::scene::Triangle>, String> {
    std::fs::write(dir.join("mesh.ply"), bytes).unwrap();
    let text = doc(
        r#"<shape type="ply"><string name="filename" value="mesh.ply"/><boolean name="face_normals" value="true"/></shape>"#,
    );
    load_str(&text, &dir.join("case.xml"))
        .map(|s| s.triangles)
        .map_err(|e| e.to_string())
}

/// The message of a PLY file `mesh.ply` refused for `reason` (which names
/// the file as `{ply}`).
fn ply_error(dir: &Path, reason: &str) -> String {
    let ply = dir.join("mesh.ply");
    format!(
        "{}:6: <string name=\"filename\">: attribute `value`: {}",
        dir.join("case.xml").display(),
        reason.replace("{ply}", &ply.display().to_string())
    )
}

/// A binary little-endian PLY: `header` lines between `format` and
/// `end_header`, then `body`.
fn binary_ply(header: &str, body: &[u8]) -> Vec<u8> {
    let mut b = format!("ply\nformat binary_little_endian 1.0\n{header}end_header\n").into_bytes();
    b.extend_from_slice(body);
    b
}

/// A triangle of three float vertices and one uchar-counted int face.
const TRIANGLE_HEADER: &str = "element vertex 3\nproperty float x\nproperty float y\n\
    property float z\nelement face 1\nproperty list uchar int vertex_indices\n";

fn triangle_body() -> Vec<u8> {
    let mut b = Vec::new();
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for c in v {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

/// Every count in a PLY header is checked, in checked arithmetic, against
/// a documented limit and against the bytes the file has after its header,
/// before anything is allocated for it. An element of billions of entries
/// of no bytes each was read one entry at a time into memory until the
/// process aborted.
#[test]
fn ply_counts_are_checked_against_the_file_and_the_limit_first() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The triangle itself loads.
    assert_eq!(
        load_ply(d, &binary_ply(TRIANGLE_HEADER, &triangle_body()))
            .unwrap()
            .len(),
        1
    );
    let refused = |bytes: &[u8], reason: &str| {
        assert_eq!(load_ply(d, bytes).unwrap_err(), ply_error(d, reason));
    };
    // Side data with no bytes per entry: only the limit bounds it.
    refused(
        &binary_ply(
            &format!("{TRIANGLE_HEADER}element junk 4000000000\n"),
            &triangle_body(),
        ),
        "PLY file {ply}: its header declares 4000000000 `junk` elements; lancer reads at most \
         268435456 of an element (docs/mitsuba.md): remove the element, or split the mesh",
    );
    // Faces of at least one byte each (their vertex count).
    refused(
        &binary_ply(
            &TRIANGLE_HEADER.replace("face 1", "face 100000000"),
            &triangle_body(),
        ),
        "PLY file {ply}: its header declares 100000000 `face` elements of at least 1 byte each, \
         but only 13 bytes are left for them after the header and the elements before them: \
         the file is truncated, or its header is wrong",
    );
    // ASCII: at least one character and one space or line end per value.
    refused(
        b"ply\nformat ascii 1.0\nelement vertex 1000000\nproperty float x\nproperty float y\n\
          property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
        "PLY file {ply}: its header declares 1000000 `vertex` elements of at least 6 bytes each, \
         but only 18 bytes are left for them after the header and the elements before them: \
         the file is truncated, or its header is wrong",
    );
    // A list whose count claims more values than the file has left.
    let mut body = triangle_body();
    let face = body.len() - 13;
    body.truncate(face);
    body.push(255);
    body.extend_from_slice(&[0; 12]);
    refused(
        &binary_ply(TRIANGLE_HEADER, &body),
        "PLY file {ply}: `face` 0: its `vertex_indices` list claims 255 values of 4 bytes, but \
         only 12 bytes are left in the file: the file is truncated or damaged",
    );
}

/// The PLY header and ASCII values separate their tokens with any white
/// space: tabs, several spaces, CRLF line ends, and white space at the
/// start or end of a line.
#[test]
fn ply_tokens_split_on_any_white_space() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let plain = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    let expected = load_ply(d, plain.as_bytes()).unwrap();
    assert_eq!(expected.len(), 2);
    let variants = [
        ("tabs", plain.replace(' ', "\t")),
        ("several spaces", plain.replace(' ', "   ")),
        ("CRLF", plain.replace('\n', "\r\n")),
        (
            "white space around lines",
            plain.replace('\n', " \t\n  ").replacen("  ply", "ply", 1),
        ),
        (
            "all of them",
            plain.replace(' ', " \t ").replace('\n', "\t\r\n "),
        ),
    ];
    for (what, text) in variants {
        assert_eq!(
            load_ply(d, text.as_bytes()).map_err(|e| format!("{what}: {e}")),
            Ok(expected.clone()),
            "{what}"
        );
    }
    // A binary file's header too, with its data after the CRLF.
    let cube = std::fs::read(repo("tests/scenes/meshes/cube.ply")).unwrap();
    let end = b"end_header\n";
    let split = cube.windows(end.len()).position(|w| w == end).unwrap() + end.len();
    let header = String::from_utf8(cube[..split].to_vec()).unwrap();
    let mut crlf = header
        .replace(' ', "\t  ")
        .replace('\n', " \r\n")
        .into_bytes();
    crlf.extend_from_slice(&cube[split..]);
    assert_eq!(load_ply(d, &crlf), load_ply(d, &cube));
    assert_eq!(load_ply(d, &cube).unwrap().len(), 12);
}

/// Mitsuba's attribute lists (points, colours, matrices, lookat) separate
/// their numbers with commas and/or any white space: tabs (written as
/// `&#9;`, since XML turns a literal tab in an attribute into a space),
/// several spaces, line breaks, and CR LF line ends in the document.
#[test]
fn xml_attribute_lists_split_on_any_white_space() {
    let scene = |sep: &str| {
        let text = format!(
            r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0{sep}0{sep}5" target="0,{sep}0,{sep}0" up="0{sep}1{sep}0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
  </sensor>
  <shape type="sphere">
    <point name="center" value="{sep}0.5{sep}0.25{sep}0{sep}"/>
    <transform name="to_world"><matrix value="1{sep}0 0 0{sep}0 1 0 0 0{sep}0 1 0 0 0 0{sep}1"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.2,{sep}0.4{sep}0.6"/></bsdf>
  </shape>
</scene>
"#
        );
        load_ok(&text)
    };
    let plain = scene(" ");
    for sep in ["&#9;", "   ", " &#9; ", "&#13;&#10;", "\n\t"] {
        let other = scene(sep);
        assert_eq!(other.camera, plain.camera, "{sep:?}");
        assert_eq!(other.spheres, plain.spheres, "{sep:?}");
        // (Materials are named by their line, which line breaks move.)
        let kinds = |s: &Scene| {
            s.materials
                .iter()
                .map(|m| m.kind.clone())
                .collect::<Vec<_>>()
        };
        assert_eq!(kinds(&other), kinds(&plain), "{sep:?}");
    }
    let crlf = load_ok(&doc(r#"<shape type="sphere"/>"#).replace('\n', "\r\n"));
    assert_eq!(
        crlf.spheres,
        load_ok(&doc(r#"<shape type="sphere"/>"#)).spheres
    );
}

/// The command line's `--width/--height` reach the loader before the field
/// of view is derived: with `fov_axis` x the horizontal angle stays the
/// file's whatever the new aspect, as in Mitsuba; a bad override is refused
/// once, naming the setting and no line.
#[test]
fn overridden_image_size_keeps_the_horizontal_field_of_view() {
    let text = r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="16"/></film>
  </sensor>
  <shape type="sphere"/>
</scene>
"#;
    let size = |w, h| RenderOverrides {
        width: Some(w),
        height: Some(h),
        ..RenderOverrides::default()
    };
    for (w, h) in [(32u32, 16u32), (16, 32), (100, 7)] {
        let s = load_str_with(text, Path::new("case.xml"), &size(w, h)).unwrap();
        assert_eq!((s.render.width, s.render.height), (w, h));
        let vfov = 2.0
            * ((30f64).to_radians().tan() * h as f64 / w as f64)
                .atan()
                .to_degrees();
        assert!(
            (s.camera.vfov_deg as f64 - vfov).abs() < 1e-4,
            "{w}x{h}: vfov {} != {vfov}",
            s.camera.vfov_deg
        );
    }
    let err = load_str_with(text, Path::new("case.xml"), &size(0, 16))
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "case.xml: render.width: must be >= 1, got 0 (the value of RenderOverrides::width)"
    );
    let depth = RenderOverrides {
        max_depth: Some(3),
        ..RenderOverrides::default()
    };
    let with_path = text.replace(
        "<sensor",
        r#"<integrator type="path"><integer name="max_depth" value="7"/></integrator>
  <sensor"#,
    );
    let s = load_str_with(&with_path, Path::new("case.xml"), &depth).unwrap();
    assert_eq!(s.render.max_depth, 3);
    let s = load_str(&with_path, Path::new("case.xml")).unwrap();
    assert_eq!(s.render.max_depth, 7);
}

/// `conductor` and `roughconductor` as Mitsuba reads them: material `none`
/// (or nothing) stays lancer's mirror; presets and eta/k become conductors;
/// Beckmann and alpha 0.1 by default; `sample_visible` is accepted.
#[test]
fn conductors_map_to_lancer() {
    let s = load_ok(&doc(
        r#"<shape type="sphere"><bsdf type="conductor"><string name="material" value="none"/><rgb name="specular_reflectance" value="0.5"/></bsdf></shape>
  <shape type="sphere"><bsdf type="conductor"><string name="material" value="Cu"/></bsdf></shape>
  <shape type="sphere"><bsdf type="conductor"><rgb name="eta" value="0.2, 0.9, 1.1"/></bsdf></shape>
  <shape type="sphere"><bsdf type="roughconductor"/></shape>
  <shape type="sphere"><bsdf type="twosided"><bsdf type="roughconductor"><string name="material" value="Al"/><string name="distribution" value="GGX"/><float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.3"/><boolean name="sample_visible" value="false"/></bsdf></bsdf></shape>"#,
    ));
    let kind = |i: usize| s.materials[s.spheres[i].material as usize].kind.clone();
    assert_eq!(
        kind(0),
        MaterialKind::Mirror {
            reflectance: Vec3::splat(0.5)
        }
    );
    assert_eq!(
        kind(1),
        MaterialKind::Conductor {
            ior: conductor_preset("Cu").unwrap(),
            specular_reflectance: Vec3::ONE
        }
    );
    assert_eq!(
        kind(2),
        MaterialKind::Conductor {
            ior: ComplexIor {
                eta: Vec3::new(0.2, 0.9, 1.1),
                k: Vec3::ONE
            },
            specular_reflectance: Vec3::ONE
        }
    );
    assert_eq!(
        kind(3),
        MaterialKind::RoughConductor {
            distribution: Microfacet::Beckmann,
            alpha_u: 0.1,
            alpha_v: 0.1,
            alpha_textures: None,
            ior: ComplexIor::PERFECT,
            specular_reflectance: Vec3::ONE
        }
    );
    assert_eq!(
        kind(4),
        MaterialKind::RoughConductor {
            distribution: Microfacet::Ggx,
            alpha_u: 0.05,
            alpha_v: 0.3,
            alpha_textures: None,
            ior: conductor_preset("Al").unwrap(),
            specular_reflectance: Vec3::ONE
        }
    );
}

/// A textured roughness as Mitsuba reads it (`get_unbounded_texture`):
/// `alpha` as one texture for both directions, `alpha_u` and `alpha_v` as
/// textures or numbers each, a `<ref>` to a top-level texture; the sides
/// given as numbers keep them.
#[test]
fn textured_roughness_maps_to_lancer() {
    use lancer::scene::{AlphaTextures, ColorSource};
    let checker = r#"<texture type="checkerboard" name="NAME"><float name="color0" value="0.05"/><float name="color1" value="0.3"/></texture>"#;
    let s = load_ok(&doc(&format!(
        r#"<texture type="checkerboard" id="t"><float name="color1" value="0.2"/></texture>
  <shape type="sphere"><bsdf type="roughconductor">{}</bsdf></shape>
  <shape type="sphere"><bsdf type="roughdielectric">{}<float name="alpha_v" value="0.25"/></bsdf></shape>
  <shape type="sphere"><bsdf type="roughconductor"><float name="alpha_u" value="0.15"/><ref name="alpha_v" id="t"/></bsdf></shape>"#,
        checker.replace("NAME", "alpha"),
        checker.replace("NAME", "alpha_u"),
    )));
    let kind = |i: usize| &s.materials[s.spheres[i].material as usize].kind;
    let textures = |i: usize| kind(i).alpha_textures().expect("textured").clone();
    let checker = textures(0).u.expect("alpha_u");
    assert!(matches!(checker, ColorSource::Mapped(_)));
    assert_eq!(
        textures(0),
        AlphaTextures {
            u: Some(checker.clone()),
            v: Some(checker.clone())
        }
    );
    assert!(!kind(0).is_anisotropic());
    assert_eq!(
        textures(1),
        AlphaTextures {
            u: Some(checker.clone()),
            v: None
        }
    );
    assert!(matches!(kind(1), MaterialKind::RoughDielectric { alpha_v, .. } if *alpha_v == 0.25));
    assert!(kind(1).is_anisotropic());
    let t = textures(2);
    assert!(t.u.is_none() && matches!(t.v, Some(ColorSource::Mapped(_))));
    assert!(matches!(kind(2), MaterialKind::RoughConductor { alpha_u, .. } if *alpha_u == 0.15));
}

/// A principled material's weights as Mitsuba reads them: numbers, or
/// textures (a `<texture>` or a `<ref>` to a top-level one) read as one
/// channel; a textured weight's constant is its default (the roughness
/// 0.5), every other weight keeps its number; a textured anisotropy makes
/// the material anisotropic; a material with no texture keeps none.
#[test]
fn principled_weight_textures_map_to_lancer() {
    use lancer::scene::{ColorSource, Principled};
    let s = load_ok(&doc(
        r#"<texture type="checkerboard" id="t"><float name="color1" value="0.2"/></texture>
  <shape type="sphere"><bsdf type="principled"><texture type="checkerboard" name="roughness"/><float name="metallic" value="0.3"/><ref name="clearcoat" id="t"/><texture type="checkerboard" name="flatness"/></bsdf></shape>
  <shape type="sphere"><bsdf type="principled"><texture type="checkerboard" name="anisotropic"/></bsdf></shape>
  <shape type="sphere"><bsdf type="principled"><float name="sheen" value="0.4"/></bsdf></shape>"#,
    ));
    let principled = |i: usize| match &s.materials[s.spheres[i].material as usize].kind {
        MaterialKind::Principled(p) => (**p).clone(),
        other => panic!("not principled: {other:?}"),
    };
    let p = principled(0);
    let textured: Vec<&str> = Principled::WEIGHT_NAMES
        .into_iter()
        .filter(|n| p.weight_texture(n).is_some())
        .collect();
    assert_eq!(textured, ["roughness", "clearcoat", "flatness"]);
    assert!(Principled::WEIGHT_NAMES
        .iter()
        .filter_map(|n| p.weight_texture(n))
        .all(|t| matches!(t, ColorSource::Mapped(_))));
    assert_eq!((p.roughness, p.metallic, p.clearcoat), (0.5, 0.3, 0.0));
    assert!(!MaterialKind::Principled(Box::new(p.clone())).is_anisotropic());
    assert!(MaterialKind::Principled(Box::new(principled(1))).is_anisotropic());
    let plain = principled(2);
    assert!(plain.weight_textures.is_none());
    assert_eq!(plain.weights()[4], 0.4);
}

/// `roughdielectric` as Mitsuba reads it: Beckmann, alpha 0.1, int_ior
/// "bk7" and ext_ior "air" by default; indices as numbers or Mitsuba's
/// names (any case), their ratio lancer's ior; `sample_visible` accepted;
/// both specular factors; no sides (it transmits). `dielectric` takes the
/// names too. `lancer convert` cannot write it: the TOML format has none.
#[test]
fn rough_dielectrics_map_to_lancer() {
    let s = load_ok(&doc(
        r#"<shape type="sphere"><bsdf type="roughdielectric"/></shape>
  <shape type="sphere"><bsdf type="roughdielectric"><string name="distribution" value="GGX"/><float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.3"/><string name="int_ior" value="Water"/><string name="ext_ior" value="vacuum"/><boolean name="sample_visible" value="false"/><rgb name="specular_reflectance" value="0.5"/><rgb name="specular_transmittance" value="0.9, 0.8, 0.7"/></bsdf></shape>
  <shape type="sphere"><bsdf type="roughdielectric"><float name="int_ior" value="1"/><float name="ext_ior" value="1.5"/><float name="alpha" value="0.3"/></bsdf></shape>
  <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="diamond"/><string name="ext_ior" value="water"/></bsdf></shape>"#,
    ));
    let kind = |i: usize| s.materials[s.spheres[i].material as usize].kind.clone();
    assert_eq!(
        kind(0),
        MaterialKind::RoughDielectric {
            distribution: Microfacet::Beckmann,
            alpha_u: 0.1,
            alpha_v: 0.1,
            alpha_textures: None,
            ior: (1.5046f64 / 1.000277) as f32,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::ONE,
        }
    );
    assert_eq!(
        kind(1),
        MaterialKind::RoughDielectric {
            distribution: Microfacet::Ggx,
            alpha_u: 0.05,
            alpha_v: 0.3,
            alpha_textures: None,
            ior: 1.333,
            specular_reflectance: Vec3::splat(0.5),
            specular_transmittance: Vec3::new(0.9, 0.8, 0.7),
        }
    );
    assert_eq!(
        kind(2),
        MaterialKind::RoughDielectric {
            distribution: Microfacet::Beckmann,
            alpha_u: 0.3,
            alpha_v: 0.3,
            alpha_textures: None,
            ior: (1.0f64 / 1.5) as f32,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::ONE,
        }
    );
    assert_eq!(
        kind(3),
        MaterialKind::Dielectric {
            ior: (f64::from(2.419f32) / f64::from(1.333f32)) as f32,
            tint: Vec3::ONE,
        }
    );
    for i in 0..3 {
        assert_eq!(
            s.materials[s.spheres[i].material as usize].sides,
            Sides::Both
        );
    }
    assert!(!kind(0).in_toml_format() && kind(3).in_toml_format());
}

/// `lancer convert` keeps the pixel filter and the clip planes: the TOML
/// scene reads back with the very same settings and camera.
#[test]
fn converted_toml_keeps_the_filter_and_the_clip_planes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let xml = load("tests/scenes/mitsuba/filter.xml");
    for filter in [
        lancer::scene::PixelFilter::Gaussian { stddev: 0.3 },
        lancer::scene::PixelFilter::Tent { radius: 1.5 },
        lancer::scene::PixelFilter::Mitchell { b: 0.2, c: 0.4 },
        lancer::scene::PixelFilter::Lanczos { lobes: 2 },
        lancer::scene::PixelFilter::Box,
    ] {
        let mut scene = xml.clone();
        scene.render.filter = filter;
        // filter.xml samples its border: the TOML format's filters do.
        assert!(!scene.render.filter_inside_film);
        scene.camera.near_clip = 0.25;
        scene.camera.far_clip = 123.5;
        let out = dir.path().join("filter.toml");
        for (path, bytes) in lancer::scene::to_toml(&scene, &out) {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, bytes).unwrap();
        }
        let back = lancer::scene::load(&out).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back.render, scene.render);
        assert_eq!(back.camera, scene.camera);
    }
}

/// `plastic` as Mitsuba reads it: diffuse 0.5, specular 1, int_ior
/// "polypropylene" (1.49) over air, linear by default; one-sided outside
/// `twosided`.
#[test]
fn plastics_map_to_lancer() {
    let s = load_ok(&doc(r#"<shape type="sphere"><bsdf type="plastic"/></shape>
  <shape type="sphere"><bsdf type="twosided"><bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.1, 0.2, 0.3"/><rgb name="specular_reflectance" value="0.5"/><string name="int_ior" value="PET"/><float name="ext_ior" value="1"/><boolean name="nonlinear" value="true"/></bsdf></bsdf></shape>"#));
    let m = |i: usize| &s.materials[s.spheres[i].material as usize];
    assert_eq!(
        m(0).kind,
        MaterialKind::Plastic {
            diffuse_reflectance: ColorSource::Constant(Vec3::splat(0.5)),
            specular_reflectance: Vec3::ONE,
            ior: (1.49f64 / 1.000277) as f32,
            nonlinear: false,
        }
    );
    assert_eq!(m(0).sides, Sides::Front);
    assert_eq!(
        m(1).kind,
        MaterialKind::Plastic {
            diffuse_reflectance: ColorSource::Constant(Vec3::new(0.1, 0.2, 0.3)),
            specular_reflectance: Vec3::splat(0.5),
            ior: 1.575,
            nonlinear: true,
        }
    );
    assert_eq!(m(1).sides, Sides::Shading);
    assert!(!m(0).kind.in_toml_format());
    // A textured base: a nested bitmap, or a <ref> to a top-level texture
    let checker = repo("scenes/tex/checker.png");
    let t = load_ok(&doc(&format!(
        r#"<texture type="bitmap" id="t"><string name="filename" value="{0}"/></texture>
  <shape type="sphere"><bsdf type="plastic"><texture type="bitmap" name="diffuse_reflectance"><string name="filename" value="{0}"/></texture></bsdf></shape>
  <shape type="sphere"><bsdf type="plastic"><ref name="diffuse_reflectance" id="t"/></bsdf></shape>"#,
        checker.display()
    )));
    for i in 0..2 {
        let m = &t.materials[t.spheres[i].material as usize];
        assert_eq!(
            m.kind,
            MaterialKind::Plastic {
                diffuse_reflectance: ColorSource::Texture(checker.clone()),
                specular_reflectance: Vec3::ONE,
                ior: (1.49f64 / 1.000277) as f32,
                nonlinear: false,
            }
        );
        assert_eq!(m.texture(), Some(checker.as_path()));
    }
}

/// Mitsuba 3.9's texture lookups, as the loader reads them: `to_uv` as
/// the 2 x 2 block and x, y translation of the transform (a 9-number
/// `<matrix>` has no translation, as in Mitsuba), `wrap_mode` and
/// `filter_type`, a checkerboard's colours (0.4 and 0.2 by default); a
/// bitmap with Mitsuba's defaults stays lancer's plain texture.
#[test]
fn texture_lookups_are_read_as_mitsuba_defines_them() {
    use lancer::scene::{MappedTexture, TextureFilter, TexturePattern, TextureWrap};
    let checker = repo("scenes/tex/checker.png");
    let t = load_ok(&doc(&format!(
        r#"<texture type="checkerboard" id="c"/>
  <shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{0}"/><boolean name="accel" value="false"/><string name="format" value="variant"/></texture></bsdf></shape>
  <shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{0}"/><string name="wrap_mode" value="mirror"/><string name="filter_type" value="nearest"/><transform name="to_uv"><scale x="2" y="4"/><translate x="0.5" y="0.25" z="7"/></transform></texture></bsdf></shape>
  <shape type="sphere"><bsdf type="plastic"><ref name="diffuse_reflectance" id="c"/></bsdf></shape>
  <shape type="sphere"><bsdf type="roughplastic"><texture type="checkerboard" name="diffuse_reflectance"><rgb name="color0" value="0.1, 0.2, 0.3"/><float name="color1" value="0.9"/><transform name="to_uv"><matrix value="1 2 3 4 5 6 7 8 9"/></transform></texture></bsdf></shape>
  <shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{0}"/><string name="wrap_mode" value="clamp"/><transform name="to_uv"><rotate z="1" angle="90"/></transform></texture></bsdf></shape>"#,
        checker.display()
    )));
    let source = |i: usize| {
        t.materials[t.spheres[i].material as usize]
            .diffuse_source()
            .cloned()
            .expect("a diffuse colour")
    };
    let mapped = |i: usize| match source(i) {
        ColorSource::Mapped(m) => *m,
        other => panic!("sphere {i}: {other:?}"),
    };
    assert_eq!(source(0), ColorSource::Texture(checker.clone()));
    assert_eq!(
        mapped(1),
        MappedTexture {
            pattern: TexturePattern::Bitmap(checker.clone()),
            to_uv: [2.0, 0.0, 0.5, 0.0, 4.0, 0.25],
            wrap: TextureWrap::Mirror,
            filter: TextureFilter::Nearest,
            raw: false,
        }
    );
    assert_eq!(
        t.materials[t.spheres[1].material as usize].texture(),
        Some(checker.as_path())
    );
    assert_eq!(
        mapped(2),
        MappedTexture {
            pattern: TexturePattern::Checkerboard {
                color0: Vec3::splat(0.4),
                color1: Vec3::splat(0.2),
            },
            to_uv: MappedTexture::IDENTITY_UV,
            wrap: TextureWrap::Repeat,
            filter: TextureFilter::Bilinear,
            raw: false,
        }
    );
    assert_eq!(t.materials[t.spheres[2].material as usize].texture(), None);
    let m3 = mapped(3);
    assert_eq!(m3.to_uv, [1.0, 2.0, 0.0, 4.0, 5.0, 0.0]);
    assert_eq!(
        m3.pattern,
        TexturePattern::Checkerboard {
            color0: Vec3::new(0.1, 0.2, 0.3),
            color1: Vec3::splat(0.9),
        }
    );
    let m4 = mapped(4);
    assert_eq!(m4.wrap, TextureWrap::Clamp);
    let want = [0.0, -1.0, 0.0, 1.0, 0.0, 0.0];
    for (got, want) in m4.to_uv.iter().zip(want) {
        assert!((got - want).abs() < 1e-7, "{:?}", m4.to_uv);
    }
}

/// Mitsuba 3.9's `mask`, as the loader reads it: its opacity as a float,
/// an <rgb>, a texture or a `<ref>` to a top-level texture (Mitsuba's 0.5
/// when absent), kept through a `twosided` either side of it and through a
/// `<ref>` to the mask; a bitmap read `raw` is a mapped texture that says
/// so. A mask without a nested BSDF, and a mask inside a mask, are refused
/// with what to change.
#[test]
fn masks_are_read_as_mitsuba_defines_them() {
    use lancer::scene::{MappedTexture, TextureFilter, TexturePattern, TextureWrap};
    let checker = repo("scenes/tex/checker.png");
    let t = load_ok(&doc(&format!(
        r#"<texture type="bitmap" id="t"><string name="filename" value="{0}"/></texture>
  <bsdf type="mask" id="m"><float name="opacity" value="0.25"/><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></bsdf>
  <shape type="sphere"><ref id="m"/></shape>
  <shape type="sphere"><bsdf type="mask"><rgb name="opacity" value="0.9, 0.1, 0.5"/><bsdf type="diffuse"/></bsdf></shape>
  <shape type="sphere"><bsdf type="twosided"><bsdf type="mask"><ref name="opacity" id="t"/><bsdf type="diffuse"/></bsdf></bsdf></shape>
  <shape type="sphere"><bsdf type="mask"><texture type="bitmap" name="opacity"><string name="filename" value="{0}"/><boolean name="raw" value="true"/></texture><bsdf type="diffuse"/></bsdf></shape>
  <shape type="sphere"><bsdf type="mask"><bsdf type="roughconductor"/></bsdf></shape>
  <shape type="sphere"><bsdf type="diffuse"/></shape>"#,
        checker.display()
    )));
    let m = |i: usize| &t.materials[t.spheres[i].material as usize];
    assert_eq!(m(0).opacity, Some(ColorSource::Constant(Vec3::splat(0.25))));
    assert_eq!(m(0).sides, Sides::Shading);
    assert_eq!(
        m(1).opacity,
        Some(ColorSource::Constant(Vec3::new(0.9, 0.1, 0.5)))
    );
    assert_eq!(m(1).sides, Sides::Front);
    assert_eq!(m(2).opacity, Some(ColorSource::Texture(checker.clone())));
    assert_eq!(m(2).sides, Sides::Shading);
    assert_eq!(
        m(3).opacity,
        Some(ColorSource::Mapped(Box::new(MappedTexture {
            pattern: TexturePattern::Bitmap(checker.clone()),
            to_uv: MappedTexture::IDENTITY_UV,
            wrap: TextureWrap::Repeat,
            filter: TextureFilter::Bilinear,
            raw: true,
        })))
    );
    assert_eq!(m(3).files().collect::<Vec<_>>(), [checker.as_path()]);
    assert_eq!(m(4).opacity, Some(ColorSource::Constant(Vec3::splat(0.5))));
    assert!(matches!(m(4).kind, MaterialKind::RoughConductor { .. }));
    assert_eq!(m(5).opacity, None);
    for (body, message) in [
        (
            r#"<shape type="sphere"><bsdf type="mask"><float name="opacity" value="0.5"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"mask\">: a mask needs one nested <bsdf> or <ref>",
        ),
        (
            r#"<shape type="sphere"><bsdf type="mask"><bsdf type="mask"><bsdf type="diffuse"/></bsdf></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"mask\">: a mask inside a mask is outside the subset lancer \
             reads: give the outer mask the product of both opacities",
        ),
    ] {
        assert_eq!(load_xml(&doc(body)).expect_err(body), message);
    }
}

/// Mitsuba 3.9's `normalmap`, as the loader reads it: its texture nested
/// or by `<ref>`, whether it wraps a two-sided BSDF (so that its tilt is
/// mirrored behind) or sits inside one, `use_shadowing_function`, and its
/// combination with a mask. A map without a texture or a nested BSDF, a
/// map in a map, a map over a dielectric and `flip_invalid_normals` false
/// are refused with what to change.
#[test]
fn normal_maps_are_read_as_mitsuba_defines_them() {
    use lancer::scene::{MappedTexture, NormalMap, TextureFilter, TexturePattern, TextureWrap};
    let checker = repo("scenes/tex/checker.png");
    let t = load_ok(&doc(&format!(
        r#"<texture type="bitmap" id="t"><string name="filename" value="{0}"/><boolean name="raw" value="true"/></texture>
  <shape type="sphere"><bsdf type="normalmap"><ref name="normalmap" id="t"/><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></bsdf></shape>
  <shape type="sphere"><bsdf type="twosided"><bsdf type="normalmap"><ref name="normalmap" id="t"/><bsdf type="diffuse"/></bsdf></bsdf></shape>
  <shape type="sphere"><bsdf type="normalmap"><texture type="bitmap" name="normalmap"><string name="filename" value="{0}"/></texture><boolean name="use_shadowing_function" value="false"/><bsdf type="roughconductor"/></bsdf></shape>
  <shape type="sphere"><bsdf type="mask"><float name="opacity" value="0.5"/><bsdf type="normalmap"><ref name="normalmap" id="t"/><bsdf type="diffuse"/></bsdf></bsdf></shape>"#,
        checker.display()
    )));
    let m = |i: usize| &t.materials[t.spheres[i].material as usize];
    let raw = ColorSource::Mapped(Box::new(MappedTexture {
        pattern: TexturePattern::Bitmap(checker.clone()),
        to_uv: MappedTexture::IDENTITY_UV,
        wrap: TextureWrap::Repeat,
        filter: TextureFilter::Bilinear,
        raw: true,
    }));
    let map = |wraps_two_sided, shadowing, texture: &ColorSource| NormalMap {
        texture: texture.clone(),
        bump_scale: None,
        wraps_two_sided,
        shadowing,
    };
    assert_eq!(m(0).normal_map, Some(map(true, true, &raw)));
    assert_eq!(m(0).sides, Sides::Shading);
    assert_eq!(m(1).normal_map, Some(map(false, true, &raw)));
    assert_eq!(m(1).sides, Sides::Shading);
    let srgb = ColorSource::Texture(checker.clone());
    assert_eq!(m(2).normal_map, Some(map(false, false, &srgb)));
    assert!(matches!(m(2).kind, MaterialKind::RoughConductor { .. }));
    assert_eq!(m(2).files().collect::<Vec<_>>(), [checker.as_path()]);
    assert_eq!(m(3).normal_map, Some(map(false, true, &raw)));
    assert_eq!(m(3).opacity, Some(ColorSource::Constant(Vec3::splat(0.5))));
    for (body, message) in [
        (
            r#"<shape type="sphere"><bsdf type="normalmap"><bsdf type="diffuse"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"normalmap\">: a normalmap needs a <texture name=\"normalmap\"> (a bitmap) or a <ref> to one",
        ),
        (
            r#"<shape type="sphere"><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"normalmap\">: a normalmap needs one nested <bsdf> or <ref>",
        ),
        (
            r#"<shape type="sphere"><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="diffuse"/></bsdf></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"normalmap\">: a normalmap or bumpmap inside a normalmap is outside the subset lancer reads; keep one",
        ),
        (
            r#"<shape type="sphere"><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="dielectric"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"dielectric\">: a normalmap over a transmitting BSDF (a dielectric) is outside the subset lancer reads; remove the normalmap",
        ),
        (
            r#"<shape type="sphere"><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><boolean name="flip_invalid_normals" value="false"/><bsdf type="diffuse"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"normalmap\">: flip_invalid_normals false is outside the subset lancer reads: lancer always turns a tilted normal to face the viewer; remove it",
        ),
    ] {
        assert_eq!(load_xml(&doc(body)).expect_err(body), message);
    }
}

/// Mitsuba 3.9's `bumpmap`, as the loader reads it: its one texture under
/// any name or by `<ref>`, `scale` (1 by default), and the rest as for
/// `normalmap`. A bump map without a texture, with two, or with a texture
/// other than a bitmap (Mitsuba has no gradient of it) is refused.
#[test]
fn bump_maps_are_read_as_mitsuba_defines_them() {
    let checker = repo("scenes/tex/checker.png");
    let t = load_ok(&doc(&format!(
        r#"<texture type="bitmap" id="t"><string name="filename" value="{0}"/></texture>
  <shape type="sphere"><bsdf type="bumpmap"><texture type="bitmap" name="anything"><string name="filename" value="{0}"/></texture><bsdf type="diffuse"/></bsdf></shape>
  <shape type="sphere"><bsdf type="bumpmap"><ref id="t"/><float name="scale" value="0.25"/><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></bsdf></shape>"#,
        checker.display()
    )));
    let m = |i: usize| &t.materials[t.spheres[i].material as usize];
    let bump = |scale, wraps_two_sided| lancer::scene::NormalMap {
        texture: ColorSource::Texture(checker.clone()),
        bump_scale: Some(scale),
        wraps_two_sided,
        shadowing: true,
    };
    assert_eq!(m(0).normal_map, Some(bump(1.0, false)));
    assert_eq!(m(1).normal_map, Some(bump(0.25, true)));
    for (body, message) in [
        (
            r#"<shape type="sphere"><bsdf type="bumpmap"><bsdf type="diffuse"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"bumpmap\">: a bumpmap needs one <texture> (a bitmap) or a <ref> to one",
        ),
        (
            r#"<shape type="sphere"><bsdf type="bumpmap"><texture type="checkerboard" name="a"/><texture type="checkerboard" name="b"/><bsdf type="diffuse"/></bsdf></shape>"#,
            "case.xml:6: <texture type=\"checkerboard\" name=\"b\">: a second texture in a bumpmap; give one",
        ),
        (
            r#"<shape type="sphere"><bsdf type="bumpmap"><texture type="checkerboard" name="a"/><bsdf type="diffuse"/></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"bumpmap\">: a bumpmap's texture must be a bitmap (Mitsuba has no gradient of the others)",
        ),
        (
            r#"<shape type="sphere"><bsdf type="bumpmap"><texture type="checkerboard" name="a"/><bsdf type="normalmap"><texture type="checkerboard" name="normalmap"/><bsdf type="diffuse"/></bsdf></bsdf></shape>"#,
            "case.xml:6: <bsdf type=\"bumpmap\">: a bumpmap's texture must be a bitmap (Mitsuba has no gradient of the others)",
        ),
    ] {
        assert_eq!(load_xml(&doc(body)).expect_err(body), message);
    }
}

/// Mitsuba 3.9's orthographic sensor, as the loader reads it: the film
/// spans [-1, 1] x [-H/W, H/W] in camera space on the plane z =
/// `near_clip`, +x at the image's left, mapped by `to_world` (here a
/// non-uniform scale and a translation); a crop window takes its part of
/// the film, its centre off the film's by `Camera::shift`. `fov` is not an
/// orthographic property and is refused by name.
#[test]
fn orthographic_sensor_is_read_as_mitsuba_defines_it() {
    use lancer::scene::Orthographic;
    let sensor = |film: &str, extra: &str| {
        format!(
            r#"<scene version="3.0.0">
  <sensor type="orthographic">
    <float name="near_clip" value="0.5"/>{extra}
    <transform name="to_world"><scale x="2" y="3"/><translate x="1" y="2" z="3"/></transform>
    <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="20"/>{film}</film>
  </sensor>
</scene>
"#
        )
    };
    let whole = load_ok(&sensor("", ""));
    assert_eq!(
        whole.camera.orthographic,
        Some(Orthographic {
            origin: Vec3::new(1.0, 2.0, 3.5),
            right: Vec3::new(-2.0, 0.0, 0.0),
            up: Vec3::new(0.0, 1.5, 0.0),
            dir: Vec3::Z,
        })
    );
    assert_eq!(whole.camera.shift, [0.0; 2]);
    assert_eq!((whole.camera.near_clip, whole.camera.far_clip), (0.5, 1e4));
    assert_eq!((whole.render.width, whole.render.height), (40, 20));
    // The film's top-left quarter: camera x in [0, 1], y in [0, 1/2]
    let crop = load_ok(&sensor(
        r#"<integer name="crop_width" value="20"/><integer name="crop_height" value="10"/>"#,
        "",
    ));
    let o = crop.camera.orthographic.expect("orthographic");
    assert_eq!(
        (o.right, o.up),
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::new(0.0, 0.75, 0.0))
    );
    assert_eq!(crop.camera.shift, [-1.0, 1.0]);
    assert_eq!((crop.render.width, crop.render.height), (20, 10));
    let centre = o.origin + crop.camera.shift[0] * o.right + crop.camera.shift[1] * o.up;
    assert_eq!(centre, Vec3::new(2.0, 2.75, 3.5));
    let err = load_xml(&sensor("", r#"<float name="fov" value="40"/>"#)).expect_err("fov");
    assert_eq!(
        err,
        r#"case.xml:3: <float name="fov">: property `fov` of <sensor type="orthographic"> is outside the subset lancer reads (docs/mitsuba.md); remove it"#
    );
}

/// `lancer convert` stops at a material the TOML format has no type for
/// (a rough dielectric, a rough plastic, a thin dielectric), names it, and
/// writes nothing.
#[test]
fn convert_refuses_a_rough_dielectric() {
    for name in ["roughdielectric", "roughplastic", "thindielectric"] {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = dir.path().join("scene.toml");
        let run = lancer(
            &[
                "convert",
                &format!("tests/scenes/mitsuba/{name}.xml"),
                "--out",
                out.to_str().expect("utf-8 path"),
            ],
            &[],
        );
        let err = stderr(&run);
        assert!(!run.status.success(), "convert succeeded: {err}");
        assert!(
            err.contains(&format!(
                "is a Mitsuba `{name}`, which the TOML scene format has no type for"
            )),
            "{err}"
        );
        assert!(!out.exists(), "convert wrote {}", out.display());
    }
}

/// `lancer convert` stops at what the TOML format cannot state: a texture
/// with a `to_uv` (or a checkerboard), a textured roughness, and an
/// orthographic sensor; it names it and writes nothing.
#[test]
fn convert_refuses_mapped_textures_and_an_orthographic_sensor() {
    let dir = tempfile::tempdir().expect("temp dir");
    let checker = repo("scenes/tex/checker.png");
    let mapped = dir.path().join("mapped.xml");
    std::fs::write(
        &mapped,
        format!(
            r#"<scene version="3.0.0">
  <sensor type="perspective">
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film>
  </sensor>
  <shape type="sphere"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="{}"/><transform name="to_uv"><scale value="2"/></transform></texture></bsdf></shape>
</scene>
"#,
            checker.display()
        ),
    )
    .expect("write scene");
    let ortho = repo("tests/scenes/mitsuba/orthographic.xml");
    let rough = dir.path().join("rough.xml");
    let text = std::fs::read_to_string(&mapped)
        .expect("read scene")
        .replace(
            r#"<bsdf type="diffuse"><texture type="bitmap" name="reflectance">"#,
            r#"<bsdf type="roughconductor"><texture type="bitmap" name="alpha">"#,
        );
    std::fs::write(&rough, text).expect("write scene");
    for (scene, says) in [
        (
            mapped.as_path(),
            "reads a Mitsuba texture with a `to_uv` transform",
        ),
        (
            rough.as_path(),
            "reads its roughness from a texture, which the TOML scene format cannot state",
        ),
        (
            ortho.as_path(),
            "the sensor is orthographic, which a TOML scene cannot state",
        ),
    ] {
        let out = dir.path().join("scene.toml");
        let run = lancer(
            &[
                "convert",
                scene.to_str().expect("utf-8 path"),
                "--out",
                out.to_str().expect("utf-8 path"),
            ],
            &[],
        );
        let err = stderr(&run);
        assert!(!run.status.success(), "convert succeeded: {err}");
        assert!(err.contains(says), "{err}");
        assert!(!out.exists(), "convert wrote {}", out.display());
    }
}

/// A uniform `<spectrum value="x">` (one number) where Mitsuba's RGB
/// variants take a colour: outside emitters the grey x, the same scene as
/// `<rgb value="x">` (reflectance, eta and k, specular factors, a plastic's
/// base); in an emitter (area radiance, a point light's intensity, a
/// constant environment's radiance) the D65 illuminant times x, as
/// Mitsuba 3.9.1 reads it (its RGB for 1: 1.2047939, 0.948291, 0.90891606).
#[test]
fn uniform_spectra_load_as_their_rgb() {
    let materials = |tag: &str| {
        doc(&format!(
            r#"<shape type="sphere"><bsdf type="diffuse"><{tag} name="reflectance" value="0.3"/></bsdf></shape>
  <shape type="sphere"><bsdf type="conductor"><{tag} name="eta" value="0.5"/><{tag} name="k" value="2"/><{tag} name="specular_reflectance" value="0.9"/></bsdf></shape>
  <shape type="sphere"><bsdf type="dielectric"><{tag} name="specular_transmittance" value="0.7"/></bsdf></shape>
  <shape type="sphere"><bsdf type="thindielectric"><{tag} name="specular_reflectance" value="0.8"/></bsdf></shape>
  <shape type="sphere"><bsdf type="plastic"><{tag} name="diffuse_reflectance" value="0.25"/></bsdf></shape>"#
        ))
    };
    let spectra = load_ok(&materials("spectrum"));
    let rgb = load_ok(&materials("rgb"));
    assert_eq!(spectra.materials, rgb.materials);
    assert_eq!(spectra.spheres, rgb.spheres);
    let m = &spectra.materials[spectra.spheres[0].material as usize];
    assert_eq!(
        m.kind,
        MaterialKind::Lambert {
            albedo: lancer::scene::ColorSource::Constant(Vec3::splat(0.3))
        }
    );

    let d65 = Vec3::new(1.204_793_9, 0.948_291, 0.908_916_06);
    let emitters = |tag: &str, x: [f32; 3]| {
        let v = |s: f32| {
            if tag == "spectrum" {
                format!("{s}")
            } else {
                format!("{}, {}, {}", s * d65.x, s * d65.y, s * d65.z)
            }
        };
        doc(&format!(
            r#"<emitter type="constant"><{tag} name="radiance" value="{}"/></emitter>
  <emitter type="point"><{tag} name="intensity" value="{}"/></emitter>
  <shape type="sphere"><emitter type="area"><{tag} name="radiance" value="{}"/></emitter></shape>"#,
            v(x[0]),
            v(x[1]),
            v(x[2])
        ))
    };
    let x = [0.5f32, 3.0, 7.25];
    let spectra = load_ok(&emitters("spectrum", x));
    let rgb = load_ok(&emitters("rgb", x));
    assert_eq!(spectra.environment, rgb.environment);
    assert_eq!(spectra.lights, rgb.lights);
    assert_eq!(spectra.materials, rgb.materials);
    assert_eq!(spectra.environment, d65 * 0.5);
    assert_eq!(
        spectra.materials[spectra.spheres[0].material as usize].emission,
        d65 * 7.25
    );
    // Mitsuba's figure for 7.25, read back from its plugin
    let e = spectra.materials[spectra.spheres[0].material as usize].emission;
    assert!(
        (e - Vec3::new(8.734_756, 6.875_11, 6.589_642))
            .abs()
            .max_element()
            < 1e-5
    );
}

/// `thindielectric` as Mitsuba reads it: bk7 in air and specular factors
/// of 1 by default; named and numeric indices, tinted reflection and
/// transmission; both sides, and light passes through (`transmits`), so
/// it is no `twosided` material.
#[test]
fn thin_dielectrics_map_to_lancer() {
    let s = load_ok(&doc(
        r#"<shape type="sphere"><bsdf type="thindielectric"/></shape>
  <shape type="sphere"><bsdf type="thindielectric"><string name="int_ior" value="Water"/><float name="ext_ior" value="1.1"/><rgb name="specular_reflectance" value="0.5, 0.6, 0.7"/><float name="specular_transmittance" value="0.25"/></bsdf></shape>"#,
    ));
    let m = |i: usize| &s.materials[s.spheres[i].material as usize];
    assert_eq!(
        m(0).kind,
        MaterialKind::ThinDielectric {
            ior: (1.5046f64 / 1.000277) as f32,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::ONE,
        }
    );
    assert_eq!(
        m(1).kind,
        MaterialKind::ThinDielectric {
            // A <float> is read as a 32-bit number
            ior: (1.333f64 / f64::from(1.1f32)) as f32,
            specular_reflectance: Vec3::new(0.5, 0.6, 0.7),
            specular_transmittance: Vec3::splat(0.25),
        }
    );
    for i in 0..2 {
        assert_eq!(m(i).sides, Sides::Both);
        assert!(m(i).kind.transmits());
        assert!(!m(i).kind.in_toml_format());
        assert_eq!(m(i).kind.mitsuba_name(), Some("thindielectric"));
    }
}

/// `roughplastic` as Mitsuba reads it: Beckmann, alpha 0.1, diffuse 0.5,
/// specular 1, int_ior "polypropylene" (1.49) over air, linear; GGX with
/// an isotropic `alpha_u`/`alpha_v`, a named int_ior, a texture through a
/// `<ref>`; one-sided outside `twosided`.
#[test]
fn rough_plastics_map_to_lancer() {
    let checker = repo("scenes/tex/checker.png");
    let s = load_ok(&doc(&format!(
        r#"<texture type="bitmap" id="t"><string name="filename" value="{}"/></texture>
  <shape type="sphere"><bsdf type="roughplastic"/></shape>
  <shape type="sphere"><bsdf type="twosided"><bsdf type="roughplastic"><string name="distribution" value="GGX"/><float name="alpha_u" value="0.3"/><float name="alpha_v" value="0.3"/><ref name="diffuse_reflectance" id="t"/><rgb name="specular_reflectance" value="0.5"/><string name="int_ior" value="PET"/><float name="ext_ior" value="1"/><boolean name="nonlinear" value="true"/><boolean name="sample_visible" value="false"/></bsdf></bsdf></shape>"#,
        checker.display()
    )));
    let m = |i: usize| &s.materials[s.spheres[i].material as usize];
    assert_eq!(
        m(0).kind,
        MaterialKind::RoughPlastic {
            distribution: lancer::scene::Microfacet::Beckmann,
            alpha: 0.1,
            diffuse_reflectance: lancer::scene::ColorSource::Constant(Vec3::splat(0.5)),
            specular_reflectance: Vec3::ONE,
            ior: (1.49f64 / 1.000277) as f32,
            nonlinear: false,
        }
    );
    assert_eq!(m(0).sides, Sides::Front);
    assert_eq!(
        m(1).kind,
        MaterialKind::RoughPlastic {
            distribution: lancer::scene::Microfacet::Ggx,
            alpha: 0.3,
            diffuse_reflectance: lancer::scene::ColorSource::Texture(checker.clone()),
            specular_reflectance: Vec3::splat(0.5),
            ior: 1.575,
            nonlinear: true,
        }
    );
    assert_eq!(m(1).sides, Sides::Shading);
    assert!(!m(0).kind.in_toml_format());
}

/// An emitter without `radiance` shines with Mitsuba's default, 1: a
/// `constant` environment and an `area` light on a shape.
#[test]
fn emitters_without_radiance_shine_with_one() {
    let s = load_ok(&doc(r#"<emitter type="constant"/>
  <shape type="sphere"><emitter type="area"/></shape>"#));
    assert_eq!(s.environment, Vec3::ONE);
    let m = &s.materials[s.spheres[0].material as usize];
    assert_eq!(m.emission, Vec3::ONE);
}

/// The files of the `<include>` tests.
const INCLUDES: &str = "tests/scenes/mitsuba/include";

/// A path as lancer's messages print it: canonical, as the include chain
/// compares files.
fn canonical(path: &Path) -> String {
    path.canonicalize().unwrap().display().to_string()
}

/// `<include>` as Mitsuba 3.9 reads it: include.xml is whole.xml split over
/// four files (a `<scene>` fragment named through a `$param`, one with the
/// shapes that includes a third beside it, a file whose root is a BSDF
/// included inside a shape by `name`, `<default>`s across files with the
/// first one winning, a mesh found from the scene file's folder); it loads
/// to the same scene and renders bit for bit like it. The included files
/// are inputs of the scene.
#[test]
fn an_included_scene_renders_like_the_scene_in_one_file() {
    let whole = load(&format!("{INCLUDES}/whole.xml"));
    let split = load(&format!("{INCLUDES}/include.xml"));
    let names: Vec<String> = (split.includes.iter())
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "light.xml",
            "objects.xml",
            "materials.xml",
            "green_plastic.xml"
        ]
    );
    assert!(whole.includes.is_empty());
    let inputs = split.input_files();
    assert_eq!(inputs[0].1, "the scene file");
    for (path, what) in &inputs[1..5] {
        assert_eq!(what, "a file the scene includes", "{}", path.display());
        assert!(path.is_file(), "{}", path.display());
    }
    assert!(inputs
        .iter()
        .any(|(p, _)| p.ends_with("scenes/meshes/cube.obj")));
    // The scene file's spp (16) wins over light.xml's later <default>.
    assert_eq!(split.render.spp, 16);
    assert!(
        (split.warnings.iter()).any(|w| w.contains(
            "light.xml:6: <default name=\"spp\">: a second <default> of this name is ignored"
        )),
        "{:?}",
        split.warnings
    );
    assert_eq!(split.render, whole.render);
    assert_eq!(split.camera, whole.camera);
    assert_eq!(split.environment, whole.environment);
    assert_eq!(split.spheres, whole.spheres);
    assert_eq!(split.triangles.len(), whole.triangles.len());
    let kinds = |s: &Scene| -> Vec<_> {
        (s.materials.iter())
            .map(|m| (m.kind.clone(), m.emission, m.sides))
            .collect()
    };
    assert_eq!(kinds(&split), kinds(&whole));
    let ctx = context();
    let a = render(&ctx, &whole, &options(1 << 12));
    let b = render(&ctx, &split, &options(1 << 12));
    assert!(a.mean.iter().any(|&v| v > 0.0), "a black image");
    assert_eq!(differing_bits(&a.mean, &b.mean), 0);
    assert_eq!(differing_bits(&a.var_of_mean, &b.var_of_mean), 0);
}

/// An include cycle, a missing file, a file that is not XML, a root without
/// a version and nesting past Mitsuba's 15 are refused, each naming the
/// file and the `<include>` (file and line).
#[test]
fn bad_includes_are_refused_by_name() {
    let a = repo(&format!("{INCLUDES}/cycle_a.xml"));
    let b = repo(&format!("{INCLUDES}/cycle_b.xml"));
    let err = lancer::scene::load(&a).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}:4: <include>: an include cycle: {} includes {} includes {} (Mitsuba would stop \
             at depth 15); remove one of these <include>s",
            b.display(),
            canonical(&a),
            canonical(&b),
            canonical(&a)
        )
    );

    let dir = tempfile::tempdir().expect("temp dir");
    let scene = |body: &str| format!("{HEAD}\n  {body}\n</scene>\n");
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let main = write(
        "main.xml",
        &scene(r#"<include filename="parts/missing.xml"/>"#),
    );
    let err = lancer::scene::load(&main).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}:6: <include>: included file \"parts/missing.xml\" not found (looked for {})",
            main.display(),
            dir.path().join("parts/missing.xml").display()
        )
    );

    let obj = repo("scenes/meshes/cube.obj");
    let main = write(
        "obj.xml",
        &scene(&format!(r#"<include filename="{}"/>"#, obj.display())),
    );
    let err = lancer::scene::load(&main).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}:6: <include>: included file {}:1 is not valid XML: unknown token at 1:1",
            main.display(),
            obj.display()
        )
    );
    let png = repo("tests/scenes/tex/quadrants.png");
    let main = write(
        "png.xml",
        &scene(&format!(r#"<include filename="{}"/>"#, png.display())),
    );
    let err = lancer::scene::load(&main).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}:6: <include>: included file {} is not a text (UTF-8) file; an <include> names a \
             Mitsuba XML file",
            main.display(),
            png.display()
        )
    );

    write(
        "noversion.xml",
        "<scene>\n  <shape type=\"sphere\"/>\n</scene>\n",
    );
    let main = write("v.xml", &scene(r#"<include filename="noversion.xml"/>"#));
    let err = lancer::scene::load(&main).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}:1: <scene>: the root element of an included file needs a `version` attribute \
             (Mitsuba requires it), e.g. <scene version=\"3.0.0\">",
            dir.path().join("noversion.xml").display()
        )
    );

    // A chain of 16 files, each including the next: 14 nested includes
    // load, a 15th is refused (Mitsuba's limit, checked against it).
    for k in 0..16 {
        let next = if k < 15 {
            format!(r#"<include filename="n{}.xml"/>"#, k + 1)
        } else {
            String::from(r#"<shape type="sphere"/>"#)
        };
        write(
            &format!("n{k}.xml"),
            &format!("<scene version=\"3.0.0\">\n  {next}\n</scene>\n"),
        );
    }
    let deep = write("deep.xml", &scene(r#"<include filename="n2.xml"/>"#));
    let s = lancer::scene::load(&deep).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((s.includes.len(), s.spheres.len()), (14, 1));
    let deeper = write("deeper.xml", &scene(r#"<include filename="n1.xml"/>"#));
    let err = lancer::scene::load(&deeper).unwrap_err().to_string();
    assert_eq!(
        err,
        format!(
            "{}:2: <include>: includes nested 15 deep: Mitsuba stops there \
             (`max_include_depth`, the scene file at depth 0), and so does lancer",
            dir.path().join("n14.xml").display()
        )
    );
}

/// A film crop window and a perspective sensor's principal point offset,
/// as Mitsuba's `perspective_projection` and `sample_ray` define them: the
/// image is the crop window, the camera the whole film's (the vertical
/// field of view scaled to the window's height), and the image's centre
/// sits off the axis by the window's offset and the principal point, in
/// half-widths and half-heights of the image. An image size given with a
/// crop window is refused.
#[test]
fn crop_window_and_principal_point_set_the_camera() {
    let path = repo("tests/scenes/mitsuba/crop.xml");
    let text = std::fs::read_to_string(&path).unwrap();
    let with = |defs: &[(&str, &str)]| {
        let mut t = text.clone();
        for (k, v) in defs {
            let at = t.find(&format!(r#"<default name="{k}" value=""#)).unwrap();
            let end = at + t[at..].find("/>").unwrap() + 2;
            t.replace_range(at..end, &format!(r#"<default name="{k}" value="{v}"/>"#));
        }
        t
    };
    let full = load_str(&text, &path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((full.render.width, full.render.height), (64, 48));
    assert_eq!(full.camera.shift, [0.0, 0.0]);
    let scene = load_str(
        &with(&[
            ("cx", "22"),
            ("cy", "9"),
            ("cw", "30"),
            ("ch", "26"),
            ("ppx", "0.12"),
            ("ppy", "-0.08"),
        ]),
        &path,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((scene.render.width, scene.render.height), (30, 26));
    // The window's half-height tangent is the film's times 26 / 48.
    let tan = |deg: f32| (deg as f64).to_radians().mul_add(0.5, 0.0).tan();
    assert!((tan(scene.camera.vfov_deg) - tan(full.camera.vfov_deg) * 26.0 / 48.0).abs() < 1e-6);
    // Centre of the window: x = 22 + 15 = 37 of 64, y = 9 + 13 = 22 of 48;
    // in the film's NDC x = 2 * 37 / 64 - 1 + 2 * 0.12, y = 1 - 2 * 22 / 48
    // + 2 * 0.08; in the image's half sizes: times 64 / 30 and 48 / 26.
    let expected = [
        (2.0 * 37.0 / 64.0 - 1.0 + 0.24) * 64.0 / 30.0,
        (1.0 - 2.0 * 22.0 / 48.0 + 0.16) * 48.0 / 26.0,
    ];
    for (got, want) in scene.camera.shift.iter().zip(expected) {
        assert!(
            (*got as f64 - want).abs() < 1e-6,
            "{:?} vs {expected:?}",
            scene.camera.shift
        );
    }
    assert_eq!(
        (scene.camera.eye, scene.camera.look_at),
        (full.camera.eye, full.camera.look_at)
    );
    let overrides = RenderOverrides {
        width: Some(16),
        ..RenderOverrides::default()
    };
    let err = load_str_with(&with(&[("cw", "30")]), &path, &overrides)
        .unwrap_err()
        .to_string();
    assert!(
        err.ends_with("the film has a crop window, and the image size is given too (--width/--height); lancer does not guess which of the two the new size is for: give the size in the film's width/height and crop_* instead"),
        "{err}"
    );
}

/// `tests/scenes/mitsuba/shapes.serialized` (three meshes) as the shape
/// `extra` (properties) of a scene beside it, with `to_world` a scale of
/// (2, 1, 1): the scene, or the message.
fn serialized_scene(extra: &str) -> Result<Scene, String> {
    let text = doc(&format!(
        r#"<shape type="serialized"><string name="filename" value="shapes.serialized"/><transform name="to_world"><scale x="2" y="1" z="1"/></transform>{extra}</shape>"#
    ));
    load_str(&text, &repo("tests/scenes/mitsuba/case.xml")).map_err(|e| e.to_string())
}

/// Each mesh of a serialized file is picked by `shape_index` and read as
/// Mitsuba 3.9.1 reads it. The figures are Mitsuba's own, read once with
/// `mi.load_dict({"type": "serialized", ..., "to_world": scale(2, 1, 1)})`
/// and `mi.traverse`: vertex 0's world position and normal (a smooth normal
/// computed on the scaled positions for mesh 0; for mesh 1 the file's
/// normal of length 2, transformed by the inverse transpose and
/// normalised) and mesh 1's texture coordinates, which Mitsuba keeps as
/// stored (lancer's v' = 1 - v). Mesh 2's flags ask for face normals, which
/// Mitsuba ignores: it gets smooth normals, and a warning says so.
#[test]
fn serialized_meshes_are_read_as_mitsuba_reads_them() {
    let close = |a: Vec3, b: [f32; 3]| (a - Vec3::from(b)).abs().max_element() < 1e-6;
    // Mesh 0: an icosphere, no normals, single precision.
    let s = serialized_scene("").unwrap();
    assert_eq!(s.triangles.len(), 80);
    let t = &s.triangles[0];
    assert!(close(t.p[0], [-1.0514622, 0.8506508, 0.0]), "{:?}", t.p[0]);
    let n = t.n.expect("smooth normals");
    assert!(close(n[0], [-0.324_507_87, 0.945_883, 0.0]), "{:?}", n[0]);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // Mesh 1: a sheet, double precision, normals, uvs and colours.
    let s = serialized_scene(r#"<integer name="shape_index" value="1"/>"#).unwrap();
    assert_eq!(s.triangles.len(), 48);
    let t = &s.triangles[0];
    assert!(close(t.p[0], [-2.0, -1.0, -0.08977082]), "{:?}", t.p[0]);
    let n = t.n.expect("the file's normals");
    assert!(close(n[0], [0.148_547_83, 0.0, 0.988_905_24]), "{:?}", n[0]);
    let uv = t.uv.expect("the file's uvs");
    let mitsuba_uv = [[0.0, 0.0], [1.0 / 6.0, 0.0], [1.0 / 6.0, 0.25]];
    for (got, [u, v]) in uv.iter().zip(mitsuba_uv) {
        assert!((got.x - u).abs() < 1e-7 && (got.y - (1.0 - v)).abs() < 1e-7);
    }
    // Mesh 2: a UV sphere whose face normals flag changes nothing.
    let s = serialized_scene(r#"<integer name="shape_index" value="2"/>"#).unwrap();
    assert_eq!(s.triangles.len(), 100);
    assert!(s.triangles.iter().all(|t| t.n.is_some()));
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].ends_with(
            "shapes.serialized: mesh 2's flags ask for face normals (0x0010), which Mitsuba \
             3.9.1 ignores (only the shape's `face_normals` counts), and so does lancer; add \
             <boolean name=\"face_normals\" value=\"true\"/> to the shape for face normals"
        ),
        "{}",
        s.warnings[0]
    );
    // face_normals: flat, the file's normals read past, no warning.
    for index in 0..3 {
        let s = serialized_scene(&format!(
            r#"<integer name="shape_index" value="{index}"/><boolean name="face_normals" value="true"/>"#
        ))
        .unwrap();
        assert!(s.triangles.iter().all(|t| t.n.is_none()));
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }
    // The file is an input of the scene.
    let s = serialized_scene("").unwrap();
    assert!(s
        .input_files()
        .iter()
        .any(|(p, _)| p.ends_with("mitsuba/shapes.serialized")));
}

/// A shape_index past the file's meshes, a negative one, one on another
/// shape type, `max_smooth_angle` (which Mitsuba's serialized shape does not
/// read) and a file that is not a serialized mesh are refused by name.
#[test]
fn bad_serialized_shapes_are_refused_by_name() {
    let file = repo("tests/scenes/mitsuba/shapes.serialized");
    let scene = repo("tests/scenes/mitsuba/case.xml");
    let at = |what: &str| format!("{}:6: {what}", scene.display());
    assert_eq!(
        serialized_scene(r#"<integer name="shape_index" value="3"/>"#).unwrap_err(),
        at(&format!(
            "<string name=\"filename\">: attribute `value`: serialized file {}: shape_index 3 \
             is out of range: its end-of-file table lists 3 meshes (shape_index 0 to 2)",
            file.display()
        ))
    );
    assert_eq!(
        serialized_scene(r#"<integer name="shape_index" value="-1"/>"#).unwrap_err(),
        at(
            "<integer name=\"shape_index\">: attribute `value`: must be an integer from 0 to \
            4294967295, got -1"
        )
    );
    // Mitsuba 3.9.1 refuses it too ("unreferenced property").
    assert_eq!(
        serialized_scene(r#"<float name="max_smooth_angle" value="30"/>"#).unwrap_err(),
        at(
            "<float name=\"max_smooth_angle\">: property `max_smooth_angle` of <shape \
            type=\"serialized\"> is outside the subset lancer reads (docs/mitsuba.md); remove it"
        )
    );
    let text = doc(
        r#"<shape type="ply"><string name="filename" value="../meshes/icosphere.ply"/><integer name="shape_index" value="0"/></shape>"#,
    );
    assert_eq!(
        load_str(&text, &scene).unwrap_err().to_string(),
        at(
            "<integer name=\"shape_index\">: property `shape_index` of <shape type=\"ply\"> is \
            outside the subset lancer reads (docs/mitsuba.md); remove it"
        )
    );
    let text =
        doc(r#"<shape type="serialized"><string name="filename" value="serialized.xml"/></shape>"#);
    let xml = repo("tests/scenes/mitsuba/serialized.xml");
    assert_eq!(
        load_str(&text, &scene).unwrap_err().to_string(),
        at(&format!(
            "<string name=\"filename\">: attribute `value`: serialized file {}: it starts with \
             0x733c, not the format id 0x041c of a Mitsuba serialized mesh: not a serialized \
             file",
            xml.display()
        ))
    );
}

/// An instance places its group's shapes by its `to_world` as Mitsuba
/// does (tests/scenes/mitsuba/instances.xml): points moved, shading normals
/// by the inverse transpose, a mirror turning the winding round so that the
/// geometric normal is the inverse transpose's too, spheres moved with
/// their frames; the group is read once, and a group no instance names
/// draws nothing.
#[test]
fn instances_place_their_groups_shapes_as_mitsuba_does() {
    use glam::{Mat3, Vec3};
    let scene = load("tests/scenes/mitsuba/instances.xml");
    assert_eq!(scene.spheres.len(), 3);
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    // The group's sphere, at (-0.65, 0, 0) with radius 0.3 and turned 60
    // degrees about x, in each instance
    let r = Mat3::from_rotation_x(60f32.to_radians());
    let placed: [(Mat3, Vec3); 3] = [
        (Mat3::IDENTITY, Vec3::new(-1.25, 1.15, 0.0)),
        (
            Mat3::from_diagonal(Vec3::splat(0.9))
                * Mat3::from_rotation_x(25f32.to_radians())
                * Mat3::from_rotation_y(40f32.to_radians()),
            Vec3::new(1.25, 1.15, 0.0),
        ),
        (
            Mat3::from_rotation_z(20f32.to_radians())
                * Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0)),
            Vec3::new(-1.25, -0.55, 0.0),
        ),
    ];
    for (s, (m, t)) in scene.spheres.iter().zip(placed) {
        let k = m.x_axis.length();
        assert!(close(s.center, m * Vec3::new(-0.65, 0.0, 0.0) + t), "{s:?}");
        assert!((s.radius - 0.3 * k).abs() < 1e-6, "{s:?}");
        let frame = s.mitsuba_frame.expect("a frame");
        let want = [r.x_axis, r.y_axis, r.z_axis].map(|a| (m * a).normalize());
        assert!(
            frame.iter().zip(want).all(|(a, b)| close(*a, b)),
            "{frame:?} against {want:?}"
        );
    }
    // The mirrored instance's frame is left-handed
    let [x, y, z] = scene.spheres[2].mitsuba_frame.unwrap();
    assert!(x.cross(y).dot(z) < -0.999);

    // Each instanced triangle's geometric normal (by its winding) and
    // shading normals lie on the side the inverse transpose takes the
    // group's normals to: outward from the instance's OBJ sphere
    let centres = [
        Vec3::new(-1.25, 1.15, 0.0),
        Vec3::new(1.25, 1.15, 0.0),
        Vec3::new(-1.25, -0.55, 0.0),
        Vec3::new(1.1, -0.6, 0.0),
    ];
    let mut checked = [0; 4];
    for t in &scene.triangles {
        let c = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        let Some(k) = centres.iter().position(|o| (c - *o).length() < 0.75) else {
            continue;
        };
        let Some(n) = t.n else { continue };
        let outward = c - centres[k];
        let geometric = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
        assert!(geometric.dot(outward) > 0.0, "instance {k}: {t:?}");
        assert!(
            n.iter().all(|v| v.dot(outward) > 0.0),
            "instance {k}: {t:?}"
        );
        checked[k] += 1;
    }
    assert!(checked.iter().all(|&c| c >= 20), "{checked:?}");
    // The stretched instance's shading normals: the inverse transpose of
    // the group's (a normal of the unit sphere is its point), so they are
    // normal to the stretched sphere: M^-T (M^-1 (p - o)) is the gradient
    // of |M^-1 (p - o)|^2
    let m =
        Mat3::from_rotation_z(30f32.to_radians()) * Mat3::from_diagonal(Vec3::new(1.5, 0.6, 1.0));
    let inv = m.inverse();
    let mut stretched = 0;
    for t in &scene.triangles {
        let c = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        if (c - centres[3]).length() >= 0.75 {
            continue;
        }
        let Some(n) = t.n else { continue };
        for (p, n) in t.p.iter().zip(n) {
            let gradient = (inv.transpose() * (inv * (*p - centres[3]))).normalize();
            // The OBJ sphere is coarse: its smooth normals lean by a few degrees
            assert!(n.dot(gradient) > 0.97, "{n} against {gradient}");
        }
        stretched += 1;
    }
    assert!(stretched >= 20, "{stretched}");

    // A group no instance names draws nothing, with a warning
    let scene = load_ok(&doc(
        r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape>"#,
    ));
    assert!(scene.triangles.is_empty());
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("no <shape type=\"instance\"> names this shapegroup")),
        "{:?}",
        scene.warnings
    );
    // A group instanced twice: twice its triangles
    let scene = load_ok(&doc(
        r#"<shape type="shapegroup" id="g"><shape type="cube"/></shape>
  <shape type="instance"><ref id="g"/></shape>
  <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="3"/></transform></shape>"#,
    ));
    assert_eq!(scene.triangles.len(), 24);
}

/// A sphere's frame is the rotation of its `to_world`, a mirror kept: the
/// frame Mitsuba's texture coordinates and tangent are taken in
/// (tests/scenes/mitsuba/sphere_frames.xml). `lancer convert` refuses a
/// textured sphere, whose TOML form would take lancer's coordinates.
#[test]
fn spheres_keep_mitsubas_frame_and_convert_refuses_textured_ones() {
    use glam::{Mat3, Vec3};
    let scene = load("tests/scenes/mitsuba/sphere_frames.xml");
    let frame = |i: usize| scene.spheres[i].mitsuba_frame.expect("a frame");
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
    // Moved only: the world's axes
    assert_eq!(frame(0), [Vec3::X, Vec3::Y, Vec3::Z]);
    // Turned about x by 70 degrees, then about z by 35
    let r = Mat3::from_rotation_z(35f32.to_radians()) * Mat3::from_rotation_x(70f32.to_radians());
    let [x, y, z] = frame(1);
    assert!(
        close(x, r.x_axis) && close(y, r.y_axis) && close(z, r.z_axis),
        "{:?}",
        frame(1)
    );
    // Mirrored in y: a left-handed frame
    let [x, y, z] = frame(2);
    assert!(x.cross(y).dot(z) < -0.999, "{:?}", frame(2));
    assert!((scene.spheres[2].radius - 0.8).abs() < 1e-6);
    // TOML spheres have no frame
    assert!(load("scenes/glass.toml")
        .spheres
        .iter()
        .all(|s| s.mitsuba_frame.is_none()));

    let dir = tempfile::tempdir().expect("temp dir");
    let toml = dir.path().join("spheres.toml");
    let out = lancer(
        &[
            "convert",
            "tests/scenes/mitsuba/sphere_frames.xml",
            "--out",
            toml.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("takes Mitsuba's texture coordinates or tangent")
            && err.contains("use a sphere mesh (obj or ply)"),
        "{err}"
    );
}

/// A projector's field of view as Mitsuba's `parse_fov` reads it, with the
/// aspect ratio of its irradiance image (1 for a colour); a spot's texture
/// by nesting and by `<ref>`; `lancer convert` refuses both, which the TOML
/// format cannot state. (The images are z-tested against Mitsuba in
/// tests/it/reference.rs.)
#[test]
fn projectors_and_spot_textures_are_read_as_mitsuba_defines_them() {
    use lancer::scene::DeltaLight;
    let scene = load("tests/scenes/mitsuba/projector.xml");
    let cots: Vec<(f32, f32)> = (scene.lights.iter())
        .map(|l| match l {
            DeltaLight::Projector { cot_x, cot_y, .. } => (*cot_x, *cot_y),
            other => panic!("not a projector: {other:?}"),
        })
        .collect();
    let deg = |a: f64| a.to_radians();
    // fov 45 on x over a 64 x 32 image: cot_y is twice cot_x
    let x = 1.0 / deg(22.5).tan();
    // 85 mm on 35 mm film measures the diagonal of a square (1 x 1) image
    let diagonal = 2.0 * (36f64.hypot(24.0) / (2.0 * 85.0)).atan();
    let square = 1.0 / ((diagonal / 2.0).tan() / 2f64.sqrt());
    // fov 25 on y of a square image
    let y = 1.0 / deg(12.5).tan();
    let expected = [(x, 2.0 * x), (square, square), (y, y)];
    for (k, (&(cx, cy), (ex, ey))) in cots.iter().zip(expected).enumerate() {
        assert!(
            (f64::from(cx) - ex).abs() < 1e-5 * ex && (f64::from(cy) - ey).abs() < 1e-5 * ey,
            "projector {k}: ({cx}, {cy}), expected ({ex}, {ey})"
        );
    }
    let DeltaLight::Projector {
        irradiance, scale, ..
    } = &scene.lights[0]
    else {
        unreachable!()
    };
    assert!(irradiance.file().is_some_and(|f| f.ends_with("sky.exr")));
    assert_eq!(*scale, 3.0);
    let DeltaLight::Projector { irradiance, .. } = &scene.lights[1] else {
        unreachable!()
    };
    assert_eq!(*irradiance, ColorSource::Constant(Vec3::new(3.0, 2.0, 1.0)));

    let spots = load("tests/scenes/mitsuba/spot_texture.xml");
    let textures: Vec<_> = spots.lights.iter().map(|l| l.texture().cloned()).collect();
    assert!(matches!(&textures[0], Some(ColorSource::Texture(p)) if p.ends_with("quadrants.png")));
    assert!(
        matches!(&textures[1], Some(ColorSource::Mapped(_))),
        "{:?}",
        textures[1]
    );

    let dir = tempfile::tempdir().expect("temp dir");
    for (file, what) in [
        ("projector", "a projector"),
        ("spot_texture", "a spot light with a texture"),
    ] {
        let toml = dir.path().join(format!("{file}.toml"));
        let out = lancer(
            &[
                "convert",
                &format!("tests/scenes/mitsuba/{file}.xml"),
                "--out",
                toml.to_str().unwrap(),
            ],
            &[],
        );
        assert!(!out.status.success());
        let err = stderr(&out);
        assert!(
            err.contains(&format!(
                "the scene has {what}, which a TOML scene cannot state"
            )),
            "{err}"
        );
        assert!(!toml.exists());
    }
}

/// An ASCII PLY of a unit square (4 vertices, one quad face) with the
/// vertex properties `vertex` (after x, y, z; one row per vertex in
/// `rows`) and the face properties `face` (values `face_values`).
fn attribute_ply(vertex: &[&str], rows: [&str; 4], face: &[&str], face_values: &str) -> String {
    let mut t = String::from("ply\nformat ascii 1.0\nelement vertex 4\n");
    for p in ["float x", "float y", "float z"].iter().chain(vertex) {
        t += &format!("property {p}\n");
    }
    t += "element face 1\nproperty list uchar int vertex_indices\n";
    for p in face {
        t += &format!("property {p}\n");
    }
    t += "end_header\n";
    for (xyz, row) in ["0 0 0", "1 0 0", "1 1 0", "0 1 0"].iter().zip(rows) {
        t += &format!("{xyz} {row}\n");
    }
    t + &format!("4 0 1 2 3 {face_values}\n")
}

/// The scene of one PLY shape `mesh.ply` (written from `ply` into `dir`)
/// whose BSDF is `bsdf`, loaded: the scene, or the message.
fn attribute_scene(dir: &Path, ply: &str, shape_extra: &str, bsdf: &str) -> Result<Scene, String> {
    std::fs::write(dir.join("mesh.ply"), ply).unwrap();
    let text = doc(&format!(
        r#"<shape type="ply"><string name="filename" value="mesh.ply"/>{shape_extra}{bsdf}</shape>"#
    ));
    load_str(&text, &dir.join("case.xml")).map_err(|e| e.to_string())
}

/// Mesh attributes (Mitsuba's `mesh_attribute`) are found in a PLY file
/// under Mitsuba's names, given to each triangle at its corners in its
/// order (a face's value at all three, a one-channel value in all three
/// channels, a quad's value on both its triangles; turned round with the
/// corners by `flip_normals`), and refused where Mitsuba 3.9.1 refuses
/// them, each with its own message.
#[test]
fn mesh_attributes_are_read_and_refused_as_mitsuba_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let texture = |name: &str, slot: &str| {
        format!(
            r#"<texture type="mesh_attribute" name="{slot}"><string name="name" value="{name}"/></texture>"#
        )
    };
    let diffuse = |name: &str| {
        format!(
            r#"<bsdf type="diffuse">{}</bsdf>"#,
            texture(name, "reflectance")
        )
    };
    let ply = attribute_ply(
        &[
            "float red",
            "float green",
            "float blue",
            "float gloss_0",
            "float n_x",
            "float n_y",
            "float n_z",
            "float n_w",
            "uchar level_0",
        ],
        [
            "0.1 0.2 0.3 0.5 0 0 0 0 1",
            "0.4 0.5 0.6 0.25 0 0 0 0 2",
            "0.7 0.8 0.9 0.125 0 0 0 0 3",
            "0.2 0.4 0.6 1 0 0 0 0 4",
        ],
        &[
            "float tint_0",
            "float tint_1",
            "float tint_2",
            "float weight_0",
        ],
        "0.3 0.6 0.9 0.75",
    );
    let v = |r, g, b| Vec3::new(r, g, b);
    let corners = |s: &Scene| -> Vec<[Vec3; 3]> {
        s.triangles
            .iter()
            .map(|t| s.mesh_attributes[t.attribute.expect("an attribute") as usize])
            .collect()
    };
    // Vertex colours (red, green, blue): the fan's corners 0 1 2 and 0 2 3
    let s = attribute_scene(dir.path(), &ply, "", &diffuse("vertex_color")).unwrap();
    assert_eq!(
        corners(&s),
        [
            [v(0.1, 0.2, 0.3), v(0.4, 0.5, 0.6), v(0.7, 0.8, 0.9)],
            [v(0.1, 0.2, 0.3), v(0.7, 0.8, 0.9), v(0.2, 0.4, 0.6)]
        ]
    );
    assert!(matches!(
        s.materials[0].diffuse_source(),
        Some(ColorSource::Attribute(a)) if a.name == "vertex_color" && a.scale == 1.0
    ));
    // Turned round: corners 1 and 2 change places with the vertices
    let s = attribute_scene(
        dir.path(),
        &ply,
        r#"<boolean name="flip_normals" value="true"/>"#,
        &diffuse("vertex_color"),
    )
    .unwrap();
    assert_eq!(
        corners(&s)[0],
        [v(0.1, 0.2, 0.3), v(0.7, 0.8, 0.9), v(0.4, 0.5, 0.6)]
    );
    // Instanced: a mirroring instance turns the corners round too, a plain
    // one keeps them
    std::fs::write(dir.path().join("mesh.ply"), &ply).unwrap();
    for (scale, second) in [("1", v(0.4, 0.5, 0.6)), ("-1", v(0.7, 0.8, 0.9))] {
        let text = doc(&format!(
            r#"<shape type="shapegroup" id="g"><shape type="ply"><string name="filename" value="mesh.ply"/>{}</shape></shape><shape type="instance"><ref id="g"/><transform name="to_world"><scale x="{scale}"/></transform></shape>"#,
            diffuse("vertex_color")
        ));
        let s = load_str(&text, &dir.path().join("case.xml")).unwrap();
        assert_eq!(corners(&s)[0][1], second, "x scale {scale}");
    }
    // A face colour, scaled by the texture, on both triangles of the quad
    let scaled = r#"<bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"><string name="name" value="face_tint"/><float name="scale" value="0.5"/></texture></bsdf>"#;
    let s = attribute_scene(dir.path(), &ply, "", scaled).unwrap();
    assert_eq!(corners(&s), [[v(0.3, 0.6, 0.9); 3]; 2]);
    assert!(
        matches!(s.materials[0].diffuse_source(), Some(ColorSource::Attribute(a)) if a.scale == 0.5)
    );
    // One channel in all three: a vertex roughness, a face weight
    let rough = format!(
        r#"<bsdf type="roughconductor">{}</bsdf>"#,
        texture("vertex_gloss", "alpha")
    );
    let s = attribute_scene(dir.path(), &ply, "", &rough).unwrap();
    assert_eq!(
        corners(&s)[1],
        [Vec3::splat(0.5), Vec3::splat(0.125), Vec3::splat(1.0)]
    );
    let blend = format!(
        r#"<bsdf type="blendbsdf">{}<bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#,
        texture("face_weight", "weight")
    );
    let s = attribute_scene(dir.path(), &ply, "", &blend).unwrap();
    assert_eq!(corners(&s), [[Vec3::splat(0.75); 3]; 2]);
    // n_x .. n_w is a group of four fields, which Mitsuba leaves out (it
    // keeps groups of 1 or 3): the file's attributes are listed
    let case = dir.path().join("case.xml").display().to_string();
    let err = attribute_scene(dir.path(), &ply, "", &diffuse("vertex_n")).unwrap_err();
    let ply_path = dir.path().join("mesh.ply").display().to_string();
    assert_eq!(
        err,
        format!("{case}:6: <string name=\"filename\">: attribute `value`: {ply_path}: material `bsdf@6` reads the mesh attribute `vertex_n`, which the file does not have (it has: vertex_color, vertex_gloss, vertex_level, face_tint, face_weight; Mitsuba refuses it too)")
    );
    // Refused as Mitsuba 3.9.1 refuses them
    let refused = |ply: &str, bsdf: &str| attribute_scene(dir.path(), ply, "", bsdf).unwrap_err();
    let alpha = attribute_ply(
        &["float r", "float g", "float b", "float a"],
        ["0.1 0.1 0.1 1"; 4],
        &[],
        "",
    );
    assert!(refused(&alpha, &diffuse("vertex_color")).contains("which has 4 channels (a colour with alpha); Mitsuba 3.9.1 evaluates attributes of 1 or 3 channels"));
    assert!(refused(
        &ply,
        &format!(
            r#"<bsdf type="roughconductor">{}</bsdf>"#,
            texture("vertex_color", "alpha")
        )
    )
    .contains("reads the 3-channel mesh attribute `vertex_color` as one channel"));
    let two = format!(
        r#"<bsdf type="blendbsdf">{}<bsdf type="diffuse">{}</bsdf><bsdf type="diffuse"/></bsdf>"#,
        texture("face_weight", "weight"),
        texture("vertex_color", "reflectance")
    );
    assert!(refused(&ply, &two).contains("lancer reads one attribute per material"));
    // Integer colours are read as they are (Mitsuba 3.9.1): 255 is 255
    let bytes = attribute_ply(
        &["uchar red", "uchar green", "uchar blue"],
        ["255 128 0"; 4],
        &[],
        "",
    );
    assert!(refused(&bytes, &diffuse("vertex_color")).contains("its values reach 255"));
    // A one-channel integer attribute is read, with a warning
    let s = attribute_scene(
        dir.path(),
        &ply,
        "",
        &format!(
            r#"<bsdf type="roughconductor">{}</bsdf>"#,
            texture("vertex_level", "alpha")
        ),
    )
    .unwrap();
    assert_eq!(
        corners(&s)[0],
        [Vec3::splat(1.0), Vec3::splat(2.0), Vec3::splat(3.0)]
    );
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("the mesh attribute `vertex_level` is stored as integers")),
        "{:?}",
        s.warnings
    );
    // Where no mesh gives attributes, and where a texture cannot be one
    for (body, message) in [
        (format!(r#"<shape type="sphere">{}</shape>"#, diffuse("vertex_color")), r#"case.xml:6: <shape type="sphere">: a `sphere` shape has no mesh attribute `vertex_color`, which its material reads through a mesh_attribute texture; lancer reads mesh attributes from PLY files (as Mitsuba's PLY loader names them): give the shape a PLY file, or the material another texture"#.to_string()),
        (format!(r#"<shape type="sphere"><bsdf type="diffuse">{}</bsdf></shape>"#, texture("color", "reflectance")), r#"case.xml:6: <string name="name">: attribute `value`: mesh attribute name "color" must start with "vertex_" or "face_" (Mitsuba refuses it too)"#.to_string()),
        (format!(r#"<shape type="sphere"><bsdf type="normalmap">{}<bsdf type="diffuse"/></bsdf></shape>"#, texture("vertex_color", "normalmap")), r#"case.xml:6: <bsdf type="normalmap">: a normalmap of a mesh_attribute is outside the subset lancer reads; give a bitmap"#.to_string()),
        (format!(r#"<emitter type="spot">{}</emitter>"#, texture("vertex_color", "texture")), r#"case.xml:6: <texture type="mesh_attribute" name="texture">: a light's `texture` of a mesh_attribute is outside the subset lancer reads (a light has no mesh); give a bitmap"#.to_string()),
    ] {
        assert_eq!(load_xml(&doc(&body)).unwrap_err(), message);
    }
}
