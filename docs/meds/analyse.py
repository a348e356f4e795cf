#!/usr/bin/env python3
"""Shear from `stampede fit --meds` tables (their --text form) of `stampede sim meds` tiles.

usage: analyse.py shear TRUTH_DIR FIT.txt [FIT.txt ...]
         per tile: the mean e over usable rows (status 0, flags clear of the shear-excluding bits),
         its error from the ring-pair means' scatter, and the truth's mean sheared e
       analyse.py paired TRUTH_DIR CLEAN.txt OTHER.txt
         the same galaxies and noise fitted clean and with masks: the shear difference, with its
         error from the ring pairs' differences, against the clean shear's own error
       analyse.py mc DIR1 DIR2 ... (each with truth.fits and fit.txt)
         m and c of the mean e against the truth's mean sheared e over the tiles
Standard library only (no numpy or astropy on the machines this runs on).
"""
import math
import struct
import sys

EXCLUDING = (1 << 2) | (1 << 4) | (1 << 5) | (1 << 16) | (1 << 17) | (1 << 18) | (1 << 19) | (1 << 20)


def read_truth(path):
    """The TRUTH table of a truth.fits, as a list of dicts, and its primary header keys."""
    data = open(path, 'rb').read()
    pos, hdus = 0, []
    while pos < len(data):
        hdr = {}
        while True:
            block = data[pos:pos + 2880]
            pos += 2880
            end = False
            for i in range(36):
                card = block[i * 80:(i + 1) * 80].decode('ascii')
                key = card[:8].strip()
                if key == 'END':
                    end = True
                    break
                if card[8:10] == '= ':
                    hdr[key] = card[10:].split('/')[0].strip().strip("'").strip()
            if end:
                break
        naxis, size = int(hdr.get('NAXIS', 0)), 0
        if naxis:
            size = abs(int(hdr['BITPIX'])) // 8
            for a in range(1, naxis + 1):
                size *= int(hdr['NAXIS%d' % a])
        size += int(hdr.get('PCOUNT', 0))
        hdus.append((hdr, pos))
        pos += (size + 2879) // 2880 * 2880
    primary = hdus[0][0]
    hdr, off = [h for h in hdus if h[0].get('EXTNAME') == 'TRUTH'][0]
    nf = int(hdr['TFIELDS'])
    names = [hdr['TTYPE%d' % i] for i in range(1, nf + 1)]
    fmt = '>' + ''.join('q' if hdr['TFORM%d' % i] == '1K' else 'd' for i in range(1, nf + 1))
    size = struct.calcsize(fmt)
    rows = [dict(zip(names, struct.unpack_from(fmt, data, off + size * r))) for r in range(int(hdr['NAXIS2']))]
    return rows, primary


def read_fit(path):
    lines = open(path).read().splitlines()
    header = [l for l in lines if l.startswith('#')][-1].split()[1:]
    return [dict(zip(header, map(float, l.split()))) for l in lines if l and not l.startswith('#')]


def usable(row):
    return row['status'] == 0 and not (int(row['flags']) & EXCLUDING)


def pair_means(fit, keep):
    """Per ring pair (objects 2m, 2m+1, both kept): the mean (e1, e2)."""
    out = []
    for m in range(len(fit) // 2):
        a, b = 2 * m, 2 * m + 1
        if keep[a] and keep[b]:
            out.append(((fit[a]['e1'] + fit[b]['e1']) / 2, (fit[a]['e2'] + fit[b]['e2']) / 2))
    return out


def mean_err(values):
    n = len(values)
    mu = sum(values) / n
    var = sum((v - mu) ** 2 for v in values) / (n - 1) if n > 1 else float('nan')
    return mu, math.sqrt(var / n)


def shear(truth_dir, fits):
    truth, hdr = read_truth(truth_dir + '/truth.fits')
    print('truth %s: g = (%s, %s); mean sheared e (%.5f, %.5f)' % (
        truth_dir, hdr['SHEAR1'], hdr['SHEAR2'], sum(t['e1_obs'] for t in truth) / len(truth),
        sum(t['e2_obs'] for t in truth) / len(truth)))
    for path in fits:
        fit = read_fit(path)
        keep = [usable(r) for r in fit]
        pm = pair_means(fit, keep)
        g1, s1 = mean_err([p[0] for p in pm])
        g2, s2 = mean_err([p[1] for p in pm])
        print('%s: %d of %d rows usable; g = (%+.5f +- %.5f, %+.5f +- %.5f)' % (path, sum(keep), len(fit), g1, s1, g2, s2))


def paired(truth_dir, clean_path, other_path):
    clean, other = read_fit(clean_path), read_fit(other_path)
    keep = [usable(a) and usable(b) for a, b in zip(clean, other)]
    pc, po = pair_means(clean, keep), pair_means(other, keep)
    for k, name in ((0, 'g1'), (1, 'g2')):
        gc, sc = mean_err([p[k] for p in pc])
        go, so = mean_err([p[k] for p in po])
        d, sd = mean_err([b[k] - a[k] for a, b in zip(pc, po)])
        print('%s: clean %+.5f +- %.5f, masked %+.5f +- %.5f; difference %+.6f +- %.6f (%.1f sigma of the '
              'difference, %.2f of the clean error)' % (name, gc, sc, go, so, d, sd, abs(d) / sd, abs(d) / sc))
    print('pairs used: %d (usable in both tables); usable rows: clean %d, masked %d of %d' % (
        len(pc), sum(usable(r) for r in clean), sum(usable(r) for r in other), len(clean)))


def mc(dirs):
    xs = [[], []]
    ys = [[], []]
    for d in dirs:
        truth, _ = read_truth(d + '/truth.fits')
        fit = read_fit(d + '/fit.txt')
        keep = [usable(r) for r in fit]
        for k, c in ((0, 'e1'), (1, 'e2')):
            xs[k].append(sum(t[c + '_obs'] for t, u in zip(truth, keep) if u) / sum(keep))
            ys[k].append(sum(r[c] for r, u in zip(fit, keep) if u) / sum(keep))
    for k in (0, 1):
        x, y, n = xs[k], ys[k], len(xs[k])
        sx, sy = sum(x), sum(y)
        sxx, sxy = sum(v * v for v in x), sum(a * b for a, b in zip(x, y))
        slope = (n * sxy - sx * sy) / (n * sxx - sx * sx)
        print('m%d = %+.2e, c%d = %+.2e over %d tiles' % (k + 1, slope - 1, k + 1, (sy - slope * sx) / n, n))


if __name__ == '__main__':
    if len(sys.argv) >= 4 and sys.argv[1] == 'shear':
        shear(sys.argv[2], sys.argv[3:])
    elif len(sys.argv) == 5 and sys.argv[1] == 'paired':
        paired(sys.argv[2], sys.argv[3], sys.argv[4])
    elif len(sys.argv) >= 4 and sys.argv[1] == 'mc':
        mc(sys.argv[2:])
    else:
        sys.exit(__doc__)
