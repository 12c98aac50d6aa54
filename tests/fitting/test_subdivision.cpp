// Midpoint subdivision (subdivision.h): four triangles per triangle on the same surface, every edge halved, shared
// midpoints (a closed mesh stays closed), the orientation kept.
#include "bodyfit/fitting/subdivision.h"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include <map>
#include <utility>

using bodyfit::TriMesh;

namespace
{

TriMesh tetrahedron()
{
	TriMesh m;
	m.V.resize(4, 3);
	m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
	m.F.resize(4, 3);
	m.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3; // outward
	return m;
}

Eigen::Vector3d areaVector(const TriMesh& m, int f)
{
	const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
	return 0.5 * (b - a).cross(c - a);
}

} // namespace

TEST_CASE("midpoint subdivision keeps the surface and its orientation and halves every edge", "[subdivision]")
{
	const TriMesh m = tetrahedron();
	const TriMesh s = bodyfit::midpointSubdivide(m);
	// A closed mesh: V - E + F = 2 before (4 - 6 + 4) and after (10 - 24 + 16).
	REQUIRE(s.vertexCount() == 4 + 6);
	REQUIRE(s.faceCount() == 4 * 4);
	// The original vertices come first, unchanged.
	CHECK(s.V.topRows(4) == m.V);
	// Each parent's four children lie in its plane, point the same way and split its area in four equal parts
	// (exact midpoints: only the rounding of a few products, 1e-12 relative).
	for (int f = 0; f < m.faceCount(); ++f)
	{
		const Eigen::Vector3d parent = areaVector(m, f);
		for (int k = 0; k < 4; ++k)
		{
			const Eigen::Vector3d child = areaVector(s, 4 * f + k);
			CHECK((child - parent / 4).norm() <= 1e-12 * parent.norm());
		}
	}
	// Every edge is shared by exactly two faces, in opposite directions: no crack, no flipped face.
	std::map<std::pair<int, int>, int> directed;
	for (int f = 0; f < s.faceCount(); ++f)
		for (int k = 0; k < 3; ++k)
			++directed[{s.F(f, k), s.F(f, (k + 1) % 3)}];
	CHECK(directed.size() == 2 * 24);
	for (const auto& [edge, count] : directed)
	{
		CHECK(count == 1);
		CHECK(directed.count({edge.second, edge.first}) == 1);
	}
	// Deterministic: the same input gives the same mesh.
	const TriMesh again = bodyfit::midpointSubdivide(m);
	CHECK(again.V == s.V);
	CHECK(again.F == s.F);
	// An empty mesh stays empty.
	CHECK(bodyfit::midpointSubdivide(TriMesh{}).faceCount() == 0);
}
