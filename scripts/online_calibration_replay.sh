#!/usr/bin/env bash
# A recording played once through the live pipeline (launch/deep_ois.launch with use_sim_time,
# `rosbag play --clock`), to see what the online calibration ends with, or how well a given
# calibration aligns the recording's tracks. Records the per-pair check (compensation_check) and
# the online calibration (online_calibration); prints the check's mean residuals over the usable
# pairs (with the plain gyro: the calibration alone) and the last online_calibration message, and
# writes OUTDIR/NAME.checks.csv (stamp, usable, gyro residual) for comparisons between runs.
#
#   online_calibration_replay.sh BAG OUTDIR NAME --gyro-config FILE.yaml [--calibration FILE.yaml]
#       [--model FILE.yaml] [--no-online-calibration] [--online-calibration-mount]
#
# The learned files go to OUTDIR/ros_home (emptied first). Not run in CI (a live replay: the
# recording's length plus ~20 s).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 3 ] || { sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
bag="$(realpath "$1")" out="$2" name="$3"; shift 3
gyro_config="" calibration="" model_args=() online=true mount=false
while [ $# -gt 0 ]; do
  case "$1" in
    --gyro-config) gyro_config="$(realpath "$2")"; shift 2 ;;
    --calibration) calibration="$(realpath "$2")"; shift 2 ;;
    --model) model_args=(model:="$(realpath "$2")"); shift 2 ;;
    --no-online-calibration) online=false; shift ;;
    --online-calibration-mount) mount=true; shift ;;
    *) echo "online_calibration_replay: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[ -n "$gyro_config" ] || { echo "online_calibration_replay: --gyro-config is required" >&2; exit 2; }
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
mkdir -p "$out"
out="$(realpath "$out")"
export ROS_HOME="$out/ros_home"
rm -rf "$ROS_HOME"
mkdir -p "$ROS_HOME"
export ROS_MASTER_URI=http://localhost:11354
config="$out/$name.compensation.yaml"
sed -e "s/^online_calibration: .*/online_calibration: $online/" \
    -e "s/^online_calibration_mount: .*/online_calibration_mount: $mount/" "$repo/config/compensation.yaml" >"$config"
topics=(/imu/data /camera/image_raw /camera/camera_info)
grep -q '^imu_to_camera_rotation:' "$gyro_config" || topics+=(/tf_static)

roslaunch -p 11354 deep_ois deep_ois.launch use_sim_time:=true gyro_config:="$gyro_config" \
  calibration:="$calibration" compensation_config:="$config" "${model_args[@]}" >"$out/$name.log" 2>&1 &
launch_pid=$!
for _ in $(seq 1 100); do
  rosparam get /use_sim_time >/dev/null 2>&1 && break
  kill -0 "$launch_pid" 2>/dev/null || { echo "the launch failed:"; tail -20 "$out/$name.log"; exit 1; }
  sleep 0.2
done
rosbag record -O "$out/$name.bag" /deep_ois/compensation_check /deep_ois/online_calibration \
  __name:=check_recorder >>"$out/$name.log" 2>&1 &
record_pid=$!
# The compensation subscribes its inputs only while an output has a subscriber: the recorder's.
rosbag play --clock --quiet --wait-for-subscribers --delay 3 --queue 2000 "$bag" --topics "${topics[@]}" \
  >>"$out/$name.log" 2>&1
sleep 4  # the checks come a few pairs after their pair
kill -INT "$record_pid" 2>/dev/null || true
wait "$record_pid" 2>/dev/null || true
kill -INT "$launch_pid" 2>/dev/null || true
wait "$launch_pid" 2>/dev/null || true

rostopic echo -b "$out/$name.bag" -p /deep_ois/compensation_check >"$out/$name.checks.raw.csv"
awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; print "stamp,usable,gyro_residual,model_residual"; next }
  { print $col["field.header.stamp"] "," $col["field.usable"] "," $col["field.gyro_residual"] "," $col["field.model_residual"] }' \
  "$out/$name.checks.raw.csv" | sort -t, -k1,1n >"$out/$name.checks.csv"
echo "==== $name ===="
awk -F, 'NR > 1 { n++; if ($2 == 1) { u++; g += $3; m += $4 } }
  END { printf "%d pairs checked, %d usable: mean %.4f px with the plain gyro (the calibration in use), %.4f px with the compensation published\n", n, u, u ? g / u : 0, u ? m / u : 0 }' \
  "$out/$name.checks.csv"
/usr/bin/python3 - "$out/$name.bag" <<'PY'
import sys
import rosbag
last = None
for _, m, _ in rosbag.Bag(sys.argv[1]).read_messages(topics=["/deep_ois/online_calibration"]):
    last = m
if last is None:
    print("no online_calibration message")
else:
    print("online calibration at the end: state %s, version %d, time offset %.4f ms (estimate %.4f +- %.4f ms), "
          "readout %.4f ms (estimate %.4f +- %.4f ms), bias (%.5f, %.5f, %.5f) rad/s; %d pairs (%d without tracks), "
          "%d fits (%d needing motion, %d rejected), %d swaps (%d undone, %d confirmed); %s; last: %s"
          % (last.state, last.version, 1e3 * last.time_offset, 1e3 * last.estimate_time_offset,
             1e3 * last.estimate_time_offset_sigma, 1e3 * last.readout_time, 1e3 * last.estimate_readout_time,
             1e3 * last.estimate_readout_time_sigma, last.gyro_bias[0], last.gyro_bias[1], last.gyro_bias[2],
             last.pairs, last.pairs_without_tracks, last.fits, last.fits_needing_motion, last.fits_rejected,
             last.swaps, last.swaps_undone, last.swaps_confirmed, last.confirmation, last.last_reason))
PY
grep -E "online calibration|following the online calibration" "$out/$name.log" | sed 's/^\[[^]]*\] *\[[^]]*\]: //' |
  cut -c1-300 | tail -8 || true
ls "$ROS_HOME"/deep_ois/stabilisers/ 2>/dev/null || true
