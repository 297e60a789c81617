#!/usr/bin/env bash
# The main job, end to end on the virtual KR C4: excite -> capture -> fit -> report/diagnose.
# Usage: scripts/demo.sh OUTDIR   (run by `make demo`, which installs kukaid first)
set -euo pipefail
out=${1:-reports/demo}
mkdir -p "$out"
echo "== kukaid demo: writing into $out"
# -- excitation trajectories (and KRL programs a KR C4 can run)
# -- capture on the virtual KR C4
# -- identification
# -- diagnosis
echo "== demo done: $(ls "$out" | tr '\n' ' ')"
