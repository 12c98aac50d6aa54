// bodyfit-bench accuracy-time: what accuracy costs in time. For every bundled full-resolution body, a sweep of the
// refinement thresholds (coarse -> fine) and of the --max-ellipsoids budgets 16/32/64/128; per point: ellipsoid
// count, fit time, mean radial error (paper eq. 6), air gap mean/p95/max, skin outside the union, voxel IoU
// (fit_quality.h), and a short cloth patch drop over the head and shoulders with the ellipsoid collider on both
// surfaces: the paper's ellipsoid surface and the tight skin surface (issue 14; the fit's skin field baked for it,
// bake thread CPU time and the field's max error): collision ns per node per step, contact gap (mean, p95: the nodes
// the collider touched in its last substep) and nodes inside the real body mesh. (Bullet's mesh collider is compared
// in the garment-resolution, body-resolution and colliders suites: on this drop it costs minutes per body.)
#include "bench/study_common.h"

#include "bodyfit/fitting/fit_quality.h"
#include "bodyfit/fitting/skin_field.h"

namespace
{

using namespace bodyfit_study;

struct Setting
{
	std::string kind; ///< "threshold" or "budget"
	double muTorso;
	double muLimbs;
	int budget;
};

std::vector<Setting> settings(bool quick)
{
	std::vector<Setting> s;
	// Thresholds (fractions of the height H), torso/limbs ratio 4:3 as the defaults (1.2% / 0.9%), from coarse to
	// fine. The budget cap of the threshold sweep is high enough not to stop it.
	const double torso[] = {0.040, 0.030, 0.022, 0.016, 0.012, 0.009, 0.0075, 0.006, 0.005};
	for (size_t i = 0; i < sizeof torso / sizeof torso[0]; ++i)
	{
		if (quick && i % 2 == 1)
			continue;
		s.push_back({"threshold", torso[i], torso[i] * 0.75, 400});
	}
	// Budgets: thresholds far below reach, so the budget is what stops the refinement.
	for (int b : {16, 32, 64, 128})
		s.push_back({"budget", 0.001, 0.00075, b});
	return s;
}

/// Marks the Pareto-optimal rows (no other row of the same body is at least as good in both cost and error and
/// better in one).
std::vector<bool> paretoFront(const std::vector<double>& cost, const std::vector<double>& error)
{
	std::vector<bool> front(cost.size(), true);
	for (size_t i = 0; i < cost.size(); ++i)
		for (size_t j = 0; j < cost.size(); ++j)
			if (j != i && cost[j] <= cost[i] && error[j] <= error[i] && (cost[j] < cost[i] || error[j] < error[i]))
			{
				front[i] = false;
				break;
			}
	return front;
}

/// The study's settings for a run: repeats, the patch drop, the fit-quality sampling.
struct SweepConfig
{
	int fitRepeats;
	int drapeRepeats;
	PatchDrop drop;
	bodyfit::FitQualityOptions qopt;
	int voxelResolution;
};

SweepConfig sweepConfig(const bodyfit_bench::Context& ctx)
{
	SweepConfig c;
	c.fitRepeats = ctx.repeatsGiven ? ctx.repeats : (ctx.quick ? 1 : 3);
	c.drapeRepeats = ctx.repeatsGiven ? std::min(ctx.repeats, 3) : 1;
	c.drop.resolution = ctx.quick ? 25 : 31;
	c.drop.steps = ctx.quick ? 60 : 90;
	c.qopt.sampleSpacing = ctx.quick ? 0.008 : 0.005;
	c.voxelResolution = ctx.quick ? 96 : 128;
	return c;
}

/// What one setting gave on one body: its table row (pareto column empty), and the fit time and mean air gap the
/// Pareto front is made of.
struct SettingResult
{
	std::vector<std::string> row;
	double fitMs = 0.0;
	double airGap = 0.0;
	bool nanNodes = false; ///< a drop ended with NaN nodes
};

/// One setting on one body: the fit (timed), its quality, the patch drop on both surfaces (the skin field baked for
/// the tight one).
SettingResult measureSetting(const BodyAsset& asset, const LoadedBody& body,
							 const bodyfit::FitQualityReference& reference, const Setting& s, const SweepConfig& cfg)
{
	SettingResult result;
	double& fitMs = result.fitMs;
	const char* tag = "accuracy-time";
	const int fitRepeats = cfg.fitRepeats, drapeRepeats = cfg.drapeRepeats;
	const PatchDrop& drop = cfg.drop;
	const bodyfit::FitQualityOptions& qopt = cfg.qopt;
	bodyfit::BodyFitOptions o;
	o.muTorso = s.muTorso;
	o.muLimbs = s.muLimbs;
	o.maxEllipsoids = s.budget;
	o.maxSplits = 4000;
	o.trueDistance = false; // the fit_quality metrics below measure distances properly
	const bodyfit::BodyFit fit = timedFit(body, o, fitRepeats, &fitMs);
	const std::vector<bodyfit::Ellipsoid> ells = ellipsoidsOf(fit);
	const bodyfit::FitQuality q = bodyfit::measureFitQuality(reference, ells, qopt);
	bodyfit::drape::Scene scene =
		patchDropScene(assetPath(asset.full), body.mesh.full, bodyfit::drape::ColliderKind::Ellipsoids, drop);
	scene.collider.tightSurface = false;
	bodyfit::drape::BodyData bd = bodyData(body.mesh.full, ells, assetPath(asset.full), "sweep");
	const DrapeResult d = runDrape(scene, bd, drapeRepeats, drop.steps);
	// The tight surface: the same drop on the skin field of this fit, baked for the scene's skin offset.
	bodyfit::SkinFieldOptions bakeOptions;
	bakeOptions.skinOffset = scene.collider.skinOffset;
	bodyfit::SkinField field;
	const double bakeCpuMs = bodyfit_bench::medianCpuMs(
		fitRepeats, [&] { field = bodyfit::bakeSkinField(body.mesh.full, ells, bakeOptions); });
	bd.skinField = std::make_shared<const bodyfit::SkinField>(std::move(field));
	scene.collider.tightSurface = true;
	const DrapeResult tight = runDrape(scene, bd, drapeRepeats, drop.steps);
	result.nanNodes = d.nanNodes > 0 || tight.nanNodes > 0;
	progress(tag, "%s %s mu=%.4f/%.4f budget=%d: %zu ellipsoids, fit %.0f ms, gap %.1f mm, IoU %.3f, "
				  "%.0f ns/node/step",
			 asset.name.c_str(), s.kind.c_str(), s.muTorso, s.muLimbs, s.budget, ells.size(), fitMs,
			 q.airGapMean * 1e3, q.voxelIoU, d.collisionNsPerNodeStep);
	result.airGap = q.airGapMean;
	result.row = {asset.name, s.kind, fmt(s.muTorso, 4), fmt(s.muLimbs, 5), fmtInt(s.budget),
			fmtInt(long(ells.size())), fmt(fitMs, 1), fmt(fit.meanRadialError() * 1e3, 2),
			fmt(q.airGapMean * 1e3, 2), fmt(q.airGapP95 * 1e3, 2), fmt(q.airGapMax * 1e3, 1),
			fmt(q.unionInsideBodyFraction * 100, 2), fmt(q.skinOutsideFraction * 100, 2),
			fmt(q.skinOutsideMax * 1e3, 1), fmt(q.voxelIoU, 4),
			fmt(100.0 * double(q.intersectionVoxels) / double(std::max(1LL, q.bodyVoxels)), 1),
			fmt(100.0 * double(q.unionVoxels - q.intersectionVoxels) / double(std::max(1LL, q.unionVoxels)), 1),
			fmt(d.collisionNsPerNodeStep, 0), fmt(d.collisionMsPerStep, 3), fmt(d.msPerStep, 2), fmtInt(d.contactNodes),
			fmt(d.meanContactGapM * 1e3, 2), fmtInt(d.nodesInsideBody),
			fmtInt(d.maxNodesInsideBody), "", fmt(d.p95ContactGapM * 1e3, 2), fmt(bakeCpuMs, 1),
			fmt(bd.skinField->maxError * 1e3, 2), fmt(tight.collisionNsPerNodeStep, 0),
			fmtInt(tight.contactNodes), fmt(tight.meanContactGapM * 1e3, 2),
			fmt(tight.p95ContactGapM * 1e3, 2), fmtInt(tight.nodesInsideBody),
			fmtInt(tight.maxNodesInsideBody)};
	return result;
}

/// The notes under the table: how each column was measured.
std::string accuracyNotes(const SweepConfig& cfg)
{
	const int fitRepeats = cfg.fitRepeats, drapeRepeats = cfg.drapeRepeats, voxelResolution = cfg.voxelResolution;
	const PatchDrop& drop = cfg.drop;
	const bodyfit::FitQualityOptions& qopt = cfg.qopt;
	std::ostringstream notes;
	notes << "Fit time: median of " << fitRepeats << " fits (the \"fitting\" stage, after segmentation; single thread). "
		  << "Air gap: area-weighted over the union surface outside the body, samples every "
		  << qopt.sampleSpacing * 1e3 << " mm; union_under_skin_pct: share of the union surface inside the body mesh; "
		  << "skin outside: vertices with min zeta > 1; voxel IoU on " << voxelResolution
		  << " voxels along the body height. Cloth: " << drop.resolution << "x" << drop.resolution << " patch ("
		  << drop.size << " m) dropped from " << drop.drop * 100 << " cm above the head, " << drop.steps
		  << " steps of 1/120 s, " << drop.substeps << " substeps, " << drop.iterations
		  << " iterations; collision time = Bullet collision detection + our collider per step (median step of "
		  << drapeRepeats << " run(s)); contact gap: mean distance of the nodes in contact to the skin "
		  << "(negative = inside; contact: the nodes the collider placed, held or pushed out in its last substep); "
		  << "contact_gap_* and coll_ns_node_step: the ellipsoid surface (the paper's), tight_*: the tight skin "
		  << "surface on this fit's skin field (voxel " << bodyfit::SkinFieldOptions().voxel * 1e3
		  << " mm), bake_cpu_ms: its bake (thread CPU, median of " << fitRepeats
		  << "), field_max_error_mm: the field's recorded max error (SkinField::maxError), the tight surface's "
		  << "counterpart of the union's air gap; inside_body: nodes inside the real body mesh. pareto = 1: no other setting of the "
		  << "same body fits faster with a smaller mean air gap. body_covered_pct: share of the body's interior voxels "
		  << "inside the union; union_outside_body_pct: share of the union's voxels outside the body (ellipsoids of "
		  << "surface-patch clusters bulge out as much as they reach in, so finer fits cover less of the interior).";
	return notes.str();
}

/// gnuplot variables c0, c1, ... holding one colour per bundled body.
std::string bodyColours()
{
	std::string s;
	const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd"};
	int i = 0;
	for (const BodyAsset& b : bundledBodies())
	{
		(void)b;
		s += "c" + std::to_string(i) + "='" + colors[i] + "'\n";
		++i;
	}
	return s;
}

/// A plot command of column ycol against xcol of accuracy_time.csv, one line per body over its threshold sweep
/// (and, withBudgets, a dashed one over its budgets).
std::string perBodyPlot(const std::string& ycol, const std::string& xcol, bool withBudgets)
{
	std::string cmd = "plot ";
	int i = 0;
	for (const BodyAsset& b : bundledBodies())
	{
		const std::string sel = "(strcol(1) eq '" + b.name + "' && strcol(2) eq 'threshold' ? ";
		cmd += std::string(i ? ", \\\n     " : "") + "'accuracy_time.csv' skip 1 using " + xcol + ":" + sel + ycol +
			   " : NaN) with linespoints lc rgb c" + std::to_string(i) + " pt 7 title '" + b.name + " (thresholds)'";
		if (withBudgets)
			cmd += ", \\\n     'accuracy_time.csv' skip 1 using " + xcol + ":(strcol(1) eq '" + b.name +
				   "' && strcol(2) eq 'budget' ? " + ycol + " : NaN) with linespoints dt 2 lc rgb c" +
				   std::to_string(i) + " pt 5 title '" + b.name + " (budgets 16-128)'";
		++i;
	}
	return cmd;
}

/// The two surfaces side by side against the ellipsoid count (threshold sweeps; solid: the tight skin surface's
/// column, dashed: the ellipsoid surface's, if any).
std::string bothSurfacesPlot(const std::string& tightCol, const std::string& ellipsoidCol)
{
	std::string cmd = "plot ";
	int i = 0;
	for (const BodyAsset& b : bundledBodies())
	{
		const std::string sel = "(strcol(1) eq '" + b.name + "' && strcol(2) eq 'threshold' ? ";
		const std::string c = "c" + std::to_string(i);
		cmd += std::string(i ? ", \\\n     " : "") + "'accuracy_time.csv' skip 1 using 6:" + sel + tightCol +
			   " : NaN) with linespoints lc rgb " + c + " pt 7 title '" + b.name + " tight'";
		if (!ellipsoidCol.empty())
			cmd += ", \\\n     'accuracy_time.csv' skip 1 using 6:" + sel + ellipsoidCol +
				   " : NaN) with linespoints dt 2 lc rgb " + c + " pt 6 title '" + b.name + " ellipsoids'";
		++i;
	}
	return cmd;
}

/// Mean air gap against fit time: every setting, and each body's Pareto front.
std::string paretoPlot()
{
	std::string cmd = "set title 'Accuracy vs time: mean air gap vs fit time (open: all settings; line: Pareto front)'\n"
					  "set xlabel 'fit time (ms)'\nset ylabel 'mean air gap (mm)'\nset logscale x\nplot ";
	int i = 0;
	for (const BodyAsset& b : bundledBodies())
	{
		const std::string c = "c" + std::to_string(i);
		cmd += std::string(i ? ", \\\n     " : "") + "'accuracy_time.csv' skip 1 using 7:(strcol(1) eq '" + b.name +
			   "' ? $9 : NaN) with points pt 6 lc rgb " + c + " notitle, \\\n     " +
			   "'accuracy_time_pareto.csv' skip 1 using 3:(strcol(1) eq '" + b.name +
			   "' ? $4 : NaN) with linespoints pt 7 lw 2 lc rgb " + c + " title '" + b.name + " front'";
		++i;
	}
	return cmd;
}

/// The study's gnuplot figures (they read accuracy_time.csv and accuracy_time_pareto.csv; column numbers follow the
/// table's header).
void plotAccuracyTime(const bodyfit_bench::Context& ctx)
{
	const std::string series = bodyColours();
	plot(ctx, "accuracy_time_error",
		 series + "set title 'Fit error vs ellipsoid count (all bundled bodies)'\n"
				  "set xlabel 'ellipsoids'\nset ylabel 'mean air gap (mm)'\nset logscale x 2\n" +
			 perBodyPlot("$9", "6", true));
	plot(ctx, "accuracy_time_fit_time",
		 series + "set title 'Fit time vs ellipsoid count (fitting stage, median)'\n"
				  "set xlabel 'ellipsoids'\nset ylabel 'fit time (ms)'\nset logscale x 2\nset logscale y\n" +
			 perBodyPlot("$7", "6", true));
	plot(ctx, "accuracy_time_collision",
		 series + "set title 'Cloth collision cost vs ellipsoid count (patch drop, ellipsoid surface)'\n"
				  "set xlabel 'ellipsoids'\nset ylabel 'collision ns / node / step'\nset logscale x 2\n"
				  "set yrange [0:*]\n" +
			 perBodyPlot("$18", "6", true));
	// One plot per measure: file name, title, y label, further axis settings, the tight and the ellipsoid column.
	const struct
	{
		const char* name;
		const char* title;
		const char* ylabel;
		const char* axes;
		const char* tightCol;
		const char* ellipsoidCol; ///< "": the measure has no ellipsoid counterpart
	} surfacePlots[] = {
		{"accuracy_time_contact_gap", "Mean contact gap to the skin vs ellipsoid count (patch drop)",
		 "mean contact gap (mm)", "set yrange [0:*]\n", "$31", "$22"},
		{"accuracy_time_contact_gap_p95", "p95 contact gap to the skin vs ellipsoid count (patch drop)",
		 "p95 contact gap (mm)", "set yrange [0:*]\n", "$32", "$26"},
		{"accuracy_time_surface_error", "Surface to skin: union mean air gap (dashed) vs skin field max error (solid)",
		 "mm", "set logscale y\n", "$28", "$9"},
		{"accuracy_time_tight_collision", "Cloth collision cost vs ellipsoid count, both surfaces (patch drop)",
		 "collision ns / node / step", "set yrange [0:*]\n", "$29", "$18"},
		{"accuracy_time_bake", "Skin field bake (thread CPU) vs ellipsoid count", "bake ms", "set yrange [0:*]\n",
		 "$27", ""},
	};
	for (const auto& p : surfacePlots)
		plot(ctx, p.name,
			 series + "set title '" + p.title + "'\nset xlabel 'ellipsoids'\nset ylabel '" + p.ylabel +
				 "'\nset logscale x 2\n" + p.axes + bothSurfacesPlot(p.tightCol, p.ellipsoidCol));
	plot(ctx, "accuracy_time_pareto", series + paretoPlot());
}

int runAccuracyTime(const bodyfit_bench::Context& ctx)
{
	const char* tag = "accuracy-time";
	const SweepConfig cfg = sweepConfig(ctx);
	const std::vector<Setting> sweep = settings(ctx.quick);

	Table t({"body", "kind", "mu_torso", "mu_limbs", "budget", "ellipsoids", "fit_ms", "radial_error_mm",
			 "air_gap_mean_mm", "air_gap_p95_mm", "air_gap_max_mm", "union_under_skin_pct", "skin_outside_pct",
			 "skin_outside_max_mm", "voxel_iou", "body_covered_pct", "union_outside_body_pct", "coll_ns_node_step", "coll_ms_step", "step_ms", "contact_nodes",
			 "contact_gap_mm", "inside_body_end", "inside_body_max", "pareto", "contact_gap_p95_mm", "bake_cpu_ms",
			 "field_max_error_mm", "tight_coll_ns_node_step", "tight_contact_nodes", "tight_contact_gap_mm",
			 "tight_contact_gap_p95_mm", "tight_inside_body_end", "tight_inside_body_max"});
	Table paretoRows({"body", "ellipsoids", "fit_ms", "air_gap_mean_mm"});
	int rc = 0;
	for (const BodyAsset& asset : bundledBodies())
	{
		const auto tb = std::chrono::steady_clock::now();
		progress(tag, "%s: load + segmentation", asset.full.c_str());
		const LoadedBody body = loadBody(asset.full, 1);
		const bodyfit::FitQualityReference reference(body.mesh.full, cfg.voxelResolution);
		progress(tag, "%s: fit-quality reference %.0f ms (%lld body voxels, %.1f mm)", asset.full.c_str(),
				 reference.milliseconds(), reference.bodyVoxelCount(), reference.voxelSize() * 1e3);

		std::vector<std::vector<std::string>> rows;
		std::vector<double> cost, error;
		for (const Setting& s : sweep)
		{
			SettingResult r = measureSetting(asset, body, reference, s, cfg);
			if (r.nanNodes)
				rc = 1;
			rows.push_back(std::move(r.row));
			cost.push_back(r.fitMs);
			error.push_back(r.airGap);
		}
		// Pareto front of fit time vs mean air gap (per body), also listed by increasing fit time for the plot.
		const std::vector<bool> front = paretoFront(cost, error);
		std::vector<size_t> order;
		for (size_t i = 0; i < rows.size(); ++i)
		{
			rows[i][24] = front[i] ? "1" : "0"; // the pareto column
			t.addRow(rows[i]);
			if (front[i])
				order.push_back(i);
		}
		std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return cost[a] < cost[b]; });
		for (size_t i : order)
			paretoRows.addRow({asset.name, rows[i][5], fmt(cost[i], 2), fmt(error[i] * 1e3, 3)});

		progress(tag, "%s done in %.0f s", asset.name.c_str(), secondsSince(tb));
	}

	emitTable(ctx, "accuracy_time", "accuracy-time: thresholds and budgets on every bundled body", t,
			  accuracyNotes(cfg));
	emitTable(ctx, "accuracy_time_pareto", "accuracy-time: Pareto-optimal settings (fit time vs mean air gap)",
			  paretoRows);
	plotAccuracyTime(ctx);
	return rc;
}

const bodyfit_bench::SuiteRegistrar registerAccuracyTime(
	"accuracy-time",
	"threshold sweep (9 settings, --quick 5) + budgets 16/32/64/128 on the 4 bodies: count, fit time, errors, "
	"air gap, IoU, skin field bake; cloth collision cost and contact gap on the ellipsoid and the tight surface "
	"(fits: median of 3, --quick 1)",
	&runAccuracyTime);

} // namespace
