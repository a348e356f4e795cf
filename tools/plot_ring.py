#!/usr/bin/env python3
"""Plots a `stampede ring --figure N --csv FILE` table as PNG (m1 crosses, m2 circles, one panel
per `panel`, one line per `series`), with the upcoming-survey requirement |m| < 4e-3 shaded.

usage: python3 tools/plot_ring.py FILE.csv OUT.png
Needs Debian's python3-matplotlib; the numbers themselves come from the C++ command.
"""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

XLABEL = {"2": "U1 (upsampling)", "4": "true Sersic index n", "5": "bulge - disc ellipticity",
          "6": "true bulge / disc radius ratio"}


def main(path, out):
    rows = list(csv.DictReader(open(path)))
    figure = rows[0]["figure"]
    panels = defaultdict(lambda: defaultdict(list))
    for r in rows:
        panels[r["panel"]][r["series"]].append((float(r["x"]), float(r["m1"]), float(r["m2"])))
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(5 * n, 4), squeeze=False)
    for ax, (panel, series) in zip(axes[0], sorted(panels.items())):
        for name, pts in sorted(series.items()):
            pts.sort()
            x = [p[0] for p in pts]
            line, = ax.plot(x, [p[1] for p in pts], "x-", label=name + " (m1)")
            ax.plot(x, [p[2] for p in pts], "o--", mfc="none", color=line.get_color(), label=name + " (m2)")
        ax.axhspan(-4e-3, 4e-3, color="green", alpha=0.15, lw=0)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(panel)
        ax.set_xlabel(XLABEL.get(figure, "x"))
        ax.set_ylabel("m")
        ax.set_ylim(-0.03, 0.03)
        ax.legend(fontsize=6)
    fig.suptitle("im3shape figure %s (stampede, noise-free ring tests)" % figure)
    fig.tight_layout()
    fig.savefig(out, dpi=100)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
