// Hostile and careless scene input, round 2 (docs/ROBUSTNESS.md section 7), scene side: deeply nested JSON, scene
// files and files a scene names that are not regular files, values that used to be accepted and produced NaN or
// launched cloth. Each is a FormatError with a one-line message naming the file and the key, before any run.
#include "bodyfit/drape/scene.h"

#include "bodyfit/fitting/errors.h"

#include "support/paths.h"
#include "support/temp_files.h"

#include <catch2/catch.hpp>

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
