// Two-way coupling (issue 12 item 2): a dynamic rigid body whose shape is an ellipsoid compound takes the reaction of
// every velocity change the collider gives a node; static and kinematic bodies are unaffected (the other tests).
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include "BulletDynamics/Dynamics/btRigidBody.h"
#include "BulletSoftBody/btSoftBodyHelpers.h"
#include "LinearMath/btDefaultMotionState.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <memory>

namespace
{

/// A world with a dynamic ball (ellipsoid compound of one sphere) and a horizontal cloth patch under it.
struct BallAndCloth
{
	btEllipsoidClothWorld world;
	btEllipsoidCompoundShape shape;
	std::unique_ptr<btDefaultMotionState> motion;
	std::unique_ptr<btRigidBody> ball;
	btSoftBody* cloth = nullptr;
	btEllipsoidClothCollider* collider = nullptr;

	BallAndCloth(btScalar ballMass, const btVector3& ballAt, bool pinCorners, btScalar gravity, bool coupled = true,
				 btScalar damping = 0, btScalar friction = 0)
	{
		world.getWorld()->setGravity(btVector3(0, gravity, 0));
		world.getWorldInfo().m_gravity.setValue(0, gravity, 0);
		const btScalar r = btScalar(0.1);
		shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(r, r, r));
		btVector3 inertia;
		shape.calculateLocalInertia(ballMass, inertia);
		motion.reset(new btDefaultMotionState(btTransform(btQuaternion::getIdentity(), ballAt)));
		ball.reset(new btRigidBody(btRigidBody::btRigidBodyConstructionInfo(ballMass, motion.get(), &shape, inertia)));
		ball->setActivationState(DISABLE_DEACTIVATION);
		world.getWorld()->addRigidBody(ball.get());
		const btScalar h = btScalar(0.4);
		cloth = btSoftBodyHelpers::CreatePatch(world.getWorldInfo(), btVector3(-h, 0, -h), btVector3(h, 0, -h),
											   btVector3(-h, 0, h), btVector3(h, 0, h), 21, 21,
											   pinCorners ? 1 + 2 + 4 + 8 : 0, true);
		cloth->getCollisionShape()->setMargin(btScalar(0.005));
		cloth->m_cfg.piterations = 10;
		cloth->m_cfg.kDP = damping; // 0 for the momentum test: every velocity change must be accounted for
		cloth->m_materials[0]->m_kLST = btScalar(1.0);
		cloth->setTotalMass(btScalar(0.2));
		world.getWorld()->addSoftBody(cloth);
		btEllipsoidClothCollider::Config config;
		config.m_friction = friction;
		config.m_applyReactionToBody = coupled;
		collider = world.installCollider(ball.get(), config);
		REQUIRE(collider);
	}

	~BallAndCloth()
	{
		world.getWorld()->removeSoftBody(cloth);
		delete cloth;
		world.getWorld()->removeRigidBody(ball.get());
	}

	btVector3 momentum() const
	{
		btVector3 p = ball->getLinearVelocity() / ball->getInvMass();
		for (int i = 0; i < cloth->m_nodes.size(); ++i)
			if (cloth->m_nodes[i].m_im > 0)
				p += cloth->m_nodes[i].m_v / cloth->m_nodes[i].m_im;
		return p;
	}

	void step() { world.getWorld()->stepSimulation(btScalar(1.0 / 120), 1, btScalar(1.0 / 120)); }
};

} // namespace

TEST_CASE("coupling: a dynamic ball thrown into a free cloth keeps the total momentum", "[bullet_ext][collider][coupling]")
{
	for (bool coupled : {true, false})
	{
		INFO("coupled " << coupled);
		// No gravity; the ball (1 kg) moves down at 1 m/s into a free 0.2 kg patch 5 cm below it.
		BallAndCloth s(btScalar(1.0), btVector3(0, btScalar(0.15), 0), false, 0, coupled);
		s.ball->setLinearVelocity(btVector3(0, -1, 0));
		const btVector3 p0 = s.momentum();
		for (int i = 0; i < 60; ++i)
			s.step();
		const btVector3 p1 = s.momentum();
		const double clothSpeed = double(s.cloth->m_nodes[220].m_v.y());
		REQUIRE(s.collider->getAccumulatedStats().m_nodesCorrected + s.collider->getAccumulatedStats().m_nodesPushedOut > 0);
		CHECK(clothSpeed < -0.1); // the cloth was carried along
		if (coupled)
		{
			// Every velocity change of a node is matched on the ball; Bullet's link solve conserves momentum (equal
			// and opposite corrections weighted by inverse mass). 1% of |p0| = 1 kg m/s covers float rounding.
			CHECK(double((p1 - p0).length()) < 0.01);
			CHECK(double(s.ball->getLinearVelocity().y()) > -0.999); // the ball was slowed down
		}
		else
		{
			// One-way: the cloth gains momentum the ball never loses (the check above can fail).
			CHECK(double((p1 - p0).length()) > 0.05);
			CHECK(double(s.ball->getLinearVelocity().y()) == Approx(-1.0).margin(1e-6));
		}
	}
}

TEST_CASE("coupling: a dynamic ball rests in a cloth hammock pinned at four corners", "[bullet_ext][collider][coupling]")
{
	// A 0.1 kg ball of radius 0.1 m dropped from 0.15 m above the centre of a 0.8 m patch pinned at its corners;
	// Bullet's velocity damping kDP 0.05 (an undamped pinned cloth is a trampoline that never stops bouncing; 0.05 stops it within 8 s) and
	// friction 0.5 (frictionless, the nodes slide round the ball until it slips between them).
	BallAndCloth s(btScalar(0.1), btVector3(0, btScalar(0.15), 0), true, btScalar(-9.81), true, btScalar(0.05),
				   btScalar(0.5));
	double yHalfway = 0;
	for (int i = 0; i < 960; ++i) // 8 s
	{
		s.step();
		if (i == 839)
			yHalfway = double(s.ball->getCenterOfMassPosition().y());
	}
	const double y = double(s.ball->getCenterOfMassPosition().y());
	INFO("ball centre y " << y << " after 8 s, " << yHalfway << " after 7 s");
	// Held by the cloth: its centre stays within a sag of 0.4 m below the pins (without the reaction it falls
	// through the cloth's support: after 8 s of free fall it would be 300 m down).
	CHECK(y > -0.4);
	// At rest: moved less than 1 cm in the last second. Its m_linearVelocity at the end of a step is one substep of
	// gravity (g dt = 0.082 m/s, given by the rigid solve and taken back by the cloth in the next soft solve), plus
	// 1 cm/s of residual motion.
	CHECK(std::abs(y - yHalfway) < 0.01);
	CHECK(double(s.ball->getLinearVelocity().length()) < 9.81 / 120 + 0.01);
	// And no node ended inside the ball.
	CHECK(double(s.collider->getAccumulatedStats().m_minZeta) >= 1.0);
}
