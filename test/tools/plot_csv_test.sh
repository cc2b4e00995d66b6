#!/usr/bin/env bash
# scripts/plot_csv.py under the system python: a small CSV gives a PNG of the requested size with
# ink on it; a missing column or a missing matplotlib is an exit status and a message, never a
# stale PNG.  Usage: plot_csv_test.sh SOURCE_DIR
set -euo pipefail
script="$1/scripts/plot_csv.py"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
fail() { echo "plot_csv_test: $*" >&2; exit 1; }

# PNG header: width and height are big-endian 32-bit integers at bytes 16 and 20.
png_size() { od -An -tu1 -j16 -N8 "$1" | awk '{printf "%dx%d", $1*16777216+$2*65536+$3*256+$4, $5*16777216+$6*65536+$7*256+$8}'; }

{
  echo "t_s,logged_px,predicted_px"
  for i in $(seq 0 200); do
    awk -v i="$i" 'BEGIN { t = i * 0.005; printf "%.3f,%.4f,%.4f\n", t, sin(20 * t), 0.9 * sin(20 * t) }'
  done
  echo "1.010,,0.5"  # an empty cell is a gap, not an error
} >"$work/curve.csv"

/usr/bin/python3 "$script" "$work/curve.csv" "$work/curve.png" --x t_s --x-label "time [s]" \
  --series logged_px "logged" logged 1 --series predicted_px "predicted" predicted 1 \
  --y-label "lens shift [px]" --title "plot_csv test" --size 640x360 ||
  fail "exit status $? on a valid CSV"
[ -s "$work/curve.png" ] || fail "no PNG written"
size="$(png_size "$work/curve.png")"
[ "$size" = "640x360" ] || fail "PNG is $size, expected 640x360"
bytes="$(stat -c %s "$work/curve.png")"
# A blank 640x360 PNG compresses to about 2 kB; axes, ticks, labels and two curves are far more.
[ "$bytes" -gt 15000 ] || fail "PNG of $bytes bytes: nearly empty"

# Two panels sharing x, log y.
/usr/bin/python3 "$script" "$work/curve.csv" "$work/panels.png" --x t_s \
  --series logged_px a line 1 --series predicted_px b line 2 --log-y --size 800x600 ||
  fail "exit status $? for two panels"
[ "$(png_size "$work/panels.png")" = "800x600" ] || fail "two panels: PNG is $(png_size "$work/panels.png")"

# A column that is not in the CSV: exit 1, named, no PNG.
set +e
message="$(/usr/bin/python3 "$script" "$work/curve.csv" "$work/bad.png" --x t_s --series nope n 2>&1)"
status=$?
set -e
[ "$status" = 1 ] || fail "missing column: exit status $status, expected 1"
[[ "$message" == *"no column nope"* ]] || fail "missing column not named: $message"
[ ! -e "$work/bad.png" ] || fail "a PNG was written for a missing column"

# matplotlib missing (a package of that name that fails to import, first on PYTHONPATH): exit 3.
mkdir -p "$work/shadow/matplotlib"
echo 'raise ImportError("matplotlib hidden by plot_csv_test")' >"$work/shadow/matplotlib/__init__.py"
set +e
message="$(PYTHONPATH="$work/shadow" /usr/bin/python3 "$script" "$work/curve.csv" "$work/none.png" \
  --x t_s --series logged_px logged 2>&1)"
status=$?
set -e
[ "$status" = 3 ] || fail "matplotlib missing: exit status $status, expected 3"
[[ "$message" == *"python3-matplotlib"* ]] || fail "matplotlib missing: message does not name the package: $message"
[ ! -e "$work/none.png" ] || fail "a PNG was written without matplotlib"
echo "plot_csv_test: passed"
