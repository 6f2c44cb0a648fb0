#!/usr/bin/env bash
# A picture of mskseg's outputs as ParaView shows them: the slices of OUT_DIR/image.vti with the meshes' cross-sections
# in the structures' colours, a 3D view and a legend (scripts/paraview-overlay.py, run by pvbatch, offscreen).
#   scripts/viewer-screenshot.sh OUT_DIR PNG [--center X,Y,Z] [--size W,H]
# OUT_DIR is the output folder of `mskseg segment ... --image-export vti`. Needs `scripts/install-deps.sh viewers`.
# Without a DISPLAY, pvbatch (built against X on Debian 12) renders into a private Xvfb. ParaView's messages go to a
# log that is kept only when it fails; an error is one line on stderr and exit code 1 (2 for a usage error).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

fail() { echo "viewer-screenshot: $*" >&2; exit 1; }
if [ $# -lt 2 ]; then
  echo "usage: scripts/viewer-screenshot.sh OUT_DIR PNG [--center X,Y,Z] [--size W,H]" >&2
  exit 2
fi
out_dir="$1"
png="$2"
[ -d "$out_dir" ] || fail "$out_dir: no such folder"
[ -f "$out_dir/image.vti" ] || fail "$out_dir/image.vti: missing (run mskseg segment with --image-export vti)"
compgen -G "$out_dir/*.vtk" >/dev/null || fail "$out_dir: no meshes (*.vtk)"
[ -d "$(dirname "$png")" ] || fail "$(dirname "$png"): no such folder for the picture"

command -v pvbatch >/dev/null || fail "pvbatch not found: run scripts/install-deps.sh viewers (as root)"
# ParaView's Python modules: python3-paraview if installed, else the copy install-deps.sh unpacks (it conflicts with
# libvtk9-dev's python3-vtk9 on Debian 12), first on the path so that its vtkmodules is ParaView's own.
if ! dpkg-query -W -f='${Status}' python3-paraview 2>/dev/null | grep -q 'install ok installed'; then
  modules="${MSK_PARAVIEW_PYTHON:-/opt/mskseg/python3-paraview}/usr/lib/python3/dist-packages"
  [ -f "$modules/paraview/simple.py" ] || fail "$modules: no ParaView Python modules: run install-deps.sh viewers"
  export PYTHONPATH="$modules${PYTHONPATH:+:$PYTHONPATH}"
fi

log="$(mktemp)"
xvfb_pid=""
cleanup() {
  rm -f "$log" "$log.display" "$log.xvfb"
  if [ -n "$xvfb_pid" ]; then kill "$xvfb_pid" 2>/dev/null || true; wait "$xvfb_pid" 2>/dev/null || true; fi
}
trap cleanup EXIT
# Without a display, a private Xvfb: -displayfd makes it take a free display number and write it once it accepts
# connections, so that two runs at once neither collide nor connect too early.
if [ -z "${DISPLAY:-}" ]; then
  command -v Xvfb >/dev/null || fail "no DISPLAY and no Xvfb: run scripts/install-deps.sh viewers"
  Xvfb -displayfd 3 -screen 0 1280x1024x24 -nolisten tcp 3>"$log.display" >"$log.xvfb" 2>&1 &
  xvfb_pid=$!
  for _ in $(seq 100); do
    if grep -q '^[0-9][0-9]*$' "$log.display" 2>/dev/null || ! kill -0 "$xvfb_pid" 2>/dev/null; then break; fi
    sleep 0.1
  done
  grep -q '^[0-9][0-9]*$' "$log.display" || fail "Xvfb did not start: $(tail -n 1 "$log.xvfb")"
  DISPLAY=":$(cat "$log.display")"
  export DISPLAY
fi

start=$SECONDS
if ! pvbatch "$here/paraview-overlay.py" "$@" >"$log" 2>&1; then
  # The script's own one-line error if it gave one, else where ParaView's output stopped.
  line="$(grep -a '^paraview-overlay: ' "$log" | tail -n 1 || true)"
  if [ -n "$line" ]; then
    echo "viewer-screenshot: ${line#paraview-overlay: }" >&2
  else
    kept="$(mktemp --suffix=.log /tmp/viewer-screenshot.XXXXXX)"
    sed 's/\x1b\[[0-9;]*m//g' "$log" >"$kept"
    echo "viewer-screenshot: pvbatch failed ($(grep -av '^\s*$' "$kept" | tail -n 1)); its output is in $kept" >&2
  fi
  exit 1
fi
echo "viewer-screenshot: wrote $png ($((SECONDS - start)) s)" >&2
