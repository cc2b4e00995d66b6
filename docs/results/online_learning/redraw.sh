#!/bin/bash
# Redraws every learning curve of this folder from its CSV with scripts/plot_csv.py, with the
# options benchmark_online_learning --plot gives it (src/tools/benchmark_online_learning.cpp).
#   bash docs/results/online_learning/redraw.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
plot="$here/../../../scripts/plot_csv.py"
for csv in "$here"/*.csv; do
  png="${csv%.csv}.png"
  if [[ "$csv" == *_no_ois.csv ]]; then
    title="benchmark_online_learning (camera without OIS): compensation against the plain gyro"
    y_label="worse than the plain gyro [%], capped"
    lines=(--hline 0)
  else
    title="benchmark_online_learning: gap to the non-OIS twin closed"
    y_label="gap closed to the non-OIS twin [%], capped"
    lines=(--hline 0 --hline 100)
  fi
  /usr/bin/python3 "$plot" "$csv" "$png" --x window_end_s \
    --x-label "replay time at the end of the window of 10 s [s]" \
    --series learning_pct "learning online" line 1 --series fixed_pct "fixed starting model" line 1 \
    --y-label "$y_label" "${lines[@]}" --title "$title" --size 1000x500
done
