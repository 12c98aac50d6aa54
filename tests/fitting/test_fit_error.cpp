// Fitting error (paper eq. 6) and the true distance: exact values on simple shapes, and radial >= true distance.
#include "bodyfit/fitting/fit_error.h"
#include "support/sampling.h"

#include <catch2/catch.hpp>

#include <random>

using namespace bodyfit;

TEST_CASE("fit_error: radial distance on a sphere and along the axes of an ellipsoid", "[fitting][fit_error]")
{
	Ellipsoid sphere;
	sphere.radii = Eigen::Vector3d::Constant(2.0);
	sphere.center = Eigen::Vector3d(1, 2, 3);
	// On a sphere the radial projection is the closest point: both distances are | |p - c| - r |.
	// 1e-14: a handful of roundings on numbers of size ~2.
	const Eigen::Vector3d inside = sphere.center + Eigen::Vector3d(0.3, -0.4, 1.2); // |d| = 1.3
	CHECK(radialDistance(sphere, inside) == Approx(0.7).margin(1e-14));
	CHECK(radialDistance(sphere, sphere.center + Eigen::Vector3d(0, 0, 2)) == Approx(0.0).margin(1e-14));
	CHECK(radialDistance(sphere, sphere.center + Eigen::Vector3d(3, 0, 0)) == Approx(1.0).margin(1e-14));

	Ellipsoid e;
	e.radii = Eigen::Vector3d(3, 2, 1);
	for (int axis = 0; axis < 3; ++axis)
	{
		// Half way along an axis the radial projection is the axis end point: distance = radius / 2.
		const Eigen::Vector3d p = 0.5 * e.radii(axis) * Eigen::Vector3d::Unit(axis);
		CHECK(radialDistance(e, p) == Approx(0.5 * e.radii(axis)).margin(1e-14));
	}
	// At the centre: the longest semi-axis, the answer of Ellipsoid::radialProjection for that case.
	CHECK(radialDistance(e, e.center) == 3.0);
	CHECK(radialDistance(e, e.center) == Approx((e.center - e.radialProjection(e.center)).norm()).margin(1e-14));
}

TEST_CASE("fit_error: radial distance agrees with radialProjection and bounds the true distance", "[fitting][fit_error]")
{
	std::mt19937 rng(42);
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	for (int trial = 0; trial < 20; ++trial)
	{
		const Ellipsoid e = bodyfit_test::makeEllipsoid(Eigen::Vector3d(u(rng), u(rng), u(rng)),
														Eigen::Vector3d(0.05 + std::abs(u(rng)), 0.05 + std::abs(u(rng)),
																		0.05 + std::abs(u(rng))),
														bodyfit_test::randomRotation(rng));
		Eigen::MatrixX3d pts(200, 3);
		for (int i = 0; i < 200; ++i)
			pts.row(i) = (e.center + 2.0 * e.rotation * e.radii.cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng))))
							 .transpose();
		std::vector<int> all(200);
		for (int i = 0; i < 200; ++i)
			all[std::size_t(i)] = i;
		const FitError err = fitError(e, pts, all);
		double sum = 0.0;
		for (int i = 0; i < 200; ++i)
		{
			const Eigen::Vector3d p = pts.row(i).transpose();
			const double r = radialDistance(e, p);
			// The same quantity computed from the library's radial projection; 1e-12 relative to the ~1 m scale.
			CHECK(r == Approx((p - e.radialProjection(p)).norm()).margin(1e-12));
			// The radial path ends on the surface, so it is never shorter than the closest-point distance
			// (up to the closest-point solver's accuracy, ~1e-12 here).
			CHECK(std::abs(closestSurfacePoint(e, p).signedDistance) <= r + 1e-12);
			sum += r;
		}
		CHECK(err.vertexCount == 200);
		CHECK(err.radialMean == Approx(sum / 200).epsilon(1e-14));
		CHECK(meanRadialError(e, pts, all) == err.radialMean);
		CHECK(err.distanceMean <= err.radialMean + 1e-12);
		CHECK(err.distanceMax <= err.radialMax + 1e-12);
	}
}

TEST_CASE("fit_error: subsets, empty sets and the flag for true distances", "[fitting][fit_error]")
{
	Ellipsoid e;
	e.radii = Eigen::Vector3d(1, 1, 1);
	Eigen::MatrixX3d pts(3, 3);
	pts << 0.5, 0, 0, 0, 0.9, 0, 5, 5, 5;
	const FitError two = fitError(e, pts, {0, 1});
	CHECK(two.vertexCount == 2);
	CHECK(two.radialMean == Approx(0.3).margin(1e-15)); // (0.5 + 0.1) / 2
	CHECK(two.radialMax == Approx(0.5).margin(1e-15));
	CHECK(two.distanceMean == Approx(0.3).margin(1e-12));
	const FitError noTrue = fitError(e, pts, {0, 1}, false);
	CHECK(noTrue.distanceMean == 0.0);
	CHECK(noTrue.distanceMax == 0.0);
	const FitError none = fitError(e, pts, {});
	CHECK(none.vertexCount == 0);
	CHECK(none.radialMean == 0.0);
	CHECK(meanRadialError(e, pts, {}) == 0.0);
}
