// bodyfit-bench colliders: every bundled scene (demos/scenes/*.json) with every collider kind (ellipsoids, mesh-bvh,
// convex-hull-compound, none), in one process: per-step time, collision time, nodes inside the real body mesh,
// contact gap, NaN nodes. The table a user reads to choose a collider.
#include "bench/study_common.h"

#include <filesystem>

namespace
{

using namespace bodyfit_study;

struct RunStats
{
	int steps = 0;
	int nodes = 0;
	double stepMs = 0.0, collMs = 0.0;
	int insideEnd = 0, insideMax = 0, nan = 0, contacts = 0;
	double gapMm = 0.0;
	bool capped = false;
	std::string description;
};

/// Steps the scene until `steps` or until `capS` seconds of wall time have passed (Bullet's mesh path can cost
/// seconds per step); samples the inside-body count every 5 steps and at the end.
RunStats runCapped(const bodyfit::drape::Scene& scene, const bodyfit::drape::BodyData& body, int steps, double capS)
{
	RunStats r;
	bodyfit::drape::DrapeSimulation sim(scene, body);
	r.nodes = sim.nodeCount();
	r.description = sim.colliderDescription();
	std::replace(r.description.begin(), r.description.end(), ',', ';');
	std::vector<double> stepMs, collMs;
	const auto t0 = std::chrono::steady_clock::now();
	for (int k = 1; k <= steps; ++k)
	{
		const bodyfit::drape::StepStats st = sim.step();
		stepMs.push_back(st.seconds * 1e3);
		collMs.push_back(st.collisionSeconds * 1e3);
		r.steps = k;
		const bool stop = k < steps && secondsSince(t0) > capS;
		if (k % 5 == 0 || k == steps || stop)
		{
			const bodyfit::drape::ClothSample s = sim.sample();
			r.insideEnd = s.insideBody;
			r.insideMax = std::max(r.insideMax, s.insideBody);
			r.nan = std::max(r.nan, s.nanNodes);
		}
		if (stop)
		{
			r.capped = true;
			break;
		}
	}
	r.stepMs = median(stepMs);
	r.collMs = median(collMs);
	const bodyfit::metrics::ContactMetrics contacts = sim.contacts();
	r.contacts = contacts.contactNodes;
	r.gapMm = contacts.gap.count ? 1e3 * contacts.gap.mean : 0.0;
	return r;
}

int runColliders(const bodyfit_bench::Context& ctx)
{
	const char* tag = "colliders";
	const int steps = ctx.quick ? 15 : 40;
	const double capS = ctx.quick ? 10.0 : 20.0;
	const std::string sceneDir = std::string(BODYFIT_ASSET_DIR) + "/../scenes";
	std::vector<std::string> scenes;
	for (const auto& entry : std::filesystem::directory_iterator(sceneDir))
		if (entry.path().extension() == ".json")
			scenes.push_back(entry.path().string());
	std::sort(scenes.begin(), scenes.end());
	const std::vector<bodyfit::drape::ColliderKind> kinds = {
		bodyfit::drape::ColliderKind::Ellipsoids, bodyfit::drape::ColliderKind::MeshBvh,
		bodyfit::drape::ColliderKind::ConvexHullCompound, bodyfit::drape::ColliderKind::None};

	Table t({"scene", "collider", "nodes", "steps_run", "step_ms", "coll_ms_step", "coll_ns_node_step",
			 "inside_body_end", "inside_body_max", "contact_nodes", "contact_gap_mm", "nan_nodes", "settings"});
	for (const std::string& path : scenes)
	{
		const bodyfit::drape::Scene base = bodyfit::drape::loadScene(path);
		const bodyfit::drape::BodyData body = bodyfit::drape::loadBody(base);
		for (bodyfit::drape::ColliderKind kind : kinds)
		{
			bodyfit::drape::Scene scene = base;
			scene.collider.kind = kind;
			// An animated body deforms every substep: the hull compound is built once from the bind pose and cannot
			// follow it (DrapeSimulation refuses it); Bullet's refitted mesh is measured by `bodyfit-bench animated`.
			if (base.body.animation && kind == bodyfit::drape::ColliderKind::ConvexHullCompound)
				continue;
			progress(tag, "%s with %s: up to %d steps (cap %.0f s)", base.name.c_str(), bodyfit::drape::toString(kind),
					 steps, capS);
			const RunStats r = runCapped(scene, body, steps, capS);
			t.addRow({base.name, bodyfit::drape::toString(kind), fmtInt(r.nodes),
					  fmtInt(r.steps) + (r.capped ? " (time cap)" : ""), fmt(r.stepMs, 2), fmt(r.collMs, 3),
					  fmt(r.collMs * 1e6 / std::max(1, r.nodes), 0), fmtInt(r.insideEnd), fmtInt(r.insideMax),
					  fmtInt(r.contacts), fmt(r.gapMm, 2), fmtInt(r.nan), r.description});
			progress(tag, "  %d steps, %.2f ms/step, collision %.3f ms/step, inside %d (max %d)", r.steps, r.stepMs,
					 r.collMs, r.insideEnd, r.insideMax);
		}
	}
	std::ostringstream notes;
	notes << "Each bundled scene with its own settings (dt, substeps, iterations, effects), the collider replaced; "
		  << steps << " steps or " << capS
		  << " s of wall time, whichever comes first (\"time cap\": Bullet's mesh path is that slow). Times are "
			 "medians over the steps run. inside_body: cloth nodes inside the real body mesh (ray-parity vote), at "
			 "the end and the largest of the samples taken every 5 steps; contact gap: mean distance of the nodes in "
			 "contact to the skin (negative = inside; contact = a node bodyfit's collider placed, held or pushed "
			 "out in its last substep, or one holding a Bullet contact). Not in the table: Bullet's default soft-body path on the ellipsoid compound "
			 "itself (the drape code has no such collider kind yet).";
	emitTable(ctx, "colliders", "colliders: every bundled scene with every collider kind", t, notes.str());
	// Plot: collision ms per step per scene, one bar per collider (log scale).
	std::ostringstream gp;
	gp << "set title 'Collision time per step, bundled scenes'\n"
		  "set style data histograms\nset style histogram clustered gap 1\nset style fill solid 0.8 border -1\n"
		  "set logscale y\nset ylabel 'collision ms / step (log scale)'\nset key top left\n"
		  "set xtics rotate by -20\n";
	// gnuplot histograms need one column per series: the suite writes a pivoted file for the plot.
	if (!ctx.outDir.empty())
	{
		std::ofstream piv(std::filesystem::path(ctx.outDir) / "colliders_plot.csv");
		piv << "scene,ellipsoids,mesh-bvh,convex-hull-compound,none\n";
		// rows come in scene-major order, kinds in the fixed order above
		std::ifstream in(std::filesystem::path(ctx.outDir) / "colliders.csv");
		std::string line;
		std::getline(in, line);
		std::string current;
		std::vector<std::string> vals;
		auto flush = [&] {
			if (!current.empty())
			{
				piv << current;
				for (const auto& v : vals)
					piv << "," << v;
				piv << "\n";
			}
		};
		while (std::getline(in, line))
		{
			std::vector<std::string> cells;
			std::stringstream ss(line);
			std::string cell;
			while (std::getline(ss, cell, ','))
				cells.push_back(cell);
			if (cells.size() < 6)
				continue;
			if (cells[0] != current)
			{
				flush();
				current = cells[0];
				vals.clear();
			}
			vals.push_back(std::stod(cells[5]) > 0.0 ? cells[5] : "NaN");
		}
		flush();
	}
	gp << "plot 'colliders_plot.csv' skip 1 using 2:xtic(1) title 'ellipsoids (ours)' lc rgb '#d62728', \\\n"
		  "     '' skip 1 using 3 title 'mesh-bvh (Bullet)' lc rgb '#1f77b4', \\\n"
		  "     '' skip 1 using 4 title 'convex-hull-compound (Bullet)' lc rgb '#2ca02c', \\\n"
		  "     '' skip 1 using 5 title 'none' lc rgb '#999999'";
	plot(ctx, "colliders", gp.str(), 1000, 550);
	return 0;
}

const bodyfit_bench::SuiteRegistrar registerColliders(
	"colliders",
	"every bundled scene x every collider kind: step and collision time, nodes inside the body, contact gap (40 "
	"steps or 20 s per run, --quick 15 steps / 10 s)",
	&runColliders);

} // namespace
