#!/usr/bin/env python3
"""Markdown table of the calibration experiment from `stampede metrics --json` outputs.

usage: table.py LIST
LIST: lines 'SNR uncalibrated.json calibrated.json [per_object.json]' (run_experiment.sh).
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
    m = 0.5 * (d["m1"] + d["m2"])
    m_err = 0.5 * (d["m1_err"] ** 2 + d["m2_err"] ** 2) ** 0.5
    used = sum(s["used"] for s in d["sets"])
    excluded = sum(s["excluded"] for s in d["sets"])
    size = f"{len(d['sets'])} x {(used + excluded) // len(d['sets'])}"
    return (f"| {label} | {size} | {fmt(m, m_err)} | {fmt(d['m1'], d['m1_err'])} | {fmt(d['m2'], d['m2_err'])} | "
            f"{fmt(d['c1'], d['c1_err'])} | {fmt(d['c2'], d['c2_err'])} | {fmt(d['c_plus'])} | {d['q']:.0f} | "
            f"{used} / {excluded} |"), m


def main():
    lines = [l.split() for l in open(sys.argv[1]) if l.strip()]
    print("m = (m1 + m2) / 2; errors from the per-set bootstrap errors; 'used / excluded': galaxies\n"
          "in the shear estimates / left out (flagged fits and their ring-and-noise group)\n")
    print("| S/N, catalogue | sets x galaxies | m | m1 | m2 | c1 | c2 | c+ (PSF frame) | Q | used / excluded |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    notes = []
    for snr, unc, cal, *rest in lines:
        du, dc = json.load(open(unc)), json.load(open(cal))
        ru, mu = row(f"{snr}, uncalibrated", du)
        rc, mc = row(f"{snr}, calibrated (population)", dc)
        print(ru)
        print(rc)
        if rest:
            print(row(f"{snr}, calibrated per object", json.load(open(rest[0])))[0])
        notes.append(f"S/N {snr}: |m| reduced {abs(mu) / max(abs(mc), 1e-12):.1f}x"
                     + (f" (paper: {PAPER[snr]})" if snr in PAPER else ""))
    print()
    for n in notes:
        print(f"- {n}")


if __name__ == "__main__":
    main()
