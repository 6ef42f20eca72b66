# Finds what the `opl` Python module (python/) needs: a Python 3 interpreter
# with numpy and its development files, and pybind11 (Debian: python3-dev,
# python3-numpy, python3-pybind11, pybind11-dev). Sets OPL_PYTHON_FOUND.
#
# The interpreter: Python3_EXECUTABLE when given (pip install . passes the one
# running it), else the first python3 on PATH that imports numpy, so that a
# pyenv or conda python3 without numpy ahead of /usr/bin/python3 is passed over.
if(NOT Python3_EXECUTABLE)
  string(REPLACE ":" ";" _opl_path "$ENV{PATH}")
  foreach(_dir IN LISTS _opl_path)
    if(EXISTS "${_dir}/python3")
      execute_process(COMMAND "${_dir}/python3" -c "import numpy"
                      RESULT_VARIABLE _opl_rc OUTPUT_QUIET ERROR_QUIET)
      if(_opl_rc EQUAL 0)
        set(Python3_EXECUTABLE "${_dir}/python3" CACHE FILEPATH "Python of the opl module")
        break()
      endif()
    endif()
  endforeach()
endif()
find_package(Python3 3.7 QUIET COMPONENTS Interpreter Development.Module)
if(Python3_FOUND)
  find_package(pybind11 2.6 CONFIG QUIET)
endif()
if(Python3_FOUND AND pybind11_FOUND)
  set(OPL_PYTHON_FOUND TRUE)
else()
  set(OPL_PYTHON_FOUND FALSE)
endif()
