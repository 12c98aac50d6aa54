// Velocities the collider leaves (issue 12 item 1): after the response a node's m_v must describe its motion. Before
// the fix, a node placed at the entry of a deep path kept the whole path's tangential velocity and, in the crease of
// two ellipsoids, a velocity into the second one; both grew every step while the node hardly moved (12-40 m/s on
// nodes moving < 1 cm/s). The measure: per step, |m_v| against the node's speed from its positions over that step.
#include "bullet_ext/cloth_test_scene.h"
#include "src/btEllipsoidClothResponse.h"
#include "support/settle_meter.h"

#include <catch2/catch.hpp>

using namespace bodyfit_test;

namespace
{

/// Two intersecting ellipsoids meeting in a V-shaped crease along z at the top.
std::unique_ptr<btEllipsoidCompoundShape> creaseBody()
{
	std::unique_ptr<btEllipsoidCompoundShape> s(new btEllipsoidCompoundShape());
	s->addEllipsoid(btVector3(-0.12, 0, 0), btMatrix3x3(btQuaternion(btVector3(0, 0, 1), 0.4)), btVector3(0.25, 0.1, 0.15));
	s->addEllipsoid(btVector3(0.12, 0.02, 0), btMatrix3x3(btQuaternion(btVector3(0, 0, 1), -0.5)),
					btVector3(0.25, 0.12, 0.12));
	return s;
}

/// Steps the scene and returns the largest |m_v| - actual speed over nodes and steps after the first correction.
double worstExcessAfterLanding(ClothScene& scene, btSoftBody* cloth, int steps, double dt)
{
	SettleMeter meter(*cloth);
	bool landed = false;
	double worst = 0.0;
	for (int i = 0; i < steps; ++i)
	{
		scene.collider()->resetStats();
		scene.step(btScalar(dt));
		const SettleSample s = meter.sample(dt);
		landed = landed || scene.collider()->getAccumulatedStats().m_nodesCorrected > 0;
		if (landed)
			worst = std::max(worst, s.maxExcess);
	}
	REQUIRE(landed);
	return worst;
}

} // namespace

TEST_CASE("settling: m_v stays bounded by the real motion of cloth resting in a crease", "[bullet_ext][collider][velocity]")
{
	ClothScene scene(creaseBody());
	// Pinned at two opposite edges' ends above the crease: the cloth is pulled into the crease by its own tension.
	btSoftBody* cloth = scene.addPatch(btVector3(0, 0.2, 0), btScalar(0.9), 25);
	cloth->setMass(0, 0);
	cloth->setMass(24, 0);
	cloth->setMass(24 * 25, 0);
	cloth->setMass(25 * 25 - 1, 0);
	REQUIRE(scene.install());
	// 0.5 m/s is the bound; before the fix this scene reached several m/s on nodes that hardly moved.
	CHECK(worstExcessAfterLanding(scene, cloth, 180, 1.0 / 60) < 0.5);
}

TEST_CASE("settling: a node resting in the crease keeps no velocity into either ellipsoid", "[bullet_ext][collider][velocity]")
{
	ClothScene scene(creaseBody());
	// A single free node dropped just above the crease line (x where the two surfaces meet at the top).
	btSoftBody* node = scene.addNodes({btVector3(0.01f, 0.2f, 0)});
	// Friction 0.5 holds it where it lands (the crease is not level; with Bullet's default kDF 0.2 x body friction
	// 0.5 it slides along it, which is real motion).
	btEllipsoidClothCollider::Config config;
	config.m_friction = btScalar(0.5);
	REQUIRE(scene.install(config));
	const double worst = worstExcessAfterLanding(scene, node, 240, 1.0 / 60);
	CHECK(worst < 0.5);
	// At rest in the crease its velocity is what it moves: below 1 cm/s after 4 s (gravity adds 0.16 m/s a step,
	// which the response must take out again every step).
	CHECK(double(node->m_nodes[0].m_v.length()) < 0.01);
}

TEST_CASE("settling: the contact cone projection removes velocity into every touched surface", "[bullet_ext][collider][velocity]")
{
	btNodeContacts contacts;
	contacts.add(btVector3(1, 1, 0).normalized());
	contacts.add(btVector3(-1, 1, 0).normalized());
	// Straight down into the crease: nothing is left (both planes active, the edge is along z).
	CHECK(btProjectOntoContactCone(btVector3(0, -1, 0), contacts).length() < 1e-6);
	// Down and along the crease: the part along z survives exactly.
	const btVector3 v = btProjectOntoContactCone(btVector3(0.2, -1, 0.5), contacts);
	CHECK(double(v.z()) == Approx(0.5).margin(1e-6));
	CHECK(std::abs(double(v.x())) < 1e-6);
	CHECK(std::abs(double(v.y())) < 1e-6);
	// Into one plane only, away from the other: one plane active, the result is the plane projection.
	const btVector3 w = btProjectOntoContactCone(btVector3(-1, 0, 0), contacts);
	CHECK(double(w.dot(contacts.m_normals[0])) > -1e-6);
	CHECK(double(w.dot(contacts.m_normals[1])) > -1e-6);
	CHECK(double((w - btVector3(-0.5, 0.5, 0)).length()) < 1e-6);
	// Already feasible: unchanged.
	CHECK(btProjectOntoContactCone(btVector3(0, 1, 0.3), contacts) == btVector3(0, 1, 0.3));
}

TEST_CASE("friction: the cloth's kDF times the body's friction, as Bullet combines them, unless Config overrides",
		  "[bullet_ext][collider][friction]")
{
	// A free node on a 0.3 m sphere, 20 degrees from the top (slope tan 20 = 0.36): Coulomb friction 1 holds it,
	// friction 0 lets it slide. Returns how far it moved in 1 s.
	auto slide = [](btScalar kDF, btScalar bodyFriction, btScalar configFriction) {
		ClothScene scene(singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.3, 0.3, 0.3)));
		const double a = 20.0 * SIMD_PI / 180.0;
		const btVector3 start(btScalar(0.303 * std::sin(a)), btScalar(0.303 * std::cos(a)), 0);
		btSoftBody* node = scene.addNodes({start});
		node->m_cfg.kDF = kDF;
		scene.body()->setFriction(bodyFriction);
		btEllipsoidClothCollider::Config config;
		config.m_friction = configFriction;
		REQUIRE(scene.install(config));
		for (int i = 0; i < 60; ++i)
			scene.step(btScalar(1.0 / 60));
		return double((node->m_nodes[0].m_x - start).length());
	};
	const btScalar bullet = btEllipsoidClothCollider::kBulletFriction();
	// Distances: held, it only settles onto the skin (< 1 cm); sliding freely for 1 s it moves > 10 cm.
	CHECK(slide(1, 1, bullet) < 0.01);        // kDF 1 x body 1 = 1
	CHECK(slide(0, 1, bullet) > 0.1);         // kDF 0: no friction
	CHECK(slide(1, 0, bullet) > 0.1);         // body friction 0: no friction
	CHECK(slide(0, 0, btScalar(1)) < 0.01);   // Config overrides both
	CHECK(slide(1, 1, btScalar(0)) > 0.1);
}
