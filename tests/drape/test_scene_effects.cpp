// Effects: each listed effect changes the cloth in the expected direction; an unlisted effect is never built
// (no per-step object, zero work counters, Bullet's own aerodynamics and gravity left off).
#include "bodyfit/drape/simulation.h"
#include "drape/sphere_scene.h"

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>

#include <catch2/catch.hpp>

using namespace bodyfit::drape;
using bodyfit_test::patchScene;
using bodyfit_test::sphereBody;
using nlohmann::json;

namespace
{

Eigen::MatrixX3d run(DrapeSimulation& sim, int steps)
{
	for (int i = 0; i < steps; ++i)
		sim.step();
	return sim.clothMesh().V;
}

double maxDifference(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) { return (a - b).cwiseAbs().maxCoeff(); }

const json kGravity = {{"type", "gravity"}};

} // namespace

TEST_CASE("gravity: listed makes the cloth fall, unlisted leaves soft gravity at zero", "[effects]")
{
	const BodyData body = sphereBody();
	DrapeSimulation still(patchScene(json::array()), body);
	const Eigen::MatrixX3d start = still.clothMesh().V;
	const Eigen::MatrixX3d noGravity = run(still, 30);
	CHECK(still.cloth()->getWorldInfo()->m_gravity.length() == 0);
	// Nothing acts on a cloth at rest; only float32 rounding of the link projections moves nodes (ULP at 1 m is
	// 1.2e-7 m), so 1e-6 m is "did not move".
	CHECK(maxDifference(start, noGravity) < 1e-6);

	DrapeSimulation falling(patchScene(json::array({kGravity})), body);
	const Eigen::MatrixX3d fallen = run(falling, 30);
	// 0.25 s of free fall is 0.31 m; the centre lands on the sphere top (0.1 m below) and the rim keeps falling.
	CHECK(fallen.col(1).mean() < start.col(1).mean() - 0.05);
}

TEST_CASE("wind: a steady +x wind pushes the cloth along +x, and turbulence varies in space and time", "[effects]")
{
	const BodyData body = sphereBody();
	DrapeSimulation calm(patchScene(json::array({kGravity})), body);
	const Eigen::MatrixX3d c = run(calm, 60);
	const json wind = {{"type", "wind"}, {"velocity", {6.0, 0.0, 0.0}}, {"turbulence", 0.0}};
	DrapeSimulation windy(patchScene(json::array({kGravity, wind})), body);
	const Eigen::MatrixX3d w = run(windy, 60);
	// Drag on a draped cloth in a 6 m/s wind moves it by centimetres within 0.5 s; 1 cm is well clear of noise (0).
	CHECK(w.col(0).mean() > c.col(0).mean() + 0.01);
	CHECK(windy.counters().windSubsteps == 60);
	CHECK(windy.counters().windNodeForces == 60 * 17 * 17);

	json gusty = wind;
	gusty["turbulence"] = 3.0;
	DrapeSimulation turbulent(patchScene(json::array({kGravity, gusty})), body);
	const Eigen::MatrixX3d t = run(turbulent, 60);
	CHECK(maxDifference(t, w) > 1e-3);

	WindSpec spec;
	spec.velocity = Eigen::Vector3d(2, 0, 0);
	spec.turbulence = 1.0;
	WindEffect field(spec, std::nullopt, turbulent.cloth(), const_cast<EffectCounters&>(turbulent.counters()));
	const Eigen::Vector3d a = field.airVelocity(Eigen::Vector3d(0, 1, 0), 0.0);
	const Eigen::Vector3d b = field.airVelocity(Eigen::Vector3d(0.5, 1, 0), 0.0);
	const Eigen::Vector3d later = field.airVelocity(Eigen::Vector3d(0, 1, 0), 1.0);
	CHECK((a - b).norm() > 1e-3);
	CHECK((a - later).norm() > 1e-3);
	// The noise is bounded by the turbulence amplitude per component.
	for (int i = 0; i < 200; ++i)
	{
		const Eigen::Vector3d v = field.airVelocity(Eigen::Vector3d(0.037 * i, 1.0 - 0.011 * i, 0.02 * i), 0.05 * i);
		CHECK((v - spec.velocity).cwiseAbs().maxCoeff() <= 1.0 + 1e-12);
	}
}

TEST_CASE("aerodynamics: drag slows a falling cloth, and unlisted, Bullet's coefficients stay 0", "[effects]")
{
	const BodyData body = sphereBody();
	DrapeSimulation plain(patchScene(json::array({kGravity}), 2.5), body);
	CHECK(plain.cloth()->m_cfg.kLF == 0);
	CHECK(plain.cloth()->m_cfg.kDG == 0);
	const json aero = {{"type", "aerodynamics"}, {"model", "V_TwoSided"}, {"lift", 0.0}, {"drag", 2.0}};
	DrapeSimulation dragged(patchScene(json::array({kGravity, aero}), 2.5), body);
	CHECK(dragged.cloth()->m_cfg.kDG == Approx(2.0));
	// 40 steps (0.33 s) of free fall from 2.5 m: nothing touches the sphere (top at 1.25 m).
	const Eigen::MatrixX3d p = run(plain, 40), d = run(dragged, 40);
	CHECK(d.col(1).mean() > p.col(1).mean() + 0.01); // 2 m/s^2 ... decelerations give centimetres here
}

TEST_CASE("friction: a cloth dropped off-centre on the sphere slides less with friction", "[effects]")
{
	const BodyData body = sphereBody();
	DrapeSimulation slippery(patchScene(json::array({kGravity}), 1.3, 0.12), body);
	const json friction = {{"type", "friction"}, {"coefficient", 1.0}};
	DrapeSimulation grippy(patchScene(json::array({kGravity, friction}), 1.3, 0.12), body);
	CHECK(grippy.ellipsoidCollider()->getConfig().m_friction == Approx(1.0));
	CHECK(slippery.ellipsoidCollider()->getConfig().m_friction == 0);
	const Eigen::MatrixX3d s = run(slippery, 120), g = run(grippy, 120);
	// Off-centre, the heavier +x side drags the cloth off the sphere; friction holds it back.
	CHECK(s.col(0).mean() > g.col(0).mean() + 0.005);
}

TEST_CASE("pin: pinned corners stay exactly in place, unpinned ones fall", "[effects]")
{
	const BodyData body = sphereBody();
	const json pin = {{"type", "pin"}, {"select", "corners"}};
	DrapeSimulation pinned(patchScene(json::array({kGravity, pin})), body);
	DrapeSimulation free(patchScene(json::array({kGravity})), body);
	const Eigen::MatrixX3d start = pinned.clothMesh().V;
	const Eigen::MatrixX3d p = run(pinned, 60), f = run(free, 60);
	for (int i : {0, 16, 16 * 17, 17 * 17 - 1})
	{
		CHECK((p.row(i) - start.row(i)).norm() == 0.0); // inverse mass 0: never moved
		CHECK(f(i, 1) < start(i, 1) - 0.1);
	}
	CHECK(pinned.steppedEffects().empty()); // world pins need no per-step work
}

TEST_CASE("body_motion: the kinematic body carries the cloth and pins attached to it", "[effects]")
{
	const BodyData body = sphereBody();
	const json motion = {{"type", "body_motion"},
						 {"keyframes",
						  {{{"t", 0.0}, {"translation", {0, 0, 0}}}, {{"t", 0.5}, {"translation", {0.0, 0.3, 0.0}}}}}};
	// The sphere rises 0.3 m under a cloth 5 cm above its top: the cloth is lifted.
	DrapeSimulation lifted(patchScene(json::array({kGravity, motion}), 1.3), body);
	DrapeSimulation resting(patchScene(json::array({kGravity}), 1.3), body);
	const Eigen::MatrixX3d l = run(lifted, 60), r = run(resting, 60);
	CHECK(l.col(1).maxCoeff() > r.col(1).maxCoeff() + 0.2);
	CHECK(lifted.bodyPose().translation().y() == Approx(0.3).margin(1e-9));
	CHECK(lifted.counters().bodyMotionSubsteps == 60);
	CHECK(lifted.sample().insideEllipsoids == 0);

	const json pinToBody = {{"type", "pin"}, {"select", "corners"}, {"attach", "body"}};
	DrapeSimulation carried(patchScene(json::array({kGravity, motion, pinToBody}), 1.3), body);
	const Eigen::MatrixX3d start = carried.clothMesh().V;
	const Eigen::MatrixX3d c = run(carried, 60);
	// Pinned corners follow the body translation to float rounding (positions near 1 m, float32 Bullet).
	CHECK((c.row(0) - start.row(0)).y() == Approx(0.3).margin(1e-4));
	CHECK(carried.counters().pinSubsteps == 60);
}

TEST_CASE("self_collision: two crossing cloth layers stay apart only when listed", "[effects]")
{
	// Two 9 x 9 layers 2 cm apart in one soft body, the upper one moving down at 2 m/s, no gravity, no collider.
	bodyfit::TriMesh m;
	const int n = 9;
	m.V.resize(2 * n * n, 3);
	m.F.resize(2 * 2 * (n - 1) * (n - 1), 3);
	int f = 0;
	for (int layer = 0; layer < 2; ++layer)
	{
		for (int k = 0; k < n; ++k)
			for (int i = 0; i < n; ++i)
				m.V.row(layer * n * n + k * n + i) << 0.02 * i, 0.02 * layer, 0.02 * k;
		for (int k = 0; k + 1 < n; ++k)
			for (int i = 0; i + 1 < n; ++i)
			{
				const int a = layer * n * n + k * n + i;
				m.F.row(f++) << a, a + n, a + n + 1;
				m.F.row(f++) << a, a + n + 1, a + 1;
			}
	}
	auto simulate = [&](bool withSelfCollision, EffectCounters& counters) {
		btSoftBodyRigidBodyCollisionConfiguration config;
		btCollisionDispatcher dispatcher(&config);
		btDbvtBroadphase broadphase;
		btSequentialImpulseConstraintSolver solver;
		btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
		world.getWorldInfo().m_gravity.setZero();
		MaterialSpec material;
		SolverSpec solverSpec;
		btSoftBody* cloth = buildSoftBody(world.getWorldInfo(), m, material, solverSpec);
		world.addSoftBody(cloth);
		for (int i = n * n; i < 2 * n * n; ++i)
			cloth->m_nodes[i].m_v = btVector3(0, -2, 0);
		SelfCollisionSpec spec;
		spec.thickness = 0.006;
		spec.stiffness = 1.0;
		std::unique_ptr<SelfCollisionEffect> effect;
		if (withSelfCollision)
			effect = std::make_unique<SelfCollisionEffect>(spec, cloth, counters);
		const double dt = 1.0 / 240.0;
		for (int s = 0; s < 12; ++s) // 0.05 s: the upper layer would travel 10 cm
		{
			if (effect)
				effect->beforeSubstep(s * dt, dt);
			world.stepSimulation(btScalar(dt), 0, btScalar(dt));
		}
		double gap = 1e9; // mean height of the upper layer above the lower one
		double upper = 0, lower = 0;
		for (int i = 0; i < n * n; ++i)
		{
			lower += cloth->m_nodes[i].m_x.y();
			upper += cloth->m_nodes[n * n + i].m_x.y();
		}
		gap = (upper - lower) / (n * n);
		world.removeSoftBody(cloth);
		delete cloth;
		return gap;
	};
	EffectCounters withCounters, withoutCounters;
	const double gapWith = simulate(true, withCounters);
	const double gapWithout = simulate(false, withoutCounters);
	CHECK(gapWithout < -0.05);                  // passed straight through
	CHECK(gapWith > 0.5 * 0.006);               // held at about the thickness (stiffness 1 removes the shortfall)
	CHECK(withCounters.selfCollisionImpulses > 0);
	CHECK(withoutCounters.selfCollisionPairs == 0);
}

TEST_CASE("unlisted effects cost nothing: no per-step object, zero work counters", "[effects]")
{
	const BodyData body = sphereBody();
	DrapeSimulation sim(patchScene(json::array({kGravity})), body);
	CHECK(sim.steppedEffects().empty());
	run(sim, 20);
	const EffectCounters& c = sim.counters();
	CHECK(c.windSubsteps == 0);
	CHECK(c.windNodeForces == 0);
	CHECK(c.selfCollisionSubsteps == 0);
	CHECK(c.selfCollisionPairs == 0);
	CHECK(c.pinSubsteps == 0);
	CHECK(c.bodyMotionSubsteps == 0);
	// Bullet skips its aerodynamic branch when kLF = kDG = 0 (btSoftBody::applyForces: as_aero false).
	CHECK(sim.cloth()->m_cfg.kLF == 0);
	CHECK(sim.cloth()->m_cfg.kDG == 0);

	const json everything = json::array(
		{kGravity, {{"type", "wind"}}, {{"type", "self_collision"}},
		 {{"type", "body_motion"}, {"keyframes", {{{"t", 0.0}}, {{"t", 1.0}, {"translation", {0, 0.1, 0}}}}}},
		 {{"type", "pin"}, {"select", "corners"}, {"attach", "body"}}});
	DrapeSimulation all(patchScene(everything), body);
	CHECK(all.steppedEffects() == std::vector<std::string>{"body_motion", "pin", "wind", "self_collision"});
	run(all, 5);
	CHECK(all.counters().windSubsteps == 5);
	CHECK(all.counters().selfCollisionSubsteps == 5);
	CHECK(all.counters().pinSubsteps == 5);
	CHECK(all.counters().bodyMotionSubsteps == 5);
}
