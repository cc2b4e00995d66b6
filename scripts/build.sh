#!/usr/bin/env bash
# Configures (first time) and builds deep_ois with plain cmake into _build/main (ignored by git;
# not build/, whose executables rosrun deliberately skips).
# Pass --tests to build the gtest and rostest executables too.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${DEEP_OIS_BUILD_DIR:-$repo/_build/main}"

# A pyenv or venv python first on PATH lacks catkin_pkg: catkin must use Debian's.
mkdir -p "$build_dir"
cmake -S "$repo" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=ON \
  -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 >"$build_dir.cmake.log" 2>&1 ||
  { cat "$build_dir.cmake.log"; exit 1; }
jobs="$(nproc)"
cmake --build "$build_dir" -- -j"$jobs"
if [ "${1:-}" = "--tests" ]; then
  cmake --build "$build_dir" --target tests -- -j"$jobs"
fi
echo "build: done in $build_dir"
