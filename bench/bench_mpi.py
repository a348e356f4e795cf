"""MPI-driver benchmark (results in docs/scaling.md): the whole `stampede-mpi fit` job on 1 and 2
ranks x 1 thread beside the plain `stampede fit` on 1 thread, over one simulated S/N 20 set (40 x 40
stamps of 39 px, exact renderer), and the same for `stampede-mpi metadetect` over 160 simulated
random-layout cells (the reference test's cells), repetitions interleaved at random; written as
Google Benchmark JSON (median aggregates) for bench/summarize.py. The driver's overhead per object
(cell) is the 1-rank job's time per object beyond the plain command's.

    python3 bench/bench_mpi.py BUILD_DIR OUT.json [REPETITIONS]
"""
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time

OPTIONS = ["--set", "renderer=exact", "--set", "psf_e2=0.05", "--set", "noise_sigma=1", "--set", "batch_size=8",
           "--threads", "1", "--quiet", "--overwrite"]


def main():
    build, out = sys.argv[1], sys.argv[2]
    reps = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    cli = os.path.join(build, "tools", "stampede")
    mpi = os.path.join(build, "tools", "stampede-mpi")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    with tempfile.TemporaryDirectory(prefix="stampede_bench_mpi_") as tmp:
        subprocess.run([cli, "sim", "great08", "--out", tmp, "--sets", "1", "--grid", "40", "--snr", "20"],
                       check=True, capture_output=True)
        grid = os.path.join(tmp, "set_0.fits")
        n = 40 * 40
        cells = 160
        subprocess.run([cli, "sim", "cells", "--out", os.path.join(tmp, "cells"), "--cells", str(cells), "--layout",
                        "random"], check=True, capture_output=True)
        images = sorted(os.path.join(tmp, "cells", f) for f in os.listdir(os.path.join(tmp, "cells"))
                        if f.startswith("cell_"))
        md = images + ["--threads", "1", "--quiet", "--overwrite"]
        variants = {
            "BM_FitCommand/threads:1": [cli, "fit", grid, "-o", os.path.join(tmp, "c.fits")] + OPTIONS,
            "BM_MpiFit/ranks:1/threads:1": ["mpirun", "-n", "1", mpi, "fit", grid, "-o", os.path.join(tmp, "m1.fits")]
            + OPTIONS,
            "BM_MpiFit/ranks:2/threads:1": ["mpirun", "-n", "2", "--oversubscribe", mpi, "fit", grid, "-o",
                                            os.path.join(tmp, "m2.fits")] + OPTIONS,
            "BM_MetadetectCommand/threads:1": [cli, "metadetect", "-o", os.path.join(tmp, "dc.fits")] + md,
            "BM_MpiMetadetect/ranks:1/threads:1": ["mpirun", "-n", "1", mpi, "metadetect", "-o",
                                                   os.path.join(tmp, "d1.fits")] + md,
            "BM_MpiMetadetect/ranks:2/threads:1": ["mpirun", "-n", "2", "--oversubscribe", mpi, "metadetect", "-o",
                                                   os.path.join(tmp, "d2.fits")] + md,
        }
        times = {k: [] for k in variants}
        for _ in range(reps):
            order = list(variants)
            random.shuffle(order)
            for name in order:
                t0 = time.perf_counter()
                subprocess.run(variants[name], check=True, env=env, capture_output=True)
                times[name].append(time.perf_counter() - t0)
    benchmarks = []
    for name, t in times.items():
        wall = statistics.median(t)
        units = cells if "Metadetect" in name else n
        benchmarks.append({"name": name + "_median", "run_name": name, "run_type": "aggregate",
                           "aggregate_name": "median", "repetitions": reps, "real_time": wall * 1e3,
                           "time_unit": "ms", "items_per_second": units / wall, "ms_per_object": wall * 1e3 / units})
    with open(out, "w") as f:
        json.dump({"context": {"objects": n, "cells": cells}, "benchmarks": benchmarks}, f, indent=1)


if __name__ == "__main__":
    main()
