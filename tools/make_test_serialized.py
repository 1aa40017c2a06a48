#!/usr/bin/env python3
"""Writes the meshes of tests/scenes/mitsuba/serialized.xml.

    python3 tools/make_test_serialized.py tests/scenes/mitsuba/shapes.serialized

A Mitsuba `serialized` file (version 4, little-endian, each mesh a 4-byte
header and a zlib stream, then the end-of-file table of u64 offsets and the
u32 mesh count; see Mitsuba 3.9.1's src/shapes/serialized.cpp) holding
three meshes, each exercising a different part of the format:

  0. an icosphere (42 vertices, 80 triangles), single precision, no normals:
     the reader must compute smooth normals;
  1. a wavy sheet (a 7 x 5 grid), double precision, with its own vertex
     normals (of length 2, so they must be normalised), texture coordinates
     and vertex colours (which come between the coordinates and the
     triangles, so they must be read past);
  2. a UV sphere (10 x 6), single precision, no normals, with the face
     normals flag 0x0010 set, which Mitsuba 3.9.1 ignores: it too gets
     smooth normals.

Written by this script's own encoder (standard library only), so that
Mitsuba reading the file checks lancer's reader independently of the
encoder in lancer's unit tests.
"""

import math
import struct
import sys
import zlib

HAS_NORMALS = 0x0001
HAS_TEXCOORDS = 0x0002
HAS_COLORS = 0x0008
FACE_NORMALS = 0x0010
SINGLE = 0x1000
DOUBLE = 0x2000


def icosphere():
    t = (1.0 + 5.0 ** 0.5) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
             (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [norm(v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
             (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
             (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    middle = {}

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in middle:
            pa, pb = verts[a], verts[b]
            verts.append(norm(tuple((x + y) / 2 for x, y in zip(pa, pb))))
            middle[key] = len(verts) - 1
        return middle[key]

    out = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    return verts, out


def norm(v):
    n = math.sqrt(sum(x * x for x in v))
    return tuple(x / n for x in v)


def wavy_sheet(nx=7, ny=5):
    """z = 0.15 sin(2.5 x) on [-1, 1] x [-1, 1], with the analytic normals
    (times 2), uv from the corner (0, 0) at (-1, -1), and colours."""
    pos, nrm, uv, col, faces = [], [], [], [], []
    for j in range(ny):
        for i in range(nx):
            u, v = i / (nx - 1), j / (ny - 1)
            x, y = 2 * u - 1, 2 * v - 1
            pos.append((x, y, 0.15 * math.sin(2.5 * x)))
            dz = 0.15 * 2.5 * math.cos(2.5 * x)
            n = norm((-dz, 0.0, 1.0))
            nrm.append(tuple(2 * c for c in n))
            uv.append((u, v))
            col.append((u, v, 0.5))
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            faces += [(a, a + 1, a + nx + 1), (a, a + nx + 1, a + nx)]
    return pos, nrm, uv, col, faces


def uv_sphere(nu=10, nv=6):
    pos = [(0.0, 1.0, 0.0)]
    for j in range(1, nv):
        theta = math.pi * j / nv
        for i in range(nu):
            phi = 2 * math.pi * i / nu
            pos.append((math.sin(theta) * math.cos(phi), math.cos(theta),
                        -math.sin(theta) * math.sin(phi)))
    pos.append((0.0, -1.0, 0.0))
    bottom = len(pos) - 1
    ring = lambda j, i: 1 + (j - 1) * nu + i % nu
    faces = [(0, ring(1, i), ring(1, i + 1)) for i in range(nu)]
    for j in range(1, nv - 1):
        for i in range(nu):
            a, b = ring(j, i), ring(j, i + 1)
            c, d = ring(j + 1, i), ring(j + 1, i + 1)
            faces += [(a, c, d), (a, d, b)]
    faces += [(ring(nv - 1, i), bottom, ring(nv - 1, i + 1)) for i in range(nu)]
    return pos, faces


def stream(flags, name, pos, faces, nrm=None, uv=None, col=None):
    fmt = "<d" if flags & DOUBLE else "<f"
    out = struct.pack("<I", flags) + name.encode() + b"\0"
    out += struct.pack("<QQ", len(pos), len(faces))
    for arr in (pos, nrm, uv, col):
        if arr is not None:
            out += b"".join(struct.pack(fmt, x) for p in arr for x in p)
    out += b"".join(struct.pack("<I", i) for f in faces for i in f)
    return out


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    ico_v, ico_f = icosphere()
    sheet = wavy_sheet()
    sph_v, sph_f = uv_sphere()
    meshes = [
        stream(SINGLE, "icosphere", ico_v, ico_f),
        stream(DOUBLE | HAS_NORMALS | HAS_TEXCOORDS | HAS_COLORS, "sheet",
               sheet[0], sheet[4], nrm=sheet[1], uv=sheet[2], col=sheet[3]),
        stream(SINGLE | FACE_NORMALS, "uv_sphere", sph_v, sph_f),
    ]
    data, offsets = b"", []
    for m in meshes:
        offsets.append(len(data))
        data += struct.pack("<HH", 0x041C, 4) + zlib.compress(m, 9)
    data += b"".join(struct.pack("<Q", o) for o in offsets)
    data += struct.pack("<I", len(meshes))
    with open(sys.argv[1], "wb") as f:
        f.write(data)
    print(f"{sys.argv[1]}: {len(data)} bytes, {len(meshes)} meshes")


if __name__ == "__main__":
    main()
