#!/usr/bin/env bash
# The compensation benchmark across stabiliser modules and cameras: for every module of the data
# folder written by scripts/make_module_datasets.sh, runs `evaluate` on its evaluation split with
# the module camera's gyro flow parameters and prints, per module, the Avg geometry distance of the
# non-OIS twin, the uncompensated OIS gyro and the model (capped as in the paper, and uncapped) and
# the share of the gap between the two gyro rows that the model closed.
#
#   module_benchmark.sh [DATA_DIR] [--model FILE.pt] [--image-baselines] [--ground-truth]
# (default DATA_DIR _build/main/module_datasets; the model defaults to the package's shipped one).
# Every module's full report goes to DATA_DIR/<module>/benchmark/.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
data="$build_dir/module_datasets"
if [ $# -gt 0 ] && [ "${1#--}" = "$1" ]; then data="$1"; shift; fi
extra=(--no-image-baselines --no-ground-truth)
model=()
while [ $# -gt 0 ]; do
  case "$1" in
    --model) model=(--model "$2"); shift 2 ;;
    --image-baselines) extra=("${extra[@]/--no-image-baselines}"); shift ;;
    --ground-truth) extra=("${extra[@]/--no-ground-truth}"); shift ;;
    *) echo "module_benchmark: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
flags=()
for flag in "${extra[@]}"; do [ -n "$flag" ] && flags+=("$flag"); done

# The Avg column of `row` in the n-th table of a report (1: capped, 2: uncapped).
avg() {  # $1 report, $2 row, $3 table index
  awk -F'|' -v row="$2" -v want="$3" '
    /^\| method \|/ { table++ }
    table == want && $2 == " " row " " { gsub(/ /, "", $(NF-1)); print $(NF-1); exit }' "$1"
}

printf '| module | pairs | non-OIS twin | OIS gyro, uncompensated | model | gap closed | uncapped: OIS gyro | model | gap closed |\n'
printf '|---|---:|---:|---:|---:|---:|---:|---:|---:|\n'
status=0
for dir in "$data"/*/; do
  module="$(basename "$dir")"
  [ -d "$dir/eval" ] || continue
  out="$dir/benchmark"
  mkdir -p "$out"
  report="$out/report.md"
  if ! rosrun deep_ois evaluate --bags "$dir"/eval/*.bag --gyro-config "$dir/gyro_flow.yaml" \
      "${model[@]}" "${flags[@]}" --no-progress --out "$out" >"$report" 2>"$out/evaluate.log"; then
    echo "| $module | evaluate failed: see $out/evaluate.log |"; status=1; continue
  fi
  model_row="$(grep -m1 -o '^| DeepOIS[^|]*' "$report" | sed 's/^| //; s/ *$//')"
  pairs="$(grep -c ',"gyro, OIS camera (uncompensated)",' "$out/evaluation_pairs.csv" || true)"
  gap="$(grep -m1 "^- $model_row:" "$report" | sed 's/.*: //')"
  printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$module" "$pairs" \
    "$(avg "$report" "gyro, non-OIS camera" 1)" "$(avg "$report" "gyro, OIS camera (uncompensated)" 1)" \
    "$(avg "$report" "$model_row" 1)" "$(echo "$gap" | sed 's/ capped.*//')" \
    "$(avg "$report" "gyro, OIS camera (uncompensated)" 2)" "$(avg "$report" "$model_row" 2)" \
    "$(echo "$gap" | sed 's/.*capped, //; s/ uncapped//')"
done
exit "$status"
