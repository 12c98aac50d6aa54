// Moving ellipsoids (issue 13, deliverable 3): a driver poses the compound's ellipsoids at every substep (internal
// pre-tick callback, setEllipsoid or setEllipsoids) and the collider treats the change as motion of each ellipsoid
// from its previous pose. An upper-arm sized ellipsoid (semi-axes 0.15 x 0.05 x 0.05 m) sweeps through a pinned
// 0.6 m, 30 x 30 cloth translating and swinging about a shoulder at 1, 3 and 10 m/s; a thin (5 mm) and a growing
// ellipsoid too. Checked after every substep: no movable node inside an ellipsoid; at the end: no node tunnelled to
// the far side; free probes the ellipsoid hits move with its surface. Before the per-ellipsoid motion the 10 m/s
// translation (8.3 cm per 1/120 s substep, 10 cm thick) left the cloth behind the arm.
#include "moving_test_scene.h"
#include "src/btEllipsoidSweep.h"

#include "BulletCollision/CollisionShapes/btSphereShape.h"
#include "BulletDynamics/Dynamics/btRigidBody.h"
#include "LinearMath/btDefaultMotionState.h"

#include <catch2/catch.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cstdio>
#include <random>

using bodyfit_test::MovingMotion;
using bodyfit_test::MovingPose;
using bodyfit_test::MovingScene;

namespace
{

/// The guarantee after every substep: zeta >= 1 - 1e-6. The collider leaves nodes at zeta >= 1 (in btScalar) plus
/// the skin; the check evaluates the float coordinates and the compound's float data in double, which differs from
/// the collider's float evaluation by a few ulps of zeta (1e-6 as the other collider tests, test_cloth_collider.cpp).
const double kZetaFloor = 1.0 - 1e-6;

const double kDt = 1.0 / 120.0; ///< substep
const double kStart = 0.05;     ///< the motion starts after 6 substeps (the collider's first substep sees no motion)

/// Fraction of the motion done at time t for a motion of `duration` seconds starting at kStart.
double progress(double t, double duration)
{
	return std::min(1.0, std::max(0.0, (t - kStart) / duration));
}

/// The upper arm: long axis x, centre rising along y from -0.08 (top 3 cm under the cloth) by 0.2 m at `speed`.
MovingMotion translation(double speed, const Eigen::Vector3d& radii)
{
	const double rise = 0.2;
	return [=](double t) {
		MovingPose e;
		e.center = Eigen::Vector3d(0, -0.08 + rise * progress(t, rise / speed), 0);
		e.radii = radii;
		return std::vector<MovingPose>{e};
	};
}

const Eigen::Vector3d kPivot(-0.25, -0.10, 0.0); ///< the shoulder of the swing (under the cloth)

/// The upper arm swinging about kPivot in the xy-plane from -20 to 70 degrees, its tip (0.3 m out) at `tipSpeed`.
MovingMotion swing(double tipSpeed)
{
	const double sweep = M_PI / 2, omega = tipSpeed / 0.3;
	return [=](double t) {
		const double phi = -M_PI / 9 + sweep * progress(t, sweep / omega);
		MovingPose e;
		e.rotation = Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
		e.center = kPivot + e.rotation.col(0) * 0.15;
		e.radii = Eigen::Vector3d(0.15, 0.05, 0.05);
		return std::vector<MovingPose>{e};
	};
}

/// 0.6 m square, 30 x 30 nodes, horizontal at y = 0, pinned at its four corners (or the two at z = -0.3).
btSoftBody* pinnedCloth(btSoftBodyWorldInfo& info, bool fourCorners)
{
	const btScalar h = btScalar(0.3);
	btSoftBody* psb = btSoftBodyHelpers::CreatePatch(info, btVector3(-h, 0, -h), btVector3(h, 0, -h), btVector3(-h, 0, h),
													 btVector3(h, 0, h), 30, 30, fourCorners ? 1 + 2 + 4 + 8 : 1 + 2, true);
	psb->getCollisionShape()->setMargin(btScalar(0.005));
	psb->m_cfg.piterations = 10;
	psb->m_cfg.kDP = btScalar(0.005);
	psb->m_cfg.kDF = btScalar(0.5);
	psb->m_materials[0]->m_kLST = btScalar(0.9);
	psb->setTotalMass(btScalar(0.2));
	return psb;
}

struct SweepOutcome
{
	double minZeta = 0.0;
	int nonFinite = 0;
	int crossings = 0; ///< node paths through the ellipsoid's core (MovingScene::countCrossings)
	int corrected = 0; ///< nodes the collider placed on the surface (the ellipsoid did push cloth)
	/// The cloth's middle node in the ellipsoid's frame when the motion ends: local y / a_y (> 0: on the side it pushes to, > 1: above it; later a
	/// cloth tented over a 10 cm arm slides off its sides)
	double centreSide = 0.0;
};

/// The cloth run through a motion of `duration` seconds plus 0.25 s of rest.
SweepOutcome sweepCloth(const MovingMotion& motion, double duration, bool bulk, bool fourCorners)
{
	MovingScene scene(motion, bulk, -9.81);
	btSoftBody* cloth = scene.addSoftBody(pinnedCloth(scene.world().getWorldInfo(), fourCorners));
	REQUIRE(scene.install(btEllipsoidClothCollider::Config()));
	SweepOutcome out;
	const int motionEnd = int(std::ceil((kStart + duration) / kDt));
	scene.inspect = [&](int k) {
		if (k != motionEnd)
			return;
		const MovingPose e = scene.current()[0];
		const Eigen::Vector3d middle = bodyfit_test::toEigen(cloth->m_nodes[15 * 30 + 15].m_x); // (0.01, 0.01) at rest
		out.centreSide = (e.rotation.transpose() * (middle - e.center)).y() / e.radii.y();
	};
	scene.run(int(std::ceil((kStart + duration + 0.25) / kDt)), kDt);
	out.minZeta = scene.minZeta;
	out.nonFinite = scene.nonFinite;
	out.crossings = scene.crossings;
	out.corrected = scene.collider()->getAccumulatedStats().m_nodesCorrected;
	return out;
}

/// \param overTop the motion ends under the cloth's middle (translation, growth): the middle node must be above it
void requireSweep(const SweepOutcome& r, bool overTop)
{
	INFO("min zeta " << r.minZeta << ", crossings " << r.crossings << ", corrected " << r.corrected << ", middle node at "
						 << r.centreSide << " a_y");
	CHECK(r.nonFinite == 0);
	CHECK(r.minZeta >= kZetaFloor);
	CHECK(r.corrected > 0);   // the ellipsoid did push cloth along ...
	CHECK(r.crossings == 0); // ... and none of it went through
	if (overTop)
		CHECK(r.centreSide > 0.0); // the cloth is on the side the ellipsoid pushes it to (it may slide off later)
}

} // namespace

TEST_CASE("moving ellipsoids: a translating upper arm sweeps a pinned cloth at 1, 3 and 10 m/s without tunnelling",
		  "[bullet_ext][collider][moving]")
{
	for (const double speed : {1.0, 3.0, 10.0})
		for (const bool bulk : {false, true})
		{
			INFO("speed " << speed << " m/s, " << (bulk ? "setEllipsoids" : "setEllipsoid"));
			const SweepOutcome r = sweepCloth(translation(speed, Eigen::Vector3d(0.15, 0.05, 0.05)), 0.2 / speed, bulk, true);
			std::printf("moving translation %.0f m/s (%s): min zeta %.7f, corrected %d, crossings %d\n", speed,
						bulk ? "bulk" : "single", r.minZeta, r.corrected, r.crossings);
			requireSweep(r, true);
		}
}

TEST_CASE("moving ellipsoids: the static grid's lists serve a slow sweep next to a still ellipsoid",
		  "[bullet_ext][collider][moving]")
{
	// A still 1.6 m pole 1.5 m away makes the grid's cells 5.5 cm and the margin of its lists 1.4 cm, so at 1 m/s
	// (8 mm per substep) the arm stays within the margin for a substep or two after each rebuild: those substeps
	// take the static grid's lists filtered by the swept boxes (m_sweepOnGrid), the others the swept grid.
	for (const double speed : {0.5, 1.0})
	{
		INFO("speed " << speed << " m/s");
		const MovingMotion arm = translation(speed, Eigen::Vector3d(0.15, 0.05, 0.05));
		const MovingMotion withPole = [arm](double t) {
			std::vector<MovingPose> poses = arm(t);
			MovingPose pole;
			pole.center = Eigen::Vector3d(1.5, 0.0, 0.0);
			pole.radii = Eigen::Vector3d(0.1, 0.8, 0.1);
			poses.push_back(pole);
			return poses;
		};
		const SweepOutcome r = sweepCloth(withPole, 0.2 / speed, true, true);
		std::printf("moving next to a still ellipsoid %.1f m/s: min zeta %.7f, corrected %d, crossings %d\n", speed,
					r.minZeta, r.corrected, r.crossings);
		requireSweep(r, true);
	}
}

TEST_CASE("moving ellipsoids: an upper arm swinging about a shoulder sweeps a pinned cloth without tunnelling",
		  "[bullet_ext][collider][moving]")
{
	for (const double tipSpeed : {1.0, 3.0, 10.0})
	{
		INFO("tip speed " << tipSpeed << " m/s");
		const SweepOutcome r = sweepCloth(swing(tipSpeed), (M_PI / 2) / (tipSpeed / 0.3), true, false);
		std::printf("moving swing %.0f m/s: min zeta %.7f, corrected %d, crossings %d\n", tipSpeed, r.minZeta,
					r.corrected, r.crossings);
		requireSweep(r, false);
	}
}

TEST_CASE("moving ellipsoids: a 5 mm thin ellipsoid sweeps a pinned cloth without tunnelling",
		  "[bullet_ext][collider][moving]")
{
	// 2.5 and 8.3 cm per substep against 1 cm of thickness.
	for (const double speed : {3.0, 10.0})
	{
		INFO("speed " << speed << " m/s");
		const SweepOutcome r = sweepCloth(translation(speed, Eigen::Vector3d(0.15, 0.005, 0.05)), 0.2 / speed, true, true);
		std::printf("moving thin %.0f m/s: min zeta %.7f, corrected %d, crossings %d\n", speed, r.minZeta, r.corrected,
					r.crossings);
		requireSweep(r, true);
	}
}

TEST_CASE("moving ellipsoids: an ellipsoid growing under a pinned cloth lifts it", "[bullet_ext][collider][moving]")
{
	// Semi-axes scaled by 1.15 per substep for 15 substeps (x 8.1): from 1.5 cm under the cloth to 9 cm over it,
	// the top rising at up to 1.6 m/s.
	const MovingMotion grow = [](double t) {
		MovingPose e;
		e.center = Eigen::Vector3d(0, -0.03, 0);
		const int k = int(std::lround(std::min(std::max(t - kStart, 0.0), 15 * kDt) / kDt));
		e.radii = Eigen::Vector3d(0.02, 0.015, 0.02) * std::pow(1.15, k);
		return std::vector<MovingPose>{e};
	};
	const SweepOutcome r = sweepCloth(grow, 15 * kDt, true, true);
	std::printf("moving growth: min zeta %.7f, corrected %d, crossings %d\n", r.minZeta, r.corrected, r.crossings);
	requireSweep(r, true);
}

namespace
{

/// Free probes (no links, no gravity) on the plane y = 0 over the arm's path; after every substep each probe the
/// collider moved is compared with the surface velocity of the analytic motion at its nearest surface point p:
/// v_s = (p - p0) / dt with p0 = c0 + U0 U1^-1 (p - c1) (poses of the previous and this substep).
struct ProbeCheck
{
	int moved = 0;
	double worstInward = 0.0;          ///< largest -(v - v_s) . n over the moved probes (m/s; > 0 moves into it)
	std::vector<double> relativeSpeed; ///< |v - v_s| / |v_s| per moved probe
	double medianRelative() const
	{
		std::vector<double> r = relativeSpeed;
		if (r.empty())
			return 1.0;
		std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
		return r[r.size() / 2];
	}
};

ProbeCheck sweepProbes(const MovingMotion& motion, double duration)
{
	MovingScene scene(motion, true, 0.0);
	std::vector<btVector3> positions;
	for (int i = -12; i <= 12; ++i)
		for (int k = -4; k <= 4; ++k)
			positions.push_back(btVector3(btScalar(0.01 * i), 0, btScalar(0.01 * k)));
	std::vector<btScalar> masses(positions.size(), btScalar(0.01));
	btSoftBody* probes = scene.addSoftBody(
		new btSoftBody(&scene.world().getWorldInfo(), int(positions.size()), positions.data(), masses.data()));
	btEllipsoidClothCollider::Config config;
	config.m_friction = btScalar(100); // sticking contact: the probes keep the surface velocity
	REQUIRE(scene.install(config));
	std::vector<Eigen::Vector3d> x0(positions.size(), Eigen::Vector3d::Zero()), v0 = x0;
	ProbeCheck out;
	scene.inspect = [&](int k) {
		const MovingPose now = scene.posesAt(k)[0], before = scene.posesAt(k - 1)[0];
		for (int i = 0; i < probes->m_nodes.size(); ++i)
		{
			const Eigen::Vector3d x = bodyfit_test::toEigen(probes->m_nodes[i].m_x);
			const Eigen::Vector3d v = bodyfit_test::toEigen(probes->m_nodes[i].m_v);
			// A probe nothing touched moved x0 + v0 dt and kept v0 (up to float rounding of 0.3 m and 10 m/s).
			const bool moved = (x - (x0[i] + v0[i] * scene.dt())).norm() > 1e-5 || (v - v0[i]).norm() > 1e-4;
			x0[i] = x, v0[i] = v;
			if (!moved || k < 2)
				continue;
			const Eigen::Vector3d p = bodyfit_test::nearestSurfacePoint(now, x);
			const Eigen::Vector3d n = (x - p).normalized();
			const Eigen::Vector3d p0 = before.center + before.unwhiten() * now.unwhiten().inverse() * (p - now.center);
			const Eigen::Vector3d vs = (p - p0) / scene.dt();
			out.worstInward = std::max(out.worstInward, -(v - vs).dot(n));
			out.relativeSpeed.push_back((v - vs).norm() / std::max(vs.norm(), 1e-9));
			++out.moved;
		}
	};
	scene.run(int(std::ceil((kStart + duration + 0.05) / kDt)), kDt);
	CHECK(scene.minZeta >= kZetaFloor);
	CHECK(scene.crossings == 0);
	return out;
}

} // namespace

TEST_CASE("moving ellipsoids: probes the ellipsoid hits take its surface velocity", "[bullet_ext][collider][moving]")
{
	for (const double speed : {1.0, 3.0, 10.0})
	{
		const ProbeCheck t = sweepProbes(translation(speed, Eigen::Vector3d(0.15, 0.05, 0.05)), 0.2 / speed);
		const ProbeCheck s = sweepProbes(swing(speed), (M_PI / 2) / (speed / 0.3));
		std::printf("moving probes %.0f m/s: translation %d moved, worst inward %.2e m/s, median |v - v_s| / |v_s| %.2e; "
					"swing %d moved, worst inward %.2e m/s, median %.2e\n",
					speed, t.moved, t.worstInward, t.medianRelative(), s.moved, s.worstInward, s.medianRelative());
		INFO("speed " << speed);
		CHECK(t.moved > 0);
		CHECK(s.moved > 0);
		// No probe moves into the surface: the velocity rule removes the inward relative velocity at the contact
		// exactly, so only rounding remains (float positions of ~0.3 m carry ~3e-8 m, which (p - p0) / dt amplifies
		// by 120 to ~4e-6 m/s; 1e-3 m/s bounds that and the float normals).
		CHECK(t.worstInward <= 1e-3);
		CHECK(s.worstInward <= 1e-3);
		// And they ride with it (friction 100: sticking). Translation: every surface point has the same velocity,
		// so only rounding (1e-3 of it). Swing: a probe held at its start takes the velocity of its entry point,
		// up to the contact band (3.5 mm) from the nearest point p the check uses, on an arm whose points are at
		// least ~0.05 m from the pivot: 3.5 / 50 = 7 % for such a probe; the median stays below 5 %.
		CHECK(t.medianRelative() <= 1e-3);
		CHECK(s.medianRelative() <= 0.05);
	}
}

TEST_CASE("setEllipsoids: a rigid sphere resting on a compound child rides its new pose", "[bullet_ext][compound][moving]")
{
	for (const bool bulk : {false, true})
	{
		INFO((bulk ? "setEllipsoids" : "setEllipsoid"));
		btEllipsoidClothWorld world;
		world.getWorld()->setGravity(btVector3(0, btScalar(-9.81), 0));
		btEllipsoidCompoundShape shape;
		shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.3, 0.05, 0.3)); // a platform
		shape.addEllipsoid(btVector3(1, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
		btCollisionObject platform;
		platform.setCollisionShape(&shape);
		world.getWorld()->addCollisionObject(&platform);
		btSphereShape ball(btScalar(0.05));
		btDefaultMotionState motion(btTransform(btMatrix3x3::getIdentity(), btVector3(0, btScalar(0.2), 0)));
		btVector3 inertia(0, 0, 0);
		ball.calculateLocalInertia(btScalar(1), inertia);
		btRigidBody sphere(btRigidBody::btRigidBodyConstructionInfo(btScalar(1), &motion, &ball, inertia));
		sphere.setActivationState(DISABLE_DEACTIVATION);
		world.getWorld()->addRigidBody(&sphere);
		const btScalar dt = btScalar(1.0 / 120);
		for (int i = 0; i < 120; ++i)
			world.getWorld()->stepSimulation(dt, 1, dt);
		const double restBefore = double(sphere.getWorldTransform().getOrigin().y());
		// The platform rises 10 cm in 20 substeps (0.6 m/s), the other child stays.
		for (int i = 1; i <= 140; ++i)
		{
			const btVector3 centres[2] = {btVector3(0, btScalar(0.005 * std::min(i, 20)), 0), btVector3(1, 0, 0)};
			const btMatrix3x3 bases[2] = {btMatrix3x3::getIdentity(), btMatrix3x3::getIdentity()};
			const btVector3 axes[2] = {btVector3(0.3, 0.05, 0.3), btVector3(0.1, 0.1, 0.1)};
			if (bulk)
				REQUIRE(shape.setEllipsoids(2, centres, bases, axes));
			else
				shape.setEllipsoid(0, centres[0], bases[0], axes[0]);
			world.getWorld()->stepSimulation(dt, 1, dt);
		}
		const double restAfter = double(sphere.getWorldTransform().getOrigin().y());
		std::printf("setEllipsoids sphere (%s): rests at %.4f m, then %.4f m after the platform rose 0.1 m\n",
					bulk ? "bulk" : "single", restBefore, restAfter);
		// Resting on the platform top (0.05) plus the radius (0.05) and the margins (a few mm), before and after: the
		// rise is seen within 5 mm (contact penetration and margins differ by less).
		CHECK(std::abs(restBefore - 0.10) < 0.01);
		CHECK(std::abs((restAfter - restBefore) - 0.10) < 0.005);
		btVector3 lo, hi;
		shape.getAabb(btTransform::getIdentity(), lo, hi);
		CHECK(double(hi.y()) >= 0.15 - 1e-6); // the local AABB follows the platform
		world.getWorld()->removeRigidBody(&sphere);
		world.getWorld()->removeCollisionObject(&platform);
	}
}

TEST_CASE("setEllipsoids: a wrong count or a null array is refused with a reason", "[bullet_ext][compound][moving]")
{
	btEllipsoidCompoundShape shape;
	shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
	const int revision = shape.getAnalyticRevision();
	const btVector3 c(1, 0, 0), a(0.2, 0.2, 0.2);
	const btMatrix3x3 r = btMatrix3x3::getIdentity();
	const char* error = 0;
	CHECK_FALSE(shape.setEllipsoids(2, &c, &r, &a, &error));
	REQUIRE(error);
	CHECK(std::string(error).find("count") != std::string::npos);
	CHECK_FALSE(shape.setEllipsoids(1, &c, 0, &a, &error));
	CHECK(std::string(error).find("null") != std::string::npos);
	CHECK(shape.getAnalyticRevision() == revision);
	CHECK(shape.setEllipsoids(1, &c, &r, &a, &error));
	CHECK(error == 0);
	CHECK(shape.getAnalyticRevision() == revision + 1);
	CHECK(shape.getEllipsoid(0).m_center.x() == btScalar(1));
}

namespace
{

/// Probes at rest on the plane y = 0 and an arm that jumps 6 cm up into them in substep kJump: the counters of that
/// substep. `beforeJump` runs in the pre-tick callback just before the jump is posed.
btEllipsoidClothStats jumpIntoProbes(const std::function<void(MovingScene&)>& beforeJump)
{
	const int kJump = 8;
	const MovingMotion jump = [](double t) {
		MovingPose e;
		e.center = Eigen::Vector3d(0, t < (kJump - 0.5) * kDt ? -0.08 : -0.02, 0);
		e.radii = Eigen::Vector3d(0.15, 0.05, 0.05);
		return std::vector<MovingPose>{e};
	};
	MovingScene scene(jump, false, 0.0);
	std::vector<btVector3> positions;
	for (int i = -5; i <= 5; ++i)
		positions.push_back(btVector3(btScalar(0.02 * i), 0, 0));
	std::vector<btScalar> masses(positions.size(), btScalar(0.01));
	scene.addSoftBody(new btSoftBody(&scene.world().getWorldInfo(), int(positions.size()), positions.data(), masses.data()));
	REQUIRE(scene.install(btEllipsoidClothCollider::Config()));
	btEllipsoidClothStats atJump;
	scene.inspect = [&](int k) {
		if (k == kJump - 1)
			beforeJump(scene);
		if (k == kJump)
			atJump = scene.collider()->getLastSubstepStats();
	};
	scene.run(kJump + 2, kDt);
	CHECK(scene.minZeta >= kZetaFloor);
	return atJump;
}

} // namespace

TEST_CASE("moving ellipsoids: after resetBodyPose or a count change a pose jump is not a sweep",
		  "[bullet_ext][collider][moving]")
{
	// As a sweep the probes are met by the arm's top on its way up and placed there (corrected); as a jump they
	// start inside it and are pushed out of the union (pushed out), as after a teleport of the body.
	const btEllipsoidClothStats swept = jumpIntoProbes([](MovingScene&) {});
	const btEllipsoidClothStats reset = jumpIntoProbes([](MovingScene& s) { s.collider()->resetBodyPose(); });
	const btEllipsoidClothStats grown = jumpIntoProbes([](MovingScene& s) {
		s.shape().addEllipsoid(btVector3(5, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.1, 0.1));
	});
	std::printf("moving jump: swept corrected %d pushed %d; after resetBodyPose %d / %d; after a count change %d / %d\n",
				swept.m_nodesCorrected, swept.m_nodesPushedOut, reset.m_nodesCorrected, reset.m_nodesPushedOut,
				grown.m_nodesCorrected, grown.m_nodesPushedOut);
	CHECK(swept.m_nodesCorrected == 11);
	CHECK(swept.m_nodesPushedOut == 0);
	CHECK(reset.m_nodesCorrected == 0);
	CHECK(reset.m_nodesPushedOut == 11);
	CHECK(grown.m_nodesCorrected == 0);
	CHECK(grown.m_nodesPushedOut == 11);
}

namespace
{

const double kShellHalf = 0.05; ///< the shell's slabs are centred at +-kShellHalf along its three axes

/// A closed shell of six slabs (semi-axes 0.012 normal, 0.075 in plane: neighbours overlap along every edge and at
/// every corner, e.g. the corner (d, d, d) has zeta 0.89 in each of its three slabs), turned 45 degrees about y, whose
/// +x slab slides in from 0.06 m further out at 1 m/s: the cavity (|local|_inf < 0.05 outside the slabs) closes.
MovingMotion closingShell()
{
	const Eigen::Matrix3d turn = Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitY()).toRotationMatrix();
	return [=](double t) {
		std::vector<MovingPose> slabs;
		for (int axis = 0; axis < 3; ++axis)
			for (const double side : {-1.0, 1.0})
			{
				const double out = axis == 0 && side > 0 ? 0.06 * (1.0 - progress(t, 0.06)) : 0.0;
				Eigen::Vector3d local = Eigen::Vector3d::Zero(), radii = Eigen::Vector3d::Constant(0.075);
				local[axis] = side * (kShellHalf + out);
				radii[axis] = 0.012;
				MovingPose e;
				e.center = turn * local;
				e.rotation = turn;
				e.radii = radii;
				slabs.push_back(e);
			}
		return slabs;
	};
}

} // namespace

TEST_CASE("moving ellipsoids: a node a void of the union closes around leaves it", "[bullet_ext][collider][moving][pocket]")
{
	// The node rests at the shell's centre; the sliding slab never reaches it (its inner face stops 3.8 cm away), so
	// in every slab's moving frame the node's path enters nothing. Outside every ellipsoid is then not outside the
	// body: a skinned body's union holds its skin, and a void that closes this way (an armpit, thighs meeting) left
	// cloth inside the body mesh (tests/drape/test_scene_animated.cpp "[runs]") until the sweep moved such nodes out
	// of enclosed voids, as after a jump of the body.
	MovingScene scene(closingShell(), true, 0.0);
	btVector3 centre(0, 0, 0);
	btScalar mass(0.01);
	btSoftBody* probe = scene.addSoftBody(new btSoftBody(&scene.world().getWorldInfo(), 1, &centre, &mass));
	REQUIRE(scene.install(btEllipsoidClothCollider::Config()));
	scene.run(int(std::ceil((kStart + 0.06 + 0.05) / kDt)), kDt);
	const Eigen::Matrix3d turn = Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitY()).toRotationMatrix();
	const Eigen::Vector3d local = turn.transpose() * bodyfit_test::toEigen(probe->m_nodes[0].m_x);
	std::printf("moving pocket: the node ends at |local|_inf %.4f m (the cavity is < %.2f), %d enclosed exits\n",
				local.cwiseAbs().maxCoeff(), kShellHalf, scene.collider()->getAccumulatedStats().m_pushOutEnclosed);
	CHECK(scene.minZeta >= kZetaFloor);
	// Outside every slab and within |local|_inf <= 0.05 is the cavity (a point of the cube's boundary band is inside
	// a slab: its half-thickness is 1.2 cm at a face centre and the slabs overlap at the edges), so the node must
	// end beyond 0.05 in some local coordinate.
	CHECK(local.cwiseAbs().maxCoeff() > kShellHalf);
	CHECK(scene.collider()->getAccumulatedStats().m_pushOutEnclosed >= 1);
}

namespace
{

/// The elongated ellipsoid the frame test rests nodes on (centre at the origin, long axis x).
const Eigen::Vector3d kAlignRadii(0.15, 0.05, 0.08);

/// The same ellipsoid handed over in substep k in one of three equivalent frames (U = R diag(a) spans the same
/// ellipsoid for each): k % 3 == 0 the identity; 1 the columns (0, 1, 2) -> (1, 2, 0) with the semi-axes permuted
/// with them; 2 the columns 0 and 1 negated. Consecutive substeps differ by a permutation, a permutation and two sign
/// flips, or two sign flips: each, read as motion, is a half or third turn of the ellipsoid.
MovingPose equivalentFrame(int k)
{
	MovingPose e;
	e.radii = kAlignRadii;
	if (k % 3 == 1)
	{
		e.rotation.col(0) = Eigen::Vector3d::UnitY();
		e.rotation.col(1) = Eigen::Vector3d::UnitZ();
		e.rotation.col(2) = Eigen::Vector3d::UnitX();
		e.radii = Eigen::Vector3d(kAlignRadii.y(), kAlignRadii.z(), kAlignRadii.x());
	}
	else if (k % 3 == 2)
		e.rotation = Eigen::Vector3d(-1, -1, 1).asDiagonal();
	return e;
}

} // namespace

TEST_CASE("moving ellipsoids: the same ellipsoid handed over in an equivalent frame every substep does not move resting "
		  "nodes",
		  "[bullet_ext][collider][moving][align]")
{
	// An SVD-built pose can hand over the same ellipsoid with two axes swapped or two signs flipped; the sweep takes
	// the previous frame's axis symmetry closest to the current frame (btEllipsoidSweep::alignPreviousFrame), so the
	// ellipsoid does not move. Without that the change reads as a half turn and carries the nodes resting on its top
	// across the body (to its underside, ~10 cm).
	MovingScene scene([](double t) { return std::vector<MovingPose>{equivalentFrame(int(std::lround(t / kDt)))}; },
					  true, -9.81);
	// Free nodes on the upper cap (local direction with y >= 0.6 of the unit ball), 0.5 mm outside the surface (within the
	// contact band: the collider holds them from the first substep).
	std::vector<btVector3> positions;
	for (int i = -3; i <= 3; ++i)
		for (int k = -2; k <= 2; ++k)
		{
			const double ux = 0.25 * i, uz = 0.3 * k, uy = std::sqrt(std::max(0.0, 1.0 - ux * ux - uz * uz));
			if (uy < 0.6)
				continue;
			const Eigen::Vector3d u(ux, uy, uz);
			const Eigen::Vector3d surface = u.cwiseProduct(kAlignRadii);
			const Eigen::Vector3d normal = u.cwiseQuotient(kAlignRadii).normalized();
			positions.push_back(bodyfit_test::toBt(Eigen::Vector3d(surface + 0.0005 * normal)));
		}
	std::vector<btScalar> masses(positions.size(), btScalar(0.01));
	btSoftBody* nodes = scene.addSoftBody(
		new btSoftBody(&scene.world().getWorldInfo(), int(positions.size()), positions.data(), masses.data()));
	btEllipsoidClothCollider::Config config;
	config.m_friction = btScalar(100); // sticking contact: a resting node stays where it rests
	REQUIRE(scene.install(config));
	std::vector<Eigen::Vector3d> before;
	for (const btVector3& p : positions)
		before.push_back(bodyfit_test::toEigen(p));
	double worstStep = 0.0;
	int worstSubstep = 0;
	scene.inspect = [&](int k) {
		for (int i = 0; i < nodes->m_nodes.size(); ++i)
		{
			const Eigen::Vector3d x = bodyfit_test::toEigen(nodes->m_nodes[i].m_x);
			const double step = (x - before[i]).norm();
			if (step > worstStep)
				worstStep = step, worstSubstep = k;
			before[i] = x;
		}
	};
	const int substeps = 60; // 20 cycles of the three frames
	scene.run(substeps, kDt);
	std::printf("moving align: %d resting nodes, %d substeps of equivalent frames: largest step %.2e m (substep %d), "
				"min zeta %.7f\n",
				nodes->m_nodes.size(), substeps, worstStep, worstSubstep, scene.minZeta);
	CHECK(nodes->m_nodes.size() >= 10);
	CHECK(scene.nonFinite == 0);
	CHECK(scene.minZeta >= kZetaFloor);
	// A resting node moves by gravity and the contact response only: g dt^2 = 9.81 / 120^2 = 0.7 mm in a substep if
	// it fell freely, and the sticking contact on the still surface holds it (the nodes start within the contact
	// band, so in practice they move by float rounding, ~1e-8 m). 2 mm bounds that with margin (about three substeps
	// of free fall); a frame read as a half turn carries a node across the ellipsoid (decimetres: 0.87 m per substep
	// with alignPreviousFrame disabled).
	CHECK(worstStep <= 0.002);
}

TEST_CASE("moving ellipsoids: the frame alignment's shortcut keeps a frame only where the symmetry search would",
		  "[bullet_ext][collider][moving][align]")
{
	// btEllipsoidSweep::keepsFrame skips the search over the 24 axis symmetries S (the largest trace(S^T m), S = I
	// first and kept on ties) when the diagonal of m = U0^T U1 dominates its columns. Checked against that search, in
	// btScalar as alignPreviousFrame computes it, on small turns (where the shortcut must fire: the common case),
	// large turns and frames handed over with axes swapped or signs flipped (where the search must run).
	std::mt19937 rng(20261204);
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	const int perms[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {1, 0, 2}, {0, 2, 1}, {2, 1, 0}};
	int kept = 0, smallTurns = 0, smallKept = 0;
	for (int trial = 0; trial < 20000; ++trial)
	{
		const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
		const double angle = trial % 2 ? 0.2 * u(rng) : 3.0 * u(rng); // radians: small turns and any turn
		const Eigen::Vector3d radii(0.02 + 0.1 * std::abs(u(rng)), 0.02 + 0.1 * std::abs(u(rng)),
									0.02 + 0.1 * std::abs(u(rng)));
		Eigen::Matrix3d u0 = Eigen::Matrix3d(Eigen::AngleAxisd(3.0 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()));
		Eigen::Matrix3d u1 = Eigen::AngleAxisd(angle, axis) * u0;
		u0 = u0 * radii.asDiagonal();
		u1 = u1 * (radii * (1.0 + 0.05 * u(rng))).asDiagonal();
		if (trial % 5 == 0) // the same ellipsoid handed over with two axes swapped and one sign flipped
		{
			u1.col(0).swap(u1.col(1));
			u1.col(2) = -u1.col(2);
		}
		const btMatrix3x3 b0 = bodyfit_test::toBt(u0), b1 = bodyfit_test::toBt(u1);
		const btMatrix3x3 m = b0.transpose() * b1;
		btScalar bestTrace = -SIMD_INFINITY;
		bool identityBest = false;
		for (int p = 0; p < 6; ++p)
			for (int signs = 0; signs < 8; ++signs)
			{
				btScalar sign[3];
				btScalar det = p < 3 ? btScalar(1) : btScalar(-1);
				for (int k = 0; k < 3; ++k)
					det *= (sign[k] = (signs >> k) & 1 ? btScalar(-1) : btScalar(1));
				if (!(det > btScalar(0)))
					continue;
				const btScalar trace =
					sign[0] * m[perms[p][0]][0] + sign[1] * m[perms[p][1]][1] + sign[2] * m[perms[p][2]][2];
				if (trace > bestTrace)
				{
					bestTrace = trace;
					identityBest = p == 0 && signs == 0;
				}
			}
		const bool shortcut = btEllipsoidSweep::keepsFrame(m);
		if (shortcut)
		{
			++kept;
			CHECK(identityBest);
		}
		if (trial % 5 != 0 && std::abs(angle) < 0.2)
		{
			++smallTurns;
			smallKept += shortcut ? 1 : 0;
		}
	}
	INFO("kept " << kept << ", small turns " << smallTurns << " of which kept " << smallKept);
	// Under 0.2 rad (11 degrees) and 5% of reshaping the diagonal dominates unless two semi-axes are nearly equal
	// (then a turn mixes their columns): most small turns take the shortcut, swapped frames never do.
	CHECK(smallKept * 10 >= smallTurns * 7);
	CHECK(kept > 0);
}

TEST_CASE("moving ellipsoids: the swept broad phase gives every overlapping swept box, before and after its lists",
		  "[bullet_ext][collider][moving][broadphase]")
{
	// btEllipsoidSweep::candidates answers the first kTestedQueries paths of a substep by testing every swept box and
	// builds the grid's lists for the next ones. Both must give exactly the swept boxes the grown path box overlaps
	// (the set the moving-frame test needs, btEllipsoidSweep.cpp): checked against that brute force on random short
	// and long paths near 40 ellipsoids that each move and turn, for two substeps, past the switch in each.
	std::mt19937 rng(20261205);
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	const int count = 40;
	btEllipsoidCompoundShape shape;
	std::vector<btVector3> centers(count), axes(count);
	std::vector<btMatrix3x3> bases(count);
	for (int i = 0; i < count; ++i)
	{
		centers[i] = btVector3(btScalar(0.5 * u(rng)), btScalar(0.9 * u(rng)), btScalar(0.3 * u(rng)));
		axes[i] = btVector3(btScalar(0.03 + 0.08 * std::abs(u(rng))), btScalar(0.03 + 0.08 * std::abs(u(rng))),
							btScalar(0.03 + 0.08 * std::abs(u(rng))));
		bases[i] = bodyfit_test::toBt(Eigen::Matrix3d(
			Eigen::AngleAxisd(3.0 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized())));
		shape.addEllipsoid(centers[i], bases[i], axes[i]);
	}
	btEllipsoidWorldCache cache;
	cache.update(&shape, btTransform::getIdentity());
	btEllipsoidSweep sweep;
	const btScalar radius(0.002);
	std::vector<int> out(count);
	int checked = 0, longPaths = 0, meeting = 0;
	for (int substep = 0; substep < 2; ++substep)
	{
		for (int i = 0; i < count; ++i)
		{
			centers[i] += btVector3(btScalar(0.01 * u(rng)), btScalar(0.01 * u(rng)), btScalar(0.01 * u(rng)));
			bases[i] = bodyfit_test::toBt(Eigen::Matrix3d(Eigen::AngleAxisd(0.05 * u(rng), Eigen::Vector3d::UnitZ()))) *
					   bases[i];
		}
		REQUIRE(shape.setEllipsoids(count, centers.data(), bases.data(), axes.data()));
		sweep.capture(cache);
		cache.update(&shape, btTransform::getIdentity());
		REQUIRE(sweep.prepare(cache));
		REQUIRE_FALSE(sweep.hasUnbounded());
		const btVector3* boxes = sweep.sweptBoxes();
		for (int p = 0; p < 3 * int(btEllipsoidSweep::kTestedQueries); ++p)
		{
			const btVector3 q = centers[p % count] +
								btVector3(btScalar(0.12 * u(rng)), btScalar(0.12 * u(rng)), btScalar(0.12 * u(rng)));
			const double length = p % 4 == 0 ? 0.3 : 0.02; // some paths over many cells
			longPaths += p % 4 == 0 ? 1 : 0;
			const btVector3 x =
				q + btVector3(btScalar(length * u(rng)), btScalar(length * u(rng)), btScalar(length * u(rng)));
			const int nc = sweep.candidates(q, x, radius, out.data());
			std::vector<int> got(out.begin(), out.begin() + nc);
			std::sort(got.begin(), got.end());
			const btScalar grow = sweep.growth(q, x, radius);
			btVector3 lo = q, hi = q;
			lo.setMin(x);
			hi.setMax(x);
			lo -= btVector3(grow, grow, grow);
			hi += btVector3(grow, grow, grow);
			std::vector<int> want;
			for (int j = 0; j < count; ++j)
				if (!(lo.x() > boxes[2 * j + 1].x() || hi.x() < boxes[2 * j].x() || lo.y() > boxes[2 * j + 1].y() ||
					  hi.y() < boxes[2 * j].y() || lo.z() > boxes[2 * j + 1].z() || hi.z() < boxes[2 * j].z()))
					want.push_back(j);
			INFO("substep " << substep << ", path " << p);
			CHECK(got == want); // each once, none missing, none extra
			meeting += nc > 0 ? 1 : 0;
			++checked;
		}
	}
	INFO("paths " << checked << ", long " << longPaths << ", meeting a swept box " << meeting);
	CHECK(meeting * 2 > checked); // the check has something to compare: most paths meet swept boxes
}
