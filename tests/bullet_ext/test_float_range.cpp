// Float far from the origin (btFloatRange.h): the spacing formula, the check's thresholds, and install() refusing or
// warning in a float build (the float64 build accepts every distance).
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btFloatRange.h"

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>

#include <catch2/catch.hpp>

#include <cmath>
#include <memory>

namespace
{

const bool kFloat = sizeof(btScalar) == sizeof(float);

/// Installs a collider for one 10 cm ellipsoid at `centre` (2 mm skin) and returns whether it installed, its
/// reason (refused) or its warning (installed).
bool installAt(const btVector3& centre, const char** message)
{
	btSoftBodyRigidBodyCollisionConfiguration configuration;
	btCollisionDispatcher dispatcher(&configuration);
	btDbvtBroadphase broadphase;
	btSequentialImpulseConstraintSolver constraintSolver;
	btEllipsoidClothSoftBodySolver softSolver;
	btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &constraintSolver, &configuration, &softSolver);
	btEllipsoidCompoundShape compound;
	compound.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
	btCollisionObject body;
	body.setCollisionShape(&compound);
	btTransform pose = btTransform::getIdentity();
	pose.setOrigin(centre);
	body.setWorldTransform(pose);
	const char* why = 0;
	btEllipsoidClothCollider* collider = softSolver.installCollider(&world, &body, btEllipsoidClothCollider::Config(), &why);
	*message = collider ? collider->getPrecisionWarning() : why;
	if (collider)
		softSolver.uninstallCollider(collider);
	return collider != 0;
}

} // namespace

TEST_CASE("float range: spacing of float and btScalar far from the origin", "[bullet_ext][float_range]")
{
	// 2^(floor(log2 D) - 23): exact powers of two.
	CHECK(btFloatSpacing(1000.0) == std::ldexp(1.0, 9 - 23));    // 61 um
	CHECK(btFloatSpacing(1024.0) == std::ldexp(1.0, 10 - 23));   // the next binade
	CHECK(btFloatSpacing(10000.0) == std::ldexp(1.0, 13 - 23));  // 0.98 mm
	CHECK(btFloatSpacing(-1e6) == std::ldexp(1.0, 19 - 23));     // 62.5 mm
	// It is the distance between consecutive floats: nextafter agrees.
	for (double d : {1000.0, 3000.0, 1e5})
		CHECK(double(std::nextafter(float(d), 1e30f)) - double(float(d)) == btFloatSpacing(d));
	CHECK(btScalarSpacing(1e4) == (kFloat ? btFloatSpacing(1e4) : std::ldexp(1.0, 13 - 52)));
}

TEST_CASE("float range: thresholds for a 2 mm skin", "[bullet_ext][float_range]")
{
	const btScalar skin = btScalar(0.002);
	auto at = [&](double d) {
		const char* why = 0;
		const btFloatRangeStatus s = btCheckFloatRange(btVector3(btScalar(d), 0, 0), btVector3(btScalar(d) + 1, 1, 1), skin, &why);
		CHECK((s == BT_FLOAT_RANGE_OK) == (why == 0));
		return s;
	};
	if (kFloat)
	{
		// Spacing <= skin / 32 (62.5 um): fine up to 1,024 m; <= skin / 4 (0.5 mm) up to 8,192 m; beyond refused.
		CHECK(btFloatRangeLimit(skin, BT_FLOAT_RANGE_WARN) == 1024.0);
		CHECK(btFloatRangeLimit(skin, BT_FLOAT_RANGE_REFUSE) == 8192.0);
		CHECK(at(500.0) == BT_FLOAT_RANGE_OK);
		CHECK(at(1022.0) == BT_FLOAT_RANGE_OK);
		CHECK(at(2000.0) == BT_FLOAT_RANGE_WARN);
		CHECK(at(8000.0) == BT_FLOAT_RANGE_WARN);
		CHECK(at(10000.0) == BT_FLOAT_RANGE_REFUSE);
		CHECK(at(1e6) == BT_FLOAT_RANGE_REFUSE);
	}
	else
	{
		// 53 bits: the spacing passes 62.5 um only at 2^39 m = 5.5e8 km.
		CHECK(btFloatRangeLimit(skin, BT_FLOAT_RANGE_WARN) == std::ldexp(1.0, 39));
		for (double d : {500.0, 1e4, 1e6})
			CHECK(at(d) == BT_FLOAT_RANGE_OK);
	}
	// Non-finite boxes are refused in any build.
	CHECK(btCheckFloatRange(btVector3(0, 0, 0), btVector3(BT_INFINITY, 0, 0), skin) == BT_FLOAT_RANGE_REFUSE);
}

TEST_CASE("float range: install refuses or warns far from the origin in a float build", "[bullet_ext][float_range]")
{
	const char* message = 0;
	CHECK(installAt(btVector3(500, 0, 0), &message));
	CHECK(message == 0);
	// 2 km along a diagonal: warning (float), fine (double).
	CHECK(installAt(btVector3(1200, 1200, 1200), &message));
	if (kFloat)
	{
		REQUIRE(message != 0);
		CHECK_THAT(message, Catch::Contains("far from the origin"));
	}
	else
		CHECK(message == 0);
	// 100 km: refused with the reason (float), fine (double).
	const bool installed = installAt(btVector3(0, 1e5, 0), &message);
	CHECK(installed == !kFloat);
	if (kFloat)
	{
		REQUIRE(message != 0);
		CHECK_THAT(message, Catch::Contains("too far from the origin") && Catch::Contains("BODYFIT_BULLET_DOUBLE"));
	}
	else
		CHECK(message == 0);
}
