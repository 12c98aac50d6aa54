// btEllipsoidCompoundShape (analytic data in sync with the Bullet children), btEllipsoidWorldCache (world space
// + grid broadphase) and the bridge from bodyfit::Ellipsoid.
#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/bridge/btEigenConversion.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include "bodyfit/fitting/errors.h"

#include "support/paths.h"

#include <catch2/catch.hpp>

#include <algorithm>

#include <cstdio>
#include <fstream>
#include <random>

namespace
{

// Relative precision of btScalar: geometric tolerances below are a small multiple of it (float and double builds).
const double kEps = double(SIMD_EPSILON);

btVector3 randomUnit(std::mt19937& rng)
{
	std::normal_distribution<double> n(0.0, 1.0);
	return btVector3(btScalar(n(rng)), btScalar(n(rng)), btScalar(n(rng))).normalized();
}

btMatrix3x3 randomRotation(std::mt19937& rng)
{
	std::uniform_real_distribution<double> a(0.0, 6.283);
	return btMatrix3x3(btQuaternion(randomUnit(rng), btScalar(a(rng))));
}

/// zeta of child i evaluated through the Bullet child (transform + btEllipsoidShape).
double childZeta(const btEllipsoidCompoundShape& s, int i, const btVector3& localPoint)
{
	const btTransform& t = s.getChildTransform(i);
	return double(s.getEllipsoidShape(i)->zeta(t.invXform(localPoint)));
}

/// The analytic array and the Bullet children describe the same ellipsoids: zeta agrees at random points.
void requireInSync(const btEllipsoidCompoundShape& s, std::mt19937& rng)
{
	REQUIRE(s.getNumChildShapes() == s.getNumEllipsoids());
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	for (int i = 0; i < s.getNumEllipsoids(); ++i)
		for (int k = 0; k < 20; ++k)
		{
			const btVector3 p(btScalar(u(rng)), btScalar(u(rng)), btScalar(u(rng)));
			const double a = double(s.zeta(i, p));
			const double b = childZeta(s, i, p);
			// Two evaluation orders of the same quadratic form: relative agreement to ~100 ulps.
			CHECK(a == Approx(b).epsilon(200 * kEps).margin(200 * kEps));
		}
}

} // namespace

TEST_CASE("compound: packed analytic data stays in sync with the children", "[bullet_ext][compound]")
{
	std::mt19937 rng(1);
	btEllipsoidCompoundShape s;
	REQUIRE(s.getShapeType() == COMPOUND_SHAPE_PROXYTYPE);
	for (int i = 0; i < 6; ++i)
		s.addEllipsoid(randomUnit(rng) * btScalar(0.3), randomRotation(rng),
					   btVector3(btScalar(0.05 + 0.05 * i), btScalar(0.1), btScalar(0.04 + 0.01 * i)));
	requireInSync(s, rng);

	// Q = R diag(a^-2) R^T: the semi-axis end points have zeta 1.
	for (int i = 0; i < s.getNumEllipsoids(); ++i)
	{
		const btEllipsoidLocalData& d = s.getEllipsoid(i);
		for (int k = 0; k < 3; ++k)
		{
			const btVector3 end = d.m_center + d.m_basis.getColumn(k) * d.m_semiAxes[k];
			CHECK(double(s.zeta(i, end)) == Approx(1.0).margin(64 * kEps));
		}
		// The analytic local AABB is tight: each face is touched by a surface point (u = unit row of R diag(a)).
		btVector3 mn, mx;
		s.getChildShape(i)->getAabb(s.getChildTransform(i), mn, mx);
		const btMatrix3x3 m = d.m_basis.scaled(d.m_semiAxes);
		for (int k = 0; k < 3; ++k)
		{
			const btVector3 u = m[k].normalized();
			const btVector3 touch = d.m_center + m * u;
			CHECK(double(s.zeta(i, touch)) == Approx(1.0).margin(64 * kEps));
			CHECK(double(touch[k]) == Approx(double(d.m_aabbMax[k])).margin(1e-6));
			// Bullet's box of the child (core + margin sphere) contains it and is at most one margin larger.
			CHECK(double(mx[k]) >= double(d.m_aabbMax[k]) - 1e-6);
			CHECK(double(mn[k]) <= double(d.m_aabbMin[k]) + 1e-6);
			CHECK(double(mx[k] - d.m_aabbMax[k]) <= double(s.getChildMargin()) + 1e-6);
		}
	}

	SECTION("setEllipsoid")
	{
		s.setEllipsoid(2, btVector3(0.1, 0.2, 0.3), randomRotation(rng), btVector3(0.2, 0.05, 0.1));
		requireInSync(s, rng);
		CHECK(double(s.getEllipsoid(2).m_semiAxes.y()) == Approx(0.05));
	}
	SECTION("removeEllipsoid moves the last one into the hole")
	{
		const btVector3 lastCenter = s.getEllipsoid(5).m_center;
		const btCollisionShape* lastShape = s.getChildShape(5);
		s.removeEllipsoid(1);
		REQUIRE(s.getNumEllipsoids() == 5);
		CHECK(s.getChildShape(1) == lastShape);
		CHECK((s.getEllipsoid(1).m_center - lastCenter).length() < 1e-6);
		requireInSync(s, rng);
		s.removeChildShape(s.getChildShape(0)); // the virtual Bullet entry point keeps the arrays in sync too
		REQUIRE(s.getNumEllipsoids() == 4);
		requireInSync(s, rng);
	}
	SECTION("non-uniform local scaling is the exact affine image")
	{
		std::vector<btEllipsoidLocalData> before;
		for (int i = 0; i < s.getNumEllipsoids(); ++i)
			before.push_back(s.getEllipsoid(i));
		const btVector3 scale(1.5, 0.7, 1.2);
		s.setLocalScaling(scale);
		requireInSync(s, rng);
		// p inside the original <=> S p inside the scaled one: zeta(S p) after = zeta(p) before.
		std::uniform_real_distribution<double> u(-0.6, 0.6);
		for (int i = 0; i < s.getNumEllipsoids(); ++i)
			for (int k = 0; k < 20; ++k)
			{
				const btVector3 p(btScalar(u(rng)), btScalar(u(rng)), btScalar(u(rng)));
				const btVector3 d = p - before[size_t(i)].m_center;
				const double zBefore = double(d.dot(before[size_t(i)].m_Q * d));
				// The Jacobi eigen-decomposition (btMatrix3x3::diagonalize) converges to ~1e-6 relative in float.
				CHECK(double(s.zeta(i, p * scale)) == Approx(zBefore).epsilon(1e-4).margin(1e-5));
			}
		s.setLocalScaling(btVector3(1, 1, 1));
		for (int i = 0; i < s.getNumEllipsoids(); ++i)
			CHECK((s.getEllipsoid(i).m_center - before[size_t(i)].m_center).length() < 1e-5);
	}
}

TEST_CASE("compound: the local AABB grown per add is exactly the recomputed one", "[bullet_ext][compound]")
{
	// addEllipsoid grows the AABB by the new child's box (O(1)) instead of recomputing it over all children (O(n));
	// min/max of the same boxes, so the result must be bit-identical to Bullet's recalculateLocalAabb.
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> u(0.01, 0.2);
	btEllipsoidCompoundShape s;
	auto check = [&] {
		btVector3 lo, hi;
		s.getAabb(btTransform::getIdentity(), lo, hi);
		// Independent reference: the union of every child's Bullet box, plus the compound's margin.
		btVector3 refLo(BT_LARGE_FLOAT, BT_LARGE_FLOAT, BT_LARGE_FLOAT), refHi = -refLo;
		for (int i = 0; i < s.getNumChildShapes(); ++i)
		{
			btVector3 a, b;
			s.getChildShape(i)->getAabb(s.getChildTransform(i), a, b);
			refLo.setMin(a);
			refHi.setMax(b);
		}
		// getAabb goes through centre +- half extent (+ margin), which rounds: a few ulps of coordinates below 4 m
		// (float ulp 2.4e-7 m), so 1e-6 m.
		for (int k = 0; k < 3; ++k)
		{
			CHECK(double(lo[k]) == Approx(double(refLo[k] - s.getMargin())).margin(1e-6));
			CHECK(double(hi[k]) == Approx(double(refHi[k] + s.getMargin())).margin(1e-6));
		}
		// Bit-identical to Bullet's recomputation over all children.
		s.recalculateLocalAabb();
		btVector3 lo2, hi2;
		s.getAabb(btTransform::getIdentity(), lo2, hi2);
		CHECK(lo2 == lo);
		CHECK(hi2 == hi);
	};
	for (int i = 0; i < 400; ++i)
	{
		if (i == 200)
			s.setLocalScaling(btVector3(1.5, 0.7, 1.2)); // later adds go in scaled (non-uniform: rotated boxes)
		s.addEllipsoid(randomUnit(rng) * btScalar(3.0 * u(rng)), randomRotation(rng),
			btVector3(btScalar(u(rng)), btScalar(u(rng)), btScalar(u(rng))));
		if (i % 25 == 0 || i == 399)
			check();
	}
	requireInSync(s, rng);
	// The first add into an empty compound: the box is the child's, not grown from the origin.
	btEllipsoidCompoundShape one;
	one.addEllipsoid(btVector3(5, 5, 5), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
	btVector3 lo, hi;
	one.getAabb(btTransform::getIdentity(), lo, hi);
	CHECK(double(lo.x()) > 4.8);
	CHECK(double(hi.x()) < 5.2);
}

TEST_CASE("compound: bad input is sanitised, never NaN", "[bullet_ext][compound]")
{
	btEllipsoidCompoundShape s;
	// A reflection (det -1) and a non-orthonormal basis are turned into a proper rotation describing the same set.
	btMatrix3x3 reflect(1, 0, 0, 0, 1, 0, 0, 0, -1);
	s.addEllipsoid(btVector3(0, 0, 0), reflect, btVector3(0.3, 0.2, 0.1));
	CHECK(double(s.getEllipsoid(0).m_basis.determinant()) == Approx(1.0).margin(1e-5));
	CHECK(double(s.zeta(0, btVector3(0, 0, 0.1))) == Approx(1.0).margin(1e-5));
	btMatrix3x3 sheared(1, 0.1, 0, 0, 1, 0, 0, 0, 1);
	s.addEllipsoid(btVector3(0, 0, 0), sheared, btVector3(0.3, 0.2, 0.1));
	const btMatrix3x3& r = s.getEllipsoid(1).m_basis;
	CHECK(double((r * r.transpose())[0][1]) == Approx(0.0).margin(1e-5));
	btMatrix3x3 zero(0, 0, 0, 0, 0, 0, 0, 0, 0);
	s.addEllipsoid(btVector3(0, 0, 0), zero, btVector3(0.3, 0.2, 0.1));
	CHECK(double(s.getEllipsoid(2).m_basis.determinant()) == Approx(1.0).margin(1e-5));
}

TEST_CASE("world cache: world-space entries match the local data, grid query equals brute force", "[bullet_ext][compound]")
{
	std::mt19937 rng(9);
	btEllipsoidCompoundShape s;
	std::uniform_real_distribution<double> u(-0.5, 0.5);
	for (int i = 0; i < 40; ++i)
		s.addEllipsoid(btVector3(btScalar(u(rng)), btScalar(3 * u(rng)), btScalar(u(rng))), randomRotation(rng),
					   btVector3(btScalar(0.02 + 0.1 * (u(rng) + 0.5)), btScalar(0.05), btScalar(0.01 + 0.001 * i)));
	btTransform body(btQuaternion(btVector3(0.3, 1, 0.2).normalized(), btScalar(0.8)), btVector3(2, -1, 0.5));
	btEllipsoidWorldCache cache;
	REQUIRE(cache.update(&s, body));
	CHECK_FALSE(cache.update(&s, body)); // nothing changed: no recomputation
	REQUIRE(cache.size() == 40);
	for (int k = 0; k < 200; ++k)
	{
		const btVector3 local(btScalar(u(rng)), btScalar(3 * u(rng)), btScalar(u(rng)));
		const btVector3 world = body * local;
		for (int i = 0; i < 40; i += 7)
			CHECK(double(cache.zeta(i, world)) == Approx(double(s.zeta(i, local))).epsilon(1e-4).margin(1e-5));
		// Grid query vs brute force over entry boxes.
		const btVector3 half(btScalar(0.05 * (k % 4)), btScalar(0.02), btScalar(0.1));
		btAlignedObjectArray<int> got;
		cache.query(world - half, world + half, got);
		std::vector<int> expect;
		for (int i = 0; i < cache.size(); ++i)
		{
			const btEllipsoidWorldCache::Entry& e = cache[i];
			const btVector3 mn = world - half, mx = world + half;
			if (!(mn.x() > e.m_aabbMax.x() || mx.x() < e.m_aabbMin.x() || mn.y() > e.m_aabbMax.y() ||
				  mx.y() < e.m_aabbMin.y() || mn.z() > e.m_aabbMax.z() || mx.z() < e.m_aabbMin.z()))
				expect.push_back(i);
		}
		std::vector<int> gotSorted;
		for (int j = 0; j < got.size(); ++j)
			gotSorted.push_back(got[j]);
		std::sort(gotSorted.begin(), gotSorted.end());
		CHECK(gotSorted == expect);
		// minZeta through the grid equals the brute-force minimum where it is finite (inside some box).
		double brute = 1e30;
		for (int i = 0; i < cache.size(); ++i)
		{
			const btEllipsoidWorldCache::Entry& e = cache[i];
			if (world.x() >= e.m_aabbMin.x() && world.x() <= e.m_aabbMax.x() && world.y() >= e.m_aabbMin.y() &&
				world.y() <= e.m_aabbMax.y() && world.z() >= e.m_aabbMin.z() && world.z() <= e.m_aabbMax.z())
				brute = std::min(brute, double(cache.zeta(i, world)));
		}
		if (brute < 1e30)
			CHECK(double(cache.minZeta(world)) == Approx(brute));
	}
	// The whitening maps each ellipsoid to the unit ball and back.
	for (int i = 0; i < cache.size(); ++i)
	{
		const btEllipsoidWorldCache::Entry& e = cache[i];
		const btMatrix3x3 id = e.m_whiten * e.m_unwhiten;
		for (int r = 0; r < 3; ++r)
			for (int c = 0; c < 3; ++c)
				CHECK(double(id[r][c]) == Approx(r == c ? 1.0 : 0.0).margin(100 * kEps));
	}
	// Moving the body or editing the compound refreshes the cache.
	body.setOrigin(btVector3(0, 0, 0));
	CHECK(cache.update(&s, body));
	s.setEllipsoid(0, btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
	CHECK(cache.update(&s, body));
}

TEST_CASE("bridge: bodyfit::Ellipsoid <-> compound, and the JSON path", "[bullet_ext][compound][bridge]")
{
	std::vector<bodyfit::Ellipsoid> list(3);
	list[0].center = Eigen::Vector3d(0, 1, 0);
	list[0].radii = Eigen::Vector3d(0.2, 0.1, 0.05);
	list[1].center = Eigen::Vector3d(0.1, 0.9, 0);
	list[1].rotation = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
	list[1].radii = Eigen::Vector3d(0.15, 0.15, 0.3);
	list[2].center = Eigen::Vector3d(-0.2, 1.1, 0.05);
	list[2].radii = Eigen::Vector3d(0.05, 0.05, 0.05);
	std::unique_ptr<btEllipsoidCompoundShape> s = bodyfit::createEllipsoidCompound(list);
	REQUIRE(s->getNumEllipsoids() == 3);
	const std::vector<bodyfit::Ellipsoid> back = bodyfit::toEllipsoids(*s);
	for (size_t i = 0; i < list.size(); ++i)
	{
		// btScalar round trip: float keeps ~7 digits.
		CHECK((back[i].center - list[i].center).norm() < 1e-6);
		CHECK((back[i].radii - list[i].radii).norm() < 1e-6);
		CHECK((back[i].rotation - list[i].rotation).norm() < 1e-5);
		std::mt19937 rng{unsigned(i)};
		std::uniform_real_distribution<double> u(-0.4, 0.4);
		for (int k = 0; k < 20; ++k)
		{
			const Eigen::Vector3d p = list[i].center + Eigen::Vector3d(u(rng), u(rng), u(rng));
			CHECK(double(s->zeta(int(i), bodyfit::toBt(p))) == Approx(list[i].zeta(p)).epsilon(1e-4).margin(1e-5));
		}
	}

	// Errors at the edge are typed and name the problem.
	CHECK_THROWS_AS(bodyfit::createEllipsoidCompound({}), bodyfit::InvalidInputError);
	std::vector<bodyfit::Ellipsoid> bad = list;
	bad[1].radii.y() = -1;
	CHECK_THROWS_WITH(bodyfit::createEllipsoidCompound(bad), Catch::Contains("ellipsoid 1"));
	CHECK_THROWS(bodyfit::loadEllipsoidCompound(bodyfit_test::dataPath("does_not_exist.json")));
	CHECK_THROWS(bodyfit::loadEllipsoidCompound(bodyfit_test::dataPath("garbage.obj")));

	// A minimal valid file through the JSON reader.
	const std::string path = "bridge_test_ellipsoids.json";
	{
		std::ofstream f(path);
		f << R"({"format": "bodyfit.ellipsoids", "version": 1, "ellipsoids": [
			{"region": "whole", "center": [0, 1, 0], "rotation": [1, 0, 0, 0], "axes": [0.2, 0.1, 0.05]},
			{"region": "whole", "center": [0.1, 1, 0], "rotation": [0.7071067811865476, 0, 0.7071067811865476, 0],
			 "axes": [0.1, 0.1, 0.3]}]})";
	}
	std::unique_ptr<btEllipsoidCompoundShape> fromFile = bodyfit::loadEllipsoidCompound(path);
	std::remove(path.c_str());
	REQUIRE(fromFile->getNumEllipsoids() == 2);
	// Rotation (w, x, y, z) = 90 degrees about y: the local x axis (semi-axis 0.1) points along world -z.
	CHECK(double(fromFile->zeta(1, btVector3(0.1, 1, 0.1))) == Approx(1.0).margin(1e-5));
	CHECK(double(fromFile->zeta(1, btVector3(0.4, 1, 0))) == Approx(1.0).margin(1e-5));
}
