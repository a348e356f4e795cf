"""docs/metacal/meds_noise_pairs.sh's helpers.

    python3 docs/metacal/meds_noise_pairs.py negate OUTDIR   # B/meds.fits = 2 F - A (image cutouts)
    python3 docs/metacal/meds_noise_pairs.py table OUTDIR    # the ratios

Ratios are rms over objects of (noise effect on e) / e_err, with a bootstrap sd: plain bd, half
its noise pair's difference; metacal, sqrt 2 x half the A1 - B1 difference (the pixel noise, half the
images' noise power: fixnoise carries the other half) and (A1 - A2) (the fixnoise field, seed pairs;
Var(A1 - A2) = 2 Var_fix), their quadrature mean the total. |z| > 4 counts the tails.
"""
import os
import shutil
import sys

import numpy as np
from astropy.io import fits

# status ok and none of the shear-excluding flags (stampede.shear_excluding_flags)
EXCLUDING = 4 | 16 | 32 | 65536 | 131072 | 262144 | 524288 | 1048576
rng = np.random.default_rng(1)


def negate(out):
    a = fits.open(f"{out}/A/meds.fits")
    f = fits.getdata(f"{out}/F/meds.fits", "image_cutouts").astype(float)
    os.makedirs(f"{out}/B", exist_ok=True)
    shutil.copytree(f"{out}/A/psfex", f"{out}/B/psfex", dirs_exist_ok=True)
    a["image_cutouts"].data[:] = (2 * f - a["image_cutouts"].data.astype(float)).astype(np.float32)
    a.writeto(f"{out}/B/meds.fits", overwrite=True)


def tab(path):
    d = fits.getdata(path, "RESULTS")
    t = {k: np.asarray(d[k], dtype=float) for k in ("id", "e1", "e2", "e1_err", "e2_err", "snr", "flags", "status")}
    t["ok"] = (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0) & np.isfinite(t["e1_err"])
    return t


def align(*ts):
    """The rows of the ids every table has, in one order (the runs are shards of the tile)."""
    ids = ts[0]["id"]
    for t in ts[1:]:
        ids = np.intersect1d(ids, t["id"])
    return [{k: v[np.searchsorted(t["id"], ids)] for k, v in t.items()} for t in ts]


def rms(z):
    boot = [np.sqrt(np.mean(z[rng.integers(0, len(z), len(z))] ** 2)) for _ in range(300)]
    return f"{np.sqrt(np.mean(z ** 2)):.3f} ± {np.std(boot):.3f} | {int(np.sum(np.abs(z) > 4))}"


def table(out):
    print("| case | objects | e1: rms ratio ± sd | \\|z\\| > 4 | e2 | \\|z\\| > 4 | median snr |")
    print("|---|---|---|---|---|---|---|")
    pa, pb = align(tab(f"{out}/plain_A.fits"), tab(f"{out}/plain_B.fits"))
    ok = pa["ok"] & pb["ok"]
    z = [0.5 * (pa[e] - pb[e])[ok] / (0.5 * (pa[e + "_err"] + pb[e + "_err"]))[ok] for e in ("e1", "e2")]
    print(f"| plain bd, noise pairs | {ok.sum()} | {rms(z[0])} | {rms(z[1])} | {np.median(pa['snr'][ok]):.1f} |")
    for model in ("bd", "wmom"):
        a1, b1, a2 = align(*(tab(f"{out}/{model}_{r}.fits") for r in ("A1", "B1", "A2")))
        ok = a1["ok"] & b1["ok"] & a2["ok"]
        err = {e: ((a1[e + "_err"] + b1[e + "_err"] + a2[e + "_err"]) / 3)[ok] for e in ("e1", "e2")}
        pix = [np.sqrt(2) * 0.5 * (a1[e] - b1[e])[ok] / err[e] for e in ("e1", "e2")]
        fix = [(a1[e] - a2[e])[ok] / err[e] for e in ("e1", "e2")]
        snr = f"{np.median(a1['snr'][ok]):.1f}"
        print(f"| metacal {model}, pixel noise (noise pairs) | {ok.sum()} | {rms(pix[0])} | {rms(pix[1])} | {snr} |")
        print(f"| metacal {model}, fixnoise (seed pairs) | {ok.sum()} | {rms(fix[0])} | {rms(fix[1])} | |")
        tot = [np.sqrt(0.5 * (p ** 2 + f ** 2)) for p, f in zip(pix, fix)]
        print(f"| metacal {model}, total | {ok.sum()} | {rms(tot[0])} | {rms(tot[1])} | |")


if __name__ == "__main__":
    {"negate": negate, "table": table}[sys.argv[1]](sys.argv[2])
