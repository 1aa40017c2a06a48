#!/usr/bin/env python3
"""Writes the opacity image of tests/scenes/mitsuba/mask.xml.

    python3 tools/make_test_mask.py tests/scenes/tex/mask_bars.png

An 8 x 8 one-channel (grey, 8-bit) PNG: vertical bars whose values run
0, 36, 73, ..., 255 from left to right, with the top row inverted. Read
with `raw` true, its values are the opacities (0 to 1 in steps of 1/7);
read without, they would be sRGB-decoded first, which the test's broken
variant checks. Standard library only.
"""

import struct
import sys
import zlib


def png_grey(width, height, rows):
    """A PNG file of 8-bit grey rows (each a list of `width` values)."""

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    raw = b"".join(b"\x00" + bytes(r) for r in rows)
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def main():
    n = 8
    bars = [round(255 * x / (n - 1)) for x in range(n)]
    rows = [list(reversed(bars))] + [bars for _ in range(n - 1)]
    with open(sys.argv[1], "wb") as f:
        f.write(png_grey(n, n, rows))


if __name__ == "__main__":
    main()
