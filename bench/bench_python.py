"""Python-module benchmarks: fit_stamps on 1 and 2 engine threads, and the per-stamp
overhead of the one-stamp call (Fitter.fit) against the fit itself, on S/N 20 GREAT08-like stamps
with the fastest renderer. Repetitions are interleaved at random, as bench/run does for the C++
benchmarks, and written as Google Benchmark JSON (median aggregates) for bench/summarize.py.

    PYTHONPATH=build/python python3 bench/bench_python.py OUT.json [REPETITIONS]
"""
import json
import random
import statistics
import sys
import time

import numpy as np

import stampede

OPTIONS = {"renderer": "exact", "psf_e2": 0.05}


def main():
    out = sys.argv[1]
    reps = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    stamps = stampede.simulate_great08(grid=16, snr=20, seed=11)["stamps"]  # 256 stamps, 39 px: 8 batches
    n = len(stamps)
    fitter = stampede.Fitter(OPTIONS, stamp_size=39)
    stampede.fit_stamps(stamps[:4], options=OPTIONS, threads=1)  # warm-up: FFTW plans, tables

    def batch(threads):
        t0 = time.perf_counter()
        rows = stampede.fit_stamps(stamps, options=OPTIONS, threads=threads)
        return time.perf_counter() - t0, float(np.sum(rows["time_us"])) * 1e-6

    def one_by_one():
        t0 = time.perf_counter()
        fit_seconds = 0.0
        for s in stamps:
            fit_seconds += fitter.fit(s)["time_us"] * 1e-6
        return time.perf_counter() - t0, fit_seconds

    variants = {
        "BM_PythonFitStamps/threads:1": lambda: batch(1),
        "BM_PythonFitStamps/threads:2": lambda: batch(2),
        "BM_PythonFitterCall": one_by_one,
    }
    times = {k: [] for k in variants}
    fit_times = {k: [] for k in variants}
    for _ in range(reps):
        order = list(variants)
        random.shuffle(order)
        for name in order:
            wall, fit = variants[name]()
            times[name].append(wall)
            fit_times[name].append(fit)

    benchmarks = []
    for name in variants:
        wall = statistics.median(times[name])
        fit = statistics.median(fit_times[name])
        benchmarks.append({
            "name": name + "_median", "run_name": name, "run_type": "aggregate", "aggregate_name": "median",
            "repetitions": reps, "real_time": wall * 1e3, "time_unit": "ms", "items_per_second": n / wall,
            "ms_per_stamp": wall * 1e3 / n, "fit_ms_per_stamp": fit * 1e3 / n,
            # Wall time beyond the fits themselves (their time_us), per stamp: the call's overhead.
            "overhead_ms_per_stamp": (wall - fit) * 1e3 / n if name == "BM_PythonFitterCall" else 0.0,
        })
    with open(out, "w") as f:
        json.dump({"context": {"stamps": n, "options": OPTIONS}, "benchmarks": benchmarks}, f, indent=1)


if __name__ == "__main__":
    main()
