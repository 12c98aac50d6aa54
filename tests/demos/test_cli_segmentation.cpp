// bodyfit-fit and segmentation: regions by default, --segments preview, --no-segmentation, and the fallback with a
// warning (exit 0) for a mesh that is not a standing human. Runs the built executable.

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/segmentation.h"
#include "support/mesh_shapes.h"
#include "support/paths.h"
#include "support/run_program.h"

#include <catch2/catch.hpp>



#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace
{

namespace fs = std::filesystem;

using bodyfit_test::quoted;
using bodyfit_test::readFile;

fs::path scratch()
{
	return bodyfit_test::scratchDir("bodyfit_test_cli_segmentation");
}

bodyfit_test::ProgramRun run(const std::string& args)
{
	return bodyfit_test::runProgram(BODYFIT_FIT_EXE, args);
}

std::set<std::string> regionsOf(const bodyfit::BodyFit& fit)
{
	std::set<std::string> names;
	for (const bodyfit::FittedEllipsoid& e : fit.ellipsoids)
		names.insert(bodyfit::regionName(e.region));
	return names;
}

} // namespace

TEST_CASE("cli segmentation: a body is fitted per region and the preview is written", "[fitting][cli][segmentation]")
{
	const std::string json = (scratch() / "body.json").string();
	const std::string ply = (scratch() / "body_segments.ply").string();
	const bodyfit_test::ProgramRun r = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
					  " --max-ellipsoids 60 --segments " + quoted(ply));
	CAPTURE(r.out, r.err);
	REQUIRE(r.exitCode == 0);
	CHECK(r.err.empty());
	CHECK(r.out.find("15 body regions") != std::string::npos);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	// Every one of the 15 regions has at least one ellipsoid (the torso group starts with its 6 parts), and no
	// ellipsoid is labelled "whole".
	const std::set<std::string> names = regionsOf(fit);
	CHECK(names.size() == size_t(bodyfit::kBodyRegionCount));
	CHECK(names.count("whole") == 0);
	CHECK(fit.timingMs("segmentation") > 0.0);

	// The preview: the body's vertices plus an octahedron (6 vertices) per feature point (13 of them).
	const bodyfit::TriMesh preview = bodyfit::loadTriMesh(ply).full; // the markers are separate components
	CHECK(preview.vertexCount() == 4508 + 6 * 13);
	CHECK(readFile(ply).find("property uchar red") != std::string::npos);
}

TEST_CASE("cli segmentation: --no-segmentation keeps the generic path", "[fitting][cli][segmentation]")
{
	const std::string json = (scratch() / "generic.json").string();
	const bodyfit_test::ProgramRun r = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
					  " --max-ellipsoids 20 --no-segmentation");
	CAPTURE(r.err);
	REQUIRE(r.exitCode == 0);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	CHECK(regionsOf(fit) == std::set<std::string>{"whole"});
	CHECK(fit.timingMs("segmentation") == 0.0);

	const bodyfit_test::ProgramRun bad = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
						" --no-segmentation --segments " + quoted((scratch() / "x.ply").string()));
	CHECK(bad.exitCode == 2);
	CHECK(bad.err.find("--segments needs the segmentation") != std::string::npos);
	CHECK(run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) + " --segments x.stl")
			  .exitCode == 2);
}

TEST_CASE("cli segmentation: a non-human mesh falls back with a warning and exit 0", "[fitting][cli][segmentation]")
{
	const std::string mesh = (scratch() / "sphere.obj").string();
	bodyfit::saveTriMesh(mesh, bodyfit_test::uvSphere(0.3, 32, 16));
	const std::string json = (scratch() / "sphere.json").string();
	const std::string ply = (scratch() / "sphere_segments.ply").string();
	const bodyfit_test::ProgramRun r = run(quoted(mesh) + " -o " + quoted(json) + " --segments " + quoted(ply));
	CAPTURE(r.out, r.err);
	REQUIRE(r.exitCode == 0);
	CHECK(r.err.rfind("bodyfit-fit: warning: segmentation failed (not a standing human: ", 0) == 0);
	CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	CHECK(regionsOf(fit) == std::set<std::string>{"whole"});
	REQUIRE_FALSE(fit.warnings.empty());
	CHECK(fit.warnings.front().find("segmentation failed") != std::string::npos);
	CHECK(fs::file_size(ply) > 0); // the preview is written all grey, so a person can see what was found
}


TEST_CASE("cli segmentation: a body of several meshes is fitted whole, a prop is ignored with a warning",
	"[fitting][cli][segmentation][components]")
{
	// male_young.4508v with the head (everything 0.2 m below the top and up) as a separate mesh 3 mm above the
	// neck, and a 20 cm box 1.5 m to the side: a game asset with a prop.
	const bodyfit::TriMesh body = bodyfit::loadTriMesh(bodyfit_test::assetPath("male_young.4508v.obj")).mesh;
	const double neck = body.V.col(1).maxCoeff() - 0.2;
	const bodyfit::TriMesh split = bodyfit_test::detached(
		body,
		[&](int f) { return std::min({body.V(body.F(f, 0), 1), body.V(body.F(f, 1), 1), body.V(body.F(f, 2), 1)}) > neck; },
		Eigen::Vector3d(0, 0.003, 0));
	bodyfit::TriMesh prop = bodyfit_test::subdividedCube(0.2, 4);
	prop.V.rowwise() += Eigen::RowVector3d(1.5, 0.0, 0.0);
	const std::string mesh = (scratch() / "game_asset.obj").string();
	bodyfit::saveTriMesh(mesh, bodyfit_test::appended(split, prop));
	const std::string json = (scratch() / "game_asset.json").string();
	const bodyfit_test::ProgramRun r = run(quoted(mesh) + " -o " + quoted(json) + " --max-ellipsoids 60");
	CAPTURE(r.out, r.err);
	REQUIRE(r.exitCode == 0);
	CHECK(r.out.find("15 body regions") != std::string::npos);
	// Two warnings (joined parts, ignored prop), on stderr and in the fit file. The plane cut may leave more than one
	// piece above it (measured: 2); every piece is joined.
	CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 2);
	CHECK(r.err.find("bodyfit-fit: warning: the body is made of several meshes: ") != std::string::npos);
	CHECK(r.err.find("bodyfit-fit: warning: 1 detached component (" + std::to_string(prop.vertexCount()) +
					 " vertices)") != std::string::npos);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	REQUIRE(fit.warnings.size() >= 2);
	CHECK(fit.warnings[0].find("several meshes") != std::string::npos);
	CHECK(fit.warnings[1].find("detached component") != std::string::npos);
	// The head is fitted (it has ellipsoids) and every vertex of the body and the head is inside the union
	// (zeta <= 1 + 1e-6: the MVEE guarantee of 1e-9 plus the 9 significant digits of the JSON numbers).
	CHECK(regionsOf(fit).count("head") == 1);
	for (int v = 0; v < split.vertexCount(); ++v)
	{
		double best = 1e300;
		for (const bodyfit::FittedEllipsoid& e : fit.ellipsoids)
			best = std::min(best, e.ellipsoid.zeta(split.V.row(v).transpose()));
		CHECK(best <= 1.0 + 1e-6);
	}
}
