#!/usr/bin/env bash
# The cohort workflow (workflow/) for real on a single-node SLURM started for the test (scripts/slurm-local.sh):
# three phantom cases and one corrupt image; one running job is cancelled (scancel) and the workflow rerun. The three
# cases must end with the Dice of a local `mskseg batch` of the same cases (metrics.csv identical), the corrupt one
# failed with its one-line error in the summary, and nothing half-written left. The cluster is stopped however the
# test ends. Usage: slurm_workflow_test.sh [MSKSEG] (default build/apps/mskseg); KEEP=1 keeps the work folder.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
M="$(realpath "${1:-$here/build/apps/mskseg}")"
work=$(mktemp -d /tmp/mskseg-workflow-test.XXXXXX)
cleanup() {
  bash "$here/scripts/slurm-local.sh" stop "$work/slurm" || true
  if [ "${KEEP:-0}" = 1 ]; then echo "workflow test: work folder kept: $work" >&2; else rm -rf "$work"; fi
}
trap cleanup EXIT
fail() {
  echo "workflow test: FAILED: $*" >&2
  exit 1
}
start=$(date +%s)
SLURM_CONF=$(bash "$here/scripts/slurm-local.sh" start "$work/slurm")
export SLURM_CONF
export USER="${USER:-$(id -un)}"

# The cohort: the bundled sample (phantom seed 1), phantoms of seeds 2 and 3, and a truncated image.
S="$here/data-samples/thigh-seed1"
mkdir -p "$work/cases/p01" "$work/cases/p99"
ln -s "$S/image.nii.gz" "$work/cases/p01/image.nii.gz"
ln -s "$S/labels.nii.gz" "$work/cases/p01/labels.nii.gz"
for seed in 2 3; do "$M" --quiet phantom --seed "$seed" --out "$work/cases/p0$seed" >/dev/null; done
head -c 20000 "$S/image.nii.gz" >"$work/cases/p99/image.nii.gz"
config=(cases="$work/cases" out="$work/out" scene="$S/scene.json" mskseg="$M" reference=labels.nii.gz
  "segment_options=--quality fast --threads 1")
run() { (cd "$work" && snakemake -s "$here/workflow/Snakefile" --profile "$here/workflow/profiles/slurm" --jobs 2 \
  --config "${config[@]}"); }

# First run: a running job of a good case is cancelled; the run must fail.
run >"$work/run1.log" 2>&1 &
snake=$!
job="" victim=""
for _ in $(seq 1200); do
  for id in $(squeue -h -t RUNNING -o %i); do
    out=$(scontrol show job -o "$id" | grep -o 'StdOut=[^ ]*' | cut -d= -f2)
    case "$out" in */p99.log.slurm) ;; *) job=$id victim=$(basename "$out" .log.slurm) ;; esac
  done
  [ -n "$job" ] && break
  sleep 0.1
done
[ -n "$job" ] || fail "no job of a good case was seen running"
sleep 1
scancel "$job"
if wait "$snake"; then fail "the first run succeeded although job $job ($victim) was cancelled"; fi
[ -f "$work/out/logs/$victim.exit" ] && fail "the cancelled case $victim has an exit code recorded"
echo "workflow test: job $job (case $victim) cancelled; the first run failed" >&2

# Second run: does what is missing, then gathers the tables.
run >"$work/run2.log" 2>&1 || {
  tail -30 "$work/run2.log" >&2
  fail "the rerun failed"
}
summary="$work/out/summary.csv"
for c in p01 p02 p03; do
  grep -q "^$c,ok," "$summary" || fail "case $c is not ok in $summary: $(grep "^$c," "$summary")"
done
grep -q "^p99,failed,.*p99/image.nii.gz: truncated" "$summary" || fail "p99 is not failed with its error: $(grep '^p99,' "$summary")"
partial=$(find "$work/out" -name '*.partial*')
[ -z "$partial" ] || fail "half-written output left: $partial"

# The same cases by a local batch: the same scores.
if "$M" --quiet batch --cases "$work/cases" --scene "$S/scene.json" --out "$work/local" --reference labels.nii.gz \
  -- --quality fast --threads 1; then fail "the local batch succeeded with a corrupt case"; fi
cmp "$work/out/metrics.csv" "$work/local/metrics.csv" || {
  diff "$work/out/metrics.csv" "$work/local/metrics.csv" >&2
  fail "the workflow's scores differ from the local batch's"
}
echo "workflow test: passed in $(($(date +%s) - start)) s: 3 cases ok with the local batch's scores ($(wc -l <"$work/out/metrics.csv") lines of metrics.csv identical), the corrupt one failed with its error, the cancelled one redone, nothing half-written" >&2
