// Long-run stability (issue 7, item 2): a 20 x 20 cloth dropped over the shoulders of the fitted female_young body
// (demos/assets/fits/female_young.json, 1 km of nothing else in the world but a ground box), in a gusty wind with
// Bullet's lift/drag aerodynamics, stepped at 120 Hz. After every step: no NaN/Inf in any node position or velocity,
// no node inside any ellipsoid (zeta >= 1 - 1e-6, evaluated in long double from the compound's analytic data), and
// the kinetic energy below a physical bound. Default: 10,000 steps (83 s of simulated time, a few seconds in Release);
// BODYFIT_LONGRUN_STEPS overrides the count. Runs in the float and the float64 Bullet builds.
#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include "support/paths.h"

#include "BulletDynamics/Dynamics/btRigidBody.h"
#include "BulletSoftBody/btSoftBodyHelpers.h"
#include "BulletCollision/CollisionShapes/btBoxShape.h"

#include "bullet_ext/cloth_test_scene.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <memory>

namespace
{

typedef long double Real;
const double kTwoPi = 6.283185307179586;

using bodyfit_test::refZeta; // cloth_test_scene.h

bool finite3(const btVector3& v)
{
	return std::isfinite(double(v.x())) && std::isfinite(double(v.y())) && std::isfinite(double(v.z()));
}

int stepsFromEnvironment(int fallback)
{
	const char* v = std::getenv("BODYFIT_LONGRUN_STEPS");
	const int n = v ? std::atoi(v) : 0;
	return n > 0 ? n : fallback;
}

} // namespace

TEST_CASE("robust: 10,000 steps of a cloth on the fitted body in wind stay finite, outside and bounded",
		  "[robust][longrun]")
{
	const int steps = stepsFromEnvironment(10000);
	const btScalar dt = btScalar(1.0 / 120.0);

	btEllipsoidClothWorld world;
	btSoftRigidDynamicsWorld* dw = world.getWorld();
	dw->setGravity(btVector3(0, btScalar(-9.81), 0));
	btSoftBodyWorldInfo& info = world.getWorldInfo();
	info.m_gravity = btVector3(0, btScalar(-9.81), 0);
	info.air_density = btScalar(1.2);

	// The fitted body: static, at the origin (the fit is in the body frame, +y up, feet at y ~ 0).
	std::unique_ptr<btEllipsoidCompoundShape> shape =
		bodyfit::loadEllipsoidCompound(bodyfit_test::assetPath("fits/female_young.json"));
	REQUIRE(shape->getNumEllipsoids() > 10);
	btCollisionObject body;
	body.setCollisionShape(shape.get());
	dw->addCollisionObject(&body);

	// Ground: a static box whose top face is y = 0 (cloth that slides off the body comes to rest there; Bullet's
	// own soft-rigid contact handles it).
	btBoxShape groundShape(btVector3(5, btScalar(0.5), 5));
	btRigidBody ground(btRigidBody::btRigidBodyConstructionInfo(0, 0, &groundShape));
	btTransform groundPose;
	groundPose.setIdentity();
	groundPose.setOrigin(btVector3(0, btScalar(-0.5), 0));
	ground.setWorldTransform(groundPose);
	dw->addRigidBody(&ground);

	// Cloth: 0.9 m square, 20 x 20 nodes, centred over the shoulders (as the bundled windy_patch scene).
	const btScalar h = btScalar(0.45), y = btScalar(1.66), zc = btScalar(0.03);
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(info, btVector3(-h, y, zc - h), btVector3(h, y, zc - h),
													   btVector3(-h, y, zc + h), btVector3(h, y, zc + h), 20, 20, 0,
													   true);
	const btScalar clothMass = btScalar(0.2);
	cloth->setTotalMass(clothMass);
	cloth->m_materials[0]->m_kLST = btScalar(0.9);
	cloth->generateBendingConstraints(2, cloth->m_materials[0]);
	cloth->m_cfg.piterations = 10;
	cloth->m_cfg.kDP = btScalar(0.01);
	cloth->m_cfg.kDG = btScalar(0.4);
	cloth->m_cfg.kLF = btScalar(0.05);
	cloth->m_cfg.aeromodel = btSoftBody::eAeroModel::V_TwoSidedLiftDrag;
	cloth->getCollisionShape()->setMargin(btScalar(0.005));
	dw->addSoftBody(cloth);

	btEllipsoidClothCollider::Config config;
	config.m_friction = btScalar(0.6);
	const char* whyNot = 0;
	btEllipsoidClothCollider* collider = world.installCollider(&body, config, &whyNot);
	REQUIRE(collider != 0);

	// Kinetic-energy bound: a node can reach at most the free-fall speed from the cloth's height,
	// sqrt(2 g 1.7 m) = 5.8 m/s, or the wind speed, 3 m/s steady + 1.5 m/s gusts on each of 3 axes = 5.6 m/s (drag
	// pulls the cloth towards the wind velocity, never beyond). With a factor 1.7 of margin on speed (10 m/s for
	// every node at once) the whole cloth's energy stays below 0.5 * 0.2 kg * (10 m/s)^2 = 10 J. An explosion
	// exceeds it within a few steps.
	const double keBound = 0.5 * double(clothMass) * 10.0 * 10.0;

	const int nNodes = cloth->m_nodes.size();
	double maxKe = 0.0;
	Real minZeta = INFINITY;
	int badStep = -1;
	const char* badWhat = "";
	int insideCount = 0;
	for (int s = 0; s < steps && badStep < 0; ++s)
	{
		// Deterministic gusts: steady 3 m/s from the front plus three incommensurate sines (periods 0.7-2.3 s).
		const double t = s * double(dt);
		const btVector3 wind(btScalar(1.5 * std::sin(kTwoPi * t / 0.7)),
							 btScalar(0.5 * std::sin(kTwoPi * t / 2.3)),
							 btScalar(-3.0 + 1.5 * std::sin(kTwoPi * t / 1.3)));
		cloth->setWindVelocity(wind);
		dw->stepSimulation(dt, 1, dt);

		double ke = 0.0;
		for (int i = 0; i < nNodes && badStep < 0; ++i)
		{
			const btSoftBody::Node& n = cloth->m_nodes[i];
			if (!finite3(n.m_x) || !finite3(n.m_v))
			{
				badStep = s;
				badWhat = "non-finite node";
				break;
			}
			if (n.m_im > btScalar(0))
				ke += 0.5 * double(n.m_v.length2()) / double(n.m_im);
			for (int k = 0; k < shape->getNumEllipsoids(); ++k)
			{
				const btEllipsoidLocalData& e = shape->getEllipsoid(k);
				// Only ellipsoids whose box (grown by 1 cm) holds the node can contain it.
				if (n.m_x.x() < e.m_aabbMin.x() - btScalar(0.01) || n.m_x.x() > e.m_aabbMax.x() + btScalar(0.01) ||
					n.m_x.y() < e.m_aabbMin.y() - btScalar(0.01) || n.m_x.y() > e.m_aabbMax.y() + btScalar(0.01) ||
					n.m_x.z() < e.m_aabbMin.z() - btScalar(0.01) || n.m_x.z() > e.m_aabbMax.z() + btScalar(0.01))
					continue;
				const Real z = refZeta(e, n.m_x);
				if (z < minZeta)
					minZeta = z;
				if (z < Real(1) - Real(1e-6))
					++insideCount;
			}
		}
		if (badStep < 0 && insideCount > 0)
		{
			badStep = s;
			badWhat = "node inside an ellipsoid";
		}
		if (badStep < 0 && !(ke <= keBound))
		{
			badStep = s;
			badWhat = "kinetic energy above the bound";
		}
		if (ke > maxKe)
			maxKe = ke;
	}
	const btEllipsoidClothStats& stats = collider->getAccumulatedStats();
	INFO("btScalar " << (sizeof(btScalar) == 8 ? "double" : "float") << ", " << steps << " steps, " << nNodes
					 << " nodes; max kinetic energy " << maxKe << " J (bound " << keBound << " J); min zeta "
					 << double(minZeta) << "; collider: corrected " << stats.m_nodesCorrected << ", pushed out "
					 << stats.m_nodesPushedOut << ", repaired " << stats.m_nodesRepaired << ", non-finite "
					 << stats.m_nonFiniteNodes);
	INFO("first bad step " << badStep << ": " << badWhat);
	CHECK(badStep == -1);
	CHECK(stats.m_nonFiniteNodes == 0);
	// The cloth did reach the body (otherwise the test proves nothing about the collider).
	CHECK(stats.m_nodesCorrected > 0);

	dw->removeSoftBody(cloth);
	delete cloth;
	dw->removeRigidBody(&ground);
	dw->removeCollisionObject(&body);
}
