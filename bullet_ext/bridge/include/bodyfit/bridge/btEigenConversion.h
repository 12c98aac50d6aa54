/*
bodyfit: the only header that mixes Eigen and Bullet types. Converts between double-precision Eigen values
(fitting/) and btScalar Bullet values (bullet_ext/); with a float Bullet build the conversion rounds to float.
*/

#ifndef BT_EIGEN_CONVERSION_H
#define BT_EIGEN_CONVERSION_H

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "LinearMath/btMatrix3x3.h"
#include "LinearMath/btQuaternion.h"
#include "LinearMath/btTransform.h"
#include "LinearMath/btVector3.h"

namespace bodyfit
{

inline btVector3 toBt(const Eigen::Vector3d& v)
{
	return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z()));
}

inline Eigen::Vector3d toEigen(const btVector3& v)
{
	return Eigen::Vector3d(double(v.x()), double(v.y()), double(v.z()));
}

inline btMatrix3x3 toBt(const Eigen::Matrix3d& m)
{
	return btMatrix3x3(btScalar(m(0, 0)), btScalar(m(0, 1)), btScalar(m(0, 2)), btScalar(m(1, 0)), btScalar(m(1, 1)),
					   btScalar(m(1, 2)), btScalar(m(2, 0)), btScalar(m(2, 1)), btScalar(m(2, 2)));
}

inline Eigen::Matrix3d toEigen(const btMatrix3x3& m)
{
	Eigen::Matrix3d out;
	for (int r = 0; r < 3; ++r)
		for (int c = 0; c < 3; ++c)
			out(r, c) = double(m[r][c]);
	return out;
}

/// Eigen stores (w, x, y, z) in coeffs() as (x, y, z, w); Bullet's constructor takes (x, y, z, w).
inline btQuaternion toBt(const Eigen::Quaterniond& q)
{
	return btQuaternion(btScalar(q.x()), btScalar(q.y()), btScalar(q.z()), btScalar(q.w()));
}

inline Eigen::Quaterniond toEigen(const btQuaternion& q)
{
	return Eigen::Quaterniond(double(q.w()), double(q.x()), double(q.y()), double(q.z()));
}

inline btTransform toBt(const Eigen::Isometry3d& t)
{
	return btTransform(toBt(Eigen::Matrix3d(t.linear())), toBt(Eigen::Vector3d(t.translation())));
}

inline Eigen::Isometry3d toEigen(const btTransform& t)
{
	Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
	out.linear() = toEigen(t.getBasis());
	out.translation() = toEigen(t.getOrigin());
	return out;
}

} // namespace bodyfit

#endif // BT_EIGEN_CONVERSION_H
