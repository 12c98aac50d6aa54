// Teleport (issue 12 item 3): after resetBodyPose() a jump of a fitted body through draped cloth must not leave
// nodes inside the body mesh. Before, nodes that the jump put outside every ellipsoid but inside the body (pockets of
// the union under the skin) stayed there: 16 right after a 0.3 m jump, 17 sixty steps later. Also a pose that holds
// a NaN for a few steps.
#include "bullet_ext/cloth_test_scene.h"
#include "bodyfit/fitting/inside_test.h"
#include "support/fitted_body.h"

#include "BulletSoftBody/btSoftBodyHelpers.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <limits>

namespace
{

/// Nodes inside the body mesh (given in the body frame) at the body's current pose.
int nodesInsideMesh(const btSoftBody& cloth, const btTransform& pose, const bodyfit::MeshInsideTest& inside)
{
	const btTransform toBody = pose.inverse();
	int n = 0;
	for (int i = 0; i < cloth.m_nodes.size(); ++i)
	{
		const btVector3 p = toBody * cloth.m_nodes[i].m_x;
		n += inside.isInside(Eigen::Vector3d(double(p.x()), double(p.y()), double(p.z()))) ? 1 : 0;
	}
	return n;
}

} // namespace

TEST_CASE("teleport: a 0.3 m jump of a fitted body after resetBodyPose leaves no node inside the body",
		  "[bullet_ext][collider][teleport]")
{
	const bodyfit_test::FittedBody fitted("female_young");
	const bodyfit::LoadedMesh& mesh = fitted.mesh;
	const bodyfit::MeshInsideTest inside(mesh.full);
	const double top = mesh.full.V.col(1).maxCoeff();
	const btVector3 jumps[] = {btVector3(0, 0.3, 0), btVector3(0.3, 0, 0), btVector3(-0.3, 0, 0)};
	for (const btVector3& jump : jumps)
	{
		INFO("jump (" << jump.x() << ", " << jump.y() << ", " << jump.z() << ")");
		btEllipsoidClothWorld world;
		btCollisionObject body;
		bodyfit_test::addBodyWithGravity(world, body, fitted.compound.get());
		// A 1.2 m, 60 x 60 patch draped over the head and shoulders for 1.5 s.
		const btScalar s = btScalar(0.6), y = btScalar(top + 0.03);
		btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(world.getWorldInfo(), btVector3(-s, y, -s), btVector3(s, y, -s),
														   btVector3(-s, y, s), btVector3(s, y, s), 60, 60, 0, true);
		cloth->m_cfg.piterations = 10;
		cloth->m_cfg.kDP = btScalar(0.01);
		cloth->setTotalMass(btScalar(0.3));
		world.getWorld()->addSoftBody(cloth);
		btEllipsoidClothCollider* collider = world.installCollider(&body);
		REQUIRE(collider);
		const btScalar dt = btScalar(1.0 / 60);
		for (int i = 0; i < 90; ++i)
			world.getWorld()->stepSimulation(dt, 1, dt);
		REQUIRE(nodesInsideMesh(*cloth, body.getWorldTransform(), inside) == 0);

		// The jump, by hand, as the docs advise: move, then resetBodyPose().
		btTransform pose = body.getWorldTransform();
		pose.setOrigin(pose.getOrigin() + jump);
		body.setWorldTransform(pose);
		collider->resetBodyPose();
		collider->resetStats();
		world.getWorld()->stepSimulation(dt, 1, dt);
		const int insideAfter = nodesInsideMesh(*cloth, pose, inside);
		std::printf("teleport jump (%.1f, %.1f, %.1f): pushed out %d (from pockets of the union %d), inside the mesh "
					"after the jump %d\n",
					double(jump.x()), double(jump.y()), double(jump.z()), collider->getAccumulatedStats().m_nodesPushedOut,
					collider->getAccumulatedStats().m_pushOutEnclosed, insideAfter);
		CHECK(collider->getAccumulatedStats().m_nodesPushedOut > 0); // the jump did put cloth into the body
		CHECK(insideAfter == 0);
		for (int i = 0; i < 60; ++i)
			world.getWorld()->stepSimulation(dt, 1, dt);
		const int insideLater = nodesInsideMesh(*cloth, pose, inside);
		std::printf("teleport: inside the mesh 60 steps later %d\n", insideLater);
		CHECK(insideLater == 0);
		CHECK(double(collider->getAccumulatedStats().m_minZeta) >= 1.0);
		world.getWorld()->removeSoftBody(cloth);
		delete cloth;
		world.getWorld()->removeCollisionObject(&body);
	}
}

TEST_CASE("teleport: a body pose that holds a NaN for a few steps is skipped, and the cloth comes back whole",
		  "[bullet_ext][collider][teleport][robust]")
{
	// An animation gone wrong for three frames (a zero quaternion normalised, a division by zero) hands the body a
	// world transform with a NaN. The collider skips those substeps and moves on from the last finite pose. Before,
	// the NaN pose became the previous pose of the first finite substep, and the sweep from it wrote NaN into the 37
	// nodes it reached.
	for (const bool kinematic : {false, true})
		for (const int entry : {0, 4, 11}) // a basis entry (row 0, column 0), another (row 1, column 1), the origin's z
		{
			INFO((kinematic ? "kinematic" : "static") << " body, NaN in entry " << entry);
			bodyfit_test::ClothScene scene(bodyfit_test::singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(),
																		 btVector3(0.2, 0.2, 0.2)),
										   btTransform::getIdentity(), kinematic);
			btSoftBody* cloth = scene.addPatch(btVector3(0, btScalar(0.25), 0), btScalar(0.6), 15);
			REQUIRE(scene.install());
			const btScalar dt = btScalar(1.0 / 60);
			for (int s = 0; s < 20; ++s) // the cloth lands on the ball
				scene.world()->stepSimulation(dt, 1, dt);
			btTransform bad = btTransform::getIdentity();
			const btScalar nan = std::numeric_limits<btScalar>::quiet_NaN();
			if (entry < 9)
				bad.getBasis()[entry / 3][entry % 3] = nan;
			else
				bad.getOrigin()[entry - 9] = nan;
			for (int phase = 0; phase < 2; ++phase) // 3 steps at the bad pose, then 30 back at the identity
			{
				const btTransform pose = phase == 0 ? bad : btTransform::getIdentity();
				scene.body()->setWorldTransform(pose);
				scene.motion()->setWorldTransform(pose);
				for (int s = 0; s < (phase == 0 ? 3 : 30); ++s)
					scene.world()->stepSimulation(dt, 1, dt);
			}
			const btEllipsoidClothStats& stats = scene.collider()->getAccumulatedStats();
			CHECK(stats.m_invalidPoseSubsteps == 3); // one substep per step
			int nonFinite = 0, inside = 0;
			for (int i = 0; i < cloth->m_nodes.size(); ++i)
			{
				const btVector3& x = cloth->m_nodes[i].m_x;
				nonFinite += std::isfinite(double(x.x())) && std::isfinite(double(x.y())) && std::isfinite(double(x.z())) ? 0 : 1;
				// Any depth at all into the 0.2 m ball counts (the collider rests nodes at its 2 mm skin offset).
				inside += double(x.length()) < 0.2 ? 1 : 0;
			}
			CHECK(nonFinite == 0);
			CHECK(inside == 0);
			CHECK(stats.m_nodesCorrected > 0); // it went on colliding after the pose came back
		}
}
