// bodyfit-fit and segmentation: regions by default, --segments preview, --no-segmentation, and the fallback with a
// warning (exit 0) for a mesh that is not a standing human. Runs the built executable.

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/segmentation.h"
#include "support/mesh_shapes.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

#include <unistd.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace
{

namespace fs = std::filesystem;

struct Run
{
	int status = -1;
	std::string out, err;
};

fs::path scratch()
{
	// One directory per process: ctest runs the test cases of this file in parallel processes.
	const fs::path dir = fs::temp_directory_path() / ("bodyfit_test_cli_segmentation_" + std::to_string(::getpid()));
	fs::create_directories(dir);
	return dir;
}

std::string slurp(const fs::path& p)
{
	std::ifstream in(p);
	std::ostringstream s;
	s << in.rdbuf();
	return s.str();
}

std::string quoted(const std::string& s) { return "\"" + s + "\""; }

Run run(const std::string& args)
{
	const fs::path out = scratch() / "stdout.txt", err = scratch() / "stderr.txt";
	const std::string cmd = quoted(BODYFIT_FIT_EXE) + " " + args + " > " + quoted(out.string()) + " 2> " +
							quoted(err.string());
	const int rc = std::system(cmd.c_str());
	Run r;
	r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
	r.out = slurp(out);
	r.err = slurp(err);
	return r;
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
	const Run r = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
					  " --max-ellipsoids 60 --segments " + quoted(ply));
	CAPTURE(r.out, r.err);
	REQUIRE(r.status == 0);
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
	CHECK(slurp(ply).find("property uchar red") != std::string::npos);
}

TEST_CASE("cli segmentation: --no-segmentation keeps the generic path", "[fitting][cli][segmentation]")
{
	const std::string json = (scratch() / "generic.json").string();
	const Run r = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
					  " --max-ellipsoids 20 --no-segmentation");
	CAPTURE(r.err);
	REQUIRE(r.status == 0);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	CHECK(regionsOf(fit) == std::set<std::string>{"whole"});
	CHECK(fit.timingMs("segmentation") == 0.0);

	const Run bad = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
						" --no-segmentation --segments " + quoted((scratch() / "x.ply").string()));
	CHECK(bad.status == 2);
	CHECK(bad.err.find("--segments needs the segmentation") != std::string::npos);
	CHECK(run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) + " --segments x.stl")
			  .status == 2);
}

TEST_CASE("cli segmentation: a non-human mesh falls back with a warning and exit 0", "[fitting][cli][segmentation]")
{
	const std::string mesh = (scratch() / "sphere.obj").string();
	bodyfit::saveTriMesh(mesh, bodyfit_test::uvSphere(0.3, 32, 16));
	const std::string json = (scratch() / "sphere.json").string();
	const std::string ply = (scratch() / "sphere_segments.ply").string();
	const Run r = run(quoted(mesh) + " -o " + quoted(json) + " --segments " + quoted(ply));
	CAPTURE(r.out, r.err);
	REQUIRE(r.status == 0);
	CHECK(r.err.rfind("bodyfit-fit: warning: segmentation failed (not a standing human: ", 0) == 0);
	CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	CHECK(regionsOf(fit) == std::set<std::string>{"whole"});
	REQUIRE_FALSE(fit.warnings.empty());
	CHECK(fit.warnings.front().find("segmentation failed") != std::string::npos);
	CHECK(fs::file_size(ply) > 0); // the preview is written all grey, so a person can see what was found
}

