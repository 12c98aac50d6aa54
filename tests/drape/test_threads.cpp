// Simulations in threads of their own (a server draping several garments at once, a game stepping a world per
// character on a job system): each world with its collider is independent of the others, so stepping them at the
// same time gives, to the bit, what stepping them one after the other gives. The ThreadSanitizer job of
// tools/ci-extra.sh runs this file: a shared table the sweep made on first use without a lock was a data race there
// (btEllipsoidSweep.cpp, axisSymmetries).
#include "bodyfit/drape/simulation.h"

#include <BulletSoftBody/btSoftBody.h>
#include <catch2/catch.hpp>

#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

using namespace bodyfit::drape;

namespace
{

/// The cloth's node positions after `steps` steps of the scene.
std::vector<btScalar> clothAfter(const Scene& scene, const BodyData& body, int steps)
{
	DrapeSimulation sim(scene, body);
	for (int s = 0; s < steps; ++s)
		sim.step();
	std::vector<btScalar> x;
	const btSoftBody* cloth = sim.cloth();
	for (int i = 0; i < cloth->m_nodes.size(); ++i)
		for (int k = 0; k < 3; ++k)
			x.push_back(cloth->m_nodes[i].m_x[k]);
	return x;
}

} // namespace

TEST_CASE("threads: scenes stepped in threads at the same time end as they end one after the other", "[drape][threads]")
{
	// Two animated bodies (their ellipsoids move every substep: the sweep runs) and a static one on the tight surface.
	// 6 steps: 48 substeps of the walk, enough for the sweep and the bone fields (the race above showed in 3).
	const std::vector<std::string> names = {"animated_walk_skirt", "animated_walk_tights", "tablecloth_shoulders"};
	constexpr int kSteps = 6;
	std::vector<Scene> scenes;
	std::vector<BodyData> bodies;
	for (const std::string& name : names)
	{
		scenes.push_back(loadScene(std::string(BODYFIT_SCENE_DIR) + "/" + name + ".json"));
		bodies.push_back(loadBody(scenes.back()));
	}
	// Together first: what a world makes once per process on first use is then made by threads at the same time.
	std::vector<std::vector<btScalar>> alone, together(names.size());
	std::vector<std::string> failed(names.size());
	std::vector<std::thread> threads;
	for (std::size_t i = 0; i < names.size(); ++i)
		threads.emplace_back([&, i] {
			try
			{
				together[i] = clothAfter(scenes[i], bodies[i], kSteps);
			}
			catch (const std::exception& e) // reported below: an exception leaving a thread would end the process
			{
				failed[i] = e.what();
			}
		});
	for (std::thread& t : threads)
		t.join();
	for (std::size_t i = 0; i < names.size(); ++i)
		alone.push_back(clothAfter(scenes[i], bodies[i], kSteps));
	for (std::size_t i = 0; i < names.size(); ++i)
	{
		INFO(names[i]);
		CHECK(failed[i] == "");
		REQUIRE(!alone[i].empty());
		// Bit for bit: every operation of a world runs in its own thread in the same order either way.
		CHECK(together[i] == alone[i]);
	}
}
