"""Markdown summary of bench/run's JSON files: medians over repetitions, and the ratios the
performance claims rest on (each ratio from variants measured side by side in one run)."""
import json
import os
import re
import sys


def cpu_line():
    model, flags = "unknown CPU", set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name") and model == "unknown CPU":
                    model = line.split(":", 1)[1].strip()
                if line.startswith("flags"):
                    flags = set(line.split(":", 1)[1].split())
    except OSError:
        pass
    isa = [name for name, flag in [("avx512f", "avx512f"), ("avx2", "avx2"), ("fma", "fma"), ("sse4.2", "sse4_2")] if flag in flags]
    return model, " ".join(isa) or "unknown"


def medians(path):
    with open(path) as f:
        data = json.load(f)
    out = {}
    for b in data["benchmarks"]:
        if b.get("run_type") == "aggregate" and b.get("aggregate_name") == "median":
            out[b["run_name"]] = b
    return data.get("context", {}), out


def fmt_time(b):
    return f"{b['real_time']:.4g} {b.get('time_unit', 'ns')}"


def seconds(b):
    scale = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b.get("time_unit", "ns")]
    return b["real_time"] * scale


def main():
    out_dir, targets = sys.argv[1], sys.argv[2:]
    model, isa = cpu_line()
    print("# Benchmark medians\n")
    print(f"CPU: {model}; instruction sets: {isa}; {os.cpu_count()} logical CPUs\n")
    all_runs = {}
    for t in targets:
        path = os.path.join(out_dir, t + ".json")
        if not os.path.exists(path):
            continue
        context, runs = medians(path)
        all_runs.update(runs)
        print(f"## {t}\n")
        print("| benchmark | median time | items/s | counters |")
        print("|---|---|---|---|")
        skip = {"name", "run_name", "run_type", "repetitions", "threads", "aggregate_name", "aggregate_unit",
                "iterations", "real_time", "cpu_time", "time_unit", "family_index", "per_family_instance_index",
                "repetition_index", "items_per_second", "error_occurred", "error_message"}
        for name, b in sorted(runs.items()):
            counters = ", ".join(f"{k} {v:.4g}" for k, v in b.items() if k not in skip and isinstance(v, (int, float)))
            ips = f"{b['items_per_second']:.4g}" if "items_per_second" in b else ""
            print(f"| {name} | {fmt_time(b)} | {ips} | {counters} |")
        print()
    print("## Ratios (same run)\n")
    for name, b in sorted(all_runs.items()):
        m = re.match(r"(BM_\w+)/(sse4\.2|avx2|avx512)(/n\d)?$", name)
        if m:
            ref = all_runs.get(f"{m.group(1)}/scalar{m.group(3) or ''}")
            if ref:
                width = {"sse4.2": 2, "avx2": 4, "avx512": 8}[m.group(2)]
                speed = seconds(ref) / seconds(b)
                verdict = "meets" if speed >= 0.7 * width else "below"
                print(f"- {name}: {speed:.2f}x the scalar reference ({verdict} 0.7 x {width} = {0.7 * width:.1f})")
    fit_scalar = all_runs.get("BM_Fit/isa:1/real_time")
    fit_best = all_runs.get("BM_Fit/isa:0/real_time")
    if fit_scalar and fit_best:
        print(f"- fit, best instruction set vs scalar kernels: {seconds(fit_scalar) / seconds(fit_best):.2f}x")
    full = {k.split(":")[-1]: v for k, v in all_runs.items() if k.startswith("BM_ConvolveFullInverse")}
    folded = {k.split(":")[-1]: v for k, v in all_runs.items() if k.startswith("BM_ConvolveFolded")}
    for stamp in sorted(set(full) & set(folded)):
        print(f"- convolution + downsampling, stamp {stamp}: folded inverse {seconds(full[stamp]) / seconds(folded[stamp]):.2f}x faster than full inverse")
    plain = next((v for k, v in all_runs.items() if k.startswith("BM_PlainLoop")), None)
    e1 = next((v for k, v in all_runs.items() if k.startswith("BM_Engine/threads:1")), None)
    e2 = next((v for k, v in all_runs.items() if k.startswith("BM_Engine/threads:2")), None)
    if plain and e1:
        print(f"- engine overhead at 1 thread: {100 * (1 - e1['items_per_second'] / plain['items_per_second']):+.1f} % "
              f"(plain loop {plain['items_per_second']:.2f}, engine {e1['items_per_second']:.2f} stamps/s)")
    if e1 and e2:
        print(f"- engine 2-thread speed-up: {e2['items_per_second'] / e1['items_per_second']:.2f}x")
    c1 = all_runs.get("BM_FitCommand/threads:1")
    m1 = all_runs.get("BM_MpiFit/ranks:1/threads:1")
    m2 = all_runs.get("BM_MpiFit/ranks:2/threads:1")
    if m1 and m2:
        print(f"- MPI driver, 2 ranks x 1 thread against 1 rank x 1 thread (whole jobs): "
              f"{m2['items_per_second'] / m1['items_per_second']:.2f}x (target >= 1.8)")
    if c1 and m1:
        print(f"- MPI driver overhead per object (1-rank job beyond the plain command): "
              f"{m1['ms_per_object'] - c1['ms_per_object']:+.3f} ms of {c1['ms_per_object']:.3f} ms")
    def first(prefix):
        return next((v for k, v in sorted(all_runs.items()) if k.startswith(prefix)), None)

    for snr, label in (("20", "S/N 20"), ("0", "noise-free")):
        d, x, u = (first(f"BM_Fit{v}/snr:{snr}") for v in ("Default", "ExactOnly", "Upsampled"))
        if d and x and u:
            ms = {k: b.get("ms_per_fit", seconds(b) * 1e3) for k, b in (("d", d), ("x", x), ("u", u))}
            print(f"- fit, {label}: default {ms['d']:.3g} ms, all exact {ms['x']:.3g} ms ({ms['x'] / ms['d']:.2f}x the "
                  f"default's), upsampled {ms['u']:.3g} ms ({ms['u'] / ms['d']:.2f}x)")
    s1, s2 = first("BM_StampedeFitS20/threads:1"), first("BM_StampedeFitS20/threads:2")
    if s1 and s2:
        print(f"- `stampede fit`, 10,000 S/N 20 stamps, whole process: {s1['items_per_second']:.0f} objects/s on 1 "
              f"thread, {s2['items_per_second']:.0f} on 2 ({s2['items_per_second'] / s1['items_per_second']:.2f}x; "
              f"targets >= 2,500 objects/s and >= 1.9x)")
    one = all_runs.get("BM_OneEpoch/real_time")
    four = all_runs.get("BM_FourEpochs/real_time")
    if one and four:
        print(f"- multi-epoch: four cutouts {seconds(four) / seconds(one):.2f}x one (target <= 4.5)")
    band1 = all_runs.get("BM_OneBandFourEpochs/real_time")
    band3 = all_runs.get("BM_ThreeBandsFourEpochs/real_time")
    if band1 and band3:
        print(f"- multi-band: three bands of four cutouts {seconds(band3) / seconds(band1):.2f}x one band's (target <= 3)")
    one_fit = all_runs.get("BM_OneFit/real_time")
    mcal = all_runs.get("BM_Metacal/real_time")
    if one_fit and mcal:
        print(f"- metacal: {seconds(mcal) / seconds(one_fit):.2f}x one fit (target <= 6)")
    p1 = all_runs.get("BM_PythonFitStamps/threads:1")
    p2 = all_runs.get("BM_PythonFitStamps/threads:2")
    call = all_runs.get("BM_PythonFitterCall")
    if p1 and p2:
        print(f"- Python fit_stamps 2-thread speed-up: {p2['items_per_second'] / p1['items_per_second']:.2f}x (target >= 1.8)")
    if call and p1:
        over = call["ms_per_stamp"] - p1["ms_per_stamp"]
        print(f"- Python one-stamp call (Fitter.fit): {call['ms_per_stamp']:.3f} ms per stamp against fit_stamps' "
              f"{p1['ms_per_stamp']:.3f} ms on 1 thread: {100 * over / p1['ms_per_stamp']:+.1f} %; wall beyond the "
              f"fit's own time_us {call['overhead_ms_per_stamp']:.4f} ms = "
              f"{100 * call['overhead_ms_per_stamp'] / call['fit_ms_per_stamp']:.2f} % of a fit (target <= 10 %)")


if __name__ == "__main__":
    main()
