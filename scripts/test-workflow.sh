#!/usr/bin/env bash
# Installs what the cohort workflow needs (Snakemake, SLURM, munge), builds mskseg, and runs the workflow on a
# single-node SLURM started for the test (tests/workflow/slurm_workflow_test.sh); run as root.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$here/scripts/install-deps.sh" workflow
bash "$here/scripts/build.sh"
bash "$here/tests/workflow/slurm_workflow_test.sh" "${MSK_BUILD_DIR:-$here/build}/apps/mskseg"
