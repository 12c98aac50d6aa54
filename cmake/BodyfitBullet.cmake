# Bullet 3.24 from Debian ships BulletConfig.cmake with variables only (relative paths, no targets) and
# two builds side by side: float (libBulletSoftBody.so) and float64 (libBulletSoftBody-float64.so).
# The ABI depends on BT_USE_DOUBLE_PRECISION (sizeof(btSoftBody::Node) is 256 vs 472 bytes), so the define
# must travel with the libraries. We wrap them once in an INTERFACE target; nothing directory-wide.
find_package(Bullet REQUIRED CONFIG)

set(_bodyfit_bullet_root "${BULLET_ROOT_DIR}")
set(_bodyfit_bullet_inc "${BULLET_INCLUDE_DIR}")
if(NOT IS_ABSOLUTE "${_bodyfit_bullet_inc}")
	set(_bodyfit_bullet_inc "${_bodyfit_bullet_root}/${_bodyfit_bullet_inc}")
endif()
set(_bodyfit_bullet_libdir "${BULLET_LIBRARY_DIRS}")
if(NOT IS_ABSOLUTE "${_bodyfit_bullet_libdir}")
	set(_bodyfit_bullet_libdir "${_bodyfit_bullet_root}/${_bodyfit_bullet_libdir}")
endif()

set(_bodyfit_suffix "")
if(BODYFIT_BULLET_DOUBLE)
	set(_bodyfit_suffix "-float64")
endif()

set(BODYFIT_BULLET_LIBRARIES "")
foreach(_lib BulletSoftBody BulletDynamics BulletCollision LinearMath)
	find_library(BODYFIT_${_lib}_LIBRARY NAMES ${_lib}${_bodyfit_suffix}
		HINTS "${_bodyfit_bullet_libdir}" NO_DEFAULT_PATH)
	if(NOT BODYFIT_${_lib}_LIBRARY)
		message(FATAL_ERROR "bodyfit: Bullet library ${_lib}${_bodyfit_suffix} not found in ${_bodyfit_bullet_libdir}")
	endif()
	list(APPEND BODYFIT_BULLET_LIBRARIES "${BODYFIT_${_lib}_LIBRARY}")
endforeach()

add_library(bodyfit_bullet_deps INTERFACE)
target_include_directories(bodyfit_bullet_deps SYSTEM INTERFACE "$<BUILD_INTERFACE:${_bodyfit_bullet_inc}>"
	"$<INSTALL_INTERFACE:${_bodyfit_bullet_inc}>")
target_link_libraries(bodyfit_bullet_deps INTERFACE ${BODYFIT_BULLET_LIBRARIES})
if(BODYFIT_BULLET_DOUBLE)
	target_compile_definitions(bodyfit_bullet_deps INTERFACE BT_USE_DOUBLE_PRECISION)
endif()
message(STATUS "bodyfit: Bullet ${BULLET_VERSION_STRING} (${_bodyfit_bullet_libdir}), double precision: ${BODYFIT_BULLET_DOUBLE}")
