#!/usr/bin/env bash
# Run (or resume) the study: every experiment file here, in order, into its own folder
# (docs/study/NN-name/, or $STUDY_OUT/NN-name/). A folder's committed results.csv is all
# resuming needs: the runs it already has a row for are not run again (docs/study/README.md).
# One run at a time.
#   bash docs/study/run.sh [FIRST_FILE_PREFIX]     e.g. bash docs/study/run.sh 09
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${STUDY_OUT:-$here}
mrta=${MRTA:-mrta}
metrics=metrics.completed,metrics.makespan,metrics.optimality,metrics.objective_minsum,metrics.objective_makespan,metrics.objective_flowtime,takeover_seconds,coordination_messages_per_second
for file in "$here"/[0-9][0-9]-*.yaml; do
  name=$(basename "$file" .yaml)
  [[ -n "${1:-}" && "$name" < "$1" ]] && continue
  echo "== $(date -u +%H:%M:%S) $name (load $(cut -d' ' -f1-3 /proc/loadavg))"
  "$mrta" experiment run "$file" --output "$out/$name" --jobs 1 --no-plots \
      --metrics "$metrics" || echo "== $name: exit $?"
  find "$out/$name" -maxdepth 1 -type d -name 'run[0-9]*' -exec rm -rf {} +   # run folders: not kept
done
