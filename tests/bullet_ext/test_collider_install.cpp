// Installing the collider the ways users do, right and wrong (issue 12 items 4-8): a soft body added after install
// never gets Bullet's own response to the body; worlds other than btSoftRigidDynamicsWorld are refused by their
// virtual type (a C-style cast of a btDeformableMultiBodyDynamicsWorld too); a body removed from the world, or given
// another shape, detaches its collider (the body, or the old shape, may then be deleted); Config is validated; compounds built the wrong way get the useful message.
#include "bullet_ext/cloth_test_scene.h"

#include "BulletCollision/BroadphaseCollision/btDbvtBroadphase.h"
#include "BulletCollision/CollisionDispatch/btCollisionDispatcher.h"
#include "BulletCollision/CollisionShapes/btBoxShape.h"
#include "BulletCollision/CollisionShapes/btCompoundShape.h"
#include "BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h"
#include "BulletDynamics/Dynamics/btDiscreteDynamicsWorld.h"
#include "BulletSoftBody/btDeformableBodySolver.h"
#include "BulletSoftBody/btDeformableMultiBodyConstraintSolver.h"
#include "BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h"
#include "BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <new>
#include <string>

using namespace bodyfit_test;

namespace
{

std::unique_ptr<btEllipsoidCompoundShape> ball(btScalar r = btScalar(0.2))
{
	return singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(r, r, r));
}

/// A 9 x 9 patch 0.6 m wide at height y over the origin, added to the world (margin 0: Bullet's default kept).
btSoftBody* addPatch(btEllipsoidClothWorld& w, btScalar y, btScalar margin = 0)
{
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(w.getWorldInfo(), btVector3(-0.3, y, -0.3), btVector3(0.3, y, -0.3),
													   btVector3(-0.3, y, 0.3), btVector3(0.3, y, 0.3), 9, 9, 0, true);
	if (margin > 0)
		cloth->getCollisionShape()->setMargin(margin);
	w.getWorld()->addSoftBody(cloth);
	return cloth;
}

/// Rigid contacts Bullet's own soft response made with `body` in the last step.
int bulletContactsWith(const btSoftBody* psb, const btCollisionObject* body)
{
	int n = 0;
	for (int i = 0; i < psb->m_rcontacts.size(); ++i)
		n += psb->m_rcontacts[i].m_cti.m_colObj == body ? 1 : 0;
	return n;
}

std::string installError(btDynamicsWorld* world, btCollisionObject* body,
						 const btEllipsoidClothCollider::Config& config = btEllipsoidClothCollider::Config())
{
	btEllipsoidClothSoftBodySolver solver;
	const char* why = nullptr;
	btEllipsoidClothCollider* c = solver.installCollider(world, body, config, &why);
	CHECK(c == nullptr);
	REQUIRE(why != nullptr);
	CHECK(std::string(why).find('\n') == std::string::npos);
	return why;
}

} // namespace

TEST_CASE("install: a soft body added after install gets no Bullet response in its first step", "[bullet_ext][collider][install]")
{
	ClothScene scene(ball());
	REQUIRE(scene.install());
	// Added after install, 3 mm above the top of the ball: inside Bullet's 5 mm cloth margin, so Bullet's own
	// response would make contacts in the very first collision pass.
	btSoftBody* late = scene.addPatch(btVector3(0, btScalar(0.203), 0), btScalar(0.3), 9);
	scene.step(btScalar(1.0 / 60));
	CHECK(bulletContactsWith(late, scene.body()) == 0);
	CHECK(late->m_collisionDisabledObjects.findLinearSearch(scene.body()) < late->m_collisionDisabledObjects.size());
	// The same patch with the response left on (Config) does get Bullet's contacts: the check above can fail.
	ClothScene control(ball());
	btEllipsoidClothCollider::Config keep;
	keep.m_disableBulletResponse = false;
	REQUIRE(control.install(keep));
	btSoftBody* other = control.addPatch(btVector3(0, btScalar(0.203), 0), btScalar(0.3), 9);
	control.step(btScalar(1.0 / 60));
	CHECK(bulletContactsWith(other, control.body()) > 0);
}

TEST_CASE("install: worlds are checked by their virtual type, never dereferenced as the wrong one", "[bullet_ext][collider][install]")
{
	btEllipsoidCompoundShape shape;
	shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
	btCollisionObject body;
	body.setCollisionShape(&shape);
	btSoftBodyRigidBodyCollisionConfiguration config;
	btCollisionDispatcher dispatcher(&config);
	btDbvtBroadphase broadphase;
	SECTION("btDeformableMultiBodyDynamicsWorld, C-cast as Bullet's examples cast worlds")
	{
		btDeformableMultiBodyConstraintSolver solver;
		btDeformableBodySolver deformableSolver;
		solver.setDeformableSolver(&deformableSolver);
		btDeformableMultiBodyDynamicsWorld world(&dispatcher, &broadphase, &solver, &config, &deformableSolver);
		const std::string why = installError((btSoftRigidDynamicsWorld*)&world, &body);
		CHECK(why.find("btDeformableMultiBodyDynamicsWorld is not supported") != std::string::npos);
	}
	SECTION("a btDiscreteDynamicsWorld")
	{
		btSequentialImpulseConstraintSolver solver;
		btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
		CHECK(installError(&world, &body).find("not a btSoftRigidDynamicsWorld") != std::string::npos);
	}
}

#ifndef BT_DEBUG // debug builds assert on the removal (the ownership rule); release builds detach
TEST_CASE("install: a body removed from the world detaches its collider, which may then be deleted", "[bullet_ext][collider][install]")
{
	btEllipsoidClothWorld w;
	w.getWorld()->setGravity(btVector3(0, btScalar(-9.81), 0));
	w.getWorldInfo().m_gravity.setValue(0, btScalar(-9.81), 0);
	std::unique_ptr<btEllipsoidCompoundShape> shape = ball();
	btCollisionObject* body = new btCollisionObject();
	body->setCollisionShape(shape.get());
	w.getWorld()->addCollisionObject(body);
	btSoftBody* cloth = addPatch(w, btScalar(0.25));
	btEllipsoidClothCollider* c = w.installCollider(body);
	REQUIRE(c);
	for (int i = 0; i < 30; ++i)
		w.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	CHECK(c->getAccumulatedStats().m_nodesCorrected > 0); // it was colliding
	CHECK_FALSE(c->isDetached());

	w.getWorld()->removeCollisionObject(body);
	delete body; // the collider must not read it again (valgrind: no invalid read in the steps below)
	c->resetStats();
	for (int i = 0; i < 30; ++i)
		w.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	CHECK(c->isDetached());
	CHECK(c->getBody() == nullptr);
	CHECK(c->getAccumulatedStats().m_substeps == 0); // no longer colliding
	// The cloth fell through where the body was (nothing holds it), and no soft body still lists the body.
	CHECK(double(cloth->m_nodes[40].m_x.y()) < 0.0);
	CHECK(cloth->m_collisionDisabledObjects.size() == 0);
	CHECK(w.getSoftBodySolver()->uninstallCollider(c));
	w.getWorld()->removeSoftBody(cloth);
	delete cloth;
}

TEST_CASE("install: a body given another shape detaches its collider, and the old shape may then be deleted",
		  "[bullet_ext][collider][install]")
{
	// The collider holds the compound of the shape it was installed with. A body handed a new shape (a refit, a level
	// of detail) whose old one is deleted left it reading freed memory every substep (valgrind: 15 invalid reads;
	// ctest valgrind_collider_shape_replaced). Now it detaches as for a removed body and Bullet's own response to the body comes
	// back; to keep bodyfit's response, uninstall, set the shape and install again.
	btEllipsoidClothWorld w;
	w.getWorld()->setGravity(btVector3(0, btScalar(-9.81), 0));
	w.getWorldInfo().m_gravity.setValue(0, btScalar(-9.81), 0);
	std::unique_ptr<btEllipsoidCompoundShape> shape = ball(), replacement = ball(btScalar(0.15));
	btRigidBody body(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, shape.get()));
	w.getWorld()->addRigidBody(&body);
	btSoftBody* cloth = addPatch(w, btScalar(0.25), btScalar(0.005));
	btEllipsoidClothCollider* c = w.installCollider(&body);
	REQUIRE(c);
	for (int i = 0; i < 30; ++i)
		w.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	CHECK(c->getAccumulatedStats().m_nodesCorrected > 0); // it was colliding
	CHECK(cloth->m_collisionDisabledObjects.size() == 1);

	body.setCollisionShape(replacement.get());
	shape.reset(); // the collider must not read it again (valgrind: no invalid read in the steps below)
	c->resetStats();
	for (int i = 0; i < 30; ++i)
		w.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	CHECK(c->isDetached());
	CHECK(c->getBody() == nullptr);
	CHECK(c->getActiveSkinField() == nullptr);
	CHECK(c->getAccumulatedStats().m_substeps == 0); // no longer colliding
	CHECK(cloth->m_collisionDisabledObjects.size() == 0); // Bullet's own response to the body is back
	// Reinstalled on the new shape, bodyfit's response holds a new cloth on it.
	CHECK(w.getSoftBodySolver()->uninstallCollider(c));
	w.getWorld()->removeSoftBody(cloth);
	delete cloth;
	cloth = addPatch(w, btScalar(0.2), btScalar(0.005));
	btEllipsoidClothCollider* again = w.installCollider(&body);
	REQUIRE(again);
	for (int i = 0; i < 20; ++i)
		w.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	CHECK_FALSE(again->isDetached());
	CHECK(again->getAccumulatedStats().m_nodesCorrected > 0);
	int inside = 0; // any depth at all into the 0.15 m ball (the collider rests nodes 2 mm off it)
	for (int i = 0; i < cloth->m_nodes.size(); ++i)
		inside += double(cloth->m_nodes[i].m_x.length()) < 0.15 ? 1 : 0;
	CHECK(inside == 0);
	CHECK(w.getSoftBodySolver()->uninstallCollider(again));
	w.getWorld()->removeSoftBody(cloth);
	delete cloth;
	w.getWorld()->removeRigidBody(&body);
}
#endif

TEST_CASE("install: Config is validated (non-finite and out of range refused, implausible warned)", "[bullet_ext][collider][install]")
{
	typedef btEllipsoidClothCollider::Config Config;
	const btScalar nan = std::numeric_limits<btScalar>::quiet_NaN();
	const char* error = nullptr;
	const char* warning = nullptr;
	Config c;
	CHECK(btEllipsoidClothCollider::validateConfig(c, &error, &warning));
	CHECK(error == nullptr);
	CHECK(warning == nullptr);
	c.m_friction = nan;
	CHECK_FALSE(btEllipsoidClothCollider::validateConfig(c, &error, &warning));
	CHECK(std::string(error).find("finite") != std::string::npos);
	c = Config();
	c.m_skinOffset = btScalar(-0.001);
	CHECK_FALSE(btEllipsoidClothCollider::validateConfig(c, &error, &warning));
	CHECK(std::string(error).find("negative") != std::string::npos);
	c = Config();
	c.m_skinOffset = btScalar(2.0); // metres taken for millimetres, on a body of 0.4 m semi-axes
	CHECK_FALSE(btEllipsoidClothCollider::validateConfig(c, &error, &warning, btScalar(0.4)));
	CHECK(std::string(error).find("metres") != std::string::npos);
	c = Config();
	c.m_skinOffset = btScalar(0.06);
	CHECK(btEllipsoidClothCollider::validateConfig(c, &error, &warning));
	REQUIRE(warning != nullptr);
	CHECK(std::string(warning).find("5 cm") != std::string::npos);
	for (const btScalar clearance : {btScalar(0), btScalar(-0.5), btScalar(1.5), nan})
	{
		c = Config();
		c.m_liftClearance = clearance;
		CHECK_FALSE(btEllipsoidClothCollider::validateConfig(c, &error, &warning));
		CHECK(std::string(error).find("m_liftClearance") != std::string::npos);
	}
	c = Config();
	c.m_liftClearance = btScalar(1); // the whole offset: edges as far from the skin as the nodes
	CHECK(btEllipsoidClothCollider::validateConfig(c, &error, &warning));

	// install refuses, setConfig refuses and keeps the old Config.
	ClothScene scene(ball());
	btEllipsoidClothCollider::Config bad;
	bad.m_skinOffset = nan;
	const char* why = nullptr;
	CHECK(scene.solver()->installCollider(scene.world(), scene.body(), bad, &why) == nullptr);
	CHECK(std::string(why).find("finite") != std::string::npos);
	btEllipsoidClothCollider* collider = scene.install();
	REQUIRE(collider);
	CHECK(collider->getConfigWarning() == nullptr);
	CHECK_FALSE(collider->setConfig(bad, &why));
	CHECK(collider->getConfig().m_skinOffset == btScalar(0.002));
	btEllipsoidClothCollider::Config wide;
	wide.m_skinOffset = btScalar(0.08);
	CHECK(collider->setConfig(wide));
	CHECK(collider->getConfigWarning() != nullptr);
}

TEST_CASE("install: compounds built the wrong way get the useful message", "[bullet_ext][collider][install]")
{
	btEllipsoidClothWorld w;
	SECTION("a btEllipsoidCompoundShape filled with addChildShape")
	{
		btEllipsoidCompoundShape shape;
		// The compound owns and frees its children with btAlignedFree.
		btEllipsoidShape* child = new (btAlignedAlloc(sizeof(btEllipsoidShape), 16)) btEllipsoidShape(btVector3(0.1, 0.1, 0.1));
		shape.addChildShape(btTransform::getIdentity(), child);
		btCollisionObject body;
		body.setCollisionShape(&shape);
		const std::string why = installError(w.getWorld(), &body);
		CHECK(why.find("addChildShape") != std::string::npos);
		CHECK(why.find("addEllipsoid") != std::string::npos);
	}
	SECTION("a plain btCompoundShape of btEllipsoidShape children")
	{
		btCompoundShape shape;
		btEllipsoidShape a(btVector3(0.1, 0.1, 0.1)), b(btVector3(0.2, 0.1, 0.1));
		shape.addChildShape(btTransform::getIdentity(), &a);
		shape.addChildShape(btTransform(btQuaternion::getIdentity(), btVector3(0.1, 0, 0)), &b);
		btCollisionObject body;
		body.setCollisionShape(&shape);
		const std::string why = installError(w.getWorld(), &body);
		CHECK(why.find("plain btCompoundShape") != std::string::npos);
		CHECK(why.find("addEllipsoid") != std::string::npos);
	}
	SECTION("an empty btEllipsoidCompoundShape")
	{
		btEllipsoidCompoundShape shape;
		btCollisionObject body;
		body.setCollisionShape(&shape);
		CHECK(installError(w.getWorld(), &body).find("no ellipsoids") != std::string::npos);
	}
}

TEST_CASE("install: two bodies with a collider each hold a cloth draped over both, apart or touching", "[bullet_ext][collider][install]")
{
	// Colliders run one after the other in a substep, each against its own body. Bodies that do not overlap (two
	// characters side by side, touching at most) keep every node outside both: the second collider's response never
	// reaches into the first body. (Overlapping bodies are not: there the second can push a node into the first,
	// which is why overlapping parts belong in one compound; bullet_ext/README.md.)
	for (const double gap : {0.0, 0.03})
	{
		INFO("gap " << gap);
		btEllipsoidClothWorld w;
		w.getWorldInfo().m_gravity.setValue(0, btScalar(-9.81), 0);
		w.getWorld()->setGravity(btVector3(0, btScalar(-9.81), 0));
		const double r = 0.2, cx = r + gap / 2;
		std::unique_ptr<btEllipsoidCompoundShape> left = ball(btScalar(r)), right = ball(btScalar(r));
		btRigidBody a(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, left.get()));
		btRigidBody b(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, right.get()));
		a.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(btScalar(-cx), 1, 0)));
		b.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(btScalar(cx), 1, 0)));
		w.getWorld()->addRigidBody(&a);
		w.getWorld()->addRigidBody(&b);
		const btScalar h = btScalar(0.5);
		btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(w.getWorldInfo(), btVector3(-h, btScalar(1.3), -h),
														   btVector3(h, btScalar(1.3), -h), btVector3(-h, btScalar(1.3), h),
														   btVector3(h, btScalar(1.3), h), 41, 41, 0, true);
		cloth->m_cfg.piterations = 8;
		cloth->m_materials[0]->m_kLST = btScalar(0.9);
		cloth->m_cfg.kDP = btScalar(0.005);
		cloth->setTotalMass(btScalar(0.3));
		cloth->getCollisionShape()->setMargin(btScalar(0.005));
		w.getWorld()->addSoftBody(cloth);
		btEllipsoidClothCollider* ca = w.installCollider(&a);
		btEllipsoidClothCollider* cb = w.installCollider(&b);
		REQUIRE(ca);
		REQUIRE(cb);
		int inside = 0;
		for (int s = 0; s < 240; ++s) // 4 s: the cloth lands on both, slides into the gap between them and rests
		{
			w.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
			for (int i = 0; i < cloth->m_nodes.size(); ++i)
			{
				const btVector3& x = cloth->m_nodes[i].m_x;
				// Inside a sphere, in double: any depth at all counts (the collider keeps nodes 2 mm off the skin).
				const double da = double((x - a.getWorldTransform().getOrigin()).length()) - r;
				const double db = double((x - b.getWorldTransform().getOrigin()).length()) - r;
				inside += (da < 0.0 || db < 0.0) ? 1 : 0;
			}
		}
		CHECK(inside == 0);
		// Both bodies held the cloth: each collider corrected nodes.
		CHECK(ca->getAccumulatedStats().m_nodesCorrected > 100);
		CHECK(cb->getAccumulatedStats().m_nodesCorrected > 100);
		// The documented order: uninstall, then remove the bodies.
		CHECK(w.getSoftBodySolver()->uninstallCollider(ca));
		CHECK(w.getSoftBodySolver()->uninstallCollider(cb));
		w.getWorld()->removeSoftBody(cloth);
		delete cloth;
		w.getWorld()->removeRigidBody(&a);
		w.getWorld()->removeRigidBody(&b);
	}
}
