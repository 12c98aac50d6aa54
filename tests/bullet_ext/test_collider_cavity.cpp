// Push-out never lands in a cavity of the union: a node that starts inside an ellipsoid leaves the union at the
// nearest exit that is connected to the outside, not at a nearer one inside a pocket the ellipsoids enclose
// (fitted bodies have such pockets between neighbouring ellipsoids under the skin; a node pushed there is outside
// every ellipsoid but inside the body).
#include "bullet_ext/cloth_test_scene.h"

#include <catch2/catch.hpp>

using namespace bodyfit_test;

namespace
{

/// Six flat ellipsoids (semi-axes 1.6, 1.6, 0.15) centred on the faces of the cube [-1, 1]^3. Every point of the
/// cube's surface lies inside one of them (a point with |x| = 1 has y^2 + z^2 <= 2 < 1.6^2 on the x slab's
/// mid-plane), so the inside of the cube, |x|, |y|, |z| < 0.85, is a cavity enclosed by the union.
std::unique_ptr<btEllipsoidCompoundShape> sealedBox()
{
	std::unique_ptr<btEllipsoidCompoundShape> s(new btEllipsoidCompoundShape());
	for (int axis = 0; axis < 3; ++axis)
		for (int side = -1; side <= 1; side += 2)
		{
			btVector3 c(0, 0, 0), r(1.6, 1.6, 1.6);
			c[axis] = btScalar(side);
			r[axis] = btScalar(0.15);
			s->addEllipsoid(c, btMatrix3x3::getIdentity(), r);
		}
	return s;
}

bool insideCube(const btVector3& p, double half)
{
	return std::abs(double(p.x())) < half && std::abs(double(p.y())) < half && std::abs(double(p.z())) < half;
}

} // namespace

TEST_CASE("push-out: a node inside the wall of a sealed box leaves to the outside, not into the box",
		  "[bullet_ext][collider]")
{
	ClothScene scene(sealedBox());
	btEllipsoidClothCollider* collider = scene.install();
	REQUIRE(collider != nullptr);
	// Nodes inside the +z wall near its inner face (z = 0.85): the nearest exit is 0.02-0.05 m inward, into the
	// cavity; the way out to the outside (z = 1.15) is 0.23-0.26 m. One node on each wall, and one in an edge.
	std::vector<btVector3> starts = {btVector3(0.2f, 0.1f, 0.9f),  btVector3(-0.3f, 0.87f, 0.4f),
									 btVector3(0.88f, -0.2f, 0.1f), btVector3(0.1f, -0.9f, -0.3f),
									 btVector3(-0.89f, 0.3f, 0.2f), btVector3(0.0f, 0.2f, -0.86f),
									 btVector3(0.88f, 0.88f, 0.0f)};
	btSoftBody* probe = scene.addNodes(starts);
	for (int step = 0; step < 3; ++step)
	{
		scene.step(btScalar(1.0 / 60));
		for (int i = 0; i < probe->m_nodes.size(); ++i)
		{
			const btVector3 x = probe->m_nodes[i].m_x;
			INFO("node " << i << " at " << x.x() << " " << x.y() << " " << x.z() << " after step " << step);
			// Outside every ellipsoid (the collider's guarantee) ...
			double z = 1e30;
			for (const RefEllipsoid& e : worldEllipsoids(*scene.shape(), scene.body()->getWorldTransform()))
				z = std::min(z, e.zeta(toE(x)));
			CHECK(z >= 1.0 - 1e-6);
			// ... and outside the box: the cube of half size 1.15 (wall outer face) contains the union's inner
			// boundary; a node in the cavity would be within |.| < 0.85.
			CHECK_FALSE(insideCube(x, 1.0));
		}
	}
	CHECK(scene.report.minZeta >= 1.0 - 1e-6);
}
