#!/usr/bin/env python3
"""Our detector (`--detector tree`) against SEP's library (`--detector sep`), object by object
(docs/metadetect.md, "Detection").

1. Catalogues: `stampede sim cells` cells of each kind (grid and random positions of the reference
   shear test, per-object S/N 1e6 and 20; and three bands g, r, i of random S/N 20 cells, each band
   detected alone) detected with stampede.detect() by both: objects matched by position (nearest
   within 0.5 px); the match rate, the largest position difference, and for the objects SEP did not
   deblend the differences in isophotal area, flux and bounding box (the same pixels: none
   expected); for deblended children the area differences (the pixels outside the children's cores
   are drawn at random by SEP, given to the most probable child by ours); flags; and the objects
   unmatched when neither cleans (the cleaning of an object next to a deblended child depends on
   that child's shape and flux over its gathered pixels).
2. Metadetection: `stampede metadetect` of cells of each kind with either detector: the rows of
   each cell and shear type matched by position, their e1, e2 differences.

usage: detector_comparison.py [--cells 200] [--table-cells 50] [--build build] [--work /tmp/detcmp]
prints the tables of docs/metadetect.md.
"""
import argparse
import os
import shutil
import subprocess
import sys

import numpy as np

KINDS = [  # label, sim cells options
    ("grid S/N 1e6", ["--reference", "--layout", "grid"]),
    ("random S/N 1e6", ["--reference", "--layout", "random"]),
    ("grid S/N 20", ["--reference", "--layout", "grid", "--snr", "20"]),
    ("random S/N 20", ["--reference", "--layout", "random", "--snr", "20"]),
]


def match(a, b, radius=0.5):
    """For each object of a, the index of its nearest object of b within radius (-1: none)."""
    if len(b["x"]) == 0:
        return np.full(len(a["x"]), -1), np.full(len(a["x"]), np.inf)
    d = np.hypot(a["x"][:, None] - b["x"][None, :], a["y"][:, None] - b["y"][None, :])
    j = d.argmin(axis=1)
    dist = d[np.arange(len(a["x"])), j]
    return np.where(dist < radius, j, -1), dist


def compare_catalogues(stampede, files, band_hdu=0):
    s = dict(cells=0, sep=0, tree=0, matched=0, dpos=0.0, plain=0, plain_diff=0, merged=0, merged_area_diff=[],
             flag_diff=0, unmatched=[], unclean=0, unclean_diff=0)
    for path in files:
        im = stampede.read_image(path, band_hdu)
        w = stampede.read_image(path, "WEIGHT")
        sigma = 1 / np.sqrt(np.median(w))
        a = stampede.detect(im, sigma, detector="sep")
        b = stampede.detect(im, sigma, detector="tree")
        j, dist = match(a, b)
        back, _ = match(b, a)
        s["cells"] += 1
        s["sep"] += len(a["x"])
        s["tree"] += len(b["x"])
        ok = j >= 0
        s["matched"] += int(ok.sum())
        if ok.any():
            s["dpos"] = max(s["dpos"], float(dist[ok].max()))
        for i in np.where(ok)[0]:
            k = j[i]
            merged = a["sep_flags"][i] & 1
            flags_a, flags_b = a["sep_flags"][i], b["sep_flags"][k]
            if merged:
                flags_a, flags_b = flags_a & ~8, flags_b & ~8  # singular: moments over the gathered pixels
                s["merged"] += 1
                s["merged_area_diff"].append(int(b["isophotal_area"][k]) - int(a["isophotal_area"][i]))
            else:
                s["plain"] += 1
                same = (a["isophotal_area"][i] == b["isophotal_area"][k] and a["xmin"][i] == b["xmin"][k] and
                        a["xmax"][i] == b["xmax"][k] and a["ymin"][i] == b["ymin"][k] and
                        a["ymax"][i] == b["ymax"][k] and
                        abs(a["flux"][i] - b["flux"][k]) <= 1e-6 * abs(a["flux"][i]) + 1e-9)
                s["plain_diff"] += not same
            s["flag_diff"] += int(flags_a != flags_b)
        # Without the cleaning: whether every difference is the cleaning's.
        ua = stampede.detect(im, sigma, detector="sep", clean=False)
        ub = stampede.detect(im, sigma, detector="tree", clean=False)
        uj, _ = match(ua, ub)
        ub_back, _ = match(ub, ua)
        s["unclean"] += len(ua["x"])
        s["unclean_diff"] += int((uj < 0).sum() + (ub_back < 0).sum())
        for i in np.where(~ok)[0]:
            s["unmatched"].append(("sep only", path, float(a["x"][i]), float(a["y"][i]), int(a["sep_flags"][i])))
        for k in np.where(back < 0)[0]:
            s["unmatched"].append(("tree only", path, float(b["x"][k]), float(b["y"][k]), int(b["sep_flags"][k])))
    return s


def compare_tables(stampede, sep_table, tree_table):
    cols = ["cell", "shear_type", "x", "y", "e1", "e2", "flags"]
    a = {k: np.asarray(v) for k, v in stampede.read_table(sep_table, 1, cols).items()}
    b = {k: np.asarray(v) for k, v in stampede.read_table(tree_table, 1, cols).items()}
    out = dict(sep=len(a["x"]), tree=len(b["x"]), matched=0, dpos=0.0, de=0.0)
    key = lambda t, i: (int(t["cell"][i]), str(t["shear_type"][i]).strip())
    groups = {}
    for i in range(len(b["x"])):
        groups.setdefault(key(b, i), []).append(i)
    for i in range(len(a["x"])):
        cand = groups.get(key(a, i), [])
        if not cand:
            continue
        d = np.hypot(b["x"][cand] - a["x"][i], b["y"][cand] - a["y"][i])
        k = cand[int(d.argmin())]
        if d.min() < 0.5:
            out["matched"] += 1
            out["dpos"] = max(out["dpos"], float(d.min()))
            if a["flags"][i] == 0 and b["flags"][k] == 0:
                out["de"] = max(out["de"], float(abs(a["e1"][i] - b["e1"][k])), float(abs(a["e2"][i] - b["e2"][k])))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cells", type=int, default=200)
    p.add_argument("--table-cells", type=int, default=50)
    p.add_argument("--build", default="build")
    p.add_argument("--work", default="/tmp/detcmp")
    a = p.parse_args()
    sys.path.insert(0, os.path.join(a.build, "python"))
    import stampede
    exe = os.path.join(a.build, "tools", "stampede")
    shutil.rmtree(a.work, ignore_errors=True)
    print("| cells | objects SEP / ours | matched | largest position difference (px) | not deblended: "
          "differing pixels | deblended children: area difference median [min, max] | flags differing | "
          "without cleaning: objects unmatched |")
    print("|---|---|---|---|---|---|---|---|")
    kinds = KINDS + [("random S/N 20, band %s" % b, None) for b in "gri"]
    made = {}
    for label, sim in kinds:
        if sim is None:  # the three-band cells, made once
            band = label[-1]
            if "bands" not in made:
                d = os.path.join(a.work, "bands")
                subprocess.run([exe, "sim", "cells", "--out", d, "--cells", str(a.cells), "--bands", "g,r,i",
                                "--reference", "--layout", "random", "--snr", "20", "--seed", "7"],
                               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                made["bands"] = d
            d = os.path.join(made["bands"], band)
        else:
            d = os.path.join(a.work, label.replace(" ", "_").replace("/", ""))
            subprocess.run([exe, "sim", "cells", "--out", d, "--cells", str(a.cells), "--seed", "3"] + sim,
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            made[label] = d
        files = sorted(os.path.join(d, f) for f in os.listdir(d) if f.startswith("cell_") and f.endswith(".fits"))
        s = compare_catalogues(stampede, files)
        md = np.array(s["merged_area_diff"] or [0])
        print("| %s, %d | %d / %d | %.4f | %.1e | %d of %d | %+d [%+d, %+d] of %d | %d | %d of %d |" % (
            label, s["cells"], s["sep"], s["tree"], s["matched"] / max(1, s["sep"]), s["dpos"], s["plain_diff"],
            s["plain"], int(np.median(md)), md.min(), md.max(), s["merged"], s["flag_diff"], s["unclean_diff"],
            s["unclean"]))
        for u in s["unmatched"][:10]:
            print("    %s %s at (%.2f, %.2f) flags %d" % u)
    print()
    print("| metadetect cells | rows SEP / ours | matched | largest position difference (px) | largest e difference |")
    print("|---|---|---|---|---|")
    for label, _ in KINDS:
        d = made[label]
        files = sorted(os.path.join(d, f) for f in os.listdir(d) if f.startswith("cell_"))[:a.table_cells]
        tables = {}
        for det in ("sep", "tree"):
            tables[det] = os.path.join(a.work, "%s_%s.fits" % (label.replace(" ", "_").replace("/", ""), det))
            subprocess.run([exe, "metadetect"] + files + ["-o", tables[det], "--detector", det, "--quiet", "--overwrite"],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t = compare_tables(stampede, tables["sep"], tables["tree"])
        print("| %s, %d | %d / %d | %.4f | %.1e | %.1e |" % (label, len(files), t["sep"], t["tree"],
                                                            t["matched"] / max(1, t["sep"]), t["dpos"], t["de"]))


if __name__ == "__main__":
    main()
