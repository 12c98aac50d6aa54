// The bad-input catalogue of docs/ROBUSTNESS.md (issue 7, item 3), fitting side: every file in tests/data used there
// gives exactly the documented behaviour, a typed exception with a one-line message naming the file and the
// problem, or the documented repair. (CLI exit codes: tests/robustness/cli_exit_codes.sh; scenes:
// tests/bullet_ext/test_robust_scene_inputs.cpp.)
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/mvee.h"
#include "bodyfit/fitting/segmentation.h"

#include "support/paths.h"

#include <catch2/catch.hpp>

#include <string>

namespace
{

using namespace bodyfit;
using bodyfit_test::dataPath;

/// The message is one line and names the file.
template <class Error, class F>
std::string oneLineError(F&& f, const std::string& file)
{
	try
	{
		f();
	}
	catch (const Error& e)
	{
		const std::string what = e.what();
		CHECK(what.find('\n') == std::string::npos);
		CHECK(what.find(file) != std::string::npos);
		return what;
	}
	FAIL("no " << typeid(Error).name() << " for " << file);
	return "";
}

std::string meshError(const std::string& file)
{
	return oneLineError<MeshLoadError>([&] { loadTriMesh(dataPath(file)); }, file);
}

std::string inputError(const std::string& file, const LoadOptions& options = {})
{
	return oneLineError<InvalidInputError>([&] { loadTriMesh(dataPath(file), options); }, file);
}

std::string jsonError(const std::string& file)
{
	return oneLineError<FormatError>([&] { readEllipsoidJson(dataPath(file)); }, file);
}

} // namespace

TEST_CASE("robust catalogue: unreadable mesh files are MeshLoadError naming the file", "[robust][inputs][mesh]")
{
	CHECK_THAT(meshError("robust_does_not_exist.obj"), Catch::EndsWith(": cannot open file: does not exist"));
	CHECK_THAT(meshError("empty.obj"), Catch::EndsWith(": file is empty"));
	// Truncated files: assimp either rejects them (the reason is appended) or reads nothing usable.
	CHECK_THAT(meshError("truncated.obj"), Catch::Contains("truncated.obj: "));
	CHECK_THAT(meshError("robust_truncated.ply"), Catch::Contains("robust_truncated.ply: "));
	CHECK_THAT(meshError("robust_truncated.glb"), Catch::Contains("robust_truncated.glb: "));
	CHECK_THAT(meshError("garbage.bin"), Catch::Contains("garbage.bin: "));
	// Found by fuzz_mesh_file: an ASCII PLY header with a non-ASCII byte inside "property" (assimp throws, and leaks
	// its partial scene: suppressed in fuzz/lsan.supp, ours is clean).
	CHECK_THAT(meshError("robust_fuzz_ply_bad_header.ply"), Catch::Contains("malformed PLY header, line 6"));
	// Found by fuzz_mesh_file: a garbled PLY header without end_header made assimp loop forever (a hang, not a crash).
	CHECK_THAT(meshError("robust_fuzz_ply_hang.ply"), Catch::Contains("malformed PLY header, line 5"));
	// Found by fuzz_mesh_file in the clean-clone CI run: magic "ply/" (assimp still reads it as PLY, then hangs).
	CHECK_THAT(meshError("robust_fuzz_ply_magic_hang.ply"), Catch::Contains("malformed PLY header, line 1"));
}

TEST_CASE("robust catalogue: a truncated ASCII PLY is rejected", "[robust][inputs][mesh]")
{
	// Two and a half vertex lines for a header of 4 vertices and 4 faces: either the reader fails (MeshLoadError),
	// or it yields no usable faces / too few points (InvalidInputError). Never a crash, never a silent success.
	bool rejected = false;
	try
	{
		loadTriMesh(dataPath("robust_truncated_ascii.ply"));
	}
	catch (const MeshLoadError& e)
	{
		rejected = std::string(e.what()).find("robust_truncated_ascii.ply") != std::string::npos;
	}
	catch (const InvalidInputError& e)
	{
		rejected = std::string(e.what()).find("robust_truncated_ascii.ply") != std::string::npos;
	}
	CHECK(rejected);
}

TEST_CASE("robust catalogue: unusable geometry is InvalidInputError naming the problem", "[robust][inputs][mesh]")
{
	CHECK_THAT(inputError("nan_vertex.obj"), Catch::Contains("non-finite coordinate"));
	CHECK_THAT(inputError("robust_inf_vertex.obj"), Catch::Contains("non-finite coordinate"));
	CHECK_THAT(inputError("single_triangle.obj"), Catch::Contains("fewer than 4 distinct points"));
	// Five copies of one point: welding leaves one vertex, every face is degenerate.
	const std::string identical = inputError("robust_identical.obj");
	CHECK((identical.find("degenerate") != std::string::npos || identical.find("fewer than 4") != std::string::npos));
	// One wild coordinate (a corrupt float in a binary file) stretches the box, and with it the weld and area
	// tolerances, until every face is degenerate: the error names that vertex, not only the symptom. A unit cube's 8
	// corners lie within 0.87 m of their median; the 9th vertex at 1e30 m is far beyond 1000x that.
	TriMesh wild;
	wild.V.resize(9, 3);
	for (int i = 0; i < 8; ++i)
		wild.V.row(i) << double(i & 1), double((i >> 1) & 1), double((i >> 2) & 1);
	wild.V.row(8) << 1e30, 0.5, 0.5;
	wild.F.resize(4, 3);
	wild.F << 0, 1, 3, 0, 3, 2, 4, 5, 8, 1, 5, 8;
	const std::string wildError =
		oneLineError<InvalidInputError>([&] { repairMesh(wild, LoadOptions(), "wild.obj"); }, "wild.obj");
	CHECK_THAT(wildError, Catch::Contains("wild.obj: vertex 8 at (1e+30") && Catch::Contains("corrupt coordinate"));
	LoadOptions badScale;
	badScale.scale = -1.0;
	CHECK_THAT(inputError("tetra.obj", badScale), Catch::Contains("scale must be a positive finite number"));
}

TEST_CASE("robust catalogue: non-manifold and self-intersecting meshes load unchanged", "[robust][inputs][mesh]")
{
	// Documented behaviour: no manifold repair is attempted (the fitter needs vertices and an edge graph, not a
	// manifold); every face is kept, the report counts components.
	const LoadedMesh nm = loadTriMesh(dataPath("robust_nonmanifold.obj"));
	CHECK(nm.full.faceCount() == 6);
	CHECK(nm.report.degenerateFaces == 0);
	CHECK(nm.report.components == 1); // the fin and the bow-tie triangle (sharing only vertex 4) are connected
	CHECK(nm.mesh.faceCount() == 6);
	const LoadedMesh si = loadTriMesh(dataPath("robust_self_intersecting.obj"));
	CHECK(si.report.components == 2);
	// The two pass through each other, so they are one body of two meshes (components.h): both are fitted.
	CHECK(si.report.attachedComponents == 1);
	CHECK(si.mesh.vertexCount() == 8);
	CHECK(si.full.vertexCount() == 8);
	CHECK(si.report.droppedComponentVertices == 0);
	REQUIRE(si.report.warnings.size() == 1);
	CHECK_THAT(si.report.warnings[0], Catch::Contains("several meshes"));
	// Both still give a finite enclosing MVEE.
	const EllipsoidFit fit = minimumVolumeEllipsoid(si.full.V);
	for (int i = 0; i < si.full.vertexCount(); ++i)
		CHECK(fit.ellipsoid.zeta(si.full.V.row(i).transpose()) <= 1 + 1e-9);
}

TEST_CASE("robust catalogue: millimetres and z-up are converted only when asked", "[robust][inputs][mesh]")
{
	// Never guessed: without --scale the millimetre tetrahedron is 1700 m tall; the report says scale 1.
	const LoadedMesh raw = loadTriMesh(dataPath("robust_millimetre.obj"));
	CHECK(raw.report.height == Approx(1700.0));
	CHECK(raw.report.scale == 1.0);
	LoadOptions mm;
	mm.scale = 0.001;
	const LoadedMesh m = loadTriMesh(dataPath("robust_millimetre.obj"), mm);
	CHECK(m.report.height == Approx(1.7).epsilon(1e-12)); // exact up to one rounding of the product
	CHECK(m.report.scale == 0.001);

	const LoadedMesh zRaw = loadTriMesh(dataPath("robust_zup.obj"));
	CHECK(zRaw.report.height == Approx(0.2));
	LoadOptions zUp;
	zUp.up = UpAxis::Z;
	const LoadedMesh z = loadTriMesh(dataPath("robust_zup.obj"), zUp);
	CHECK(z.report.height == Approx(1.7));
	CHECK(z.report.up == UpAxis::Z);
}

TEST_CASE("robust catalogue: a non-human mesh is not segmented and does not crash", "[robust][inputs][mesh]")
{
	// A sphere (icosphere of 642 vertices): segmentation reports failure with a reason and labels everything Whole;
	// the generic fitting path (one region) then applies (docs/DESIGN.md sec. 2).
	FittedEllipsoid sphere;
	sphere.ellipsoid.radii = Eigen::Vector3d(0.3, 0.3, 0.3);
	const TriMesh ball = ellipsoidMesh({sphere}, 3);
	const Segmentation s = segmentBody(ball);
	CHECK_FALSE(s.ok);
	CHECK_FALSE(s.failureReason.empty());
	CHECK(s.failureReason.find('\n') == std::string::npos);
	REQUIRE(s.labels.size() == std::size_t(ball.vertexCount()));
	for (Region r : s.labels)
		CHECK(r == Region::Whole);
}

TEST_CASE("robust catalogue: bad ellipsoid JSON is FormatError naming the field", "[robust][inputs][json]")
{
	CHECK_THAT(jsonError("robust_axes_negative.json"), Catch::Contains("ellipsoids[0].axes[1]: must be > 0 (got -0.12)"));
	CHECK_THAT(jsonError("robust_axes_zero.json"), Catch::Contains("ellipsoids[0].axes[2]: must be > 0 (got 0)"));
	CHECK_THAT(jsonError("robust_rotation_nonunit.json"),
			   Catch::Contains("ellipsoids[0].rotation: must be a unit quaternion"));
	CHECK_THAT(jsonError("robust_missing_axes.json"), Catch::Contains("ellipsoids[0].axes: missing"));
	CHECK_THAT(jsonError("robust_does_not_exist.json"), Catch::Contains("cannot open"));
	CHECK_THAT(jsonError("garbage.bin"), Catch::Contains("not valid JSON"));
	CHECK_THAT(jsonError("empty.obj"), Catch::Contains("not valid JSON"));
	// The valid one-ellipsoid file next to them parses.
	const BodyFit ok = readEllipsoidJson(dataPath("robust_valid_one.json"));
	CHECK(ok.ellipsoids.size() == 1);
}
