// The code of README.md, section "Using it in your own Bullet scene", verbatim between the markers below (issue 12
// item 10: the snippet must compile as printed). test_readme_snippet.cpp checks that the README shows exactly this
// text and runs it on a bundled fit. Edit both together.
// README snippet begin
#include "bodyfit/bridge/btBodyFitToBullet.h"          // JSON -> btEllipsoidCompoundShape
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h" // the collider and its soft-body solver

#include "BulletCollision/BroadphaseCollision/btDbvtBroadphase.h"
#include "BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h"
#include "BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h"

#include <cstdio>
#include <memory>

int dropIn(const char* fitFile)
{
    btSoftBodyRigidBodyCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btEllipsoidClothSoftBodySolver softSolver;  // instead of Bullet's default soft-body solver
    btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config, &softSolver);

    std::unique_ptr<btEllipsoidCompoundShape> shape = bodyfit::loadEllipsoidCompound(fitFile);
    btRigidBody body(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, shape.get()));
    world.addRigidBody(&body);                  // rigid bodies still collide with it (GJK/EPA)

    btEllipsoidClothCollider::Config cfg;       // skin offset 2 mm, friction kDF x body friction, optional eq. 10
    const char* why = nullptr;
    btEllipsoidClothCollider* collider = softSolver.installCollider(&world, &body, cfg, &why);
    if (!collider)                              // one call; disables Bullet's own response to that body
    {                                           // for every soft body
        std::fprintf(stderr, "%s\n", why);
        return 1;
    }
    world.stepSimulation(1.0f / 60, 1, 1.0f / 60); // add your cloth with world.addSoftBody first
    softSolver.uninstallCollider(collider);     // the body must outlive its collider
    world.removeRigidBody(&body);
    return 0;
}
// README snippet end
