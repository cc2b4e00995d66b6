#!/usr/bin/env bash
# The main job on a fresh Debian bookworm machine: installs the dependencies, builds, and replays
# the committed sample bag (bags/sample.bag, written by the OIS simulator: IMU, rolling-shutter
# camera, camera_info, tf_static and ground truth) through the live pipeline with the shipped model
# (launch/demo.launch -> launch/deep_ois.launch: gyro flow + compensation nodelets), recording their
# flows; prints the summary of the gyro flows, then the paper's table on the bag's annotated
# correspondences, with the rows of the live recording beside the offline ones (they must agree).
# Fails when a frame pair got no gyro flow. Builds only what it runs (build.sh --demo); `bash
# scripts/build.sh` builds the other tools.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/install_deps.sh"
bash "$repo/scripts/build.sh" --demo
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"

out="$build_dir/demo"
mkdir -p "$out"
bag="$repo/bags/sample.bag"

# A private master port, so that the demo neither needs nor disturbs a running roscore.
export ROS_MASTER_URI=http://localhost:11351
recording="$out/live_flows.bag"
rm -f "$recording"
roslaunch -p 11351 deep_ois demo.launch bag:="$bag" summary:=false play:=false record:="$recording" \
  >"$out/roslaunch.log" 2>&1 &
launch_pid=$!
trap 'kill -INT "$launch_pid" 2>/dev/null || true; wait "$launch_pid" 2>/dev/null || true' EXIT

# The launch sets /use_sim_time once its master is up.
for _ in $(seq 1 100); do
  rosparam get /use_sim_time >/dev/null 2>&1 && break
  if ! kill -0 "$launch_pid" 2>/dev/null; then
    echo "demo: the launch failed:"; tail -20 "$out/roslaunch.log"; exit 1
  fi
  sleep 0.2
done

status=0
rosrun deep_ois gyro_flow_summary --bag "$bag" gyro_flow:=/deep_ois/gyro_flow __name:=gyro_flow_summary &
summary_pid=$!
# The bag plays only once the summary listens: on a busy machine starting it can take longer than
# any fixed delay, and a flow published before it subscribed would be missing from the summary.
for _ in $(seq 1 300); do
  rostopic info /deep_ois/gyro_flow 2>/dev/null | grep -q "/gyro_flow_summary" && break
  kill -0 "$summary_pid" 2>/dev/null || break  # it failed: its exit status says why
  sleep 0.2
done
# The launch's player, run here (same flags as launch/demo.launch).
rosbag play --clock --quiet --wait-for-subscribers --delay 2 --queue 2000 "$bag" \
  --topics /imu/data /camera/image_raw /camera/camera_info /tf_static >>"$out/roslaunch.log" 2>&1 || status=$?
wait "$summary_pid" || status=$?
# The compensated flow of the last pair follows its gyro flow by a few ms; then stop the launch,
# which closes the recording.
sleep 2
kill -INT "$launch_pid" 2>/dev/null || true
wait "$launch_pid" 2>/dev/null || true
trap - EXIT
if grep -qE "WARN|ERROR|FATAL" "$out/roslaunch.log"; then
  echo "warnings and errors of the pipeline (full log: $out/roslaunch.log):"
  grep -E "WARN|ERROR|FATAL" "$out/roslaunch.log" | head -20
fi

# Geometry distance on the bag's annotated correspondences (pixels): every row of the paper's
# table (identity, image baselines, the gyro uncompensated on this OIS camera, the ground truths,
# the shipped model) computed offline, and the live nodelets' recorded flows; figures in $out.
echo
echo "==== geometry distance on the annotated correspondences of $(basename "$bag") ===="
rosrun deep_ois evaluate --bags "$bag" --recorded "$recording" --out "$out" || status=$?
echo
echo "demo: built only what it runs; 'bash scripts/build.sh' builds the other tools (rosrun deep_ois TOOL)."
exit "$status"
