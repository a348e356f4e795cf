#!/usr/bin/env python3
"""Compares the table data of two outputs of stampede, old build against new, bit for bit.

Standard library only (no astropy, no fitsio). For each pair:

  *.fits  every BINTABLE HDU, in file order: EXTNAME, NAXIS1, NAXIS2, PCOUNT and every column's
          TTYPE, TFORM (and TZERO, TSCAL, TDIM, TNULL, which change what the bytes mean) must be
          equal, and the row bytes (and any heap) equal with the bytes of the timing column
          time_us masked. Header keys outside the column descriptions (RUNFP, INPUT, digests,
          COMMENT cards, ...) are not compared: they may legitimately differ.
  *.txt   `stampede fit --text` tables: the '#' header line of column names must be equal, and
          every other token of every row equal as text, the time_us column left out.
  other   (.npy, .repr, ...) byte for byte.

Usage:
  compare_tables.py LABEL OLD NEW            one pair
  compare_tables.py --manifest FILE          one pair a line: LABEL<TAB>OLD<TAB>NEW; a line
                                             LABEL<TAB>!<TAB>REASON records a run that failed
  compare_tables.py --dump FILE.fits         the BINTABLEs' columns (for a look)

Prints one line per pair: label, rows, and "same" or what differs. Exits 1 if any pair differs
or could not be compared, else 0.
"""

import os
import sys

BLOCK = 2880
CARD = 80
SKIP_COLUMNS = ("time_us",)
# Bytes per element of each binary-table TFORM type code (FITS 4.0, table 18).
TYPE_BYTES = {"L": 1, "B": 1, "I": 2, "J": 4, "K": 8, "A": 1, "E": 4, "D": 8, "C": 8, "M": 16, "P": 8, "Q": 16}
DESCRIPTOR_KEYS = ("TTYPE", "TFORM", "TZERO", "TSCAL", "TDIM", "TNULL")


class FitsError(Exception):
    pass


def parse_value(raw):
    """The value of a card's value field (after '= '), as a str, int, float, bool or None."""
    s = raw.strip()
    if s.startswith("'"):
        # A string: '' is an escaped quote; a comment may follow the closing quote.
        out, i = [], 1
        while i < len(s):
            if s[i] == "'":
                if i + 1 < len(s) and s[i + 1] == "'":
                    out.append("'")
                    i += 2
                    continue
                break
            out.append(s[i])
            i += 1
        return "".join(out).rstrip()
    s = s.split("/", 1)[0].strip()
    if s == "T":
        return True
    if s == "F":
        return False
    if s == "":
        return None
    try:
        return int(s)
    except ValueError:
        pass
    try:
        return float(s.replace("D", "E"))
    except ValueError:
        return s


def read_header(data, pos):
    """The header starting at byte pos: (dict of keyword -> value, position after the header)."""
    keys = {}
    while True:
        if pos + BLOCK > len(data):
            raise FitsError("truncated header at byte %d" % pos)
        block = data[pos:pos + BLOCK]
        pos += BLOCK
        for k in range(BLOCK // CARD):
            card = block[k * CARD:(k + 1) * CARD].decode("ascii", errors="replace")
            key = card[:8].rstrip()
            if key == "END":
                return keys, pos
            if card[8:10] == "= " and key not in keys:
                keys[key] = parse_value(card[10:])


def hdus(path):
    """Every HDU of the file: a list of (header dict, data bytes including any heap)."""
    with open(path, "rb") as f:
        data = f.read()
    out, pos = [], 0
    while pos < len(data):
        if not data[pos:pos + BLOCK].strip(b"\0 "):
            break  # trailing padding
        header, pos = read_header(data, pos)
        naxis = int(header.get("NAXIS", 0))
        size = 0
        if naxis > 0:
            size = abs(int(header["BITPIX"])) // 8
            for a in range(1, naxis + 1):
                size *= int(header["NAXIS%d" % a])
            size = (size + int(header.get("PCOUNT", 0))) * int(header.get("GCOUNT", 1))
        if pos + size > len(data):
            raise FitsError("HDU %d: data truncated (%d bytes of %d)" % (len(out), len(data) - pos, size))
        out.append((header, data[pos:pos + size]))
        pos += (size + BLOCK - 1) // BLOCK * BLOCK
    return out


def column_width(tform):
    """Bytes of one row's cell of a column of format tform (e.g. '1D', '16A', '3X', '1PE(10)')."""
    t = tform.strip()
    i = 0
    while i < len(t) and t[i].isdigit():
        i += 1
    repeat = int(t[:i]) if i else 1
    code = t[i:i + 1]
    if code == "X":
        return (repeat + 7) // 8
    if code not in TYPE_BYTES:
        raise FitsError("unknown TFORM %r" % tform)
    if code in "PQ":
        return TYPE_BYTES[code] * (1 if repeat else 0)
    return TYPE_BYTES[code] * repeat


class Table:
    def __init__(self, header, data):
        self.header = header
        self.extname = header.get("EXTNAME", "")
        self.naxis1 = int(header["NAXIS1"])
        self.naxis2 = int(header["NAXIS2"])
        self.pcount = int(header.get("PCOUNT", 0))
        n = int(header["TFIELDS"])
        self.columns = []  # (name, descriptors, offset, width)
        offset = 0
        for c in range(1, n + 1):
            desc = tuple((k, header.get("%s%d" % (k, c))) for k in DESCRIPTOR_KEYS)
            width = column_width(str(header["TFORM%d" % c]))
            self.columns.append((str(header.get("TTYPE%d" % c, "")), desc, offset, width))
            offset += width
        if offset != self.naxis1:
            raise FitsError("%s: columns sum to %d bytes, NAXIS1 = %d" % (self.extname, offset, self.naxis1))
        self.rows = data[:self.naxis1 * self.naxis2]
        self.heap = data[self.naxis1 * self.naxis2:]

    def masked_rows(self):
        """The row bytes with each skipped column's bytes set to zero."""
        spans = [(o, w) for name, _, o, w in self.columns if name in SKIP_COLUMNS]
        if not spans:
            return self.rows
        rows = bytearray(self.rows)
        zero = {w: bytes(w) for _, w in spans}
        for r in range(self.naxis2):
            base = r * self.naxis1
            for o, w in spans:
                rows[base + o:base + o + w] = zero[w]
        return bytes(rows)

    def differing_columns(self, other, limit=8):
        """Names of the columns whose bytes differ (a column is compared over all rows), with the
        first differing row of each."""
        out = []
        for name, _, o, w in self.columns:
            if name in SKIP_COLUMNS:
                continue
            for r in range(min(self.naxis2, other.naxis2)):
                a = self.rows[r * self.naxis1 + o:r * self.naxis1 + o + w]
                b = other.rows[r * other.naxis1 + o:r * other.naxis1 + o + w]
                if a != b:
                    n = sum(1 for rr in range(r, min(self.naxis2, other.naxis2))
                            if self.rows[rr * self.naxis1 + o:rr * self.naxis1 + o + w]
                            != other.rows[rr * other.naxis1 + o:rr * other.naxis1 + o + w])
                    out.append("%s(%d rows, first row %d)" % (name, n, r))
                    break
            if len(out) >= limit:
                out.append("...")
                break
        return out


def tables(path):
    return [Table(h, d) for h, d in hdus(path)[1:] if h.get("XTENSION") == "BINTABLE"]


def compare_fits(old, new):
    """(rows, list of differences) of two FITS files' binary tables."""
    a, b = tables(old), tables(new)
    if not a and not b:
        return 0, ["no BINTABLE HDU in either file"]
    diffs = []
    if len(a) != len(b):
        diffs.append("BINTABLE count %d vs %d" % (len(a), len(b)))
    rows = 0
    for i, (ta, tb) in enumerate(zip(a, b)):
        where = "HDU %s" % (ta.extname or "#%d" % i)
        rows += ta.naxis2
        if ta.extname != tb.extname:
            diffs.append("%s: EXTNAME %r vs %r" % (where, ta.extname, tb.extname))
        for key in ("naxis1", "naxis2", "pcount"):
            if getattr(ta, key) != getattr(tb, key):
                diffs.append("%s: %s %d vs %d" % (where, key.upper(), getattr(ta, key), getattr(tb, key)))
        if len(ta.columns) != len(tb.columns):
            diffs.append("%s: TFIELDS %d vs %d" % (where, len(ta.columns), len(tb.columns)))
        for k, (ca, cb) in enumerate(zip(ta.columns, tb.columns), start=1):
            for (key, va), (_, vb) in zip(ca[1], cb[1]):
                if va != vb:
                    diffs.append("%s: %s%d %r vs %r" % (where, key, k, va, vb))
        if diffs:
            continue  # layouts differ: the bytes cannot be compared column by column
        if ta.masked_rows() != tb.masked_rows():
            diffs.append("%s: row bytes differ in %s" % (where, ", ".join(ta.differing_columns(tb))))
        if ta.heap != tb.heap:
            diffs.append("%s: heap bytes differ" % where)
    return rows, diffs


def compare_text(old, new):
    """(rows, differences) of two `fit --text` tables, the time_us column left out."""
    with open(old) as f:
        la = f.read().splitlines()
    with open(new) as f:
        lb = f.read().splitlines()
    head_a = [line for line in la if line.startswith("#")]
    head_b = [line for line in lb if line.startswith("#")]
    diffs = []
    if head_a != head_b:
        diffs.append("'#' header lines differ")
    names = head_a[-1][1:].split() if head_a else []
    skip = {i for i, n in enumerate(names) if n in SKIP_COLUMNS}
    ra = [line.split() for line in la if not line.startswith("#")]
    rb = [line.split() for line in lb if not line.startswith("#")]
    if len(ra) != len(rb):
        diffs.append("rows %d vs %d" % (len(ra), len(rb)))
    bad_cols, first = {}, None
    for r, (xa, xb) in enumerate(zip(ra, rb)):
        if len(xa) != len(xb):
            diffs.append("row %d: %d vs %d fields" % (r, len(xa), len(xb)))
            break
        for c, (va, vb) in enumerate(zip(xa, xb)):
            if c not in skip and va != vb:
                bad_cols[c] = bad_cols.get(c, 0) + 1
                if first is None:
                    first = r
    if bad_cols:
        diffs.append("text differs in %s (first row %d)" % (
            ", ".join("%s(%d rows)" % (names[c] if c < len(names) else "#%d" % c, n) for c, n in sorted(bad_cols.items())),
            first))
    return len(ra), diffs


def count_rows(path, data):
    """Rows of a byte-compared file: a .npy array's first dimension, else its lines not starting
    with '#'."""
    if path.endswith(".npy") and data[:6] == b"\x93NUMPY":
        import ast
        major = data[6]
        n = int.from_bytes(data[8:10] if major == 1 else data[8:12], "little")
        start = 10 if major == 1 else 12
        try:
            shape = ast.literal_eval(data[start:start + n].decode("latin1"))["shape"]
            return shape[0] if shape else 1
        except (ValueError, SyntaxError, KeyError):
            return 0
    return sum(1 for line in data.splitlines() if not line.startswith(b"#"))


def compare_bytes(old, new):
    with open(old, "rb") as f:
        a = f.read()
    with open(new, "rb") as f:
        b = f.read()
    rows = count_rows(old, a)
    if a == b:
        return rows, []
    n = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
    return rows, ["bytes differ (%d vs %d bytes, first at byte %d)" % (len(a), len(b), n)]


def compare(label, old, new):
    """The report line of one pair, and whether it is the same."""
    for p in (old, new):
        if not os.path.isfile(p):
            return "%-40s %7s  MISSING %s" % (label, "-", p), False
    try:
        if old.endswith(".fits"):
            rows, diffs = compare_fits(old, new)
        elif old.endswith(".txt"):
            rows, diffs = compare_text(old, new)
        else:
            rows, diffs = compare_bytes(old, new)
    except (FitsError, KeyError, ValueError, OSError) as e:
        return "%-40s %7s  ERROR %s" % (label, "-", e), False
    if diffs:
        return "%-40s %7d  DIFFERS: %s" % (label, rows, "; ".join(diffs)), False
    return "%-40s %7d  same" % (label, rows), True


def main(argv):
    if len(argv) == 2 and argv[0] == "--dump":
        for t in tables(argv[1]):
            print("%s: %d rows x %d bytes, PCOUNT %d" % (t.extname, t.naxis2, t.naxis1, t.pcount))
            for name, desc, o, w in t.columns:
                print("  %-24s %-8s offset %4d width %3d" % (name, dict(desc)["TFORM"], o, w))
        return 0
    pairs = []
    if len(argv) == 2 and argv[0] == "--manifest":
        with open(argv[1]) as f:
            for line in f:
                line = line.rstrip("\n")
                if line.strip():
                    pairs.append(line.split("\t"))
    elif len(argv) == 3:
        pairs.append(argv)
    else:
        sys.stderr.write(__doc__)
        return 2
    ok = True
    for label, old, new in pairs:
        if old == "!":
            print("%-40s %7s  RUN FAILED: %s" % (label, "-", new))
            ok = False
            continue
        line, same = compare(label, old, new)
        print(line)
        ok = ok and same
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
