#pragma once
// A bundled body with its bundled ellipsoid fit as a static collision object of a cloth world with gravity: the
// setup of the collider tests that drape cloth on a fitted body (test_collider_teleport.cpp, test_settle_patch.cpp).

#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/fitting/mesh_io.h"
#include "support/paths.h"

#include <memory>
#include <string>

namespace bodyfit_test
{

/// demos/assets/<name>.obj and its fit demos/assets/fits/<name>.json.
struct FittedBody
{
	bodyfit::LoadedMesh mesh;
	std::unique_ptr<btEllipsoidCompoundShape> compound;

	explicit FittedBody(const std::string& name)
		: mesh(bodyfit::loadTriMesh(assetPath(name + ".obj"))),
		  compound(bodyfit::loadEllipsoidCompound(assetPath("fits/" + name + ".json")))
	{
	}
};

/// Gravity of -9.81 m/s^2 along y for the rigid and the soft bodies, then `body` (shape `shape`, its transform as
/// it is) added to the world.
inline void addBodyWithGravity(btEllipsoidClothWorld& world, btCollisionObject& body, btCollisionShape* shape)
{
	world.getWorld()->setGravity(btVector3(0, btScalar(-9.81), 0));
	world.getWorldInfo().m_gravity.setValue(0, btScalar(-9.81), 0);
	body.setCollisionShape(shape);
	world.getWorld()->addCollisionObject(&body);
}

} // namespace bodyfit_test
