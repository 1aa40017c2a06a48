#!/usr/bin/env python3
"""Benchmark anchor: renders a lancer scene with Mitsuba 3 and times it.

The scene is converted exactly as in tools/mitsuba_reference.py, at the
scene's own [render] settings unless --width, --height, --spp, --max-depth
or --seed override them. Mitsuba's Russian roulette (--rr-depth) and its
sampler (--sampler) must be given: there is no default, so that no run
races at a setting nobody chose. For equal work with lancer, --rr-depth is
lancer's rr_depth (5 by default, as Mitsuba's): see roulette_rule in mitsuba_reference.py.

Two ways to run it:

  one render (default): what one whole process costs. Time the process:

    /usr/bin/time -f "%e s wall" python3 tools/mitsuba_bench.py \\
        scenes/cornell.toml --rr-depth 3 --sampler independent --out /tmp/b.exr

  --warm: render once untimed (another seed), then time a second render in
    the same process, its kernels compiled and cached: the render alone, as
    a user who renders twice sees it.

The log on stderr splits the time: Python imports, the conversion (which
parses and rewrites every OBJ in Python: slow for big meshes, and not
Mitsuba's own cost), Mitsuba's scene load, and the render call(s), each
timed until drjit has finished (dr.sync_thread). --json FILE keeps the
figures and the settings.
"""

import argparse
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_reference as ref  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--rr-depth", type=ref.parse_rr_depth, required=True,
                    help="Mitsuba's Russian roulette starts at this depth "
                         "in surface hits (lancer's rule: 3; Mitsuba's "
                         "default: 5), or off")
    ap.add_argument("--sampler", choices=ref.SAMPLERS, required=True,
                    help="Mitsuba's sampler")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--spp", type=int)
    ap.add_argument("--max-depth", type=int)
    ap.add_argument("--seed", type=int, help="seed of the timed render")
    ap.add_argument("--warm", action="store_true",
                    help="render once untimed first, with another seed")
    ap.add_argument("--out", default=None,
                    help="EXR of the timed render (optional)")
    ap.add_argument("--json", default=None, help="write the figures here")
    ap.add_argument("--variant", default="auto")
    args = ap.parse_args()

    t0 = time.perf_counter()
    variant = args.variant
    llvm = ref.find_libllvm()
    if variant == "auto":
        variant = "llvm_ad_rgb" if llvm else "scalar_rgb"
    if variant.startswith("llvm") and llvm:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", llvm)
    import numpy as np
    import drjit as dr
    import mitsuba as mi
    mi.set_variant(variant)
    t_import = time.perf_counter() - t0

    try:
        scene = ref.load_scene(args.scene)
    except (ref.SceneError, ref.tomllib.TOMLDecodeError, OSError) as e:
        sys.exit(f"error: {args.scene}: {e}")
    R = scene["render"]
    width = args.width or R["width"]
    height = args.height or R["height"]
    spp = args.spp or R["spp"]
    max_depth = args.max_depth if args.max_depth is not None \
        else R["max_depth"]
    seed = args.seed if args.seed is not None else R["seed"]
    warm_seed = (seed + 1000003) & 0xFFFFFFFF
    with tempfile.TemporaryDirectory(prefix="lancer_mi_") as tmp:
        t1 = time.perf_counter()
        try:
            conv = ref.Converter(mi, scene, tmp)
            d = conv.scene_dict(width, height, max_depth, spp,
                                rr_depth=args.rr_depth, sampler=args.sampler)
        except ref.SceneError as e:
            sys.exit(f"error: {args.scene}: {e}")
        t_conv = time.perf_counter() - t1
        t1 = time.perf_counter()
        s = mi.load_dict(d)
        t_load = time.perf_counter() - t1
        try:
            ref.check_sample_count(s, spp, args.sampler)
        except ref.SceneError as e:
            sys.exit(f"error: {e}")

        def render(sd):
            t = time.perf_counter()
            img = mi.render(s, seed=sd)
            dr.sync_thread()
            return img, time.perf_counter() - t

        t_warmup = None
        if args.warm:
            _, t_warmup = render(warm_seed)
        img, t_render = render(seed)
        img = np.array(img)
    if args.out:
        ref.write_exr(mi, args.out, img)
    total = time.perf_counter() - t0
    rule = ref.roulette_rule(args.rr_depth, max_depth)
    which = "render, kernels warm" if args.warm else "render (incl. JIT)"
    warm = f"untimed first render {t_warmup:.3f} s, " if args.warm else ""
    print(f"{variant} (Mitsuba {mi.__version__}, drjit {dr.__version__}, "
          f"{dr.thread_count()} threads): {width}x{height} {spp} spp "
          f"max_depth {max_depth}, sampler {args.sampler}, seed {seed}; "
          f"{rule}", file=sys.stderr)
    print(f"import {t_import:.2f} s, convert {t_conv:.2f} s, load "
          f"{t_load:.2f} s, {warm}{which} {t_render:.3f} s, total "
          f"{total:.2f} s", file=sys.stderr)
    if args.json:
        info = {
            "variant": variant, "mitsuba": mi.__version__,
            "drjit": dr.__version__, "threads": dr.thread_count(),
            "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH"),
            "width": width, "height": height, "spp": spp,
            "max_depth": max_depth, "seed": seed,
            "warm_seed": warm_seed if args.warm else None,
            "sampler": args.sampler,
            "rr_depth": ref.mitsuba_rr_depth(args.rr_depth, max_depth),
            "roulette": rule, "warm": args.warm,
            "seconds_import": t_import, "seconds_convert": t_conv,
            "seconds_load": t_load, "seconds_warmup_render": t_warmup,
            "seconds_render": t_render, "seconds_total": total,
        }
        with open(args.json, "w") as f:
            json.dump(info, f, indent=2)
            f.write("\n")


if __name__ == "__main__":
    main()
