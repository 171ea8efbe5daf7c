# Included after project() (CMAKE_PROJECT_INCLUDE) when an interface package here is built
# against the ROS 2 wheels from PyPI: their exported targets name the Python and NumPy include
# folders of the machine that built the wheels (/opt/python/...), which do not exist here. At
# the end of the configuration, every imported target's include folders that do not exist are
# replaced by this interpreter's (Python3_INCLUDE_DIRS, Python3_NumPy_INCLUDE_DIRS).
function(_ltd_repoint_wheel_includes)
  find_package(Python3 REQUIRED COMPONENTS Interpreter Development.Module NumPy)
  get_property(targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(target IN LISTS targets)
    get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT dirs)
      continue()
    endif()
    set(fixed "")
    foreach(dir IN LISTS dirs)
      if(dir MATCHES "^/opt/python/.*numpy" AND NOT EXISTS "${dir}")
        list(APPEND fixed ${Python3_NumPy_INCLUDE_DIRS})
      elseif(dir MATCHES "^/opt/python/" AND NOT EXISTS "${dir}")
        list(APPEND fixed ${Python3_INCLUDE_DIRS})
      else()
        list(APPEND fixed "${dir}")
      endif()
    endforeach()
    set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${fixed}")
  endforeach()
endfunction()
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _ltd_repoint_wheel_includes)
