#!/usr/bin/env bash
# Writes docs/command_line_tools.md from the tools' own `--help` output, so the page says what the
# built tools accept. Run after a build: bash scripts/make_command_line_docs.sh [BUILD_DIR]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${1:-${DEEP_OIS_BUILD_DIR:-$repo/_build/main}}"
bin="$build_dir/devel/lib/deep_ois"
out="$repo/docs/command_line_tools.md"
# The tools in the order a user meets them; the list must match DEEP_OIS_TOOLS in CMakeLists.txt.
tools=(simulate sim_contact_sheet convert_recording annotate_pairs calibrate make_calibration_configs
  calibration_benchmark train_stabiliser benchmark_lens_dynamics benchmark_solver
  benchmark_linear_dynamics lens_log_fit predict_lens
  fundamental_mixtures train evaluate
  evaluate_fundamental_mixtures evaluate_lens_shift_ground_truth gyro_flow_summary bag_static_transforms
  live_rate_monitor recover_bag benchmark_gyro_flow benchmark_compensation benchmark_fundamental_mixtures
  benchmark_simulator benchmark_online_learning benchmark_online_calibration benchmark_fusion)
listed="$(sed -n '/^set(DEEP_OIS_TOOLS/,/^endif()/p' "$repo/CMakeLists.txt" | tr -s ' ()\n' '\n' |
  grep -E '^[a-z_]+$' | grep -vE '^(set|if|endif|list|APPEND|DEEP_OIS_TOOLS|Torch_FOUND)$' | sort)"
if [ "$listed" != "$(printf '%s\n' "${tools[@]}" | sort)" ]; then
  echo "make_command_line_docs: the tool list differs from DEEP_OIS_TOOLS in CMakeLists.txt" >&2
  exit 1
fi
{
  echo "# Command-line tools"
  echo
  echo "Every tool parses its flags the same way (CLI11, \`include/deep_ois/tools/support/command_line.h\`):"
  echo "\`TOOL --help\` prints what it does and every flag with its type or unit and its default, and"
  echo "exits 0; an unknown flag, a missing or malformed value (\`--epochs 10x\`, \`--lr nan\`, a negative"
  echo "count) or a missing required flag prints \`TOOL: --flag: problem\` and exits 2 before any work."
  echo "Run a tool with \`rosrun deep_ois TOOL\` (or from \`_build/main/devel/lib/deep_ois/\`)."
  echo "\`train\` and \`benchmark_compensation\` exist only in builds with libtorch."
  echo
  echo "Charts: a tool that draws a PNG (train, train_stabiliser, lens_log_fit, predict_lens, evaluate,"
  echo "benchmark_online_learning) writes its data as CSV first, time in seconds, then draws the PNG with"
  echo "\`scripts/plot_csv.py\` (Debian's \`python3-matplotlib\`, under \`/usr/bin/python3\`). Without"
  echo "matplotlib it says so and keeps the CSV; \`scripts/plot_csv.py --help\` redraws one by hand."
  echo
  echo "This page is generated from the tools' \`--help\` by \`scripts/make_command_line_docs.sh\`."
  for tool in "${tools[@]}"; do
    echo
    echo "## $tool"
    echo
    echo '```'
    if [ -x "$bin/$tool" ]; then
      # Defaults that are paths of this checkout read as the package's.
      "$bin/$tool" --help | sed "s|$repo/|<deep_ois>/|g"
    else
      echo "(not built here: $bin/$tool)"
    fi
    echo '```'
  done
} >"$out"
echo "make_command_line_docs: wrote $out"
