#!/usr/bin/env bash
# Installs the dependencies, builds everything including the tests, and runs every gtest and
# rostest through CTest; then configures a second build without libtorch (-DDEEP_OIS_WITH_TORCH=OFF)
# and runs its tests, so the torch-free part of the package is proven to build and work on its own.
# Ends with CTest's summary lines; exits non-zero when a test fails.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/install_deps.sh"

run_suite() {  # $1: build directory, further arguments: extra CMake options
  local dir="$1"
  shift
  # Called in a `||` list, where `set -e` does not apply: every step checks its own status.
  DEEP_OIS_BUILD_DIR="$dir" bash "$repo/scripts/build.sh" --tests "$@" || return 1
  (
    export DEEP_OIS_BUILD_DIR="$dir"
    # shellcheck disable=SC1091
    source "$repo/scripts/ros_env.sh"
    cd "$dir" && ctest --output-on-failure
  ) || return 1
}

status=0
run_suite "$repo/_build/main" || status=$?
# Outside the package folder: rosrun searches the whole package for executables, and a second
# build tree in it would make `rosrun deep_ois TOOL` ambiguous for the demo.
notorch_dir="${DEEP_OIS_NOTORCH_BUILD_DIR:-${TMPDIR:-/tmp}/deep_ois_build_notorch_$(printf %s "$repo" | md5sum | cut -c1-8)}"
echo "test: the torch-free build (-DDEEP_OIS_WITH_TORCH=OFF) in $notorch_dir"
run_suite "$notorch_dir" -DDEEP_OIS_WITH_TORCH=OFF || status=$?
exit "$status"
