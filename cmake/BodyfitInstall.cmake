# Installation and the CMake package: `cmake --install build --prefix P` puts the libraries, the headers and
# P/lib/cmake/bodyfit/bodyfitConfig.cmake in place, so an outside project does
#     find_package(bodyfit REQUIRED)
#     target_link_libraries(app PRIVATE bodyfit::bullet_ext)
# and gets the Bullet libraries of the precision bodyfit was built with, plus BT_USE_DOUBLE_PRECISION when that was
# the float64 build (through bodyfit::bullet_deps). Layout:
#     include/bodyfit/*.h                    fitting (namespace bodyfit)
#     include/bodyfit/bullet_ext/*.h         btEllipsoidShape.h, btEllipsoidCompoundShape.h, btEllipsoidClothCollider.h
#     include/bodyfit/bullet_ext/bridge/*.h  btEigenConversion.h, btBodyFitToBullet.h
# bodyfit::bullet_ext puts include/bodyfit/bullet_ext on the include path, so `#include "btEllipsoidClothCollider.h"`
# works the same in and outside the build tree.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(BODYFIT_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/bodyfit")

set_target_properties(bodyfit_bullet_deps PROPERTIES EXPORT_NAME bullet_deps)
install(TARGETS bodyfit_fitting bodyfit_bullet_ext bodyfit_bullet_deps
	EXPORT bodyfitTargets
	ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}"
	LIBRARY DESTINATION "${CMAKE_INSTALL_LIBDIR}"
	RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}")

install(DIRECTORY "${PROJECT_SOURCE_DIR}/fitting/include/bodyfit/" DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/bodyfit"
	FILES_MATCHING PATTERN "*.h")
install(FILES
	"${PROJECT_SOURCE_DIR}/bullet_ext/btEllipsoidShape.h"
	"${PROJECT_SOURCE_DIR}/bullet_ext/btEllipsoidCompoundShape.h"
	"${PROJECT_SOURCE_DIR}/bullet_ext/btEllipsoidClothCollider.h"
	DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/bodyfit/bullet_ext")
install(FILES
	"${PROJECT_SOURCE_DIR}/bullet_ext/bridge/btEigenConversion.h"
	"${PROJECT_SOURCE_DIR}/bullet_ext/bridge/btBodyFitToBullet.h"
	DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/bodyfit/bullet_ext/bridge")

install(EXPORT bodyfitTargets NAMESPACE bodyfit:: DESTINATION "${BODYFIT_INSTALL_CMAKEDIR}")

# The config file: dependencies of the static libraries first, then the targets.
set(_bodyfit_config_in "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfig.cmake.in")
file(WRITE "${_bodyfit_config_in}" [=[
@PACKAGE_INIT@
# bodyfit @PROJECT_VERSION@: bodyfit::fitting (mesh -> ellipsoids), bodyfit::bullet_ext (Bullet extension).
# Built against Bullet @BULLET_VERSION_STRING@, double precision: @BODYFIT_BULLET_DOUBLE@.
include(CMakeFindDependencyMacro)
find_dependency(Eigen3 3.3 NO_MODULE)
find_dependency(assimp)
find_dependency(nlohmann_json 3.10)
include("${CMAKE_CURRENT_LIST_DIR}/bodyfitTargets.cmake")
set(bodyfit_BULLET_DOUBLE @BODYFIT_BULLET_DOUBLE@)
check_required_components(bodyfit)
]=])
configure_package_config_file("${_bodyfit_config_in}" "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfig.cmake"
	INSTALL_DESTINATION "${BODYFIT_INSTALL_CMAKEDIR}")
write_basic_package_version_file("${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfigVersion.cmake"
	VERSION "${PROJECT_VERSION}" COMPATIBILITY SameMinorVersion)
install(FILES "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfig.cmake" "${CMAKE_CURRENT_BINARY_DIR}/bodyfitConfigVersion.cmake"
	DESTINATION "${BODYFIT_INSTALL_CMAKEDIR}")
