#!/usr/bin/env bash
# Soak test of the live pipeline (not run in CI): loops bags/sample.bag with `rosbag play --loop
# --clock` (use_sim_time, so ROS time jumps back at every loop, as a user replaying a bag sees)
# through launch/deep_ois.launch (gyro flow + compensation in one manager, the shipped model) for N
# minutes, with subscribers on gyro_flow/color, compensated_flow/color and aligned/ghost, and prints once a
# minute the manager's resident memory (RSS) and the number of messages each output got in that
# minute. The sample bag holds 61 frames in 2.2 s; each loop restarts the pairing, so about
# 59 pairs per 2.2 s loop is the full rate.
#
#   bash scripts/soak.sh [minutes (10)] [master port (random)]
#
# Build first (scripts/build.sh). Logs go to _build/main/soak/.
set -euo pipefail
minutes="${1:-10}"
port="${2:-$((20000 + RANDOM % 20000))}"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
out="$build_dir/soak"
mkdir -p "$out"
export ROS_MASTER_URI="http://localhost:$port"

pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

roscore -p "$port" >"$out/roscore.log" 2>&1 &
pids+=($!)
for _ in $(seq 1 100); do rosparam list >/dev/null 2>&1 && break; sleep 0.2; done
rosparam set /use_sim_time true
roslaunch -p "$port" deep_ois deep_ois.launch >"$out/roslaunch.log" 2>&1 &
pids+=($!)

manager_pid=""
for _ in $(seq 1 150); do
  manager_pid="$(rosnode info /deep_ois/deep_ois_manager 2>/dev/null | sed -n 's/^Pid: //p')"
  [ -n "$manager_pid" ] && break
  sleep 0.2
done
[ -n "$manager_pid" ] || { echo "soak: the manager did not start"; tail -20 "$out/roslaunch.log"; exit 1; }

sleep 3
rosbag play --clock --loop --quiet --queue 2000 "$repo/bags/sample.bag" \
  --topics /imu/data /camera/image_raw /camera/camera_info /tf_static >"$out/rosbag.log" 2>&1 &
pids+=($!)

# Subscribing to an output makes its nodelet compute it (they subscribe lazily).
echo "messages per minute on each output, and the manager's resident memory:"
rosrun deep_ois live_rate_monitor --pid "$manager_pid" --period 60 --periods "$minutes" \
  /deep_ois/gyro_flow/color /deep_ois/compensated_flow/color /deep_ois/aligned/ghost
kill -0 "$manager_pid" 2>/dev/null || { echo "soak: the manager died"; tail -30 "$out/roslaunch.log"; exit 1; }
echo "warnings in the log: $(grep -c WARN "$out/roslaunch.log" || true) (see $out/roslaunch.log)"
