#!/usr/bin/env python3
"""Writes the small environment map of tests/scenes/mitsuba/envmap.xml.

    python3 tools/make_test_envmap.py tests/scenes/mitsuba/textures/sky.exr

A 64 x 32 latitude-longitude map (linear RGB, float32 EXR) that shows
at once where a renderer puts up, down, u = 0 and the direction u runs: a
sky brightening towards the top row and varying around the horizon, a
ground below the middle row, darkening downwards and varying around, with
a red patch, and a small bright sun. No texel has a neighbour of the same
value but in the red patch and the sun, so every pixel that sees the map
varies within its footprint. No
two directions mirror each other, so a flipped or turned lookup changes
the image.
"""

import math
import sys

import numpy as np


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    w, h = 64, 32
    img = np.zeros((h, w, 3), dtype=np.float32)
    for y in range(h):
        up = 1.0 - y / (h - 1)
        for x in range(w):
            around = 1.0 + 0.5 * math.sin(2.0 * math.pi * x / w)
            if y < h // 2:
                c = [(0.3 + 0.7 * up) * around, (0.4 + 0.6 * up) * around,
                     (0.6 + 0.9 * up) * around]
            else:
                down = (y - h // 2) / (h // 2)
                shade = (1.0 + 0.3 * math.cos(2.0 * math.pi * x / w)) * (1.0 - 0.4 * down)
                c = [0.25 * shade, 0.2 * shade, 0.15 * shade]
                if 40 <= x < 48:
                    c = [0.8, 0.1, 0.05]
            img[y, x] = c
    img[8:11, 20:23] = [60.0, 55.0, 45.0]
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    mi.Bitmap(img).write(sys.argv[1])


if __name__ == "__main__":
    main()
