//! The `[[objects]]` of a TOML scene: spheres, quads and meshes turned into
//! spheres and triangles, with the `.mtl` materials of meshes merged into
//! the scene's list.

use super::*;

/// Objects, turned into spheres and triangles, and `.mtl` materials merged
/// into the scene's list.
pub(super) struct Builder<'a> {
    pub(super) ctx: &'a Ctx<'a>,
    pub(super) materials: Vec<Material>,
    pub(super) by_name: HashMap<String, u32>,
    /// (`.mtl` file, material name) -> scene material index.
    pub(super) mtl_index: HashMap<(PathBuf, String), u32>,
    pub(super) spheres: Vec<Sphere>,
    pub(super) triangles: Vec<Triangle>,
    pub(super) warnings: Vec<String>,
    /// Mesh files and material libraries read ([`Scene::files`]).
    pub(super) files: Vec<PathBuf>,
    /// The camera's eye as the device gets it, which spheres must keep clear of.
    pub(super) eye: DVec3,
}

impl Builder<'_> {
    pub(super) fn object(&mut self, i: usize, v: &Val) -> Result<()> {
        let ctx = self.ctx;
        let (mut s, kind) = Section::array_entry(ctx, "objects", i, v, OBJECT_TYPES)?;
        let allowed: &[&str] = match kind {
            "sphere" => &["type", "center", "radius", "material"],
            "quad" => &["type", "origin", "edge_u", "edge_v", "material"],
            "mesh" => &[
                "type",
                "file",
                "material",
                "translate",
                "rotate",
                "scale",
                "smooth_normals",
            ],
            other => {
                let mut reason = format!(
                    "unknown object type `{}`; expected one of: {}",
                    cut(other),
                    OBJECT_TYPES.join(", ")
                );
                if let Some(close) = closest(other, OBJECT_TYPES) {
                    reason += &format!(" (did you mean `{}`?)", cut(close));
                }
                return Err(ctx.err(s.line_of("type"), &s.key("type"), reason));
            }
        };
        s.desc = format!("{} (a {kind})", s.desc);
        s.check_keys(allowed)?;
        let point = "a point [x, y, z]";
        match kind {
            "sphere" => {
                let center = s.req("center", point, |v, k| ctx.vec3(v, k))?;
                let radius = s.req("radius", "a number > 0", |v, k| {
                    let x = ctx.number(v, k)?;
                    if x > 0.0 && (x as f32) > 0.0 {
                        Ok(x as f32)
                    } else {
                        Err(ctx.bad(v, k, format!("must be > 0, got {}", ctx.snippet(v))))
                    }
                })?;
                let material = self.material_ref(&s, true)?.unwrap_or(0);
                let (c, r) = (center.as_vec3().as_dvec3(), radius as f64);
                limits::check_coordinates("the sphere", [c - r, c + r])
                    .map_err(|reason| ctx.err(s.line_of("radius"), &s.key("radius"), reason))?;
                limits::check_sphere_clearance(self.eye, c, r)
                    .map_err(|reason| ctx.err(s.line_of("radius"), &s.key("radius"), reason))?;
                self.spheres.push(Sphere {
                    center: center.as_vec3(),
                    radius,
                    material,
                    mitsuba_frame: None,
                });
            }
            "quad" => self.quad(&s)?,
            _ => self.mesh(&s)?,
        }
        Ok(())
    }

    /// The object's `material` key, resolved; `None` when absent and not
    /// required.
    pub(super) fn material_ref(&self, s: &Section, required: bool) -> Result<Option<u32>> {
        let ctx = self.ctx;
        let Some(v) = s.get("material") else {
            if required {
                return Err(s.missing("material", "the name of a [materials.NAME] table"));
            }
            return Ok(None);
        };
        let key = s.key("material");
        let name = ctx.string(v, &key)?;
        if let Some(&index) = self.by_name.get(name) {
            return Ok(Some(index));
        }
        let mut names: Vec<&str> = self.by_name.keys().map(String::as_str).collect();
        names.sort_unstable();
        let mut reason = if names.is_empty() {
            format!(
                "no material named `{}`: the scene defines no materials; \
                 add a [materials.{}] table",
                cut(name),
                toml_key(name)
            )
        } else {
            format!(
                "no material named `{}`; defined materials: {}",
                cut(name),
                names.iter().map(|n| cut(n)).collect::<Vec<_>>().join(", ")
            )
        };
        if let Some(close) = closest(name, &names) {
            reason += &format!(" (did you mean `{}`?)", cut(close));
        }
        Err(ctx.bad(v, &key, reason))
    }

    pub(super) fn quad(&mut self, s: &Section) -> Result<()> {
        let ctx = self.ctx;
        let origin = s.req("origin", "a point [x, y, z]", |v, k| ctx.vec3(v, k))?;
        let edge_u = s.req("edge_u", "a vector [x, y, z]", |v, k| ctx.vec3(v, k))?;
        let edge_v = s.req("edge_v", "a vector [x, y, z]", |v, k| ctx.vec3(v, k))?;
        let material = self.material_ref(s, true)?.unwrap_or(0);
        limits::check_coordinates(
            "the quad",
            [
                origin,
                origin + edge_u,
                origin + edge_u + edge_v,
                origin + edge_v,
            ],
        )
        .map_err(|reason| ctx.err(s.line_of("origin"), &s.key("origin"), reason))?;
        let pair = quad_triangles(origin, edge_u, edge_v, material)
            .ok_or_else(|| ctx.err(s.line_of("edge_v"), &s.key("edge_v"), ZERO_AREA_QUAD))?;
        self.triangles.extend(pair);
        Ok(())
    }

    pub(super) fn mesh(&mut self, s: &Section) -> Result<()> {
        let ctx = self.ctx;
        let file_key = s.key("file");
        let file_val = s.require("file", "the OBJ file, relative to the scene file")?;
        let file = ctx.string(file_val, &file_key)?;
        let file_line = ctx.line(&file_val.span());
        let fixed = self.material_ref(s, false)?;
        let mut transform = Transform::default();
        if let Some(t) = s.opt("translate", |v, k| ctx.vec3(v, k))? {
            transform.translate = t;
        }
        if let Some(r) = s.opt("rotate", |v, k| ctx.vec3(v, k))? {
            transform.rotate_deg = r;
        }
        if let Some(v) = s.get("scale") {
            let key = s.key("scale");
            let scale = match v.get_ref() {
                DeValue::Array(_) => ctx.vec3(v, &key)?,
                DeValue::Integer(_) | DeValue::Float(_) => DVec3::splat(ctx.number(v, &key)?),
                _ => {
                    return Err(ctx.wrong_type(
                        v,
                        &key,
                        "a number or an array of 3 numbers [x, y, z]",
                    ))
                }
            };
            if scale.min_element() <= 0.0 {
                return Err(ctx.bad(
                    v,
                    &key,
                    format!("every scale component must be > 0, got {}", ctx.snippet(v)),
                ));
            }
            transform.scale = scale;
        }
        if file.is_empty() {
            return Err(ctx.bad(file_val, &file_key, "expected an OBJ file name, got \"\""));
        }
        let smooth = s
            .opt("smooth_normals", |v, k| ctx.boolean(v, k))?
            .unwrap_or(false);
        let resolved = ctx.dir.join(file);
        let loaded = obj::load_mesh(&resolved, &resolved, &transform.affine(), fixed, smooth)
            .map_err(|reason| ctx.err(file_line, &file_key, reason))?;
        self.files.extend(loaded.files.iter().cloned());

        limits::check_coordinates(
            &format!(
                "{} after its transform",
                crate::util::text::cut_path(&resolved)
            ),
            loaded
                .triangles
                .iter()
                .flat_map(|t| t.p.iter().map(|p| p.as_dvec3())),
        )
        .map_err(|reason| ctx.err(file_line, &file_key, reason))?;

        let mut notes = Vec::new();
        if loaded.dropped_non_finite > 0 {
            notes.push(format!(
                "dropped {} triangle(s) with a NaN or infinite vertex",
                loaded.dropped_non_finite
            ));
        }
        if loaded.dropped_degenerate > 0 {
            notes.push(format!(
                "dropped {} degenerate (zero-area) triangle(s)",
                loaded.dropped_degenerate
            ));
        }
        if loaded.bad_normals > 0 {
            notes.push(format!(
                "{} triangle(s) with NaN, infinite or zero vertex normals use the geometric normal",
                loaded.bad_normals
            ));
        }
        if loaded.bad_uvs > 0 {
            notes.push(format!(
                "{} triangle(s) with NaN or infinite texture coordinates have none",
                loaded.bad_uvs
            ));
        }
        if loaded.triangles.is_empty() {
            notes.push(String::from("the mesh has no triangles"));
        }
        let here = format!(
            "{}: {file_key}",
            crate::scene::location(ctx.path, file_line)
        );
        for note in notes {
            self.warnings.push(format!(
                "{here}: {}: {note}",
                crate::util::text::cut_path(&resolved)
            ));
        }
        for note in &loaded.notes {
            self.warnings.push(format!("{here}: {note}"));
        }

        // .mtl materials -> scene materials, deduplicated per (file, name).
        let mut remap = Vec::with_capacity(loaded.materials.len());
        for m in &loaded.materials {
            let id = (m.mtl_path.clone(), m.name.clone());
            let index = match self.mtl_index.get(&id) {
                Some(&index) => index,
                None => {
                    let index = self.materials.len() as u32;
                    let name = self.mtl_material_name(m, file);
                    self.materials.push(Material {
                        name: name.clone(),
                        kind: m.kind.clone(),
                        emission: m.emission,
                        sides: Sides::Both,
                        opacity: None,
                        normal_map: None,
                    });
                    self.mtl_index.insert(id, index);
                    index
                }
            };
            remap.push(index);
        }
        for mut t in loaded.triangles {
            if fixed.is_none() {
                t.material = remap.get(t.material as usize).copied().ok_or_else(|| {
                    ctx.err(
                        file_line,
                        &file_key,
                        "internal error: bad .mtl material index",
                    )
                })?;
            }
            self.triangles.push(t);
        }
        Ok(())
    }

    /// `file.mtl:name`, or a longer form if that is already taken.
    pub(super) fn mtl_material_name(&self, m: &obj::MtlMaterial, obj_file: &str) -> String {
        let taken = |n: &str| self.materials.iter().any(|x| x.name == n);
        let short = format!("{}:{}", m.mtllib, m.name);
        if !taken(&short) {
            return short;
        }
        let dir = Path::new(obj_file).parent().unwrap_or(Path::new(""));
        let long = format!("{}:{}", dir.join(&m.mtllib).display(), m.name);
        if !taken(&long) {
            return long;
        }
        (2..)
            .map(|k| format!("{long}#{k}"))
            .find(|n| !taken(n))
            .unwrap_or(long)
    }
}
