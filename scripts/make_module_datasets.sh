#!/usr/bin/env bash
# Writes training and evaluation splits for the committed stabiliser modules and cameras of
# config/simulator/modules/ (outside git; default _build/main/module_datasets):
#   <module>/train/RE_<seed>.bag            training split: TRAIN_SEQUENCES x 5 s of rich texture
#   <module>/eval/<CAT>_<seed>.bag          evaluation: per category RE, LT, LL, MF, EVAL_SEQUENCES
#   <module>/eval/<CAT>_<seed>_nonois.bag   sequences of 70 frame pairs, each with its non-OIS twin
#   <module>/gyro_flow.yaml                 the gyro flow parameters of the module's camera (its
#                                           readout time), for fundamental_mixtures and evaluate
#
#   make_module_datasets.sh [DIR] [MODULE ...]     (default: every module)
# Environment: TRAIN_SEQUENCES (default 20), EVAL_SEQUENCES (default 2). Seeds: training 3000..,
# evaluation 4000.. (apart from the standard splits' 1000.. and 2000..). One simulator per core;
# re-running skips bags that already exist.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
out="${1:-$build_dir/module_datasets}"
shift || true
config="$repo/config/simulator"
modules=("$@")
if [ "${#modules[@]}" -eq 0 ]; then
  for file in "$config"/modules/*.yaml; do modules+=("$(basename "$file" .yaml)"); done
fi
train_sequences="${TRAIN_SEQUENCES:-20}"
eval_sequences="${EVAL_SEQUENCES:-2}"

jobs_file="$(mktemp)"
trap 'rm -f "$jobs_file"' EXIT
for module in "${modules[@]}"; do
  overlay="$config/modules/$module.yaml"
  [ -f "$overlay" ] || { echo "make_module_datasets: no module '$module' ($overlay)" >&2; exit 2; }
  mkdir -p "$out/$module/train" "$out/$module/eval"
  # The camera's readout time for the gyro flow (the only camera parameter it does not read from
  # camera_info); everything else as the package's config/gyro_flow.yaml.
  readout=$(sed -n 's/^ *readout_time_s: *\([0-9.eE+-]*\).*/\1/p' "$overlay")
  sed "s/^readout_time: .*/readout_time: ${readout:-0.022}/" "$repo/config/gyro_flow.yaml" \
    >"$out/$module/gyro_flow.yaml"
  for seed in $(seq 3000 $((3000 + train_sequences - 1))); do
    echo "$config/RE.yaml $overlay $seed 5.0 on $out/$module/train/RE_$seed.bag" >>"$jobs_file"
  done
  for cat in RE LT LL MF; do
    for seed in $(seq 4000 $((4000 + eval_sequences - 1))); do
      echo "$config/$cat.yaml $overlay $seed 2.3334 on $out/$module/eval/${cat}_$seed.bag" >>"$jobs_file"
      echo "$config/$cat.yaml $overlay $seed 2.3334 off $out/$module/eval/${cat}_${seed}_nonois.bag" >>"$jobs_file"
    done
  done
done

started=$(date +%s)
total=$(wc -l <"$jobs_file")
echo "make_module_datasets: $total bags for ${#modules[@]} modules into $out with $(nproc) parallel simulators"
# shellcheck disable=SC2016
xargs -P "$(nproc)" -L 1 bash -c '
  [ -s "$5" ] && { echo "exists: $5"; exit 0; }
  rosrun deep_ois simulate --config "$0" --overlay "$1" --seed "$2" --duration "$3" --ois "$4" \
    --out "$5.tmp" --quiet --compression lz4 && mv "$5.tmp" "$5"' <"$jobs_file"
echo "make_module_datasets: done in $(( $(date +%s) - started )) s: $out"
