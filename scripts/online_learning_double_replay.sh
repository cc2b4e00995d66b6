#!/usr/bin/env bash
# Issue 33's double-replay case: one recording played PLAYS times (default 2) in one session of the
# live pipeline (launch/demo.launch -> deep_ois.launch, online learning on as shipped) from an empty
# learning folder, then a second session started on what the first one kept (the learned model file
# of the camera, if any), playing the recording once more. Prints, per play of each session, the
# per-pair check (tracks' mean error with the model in use and with the plain gyro over the usable
# pairs, the share published as the plain gyro), the swaps and their verdicts the log said, and the
# learned model file at the end of the first session.
#
#   online_learning_double_replay.sh BAG OUTDIR --gyro-config FILE.yaml [--model FILE.yaml] [--plays N]
#
# --model is the pipeline's ~model (default: the shipped generic model). Not run in CI (a live
# replay: about (PLAYS + 1) x the recording's length, plus ~20 s).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 2 ] || { sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
bag="$(realpath "$1")" out="$2"; shift 2
gyro_config="" model_args=() plays=2
while [ $# -gt 0 ]; do
  case "$1" in
    --gyro-config) gyro_config="$(realpath "$2")"; shift 2 ;;
    --model) model_args=(model:="$(realpath "$2")"); shift 2 ;;
    --plays) plays="$2"; shift 2 ;;
    *) echo "online_learning_double_replay: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[ -n "$gyro_config" ] || { echo "online_learning_double_replay: --gyro-config is required" >&2; exit 2; }
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
mkdir -p "$out"
out="$(realpath "$out")"
export ROS_HOME="$out/ros_home"  # the learned files go to $ROS_HOME/deep_ois/stabilisers
rm -rf "$ROS_HOME"
mkdir -p "$ROS_HOME"
export ROS_MASTER_URI=http://localhost:11353
topics=(/imu/data /camera/image_raw /camera/camera_info)
grep -q '^imu_to_camera_rotation:' "$gyro_config" || topics+=(/tf_static)

# One session: the launch, a recorder of the checks, the bag played $1 times; $2 names it.
session() {
  local n="$1" name="$2"
  roslaunch -p 11353 deep_ois demo.launch bag:="$bag" gyro_config:="$gyro_config" "${model_args[@]}" \
    summary:=false play:=false >"$out/$name.log" 2>&1 &
  local launch_pid=$!
  for _ in $(seq 1 100); do
    rosparam get /use_sim_time >/dev/null 2>&1 && break
    kill -0 "$launch_pid" 2>/dev/null || { echo "the launch failed:"; tail -20 "$out/$name.log"; exit 1; }
    sleep 0.2
  done
  rosbag record -O "$out/$name.checks.bag" /deep_ois/compensation_check __name:=check_recorder \
    >>"$out/$name.log" 2>&1 &
  local record_pid=$!
  for play in $(seq 1 "$n"); do
    rosbag play --clock --quiet --wait-for-subscribers --delay 3 --queue 2000 "$bag" \
      --topics "${topics[@]}" >>"$out/$name.log" 2>&1
    sleep 3  # the checks come a few pairs after their pair
  done
  kill -INT "$record_pid" 2>/dev/null || true
  wait "$record_pid" 2>/dev/null || true
  kill -INT "$launch_pid" 2>/dev/null || true
  wait "$launch_pid" 2>/dev/null || true
  rostopic echo -b "$out/$name.checks.bag" -p /deep_ois/compensation_check >"$out/$name.checks.csv"
  echo "==== $name: $n play(s) ===="
  # In publication order (the recorder's times repeat with every play); a play starts where the
  # stamps go back.
  { head -1 "$out/$name.checks.csv"; tail -n +2 "$out/$name.checks.csv" | sort -t, -k2,2n; } >"$out/$name.checks.sorted.csv"
  awk -F, 'BEGIN { play = 0 } NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
    { stamp = $col["field.header.stamp"] / 1e9; if (NR > 2 && stamp < last - 1.0) play++; last = stamp
      n[play]++; if ($col["field.usable"] == 1) { u[play]++; m[play] += $col["field.model_residual"]; g[play] += $col["field.gyro_residual"] }
      if ($col["field.falling_back"] == 1) back[play]++
      v = $col["field.model_version"]; if (!(play SUBSEP v in seenv)) { seenv[play SUBSEP v] = 1; versions[play] = versions[play] " " v } }
    END { for (p = 0; p <= play; ++p)
      printf "play %d: %d pairs checked, %d usable: mean %.3f px with the model in use, %.3f px with the plain gyro; plain gyro published after %d (%.0f %% of the usable); model versions:%s\n",
        p + 1, n[p], u[p], u[p] ? m[p] / u[p] : 0, u[p] ? g[p] / u[p] : 0, back[p], u[p] ? 100 * back[p] / u[p] : 0, versions[p] }' \
    "$out/$name.checks.sorted.csv"
  grep -E "model in use:|stabiliser model swapped|confirmed |undone |kept .* in use but|already learned from|removed .* partial" \
    "$out/$name.log" | sed 's/^\[[^]]*\] *\[[^]]*\]: //' | cut -c1-400 || true
}

session "$plays" session1
echo "==== learned files after session 1 ($ROS_HOME/deep_ois/stabilisers) ===="
ls -l "$ROS_HOME/deep_ois/stabilisers" 2>/dev/null || echo "(none)"
for f in "$ROS_HOME"/deep_ois/stabilisers/*.yaml; do [ -f "$f" ] && head -3 "$f"; done
session 1 session2
