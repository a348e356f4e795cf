#!/usr/bin/env python3
"""Summarises docs/solver/run_experiment.sh's fits: per S/N, renderer and solver mode, the share
of fits at the iteration limit, time per fit (mean, median, their ratio, the slowest 5 %'s share),
iterations and evaluations; per pair of modes, how far the fitted e and chi2 differ; and the shear
bias m, c of each mode from `stampede metrics`.   usage: summarize.py OUT_DIR SETS"""
import json
import os
import statistics as st
import subprocess
import sys

out, sets = sys.argv[1], int(sys.argv[2])
root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
stampede = os.path.join(root, "build", "tools", "stampede")


def shear(path):
    """SHEAR1, SHEAR2 from a truth file's primary header (80-character cards)."""
    with open(path, "rb") as f:
        cards = {}
        while True:
            block = f.read(2880)
            if not block:
                break
            for i in range(0, 2880, 80):
                card = block[i:i + 80].decode("ascii", "replace")
                if card.startswith("END"):
                    return cards["SHEAR1"], cards["SHEAR2"]
                if card[8:10] == "= ":
                    cards[card[:8].strip()] = card[10:].split("/")[0].strip()
    raise ValueError(path + ": no END card")


def load(path):
    with open(path) as f:
        header = f.readline()[2:].split()
        rows = [line.split() for line in f if not line.startswith("#")]
    ix = {h: i for i, h in enumerate(header)}
    return [{h: r[ix[h]] for h in ("e1", "e2", "chi2", "n_iter", "n_eval", "status", "time_us")} for r in rows]


print("| S/N | renderer | amplitudes | fits | at max_iterations | mean ms | median ms | mean/median | slowest 5 % share | iterations (mean) | evaluations (mean) |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
pairs = []
metrics = []
paired = []  # (snr, renderer, [(g1, g2, mean de1, mean de2) per set])
for snr in (10, 20, 40):
    d = os.path.join(out, f"snr{snr}")
    for renderer in ("exact", "upsampled"):
        fits = {}
        for mode in ("true", "false"):
            rows, files = [], []
            for k in range(sets):
                p = os.path.join(d, f"fit_{k}_{renderer}_{mode}.txt")
                if os.path.exists(p):
                    rows += load(p)
                    files.append(k)
            if not rows:
                continue
            fits[mode] = rows
            t = sorted(float(r["time_us"]) / 1000 for r in rows)
            top = t[int(0.95 * len(t)):]
            at_limit = sum(1 for r in rows if r["status"] == "1")
            print(f"| {snr} | {renderer} | {'projected' if mode == 'true' else 'joint'} | {len(rows)} | "
                  f"{at_limit} ({100 * at_limit / len(rows):.2f} %) | {st.mean(t):.2f} | {st.median(t):.2f} | "
                  f"{st.mean(t) / st.median(t):.2f} | {sum(top) / sum(t):.2f} | "
                  f"{st.mean(int(r['n_iter']) for r in rows):.1f} | {st.mean(int(r['n_eval']) for r in rows):.1f} |")
            if renderer == "exact" and len(files) >= 2:
                args = [stampede, "metrics"]
                for k in files:
                    args += ["--fit", os.path.join(d, f"fit_{k}_{renderer}_{mode}.fits"), "--truth", os.path.join(d, f"truth_{k}.fits")]
                js = os.path.join(d, f"metrics_{renderer}_{mode}.json")
                subprocess.run(args + ["--json", js], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                with open(js) as f:
                    metrics.append((snr, renderer, mode, json.load(f)))
        if len(fits) == 2 and renderer == "exact":
            per_set = []
            for k in range(sets):
                pa = os.path.join(d, f"fit_{k}_{renderer}_true.txt")
                pb = os.path.join(d, f"fit_{k}_{renderer}_false.txt")
                if not (os.path.exists(pa) and os.path.exists(pb)):
                    continue
                both = [(x, y) for x, y in zip(load(pa), load(pb)) if x["status"] == "0" and y["status"] == "0"]
                g1, g2 = (float(v) for v in shear(os.path.join(d, f"truth_{k}.fits")))
                per_set.append((g1, g2, st.mean(float(x["e1"]) - float(y["e1"]) for x, y in both),
                                st.mean(float(x["e2"]) - float(y["e2"]) for x, y in both)))
            paired.append((snr, renderer, per_set))
        if len(fits) == 2:
            a, b = fits["true"], fits["false"]
            de = [max(abs(float(x["e1"]) - float(y["e1"])), abs(float(x["e2"]) - float(y["e2"]))) for x, y in zip(a, b)]
            dchi = [float(x["chi2"]) - float(y["chi2"]) for x, y in zip(a, b)]
            pairs.append((snr, renderer, len(de), sum(v < 1e-4 for v in de), sum(v < 1e-3 for v in de),
                          sum(c < -1e-3 for c in dchi), sum(c > 1e-3 for c in dchi)))

print()
print("| S/N | renderer | fits | \\|e_projected - e_joint\\| < 1e-4 | < 1e-3 | projected chi2 lower by > 1e-3 | higher by > 1e-3 |")
print("|---|---|---|---|---|---|---|")
for snr, renderer, n, e4, e3, lower, higher in pairs:
    print(f"| {snr} | {renderer} | {n} | {e4} ({100 * e4 / n:.1f} %) | {e3} ({100 * e3 / n:.1f} %) | {lower} | {higher} |")

print()
print("| S/N | amplitudes | m1 | m2 | c1 | c2 | Q |")
print("|---|---|---|---|---|---|---|")
for snr, renderer, mode, m in metrics:
    def fmt(key):
        v, e = m.get(key), m.get(key + "_err")
        return f"{v:+.2e} ± {e:.1e}" if v is not None and e is not None else "-"
    q = m.get("q")
    print(f"| {snr} | {'projected' if mode == 'true' else 'joint'} | {fmt('m1')} | {fmt('m2')} | {fmt('c1')} | {fmt('c2')} | "
          f"{q:.0f} |" if q is not None else "- |")

print()
print("Paired: the projected minus the joint fit's mean e per set (objects ok in both), fitted as")
print("dm g + dc over sets and both components (errors from the fit's residual scatter).")
print()
print("| S/N | sets | dm | dc | largest \\|mean de\\| of a set |")
print("|---|---|---|---|---|")
for snr, renderer, per_set in paired:
    xs = [g for g1, g2, _, _ in per_set for g in (g1, g2)]
    ys = [d for _, _, d1, d2 in per_set for d in (d1, d2)]
    if len(xs) < 4:
        continue
    mx, my = st.mean(xs), st.mean(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    dm = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    dc = my - dm * mx
    scatter = (sum((y - dc - dm * x) ** 2 for x, y in zip(xs, ys)) / (len(xs) - 2)) ** 0.5
    dm_err = scatter / sxx ** 0.5
    dc_err = scatter * (1 / len(xs) + mx * mx / sxx) ** 0.5
    print(f"| {snr} | {len(per_set)} | {dm:+.2e} ± {dm_err:.1e} | {dc:+.2e} ± {dc_err:.1e} | {max(abs(y) for y in ys):.1e} |")
