#!/usr/bin/env bash
# Launch-argument test (run by CTest, issue 23 papercut 7): roslaunch accepts any name:=value on
# its command line and silently ignores one that a launch file does not declare, so
# `deep_ois.launch calibration:=cal.yaml` once ran with time_offset 0. Every launch file that runs
# the gyro flow nodelet must declare the arguments a user gives it and pass them through:
#   - calibration:=FILE  -> the file's values on /deep_ois/gyro_flow (roslaunch --dump-params);
#   - lens_shift_topic, imu_topic, image_topic -> the gyro flow's remaps (roslaunch --args).
# Needs the package on ROS_PACKAGE_PATH (the devel space, as CTest runs it); no master.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
work="$(mktemp -d /tmp/deep_ois_launch_args.XXXXXX)"
trap 'rm -rf "$work"' EXIT
calibration="$work/calibration.yaml"
printf 'time_offset: 0.0123\nreadout_time: 0.0311\n' >"$calibration"
bag="$repo/bags/sample.bag"

failures=0
check() {  # $1 launch file, further: its required arguments
  local launch="$1"
  shift
  local failures_before="$failures"
  local params
  params="$(roslaunch --dump-params deep_ois "$launch" "$@" calibration:="$calibration" 2>&1)" ||
    { echo "FAIL $launch: roslaunch --dump-params failed: $params"; failures=$((failures + 1)); return; }
  for expected in "/deep_ois/gyro_flow/time_offset: 0.0123" "/deep_ois/gyro_flow/readout_time: 0.0311"; do
    if ! grep -qxF "$expected" <<<"$params"; then
      echo "FAIL $launch calibration:=FILE: '$expected' not among the parameters:"
      grep '/deep_ois/gyro_flow/\(time_offset\|readout_time\)' <<<"$params" || echo "  (neither is set)"
      failures=$((failures + 1))
    fi
  done
  local command
  command="$(roslaunch --args /deep_ois/gyro_flow deep_ois "$launch" "$@" lens_shift_topic:=/test/lens \
    imu_topic:=/test/imu image_topic:=/test/image_raw 2>&1)" ||
    { echo "FAIL $launch: roslaunch --args failed: $command"; failures=$((failures + 1)); return; }
  for remap in "lens_shift:=/test/lens" "imu:=/test/imu" "image_raw:=/test/image_raw"; do
    if ! grep -qF " $remap" <<<"$command"; then
      echo "FAIL $launch: the gyro flow is not remapped $remap: $command"
      failures=$((failures + 1))
    fi
  done
  [ "$failures" -eq "$failures_before" ] && echo "ok   $launch"
  return 0
}

# The benchmark times what the launch runs: its default model is deep_ois.launch's.
launch_model="$(roslaunch --dump-params deep_ois deep_ois.launch 2>/dev/null | sed -n 's|^/deep_ois/compensation/model: ||p')"
if command -v rospack >/dev/null && [ -x "$(dirname "$(command -v roslaunch)")/rosrun" ] &&
    benchmark_help="$(rosrun deep_ois benchmark_compensation --help 2>/dev/null)"; then
  if ! grep -qF "$(basename "$launch_model")" <<<"$benchmark_help"; then
    echo "FAIL benchmark_compensation's default model is not deep_ois.launch's ($(basename "$launch_model"))"
    failures=$((failures + 1))
  else
    echo "ok   benchmark_compensation defaults to $(basename "$launch_model")"
  fi
fi

check gyro_flow.launch
check deep_ois.launch
check replay.launch bag:="$bag" rviz:=false
check demo.launch bag:="$bag"
if [ "$failures" -gt 0 ]; then
  echo "launch_arguments_test: $failures failure(s)"
  exit 1
fi
echo "launch_arguments_test: every launch file takes calibration, lens_shift_topic, imu_topic and image_topic"
