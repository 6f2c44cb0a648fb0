#!/usr/bin/env bash
# The main job on the bundled sample: install dependencies, build, segment the bundled thigh phantom
# (femur + three muscle compartments, from the mean-anatomy templates in its scene.json), score the result
# against the phantom's exact labels, and say where everything is.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$here/scripts/install-deps.sh"
bash "$here/scripts/build.sh"
exe="${MSK_BUILD_DIR:-$here/build}/apps/mskseg"
sample="$here/data-samples/thigh-seed1"
out="${MSK_OUT_DIR:-$here/out/sample}"  # replaced on a rerun; a folder this script did not write is refused
source "$here/scripts/output-folder.sh"
prepare_output_folder run-sample "$out"
"$exe" info "$sample/image.nii.gz"
"$exe" segment --image "$sample/image.nii.gz" --scene "$sample/scene.json" --out "$out"
echo "== result vs the phantom's exact labels (1 femur, 2 quadriceps, 3 hamstrings, 4 adductors)"
"$exe" eval --result "$out/labels.nii.gz" --reference "$sample/labels.nii.gz" --json "$out/metrics.json"
echo "outputs in $out:"
echo "  meshes (LPS, open in 3D Slicer/ParaView): $(cd "$out" && ls *.vtk | tr '\n' ' ')"
echo "  labels.nii.gz (input grid), report.json (parameters, timings, steps), metrics.json, qc/*.png"
