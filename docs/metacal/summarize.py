"""Tables of docs/metacal/run_experiment.sh: per S/N, the plain fit's and metacal's m and c, from the
shear pairs (half differences and half sums of the +g/-g sets) and from the usual regression over
independent sets (with the GREAT08 Q)."""
import json
import os
import sys


def pm(v, e):
    return f"{v:+.2e} ± {e:.1e}"


def mean_m(d):
    return pm((d["m1"] + d["m2"]) / 2, ((d["m1_err"] ** 2 + d["m2_err"] ** 2) ** 0.5) / 2)


def paired_row(label, m):
    p = m["paired"]
    n = sum(s["used"] for s in m["sets"])
    return (f"| {label} | {p['pairs']} x 2 | {n} | {mean_m(p)} | {pm(p['m1'], p['m1_err'])} | {pm(p['m2'], p['m2_err'])} | "
            f"{pm(p['c1'], p['c1_err'])} | {pm(p['c2'], p['c2_err'])} |")


def sets_row(label, m):
    return (f"| {label} | {len(m['sets'])} | {mean_m(m)} | {pm(m['c1'], m['c1_err'])} | {pm(m['c2'], m['c2_err'])} | "
            f"{m['q']:.0f} |")


out = sys.argv[1]
snrs = sys.argv[2:]
runs = []
for snr in snrs:
    d = os.path.join(out, f"snr{snr}")
    for kind, label in (("plain", "plain fit (uncalibrated)"), ("metacal", "metacal")):
        path = os.path.join(d, f"{kind}.json")
        if os.path.exists(path):
            runs.append((f"{snr}, {label}", json.load(open(path))))
print("Shear pairs: m from (g+ - g-)/2 = (1 + m) g, c from (g+ + g-)/2 (c2 is c+ for this PSF)\n")
print("| S/N, catalogue | sets | galaxies used | m | m1 | m2 | c1 | c2 |")
print("|---|---|---|---|---|---|---|---|")
for label, m in runs:
    if "paired" in m:
        print(paired_row(label, m))
print("\nThe same sets as independent sets (regression g_est = (1 + m) g + c over sets):\n")
print("| S/N, catalogue | sets | m | c1 | c2 | Q |")
print("|---|---|---|---|---|---|")
for label, m in runs:
    print(sets_row(label, m))
