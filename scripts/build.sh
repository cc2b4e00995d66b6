#!/usr/bin/env bash
# Configures (first time) and builds deep_ois with plain cmake into _build/main (ignored by git;
# not build/, whose executables rosrun deliberately skips).
#   build.sh [--tests | --demo] [-DOPTION=VALUE ...]
# --tests also builds the gtest and rostest executables; --demo builds only what scripts/demo.sh
# runs (CMake target deep_ois_demo: the two live nodelets, gyro_flow_summary and evaluate; a later
# build.sh builds the rest); -D options go to CMake's configure step (e.g. -DDEEP_OIS_WITH_TORCH=OFF;
# DEEP_OIS_BUILD_DIR chooses the build directory).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${DEEP_OIS_BUILD_DIR:-$repo/_build/main}"
with_tests=false
target=all
cmake_options=()
for arg in "$@"; do
  case "$arg" in
    --tests) with_tests=true ;;
    --demo) target=deep_ois_demo ;;
    -D*) cmake_options+=("$arg") ;;
    *) echo "build.sh: unknown argument '$arg' (expected --tests, --demo or -DOPTION=VALUE)" >&2; exit 2 ;;
  esac
done

# A compiler cache when the machine has one (not a dependency: `apt-get install ccache` to use it).
# Paths relative to the checkout's parent folder, so that two clones share cached objects.
if command -v ccache >/dev/null && [ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" ]; then
  # pch_defines,time_macros: what ccache needs to cache a compilation that uses a precompiled
  # header (cmake/precompiled_headers.cmake); in the launcher, so that `cmake --build` has it too.
  cmake_options+=("-DCMAKE_CXX_COMPILER_LAUNCHER=env;CCACHE_SLOPPINESS=pch_defines,time_macros;ccache")
  export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$(dirname "$repo")}"
fi

# A pyenv or venv python first on PATH lacks catkin_pkg: catkin must use Debian's.
mkdir -p "$build_dir"
cmake -S "$repo" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=ON \
  -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 "${cmake_options[@]}" \
  >"$build_dir.cmake.log" 2>&1 ||
  { cat "$build_dir.cmake.log"; exit 1; }
jobs="$(nproc)"
cmake --build "$build_dir" --target "$target" -- -j"$jobs"
if [ "$with_tests" = true ]; then
  cmake --build "$build_dir" --target tests -- -j"$jobs"
fi
echo "build: done in $build_dir"
