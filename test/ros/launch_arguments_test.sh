#!/usr/bin/env bash
# Launch-argument test (run by CTest, issue 23 papercut 7): roslaunch accepts any name:=value on
# its command line and silently ignores one that a launch file does not declare, so
# `deep_ois.launch calibration:=cal.yaml` once ran with time_offset 0. Every launch file that runs
# the gyro flow nodelet must declare the arguments a user gives it and pass them through:
#   - calibration:=FILE  -> the file's values on /deep_ois/gyro_flow (roslaunch --dump-params);
#   - lens_shift_topic, imu_topic, image_topic -> the gyro flow's remaps (roslaunch --args).
# Issue 31: the same argument has the same name in every launch file:
#   - gyro_config:=FILE -> loaded over config/gyro_flow.yaml (a file that sets one parameter keeps
#     the package's values of the others); fundamental_mixtures.launch passes it to its nodelet;
#   - the old names (config:=, fundamental_mixtures.launch's gyro_flow_config:=) still work, and a
#     node of the launch says so: its command line (roslaunch --args) run here prints the warning;
#   - use_sim_time: deep_ois.launch and gyro_flow.launch set /use_sim_time from it (default false),
#     replay.launch and demo.launch (which play with --clock) to true.
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

fragment="$work/camera.gyro_flow.yaml"  # one parameter only, as convert_recording's files set a few
printf 'max_frame_interval: 0.0777\n' >"$fragment"

# $1 what is checked, $2 the parameter dump, further: lines it must hold.
expect_params() {
  local what="$1" params="$2"
  shift 2
  for expected in "$@"; do
    if ! grep -qxF "$expected" <<<"$params"; then
      echo "FAIL $what: '$expected' not among the parameters"
      failures=$((failures + 1))
    fi
  done
}

# $1 launch file, $2 the node saying the old name (resolved name), $3 old name, $4 new name,
# further: the launch file's required arguments. The node must be there with the old name only,
# and its own command line must print the warning naming both.
check_old_name() {
  local launch="$1" node="$2" old="$3" new="$4"
  shift 4
  if roslaunch --nodes deep_ois "$launch" "$@" 2>/dev/null | grep -qxF "$node"; then
    echo "FAIL $launch: $node runs although $old:= was not given"
    failures=$((failures + 1))
  fi
  local command output
  command="$(roslaunch --args "$node" deep_ois "$launch" "$@" "$old:=$fragment" 2>&1)" ||
    { echo "FAIL $launch $old:=FILE: no node $node tells that $old is an old name: $command"
      failures=$((failures + 1)); return 0; }
  # Run as roslaunch would, against a port where no master listens: the warning goes to stderr.
  command="$(sed 's/^ROS_MASTER_URI="[^"]*" //' <<<"$command")"
  output="$(ROS_MASTER_URI=http://127.0.0.1:9/ bash -c "$command" 2>&1)" ||
    { echo "FAIL $launch: '$command' failed: $output"; failures=$((failures + 1)); return 0; }
  if ! grep -qF "'$old' is the old name of '$new'" <<<"$output" || ! grep -qF "$new:=$fragment" <<<"$output"; then
    echo "FAIL $launch $old:=FILE: the warning does not name $old, $new and the file: $output"
    failures=$((failures + 1))
  fi
}

check_gyro_config() {  # $1 launch file, further: its required arguments
  local launch="$1"
  shift
  local failures_before="$failures" params
  # The fragment's value, and the package's yaml for what it does not set (image_queue_size: 30
  # there; demo.launch sets its own 100 afterwards).
  local queue="/deep_ois/gyro_flow/image_queue_size: 30"
  [ "$launch" = demo.launch ] && queue="/deep_ois/gyro_flow/image_queue_size: 100"
  for name in gyro_config config; do
    params="$(roslaunch --dump-params deep_ois "$launch" "$@" "$name:=$fragment" 2>&1)" ||
      { echo "FAIL $launch $name:=FILE: roslaunch --dump-params failed: $params"; failures=$((failures + 1)); continue; }
    expect_params "$launch $name:=FILE" "$params" "/deep_ois/gyro_flow/max_frame_interval: 0.0777" "$queue" \
      "/deep_ois/gyro_flow/readout_time: 0.022"
  done
  local node=/deprecated_argument_config
  [ "$launch" = gyro_flow.launch ] && node=/deep_ois/deprecated_argument_config
  check_old_name "$launch" "$node" config gyro_config "$@"
  # /use_sim_time: from the argument (default false), or true for the launch files that replay.
  case "$launch" in
    replay.launch | demo.launch)
      expect_params "$launch" "$(roslaunch --dump-params deep_ois "$launch" "$@" 2>&1)" "/use_sim_time: true" ;;
    *)
      expect_params "$launch" "$(roslaunch --dump-params deep_ois "$launch" "$@" 2>&1)" "/use_sim_time: false"
      expect_params "$launch use_sim_time:=true" \
        "$(roslaunch --dump-params deep_ois "$launch" "$@" use_sim_time:=true 2>&1)" "/use_sim_time: true" ;;
  esac
  [ "$failures" -eq "$failures_before" ] && echo "ok   $launch: gyro_config (old name config), use_sim_time"
  return 0
}

check gyro_flow.launch
check deep_ois.launch
check replay.launch bag:="$bag" rviz:=false
check demo.launch bag:="$bag"
check_gyro_config gyro_flow.launch
check_gyro_config deep_ois.launch
check_gyro_config replay.launch bag:="$bag" rviz:=false
check_gyro_config demo.launch bag:="$bag"

# The offline job takes the gyro flow's file under the same name (its nodelet reads it itself).
failures_before="$failures"
mixtures=(bags:="[$bag]" output:="$work/training.bag")
for name in gyro_config gyro_flow_config; do
  expect_params "fundamental_mixtures.launch $name:=FILE" \
    "$(roslaunch --dump-params deep_ois fundamental_mixtures.launch "${mixtures[@]}" "$name:=$fragment" 2>&1)" \
    "/fundamental_mixtures/gyro_flow_config: $fragment"
done
check_old_name fundamental_mixtures.launch /deprecated_argument_gyro_flow_config gyro_flow_config gyro_config \
  "${mixtures[@]}"
check_old_name fundamental_mixtures.launch /deprecated_argument_config config fundamental_mixtures_config \
  "${mixtures[@]}"
[ "$failures" -eq "$failures_before" ] && echo "ok   fundamental_mixtures.launch: gyro_config (old name gyro_flow_config)"

if [ "$failures" -gt 0 ]; then
  echo "launch_arguments_test: $failures failure(s)"
  exit 1
fi
echo "launch_arguments_test: every launch file takes calibration, lens_shift_topic, imu_topic, image_topic," \
  "gyro_config (the old names with a warning) and use_sim_time"
