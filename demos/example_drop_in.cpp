// example_drop_in: the ellipsoid collider dropped into an ordinary Bullet soft-body scene.
//   example_drop_in [ELLIPSOIDS.json] [--steps N]
// Loads a fitted body (bodyfit-fit output; default: the bundled female_young fit), makes it a static body of an
// existing btSoftRigidDynamicsWorld, drops a cloth patch on it and prints what the collider did.
// The only changes to a stock Bullet scene are marked "bodyfit".
#include "bodyfit/bridge/btBodyFitToBullet.h" // bodyfit: JSON -> btEllipsoidCompoundShape
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h" // bodyfit: the collider and its soft-body solver

#include "BulletSoftBody/btSoftBodyHelpers.h"
#include "BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h"
#include "btBulletDynamicsCommon.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

int main(int argc, char** argv)
{
	std::string path = std::string(BODYFIT_ASSET_DIR) + "/fits/female_young.json";
	int steps = 120;
	for (int i = 1; i < argc; ++i)
	{
		if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h"))
		{
			std::printf("usage: example_drop_in [ELLIPSOIDS.json] [--steps N]\n");
			return 0;
		}
		if (!std::strcmp(argv[i], "--steps") && i + 1 < argc)
			steps = std::atoi(argv[++i]);
		else
			path = argv[i];
	}
	if (steps <= 0)
	{
		std::fprintf(stderr, "example_drop_in: --steps must be a positive integer\n");
		return 2;
	}

	// A stock soft-body world, except for the 5th constructor argument.
	btSoftBodyRigidBodyCollisionConfiguration config;
	btCollisionDispatcher dispatcher(&config);
	btDbvtBroadphase broadphase;
	btSequentialImpulseConstraintSolver solver;
	btEllipsoidClothSoftBodySolver softSolver; // bodyfit: instead of the default soft-body solver
	btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config, &softSolver);
	world.getWorldInfo().m_gravity.setValue(0, -9.81f, 0);

	// bodyfit: the body is a compound of ellipsoids read from the fitter's JSON file.
	std::unique_ptr<btEllipsoidCompoundShape> bodyShape;
	try
	{
		bodyShape = bodyfit::loadEllipsoidCompound(path);
	}
	catch (const std::exception& e)
	{
		std::fprintf(stderr, "example_drop_in: %s\n", e.what());
		return 2;
	}
	btRigidBody body(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, bodyShape.get()));
	world.addRigidBody(&body); // rigid bodies keep colliding with it through GJK/EPA

	// A 40 x 40 cloth patch 5 cm above the top of the body.
	btVector3 lo, hi;
	bodyShape->getAabb(body.getWorldTransform(), lo, hi);
	const btVector3 c((lo.x() + hi.x()) / 2, hi.y() + btScalar(0.05), (lo.z() + hi.z()) / 2);
	const btScalar h = 0.5;
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(world.getWorldInfo(), c + btVector3(-h, 0, -h),
													   c + btVector3(h, 0, -h), c + btVector3(-h, 0, h),
													   c + btVector3(h, 0, h), 40, 40, 0, true);
	cloth->getCollisionShape()->setMargin(0.005f);
	cloth->m_cfg.piterations = 8;
	cloth->setTotalMass(0.2f);
	world.addSoftBody(cloth);

	// bodyfit: one call; Bullet's own (sparse-SDF) response to this body is switched off for the cloth.
	btEllipsoidClothCollider::Config cfg;
	cfg.m_skinOffset = 0.002f; // 2 mm
	cfg.m_friction = 0.4f;
	const char* why = nullptr;
	btEllipsoidClothCollider* collider = softSolver.installCollider(&world, &body, cfg, &why);
	if (!collider)
	{
		std::fprintf(stderr, "example_drop_in: %s\n", why);
		return 1;
	}

	for (int i = 0; i < steps; ++i)
		world.stepSimulation(1.0f / 60, 1, 1.0f / 60);

	const btEllipsoidClothStats& s = collider->getAccumulatedStats();
	std::printf("%d ellipsoids, %d cloth nodes, %d steps: %d node corrections, %d push-outs, min zeta %.6f, "
				"collider %.3f ms/step\n",
				bodyShape->getNumEllipsoids(), cloth->m_nodes.size(), s.m_substeps, s.m_nodesCorrected,
				s.m_nodesPushedOut, double(s.m_minZeta), 1e3 * s.m_collisionSeconds / s.m_substeps);

	world.removeSoftBody(cloth);
	delete cloth;
	world.removeRigidBody(&body);
	return 0;
}
