#!/usr/bin/env python3
"""Every file-size limit from STEP bytes to the finished table's size, for `stampede fit` (a GREAT08
grid) or `stampede metadetect` (three simulated cells): each run under the limit (RLIMIT_FSIZE, as a
full disk or a batch system's limit) either finishes with the whole table, or fails and is then
resumed (`--resume`, no limit), which must give the uninterrupted table (fit: every column but
time_us; metadetect: byte for byte). Prints the outcomes by kind; a "SHORT-COMPLETE",
"RESUMED-DIFFERS" or "RESUME-FAILS" line is a failure of the durable table's protocol.

usage: file_size_limits.py fit|mdet [STEP] [--build BUILD_DIR] [--work DIR]
"""
import argparse, collections, os, resource, shutil, subprocess

def norm(path):
    d = bytearray(open(path, 'rb').read())
    pos = 0; hdus = 0
    while pos < len(d):
        cards = {}; order = []; i = pos
        while True:
            c = d[i:i+80].decode('latin1'); i += 80
            k = c[:8].strip()
            if '=' in c[8:10]: cards[k] = c[10:].split('/')[0].strip().strip("'").strip()
            if k == 'END': break
        hstart = pos; dstart = (i + 2879)//2880*2880
        if cards.get('XTENSION') == 'BINTABLE':
            n1 = int(cards['NAXIS1']); n2 = int(cards['NAXIS2']); off = 0
            size = {'K':8,'D':8,'J':4,'E':4,'I':2,'B':1}
            for c in range(1, int(cards['TFIELDS'])+1):
                f = cards['TFORM%d'%c]; w = size.get(f[-1], 1)*(int(f[:-1]) if f[:-1].isdigit() else 1)
                if cards['TTYPE%d'%c] == 'time_us':
                    for r in range(n2): d[dstart+r*n1+off:dstart+r*n1+off+w] = b'\0'*w
                off += w
            ln = n1*n2
        else:
            ln = 1
            for a in range(1, int(cards.get('NAXIS', 0))+1): ln *= int(cards['NAXIS%d'%a])
            ln = ln*abs(int(cards.get('BITPIX', 8)))//8 if int(cards.get('NAXIS', 0)) else 0
        pos = dstart + (ln + 2879)//2880*2880
    return bytes(d)
def same(a, b):
    return norm(a) == norm(b)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("kind", choices=["fit", "mdet"])
    ap.add_argument("step", nargs="?", type=int, default=1024)
    ap.add_argument("--build", default=os.path.join(os.path.dirname(__file__), "../../build"))
    ap.add_argument("--work", default="/tmp/stampede_file_size_limits")
    a = ap.parse_args()
    S = os.path.abspath(os.path.join(a.build, "tools/stampede"))
    w = os.path.join(a.work, a.kind)
    shutil.rmtree(w, ignore_errors=True)
    os.makedirs(w)
    if a.kind == "mdet":
        subprocess.run([S, "sim", "cells", "--cells", "3", "--seed", "5", "--out", w + "/cells"], check=True,
                       capture_output=True)
        inputs = [f"{w}/cells/cell_000{k}.fits" for k in range(3)]
        def args(out, resume):
            return [S, "metadetect"] + inputs + ["-o", out, "--quiet", "--threads", "1"] + (["--resume"] if resume else [])
    else:
        grid = os.path.join(os.path.dirname(__file__), "../../../shared/data/galsim-great08-mini/nf/set_0.fits")
        cheap = ["--set", "batch_size=20", "--threads", "2", "--quiet", "--set", "upsampling=2", "--set",
                 "n_central_pixels_to_upsample=1", "--set", "padding=0", "--set", "minimizer_max_iterations=20"]
        def args(out, resume):
            return [S, "fit", grid, "-o", out] + cheap + (["--resume"] if resume else [])
    full = w + "/full.fits"
    r = subprocess.run(args(full, False), capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    size = os.path.getsize(full)
    print("table", size, "bytes")

    def limit(n):
        return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (n, resource.RLIM_INFINITY))

    outcomes = collections.defaultdict(list)
    for n in list(range(a.step, size, a.step)) + [size]:
        out = f"{w}/o{n}.fits"
        r = subprocess.run(args(out, False), capture_output=True, text=True, preexec_fn=limit(n))
        if r.returncode == 0:
            res = "whole" if same(out, full) else "SHORT-COMPLETE"
        else:
            kept = os.path.exists(out + ".checkpoint")
            r2 = subprocess.run(args(out, True), capture_output=True, text=True)
            if r2.returncode != 0:
                res = "RESUME-FAILS: " + r2.stderr.strip().splitlines()[-1][:150]
            elif not same(out, full):
                res = "RESUMED-DIFFERS"
            else:
                res = "resumed, same table" if kept else "started by --resume (nothing committed), same table"
        outcomes[res.split(":")[0]].append(n)
    for k, v in outcomes.items():
        print(f"{k}: {len(v)} limits ({v[0]}..{v[-1]} bytes)")
    bad = [k for k in outcomes if k in ("SHORT-COMPLETE", "RESUMED-DIFFERS", "RESUME-FAILS")]
    raise SystemExit(1 if bad else 0)


if __name__ == "__main__":
    main()
