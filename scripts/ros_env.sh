# Sourced by the demo and test scripts: the package's devel space and a ROS environment that
# keeps logs in the build folder and talks to a private master on loopback.
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${DEEP_OIS_BUILD_DIR:-$repo/_build/main}"
# Debian's catkin profile scripts read unset variables: relax `set -u` while sourcing them.
case $- in *u*) had_nounset=1; set +u ;; *) had_nounset=0 ;; esac
# shellcheck disable=SC1091
source "$build_dir/devel/setup.bash"
[ "$had_nounset" = 1 ] && set -u
export ROS_HOSTNAME=localhost
export ROS_HOME="$build_dir/ros_home"
export ROSCONSOLE_STDOUT_LINE_BUFFERED=1
export PYTHONUNBUFFERED=1
mkdir -p "$ROS_HOME"
