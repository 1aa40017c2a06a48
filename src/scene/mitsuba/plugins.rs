//! The plugins of a Mitsuba scene: the integrator, the sensor and its film,
//! BSDFs and textures, and shapes (spheres, rectangles, cubes, OBJ and PLY
//! meshes), each turned into lancer's scene types.

use super::*;

/// A roughness as Mitsuba reads it: a number, or a texture read as one
/// channel.
#[derive(Clone)]
enum Alpha {
    /// A constant roughness.
    Value(f32),
    /// A roughness varying over the surface.
    Texture(ColorSource),
}

/// A BSDF as a shape takes it.
struct Bsdf<'a, 'i> {
    /// Its element, for identity and naming.
    node: Node<'a, 'i>,
    /// How it scatters.
    kind: MaterialKind,
    /// The sides Mitsuba shades.
    sides: Sides,
    /// A `mask`'s opacity; `None` when opaque.
    opacity: Option<ColorSource>,
    /// A `normalmap`'s map; `None` without one.
    normal_map: Option<NormalMap>,
}

/// Mitsuba's `rectangle`: [-1, 1]^2 in z = 0, front side +z: corners,
/// their texture coordinates (Mitsuba's: v = 0 is the image's top row) and
/// the two faces.
const RECTANGLE_CORNERS: [[f64; 3]; 4] = [
    [-1.0, -1.0, 0.0],
    [1.0, -1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [1.0, 1.0, 0.0],
];
const RECTANGLE_UV: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
const RECTANGLE_FACES: [[usize; 3]; 2] = [[1, 2, 0], [1, 3, 2]];

/// One face of Mitsuba's `cube` ([-1, 1]^3): four corners, counter-clockwise
/// seen from outside, with Mitsuba's texture coordinates (0,1) (1,1) (1,0)
/// (0,0); the faces are (0, 1, 2) and (3, 0, 2).
const CUBE_FACES: [[[f64; 3]; 4]; 6] = [
    [
        [1., -1., -1.],
        [1., -1., 1.],
        [-1., -1., 1.],
        [-1., -1., -1.],
    ],
    [[1., 1., -1.], [-1., 1., -1.], [-1., 1., 1.], [1., 1., 1.]],
    [[1., -1., -1.], [1., 1., -1.], [1., 1., 1.], [1., -1., 1.]],
    [[1., -1., 1.], [1., 1., 1.], [-1., 1., 1.], [-1., -1., 1.]],
    [
        [-1., -1., 1.],
        [-1., 1., 1.],
        [-1., 1., -1.],
        [-1., -1., -1.],
    ],
    [
        [1., 1., -1.],
        [1., -1., -1.],
        [-1., -1., -1.],
        [-1., 1., -1.],
    ],
];
const CUBE_UV: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];

/// What the `<integrator>` decides about the render.
struct Integration {
    /// Longest path in segments.
    max_depth: u32,
    /// Mitsuba's `hide_emitters`.
    hide_emitters: bool,
    /// `direct` with `bsdf_samples` 0.
    emitter_sampling_only: bool,
    /// `direct` with `emitter_samples` 0.
    bsdf_sampling_only: bool,
    /// `direct`'s `emitter_samples`, by which it multiplies delta lights.
    delta_light_gain: u32,
    /// Russian roulette's start in lancer's terms (`path`'s `rr_depth`).
    rr_depth: u32,
    /// With `hide_emitters`, how the integrator treats an area emitter seen
    /// directly where that is not `path`'s rule (which lancer follows): the
    /// scene is refused if it has one.
    hidden_emitter_rule: Option<&'static str>,
}

/// The path tracers of Mitsuba 3.9.1 that give `path`'s image in
/// expectation on a scene without media, and how they differ from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PathTracer {
    /// `path` (and `direct`, which sets its own depth).
    Path,
    /// `volpath` and `volpathmis`: on surfaces the standard path tracer.
    VolPath,
    /// `prb`: path replay backpropagation, whose primal pass is a path
    /// tracer with `path`'s estimators.
    Prb,
    /// `prb_projective`: `prb` with projective sampling of derivatives.
    PrbProjective,
    /// `direct_projective`: direct light by MIS of emitter and BSDF
    /// samples, as `direct` with one sample of each; it sets its depth to
    /// 2 whatever the scene says.
    DirectProjective,
}

/// The integrators lancer reads, by Mitsuba's name, in the order its
/// messages list them (`direct` is the path tracer with its own depth).
const INTEGRATORS: &[(&str, PathTracer)] = &[
    ("path", PathTracer::Path),
    ("direct", PathTracer::Path),
    ("volpath", PathTracer::VolPath),
    ("volpathmis", PathTracer::VolPath),
    ("prb", PathTracer::Prb),
    ("prb_projective", PathTracer::PrbProjective),
    ("direct_projective", PathTracer::DirectProjective),
];

impl PathTracer {
    /// `max_depth` when the scene gives none: Mitsuba's C++ integrators
    /// trace without limit, its Python ones (`ADIntegrator`) stop at 6.
    fn default_max_depth(self) -> u32 {
        match self {
            PathTracer::Prb | PathTracer::PrbProjective => 6,
            PathTracer::DirectProjective => 2,
            PathTracer::Path | PathTracer::VolPath => UNLIMITED_DEPTH,
        }
    }

    /// How much later than `path` the roulette starts for the same
    /// `rr_depth`: `path` counts the vertex before it tests `depth >=
    /// rr_depth`; `prb` tests `depth >= rr_depth` before counting it, and
    /// `volpath` tests `depth > rr_depth` at the top of the next round. The
    /// start changes the noise and the work, not the expected image; lancer
    /// starts at the same vertex, so the work per sample is the same.
    fn rr_offset(self) -> u32 {
        match self {
            PathTracer::Path => 0,
            PathTracer::VolPath
            | PathTracer::Prb
            | PathTracer::PrbProjective
            | PathTracer::DirectProjective => 1,
        }
    }

    /// What `hide_emitters` does with an area emitter seen directly, where
    /// that differs from `path`, which passes through it and shows what
    /// lies behind.
    fn hidden_emitter_rule(self) -> Option<&'static str> {
        match self {
            PathTracer::Path | PathTracer::Prb => None,
            PathTracer::DirectProjective => Some(
                "direct_projective's hide_emitters stops a camera ray at an area emitter and \
                 shows its surface without the emission, where lancer follows path, which \
                 shows what lies behind it",
            ),
            PathTracer::VolPath => Some(
                "volpath's hide_emitters stops a camera ray at an area emitter and shows its \
                 surface without the emission, where lancer follows path, which shows what \
                 lies behind it",
            ),
            PathTracer::PrbProjective => Some(
                "prb_projective's hide_emitters hides only the environment and still shows \
                 area emitters seen directly, where lancer follows path, which hides them",
            ),
        }
    }
}

/// What the `<film>` decides.
struct Film {
    /// The film's size in pixels.
    width: u32,
    /// The film's height in pixels.
    height: u32,
    /// The reconstruction filter.
    filter: PixelFilter,
    /// Mitsuba's `sample_border`.
    sample_border: bool,
    /// The crop window, `[offset_x, offset_y, width, height]`, where it is
    /// not the whole film.
    crop: Option<[u32; 4]>,
}

/// A built-in shape's corners, their texture coordinates and its faces.
pub(super) type ShapeFaces = (Vec<[f64; 3]>, Vec<[f32; 2]>, Vec<[usize; 3]>);

/// Segments of the polygon that stands for Mitsuba's `disk`.
pub(super) const DISK_SEGMENTS: usize = 256;

/// Sides of the prism that stands for Mitsuba's `cylinder`.
pub(super) const CYLINDER_SEGMENTS: usize = 256;

/// The tangent and bitangent Mitsuba 3 gives a unit normal `n` when it
/// builds a frame from it (`coordinate_system` in its vector.h: Duff et
/// al. 2017, branchless), so that the frame's x axis is Mitsuba's.
pub(super) fn mitsuba_coordinate_system(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Mitsuba's `disk` (the unit disk in z = 0, front side +z) as a fan of
/// [`DISK_SEGMENTS`] triangles around its centre: corners, Mitsuba's
/// texture coordinates (u = radius, v = angle / 2 pi; the centre takes the
/// middle angle of its triangle) and faces. The polygon's corners lie at
/// radius `1 / sqrt(n sin(2 pi / n) / (2 pi))`, so that its area is the
/// disk's (pi): emitted power and the chance to be hit are exact, and the
/// outline is within 5.1e-5 radii of the circle (corners 5.0e-5 outside,
/// edge midpoints 2.5e-5 inside).
pub(super) fn disk_fan() -> ShapeFaces {
    let n = DISK_SEGMENTS;
    let step = std::f64::consts::TAU / n as f64;
    let rim = (std::f64::consts::PI / (0.5 * n as f64 * step.sin())).sqrt();
    let mut pos = Vec::with_capacity(2 * n + 1);
    let mut uv = Vec::with_capacity(2 * n + 1);
    let mut faces = Vec::with_capacity(n);
    for k in 0..n {
        let (a0, a1) = (k as f64 * step, (k + 1) as f64 * step);
        let base = pos.len();
        pos.push([0.0, 0.0, 0.0]);
        pos.push([rim * a0.cos(), rim * a0.sin(), 0.0]);
        pos.push([rim * a1.cos(), rim * a1.sin(), 0.0]);
        let v = |a: f64| (a / std::f64::consts::TAU) as f32;
        uv.push([0.0, v(0.5 * (a0 + a1))]);
        uv.push([1.0, v(a0)]);
        uv.push([1.0, v(a1)]);
        faces.push([base, base + 1, base + 2]);
    }
    (pos, uv, faces)
}

impl<'a, 'i> Loader<'a, 'i> {
    pub(super) fn scene(&mut self, root: Node<'a, 'i>) -> Result<Scene> {
        if root.tag_name().name() != "scene" {
            return Err(self.err(root, "the top element must be <scene version=\"3.0.0\">"));
        }
        self.check_attrs(root, &["version"])?;
        let version = self.required_attr(root, "version")?;
        let Some(parsed) = parse_version(&version) else {
            return Err(self.attr_err(
                root,
                "version",
                format!(
                    "expected three numbers separated by periods (e.g. \"3.0.0\"), got \"{}\"",
                    cut(&version)
                ),
            ));
        };
        // Mitsuba 3 upgrades the property names of files older than 2.0.0
        // (each included file by its own version, checked as it was read).
        self.upgrade_v1[0] = parsed < [2, 0, 0];
        for (k, doc) in self.docs.iter().enumerate().skip(1) {
            let v = doc
                .root_element()
                .attribute("version")
                .and_then(parse_version);
            self.upgrade_v1[k] = v.is_some_and(|v| v < [2, 0, 0]);
        }
        let mut top = self.props(root)?;
        // Defaults (gathered in document order with the included files) and
        // named BSDFs first: `$name` and `<ref>` may use them.
        for (child, used) in top.children.iter_mut() {
            match child.tag_name().name() {
                "default" => {
                    *used = true;
                    self.check_attrs(*child, &["name", "value"])?;
                }
                // The <path>s of an included file serve its <include>s only
                // (include.rs); Mitsuba finds the files plugins name by the
                // scene file's own.
                "path" if self.doc_index(*child) > 0 => *used = true,
                "path" => {
                    *used = true;
                    self.check_attrs(*child, &["value"])?;
                    let value = self.required_attr(*child, "value")?;
                    let folder = self.dir.join(&value);
                    if !folder.is_dir() {
                        return Err(self.attr_err(
                            *child,
                            "value",
                            format!(
                                "folder {} not found (a <path> is relative to the scene file)",
                                crate::util::text::cut_path(&folder)
                            ),
                        ));
                    }
                    // A later <path> is searched first, as in Mitsuba.
                    self.search.insert(0, folder);
                }
                "bsdf" | "texture" if child.attribute("id").is_none() => {
                    return Err(self.err(
                        *child,
                        format!(
                            "a top-level <{}> needs an `id` for <ref id=\"...\"/>",
                            child.tag_name().name()
                        ),
                    ));
                }
                _ => {}
            }
        }
        // Every BSDF and texture with an id, wherever it is, for <ref>.
        let mut all = Vec::new();
        self.descendants(root, &mut all)?;
        for node in all {
            let tag = node.tag_name().name();
            let referable = matches!(tag, "bsdf" | "texture" | "sampler")
                || (tag == "emitter" && node.attribute("type") == Some("area"))
                || (tag == "shape" && node.attribute("type") == Some("shapegroup"));
            if let (true, Some(id)) = (referable, node.attribute("id")) {
                if self.ids.insert(id.to_string(), node).is_some() {
                    return Err(self.attr_err(
                        node,
                        "id",
                        "a second <bsdf>, <texture>, <sampler>, area <emitter> or shapegroup \
                         with this id; ids must be unique",
                    ));
                }
            }
        }
        let integrator = self.take_one(&mut top, &["integrator"])?;
        let integration = match integrator {
            Some(node) => self.integrator(self.unwrap_moment(node)?)?,
            None => Integration {
                max_depth: UNLIMITED_DEPTH,
                hide_emitters: false,
                emitter_sampling_only: false,
                bsdf_sampling_only: false,
                delta_light_gain: 1,
                rr_depth: MITSUBA_RR_DEPTH,
                hidden_emitter_rule: None,
            },
        };
        let sensors = self.take_nested(&mut top, &["sensor"]);
        let sensor = match sensors.as_slice() {
            [one] => *one,
            [] => {
                return Err(self.err(
                    root,
                    "the scene has no <sensor>; add a perspective or thinlens sensor",
                ))
            }
            [_, second, ..] => {
                return Err(self.err(*second, "a second <sensor>; lancer renders one camera"))
            }
        };
        let (camera, mut render) = self.sensor(sensor)?;
        if self.overrides.max_depth.is_none() {
            render.max_depth = integration.max_depth;
        }
        render.hide_emitters = integration.hide_emitters;
        render.emitter_sampling_only = integration.emitter_sampling_only;
        render.bsdf_sampling_only = integration.bsdf_sampling_only;
        render.delta_light_gain = integration.delta_light_gain;
        render.rr_depth = integration.rr_depth;
        let mut environment = Vec3::ZERO;
        let mut envmap = None;
        // Mitsuba allows one environment emitter (constant or envmap) per scene.
        let mut infinite: Option<Node> = None;
        let mut lights = Vec::new();
        for (child, used) in top.children.clone() {
            if used {
                continue;
            }
            match child.tag_name().name() {
                "bsdf" | "texture" => {
                    // Read where a shape refers to it, and there an error stops
                    // the load. Here each is read once more, so that an unused
                    // one is checked too; but one that no shape draws cannot
                    // change the image, so what lancer cannot read in it is a
                    // warning (Mitsuba loads it, and draws nothing of it).
                    let read = match child.tag_name().name() {
                        "bsdf" => self.bsdf(child).map(drop),
                        _ => self.texture(child).map(drop),
                    };
                    if let Err(e) = read {
                        if self.ref_count(child) > 0 {
                            return Err(e);
                        }
                        self.warnings.push(format!(
                            "{e:#} (no shape uses this <{}>, so lancer leaves it out)",
                            child.tag_name().name()
                        ));
                    }
                }
                "shape" => self.shape(child)?,
                // Read by the shape that refers to it; Mitsuba attaches an
                // area emitter to exactly one shape
                "emitter" if child.attribute("type") == Some("area") => {
                    let refs = self.ref_count(child);
                    if refs != 1 {
                        return Err(self.err(
                            child,
                            if refs == 0 {
                                "a top-level area emitter that no shape refers to; Mitsuba \
                                 attaches an area emitter to a shape: add <ref id=\"...\"/> to \
                                 one shape, or nest the emitter in it"
                            } else {
                                "an area emitter that several shapes refer to; Mitsuba attaches \
                                 an area emitter to one shape only: give each shape its own"
                            },
                        ));
                    }
                }
                "emitter" if child.attribute("type") == Some("envmap") => {
                    self.one_environment(infinite, child)?;
                    infinite = Some(child);
                    envmap = Some(self.envmap(child)?);
                }
                "emitter" if child.attribute("type") != Some("constant") => {
                    lights.push(self.delta_light(child)?);
                }
                "emitter" => {
                    self.one_environment(infinite, child)?;
                    infinite = Some(child);
                    self.plugin_type(child, &["constant"])?;
                    self.check_attrs(child, &["type", "id", "name"])?;
                    let mut p = self.props(child)?;
                    // Mitsuba's default radiance is 1
                    let radiance = self.radiance(&mut p, "radiance")?.unwrap_or(Vec3::ONE);
                    self.finish(p)?;
                    environment = radiance;
                }
                // Read where a sensor refers to it
                "sampler" => {
                    self.plugin_type(child, SAMPLER_TYPES)?;
                }
                "default" | "path" => {}
                other => {
                    return Err(self.err(
                        child,
                        format!(
                            "unsupported element <{}> in <scene>; lancer reads: {}",
                            cut(other),
                            TOP_ELEMENTS.join(", ")
                        ),
                    ))
                }
            }
        }
        if let Some(rule) = integration.hidden_emitter_rule {
            if self
                .materials
                .iter()
                .any(|m| m.emission.max_element() > 0.0)
            {
                return Err(self.err(
                    integrator.unwrap_or(root),
                    format!(
                        "hide_emitters with an area emitter in the scene is not supported \
                         here: {rule}; use <integrator type=\"path\"> (the same image where \
                         no emitter is hidden), or remove hide_emitters"
                    ),
                ));
            }
        }
        if render.emitter_sampling_only && environment != Vec3::ZERO {
            return Err(self.err(
                integrator.unwrap_or(root),
                "bsdf_samples = 0 with a constant environment is not supported: lancer finds the \
                 environment by BSDF sampling only; give bsdf_samples >= 1 (the same image, by MIS)",
            ));
        }
        Ok(Scene {
            render,
            camera,
            environment,
            envmap,
            materials: std::mem::take(&mut self.materials),
            spheres: std::mem::take(&mut self.spheres),
            triangles: std::mem::take(&mut self.triangles),
            mesh_attributes: std::mem::take(&mut self.mesh_attributes),
            lights,
            source: self.path.to_path_buf(),
            includes: (self.sources.files.iter().skip(1))
                .map(|f| f.path.clone())
                .collect(),
            files: std::mem::take(&mut self.files),
            warnings: {
                let dropped = dropped_warnings(&self.dropped);
                let mut w = std::mem::take(&mut self.warnings);
                w.extend(dropped);
                w
            },
        })
    }

    /// The sensor's sampler: a nested `<sampler>`, or a `<ref id>` of a
    /// top-level one (as Mitsuba's plugin gallery writes it); at most one.
    fn sensor_sampler(&self, p: &mut Props<'a, 'i>) -> Result<Option<Node<'a, 'i>>> {
        Ok(self
            .nested_or_referenced(p, "sampler", "the sensor")?
            .map(|f| f.1))
    }

    /// The one `<tag>` of `p`, nested or named by a `<ref id>` of a
    /// top-level one, as (where it is given, the element); `None` when there
    /// is neither, an error naming `whose` when there are two. The `<ref>`s
    /// of other elements stay for their readers.
    fn nested_or_referenced(
        &self,
        p: &mut Props<'a, 'i>,
        tag: &str,
        whose: &str,
    ) -> Result<Option<(Node<'a, 'i>, Node<'a, 'i>)>> {
        // In document order
        let mut found: Vec<_> = (self.take_nested(p, &[tag]).into_iter())
            .map(|n| (n, n))
            .collect();
        for (child, used) in p.children.iter_mut() {
            let target = (child.tag_name().name() == "ref")
                .then(|| child.attribute("id"))
                .flatten()
                .and_then(|id| self.ids.get(id));
            if let Some(&target) = target.filter(|t| t.tag_name().name() == tag) {
                self.check_attrs(*child, &["id", "name"])?;
                *used = true;
                found.push((*child, target));
            }
        }
        found.sort_by_key(|(at, _)| at.range().start);
        if let Some((second, _)) = found.get(1) {
            return Err(self.err(*second, format!("a second <{tag}> for {whose}; give one")));
        }
        Ok(found.first().copied())
    }

    /// The integrator whose image `node` renders: `node` itself, or for
    /// Mitsuba's `moment` (`src/integrators/moment.cpp`), which renders its
    /// nested integrators and adds their second moments as extra channels,
    /// its one nested integrator (the image; lancer's film keeps its own
    /// variance, `--var-out`). A `moment` of several integrators is refused.
    fn unwrap_moment(&self, node: Node<'a, 'i>) -> Result<Node<'a, 'i>> {
        if node.attribute("type") != Some("moment") {
            return Ok(node);
        }
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        let nested = self.take_nested(&mut p, &["integrator"]);
        self.finish(p)?;
        match nested.as_slice() {
            [one] => self.unwrap_moment(*one),
            [] => Err(self.err(
                node,
                "a moment integrator with no nested <integrator>; nest the one to render",
            )),
            [_, second, ..] => Err(self.err(
                *second,
                "a second integrator in moment: Mitsuba renders each into channels of its own, \
                 lancer renders one image; keep one",
            )),
        }
    }

    /// Reads the properties of `tracer` beyond `path`'s: those that steer
    /// only derivatives or media are read and ignored; one that would
    /// change the image is refused by name.
    fn tracer_options(&self, tracer: PathTracer, p: &mut Props<'a, 'i>) -> Result<()> {
        match tracer {
            PathTracer::Path | PathTracer::Prb => {}
            PathTracer::VolPath => {
                // 0 (the default) is emitter and BSDF sampling by MIS, as in
                // `path`; 1 and 2 drop one of them
                if let Some((mode, n)) = self.integer(p, "sampling_mode")? {
                    if mode != 0 {
                        return Err(self.attr_err(
                            n,
                            "value",
                            format!(
                                "sampling_mode {mode} is not read: lancer samples emitters and \
                                 BSDFs by MIS (sampling_mode 0, the default); remove it"
                            ),
                        ));
                    }
                }
            }
            PathTracer::PrbProjective | PathTracer::DirectProjective => {
                // Sample counts and guiding of the discontinuous derivatives
                for name in ["sppc", "sppp", "sppi", "guiding_rounds"] {
                    self.integer(p, name)?;
                }
                self.boolean(p, "guiding_proj")?;
                for (name, values) in [
                    ("guiding", [("none", ()), ("grid", ()), ("octree", ())]),
                    (
                        "project_seed",
                        [("both", ()), ("bsdf", ()), ("emitter", ())],
                    ),
                ] {
                    self.named(p, name, false, &values, ())?;
                }
            }
        }
        Ok(())
    }

    /// `<integrator>`: the render settings it decides (`max_depth`,
    /// `hide_emitters`, `emitter_sampling_only`, `rr_depth`), with Mitsuba
    /// 3.9.1's meaning. `path` (`src/integrators/path.cpp`) is lancer's path
    /// tracer. `direct` (`direct.cpp`) is the path tracer stopped after two
    /// segments: emitted light seen directly plus one bounce of direct
    /// light, by MIS of emitter and BSDF samples. The other path tracers
    /// give `path`'s image in expectation on scenes without media:
    /// `volpath` and `volpathmis` (`volpath.cpp`, `volpathmis.cpp`), `prb`
    /// and `prb_projective` (the differentiable variants' `prb.py`,
    /// `prb_projective.py`, whose `max_depth` defaults to 6; their other
    /// properties steer derivatives only); `direct_projective` gives
    /// `direct`'s. [`PathTracer`] says how each differs.
    fn integrator(&self, node: Node<'a, 'i>) -> Result<Integration> {
        let names: Vec<&str> = INTEGRATORS.iter().map(|i| i.0).collect();
        let kind = self.plugin_type(node, &names)?;
        let tracer = (INTEGRATORS.iter())
            .find(|i| i.0 == kind)
            .map_or(PathTracer::Path, |i| i.1);
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        let mut out = Integration {
            max_depth: tracer.default_max_depth(),
            hide_emitters: false,
            emitter_sampling_only: false,
            bsdf_sampling_only: false,
            delta_light_gain: 1,
            rr_depth: MITSUBA_RR_DEPTH + tracer.rr_offset(),
            hidden_emitter_rule: None,
        };
        if kind == "direct" {
            out.max_depth = 2;
            // Sample counts change the variance only, as long as both
            // strategies run; without BSDF samples light comes from emitter
            // sampling alone, and without emitter samples from BSDF sampling
            // alone, which finds no point light.
            let shading = self.integer(&mut p, "shading_samples")?;
            let emitter = self.integer(&mut p, "emitter_samples")?;
            let bsdf = self.integer(&mut p, "bsdf_samples")?;
            if let (Some((_, n)), true) = (shading, emitter.is_some() || bsdf.is_some()) {
                return Err(self.err(n, "give either shading_samples or emitter_samples and bsdf_samples, not both (Mitsuba refuses both too)"));
            }
            let default = shading.map_or(1, |s| s.0);
            let (e, b) = (
                emitter.map_or(default, |s| s.0),
                bsdf.map_or(default, |s| s.0),
            );
            let at = |x: Option<(i64, Node<'a, 'i>)>| x.or(shading).map_or(node, |s| s.1);
            for (count, name, n) in [
                (e, "emitter_samples", at(emitter)),
                (b, "bsdf_samples", at(bsdf)),
            ] {
                if count < 0 {
                    return Err(self.attr_err(
                        n,
                        "value",
                        format!("{name} must be >= 0, got {count}"),
                    ));
                }
            }
            if e == 0 && b == 0 {
                return Err(self.err(
                    at(emitter),
                    "emitter_samples and bsdf_samples are both 0: give at least one sample (Mitsuba refuses this too)",
                ));
            }
            out.emitter_sampling_only = b == 0;
            // Without emitter samples light comes from BSDF sampling alone,
            // with MIS weight 1: lancer's BSDF-sampling estimator, which
            // finds no delta light (as Mitsuba's finds none)
            out.bsdf_sampling_only = e == 0;
            out.delta_light_gain = u32::try_from(e.max(1)).map_err(|_| {
                self.attr_err(
                    at(emitter),
                    "value",
                    format!("emitter_samples must be at most {}, got {e}", u32::MAX),
                )
            })?;
        } else {
            out.max_depth = match self.integer(&mut p, "max_depth")? {
                None => tracer.default_max_depth(),
                Some((-1, _)) => UNLIMITED_DEPTH,
                Some((x, n)) => u32::try_from(x).ok().filter(|&x| x >= 1).ok_or_else(|| {
                    self.attr_err(
                        n,
                        "value",
                        format!(
                            "max_depth must be -1 (no limit) or from 1 to {}, got {x}",
                            u32::MAX
                        ),
                    )
                })?,
            };
            // Russian roulette starts where Mitsuba's does (the same hit, the
            // same survival rule): equal work per sample, the same noise
            // (one vertex later for the tracers that test it before counting
            // the vertex, `tracer.rr_offset()`)
            if let Some((x, n)) = self.integer(&mut p, "rr_depth")? {
                let limit = u32::MAX - tracer.rr_offset();
                out.rr_depth = u32::try_from(x)
                    .ok()
                    .filter(|&d| (1..=limit).contains(&d))
                    .ok_or_else(|| {
                        self.attr_err(
                            n,
                            "value",
                            format!("rr_depth must be from 1 to {limit}, got {x}"),
                        )
                    })?
                    + tracer.rr_offset();
            }
            self.tracer_options(tracer, &mut p)?;
            if tracer == PathTracer::DirectProjective {
                // It reads both depths, then traces two segments whatever they say
                out.max_depth = 2;
            }
        }
        out.hide_emitters = self.boolean(&mut p, "hide_emitters")?.unwrap_or(false);
        if out.hide_emitters {
            out.hidden_emitter_rule = tracer.hidden_emitter_rule();
        }
        self.finish(p)?;
        Ok(out)
    }

    /// `<emitter type="point|spot|directional|projector">`: a light with no
    /// area, as Mitsuba defines it (`src/emitters/point.cpp`, `spot.cpp`,
    /// `directional.cpp`, `projector.cpp`).
    fn delta_light(&self, node: Node<'a, 'i>) -> Result<DeltaLight> {
        let kind = self.plugin_type(
            node,
            &[
                "constant",
                "envmap",
                "point",
                "spot",
                "directional",
                "projector",
            ],
        )?;
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        // Both `position` (or `direction`) and `to_world` is an error in Mitsuba too.
        let exclusive = |p: &mut Props<'a, 'i>, name: &str| -> Result<Option<Node<'a, 'i>>> {
            let given = p
                .children
                .iter()
                .find(|(c, _)| c.attribute("name") == Some(name))
                .map(|c| c.0);
            let world = p
                .children
                .iter()
                .any(|(c, _)| c.attribute("name") == Some("to_world"));
            match given {
                Some(n) if world => Err(self.err(
                    n,
                    format!(
                        "give either `{name}` or `to_world`, not both (Mitsuba refuses both too)"
                    ),
                )),
                _ => Ok(given),
            }
        };
        let radiant = |p: &mut Props<'a, 'i>, name: &str| -> Result<Rgb> {
            Ok(self.radiance(p, name)?.unwrap_or(Vec3::ONE))
        };
        let light = match kind.as_str() {
            "point" => {
                let position = match exclusive(&mut p, "position")? {
                    Some(_) => self.point(&mut p, "position")?.unwrap_or_default(),
                    None => self
                        .transform(&mut p, "to_world")?
                        .map_or(DVec3::ZERO, |m| m.translation),
                };
                DeltaLight::Point {
                    position: position.as_vec3(),
                    intensity: radiant(&mut p, "intensity")?,
                }
            }
            "spot" => {
                let m = self
                    .transform(&mut p, "to_world")?
                    .unwrap_or(DAffine3::IDENTITY);
                if m.matrix3.determinant() == 0.0 {
                    return Err(self.err(node, "the spot light's to_world is singular"));
                }
                // The projected image; Mitsuba refuses a constant one
                let texture = self.emitted_texture(&mut p, "texture")?;
                if let Some(ColorSource::Constant(_)) = texture {
                    return Err(self.err(
                        node,
                        "a spot light's `texture` must be an image (a <texture>), as Mitsuba \
                         requires; scale its `intensity` instead",
                    ));
                }
                let cutoff = self
                    .float(&mut p, "cutoff_angle")?
                    .unwrap_or(crate::scene::parse::lights::DEFAULT_CUTOFF_DEG);
                let beam = self
                    .float(&mut p, "beam_width")?
                    .unwrap_or(cutoff * crate::scene::parse::lights::DEFAULT_BEAM_FRACTION);
                DeltaLight::Spot {
                    position: m.translation.as_vec3(),
                    to_local: m.matrix3.inverse().as_mat3(),
                    intensity: radiant(&mut p, "intensity")?,
                    cutoff_deg: cutoff as f32,
                    beam_width_deg: beam as f32,
                    texture,
                }
            }
            "projector" => {
                let m = self
                    .transform(&mut p, "to_world")?
                    .unwrap_or(DAffine3::IDENTITY);
                if m.matrix3.determinant() == 0.0 {
                    return Err(self.err(node, "the projector's to_world is singular"));
                }
                let irradiance = self
                    .emitted_texture(&mut p, "irradiance")?
                    .unwrap_or(ColorSource::Constant(Vec3::ONE));
                // The image's size sets the aspect ratio, as its resolution
                // does in Mitsuba (1 x 1 for a colour or a pattern)
                let (width, height) = match irradiance.file() {
                    Some(path) => image::ImageReader::open(path)
                        .and_then(|r| r.with_guessed_format())
                        .map_err(anyhow::Error::from)
                        .and_then(|r| r.into_dimensions().map_err(anyhow::Error::from))
                        .map_err(|e| {
                            self.err(
                                node,
                                format!(
                                    "cannot read the size of the projector's image {}: {e}",
                                    crate::util::text::cut_path(path)
                                ),
                            )
                        })?,
                    None => (1, 1),
                };
                let fov_y = self.field_of_view(node, &mut p, width, height)?;
                let cot_y = 1.0 / (fov_y.to_radians() * 0.5).tan();
                let scale = self.float(&mut p, "scale")?.unwrap_or(1.0);
                DeltaLight::Projector {
                    position: m.translation.as_vec3(),
                    to_local: m.matrix3.inverse().as_mat3(),
                    irradiance,
                    scale: scale as f32,
                    cot_x: (cot_y * f64::from(height) / f64::from(width)) as f32,
                    cot_y: cot_y as f32,
                }
            }
            _ => {
                let direction = match exclusive(&mut p, "direction")? {
                    Some(_) => self.point(&mut p, "direction")?.unwrap_or_default(),
                    None => self
                        .transform(&mut p, "to_world")?
                        .map_or(DVec3::Z, |m| m.matrix3.z_axis),
                };
                let unit = direction.normalize_or_zero();
                if unit == DVec3::ZERO {
                    return Err(self.err(node, "the light's direction is zero; give a non-zero `direction` or a to_world that does not flatten z"));
                }
                DeltaLight::Directional {
                    direction: unit.as_vec3(),
                    irradiance: radiant(&mut p, "irradiance")?,
                }
            }
        };
        self.finish(p)?;
        crate::scene::limits::check_light(&light)
            .map_err(|(key, reason)| self.err(node, format!("{key}: {reason}")))?;
        Ok(light)
    }

    /// An emitter's colour or image `name` (a spot's `texture`, a
    /// projector's `irradiance`): an `<rgb>`, `<float>` or `<spectrum>`
    /// read as a radiance ([`Self::radiance`]), a `<texture>`, or a `<ref>`
    /// to a top-level one; `None` when absent.
    fn emitted_texture(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<Option<ColorSource>> {
        const TAGS: &[&str] = &["rgb", "float", "spectrum", "texture"];
        let (source, node) = match self.take(p, TAGS, name)? {
            Some(t) if t.tag_name().name() == "texture" => (Some(self.texture(t)?), Some(t)),
            Some(c) => (Some(ColorSource::Constant(self.radiance_of(c)?)), Some(c)),
            None => match self.take_ref(p, name)? {
                Some(r) => (Some(self.texture(self.referenced(r, "texture")?)?), Some(r)),
                None => (None, None),
            },
        };
        if let (Some(ColorSource::Attribute(_)), Some(n)) = (&source, node) {
            return Err(self.err(
                n,
                format!(
                    "a light's `{name}` of a mesh_attribute is outside the subset lancer reads \
                     (a light has no mesh); give a bitmap"
                ),
            ));
        }
        Ok(source)
    }

    /// Fails on a second environment emitter: Mitsuba allows one constant
    /// or envmap emitter per scene.
    fn one_environment(&self, first: Option<Node>, child: Node) -> Result<()> {
        match first {
            Some(first) => Err(self.err(
                child,
                format!(
                    "a second environment emitter (the first is on {}); Mitsuba allows \
                     one constant or envmap emitter per scene, and so does lancer: remove one",
                    self.place(first, child)
                ),
            )),
            None => Ok(()),
        }
    }

    /// `<emitter type="envmap">`: an environment map, as Mitsuba 3 defines
    /// it (`src/emitters/envmap.cpp`): `filename` (required), `scale`
    /// (>= 0, default 1), `to_world` (a rotation, or a mirroring orthogonal
    /// map; a translation is ignored, as it is for any direction), and
    /// `mis_compensation`, which changes Mitsuba's sampling, not the image.
    fn envmap(&self, node: Node<'a, 'i>) -> Result<EnvMap> {
        self.plugin_type(node, &["envmap"])?;
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        let (file, file_node) = self.string(&mut p, "filename")?.ok_or_else(|| {
            self.err(
                node,
                "missing property <string name=\"filename\"> (the latitude-longitude image)",
            )
        })?;
        let scale = self.float(&mut p, "scale")?.unwrap_or(1.0);
        if !(scale >= 0.0 && (scale as f32).is_finite()) {
            return Err(self.err(
                node,
                format!("property `scale` must be >= 0 and finite, got {scale}"),
            ));
        }
        let to_world = self
            .transform(&mut p, "to_world")?
            .unwrap_or(DAffine3::IDENTITY);
        let m = to_world.matrix3;
        let gram = m.transpose() * m;
        let off = (gram - DMat3::IDENTITY).to_cols_array();
        if off.iter().any(|x| x.abs() > RIGID_TOLERANCE) {
            return Err(self.err(
                node,
                "property `to_world` of <emitter type=\"envmap\"> scales or shears directions; \
                 Mitsuba reads the map with the transformed direction as if it had unit length, \
                 which lancer does not reproduce: keep to rotations (remove <scale> and \
                 non-orthogonal <matrix> steps)",
            ));
        }
        // Read and ignored: it changes how Mitsuba samples, not the image.
        self.boolean(&mut p, "mis_compensation")?;
        self.finish(p)?;
        let path = self.resolve(&file);
        let here = |reason: String| self.attr_err(file_node, "value", reason);
        obj::check_readable(&path).map_err(|e| {
            here(format!(
                "cannot read the environment map {}: {e}",
                crate::util::text::cut_path(&path)
            ))
        })?;
        let (w, h) = image::ImageReader::open(&path)
            .and_then(|r| r.with_guessed_format())
            .map_err(image::ImageError::IoError)
            .and_then(|r| r.into_dimensions())
            .map_err(|e| {
                here(format!(
                    "cannot read the environment map {}: {e}",
                    crate::util::text::cut_path(&path)
                ))
            })?;
        if w < 2 || h < 3 {
            return Err(here(format!(
                "the environment map {} is {w} x {h} pixels; it must be at least 2 x 3 \
                 (Mitsuba refuses smaller ones too)",
                crate::util::text::cut_path(&path)
            )));
        }
        Ok(EnvMap {
            file: path,
            scale: scale as f32,
            to_local: m.inverse().as_mat3(),
        })
    }

    /// `<sensor>` with its film and sampler: the camera and the render
    /// settings (but `max_depth`, unless overridden), with the overrides
    /// applied and checked before the field of view is derived from them.
    fn sensor(&self, node: Node<'a, 'i>) -> Result<(Camera, RenderSettings)> {
        let kind = self.plugin_type(node, &["perspective", "thinlens", "orthographic"])?;
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        let film = match self.take_one(&mut p, &["film"])? {
            Some(film) => self.film(film)?,
            None => Film {
                width: DEFAULT_FILM.0,
                height: DEFAULT_FILM.1,
                filter: PixelFilter::MITSUBA_DEFAULT,
                sample_border: false,
                crop: None,
            },
        };
        let Film {
            width,
            height,
            filter,
            sample_border,
            crop,
        } = film;
        if let (Some(_), true) = (
            crop,
            self.overrides.width.is_some() || self.overrides.height.is_some(),
        ) {
            return Err(self.err(
                node,
                "the film has a crop window, and the image size is given too (--width/--height); \
                 lancer does not guess which of the two the new size is for: give the size in \
                 the film's width/height and crop_* instead",
            ));
        }
        let (spp, seed) = match self.sensor_sampler(&mut p)? {
            Some(sampler) => {
                self.plugin_type(sampler, SAMPLER_TYPES)?;
                self.check_attrs(sampler, &["type", "id", "name"])?;
                let mut s = self.props(sampler)?;
                let spp = self
                    .count(&mut s, "sample_count", 1)?
                    .unwrap_or(DEFAULT_SAMPLE_COUNT);
                let seed = self.count(&mut s, "seed", 0)?.unwrap_or(0);
                self.finish(s)?;
                (spp, seed)
            }
            None => (DEFAULT_SAMPLE_COUNT, 0),
        };
        let mut render = RenderSettings {
            width,
            height,
            spp,
            max_depth: UNLIMITED_DEPTH,
            seed,
            filter,
            // Mitsuba's sample_border false matters only for a filter
            // reaching past its pixel.
            filter_inside_film: !sample_border && filter.radius() > 0.5,
            hide_emitters: false,
            emitter_sampling_only: false,
            bsdf_sampling_only: false,
            delta_light_gain: 1,
            rr_depth: MITSUBA_RR_DEPTH,
        };
        self.overrides.apply(&mut render);
        render.check().map_err(|(key, reason)| {
            if self.overrides.sets(key) {
                crate::scene::overridden(self.path, key, reason)
            } else {
                self.err(node, format!("film size: {reason}"))
            }
        })?;
        let (width, height) = (render.width, render.height);

        // The field of view is the whole film's; the image is the crop window
        // (an orthographic sensor has none: its to_world's scale sets the extent)
        let mut vfov = if kind == "orthographic" {
            90.0
        } else {
            self.field_of_view(node, &mut p, width, height)?
        };
        let m = self
            .transform(&mut p, "to_world")?
            .unwrap_or(DAffine3::IDENTITY);
        let near = self
            .float(&mut p, "near_clip")?
            .unwrap_or(DEFAULT_NEAR_CLIP);
        let far = self.float(&mut p, "far_clip")?.unwrap_or(DEFAULT_FAR_CLIP);
        if !(near > 0.0 && near < far && (far as f32).is_finite()) {
            return Err(self.err(
                node,
                format!(
                    "near_clip must be > 0 and below far_clip (a finite number), got {near} \
                     and {far}"
                ),
            ));
        }
        let focus = self.float(&mut p, "focus_distance")?;
        let (aperture, focus) = if kind == "thinlens" {
            let a = self.float(&mut p, "aperture_radius")?.ok_or_else(|| {
                self.err(node, "missing property <float name=\"aperture_radius\">")
            })?;
            // Mitsuba focuses on the far plane unless told otherwise
            let f = focus.unwrap_or(far);
            if a < 0.0 || f <= 0.0 {
                return Err(self.err(
                    node,
                    format!("aperture_radius must be >= 0 and focus_distance > 0, got {a} and {f}"),
                ));
            }
            (a, Some(f))
        } else {
            // Mitsuba's perspective sensor reads focus_distance and ignores it
            (0.0, None)
        };
        // Read past what does not change the image: the shutter (no motion)
        let open = self.float(&mut p, "shutter_open")?.unwrap_or(0.0);
        let close = self.float(&mut p, "shutter_close")?.unwrap_or(0.0);
        if close < open {
            return Err(self.err(
                node,
                format!("shutter_close must be >= shutter_open, got {close} and {open}"),
            ));
        }
        // Mitsuba's perspective sensor moves its principal point by this
        // fraction of the film (thinlens has no such property)
        let mut principal = [0.0; 2];
        if kind == "perspective" {
            for (key, slot) in ["principal_point_offset_x", "principal_point_offset_y"]
                .into_iter()
                .zip(principal.iter_mut())
            {
                *slot = self.float(&mut p, key)?.unwrap_or(0.0);
            }
        }
        self.finish(p)?;
        // A crop window [ox, ox + cw] x [oy, oy + ch] of the W x H film, with
        // the principal point offset (px, py): Mitsuba's sample position in
        // the film is (ox + cw s + px W) / W, s in [0, 1] across the crop
        // (`perspective_projection`, `sample_ray`). The image's vertical
        // half-angle tangent is the film's times ch / H, and its centre sits
        // off the axis by `shift`, in half-widths of the image (x right, y up).
        let (fw, fh) = (f64::from(width), f64::from(height));
        let [ox, oy, cw, ch] = crop.map_or([0.0, 0.0, fw, fh], |c| c.map(f64::from));
        let shift = [
            (cw + 2.0 * ox - fw + 2.0 * principal[0] * fw) / cw,
            (fh - ch - 2.0 * oy - 2.0 * principal[1] * fh) / ch,
        ];
        if !shift.iter().all(|s| s.is_finite() && s.abs() <= 1e6) {
            return Err(self.err(
                node,
                format!(
                    "principal_point_offset ({:e}, {:e}) must move the image by less than a \
                     million image widths",
                    principal[0], principal[1]
                ),
            ));
        }
        if crop.is_some() {
            if kind != "orthographic" {
                let tan_half = (vfov.to_radians() * 0.5).tan() * ch / fh;
                vfov = 2.0 * tan_half.atan().to_degrees();
            }
            render.width = cw as u32;
            render.height = ch as u32;
        }
        if kind == "orthographic" {
            let camera = self.orthographic(node, &m, [fw, fh, cw, ch], [near, far], shift)?;
            return Ok((camera, render));
        }

        let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let rigid = cols
            .iter()
            .all(|c| (c.length() - 1.0).abs() < RIGID_TOLERANCE)
            && cols[0].dot(cols[1]).abs() < RIGID_TOLERANCE
            && cols[1].dot(cols[2]).abs() < RIGID_TOLERANCE
            && cols[0].dot(cols[2]).abs() < RIGID_TOLERANCE
            && m.matrix3.determinant() > 0.0;
        if !rigid {
            return Err(self.err(node, "the sensor's to_world must be a rotation and a translation (no scale or mirror); use <lookat>"));
        }
        let eye = m.translation;
        let forward = m.matrix3.z_axis;
        let camera = Camera {
            eye: eye.as_vec3(),
            look_at: (eye + forward).as_vec3(),
            up: m.matrix3.y_axis.as_vec3(),
            vfov_deg: vfov as f32,
            aperture_radius: aperture as f32,
            focus_distance: focus.unwrap_or(1.0) as f32,
            near_clip: near as f32,
            far_clip: far as f32,
            shift: shift.map(|s| s as f32),
            orthographic: None,
        };
        camera
            .basis()
            .map_err(|(key, reason)| self.err(node, format!("camera {key}: {reason}")))?;
        Ok((camera, render))
    }

    /// Mitsuba 3.9's orthographic sensor (`src/sensors/orthographic.cpp`,
    /// `orthographic_projection` in `sensor.h`): in camera space the film
    /// spans x in [-1, 1] (+x at the image's left edge, as Mitsuba's
    /// cameras look) and y in [-H/W, H/W] (+y at the top) on the plane z =
    /// `near_clip`; `to_world` (any invertible affine map: its scale sets
    /// the extent) takes that point to the ray's origin and (0, 0, 1),
    /// normalised, to its direction; the ray runs `far_clip - near_clip`.
    /// `film` is the film's width and height and the crop window's (the
    /// image's); `shift` is the window's centre off the film's, in
    /// half-sizes of the window.
    fn orthographic(
        &self,
        node: Node<'a, 'i>,
        m: &DAffine3,
        film: [f64; 4],
        [near, far]: [f64; 2],
        shift: [f64; 2],
    ) -> Result<Camera> {
        let [fw, _, cw, ch] = film;
        if m.matrix3.determinant() == 0.0 {
            return Err(self.err(
                node,
                "the orthographic sensor's to_world is singular (a scale of 0?): give it a scale \
                 that is not 0 on any axis",
            ));
        }
        let origin = m.transform_point3(DVec3::new(0.0, 0.0, near));
        // The image's right is camera -x, its up camera +y; the window
        // spans cw / W of the film's width 2 and ch / W of its height 2 H / W
        let right = -m.transform_vector3(DVec3::X) * (cw / fw);
        let up = m.transform_vector3(DVec3::Y) * (ch / fw);
        let dir = m.transform_vector3(DVec3::Z).normalize_or_zero();
        let o = Orthographic {
            origin: origin.as_vec3(),
            right: right.as_vec3(),
            up: up.as_vec3(),
            dir: dir.as_vec3(),
        };
        let finite = [o.origin, o.right, o.up, o.dir]
            .iter()
            .all(|v| v.is_finite())
            && o.dir != Vec3::ZERO
            && o.right.length() > 0.0
            && o.up.length() > 0.0;
        if !finite {
            return Err(self.err(
                node,
                "the orthographic sensor's to_world makes its image degenerate or not finite in \
                 32-bit floats; give it a moderate scale",
            ));
        }
        let camera = Camera {
            eye: o.origin,
            look_at: o.origin + o.dir,
            up: o.up,
            vfov_deg: 90.0,
            aperture_radius: 0.0,
            focus_distance: 1.0,
            near_clip: near as f32,
            far_clip: far as f32,
            shift: shift.map(|s| s as f32),
            orthographic: Some(o),
        };
        camera.basis().map_err(|(key, reason)| {
            self.err(
                node,
                format!("the orthographic sensor's to_world: camera {key}: {reason}"),
            )
        })?;
        Ok(camera)
    }

    /// The vertical field of view, in degrees, of a sensor's `fov` and
    /// `fov_axis`, or of its `focal_length` (Mitsuba's `parse_fov`: a
    /// focal length on 35 mm film, 36 x 24 mm, measured on the diagonal;
    /// "50mm" when neither is given).
    fn field_of_view(
        &self,
        node: Node<'a, 'i>,
        p: &mut Props<'a, 'i>,
        width: u32,
        height: u32,
    ) -> Result<f64> {
        let fov = self.float(p, "fov")?;
        let focal = match self.take(p, &["string", "float", "integer"], "focal_length")? {
            Some(n) => Some((self.value(n)?, n)),
            None => None,
        };
        let axis = self.string(p, "fov_axis")?;
        let (fov, axis) = match (fov, focal) {
            (Some(_), Some((_, n))) => {
                return Err(self.err(
                    n,
                    "give either a focal length (focal_length) or a field of view (fov), not both",
                ))
            }
            (Some(fov), None) => {
                let axis = match &axis {
                    Some((a, n)) => {
                        let a = a.to_ascii_lowercase();
                        if !["x", "y", "diagonal", "smaller", "larger"].contains(&a.as_str()) {
                            return Err(self.attr_err(
                                *n,
                                "value",
                                format!(
                                    "fov_axis must be x, y, diagonal, smaller or larger, got \"{}\"",
                                    cut(&a)
                                ),
                            ));
                        }
                        a
                    }
                    None => String::from("x"),
                };
                (fov, axis)
            }
            (None, focal) => {
                let text = focal.as_ref().map_or("50mm", |(t, _)| t.as_str());
                let mm = text.trim().strip_suffix("mm").unwrap_or(text.trim());
                let value: f64 = match mm.trim().parse::<f64>() {
                    Ok(v) if v > 0.0 && v.is_finite() => v,
                    _ => {
                        return Err(self.err(
                            focal.as_ref().map_or(node, |(_, n)| *n),
                            format!(
                                "focal_length must be a positive number of millimetres such \
                                 as \"50mm\", got \"{}\"",
                                cut(text)
                            ),
                        ))
                    }
                };
                let diagonal = (36.0f64 * 36.0 + 24.0 * 24.0).sqrt();
                let fov = 2.0 * (diagonal / (2.0 * value)).atan().to_degrees();
                // Mitsuba measures a focal length's field of view on the diagonal
                (fov, String::from("diagonal"))
            }
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.err(
                node,
                format!("fov must be > 0 and < 180 degrees, got {fov}"),
            ));
        }
        let (w, h) = (width as f64, height as f64);
        let scale = match axis.as_str() {
            "x" => h / w,
            "y" => 1.0,
            "diagonal" => h / w.hypot(h),
            "smaller" => {
                if w < h {
                    h / w
                } else {
                    1.0
                }
            }
            // "larger"
            _ => {
                if w > h {
                    h / w
                } else {
                    1.0
                }
            }
        };
        Ok(2.0 * ((fov.to_radians() * 0.5).tan() * scale).atan().to_degrees())
    }

    /// `<film type="hdrfilm">`: width, height, the pixel filter (Mitsuba's
    /// Gaussian when the film has no `<rfilter>`), `sample_border` and the
    /// crop window.
    fn film(&self, node: Node<'a, 'i>) -> Result<Film> {
        self.plugin_type(node, &["hdrfilm"])?;
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        let width = self.count(&mut p, "width", 1)?.unwrap_or(DEFAULT_FILM.0);
        let height = self.count(&mut p, "height", 1)?.unwrap_or(DEFAULT_FILM.1);
        let filter = match self.take_one(&mut p, &["rfilter"])? {
            Some(f) => self.rfilter(f)?,
            None => PixelFilter::MITSUBA_DEFAULT,
        };
        // What only changes the file Mitsuba would write, not the image
        for (key, allowed) in [
            ("file_format", &["openexr", "exr", "rgbe", "pfm"][..]),
            ("pixel_format", &["rgb", "rgba"][..]),
            ("component_format", &["float16", "float32", "uint32"][..]),
        ] {
            if let Some((v, n)) = self.string(&mut p, key)? {
                if !allowed.contains(&v.to_ascii_lowercase().as_str()) {
                    return Err(self.attr_err(
                        n,
                        "value",
                        format!(
                            "{key} must be {}, got \"{}\"",
                            allowed.join(" or "),
                            cut(&v)
                        ),
                    ));
                }
            }
        }
        // Mitsuba 3 reads `banner` and `compensate` and ignores them
        self.boolean(&mut p, "banner")?;
        self.boolean(&mut p, "compensate")?;
        // false (Mitsuba's default): film positions stay inside the image
        let sample_border = self.boolean(&mut p, "sample_border")?.unwrap_or(false);
        // The crop window, as Mitsuba's Film::set_crop_window checks it
        let offset_x = self.count(&mut p, "crop_offset_x", 0)?.unwrap_or(0);
        let offset_y = self.count(&mut p, "crop_offset_y", 0)?.unwrap_or(0);
        let crop_width = self.count(&mut p, "crop_width", 1)?.unwrap_or(width);
        let crop_height = self.count(&mut p, "crop_height", 1)?.unwrap_or(height);
        if u64::from(offset_x) + u64::from(crop_width) > u64::from(width)
            || u64::from(offset_y) + u64::from(crop_height) > u64::from(height)
        {
            return Err(self.err(
                node,
                format!(
                    "the crop window ({crop_width} x {crop_height} at {offset_x}, {offset_y}) \
                     reaches past the film ({width} x {height}); Mitsuba refuses it too"
                ),
            ));
        }
        let crop = [offset_x, offset_y, crop_width, crop_height];
        let crop = (crop != [0, 0, width, height]).then_some(crop);
        self.finish(p)?;
        Ok(Film {
            width,
            height,
            filter,
            sample_border,
            crop,
        })
    }

    /// `<rfilter>`: Mitsuba's reconstruction filters with their properties.
    fn rfilter(&self, node: Node<'a, 'i>) -> Result<PixelFilter> {
        let kind = self.plugin_type(
            node,
            &[
                "box",
                "tent",
                "gaussian",
                "mitchell",
                "catmullrom",
                "lanczos",
            ],
        )?;
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        let float = |p: &mut Props<'a, 'i>, key: &str, default: f32| -> Result<f32> {
            Ok(self.float(p, key)?.map_or(default, |x| x as f32))
        };
        let filter = match kind.as_str() {
            "box" => PixelFilter::Box,
            "tent" => PixelFilter::Tent {
                radius: float(&mut p, "radius", 1.0)?,
            },
            "gaussian" => PixelFilter::Gaussian {
                stddev: float(&mut p, "stddev", 0.5)?,
            },
            "mitchell" => PixelFilter::Mitchell {
                b: float(&mut p, "B", 1.0 / 3.0)?,
                c: float(&mut p, "C", 1.0 / 3.0)?,
            },
            "catmullrom" => PixelFilter::CATMULL_ROM,
            _ => PixelFilter::Lanczos {
                lobes: match self.integer(&mut p, "lobes")? {
                    Some((x, n)) => u32::try_from(x).map_err(|_| {
                        self.attr_err(n, "value", format!("lobes must be from 1 to 16, got {x}"))
                    })?,
                    None => 3,
                },
            },
        };
        self.finish(p)?;
        filter.validate().map_err(|reason| self.err(node, reason))?;
        Ok(filter)
    }

    // --------------------------------------------------------------- BSDFs

    /// The BSDF a `<bsdf>` or `<ref>` element means: its element (for
    /// identity and naming), its kind, the sides Mitsuba shades (the front
    /// of the shading normal for a plain diffuse or conductor, both, the
    /// side given by the shading normal, inside `twosided`) and a `mask`'s
    /// opacity.
    fn bsdf(&self, node: Node<'a, 'i>) -> Result<Bsdf<'a, 'i>> {
        if node.tag_name().name() == "ref" {
            self.check_attrs(node, &["id", "name"])?;
            if let Some(name) = node.attribute("name") {
                if name != "bsdf" {
                    return Err(self.attr_err(
                        node,
                        "name",
                        "a shape's <ref> must name a bsdf (name=\"bsdf\" or no name)",
                    ));
                }
            }
            let target = self.referenced(node, "bsdf")?;
            return self.bsdf(target);
        }
        let kind = self.plugin_type(node, BSDF_TYPES)?;
        self.check_attrs(node, &["type", "id", "name"])?;
        let mut p = self.props(node)?;
        match kind.as_str() {
            "mask" => return self.mask(node, p),
            "normalmap" => return self.normal_map(node, p),
            "bumpmap" => return self.bump_map(node, p),
            "blendbsdf" => return self.blend(node, p),
            _ => {}
        }
        let out = match kind.as_str() {
            "diffuse" => {
                let albedo = self.reflectance(&mut p, "reflectance")?;
                (node, MaterialKind::Lambert { albedo }, Sides::Front)
            }
            "conductor" => {
                let ior = self.complex_ior(&mut p)?;
                let reflectance = self
                    .color(&mut p, "specular_reflectance")?
                    .unwrap_or(Vec3::ONE);
                // The perfect reflector stays lancer's mirror
                let kind = match ior {
                    None => MaterialKind::Mirror { reflectance },
                    Some(ior) => MaterialKind::Conductor {
                        ior,
                        specular_reflectance: reflectance,
                    },
                };
                (node, kind, Sides::Front)
            }
            "roughconductor" => {
                let ior = self.complex_ior(&mut p)?.unwrap_or(ComplexIor::PERFECT);
                let specular_reflectance = self
                    .color(&mut p, "specular_reflectance")?
                    .unwrap_or(Vec3::ONE);
                let distribution = self.distribution(&mut p)?;
                let (alpha_u, alpha_v, alpha_textures) = self.roughness(&mut p, node)?;
                // Visible-normal sampling or not changes the noise, not the image
                self.boolean(&mut p, "sample_visible")?;
                let kind = MaterialKind::RoughConductor {
                    distribution,
                    alpha_u,
                    alpha_v,
                    alpha_textures,
                    ior,
                    specular_reflectance,
                };
                (node, kind, Sides::Front)
            }
            "dielectric" => {
                let int_ior = self.ior(&mut p, "int_ior", DEFAULT_INT_IOR)?;
                let ext_ior = self.ior(&mut p, "ext_ior", DEFAULT_EXT_IOR)?;
                if !(int_ior > 0.0 && ext_ior > 0.0) {
                    return Err(self.err(
                        node,
                        format!("int_ior and ext_ior must be > 0, got {int_ior} and {ext_ior}"),
                    ));
                }
                if let Some(r) = self.color(&mut p, "specular_reflectance")? {
                    if r != Vec3::ONE {
                        return Err(self.err(node, "specular_reflectance other than 1 is not supported: lancer's dielectric reflects by exact Fresnel only"));
                    }
                }
                let tint = self
                    .color(&mut p, "specular_transmittance")?
                    .unwrap_or(Vec3::ONE);
                let ior = (int_ior / ext_ior) as f32;
                (node, MaterialKind::Dielectric { ior, tint }, Sides::Both)
            }
            "thindielectric" => {
                let int_ior = self.ior(&mut p, "int_ior", DEFAULT_INT_IOR)?;
                let ext_ior = self.ior(&mut p, "ext_ior", DEFAULT_EXT_IOR)?;
                if !(int_ior > 0.0 && ext_ior > 0.0) {
                    return Err(self.err(
                        node,
                        format!("int_ior and ext_ior must be > 0, got {int_ior} and {ext_ior}"),
                    ));
                }
                let specular_reflectance = self
                    .color(&mut p, "specular_reflectance")?
                    .unwrap_or(Vec3::ONE);
                let specular_transmittance = self
                    .color(&mut p, "specular_transmittance")?
                    .unwrap_or(Vec3::ONE);
                let kind = MaterialKind::ThinDielectric {
                    ior: (int_ior / ext_ior) as f32,
                    specular_reflectance,
                    specular_transmittance,
                };
                (node, kind, Sides::Both)
            }
            "roughdielectric" => {
                let int_ior = self.ior(&mut p, "int_ior", DEFAULT_INT_IOR)?;
                let ext_ior = self.ior(&mut p, "ext_ior", DEFAULT_EXT_IOR)?;
                if !(int_ior > 0.0 && ext_ior > 0.0) || int_ior == ext_ior {
                    return Err(self.err(
                        node,
                        format!(
                            "int_ior and ext_ior must be > 0 and differ (Mitsuba refuses it too), \
                             got {int_ior} and {ext_ior}"
                        ),
                    ));
                }
                let distribution = self.distribution(&mut p)?;
                let (alpha_u, alpha_v, alpha_textures) = self.roughness(&mut p, node)?;
                // Visible-normal sampling or not changes the noise, not the image
                self.boolean(&mut p, "sample_visible")?;
                let specular_reflectance = self
                    .color(&mut p, "specular_reflectance")?
                    .unwrap_or(Vec3::ONE);
                let specular_transmittance = self
                    .color(&mut p, "specular_transmittance")?
                    .unwrap_or(Vec3::ONE);
                let kind = MaterialKind::RoughDielectric {
                    distribution,
                    alpha_u,
                    alpha_v,
                    alpha_textures,
                    ior: (int_ior / ext_ior) as f32,
                    specular_reflectance,
                    specular_transmittance,
                };
                (node, kind, Sides::Both)
            }
            "plastic" => {
                let int_ior = self.ior(&mut p, "int_ior", DEFAULT_PLASTIC_IOR)?;
                let ext_ior = self.ior(&mut p, "ext_ior", DEFAULT_EXT_IOR)?;
                if !(int_ior > 0.0 && ext_ior > 0.0) {
                    return Err(self.err(
                        node,
                        format!("int_ior and ext_ior must be > 0, got {int_ior} and {ext_ior}"),
                    ));
                }
                let diffuse_reflectance = self.reflectance(&mut p, "diffuse_reflectance")?;
                let specular_reflectance = self
                    .color(&mut p, "specular_reflectance")?
                    .unwrap_or(Vec3::ONE);
                let nonlinear = self.boolean(&mut p, "nonlinear")?.unwrap_or(false);
                let kind = MaterialKind::Plastic {
                    diffuse_reflectance,
                    specular_reflectance,
                    ior: (int_ior / ext_ior) as f32,
                    nonlinear,
                };
                (node, kind, Sides::Front)
            }
            "principled" => (node, self.principled(node, &mut p)?, Sides::Front),
            "roughplastic" => {
                let int_ior = self.ior(&mut p, "int_ior", DEFAULT_PLASTIC_IOR)?;
                let ext_ior = self.ior(&mut p, "ext_ior", DEFAULT_EXT_IOR)?;
                if !(int_ior > 0.0 && ext_ior > 0.0) || int_ior == ext_ior {
                    return Err(self.err(
                        node,
                        format!(
                            "int_ior and ext_ior must be > 0 and differ (Mitsuba refuses it too), \
                             got {int_ior} and {ext_ior}"
                        ),
                    ));
                }
                let diffuse_reflectance = self.reflectance(&mut p, "diffuse_reflectance")?;
                let specular_reflectance = self
                    .color(&mut p, "specular_reflectance")?
                    .unwrap_or(Vec3::ONE);
                let nonlinear = self.boolean(&mut p, "nonlinear")?.unwrap_or(false);
                let distribution = self.distribution(&mut p)?;
                let (alpha_u, alpha_v, textures) = self.roughness(&mut p, node)?;
                if textures.is_some() {
                    return Err(self.err(
                        node,
                        "a roughplastic's roughness is a plain number (Mitsuba reads no texture \
                         there either); give a <float name=\"alpha\">",
                    ));
                }
                if alpha_u != alpha_v {
                    return Err(self.err(
                        node,
                        "a roughplastic's roughness is isotropic (Mitsuba refuses alpha_u != alpha_v too); give one `alpha`",
                    ));
                }
                // Visible-normal sampling or not changes the noise, not the image
                self.boolean(&mut p, "sample_visible")?;
                let kind = MaterialKind::RoughPlastic {
                    distribution,
                    alpha: alpha_u,
                    diffuse_reflectance,
                    specular_reflectance,
                    ior: (int_ior / ext_ior) as f32,
                    nonlinear,
                };
                (node, kind, Sides::Front)
            }
            _ => {
                let inner = self.take_one(&mut p, &["bsdf", "ref"])?.ok_or_else(|| {
                    self.err(node, "a twosided BSDF needs one nested <bsdf> or <ref>")
                })?;
                let inner = self.bsdf(inner)?;
                if inner.kind.transmits() {
                    return Err(self.err(inner.node, "a dielectric cannot be two-sided (Mitsuba refuses it too); remove the twosided wrapper"));
                }
                // A mask keeps its opacity on both sides
                self.finish(p)?;
                return Ok(Bsdf {
                    node,
                    sides: Sides::Shading,
                    ..inner
                });
            }
        };
        self.finish(p)?;
        Ok(Bsdf {
            node: out.0,
            kind: out.1,
            sides: out.2,
            opacity: None,
            normal_map: None,
        })
    }

    /// Mitsuba's `mask`: its nested BSDF, met with the probability
    /// `opacity` (a float, colour or texture, read as one channel;
    /// Mitsuba's default 0.5), and passed straight through otherwise.
    fn mask(&self, node: Node<'a, 'i>, mut p: Props<'a, 'i>) -> Result<Bsdf<'a, 'i>> {
        let opacity = self.reflectance(&mut p, "opacity")?;
        let inner = self
            .take_one(&mut p, &["bsdf", "ref"])?
            .ok_or_else(|| self.err(node, "a mask needs one nested <bsdf> or <ref>"))?;
        let inner = self.bsdf(inner)?;
        if inner.opacity.is_some() {
            return Err(self.err(
                inner.node,
                "a mask inside a mask is outside the subset lancer reads: give the outer mask \
                 the product of both opacities",
            ));
        }
        self.finish(p)?;
        Ok(Bsdf {
            node,
            opacity: Some(opacity),
            ..inner
        })
    }

    /// Mitsuba's `blendbsdf` (`src/bsdfs/blendbsdf.cpp`): two nested BSDFs,
    /// `(1 - weight)` times the first plus `weight` times the second, where
    /// `weight` (required, as in Mitsuba) is a float, colour or texture read
    /// as one channel and clamped to [0, 1]. Mitsuba samples one component
    /// and weighs the direction by the mixture; where a component samples a
    /// delta lobe it mixes that lobe's probability with the other's density,
    /// and so does lancer. Transmitting components, blends in a blend, and
    /// masks or normal maps inside (they go around the blend) are refused. Both components must scatter on the same
    /// sides (`twosided` around both, or around neither).
    fn blend(&self, node: Node<'a, 'i>, mut p: Props<'a, 'i>) -> Result<Bsdf<'a, 'i>> {
        const TAGS: &[&str] = &["rgb", "float", "spectrum", "texture"];
        let weight = match self.take(&mut p, TAGS, "weight")? {
            Some(t) if t.tag_name().name() == "texture" => self.texture(t)?,
            Some(c) => ColorSource::Constant(self.color_of(c)?),
            None => match self.take_ref(&mut p, "weight")? {
                Some(r) => self.texture(self.referenced(r, "texture")?)?,
                None => {
                    return Err(self.err(
                        node,
                        "a blendbsdf needs its `weight` (<float name=\"weight\">, or a \
                         texture); Mitsuba has no default",
                    ))
                }
            },
        };
        let nested = self.take_nested(&mut p, &["bsdf", "ref"]);
        let [first, second] = nested[..] else {
            return Err(self.err(
                node,
                format!(
                    "a blendbsdf needs two nested <bsdf> or <ref> (Mitsuba: \"Two child BSDFs \
                     must be specified\"), got {}",
                    nested.len()
                ),
            ));
        };
        let parts = [self.bsdf(first)?, self.bsdf(second)?];
        for part in &parts {
            let why = if matches!(part.kind, MaterialKind::Blend { .. }) {
                Some("a blendbsdf inside a blendbsdf is outside the subset lancer reads")
            } else if part.opacity.is_some() || part.normal_map.is_some() {
                Some(
                    "a mask, normalmap or bumpmap inside a blendbsdf is outside the subset lancer \
                     reads; put it around the blendbsdf",
                )
            } else if part.kind.transmits() {
                Some("a transmitting BSDF inside a blendbsdf is outside the subset lancer reads")
            } else {
                None
            };
            if let Some(why) = why {
                return Err(self.err(part.node, why));
            }
        }
        if parts[0].sides != parts[1].sides {
            return Err(self.err(
                node,
                "one component of the blendbsdf is twosided and the other is not, so the blend \
                 is half two-sided, which lancer does not copy; wrap both in twosided, or put \
                 one twosided around the blendbsdf",
            ));
        }
        self.finish(p)?;
        let sides = parts[0].sides;
        let [a, b] = parts.map(|part| part.kind);
        Ok(Bsdf {
            node,
            kind: MaterialKind::Blend {
                weight,
                components: Box::new([a, b]),
            },
            sides,
            opacity: None,
            normal_map: None,
        })
    }

    /// Mitsuba's `normalmap`: its nested BSDF with the shading normal tilted
    /// by the `normalmap` texture (its `2 c - 1` in the frame of the shading
    /// normal and dp/du), weighed by Mitsuba's shadowing term unless
    /// `use_shadowing_function` is false.
    fn normal_map(&self, node: Node<'a, 'i>, mut p: Props<'a, 'i>) -> Result<Bsdf<'a, 'i>> {
        let texture = match self.take(&mut p, &["texture"], "normalmap")? {
            Some(t) => self.texture(t)?,
            None => match self.take_ref(&mut p, "normalmap")? {
                Some(r) => self.texture(self.referenced(r, "texture")?)?,
                None => return Err(self.err(
                    node,
                    "a normalmap needs a <texture name=\"normalmap\"> (a bitmap) or a <ref> to one",
                )),
            },
        };
        if let ColorSource::Attribute(_) = texture {
            return Err(self.err(
                node,
                "a normalmap of a mesh_attribute is outside the subset lancer reads; give a \
                 bitmap",
            ));
        }
        self.tilted(node, p, "normalmap", texture, None)
    }

    /// Mitsuba's `bumpmap`: its nested BSDF with the shading normal of the
    /// surface moved along it by the gradient of its one texture (any name,
    /// nested or by `<ref>`; a bitmap, read as one channel), times `scale`
    /// (1 by default).
    fn bump_map(&self, node: Node<'a, 'i>, mut p: Props<'a, 'i>) -> Result<Bsdf<'a, 'i>> {
        let scale = self.float(&mut p, "scale")?.unwrap_or(1.0) as f32;
        // The one texture, nested under any name or named by a <ref>
        let mut heights = Vec::new();
        for (child, used) in p.children.iter_mut() {
            let target = match child.tag_name().name() {
                "texture" => Some(*child),
                "ref" => (self.ids.get(&self.required_attr(*child, "id")?))
                    .filter(|t| t.tag_name().name() == "texture")
                    .copied(),
                _ => None,
            };
            if let (false, Some(t)) = (*used, target) {
                *used = true;
                heights.push(t);
            }
        }
        let texture = match heights[..] {
            [t] => self.texture(t)?,
            [] => {
                return Err(self.err(
                    node,
                    "a bumpmap needs one <texture> (a bitmap) or a <ref> to one",
                ))
            }
            [_, second, ..] => {
                return Err(self.err(second, "a second texture in a bumpmap; give one"))
            }
        };
        let bitmap = match &texture {
            ColorSource::Texture(_) => true,
            ColorSource::Mapped(m) => matches!(m.pattern, TexturePattern::Bitmap(_)),
            ColorSource::Constant(_) | ColorSource::Attribute(_) => false,
        };
        if !bitmap {
            return Err(self.err(
                node,
                "a bumpmap's texture must be a bitmap (Mitsuba has no gradient of the others)",
            ));
        }
        self.tilted(node, p, "bumpmap", texture, Some(scale))
    }

    /// The nested BSDF of a `normalmap` or `bumpmap` (`kind`) at `node`,
    /// tilted by `texture` (heights when `bump_scale` is given), with the
    /// properties both read.
    fn tilted(
        &self,
        node: Node<'a, 'i>,
        mut p: Props<'a, 'i>,
        kind: &str,
        texture: ColorSource,
        bump_scale: Option<f32>,
    ) -> Result<Bsdf<'a, 'i>> {
        if self.boolean(&mut p, "flip_invalid_normals")? == Some(false) {
            return Err(self.err(
                node,
                "flip_invalid_normals false is outside the subset lancer reads: lancer always \
                 turns a tilted normal to face the viewer; remove it",
            ));
        }
        let shadowing = self
            .boolean(&mut p, "use_shadowing_function")?
            .unwrap_or(true);
        let inner = self
            .take_one(&mut p, &["bsdf", "ref"])?
            .ok_or_else(|| self.err(node, format!("a {kind} needs one nested <bsdf> or <ref>")))?;
        let inner = self.bsdf(inner)?;
        if inner.normal_map.is_some() {
            return Err(self.err(
                inner.node,
                format!(
                    "a normalmap or bumpmap inside a {kind} is outside the subset lancer reads; \
                     keep one"
                ),
            ));
        }
        if inner.kind.transmits() {
            return Err(self.err(
                inner.node,
                format!(
                    "a {kind} over a transmitting BSDF (a dielectric) is outside the subset lancer \
                     reads; remove the {kind}"
                ),
            ));
        }
        self.finish(p)?;
        Ok(Bsdf {
            node,
            normal_map: Some(NormalMap {
                texture,
                bump_scale,
                wraps_two_sided: inner.sides == Sides::Shading,
                shadowing,
            }),
            ..inner
        })
    }

    /// A diffuse colour `name`: an `<rgb>`, a `<float>`, a uniform
    /// `<spectrum>`, a bitmap `<texture>` or a `<ref>` to a top-level one;
    /// Mitsuba's 0.5 when absent.
    fn reflectance(&self, p: &mut Props<'a, 'i>, name: &str) -> Result<ColorSource> {
        const TAGS: &[&str] = &["rgb", "float", "spectrum", "texture"];
        Ok(match self.take(p, TAGS, name)? {
            None => match self.take_ref(p, name)? {
                Some(r) => self.texture(self.referenced(r, "texture")?)?,
                None => ColorSource::Constant(Vec3::splat(DEFAULT_REFLECTANCE)),
            },
            Some(t) if t.tag_name().name() == "texture" => self.texture(t)?,
            Some(c) => ColorSource::Constant(self.color_of(c)?),
        })
    }

    /// A conductor's complex index of refraction, as Mitsuba reads it:
    /// `eta` and `k` (defaults 0 and 1), or the `material` preset, not both;
    /// `None` for the perfect reflector given as material `none` or by
    /// nothing at all.
    fn complex_ior(&self, p: &mut Props<'a, 'i>) -> Result<Option<ComplexIor>> {
        let material = self.string(p, "material")?;
        let eta = self.take(p, COLOR_TAGS, "eta")?;
        let k = self.take(p, COLOR_TAGS, "k")?;
        let given = |n: Option<Node<'a, 'i>>| n.map(|n| self.unbounded_color_of(n)).transpose();
        match material {
            Some((m, n)) if m != "none" => {
                if let Some(extra) = eta.or(k) {
                    return Err(self.err(
                        extra,
                        "the BSDF also names a `material` preset; give either eta and k or material, not both (Mitsuba refuses it too)",
                    ));
                }
                let ior = conductor_preset(&m).ok_or_else(|| {
                    let names: Vec<&str> = conductor_preset_names().collect();
                    self.attr_err(
                        n,
                        "value",
                        format!(
                            "unknown conductor material \"{}\"; Mitsuba's presets are: {}",
                            cut(&m),
                            names.join(", ")
                        ),
                    )
                })?;
                Ok(Some(ior))
            }
            _ if eta.is_none() && k.is_none() => Ok(None),
            _ => Ok(Some(ComplexIor {
                eta: given(eta)?.unwrap_or(ComplexIor::PERFECT.eta),
                k: given(k)?.unwrap_or(ComplexIor::PERFECT.k),
            })),
        }
    }

    /// A rough BSDF's `alpha`, or `alpha_u` and `alpha_v` (both, and not
    /// with `alpha`), as Mitsuba reads them: numbers >= 0, or textures
    /// (`bitmap`, `checkerboard`, or a `<ref>` to one) read as one channel;
    /// 0.1 by default. The constants, and the textures where the roughness
    /// varies.
    fn roughness(
        &self,
        p: &mut Props<'a, 'i>,
        node: Node<'a, 'i>,
    ) -> Result<(f32, f32, Option<Box<AlphaTextures>>)> {
        let mut read = |name: &str| self.number_or_texture(p, name, 0.0..=f64::INFINITY);
        let (alpha, u, v) = (read("alpha")?, read("alpha_u")?, read("alpha_v")?);
        let (u, v) = match (alpha, u, v) {
            (Some(a), None, None) => (a.clone(), a),
            (None, None, None) => (Alpha::Value(DEFAULT_ALPHA as f32), Alpha::Value(DEFAULT_ALPHA as f32)),
            (None, Some(u), Some(v)) => (u, v),
            (Some(_), _, _) => {
                return Err(self.err(
                    node,
                    "give either `alpha` or `alpha_u` and `alpha_v`, not both (Mitsuba refuses it too)",
                ))
            }
            _ => {
                return Err(self.err(
                    node,
                    "an anisotropic roughness needs both `alpha_u` and `alpha_v` (Mitsuba refuses one alone)",
                ))
            }
        };
        let value = |a: &Alpha| match a {
            Alpha::Value(x) => (*x, None),
            Alpha::Texture(t) => (DEFAULT_ALPHA as f32, Some(t.clone())),
        };
        let ((alpha_u, tu), (alpha_v, tv)) = (value(&u), value(&v));
        let textures =
            (tu.is_some() || tv.is_some()).then(|| Box::new(AlphaTextures { u: tu, v: tv }));
        Ok((alpha_u, alpha_v, textures))
    }

    /// A roughness that is a plain number in `range` or a texture (a
    /// `<texture>`, or a `<ref>` to one), as Mitsuba's unbounded textures.
    fn number_or_texture(
        &self,
        p: &mut Props<'a, 'i>,
        name: &str,
        range: std::ops::RangeInclusive<f64>,
    ) -> Result<Option<Alpha>> {
        if let Some(r) = self.take_ref(p, name)? {
            return Ok(Some(Alpha::Texture(
                self.texture(self.referenced(r, "texture")?)?,
            )));
        }
        let Some(n) = self.take(p, &["float", "integer", "texture"], name)? else {
            return Ok(None);
        };
        Ok(Some(match n.tag_name().name() {
            "texture" => Alpha::Texture(self.texture(n)?),
            _ => Alpha::Value(self.number_in(n, name, range)?),
        }))
    }

    /// A number Mitsuba reads as a texture where lancer reads a plain one
    /// (a `<float>` or `<integer>`): a `<texture>` or `<ref>` there is
    /// refused by name, and so is a value outside `range`.
    fn plain_number(
        &self,
        p: &mut Props<'a, 'i>,
        name: &str,
        range: std::ops::RangeInclusive<f64>,
    ) -> Result<Option<f32>> {
        let textured = |n: Node<'a, 'i>| {
            self.err(
                n,
                format!("a textured `{name}` is outside the subset lancer reads; give a <float>"),
            )
        };
        if let Some(r) = self.take_ref(p, name)? {
            return Err(textured(r));
        }
        let Some(n) = self.take(p, &["float", "integer", "texture"], name)? else {
            return Ok(None);
        };
        if n.tag_name().name() == "texture" {
            return Err(textured(n));
        }
        self.number_in(n, name, range).map(Some)
    }

    /// The number a `<float>` or `<integer>` property `name` holds, which
    /// must lie in `range`.
    fn number_in(
        &self,
        n: Node<'a, 'i>,
        name: &str,
        range: std::ops::RangeInclusive<f64>,
    ) -> Result<f32> {
        let text = self.value(n)?;
        let bounds = match (range.start().is_finite(), range.end().is_finite()) {
            (true, true) => format!("from {} to {}", range.start(), range.end()),
            (true, false) => format!(">= {}", range.start()),
            _ => String::from("finite"),
        };
        match numbers(&text).as_deref() {
            Some(&[x]) if range.contains(&x) => Ok(x as f32),
            _ => Err(self.attr_err(
                n,
                "value",
                format!("`{name}` must be a number {bounds}, got \"{}\"", cut(&text)),
            )),
        }
    }

    /// Mitsuba's `principled` (`src/bsdfs/principled.cpp`): the base
    /// colour (a colour or texture), the lobes' weights as numbers in
    /// [0, 1] or textures read as one channel, the index of refraction as
    /// `eta` or `specular` (not both, as Mitsuba refuses), and the lobes'
    /// sampling rates. Its specular transmission (`spec_trans` other than
    /// 0) is refused by name.
    fn principled(&self, node: Node<'a, 'i>, p: &mut Props<'a, 'i>) -> Result<MaterialKind> {
        let base_color = self.reflectance(p, "base_color")?;
        // Each weight a number in [0, 1] or a texture (Mitsuba's
        // `eval_1`); the roughness 0.5 by default, the others 0
        let mut textures: PrincipledTextures = Default::default();
        let mut weights = [0.0; Principled::WEIGHTS];
        for (k, name) in Principled::WEIGHT_NAMES.into_iter().enumerate() {
            let default = if name == "roughness" { 0.5 } else { 0.0 };
            weights[k] = match self.number_or_texture(p, name, 0.0..=1.0)? {
                Some(Alpha::Value(v)) => v,
                Some(Alpha::Texture(t)) => {
                    textures[k] = Some(t);
                    default
                }
                None => default,
            };
        }
        let [roughness, anisotropic, metallic, spec_tint, sheen, sheen_tint, clearcoat, clearcoat_gloss, flatness] =
            weights;
        let spec_trans = self
            .plain_number(p, "spec_trans", 0.0..=1.0)?
            .unwrap_or(0.0);
        if spec_trans != 0.0 {
            return Err(self.err(
                node,
                "a principled BSDF's specular transmission (`spec_trans` other than 0) is \
                 outside the subset lancer reads; give spec_trans 0, or use a roughdielectric",
            ));
        }
        let eta = self.plain_number(p, "eta", 0.0..=f64::INFINITY)?;
        let specular = self.plain_number(p, "specular", 0.0..=1.0)?;
        let eta = match (eta, specular) {
            (Some(_), Some(_)) => {
                return Err(self.err(
                    node,
                    "give either `eta` or `specular`, not both (Mitsuba refuses it too: \
                     \"either use eta or specular\")",
                ))
            }
            (Some(eta), None) if eta > 0.0 => eta,
            (Some(eta), None) => {
                return Err(self.err(node, format!("`eta` must be > 0, got {eta}")))
            }
            (None, specular) => {
                // Mitsuba's mapping of the specular reflectance at normal
                // incidence, 0.08 specular, to an index of refraction
                2.0 / (1.0 - (0.08 * specular.unwrap_or(0.5)).sqrt()) - 1.0
            }
        };
        let mut rate = |name: &str| {
            Ok::<_, SceneError>(
                self.plain_number(p, name, 0.0..=f64::INFINITY)?
                    .unwrap_or(1.0),
            )
        };
        let sampling_rates = [
            rate("main_specular_sampling_rate")?,
            rate("clearcoat_sampling_rate")?,
            rate("diffuse_reflectance_sampling_rate")?,
        ];
        let principled = Principled {
            base_color,
            roughness,
            anisotropic,
            metallic,
            spec_tint,
            sheen,
            sheen_tint,
            clearcoat,
            clearcoat_gloss,
            flatness,
            eta,
            sampling_rates,
            weight_textures: textures
                .iter()
                .any(Option::is_some)
                .then(|| Box::new(textures)),
        };
        if principled.may_sample_nothing() {
            return Err(self.err(
                node,
                "every lobe of this principled BSDF has sampling rate 0 (or weight 0): give \
                 one a rate > 0",
            ));
        }
        Ok(MaterialKind::Principled(Box::new(principled)))
    }

    /// A rough BSDF's `distribution` (any case), Beckmann by default.
    fn distribution(&self, p: &mut Props<'a, 'i>) -> Result<Microfacet> {
        self.named(
            p,
            "distribution",
            true,
            &[("beckmann", Microfacet::Beckmann), ("ggx", Microfacet::Ggx)],
            Microfacet::default(),
        )
    }

    /// A string property that names one of `choices` (in any case when
    /// `any_case`), or `default` when absent; another value is refused,
    /// naming Mitsuba's values.
    fn named<T: Copy>(
        &self,
        p: &mut Props<'a, 'i>,
        name: &str,
        any_case: bool,
        choices: &[(&str, T)],
        default: T,
    ) -> Result<T> {
        let Some((v, n)) = self.string(p, name)? else {
            return Ok(default);
        };
        let key = if any_case {
            v.to_lowercase()
        } else {
            v.clone()
        };
        if let Some(&(_, t)) = choices.iter().find(|(c, _)| *c == key) {
            return Ok(t);
        }
        let names: Vec<String> = choices.iter().map(|(c, _)| format!("\"{c}\"")).collect();
        let names = match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => names.concat(),
        };
        Err(self.attr_err(
            n,
            "value",
            format!("unknown {name} \"{}\"; Mitsuba has {}", cut(&v), names),
        ))
    }

    /// A dielectric's `int_ior` or `ext_ior`: a number, or one of
    /// Mitsuba's named indices (`<string value="water">`, any case).
    fn ior(&self, p: &mut Props<'a, 'i>, name: &str, default: f64) -> Result<f64> {
        let Some(node) = self.take(p, &["float", "integer", "string"], name)? else {
            return Ok(default);
        };
        let text = self.value(node)?;
        if node.tag_name().name() != "string" {
            return match numbers(&text).as_deref() {
                Some([x]) => Ok(*x),
                _ => Err(self.attr_err(
                    node,
                    "value",
                    format!("expected a finite number, got \"{}\"", cut(&text)),
                )),
            };
        }
        ior::ior_preset(text.trim()).map(f64::from).ok_or_else(|| {
            let names: Vec<&str> = ior::IOR_PRESETS.iter().map(|(n, _)| *n).collect();
            self.attr_err(
                node,
                "value",
                format!(
                    "unknown index of refraction \"{}\"; give a number or one of Mitsuba's names: {}",
                    cut(&text),
                    names.join(", ")
                ),
            )
        })
    }

    /// How many `<ref>` elements of the scene (its included files too) name
    /// `node`'s `id`.
    fn ref_count(&self, node: Node<'a, 'i>) -> usize {
        let Some(id) = node.attribute("id") else {
            return 0;
        };
        self.docs
            .iter()
            .flat_map(|doc| doc.descendants())
            .filter(|n| n.tag_name().name() == "ref" && n.attribute("id") == Some(id))
            .count()
    }

    /// The element a `<ref id>` names, which must be a `<tag>`.
    fn referenced(&self, node: Node<'a, 'i>, tag: &str) -> Result<Node<'a, 'i>> {
        let id = self.required_attr(node, "id")?;
        match self.ids.get(&id) {
            Some(&target) if target.tag_name().name() == tag => Ok(target),
            Some(&target) => Err(self.attr_err(
                node,
                "id",
                format!(
                    "\"{}\" is a <{}> ({}), where a <{tag}> is expected",
                    cut(&id),
                    target.tag_name().name(),
                    self.place(target, node)
                ),
            )),
            None => {
                let mut ids: Vec<&str> = (self.ids.iter())
                    .filter(|(_, n)| n.tag_name().name() == tag)
                    .map(|(id, _)| id.as_str())
                    .collect();
                ids.sort_unstable();
                Err(self.attr_err(
                    node,
                    "id",
                    format!(
                        "no <{tag} id=\"{}\"> in the scene; defined: {}",
                        cut(&id),
                        if ids.is_empty() {
                            String::from("none")
                        } else {
                            ids.join(", ")
                        }
                    ),
                ))
            }
        }
    }

    /// A colour `<texture>`: `bitmap` (the image file, with `to_uv`,
    /// `wrap_mode` and `filter_type`; sRGB-decoded), `checkerboard`
    /// (`color0`, `color1`, `to_uv`) or `mesh_attribute` (`name`, `scale`;
    /// the shape's file gives the values), as Mitsuba 3.9 defines them. A bitmap
    /// with Mitsuba's defaults (bilinear, repeat, no `to_uv`, which are
    /// lancer's) is a plain texture.
    fn texture(&self, node: Node<'a, 'i>) -> Result<ColorSource> {
        let kind = self.plugin_type(node, &["bitmap", "checkerboard", "mesh_attribute"])?;
        self.check_attrs(node, &["type", "name", "id"])?;
        let mut p = self.props(node)?;
        if kind == "mesh_attribute" {
            // Mitsuba's mesh_attribute: the shape's attribute `name`, times `scale`
            let (name, n) = self
                .string(&mut p, "name")?
                .ok_or_else(|| self.err(node, "missing property <string name=\"name\">"))?;
            if !name.starts_with("vertex_") && !name.starts_with("face_") {
                return Err(self.attr_err(
                    n,
                    "value",
                    format!(
                        "mesh attribute name \"{}\" must start with \"vertex_\" or \"face_\" \
                         (Mitsuba refuses it too)",
                        cut(&name)
                    ),
                ));
            }
            let scale = self.float(&mut p, "scale")?.map_or(1.0, |v| v as f32);
            self.finish(p)?;
            return Ok(ColorSource::Attribute(MeshAttribute { name, scale }));
        }
        let to_uv = self.to_uv(&mut p)?;
        if kind == "checkerboard" {
            let mut color = |name: &str, default: f32| -> Result<Rgb> {
                let refused = |n: Node| {
                    self.err(
                        n,
                        format!(
                            "a textured `{name}` of a checkerboard is outside the subset lancer \
                             reads; give an <rgb> or a <float>"
                        ),
                    )
                };
                match self.take(&mut p, &["rgb", "float", "spectrum", "texture"], name)? {
                    Some(t) if t.tag_name().name() == "texture" => Err(refused(t)),
                    Some(c) => self.color_of(c),
                    None => match self.take_ref(&mut p, name)? {
                        Some(r) => Err(refused(r)),
                        None => Ok(Vec3::splat(default)),
                    },
                }
            };
            let (color0, color1) = (color("color0", 0.4)?, color("color1", 0.2)?);
            self.finish(p)?;
            return Ok(ColorSource::Mapped(Box::new(MappedTexture {
                pattern: TexturePattern::Checkerboard { color0, color1 },
                to_uv,
                wrap: TextureWrap::default(),
                filter: TextureFilter::default(),
                raw: false,
            })));
        }
        let (file, n) = self
            .string(&mut p, "filename")?
            .ok_or_else(|| self.err(node, "missing property <string name=\"filename\">"))?;
        let filter = self.named(
            &mut p,
            "filter_type",
            false,
            &[
                ("bilinear", TextureFilter::Bilinear),
                ("nearest", TextureFilter::Nearest),
            ],
            TextureFilter::Bilinear,
        )?;
        let wrap = self.named(
            &mut p,
            "wrap_mode",
            false,
            &[
                ("repeat", TextureWrap::Repeat),
                ("mirror", TextureWrap::Mirror),
                ("clamp", TextureWrap::Clamp),
            ],
            TextureWrap::Repeat,
        )?;
        // Mitsuba decodes 8-bit and 16-bit images from sRGB unless `raw`
        let raw = self.boolean(&mut p, "raw")?.unwrap_or(false);
        // Mitsuba's hardware texture filtering, used on CUDA devices only:
        // the image is the same
        self.boolean(&mut p, "accel")?;
        // The precision Mitsuba stores texels in (3.9.1's bitmap `format`):
        // the image is the same to within its rounding
        if let Some((format, n)) = self.string(&mut p, "format")? {
            const FORMATS: [&str; 5] = ["auto", "variant", "float16", "fp16", "uint8"];
            if !FORMATS.contains(&format.as_str()) {
                return Err(self.attr_err(
                    n,
                    "value",
                    format!(
                        "unknown bitmap format \"{}\"; Mitsuba reads: {}",
                        cut(&format),
                        FORMATS.join(", ")
                    ),
                ));
            }
        }
        self.finish(p)?;
        let path = self.resolve(&file);
        obj::check_readable(&path).map_err(|e| {
            self.attr_err(
                n,
                "value",
                format!(
                    "cannot read texture {}: {e}",
                    crate::util::text::cut_path(&path)
                ),
            )
        })?;
        if to_uv == MappedTexture::IDENTITY_UV
            && wrap == TextureWrap::Repeat
            && filter == TextureFilter::Bilinear
            && !raw
        {
            return Ok(ColorSource::Texture(path));
        }
        Ok(ColorSource::Mapped(Box::new(MappedTexture {
            pattern: TexturePattern::Bitmap(path),
            to_uv,
            wrap,
            filter,
            raw,
        })))
    }

    /// A texture's `to_uv` as Mitsuba 3.9 reads it: the transform's 2 x 2
    /// upper-left block and the x and y of its translation (Mitsuba's
    /// `extract()` of the 4 x 4 matrix; its z row and column are dropped).
    fn to_uv(&self, p: &mut Props<'a, 'i>) -> Result<[f32; 6]> {
        let Some(m) = self.transform(p, "to_uv")? else {
            return Ok(MappedTexture::IDENTITY_UV);
        };
        let (x, y, t) = (m.matrix3.x_axis, m.matrix3.y_axis, m.translation);
        Ok([x.x, y.x, t.x, x.y, y.y, t.y].map(|v| v as f32))
    }

    /// The material index for a BSDF with an emission, made once per pair.
    fn material(&mut self, bsdf: Option<Bsdf>, emitter: Option<(Node, Rgb)>) -> u32 {
        let emission = emitter.map_or(Vec3::ZERO, |e| e.1);
        let key = (
            bsdf.as_ref().map_or((usize::MAX, usize::MAX), |b| {
                (self.doc_index(b.node), b.node.range().start)
            }),
            emission.to_array().map(f32::to_bits),
        );
        if let Some(&index) = self.material_index.get(&key) {
            return index;
        }
        let (base, kind, sides, opacity, normal_map) = match bsdf {
            Some(b) => (
                match b.node.attribute("id") {
                    Some(id) => id.to_string(),
                    None => format!("bsdf@{}", self.line(b.node)),
                },
                b.kind,
                b.sides,
                b.opacity,
                b.normal_map,
            ),
            // Mitsuba's default BSDF is a plain (one-sided) diffuse, black
            // on an emitter.
            None => (
                String::from(if emitter.is_some() {
                    "default_black"
                } else {
                    "default_diffuse"
                }),
                MaterialKind::Lambert {
                    albedo: ColorSource::Constant(Vec3::splat(if emitter.is_some() {
                        0.0
                    } else {
                        DEFAULT_REFLECTANCE
                    })),
                },
                Sides::Front,
                None,
                None,
            ),
        };
        let mut name = match emitter {
            Some((node, _)) => format!("{base}+area@{}", self.line(node)),
            None => base,
        };
        let taken = |n: &str| self.materials.iter().any(|m| m.name == n);
        if taken(&name) {
            name = (2..)
                .map(|k| format!("{name}#{k}"))
                .find(|n| !taken(n))
                .unwrap_or(name);
        }
        let index = self.materials.len() as u32;
        self.materials.push(Material {
            name,
            kind,
            emission,
            sides,
            opacity,
            normal_map,
        });
        self.material_index.insert(key, index);
        index
    }

    // -------------------------------------------------------------- shapes

    fn shape(&mut self, node: Node<'a, 'i>) -> Result<()> {
        let kind = self.plugin_type(node, SHAPE_TYPES)?;
        self.check_attrs(node, &["type", "id", "name"])?;
        match kind.as_str() {
            "instance" => return self.instance(node),
            // Read where an instance names it; on its own it draws nothing
            "shapegroup" => {
                if self.ref_count(node) == 0 {
                    self.warnings.push(format!(
                        "{}:{}: no <shape type=\"instance\"> names this shapegroup, so it draws \
                         nothing (as in Mitsuba); lancer leaves it unread",
                        crate::util::text::cut_path(self.file_of(node)),
                        self.line(node)
                    ));
                }
                return Ok(());
            }
            _ => {}
        }
        let mut p = self.props(node)?;
        // An area emitter, nested or a top-level one by <ref id>, is taken
        // first: the <ref> left is the BSDF's
        let emitter = self.nested_or_referenced(&mut p, "emitter", "a shape")?;
        if let (Some((at, _)), Some(group)) = (emitter, self.in_group) {
            return Err(self.err(
                at,
                format!(
                    "an area emitter on a shape of a shapegroup ({}): Mitsuba instances no \
                     emitter (\"Instancing of emitters is not supported\"); move this shape out \
                     of the group, and place a copy of it per instance",
                    self.place(group, at)
                ),
            ));
        }
        let bsdf = match self.take_one(&mut p, &["bsdf", "ref"])? {
            Some(b) => Some(self.bsdf(b)?),
            None => None,
        };
        let emitter = match emitter.map(|f| f.1) {
            Some(e) => {
                self.plugin_type(e, &["area"])?;
                self.check_attrs(e, &["type", "id", "name"])?;
                let mut ep = self.props(e)?;
                // Mitsuba's default radiance is 1
                let radiance = self.radiance(&mut ep, "radiance")?.unwrap_or(Vec3::ONE);
                self.finish(ep)?;
                Some((e, radiance))
            }
            None => None,
        };
        let material = self.material(bsdf, emitter);
        let m = self
            .transform(&mut p, "to_world")?
            .unwrap_or(DAffine3::IDENTITY);
        let flip = self.boolean(&mut p, "flip_normals")?.unwrap_or(false);
        let first_triangle = self.triangles.len();
        let mesh_file = matches!(kind.as_str(), "obj" | "ply" | "serialized");
        if !mesh_file
            && !self.materials[material as usize]
                .mesh_attribute_reads()
                .is_empty()
        {
            return Err(self.no_attributes(node, material, &kind));
        }
        match kind.as_str() {
            "sphere" => self.sphere(node, &mut p, &m, flip, material)?,
            "rectangle" => {
                self.add_faces(
                    node,
                    &m,
                    &RECTANGLE_CORNERS,
                    &RECTANGLE_UV,
                    &RECTANGLE_FACES,
                    None,
                    material,
                )?;
            }
            "cube" => {
                for face in &CUBE_FACES {
                    self.add_faces(
                        node,
                        &m,
                        face,
                        &CUBE_UV,
                        &[[0, 1, 2], [3, 0, 2]],
                        None,
                        material,
                    )?;
                }
            }
            "disk" => {
                let (pos, uv, faces) = disk_fan();
                self.add_faces(node, &m, &pos, &uv, &faces, None, material)?;
            }
            "cylinder" => self.cylinder(node, &mut p, &m, material)?,
            _ => self.mesh_file(node, &mut p, &kind, &m, material)?,
        }
        if flip {
            // The other side is the front: reverse each triangle's winding
            // and turn its shading normals round.
            for t in &mut self.triangles[first_triangle..] {
                t.p.swap(1, 2);
                if let Some(a) = t.attribute {
                    self.mesh_attributes[a as usize].swap(1, 2);
                }
                if let Some(uv) = &mut t.uv {
                    uv.swap(1, 2);
                }
                if let Some(n) = &mut t.n {
                    n.swap(1, 2);
                    for v in n.iter_mut() {
                        *v = -*v;
                    }
                }
            }
        }
        self.finish(p)
    }

    /// `<shape type="instance">`: the shapes of one top-level `shapegroup`,
    /// named by `<ref id>`, placed by `to_world` as
    /// Mitsuba 3.9.1's `src/shapes/instance.cpp` places them: points by
    /// `to_world`, geometric and shading normals by its inverse transpose.
    /// The group's shapes are read once, in the group's space, and copied
    /// per instance: the image is Mitsuba's, the memory that of the copies.
    fn instance(&mut self, node: Node<'a, 'i>) -> Result<()> {
        let mut p = self.props(node)?;
        let m = self
            .transform(&mut p, "to_world")?
            .unwrap_or(DAffine3::IDENTITY);
        let mut groups = Vec::new();
        for (child, used) in p.children.iter_mut() {
            let group = match child.tag_name().name() {
                _ if *used => continue,
                "shape" if child.attribute("type") == Some("shapegroup") => {
                    return Err(self.err(
                        *child,
                        "a shapegroup nested in an instance, which Mitsuba 3.9.1 fails to load \
                         (\"Couldn't find key\"); make it a top-level <shape type=\"shapegroup\" \
                         id=\"...\"> and name it here by <ref id=\"...\"/>",
                    ))
                }
                "shape" => *child,
                "ref" => {
                    self.check_attrs(*child, &["id", "name"])?;
                    self.referenced(*child, "shape")?
                }
                "bsdf" | "emitter" => {
                    return Err(self.err(
                        *child,
                        format!(
                            "a <{}> on an instance: Mitsuba takes an instance's materials and \
                             emitters from the shapes of its group (\"Only a shapegroup can be \
                             specified in an instance\"); put it on the group's shapes",
                            child.tag_name().name()
                        ),
                    ))
                }
                _ => continue,
            };
            if group.attribute("type") != Some("shapegroup") {
                return Err(self.err(
                    *child,
                    "an instance holds one shapegroup and no other shape (Mitsuba: \"Only a \
                     shapegroup can be specified in an instance\"); put this shape in a \
                     <shape type=\"shapegroup\" id=\"...\"> and name it by <ref id=\"...\"/>",
                ));
            }
            *used = true;
            groups.push((*child, group));
        }
        let group = match groups.as_slice() {
            [(_, one)] => *one,
            [] => {
                return Err(self.err(
                    node,
                    "an instance without a shapegroup: add <ref id=\"...\"/> naming a \
                     <shape type=\"shapegroup\" id=\"...\">",
                ))
            }
            [_, (second, _), ..] => {
                return Err(self.err(
                    *second,
                    "a second shapegroup in one instance; an instance places one group",
                ))
            }
        };
        self.finish(p)?;
        let det = m.matrix3.determinant();
        if !(det.is_finite() && det != 0.0 && m.translation.is_finite()) {
            return Err(self.err(
                node,
                "property `to_world` of the instance is singular or not finite; give it an \
                 invertible transform",
            ));
        }
        let key = self.group(group)?;
        self.add_instance_shapes(node, key, &m)
    }

    /// Copies the shapes of group `key` into the scene, moved by instance
    /// `node`'s `to_world` `m` (invertible).
    fn add_instance_shapes(
        &mut self,
        node: Node<'a, 'i>,
        key: (usize, usize),
        m: &DAffine3,
    ) -> Result<()> {
        let shapes = &self.groups[&key];
        let det = m.matrix3.determinant();
        let lin = m.matrix3;
        let normal_matrix = lin.inverse().transpose();
        // A mirror keeps each geometric normal where the inverse transpose
        // takes it, opposite to the winding of the moved corners: the
        // winding turns round with it
        let mirror = det < 0.0;
        let mut degenerate = 0;
        for t in &shapes.triangles {
            let mut p = t.p.map(|v| m.transform_point3(v.as_dvec3()).as_vec3());
            let mut n =
                t.n.map(|n| n.map(|v| (normal_matrix * v.as_dvec3()).normalize().as_vec3()));
            let mut uv = t.uv;
            if mirror {
                p.swap(1, 2);
                if let Some(n) = &mut n {
                    n.swap(1, 2);
                }
                if let Some(uv) = &mut uv {
                    uv.swap(1, 2);
                }
            }
            if !p.iter().all(|v| v.is_finite()) {
                return Err(self.err(
                    node,
                    "property `to_world` of the instance moves the group's shapes beyond \
                     32-bit floats",
                ));
            }
            if (p[1] - p[0]).cross(p[2] - p[0]).length_squared() <= 0.0 {
                degenerate += 1;
                continue;
            }
            // A mirrored copy's attribute values turn round with its corners
            let attribute = match t.attribute {
                Some(a) if mirror => {
                    let mut values = self.mesh_attributes[a as usize];
                    values.swap(1, 2);
                    self.mesh_attributes.push(values);
                    Some(self.mesh_attributes.len() as u32 - 1)
                }
                a => a,
            };
            self.triangles.push(Triangle {
                p,
                n,
                uv,
                material: t.material,
                attribute,
            });
        }
        if !shapes.spheres.is_empty() {
            let k = lin.x_axis.length();
            if !is_similarity(&lin) {
                return Err(self.err(
                    node,
                    "property `to_world` of the instance scales non-uniformly or shears, and its \
                     group holds a sphere: Mitsuba intersects the sphere in the group's space, \
                     which makes it an ellipsoid, and lancer's spheres are round; scale the \
                     instance uniformly, or use a sphere mesh (obj or ply) in the group",
                ));
            }
            for s in &shapes.spheres {
                let radius = (s.radius as f64 * k) as f32;
                let center = m.transform_point3(s.center.as_dvec3()).as_vec3();
                if !(radius.is_finite() && radius > 0.0 && center.is_finite()) {
                    return Err(self.err(
                        node,
                        "property `to_world` of the instance gives a sphere of its group a \
                         radius of zero or moves it beyond 32-bit floats",
                    ));
                }
                self.spheres.push(Sphere {
                    center,
                    radius,
                    material: s.material,
                    // Mitsuba's texture coordinates stay those of the
                    // group's sphere: its frame moves with the instance
                    mitsuba_frame: s
                        .mitsuba_frame
                        .map(|f| f.map(|a| (lin * a.as_dvec3()).normalize().as_vec3())),
                });
            }
        }
        if degenerate > 0 {
            let place = format!(
                "{}:{}: an instance",
                crate::util::text::cut_path(self.file_of(node)),
                self.line(node)
            );
            self.dropped.push((place, degenerate));
        }
        // Mitsuba orients an instanced shape's shading frame by its dp/du
        // before the instance moves it (`initialize_sh_frame` precedes
        // `dp_du = to_world * dp_du`): an anisotropic BSDF there turns with
        // the group's space, not the world's
        let scaled_identity = DMat3::from_diagonal(DVec3::splat(lin.x_axis.x));
        if !lin.abs_diff_eq(scaled_identity, RIGID_TOLERANCE * lin.x_axis.x.abs()) {
            let anisotropic = shapes
                .triangles
                .iter()
                .map(|t| t.material)
                .chain(shapes.spheres.iter().map(|s| s.material))
                .map(|i| &self.materials[i as usize])
                .find(|mat| mat.normal_map.is_none() && mat.kind.is_anisotropic());
            if let Some(mat) = anisotropic {
                return Err(self.err(
                    node,
                    format!(
                        "the instance turns or stretches an anisotropic material (`{}`): Mitsuba \
                         3.9.1 orients its tangent by the group's unmoved dp/du, which lancer \
                         does not copy; use alpha_u = alpha_v, or place the shape outside a \
                         shapegroup",
                        mat.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The shapes of `shapegroup` element `group`, read on first use into
    /// [`Loader::groups`]; returns its key there. As Mitsuba's
    /// `src/render/shapegroup.cpp`, a group holds shapes only, and no group,
    /// instance or emitter among them.
    fn group(&mut self, group: Node<'a, 'i>) -> Result<(usize, usize)> {
        let key = (self.doc_index(group), group.range().start);
        if self.groups.contains_key(&key) {
            return Ok(key);
        }
        self.check_attrs(group, &["type", "id", "name"])?;
        let mut p = self.props(group)?;
        let (first_triangle, first_sphere) = (self.triangles.len(), self.spheres.len());
        for child in self.take_nested(&mut p, &["shape"]) {
            let nested = match child.attribute("type") {
                Some("shapegroup") => Some("a shapegroup (\"Nested ShapeGroup is not permitted\")"),
                Some("instance") => Some("an instance (\"Nested instancing is not permitted\")"),
                _ => None,
            };
            if let Some(what) = nested {
                return Err(self.err(
                    child,
                    format!(
                        "{what} inside a shapegroup: Mitsuba refuses it; keep shapegroups \
                         and instances at the top level"
                    ),
                ));
            }
            self.in_group = Some(group);
            let read = self.shape(child);
            self.in_group = None;
            read?;
        }
        self.finish(p)?;
        let shapes = GroupShapes {
            triangles: self.triangles.split_off(first_triangle),
            spheres: self.spheres.split_off(first_sphere),
        };
        self.groups.insert(key, shapes);
        Ok(key)
    }

    /// `<shape type="sphere">`: `center`, `radius` and `to_world`, as
    /// Mitsuba reads them: the centre is `to_world` of the origin and the
    /// radius the length of `to_world` of (1, 0, 0) (a shear or a
    /// non-uniform scale is warned of, by Mitsuba too, and ignored); the
    /// rotation of `to_world` turns Mitsuba's texture coordinates and
    /// tangent with the sphere ([`Sphere::mitsuba_frame`]).
    fn sphere(
        &mut self,
        node: Node<'a, 'i>,
        p: &mut Props<'a, 'i>,
        m: &DAffine3,
        flip: bool,
        material: u32,
    ) -> Result<()> {
        let center = self.point(p, "center")?.unwrap_or(DVec3::ZERO);
        let radius = self.float(p, "radius")?.unwrap_or(1.0);
        if radius <= 0.0 {
            return Err(self.err(node, format!("radius must be > 0, got {radius}")));
        }
        let full =
            *m * DAffine3::from_translation(center) * DAffine3::from_scale(DVec3::splat(radius));
        let cols = [
            full.matrix3.x_axis,
            full.matrix3.y_axis,
            full.matrix3.z_axis,
        ];
        let r = cols[0].length();
        if !(r > 0.0 && (r as f32).is_finite() && r as f32 > 0.0) {
            return Err(self.err(
                node,
                "property `to_world` gives the sphere a radius of zero or beyond 32-bit floats",
            ));
        }
        if !is_similarity(&full.matrix3) {
            self.warnings.push(format!(
                "{}:{}: property `to_world` of <shape type=\"sphere\"> scales non-uniformly or \
                 shears: Mitsuba warns and renders a round sphere of radius |to_world * (1, 0, 0)| = \
                 {r}, and so does lancer; use an obj or ply mesh for an ellipsoid",
                crate::util::text::cut_path(self.file_of(node)),
                self.line(node)
            ));
        }
        // A mirroring to_world turns the sphere inside out, as flip_normals does.
        let inward = flip != (full.matrix3.determinant() < 0.0);
        if inward {
            let mat = &self.materials[material as usize];
            let matters = mat.sides == Sides::Front
                || mat.emission.max_element() > 0.0
                || mat.kind.transmits();
            if matters {
                return Err(self.err(
                    node,
                    "property `flip_normals` (or a mirroring to_world) turns the sphere's front side \
                     inward, which lancer's spheres cannot do for a one-sided, emitting or dielectric \
                     material; use a twosided BSDF without an emitter, or a sphere mesh (obj/ply) \
                     with flip_normals",
                ));
            }
        }
        // Mitsuba's local frame, for its texture coordinates and tangent:
        // the columns made orthonormal in order (a mirror stays one)
        let x = cols[0].normalize();
        let y = (cols[1] - cols[1].dot(x) * x).normalize();
        let z = (cols[2] - cols[2].dot(x) * x - cols[2].dot(y) * y).normalize();
        self.spheres.push(Sphere {
            center: full.translation.as_vec3(),
            radius: r as f32,
            material,
            mitsuba_frame: Some([x.as_vec3(), y.as_vec3(), z.as_vec3()]),
        });
        Ok(())
    }

    /// Triangles of a built-in shape, with Mitsuba's texture coordinates
    /// turned into lancer's (v = 0 is the image's bottom row) and, where
    /// given, the world-space shading normal of each corner.
    #[allow(clippy::too_many_arguments)]
    fn add_faces(
        &mut self,
        node: Node,
        m: &DAffine3,
        pos: &[[f64; 3]],
        uv: &[[f32; 2]],
        faces: &[[usize; 3]],
        normals: Option<&[Vec3]>,
        material: u32,
    ) -> Result<()> {
        for f in faces {
            let p = f.map(|i| m.transform_point3(DVec3::from_array(pos[i])).as_vec3());
            let (a, b, c) = (p[0].as_dvec3(), p[1].as_dvec3(), p[2].as_dvec3());
            let area2 = (b - a).cross(c - a).length_squared();
            if area2.is_nan() || area2 <= 0.0 || !p.iter().all(|x| x.is_finite()) {
                return Err(self.err(
                    node,
                    "to_world flattens the shape to zero area or makes it non-finite",
                ));
            }
            let uv = f.map(|i| Vec2::new(uv[i][0], 1.0 - uv[i][1]));
            self.triangles.push(Triangle {
                p,
                n: normals.map(|n| f.map(|i| n[i])),
                uv: Some(uv),
                material,
                attribute: None,
            });
        }
        Ok(())
    }

    /// Mitsuba's `cylinder` (`src/shapes/cylinder.cpp`): the open tube of
    /// `radius` from `p0` to `p1`, moved by `to_world`, its front side
    /// outwards (towards dp/du x dp/dv), as a prism of
    /// [`CYLINDER_SEGMENTS`] sides with Mitsuba's normals at its corners.
    /// The tube's own frame is Mitsuba's: `to_world` times the translation
    /// to `p0`, the frame Mitsuba builds about `p1 - p0`, and the scale by
    /// the radius and the length; u = angle / 2 pi from that frame's x
    /// axis, v = the height from 0 at `p0` to 1 at `p1`. The corners lie at
    /// radius pi / (n sin(pi / n)), so that the prism's area is the tube's:
    /// emitted power and the chance to be hit are exact, and its outline is
    /// within 5.1e-5 radii of the circle (corners 2.5e-5 outside, side
    /// midpoints 5.0e-5 inside).
    fn cylinder(
        &mut self,
        node: Node<'a, 'i>,
        p: &mut Props<'a, 'i>,
        m: &DAffine3,
        material: u32,
    ) -> Result<()> {
        let radius = self.float(p, "radius")?.unwrap_or(1.0);
        let p0 = self.point(p, "p0")?.unwrap_or(DVec3::ZERO);
        let p1 = self.point(p, "p1")?.unwrap_or(DVec3::Z);
        let d = p1 - p0;
        let length = d.length();
        if !(length > 0.0 && radius != 0.0 && length.is_finite()) {
            return Err(self.err(
                node,
                format!(
                    "a cylinder needs p0 and p1 apart and a radius other than 0, got length \
                     {length} and radius {radius}"
                ),
            ));
        }
        let axis = d / length;
        let (s, t) = mitsuba_coordinate_system(axis);
        let frame = DAffine3::from_cols(s, t, axis, p0);
        let m = *m * frame * DAffine3::from_scale(DVec3::new(radius, radius, length));
        let n = CYLINDER_SEGMENTS;
        let step = std::f64::consts::TAU / n as f64;
        let rim = std::f64::consts::PI / (n as f64 * (0.5 * step).sin());
        // The corners, column k at angle k step, bottom then top; each with
        // Mitsuba's normal there (dp/du x dp/dv) and texture coordinates
        let mut pos = Vec::with_capacity(2 * (n + 1));
        let mut uv = Vec::with_capacity(2 * (n + 1));
        let mut normals = Vec::with_capacity(2 * (n + 1));
        for k in 0..=n {
            let (sin, cos) = (k as f64 * step).sin_cos();
            let dp_du = m.transform_vector3(DVec3::new(-sin, cos, 0.0));
            let normal = dp_du.cross(m.transform_vector3(DVec3::Z)).normalize();
            for z in [0.0, 1.0] {
                pos.push([rim * cos, rim * sin, z]);
                uv.push([(k as f64 / n as f64) as f32, z as f32]);
                normals.push(normal.as_vec3());
            }
        }
        let faces: Vec<[usize; 3]> = (0..n)
            .flat_map(|k| {
                let [b0, b1, t1, t0] = [2 * k, 2 * k + 2, 2 * k + 3, 2 * k + 1];
                [[b0, b1, t1], [b0, t1, t0]]
            })
            .collect();
        self.add_faces(node, &m, &pos, &uv, &faces, Some(&normals), material)
    }

    /// `obj`, `ply` and `serialized` shapes.
    fn mesh_file(
        &mut self,
        node: Node<'a, 'i>,
        p: &mut Props<'a, 'i>,
        kind: &str,
        m: &DAffine3,
        material: u32,
    ) -> Result<()> {
        let (file, file_node) = self
            .string(p, "filename")?
            .ok_or_else(|| self.err(node, "missing property <string name=\"filename\">"))?;
        let face_normals = self.boolean(p, "face_normals")?.unwrap_or(false);
        if kind == "obj" && self.boolean(p, "flip_tex_coords")? == Some(false) {
            return Err(self.err(node, "flip_tex_coords = false is not supported: lancer reads OBJ texture coordinates as OBJ defines them"));
        }
        // Mitsuba's default: the file's first mesh.
        let shape_index = match kind {
            "serialized" => self.count(p, "shape_index", 0)?.unwrap_or(0),
            _ => 0,
        };
        let resolved = self.resolve(&file);
        let here = |reason: String| self.attr_err(file_node, "value", reason);
        // Mitsuba computes smooth normals for a mesh without any.
        let smooth = !face_normals;
        let mut flag_note = None;
        let reads_attribute = !self.materials[material as usize]
            .mesh_attribute_reads()
            .is_empty();
        let mut warnings: Vec<String> = Vec::new();
        if reads_attribute && kind != "ply" {
            return Err(self.no_attributes(node, material, kind));
        }
        let mut attributes = None;
        let mut loaded = if kind == "obj" {
            obj::load_mesh(&resolved, &resolved, m, Some(material), smooth).map_err(here)?
        } else {
            let shown = crate::util::text::cut_path(&resolved);
            let mut mesh = if kind == "ply" {
                let ply = crate::scene::ply::read_ply(&resolved, &shown).map_err(here)?;
                if reads_attribute {
                    let (values, warning) =
                        self.triangle_attributes(file_node, &shown, &ply, material)?;
                    attributes = Some(values);
                    warnings.extend(warning);
                }
                ply.mesh
            } else {
                let read =
                    serialized::read_serialized(&resolved, &shown, shape_index, face_normals)
                        .map_err(here)?;
                if read.flags & serialized::FACE_NORMALS != 0 && !face_normals {
                    flag_note = Some(format!(
                        "{}:{}: {shown}: mesh {shape_index}'s flags ask for face normals \
                         (0x0010), which Mitsuba 3.9.1 ignores (only the shape's `face_normals` \
                         counts), and so does lancer; add <boolean name=\"face_normals\" \
                         value=\"true\"/> to the shape for face normals",
                        crate::util::text::cut_path(self.file_of(file_node)),
                        self.line(file_node),
                    ));
                }
                read.mesh
            };
            let mut normal_matrix = m.matrix3.inverse().transpose();
            if smooth && mesh.normals.is_empty() {
                obj::smooth_mesh_normals(&mut mesh, m);
                normal_matrix = DMat3::IDENTITY;
            }
            let mut out = LoadedMesh::default();
            obj::add_mesh_triangles(
                &mut out,
                &mesh,
                m,
                &normal_matrix,
                material,
                attributes.as_deref(),
            )
            .map_err(here)?;
            out
        };
        self.warnings.extend(flag_note);
        self.warnings.append(&mut warnings);
        if kind == "obj" {
            self.files.append(&mut loaded.files);
        } else {
            self.files.push(resolved.clone());
        }
        if face_normals {
            for t in &mut loaded.triangles {
                t.n = None;
            }
        } else {
            let flat = loaded.triangles.iter().filter(|t| t.n.is_none()).count();
            if flat > 0 {
                self.warnings.push(format!(
                    "{}:{}: {}: {flat} triangle(s) have no usable vertex normal (the file gives \
                     normals to some faces only, or a smooth normal vanishes) and are shaded \
                     with the geometric normal",
                    crate::util::text::cut_path(self.file_of(file_node)),
                    self.line(file_node),
                    crate::util::text::cut_path(&resolved)
                ));
            }
        }
        let dropped = loaded.dropped_non_finite + loaded.dropped_degenerate;
        if dropped > 0 {
            let place = format!(
                "{}:{}: {}",
                crate::util::text::cut_path(self.file_of(file_node)),
                self.line(file_node),
                crate::util::text::cut_path(&resolved)
            );
            self.dropped.push((place, dropped));
        }
        self.warnings.extend(loaded.notes);
        let first_attribute = self.mesh_attributes.len() as u32;
        self.mesh_attributes.append(&mut loaded.attributes);
        self.triangles
            .extend(loaded.triangles.into_iter().map(|mut t| {
                t.attribute = t.attribute.map(|a| a + first_attribute);
                t
            }));
        Ok(())
    }

    /// The refusal of a shape of `kind` whose material reads a mesh
    /// attribute: only PLY files give lancer attributes.
    fn no_attributes(&self, node: Node<'a, 'i>, material: u32, kind: &str) -> SceneError {
        let mat = &self.materials[material as usize];
        let names: Vec<&str> = (mat.mesh_attribute_reads().iter())
            .map(|(a, _)| a.name.as_str())
            .collect();
        self.err(
            node,
            format!(
                "a `{kind}` shape has no mesh attribute `{}`, which its material reads through \
                 a mesh_attribute texture; lancer reads mesh attributes from PLY files (as \
                 Mitsuba's PLY loader names them): give the shape a PLY file, or the material \
                 another texture",
                names.first().copied().unwrap_or_default()
            ),
        )
    }

    /// The values at each triangle's vertices of the one mesh attribute
    /// `material` reads, from a PLY mesh, as Mitsuba 3.9.1 evaluates them
    /// (`Mesh::eval_attribute`): a vertex attribute at the triangle's
    /// vertices, a face attribute its face's value at all three; one
    /// channel in all three. Refused as Mitsuba refuses them: a name the
    /// file does not have, an attribute of 4 channels (a colour with
    /// alpha), one of 3 channels where one is read (Mitsuba's `eval_1`: a
    /// weight, opacity or roughness).
    fn triangle_attributes(
        &self,
        file_node: Node<'a, 'i>,
        shown: &str,
        ply: &crate::scene::ply::PlyMesh,
        material: u32,
    ) -> Result<(Vec<[Vec3; 3]>, Option<String>)> {
        let mat = &self.materials[material as usize];
        let reads = mat.mesh_attribute_reads();
        let refuse = |reason: String| {
            self.attr_err(
                file_node,
                "value",
                format!("{shown}: material `{}` {reason}", mat.name),
            )
        };
        let name = reads[0].0.name.as_str();
        if let Some((other, _)) = reads.iter().find(|(a, _)| a.name != name) {
            return Err(refuse(format!(
                "reads mesh attributes `{name}` and `{}`; lancer reads one attribute per \
                 material: give the other slot a constant or a bitmap",
                other.name
            )));
        }
        let Some(attr) = ply.attributes.iter().find(|a| a.name == name) else {
            let have: Vec<&str> = ply.attributes.iter().map(|a| a.name.as_str()).collect();
            return Err(refuse(format!(
                "reads the mesh attribute `{name}`, which the file does not have (it has: {}; \
                 Mitsuba refuses it too)",
                if have.is_empty() {
                    String::from("none")
                } else {
                    have.join(", ")
                }
            )));
        };
        if attr.channels != 1 && attr.channels != 3 {
            return Err(refuse(format!(
                "reads the mesh attribute `{name}`, which has {} channels (a colour with \
                 alpha); Mitsuba 3.9.1 evaluates attributes of 1 or 3 channels and refuses it \
                 too: drop the alpha property from the file",
                attr.channels
            )));
        }
        if attr.channels == 3 && reads.iter().any(|&(_, one)| one) {
            return Err(refuse(format!(
                "reads the 3-channel mesh attribute `{name}` as one channel (a weight, an \
                 opacity or a roughness); Mitsuba 3.9.1 reads only 1-channel attributes there \
                 and refuses it too"
            )));
        }
        let warning = attr.integer.then(|| {
            format!(
                "{}:{}: {shown}: the mesh attribute `{name}` is stored as integers, which \
                 Mitsuba 3.9.1 and lancer read as they are (255 is 255, not 1); store \
                 values as floats",
                crate::util::text::cut_path(self.file_of(file_node)),
                self.line(file_node),
            )
        });
        if let Some(bad) = attr.values.iter().find(|v| !v.is_finite()) {
            return Err(refuse(format!(
                "reads the mesh attribute `{name}`, which holds the value {bad}; give finite \
                 values"
            )));
        }
        // A colour above 1 (times its texture's scale) would make the
        // surface reflect more light than it receives
        let most = attr.values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let scale = (reads.iter())
            .filter(|(_, one)| !one)
            .fold(0.0f32, |m, (a, _)| m.max(a.scale.abs()));
        if most * scale > 1.0 {
            return Err(refuse(format!(
                "reads the mesh attribute `{name}` as a colour, and its values reach {most} \
                 (times the texture's scale {scale}): above 1, the surface would reflect more \
                 light than it receives; store colours in [0, 1] (Mitsuba 3.9.1 reads integer \
                 colours as they are: 255 is 255)"
            )));
        }
        let c = attr.channels;
        let value = |i: usize| -> Vec3 {
            let v = &attr.values[c * i..c * i + c];
            if c == 1 {
                Vec3::splat(v[0])
            } else {
                Vec3::new(v[0], v[1], v[2])
            }
        };
        let triangles = ply.mesh.indices.chunks_exact(3).zip(&ply.triangle_faces);
        let values = if attr.per_vertex {
            triangles
                .map(|(t, _)| {
                    [
                        value(t[0] as usize),
                        value(t[1] as usize),
                        value(t[2] as usize),
                    ]
                })
                .collect()
        } else {
            triangles.map(|(_, &f)| [value(f as usize); 3]).collect()
        };
        Ok((values, warning))
    }
}

/// Whether the linear map `m` is a rotation (a mirror allowed) times a
/// uniform scale, within [`RIGID_TOLERANCE`]: its columns of one length
/// and orthogonal.
fn is_similarity(m: &DMat3) -> bool {
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    let k = cols[0].length();
    cols.iter()
        .all(|c| (c.length() - k).abs() <= RIGID_TOLERANCE * k)
        && cols[0].dot(cols[1]).abs() <= RIGID_TOLERANCE * k * k
        && cols[1].dot(cols[2]).abs() <= RIGID_TOLERANCE * k * k
        && cols[0].dot(cols[2]).abs() <= RIGID_TOLERANCE * k * k
}

/// The warnings for meshes that lost degenerate or non-finite triangles
/// (`(where, how many)` per mesh): one each for a few, else one that sums
/// them up and names the first few, so that a scene of hundreds of meshes
/// does not bury its other warnings.
fn dropped_warnings(dropped: &[(String, usize)]) -> Vec<String> {
    const NAMED: usize = 3;
    let line = |(place, n): &(String, usize)| {
        format!("{place}: dropped {n} degenerate or non-finite triangle(s)")
    };
    if dropped.len() <= NAMED {
        return dropped.iter().map(line).collect();
    }
    let total: usize = dropped.iter().map(|d| d.1).sum();
    let first: Vec<String> = dropped[..NAMED].iter().map(line).collect();
    vec![format!(
        "{} meshes lost {total} degenerate or non-finite triangle(s) in all; the first: {}",
        dropped.len(),
        first.join("; ")
    )]
}

#[cfg(test)]
mod dropped_tests {
    use super::dropped_warnings;

    /// A few meshes get a warning each; many get one that sums them up.
    #[test]
    fn many_meshes_that_lost_triangles_get_one_warning() {
        let mesh = |i: usize| (format!("s.xml:{i}: m{i}.ply"), i);
        let few: Vec<_> = (1..=3).map(mesh).collect();
        assert_eq!(
            dropped_warnings(&few),
            (1..=3)
                .map(|i| format!(
                    "s.xml:{i}: m{i}.ply: dropped {i} degenerate or non-finite triangle(s)"
                ))
                .collect::<Vec<_>>()
        );
        let many: Vec<_> = (1..=40).map(mesh).collect();
        let w = dropped_warnings(&many);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with("40 meshes lost 820 degenerate or non-finite triangle(s) in all; the first: s.xml:1: m1.ply: dropped 1")
                && w[0].ends_with("s.xml:3: m3.ply: dropped 3 degenerate or non-finite triangle(s)"),
            "{}",
            w[0]
        );
    }
}
