#!/usr/bin/env python3
"""Reference renders of Mitsuba 3 XML scenes, as Mitsuba itself loads them.

Loads SCENE.xml with Mitsuba's own parser (every plugin, default and
property as the file states them), renders K independent passes of S
samples per pixel each, and writes the same three files as
tools/mitsuba_reference.py:

    <out>.exr      mean radiance (float32 RGB, channels R, G, B)
    <out>.var.exr  per-pixel variance OF THE MEAN: the sample variance across
                   the K passes divided by K (float32 RGB)
    <out>.json     how it was made (command, spp, variant, runtime, versions)

Example (a published scene, read where it is, at the size its README gives):

    python3 tools/mitsuba_xml_reference.py \
        ../shared/realscenes/tut_cbox/cbox.xml --out /tmp/cbox \
        --spp-per-pass 64 --passes 16

--width/--height replace the film's size the way `lancer render --width
--height` does (the field of view and everything else stay as written):
the film's `width`/`height` are rewritten in memory, never on disk.
-D NAME=VALUE sets a `<default>` parameter, as `mitsuba -D` does.
"""

import argparse
import json
import os
import platform
import shlex
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mitsuba_reference import find_libllvm, write_exr  # noqa: E402


def set_film_size(root, width, height):
    """Rewrites the film's width and height in the parsed XML tree."""
    films = root.findall("./sensor/film")
    if len(films) != 1:
        sys.exit("error: --width/--height need exactly one <sensor><film>")
    film = films[0]
    for name, value in (("width", width), ("height", height)):
        if value is None:
            continue
        for el in list(film):
            if el.get("name") == name:
                film.remove(el)
        ET.SubElement(film, "integer", name=name, value=str(value))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--out", required=True,
                    help="output stem: writes STEM.exr, STEM.var.exr, "
                         "STEM.json")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("-D", dest="params", action="append", default=[],
                    metavar="NAME=VALUE",
                    help="a <default> parameter of the scene")
    ap.add_argument("--seed", type=int, default=0, help="base seed")
    ap.add_argument("--spp-per-pass", type=int, required=True,
                    help="samples per pixel of each pass")
    ap.add_argument("--passes", type=int, default=16,
                    help="independent passes K (>= 2; 16 or more for a "
                         "usable variance)")
    ap.add_argument("--chunk", type=int, default=1 << 21,
                    help="most samples (pixels x spp) per render call")
    ap.add_argument("--variant", default="auto",
                    help="auto (llvm_ad_rgb with a libLLVM >= 16, else "
                         "scalar_rgb), or a variant name")
    ap.add_argument("--png", help="also write a preview PNG (sRGB, clamped)")
    args = ap.parse_args()
    K = args.passes
    if K < 2:
        sys.exit("error: --passes must be >= 2 to estimate a variance")
    params = {}
    for p in args.params:
        name, sep, value = p.partition("=")
        if not sep:
            sys.exit(f"error: -D {p!r}: expected NAME=VALUE")
        params[name] = value

    variant = args.variant
    llvm = find_libllvm()
    if variant == "auto":
        variant = "llvm_ad_rgb" if llvm else "scalar_rgb"
    if llvm:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", llvm)

    import numpy as np
    import drjit as dr
    import mitsuba as mi
    mi.set_variant(variant)

    scene_path = os.path.abspath(args.scene)
    t0 = time.time()
    if args.width is None and args.height is None:
        mscene = mi.load_file(scene_path, **params)
    else:
        # Rewrite the film size in a copy beside nothing: Mitsuba reads the
        # copy from a temporary folder and finds the scene's files through
        # its file resolver, with the scene's own folder first.
        tree = ET.parse(scene_path)
        set_film_size(tree.getroot(), args.width, args.height)
        with tempfile.TemporaryDirectory(prefix="lancer_mi_xml_") as tmp:
            copy = os.path.join(tmp, os.path.basename(scene_path))
            tree.write(copy)
            mi.Thread.thread().file_resolver().prepend(
                os.path.dirname(scene_path))
            mscene = mi.load_file(copy, **params)
    t_load = time.time() - t0
    film = mscene.sensors()[0].film()
    width, height = (int(x) for x in film.crop_size())
    channels = 3

    spp = args.spp_per_pass
    per_call = max(1, min(spp, args.chunk // (width * height)))
    calls = [per_call] * (spp // per_call)
    if spp % per_call:
        calls.append(spp % per_call)
    sum1 = np.zeros((height, width, channels))
    sum2 = np.zeros((height, width, channels))
    call_index = 0
    for k in range(K):
        acc = np.zeros((height, width, channels))
        for n in calls:
            s = (args.seed * 1000003 + call_index) & 0xFFFFFFFF
            call_index += 1
            img = np.array(mi.render(mscene, spp=n, seed=s), dtype=np.float64)
            acc += img[:, :, :channels] * n
        acc /= spp
        sum1 += acc
        sum2 += acc * acc
        print(f"pass {k + 1}/{K} done, {time.time() - t0:.1f} s",
              file=sys.stderr, flush=True)
    mean = sum1 / K
    var_mean = np.maximum(sum2 - K * mean * mean, 0.0) / (K - 1) / K
    if not np.all(np.isfinite(mean)) or not np.all(np.isfinite(var_mean)):
        sys.exit("error: non-finite values in the result")

    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
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
        "scene": args.scene,
        "command": "python3 " + " ".join(shlex.quote(a) for a in sys.argv),
        "width": width, "height": height, "params": params,
        "seed": args.seed, "spp_per_pass": spp, "passes": K,
        "spp_total": spp * K, "variant": variant,
        "mitsuba": mi.__version__, "drjit": dr.__version__,
        "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH"),
        "seconds": round(time.time() - t0, 1),
        "seconds_load": round(t_load, 2),
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
