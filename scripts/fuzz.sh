#!/usr/bin/env bash
# Builds the libFuzzer programs (clang, AddressSanitizer + UndefinedBehaviorSanitizer) in scripts/sanitize.sh's build
# folder, build-sanitize/ (or $MSK_SANITIZE_BUILD_DIR), and fuzzes each target for SECONDS (default 30), starting
# from its seed corpus and regression inputs.
#   scripts/fuzz.sh [SECONDS] [TARGET...]   (targets: every one in fuzz/CMakeLists.txt by default)
# Limits: an input may take 30 s; one allocation over 1 GB or a process over 2 GB resident is a finding. The targets
# whose reader runs VTK in a child process (mesh_vtp, mesh_stl, tet_vtu, image_vti) get 150 s per input and no
# libFuzzer memory limits: the child inherits libFuzzer's malloc hooks, which would report the child's allocations as
# the fuzzer's own, and the child has its own bounds (60 s of CPU, 3 GB).
# Prints one line per target (runs, seconds, coverage, corpus size). Crashes, leaks, out-of-memory and timeouts are
# kept in the build folder's fuzz-findings/<target>/ and make the script fail; copy a finding into
# fuzz/regressions/<target>/ once it is fixed. Findings of earlier runs are replayed first: those that no longer fail
# are removed (and named). Inputs slower than 10 s (libFuzzer's slow-unit-*) are reported, not failures.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-30}"
shift || true
build="${MSK_SANITIZE_BUILD_DIR:-$here/build-sanitize}"
jobs="${MSK_JOBS:-$(nproc)}"
all=(nifti mesh_vtk mesh_vtp mesh_stl mesh_obj mesh_ply tet_vtu image_vti scene atlas transform)
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all[@]}")

bash "$here/scripts/sanitize.sh" configure
cmake --build "$build" -j "$jobs" --target $(printf 'fuzz_%s ' "${targets[@]}")

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
failed=0
for t in "${targets[@]}"; do
  work="$build/fuzz-corpus/$t"
  findings="$build/fuzz-findings/$t"
  mkdir -p "$work" "$findings"
  limits=(-timeout=30 -malloc_limit_mb=1024 -rss_limit_mb=2048)
  case "$t" in mesh_vtp | mesh_stl | tet_vtu | image_vti) limits=(-timeout=150 -malloc_limit_mb=0 -rss_limit_mb=0) ;; esac
  # Earlier findings: replayed; the fixed ones go.
  for f in "$findings"/*; do
    [ -f "$f" ] || continue
    case "$(basename "$f")" in slow-unit-*) rm -f "$f"; continue ;; esac
    if (cd "$build" && "./fuzz/fuzz_$t" "${limits[@]}" "$f" >/dev/null 2>&1); then
      echo "fuzz $t: earlier finding $(basename "$f") no longer fails; removed" >&2
      rm -f "$f"
    fi
  done
  dirs=("$work")
  for d in "$here/fuzz/corpus/$t" "$here/fuzz/regressions/$t"; do [ -d "$d" ] && dirs+=("$d"); done
  log="$build/fuzz-$t.log"
  set +e
  (cd "$build" && "./fuzz/fuzz_$t" "${dirs[@]}" \
    -max_total_time="$seconds" -max_len=65536 -artifact_prefix="$findings/" -print_final_stats=1 "${limits[@]}" \
    >"$log" 2>&1)
  rc=$?
  set -e
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo 0)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo 0)
  took=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | grep -o 'in [0-9]*' | grep -o '[0-9]*' || echo "$seconds")
  corpus=$(find "$work" -type f | wc -l)
  slow=$(find "$findings" -name 'slow-unit-*' | wc -l)
  note=""
  [ "$slow" -gt 0 ] && note=" ($slow input(s) slower than 10 s, kept in $findings/)"
  if [ $rc -ne 0 ] || [ -n "$(find "$findings" -type f ! -name 'slow-unit-*')" ]; then
    failed=1
    echo "fuzz $t: FINDING (exit $rc) after ${runs} runs; see $log and $findings/" >&2
    grep -m3 -E 'ERROR|runtime error|mskseg fuzz|deadly signal|out-of-memory|timeout' "$log" >&2 || true
  else
    echo "fuzz $t: ${runs} runs in ${took} s, coverage ${cov}, corpus ${corpus} inputs, no finding$note" >&2
  fi
done
exit $failed
