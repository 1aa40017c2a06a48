#!/usr/bin/env python3
"""Writes the test textures of tests/scenes/mitsuba/mask.xml, normalmap.xml
and bumpmap.xml.

    python3 tools/make_test_textures.py tests/scenes/tex

- `mask_bars.png`: an 8 x 8 one-channel (grey, 8-bit) PNG of vertical bars
  whose values run 0, 36, 73, ..., 255 from left to right, the top row
  inverted. Read with `raw` true, its values are the opacities (0 to 1 in
  steps of 1/7); read without, they would be sRGB-decoded first, which the
  test's broken variant checks.
- `normal_waves.png`: a 16 x 16 RGB (8-bit) tangent-space normal map, read
  with `raw` true: at texel (i, j) the normal (0.6 sin(2 pi (i + 1/2) / 8),
  0.45 cos(2 pi (j + 1/2) / 16), 1), normalised, stored as 255 (n + 1) / 2
  rounded. Two waves along u and one along v, so that both tangent
  directions, and their signs, show in the image.
- `bump_ramp.png`: a 16 x 16 one-channel (grey, 8-bit) height map, read
  with `raw` true: 0.2 + 0.15 sin(2 pi (i + 1/2) / 8) + 0.6 (j + 1/2) / 16
  at texel (i, j), times 255, rounded: waves along u on a ramp along v, so
  that the sign of each axis of the gradient shows in the image.

Standard library only.
"""

import math
import struct
import sys
import zlib


def png(width, height, rows, channels):
    """A PNG file of 8-bit rows (each a flat list of width * channels values)."""

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    colour_type = {1: 0, 3: 2}[channels]
    raw = b"".join(b"\x00" + bytes(r) for r in rows)
    header = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def mask_bars():
    n = 8
    bars = [round(255 * x / (n - 1)) for x in range(n)]
    rows = [list(reversed(bars))] + [bars for _ in range(n - 1)]
    return png(n, n, rows, 1)


def normal_waves():
    n = 16
    rows = []
    for j in range(n):
        row = []
        for i in range(n):
            v = (0.6 * math.sin(2 * math.pi * (i + 0.5) / 8),
                 0.45 * math.cos(2 * math.pi * (j + 0.5) / 16), 1.0)
            length = math.sqrt(sum(c * c for c in v))
            row += [round(255 * (c / length + 1) / 2) for c in v]
        rows.append(row)
    return png(n, n, rows, 3)


def bump_ramp():
    n = 16
    rows = [[round(255 * (0.2 + 0.15 * math.sin(2 * math.pi * (i + 0.5) / 8)
                          + 0.6 * (j + 0.5) / n)) for i in range(n)] for j in range(n)]
    return png(n, n, rows, 1)


def main():
    folder = sys.argv[1]
    for name, data in [("mask_bars.png", mask_bars()), ("normal_waves.png", normal_waves()),
                       ("bump_ramp.png", bump_ramp())]:
        with open(f"{folder}/{name}", "wb") as f:
            f.write(data)


if __name__ == "__main__":
    main()
