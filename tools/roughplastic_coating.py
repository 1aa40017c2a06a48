#!/usr/bin/env python3
"""Write Mitsuba 3's rough-plastic coating figures as JSON.

Mitsuba's `roughplastic` precomputes, per BSDF, the coating's transmittance
T(mu) at 64 cosines (`m_external_transmittance`) and its internal diffuse
reflectance (`m_internal_reflectance`). Neither is exposed, so this script
reads them back from the BSDF's diffuse lobe (`BSDFContext.component = 1`),
whose value is

    d / (1 - d R) / (pi eta^2) * cos_o * T(cos_i) * T(cos_o)    (nonlinear)

R from the ratio of two diffuse colours at normal incidence, T(1) from
either, then T(mu_k) with the light at the table's own cosines mu_k = k/63
(the first 1e-6), where Mitsuba's interpolation returns the entry itself.
`tests/it/materials.rs` compares lancer's tables (src/gpu/rough_plastic.rs)
with these:

    python3 tools/roughplastic_coating.py > tests/reference/roughplastic_coating.json
"""
import json
import math
import sys

import drjit as dr
import mitsuba as mi

mi.set_variant("scalar_rgb")


def bsdf(dist, alpha, eta, d):
    return mi.load_dict({
        "type": "roughplastic", "distribution": dist, "alpha": alpha,
        "int_ior": eta, "ext_ior": 1.0, "nonlinear": True,
        "diffuse_reflectance": {"type": "rgb", "value": [d, d, d]},
    })


def diffuse(b, cos_i, cos_o):
    ctx = mi.BSDFContext()
    ctx.component = 1
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(dr.sqrt(1 - cos_i * cos_i), 0, cos_i)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    wo = mi.Vector3f(-dr.sqrt(1 - cos_o * cos_o), 0, cos_o)
    return float(b.eval(ctx, si, wo)[0])


out = {"mitsuba": mi.__version__, "coatings": []}
for dist in ["ggx", "beckmann"]:
    for alpha in [0.01, 0.1, 0.3, 1.0]:
        for eta in [1.5, 1.333, 0.8]:
            half, white = bsdf(dist, alpha, eta, 0.5), bsdf(dist, alpha, eta, 1.0)
            q = diffuse(half, 1, 1) / diffuse(white, 1, 1)
            # q = 0.5 (1 - R) / (1 - 0.5 R)
            r = (0.5 - q) / (0.5 - 0.5 * q)
            c = diffuse(white, 1, 1) * (1 - r) * math.pi * eta * eta
            t1 = math.sqrt(c)
            table = []
            for k in range(64):
                mu = max(1e-6, k / 63)
                v = diffuse(white, 1.0, mu)
                table.append(v * (1 - r) * math.pi * eta * eta / (mu * t1))
            out["coatings"].append({
                "distribution": dist, "alpha": alpha, "eta": eta,
                "internal_reflectance": r, "transmittance": table,
            })
json.dump(out, sys.stdout, indent=1)
print()
