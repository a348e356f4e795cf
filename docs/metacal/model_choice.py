"""Summarises docs/metacal/model_choice.sh: per metacal model, the response's distribution, the
shear noise per object, m and c from the shear pairs, and the cost, as a markdown table.

    model_choice.py OUTDIR MODEL...   (needs `import stampede`: PYTHONPATH=build/python)
"""
import glob
import json
import math
import sys

import numpy as np

import stampede


def main(out, models):
    rows = []
    for model in models:
        tables = [stampede.read_results(f) for f in sorted(glob.glob(f"{out}/{model}/fit_*.fits"))]
        t = np.concatenate(tables)
        usable = (t["status"] == 0) & ((t["flags"] & stampede.shear_excluding_flags) == 0)
        r = {c: t[c][usable] for c in ("R11", "R22", "e1", "e2")}
        m = json.load(open(f"{out}/{model}/metrics.json"))["paired"]
        mean_r = 0.5 * (r["R11"].mean() + r["R22"].mean())
        # The shear noise per object: sigma_e / <R> (one component), and what one object weighs in
        # the paired m's error: sigma_m sqrt(N).
        sigma_g = 0.5 * (r["e1"].std() / r["R11"].mean() + r["e2"].std() / r["R22"].mean())
        n = int(usable.sum())
        # The response's core and its tail: the width of its middle half (as a Gaussian's sigma) and
        # the fraction of objects more than 3 from 1 (which set sd R).
        q1, q3 = np.percentile(r["R11"], [25, 75])
        core = (q3 - q1) / 1.349
        tail = float(np.mean(np.abs(np.concatenate([r["R11"], r["R22"]]) - 1) > 3))
        rows.append((model, n, len(t) - n, r["R11"].mean(), r["R22"].mean(), r["R11"].std(), r["R22"].std(),
                     np.percentile(r["R11"], 1), np.percentile(r["R11"], 99), sigma_g,
                     m["m1"], m["m1_err"], m["m2"], m["m2_err"], m["c1"], m["c1_err"], m["c2"], m["c2_err"],
                     m["m1_err"] * math.sqrt(n), m["m2_err"] * math.sqrt(n), np.median(t["time_us"]) * 1e-3, core, tail))
    print("| metacal_model | objects used (excluded) | <R11> | <R22> | sd R11 | sd R22 | R11 IQR/1.349 | |R-1| > 3 | "
          "R11 1st-99th % | sigma_e/<R> | m1 | m2 | c1 | c2 | sigma_m1, sigma_m2 x sqrt(N) | ms per object (median time_us) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for x in rows:
        print(f"| {x[0]} | {x[1]} ({x[2]}) | {x[3]:.3f} | {x[4]:.3f} | {x[5]:.3f} | {x[6]:.3f} | {x[21]:.3f} | {x[22]:.1%} "
              f"| {x[7]:+.2f} … {x[8]:+.2f} | {x[9]:.3f} | {x[10]:+.2e} ± {x[11]:.1e} | {x[12]:+.2e} ± {x[13]:.1e} "
              f"| {x[14]:+.1e} ± {x[15]:.1e} | {x[16]:+.1e} ± {x[17]:.1e} | {x[18]:.1f}, {x[19]:.1f} | {x[20]:.1f} |")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
