"""Compares the surrogate fit's text table with the all-exact one's (run_experiment.sh)."""
import sys

import numpy as np

from fit_table import table

work = sys.argv[1]
fast, exact = table(f"{work}/fit_true.txt"), table(f"{work}/fit_false.txt")
ok = exact["status"] == 0
sigma = np.minimum(exact["e1_err"], exact["e2_err"])
de = np.maximum(np.abs(fast["e1"] - exact["e1"]), np.abs(fast["e2"] - exact["e2"]))
ratio = de[ok] / sigma[ok]
times = {m: open(f"{work}/time_{m}").read().split() for m in ("true", "false")}
n = len(exact["e1"])
print("| quantity | value |")
print("|---|---|")
print(f"| objects | {n} ({ok.sum()} status ok in the all-exact fit) |")
print(f"| same status | {(fast['status'] == exact['status']).sum()} of {n} |")
print(f"| \\|de\\| / sigma_e <= 0.01 | {(ratio <= 0.01).sum()} of {ok.sum()} ({100 * (ratio <= 0.01).mean():.2f} %) |")
print(f"| \\|de\\| / sigma_e median, 99.9th percentile, max | {np.median(ratio):.2e}, {np.percentile(ratio, 99.9):.2e}, {ratio.max():.2e} |")
print(f"| whole process, 2 threads: surrogate / all exact | {times['true'][0]} s / {times['false'][0]} s (CPU {times['true'][1]} / {times['false'][1]} s) |")

mu = table(f"{work}/fit_mu.txt")
de_mu = np.maximum(np.abs(mu["e1"] - exact["e1"]), np.abs(mu["e2"] - exact["e2"]))[ok] / sigma[ok]
print(f"| all exact, LM_INIT_MU 2e-3 against 1e-3: \\|de\\| / sigma_e <= 0.01 | {(de_mu <= 0.01).sum()} of {ok.sum()} ({100 * (de_mu <= 0.01).mean():.2f} %); same status {(mu['status'] == exact['status']).sum()} |")
print(f"| objects over 0.01 sigma_e in both comparisons | {((ratio > 0.01) & (de_mu > 0.01)).sum()} |")
