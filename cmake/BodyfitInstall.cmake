# Installation and the CMake package: `cmake --install build --prefix P` puts the libraries, the headers and
# P/lib/cmake/bodyfit/bodyfitConfig.cmake in place. An outside project then does
#     find_package(bodyfit REQUIRED)                          # every component
#     find_package(bodyfit REQUIRED COMPONENTS bullet_ext)    # Bullet only: assimp, Eigen, nlohmann-json not searched
#     target_link_libraries(app PRIVATE bodyfit::bullet_ext)
# and gets the Bullet libraries of the precision bodyfit was built with, plus BT_USE_DOUBLE_PRECISION when that was
# the float64 build (through bodyfit::bullet_deps). Components and what they pull in:
#     bullet_ext  bodyfit::bullet_ext   Bullet only
#     fitting     bodyfit::fitting      Eigen, assimp, nlohmann-json
#     bridge      bodyfit::bridge       bullet_ext + fitting
#     metrics     bodyfit::metrics      bullet_ext + fitting (+ the bridge's conversions) + nlohmann-json
#     drape       bodyfit::drape        bridge + metrics + nlohmann-json
# Headers: include/bodyfit/<layer>/*.h, included as "bodyfit/<layer>/file.h" in and outside the build tree.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(BODYFIT_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/bodyfit")

set_target_properties(bodyfit_bullet_deps PROPERTIES EXPORT_NAME bullet_deps)
set(_bodyfit_dest ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}" LIBRARY DESTINATION "${CMAKE_INSTALL_LIBDIR}"
	RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}")
# One export set per dependency group, so the Bullet-only component can be loaded alone.
install(TARGETS bodyfit_bullet_ext bodyfit_bullet_deps EXPORT bodyfitBulletTargets ${_bodyfit_dest})
install(TARGETS bodyfit_fitting EXPORT bodyfitFittingTargets ${_bodyfit_dest})
install(TARGETS bodyfit_bridge bodyfit_metrics bodyfit_drape EXPORT bodyfitSceneTargets ${_bodyfit_dest})

install(DIRECTORY "${PROJECT_SOURCE_DIR}/fitting/include/bodyfit/" DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/bodyfit"
	FILES_MATCHING PATTERN "*.h")
foreach(_dir bullet_ext bullet_ext/bridge bullet_ext/metrics bullet_ext/drape)
	install(DIRECTORY "${PROJECT_SOURCE_DIR}/${_dir}/include/bodyfit/" DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/bodyfit"
		FILES_MATCHING PATTERN "*.h")
endforeach()

install(FILES "${BODYFIT_GENERATED_INCLUDE_DIR}/bodyfit/bullet_ext/btBodyfitPrecision.h"
	DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/bodyfit/bullet_ext")

foreach(_set bodyfitBulletTargets bodyfitFittingTargets bodyfitSceneTargets)
	install(EXPORT ${_set} NAMESPACE bodyfit:: DESTINATION "${BODYFIT_INSTALL_CMAKEDIR}")
endforeach()

# The config file: resolves the requested components (and what they need), finds only those dependencies.
set(_bodyfit_config_in "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfig.cmake.in")
file(WRITE "${_bodyfit_config_in}" [=[
@PACKAGE_INIT@
# bodyfit @PROJECT_VERSION@, built against Bullet @BULLET_VERSION_STRING@, double precision: @BODYFIT_BULLET_DOUBLE@.
include(CMakeFindDependencyMacro)
set(bodyfit_BULLET_DOUBLE @BODYFIT_BULLET_DOUBLE@)
set(_bodyfit_known bullet_ext fitting bridge metrics drape)
set(_bodyfit_wanted ${bodyfit_FIND_COMPONENTS})
if(NOT _bodyfit_wanted)
	set(_bodyfit_wanted ${_bodyfit_known})
endif()
set(_bodyfit_need_fitting OFF)
set(_bodyfit_need_scene OFF)
foreach(_c IN LISTS _bodyfit_wanted)
	if(NOT _c IN_LIST _bodyfit_known)
		set(bodyfit_FOUND FALSE)
		set(bodyfit_NOT_FOUND_MESSAGE "bodyfit: unknown component '${_c}' (known: ${_bodyfit_known})")
		return()
	endif()
	if(_c STREQUAL "fitting" OR _c STREQUAL "bridge" OR _c STREQUAL "metrics" OR _c STREQUAL "drape")
		set(_bodyfit_need_fitting ON)
	endif()
	if(_c STREQUAL "bridge" OR _c STREQUAL "metrics" OR _c STREQUAL "drape")
		set(_bodyfit_need_scene ON)
	endif()
endforeach()
include("${CMAKE_CURRENT_LIST_DIR}/bodyfitBulletTargets.cmake")
if(_bodyfit_need_fitting)
	find_dependency(Eigen3 3.3 NO_MODULE)
	find_dependency(assimp)
	find_dependency(nlohmann_json 3.10)
	find_dependency(Threads)
	include("${CMAKE_CURRENT_LIST_DIR}/bodyfitFittingTargets.cmake")
endif()
if(_bodyfit_need_scene)
	include("${CMAKE_CURRENT_LIST_DIR}/bodyfitSceneTargets.cmake")
endif()
foreach(_c IN LISTS _bodyfit_wanted)
	set(bodyfit_${_c}_FOUND TRUE)
endforeach()
check_required_components(bodyfit)
]=])
configure_package_config_file("${_bodyfit_config_in}" "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfig.cmake"
	INSTALL_DESTINATION "${BODYFIT_INSTALL_CMAKEDIR}")
write_basic_package_version_file("${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfigVersion.cmake"
	VERSION "${PROJECT_VERSION}" COMPATIBILITY SameMinorVersion)
install(FILES "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfig.cmake" "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfigVersion.cmake"
	DESTINATION "${BODYFIT_INSTALL_CMAKEDIR}")
