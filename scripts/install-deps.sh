#!/usr/bin/env bash
# Installs mskseg's build dependencies from Debian 12 packages (run as root).
#   scripts/install-deps.sh            what building and testing mskseg needs
#   scripts/install-deps.sh workflow   also Snakemake, SLURM and munge (the cohort workflow in workflow/ and its test)
# Skips apt entirely when every package is already installed, so a second run is fast.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev
  libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libopencv-dev
  libvtk9-dev
  libnifti2-dev zlib1g-dev
  libssl-dev
  nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang-format
  clang libclang-rt-14-dev   # the sanitizer build and the libFuzzer programs (scripts/sanitize.sh, scripts/fuzz.sh)
  chromium                   # the test that loads the cohort QC page (report.html) in a real browser, headless
  libxml2-utils              # xmllint: the test that validates the 3D Slicer module descriptions (mskseg segment --xml)
)

WORKFLOW_PACKAGES=(slurm-wlm munge snakemake)
[ "${1:-}" = workflow ] && PACKAGES+=("${WORKFLOW_PACKAGES[@]}")

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages already installed" >&2
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
# Snakemake pulls in tens of thousands of Python files whose byte-compiling at install time takes most of a minute;
# py3compile is diverted to /bin/true for the install (Python compiles what it imports, when it imports it).
diverted=0
if [[ " ${missing[*]} " == *" snakemake "* ]] && [ -x /usr/bin/py3compile ]; then
  $SUDO dpkg-divert --local --rename --divert /usr/bin/py3compile.mskseg --add /usr/bin/py3compile >/dev/null
  $SUDO ln -sf /bin/true /usr/bin/py3compile
  diverted=1
fi
restore() {
  if [ "$diverted" = 1 ]; then
    $SUDO rm -f /usr/bin/py3compile
    $SUDO dpkg-divert --local --rename --divert /usr/bin/py3compile.mskseg --remove /usr/bin/py3compile >/dev/null
  fi
}
trap restore EXIT
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done" >&2
