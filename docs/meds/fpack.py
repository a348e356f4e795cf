"""docs/meds/fpack.sh's helpers.

    python3 docs/meds/fpack.py splice TILEDIR   # wlossy.fits, ilossy.fits from lossy_unpacked.fits
    python3 docs/meds/fpack.py compare OUTDIR   # the table: each version's e against meds.fits's
"""
import sys

import numpy as np
from astropy.io import fits

# status ok and none of the shear-excluding flags (stampede.shear_excluding_flags)
EXCLUDING = 4 | 16 | 32 | 65536 | 131072 | 262144 | 524288 | 1048576
CASES = [("q0", "fpack -g -q 0 (lossless)"), ("lossy", "fpack default (images and weights quantised)"),
         ("wlossy", "weights quantised, images exact"), ("ilossy", "images quantised, weights exact")]


def splice(tile):
    lossy = fits.open(f"{tile}/lossy_unpacked.fits")
    for name, hdu in (("wlossy", "weight_cutouts"), ("ilossy", "image_cutouts")):
        with fits.open(f"{tile}/meds.fits") as f:
            f[hdu].data[:] = lossy[hdu].data
            f.writeto(f"{tile}/{name}.fits", overwrite=True)
    exact = fits.open(f"{tile}/meds.fits")
    for hdu in ("image_cutouts", "weight_cutouts"):
        a, b = exact[hdu].data.astype(float), lossy[hdu].data.astype(float)
        print(f"{hdu}: rms change {np.sqrt(np.mean((b - a) ** 2)):.3g}, max {np.max(np.abs(b - a)):.3g}, "
              f"rms relative (nonzero pixels) {np.sqrt(np.mean(((b - a)[a != 0] / a[a != 0]) ** 2)):.3g}")


def table(path):
    d = fits.getdata(path, "RESULTS")
    t = {k: np.asarray(d[k], dtype=float) for k in ("e1", "e2", "e1_err", "e2_err", "flags", "status")}
    t["ok"] = (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0)
    return t


def compare(out):
    base = table(f"{out}/fit_meds.fits")
    print("| tile | rows | e bitwise | median \\|Δe\\| | rms Δe | max \\|Δe\\| | rms Δe / e_err | mean Δe |")
    print("|---|---|---|---|---|---|---|---|")
    for name, what in CASES:
        t = table(f"{out}/fit_{name}.fits")
        ok = base["ok"] & t["ok"]
        same = all(np.array_equal(base[k], t[k], equal_nan=True) for k in ("e1", "e2", "e1_err", "e2_err"))
        de = np.concatenate([(t["e1"] - base["e1"])[ok], (t["e2"] - base["e2"])[ok]])
        err = np.concatenate([base["e1_err"][ok], base["e2_err"][ok]])
        print(f"| {what} | {ok.sum()} | {'yes' if same else 'no'} | {np.median(np.abs(de)):.1e} | "
              f"{np.sqrt(np.mean(de ** 2)):.1e} | {np.max(np.abs(de)):.1e} | {np.sqrt(np.mean((de / err) ** 2)):.3f} | "
              f"{np.mean(de):+.1e} |")


if __name__ == "__main__":
    {"splice": splice, "compare": compare}[sys.argv[1]](sys.argv[2])
