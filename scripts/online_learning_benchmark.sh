#!/usr/bin/env bash
# The cold-start learning curve of the online learner (docs/online_learning.md) for every simulator
# module: per module, hand-held recordings (`RE`, 360x270 unless the module's camera differs) of
# the module and of its non-OIS twin, replayed through benchmark_online_learning from the shipped
# generic model. Long (minutes, a few GB of bags): a benchmark, never run in CI.
#
#   online_learning_benchmark.sh OUTDIR [--modules "pan_release phone_main ..."] [--overlay FILE.yaml ...]
#       [--designs "0 5 10"] [--seeds "6002"] [--duration 60] [--no-ois "pan_release ..."] [--cpu-share 0.3]
#       [-- BENCHMARK_ARGS...]
#
# --modules   modules of config/simulator/modules (default: all of them, unless --overlay or
#             --designs is given)
# --overlay   a stabiliser design outside the repository (a simulator module overlay), run after
#             the modules and reported under its file name (repeatable)
# --designs   generated stabiliser designs by seed (the simulator's `ois: {design_seed: N}`), run
#             after those and reported as design_<seed> with their split: seed % 5 == 0 is the
#             generator's held-out split (never used for a decision), the others training
# --seeds     one recording per seed, replayed one after the other through one learner (more than
#             one: --continue-bags, the stamps of each next recording follow the previous one)
# --no-ois    modules whose non-OIS twin is also replayed as the camera (scored against the gyro)
# Arguments after `--` go to every benchmark_online_learning run.
#
# Writes OUTDIR/bags/<module>_<seed>_on|off.bag (kept: a re-run reuses them), per module
# OUTDIR/<module>.md (the benchmark's report) and OUTDIR/<module>.png (the curve), and prints one
# table: gap closed to the non-OIS twin, capped / uncapped, per window, and the learning's CPU.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
if [ $# -lt 1 ] || [ "${1#--}" != "$1" ]; then sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; fi
out="$1"; shift
config="$repo/config/simulator"
modules=() overlays=() designs=() no_ois=() bench_args=()
seeds="6002" duration=60 cpu_share=0.3
while [ $# -gt 0 ]; do
  case "$1" in
    --modules) read -r -a modules <<<"$2"; shift 2 ;;
    --overlay) overlays+=("$2"); shift 2 ;;
    --designs) read -r -a designs <<<"$2"; shift 2 ;;
    --seeds) seeds="$2"; shift 2 ;;
    --duration) duration="$2"; shift 2 ;;
    --no-ois) read -r -a no_ois <<<"$2"; shift 2 ;;
    --cpu-share) cpu_share="$2"; shift 2 ;;
    --) shift; bench_args=("$@"); break ;;
    *) echo "online_learning_benchmark: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
if [ "${#modules[@]}" -eq 0 ] && [ "${#overlays[@]}" -eq 0 ] && [ "${#designs[@]}" -eq 0 ]; then
  for file in "$config"/modules/*.yaml; do modules+=("$(basename "$file" .yaml)"); done
fi
# name:overlay file, modules first.
runs=()
for module in "${modules[@]}"; do
  [ -f "$config/modules/$module.yaml" ] || { echo "online_learning_benchmark: no module '$module'" >&2; exit 2; }
  runs+=("$module:$config/modules/$module.yaml")
done
for file in "${overlays[@]}"; do
  [ -f "$file" ] || { echo "online_learning_benchmark: no overlay '$file'" >&2; exit 2; }
  runs+=("$(basename "$file" .yaml):$file")
done
mkdir -p "$out/bags"
for seed in "${designs[@]}"; do
  [[ "$seed" =~ ^[0-9]+$ ]] || { echo "online_learning_benchmark: design seed '$seed' is not a number" >&2; exit 2; }
  printf 'ois:\n  design_seed: %s\n' "$seed" >"$out/design_$seed.yaml"
  runs+=("design_$seed:$out/design_$seed.yaml")
done
read -r -a seed_list <<<"$seeds"
continue_args=()
[ "${#seed_list[@]}" -gt 1 ] && continue_args=(--continue-bags)

bag() {  # $1 name, $2 overlay, $3 seed, $4 on|off: the recording's path, simulated when missing
  local path="$out/bags/$1_$3_$4.bag"
  if [ ! -s "$path" ]; then
    rosrun deep_ois simulate --config "$config/RE.yaml" --overlay "$2" --seed "$3" --duration "$duration" \
      --ois "$4" --out "$path.tmp" --quiet --compression lz4 >&2 && mv "$path.tmp" "$path"
  fi
  echo "$path"
}
gyro_config() {  # $1 name, $2 overlay: the module camera's readout time (as make_module_datasets.sh)
  local readout
  readout=$(sed -n 's/^ *readout_time_s: *\([0-9.eE+-]*\).*/\1/p' "$2")
  sed "s/^readout_time: .*/readout_time: ${readout:-0.022}/" "$repo/config/gyro_flow.yaml" >"$out/$1_gyro_flow.yaml"
  echo "$out/$1_gyro_flow.yaml"
}
# The table's rows of a report: column `col` (1-based among the '|' cells) of each window.
cells() {  # $1 report, $2 column
  awk -F'|' -v col="$2" '/^\| [0-9]+-[0-9]+ \|/ { v = $(col + 1); gsub(/^ +| +$/, "", v); printf "%s%s", sep, v; sep = " | " }' "$1"
}
cpu() { sed -n 's/.*(\([0-9]*\) % of a core).*/\1 %/p' "$1"; }

status=0
table=() off_table=()
for run in "${runs[@]}"; do
  name="${run%%:*}" overlay="${run#*:}"
  gyro="$(gyro_config "$name" "$overlay")"
  on_bags=() off_bags=()
  for seed in "${seed_list[@]}"; do
    on_bags+=("$(bag "$name" "$overlay" "$seed" on)") || { echo "| $name | simulate failed |"; status=1; continue 2; }
    off_bags+=("$(bag "$name" "$overlay" "$seed" off)") || { echo "| $name | simulate failed |"; status=1; continue 2; }
  done
  report="$out/$name.md"
  if ! rosrun deep_ois benchmark_online_learning --bags "${on_bags[@]}" --twins "${off_bags[@]}" \
      --gyro-config "$gyro" --cpu-share "$cpu_share" --plot "$out/$name.png" "${continue_args[@]}" \
      "${bench_args[@]}" >"$report" 2>"$out/$name.log"; then
    table+=("| $name | benchmark_online_learning failed: see $out/$name.log |"); status=1; continue
  fi
  split=""
  if [[ "$name" =~ ^design_([0-9]+)$ ]]; then
    if (( BASH_REMATCH[1] % 5 == 0 )); then split=" (held out)"; else split=" (training)"; fi
  fi
  table+=("| $name$split | $(cells "$report" 8) | $(cpu "$report") |")
  echo "${table[-1]}"
  for twin in "${no_ois[@]}"; do
    [ "$twin" = "$name" ] || continue
    report="$out/${name}_no_ois.md"
    if ! rosrun deep_ois benchmark_online_learning --bags "${off_bags[@]}" --no-ois --gyro-config "$gyro" \
        --cpu-share "$cpu_share" --plot "$out/${name}_no_ois.png" "${continue_args[@]}" "${bench_args[@]}" \
        >"$report" 2>"$out/${name}_no_ois.log"; then
      off_table+=("| $name | benchmark_online_learning --no-ois failed: see $out/${name}_no_ois.log |"); status=1; continue
    fi
    off_table+=("| $name (non-OIS twin) | $(cells "$report" 6) | $(cpu "$report") |")
    echo "${off_table[-1]}"
  done
done

echo
echo "Gap closed to the non-OIS twin by the learning compensation, capped / uncapped, per window"
echo "(seeds $seeds, ${duration} s each; reports: $out/<module>.md):"
echo
printf '%s\n' "${table[@]}"
if [ "${#off_table[@]}" -gt 0 ]; then
  echo
  echo "Cameras without OIS: the learning compensation worse than the plain gyro, capped / uncapped, per window:"
  echo
  printf '%s\n' "${off_table[@]}"
fi
exit "$status"
