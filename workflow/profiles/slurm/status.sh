#!/usr/bin/env bash
# Snakemake's --cluster-status for SLURM: prints success, running or failed for job $1 (sbatch --parsable may have
# printed "id;cluster"). Asks scontrol (which knows finished jobs for MinJobAge, 300 s by default), then sacct where
# accounting is kept; a job neither knows is failed, and one asked about while the controller does not answer is
# still running.
id="${1%%;*}"
if answer=$(scontrol show job -o "$id" 2>&1); then
  state=$(grep -o 'JobState=[A-Z_]*' <<<"$answer" | cut -d= -f2)
elif grep -qi 'invalid job id' <<<"$answer"; then
  state=""
else  # the controller did not answer: ask again later
  echo running
  exit 0
fi
if [ -z "$state" ] && command -v sacct >/dev/null; then
  state=$(sacct -n -X -P -j "$id" -o State 2>/dev/null | head -n1 | cut -d' ' -f1)
fi
case "$state" in
  COMPLETED) echo success ;;
  PENDING | CONFIGURING | RUNNING | COMPLETING | SUSPENDED | REQUEUED | REQUEUE_HOLD | REQUEUE_FED | RESIZING | \
    SIGNALING | STAGE_OUT | STOPPED) echo running ;;
  *) echo failed ;;
esac
