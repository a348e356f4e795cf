#!/usr/bin/env python3
"""Markdown table of the calibration experiment from `stampede metrics --json` outputs.

usage: table.py LIST
LIST: lines 'SNR uncalibrated.json calibrated.json [per_object.json [matched.json]]' (run_experiment.sh;
matched.json: population-calibrated with a table measured at that S/N itself).
"""
import json
import sys

PAPER = {  # im3shape paper, GREAT08 RealNoise fiducial branch (tables C1-C2): I3-U / I3
    "20": "I3-U m = 3.76e-2, Q = 129; I3 m = 1.53e-2, Q = 817",
}


def fmt(v, e=None):
    if v is None:
        return "n/a"
    return f"{v:+.2e}" if e is None else f"{v:+.2e} ± {e:.1e}"


def row(label, d):
    """The set-based row, or with shear pairs (d["paired"]) the paired estimate of the same sets."""
    if "paired" in d:
        p = d["paired"]
        m = 0.5 * (p["m1"] + p["m2"])
        # m1 and m2 share galaxies: their errors added as if independent (not a joint bootstrap).
        m_err = 0.5 * (p["m1_err"] ** 2 + p["m2_err"] ** 2) ** 0.5
        used = sum(s["used"] for s in d["sets"])
        excluded = sum(s["excluded"] for s in d["sets"])
        size = f"{p['pairs']} pairs x 2 x {(used + excluded) // len(d['sets'])}"
        return (f"| {label} | {size} | {fmt(m, m_err)} | {fmt(p['m1'], p['m1_err'])} | {fmt(p['m2'], p['m2_err'])} | "
                f"{fmt(p['c1'], p['c1_err'])} | {fmt(p['c2'], p['c2_err'])} | {fmt(p['c_plus'])} | n/a | "
                f"{used} / {excluded} |"), m, m_err
    m = 0.5 * (d["m1"] + d["m2"])
    m_err = 0.5 * (d["m1_err"] ** 2 + d["m2_err"] ** 2) ** 0.5
    used = sum(s["used"] for s in d["sets"])
    excluded = sum(s["excluded"] for s in d["sets"])
    size = f"{len(d['sets'])} x {(used + excluded) // len(d['sets'])}"
    return (f"| {label} | {size} | {fmt(m, m_err)} | {fmt(d['m1'], d['m1_err'])} | {fmt(d['m2'], d['m2_err'])} | "
            f"{fmt(d['c1'], d['c1_err'])} | {fmt(d['c2'], d['c2_err'])} | {fmt(d['c_plus'])} | {d['q']:.0f} | "
            f"{used} / {excluded} |"), m, m_err


def main():
    lines = [l.split() for l in open(sys.argv[1]) if l.strip()]
    print("m = (m1 + m2) / 2; errors from the per-set bootstrap errors; 'used / excluded': galaxies\n"
          "in the shear estimates / left out (flagged fits and their ring-and-noise group); shear-pair\n"
          "sets ('N pairs x 2 x galaxies'): m from half the pair differences, c from half the sums\n"
          "(metrics --shear-pairs), Q not defined\n")
    print("| S/N, catalogue | sets x galaxies | m | m1 | m2 | c1 | c2 | c+ (PSF frame) | Q | used / excluded |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    notes = []
    for snr, unc, cal, *rest in lines:
        du, dc = json.load(open(unc)), json.load(open(cal))
        ru, mu, mu_err = row(f"{snr}, uncalibrated", du)
        rc, mc, _ = row(f"{snr}, calibrated (population)", dc)
        print(ru)
        print(rc)
        if rest:
            print(row(f"{snr}, calibrated per object", json.load(open(rest[0])))[0])
        calibrated = [("population", dc, mc)]
        if len(rest) > 1:
            dm = json.load(open(rest[1]))
            rm, mm, _ = row(f"{snr}, calibrated (population, table measured at S/N {snr})", dm)
            print(rm)
            calibrated.append((f"table measured at S/N {snr}", dm, mm))
        for label, d, m in calibrated:
            # A reduction factor means something only where the raw m is measured to be non-zero.
            factor = f", |m| reduced {abs(mu) / max(abs(m), 1e-12):.1f}x" if abs(mu) > 3 * mu_err else \
                ", raw m within 3 sigma of zero"
            notes.append(f"S/N {snr} ({label}): m {mu:+.2e} -> {m:+.2e}{factor}"
                         + (f" (paper: {PAPER[snr]})" if snr in PAPER and label == "population" else ""))
    print()
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
