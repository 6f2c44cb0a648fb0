#!/usr/bin/env bash
# One case of the workflow: run-case.sh EXIT_FILE LOG_FILE COMMAND... runs the case's `mskseg segment` with its
# output in LOG_FILE. An input the program refuses (exit 1 or 2) is a result, not a failed job: its exit code goes to
# EXIT_FILE, the job succeeds, and `mskseg collect` lists the case as failed with its error. A run ended otherwise (a
# cancelled or timed-out job, a crash) writes nothing and fails the job, so that a rerun does the case again.
set -u
exit_file=$1
log=$2
shift 2
"$@" >"$log" 2>&1
rc=$?
if [ "$rc" -le 2 ]; then
  echo "$rc" >"$exit_file.tmp" && mv "$exit_file.tmp" "$exit_file"
  exit 0
fi
exit "$rc"
