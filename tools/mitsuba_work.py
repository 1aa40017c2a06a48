#!/usr/bin/env python3
"""Work per sample under Mitsuba's Russian roulette: path segments traced.

Converts a lancer scene as tools/mitsuba_reference.py does and follows
camera paths through Mitsuba's own scene (its ray_intersect, its BSDFs'
sample), stopping them as Mitsuba 3's path integrator does
(src/integrators/path.cpp): at max_depth, on a miss, at zero throughput,
and by roulette once depth (surface hits so far) >= rr_depth, with
survival min(max(throughput) * eta^2, 0.95). It counts the rays traced
(camera ray and continuation rays, not shadow rays) and prints them per
sample for each rr_depth asked. `lancer render --stats-json` counts the
same for lancer (rays_per_bounce, "intersect"); bench/vs_mitsuba.sh prints
both, so that "equal work per sample" is a measured statement, not a claim.

This is a check, not Mitsuba's integrator: it leaves out emitter sampling
and the radiance, which do not decide where a path stops.

    python3 tools/mitsuba_work.py scenes/cornell.toml --rr-depth 3 5 off
"""

import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_reference as ref  # noqa: E402


def segments_per_sample(mi, dr, s, width, height, spp, max_depth, rr_depth,
                        seed):
    """Mean number of rays a camera path traces under Mitsuba's rules."""
    rrd = ref.mitsuba_rr_depth(rr_depth, max_depth)
    sensor = s.sensors()[0]
    sampler = sensor.sampler().clone()
    n = width * height * spp
    sampler.seed(seed, n)
    pixel = dr.arange(mi.UInt32, n) // spp
    film = (mi.Point2f(mi.Float(pixel % width), mi.Float(pixel // width))
            + sampler.next_2d()) / mi.ScalarVector2f(width, height)
    ray, _ = sensor.sample_ray(0.0, 0.5, film, sampler.next_2d())
    throughput = dr.full(mi.Spectrum, 1.0, n)
    eta = dr.full(mi.Float, 1.0, n)
    depth = dr.zeros(mi.UInt32, n)
    active = dr.full(mi.Bool, True, n)
    ctx = mi.BSDFContext()
    rays = 0
    for _ in range(max_depth):
        rays += int(dr.count(active)[0])
        si = s.ray_intersect(ray, active)
        active_next = active & (depth + 1 < max_depth) & si.is_valid()
        bs, weight = si.bsdf(ray).sample(ctx, si, sampler.next_1d(),
                                         sampler.next_2d(), active_next)
        throughput[active_next] *= weight
        eta[active_next] *= bs.eta
        depth[active & si.is_valid()] += 1
        t_max = dr.max(throughput)
        survive = dr.minimum(t_max * eta * eta, 0.95)
        roulette = depth >= rrd
        kept = sampler.next_1d() < survive
        throughput[roulette] *= dr.rcp(survive)
        active = active_next & (~roulette | kept) & (t_max != 0)
        ray = si.spawn_ray(si.to_world(bs.wo))
        dr.eval(ray, throughput, eta, depth, active)
        if not dr.any(active)[0]:
            break
    return rays / n


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--rr-depth", type=ref.parse_rr_depth, nargs="+",
                    required=True, help="one or more rr_depth values, or off")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--spp", type=int, default=16,
                    help="paths per pixel to count (default 16)")
    ap.add_argument("--max-depth", type=int)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    llvm = ref.find_libllvm()
    if not llvm:
        sys.exit("error: needs the llvm_ad_rgb variant: no libLLVM >= 16 "
                 "found (tools/README.md)")
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", llvm)
    import drjit as dr
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    try:
        scene = ref.load_scene(args.scene)
    except (ref.SceneError, ref.tomllib.TOMLDecodeError, OSError) as e:
        sys.exit(f"error: {args.scene}: {e}")
    R = scene["render"]
    width = args.width or R["width"]
    height = args.height or R["height"]
    max_depth = args.max_depth if args.max_depth is not None \
        else R["max_depth"]
    with tempfile.TemporaryDirectory(prefix="lancer_mi_") as tmp:
        try:
            conv = ref.Converter(mi, scene, tmp)
            # rr_depth is the loop's own; the dict's is not used here
            d = conv.scene_dict(width, height, max_depth, args.spp,
                                rr_depth=None, sampler="independent")
        except ref.SceneError as e:
            sys.exit(f"error: {args.scene}: {e}")
        s = mi.load_dict(d)
        for rr in args.rr_depth:
            per = segments_per_sample(mi, dr, s, width, height, args.spp,
                                      max_depth, rr, args.seed)
            name = "off" if rr is None else str(rr)
            print(f"Mitsuba rule, rr_depth {name}: {per:.3f} path segments "
                  f"per sample ({width}x{height}, {args.spp} spp, max_depth "
                  f"{max_depth}, seed {args.seed})")


if __name__ == "__main__":
    main()
