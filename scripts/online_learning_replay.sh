#!/usr/bin/env bash
# One recording replayed through the live pipeline (launch/demo.launch -> deep_ois.launch: the gyro
# flow and compensation nodelets, online learning on as shipped) from a cold start (an empty
# learning folder: the shipped generic model, nothing learned), for recordings too short or too
# few for benchmark_online_learning (e.g. a real one with a few annotated pairs). Records the
# published flows and every pair's check (`compensation_check`), then prints:
#   - per checked pair: the tracks' mean error with the compensation published and with the plain
#     gyro, whether it was usable, and whether the nodelet fell back to the plain gyro after it;
#   - `evaluate --recorded` on the recording's annotated pairs: the live compensated flows beside
#     the plain gyro and the fixed starting model computed offline.
#
#   online_learning_replay.sh BAG OUTDIR --gyro-config FILE.yaml [--annotations FILE.csv --camera ois|non-ois]
#
# --gyro-config is the camera's complete gyro flow parameters (config/gyro_flow.yaml with the
# camera's `calibrate` output merged in). Not run in CI (a live replay, tens of seconds).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 2 ] || { sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
bag="$(realpath "$1")" out="$2"; shift 2
gyro_config="" annotations=() camera=()
while [ $# -gt 0 ]; do
  case "$1" in
    --gyro-config) gyro_config="$(realpath "$2")"; shift 2 ;;
    --annotations) annotations=(--annotations "$(realpath "$2")"); shift 2 ;;
    --camera) camera=(--camera "$2"); shift 2 ;;
    *) echo "online_learning_replay: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[ -n "$gyro_config" ] || { echo "online_learning_replay: --gyro-config is required" >&2; exit 2; }
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
mkdir -p "$out"
out="$(realpath "$out")"
# A cold start: the learner's per-camera files go to an empty folder under OUTDIR.
export ROS_HOME="$out/ros_home"
rm -rf "$ROS_HOME" "$out/live_flows.bag" "$out/checks.bag"
mkdir -p "$ROS_HOME"
export ROS_MASTER_URI=http://localhost:11352
roslaunch -p 11352 deep_ois demo.launch bag:="$bag" gyro_config:="$gyro_config" summary:=false play:=false \
  record:="$out/live_flows.bag" >"$out/roslaunch.log" 2>&1 &
launch_pid=$!
trap 'kill -INT "$launch_pid" 2>/dev/null || true; wait "$launch_pid" 2>/dev/null || true' EXIT
for _ in $(seq 1 100); do
  rosparam get /use_sim_time >/dev/null 2>&1 && break
  kill -0 "$launch_pid" 2>/dev/null || { echo "online_learning_replay: the launch failed:"; tail -20 "$out/roslaunch.log"; exit 1; }
  sleep 0.2
done
rosbag record -O "$out/checks.bag" /deep_ois/compensation_check \
  __name:=check_recorder >>"$out/roslaunch.log" 2>&1 &
record_pid=$!
# The player waits for the pipeline's subscribers (the nodelets subscribe once an output has one);
# with the rotation in the config, nothing subscribes to /tf_static (the player would wait forever).
topics=(/imu/data /camera/image_raw /camera/camera_info)
grep -q '^imu_to_camera_rotation:' "$gyro_config" || topics+=(/tf_static)
rosbag play --clock --quiet --wait-for-subscribers --delay 3 --queue 2000 "$bag" \
  --topics "${topics[@]}" >>"$out/roslaunch.log" 2>&1
# The checks come a few pairs after their pair (the tracking runs in the background).
sleep 5
kill -INT "$record_pid" 2>/dev/null || true
wait "$record_pid" 2>/dev/null || true
kill -INT "$launch_pid" 2>/dev/null || true
wait "$launch_pid" 2>/dev/null || true
trap - EXIT

echo "==== the check of every compensated pair (tracks' mean error, px) ===="
rostopic echo -b "$out/checks.bag" -p /deep_ois/compensation_check >"$out/checks.csv"
awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
  { n++; stamp = $col["field.header.stamp"] / 1e9
    usable = $col["field.usable"] == 1
    printf "| %.3f | %s | %s | %s | %s | %s | %s |\n", stamp, $col["field.inliers"], usable ? "yes" : "no",
      usable ? sprintf("%.3f", $col["field.model_residual"]) : "-", usable ? sprintf("%.3f", $col["field.gyro_residual"]) : "-",
      $col["field.falling_back"] == 1 ? "plain gyro" : "model", $col["field.model_version"]
    if (usable) { u++; m += $col["field.model_residual"]; g += $col["field.gyro_residual"]; if ($col["field.model_residual"] > $col["field.gyro_residual"]) worse++ }
    if ($col["field.falling_back"] == 1) back++ }
  BEGIN { print "| frame b [s] | inliers | usable | model | plain gyro | published after it | model version |"; print "|---:|---:|---|---:|---:|---|---:|" }
  END { printf "\n%d pairs checked, %d usable (mean: model %.3f px, plain gyro %.3f px; the model worse on %d); the plain gyro published after %d\n",
        n, u, u ? m / u : 0, u ? g / u : 0, worse, back }' "$out/checks.csv"
echo
echo "==== evaluate --recorded: the live compensated flows on the annotated pairs ===="
status=0
rosrun deep_ois evaluate --bags "$bag" --recorded "$out/live_flows.bag" --gyro-config "$gyro_config" \
  "${annotations[@]}" "${camera[@]}" --no-model --no-image-baselines --no-ground-truth --ghost-pairs 0 \
  --no-progress --out "$out/evaluation" || status=$?
echo
echo "Per annotated pair (capped px): the plain gyro, the fixed starting model, the live compensation:"
awk -F, 'NR > 1 { key = $3; if ($0 ~ /uncompensated/) g[key] = $(NF - 1); else if ($0 ~ /stabiliser model/) f[key] = $(NF - 1);
    else if ($0 ~ /compensation \(live/) l[key] = $(NF - 1); if (!(key in seen)) { seen[key] = 1; order[++n] = key } }
  END { print "| frame b [s] | plain gyro | fixed model | live |"; print "|---:|---:|---:|---:|"
        for (i = 1; i <= n; ++i) { k = order[i]; printf "| %s | %s | %s | %s |\n", k, g[k], f[k], l[k] } }' \
  "$out/evaluation/evaluation_pairs.csv" 2>/dev/null || true
# 4: the live flows differ from the fixed model's offline row, as they must when the pipeline fell
# back to the plain gyro or learned another model.
[ "$status" = 4 ] && status=0
exit "$status"
