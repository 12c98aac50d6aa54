// Meshes far from the origin (mesh_io.cpp): assimp reads coordinates as 32-bit floats, so a mesh whose float spacing
// exceeds 1/64 of its typical edge (bounding-box diagonal / sqrt(faces)) loads with a warning and one beyond 1/4 is refused (vertices would merge).
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

#include <unistd.h>

#include <filesystem>

using namespace bodyfit;

namespace
{

/// male_young.4508v (typical edge 22.5 mm) moved `offset` metres along x, written as OBJ (9 significant digits:
/// 1 mm at 100 km, finer than the float spacing the test is about).
std::string movedBody(double offset)
{
	TriMesh m = loadTriMesh(bodyfit_test::assetPath("male_young.4508v.obj")).mesh;
	m.V.col(0).array() += offset;
	const std::filesystem::path dir =
		std::filesystem::temp_directory_path() / ("bodyfit_test_far_origin_" + std::to_string(::getpid()));
	std::filesystem::create_directories(dir);
	const std::string path = (dir / ("moved_" + std::to_string(long(offset)) + ".obj")).string();
	saveTriMesh(path, m);
	return path;
}

} // namespace

TEST_CASE("far origin: meshes whose float coordinates are coarse warn, coarser ones are refused", "[fitting][far_origin]")
{
	// 500 m: spacing 31 um < 22.5 mm / 64 = 0.35 mm: no warning, nothing merges.
	const LoadedMesh near = loadTriMesh(movedBody(500.0));
	CHECK(near.report.warnings.empty());
	CHECK(near.mesh.vertexCount() == 4508);
	// 5 km: spacing 0.49 mm > 0.35 mm: loads with a warning naming the distance and the spacing.
	const LoadedMesh far = loadTriMesh(movedBody(5000.0));
	REQUIRE(far.report.warnings.size() == 1);
	CHECK_THAT(far.report.warnings[0], Catch::Contains("32-bit floats") && Catch::Contains("0.000488 apart"));
	// 100 km: spacing 7.8 mm > 22.5 mm / 4: refused with a one-line reason.
	CHECK_THROWS_AS(loadTriMesh(movedBody(100000.0)), InvalidInputError);
	CHECK_THROWS_WITH(loadTriMesh(movedBody(100000.0)), Catch::Contains("vertices merge and faces collapse"));
	// The tests/data file of the bad-input catalogue (a 1 m tetrahedron 1e8 m away).
	CHECK_THROWS_WITH(loadTriMesh(bodyfit_test::dataPath("robust_far_origin.obj")), Catch::Contains("32-bit floats"));
}
