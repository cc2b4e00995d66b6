#!/usr/bin/env bash
# Install-space test (run by CTest): installs the built package into a temporary prefix and runs
# the demo's launch (launch/demo.launch -> launch/deep_ois.launch: gyro flow and compensation
# nodelets in one manager, the shipped model) from that prefix on the installed bags/sample.bag,
# recording the compensated flows; passes when every frame pair after the first gave a gyro flow
# and a compensated flow.
#
# The environment holds the prefix and the system ROS (/usr) only: no devel space, no source tree
# on ROS_PACKAGE_PATH, so anything the package still reads from its source tree fails here.
#
# usage: install_space_test.sh BUILD_DIR
set -euo pipefail
build_dir="$(cd "$1" && pwd)"
work="$(mktemp -d /tmp/deep_ois_install_test.XXXXXX)"
prefix="$work/prefix"
launch_pid=""
cleanup() {
  if [ -n "$launch_pid" ]; then
    kill -INT "$launch_pid" 2>/dev/null || true
    wait "$launch_pid" 2>/dev/null || true
  fi
  rm -rf "$work"
}
trap cleanup EXIT

cmake --install "$build_dir" --prefix "$prefix" >"$work/install.log" 2>&1 ||
  { echo "install_space_test: cmake --install failed:"; tail -20 "$work/install.log"; exit 1; }

# What sourcing the prefix's setup.bash gives, written out so that nothing of the calling
# environment (a devel space, the source tree) leaks in.
unset ROS_PACKAGE_PATH CMAKE_PREFIX_PATH PYTHONPATH LD_LIBRARY_PATH PKG_CONFIG_PATH ROSLISP_PACKAGE_DIRECTORIES
export ROS_PACKAGE_PATH="$prefix/share:/usr/share"
export CMAKE_PREFIX_PATH="$prefix:/usr"
export LD_LIBRARY_PATH="$prefix/lib"
export PYTHONPATH="$prefix/lib/python3/dist-packages"
export PATH="$prefix/bin:/usr/bin:/bin"
export ROS_HOSTNAME=localhost
export ROS_HOME="$work/ros_home"
export ROSCONSOLE_STDOUT_LINE_BUFFERED=1
mkdir -p "$ROS_HOME"

package_dir="$(rospack find deep_ois)"
if [ "$package_dir" != "$prefix/share/deep_ois" ]; then
  echo "install_space_test: rospack finds deep_ois in '$package_dir', not in the prefix $prefix"
  exit 1
fi
for file in models/fast.pt models/fast.yaml models/stabiliser_generic.yaml bags/sample.bag config/gyro_flow.yaml config/compensation.yaml \
            launch/deep_ois.launch launch/demo.launch rviz nodelet_plugins.xml package.xml; do
  [ -e "$package_dir/$file" ] || { echo "install_space_test: $file is not installed"; exit 1; }
done
# The launch files run it when an argument is given by its old name (config:= for gyro_config:=).
[ -x "$prefix/lib/deep_ois/deprecated_launch_argument" ] ||
  { echo "install_space_test: lib/deep_ois/deprecated_launch_argument is not installed"; exit 1; }
bag="$package_dir/bags/sample.bag"

# A private master port: several tests (and engineers) run on one machine.
port=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI="http://localhost:$port"
recording="$work/flows.bag"
roslaunch -p "$port" deep_ois demo.launch bag:="$bag" summary:=false play:=false record:="$recording" \
  >"$work/roslaunch.log" 2>&1 &
launch_pid=$!

for _ in $(seq 1 150); do
  rosparam get /use_sim_time >/dev/null 2>&1 && break
  if ! kill -0 "$launch_pid" 2>/dev/null; then
    echo "install_space_test: the launch failed:"; tail -30 "$work/roslaunch.log"; exit 1
  fi
  sleep 0.2
done
# The recorder and the compensation nodelet must listen before the bag plays.
for _ in $(seq 1 300); do
  if rostopic info /deep_ois/compensated_flow 2>/dev/null | grep -q "/recorder" &&
     rostopic info /deep_ois/gyro_flow 2>/dev/null | grep -q "/recorder"; then
    break
  fi
  kill -0 "$launch_pid" 2>/dev/null || { echo "install_space_test: the launch died:"; tail -30 "$work/roslaunch.log"; exit 1; }
  sleep 0.2
done
rosbag play --clock --quiet --wait-for-subscribers --delay 2 --queue 2000 "$bag" \
  --topics /imu/data /camera/image_raw /camera/camera_info /tf_static >>"$work/roslaunch.log" 2>&1
sleep 3
kill -INT "$launch_pid" 2>/dev/null || true
wait "$launch_pid" 2>/dev/null || true
launch_pid=""

frames="$(rosbag info --yaml --key topics "$bag" | awk '/topic: \/camera\/image_raw$/ {f=1} f && /messages:/ {print $2; exit}')"
count() { rosbag info --yaml --key topics "$recording" 2>/dev/null | awk -v t="$1" '$0 ~ "topic: "t"$" {f=1} f && /messages:/ {print $2; exit}'; }
gyro="$(count /deep_ois/gyro_flow)"
compensated="$(count /deep_ois/compensated_flow)"
echo "install_space_test: prefix $prefix: $frames frames played, ${gyro:-0} gyro flows and ${compensated:-0} compensated flows recorded"
if grep -qE "ERROR|FATAL" "$work/roslaunch.log"; then
  echo "install_space_test: errors in the launch:"; grep -E "ERROR|FATAL" "$work/roslaunch.log" | head -20
fi
if [ -z "$frames" ] || [ "${gyro:-0}" -lt $((frames - 1)) ] || [ "${compensated:-0}" -lt $((frames - 1)) ]; then
  echo "install_space_test: expected $((frames - 1)) gyro and compensated flows; launch log:"
  tail -40 "$work/roslaunch.log"
  exit 1
fi
