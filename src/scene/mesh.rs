//! A mesh as the OBJ readers give it: the object transform, the cleaned
//! world-space triangles with their counts, and the one function that makes
//! a triangle from its corners, shared by the general loader
//! ([`super::obj`]) and the parallel reader of plain files
//! ([`super::obj_fast`]) so that the two give the same mesh.

use super::types::{MaterialKind, Rgb, Triangle};
use glam::{DAffine3, DMat3, DVec3, Vec2, Vec3};
use std::path::PathBuf;

/// An object transform: `translate * Rz * Ry * Rx * scale`, rotations in
/// degrees, right-handed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Transform {
    /// Translation.
    pub translate: DVec3,
    /// Rotation in degrees about x, then y, then z.
    pub rotate_deg: DVec3,
    /// Scale per axis (every component > 0).
    pub scale: DVec3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform {
            translate: DVec3::ZERO,
            rotate_deg: DVec3::ZERO,
            scale: DVec3::ONE,
        }
    }
}

impl Transform {
    /// The linear part, `Rz * Ry * Rx * scale`.
    pub fn linear(&self) -> DMat3 {
        let r = self.rotate_deg;
        DMat3::from_rotation_z(r.z.to_radians())
            * DMat3::from_rotation_y(r.y.to_radians())
            * DMat3::from_rotation_x(r.x.to_radians())
            * DMat3::from_diagonal(self.scale)
    }

    /// The whole transform as an affine map (`linear() * p + translate`).
    pub fn affine(&self) -> DAffine3 {
        DAffine3::from_mat3_translation(self.linear(), self.translate)
    }
}

/// A `.mtl` material used by a mesh, converted to a scene material.
#[derive(Debug, Clone)]
pub(crate) struct MtlMaterial {
    /// The `.mtl` file on disk.
    pub mtl_path: PathBuf,
    /// The `mtllib` argument as written in the OBJ.
    pub mtllib: String,
    /// The material's name in the `.mtl`.
    pub name: String,
    /// Scattering model.
    pub kind: MaterialKind,
    /// Emission (`Ke`).
    pub emission: Rgb,
}

/// A loaded, transformed and cleaned mesh.
#[derive(Debug, Default)]
pub(crate) struct LoadedMesh {
    /// World-space triangles. `material` is the fixed material index when
    /// one was given, else an index into `materials`.
    pub triangles: Vec<Triangle>,
    /// The `.mtl` materials the faces use (empty with a fixed material).
    pub materials: Vec<MtlMaterial>,
    /// Triangles dropped for a NaN or infinite vertex.
    pub dropped_non_finite: usize,
    /// Triangles dropped for zero area.
    pub dropped_degenerate: usize,
    /// Triangles whose vertex normals were unusable (non-finite or zero).
    pub bad_normals: usize,
    /// Triangles whose texture coordinates were non-finite.
    pub bad_uvs: usize,
    /// Other notes (e.g. `.mtl` materials scaled down to conserve energy).
    pub notes: Vec<String>,
    /// The files read: the mesh, then its `.mtl` libraries.
    pub files: Vec<PathBuf>,
    /// The mesh attribute values of the triangles that carry one
    /// ([`crate::scene::Triangle::attribute`] indexes them).
    pub attributes: Vec<[glam::Vec3; 3]>,
}

/// What became of one triangle of a mesh file.
pub(crate) enum Made {
    /// Dropped: a vertex is NaN or infinite (before or after the transform).
    NonFinite,
    /// Dropped: zero area.
    Degenerate,
    /// Kept, and whether its normals (then dropped) and its texture
    /// coordinates (then dropped) were unusable.
    Kept(Triangle, bool, bool),
}

/// Transforms and checks one triangle given its corners as read: local
/// positions (`None`: the index named nothing, an error), and, when the
/// mesh has them, local normals and texture coordinates (`None`: unusable).
pub(crate) fn make_triangle(
    positions: [Option<DVec3>; 3],
    normals: Option<[Option<DVec3>; 3]>,
    uvs: Option<[Option<[f32; 2]>; 3]>,
    transform: &DAffine3,
    normal_matrix: &DMat3,
    material: u32,
) -> Result<Made, String> {
    let mut p = [Vec3::ZERO; 3];
    for (k, local) in positions.into_iter().enumerate() {
        let local = local.ok_or_else(|| String::from("OBJ face index out of range"))?;
        let world = transform.transform_point3(local).as_vec3();
        if !local.is_finite() || !world.is_finite() {
            return Ok(Made::NonFinite);
        }
        p[k] = world;
    }
    let (a, b, c) = (p[0].as_dvec3(), p[1].as_dvec3(), p[2].as_dvec3());
    let area2 = (b - a).cross(c - a).length_squared();
    if !(area2 > 0.0 && area2.is_finite()) {
        return Ok(Made::Degenerate);
    }
    let (mut n, mut bad_normals) = (None, false);
    if let Some(local) = normals {
        let mut normals = [Vec3::ZERO; 3];
        let mut ok = true;
        for (k, local) in local.into_iter().enumerate() {
            let world = local.map(|local| *normal_matrix * local);
            match world {
                Some(w) if w.is_finite() && w.length_squared() > 0.0 => {
                    let unit = w.normalize().as_vec3();
                    ok &= unit.is_finite();
                    normals[k] = unit;
                }
                _ => ok = false,
            }
        }
        if ok {
            n = Some(normals);
        } else {
            bad_normals = true;
        }
    }
    let (mut uv, mut bad_uvs) = (None, false);
    if let Some(local) = uvs {
        let mut out = [Vec2::ZERO; 3];
        let mut ok = true;
        for (k, t) in local.into_iter().enumerate() {
            match t {
                Some(t) if t[0].is_finite() && t[1].is_finite() => out[k] = Vec2::new(t[0], t[1]),
                _ => ok = false,
            }
        }
        if ok {
            uv = Some(out);
        } else {
            bad_uvs = true;
        }
    }
    Ok(Made::Kept(
        Triangle {
            p,
            n,
            uv,
            material,
            attribute: None,
        },
        bad_normals,
        bad_uvs,
    ))
}
