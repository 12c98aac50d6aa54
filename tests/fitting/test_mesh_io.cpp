// Mesh input: every documented bad input gives its typed error; repairs and conversions are applied.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

using namespace bodyfit;
using bodyfit_test::assetPath;
using bodyfit_test::dataPath;

TEST_CASE("mesh_io: bad files raise MeshLoadError or InvalidInputError with the path", "[fitting][mesh_io]")
{
	SECTION("missing file")
	{
		REQUIRE_THROWS_AS(loadTriMesh(dataPath("does_not_exist.obj")), MeshLoadError);
		REQUIRE_THROWS_WITH(loadTriMesh(dataPath("does_not_exist.obj")), Catch::Contains("does_not_exist.obj"));
	}
	SECTION("empty file") { REQUIRE_THROWS_WITH(loadTriMesh(dataPath("empty.obj")), Catch::Contains("empty")); }
	SECTION("truncated OBJ (vertices, no faces)") { REQUIRE_THROWS_AS(loadTriMesh(dataPath("truncated.obj")), MeshLoadError); }
	SECTION("binary garbage") { REQUIRE_THROWS_AS(loadTriMesh(dataPath("garbage.bin")), MeshLoadError); }
	SECTION("NaN coordinate")
	{
		REQUIRE_THROWS_AS(loadTriMesh(dataPath("nan_vertex.obj")), InvalidInputError);
		REQUIRE_THROWS_WITH(loadTriMesh(dataPath("nan_vertex.obj")), Catch::Contains("non-finite"));
	}
	SECTION("a single triangle has fewer than 4 distinct points")
	{
		REQUIRE_THROWS_WITH(loadTriMesh(dataPath("single_triangle.obj")), Catch::Contains("fewer than 4"));
	}
}

TEST_CASE("mesh_io: quads are triangulated and duplicates welded", "[fitting][mesh_io]")
{
	const LoadedMesh m = loadTriMesh(dataPath("cube_quads.obj"));
	CHECK(m.mesh.vertexCount() == 8);
	CHECK(m.mesh.faceCount() == 12);
	CHECK(m.report.components == 1);

	// Duplicate every vertex: welding must restore the 8 corners and keep all 12 faces.
	TriMesh doubled;
	doubled.V.resize(16, 3);
	doubled.V << m.mesh.V, m.mesh.V;
	doubled.F = m.mesh.F;
	doubled.F.topRows(6).array() += 8; // half the faces use the copies
	const LoadedMesh w = repairMesh(doubled);
	CHECK(w.report.weldedVertices == 8);
	CHECK(w.mesh.vertexCount() == 8);
	CHECK(w.mesh.faceCount() == 12);
}

TEST_CASE("mesh_io: unit scale and z-up conversion are explicit", "[fitting][mesh_io]")
{
	LoadOptions opt;
	opt.scale = 0.01;
	opt.up = UpAxis::Z;
	const LoadedMesh m = loadTriMesh(dataPath("tetra.obj"), opt);
	// tetra.obj spans 1 unit on each axis: scaled to 1 cm, and its +z extent becomes the +y extent.
	CHECK(m.report.height == Approx(0.01).epsilon(1e-12));
	CHECK(m.mesh.V.col(2).minCoeff() == Approx(-0.01).epsilon(1e-12));
}

TEST_CASE("mesh_io: the bundled body loads as one closed component of 13,380 vertices", "[fitting][mesh_io]")
{
	const LoadedMesh m = loadTriMesh(assetPath("male_young.obj"));
	CHECK(m.mesh.vertexCount() == 13380);
	CHECK(m.report.components == 1);
	// 1.75 m adult (data/README.md); 1 cm covers the head-top/sole vertices vs the nominal stature.
	CHECK(m.report.height == Approx(1.75).margin(0.01));
}

TEST_CASE("mesh_io: components are ordered by size, deterministically", "[fitting][mesh_io]")
{
	const LoadedMesh cube = loadTriMesh(dataPath("cube_quads.obj"));
	TriMesh two;
	two.V.resize(12, 3);
	two.V.topRows(8) = cube.mesh.V;
	two.V.bottomRows(4) << 5, 0, 0, 6, 0, 0, 5, 1, 0, 5, 0, 1;
	two.F.resize(16, 3);
	two.F.topRows(12) = cube.mesh.F;
	two.F.bottomRows(4) << 8, 9, 10, 8, 9, 11, 8, 10, 11, 9, 10, 11;
	int count = 0;
	const std::vector<int> id = connectedComponents(two, &count);
	CHECK(count == 2);
	CHECK(id[0] == 0);
	CHECK(id[8] == 1);
	const LoadedMesh r = repairMesh(two);
	CHECK(r.mesh.vertexCount() == 8);
	CHECK(r.report.droppedComponentVertices == 4);
}
