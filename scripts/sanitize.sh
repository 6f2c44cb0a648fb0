#!/usr/bin/env bash
# Builds mskseg with clang under AddressSanitizer + UndefinedBehaviorSanitizer (and libFuzzer coverage, so that
# scripts/fuzz.sh reuses the build) into build-sanitize/ (or $MSK_SANITIZE_BUILD_DIR) and runs tests there.
#   scripts/sanitize.sh        the core, imaging, fuzz-replay and CLI tests, then the bundled sample's segmentation
#   scripts/sanitize.sh all    the whole test suite, then the bundled sample's segmentation
#   scripts/sanitize.sh configure   only configures the build folder (scripts/fuzz.sh builds its programs there)
# Any sanitizer report fails the test that produced it (UBSan findings abort; leaks fail at exit).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
what="${1:-ci}"
build="${MSK_SANITIZE_BUILD_DIR:-$here/build-sanitize}"
jobs="${MSK_JOBS:-$(nproc)}"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
  -DMSK_SANITIZE=address,undefined -DMSK_BUILD_FUZZERS=ON -DMSK_BUILD_TESTS=ON -DMSK_BUILD_BENCHMARKS=OFF \
  -DMSK_TEST_TIMEOUT=3600 \
  "${launcher[@]}" >/dev/null
[ "$what" = configure ] && exit 0
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:check_initialization_order=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
start=$(date +%s)
case "$what" in
  ci)
    cmake --build "$build" -j "$jobs" --target mskseg core_tests imaging_tests fuzz_tests apps_tests
    (cd "$build" && ctest --output-on-failure -j "$jobs" --timeout 1800 -L '^(core|imaging|fuzz|apps)$')
    ;;
  all)
    cmake --build "$build" -j "$jobs"
    (cd "$build" && ctest --output-on-failure -j "$jobs" --timeout 3600)
    ;;
  *) echo "usage: scripts/sanitize.sh [ci|all]" >&2; exit 2 ;;
esac
out="$build/sample-run"
rm -rf "$out"
"$build/apps/mskseg" segment --scene "$here/data-samples/thigh-seed1/scene.json" \
  --image "$here/data-samples/thigh-seed1/image.nii.gz" --quality fast --out "$out"
echo "sanitize ($what): tests and the sample segmentation ran under ASan+UBSan with no finding in $(( $(date +%s) - start )) s" >&2
