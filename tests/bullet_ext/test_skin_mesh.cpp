// The skinned skin as a refitted triangle mesh (bodyfit/bullet_ext/btSkinMesh.h): the tree's closest point against
// brute force over every triangle, through poses that deform the mesh non-rigidly (the refit), the previous pose's
// point, the outward normals whatever the winding, and the refused inputs.
#include "bodyfit/bullet_ext/btSkinMesh.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

namespace
{

/// A closed UV sphere of radius r (poles as single vertices), triangles wound outwards (or inwards).
void uvSphere(int rings, int segments, btScalar r, bool inwards, std::vector<btVector3>& v, std::vector<int>& f)
{
	v.clear();
	f.clear();
	v.push_back(btVector3(0, r, 0));
	for (int i = 1; i < rings; ++i)
	{
		const double th = M_PI * i / rings;
		for (int j = 0; j < segments; ++j)
		{
			const double ph = 2 * M_PI * j / segments;
			v.push_back(btVector3(btScalar(r * std::sin(th) * std::cos(ph)), btScalar(r * std::cos(th)),
								  btScalar(r * std::sin(th) * std::sin(ph))));
		}
	}
	v.push_back(btVector3(0, -r, 0));
	const int south = int(v.size()) - 1;
	auto ring = [&](int i, int j) { return 1 + (i - 1) * segments + (j % segments); };
	auto tri = [&](int a, int b, int c) {
		f.push_back(a);
		f.push_back(inwards ? c : b);
		f.push_back(inwards ? b : c);
	};
	for (int j = 0; j < segments; ++j)
	{
		tri(0, ring(1, j + 1), ring(1, j));
		for (int i = 1; i + 1 < rings; ++i)
		{
			tri(ring(i, j), ring(i, j + 1), ring(i + 1, j));
			tri(ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
		}
		tri(south, ring(rings - 1, j), ring(rings - 1, j + 1));
	}
}

/// A non-rigid motion (a bend and a stretch that grow with the phase), as skinning makes at a joint.
btVector3 deform(const btVector3& p, double phase)
{
	const double a = 0.6 * phase * p.y() / 0.1; // rotation angle about z grows along y: a bend
	const double c = std::cos(a), s = std::sin(a);
	const double x = p.x() * (1.0 + 0.3 * phase), y = p.y();
	return btVector3(btScalar(c * x - s * y), btScalar(s * x + c * y), btScalar(p.z() * (1.0 - 0.2 * phase))) +
		   btVector3(btScalar(0.01 * phase), 0, 0);
}

/// Brute force: the smallest distance from p to any triangle of (v, f).
btScalar bruteDistance(const btVector3& p, const std::vector<btVector3>& v, const std::vector<int>& f)
{
	btScalar best = SIMD_INFINITY;
	for (std::size_t t = 0; t < f.size(); t += 3)
	{
		btScalar b[3];
		btClosestOnTriangle(p, v[std::size_t(f[t])], v[std::size_t(f[t + 1])], v[std::size_t(f[t + 2])], b);
		const btVector3 q = v[std::size_t(f[t])] * b[0] + v[std::size_t(f[t + 1])] * b[1] + v[std::size_t(f[t + 2])] * b[2];
		best = btMin(best, (p - q).length());
	}
	return best;
}

/// Appends a closed axis-aligned box [lo, hi] as 12 triangles wound outwards.
void box(const btVector3& lo, const btVector3& hi, std::vector<btVector3>& v, std::vector<int>& f)
{
	const int base = int(v.size());
	for (int i = 0; i < 8; ++i)
		v.push_back(btVector3((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(), (i & 4) ? hi.z() : lo.z()));
	// Each face as a quad (a, b, c, d) counter-clockwise seen from outside.
	const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
	for (const auto& q : quads)
		for (int k : {q[0], q[1], q[2], q[0], q[2], q[3]})
			f.push_back(base + k);
}

} // namespace

TEST_CASE("btClosestOnTriangle: corners, edges and the face", "[skin_mesh]")
{
	const btVector3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
	btScalar w[3];
	btClosestOnTriangle(btVector3(-1, -1, 0.5f), a, b, c, w);
	CHECK(w[0] == btScalar(1)); // corner a
	btClosestOnTriangle(btVector3(0.5f, -1, 0), a, b, c, w);
	CHECK(w[0] == Approx(0.5)); // edge ab, its midpoint
	CHECK(w[1] == Approx(0.5));
	btClosestOnTriangle(btVector3(1, 1, 0), a, b, c, w);
	CHECK(w[1] == Approx(0.5)); // edge bc
	CHECK(w[2] == Approx(0.5));
	btClosestOnTriangle(btVector3(0.25f, 0.25f, 3), a, b, c, w);
	CHECK(w[1] == Approx(0.25)); // face: the projection
	CHECK(w[2] == Approx(0.25));
}

TEST_CASE("btSkinMesh: the tree's closest point is brute force's through non-rigid poses", "[skin_mesh]")
{
	std::vector<btVector3> bind;
	std::vector<int> f;
	uvSphere(24, 32, btScalar(0.1), false, bind, f);
	btSkinMesh mesh;
	REQUIRE(mesh.setTopology(int(bind.size()), f.data(), int(f.size() / 3), bind.data()));
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> u(-0.14, 0.14);
	std::vector<btVector3> pose = bind, previous = bind;
	for (int k = 0; k <= 3; ++k)
	{
		if (k > 0)
		{
			previous = pose;
			btVector3* out = mesh.beginPose();
			for (std::size_t i = 0; i < bind.size(); ++i)
				out[i] = pose[i] = deform(bind[i], k / 3.0);
			mesh.endPose();
		}
		for (int s = 0; s < 300; ++s)
		{
			const btVector3 p(btScalar(u(rng)), btScalar(u(rng)), btScalar(u(rng)));
			const btScalar expected = bruteDistance(p, pose, f);
			btSkinMeshPoint near;
			const bool found = mesh.closestPoint(p, btScalar(0.03), near);
			// Within the radius the tree finds the same distance; the points differ only in rounding (coordinates of
			// 0.1 m: float rounding ~1e-8 m, so 1e-6 m is loose for both precisions).
			REQUIRE(found == (expected < btScalar(0.03)));
			if (!found)
				continue;
			CHECK(std::fabs(near.m_distance - expected) <= 1e-6);
			CHECK((near.m_point - p).length() == Approx(near.m_distance).margin(1e-6));
			// The previous point is the same barycentric point of the previous pose.
			const int t = near.m_triangle;
			const btVector3 prev = previous[std::size_t(f[3 * t])] * near.m_bary[0] +
								   previous[std::size_t(f[3 * t + 1])] * near.m_bary[1] +
								   previous[std::size_t(f[3 * t + 2])] * near.m_bary[2];
			CHECK((mesh.previousPoint(near) - prev).length() <= 1e-6);
		}
	}
	CHECK(mesh.getRevision() == 4);
}

TEST_CASE("btSkinMesh: normals point outwards whatever the winding", "[skin_mesh]")
{
	for (bool inwards : {false, true})
	{
		std::vector<btVector3> v;
		std::vector<int> f;
		uvSphere(12, 16, btScalar(0.1), inwards, v, f);
		btSkinMesh mesh;
		REQUIRE(mesh.setTopology(int(v.size()), f.data(), int(f.size() / 3), v.data()));
		for (int t = 0; t < mesh.getNumTriangles(); ++t)
		{
			const btVector3 centroid = (v[std::size_t(f[3 * t])] + v[std::size_t(f[3 * t + 1])] + v[std::size_t(f[3 * t + 2])]) / 3;
			// On a sphere the outward normal is within the facet's half-angle (< 15 degrees here) of the radial direction.
			CHECK(mesh.getNormal(t).dot(centroid.normalized()) > 0.95);
		}
	}
}

TEST_CASE("btSkinMesh: refused inputs leave it empty with a one-line reason", "[skin_mesh]")
{
	const btVector3 v[3] = {btVector3(0, 0, 0), btVector3(1, 0, 0), btVector3(0, 1, 0)};
	const int bad[3] = {0, 1, 3};
	btSkinMesh mesh;
	const char* why = 0;
	CHECK_FALSE(mesh.setTopology(3, bad, 1, v, &why));
	REQUIRE(why != 0);
	CHECK(std::string(why).find("index") != std::string::npos);
	CHECK_FALSE(mesh.setTopology(3, bad, 0, v, &why));
	btSkinMeshPoint near;
	CHECK_FALSE(mesh.closestPoint(btVector3(0, 0, 0), 1, near));
	CHECK(near.m_triangle == -1);
}

TEST_CASE("btSkinMesh: the signed distance does not trust the nearest sheet inside another part", "[skin_mesh]")
{
	// In small, the walk's node inside the body (2026-12-04, walk tights, step 125): a "hip" box and an "arm" box
	// pressed 1 mm into it, as skinning leaves them; p is 2.1 mm outside the hip's face, 3.1 mm inside the arm's
	// inner face, so inside the arm. The nearest sheet (the hip's face) alone says outside.
	const btScalar hipFace = btScalar(0.1);
	const btVector3 p(hipFace + btScalar(0.0021), 0, 0);
	for (btScalar armFace : {btScalar(0.099), btScalar(0.105)})
	{
		std::vector<btVector3> v;
		std::vector<int> f;
		box(btVector3(-0.1, -0.1, -0.1), btVector3(hipFace, 0.1, 0.1), v, f);
		box(btVector3(armFace, -0.05, -0.05), btVector3(0.16, 0.05, 0.05), v, f);
		btSkinMesh mesh;
		REQUIRE(mesh.setTopology(int(v.size()), f.data(), int(f.size() / 3), v.data()));
		btSkinMeshPoint near;
		btScalar side = 0;
		const bool trusted = mesh.signedDistance(p, btScalar(0.03), near, side);
		REQUIRE(near.m_triangle >= 0);
		CHECK(near.m_distance == Approx(0.0021).margin(1e-6)); // (float coordinates near 0.1 m: ~1e-8 m rounding)
		if (armFace < hipFace)
			CHECK_FALSE((trusted && side > 0)); // inside the arm: never outside (untrusted is the union's case)
		else
		{
			// The arm 5 mm away: p lies between two sheets that both see it outside, so the sign stands.
			CHECK(trusted);
			CHECK(side == Approx(0.0021).margin(1e-6));
		}
	}
}
