#!/usr/bin/env bash
# Installs mskseg's build dependencies from Debian 12 packages (run as root).
#   scripts/install-deps.sh            what building and testing mskseg needs
#   scripts/install-deps.sh workflow   also Snakemake, SLURM and munge (the cohort workflow in workflow/ and its test)
#   scripts/install-deps.sh viewers    also ParaView (pvbatch, paraview.simple) and Xvfb (scripts/viewer-screenshot.sh)
# Groups combine: scripts/install-deps.sh workflow viewers.
# Skips apt entirely when every package is already installed, so a second run is fast. Never removes a package: an
# install that would (a conflict) fails instead.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev
  libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libopencv-dev libpng-dev libjpeg-dev   # drawing (OpenCV core, imgproc); PNG and JPEG files (libpng, libjpeg)
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
# ParaView's Python modules (paraview.simple, its own vtkmodules) are in python3-paraview, which Debian 12 declares in
# conflict with python3-vtk9, a dependency of libvtk9-dev: both ship the Python package vtkmodules. So that mskseg's
# build keeps libvtk9-dev, python3-paraview is unpacked (same version as paraview, not registered with dpkg) into
# $PARAVIEW_PYTHON, which scripts/viewer-screenshot.sh puts first on pvbatch's PYTHONPATH.
VIEWER_PACKAGES=(paraview xvfb)
PARAVIEW_PYTHON=/opt/mskseg/python3-paraview
viewers=0
for group in "$@"; do
  case "$group" in
    workflow) PACKAGES+=("${WORKFLOW_PACKAGES[@]}") ;;
    viewers) PACKAGES+=("${VIEWER_PACKAGES[@]}"); viewers=1 ;;
    *) echo "install-deps: unknown group '$group' (workflow, viewers)" >&2; exit 2 ;;
  esac
done

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

# Unpacks python3-paraview of paraview's installed version into $PARAVIEW_PYTHON (see VIEWER_PACKAGES), unless it is
# there already or python3-paraview is installed.
unpack_paraview_python() {
  if dpkg-query -W -f='${Status}' python3-paraview 2>/dev/null | grep -q 'install ok installed'; then return; fi
  local version
  version="$(dpkg-query -W -f='${Version}' paraview)"
  if [ "$(cat "$PARAVIEW_PYTHON/VERSION" 2>/dev/null)" = "$version" ]; then return; fi
  echo "install-deps: unpacking python3-paraview $version into $PARAVIEW_PYTHON" >&2
  local tmp
  tmp="$(mktemp -d)"
  chmod 755 "$tmp" && { chown _apt "$tmp" 2>/dev/null || true; }   # apt downloads as _apt where it may write
  if ! (cd "$tmp" && $SUDO apt-get download -qq "python3-paraview=$version" 2>/dev/null); then
    $SUDO apt-get update -qq
    (cd "$tmp" && $SUDO apt-get download -qq "python3-paraview=$version")
  fi
  $SUDO rm -rf "$PARAVIEW_PYTHON.new"
  $SUDO mkdir -p "$PARAVIEW_PYTHON.new"
  $SUDO dpkg-deb -x "$tmp"/python3-paraview_*.deb "$PARAVIEW_PYTHON.new"
  echo "$version" | $SUDO tee "$PARAVIEW_PYTHON.new/VERSION" >/dev/null
  $SUDO rm -rf "$PARAVIEW_PYTHON" "$tmp"
  $SUDO mv "$PARAVIEW_PYTHON.new" "$PARAVIEW_PYTHON"
}

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages already installed" >&2
  if [ "$viewers" = 1 ]; then unpack_paraview_python; fi
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
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
$SUDO apt-get install -y -qq --no-install-recommends --no-remove "${missing[@]}" >/dev/null
if [ "$viewers" = 1 ]; then unpack_paraview_python; fi
echo "install-deps: done" >&2
