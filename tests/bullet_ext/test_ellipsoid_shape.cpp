// btEllipsoidShape: support map, AABB, inertia, margin and scaling, GJK/EPA against other shapes, ray tests.
#include "bodyfit/bullet_ext/btEllipsoidShape.h"

#include "bodyfit/fitting/ellipsoid.h"

#include "BulletCollision/CollisionShapes/btBoxShape.h"
#include "BulletCollision/CollisionShapes/btSphereShape.h"
#include "BulletCollision/CollisionShapes/btStaticPlaneShape.h"
#include "BulletCollision/NarrowPhaseCollision/btGjkEpa2.h"
#include "BulletCollision/NarrowPhaseCollision/btRaycastCallback.h"
#include "btBulletDynamicsCommon.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <memory>
#include <random>

namespace
{

// Relative precision of btScalar: tolerances below scale with it so the same test is meaningful in float and double.
const double kEps = double(SIMD_EPSILON);

btVector3 randomUnit(std::mt19937& rng)
{
	std::normal_distribution<double> n(0.0, 1.0);
	btVector3 v(btScalar(n(rng)), btScalar(n(rng)), btScalar(n(rng)));
	return v.normalized();
}

/// Max of d . p over a dense sample of the core ellipsoid surface (parametrised by angles).
double bruteForceSupport(const btVector3& core, const btVector3& d, int samples)
{
	double best = -1e300;
	for (int i = 0; i <= samples; ++i)
	{
		const double theta = M_PI * i / samples;
		for (int j = 0; j < 2 * samples; ++j)
		{
			const double phi = M_PI * j / samples;
			const double px = core.x() * std::sin(theta) * std::cos(phi);
			const double py = core.y() * std::sin(theta) * std::sin(phi);
			const double pz = core.z() * std::cos(theta);
			best = std::max(best, d.x() * px + d.y() * py + d.z() * pz);
		}
	}
	return best;
}

} // namespace

TEST_CASE("support map equals the brute-force maximum over sampled surface points", "[bullet_ext][shape]")
{
	std::mt19937 rng(7);
	const btVector3 axes(0.3, 0.1, 0.05);
	btEllipsoidShape shape(axes, 0.0);
	REQUIRE(shape.getShapeType() == CUSTOM_CONVEX_SHAPE_TYPE);
	for (int k = 0; k < 50; ++k)
	{
		const btVector3 d = randomUnit(rng);
		const btVector3 s = shape.localGetSupportingVertexWithoutMargin(d);
		// The support point lies on the surface (zeta = 1 up to rounding of a few ulps).
		CHECK(std::abs(double(shape.zeta(s)) - 1.0) < 64 * kEps);
		// Its support value is the maximum: the sampled maximum can only be lower, by at most the sampling error.
		// With 400 x 800 angle samples the angular step is 7.9e-3 rad; the support value error is at most
		// max(a) * step^2 / 2 ~ 1e-5 m, so 2e-5 bounds it.
		const double analytic = double(d.dot(s));
		const double sampled = bruteForceSupport(axes, d, 400);
		CHECK(analytic >= sampled - 64 * kEps);
		CHECK(analytic - sampled < 2e-5);
	}
}

TEST_CASE("support map survives zero, tiny, huge and non-finite directions", "[bullet_ext][shape]")
{
	btEllipsoidShape shape(btVector3(0.2, 0.1, 0.3), 0.01);
	const btVector3 dirs[] = {btVector3(0, 0, 0), btVector3(1e-30, 0, 0), btVector3(0, 1e30, 0),
							  btVector3(-1e-35, 1e-36, 0), btVector3(SIMD_INFINITY, 0, 0)};
	for (const btVector3& d : dirs)
	{
		const btVector3 s = shape.localGetSupportingVertex(d);
		REQUIRE(std::isfinite(double(s.x())));
		REQUIRE(std::isfinite(double(s.y())));
		REQUIRE(std::isfinite(double(s.z())));
		// Still a point of the (margin-inflated) shape: its core part lies on the core surface.
		const btVector3 core = shape.localGetSupportingVertexWithoutMargin(d);
		const btVector3 c = shape.getCoreSemiAxes();
		CHECK(std::abs(double((core / c).length2()) - 1.0) < 64 * kEps);
	}
	// Scale invariance: tiny and unit directions give the same point.
	const btVector3 a = shape.localGetSupportingVertexWithoutMargin(btVector3(1e-30, 2e-30, -1e-30));
	const btVector3 b = shape.localGetSupportingVertexWithoutMargin(btVector3(1, 2, -1));
	CHECK((a - b).length() < 16 * kEps);
}

TEST_CASE("margin convention: core + margin sphere, margin clamped, exact on the axes", "[bullet_ext][shape]")
{
	btEllipsoidShape shape(btVector3(0.2, 0.1, 0.05), 0.01);
	CHECK(shape.getMargin() == Approx(0.01));
	CHECK(shape.getCoreSemiAxes().x() == Approx(0.19));
	// Along each axis the inflated support equals the true semi-axis.
	CHECK(shape.localGetSupportingVertex(btVector3(1, 0, 0)).x() == Approx(0.2).epsilon(1e-5));
	CHECK(shape.localGetSupportingVertex(btVector3(0, -1, 0)).y() == Approx(-0.1).epsilon(1e-5));
	// A margin larger than half the smallest semi-axis is clamped so the core stays a real ellipsoid.
	btEllipsoidShape fat(btVector3(0.2, 0.1, 0.05), 0.5);
	CHECK(fat.getMargin() == Approx(0.025));
	CHECK(fat.getCoreSemiAxes().z() == Approx(0.025));
	// Bad semi-axes are clamped to the minimum instead of producing NaN.
	btEllipsoidShape bad(btVector3(-1, 0, std::numeric_limits<btScalar>::quiet_NaN()), 0.0);
	CHECK(bad.getSemiAxes().x() == Approx(double(BT_ELLIPSOID_MIN_SEMI_AXIS)));
	CHECK(bad.getSemiAxes().z() == Approx(double(BT_ELLIPSOID_MIN_SEMI_AXIS)));
}

TEST_CASE("analytic AABB is tight and contains the shape", "[bullet_ext][shape]")
{
	std::mt19937 rng(11);
	btEllipsoidShape shape(btVector3(0.4, 0.15, 0.08), 0.005);
	for (int k = 0; k < 20; ++k)
	{
		btTransform t(btQuaternion(randomUnit(rng), btScalar(k * 0.37)), btVector3(1, -2, 3));
		btVector3 mn, mx;
		shape.getAabb(t, mn, mx);
		for (int axis = 0; axis < 3; ++axis)
		{
			btVector3 dir(0, 0, 0);
			dir[axis] = 1;
			// World support along +axis and -axis of the inflated shape = the AABB faces.
			const btVector3 up = t * shape.localGetSupportingVertex(t.getBasis().transpose() * dir);
			const btVector3 down = t * shape.localGetSupportingVertex(t.getBasis().transpose() * -dir);
			CHECK(double(mx[axis]) == Approx(double(up[axis])).margin(1e-5));
			CHECK(double(mn[axis]) == Approx(double(down[axis])).margin(1e-5));
		}
	}
}

TEST_CASE("inertia is the solid ellipsoid's and local scaling scales the shape", "[bullet_ext][shape]")
{
	btEllipsoidShape shape(btVector3(1, 2, 3), 0.0);
	btVector3 inertia;
	shape.calculateLocalInertia(5, inertia);
	CHECK(inertia.x() == Approx(1.0 * (4 + 9)));
	CHECK(inertia.y() == Approx(1.0 * (1 + 9)));
	CHECK(inertia.z() == Approx(1.0 * (1 + 4)));
	shape.setLocalScaling(btVector3(2, 1, 0.5));
	CHECK(shape.getScaledSemiAxes().x() == Approx(2));
	CHECK(shape.getScaledSemiAxes().z() == Approx(1.5));
	CHECK(shape.localGetSupportingVertex(btVector3(0, 0, 1)).z() == Approx(1.5));
	btVector3 center;
	btScalar radius;
	shape.getBoundingSphere(center, radius);
	CHECK(radius == Approx(2));
}

TEST_CASE("GJK distance between an ellipsoid and a sphere agrees with the analytic (Eberly) distance", "[bullet_ext][shape]")
{
	std::mt19937 rng(3);
	const btVector3 axes(0.3, 0.12, 0.06);
	// margin 0: GJK works on the exact ellipsoid.
	btEllipsoidShape shape(axes, 0.0);
	btSphereShape sphere(0.05);
	bodyfit::Ellipsoid ref;
	ref.radii = Eigen::Vector3d(axes.x(), axes.y(), axes.z());
	for (int k = 0; k < 30; ++k)
	{
		const btVector3 dir = randomUnit(rng);
		const btVector3 c = dir * btScalar(0.2 + 0.5 * (k % 5) / 4.0) + dir * axes.length() * btScalar(0.5);
		btTransform te, ts;
		te.setIdentity();
		ts.setIdentity();
		ts.setOrigin(c);
		btGjkEpaSolver2::sResults res;
		const bool separated = btGjkEpaSolver2::Distance(&shape, te, &sphere, ts, btVector3(1, 0, 0), res);
		const bodyfit::SurfacePoint sp = bodyfit::closestSurfacePoint(ref, Eigen::Vector3d(c.x(), c.y(), c.z()));
		// btGjkEpaSolver2::Distance measures between the cores (margins excluded): the sphere's core is its centre.
		const double analytic = sp.signedDistance;
		if (analytic - 0.05 <= 1e-3)
			continue; // only configurations where the sphere is separated from the ellipsoid are compared
		REQUIRE(separated);
		// On a curved core GJK stops when a new support point improves the distance by less than GJK_ACCURACY
		// (1e-4) relative to it; the converged distance then overestimates by up to ~2e-3 relative (measured:
		// worst 1.7e-3 over these 30 cases in float). 1e-4 m + 3e-3 relative. analytic > 0.05 here (separated spheres).
		CHECK(double(res.distance) == Approx(analytic).margin(1e-4).epsilon(3e-3));
	}
}

TEST_CASE("signed distance through EPA is negative inside", "[bullet_ext][shape]")
{
	btEllipsoidShape shape(btVector3(0.3, 0.1, 0.1), 0.0);
	btGjkEpaSolver2::sResults res;
	btTransform t;
	t.setIdentity();
	const btScalar d = btGjkEpaSolver2::SignedDistance(btVector3(0.1, 0.02, 0), 0, &shape, t, res);
	// Exact value from the Eberly closest point: the nearest surface point is about 0.078 m away (y direction).
	bodyfit::Ellipsoid ref;
	ref.radii = Eigen::Vector3d(0.3, 0.1, 0.1);
	const double analytic = bodyfit::closestSurfacePoint(ref, Eigen::Vector3d(0.1, 0.02, 0)).signedDistance;
	CHECK(analytic < 0);
	CHECK(double(d) == Approx(analytic).margin(2e-3)); // EPA on a smooth shape converges to ~1e-3 of the size
}

namespace
{

struct MiniWorld
{
	btDefaultCollisionConfiguration config;
	btCollisionDispatcher dispatcher{&config};
	btDbvtBroadphase broadphase;
	btSequentialImpulseConstraintSolver solver;
	btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
	std::vector<std::unique_ptr<btRigidBody>> bodies;
	std::vector<std::unique_ptr<btCollisionShape>> shapes;

	MiniWorld() { world.setGravity(btVector3(0, -9.81, 0)); }
	~MiniWorld()
	{
		for (auto& b : bodies)
			world.removeRigidBody(b.get());
	}
	btRigidBody* add(btCollisionShape* shape, btScalar mass, const btVector3& pos,
					 const btQuaternion& rot = btQuaternion::getIdentity())
	{
		shapes.emplace_back(shape);
		btVector3 inertia(0, 0, 0);
		if (mass > 0)
			shape->calculateLocalInertia(mass, inertia);
		btRigidBody::btRigidBodyConstructionInfo info(mass, nullptr, shape, inertia);
		info.m_startWorldTransform = btTransform(rot, pos);
		bodies.emplace_back(new btRigidBody(info));
		world.addRigidBody(bodies.back().get());
		return bodies.back().get();
	}
	void run(int steps)
	{
		for (int i = 0; i < steps; ++i)
			world.stepSimulation(btScalar(1.0 / 120), 1, btScalar(1.0 / 120));
	}
};

} // namespace

TEST_CASE("a dynamic ellipsoid rests on a plane, a box, a sphere and another ellipsoid", "[bullet_ext][shape]")
{
	// Semi-axes (0.2, 0.1, 0.15) resting on its short axis (the stable pose): the centre ends 0.1 above the support.
	// Bullet keeps a small penetration (contact slop, ~margin) at rest: 5 mm covers it for both precisions.
	const btScalar tolerance = 0.005;
	SECTION("plane")
	{
		MiniWorld w;
		w.add(new btStaticPlaneShape(btVector3(0, 1, 0), 0), 0, btVector3(0, 0, 0));
		btRigidBody* e = w.add(new btEllipsoidShape(btVector3(0.2, 0.1, 0.15), 0.004), 1, btVector3(0, 0.5, 0));
		w.run(240);
		CHECK(double(e->getWorldTransform().getOrigin().y()) == Approx(0.1).margin(tolerance));
	}
	SECTION("box")
	{
		MiniWorld w;
		w.add(new btBoxShape(btVector3(1, 0.1, 1)), 0, btVector3(0, -0.1, 0));
		btRigidBody* e = w.add(new btEllipsoidShape(btVector3(0.2, 0.1, 0.15), 0.004), 1, btVector3(0, 0.5, 0));
		w.run(240);
		CHECK(double(e->getWorldTransform().getOrigin().y()) == Approx(0.1).margin(tolerance));
	}
	SECTION("sphere: an ellipsoid falling on a static sphere's top stays above it")
	{
		MiniWorld w;
		w.add(new btSphereShape(0.3), 0, btVector3(0, 0, 0));
		btRigidBody* e = w.add(new btEllipsoidShape(btVector3(0.2, 0.1, 0.15), 0.004), 1, btVector3(0, 0.8, 0));
		// Dropped exactly on top it stays balanced there: centre at 0.3 + 0.1.
		w.run(240);
		CHECK(double(e->getWorldTransform().getOrigin().y()) == Approx(0.4).margin(tolerance));
	}
	SECTION("ellipsoid on ellipsoid")
	{
		MiniWorld w;
		w.add(new btEllipsoidShape(btVector3(0.5, 0.1, 0.5), 0.004), 0, btVector3(0, 0, 0));
		btRigidBody* e = w.add(new btEllipsoidShape(btVector3(0.2, 0.1, 0.15), 0.004), 1, btVector3(0, 0.6, 0));
		w.run(240);
		CHECK(double(e->getWorldTransform().getOrigin().y()) == Approx(0.2).margin(tolerance));
	}
}

TEST_CASE("a sphere-shaped ellipsoid behaves like btSphereShape", "[bullet_ext][shape]")
{
	// Geometrically identical shapes (core radius r - m plus margin m = r), dropped side by side in one world:
	// the vertical trajectories and the rest height must agree. Bullet uses a special sphere-box algorithm for the
	// sphere and GJK for the ellipsoid; both place the contact within GJK's accuracy (~1e-4 m in float).
	MiniWorld w;
	w.add(new btBoxShape(btVector3(10, 0.1, 10)), 0, btVector3(0, -0.1, 0));
	btRigidBody* s = w.add(new btSphereShape(0.15), 1, btVector3(-2, 1, 0));
	btRigidBody* e = w.add(new btEllipsoidShape(btVector3(0.15, 0.15, 0.15), 0.04), 1, btVector3(2, 1, 0));
	double worst = 0;
	for (int i = 0; i < 240; ++i)
	{
		w.run(1);
		const btVector3 d = e->getWorldTransform().getOrigin() - s->getWorldTransform().getOrigin() - btVector3(4, 0, 0);
		worst = std::max(worst, double(d.length()));
	}
	// Contact depth differences of ~1e-4 m per step feed the impulse; 2 mm bounds the accumulated difference.
	CHECK(worst < 2e-3);
	CHECK(double(e->getWorldTransform().getOrigin().y()) == Approx(0.15).margin(0.005));

	// Same inertia, same support everywhere, same contact distance against a box in any orientation.
	btVector3 is, ie;
	btSphereShape sphere(0.15);
	btEllipsoidShape ell(btVector3(0.15, 0.15, 0.15), 0.04);
	sphere.calculateLocalInertia(2, is);
	ell.calculateLocalInertia(2, ie);
	CHECK(double(ie.x()) == Approx(double(is.x())));
	std::mt19937 rng(2);
	btBoxShape box(btVector3(0.2, 0.3, 0.1));
	for (int k = 0; k < 20; ++k)
	{
		const btVector3 d = randomUnit(rng);
		CHECK((ell.localGetSupportingVertex(d) - sphere.localGetSupportingVertex(d)).length() < 1e-5);
		btTransform tb(btQuaternion(randomUnit(rng), btScalar(k)), btVector3(0, 0, 0));
		btTransform ts(btQuaternion::getIdentity(), randomUnit(rng) * btScalar(0.6));
		btGjkEpaSolver2::sResults r1, r2;
		btGjkEpaSolver2::Distance(&sphere, ts, &box, tb, btVector3(1, 0, 0), r1);
		btGjkEpaSolver2::Distance(&ell, ts, &box, tb, btVector3(1, 0, 0), r2);
		// Surface distance = core distance - margins (the box's margin is the same in both); GJK accuracy 1e-4.
		CHECK(double(r1.distance - sphere.getMargin()) == Approx(double(r2.distance - ell.getMargin())).margin(2e-4));
	}
}

TEST_CASE("ray tests hit the ellipsoid where the analytic intersection is", "[bullet_ext][shape]")
{
	MiniWorld w;
	btQuaternion rot(btVector3(0, 0, 1), btScalar(0.5));
	w.add(new btEllipsoidShape(btVector3(0.3, 0.1, 0.2), 0.0), 0, btVector3(1, 2, 3), rot);
	w.world.updateAabbs();
	bodyfit::Ellipsoid ref;
	ref.center = Eigen::Vector3d(1, 2, 3);
	ref.rotation = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	ref.radii = Eigen::Vector3d(0.3, 0.1, 0.2);
	std::mt19937 rng(5);
	int hits = 0;
	for (int k = 0; k < 40; ++k)
	{
		const btVector3 dir = randomUnit(rng);
		const btVector3 from = btVector3(1, 2, 3) + dir * 2;
		const btVector3 to = btVector3(1, 2, 3) - dir * 2 + randomUnit(rng) * btScalar(0.1);
		btCollisionWorld::ClosestRayResultCallback cb(from, to);
		if (k % 2)
			cb.m_flags |= btTriangleRaycastCallback::kF_UseSubSimplexConvexCastRaytest;
		w.world.rayTest(from, to, cb);
		const bodyfit::SegmentEntry entry = bodyfit::segmentEntry(ref, Eigen::Vector3d(from.x(), from.y(), from.z()),
																  Eigen::Vector3d(to.x(), to.y(), to.z()));
		REQUIRE(cb.hasHit() == entry.hit);
		if (!entry.hit)
			continue;
		++hits;
		// Bullet's convex ray casts (btGjkConvexCast, and btSubsimplexConvexCast for odd k) stop iterating once the
		// GJK distance is below 1e-3 m, so the hit lies up to ~1 mm (normal distance) before the surface, a few mm
		// along a slanted ray (measured worst: 1.03e-3 of the 4 m ray). Tolerances: 1.3e-3 of the ray (5 mm),
		// zeta within 7% (3.5 mm on the 0.1 m semi-axis), and never behind the surface.
		CHECK(double(cb.m_closestHitFraction) == Approx(entry.t).margin(1.3e-3));
		CHECK(double(cb.m_closestHitFraction) <= entry.t + 1e-4); // never behind the true surface
		const Eigen::Vector3d hitPoint(cb.m_hitPointWorld.x(), cb.m_hitPointWorld.y(), cb.m_hitPointWorld.z());
		CHECK(ref.zeta(hitPoint) == Approx(1.0).margin(0.07));
		CHECK(ref.zeta(hitPoint) >= 1.0 - 1e-4);
	}
	CHECK(hits > 10);
}
