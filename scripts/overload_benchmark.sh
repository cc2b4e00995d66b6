#!/usr/bin/env bash
# Graceful overload benchmark of the live pipeline (not run in CI; docs/reliability.md): loops
# bags/sample.bag with `rosbag play --loop --clock` through launch/deep_ois.launch (gyro flow and
# compensation in one manager, the shipped default model, online learning and calibration on as
# shipped, a cold start per run) while BUSY x (number of cores) busy-looping shell processes,
# started and stopped by this script, compete for the CPU. Every optional output of the
# compensation has a subscriber (compensated_flow/color, aligned/image_raw, aligned/ghost), as with
# rviz open. Per run it prints the gyro flows and compensated flows published over SECONDS (counted
# by live_rate_monitor), their ratio, the load average at the end, and what the compensation's
# /diagnostics said it shed; then the ratio of every run.
#
#   bash scripts/overload_benchmark.sh [--runs 3] [--seconds 60] [--busy-per-core 2] [--port PORT]
#
# --busy-per-core 0 measures the unloaded machine. Build first (scripts/build.sh, or the targets
# deep_ois_gyro_flow_nodelet deep_ois_compensation_nodelet live_rate_monitor). Logs go to
# _build/main/overload/.
set -euo pipefail
runs=3 seconds=60 busy_per_core=2 port="$((20000 + RANDOM % 20000))"
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    --busy-per-core) busy_per_core="$2"; shift 2 ;;
    --port) port="$2"; shift 2 ;;
    -h|--help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "overload_benchmark: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
for value in "$runs" "$seconds" "$busy_per_core" "$port"; do
  [[ "$value" =~ ^[0-9]+$ ]] || { echo "overload_benchmark: '$value' is not a whole number (see --help)" >&2; exit 2; }
done
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
out="$build_dir/overload"
mkdir -p "$out"
export ROS_MASTER_URI="http://localhost:$port"
cores="$(nproc)"
busy_count=$((busy_per_core * cores))

pids=()
busy_pids=()
stop_all() {
  for pid in "${busy_pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "${busy_pids[@]}" "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  busy_pids=()
  pids=()
}
trap stop_all EXIT

# The compensation's overload keys from one /diagnostics message (empty when none came).
shed_report() {
  timeout 10 rostopic echo -n 3 /diagnostics 2>/dev/null |
    grep -A1 -E "key: \"overload: (shed order|shedding now|pairs with an output shed)" |
    grep -E "key:|value:" | sed 's/^ *//' | tail -6 || true
}

summary=()
for run in $(seq 1 "$runs"); do
  log="$out/run$run"
  rm -rf "$log"
  mkdir -p "$log/ros_home"
  # A cold start: nothing learned by an earlier run.
  export ROS_HOME="$log/ros_home"
  roscore -p "$port" >"$log/roscore.log" 2>&1 &
  pids+=($!)
  for _ in $(seq 1 100); do rosparam list >/dev/null 2>&1 && break; sleep 0.2; done
  rosparam set /use_sim_time true
  roslaunch -p "$port" deep_ois deep_ois.launch use_sim_time:=true >"$log/roslaunch.log" 2>&1 &
  pids+=($!)
  manager_pid=""
  for _ in $(seq 1 150); do
    manager_pid="$(rosnode info /deep_ois/deep_ois_manager 2>/dev/null | sed -n 's/^Pid: //p')"
    [ -n "$manager_pid" ] && break
    sleep 0.2
  done
  [ -n "$manager_pid" ] || { echo "overload_benchmark: the manager did not start"; tail -20 "$log/roslaunch.log"; exit 1; }
  sleep 3
  # The competition: busy loops, one process each, at the pipeline's priority.
  for _ in $(seq 1 "$busy_count"); do
    bash -c 'while :; do :; done' &
    busy_pids+=($!)
  done
  rosbag play --clock --loop --quiet --queue 2000 "$repo/bags/sample.bag" \
    --topics /imu/data /camera/image_raw /camera/camera_info /tf_static >"$log/rosbag.log" 2>&1 &
  pids+=($!)
  # Subscribing to an output makes its nodelet compute it (they subscribe lazily).
  rosrun deep_ois live_rate_monitor --pid "$manager_pid" --period "$seconds" --periods 1 \
    /deep_ois/gyro_flow /deep_ois/compensated_flow /deep_ois/compensated_flow/color \
    /deep_ois/aligned/image_raw /deep_ois/aligned/ghost >"$log/rates.txt" 2>"$log/monitor.log"
  load="$(cut -d' ' -f1-3 /proc/loadavg)"
  shed="$(shed_report)"
  kill -0 "$manager_pid" 2>/dev/null || { echo "overload_benchmark: the manager died"; tail -30 "$log/roslaunch.log"; exit 1; }
  stop_all
  totals="$(sed -n 's/^total *//p' "$log/rates.txt")"
  read -r gyro compensated color aligned ghost <<<"$totals"
  share="$(awk -v c="$compensated" -v g="$gyro" 'BEGIN { if (g > 0) printf "%.1f", 100 * c / g; else print "n/a" }')"
  echo "run $run: $seconds s, $busy_count busy processes on $cores cores, load average at the end $load"
  echo "  gyro flows $gyro, compensated flows $compensated ($share %); compensated_flow/color $color, aligned/image_raw $aligned, aligned/ghost $ghost"
  echo "  pairs dropped by the compensation: $(grep -c 'without output since the last report' "$log/roslaunch.log" || true) warning(s) in $log/roslaunch.log"
  [ -n "$shed" ] && echo "$shed" | sed 's/^/  /'
  summary+=("$share")
done
echo "compensated flows per gyro flow, $runs run(s) of $seconds s with $busy_per_core busy process(es) per core: ${summary[*]} %"
