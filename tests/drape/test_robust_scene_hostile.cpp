// Hostile and careless scene input, round 2 (docs/ROBUSTNESS.md section 7), scene side: deeply nested JSON, scene
// files and files a scene names that are not regular files, values that used to be accepted and produced NaN or
// launched cloth. Each is a FormatError with a one-line message naming the file and the key, before any run.
#include "bodyfit/drape/scene.h"
#include "bodyfit/drape/simulation.h"
#include "bodyfit/drape/stability.h"

#include "bodyfit/fitting/errors.h"

#include "support/paths.h"
#include "support/temp_files.h"

#include <catch2/catch.hpp>

#include <BulletSoftBody/btSoftBody.h>

#include <limits>
#include <string>

namespace
{

using bodyfit::FormatError;
using bodyfit_test::nestedArrays;
using bodyfit_test::TempDir;

/// A valid patch scene with `fit` as body.fit (collider ellipsoids, so the fit parameters are needed).
std::string sceneWithFit(const std::string& fit)
{
	return R"({"body": {"mesh": ")" + bodyfit_test::assetPath("female_young.obj") + R"(", "fit": )" + fit +
		   R"(}, "collider": "ellipsoids", "garment": {"type": "patch"}})";
}

std::string sceneTextError(const std::string& text)
{
	try
	{
		bodyfit::drape::parseSceneText(text, "/virtual/s.json");
	}
	catch (const FormatError& e)
	{
		const std::string what = e.what();
		CHECK(what.find('\n') == std::string::npos);
		CHECK(what.rfind("/virtual/s.json: ", 0) == 0);
		return what;
	}
	FAIL("no FormatError");
	return "";
}

std::string quietLoadError(const std::string& path)
{
	try
	{
		bodyfit::drape::loadScene(path);
	}
	catch (const std::exception& e)
	{
		return e.what();
	}
	return "no exception";
}

} // namespace

TEST_CASE("robust hostile: deeply nested scene JSON is refused before a tree is built", "[robust][hostile][scene]")
{
	// Issue 15 class 1: a 300,000-deep value in body.fit segfaulted in the scene parser's copy of it.
	CHECK_THAT(sceneTextError(sceneWithFit("{\"x\": " + nestedArrays(300000) + "}")),
			   Catch::Contains("not a usable JSON document: arrays/objects nested deeper than 64 levels"));
	// Within the depth limit, a structured fit parameter is refused by name before it is copied.
	CHECK_THAT(sceneTextError(sceneWithFit("{\"mu_torso\": [[0.01]]}")),
			   Catch::EndsWith("body.fit.mu_torso: expected a number or true/false, got an array"));
	// Comments are allowed in scenes and are not nesting.
	CHECK_NOTHROW(bodyfit::drape::parseSceneText("// [[[[[\n" + sceneWithFit("{}"), "/virtual/s.json"));
}

TEST_CASE("robust hostile: scene files and the files they name must be regular files", "[robust][hostile][scene]")
{
	// Issue 15 classes 2 and 4: a directory as scene aborted bodyfit-drape (std::ios_failure), a FIFO blocked it;
	// a FIFO named as body mesh was reported as "does not exist".
	TempDir tmp("bodyfit_robust_scene");
	CHECK_THAT(quietLoadError(tmp.path("")), Catch::EndsWith(": cannot open scene file: is a directory, not a file"));
	const std::string fifo = tmp.fifo("pipe.json");
	std::string what;
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietLoadError(fifo); }));
	CHECK_THAT(what, Catch::EndsWith("pipe.json: cannot open scene file: is a FIFO (named pipe), not a regular file"));
	const std::string scene = tmp.write("s.json", R"({"body": {"mesh": "pipe.json"}, "collider": "none",
		"garment": {"type": "patch"}})");
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietLoadError(scene); }));
	CHECK_THAT(what, Catch::EndsWith("s.json: body.mesh: file '" + fifo + "' is a FIFO (named pipe), not a regular file"));
}

TEST_CASE("robust hostile: counts in a scene are integers, reported as given", "[robust][hostile][scene]")
{
	// Issue 15 class 14: body.fit.max_ellipsoids 0.5 reached the fitter as 0 (an error naming no key), 1.9 became 1;
	// an integer >= 2^63 was reported wrapped.
	CHECK_THAT(sceneTextError(sceneWithFit("{\"max_ellipsoids\": 0.5}")),
			   Catch::EndsWith("body.fit.max_ellipsoids: expected an integer, got a non-integral number 0.5"));
	CHECK_THAT(sceneTextError(sceneWithFit("{\"max_ellipsoids\": 1.9}")), Catch::Contains("non-integral number 1.9"));
	CHECK_THAT(sceneTextError(sceneWithFit("{\"max_ellipsoids\": 0}")),
			   Catch::EndsWith("body.fit.max_ellipsoids: value 0 is outside [1, 10000]"));
	CHECK_NOTHROW(bodyfit::drape::parseSceneText(sceneWithFit("{\"max_ellipsoids\": 40}"), "/virtual/s.json"));
	std::string big = sceneWithFit("{}");
	big.insert(big.size() - 1, ", \"solver\": {\"steps\": 18446744073709551615}");
	CHECK_THAT(sceneTextError(big), Catch::EndsWith("solver.steps: value 18446744073709551615 is outside [0, 10000000]"));
}

namespace
{
/// A scene with `garment` and `effects` (JSON texts) around the tetrahedron body, no collider: parsed or refused.
std::string sceneWith(const std::string& garment, const std::string& effects = "[{\"type\": \"gravity\"}]")
{
	return R"({"body": {"mesh": ")" + bodyfit_test::dataPath("tetra.obj") + R"("}, "collider": "none", "garment": )" +
		   garment + R"(, "effects": )" + effects + "}";
}

std::string motion(const std::string& keyframes, bool loop = false)
{
	return R"([{"type": "body_motion", "loop": )" + std::string(loop ? "true" : "false") + R"(, "keyframes": )" +
		   keyframes + "}]";
}
} // namespace

TEST_CASE("robust hostile: scene values are held to physical ranges", "[robust][hostile][scene]")
{
	// Issue 15 class 7: a patch centre at 1e6 m, a 1e-9 m patch and a 1e-9 m tube were accepted and gave 657, 1,599
	// and 6 NaN nodes with exit 0 (here: 900-925 NaN nodes of the windy patch at 1e6 m and at 1e-6 m; 1e-5 m was
	// still finite, so the 0.01 m / 1e-4 m-edge floors keep a factor of 300 from the first NaN).
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "patch", "center": [1e6, 0, 0]})")),
			   Catch::EndsWith("garment.center[0]: value 1e+06 is outside [-1000, 1000]"));
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "patch", "size_m": [1e-9, 1]})")),
			   Catch::EndsWith("garment.size_m[0]: value 1e-09 is outside [0.01, 100]"));
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "patch", "size_m": [0.01, 1], "resolution": [512, 31]})")),
			   Catch::EndsWith("garment.size_m: size_m[0] / (resolution[0] - 1) = 1.95695e-05 m per cloth edge, less than 0.0001 m"));
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "tube", "radius_m": 1e-9})")),
			   Catch::EndsWith("garment.radius_m: value 1e-09 is outside [0.005, 10]"));
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "tube", "radius_m": 0.005, "segments": 1024})")),
			   Catch::Contains("garment.segments: 2 pi radius_m / segments = 3.06796e-05 m per cloth edge"));
	// The limits themselves parse.
	CHECK_NOTHROW(bodyfit::drape::parseSceneText(
		sceneWith(R"({"type": "patch", "size_m": [0.01, 100], "resolution": [101, 512], "center": [1000, -1000, 0]})"), "/v.json"));
	// Issue 15 class 9: wind 200 m/s, turbulence 200 and air density 2,000 threw the cloth 1e6 m away.
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "patch"})", R"([{"type": "wind", "velocity": [200, 0, 0]}])")),
			   Catch::EndsWith("effects[0].velocity[0]: value 200 is outside [-50, 50]"));
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "patch"})", R"([{"type": "wind", "turbulence": 200}])")),
			   Catch::EndsWith("effects[0].turbulence: value 200 is outside [0, 20]"));
	CHECK_THAT(sceneTextError(sceneWith(R"({"type": "patch"})", R"([{"type": "aerodynamics", "air_density": 2000}])")),
			   Catch::EndsWith("effects[0].air_density: value 2000 is outside (0, 5]"));
	// Keyframes 1e-7 s apart, too fast a body, a loop that does not close: refused by name.
	const std::string patch = R"({"type": "patch"})";
	CHECK_THAT(sceneTextError(sceneWith(patch, motion(R"([{"t": 0}, {"t": 1e-7, "translation": [0, 0, 0.001]}])"))),
			   Catch::EndsWith("effects[0].keyframes[1].t: keyframes 1e-07 s apart, less than one step (solver.dt "
							   "0.00833333 s): the body would jump"));
	CHECK_THAT(sceneTextError(sceneWith(patch, motion(R"([{"t": 0}, {"t": 0.1, "translation": [0, 0, 5]}])"))),
			   Catch::EndsWith("keyframes[1].t: the body would move at 50 m/s from the previous keyframe (at most 10 m/s)"));
	CHECK_THAT(sceneTextError(sceneWith(patch, motion(R"([{"t": 0}, {"t": 0.1, "axis": [0, 1, 0], "angle_deg": 180}])"))),
			   Catch::EndsWith("keyframes[1].t: the body would turn at 1800 deg/s from the previous keyframe (at most 720 deg/s)"));
	CHECK_THAT(sceneTextError(sceneWith(patch, motion(R"([{"t": 0}, {"t": 1, "translation": [0, 0, 1]}])", true))),
			   Catch::EndsWith("effects[0].loop: a looping motion must end where it starts: the last keyframe is 1 m and 0 deg "
							   "from the first"));
	CHECK_NOTHROW(bodyfit::drape::parseSceneText(
		sceneWith(patch, motion(R"([{"t": 0}, {"t": 1, "translation": [0, 0, 1]}, {"t": 2}])", true)), "/v.json"));
}

TEST_CASE("robust hostile: a blown-up run is detected", "[robust][hostile][scene]")
{
	using namespace bodyfit::drape;
	const Scene scene = parseSceneText(sceneWith(R"({"type": "patch", "resolution": [5, 5], "center": [0, 2, 0]})"),
									   bodyfit_test::dataPath("s.json"));
	const BodyData body = loadBody(scene);
	DrapeSimulation sim(scene, body);
	const BlowUpWatch watch(sim);
	// reach(t) = 1 m + 10 m/s t + |g| t^2 here (no wind, no body motion).
	CHECK(watch.reach(0.0) == Approx(1.0));
	CHECK(watch.reach(2.0) == Approx(1.0 + 20.0 + 9.81 * 4.0));
	for (int k = 0; k < 60; ++k) // half a second of free fall: 1.2 m, inside the reach of 1 + 5 + 2.45 m
		sim.step();
	CHECK(watch.check(sim).empty());
	sim.cloth()->m_nodes[3].m_x.setValue(btScalar(1e6), 0, 0);
	CHECK_THAT(watch.check(sim), Catch::StartsWith("cloth node 3 is 999999 m from the scene's start box after 0.5 s "
												   "(a physical run stays within 8.4525 m)"));
	sim.cloth()->m_nodes[2].m_v.setValue(std::numeric_limits<btScalar>::quiet_NaN(), 0, 0);
	CHECK(watch.check(sim) == "cloth node 2 has a non-finite velocity");
}
