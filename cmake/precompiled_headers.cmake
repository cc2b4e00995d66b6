# Precompiled headers for the heavy external headers (Eigen, OpenCV, ROS). Compiling the ROS ones
# costs ~5 s of CPU in every file that includes them (gcc 12 at -O3; ~1 s from a precompiled
# header), so they are compiled once per family of targets instead of once per file.
#
# Included at the end of CMakeLists.txt: deep_ois_precompile_headers() classifies every target
# defined so far, so a target added earlier in the file gets its family's header without edits here.
# Two families:
#   core  libraries of src/core: Eigen, OpenCV and the standard library, no ROS header (the core
#         layer must not see ROS declarations it did not include)
#   ros   every other target that compiles (wrappers, bags, nodelets, the tools' library, tools,
#         nodes, tests): the same and ROS. gcc accepts a precompiled header only under the
#         -fPIC/-fPIE setting it was made with, so the executables of this family are compiled
#         with -fPIC as the libraries are (they still link as PIE); one header then serves all.
# Not: libraries that link libtorch. <torch/torch.h> alone takes ~15 s of CPU per file, but
# precompiling it took 35 s and using the 570 MB result still 5 s per file, for the three files
# that include it. Nor CLI11 or gtest: CLI11's cost is in code generated in every file that includes
# it (precompiled, the tools gained ~1 s each and the nodes lost ~2 s), and gtest's own definitions
# (GTEST_HAS_PTHREAD) would make the header invalid for the libraries.
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

set(DEEP_OIS_PCH_HEADERS_core
  <algorithm> <chrono> <cmath> <cstdint> <cstdio> <filesystem> <fstream> <functional> <limits>
  <map> <memory> <mutex> <optional> <random> <sstream> <stdexcept> <string> <vector>
  <Eigen/Core> <Eigen/Geometry> <Eigen/LU> <opencv2/core.hpp> <opencv2/imgproc.hpp>)
set(DEEP_OIS_PCH_HEADERS_ros ${DEEP_OIS_PCH_HEADERS_core}
  <ros/ros.h> <rosbag/bag.h> <rosbag/view.h> <sensor_msgs/Image.h> <sensor_msgs/Imu.h>
  <sensor_msgs/CameraInfo.h> <sensor_msgs/image_encodings.h> <cv_bridge/cv_bridge.h>)

# The family of target _target in _family (empty when it gets no precompiled header).
function(_deep_ois_pch_family _target _family)
  set(${_family} "" PARENT_SCOPE)
  get_target_property(_type ${_target} TYPE)
  get_target_property(_sources ${_target} SOURCES)
  get_target_property(_links ${_target} LINK_LIBRARIES)
  if(NOT _sources OR _target MATCHES "^deep_ois_pch_"
     OR NOT _type MATCHES "^(EXECUTABLE|SHARED_LIBRARY|STATIC_LIBRARY|MODULE_LIBRARY)$")
    return()
  endif()
  set(_core_sources ${_sources})
  list(FILTER _core_sources INCLUDE REGEX "^(${PROJECT_SOURCE_DIR}/)?src/core/")
  if(_type STREQUAL "EXECUTABLE")
    set(${_family} ros PARENT_SCOPE)
  elseif(_links AND "torch" IN_LIST _links)
    return()
  elseif(_core_sources)
    set(${_family} core PARENT_SCOPE)
  else()
    set(${_family} ros PARENT_SCOPE)
  endif()
endfunction()

function(deep_ois_precompile_headers)
  if(NOT DEEP_OIS_PRECOMPILED_HEADERS)
    return()
  endif()
  # The one source of the object libraries that compile the headers (CMake compiles a header only
  # for a target with a source that uses it). Written once: a new time stamp at every configure
  # would compile it again.
  set(_empty_source ${CMAKE_CURRENT_BINARY_DIR}/deep_ois_pch_empty.cpp)
  if(NOT EXISTS ${_empty_source})
    file(WRITE ${_empty_source} "// The object libraries that compile deep_ois' precompiled headers.\n")
  endif()
  set(_families)
  get_property(_targets DIRECTORY ${PROJECT_SOURCE_DIR} PROPERTY BUILDSYSTEM_TARGETS)
  foreach(_target ${_targets})
    _deep_ois_pch_family(${_target} _family)
    if(NOT _family)
      continue()
    endif()
    set(_producer deep_ois_pch_${_family})
    if(NOT TARGET ${_producer})
      # Not in `all`: REUSE_FROM makes every target of the family depend on it. -fPIC as the
      # libraries; the directory's include directories, which every target has.
      add_library(${_producer} OBJECT EXCLUDE_FROM_ALL ${_empty_source})
      set_target_properties(${_producer} PROPERTIES POSITION_INDEPENDENT_CODE ON)
      target_precompile_headers(${_producer} PRIVATE ${DEEP_OIS_PCH_HEADERS_${_family}})
    endif()
    get_target_property(_type ${_target} TYPE)
    if(_type STREQUAL "EXECUTABLE")
      target_compile_options(${_target} PRIVATE -fPIC)
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
