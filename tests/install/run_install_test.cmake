# ctest driver: install the build tree into a fresh prefix, then configure, build and run the outside projects in
# PROJECT_DIR (tests/install): bullet_only (Bullet extension alone: no assimp / Eigen / nlohmann-json searched for, none
# in ldd), full (every component and every public header) and precision_mismatch (compiled with the other Bullet
# precision: must fail with bodyfit's one-line message). Arguments (-D): BUILD_DIR (the bodyfit build),
# WORK_DIR (scratch, wiped), PROJECT_DIR, GENERATOR, BUILD_TYPE.
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

foreach(project bullet_only full)
	set(build "${WORK_DIR}/${project}")
	run_step("configure ${project}" "${CMAKE_COMMAND}" -S "${PROJECT_DIR}/${project}" -B "${build}" -G "${GENERATOR}"
		"-DCMAKE_PREFIX_PATH=${prefix}" "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}")
	run_step("build ${project}" "${CMAKE_COMMAND}" --build "${build}" --config "${BUILD_TYPE}")
	run_step("run ${project}" "${build}/${project}")
	message(STATUS "${last_output}")
endforeach()

# A consumer compiled with the other Bullet precision must be stopped by the compiler with bodyfit's message.
set(build "${WORK_DIR}/precision_mismatch")
run_step("configure precision_mismatch" "${CMAKE_COMMAND}" -S "${PROJECT_DIR}/precision_mismatch" -B "${build}"
	-G "${GENERATOR}" "-DCMAKE_PREFIX_PATH=${prefix}" "-DCMAKE_BUILD_TYPE=${BUILD_TYPE}")
execute_process(COMMAND "${CMAKE_COMMAND}" --build "${build}" --config "${BUILD_TYPE}" RESULT_VARIABLE rc
	OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
	message(FATAL_ERROR "precision_mismatch: built although it uses the other Bullet precision than the package")
endif()
if(NOT "${out}${err}" MATCHES "bodyfit: this bodyfit package was built against Bullet's (float|float64) libraries")
	message(FATAL_ERROR "precision_mismatch: failed without bodyfit's precision message:\n${out}\n${err}")
endif()
message(STATUS "precision_mismatch: refused by the compiler with bodyfit's precision message: ok")

# The Bullet-only consumer: the package config must not have looked for the fitter's dependencies, and the program
# must not load them.
file(STRINGS "${WORK_DIR}/bullet_only/CMakeCache.txt" cache)
foreach(dep assimp Eigen3 nlohmann_json)
	foreach(line IN LISTS cache)
		if(line MATCHES "^${dep}_DIR:")
			message(FATAL_ERROR "bullet_only: find_package(bodyfit COMPONENTS bullet_ext) searched for ${dep} (${line})")
		endif()
	endforeach()
endforeach()
find_program(LDD ldd)
if(LDD)
	run_step("ldd bullet_only" "${LDD}" "${WORK_DIR}/bullet_only/bullet_only")
	foreach(lib assimp nlohmann eigen)
		string(TOLOWER "${last_output}" ldd_lower)
		if(ldd_lower MATCHES "${lib}")
			message(FATAL_ERROR "bullet_only links ${lib}:\n${last_output}")
		endif()
	endforeach()
	message(STATUS "bullet_only: ldd lists no assimp, Eigen or nlohmann-json")
endif()
