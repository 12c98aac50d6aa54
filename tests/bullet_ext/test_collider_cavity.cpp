// Push-out never lands in a cavity of the union: a node that starts inside an ellipsoid leaves the union at the
// nearest exit that is connected to the outside, not at a nearer one inside a pocket the ellipsoids enclose
// (fitted bodies have such pockets between neighbouring ellipsoids under the skin; a node pushed there is outside
// every ellipsoid but inside the body). And the escape test that finds such pockets (leaveEnclosedPocket, whose axis
// rays run on bins) never lets a point in one go.
#include "bullet_ext/cloth_test_scene.h"
#include "src/btEllipsoidUnionPushOut.h" // the escape test, asked directly

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>

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

namespace
{

/// A ray from p along d (unit) misses every ellipsoid by a clear margin (double): for each, the whitened line's
/// discriminant is below -1e-9 or both roots lie behind p by more than 1e-9 (far above the float rounding of the
/// escape test's quadratic at unit scale, 1e-7, squared into the discriminant).
bool rayClearlyEscapes(const std::vector<RefEllipsoid>& ells, const Eigen::Vector3d& p, const Eigen::Vector3d& d)
{
	for (const RefEllipsoid& e : ells)
	{
		const Eigen::Vector3d u0 = (e.rotation.transpose() * (p - e.center)).cwiseQuotient(e.radii);
		const Eigen::Vector3d w = (e.rotation.transpose() * d).cwiseQuotient(e.radii);
		const double a = w.squaredNorm(), b = u0.dot(w), c = u0.squaredNorm() - 1.0;
		const double disc = b * b - a * c;
		if (disc < -1e-9)
			continue;
		if ((-b + std::sqrt(std::max(disc, 0.0))) / a < -1e-9)
			continue;
		return false;
	}
	return true;
}

} // namespace

TEST_CASE("escape test: points in a sealed box's cavity leave it, points with a free ray stay, in a crowd of "
		  "ellipsoids", "[bullet_ext][collider][pocket]")
{
	// The sealed box plus 40 balls (radius 0.1-0.3) around it, centred at |c|_inf >= 1.5 (so none reaches into the
	// cavity, |local|_inf < 0.89 off the slabs): the escape test's axis-ray bins then list several ellipsoids per
	// bin, and a bin that missed a slab would let an axis ray of a cavity point escape. Two body poses: the identity
	// and a turned, shifted one (the axis rays are then oblique to the slabs).
	std::unique_ptr<btEllipsoidCompoundShape> shape = sealedBox();
	std::mt19937 rng(20261202);
	std::uniform_real_distribution<double> unit(-1.0, 1.0);
	for (int added = 0; added < 40;)
	{
		const btVector3 c(btScalar(2.5 * unit(rng)), btScalar(2.5 * unit(rng)), btScalar(2.5 * unit(rng)));
		if (c.absolute()[c.absolute().maxAxis()] < btScalar(1.5))
			continue;
		const btScalar r = btScalar(0.2 + 0.1 * unit(rng));
		shape->addEllipsoid(c, btMatrix3x3::getIdentity(), btVector3(r, r, r));
		++added;
	}
	const btScalar skin(0.002);
	const btTransform poses[] = {btTransform::getIdentity(),
								 btTransform(btQuaternion(btVector3(1, 1, 0).normalized(), btScalar(0.5)),
											 btVector3(btScalar(0.3), btScalar(1.0), btScalar(-0.2)))};
	for (const btTransform& pose : poses)
	{
		btEllipsoidWorldCache cache;
		cache.update(shape.get(), pose);
		btEllipsoidUnionPushOut escape;
		escape.prepareEscapeRays(cache);
		const std::vector<RefEllipsoid> ells = worldEllipsoids(*shape, pose);
		auto minZeta = [&](const btVector3& p) {
			double z = 1e30;
			for (const RefEllipsoid& e : ells)
				z = std::min(z, e.zeta(toE(p)));
			return z;
		};
		int checkedOutside = 0;
		for (int i = 0; i < 400; ++i)
		{
			const bool cavity = i % 2 == 0;
			const double scale = cavity ? 0.8 : 2.6;
			const btVector3 local(btScalar(scale * unit(rng)), btScalar(scale * unit(rng)), btScalar(scale * unit(rng)));
			if (!cavity && local.absolute()[local.absolute().maxAxis()] < btScalar(1.3))
				continue;
			const btVector3 p = pose * local;
			if (minZeta(p) < 1.0)
				continue; // inside a ball or a slab: not a point the escape test is asked about
			btPushOutResult out;
			escape.leaveEnclosedPocket(cache, p, skin, out);
			INFO("pose origin y " << pose.getOrigin().y() << ", local point " << local.x() << " " << local.y() << " "
								  << local.z());
			// The collider keeps per node the ray that left last time (the escape hint): it changes the order of the
			// rays, never the outcome. Every hint (none, each axis ray, each lattice direction, out of range) gives
			// the same result, and the hint written back names a ray that leaves: asked again with it, nothing changes.
			for (int h = 0; h <= btEllipsoidUnionPushOut::kLatticeHint + 26; ++h)
			{
				unsigned char hint = (unsigned char)(h == btEllipsoidUnionPushOut::kLatticeHint + 26 ? 200 : h);
				btPushOutResult hinted;
				escape.leaveEnclosedPocket(cache, p, skin, hinted, &hint);
				INFO("hint " << h);
				REQUIRE(hinted.m_moved == out.m_moved);
				if (out.m_moved)
				{
					CHECK(hinted.m_point == out.m_point);
					CHECK(int(hint) == int(btEllipsoidUnionPushOut::kNoEscapeHint));
					continue;
				}
				const unsigned char written = hint;
				CHECK(int(written) != int(btEllipsoidUnionPushOut::kNoEscapeHint));
				escape.leaveEnclosedPocket(cache, p, skin, hinted, &hint);
				CHECK_FALSE(hinted.m_moved);
				CHECK(int(hint) == int(written));
			}
			if (cavity)
			{
				// Enclosed: it must leave, outside every ellipsoid (1e-6: float rounding of zeta at unit scale) and
				// outside the box (the cube of half size 1 holds the cavity and the slabs' inner halves).
				REQUIRE(out.m_moved);
				CHECK(out.m_enclosed);
				CHECK(minZeta(out.m_point) >= 1.0 - 1e-6);
				const btVector3 exitLocal = pose.invXform(out.m_point);
				CHECK_FALSE(insideCube(exitLocal, 1.0));
				continue;
			}
			// Outside the box: where one of the 26 lattice directions clearly leaves the union, the point is not in
			// an enclosed void and must not move.
			bool free = false;
			for (int dx = -1; dx <= 1 && !free; ++dx)
				for (int dy = -1; dy <= 1 && !free; ++dy)
					for (int dz = -1; dz <= 1 && !free; ++dz)
						if (dx || dy || dz)
							free = rayClearlyEscapes(ells, toE(p), Eigen::Vector3d(dx, dy, dz).normalized());
			if (!free)
				continue;
			++checkedOutside;
			CHECK_FALSE(out.m_moved);
		}
		// Most outside points have a free lattice ray (the balls are sparse): the check above is not vacuous.
		CHECK(checkedOutside >= 100);
	}
}

TEST_CASE("first sight: nodes that start in a cavity of the union leave it in the first substep that collides them",
		  "[bullet_ext][collider][pocket]")
{
	// A garment placed through the body (authored on another body, or in another pose) starts with nodes inside the
	// body; those outside every ellipsoid are in the body's interior, which the union does not fill. The static body
	// never runs the escape test (only after a jump or while its ellipsoids move), so such nodes stayed there for
	// good: the skirt drop with the skirt at 0.6x its width ended with 174 nodes inside the body (paper surface).
	// Probes in the sealed box's cavity, added before install and after it (a cloth added mid-run), at rest, no
	// gravity: each set leaves the box in the first substep that collides it, and no node outside the box moves.
	ClothScene scene(sealedBox());
	scene.world()->setGravity(btVector3(0, 0, 0));
	scene.world()->getWorldInfo().m_gravity.setValue(0, 0, 0);
	std::vector<btVector3> cavity, outside;
	std::mt19937 rng(20261207);
	std::uniform_real_distribution<double> unit(-1.0, 1.0);
	const std::vector<RefEllipsoid> slabs = worldEllipsoids(*scene.shape(), btTransform::getIdentity());
	while (outside.size() < 30)
	{
		cavity.emplace_back(btScalar(0.8 * unit(rng)), btScalar(0.8 * unit(rng)), btScalar(0.8 * unit(rng)));
		// Outside the box (|.|_inf >= 1.3 on one axis) and clear of every slab (zeta > 1.2, beyond the skin).
		btVector3 p(btScalar(2.0 * unit(rng)), btScalar(2.0 * unit(rng)), btScalar(2.0 * unit(rng)));
		const int axis = int(cavity.size() % 3);
		p[axis] = btScalar(cavity.size() % 2 ? 1.3 + 0.5 * std::abs(unit(rng)) : -1.3 - 0.5 * std::abs(unit(rng)));
		double zeta = 1e30;
		for (const RefEllipsoid& e : slabs)
			zeta = std::min(zeta, e.zeta(toE(p)));
		if (zeta > 1.2)
			outside.push_back(p);
	}
	btSoftBody* before = scene.addNodes(cavity);
	btSoftBody* still = scene.addNodes(outside);
	btEllipsoidClothCollider::Config paper;
	paper.m_surface = btEllipsoidClothCollider::ELLIPSOIDS;
	REQUIRE(scene.install(paper));
	const btScalar dt = btScalar(1.0 / 60);
	scene.step(dt);
	auto countInCube = [](const btSoftBody* psb) {
		int n = 0;
		for (int i = 0; i < psb->m_nodes.size(); ++i)
			n += insideCube(psb->m_nodes[i].m_x, 1.0) ? 1 : 0;
		return n;
	};
	CHECK(countInCube(before) == 0);
	for (int i = 0; i < still->m_nodes.size(); ++i)
	{
		const btVector3 d = still->m_nodes[i].m_x - outside[std::size_t(i)];
		INFO("outside node " << i << " moved by " << d.x() << " " << d.y() << " " << d.z());
		CHECK(d.length() == 0); // a free ray: nothing to do
	}
	// A soft body added while the collider runs: its first substep is its first sight.
	btSoftBody* after = scene.addNodes(cavity);
	scene.step(dt);
	CHECK(countInCube(after) == 0);
	for (int i = 0; i < 10; ++i)
		scene.step(dt);
	CHECK(countInCube(before) == 0);
	CHECK(countInCube(after) == 0);
	// Outside every ellipsoid after each substep (1e-6: float rounding of zeta at unit scale), nothing non-finite.
	CHECK(scene.report.minZeta >= 1.0 - 1e-6);
	CHECK(scene.report.nonFinite == 0);
}
