// Each bundled scene runs a short while with the ellipsoid collider in both surfaces: no NaN; on the ellipsoid
// surface no node inside an ellipsoid, on the tight skin surface (the default) no node inside the body mesh; the
// metrics JSON carries the fields of docs/DESIGN.md sec. 6.
#include "bodyfit/drape/simulation.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>

using namespace bodyfit::drape;

TEST_CASE("bundled scenes: a short run has no NaN and no node inside an ellipsoid or the body", "[scene][runs]")
{
	std::vector<std::string> files;
	for (const auto& entry : std::filesystem::directory_iterator(BODYFIT_SCENE_DIR))
		if (entry.path().extension() == ".json")
			files.push_back(entry.path().string());
	std::sort(files.begin(), files.end());
	REQUIRE(files.size() >= 5);
	for (const std::string& file : files)
	for (const bool tight : {false, true})
	{
		INFO(file << (tight ? ", tight skin surface" : ", ellipsoid surface"));
		Scene scene = loadScene(file);
		scene.collider.kind = ColliderKind::Ellipsoids;
		scene.collider.tightSurface = tight;
		scene.sampleEvery = 5;
		const BodyData body = loadBody(scene);
		REQUIRE_FALSE(body.ellipsoids.empty());
		DrapeSimulation sim(scene, body);
		// 40 steps = 1/3 s: garments have fallen onto the body and the walking body has not started yet.
		const nlohmann::json m = runAndMeasure(sim, 40);
		for (const char* key : {"steps", "nodes", "ms_per_step", "collision_ms_per_step", "nodes_inside_body",
								"max_nodes_inside_body", "mean_contact_gap_m", "nan_nodes"})
			CHECK(m.contains(key));
		CHECK(m["nan_nodes"] == 0);
		CHECK(m["max_nan_nodes"] == 0);
		CHECK(m["max_nodes_inside_body"] == 0); // every 5 steps, against the body mesh (or the skinned mesh)
		// The ellipsoid surface's guarantee, checked independently in double every 5 steps: no node deeper inside an
		// ellipsoid than float rounding of a position about 1 m from the origin (ulp 1.2e-7 m; 1e-6 m allows a few).
		// The tight surface lets nodes into the union down to the skin (animated bodies too, in their bones' frames).
		if (!tight)
			CHECK(m["max_ellipsoid_penetration_m"].get<double>() < 1e-6);
		// The union rule is reported beside the collider's contacts.
		CHECK(m.contains("nodes_near_union"));
		// Issue 14's goal for cloth on the skin (static bodies; an animated body keeps the ellipsoids): the nodes the
		// collider touched in its last substep are placed at the skin offset on the field, whose error where these
		// garments rest is a fraction of a millimetre; mean <= offset + 1 mm, p95 <= offset + 3 mm.
		if (tight && !body.animation && m["contact_nodes"].get<int>() > 0)
		{
			CHECK(m["mean_contact_gap_m"].get<double>() <= scene.collider.skinOffset + 0.001);
			CHECK(m["p95_contact_gap_m"].get<double>() <= scene.collider.skinOffset + 0.003);
		}
	}
}

TEST_CASE("bundled skirt drop: lifting edges takes them off the skin and keeps every node outside", "[scene][runs][edges]")
{
	// The skirt's edges are 4-10 cm long; over the hips their sag between nodes resting at the 2 mm offset cuts into
	// the skin. Config::m_liftEdges lifts them; the edges crossing the skin (measured against the body mesh, bending
	// links excluded) must fall to at most a fifth (measured 2026-12-04: 51 -> 5 of 2,088), nodes never inside.
	Scene scene = loadScene(std::string(BODYFIT_SCENE_DIR) + "/skirt_drop.json");
	scene.collider.kind = ColliderKind::Ellipsoids;
	scene.sampleEvery = 5;
	const BodyData body = loadBody(scene);
	int crossing[2] = {0, 0};
	for (const bool lift : {false, true})
	{
		INFO((lift ? "collider.lift_edges" : "default"));
		scene.collider.liftEdges = lift;
		DrapeSimulation sim(scene, body);
		const nlohmann::json m = runAndMeasure(sim, scene.solver.steps);
		CHECK(m["max_nodes_inside_body"] == 0);
		CHECK(m["max_nan_nodes"] == 0);
		crossing[lift] = m["links_crossing_body"].get<int>();
	}
	CHECK(crossing[0] >= 20); // the default run shows the sag this is about (51 measured)
	CHECK(crossing[1] * 5 <= crossing[0]);
}
