#!/usr/bin/env bash
# Installs every Debian bookworm package deep_ois needs to build, run and test.
# Idempotent: apt-get skips what is already installed. Needs root (or sudo).
#   --visualisation  also rviz (launch/replay.launch rviz:=true, rviz/deep_ois.rviz) and the tools
#                    for headless screenshots (Xvfb, ImageMagick's import). Optional: rviz pulls
#                    Qt5, Ogre and OpenGL (~270 packages) that building, testing and the demo
#                    do not need.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake pkg-config git
  # catkin and ROS 1 build machinery (Debian's own ROS, in /usr)
  catkin python3-catkin-pkg python3-catkin ros-cmake-modules
  ros-message-generation ros-message-runtime
  # message definitions (.msg files) and their C++ headers
  ros-std-msgs libstd-msgs-dev ros-sensor-msgs libsensor-msgs-dev
  ros-geometry-msgs libgeometry-msgs-dev ros-tf2-msgs libtf2-msgs-dev
  libros-rosgraph-msgs-dev ros-rosgraph-msgs
  # client libraries
  libroscpp-dev libroslib-dev librosconsole-dev libnodeletlib-dev libnodeletlib-tools pluginlib-dev
  libimage-transport-dev libcv-bridge-dev libtf2-ros-dev libtf2-dev libtf2-eigen-dev
  libmessage-filters-dev librosbag-dev librosbag-storage-dev libcamera-calibration-parsers-dev
  libtopic-tools-dev libroslz4-dev libbz2-dev
  # live tuning and health of the nodelets: dynamic_reconfigure, /diagnostics
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libdiagnostic-updater-dev ros-diagnostic-msgs libdiagnostic-msgs-dev
  # run time tools: master, rosout, roslaunch, rosbag play, rostest
  python3-rosmaster python3-roslaunch rosout python3-rosbag rosbash
  python3-rostest librostest-dev python3-rosnode python3-rostopic
  # the Python side of every message type the nodelets and tools publish or read, for rostopic
  # echo/pub, rosbag's Python API and rospy (deep_ois's generated Python messages import std_msgs
  # and sensor_msgs): Imu, Image, CameraInfo, /tf_static, /diagnostics, /clock, /rosout, the
  # dynamic_reconfigure topics; rosmsg/rossrv (python3-rosmsg); rospy for the launch files'
  # deprecated-argument warning (scripts/deprecated_launch_argument)
  python3-std-msgs python3-sensor-msgs python3-geometry-msgs python3-tf2-msgs
  python3-diagnostic-msgs python3-rosgraph-msgs python3-rosmsg python3-rospy
  # maths, vision, tests
  # the nonlinear least-squares solver of core
  libceres-dev
  libeigen3-dev libopencv-dev libgtest-dev libgmock-dev libyaml-cpp-dev mate-backgrounds
  # the tools: flag parsing, the evaluation JSON, the data-set SHA-256
  libcli11-dev nlohmann-json3-dev libssl-dev
  # the tools' PNG charts (scripts/plot_csv.py over the CSVs they write) and the figures of docs/
  # (scripts/plot_generated_designs.py)
  python3-matplotlib
  # convert_recording's video input: OpenCV's FFmpeg backend (HEVC, H.264)
  libopencv-videoio-dev
  # the compensation network (CPU libtorch 1.13)
  libtorch-dev
)

if [ "${1:-}" = "--visualisation" ]; then
  packages+=(rviz xvfb imagemagick)
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages already installed"
  exit 0
fi
echo "install_deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"

# rostest and roslaunch resolve 'localhost'; some minimal images lack the entry.
if ! grep -qE '^127\.0\.0\.1[[:space:]].*\blocalhost\b' /etc/hosts; then
  echo "127.0.0.1 localhost" | $SUDO tee -a /etc/hosts >/dev/null
fi
