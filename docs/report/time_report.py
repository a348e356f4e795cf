#!/usr/bin/env python3
"""Times `python3 -m stampede.report` on a large synthetic table and reports its peak memory.

    PYTHONPATH=build/python /usr/bin/python3 docs/report/time_report.py FIT.fits --rows 10000000

The synthetic table is FIT.fits's RESULTS rows repeated (with their header, NAXIS2 changed) to
--rows rows, written to --scratch; the report is run on it in a child process, whose wall time and
peak resident memory (getrusage of the children) are printed as a Markdown table row. The first
run reads the file from disk, later ones from the page cache: --repeat runs it more than once.
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

BLOCK = 2880


def results_hdu(data):
    """(header start, header end, data start, row bytes, rows) of the RESULTS table in `data`."""
    at = data.index(b"EXTNAME = 'RESULTS")
    start = data.rindex(b"XTENSION= 'BINTABLE'", 0, at)
    end = data.index(b"END" + b" " * 77, start)
    header_end = (end - start) // BLOCK * BLOCK + BLOCK + start
    def card(key):
        i = data.index(key.ljust(8).encode() + b"= ", start, header_end)
        return int(data[i + 10:i + 30])
    return start, header_end, card("NAXIS1"), card("NAXIS2")


def write_synthetic(source, rows, path):
    data = open(source, "rb").read()
    start, header_end, row_bytes, source_rows = results_hdu(data)
    header = bytearray(data[:header_end])
    i = header.index(b"NAXIS2  = ", start)
    header[i:i + 30] = b"NAXIS2  = %20d" % rows
    block = data[header_end:header_end + row_bytes * source_rows]
    with open(path, "wb") as f:
        f.write(header)
        repeat = max(1, (1 << 24) // len(block))  # ~16 MB per write
        chunk, written = block * repeat, 0
        while written < rows:
            take = min(rows - written, source_rows * repeat)
            f.write(chunk[:take * row_bytes])
            written += take
        f.write(b"\0" * (-(rows * row_bytes) % BLOCK))
    return row_bytes


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("table", help="a `stampede fit` table whose rows are repeated")
    p.add_argument("--rows", type=int, default=10_000_000)
    p.add_argument("--scratch", default=tempfile.gettempdir(), help="where the synthetic table is written")
    p.add_argument("--repeat", type=int, default=2)
    a = p.parse_args()
    big = os.path.join(a.scratch, f"synthetic_{a.rows}.fits")
    t0 = time.perf_counter()
    row_bytes = write_synthetic(a.table, a.rows, big)
    print(f"wrote {big}: {a.rows} rows of {row_bytes} bytes ({os.path.getsize(big) / 1e9:.2f} GB) in "
          f"{time.perf_counter() - t0:.1f} s", file=sys.stderr)
    print("| rows | table | run | wall time | peak RSS |\n|---|---|---|---|---|")
    try:
        for run in range(a.repeat):
            out = tempfile.mkdtemp(prefix="report-timing-", dir=a.scratch)
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "stampede.report", big, "-o", out, "--overwrite", "--quiet"],
                           check=True, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - t0
            peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
            print(f"| {a.rows:,} | {os.path.getsize(big) / 1e9:.2f} GB | {run + 1} | {wall:.1f} s | {peak_mb:.0f} MB |",
                  flush=True)
    finally:
        os.remove(big)


if __name__ == "__main__":
    main()
