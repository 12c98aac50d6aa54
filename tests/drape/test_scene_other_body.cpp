// A bundled scene with another body (issue 12 item 11): `bodyfit-drape SCENE --body MESH` without --ellipsoids must
// not keep the scene's ellipsoids when they were fitted to another mesh (the fit file's recorded source): the body is
// refitted and the reason is reported; a mesh garment placed for the scene's body is warned about.
#include "bodyfit/drape/simulation.h"

#include "support/paths.h"

#include <catch2/catch.hpp>

#include <string>

using namespace bodyfit::drape;

namespace
{

bool anyContains(const std::vector<std::string>& lines, const std::string& what)
{
	for (const std::string& l : lines)
		if (l.find(what) != std::string::npos)
			return true;
	return false;
}

} // namespace

TEST_CASE("other body: the scene's fit for another mesh is refitted, with the reason", "[scene][body]")
{
	const Scene scene = loadScene(std::string(BODYFIT_SCENE_DIR) + "/tablecloth_shoulders.json");
	REQUIRE_FALSE(scene.body.ellipsoids.empty()); // the scene names a fit file (female_young.json)
	SECTION("another body: refitted")
	{
		const BodyData body = loadBody(scene, bodyfit_test::assetPath("male_young.obj"));
		CHECK(body.ellipsoidSource.rfind("fit", 0) == 0); // fitted, not the file
		CHECK(body.ellipsoidSource != scene.body.ellipsoids);
		CHECK_FALSE(body.ellipsoids.empty());
		REQUIRE_FALSE(body.fitWarnings.empty());
		CHECK_THAT(body.fitWarnings[0], Catch::Contains("fitted to female_young.obj"));
		CHECK_THAT(body.fitWarnings[0], Catch::Contains("not male_young.obj"));
		CHECK(body.fitWarnings[0].find('\n') == std::string::npos);
	}
	SECTION("the same body named explicitly: the scene's fit is kept")
	{
		const BodyData body = loadBody(scene, bodyfit_test::assetPath("female_young.obj"));
		CHECK(body.ellipsoidSource == scene.body.ellipsoids);
		CHECK(body.fitWarnings.empty());
	}
	SECTION("an explicit --ellipsoids is the user's choice: kept, even for another mesh")
	{
		const BodyData body =
			loadBody(scene, bodyfit_test::assetPath("male_young.obj"), bodyfit_test::assetPath("fits/female_young.json"));
		CHECK(body.ellipsoidSource == bodyfit_test::assetPath("fits/female_young.json"));
	}
}

TEST_CASE("other body: a mesh garment placed for the scene's body is warned about", "[scene][body]")
{
	const Scene scene = loadScene(std::string(BODYFIT_SCENE_DIR) + "/skirt_drop.json");
	REQUIRE_FALSE(scene.garment.mesh.empty());
	const BodyData body = loadBody(scene, bodyfit_test::assetPath("male_young.obj"));
	CHECK(anyContains(body.fitWarnings, "garment female_young.skirt.obj was placed for"));
}
