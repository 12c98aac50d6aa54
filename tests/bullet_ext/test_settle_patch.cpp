// Settling of SoftDemo-like cloth on a fitted body (issue 12 item 1), tag [settle] (a few seconds in a Release build):
// Bullet's SoftDemo cloth setup (btSoftBodyHelpers::CreatePatch, kLST 0.4, bending constraints of distance 2,
// Bullet's default iteration counts and aero model, 60 Hz with one substep) over the head of female_young.obj with its
// bundled fit: a 60 x 60 patch pinned at its four corners, and the same 3,600-node patch free. Prints the mean node
// speed from positions and the largest |m_v| above a node's actual speed per 0.5 s, the speeds of the nodes on the
// body and of those hanging free, and checks the goals the collider owns (see the notes above the test cases).
//   build/tests/tests_bullet_ext "[settle]"
#include "support/fitted_body.h"
#include "support/settle_meter.h"

#include "BulletSoftBody/btSoftBodyHelpers.h"

#include <catch2/catch.hpp>

#include <cstdio>

namespace
{

struct SettleResult
{
	double landing = -1.0;        ///< time of the first corrected node (s)
	double restAt = -1.0;         ///< first time after landing with mean speed < 5 mm/s (-1: never)
	double worstExcess = 0.0;     ///< largest |m_v| - actual speed after landing (m/s)
	double finalMeanSpeed = 0.0;  ///< mean speed over the last step (m/s)
	double bodyRestAt = -1.0;     ///< first sample (every 0.5 s) with the nodes on the body at mean |v| < 5 mm/s
};

SettleResult runPatch(bool pinCorners, double seconds)
{
	const bodyfit_test::FittedBody fitted("female_young");
	const bodyfit::LoadedMesh& mesh = fitted.mesh;
	btEllipsoidClothWorld world;
	btCollisionObject body;
	bodyfit_test::addBodyWithGravity(world, body, fitted.compound.get());

	// Over the head: the top 10% of the vertices give x, z; 3 cm above the top.
	const double top = mesh.full.V.col(1).maxCoeff();
	const double h = top - mesh.full.V.col(1).minCoeff();
	double cx = 0, cz = 0;
	int n = 0;
	for (int i = 0; i < mesh.full.V.rows(); ++i)
		if (mesh.full.V(i, 1) > top - 0.1 * h)
			cx += mesh.full.V(i, 0), cz += mesh.full.V(i, 2), ++n;
	cx /= n;
	cz /= n;
	const btScalar s = btScalar(0.6), y = btScalar(top + 0.03);
	const btScalar x0 = btScalar(cx), z0 = btScalar(cz);
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(world.getWorldInfo(), btVector3(x0 - s, y, z0 - s),
													   btVector3(x0 + s, y, z0 - s), btVector3(x0 - s, y, z0 + s),
													   btVector3(x0 + s, y, z0 + s), 60, 60, pinCorners ? 1 + 2 + 4 + 8 : 0,
													   true);
	btSoftBody::Material* pm = cloth->appendMaterial();
	pm->m_kLST = btScalar(0.4);
	cloth->generateBendingConstraints(2, pm);
	cloth->getCollisionShape()->setMargin(btScalar(0.005));
	cloth->setTotalMass(btScalar(0.3));
	world.getWorld()->addSoftBody(cloth);
	const char* why = 0;
	btEllipsoidClothCollider* collider = world.installCollider(&body, btEllipsoidClothCollider::Config(), &why);
	REQUIRE(collider);

	bodyfit_test::SettleMeter meter(*cloth);
	SettleResult r;
	const double dt = 1.0 / 60.0;
	const int steps = int(seconds / dt + 0.5);
	bodyfit_test::SettleSample worst;
	for (int step = 1; step <= steps; ++step)
	{
		collider->resetStats();
		world.getWorld()->stepSimulation(btScalar(dt), 1, btScalar(dt));
		const bodyfit_test::SettleSample smp = meter.sample(dt);
		const double t = step * dt;
		if (r.landing < 0 && collider->getAccumulatedStats().m_nodesCorrected > 0)
			r.landing = t;
		if (r.landing >= 0)
		{
			r.worstExcess = std::max(r.worstExcess, smp.maxExcess);
			worst.nodesOverHalf = std::max(worst.nodesOverHalf, smp.nodesOverHalf);
			if (r.restAt < 0 && smp.meanSpeed < 0.005)
				r.restAt = t;
		}
		r.finalMeanSpeed = smp.meanSpeed;
		if (step % 30 == 0)
		{
			// Where the motion is: nodes on the body (zeta < 1.1: within ~5% of the radius) vs hanging free, and
			// the mean velocity of the whole cloth (a cloth sliding off or swinging moves as a whole).
			double onBody = 0, free = 0;
			int nOn = 0, nFree = 0;
			btVector3 meanV(0, 0, 0);
			for (int i = 0; i < cloth->m_nodes.size(); ++i)
			{
				const btSoftBody::Node& nd = cloth->m_nodes[i];
				const double speed = double(nd.m_v.length());
				meanV += nd.m_v / btScalar(cloth->m_nodes.size());
				if (fitted.compound->minZeta(nd.m_x) < btScalar(1.1))
					onBody += speed, ++nOn;
				else
					free += speed, ++nFree;
			}
			if (r.bodyRestAt < 0 && r.landing >= 0 && onBody / std::max(1, nOn) < 0.005)
				r.bodyRestAt = t;
			std::printf("settle %s t %.2f s: mean speed %.4f m/s, max speed %.3f, max |v| %.3f, max excess %.3f m/s, "
						"nodes > 0.5 m/s over %d; on body %d nodes mean |v| %.4f, free %d mean |v| %.4f, cloth "
						"velocity (%.3f, %.3f, %.3f)\n",
						pinCorners ? "pinned" : "free", t, smp.meanSpeed, smp.maxSpeed, smp.maxVelocity, smp.maxExcess,
						smp.nodesOverHalf, nOn, onBody / std::max(1, nOn), nFree, free / std::max(1, nFree),
						double(meanV.x()), double(meanV.y()), double(meanV.z()));
		}
	}
	std::printf("settle %s: landing %.3f s, rest (mean < 5 mm/s) at %.3f s, nodes on the body at rest at %.3f s, worst "
				"excess %.3f m/s (max %d nodes > 0.5)\n",
				pinCorners ? "pinned" : "free", r.landing, r.restAt, r.bodyRestAt, r.worstExcess, worst.nodesOverHalf);
	world.getWorld()->removeSoftBody(cloth);
	delete cloth;
	world.getWorld()->removeCollisionObject(&body);
	return r;
}

} // namespace

// SoftDemo's cloth has no damping (kDP 0), links at kLST 0.4 and one position iteration: the part hanging free of
// the body (87-96% of the nodes) swings as an undamped pendulum (the cloth's mean velocity changes sign), which is
// physical. Friction is Bullet's own combination for these defaults, kDF 0.2 x body friction 0.5 = 0.1, which cannot
// hold the hanging weight: the cloth slides off the head (real motion, measured from positions). What the collider
// owns is asserted: m_v never more than 0.5 m/s above the real motion after landing.
TEST_CASE("settle: SoftDemo-like 60 x 60 patch pinned at four corners over the head", "[settle][collider]")
{
	const SettleResult r = runPatch(true, 6.0);
	REQUIRE(r.landing > 0);
	CHECK(r.worstExcess < 0.5);
}

TEST_CASE("settle: SoftDemo-like free 3,600-node patch over the head", "[settle][collider]")
{
	const SettleResult r = runPatch(false, 6.0);
	REQUIRE(r.landing > 0);
	CHECK(r.worstExcess < 0.5);
}
