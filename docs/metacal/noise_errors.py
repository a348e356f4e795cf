"""Table of docs/metacal/noise_errors.sh's runs: per build, estimator and case, the rms over
objects of the noise's effect on e in units of the stated error (grids: half a noise pair's
difference; MEDS: the two metacal_seed runs' difference, see meds_ratio), and the median metacal
snr against the plain fit's on the same objects.

    python3 docs/metacal/noise_errors.py OUTDIR GRID GRID_BD OBJECTS OBJECTS_BD

Rows usable: status ok, no shear-excluding flag, in every table compared.
"""
import os
import sys

import numpy as np
import stampede

EXCLUDING = int(stampede.shear_excluding_flags)
COLS = ["e1", "e2", "e1_err", "e2_err", "snr", "flags", "status"]


def table(path):
    t = stampede.read_table(path, "RESULTS", COLS)
    t = {k: np.asarray(v, dtype=float) for k, v in t.items()}
    t["ok"] = (t["status"] == 0) & ((t["flags"].astype(np.int64) & EXCLUDING) == 0) & np.isfinite(t["e1_err"])
    return t


def grid_ratio(t):
    """Noise pairs 4q, 4q+2 and 4q+1, 4q+3: half their difference is the noise's effect on e."""
    n = len(t["e1"]) // 4 * 4
    a = np.concatenate([np.arange(0, n, 4), np.arange(1, n, 4)])
    b = a + 2
    ok = t["ok"][a] & t["ok"][b]
    a, b = a[ok], b[ok]
    out = []
    for e in ("e1", "e2"):
        d = 0.5 * (t[e][a] - t[e][b])
        err = 0.5 * (t[e + "_err"][a] + t[e + "_err"][b])
        out.append(np.sqrt(np.mean((d / err) ** 2)))
    return out, len(a)


def meds_ratio(t1, t2):
    """Two metacal_seed runs: e1 - e2 is the two fixnoise fields' difference, Var = 2 Var_fix, and
    the fixnoise field carries half the images' noise power, so Var(diff) = Var(e) (stated^2)."""
    ok = t1["ok"] & t2["ok"]
    out = []
    for e in ("e1", "e2"):
        d = t1[e][ok] - t2[e][ok]
        err = 0.5 * (t1[e + "_err"][ok] + t2[e + "_err"][ok])
        out.append(np.sqrt(np.mean((d / err) ** 2)))
    return out, int(ok.sum())


def main():
    out, grid, grid_bd, objects, objects_bd = sys.argv[1], *sys.argv[2:6]
    print("| build | estimator | case | pairs / objects | rms(noise effect on e1) / e1_err | e2 | median snr metacal | plain fit |")
    print("|---|---|---|---|---|---|---|---|")
    for build in ("before", "after"):
        for model in ("wmom", "bd"):
            g = grid if model == "wmom" else grid_bd
            o = objects if model == "wmom" else objects_bd
            plain_g = table(f"{out}/plain_grid{g}.fits")
            for dil in ("0", "1.5"):
                f = f"{out}/{build}_grid_{model}_dil{dil}.fits"
                if not os.path.exists(f):
                    continue
                t = table(f)
                (r1, r2), n = grid_ratio(t)
                ok = t["ok"] & plain_g["ok"]
                case = f"grid {g}x{g}, S/N 30, " + ("default Gamma" if dil == "0" else "dilation 1.5")
                print(f"| {build} | {model} | {case} | {n} | {r1:.3f} | {r2:.3f} | {np.median(t['snr'][ok]):.1f} | "
                      f"{np.median(plain_g['snr'][ok]):.1f} |")
            f1, f2 = f"{out}/{build}_meds_{model}_seed1.fits", f"{out}/{build}_meds_{model}_seed2.fits"
            if os.path.exists(f1) and os.path.exists(f2):
                t1, t2 = table(f1), table(f2)
                plain_m = table(f"{out}/plain_meds{o}.fits")
                (r1, r2), n = meds_ratio(t1, t2)
                ok = t1["ok"] & plain_m["ok"]
                print(f"| {build} | {model} | sim meds, 4 epochs, S/N 30, metacal_seed 1 vs 2 | {n} | {r1:.3f} | {r2:.3f} | "
                      f"{np.median(t1['snr'][ok]):.1f} | {np.median(plain_m['snr'][ok]):.1f} |")
    # Shapes and responses must not move: only errors and S/N changed.
    shape_cols = ["e1", "e2", "R11", "R12", "R21", "R22", "e1_1p", "e2_1p", "e1_1m", "e2_1m", "e1_2p", "e2_2p",
                  "e1_2m", "e2_2m"]
    for name in sorted(os.listdir(out)):
        if not name.startswith("after_") or not os.path.exists(f"{out}/before_{name[6:]}"):
            continue
        a = stampede.read_table(f"{out}/{name}", "RESULTS", shape_cols)
        b = stampede.read_table(f"{out}/before_{name[6:]}", "RESULTS", shape_cols)
        same = all(np.array_equal(np.asarray(a[c]), np.asarray(b[c]), equal_nan=True) for c in shape_cols)
        print(f"{name[6:]}: e, R and the sheared e before and after {'bitwise identical' if same else 'DIFFER'}")


if __name__ == "__main__":
    main()
