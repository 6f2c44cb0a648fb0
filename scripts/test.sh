#!/usr/bin/env bash
# Installs dependencies, builds everything and runs the whole test suite (CTest).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$here/scripts/install-deps.sh"
bash "$here/scripts/build.sh"
cd "${MSK_BUILD_DIR:-$here/build}"
ctest --output-on-failure -j "${MSK_JOBS:-$(nproc)}" --timeout 900
