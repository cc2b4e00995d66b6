# Precompiled headers for the heavy external headers (Eigen, OpenCV, ROS, CLI11, gtest). Compiling
# them costs ~5 s of CPU in every file that includes the ROS ones (gcc 12 at -O3; ~1 s from a
# precompiled header), so each family of targets compiles them once instead of once per file.
#
# Included at the end of CMakeLists.txt: deep_ois_precompile_headers() classifies every target
# defined so far, so a target added later in the file gets its family's header without edits here.
# Families (gcc accepts a precompiled header only under the same -fPIC/-fPIE setting, and only the
# headers a family can see may be in it):
#   library_core  libraries of src/core (Eigen, OpenCV; no ROS header, as the layers require)
#   library_ros   the other libraries (wrappers, bags, nodelets, the tools' library: also ROS)
#   tool          executables outside test/ (tools and nodes: ROS and CLI11)
#   test          executables built from test/ (gtest and ROS)
# Libraries that link libtorch get none: <torch/torch.h> alone takes ~15 s of CPU per file, but
# precompiling it took 35 s and using the 570 MB result still 5 s per file (gcc 12, measured), for
# the three files that include it.
# Each family's header is compiled once, by a small object library of its own
# (deep_ois_pch_<family>), and reused by every target of the family (REUSE_FROM), so building one
# target builds no unrelated one. Only external headers are precompiled: editing a deep_ois header
# never rebuilds a precompiled header.
#
# ccache: scripts/build.sh's compiler launcher sets CCACHE_SLOPPINESS=pch_defines,time_macros,
# which ccache needs to cache a compilation that uses a precompiled header (passed with -include).
# -DDEEP_OIS_PRECOMPILED_HEADERS=OFF builds without them (e.g. to check that every file includes
# what it uses).

option(DEEP_OIS_PRECOMPILED_HEADERS "Precompile the heavy external headers (faster cold builds)" ON)

set(_deep_ois_pch_std
  <algorithm> <chrono> <cmath> <cstdint> <cstdio> <filesystem> <fstream> <functional> <limits>
  <map> <memory> <mutex> <optional> <random> <sstream> <stdexcept> <string> <vector>)
set(_deep_ois_pch_core ${_deep_ois_pch_std}
  <Eigen/Core> <Eigen/Geometry> <Eigen/LU> <opencv2/core.hpp> <opencv2/imgproc.hpp>)
set(_deep_ois_pch_ros
  <ros/ros.h> <rosbag/bag.h> <rosbag/view.h> <sensor_msgs/Image.h> <sensor_msgs/Imu.h>
  <sensor_msgs/CameraInfo.h> <sensor_msgs/image_encodings.h> <cv_bridge/cv_bridge.h>)
set(DEEP_OIS_PCH_HEADERS_library_core ${_deep_ois_pch_core})
set(DEEP_OIS_PCH_HEADERS_library_ros ${_deep_ois_pch_core} ${_deep_ois_pch_ros})
set(DEEP_OIS_PCH_HEADERS_tool ${_deep_ois_pch_core} ${_deep_ois_pch_ros} <CLI/CLI.hpp>)
set(DEEP_OIS_PCH_HEADERS_test ${_deep_ois_pch_core} ${_deep_ois_pch_ros} <gtest/gtest.h>)

# The family of target _target in _family (empty when it gets no precompiled header).
function(_deep_ois_pch_family _target _family)
  set(${_family} "" PARENT_SCOPE)
  get_target_property(_type ${_target} TYPE)
  get_target_property(_sources ${_target} SOURCES)
  get_target_property(_links ${_target} LINK_LIBRARIES)
  if(NOT _sources OR _target MATCHES "^deep_ois_pch_")
    return()
  endif()
  set(_core_sources ${_sources})
  list(FILTER _core_sources INCLUDE REGEX "^(${PROJECT_SOURCE_DIR}/)?src/core/")
  set(_test_sources ${_sources})
  list(FILTER _test_sources INCLUDE REGEX "^(${PROJECT_SOURCE_DIR}/)?test/")
  if(_type STREQUAL "EXECUTABLE")
    if(_test_sources)
      set(${_family} test PARENT_SCOPE)
    else()
      set(${_family} tool PARENT_SCOPE)
    endif()
  elseif(_type MATCHES "^(SHARED|STATIC|MODULE)_LIBRARY$")
    if(_links AND "torch" IN_LIST _links)
      return()
    elseif(_core_sources)
      # The ROS include directories reach every target of the directory, but core code must not
      # see ROS declarations it did not include.
      set(${_family} library_core PARENT_SCOPE)
    else()
      set(${_family} library_ros PARENT_SCOPE)
    endif()
  endif()
endfunction()

function(deep_ois_precompile_headers)
  if(NOT DEEP_OIS_PRECOMPILED_HEADERS)
    return()
  endif()
  set(_families)
  get_property(_targets DIRECTORY ${PROJECT_SOURCE_DIR} PROPERTY BUILDSYSTEM_TARGETS)
  # The one source of the object libraries that compile the headers (CMake compiles a header only
  # for a target with a source that uses it). Written once: a new time stamp at every configure
  # would compile it again.
  set(_empty_source ${CMAKE_CURRENT_BINARY_DIR}/deep_ois_pch_empty.cpp)
  if(NOT EXISTS ${_empty_source})
    file(WRITE ${_empty_source} "// The object libraries that compile deep_ois' precompiled headers.\n")
  endif()
  foreach(_target ${_targets})
    _deep_ois_pch_family(${_target} _family)
    if(NOT _family)
      continue()
    endif()
    set(_producer deep_ois_pch_${_family})
    if(NOT TARGET ${_producer})
      # Same flags as the family: include directories of its first target, -fPIC for libraries
      # (executables use gcc's default -fPIE), the test framework's definitions for tests.
      # Not in `all`: REUSE_FROM makes every target of the family depend on it.
      add_library(${_producer} OBJECT EXCLUDE_FROM_ALL ${_empty_source})
      get_target_property(_includes ${_target} INCLUDE_DIRECTORIES)
      set_target_properties(${_producer} PROPERTIES INCLUDE_DIRECTORIES "${_includes}")
      if(_family MATCHES "^library_")
        set_target_properties(${_producer} PROPERTIES POSITION_INDEPENDENT_CODE ON)
      else()
        set_target_properties(${_producer} PROPERTIES POSITION_INDEPENDENT_CODE OFF)
      endif()
      if(_family STREQUAL "test")
        target_link_libraries(${_producer} PRIVATE GTest::gtest)
      endif()
      target_precompile_headers(${_producer} PRIVATE ${DEEP_OIS_PCH_HEADERS_${_family}})
    endif()
    target_precompile_headers(${_target} REUSE_FROM ${_producer})
    list(APPEND _families ${_family})
    set(_members_${_family} ${_members_${_family}} ${_target})
  endforeach()
  if(_families)
    list(REMOVE_DUPLICATES _families)
  endif()
  foreach(_family ${_families})
    list(LENGTH _members_${_family} _count)
    message(STATUS "deep_ois: precompiled headers of ${_family} for ${_count} targets")
  endforeach()
endfunction()
