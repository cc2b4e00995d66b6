#!/usr/bin/env bash
# Installs the dependencies, builds everything including the tests, and runs every gtest and
# rostest through CTest; then configures a second build without libtorch (-DDEEP_OIS_WITH_TORCH=OFF),
# builds everything in it and runs the tests whose outcome depends on that switch, so the torch-free
# part of the package is proven to build and work on its own.
# Ends with CTest's summary lines; exits non-zero when a test fails.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/install_deps.sh"

run_suite() {  # $1: build directory, $2: what to build and run ("all" or "torch_switch"), then CMake options
  local dir="$1" scope="$2"
  shift 2
  # Called in a `||` list, where `set -e` does not apply: every step checks its own status.
  if [ "$scope" = all ]; then
    DEEP_OIS_BUILD_DIR="$dir" bash "$repo/scripts/build.sh" --tests "$@" || return 1
  else
    # Every target, and of the test executables only those the labelled tests run.
    DEEP_OIS_BUILD_DIR="$dir" bash "$repo/scripts/build.sh" "$@" || return 1
    cmake --build "$dir" --target test_evaluation_runner -- -j"$(nproc)" || return 1
  fi
  (
    export DEEP_OIS_BUILD_DIR="$dir"
    # shellcheck disable=SC1091
    source "$repo/scripts/ros_env.sh"
    if [ "$scope" = all ]; then
      cd "$dir" && ctest --output-on-failure
    else
      cd "$dir" && ctest --output-on-failure -L "$scope"
    fi
  ) || return 1
}

status=0
run_suite "$repo/_build/main" all || status=$?
# Outside the package folder: rosrun searches the whole package for executables, and a second
# build tree in it would make `rosrun deep_ois TOOL` ambiguous for the demo.
notorch_dir="${DEEP_OIS_NOTORCH_BUILD_DIR:-${TMPDIR:-/tmp}/deep_ois_build_notorch_$(printf %s "$repo" | md5sum | cut -c1-8)}"
# The torch-free build: everything is built; the tests labelled torch_switch in CMakeLists.txt run
# (the others compile the same sources with the same flags and have run above).
echo "test: the torch-free build (-DDEEP_OIS_WITH_TORCH=OFF) in $notorch_dir"
run_suite "$notorch_dir" torch_switch -DDEEP_OIS_WITH_TORCH=OFF || status=$?
exit "$status"
