#!/usr/bin/env python3
"""How much any per-pixel allocation of samples can gain on a scene, and how
much lancer's adaptive rule gains, judged on the true error of its sampler.

For each scene it renders, with lancer (fixed spp, the default Sobol sampler):

- one render of VAR_SPP samples per pixel with `--var-out`, from which each
  pixel's per-sample relative variance v (mean over RGB of the sample
  variance over (reference^2 + 0.01), the relMSE's weighting) is taken;
- SEEDS renders of SPP samples per pixel, whose squared error against the
  reference, averaged over the seeds, is each pixel's true relative error e
  at SPP samples under the Sobol sampler.

Then, at equal total samples, it prints the factor by which the image's
relMSE falls against uniform sampling when pixel p gets samples in
proportion to:

- sqrt(v_p), each pixel's own variance: the ideal under the model that
  lancer's allocation assumes (error v_p / n_p), judged by that model;
- sqrt of the mean v of the eight neighbours: lancer's rule
  (src/render/adaptive.rs), judged by the same model;
- the same rule judged on the true error e instead (e_p * SPP / n_p): what
  the rule gains with Sobol samples, whose error is not v / n and differs
  from it by pixel.

The last column is what an adaptive render can gain at equal samples; at
equal time it gains less, since the pixels that get the samples cost more
per sample. Usage (after `pip install -r tools/requirements.txt`):

    tools/adaptive_bounds.py SCENE REFERENCE.exr [--spp 256] [--seeds 8]
        [--var-spp 2048] [--width 64 --height 64] [--lancer PATH]
        [--out out/adaptive-bounds]

REFERENCE may be `render:N`: a lancer render of N spp at seed 2^31, made
once into the output folder, for scenes without a Mitsuba reference.
"""
import argparse
import os
import subprocess
import sys

import numpy as np

import mitsuba as mi

mi.set_variant("scalar_rgb")

REL_OFFSET = 0.01


def read_rgb(path):
    """An EXR's RGB as float64 (height, width, 3)."""
    return np.array(mi.Bitmap(path))[..., :3].astype(np.float64)


def neighbours_mean(x):
    """Mean of each pixel's eight neighbours within the image (not itself),
    as src/render/adaptive.rs computes it."""
    h, w = x.shape
    out = np.empty_like(x)
    for y in range(h):
        for i in range(w):
            block = x[max(y - 1, 0):y + 2, max(i - 1, 0):i + 2]
            n = block.size - 1
            out[y, i] = (block.sum() - x[y, i]) / n if n > 0 else x[y, i]
    return out


def gain(error_at_uniform, shape):
    """relMSE of uniform sampling over that of samples in proportion to
    `shape`, at equal total samples, for per-pixel errors that fall as
    1 / samples."""
    n = shape / shape.mean()
    return error_at_uniform.sum() / (error_at_uniform / np.maximum(n, 1e-300)).sum()


def render(lancer, scene, args, spp, seed, out, var_out=None):
    cmd = [lancer, "render", scene, "--width", str(args.width), "--height", str(args.height),
           "--spp", str(spp), "--seed", str(seed), "--out", out, "-q"]
    if var_out:
        cmd += ["--var-out", var_out]
    subprocess.run(cmd, check=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("reference")
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--var-spp", type=int, default=2048)
    p.add_argument("--width", type=int, default=64)
    p.add_argument("--height", type=int, default=64)
    p.add_argument("--lancer", default=os.environ.get("LANCER_BIN", "lancer"))
    p.add_argument("--out", default="out/adaptive-bounds")
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    name = os.path.splitext(os.path.basename(args.scene))[0]
    base = os.path.join(args.out, name)

    reference = args.reference
    if reference.startswith("render:"):
        reference = f"{base}-reference.exr"
        if not os.path.exists(reference):
            render(args.lancer, args.scene, args, int(args.reference[7:]), 2**31, reference)
    ref = read_rgb(reference)
    weight = 1.0 / (ref * ref + REL_OFFSET)

    # Per-sample relative variance, from a render of its own seed
    render(args.lancer, args.scene, args, args.var_spp, 1000, f"{base}-var.exr", f"{base}-var.var.exr")
    v = (read_rgb(f"{base}-var.var.exr") * args.var_spp * weight).mean(-1)

    # True relative error at SPP, over SEEDS renders
    e = np.zeros_like(v)
    for seed in range(args.seeds):
        out = f"{base}-seed{seed}.exr"
        render(args.lancer, args.scene, args, args.spp, seed, out)
        e += ((read_rgb(out) - ref) ** 2 * weight).mean(-1) / args.seeds

    model = v / args.spp
    rule = np.sqrt(neighbours_mean(v))
    print(f"{args.scene}: relMSE at {args.spp} spp {e.mean():.3e} (v / n predicts "
          f"{model.mean():.3e}, ratio {e.mean() / model.mean():.2f})")
    q = np.quantile(e[model > 0] / model[model > 0], [0.1, 0.5, 0.9])
    print(f"  true error / (v / n) per pixel: {q[0]:.2f}, {q[1]:.2f}, {q[2]:.2f} "
          f"(10%, 50%, 90%)")
    print(f"  equal-samples gain: ideal sqrt(v) {gain(model, np.sqrt(v)):.2f}x, "
          f"neighbours' sqrt(v) {gain(model, rule):.2f}x (by v / n); "
          f"neighbours' sqrt(v) on the true error {gain(e, rule):.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
