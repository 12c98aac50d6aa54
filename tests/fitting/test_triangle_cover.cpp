// TriangleCover (triangle_cover.h): the pieces of the triangles across cluster boundaries, the check against the
// ellipsoids (same answer as checking every piece against every ellipsoid), the handouts, re-checks, threads.
#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/triangle_cover.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

using namespace bodyfit;

namespace
{

constexpr double kInside = 1.0 + 1e-9; // the enclosure rule of triangle_cover.h

Ellipsoid sphere(const Eigen::Vector3d& centre, double radius)
{
	Ellipsoid e;
	e.center = centre;
	e.radii.setConstant(radius);
	return e;
}

/// A unit square in the z = 0 plane, split along its diagonal; vertices 0, 1 in cluster 0, vertices 2, 3 in 1.
TriMesh square()
{
	TriMesh m;
	m.V.resize(4, 3);
	m.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
	m.F.resize(2, 3);
	m.F << 0, 1, 2, 0, 2, 3;
	return m;
}

/// Every piece of the mixed triangles as three corners, cut as the cover cuts (coverCutLevel), in cover order.
std::vector<std::array<Eigen::Vector3d, 3>> bruteForcePieces(const TriMesh& mesh, const std::vector<int>& owner,
															 double spacing)
{
	std::vector<std::array<Eigen::Vector3d, 3>> pieces;
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		const int c0 = owner[std::size_t(mesh.F(f, 0))], c1 = owner[std::size_t(mesh.F(f, 1))],
				  c2 = owner[std::size_t(mesh.F(f, 2))];
		if (c0 == c1 && c1 == c2)
			continue;
		const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), d = mesh.V.row(mesh.F(f, 2));
		const int level = coverCutLevel(a, b, d, spacing);
		auto at = [&](int i, int j) {
			return Eigen::Vector3d((double(i) * a + double(j) * b + double(level - i - j) * d) / double(level));
		};
		for (int i = 0; i < level; ++i)
			for (int j = 0; i + j < level; ++j)
			{
				pieces.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
				if (i + j + 2 <= level)
					pieces.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
			}
	}
	return pieces;
}

bool insideOne(const std::array<Eigen::Vector3d, 3>& piece, const std::vector<Ellipsoid>& ellipsoids)
{
	for (const Ellipsoid& e : ellipsoids)
	{
		const Eigen::AlignedBox3d box = e.aabb();
		bool all = true;
		for (const Eigen::Vector3d& p : piece)
			all = all && box.contains(p) && e.zeta(p) <= kInside;
		if (all)
			return true;
	}
	return false;
}

} // namespace

TEST_CASE("triangle_cover: pieces of the mixed triangles only, cut by coverCutLevel", "[fitting][triangle_cover]")
{
	const TriMesh m = square();
	// Longest edge sqrt(2): spacing 0.5 cuts each edge 3 times, 9 pieces per triangle.
	const TriangleCover cover(m, {0, 0, 1, 1}, 0.5);
	CHECK(cover.triangleCount() == 2);
	CHECK(cover.pieceCount() == 18);
	// A triangle whose corners share one cluster is inside that cluster's ellipsoid already: no pieces.
	const TriangleCover one(m, {0, 0, 0, 1}, 0.5);
	CHECK(one.triangleCount() == 1);
	const TriangleCover none(m, {0, 0, 0, 0}, 0.5);
	CHECK(none.pieceCount() == 0);
	// An unfitted corner (-1) skips its triangles.
	const TriangleCover unfitted(m, {0, -1, 1, 1}, 0.5);
	CHECK(unfitted.triangleCount() == 1);
}

TEST_CASE("triangle_cover: handouts go to the closest corner cluster, re-checks see the refit", "[fitting][triangle_cover]")
{
	const TriMesh m = square();
	TriangleCover cover(m, {0, 0, 1, 1}, 0.5);
	// Cluster 0 around the bottom edge (y = 0), cluster 1 around the top one (y = 1), both too small for the middle.
	std::vector<Ellipsoid> ellipsoids = {sphere({0.5, 0.0, 0.0}, 0.6), sphere({0.5, 1.0, 0.0}, 0.6)};
	std::vector<TriangleCover::Handout> handouts;
	std::vector<char> targeted;
	const int uncovered = cover.check(ellipsoids, {0, 0}, handouts, targeted);
	const auto pieces = bruteForcePieces(m, {0, 0, 1, 1}, 0.5);
	int expected = 0;
	for (const auto& piece : pieces)
		expected += insideOne(piece, ellipsoids) ? 0 : 1;
	REQUIRE(expected > 0); // the configuration leaves pieces out, so the handouts below are exercised
	CHECK(uncovered == expected);
	REQUIRE(!handouts.empty());
	for (const TriangleCover::Handout& h : handouts)
	{
		// Every handed-out corner lies outside the ellipsoid of the cluster it goes to, and that cluster is flagged.
		const Ellipsoid& target = ellipsoids[std::size_t(h.cluster)];
		CHECK(target.zeta(h.point) > kInside);
		CHECK(targeted[std::size_t(h.cluster)] == 1);
	}
	// Cluster 0 "refitted" to enclose the whole square: the uncovered pieces are checked again and are inside now.
	ellipsoids[0] = sphere({0.5, 0.5, 0.0}, 0.8);
	handouts.clear();
	CHECK(cover.check(ellipsoids, {1, 0}, handouts, targeted) == 0);
	CHECK(handouts.empty());
	CHECK(targeted == std::vector<char>{0, 0});
}

TEST_CASE("triangle_cover: same verdicts as every piece against every ellipsoid, for any thread count",
		  "[fitting][triangle_cover][threads]")
{
	const TriMesh mesh = loadTriMesh(bodyfit_test::assetPath("male_young.4508v.obj")).mesh;
	// Eight clusters in height bands, each with a sphere around its band: the band boundaries cut many triangles,
	// and the spheres leave some of their pieces outside (also of the spheres of other bands: the grid candidates).
	const double y0 = mesh.V.col(1).minCoeff(), h = mesh.V.col(1).maxCoeff() - y0;
	std::vector<int> owner(std::size_t(mesh.vertexCount()));
	std::vector<Eigen::Vector3d> sum(8, Eigen::Vector3d::Zero());
	std::vector<int> count(8, 0);
	for (int v = 0; v < mesh.vertexCount(); ++v)
	{
		const int band = std::min(7, int((mesh.V(v, 1) - y0) / h * 8.0));
		owner[std::size_t(v)] = band;
		sum[std::size_t(band)] += mesh.V.row(v).transpose();
		++count[std::size_t(band)];
	}
	std::vector<Ellipsoid> ellipsoids;
	for (int b = 0; b < 8; ++b)
		ellipsoids.push_back(sphere(sum[std::size_t(b)] / std::max(1, count[std::size_t(b)]), 0.17 * h));
	const double spacing = 0.01;
	const auto pieces = bruteForcePieces(mesh, owner, spacing);
	int expected = 0;
	for (const auto& piece : pieces)
		expected += insideOne(piece, ellipsoids) ? 0 : 1;
	REQUIRE(expected > 0);
	REQUIRE(expected < int(pieces.size())); // some covered, some not

	std::vector<TriangleCover::Handout> first;
	std::vector<char> targeted;
	for (const int threads : {1, 2, 3})
	{
		TriangleCover cover(mesh, owner, spacing);
		REQUIRE(cover.pieceCount() == int(pieces.size()));
		std::vector<TriangleCover::Handout> handouts;
		CHECK(cover.check(ellipsoids, std::vector<char>(8, 0), handouts, targeted, threads) == expected);
		if (threads == 1)
		{
			first = handouts;
			continue;
		}
		// The handouts are merged in piece order: the same list, point for point, whatever the thread count.
		REQUIRE(handouts.size() == first.size());
		for (std::size_t i = 0; i < handouts.size(); ++i)
		{
			CHECK(handouts[i].cluster == first[i].cluster);
			CHECK(handouts[i].point == first[i].point);
		}
	}
}
