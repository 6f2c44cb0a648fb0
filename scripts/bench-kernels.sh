#!/usr/bin/env bash
# Builds (Release) and runs the constraint-kernel benchmarks (bench/kernels_bench.cpp), then prints a summary:
# million projections per second on one core for each constraint type at every size, and the scaling exponent b of
# time ∝ N^b fitted over 10³..10⁶ vertices (b ≈ 1: linear). Takes a few minutes.
# Usage: scripts/bench-kernels.sh [extra benchmark flags, e.g. --benchmark_filter=Internal]
# Env: MSK_BUILD_DIR (default build/), MSK_JOBS, MSK_BENCH_MIN_TIME (seconds per case, default 0.1),
#      MSK_BENCH_JSON (where the raw results go, default $MSK_BUILD_DIR/kernels_bench.json).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${MSK_BUILD_DIR:-$here/build}"
jobs="${MSK_JOBS:-$(nproc)}"
json="${MSK_BENCH_JSON:-$build/kernels_bench.json}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "$jobs" --target kernels_bench >/dev/null
"$build/bench/kernels_bench" --benchmark_min_time="${MSK_BENCH_MIN_TIME:-0.1}" \
  --benchmark_out="$json" --benchmark_out_format=json "$@"
python3 - "$json" <<'EOF'
import json, math, sys
from collections import defaultdict

runs = json.load(open(sys.argv[1]))["benchmarks"]
series, bigo = defaultdict(list), {}
for r in runs:
    name = r["name"]
    if name.endswith("_BigO"):
        bigo[name[: -len("_BigO")]] = f'{r.get("cpu_coefficient", float("nan")):.3g} {r.get("big_o", "?")}'
    head, _, last = name.rpartition("/")
    family = head if head and last.isdigit() else name
    if r.get("run_type") != "iteration" or "items_per_second" not in r:
        continue
    n = r.get("complexity_n") or r.get("vertices", 0)
    series[family].append((r.get("vertices", 0), n, r["items_per_second"], r["cpu_time"]))

print("\nkernel summary (one core, CPU time): M items/s at N vertices; b = exponent of CPU time ~ N^b (least squares")
print("over the sizes; N = vertices, contacts for BM_CollisionProject); BigO = benchmark's own fit (time unit per N)")
print(f"{'benchmark':34s} {'b':>5s} {'BigO':>16s}  M items/s @ vertices")
for family, pts in series.items():
    pts.sort()
    rates = "  ".join(f"{ips / 1e6:7.2f}@{int(v):>7d}" if v else f"{ips / 1e6:7.2f}" for v, _, ips, _ in pts)
    b = float("nan")
    xs = [math.log(n) for _, n, _, _ in pts if n > 0]
    ys = [math.log(t) for _, n, _, t in pts if n > 0]
    if len(xs) >= 2:
        mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
        b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    print(f"{family:34s} {b:5.2f} {bigo.get(family, ''):>16s}  {rates}")
EOF
