#!/usr/bin/env bash
# Writes the standard simulator data sets with fixed seeds (outside git; default
# _build/datasets, or the folder given as the first argument):
#   train/RE_<seed>.bag           training split: 60 sequences x 5 s of rich texture, OIS on
#                                 (60 x 150 = 9,000 frame pairs)
#   eval/<CAT>_<seed>.bag         evaluation benchmark: per category RE, LT, LL, MF, 5 sequences of
#   eval/<CAT>_<seed>_nonois.bag  70 frame pairs (350 per category), each with its non-OIS twin
# Runs one simulator per core. Re-running skips bags that already exist (delete to regenerate).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
out="${1:-$build_dir/datasets}"
mkdir -p "$out/train" "$out/eval"
config="$repo/config/simulator"

jobs_file="$(mktemp)"
trap 'rm -f "$jobs_file"' EXIT
# Training: seeds 1000..1059, 5 s each (151 frames, 150 pairs).
for seed in $(seq 1000 1059); do
  echo "$config/RE.yaml $seed 5.0 on $out/train/RE_$seed.bag" >>"$jobs_file"
done
# Evaluation: seeds 2000.. per category, 70 pairs each (71 frames = 70/30 s), OIS on and off.
for cat in RE LT LL MF; do
  for seed in $(seq 2000 2004); do
    echo "$config/$cat.yaml $seed 2.3334 on $out/eval/${cat}_$seed.bag" >>"$jobs_file"
    echo "$config/$cat.yaml $seed 2.3334 off $out/eval/${cat}_${seed}_nonois.bag" >>"$jobs_file"
  done
done

started=$(date +%s)
total=$(wc -l <"$jobs_file")
echo "make_datasets: $total bags into $out with $(nproc) parallel simulators"
# shellcheck disable=SC2016
xargs -P "$(nproc)" -L 1 bash -c '
  [ -s "$4" ] && { echo "exists: $4"; exit 0; }
  rosrun deep_ois simulate --config "$0" --seed "$1" --duration "$2" --ois "$3" --out "$4.tmp" --quiet &&
    mv "$4.tmp" "$4"' <"$jobs_file"
echo "make_datasets: done in $(( $(date +%s) - started )) s: $out"
