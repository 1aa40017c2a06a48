#!/usr/bin/env python3
"""Writes the meshes of tests/scenes/mitsuba/mesh_attribute.xml.

    python3 tools/make_test_attributes.py tests/scenes/mitsuba

Two ASCII PLY files whose values are drawn at random (a fixed seed), so
that a reader that takes an attribute from the wrong vertex or face, or
interpolates it in the wrong order, gives another image:

  attributes_vertex.ply: a UV sphere (12 x 8, tools/make_test_serialized.py's
      `uv_sphere`) with a colour at each vertex
      as `red green blue` floats, which Mitsuba's PLY loader names
      `vertex_color`, and a one-channel `gloss_0` (`vertex_gloss`);
  attributes_face.ply: a wavy sheet (6 x 4 quads, split into triangles)
      with a colour per face as `tint_0 tint_1 tint_2` (`face_tint`) and a
      one-channel `weight_0` (`face_weight`).

Standard library only (and tools/make_test_serialized.py).
"""

import math
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_test_serialized import uv_sphere  # noqa: E402


def write_ply(path, vertex_props, vertices, faces, face_props=(), face_values=()):
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\n")
        f.write("comment written by tools/make_test_attributes.py\n")
        f.write(f"element vertex {len(vertices)}\n")
        for name in vertex_props:
            f.write(f"property float {name}\n")
        f.write(f"element face {len(faces)}\n")
        f.write("property list uchar int vertex_indices\n")
        for name in face_props:
            f.write(f"property float {name}\n")
        f.write("end_header\n")
        for v in vertices:
            f.write(" ".join(f"{x:.6f}" for x in v) + "\n")
        for k, face in enumerate(faces):
            extra = [f"{x:.6f}" for x in face_values[k]] if face_values else []
            f.write(" ".join([str(len(face))] + [str(i) for i in face] + extra) + "\n")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "."
    rng = random.Random(7)

    # A UV sphere of radius 1 about the origin (12 around, 8 rings), the
    # serialized test meshes' own
    vertices, faces = uv_sphere(12, 8)
    rows_out = [v + tuple(rng.uniform(0.05, 0.95) for _ in range(3)) + (rng.uniform(0.0, 1.0),)
                for v in vertices]
    write_ply(os.path.join(out, "attributes_vertex.ply"),
              ["x", "y", "z", "red", "green", "blue", "gloss_0"], rows_out, faces)

    # A wavy sheet in the xy plane, 6 x 4 quads over [-1, 1] x [-0.7, 0.7]
    nx, ny = 6, 4
    grid = []
    for j in range(ny + 1):
        for i in range(nx + 1):
            x, y = -1.0 + 2.0 * i / nx, -0.7 + 1.4 * j / ny
            grid.append((x, y, 0.15 * math.sin(3.0 * x) * math.cos(2.0 * y)))
    at = lambda i, j: j * (nx + 1) + i
    tris = []
    for j in range(ny):
        for i in range(nx):
            tris += [(at(i, j), at(i + 1, j), at(i + 1, j + 1)),
                     (at(i, j), at(i + 1, j + 1), at(i, j + 1))]
    values = [tuple(rng.uniform(0.05, 0.95) for _ in range(3)) + (rng.uniform(0.0, 1.0),)
              for _ in tris]
    write_ply(os.path.join(out, "attributes_face.ply"), ["x", "y", "z"], grid, tris,
              ["tint_0", "tint_1", "tint_2", "weight_0"], values)


if __name__ == "__main__":
    main()
