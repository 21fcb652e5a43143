# The ROS 2 Jazzy wheels on PyPI export <pkg>::<pkg>__rosidl_generator_py targets whose
# INTERFACE_INCLUDE_DIRECTORIES name the wheel builder's Python and numpy headers
# (/opt/python/cp311-cp311/...), which do not exist here, so CMake's generate step fails.
# Re-point every such imported target whose directories do not exist at this interpreter's headers.
# Nothing installed is modified; with a regular ROS installation the directories exist and nothing changes.
function(geodesic_planner_fix_python_include_dirs)
  find_package(Python3 REQUIRED COMPONENTS Interpreter Development.Module NumPy)
  get_directory_property(_targets IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    if(_target MATCHES "__rosidl_generator_py$")
      get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
      set(_missing FALSE)
      foreach(_dir IN LISTS _dirs)
        if(NOT EXISTS "${_dir}")
          set(_missing TRUE)
        endif()
      endforeach()
      if(_missing)
        set_target_properties(${_target} PROPERTIES
          INTERFACE_INCLUDE_DIRECTORIES "${Python3_INCLUDE_DIRS};${Python3_NumPy_INCLUDE_DIRS}")
      endif()
    endif()
  endforeach()
endfunction()
