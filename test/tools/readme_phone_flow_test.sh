#!/usr/bin/env bash
# README phone-flow test (run by CTest, issue 33): the README's "From a phone recording" commands,
# exactly as written there (REC_DIR = the shared VideoIMUCapture recording), run end to end in a
# temporary folder: convert_recording, calibrate, train_stabiliser; then the files the roslaunch
# line names must exist (the live pipeline itself is not started). calibrate used to refuse this
# recording ("readout statistical 1-sigma ... exceeds 0.25 ms") and the rest failed on the missing
# rec_cal.yaml; it now takes the logged readout and the Android mount from rec.gyro_flow.yaml as
# priors, held only where the recording cannot determine them, and must say so.
# Skips (prints "phone recording not found", which CTest reports as skipped) without the recording.
#   bash test/tools/readme_phone_flow_test.sh [BUILD_DIR] [SHARED_DATA_DIR]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
export DEEP_OIS_BUILD_DIR="${1:-$repo/_build/main}"
shared="${2:-$repo/../shared/data}"
recording="$shared/videoimucapture_pixel"
if [ ! -f "$recording/video_meta.pb3" ]; then
  echo "readme_phone_flow_test: phone recording not found: $recording"
  exit 0
fi
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
work="$(mktemp -d /tmp/deep_ois_phone_flow.XXXXXX)"
trap 'rm -rf "$work"' EXIT
cd "$work"

# The command block after "**From a phone recording**", up to the roslaunch line.
mapfile -t commands < <(awk '/^\*\*From a phone recording\*\*/ {on = 1; next}
                             on && /^    rosrun deep_ois / {sub(/^    /, ""); print; next}
                             on && /^    roslaunch / {exit}' "$repo/README.md")
[ "${#commands[@]}" -ge 3 ] || { echo "readme_phone_flow_test: no phone-flow commands found in README.md"; exit 1; }
launch="$(awk '/^\*\*From a phone recording\*\*/ {on = 1} on && /^    roslaunch / {print; exit}' "$repo/README.md")"
[ -n "$launch" ] || { echo "readme_phone_flow_test: no roslaunch line in the README's phone flow"; exit 1; }

for command in "${commands[@]}"; do
  command="${command//REC_DIR/$recording}"
  echo "readme_phone_flow_test: \$ $command"
  read -r -a words <<<"$command"
  started=$SECONDS
  if ! "${words[@]}" >"$work/out.log" 2>&1; then
    cat "$work/out.log"
    echo "readme_phone_flow_test: FAILED after $((SECONDS - started)) s: $command"
    exit 1
  fi
  # The tool's summary (its progress bars, on stderr, drawn with carriage returns, left out).
  tr "\r" "\n" <"$work/out.log" | grep -vE "^\||pairs tracked|frames \[|^ *$" | tail -n 25
  echo "readme_phone_flow_test: ok in $((SECONDS - started)) s"
  if [ "${words[2]}" = calibrate ]; then
    # The output says which values came from the recording's metadata and which from the data.
    grep -qE "^  time offset .*\(from the data\)" "$work/out.log" ||
      { echo "readme_phone_flow_test: calibrate does not say the time offset came from the data"; exit 1; }
    grep -qE "\(from rec\.gyro_flow\.yaml, held\)" "$work/out.log" ||
      { echo "readme_phone_flow_test: calibrate does not say which values came from rec.gyro_flow.yaml"; exit 1; }
    grep -q "^# from rec.gyro_flow.yaml" rec_cal.yaml ||
      { echo "readme_phone_flow_test: rec_cal.yaml does not say which values came from rec.gyro_flow.yaml"; exit 1; }
  fi
done

# The live launch line's files: what the README's next command loads.
for file in $(grep -oE '\$PWD/[A-Za-z0-9_.]+' <<<"$launch" | sed 's#^\$PWD/##'); do
  [ -s "$file" ] || { echo "readme_phone_flow_test: $file (named by the roslaunch line) was not written"; exit 1; }
done
echo "readme_phone_flow_test: the README's phone flow ran end to end on $recording"
