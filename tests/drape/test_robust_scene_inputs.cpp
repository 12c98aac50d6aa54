// The bad-input catalogue of docs/ROBUSTNESS.md, scene side: a scene file with an unknown key, a missing scene file
// and a non-JSON scene file are bodyfit::FormatError with a one-line message naming the file (and the key).
#include "bodyfit/drape/scene.h"

#include "bodyfit/fitting/errors.h"

#include "support/paths.h"

#include <catch2/catch.hpp>

namespace
{
std::string sceneError(const std::string& file)
{
	try
	{
		bodyfit::drape::loadScene(bodyfit_test::dataPath(file));
	}
	catch (const bodyfit::FormatError& e)
	{
		const std::string what = e.what();
		CHECK(what.find('\n') == std::string::npos);
		CHECK(what.find(file) != std::string::npos);
		return what;
	}
	FAIL("no FormatError for " << file);
	return "";
}
} // namespace

TEST_CASE("robust catalogue: bad scene files are FormatError naming the file and the key", "[robust][inputs][scene]")
{
	CHECK_THAT(sceneError("robust_scene_unknown_key.json"), Catch::Contains("colour: unknown key"));
	CHECK_THAT(sceneError("robust_does_not_exist.json"), Catch::Contains("cannot open scene file"));
	CHECK_THAT(sceneError("garbage.bin"), Catch::Contains("invalid JSON"));
	// The ellipsoid file of a scene is not a scene: its top-level keys are unknown here.
	CHECK_THAT(sceneError("robust_valid_one.json"), Catch::Contains("unknown key"));
}
