# Repair the include paths that the ROS 2 Jazzy PyPI wheels hard-code.
#
# The wheels' exported CMake targets (rosidl generators, rclpy-related type
# supports, ...) carry INTERFACE_INCLUDE_DIRECTORIES of the machine that built
# the wheels:
#   /opt/python/cp311-cp311/include/python3.11
#   /opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include
# This file is injected into every CMake project of the workspace with
#   -DCMAKE_PROJECT_INCLUDE=<this file>
# and defers, to the end of the top-level directory, a pass over every imported
# target that rewrites such entries to the include directories of the Python
# running the build (SEAPUP_PYTHON_INCLUDE, SEAPUP_NUMPY_INCLUDE; found from
# Python3_EXECUTABLE when not given). Nothing on disk changes. On a system ROS 2
# install no entry matches and the pass is a no-op.
#
# It fails the configure step loudly when an imported target names any other
# directory of a wheel-build machine (SEAPUP_FOREIGN_PATTERN, default: anything
# under /opt/python/): that means the wheels changed their layout and this fix
# must be revisited.
cmake_minimum_required(VERSION 3.21)  # IMPORTED_TARGETS directory property

if(NOT DEFINED SEAPUP_FOREIGN_PREFIX)
  set(SEAPUP_FOREIGN_PREFIX "/opt/python/cp311-cp311")
endif()
if(NOT DEFINED SEAPUP_FOREIGN_PATTERN)
  set(SEAPUP_FOREIGN_PATTERN "^/opt/python/")
endif()

function(_seapup_python_dirs out_inc out_numpy)
  set(_inc "${SEAPUP_PYTHON_INCLUDE}")
  set(_np "${SEAPUP_NUMPY_INCLUDE}")
  if(NOT _inc OR NOT _np)
    set(_py "${Python3_EXECUTABLE}")
    if(NOT _py)
      message(FATAL_ERROR
        "fix_ros_wheel_paths: set Python3_EXECUTABLE (or SEAPUP_PYTHON_INCLUDE and "
        "SEAPUP_NUMPY_INCLUDE) so the wheel include paths can be repaired")
    endif()
    execute_process(
      COMMAND "${_py}" -c "import sysconfig, numpy; print(sysconfig.get_paths()['include']); print(numpy.get_include())"
      OUTPUT_VARIABLE _out RESULT_VARIABLE _rc OUTPUT_STRIP_TRAILING_WHITESPACE)
    if(NOT _rc EQUAL 0)
      message(FATAL_ERROR "fix_ros_wheel_paths: '${_py}' could not report its include dirs (numpy missing?)")
    endif()
    string(REPLACE "\n" ";" _out "${_out}")
    list(GET _out 0 _inc)
    list(GET _out 1 _np)
  endif()
  set(${out_inc} "${_inc}" PARENT_SCOPE)
  set(${out_numpy} "${_np}" PARENT_SCOPE)
endfunction()

function(seapup_fix_ros_wheel_paths)
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  set(_need FALSE)
  foreach(_t IN LISTS _targets)
    get_target_property(_dirs ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(_dirs AND "${_dirs}" MATCHES "${SEAPUP_FOREIGN_PATTERN}")
      set(_need TRUE)
    endif()
  endforeach()
  if(NOT _need)
    return()
  endif()
  _seapup_python_dirs(_py_inc _np_inc)
  set(_fixed 0)
  foreach(_t IN LISTS _targets)
    get_target_property(_dirs ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs)
      continue()
    endif()
    set(_new "")
    set(_changed FALSE)
    foreach(_d IN LISTS _dirs)
      if(_d STREQUAL "${SEAPUP_FOREIGN_PREFIX}/include/python3.11")
        list(APPEND _new "${_py_inc}")
        set(_changed TRUE)
      elseif(_d MATCHES "^${SEAPUP_FOREIGN_PREFIX}/.*/numpy/_core/include$")
        list(APPEND _new "${_np_inc}")
        set(_changed TRUE)
      elseif(_d MATCHES "${SEAPUP_FOREIGN_PATTERN}")
        message(FATAL_ERROR
          "fix_ros_wheel_paths: imported target ${_t} names '${_d}', a wheel-build path "
          "this fix does not know. The ROS wheels changed: update cmake/fix_ros_wheel_paths.cmake.")
      else()
        list(APPEND _new "${_d}")
      endif()
    endforeach()
    if(_changed)
      set_target_properties(${_t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_new}")
      math(EXPR _fixed "${_fixed} + 1")
    endif()
  endforeach()
  message(STATUS "fix_ros_wheel_paths: repaired include dirs of ${_fixed} imported targets "
                 "(python: ${_py_inc}; numpy: ${_np_inc})")
endfunction()

# CMAKE_PROJECT_INCLUDE runs after every project() call: schedule the pass once.
get_property(_seapup_scheduled GLOBAL PROPERTY SEAPUP_FIX_ROS_WHEEL_PATHS_SCHEDULED)
if(NOT _seapup_scheduled)
  set_property(GLOBAL PROPERTY SEAPUP_FIX_ROS_WHEEL_PATHS_SCHEDULED TRUE)
  cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL seapup_fix_ros_wheel_paths)
endif()
