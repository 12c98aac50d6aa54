// Float far from the origin in the scene runner (checkFloatRange, bodyfit/bullet_ext/btFloatRange.h): skirt_drop
// moved 2 km away warns (float) and 20 km away is refused with the reason (float); the float64 build accepts both.
#include "bodyfit/drape/simulation.h"
#include "bodyfit/fitting/errors.h"

#include <catch2/catch.hpp>

#include <string>

using namespace bodyfit::drape;

namespace
{

const bool kFloat = sizeof(btScalar) == sizeof(float);

struct MovedScene
{
	Scene scene;
	BodyData body;
};

/// skirt_drop with the body, its ellipsoids and the garment moved `distance` metres along (1, 1, 1) / sqrt(3).
MovedScene movedSkirtDrop(double distance)
{
	MovedScene m;
	m.scene = loadScene(std::string(BODYFIT_SCENE_DIR) + "/skirt_drop.json");
	m.body = loadBody(m.scene);
	const Eigen::Vector3d offset = Eigen::Vector3d::Ones().normalized() * distance;
	m.scene.garment.offset += offset;
	m.body.mesh.V.rowwise() += offset.transpose();
	for (bodyfit::Ellipsoid& e : m.body.ellipsoids)
		e.center += offset;
	return m;
}

} // namespace

TEST_CASE("far origin: the scene runner warns beyond 1 km and refuses beyond 8 km in float", "[scene][far_origin]")
{
	{
		const MovedScene near = movedSkirtDrop(500.0);
		DrapeSimulation sim(near.scene, near.body);
		CHECK(sim.warnings().empty());
	}
	{
		const MovedScene far = movedSkirtDrop(2000.0);
		DrapeSimulation sim(far.scene, far.body);
		const nlohmann::json m = runAndMeasure(sim, 1);
		REQUIRE(m.contains("warnings"));
		CHECK(m["warnings"].size() == sim.warnings().size());
		if (kFloat)
		{
			REQUIRE(sim.warnings().size() == 1);
			// 2 km: spacing 0.24 mm (coordinates up to 1,155 m + 1 m on each axis: 1.22e-4 m), limits in the message.
			CHECK_THAT(sim.warnings()[0], Catch::Contains("float precision") && Catch::Contains("safe up to 1024 m") &&
											   Catch::Contains("refused beyond 8192 m"));
		}
		else
			CHECK(sim.warnings().empty());
	}
	const MovedScene refused = movedSkirtDrop(20000.0);
	if (kFloat)
	{
		CHECK_THROWS_WITH(DrapeSimulation(refused.scene, refused.body),
			Catch::Contains("skirt_drop.json: refused") && Catch::Contains("-DBODYFIT_BULLET_DOUBLE=ON"));
		// The bench measures past the limit on purpose: allowed when asked, with the warning kept.
		DrapeSimulation sim(refused.scene, refused.body, /*refuseFarFromOrigin=*/false);
		CHECK(sim.warnings().size() == 1);
	}
	else
	{
		DrapeSimulation sim(refused.scene, refused.body);
		CHECK(sim.warnings().empty());
	}
}

TEST_CASE("far origin: what loading the body found reaches the scene runner", "[scene][far_origin][components]")
{
	// tests/data/robust_components.obj: parts joined, one inside, one prop left out (three warnings, components.h).
	const Scene scene = loadScene(std::string(BODYFIT_SCENE_DIR) + "/skirt_drop.json");
	const BodyData body = loadBody(scene, std::string(BODYFIT_TEST_DATA_DIR) + "/robust_components.obj");
	REQUIRE(body.loadWarnings.size() == 3);
	CHECK_THAT(body.loadWarnings[2], Catch::Contains("detached component"));
	// The runner keeps every component for its metrics (the prop included).
	CHECK(body.mesh.vertexCount() == 32);
}
