#!/usr/bin/env bash
# Configures and builds mskseg (Release) into build/ (or $MSK_BUILD_DIR). Assumes dependencies are installed.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${MSK_BUILD_DIR:-$here/build}"
jobs="${MSK_JOBS:-$(nproc)}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" -j "$jobs"
