// Teleport (issue 12 item 3): after resetBodyPose() a jump of a fitted body through draped cloth must not leave
// nodes inside the body mesh. Before, nodes that the jump put outside every ellipsoid but inside the body (pockets of
// the union under the skin) stayed there: 16 right after a 0.3 m jump, 17 sixty steps later.
#include "bodyfit/fitting/inside_test.h"
#include "support/fitted_body.h"

#include "BulletSoftBody/btSoftBodyHelpers.h"

#include <catch2/catch.hpp>

#include <cstdio>

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
