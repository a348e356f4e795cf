#!/usr/bin/env python3
"""Plots a `stampede ring --figure N --csv FILE` table as PNG (m1 crosses, m2 circles, one panel
per `panel`, one line per `series`), with the upcoming-survey requirement |m| < 4e-3 shaded.
With a second table of the same figure (e.g. `--renderer exact`), each series is drawn from both:
m = (m1 + m2) / 2, solid with crosses for the first table, dotted with circles for the second.

usage: python3 tools/plot_ring.py FILE.csv OUT.png [SECOND.csv [LABEL1 LABEL2]]
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


def read(path):
    rows = list(csv.DictReader(open(path)))
    panels = defaultdict(lambda: defaultdict(list))
    for r in rows:
        panels[r["panel"]][r["series"]].append((float(r["x"]), float(r["m1"]), float(r["m2"])))
    return rows[0]["figure"], panels


def main(path, out, second=None, labels=("upsampled", "exact")):
    figure, panels = read(path)
    other = read(second)[1] if second else None
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(5 * n, 4), squeeze=False)
    for ax, (panel, series) in zip(axes[0], sorted(panels.items())):
        for name, pts in sorted(series.items()):
            pts.sort()
            x = [p[0] for p in pts]
            if other is None:
                line, = ax.plot(x, [p[1] for p in pts], "x-", label=name + " (m1)")
                ax.plot(x, [p[2] for p in pts], "o--", mfc="none", color=line.get_color(), label=name + " (m2)")
                continue
            line, = ax.plot(x, [(p[1] + p[2]) / 2 for p in pts], "x-", label=f"{name} ({labels[0]})")
            q = sorted(other[panel][name])
            ax.plot([p[0] for p in q], [(p[1] + p[2]) / 2 for p in q], "o:", mfc="none", color=line.get_color(),
                    label=f"{name} ({labels[1]})")
        ax.axhspan(-4e-3, 4e-3, color="green", alpha=0.15, lw=0)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(panel)
        ax.set_xlabel(XLABEL.get(figure, "x"))
        ax.set_ylabel("m" if other is None else "m = (m1 + m2) / 2")
        ax.set_ylim(-0.03, 0.03)
        ax.legend(fontsize=6)
    fig.suptitle("im3shape figure %s (stampede, noise-free ring tests)" % figure)
    fig.tight_layout()
    fig.savefig(out, dpi=100)


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4, 6):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], *(sys.argv[3:4]), *([tuple(sys.argv[4:6])] if len(sys.argv) == 6 else []))
