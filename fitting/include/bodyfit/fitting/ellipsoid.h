#pragma once
/// \file ellipsoid.h
/// An oriented ellipsoid and the exact geometric queries the fitter and the cloth collider need.

#include "bodyfit/fitting/types.h"

#include <Eigen/Geometry>

namespace bodyfit
{

/// Oriented ellipsoid {x : |diag(1/radii) * rotation^T * (x - center)|^2 <= 1}.
/// `rotation` is a proper rotation (det +1) whose columns are the principal axes in world space;
/// `radii` are the semi-axes along those columns (metres, > 0).
struct Ellipsoid
{
	Eigen::Vector3d center = Eigen::Vector3d::Zero();
	Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
	Eigen::Vector3d radii = Eigen::Vector3d::Ones();

	/// Point in the ellipsoid's principal frame (not scaled).
	Eigen::Vector3d toLocal(const Eigen::Vector3d& p) const { return rotation.transpose() * (p - center); }
	Eigen::Vector3d toWorld(const Eigen::Vector3d& local) const { return center + rotation * local; }

	/// zeta(p) = |diag(1/r) R^T (p - c)|^2: < 1 inside, 1 on the surface, > 1 outside (paper eq. 5).
	double zeta(const Eigen::Vector3d& p) const;

	/// Radial projection onto the surface along the ray from the centre (paper eq. 6): c + (p - c)/sqrt(zeta).
	/// For p at the centre, returns the end of the longest axis (any surface point is a valid answer).
	Eigen::Vector3d radialProjection(const Eigen::Vector3d& p) const;

	/// Outward unit normal of the level set of zeta through p (gradient direction). Finite for every p.
	Eigen::Vector3d normalAt(const Eigen::Vector3d& p) const;

	double volume() const;

	/// Tight axis-aligned bounding box in world space.
	Eigen::AlignedBox3d aabb() const;

	/// True when centre, rotation and radii are finite, radii > 0 and rotation is orthonormal with det +1
	/// (within `tolerance`).
	bool isValid(double tolerance = 1e-6) const;
};

/// Result of intersecting the segment q -> x with an ellipsoid.
struct SegmentEntry
{
	bool hit = false;          ///< the segment enters (or starts inside) the closed ellipsoid
	bool startsInside = false; ///< zeta(q) <= 1: t is 0 and the caller must push q out
	double t = 1.0;            ///< entry parameter in [0, 1]: the entry point is q + t (x - q)
};

/// First point of the segment q -> x inside the ellipsoid. Numerically stable for q at the centre,
/// very thin ellipsoids (axis ratios up to 1000:1) and far-from-origin coordinates (works in the local frame).
SegmentEntry segmentEntry(const Ellipsoid& e, const Eigen::Vector3d& q, const Eigen::Vector3d& x);

/// Closest point on the ellipsoid surface to p (Eberly, "Distance from a Point to an Ellipse, an Ellipsoid,
/// or a Hyperellipsoid", robust bisection), valid inside and outside.
struct SurfacePoint
{
	Eigen::Vector3d point;  ///< closest surface point (world)
	double signedDistance;  ///< |p - point|, negative when p is inside
};
SurfacePoint closestSurfacePoint(const Ellipsoid& e, const Eigen::Vector3d& p);

/// Quaternion (w, x, y, z) <-> rotation matrix helpers used by the file formats.
Eigen::Quaterniond toQuaternion(const Eigen::Matrix3d& rotation);

} // namespace bodyfit
