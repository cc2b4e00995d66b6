#!/usr/bin/env bash
# Installs the dependencies, builds everything including the tests, and runs every gtest and
# rostest through CTest. Ends with CTest's summary line; exits non-zero when a test fails.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/install_deps.sh"
bash "$repo/scripts/build.sh" --tests
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
cd "$build_dir"
ctest --output-on-failure
