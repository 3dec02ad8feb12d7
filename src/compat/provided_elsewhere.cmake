# Included by the compat interface packages. A machine with a system ROS 2 (e.g.
# /opt/ros/jazzy) has the real package, with all its types: then this workspace
# builds nothing for it, so the system's package is the one everyone uses.
# Sets PROVIDED_ELSEWHERE to the prefix that has ${PROJECT_NAME}, or leaves it empty.
set(PROVIDED_ELSEWHERE "")
string(REPLACE ":" ";" _dombot_prefixes "$ENV{AMENT_PREFIX_PATH}")
foreach(_prefix IN LISTS _dombot_prefixes)
  get_filename_component(_prefix "${_prefix}" ABSOLUTE)
  get_filename_component(_own "${CMAKE_INSTALL_PREFIX}" ABSOLUTE)
  if(_prefix STREQUAL _own)
    continue()  # our own earlier build of this package
  endif()
  if(EXISTS "${_prefix}/share/ament_index/resource_index/packages/${PROJECT_NAME}")
    set(PROVIDED_ELSEWHERE "${_prefix}")
    break()
  endif()
endforeach()
if(PROVIDED_ELSEWHERE)
  message(STATUS "${PROJECT_NAME} is provided by ${PROVIDED_ELSEWHERE}: nothing to build here")
endif()
