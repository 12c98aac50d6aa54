# ctest driver: install the build tree into a fresh prefix, configure + build the outside project against it,
# run it. Arguments (-D): BUILD_DIR (the bodyfit build), WORK_DIR (scratch, wiped), PROJECT_DIR (tests/install/project),
# GENERATOR, BUILD_TYPE.
foreach(var BUILD_DIR WORK_DIR PROJECT_DIR GENERATOR)
	if(NOT DEFINED ${var})
		message(FATAL_ERROR "run_install_test.cmake: ${var} is not set")
	endif()
endforeach()
if(NOT BUILD_TYPE)
	set(BUILD_TYPE Release)
endif()
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")

function(run_step what)
	execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
	if(NOT rc EQUAL 0)
		message(FATAL_ERROR "${what} failed (${rc}):\n${out}\n${err}")
	endif()
	message(STATUS "${what}: ok")
	set(last_output "${out}" PARENT_SCOPE)
endfunction()

run_step("cmake --install" "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${prefix}" --config "${BUILD_TYPE}")
run_step("configure outside project" "${CMAKE_COMMAND}" -S "${PROJECT_DIR}" -B "${WORK_DIR}/build" -G "${GENERATOR}"
	"-DCMAKE_PREFIX_PATH=${prefix}" "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}")
run_step("build outside project" "${CMAKE_COMMAND}" --build "${WORK_DIR}/build" --config "${BUILD_TYPE}")
run_step("run outside project" "${WORK_DIR}/build/outside")
message(STATUS "${last_output}")
