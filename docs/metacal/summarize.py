"""Table of docs/metacal/run_experiment.sh: per S/N, the plain fit's and metacal's m, c, Q."""
import json
import os
import sys


def row(label, path):
    m = json.load(open(path))
    n = sum(s["used"] for s in m["sets"])
    mean_m = (m["m1"] + m["m2"]) / 2
    m_err = ((m["m1_err"] ** 2 + m["m2_err"] ** 2) ** 0.5) / 2
    return (f"| {label} | {len(m['sets'])} | {n} | {mean_m:+.2e} ± {m_err:.1e} | {m['m1']:+.2e} ± {m['m1_err']:.1e} | "
            f"{m['m2']:+.2e} ± {m['m2_err']:.1e} | {m['c1']:+.2e} ± {m['c1_err']:.1e} | {m['c2']:+.2e} ± {m['c2_err']:.1e} | "
            f"{m['q']:.0f} |")


out = sys.argv[1]
print("| S/N, catalogue | sets | galaxies used | m | m1 | m2 | c1 | c2 (= c+) | Q |")
print("|---|---|---|---|---|---|---|---|---|")
for snr in sys.argv[2:]:
    d = os.path.join(out, f"snr{snr}")
    print(row(f"{snr}, plain fit (uncalibrated)", os.path.join(d, "plain.json")))
    print(row(f"{snr}, metacal", os.path.join(d, "metacal.json")))
