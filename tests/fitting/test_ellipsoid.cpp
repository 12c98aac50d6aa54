// Ellipsoid geometry: exact queries checked against closed forms and brute-force sampling.
#include "bodyfit/fitting/ellipsoid.h"
#include "support/sampling.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>

using namespace bodyfit;
using bodyfit_test::makeEllipsoid;
using bodyfit_test::randomRotation;
using bodyfit_test::randomUnitVector;

namespace
{

/// Ellipsoids the queries must handle: round, moderately and extremely (1000:1) thin, near and 1 km from the origin.
std::vector<Ellipsoid> testEllipsoids(std::mt19937& rng)
{
	std::vector<Ellipsoid> es;
	const Eigen::Vector3d far(1000.0, -250.0, 600.0);
	es.push_back(makeEllipsoid(Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(0.5, 0.5, 0.5), randomRotation(rng)));
	es.push_back(makeEllipsoid(Eigen::Vector3d(0.0, 1.0, 0.0), Eigen::Vector3d(0.3, 0.1, 0.05), randomRotation(rng)));
	es.push_back(makeEllipsoid(Eigen::Vector3d(-0.2, 0.0, 0.4), Eigen::Vector3d(1.0, 0.3, 0.001), randomRotation(rng)));
	es.push_back(makeEllipsoid(far, Eigen::Vector3d(0.2, 0.15, 0.07), randomRotation(rng)));
	es.push_back(makeEllipsoid(far, Eigen::Vector3d(0.001, 1.0, 0.001), randomRotation(rng)));
	return es;
}

double maxRadius(const Ellipsoid& e) { return e.radii.maxCoeff(); }

} // namespace

TEST_CASE("ellipsoid: zeta, radial projection and normals", "[fitting][ellipsoid]")
{
	std::mt19937 rng(11);
	for (const Ellipsoid& e : testEllipsoids(rng))
	{
		REQUIRE(e.isValid());
		for (int i = 0; i < 200; ++i)
		{
			const double s = std::uniform_real_distribution<double>(0.01, 3.0)(rng);
			const Eigen::Vector3d p = e.toWorld(s * randomUnitVector(rng).cwiseProduct(e.radii));
			// zeta is a squared scale factor: a point at scale s has zeta = s^2. World coordinates up to 1.2 km
			// carry an absolute error delta ~ 1.2e3 * 2^-52 ~ 3e-13 m; against radii >= 1e-3 m that moves zeta by
			// <= 2 s delta / r_min ~ 6e-10 s <= 1.8e-9 for s <= 3: hence the absolute margin 2e-9.
			CHECK(e.zeta(p) == Approx(s * s).epsilon(1e-9).margin(2e-9));
			const Eigen::Vector3d proj = e.radialProjection(p);
			CHECK(e.zeta(proj) == Approx(1.0).epsilon(1e-9));
			// Radial projection stays on the ray from the centre: (proj - c) parallel to (p - c).
			CHECK(((proj - e.center).normalized() - (p - e.center).normalized()).norm() < 1e-9);
			// Normal = normalised gradient of zeta, 2 R diag(1/r^2) R^T (p - c); compared in the local frame.
			const Eigen::Vector3d g = e.rotation * e.toLocal(p).cwiseQuotient(e.radii.cwiseProduct(e.radii));
			const Eigen::Vector3d n = e.normalAt(p);
			CHECK(n.norm() == Approx(1.0).epsilon(1e-12)); // unit vector up to rounding
			CHECK((n - g.normalized()).norm() < 1e-9);
		}
		// At the centre every direction is a valid answer; ours is the end of the longest axis, exactly on the surface.
		const Eigen::Vector3d top = e.radialProjection(e.center);
		CHECK(e.zeta(top) == Approx(1.0).epsilon(1e-9));
		CHECK((top - e.center).norm() == Approx(maxRadius(e)).epsilon(1e-9));
		const Eigen::Vector3d n0 = e.normalAt(e.center);
		CHECK(n0.allFinite());
		CHECK(n0.norm() == Approx(1.0).epsilon(1e-12));
	}
}

TEST_CASE("ellipsoid: normals stay finite for extreme and non-finite queries", "[fitting][ellipsoid]")
{
	const Ellipsoid e = makeEllipsoid(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1.0, 0.01, 0.001),
	                                  Eigen::Matrix3d::Identity());
	const double big = 1e300, tiny = 1e-300, nan = std::numeric_limits<double>::quiet_NaN();
	for (const Eigen::Vector3d& p : {Eigen::Vector3d(1 + big, 2, 3), Eigen::Vector3d(1 + tiny, 2, 3 + tiny),
	                                 Eigen::Vector3d(nan, 0, 0), Eigen::Vector3d(big, big, big)})
	{
		CHECK(e.normalAt(p).allFinite());
		CHECK(e.normalAt(p).norm() == Approx(1.0).epsilon(1e-12));
		CHECK(e.radialProjection(p).allFinite());
	}
}

TEST_CASE("ellipsoid: volume, tight AABB, validity and quaternion", "[fitting][ellipsoid]")
{
	std::mt19937 rng(12);
	for (const Ellipsoid& e : testEllipsoids(rng))
	{
		CHECK(e.volume() == Approx(4.0 / 3.0 * M_PI * e.radii.prod()).epsilon(1e-14));
		const Eigen::AlignedBox3d box = e.aabb();
		// Tightness: the support point along +axis i, c + S e_i / sqrt(e_i^T S e_i) with S = R diag(r^2) R^T,
		// lies on the surface and touches the box face (relative 1e-9: far-from-origin rounding, see above).
		const Eigen::Matrix3d S = e.rotation * e.radii.cwiseProduct(e.radii).asDiagonal() * e.rotation.transpose();
		for (int i = 0; i < 3; ++i)
		{
			const Eigen::Vector3d support = e.center + S.col(i) / std::sqrt(S(i, i));
			CHECK(e.zeta(support) == Approx(1.0).epsilon(1e-9));
			CHECK(support[i] - e.center[i] == Approx(box.max()[i] - e.center[i]).epsilon(1e-9));
			CHECK(e.center[i] - box.min()[i] == Approx(box.max()[i] - e.center[i]).epsilon(1e-12));
		}
		// Containment: surface samples never leave the box (slack 1e-9 * radius for rounding).
		for (int k = 0; k < 500; ++k)
		{
			const Eigen::Vector3d p = bodyfit_test::surfacePoint(e, rng);
			CHECK(((p - box.min()).array() >= -1e-9 * maxRadius(e)).all());
			CHECK(((box.max() - p).array() >= -1e-9 * maxRadius(e)).all());
		}
		// Quaternion round trip reproduces the rotation to rounding (1e-12 on unit-size entries), canonical w >= 0.
		const Eigen::Quaterniond q = toQuaternion(e.rotation);
		CHECK(q.w() >= 0.0);
		CHECK((q.toRotationMatrix() - e.rotation).cwiseAbs().maxCoeff() < 1e-12);
	}
	Ellipsoid bad;
	CHECK(bad.isValid());
	bad.radii[1] = 0.0;
	CHECK_FALSE(bad.isValid());
	bad = Ellipsoid();
	bad.rotation(0, 0) = -1.0; // reflection: orthonormal but det -1
	CHECK_FALSE(bad.isValid());
	bad = Ellipsoid();
	bad.center[2] = std::numeric_limits<double>::infinity();
	CHECK_FALSE(bad.isValid());
	bad = Ellipsoid();
	bad.rotation(0, 1) = 0.01; // not orthonormal
	CHECK_FALSE(bad.isValid());
}

TEST_CASE("ellipsoid: segmentEntry agrees with brute-force sampling", "[fitting][ellipsoid]")
{
	std::mt19937 rng(13);
	const int kSamples = 20000;
	int hits = 0, misses = 0;
	for (const Ellipsoid& e : testEllipsoids(rng))
	{
		const double R = maxRadius(e);
		for (int trial = 0; trial < 60; ++trial)
		{
			// Start outside (scale 1.05..3 of the surface), end anywhere from the centre to well outside.
			const double sq = std::uniform_real_distribution<double>(1.05, 3.0)(rng);
			const double sx = std::uniform_real_distribution<double>(0.0, 2.0)(rng);
			const Eigen::Vector3d q = e.toWorld(sq * randomUnitVector(rng).cwiseProduct(e.radii));
			const Eigen::Vector3d x = e.toWorld(sx * randomUnitVector(rng).cwiseProduct(e.radii));
			const SegmentEntry s = segmentEntry(e, q, x);
			CHECK_FALSE(s.startsInside);
			// Brute force: first grid sample inside. zeta along the segment is a quadratic, so zeta values within
			// 1e-6 of 1 (grazing) are ambiguous under rounding and skipped.
			double tFirst = -1.0, zMin = std::numeric_limits<double>::infinity();
			for (int k = 0; k <= kSamples; ++k)
			{
				const double t = double(k) / kSamples;
				const double z = e.zeta(q + t * (x - q));
				zMin = std::min(zMin, z);
				if (tFirst < 0.0 && z <= 1.0)
					tFirst = t;
			}
			if (std::abs(zMin - 1.0) < 1e-6)
				continue;
			REQUIRE(s.hit == (zMin < 1.0));
			if (!s.hit)
			{
				++misses;
				continue;
			}
			++hits;
			// The entry point is on the surface (relative 1e-8: the solve is in the unit-sphere frame; a 1000:1
			// ellipsoid 1 km away costs ~1e-13 m absolute against a 1e-3 m axis), and it is the first crossing:
			// the brute-force first inside sample lies at most one grid step after it.
			const Eigen::Vector3d entry = q + s.t * (x - q);
			CHECK(e.zeta(entry) == Approx(1.0).epsilon(1e-8));
			CHECK(s.t <= tFirst + 1e-12);
			CHECK(s.t >= tFirst - 1.0 / kSamples - 1e-12);
			(void)R;
		}
	}
	// Both outcomes must have been exercised for the comparison to mean anything.
	CHECK(hits > 50);
	CHECK(misses > 20);
}

TEST_CASE("ellipsoid: segmentEntry special cases", "[fitting][ellipsoid]")
{
	std::mt19937 rng(14);
	for (const Ellipsoid& e : testEllipsoids(rng))
	{
		const Eigen::Vector3d outside = e.toWorld(2.0 * e.radii.cwiseProduct(Eigen::Vector3d(0.6, 0.0, 0.8)));
		// q at the centre: starts inside, t = 0.
		SegmentEntry s = segmentEntry(e, e.center, outside);
		CHECK(s.hit);
		CHECK(s.startsInside);
		CHECK(s.t == 0.0);
		// q == x outside: a point, no entry. q == x inside: starts inside.
		s = segmentEntry(e, outside, outside);
		CHECK_FALSE(s.hit);
		s = segmentEntry(e, e.center, e.center);
		CHECK(s.startsInside);
		// Segment from outside ending exactly at the centre: enters at scale 1/2 along the ray (q is at scale 2).
		s = segmentEntry(e, outside, e.center);
		CHECK(s.hit);
		CHECK(s.t == Approx(0.5).epsilon(1e-9)); // relative 1e-9: far-from-origin rounding as above
		// A segment stopping short of the surface misses.
		s = segmentEntry(e, outside, e.center + 0.6 * (outside - e.center));
		CHECK_FALSE(s.hit);
		// Tangent line through a point at scale 1 + 1e-3 along the thinnest direction misses.
		int thin = 0;
		e.radii.minCoeff(&thin);
		int wide = (thin + 1) % 3;
		const Eigen::Vector3d base = e.center + 1.001 * e.radii[thin] * e.rotation.col(thin);
		s = segmentEntry(e, base - 5.0 * e.radii[wide] * e.rotation.col(wide),
		                 base + 5.0 * e.radii[wide] * e.rotation.col(wide));
		CHECK_FALSE(s.hit);
	}
}

TEST_CASE("ellipsoid: Eberly closest point agrees with brute-force surface sampling", "[fitting][ellipsoid]")
{
	std::mt19937 rng(15);
	const int nTheta = 300, nPhi = 600;
	for (const Ellipsoid& e : testEllipsoids(rng))
	{
		// Dense parametric grid of the surface; any surface point is within `spacing` of a grid point.
		std::vector<Eigen::Vector3d> grid;
		grid.reserve(size_t(nTheta + 1) * nPhi);
		for (int i = 0; i <= nTheta; ++i)
			for (int j = 0; j < nPhi; ++j)
			{
				const double th = M_PI * i / nTheta, ph = 2.0 * M_PI * j / nPhi;
				const Eigen::Vector3d u(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
				grid.push_back(e.toLocal(e.toWorld(u.cwiseProduct(e.radii)))); // local coordinates
			}
		const double spacing = maxRadius(e) * 2.0 * M_PI / nTheta;

		std::vector<Eigen::Vector3d> queries;
		for (int k = 0; k < 12; ++k) // inside and outside, generic
		{
			const double s = std::uniform_real_distribution<double>(0.05, 2.5)(rng);
			queries.push_back(e.toWorld(s * randomUnitVector(rng).cwiseProduct(e.radii)));
		}
		queries.push_back(e.center); // the centre: nearest points are the ends of the shortest axis
		for (int a = 0; a < 3; ++a)  // on each axis, inside and outside
		{
			queries.push_back(e.toWorld(0.3 * e.radii[a] * Eigen::Vector3d::Unit(a)));
			queries.push_back(e.toWorld(-1.7 * e.radii[a] * Eigen::Vector3d::Unit(a)));
		}
		for (const Eigen::Vector3d& p : queries)
		{
			const SurfacePoint sp = closestSurfacePoint(e, p);
			CHECK(e.zeta(sp.point) == Approx(1.0).epsilon(1e-8)); // on the surface (rounding, see segmentEntry)
			const Eigen::Vector3d pl = e.toLocal(p);
			double best = std::numeric_limits<double>::infinity();
			for (const Eigen::Vector3d& g : grid)
				best = std::min(best, (g - pl).squaredNorm());
			best = std::sqrt(best);
			const double d = std::abs(sp.signedDistance);
			// Eberly's answer is the true minimum: never worse than a sample (1e-9 * R for rounding), and a sample
			// lies within `spacing` of the true closest point, so the sampled minimum exceeds it by <= spacing.
			CHECK(d <= best + 1e-9 * maxRadius(e));
			CHECK(d >= best - spacing);
			CHECK(d == Approx((e.toLocal(sp.point) - pl).norm()).margin(1e-9 * maxRadius(e)));
			CHECK((sp.signedDistance < 0.0) == (e.zeta(p) < 1.0));
		}
		int thin = 0;
		const double rMin = e.radii.minCoeff(&thin);
		CHECK(closestSurfacePoint(e, e.center).signedDistance == Approx(-rMin).epsilon(1e-9));
	}
}

TEST_CASE("ellipsoid: closest point of an outside point is along the surface normal", "[fitting][ellipsoid]")
{
	std::mt19937 rng(16);
	for (const Ellipsoid& e : testEllipsoids(rng))
		for (int k = 0; k < 200; ++k)
		{
			const double s = std::uniform_real_distribution<double>(1.01, 4.0)(rng);
			const Eigen::Vector3d p = e.toWorld(s * randomUnitVector(rng).cwiseProduct(e.radii));
			const SurfacePoint sp = closestSurfacePoint(e, p);
			// First-order optimality: p - x is parallel to the outward normal at x. The angle test uses 1e-6 because
			// the thin (1000:1) cases have normals that turn by ~1e3 rad per unit of relative position error.
			const Eigen::Vector3d dir = (e.toLocal(p) - e.toLocal(sp.point)).normalized();
			const Eigen::Vector3d n = e.rotation.transpose() * e.normalAt(sp.point);
			CHECK((dir - n).norm() < 1e-6);
		}
}

TEST_CASE("ellipsoid: cloth nodes exactly on the surface", "[fitting][ellipsoid]")
{
	std::mt19937 rng(17);
	for (const Ellipsoid& e : testEllipsoids(rng))
		for (int k = 0; k < 200; ++k)
		{
			// A node projected onto the surface (as the collider leaves it) has zeta = 1 up to rounding.
			const Eigen::Vector3d q = e.radialProjection(e.toWorld(randomUnitVector(rng).cwiseProduct(e.radii)));
			const Eigen::Vector3d n = e.normalAt(q);
			const double R = maxRadius(e);
			// Moving inwards from the surface: the segment is inside from (essentially) its start. Either the
			// rounding put q inside (startsInside) or the entry is within 1e-6 of the start (relative 1e-8 zeta
			// error along a segment crossing the surface at a steep angle).
			const SegmentEntry in = segmentEntry(e, q, q - 0.5 * e.radii.minCoeff() * n);
			CHECK(in.hit);
			CHECK(in.t <= 1e-6);
			// Moving outwards along the normal never enters (a start inside by rounding reports startsInside).
			const SegmentEntry out = segmentEntry(e, q, q + 0.1 * R * n);
			CHECK((!out.hit || out.startsInside));
			// Distance of a surface point to the surface is zero (1e-9 R: rounding of the local frame).
			const SurfacePoint sp = closestSurfacePoint(e, q);
			CHECK(std::abs(sp.signedDistance) <= 1e-9 * R);
			CHECK((sp.point - q).norm() <= 1e-8 * R);
		}
}
