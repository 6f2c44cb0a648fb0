#!/usr/bin/env bash
# A real CT from the command line alone (../shared/data/totalseg-ct, 3 mm voxels): the right femur, hip bone, gluteus
# maximus and gluteus medius segmented together from templates built out of the LEFT side's labels (`mskseg scene`),
# mirrored across the midline (the x of the sacrum's centroid, label 25), each learning its intensity profiles on the
# left structure it came from; the bones take the refinement pass. Then each result is scored against the right side's labels. The
# templates start where the mirror puts them (the test RealScenes.CtFemurHipAndGlutealMusclesOfOneSide also displaces
# and scales them). Usage: bash scripts/ct-example.sh [DATA_DIR [OUT_DIR]] (default ../shared/data and a new temporary
# folder; OUT_DIR must be new, empty, or an earlier output of this script); needs a build. Environment: MSKSEG (the
# program; default build/apps/mskseg), MSK_OUT_DIR (OUT_DIR when not given).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exe="${MSKSEG:-${MSK_BUILD_DIR:-$here/build}/apps/mskseg}"
data="${1:-$here/../shared/data}/totalseg-ct"
out="${2:-${MSK_OUT_DIR:-}}"
[ -x "$exe" ] || { echo "ct-example: build first (bash scripts/build.sh)" >&2; exit 1; }
[ -f "$data/ct.nii.gz" ] || { echo "ct-example: $data/ct.nii.gz not found" >&2; exit 1; }
source "$here/scripts/output-folder.sh"
if [ -z "$out" ]; then out="$(mktemp -d "${TMPDIR:-/tmp}/mskseg-ct-example.XXXXXX")"; fi
prepare_output_folder ct-example "$out"
echo "ct-example: writing into $out" >&2

# The scene: each right-side object's template from the left side's label, mirrored across the midline (x of the
# sacrum's centroid, label 25), learning its profiles there; every pair may touch; the bones refine.
"$exe" scene --labels "$data/labels.nii.gz" --midline-label 25 --collisions all --refine-bones --out "$out/scene" \
  --objects femur_right:76:75:bone,hip_right:78:77:bone,gluteus_maximus_right:81:80:muscle,gluteus_medius_right:83:82:muscle

# The settings of the CT test: the global prior ends at 0.2, the finest search reaches ±1 voxel on an image
# smoothed at 1 voxel.
"$exe" segment --image "$data/ct.nii.gz" --scene "$out/scene/scene.json" --out "$out/result" \
  --prior-end 0.2 --range-fine 1 --sigma-fine 1
echo "== result vs the right side's labels (76 femur, 78 hip bone, 81 gluteus maximus, 83 gluteus medius)"
"$exe" eval --result "$out/result/labels.nii.gz" --reference "$data/labels.nii.gz" --labels 76,78,81,83 \
  --json "$out/metrics.json"
echo "outputs in $out: scene/ (scene.json, templates/), result/ (meshes LPS, labels.nii.gz, report.json, qc/), metrics.json"
