// Ellipsoid-set JSON: bit-exact round trip, one FormatError per bad field (naming it), and the mesh export.
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "support/sampling.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <fstream>
#include <random>
#include <unistd.h>

using namespace bodyfit;

namespace
{

BodyFit sampleFit()
{
	std::mt19937 rng(2024);
	std::uniform_real_distribution<double> u(0.0, 1.0);
	BodyFit fit;
	fit.source = {"male_young.obj", 13380, 1.74813};
	fit.params = {0.006, 0.004, true, 0.001, 128, 0.0034962, true, true, 0.0031234567890123};
	const Region regions[] = {Region::Head, Region::TorsoUpperLeft, Region::ArmLowerRight, Region::Whole};
	for (int i = 0; i < 4; ++i)
	{
		FittedEllipsoid f;
		// Values with full 53-bit mantissas, so that a lossy writer could not pass by luck.
		f.ellipsoid = bodyfit_test::makeEllipsoid(Eigen::Vector3d(u(rng), 1.0 + u(rng), -u(rng)),
												  Eigen::Vector3d(0.01 + u(rng), 0.01 + u(rng), 0.01 + u(rng)),
												  bodyfit_test::randomRotation(rng));
		f.region = regions[i];
		f.vertexCount = 100 + i;
		f.radialError = 0.01 * u(rng);
		f.maxRadialError = 0.05 * u(rng);
		f.meanDistance = 0.005 * u(rng);
		f.maxDistance = 0.04 * u(rng);
		fit.ellipsoids.push_back(f);
	}
	fit.timings = {{"load", 12.5 + u(rng)}, {"fitting", 20.0 + u(rng)}};
	fit.warnings = {"a warning"};
	fit.status = RefineStatus::BudgetReached;
	fit.splitsAccepted = 120;
	fit.splitsRejected = 3;
	return fit;
}

std::string tempPath(const std::string& name)
{
	const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("bodyfit_test_ellipsoid_io_" + std::to_string(long(::getpid()))); // per process (parallel ctest)
	std::filesystem::create_directories(dir);
	return (dir / name).string();
}

} // namespace

TEST_CASE("ellipsoid_io: JSON round trip is bit-exact", "[fitting][ellipsoid_io]")
{
	const BodyFit fit = sampleFit();
	const std::string text = toEllipsoidJson(fit);
	const BodyFit back = parseEllipsoidJson(text, "memory");

	REQUIRE(back.ellipsoids.size() == fit.ellipsoids.size());
	for (std::size_t i = 0; i < fit.ellipsoids.size(); ++i)
	{
		const FittedEllipsoid& a = fit.ellipsoids[i];
		const FittedEllipsoid& b = back.ellipsoids[i];
		CAPTURE(i);
		// Every stored double parses back to the identical double (shortest round-trip printing).
		CHECK(a.ellipsoid.center == b.ellipsoid.center);
		CHECK(a.ellipsoid.radii == b.ellipsoid.radii);
		CHECK(a.radialError == b.radialError);
		CHECK(a.maxRadialError == b.maxRadialError);
		CHECK(a.meanDistance == b.meanDistance);
		CHECK(a.maxDistance == b.maxDistance);
		CHECK(a.region == b.region);
		CHECK(a.vertexCount == b.vertexCount);
		// The rotation is stored as a quaternion: matrix -> quaternion -> matrix costs a few ulp (1e-15 on unit
		// entries); 1e-14 leaves room for the normalisation.
		CHECK((a.ellipsoid.rotation - b.ellipsoid.rotation).cwiseAbs().maxCoeff() < 1e-14);
		CHECK(b.ellipsoid.isValid(1e-12));
	}
	// The quaternion numbers themselves survive the text bit for bit.
	const nlohmann::json doc = nlohmann::json::parse(text);
	for (std::size_t i = 0; i < fit.ellipsoids.size(); ++i)
	{
		Eigen::Quaterniond q = toQuaternion(fit.ellipsoids[i].ellipsoid.rotation).normalized();
		if (q.w() < 0.0)
			q.coeffs() = -q.coeffs();
		const auto& r = doc["ellipsoids"][i]["rotation"];
		CHECK(r[0].get<double>() == q.w());
		CHECK(r[1].get<double>() == q.x());
		CHECK(r[2].get<double>() == q.y());
		CHECK(r[3].get<double>() == q.z());
	}
	CHECK(back.source.mesh == fit.source.mesh);
	CHECK(back.source.vertices == fit.source.vertices);
	CHECK(back.source.height == fit.source.height);
	CHECK(back.params.muTorso == fit.params.muTorso);
	CHECK(back.params.muLimbs == fit.params.muLimbs);
	CHECK(back.params.sigma == fit.params.sigma);
	CHECK(back.params.maxEllipsoids == fit.params.maxEllipsoids);
	CHECK(back.params.minRadius == fit.params.minRadius);
	CHECK(back.params.relativeToHeight == fit.params.relativeToHeight);
	CHECK(back.params.reclusterGroup == fit.params.reclusterGroup);
	CHECK(back.params.coverTriangles == fit.params.coverTriangles);
	CHECK(back.params.coverSpacing == fit.params.coverSpacing);
	REQUIRE(back.timings.size() == 2);
	CHECK(back.timings[0].stage == "load");
	CHECK(back.timings[1].ms == fit.timings[1].ms);
	CHECK(back.warnings == fit.warnings);
	CHECK(back.status == fit.status);
	CHECK(back.splitsAccepted == 120);
	CHECK(back.splitsRejected == 3);
	// Writing what was read reproduces the document except for last-ulp quaternion differences: compare the
	// parts without rotations exactly.
	nlohmann::json again = nlohmann::json::parse(toEllipsoidJson(back));
	nlohmann::json first = doc;
	for (auto* d : {&again, &first})
		for (auto& e : (*d)["ellipsoids"])
			e.erase("rotation");
	CHECK(again == first);
}

TEST_CASE("ellipsoid_io: files, document keys and the stats block", "[fitting][ellipsoid_io]")
{
	const BodyFit fit = sampleFit();
	const std::string path = tempPath("fit.json");
	writeEllipsoidJson(path, fit);
	const BodyFit back = readEllipsoidJson(path);
	CHECK(back.ellipsoids.size() == 4);

	const nlohmann::json doc = nlohmann::json::parse(toEllipsoidJson(fit));
	CHECK(doc["format"] == "bodyfit.ellipsoids");
	CHECK(doc["version"] == 1);
	CHECK(doc["units"] == "m");
	CHECK(doc["up"] == "+y");
	CHECK(doc["ellipsoids"][0]["region"] == "head");
	CHECK(doc["ellipsoids"][1]["region"] == "torso.upper.left");
	CHECK(doc["ellipsoids"][3]["region"] == "whole");
	CHECK(doc["stats"]["count"] == 4);
	CHECK(doc["stats"]["mean_radial_error"].get<double>() == fit.meanRadialError());
	CHECK(doc["stats"]["max_radial_error"].get<double>() == fit.maxRadialError());

	CHECK_THROWS_AS(readEllipsoidJson(tempPath("missing.json")), FormatError);
	CHECK_THROWS_WITH(readEllipsoidJson(tempPath("missing.json")), Catch::Contains("missing.json"));
	CHECK_THROWS_AS(writeEllipsoidJson(tempPath("no_such_dir/x.json"), fit), FormatError);
}

TEST_CASE("ellipsoid_io: optional error fields may be absent", "[fitting][ellipsoid_io]")
{
	const std::string minimal = R"({"format": "bodyfit.ellipsoids", "version": 1, "ellipsoids": [
		{"region": "arm.lower.left", "center": [0, 1, 0], "rotation": [1, 0, 0, 0], "axes": [0.1, 0.05, 0.04]}]})";
	const BodyFit fit = parseEllipsoidJson(minimal, "minimal.json");
	REQUIRE(fit.ellipsoids.size() == 1);
	CHECK(fit.ellipsoids[0].region == Region::ArmLowerLeft);
	CHECK(fit.ellipsoids[0].ellipsoid.radii == Eigen::Vector3d(0.1, 0.05, 0.04));
	CHECK(std::isnan(fit.ellipsoids[0].radialError));
	// Unknown (NaN) errors are omitted again when written.
	const nlohmann::json doc = nlohmann::json::parse(toEllipsoidJson(fit));
	CHECK_FALSE(doc["ellipsoids"][0].contains("radial_error"));
}

TEST_CASE("ellipsoid_io: every bad field gives a FormatError naming the file and the field", "[fitting][ellipsoid_io]")
{
	const nlohmann::json valid = nlohmann::json::parse(toEllipsoidJson(sampleFit()));
	using Mutation = std::function<void(nlohmann::json&)>;
	struct Case
	{
		const char* what;
		Mutation mutate;
		const char* field; ///< expected in the message
	};
	const std::vector<Case> cases = {
		{"missing format", [](nlohmann::json& d) { d.erase("format"); }, "format: missing"},
		{"wrong format", [](nlohmann::json& d) { d["format"] = "something.else"; }, "format: must be"},
		{"format not a string", [](nlohmann::json& d) { d["format"] = 3; }, "format: must be a string"},
		{"missing version", [](nlohmann::json& d) { d.erase("version"); }, "version: missing"},
		{"future version", [](nlohmann::json& d) { d["version"] = 2; }, "version: unsupported version 2"},
		{"version not an integer", [](nlohmann::json& d) { d["version"] = 1.5; }, "version: must be an integer"},
		{"wrong units", [](nlohmann::json& d) { d["units"] = "cm"; }, "units"},
		{"wrong up", [](nlohmann::json& d) { d["up"] = "+z"; }, "up"},
		{"missing ellipsoids", [](nlohmann::json& d) { d.erase("ellipsoids"); }, "ellipsoids: missing"},
		{"ellipsoids not an array", [](nlohmann::json& d) { d["ellipsoids"] = 1; }, "ellipsoids: must be an array"},
		{"ellipsoid not an object", [](nlohmann::json& d) { d["ellipsoids"][1] = 5; }, "ellipsoids[1]: must be an object"},
		{"missing region", [](nlohmann::json& d) { d["ellipsoids"][0].erase("region"); }, "ellipsoids[0].region: missing"},
		{"unknown region", [](nlohmann::json& d) { d["ellipsoids"][2]["region"] = "tail"; },
		 "ellipsoids[2].region: unknown region \"tail\""},
		{"missing center", [](nlohmann::json& d) { d["ellipsoids"][0].erase("center"); }, "ellipsoids[0].center: missing"},
		{"center too short", [](nlohmann::json& d) { d["ellipsoids"][0]["center"] = {1, 2}; },
		 "ellipsoids[0].center: must be an array of 3 numbers"},
		{"center not a number", [](nlohmann::json& d) { d["ellipsoids"][1]["center"][2] = "x"; },
		 "ellipsoids[1].center[2]: must be a number"},
		{"missing rotation", [](nlohmann::json& d) { d["ellipsoids"][3].erase("rotation"); },
		 "ellipsoids[3].rotation: missing"},
		{"non-unit quaternion", [](nlohmann::json& d) { d["ellipsoids"][1]["rotation"] = {1, 1, 0, 0}; },
		 "ellipsoids[1].rotation: must be a unit quaternion"},
		{"zero quaternion", [](nlohmann::json& d) { d["ellipsoids"][1]["rotation"] = {0, 0, 0, 0}; },
		 "ellipsoids[1].rotation: must be a unit quaternion"},
		{"quaternion with 3 numbers", [](nlohmann::json& d) { d["ellipsoids"][0]["rotation"] = {1, 0, 0}; },
		 "ellipsoids[0].rotation: must be an array of 4 numbers"},
		{"missing axes", [](nlohmann::json& d) { d["ellipsoids"][0].erase("axes"); }, "ellipsoids[0].axes: missing"},
		{"negative axis", [](nlohmann::json& d) { d["ellipsoids"][2]["axes"][1] = -0.01; },
		 "ellipsoids[2].axes[1]: must be > 0"},
		{"zero axis", [](nlohmann::json& d) { d["ellipsoids"][0]["axes"][0] = 0.0; }, "ellipsoids[0].axes[0]: must be > 0"},
		{"negative error", [](nlohmann::json& d) { d["ellipsoids"][0]["radial_error"] = -1.0; },
		 "ellipsoids[0].radial_error: must be >= 0"},
		{"bad vertex count", [](nlohmann::json& d) { d["ellipsoids"][0]["vertices"] = -4; },
		 "ellipsoids[0].vertices: must be an integer >= 0"},
		{"params not an object", [](nlohmann::json& d) { d["params"] = "x"; }, "params: must be an object"},
		{"bad mu", [](nlohmann::json& d) { d["params"]["mu_torso"] = "big"; }, "params.mu_torso: must be a number"},
		{"bad timing", [](nlohmann::json& d) { d["timing_ms"]["load"] = -2; }, "timing_ms.load: must be >= 0"},
		{"count mismatch", [](nlohmann::json& d) { d["stats"]["count"] = 7; }, "stats.count"},
		{"unknown status", [](nlohmann::json& d) { d["refinement"]["status"] = "maybe"; }, "refinement.status"},
		{"warnings not strings", [](nlohmann::json& d) { d["warnings"] = {1}; }, "warnings[0]: must be a string"},
	};
	for (const Case& c : cases)
	{
		nlohmann::json doc = valid;
		c.mutate(doc);
		CAPTURE(c.what);
		CHECK_THROWS_AS(parseEllipsoidJson(doc.dump(), "bad.json"), FormatError);
		CHECK_THROWS_WITH(parseEllipsoidJson(doc.dump(), "bad.json"),
						  Catch::StartsWith("bad.json: ") && Catch::Contains(c.field));
	}
	SECTION("not JSON at all")
	{
		CHECK_THROWS_WITH(parseEllipsoidJson("{\"format\": ", "broken.json"),
						  Catch::StartsWith("broken.json: not valid JSON"));
		CHECK_THROWS_WITH(parseEllipsoidJson("[1, 2]", "array.json"), Catch::Contains("document: must be an object"));
	}
	SECTION("an overflowing number")
	{
		std::string text = valid.dump();
		const std::string key = "\"axes\":[";
		const std::size_t start = text.find(key) + key.size();
		text.replace(start, text.find(',', start) - start, "1e999");
		// nlohmann rejects the overflow while parsing; it must still arrive as a one-line FormatError.
		CHECK_THROWS_WITH(parseEllipsoidJson(text, "inf.json"),
						  Catch::StartsWith("inf.json: not valid JSON") && Catch::Contains("1e999"));
	}
}

TEST_CASE("ellipsoid_io: mesh export puts every vertex on its ellipsoid", "[fitting][ellipsoid_io]")
{
	const BodyFit fit = sampleFit();
	Eigen::MatrixX3d colors;
	const TriMesh mesh = ellipsoidMesh(fit.ellipsoids, 2, &colors);
	// Icosphere level 2: 162 vertices, 320 triangles per ellipsoid.
	REQUIRE(mesh.vertexCount() == 162 * 4);
	REQUIRE(mesh.faceCount() == 320 * 4);
	REQUIRE(colors.rows() == mesh.vertexCount());
	for (int e = 0; e < 4; ++e)
		for (int i = 0; i < 162; ++i)
			// zeta = 1 on the surface; 1e-12 covers the rotation and scaling roundings.
			CHECK(fit.ellipsoids[std::size_t(e)].ellipsoid.zeta(mesh.V.row(e * 162 + i).transpose()) ==
				  Approx(1.0).margin(1e-12));
	// Faces are outward (CCW seen from outside): the normal points away from the centre for every triangle.
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
		const Eigen::Vector3d centre = fit.ellipsoids[std::size_t(f / 320)].ellipsoid.center;
		CHECK((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0);
	}
	CHECK(ellipsoidMesh(fit.ellipsoids, 0).faceCount() == 20 * 4);

	const std::string ply = tempPath("ellipsoids.ply");
	exportEllipsoidMesh(ply, fit.ellipsoids);
	// Each ellipsoid is its own connected component: count the faces of all components.
	CHECK(loadTriMesh(ply).full.faceCount() == 320 * 4);
	const std::string obj = tempPath("ellipsoids.obj");
	exportEllipsoidMesh(obj, fit.ellipsoids, 1);
	CHECK(loadTriMesh(obj).full.faceCount() == 80 * 4);
	CHECK_THROWS_AS(exportEllipsoidMesh(tempPath("ellipsoids.stl"), fit.ellipsoids), InvalidInputError);
}
