"""Must-show 2 of issue 29 split by the fitted |e|: the default (surrogate, then exact) fit against
the all-exact one, within 0.01 sigma_e, over all objects and over those with |e| below a cut, and
where the objects over it are. usage: by_ellipticity.py WORK_DIR (run_experiment.sh's work dir,
or run_eps4_experiment.sh's)."""
import sys

import numpy as np

from fit_table import table

work = sys.argv[1]
fast, exact = table(f"{work}/fit_true.txt"), table(f"{work}/fit_false.txt")
ok = exact["status"] == 0
sigma = np.minimum(exact["e1_err"], exact["e2_err"])
ratio = np.maximum(np.abs(fast["e1"] - exact["e1"]), np.abs(fast["e2"] - exact["e2"])) / sigma
e = np.hypot(exact["e1"], exact["e2"])
over = ok & (ratio > 0.01)
dlnl = fast["likelihood"] - exact["likelihood"]
print("| objects | count | within 0.01 sigma_e |")
print("|---|---|---|")
for label, sel in [("all, status ok", ok), ("\\|e\\| < 0.9", ok & (e < 0.9)), ("\\|e\\| < 0.8", ok & (e < 0.8)),
                   ("flags = 0", ok & (exact["flags"] == 0))]:
    print(f"| {label} | {sel.sum()} | {100 * (ratio[sel] <= 0.01).mean():.3f} % |")
print()
print(f"Over 0.01 sigma_e: {over.sum()}; their median |e| {np.median(e[over]):.3f}, median radius "
      f"{np.median(exact['radius'][over]):.3f} px, median exact iterations {np.median(exact['n_iter'][over]):.0f} "
      f"(all objects: {np.median(exact['n_iter'][ok]):.0f}); the default's end has the higher likelihood "
      f"{(dlnl[over] > 0).sum()} times, |d lnL| > 0.01 {(np.abs(dlnl[over]) > 0.01).sum()} times.")
