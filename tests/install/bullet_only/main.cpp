// Outside consumer of the Bullet extension alone: a compound of two ellipsoids built with addEllipsoid (no fit file,
// no bridge), a cloth dropped on it with the collider installed. Exit 0 when the cloth met the body and no node
// ended inside an ellipsoid.
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btTiming.h"

#include "BulletSoftBody/btSoftBodyHelpers.h"

#include <cstdio>

int main()
{
	btEllipsoidCompoundShape shape;
	shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.25, 0.1, 0.15));
	shape.addEllipsoid(btVector3(0.15, 0.05, 0), btMatrix3x3::getIdentity(), btVector3(0.12, 0.12, 0.12));

	btEllipsoidClothWorld world;
	btCollisionObject body;
	body.setCollisionShape(&shape);
	world.getWorld()->addCollisionObject(&body);
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(world.getWorldInfo(), btVector3(-0.4, 0.3, -0.4),
													   btVector3(0.4, 0.3, -0.4), btVector3(-0.4, 0.3, 0.4),
													   btVector3(0.4, 0.3, 0.4), 15, 15, 0, true);
	cloth->getCollisionShape()->setMargin(0.005);
	cloth->setTotalMass(0.2);
	world.getWorld()->addSoftBody(cloth);
	const char* why = 0;
	btEllipsoidClothCollider* collider = world.installCollider(&body, btEllipsoidClothCollider::Config(), &why);
	if (!collider)
	{
		std::printf("install refused: %s\n", why);
		return 2;
	}
	for (int i = 0; i < 60; ++i)
		world.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	const btEllipsoidClothStats& stats = collider->getAccumulatedStats();
	const bool ok = stats.m_nodesCorrected > 0 && stats.m_minZeta >= btScalar(1) && stats.m_nonFiniteNodes == 0;
	std::printf("bullet-only project: %d substeps, %d corrections, min zeta %.6f -> %s\n", stats.m_substeps,
				stats.m_nodesCorrected, double(stats.m_minZeta), ok ? "ok" : "FAILED");
	world.getWorld()->removeSoftBody(cloth);
	delete cloth;
	world.getWorld()->removeCollisionObject(&body);
	return ok ? 0 : 3;
}
