#!/usr/bin/env bash
# README command test (run by CTest, issue 23 papercut 14): the README's catkin workspace command
# once failed where a pyenv or conda python was first on PATH (pluginlib pulls in
# ament_cmake_core, whose find_package(Python3) took that python: "No module named
# 'ament_package'"). This configures the package with exactly the -D flags of the README's
# `catkin_make` line, with a python3 first on PATH that lacks Debian's modules (Debian's own
# python without its site packages, as a pyenv python is), and fails when configuring fails.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
work="$(mktemp -d /tmp/deep_ois_readme_catkin.XXXXXX)"
trap 'rm -rf "$work"' EXIT

line="$(grep -m1 -E '^ *catkin_make -D' "$repo/README.md" || true)"
[ -n "$line" ] || { echo "readme_catkin_command_test: no 'catkin_make -D...' line in README.md"; exit 1; }
read -r -a flags <<<"$(grep -oE -- '-D[A-Za-z0-9_]+=[^ `]+' <<<"$line" | tr '\n' ' ')"
echo "README: $line"

mkdir -p "$work/bin"
printf '#!/bin/sh\nexec /usr/bin/python3 -S "$@"\n' >"$work/bin/python3"
chmod +x "$work/bin/python3"
ln -s python3 "$work/bin/python"
if PATH="$work/bin:$PATH" python3 -c 'import catkin_pkg' 2>/dev/null; then
  echo "readme_catkin_command_test: the stand-in python still finds catkin_pkg"; exit 1
fi
# Torch off: configuring is what failed, and libtorch's configure step is slow.
if ! PATH="$work/bin:$PATH" cmake -S "$repo" -B "$work/build" -DDEEP_OIS_WITH_TORCH=OFF "${flags[@]}" \
    >"$work/configure.log" 2>&1; then
  echo "readme_catkin_command_test: configuring with the README's flags (${flags[*]}) failed:"
  grep -m5 -iE 'error|No module' "$work/configure.log" || tail -20 "$work/configure.log"
  exit 1
fi
echo "readme_catkin_command_test: configured with the README's flags (${flags[*]}) under a python without catkin_pkg"
