#!/usr/bin/env bash
# The standard ROS tools on the package's own messages (issue 31, item 1), run as a user runs them,
# with the system python (/usr/bin/python3): on a machine with only the C++ message packages,
# `rostopic echo` of any deep_ois topic failed ("No module named 'sensor_msgs'"), so did `rostopic
# echo /diagnostics`, `rostopic pub` of a deep_ois message, and `rosmsg` was not installed.
# scripts/install_deps.sh installs what they need; this test fails when any of it is missing.
#   1. the live pipeline (launch/deep_ois.launch use_sim_time:=true) fed by bags/sample.bag played
#      with --clock on a private master: `rostopic echo -n1` of /deep_ois/gyro_flow,
#      /deep_ois/compensated_flow and /diagnostics;
#   2. `rostopic pub -1` of a deep_ois/LensShiftSample, received by `rostopic echo -n1`;
#   3. `rosmsg show` of every message in msg/;
#   4. rosbag's Python API on bags/sample.bag: /tf_static as tf2_msgs/TFMessage, /imu/data as
#      sensor_msgs/Imu, /ground_truth/lens_shift as deep_ois/LensShift (the installed classes, with
#      the bag's MD5 sums), and a TFMessage written back.
# Needs the devel space sourced (as CTest runs it, scripts/ros_env.sh).
set -uo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
python=/usr/bin/python3
bag="$repo/bags/sample.bag"
work="$(mktemp -d /tmp/deep_ois_ros_tools.XXXXXX)"
export ROS_HOME="$work/ros_home" ROS_LOG_DIR="$work/log" ROS_HOSTNAME=localhost PYTHONUNBUFFERED=1
port=$((20000 + RANDOM % 20000))  # several tests (and engineers) share the machine
export ROS_MASTER_URI="http://localhost:$port"
background=()
cleanup() {
  # Stop what this test started, newest first, by process id (SIGINT, as Ctrl-C: roslaunch then
  # stops its nodes), then wait for each.
  local k
  for ((k = ${#background[@]} - 1; k >= 0; k--)); do kill -INT "${background[k]}" 2>/dev/null; done
  for pid in "${background[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    kill -KILL "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
  done
  rm -rf "$work"
}
trap cleanup EXIT

failures=0
fail() { echo "FAIL $*"; failures=$((failures + 1)); }

# A tool by its name on PATH, run with the system python whatever python is first on PATH.
tool() {
  local path
  path="$(command -v "$1")" || { echo "$1: command not found"; return 127; }
  shift
  "$python" "$path" "$@"
}
for t in rostopic rosmsg rosbag roslaunch roscore; do
  command -v "$t" >/dev/null || fail "$t: command not found (scripts/install_deps.sh installs it)"
done

# --- 3. rosmsg show of every message in msg/ (no master needed) ---
for file in "$repo"/msg/*.msg; do
  name="$(basename "$file" .msg)"
  output="$(tool rosmsg show "deep_ois/$name" 2>&1)"
  first_field="$(grep -v '^[[:space:]]*#' "$file" | grep -v '^[[:space:]]*$' | head -1 | awk '{print $2}')"
  first_field="${first_field%%=*}"
  if grep -qE "(^| )$first_field( |=|$)" <<<"$output"; then
    echo "ok   rosmsg show deep_ois/$name"
  else
    fail "rosmsg show deep_ois/$name does not show its field '$first_field': $output"
  fi
done

# --- 4. rosbag's Python API with the installed message classes ---
if output="$("$python" - "$bag" "$work/written.bag" 2>&1 <<'PYTHON'
import sys
import rosbag
from tf2_msgs.msg import TFMessage
from sensor_msgs.msg import Imu
from deep_ois.msg import LensShift
classes = {"/tf_static": TFMessage, "/imu/data": Imu, "/ground_truth/lens_shift": LensShift}
read = {}
with rosbag.Bag(sys.argv[1]) as bag:
    for topic, raw, _ in bag.read_messages(topics=list(classes), raw=True):
        if topic in read:
            continue
        datatype, data, md5sum = raw[0], raw[1], raw[2]
        cls = classes[topic]
        assert cls._type == datatype, f"{topic}: the bag has {datatype}, not {cls._type}"
        assert cls._md5sum == md5sum, f"{topic}: the installed {datatype} differs from the bag's (MD5)"
        read[topic] = cls().deserialize(data)
missing = set(classes) - set(read)
assert not missing, f"not in the bag: {sorted(missing)}"
tf = read["/tf_static"]
child = tf.transforms[0].child_frame_id
assert child, "a /tf_static transform without child frame"
with rosbag.Bag(sys.argv[2], "w") as out:
    out.write("/tf_static", tf)
with rosbag.Bag(sys.argv[2]) as back:
    (_, again, _), = list(back.read_messages())
assert again.transforms[0].child_frame_id == child
print(f"/tf_static {tf.transforms[0].header.frame_id} -> {child}, imu frame "
      f"{read['/imu/data'].header.frame_id}, lens shift x {read['/ground_truth/lens_shift'].shift_x:.3f} px")
PYTHON
)"; then
  echo "ok   rosbag Python API: $output"
else
  fail "rosbag's Python API with the installed message classes: $output"
fi

# --- 1. and 2. the live pipeline on a private master ---
roscore -p "$port" >"$work/roscore.log" 2>&1 &
background+=($!)
master_up=false
for _ in $(seq 100); do
  if "$python" -c "import rosgraph, sys; sys.exit(0 if rosgraph.Master('/t').is_online() else 1)" 2>/dev/null; then
    master_up=true
    break
  fi
  sleep 0.2
done
if [ "$master_up" = false ]; then
  fail "no master on port $port after 20 s: $(tail -5 "$work/roscore.log")"
else
  # The online learner writes its models under ROS_HOME: the temporary folder here.
  roslaunch -p "$port" deep_ois deep_ois.launch use_sim_time:=true output:=log >"$work/roslaunch.log" 2>&1 &
  background+=($!)
  advertised=false
  for _ in $(seq 120); do
    if tool rostopic list 2>/dev/null | grep -qx /deep_ois/compensated_flow; then
      advertised=true
      break
    fi
    sleep 0.5
  done
  [ "$advertised" = true ] || fail "deep_ois.launch did not advertise /deep_ois/compensated_flow in 60 s: $(tail -20 "$work/roslaunch.log")"

  # The subscribers first (the nodelets subscribe their inputs once an output has one), then the bag,
  # looped (ROS time jumps back at every loop: the nodelets restart) until every echo has its message.
  echo_pids=()
  echo_topic() {  # $1 output file, further: rostopic echo arguments
    local out="$1"
    shift
    timeout 120 "$python" "$(command -v rostopic)" echo -n1 "$@" >"$work/$out.out" 2>"$work/$out.err" &
    echo_pids+=($!)
  }
  echo_topic gyro_flow --noarr /deep_ois/gyro_flow
  echo_topic compensated_flow --noarr /deep_ois/compensated_flow
  echo_topic diagnostics /diagnostics
  echo_topic lens_shift /ros_tools_test/lens_shift
  sleep 2
  rosbag play -q --clock --loop --delay 1 "$bag" >"$work/play.log" 2>&1 &
  player=$!
  background+=("$player")
  pub_output="$(timeout 60 "$python" "$(command -v rostopic)" pub -1 /ros_tools_test/lens_shift \
    deep_ois/LensShiftSample "{header: {frame_id: camera_optical_frame}, x: 1.25, y: -0.5}" 2>&1)" ||
    fail "rostopic pub -1 /ros_tools_test/lens_shift deep_ois/LensShiftSample: $pub_output"
  for pid in "${echo_pids[@]}"; do wait "$pid"; done
  kill -INT "$player" 2>/dev/null

  check_echo() {  # $1 output file, $2 what, further: lines the echo must print
    local out="$1" what="$2"
    shift 2
    local ok=true
    for expected in "$@"; do
      grep -qE "$expected" "$work/$out.out" || ok=false
    done
    if [ "$ok" = true ]; then
      echo "ok   rostopic echo -n1 $what"
    else
      fail "rostopic echo -n1 $what: $(head -c 600 "$work/$out.out") $(head -c 600 "$work/$out.err")"
    fi
  }
  check_echo gyro_flow /deep_ois/gyro_flow "^patch_count: 6$" "^motion_model: \"?gyro\"?$" "encoding: \"?32FC2\"?"
  check_echo compensated_flow /deep_ois/compensated_flow "^patch_count: 6$" "encoding: \"?32FC2\"?"
  check_echo diagnostics /diagnostics "name: \"?deep_ois/(gyro_flow|compensation): status\"?" "key: \"?dropped total\"?"
  check_echo lens_shift "/ros_tools_test/lens_shift (after rostopic pub -1)" "^x: 1\.25$" "^y: -0\.5$" \
    "frame_id: \"?camera_optical_frame\"?"
fi

if [ "$failures" -gt 0 ]; then
  echo "ros_tools_test: $failures failure(s); scripts/install_deps.sh installs the Python message packages and rosmsg"
  exit 1
fi
echo "ros_tools_test: rostopic echo/pub, rosmsg show and rosbag's Python API work on the package's messages"
