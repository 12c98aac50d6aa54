// bodyfit-fit command line: exit codes (0 ok, 2 bad input) and one-line errors, run on the built executable.

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/skin_field.h"
#include "bodyfit/fitting/skinned_fit.h"
#include "support/paths.h"
#include "support/run_program.h"

#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>


#include <cstdio>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace
{

namespace fs = std::filesystem;

using bodyfit_test::quoted;
using bodyfit_test::readFile;

fs::path scratch()
{
	return bodyfit_test::scratchDir("bodyfit_test_cli");
}

/// Runs bodyfit-fit with `args` (already shell-quoted where needed) and captures exit status, stdout, stderr.
bodyfit_test::ProgramRun run(const std::string& args)
{
	return bodyfit_test::runProgram(BODYFIT_FIT_EXE, args);
}

/// Bad input: exit 2, nothing on stdout, exactly one stderr line "bodyfit-fit: error: ..." containing `needle`.
void checkBadInput(const std::string& args, const std::string& needle)
{
	const bodyfit_test::ProgramRun r = run(args);
	CAPTURE(args, r.err);
	CHECK(r.exitCode == 2);
	CHECK(r.out.empty());
	CHECK(r.err.rfind("bodyfit-fit: error: ", 0) == 0);
	CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
	CHECK(r.err.find(needle) != std::string::npos);
}

} // namespace

TEST_CASE("cli: --help prints the usage and exits 0", "[fitting][cli]")
{
	const bodyfit_test::ProgramRun r = run("--help");
	CHECK(r.exitCode == 0);
	CHECK(r.out.find("usage: bodyfit-fit MESH -o OUT.json") != std::string::npos);
	CHECK(r.out.find("--max-ellipsoids") != std::string::npos);
	CHECK(r.err.empty());
}

TEST_CASE("cli: bad arguments and bad files exit 2 with a one-line reason", "[fitting][cli]")
{
	const std::string body = quoted(bodyfit_test::assetPath("male_young.4508v.obj"));
	const std::string out = " -o " + quoted((scratch() / "bad.json").string());
	checkBadInput("", "missing MESH");
	checkBadInput(body, "missing -o");
	checkBadInput(body + out + " --frobnicate", "unknown option --frobnicate");
	checkBadInput(body + out + " --mu-torso abc", "--mu-torso: expected a number");
	checkBadInput(body + out + " --mu-torso -0.1", "--mu-torso: -0.1 is out of range");
	checkBadInput(body + out + " --mu-limbs 0", "--mu-limbs: 0 is out of range");
	checkBadInput(body + out + " --max-ellipsoids 0", "--max-ellipsoids: 0 is out of range");
	checkBadInput(body + out + " --max-ellipsoids 2.5", "--max-ellipsoids: expected an integer");
	checkBadInput(body + out + " --up x", "--up: expected y|z");
	checkBadInput(body + out + " --scale 0", "--scale: 0 is out of range");
	checkBadInput(body + out + " --scale", "--scale needs a value");
	checkBadInput(body + out + " --absolute --absolute", "--absolute given more than once");
	checkBadInput(body + out + " --export-mesh x.stl", "must end in .obj or .ply");
	checkBadInput(body + " extra.obj" + out, "unexpected argument");
	checkBadInput(body + out + " --skin-voxel 0", "--skin-voxel: 0 is out of range");
	checkBadInput(body + out + " --skin-voxel 0.2", "--skin-voxel: 0.2 is out of range");
	checkBadInput(body + out + " --skin-clamp x", "--skin-clamp: expected a number");
	checkBadInput(body + out + " --skin-voxel 0.01 --skin-clamp 0.015", "less than 2 voxels");
	checkBadInput(body + out + " --no-skin-field --skin-clamp 0.02", "drop --no-skin-field");
	checkBadInput(quoted(bodyfit_test::dataPath("does_not_exist.obj")) + out, "does_not_exist.obj");
	checkBadInput(quoted(bodyfit_test::dataPath("garbage.bin")) + out, "garbage.bin");
	checkBadInput(quoted(bodyfit_test::dataPath("nan_vertex.obj")) + out, "non-finite");
	checkBadInput(quoted(bodyfit_test::dataPath("empty.obj")) + out, "empty");
	// An output directory that cannot be created (its parent is a regular file).
	std::ofstream(scratch() / "a_file") << "x";
	checkBadInput(body + " -o " + quoted((scratch() / "a_file" / "sub" / "fit.json").string()), "-o: cannot write");
}

TEST_CASE("cli: a fit writes readable JSON and the ellipsoid mesh, creating the directory", "[fitting][cli]")
{
	const fs::path dir = scratch() / "nested" / "out";
	fs::remove_all(scratch() / "nested");
	const std::string json = (dir / "fit.json").string();
	const std::string ply = (dir / "fit.ply").string();
	const std::string args = quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json) +
							 " --max-ellipsoids 40 --export-mesh " + quoted(ply);
	const bodyfit_test::ProgramRun r = run(args);
	CAPTURE(r.err);
	REQUIRE(r.exitCode == 0);
	CHECK(r.out.find("ellipsoids") != std::string::npos);
	CHECK(r.out.find("air gap") != std::string::npos);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	CHECK(fit.ellipsoids.size() >= 1);
	CHECK(fit.ellipsoids.size() <= 40);
	CHECK(fit.source.mesh == "male_young.4508v.obj");
	CHECK(fit.source.vertices == 4508);
	CHECK(fit.timingMs("load") > 0.0);
	CHECK(fs::file_size(ply) > 0);
	// The skin field is baked by default, written next to the fit, reported, and read back with it.
	REQUIRE(fit.skinField);
	CHECK(fit.skinFieldFile == "fit.skin");
	CHECK(fs::exists(dir / "fit.skin"));
	CHECK(fit.timingMs("skin_field") > 0.0);
	CHECK(r.out.find("skin      field in") != std::string::npos);
	CHECK(fit.skinField->voxel == 0.005);

	// Same input, same options: the same ellipsoids (the timings differ).
	const std::string json2 = (dir / "fit2.json").string();
	REQUIRE(run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json2) +
				" --max-ellipsoids 40")
				.exitCode == 0);
	CHECK(nlohmann::json::parse(readFile(json))["ellipsoids"] == nlohmann::json::parse(readFile(json2))["ellipsoids"]);

	// --absolute: thresholds in metres are recorded as such.
	const std::string json3 = (dir / "fit3.json").string();
	REQUIRE(run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json3) +
				" --absolute --mu-torso 0.03 --mu-limbs 0.02")
				.exitCode == 0);
	const bodyfit::BodyFit abs = bodyfit::readEllipsoidJson(json3);
	CHECK_FALSE(abs.params.relativeToHeight);
	CHECK(abs.params.muTorso == 0.03);

	// --no-skin-field: no side file, no section; --skin-voxel / --skin-clamp reach the bake.
	const std::string json4 = (dir / "fit4.json").string();
	const bodyfit_test::ProgramRun none = run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json4) + " --no-skin-field");
	REQUIRE(none.exitCode == 0);
	CHECK(none.out.find("no skin field (--no-skin-field)") != std::string::npos);
	CHECK_FALSE(fs::exists(dir / "fit4.skin"));
	CHECK_FALSE(bodyfit::readEllipsoidJson(json4).skinField);
	const std::string json5 = (dir / "fit5.json").string();
	REQUIRE(run(quoted(bodyfit_test::assetPath("male_young.4508v.obj")) + " -o " + quoted(json5) +
				" --skin-voxel 0.008 --skin-clamp 0.02")
				.exitCode == 0);
	const bodyfit::BodyFit coarse = bodyfit::readEllipsoidJson(json5);
	REQUIRE(coarse.skinField);
	CHECK(coarse.skinField->voxel == 0.008);
	CHECK(coarse.skinField->clamp == 0.02);
}


namespace
{

/// The count in the summary line "cover     skin between ellipsoids inside the union: N extra points ...", or -1.
long coverPoints(const std::string& stdoutText)
{
	const std::string key = "inside the union: ";
	const std::size_t at = stdoutText.find(key);
	return at == std::string::npos ? -1 : std::stol(stdoutText.substr(at + key.size()));
}

std::string exact(double v)
{
	char buf[40];
	std::snprintf(buf, sizeof buf, "%.17g", v); // round-trips the double exactly
	return buf;
}

} // namespace

TEST_CASE("cli: --absolute with the relative thresholds times H gives the same fit and cover", "[fitting][cli]")
{
	const std::string body = quoted(bodyfit_test::assetPath("male_young.4508v.obj"));
	const std::string relJson = (scratch() / "units_rel.json").string();
	const bodyfit_test::ProgramRun rel = run(body + " -o " + quoted(relJson));
	REQUIRE(rel.exitCode == 0);
	const bodyfit::BodyFit relFit = bodyfit::readEllipsoidJson(relJson);
	const double h = relFit.source.height;
	const bodyfit::BodyFitOptions defaults;

	const std::string absJson = (scratch() / "units_abs.json").string();
	const bodyfit_test::ProgramRun abs = run(body + " -o " + quoted(absJson) + " --absolute --mu-torso " + exact(defaults.muTorso * h) +
						" --mu-limbs " + exact(defaults.muLimbs * h));
	CAPTURE(abs.err);
	REQUIRE(abs.exitCode == 0);
	CHECK(nlohmann::json::parse(readFile(relJson))["ellipsoids"] == nlohmann::json::parse(readFile(absJson))["ellipsoids"]);
	// The triangle cover used the same piece size (before the fit pipeline --absolute left it at 0.003 m instead of
	// 0.003 H: 291,440 points instead of 100,504 on this body).
	CHECK(coverPoints(rel.out) > 0);
	CHECK(coverPoints(abs.out) == coverPoints(rel.out));
	// Every length is recorded in metres, each the relative default times H.
	const bodyfit::BodyFit absFit = bodyfit::readEllipsoidJson(absJson);
	CHECK_FALSE(absFit.params.relativeToHeight);
	CHECK(absFit.params.sigma == defaults.sigma * h);
	CHECK(absFit.params.coverSpacing == defaults.coverSpacing * h);
	CHECK(relFit.params.relativeToHeight);
	CHECK(relFit.params.coverSpacing == defaults.coverSpacing);
}

TEST_CASE("cli: a rigged GLB is fitted in its bind pose and the fit records the bone bindings", "[fitting][cli][rig]")
{
	const std::string glb = bodyfit_test::assetPath("animated/male_young.animated.glb");
	const std::string json = (scratch() / "rig" / "fit.json").string();
	const bodyfit_test::ProgramRun r = run(quoted(glb) + " -o " + quoted(json));
	INFO(r.err);
	REQUIRE(r.exitCode == 0);
	CHECK(r.out.find("skinning  rig with") != std::string::npos);
	const bodyfit::BodyFit fit = bodyfit::readEllipsoidJson(json);
	REQUIRE(fit.skinning != nullptr);
	// The skin field of the bind pose (the collider reads it in the bones' frames), on the bind mesh.
	REQUIRE(fit.skinField);
	CHECK(fs::exists(scratch() / "rig" / "fit.skin"));
	CHECK(r.out.find("skin      field in") != std::string::npos);
	CHECK(fit.skinning->vertices == 13380);
	CHECK(fit.skinning->ellipsoids.size() == fit.ellipsoids.size());
	CHECK(int(fit.skinning->vertexEllipsoid.size()) == 13380);

	// A static mesh gets no section; --skinned-mesh on it, or an unknown name, is bad input (exit 2, one line).
	const std::string obj = bodyfit_test::assetPath("male_young.4508v.obj");
	REQUIRE(run(quoted(obj) + " -o " + quoted(json)).exitCode == 0);
	CHECK(bodyfit::readEllipsoidJson(json).skinning == nullptr);
	const bodyfit_test::ProgramRun noSkin = run(quoted(obj) + " -o " + quoted(json) + " --skinned-mesh body");
	CHECK(noSkin.exitCode == 2);
	CHECK_THAT(noSkin.err, Catch::Contains("no skinned mesh"));
	const bodyfit_test::ProgramRun unknown = run(quoted(glb) + " -o " + quoted(json) + " --skinned-mesh cloth");
	CHECK(unknown.exitCode == 2);
	CHECK_THAT(unknown.err, Catch::Contains("no skinned mesh named 'cloth'"));
	CHECK(std::count(unknown.err.begin(), unknown.err.end(), '\n') == 1);
}
