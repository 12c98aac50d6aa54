#pragma once
// Deterministic random geometry for the tests and benchmarks: rotations, ellipsoids, point clouds.
// Everything takes an explicit std::mt19937 so every run draws the same numbers.
#include "bodyfit/fitting/ellipsoid.h"

#include <Eigen/Geometry>

#include <cmath>
#include <random>

namespace bodyfit_test
{

/// Uniformly distributed rotation (normalised Gaussian quaternion), det +1.
inline Eigen::Matrix3d randomRotation(std::mt19937& rng)
{
	std::normal_distribution<double> n(0.0, 1.0);
	Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
	q.normalize();
	return q.toRotationMatrix();
}

/// Uniform direction on the unit sphere.
inline Eigen::Vector3d randomUnitVector(std::mt19937& rng)
{
	std::normal_distribution<double> n(0.0, 1.0);
	Eigen::Vector3d v(n(rng), n(rng), n(rng));
	while (v.squaredNorm() < 1e-12)
		v = Eigen::Vector3d(n(rng), n(rng), n(rng));
	return v.normalized();
}

/// Ellipsoid with a random rotation, the given centre and radii.
inline bodyfit::Ellipsoid makeEllipsoid(const Eigen::Vector3d& center, const Eigen::Vector3d& radii,
                                        const Eigen::Matrix3d& rotation)
{
	bodyfit::Ellipsoid e;
	e.center = center;
	e.radii = radii;
	e.rotation = rotation;
	return e;
}

/// Point exactly on the surface: centre + R diag(r) u with u uniform on the unit sphere (not area-uniform).
inline Eigen::Vector3d surfacePoint(const bodyfit::Ellipsoid& e, std::mt19937& rng)
{
	return e.toWorld(randomUnitVector(rng).cwiseProduct(e.radii));
}

/// n points on the ellipsoid surface, one per row.
inline Eigen::MatrixX3d surfaceSamples(const bodyfit::Ellipsoid& e, int n, std::mt19937& rng)
{
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
		P.row(i) = surfacePoint(e, rng).transpose();
	return P;
}

/// n points uniform in the box [-h, h] (componentwise half-extents h), one per row.
inline Eigen::MatrixX3d boxSamples(const Eigen::Vector3d& h, int n, std::mt19937& rng)
{
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
		P.row(i) << h[0] * u(rng), h[1] * u(rng), h[2] * u(rng);
	return P;
}

/// n points from an anisotropic Gaussian with standard deviations sigma, one per row.
inline Eigen::MatrixX3d gaussianSamples(const Eigen::Vector3d& sigma, int n, std::mt19937& rng)
{
	std::normal_distribution<double> g(0.0, 1.0);
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
		P.row(i) << sigma[0] * g(rng), sigma[1] * g(rng), sigma[2] * g(rng);
	return P;
}

/// Rigid motion applied to every row: p -> R p + t.
inline Eigen::MatrixX3d transformed(const Eigen::MatrixX3d& P, const Eigen::Matrix3d& R, const Eigen::Vector3d& t)
{
	return (P * R.transpose()).rowwise() + t.transpose();
}

} // namespace bodyfit_test
