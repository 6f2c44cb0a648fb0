#!/usr/bin/env bash
# The calibration cases of the quality check (docs/measurements.md, "Knowing when a segmentation failed"): the bundled
# thigh scene run correctly, on five more phantom seeds, and where it cannot succeed (its templates moved 30 mm along
# x, pure noise of the image's mean and spread on its grid, a constant image, the abdominal MR, the pelvis CT as it is
# and with the templates centred in it); prints each object's quality figures from report.json. Usage:
# bash scripts/quality-calibration.sh [CASE ...] (default: all; cases: bundled moved noise constant mr ct ct-centred
# seed2 ... seed6). Needs a build, python3 and ../shared/data for mr/ct. Environment: MSKSEG (the program; default
# build/apps/mskseg), MSK_OUT_DIR (the output folder: new, empty, or an earlier output of this script; default a new
# temporary folder), QUALITY (the preset, default balanced).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exe="${MSKSEG:-${MSK_BUILD_DIR:-$here/build}/apps/mskseg}"
data="$here/../shared/data"
sample="$here/data-samples/thigh-seed1"
out="${MSK_OUT_DIR:-}"
quality="${QUALITY:-balanced}"
[ -x "$exe" ] || { echo "quality-calibration: build first (bash scripts/build.sh)" >&2; exit 1; }
source "$here/scripts/output-folder.sh"
if [ -z "$out" ]; then out="$(mktemp -d "${TMPDIR:-/tmp}/mskseg-quality-calibration.XXXXXX")"; fi
prepare_output_folder quality-calibration "$out"
echo "quality-calibration: writing into $out" >&2
mkdir -p "$out/inputs"

# Inputs made from the bundled sample: noise.nii.gz and constant.nii.gz on its grid (int16, header kept), and the
# scene's templates moved 30 mm along LPS x (moved/) and centred on the CT's grid centre (ct-centred/).
python3 - "$sample" "$out/inputs" <<'PY'
import gzip, json, os, random, re, struct, sys
src, dst = sys.argv[1], sys.argv[2]
raw = gzip.open(os.path.join(src, "image.nii.gz")).read()
dims = struct.unpack("<8h", raw[40:56]); offset = int(struct.unpack("<f", raw[108:112])[0])
assert struct.unpack("<h", raw[70:72])[0] == 4, "the sample is int16"
n = dims[1] * dims[2] * dims[3]
vals = struct.unpack("<%dh" % n, raw[offset:offset + 2 * n])
mean = sum(vals) / n; sd = (sum((v - mean) ** 2 for v in vals) / n) ** 0.5
random.seed(7)
def write(name, values):
    gzip.open(os.path.join(dst, name), "wb").write(raw[:offset] + struct.pack("<%dh" % n, *values) + raw[offset + 2 * n:])
write("noise.nii.gz", [max(-32768, min(32767, round(random.gauss(mean, sd)))) for _ in range(n)])
write("constant.nii.gz", [round(mean)] * n)
scene = json.load(open(os.path.join(src, "scene.json")))
def points(name):
    t = open(os.path.join(src, name), "rb").read()
    m = re.search(rb"POINTS (\d+) double\n", t); k = int(m.group(1))
    return t, m.end(), k, list(struct.unpack(">%dd" % (3 * k), t[m.end():m.end() + 24 * k]))
meshes = {o["template"]: points(o["template"]) for o in scene["objects"]}
allp = [p[3 * i:3 * i + 3] for (_, _, k, p) in meshes.values() for i in range(k)]
centroid = [sum(q[a] for q in allp) / len(allp) for a in range(3)]
ct_centre_lps = [-3.5437, -161.319, 260.8018]  # the centre of totalseg-ct's grid (mskseg info), LPS mm
for folder, shift in (("moved", [30.0, 0.0, 0.0]), ("ct-centred", [ct_centre_lps[a] - centroid[a] for a in range(3)])):
    os.makedirs(os.path.join(dst, folder), exist_ok=True)
    for name, (t, s, k, p) in meshes.items():
        q = [p[i] + shift[i % 3] for i in range(3 * k)]
        open(os.path.join(dst, folder, name), "wb").write(t[:s] + struct.pack(">%dd" % (3 * k), *q) + t[s + 24 * k:])
    json.dump(scene, open(os.path.join(dst, folder, "scene.json"), "w"), indent=1)
PY

run() {  # NAME IMAGE SCENE
  rm -rf "$out/$1"
  "$exe" segment --image "$2" --scene "$3" --out "$out/$1" --quality "$quality" --no-qc > "$out/$1.log" 2>&1 || true
  if [ ! -f "$out/$1/report.json" ]; then  # refused before any work (a constant image, templates outside it)
    echo "== $1: refused: $(tail -1 "$out/$1.log")"
    return
  fi
  python3 - "$1" "$out/$1/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[2]))
print("== %s: %s" % (sys.argv[1], r["status"]))
for o in r["objects"]:
    q = o["quality"]
    print("  %-12s %-8s in image %.2f  edge share %.3f  contrast-to-noise %5.2f%s" % (o["name"], q["status"],
          q["in_image_share"], q["edge_share"], q["contrast_to_noise"], "" if q["contrast_judged"] else " (not judged)"))
PY
}
cases=("$@")
[ ${#cases[@]} -gt 0 ] || cases=(bundled moved noise constant mr ct ct-centred seed2 seed3 seed4 seed5 seed6)
for c in "${cases[@]}"; do
  case "$c" in
    bundled) run bundled "$sample/image.nii.gz" "$sample/scene.json" ;;
    moved) run moved "$sample/image.nii.gz" "$out/inputs/moved/scene.json" ;;
    noise) run noise "$out/inputs/noise.nii.gz" "$sample/scene.json" ;;
    constant) run constant "$out/inputs/constant.nii.gz" "$sample/scene.json" ;;
    mr) run thigh-on-mr "$data/totalseg-mr/mr.nii.gz" "$sample/scene.json" ;;
    ct) run thigh-on-ct "$data/totalseg-ct/ct.nii.gz" "$sample/scene.json" ;;
    ct-centred) run thigh-centred-in-ct "$data/totalseg-ct/ct.nii.gz" "$out/inputs/ct-centred/scene.json" ;;
    seed*)
      s="${c#seed}"
      [ -f "$out/inputs/phantom$s/image.nii.gz" ] || "$exe" --quiet phantom --seed "$s" --out "$out/inputs/phantom$s"
      run "$c" "$out/inputs/phantom$s/image.nii.gz" "$out/inputs/phantom$s/scene.json" ;;
    *) echo "quality-calibration: unknown case $c" >&2; exit 2 ;;
  esac
done
