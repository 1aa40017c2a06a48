#!/usr/bin/env python3
"""Independent reference renders of lancer scenes with Mitsuba 3.

Reads a lancer scene (TOML, docs/scene-format.md, version 1),
converts it to a Mitsuba 3 scene, renders K independent passes of S samples
per pixel each, and writes

    <out>.exr      mean radiance (float32 RGB, channels R, G, B)
    <out>.var.exr  per-pixel variance OF THE MEAN: the sample variance across
                   the K passes divided by K (float32 RGB)
    <out>.json     how it was made (command, spp, variant, runtime, versions)

Example:

    python3 tools/mitsuba_reference.py scenes/cornell.toml \
        --out tests/reference/cornell --width 64 --height 64 \
        --spp-per-pass 4096 --passes 16

Mapping (lancer -> Mitsuba):
  sphere      -> sphere (rotated so that Mitsuba's uv matches lancer's, see
                 sphere_to_world)
  quad        -> two-triangle OBJ, winding kept: edge_u x edge_v is the front
  mesh        -> OBJ re-written per (material, has normals, has uv) group;
                 face_normals = true for faces without vertex normals (lancer
                 then shades with the geometric normal; Mitsuba would
                 otherwise invent smooth normals)
  transform   -> translate * Rz * Ry * Rx * scale, degrees, right-handed
  lambert     -> twosided(diffuse), albedo_texture -> bitmap (bilinear,
                 repeat, sRGB decoded: raw = false)
  mirror      -> twosided(conductor, material none, specular_reflectance)
  dielectric  -> dielectric(int_ior = ior, ext_ior = 1,
                 specular_transmittance = tint); not two-sided
  phong,
  glossy      -> error: Mitsuba has no equivalent BSDF
  emission    -> area emitter (one-sided, front side)
  environment -> constant emitter
  camera      -> perspective (fov_axis y) or thinlens when aperture_radius > 0
  film        -> hdrfilm, box reconstruction filter, rgb, float32
  sampler     -> --sampler (default independent)
  integrator  -> path, same max_depth (1 = emitters seen directly); Russian
                 roulette per --rr-depth, by default off (see roulette_rule)
"""

import argparse
import json
import math
import os
import platform
import shlex
import sys
import tempfile
import time
import tomllib

# --------------------------------------------------------------- LLVM setup
#
# Mitsuba's llvm_* variants JIT-compile through a libLLVM found at run time.
# On Debian bookworm libLLVM 15 is too old (drjit's code generation aborts in
# instruction selection); libllvm19 (apt-get install libllvm19) works.

LLVM_CANDIDATES = [
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-18.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-17.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-16.so",
]


def find_libllvm():
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    if path and os.path.exists(path):
        return path
    for p in LLVM_CANDIDATES:
        if os.path.exists(p):
            return p
    return None


class SceneError(Exception):
    pass


# --------------------------------------------------------- Russian roulette
#
# Mitsuba 3's path integrator (src/integrators/path.cpp) counts `depth` in
# surface hits: after the BSDF sample at the k-th hit it sets depth = k, and
# when depth >= rr_depth it keeps the path with probability
# min(max(throughput) * eta^2, 0.95), eta being the product of the relative
# indices of refraction along the path (1 in air, the ior inside glass).
# lancer (shaders/common/path.glsl) counts segments, the camera ray being
# segment 1: after the BSDF sample at the hit that ends segment k it keeps
# the path, when k >= the scene's render.rr_depth (RenderSettings::rr_depth;
# DEFAULT_RR_DEPTH, 5, in a TOML scene that does not state it), with
# probability min(max(throughput) * ior^2 if the new ray goes into a
# dielectric else 1, 0.95). The k-th hit ends segment k, so the same
# rr_depth on both sides makes both roulettes start at the same vertex with the same
# survival probability (the same eta^2 unless dielectrics nest or touch,
# which the scenes here do not have). Mitsuba's default, rr_depth 5, is
# lancer's default too (TOML), and lancer reads a Mitsuba XML scene's own
# rr_depth, 5 when unstated, as Mitsuba does.

LANCER_DEFAULT_RR_DEPTH = 5  # src/scene/types.rs, DEFAULT_RR_DEPTH
MITSUBA_DEFAULT_RR_DEPTH = 5


def mitsuba_rr_depth(rr_depth, max_depth):
    """The rr_depth to give Mitsuba: rr_depth itself, or for None (roulette
    off) max_depth + 1, a depth no path reaches (depth stops at max_depth).
    The random numbers drawn are the same either way: Mitsuba draws the
    roulette sample at every vertex, used or not."""
    if rr_depth is None:
        return max_depth + 1
    if rr_depth < 1:
        raise SceneError(f"rr_depth {rr_depth}: must be >= 1")
    return rr_depth


def roulette_rule(rr_depth, max_depth):
    """One line that says which roulette Mitsuba runs."""
    if rr_depth is None or rr_depth >= max_depth:
        return ("Mitsuba roulette: off (every path runs to max_depth "
                f"{max_depth} unless it escapes or its throughput is 0)")
    same = (" = lancer's default rr_depth: the same rule as lancer"
            if rr_depth == LANCER_DEFAULT_RR_DEPTH else "")
    default = " (Mitsuba's default)" \
        if rr_depth == MITSUBA_DEFAULT_RR_DEPTH else ""
    return (f"Mitsuba roulette: rr_depth {rr_depth}{default}{same}; from "
            f"the hit that ends segment {rr_depth} (camera ray = segment 1) "
            "on, survival min(max(throughput) * eta^2, 0.95)")


def parse_rr_depth(text):
    """argparse type for --rr-depth: a depth >= 1, or 'off'."""
    if text == "off":
        return None
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: an integer >= 1 or off")
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: an integer >= 1 or off")
    return v


SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal",
            "ldsampler")


def check_sample_count(mscene, spp, sampler):
    """Stop unless Mitsuba's sampler takes exactly spp samples (stratified,
    multijitter, orthogonal and ldsampler round some counts up)."""
    got = mscene.sensors()[0].sampler().sample_count()
    if got != spp:
        raise SceneError(f"sampler {sampler} rounds {spp} samples per pixel "
                         f"to {got}; choose a count it takes as it is")


# ------------------------------------------------------------ scene reading

def _vec3(table, key, where, default=None):
    if key not in table:
        if default is None:
            raise SceneError(f"{where}: missing key '{key}'")
        return list(default)
    v = table[key]
    if (not isinstance(v, list) or len(v) != 3
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                       for x in v)):
        raise SceneError(f"{where}.{key}: expected an array of 3 numbers")
    return [float(x) for x in v]


def _num(table, key, where, default=None, integer=False):
    if key not in table:
        if default is None:
            raise SceneError(f"{where}: missing key '{key}'")
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise SceneError(f"{where}.{key}: expected a number")
    if integer:
        if not isinstance(v, int):
            raise SceneError(f"{where}.{key}: expected an integer")
        return v
    return float(v)


def _keys(table, allowed, where):
    for k in table:
        if k not in allowed:
            raise SceneError(f"{where}: unknown key '{k}'")


def load_scene(path):
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    _keys(doc, {"render", "camera", "environment", "materials", "objects"},
          path)
    base = os.path.dirname(os.path.abspath(path))
    r = doc.get("render")
    c = doc.get("camera")
    if r is None or c is None:
        raise SceneError(f"{path}: needs [render] and [camera]")
    # rr_depth (lancer's roulette start) changes the noise only: Mitsuba's
    # comes from --rr-depth
    _keys(r, {"width", "height", "spp", "max_depth", "seed", "rr_depth"},
          "render")
    _keys(c, {"eye", "look_at", "up", "vfov", "aperture_radius",
              "focus_distance"}, "camera")
    render = {
        "width": _num(r, "width", "render", integer=True),
        "height": _num(r, "height", "render", integer=True),
        "spp": _num(r, "spp", "render", integer=True),
        "max_depth": _num(r, "max_depth", "render", 8, integer=True),
        "seed": _num(r, "seed", "render", 0, integer=True),
    }
    eye = _vec3(c, "eye", "camera")
    look_at = _vec3(c, "look_at", "camera")
    camera = {
        "eye": eye,
        "look_at": look_at,
        "up": _vec3(c, "up", "camera", [0.0, 1.0, 0.0]),
        "vfov": _num(c, "vfov", "camera"),
        "aperture_radius": _num(c, "aperture_radius", "camera", 0.0),
        "focus_distance": _num(c, "focus_distance", "camera",
                               math.dist(eye, look_at)),
    }
    if not 0.0 < camera["vfov"] < 180.0:
        raise SceneError("camera.vfov: must be in (0, 180)")
    env = doc.get("environment", {})
    _keys(env, {"radiance"}, "environment")
    environment = _vec3(env, "radiance", "environment", [0.0, 0.0, 0.0])
    materials = doc.get("materials", {})
    objects = doc.get("objects", [])
    return {"base": base, "render": render, "camera": camera,
            "environment": environment, "materials": materials,
            "objects": objects}


# ----------------------------------------------------------- OBJ and .mtl

def parse_mtl(path):
    """Minimal .mtl reader: name -> dict of the keys docs/scene-format.md maps."""
    mats, cur = {}, None
    base = os.path.dirname(path)
    with open(path, "r", errors="replace") as f:
        for line in f:
            t = line.split()
            if not t or t[0].startswith("#"):
                continue
            if t[0] == "newmtl":
                cur = mats.setdefault(" ".join(t[1:]), {})
            elif cur is None:
                continue
            elif t[0] in ("Kd", "Ks", "Ke", "Tf") and len(t) >= 4:
                cur[t[0]] = [float(x) for x in t[1:4]]
            elif t[0] in ("Ns", "Ni") and len(t) >= 2:
                cur[t[0]] = float(t[1])
            elif t[0] == "illum" and len(t) >= 2:
                cur["illum"] = int(t[1])
            elif t[0] == "map_Kd":
                cur["map_Kd"] = os.path.join(base, t[-1])
    return mats


def mtl_to_material(name, m):
    """The .mtl mapping of docs/scene-format.md, as a lancer material table."""
    illum = m.get("illum")
    out = {}
    if illum == 5:
        out = {"type": "mirror", "reflectance": m.get("Ks", [1.0, 1.0, 1.0])}
    elif illum in (4, 6, 7) and "Ni" in m:
        out = {"type": "dielectric", "ior": m["Ni"],
               "tint": m.get("Tf", [1.0, 1.0, 1.0])}
    elif any(x != 0.0 for x in m.get("Ks", [0.0, 0.0, 0.0])):
        out = {"type": "phong"}  # rejected later: no Mitsuba equivalent
    else:
        out = {"type": "lambert"}
        if "map_Kd" in m:
            out["albedo_texture_abs"] = m["map_Kd"]
        else:
            out["albedo"] = m.get("Kd", [0.0, 0.0, 0.0])
    if "Ke" in m:
        out["emission"] = m["Ke"]
    return out


def parse_obj(path):
    """Reads v/vt/vn/f/usemtl/mtllib; fan-triangulates polygons like tobj."""
    V, VT, VN = [], [], []
    groups = {}  # (material, has_vn, has_vt) -> list of triangles
    mtllibs, mtl = [], None
    base = os.path.dirname(path)

    def idx(s, n):
        i = int(s)
        return i - 1 if i > 0 else n + i

    with open(path, "r", errors="replace") as f:
        for line in f:
            t = line.split()
            if not t or t[0].startswith("#"):
                continue
            if t[0] == "v":
                V.append([float(x) for x in t[1:4]])
            elif t[0] == "vt":
                VT.append([float(x) for x in t[1:3]] + [0.0] * (3 - len(t)))
            elif t[0] == "vn":
                VN.append([float(x) for x in t[1:4]])
            elif t[0] == "usemtl":
                mtl = " ".join(t[1:])
            elif t[0] == "mtllib":
                mtllibs.append(os.path.join(base, " ".join(t[1:])))
            elif t[0] == "f":
                corners = []
                for c in t[1:]:
                    p = c.split("/")
                    vi = idx(p[0], len(V))
                    ti = idx(p[1], len(VT)) if len(p) > 1 and p[1] else None
                    ni = idx(p[2], len(VN)) if len(p) > 2 and p[2] else None
                    corners.append((vi, ti, ni))
                has_vt = all(c[1] is not None for c in corners)
                has_vn = all(c[2] is not None for c in corners)
                key = (mtl, has_vn, has_vt)
                for k in range(1, len(corners) - 1):
                    groups.setdefault(key, []).append(
                        (corners[0], corners[k], corners[k + 1]))
    return {"V": V, "VT": VT, "VN": VN, "groups": groups, "mtllibs": mtllibs}


def write_obj(path, V, VT, VN, tris, has_vt, has_vn):
    """Writes the triangles with their own compact vertex lists."""
    vmap, tmap, nmap = {}, {}, {}
    lines = []

    def get(m, i, arr, tag):
        if i not in m:
            m[i] = len(m) + 1
            lines.append(tag + " " + " ".join(repr(float(x)) for x in arr[i]))
        return m[i]

    faces = []
    for tri in tris:
        fc = []
        for (vi, ti, ni) in tri:
            s = str(get(vmap, vi, V, "v"))
            if has_vt or has_vn:
                s += "/" + (str(get(tmap, ti, [x[:2] for x in VT], "vt"))
                            if has_vt else "")
            if has_vn:
                s += "/" + str(get(nmap, ni, VN, "vn"))
            fc.append(s)
        faces.append("f " + " ".join(fc))
    with open(path, "w") as f:
        f.write("\n".join(lines + faces) + "\n")


# --------------------------------------------------------------- conversion

def to_world(mi, obj, where):
    """translate * Rz * Ry * Rx * scale (degrees, right-handed)."""
    T = mi.ScalarTransform4f
    s = obj.get("scale", 1.0)
    if isinstance(s, (int, float)) and not isinstance(s, bool):
        s = [float(s)] * 3
    else:
        s = _vec3(obj, "scale", where)
    if any(x <= 0.0 for x in s):
        raise SceneError(f"{where}.scale: components must be > 0")
    rx, ry, rz = _vec3(obj, "rotate", where, [0.0, 0.0, 0.0])
    t = _vec3(obj, "translate", where, [0.0, 0.0, 0.0])
    return (T().translate(t) @ T().rotate([0, 0, 1], rz)
            @ T().rotate([0, 1, 0], ry) @ T().rotate([1, 0, 0], rx)
            @ T().scale(s))


def sphere_to_world(mi, center, radius):
    """Mitsuba's sphere has uv = (atan2(y, x) / 2pi mod 1, acos(z) / pi) in
    its local frame, with uv.y = 0 the top row of a bitmap. lancer has
    u = 0.5 + atan2(z, x) / 2pi, v = 0.5 + asin(y) / pi with v = 0 the bottom
    row. The rotation local (x, y, z) -> world (-x, z, y) (det +1) makes
    Mitsuba's v equal lancer's and Mitsuba's u = 1 - lancer's u; the texture
    of a sphere is therefore mirrored left-right (see texture())."""
    T = mi.ScalarTransform4f
    R = mi.ScalarTransform4f([[-1, 0, 0, 0], [0, 0, 1, 0], [0, 1, 0, 0],
                              [0, 0, 0, 1]])
    return T().translate(center) @ R @ T().scale(radius)


class Converter:
    def __init__(self, mi, scene, tmpdir):
        self.mi = mi
        self.scene = scene
        self.tmp = tmpdir
        self.n_files = 0
        self.bitmaps = {}

    def tmpfile(self, stem, ext):
        self.n_files += 1
        return os.path.join(self.tmp, f"{self.n_files:04d}_{stem}.{ext}")

    # -- textures ---------------------------------------------------------
    def texture(self, path, mirror_u):
        """bitmap texture: sRGB-decoded texels (raw = false), bilinear,
        repeat. mirror_u flips the image left-right (spheres)."""
        import numpy as np
        mi = self.mi
        if not os.path.exists(path):
            raise SceneError(f"texture not found: {path}")
        key = (path, mirror_u)
        if key not in self.bitmaps:
            bmp = mi.Bitmap(path)
            if mirror_u:
                arr = np.array(bmp)[:, ::-1].copy()
                srgb = bmp.srgb_gamma()
                bmp = mi.Bitmap(arr, bmp.pixel_format())
                bmp.set_srgb_gamma(srgb)
            self.bitmaps[key] = bmp
        return {"type": "bitmap", "bitmap": self.bitmaps[key],
                "filter_type": "bilinear", "wrap_mode": "repeat",
                "raw": False}

    # -- materials --------------------------------------------------------
    def material(self, name, m, where, on_sphere, tex_base=None):
        """Returns (bsdf dict, emission rgb or None)."""
        if not isinstance(m, dict) or "type" not in m:
            raise SceneError(f"{where}: material needs a 'type'")
        typ = m["type"]
        common = {"type", "emission"}
        emission = _vec3(m, "emission", where, [0.0, 0.0, 0.0])
        if typ == "lambert":
            _keys(m, common | {"albedo", "albedo_texture",
                               "albedo_texture_abs"}, where)
            texs = [k for k in ("albedo_texture", "albedo_texture_abs")
                    if k in m]
            if texs and "albedo" in m:
                raise SceneError(f"{where}: give albedo or albedo_texture, "
                                 "not both")
            if "albedo_texture" in m:
                refl = self.texture(os.path.join(
                    tex_base or self.scene["base"], m["albedo_texture"]),
                    on_sphere)
            elif "albedo_texture_abs" in m:
                refl = self.texture(m["albedo_texture_abs"], on_sphere)
            else:
                refl = {"type": "rgb", "value": _vec3(m, "albedo", where)}
            bsdf = {"type": "twosided",
                    "inner": {"type": "diffuse", "reflectance": refl}}
        elif typ == "mirror":
            _keys(m, common | {"reflectance"}, where)
            bsdf = {"type": "twosided",
                    "inner": {"type": "conductor", "material": "none",
                              "specular_reflectance": {
                                  "type": "rgb",
                                  "value": _vec3(m, "reflectance", where)}}}
        elif typ == "dielectric":
            _keys(m, common | {"ior", "tint"}, where)
            ior = _num(m, "ior", where)
            if ior <= 0:
                raise SceneError(f"{where}.ior: must be > 0")
            # Mitsuba's dielectric scales radiance crossing into the denser
            # side by eta^2 (TransportMode::Radiance), as lancer does; the
            # transmittance multiplies refraction only, never reflection.
            bsdf = {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0,
                    "specular_transmittance": {
                        "type": "rgb",
                        "value": _vec3(m, "tint", where, [1.0, 1.0, 1.0])}}
        elif typ in ("phong", "glossy"):
            raise SceneError(
                f"{where}: material type '{typ}' has no Mitsuba equivalent "
                "(lancer's normalised modified Phong and cone-sampled glossy "
                "reflection are not Mitsuba BSDFs); this tool cannot make a "
                "reference for it")
        else:
            raise SceneError(f"{where}: unknown material type '{typ}'")
        return bsdf, (emission if any(e != 0.0 for e in emission) else None)

    def named_material(self, name, where, on_sphere):
        mats = self.scene["materials"]
        if not isinstance(name, str) or name not in mats:
            raise SceneError(f"{where}.material: no material named {name!r}")
        return self.material(name, mats[name], f"materials.{name}", on_sphere)

    @staticmethod
    def attach(shape, bsdf, emission):
        shape["bsdf"] = bsdf
        if emission is not None:
            shape["emitter"] = {"type": "area", "radiance": {
                "type": "rgb", "value": emission}}
        return shape

    # -- objects ----------------------------------------------------------
    def objects(self):
        mi = self.mi
        out = {}
        for i, o in enumerate(self.scene["objects"]):
            where = f"objects[{i}]"
            typ = o.get("type")
            if typ == "sphere":
                _keys(o, {"type", "center", "radius", "material"}, where)
                r = _num(o, "radius", where)
                if r <= 0:
                    raise SceneError(f"{where}.radius: must be > 0")
                bsdf, em = self.named_material(o.get("material"), where, True)
                out[f"obj{i}"] = self.attach(
                    {"type": "sphere",
                     "to_world": sphere_to_world(
                         mi, _vec3(o, "center", where), r)}, bsdf, em)
            elif typ == "quad":
                _keys(o, {"type", "origin", "edge_u", "edge_v", "material"},
                      where)
                p0 = _vec3(o, "origin", where)
                eu = _vec3(o, "edge_u", where)
                ev = _vec3(o, "edge_v", where)
                p1 = [a + b for a, b in zip(p0, eu)]
                p2 = [a + b + c for a, b, c in zip(p0, eu, ev)]
                p3 = [a + b for a, b in zip(p0, ev)]
                # Triangles (0,1,2), (0,2,3): Mitsuba's face normal
                # (p1-p0) x (p2-p0) = edge_u x edge_v, the front side.
                # uv: (0,0) at origin, (1,0) at +edge_u, (0,1) at +edge_v,
                # written as OBJ vt (Mitsuba flips OBJ v on load, which is
                # what puts v = 0 on the bottom image row).
                path = self.tmpfile(f"quad{i}", "obj")
                write_obj(path, [p0, p1, p2, p3],
                          [[0, 0], [1, 0], [1, 1], [0, 1]], [],
                          [((0, 0, None), (1, 1, None), (2, 2, None)),
                           ((0, 0, None), (2, 2, None), (3, 3, None))],
                          True, False)
                bsdf, em = self.named_material(o.get("material"), where,
                                               False)
                out[f"obj{i}"] = self.attach(
                    {"type": "obj", "filename": path, "face_normals": True},
                    bsdf, em)
            elif typ == "mesh":
                _keys(o, {"type", "file", "material", "translate", "rotate",
                          "scale"}, where)
                if not isinstance(o.get("file"), str):
                    raise SceneError(f"{where}: missing key 'file'")
                fpath = os.path.join(self.scene["base"], o["file"])
                if not os.path.exists(fpath):
                    raise SceneError(f"{where}.file: not found: {fpath}")
                xf = to_world(mi, o, where)
                obj = parse_obj(fpath)
                mtl = {}
                if "material" not in o:
                    for lib in obj["mtllibs"]:
                        mtl.update(parse_mtl(lib))
                for g, ((mname, has_vn, has_vt), tris) in enumerate(
                        sorted(obj["groups"].items(),
                               key=lambda kv: (str(kv[0][0]), kv[0][1],
                                               kv[0][2]))):
                    if "material" in o:
                        bsdf, em = self.named_material(o["material"], where,
                                                       False)
                    else:
                        if mname is None or mname not in mtl:
                            raise SceneError(
                                f"{where}: faces without a material in "
                                f"{fpath} and no 'material' key")
                        bsdf, em = self.material(
                            mname, mtl_to_material(mname, mtl[mname]),
                            f"{fpath}: material {mname}", False)
                    path = self.tmpfile(f"mesh{i}_{g}", "obj")
                    write_obj(path, obj["V"], obj["VT"], obj["VN"], tris,
                              has_vt, has_vn)
                    shape = {"type": "obj", "filename": path,
                             "to_world": xf,
                             # no vertex normals: shade with the geometric
                             # normal as lancer does (Mitsuba would
                             # otherwise compute smooth vertex normals)
                             "face_normals": not has_vn}
                    out[f"obj{i}_{g}"] = self.attach(shape, bsdf, em)
            else:
                raise SceneError(f"{where}: unknown object type {typ!r}")
        return out

    # -- whole scene ------------------------------------------------------
    def scene_dict(self, width, height, max_depth, spp, *, rr_depth,
                   sampler):
        """The Mitsuba scene dict. rr_depth and sampler have no default on
        purpose: a caller says which roulette and which sampler it wants
        (rr_depth None: roulette off, see mitsuba_rr_depth)."""
        mi = self.mi
        cam = self.scene["camera"]
        sensor = {
            "type": "perspective",
            "fov": cam["vfov"],
            "fov_axis": "y",
            "near_clip": 1e-4,
            "far_clip": 1e7,
            "to_world": mi.ScalarTransform4f().look_at(
                origin=cam["eye"], target=cam["look_at"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": width, "height": height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb",
                     "component_format": "float32"},
            "sampler": {"type": sampler, "sample_count": spp},
        }
        if cam["aperture_radius"] > 0.0:
            sensor["type"] = "thinlens"
            sensor["aperture_radius"] = cam["aperture_radius"]
            sensor["focus_distance"] = cam["focus_distance"]
        d = {"type": "scene",
             "integrator": {"type": "path", "max_depth": max_depth,
                            "rr_depth": mitsuba_rr_depth(rr_depth, max_depth),
                            "hide_emitters": False},
             "sensor": sensor}
        env = self.scene["environment"]
        if any(x != 0.0 for x in env):
            d["environment"] = {"type": "constant", "radiance": {
                "type": "rgb", "value": env}}
        d.update(self.objects())
        return d


# -------------------------------------------------------------------- main

def write_exr(mi, path, arr):
    import numpy as np
    bmp = mi.Bitmap(np.ascontiguousarray(arr, dtype=np.float32),
                    mi.Bitmap.PixelFormat.RGB)
    tmp = path + ".tmp.exr"
    bmp.write(tmp)
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--out", required=True,
                    help="output stem: writes STEM.exr, STEM.var.exr, "
                         "STEM.json")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--max-depth", type=int)
    ap.add_argument("--seed", type=int,
                    help="base seed (default: render.seed)")
    ap.add_argument("--spp-per-pass", type=int, default=None,
                    help="samples per pixel of each pass (default: "
                         "render.spp)")
    ap.add_argument("--passes", type=int, default=16,
                    help="independent passes K (>= 2; 16 or more for a "
                         "usable variance)")
    ap.add_argument("--chunk", type=int, default=1 << 21,
                    help="most samples (pixels x spp) per Mitsuba render "
                         "call, to bound memory")
    ap.add_argument("--variant", default="auto",
                    help="Mitsuba variant: auto (llvm_ad_rgb when a libLLVM "
                         ">= 16 is found, else scalar_rgb), or a name")
    ap.add_argument("--threads", type=int, default=0,
                    help="worker threads (0: all cores)")
    ap.add_argument("--png", help="also write a preview PNG (sRGB, clamped)")
    ap.add_argument("--rr-depth", type=parse_rr_depth, default=None,
                    help="Mitsuba's Russian roulette: from this depth in "
                         "surface hits on, or off (default: off; the "
                         "expected image is the same either way)")
    ap.add_argument("--sampler", choices=SAMPLERS, default="independent",
                    help="Mitsuba's sampler (default: independent)")
    args = ap.parse_args()

    try:
        scene = load_scene(args.scene)
    except (SceneError, tomllib.TOMLDecodeError, OSError) as e:
        sys.exit(f"error: {args.scene}: {e}")
    R = scene["render"]
    width = args.width or R["width"]
    height = args.height or R["height"]
    max_depth = args.max_depth if args.max_depth is not None \
        else R["max_depth"]
    seed = args.seed if args.seed is not None else R["seed"]
    spp = args.spp_per_pass or R["spp"]
    K = args.passes
    if K < 2:
        sys.exit("error: --passes must be >= 2 to estimate a variance")

    variant = args.variant
    if variant == "auto":
        llvm = find_libllvm()
        if llvm:
            os.environ["DRJIT_LIBLLVM_PATH"] = llvm
            variant = "llvm_ad_rgb"
        else:
            print("note: no libLLVM >= 16 found (apt-get install libllvm19);"
                  " using the slower scalar_rgb variant", file=sys.stderr)
            variant = "scalar_rgb"
    elif variant.startswith("llvm") and find_libllvm():
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", find_libllvm())

    import numpy as np
    import drjit as dr
    import mitsuba as mi
    mi.set_variant(variant)
    if args.threads > 0:
        dr.set_thread_count(args.threads)

    # Split each pass into render calls of at most --chunk samples.
    per_call = max(1, min(spp, args.chunk // (width * height)))
    calls = [per_call] * (spp // per_call)
    if spp % per_call:
        calls.append(spp % per_call)
        if args.sampler != "independent":
            sys.exit(f"error: --sampler {args.sampler} needs every render "
                     f"call to take the same count: make --chunk a multiple "
                     f"of {width * height} that divides {spp} spp")

    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix="lancer_mi_") as tmp:
        conv = Converter(mi, scene, tmp)
        try:
            sdict = conv.scene_dict(width, height, max_depth, per_call,
                                    rr_depth=args.rr_depth,
                                    sampler=args.sampler)
            mscene = mi.load_dict(sdict)
            check_sample_count(mscene, per_call, args.sampler)
        except SceneError as e:
            sys.exit(f"error: {args.scene}: {e}")
        print(roulette_rule(args.rr_depth, max_depth), file=sys.stderr)
        t_load = time.time() - t0
        sum1 = np.zeros((height, width, 3))
        sum2 = np.zeros((height, width, 3))
        # Every render call gets its own seed; passes never share one.
        call_index = 0
        for k in range(K):
            acc = np.zeros((height, width, 3))
            for n in calls:
                s = (seed * 1000003 + call_index) & 0xFFFFFFFF
                call_index += 1
                img = np.array(mi.render(mscene, spp=n, seed=s),
                               dtype=np.float64)
                acc += img * n
            acc /= spp
            sum1 += acc
            sum2 += acc * acc
            print(f"pass {k + 1}/{K} done, {time.time() - t0:.1f} s",
                  file=sys.stderr, flush=True)
    mean = sum1 / K
    var_pass = np.maximum(sum2 - K * mean * mean, 0.0) / (K - 1)
    var_mean = var_pass / K
    elapsed = time.time() - t0

    if not np.all(np.isfinite(mean)) or not np.all(np.isfinite(var_mean)):
        sys.exit("error: non-finite values in the result")
    out_dir = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(out_dir, exist_ok=True)
    write_exr(mi, args.out + ".exr", mean)
    write_exr(mi, args.out + ".var.exr", var_mean)
    if args.png:
        srgb = np.where(mean <= 0.0031308, 12.92 * mean,
                        1.055 * np.power(np.maximum(mean, 0.0031308),
                                         1 / 2.4) - 0.055)
        png = np.clip(np.round(np.clip(srgb, 0, 1) * 255), 0, 255)
        bmp = mi.Bitmap(png.astype(np.uint8), mi.Bitmap.PixelFormat.RGB)
        bmp.set_srgb_gamma(True)
        bmp.write(args.png)
    info = {
        "scene": os.path.relpath(os.path.abspath(args.scene)),
        "command": "python3 " + " ".join(shlex.quote(a) for a in sys.argv),
        "width": width, "height": height, "max_depth": max_depth,
        "seed": seed, "spp_per_pass": spp, "passes": K,
        "spp_total": spp * K, "variant": variant,
        "sampler": args.sampler,
        "rr_depth": mitsuba_rr_depth(args.rr_depth, max_depth),
        "roulette": roulette_rule(args.rr_depth, max_depth),
        "mitsuba": mi.__version__, "drjit": dr.__version__,
        "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH"),
        "seconds": round(elapsed, 1), "seconds_load": round(t_load, 2),
        "cpus": os.cpu_count(), "machine": platform.machine(),
        "mean_rgb": [float(x) for x in mean.mean(axis=(0, 1))],
        "mean_std_of_mean": float(np.sqrt(var_mean).mean()),
    }
    with open(args.out + ".json", "w") as f:
        json.dump(info, f, indent=2)
        f.write("\n")
    print(json.dumps(info, indent=2))


if __name__ == "__main__":
    main()
