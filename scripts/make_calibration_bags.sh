#!/usr/bin/env bash
# Writes the calibration benchmark's simulator bags (outside git; default
# _build/main/calib_bags, or the folder given as the first argument): COUNT configs with known
# camera-IMU calibrations (make_calibration_configs: time offsets over -50..+50 ms, readouts over
# 0..33 ms, all 24 signed axis permutations turned by 1-5 degrees, gyro biases up to 0.01 rad/s),
# each simulated twice, with OIS (cal_<i>_ois.bag) and without (cal_<i>_nonois.bag, the twin), plus
# manifest.txt for calibration_benchmark. Base config config/simulator/sample.yaml (RE at 256x192,
# to keep rendering cheap: a hand-held shot, not a calibration recording), DURATION seconds per
# bag, lz4 compression. Also protocol/: the same COUNT calibrations recorded the way README
# "Calibration" asks for (config/simulator/calibration.yaml: 360x270, 10 s of deliberate turns
# about all three axes facing a scene 4 m away or more), OIS and twin (protocol/manifest.txt);
# and runtime/: one 10 s pair at the standard 360x270 (config/simulator/RE.yaml with a known
# calibration), for timing calibrate (runtime/manifest.txt).
# SEED picks the calibrations (and the simulations' seeds); another seed gives an independent set,
# e.g. to check on fresh bags a figure chosen on the default one.
#   bash scripts/make_calibration_bags.sh [DIR] [COUNT=24] [DURATION=5] [SEED=7]
#   rosrun deep_ois calibration_benchmark --manifest DIR/manifest.txt
#   rosrun deep_ois calibration_benchmark --manifest DIR/protocol/manifest.txt
# Re-running skips bags that already exist (delete them to regenerate).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
out="${1:-$build_dir/calib_bags}"
count="${2:-24}"
duration="${3:-5}"
seed="${4:-7}"
mkdir -p "$out"

jobs_file="$(mktemp)"
trap 'rm -f "$jobs_file"' EXIT

# One set: COUNT configs from BASE (SEED, so every set has the same calibrations), each simulated
# with OIS and as its twin for SECONDS, queued in $jobs_file and listed in DIR/manifest.txt.
add_set() {
  local base="$1" dir="$2" seconds="$3" i ois name bag
  mkdir -p "$dir"
  rosrun deep_ois make_calibration_configs --base "$base" --count "$count" --seed "$seed" --out "$dir" |
    tee "$dir/truth.txt"
  : >"$dir/manifest.txt"
  for ((i = 0; i < count; ++i)); do
    name="$(printf 'cal_%02d' "$i")"
    for ois in off on; do
      bag="${name}_$([ "$ois" = on ] && echo ois || echo nonois).bag"
      echo "$dir/$name.yaml $((500 + i + 100 * (seed - 7))) $seconds $ois $dir/$bag" >>"$jobs_file"
      echo "$bag $name.yaml" >>"$dir/manifest.txt"
    done
  done
}
add_set "$repo/config/simulator/sample.yaml" "$out" "$duration"               # hand-held shots
add_set "$repo/config/simulator/calibration.yaml" "$out/protocol" 10          # the protocol

# The 10 s runtime pair at 360x270.
mkdir -p "$out/runtime"
rosrun deep_ois make_calibration_configs --base "$repo/config/simulator/RE.yaml" --count 1 --seed 11 \
  --out "$out/runtime" >"$out/runtime/truth.txt"
: >"$out/runtime/manifest.txt"
for ois in off on; do
  bag="runtime_10s_$([ "$ois" = on ] && echo ois || echo nonois).bag"
  echo "$out/runtime/cal_00.yaml 900 10 $ois $out/runtime/$bag" >>"$jobs_file"
  echo "$bag cal_00.yaml" >>"$out/runtime/manifest.txt"
done

started=$(date +%s)
echo "make_calibration_bags: $((4 * count + 2)) bags into $out with $(nproc) parallel simulators"
# shellcheck disable=SC2016
xargs -P "$(nproc)" -L 1 bash -c '
  [ -s "$4" ] && { echo "exists: $4"; exit 0; }
  rosrun deep_ois simulate --config "$0" --seed "$1" --duration "$2" --ois "$3" --out "$4.tmp" \
    --compression lz4 --quiet && mv "$4.tmp" "$4"' <"$jobs_file"
echo "make_calibration_bags: done in $(( $(date +%s) - started )) s: $out"
