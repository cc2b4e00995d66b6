#!/usr/bin/env bash
# Soak test of the live pipeline (not run in CI): loops a recording with `rosbag play --loop
# --clock` (use_sim_time, so ROS time jumps back at every loop, as a user replaying a bag sees)
# through launch/deep_ois.launch (gyro flow + compensation in one manager, the shipped model, the
# online learning and the online calibration on, as config/compensation.yaml ships them) for N
# minutes, with subscribers on gyro_flow/color, compensated_flow/color and aligned/ghost, and prints once a
# minute the manager's resident memory (RSS) and the number of messages each output got in that
# minute.
#
#   bash scripts/soak.sh [minutes (10)] [master port (random)]
#       bags/sample.bag: 61 frames in 2.2 s; each loop restarts the pairing, so about 59 pairs per
#       2.2 s loop is the full rate. Too short for a calibration window: the calibration says
#       "needs motion" there.
#   bash scripts/soak.sh --drifting-clock RECORDING [minutes (30)] [master port (random)]
#       RECORDING (a simulated bag, e.g. `simulate --config config/simulator/RE.yaml --seed 7
#       --duration 90 --compression lz4`) with its IMU clock drifting against the camera's
#       (scripts/drifting_clock_bag.py: a sine of steepest slope 3 ms a minute, whose period is the
#       recording's length, so the loop has no jump in the offset). The learned files go to a fresh
#       ROS_HOME (_build/main/soak/ros_home); the online calibration and /diagnostics are recorded,
#       and at the end scripts/soak_clock_report.py prints the calibration in use against the
#       truth, the swaps and the files persisted.
#
# Build first (scripts/build.sh). Logs go to _build/main/soak/.
set -euo pipefail
recording=""
if [ "${1:-}" = "--drifting-clock" ]; then
  [ $# -ge 2 ] && [ -f "$2" ] || { echo "soak: --drifting-clock needs a recording (a bag file)" >&2; exit 2; }
  recording="$(realpath "$2")"
  shift 2
fi
minutes="${1:-$([ -n "$recording" ] && echo 30 || echo 10)}"
port="${2:-$((20000 + RANDOM % 20000))}"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
out="$build_dir/soak"
mkdir -p "$out"
export ROS_MASTER_URI="http://localhost:$port"
bag="$repo/bags/sample.bag"
if [ -n "$recording" ]; then
  bag="$out/drifting_clock.bag"
  if [ ! -s "$bag" ] || [ "$recording" -nt "$bag" ]; then
    /usr/bin/python3 "$repo/scripts/drifting_clock_bag.py" "$recording" "$bag"
  fi
  export ROS_HOME="$out/ros_home"
  rm -rf "$ROS_HOME"
  mkdir -p "$ROS_HOME"
fi

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
if [ -n "$recording" ]; then
  rosbag record -O "$out/drifting_clock_record.bag" /deep_ois/online_calibration /diagnostics \
    __name:=soak_recorder >"$out/rosbag_record.log" 2>&1 &
  recorder_pid=$!
  pids+=("$recorder_pid")
fi
rosbag play --clock --loop --quiet --queue 2000 "$bag" \
  --topics /imu/data /camera/image_raw /camera/camera_info /tf_static >"$out/rosbag.log" 2>&1 &
pids+=($!)

# Subscribing to an output makes its nodelet compute it (they subscribe lazily).
echo "messages per minute on each output, and the manager's resident memory:"
rosrun deep_ois live_rate_monitor --pid "$manager_pid" --period 60 --periods "$minutes" \
  /deep_ois/gyro_flow/color /deep_ois/compensated_flow/color /deep_ois/aligned/ghost
kill -0 "$manager_pid" 2>/dev/null || { echo "soak: the manager died"; tail -30 "$out/roslaunch.log"; exit 1; }
echo "warnings in the log: $(grep -c WARN "$out/roslaunch.log" || true) (see $out/roslaunch.log)"
if [ -n "$recording" ]; then
  kill -INT "$recorder_pid" 2>/dev/null || true
  wait "$recorder_pid" 2>/dev/null || true  # the bag is closed
  /usr/bin/python3 "$repo/scripts/soak_clock_report.py" "$out/drifting_clock_record.bag" "$bag.truth.yaml" "$ROS_HOME"
fi
