// bodyfit-bench animated: the bundled walk-skirt scene (demos/scenes/animated_walk_skirt.json: female_young's skirt on
// the rig's walk clip) with our ellipsoid collider, whose bone-bound ellipsoids are updated every substep, beside
// Bullet's own alternative: the same skinned body as a btBvhTriangleMeshShape whose vertices are replaced and tree
// refitted every substep, with Bullet's default soft-body collision (SDF_RS) against it. Both are the scene runner's
// worlds (collider kinds `ellipsoids` and `mesh-bvh`; bodyfit/drape/simulation.h), in one process.
// Per step: the body update (pose + skinning + ellipsoid update, then the write into the shape: the compound's
// ellipsoids, or the mesh's vertices with refitTree and Bullet's cached triangle prisms and sparse-SDF cells
// dropped), the collision (Bullet's collision detection, where Bullet rebuilds its prisms and SDF cells, plus our
// collider), nodes inside the skinned body mesh and the mean contact gap every 5 steps. Ours runs the whole clip
// (--repeats times, medians of the per-run medians); Bullet's path costs seconds per step, so it runs
// --bullet-steps steps once and the ratios compare the two over those same first steps.
// Writes animated.csv / .md (the table), animated_series.csv (nodes inside and contact gap over time, both) and
// animated.png (gnuplot).
#include "bench/study_common.h"

#include "bodyfit/drape/simulation.h"

#include <cmath>
#include <fstream>
#include <limits>

namespace
{

using namespace bodyfit_study;
using bodyfit::drape::ColliderKind;

struct Sample
{
	int step = 0;
	double time = 0.0;
	int inside = 0;
	double gapMm = std::numeric_limits<double>::quiet_NaN(); ///< mean contact gap (NaN: no contact)
	int crossing = 0; ///< cloth edges crossing the skinned body (both ends outside): faces cutting into a limb
};

/// Per-step costs (ms) and the samples of one run.
struct Run
{
	std::vector<double> skinMs, writeMs, collMs, stepMs;
	std::vector<double> insideMs;  ///< one sample's inside count, the inside test rebuilt for the pose first
	std::vector<double> contactMs; ///< then its contact gap, the distance grid rebuilt first
	std::vector<Sample> samples;
	int nodes = 0;
	std::string settings;
};

Run runScene(const bodyfit::drape::Scene& scene, const bodyfit::drape::BodyData& body, int steps, const char* tag)
{
	Run r;
	bodyfit::drape::DrapeSimulation sim(scene, body);
	r.nodes = sim.nodeCount();
	r.settings = sim.colliderDescription();
	std::replace(r.settings.begin(), r.settings.end(), ',', ';');
	const auto t0 = std::chrono::steady_clock::now();
	for (int k = 1; k <= steps; ++k)
	{
		const bodyfit::drape::StepStats st = sim.step();
		r.skinMs.push_back(st.bodySkinSeconds * 1e3);
		r.writeMs.push_back(st.bodyWriteSeconds * 1e3);
		r.collMs.push_back(st.collisionSeconds * 1e3);
		r.stepMs.push_back(st.seconds * 1e3);
		if (k % 5 == 0 || k == steps)
		{
			const auto s0 = std::chrono::steady_clock::now();
			const int inside = sim.sample().insideBody;
			r.insideMs.push_back(secondsSince(s0) * 1e3);
			const auto s1 = std::chrono::steady_clock::now();
			const bodyfit::metrics::ContactMetrics c = sim.contacts();
			r.contactMs.push_back(secondsSince(s1) * 1e3);
			r.samples.push_back({k, sim.time(), inside,
								 c.gap.count > 0 ? 1e3 * c.gap.mean : std::numeric_limits<double>::quiet_NaN(),
								 sim.edgeCrossings().crossing});
		}
		if (k % 50 == 0 || (k == steps && steps < 50))
			progress(tag, "  %s: step %d/%d (%.0f s)", bodyfit::drape::toString(scene.collider.kind), k, steps,
					 secondsSince(t0));
	}
	return r;
}

/// Median of the first `n` entries (all when n <= 0 or larger).
double medianOfFirst(const std::vector<double>& v, int n)
{
	const std::size_t m = n > 0 ? std::min(v.size(), std::size_t(n)) : v.size();
	return median(std::vector<double>(v.begin(), v.begin() + std::ptrdiff_t(m)));
}

struct Costs
{
	double skin = 0.0, write = 0.0, coll = 0.0, step = 0.0;
	double body() const { return skin + write; }
};

/// Medians over the first `n` steps, then the median over the runs.
Costs costsOf(const std::vector<Run>& runs, int n)
{
	std::vector<double> skin, write, coll, step;
	for (const Run& r : runs)
	{
		skin.push_back(medianOfFirst(r.skinMs, n));
		write.push_back(medianOfFirst(r.writeMs, n));
		coll.push_back(medianOfFirst(r.collMs, n));
		step.push_back(medianOfFirst(r.stepMs, n));
	}
	return {median(skin), median(write), median(coll), median(step)};
}

/// Largest value of a sample field over the samples up to `steps`.
int maxOver(const Run& r, int steps, int Sample::*field)
{
	int m = 0;
	for (const Sample& s : r.samples)
		if (s.step <= steps)
			m = std::max(m, s.*field);
	return m;
}

double meanGap(const Run& r, int steps)
{
	double sum = 0.0;
	int n = 0;
	for (const Sample& s : r.samples)
		if (s.step <= steps && std::isfinite(s.gapMm))
		{
			sum += s.gapMm;
			++n;
		}
	return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

void writeSeries(const bodyfit_bench::Context& ctx, const Run& ours, const Run& bullet)
{
	if (ctx.outDir.empty())
		return;
	std::filesystem::create_directories(ctx.outDir);
	std::ofstream csv(std::filesystem::path(ctx.outDir) / "animated_series.csv");
	csv << "step,time_s,ours_nodes_inside,ours_contact_gap_mm,bullet_nodes_inside,bullet_contact_gap_mm,"
		   "ours_links_crossing,bullet_links_crossing\n";
	auto cell = [](double v) { return std::isfinite(v) ? fmt(v, 3) : std::string("NaN"); };
	for (std::size_t i = 0; i < ours.samples.size(); ++i)
	{
		const Sample& s = ours.samples[i];
		const bool both = i < bullet.samples.size() && bullet.samples[i].step == s.step;
		csv << s.step << "," << fmt(s.time, 4) << "," << s.inside << "," << cell(s.gapMm);
		if (both)
			csv << "," << bullet.samples[i].inside << "," << cell(bullet.samples[i].gapMm);
		else
			csv << ",NaN,NaN";
		csv << "," << s.crossing << "," << (both ? std::to_string(bullet.samples[i].crossing) : std::string("NaN"))
			<< "\n";
	}
}

void plotSeries(const bodyfit_bench::Context& ctx, double bulletEnd)
{
	std::ostringstream gp;
	gp << "set multiplot layout 3,1 title 'Walk clip, skirt: ours (bone-bound ellipsoids) vs Bullet (refitted "
		  "btBvhTriangleMeshShape, SDF_RS), every 5 steps'\n"
		  "set xlabel 'time (s)'\nset xrange [0:*]\n"
		  "set arrow 1 from "
	   << bulletEnd << ", graph 0 to " << bulletEnd
	   << ", graph 1 nohead dt 2 lc rgb '#1f77b4'\n"
		  "set ylabel 'cloth nodes inside the skinned body'\nset yrange [0:*]\n"
		  "plot 'animated_series.csv' skip 1 using 2:3 with lines lw 2 lc rgb '#d62728' title 'ours', \\\n"
		  "     '' skip 1 using 2:5 with linespoints pt 7 ps 0.5 lc rgb '#1f77b4' title 'Bullet (until the dashed line)'\n"
		  "set ylabel 'mean contact gap to the skin (mm)'\nset yrange [*:*]\n"
		  "plot 'animated_series.csv' skip 1 using 2:4 with lines lw 2 lc rgb '#d62728' title 'ours', \\\n"
		  "     '' skip 1 using 2:6 with linespoints pt 7 ps 0.5 lc rgb '#1f77b4' title 'Bullet (until the dashed line)'\n"
		  "set ylabel 'cloth edges crossing the skinned body'\nset yrange [0:*]\n"
		  "plot 'animated_series.csv' skip 1 using 2:7 with lines lw 2 lc rgb '#d62728' title 'ours', \\\n"
		  "     '' skip 1 using 2:8 with linespoints pt 7 ps 0.5 lc rgb '#1f77b4' title 'Bullet (until the dashed line)'\n"
		  "unset multiplot";
	plot(ctx, "animated", gp.str(), 1000, 1100);
}

} // namespace

BODYFIT_BENCH_SUITE_WITH_OPTIONS(animated,
								 "issue 13: walk-skirt scene, our bone-bound ellipsoids vs Bullet's refitted mesh: body "
								 "update and collision per step, nodes inside the skinned body, contact gap",
								 {"--steps", "N", "steps of ours (default: the scene's 516 = the 4.3 s clip; --quick 120)"},
								 {"--bullet-steps", "N", "steps of Bullet's refitted mesh (default 60, --quick 8)"})
{
	const char* tag = "animated";
	const std::string scenePath = std::string(BODYFIT_ASSET_DIR) + "/../scenes/animated_walk_skirt.json";
	bodyfit::drape::Scene scene = bodyfit::drape::loadScene(scenePath);
	const int steps = ctx.integer("--steps", ctx.quick ? 120 : scene.solver.steps, 1, 100000);
	const int bulletSteps = std::min(steps, ctx.integer("--bullet-steps", ctx.quick ? 8 : 60, 1, 100000));
	const int repeats = ctx.repeatsGiven ? ctx.repeats : (ctx.quick ? 1 : 3);
	progress(tag, "loading %s (rig, bind-pose fit, binding)", scenePath.c_str());
	const bodyfit::drape::BodyData body = bodyfit::drape::loadBody(scene);

	std::vector<Run> ours;
	for (int r = 0; r < repeats; ++r)
	{
		progress(tag, "ours, run %d/%d: %d steps", r + 1, repeats, steps);
		scene.collider.kind = ColliderKind::Ellipsoids;
		ours.push_back(runScene(scene, body, steps, tag));
	}
	progress(tag, "Bullet's refitted mesh: %d steps", bulletSteps);
	scene.collider.kind = ColliderKind::MeshBvh;
	const std::vector<Run> bullet = {runScene(scene, body, bulletSteps, tag)};

	const Costs oursAll = costsOf(ours, 0), oursWindow = costsOf(ours, bulletSteps), b = costsOf(bullet, 0);
	auto ratio = [](double a, double o) { return fmt(a / std::max(1e-9, o), 0) + "x"; };
	Table t({"collider", "steps", "nodes", "body update ms/step", "of which pose+skin+ellipsoids",
			 "of which shape write", "collision ms/step", "body update + collision ms/step", "step ms",
			 "max nodes inside skinned body", "max links crossing skinned body", "mean contact gap mm", "settings"});
	auto row = [&](const std::string& name, const Run& r, int n, const Costs& c) {
		t.addRow({name, fmtInt(n), fmtInt(r.nodes), fmt(c.body(), 3), fmt(c.skin, 3), fmt(c.write, 3), fmt(c.coll, 3),
				  fmt(c.body() + c.coll, 3), fmt(c.step, 2), fmtInt(maxOver(r, n, &Sample::inside)),
				  fmtInt(maxOver(r, n, &Sample::crossing)), fmt(meanGap(r, n), 2), r.settings});
	};
	row("ours (whole run)", ours.front(), steps, oursAll);
	row("ours (first " + std::to_string(bulletSteps) + " steps)", ours.front(), bulletSteps, oursWindow);
	row("Bullet refitted mesh", bullet.front(), bulletSteps, b);
	std::ostringstream notes;
	notes << "Scene demos/scenes/animated_walk_skirt.json (dt 1/120 s, 4 substeps: the body is posed 4 times per "
			 "step). Medians over the steps of a run, then over "
		  << repeats << " run(s) of ours; Bullet 1 run. Same first " << bulletSteps
		  << " steps: Bullet / ours = " << ratio(b.body(), oursWindow.body()) << " body update, "
		  << ratio(b.coll, oursWindow.coll) << " collision, " << ratio(b.body() + b.coll, oursWindow.body() + oursWindow.coll)
		  << " body update + collision, " << ratio(b.step, oursWindow.step)
		  << " whole step. A metrics sample, taken every 5 steps, costs (medians, ours) "
		  << fmt(median(ours.front().insideMs), 1)
		  << " ms for the inside count (the skinned body's inside test rebuilt for the pose) and "
		  << fmt(median(ours.front().contactMs), 1)
		  << " ms for the contact gap (its distance grid rebuilt). Nodes inside: cloth nodes inside the skinned body mesh of the instant (ray-parity vote), "
			 "largest over samples every 5 steps. Links crossing: cloth edges (links that are not bending links) with both ends "
			 "outside the skinned body whose "
			 "segment passes through it (a face cutting into a limb between nodes), largest over the samples. Contact gap: mean signed distance to the skin of the nodes in contact "
			 "(ours: the nodes the collider placed, held or pushed out in its last substep; Bullet: holding a rigid contact), averaged over the "
			 "samples. Time series: animated_series.csv, animated.png.";
	emitTable(ctx, "animated", "animated body: bone-bound ellipsoids vs Bullet's refitted mesh (walk, skirt)", t,
			  notes.str());
	writeSeries(ctx, ours.front(), bullet.front());
	plotSeries(ctx, bullet.front().samples.empty() ? 0.0 : bullet.front().samples.back().time);
	return 0;
}
