#!/usr/bin/env bash
# Run (or resume) the windows study (docs/study/windows/README.md): the experiment files here, in
# order, each into its own folder (docs/study/windows/NAME/, or $STUDY_OUT/NAME/). A folder's
# committed results.csv is all resuming needs (supervisor/experiment/resume.py). One run at a time
# (JOBS=2: two).
#   bash docs/study/windows/run.sh [PREFIX…]        e.g. run.sh w01 w04 (default: every file)
#   bash docs/study/windows/run.sh --solomon DIR     make the Solomon instances (w19, w20) from
#                                                     Solomon's files in DIR, then stop
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${STUDY_OUT:-$here}
mrta=${MRTA:-mrta}
if [[ "${1:-}" == --solomon ]]; then
  dir=${2:?"the folder of the Solomon files (C101.txt …)"}
  for t in 1 2; do
    mkdir -p "$here/solomon25-type$t"
    for f in "$dir"/{C,R,RC}$t[0-9][0-9].txt; do
      [[ -e "$f" ]] || continue
      "$mrta" instance generate solomon --file "$f" --robots 5 --tasks 25 \
          -o "$here/solomon25-type$t/$(basename "$f" .txt).yaml" || exit 1
    done
  done
  exit 0
fi
metrics=metrics.completed,metrics.served_in_window,metrics.served_gap,metrics.missed,metrics.lateness,metrics.total_distance,takeover_seconds
for file in "$here"/w[0-9][0-9]-*.yaml; do
  name=$(basename "$file" .yaml)
  if [[ $# -gt 0 ]]; then
    keep=0; for p in "$@"; do [[ "$name" == "$p"* ]] && keep=1; done
    [[ $keep == 1 ]] || continue
  fi
  echo "== $(date -u +%H:%M:%S) $name (load $(cut -d' ' -f1-3 /proc/loadavg))"
  "$mrta" experiment run "$file" --output "$out/$name" --jobs "${JOBS:-1}" --no-plots \
      --metrics "$metrics" || echo "== $name: exit $?"
  find "$out/$name" -maxdepth 1 -type d -name 'run[0-9]*' -exec rm -rf {} +   # run folders: not kept
done
