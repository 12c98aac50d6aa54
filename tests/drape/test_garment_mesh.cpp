// Mesh garments (skirt, tights): garment.subdivide refines the loaded, scaled mesh without changing its surface.
#include "bodyfit/drape/garment.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

using namespace bodyfit::drape;

namespace
{

/// The longest edge, and the number of edges.
double longestEdge(const bodyfit::TriMesh& m, int* edges)
{
	std::set<std::pair<int, int>> seen;
	double longest = 0;
	for (int f = 0; f < m.faceCount(); ++f)
		for (int k = 0; k < 3; ++k)
		{
			const int a = m.F(f, k), b = m.F(f, (k + 1) % 3);
			if (seen.insert(std::minmax(a, b)).second)
				longest = std::max(longest, (m.V.row(a) - m.V.row(b)).norm());
		}
	*edges = int(seen.size());
	return longest;
}

} // namespace

TEST_CASE("garment.subdivide: 4x the faces, every edge halved, the same scaled surface", "[scene][garment]")
{
	GarmentSpec spec;
	spec.type = GarmentType::Skirt;
	spec.mesh = bodyfit_test::assetPath("female_young.skirt.obj");
	spec.scale = Eigen::Vector3d(1.1, 1.0, 1.1);
	const GarmentMesh coarse = buildGarmentMesh(spec);
	spec.subdivisions = 1;
	const GarmentMesh fine = buildGarmentMesh(spec);
	int coarseEdges = 0, fineEdges = 0;
	const double coarseLongest = longestEdge(coarse.mesh, &coarseEdges);
	const double fineLongest = longestEdge(fine.mesh, &fineEdges);
	REQUIRE(coarse.mesh.faceCount() > 0);
	CHECK(fine.mesh.faceCount() == 4 * coarse.mesh.faceCount());
	CHECK(fine.mesh.vertexCount() == coarse.mesh.vertexCount() + coarseEdges); // one new vertex per edge
	CHECK(fineEdges == 2 * coarseEdges + 3 * coarse.mesh.faceCount());
	// The scaled coarse vertices are kept as they are (subdivision after the scale), and the surface with them: the
	// same box. Every child edge is half of a parent edge (the halves of an edge, and the inner edges joining two
	// midpoints, parallel to the third side), so the longest halves, up to the rounding of a midpoint (1e-12).
	CHECK(fine.mesh.V.topRows(coarse.mesh.vertexCount()) == coarse.mesh.V);
	CHECK((fine.mesh.V.colwise().maxCoeff() - coarse.mesh.V.colwise().maxCoeff()).norm() == 0.0);
	CHECK((fine.mesh.V.colwise().minCoeff() - coarse.mesh.V.colwise().minCoeff()).norm() == 0.0);
	CHECK(std::abs(fineLongest - 0.5 * coarseLongest) <= 1e-12 * coarseLongest);
}
