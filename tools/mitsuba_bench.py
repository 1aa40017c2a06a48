#!/usr/bin/env python3
"""Benchmark anchor: renders a lancer scene once with Mitsuba 3 at the
scene's own settings (width, height, spp, max_depth) and writes an EXR.

Time the whole process:

    /usr/bin/time -f "%e s wall %U s user" \
        python3 tools/mitsuba_bench.py scenes/cornell.toml --out /tmp/bench.exr

The scene is converted exactly as in tools/mitsuba_reference.py. The log
line on stderr splits the time: Python imports, the conversion (which
parses and rewrites every OBJ in Python: slow for big meshes, and not
Mitsuba's own cost), Mitsuba's scene load, and the render with its JIT.
"""

import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_reference as ref  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--out", default=None, help="EXR to write (optional)")
    ap.add_argument("--variant", default="auto")
    args = ap.parse_args()

    t0 = time.time()
    variant = args.variant
    llvm = ref.find_libllvm()
    if variant == "auto":
        variant = "llvm_ad_rgb" if llvm else "scalar_rgb"
    if variant.startswith("llvm") and llvm:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", llvm)
    import numpy as np
    import mitsuba as mi
    mi.set_variant(variant)
    t_import = time.time() - t0

    scene = ref.load_scene(args.scene)
    R = scene["render"]
    with tempfile.TemporaryDirectory(prefix="lancer_mi_") as tmp:
        t_conv = time.time()
        conv = ref.Converter(mi, scene, tmp)
        d = conv.scene_dict(R["width"], R["height"], R["max_depth"], R["spp"])
        t_conv = time.time() - t_conv
        t1 = time.time()
        s = mi.load_dict(d)
        t_load = time.time() - t1
        t2 = time.time()
        img = np.array(mi.render(s, spp=R["spp"], seed=R["seed"]))
        t_render = time.time() - t2
    if args.out:
        ref.write_exr(mi, args.out, img)
    print(f"{variant}: {R['width']}x{R['height']} {R['spp']} spp "
          f"max_depth {R['max_depth']}: import {t_import:.2f} s, convert "
          f"{t_conv:.2f} s, load "
          f"{t_load:.2f} s, render (incl. JIT) {t_render:.2f} s, total "
          f"{time.time() - t0:.2f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
