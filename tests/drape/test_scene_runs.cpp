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
		// Cloth on the skin (static bodies; an animated body keeps the ellipsoids). The nodes the collider touched in
		// its last substep rest at the skin offset on the field (error a fraction of a millimetre where these garments
		// rest), or, lifted by edges that sag over curved skin (collider.lift_edges, the default), higher by that sag
		// less half the offset: the bundled garments' 3-10 cm edges over hips, legs and shoulders sag up to ~6 mm
		// (measured at full length: mean 3.1-3.6 mm, p95 4.4-7.0 mm). Bounds: mean <= offset + 2 mm, p95 <= offset +
		// 6 mm; issue 14's offset + 1 / + 3 mm are checked without the lift in the next test case.
		if (tight && !body.animation && m["contact_nodes"].get<int>() > 0)
		{
			CHECK(m["mean_contact_gap_m"].get<double>() <= scene.collider.skinOffset + 0.002);
			CHECK(m["p95_contact_gap_m"].get<double>() <= scene.collider.skinOffset + 0.006);
		}
	}
}

TEST_CASE("bundled static scenes: lifted edges clear the skin, and without the lift nodes rest at the offset",
		  "[scene][runs][edges]")
{
	// The garments' edges are 3-10 cm long; over hips, legs and shoulders their sag between nodes resting at the
	// 2 mm offset cuts into the skin. The lift (default) takes them off it. Measured at full length on 2026-12-04
	// (edges crossing the skin against the body mesh, bending links excluded, without -> with the lift): skirt drop
	// 51 -> 4 of 2,088, tights 542 -> 59 of 7,975, tablecloth 37 -> 8, windy patch 32 -> 2. Here 120 steps (the
	// garments have settled) of the two skirts and the tights: with the lift at most a fifth of the crossings without.
	for (const char* name : {"skirt_drop", "walking_skirt", "tights_settle"})
	{
		Scene scene = loadScene(std::string(BODYFIT_SCENE_DIR) + "/" + name + ".json");
		scene.collider.kind = ColliderKind::Ellipsoids;
		scene.sampleEvery = 5;
		const BodyData body = loadBody(scene);
		int crossing[2] = {0, 0};
		for (const bool lift : {false, true})
		{
			INFO(name << (lift ? ", edges lifted" : ", collider.lift_edges false"));
			scene.collider.liftEdges = lift;
			DrapeSimulation sim(scene, body);
			const nlohmann::json m = runAndMeasure(sim, 120);
			CHECK(m["max_nodes_inside_body"] == 0);
			CHECK(m["max_nan_nodes"] == 0);
			crossing[lift] = m["links_crossing_body"].get<int>();
			// Without the lift, issue 14's goal for cloth on the skin: the touched nodes rest at the skin offset on the
			// field; mean <= offset + 1 mm, p95 <= offset + 3 mm.
			if (!lift)
			{
				CHECK(m["mean_contact_gap_m"].get<double>() <= scene.collider.skinOffset + 0.001);
				CHECK(m["p95_contact_gap_m"].get<double>() <= scene.collider.skinOffset + 0.003);
			}
		}
		CHECK(crossing[0] >= 20); // the sag this is about shows without the lift (49-542 measured at full length)
		CHECK(crossing[1] * 5 <= crossing[0]);
	}
}
