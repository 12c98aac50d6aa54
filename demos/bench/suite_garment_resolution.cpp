// bodyfit-bench garment-resolution (paper Fig. 12): a 1 m cloth patch draped over the head and shoulders of the
// full-resolution male_young body at ~1k ... ~100k nodes, the same drop with both colliders: per-step collision time of our ellipsoid collider and of Bullet's mesh collider (btBvhTriangleMeshShape), and their ratio
// (goal: >= 50x at every size).
#include "bench/study_common.h"

namespace
{

using namespace bodyfit_study;

int runGarmentResolution(const bodyfit_bench::Context& ctx)
{
	const char* tag = "garment-resolution";
	const int ellRepeatsSmall = ctx.repeatsGiven ? ctx.repeats : 3; // cloths below 20k nodes
	const int steps = ctx.quick ? 16 : 24;
	const double meshBudgetS = ctx.quick ? 40.0 : 90.0;
	std::vector<int> resolutions = {32, 71, 100, 158, 224, 317}; // 1k, 5k, 10k, 25k, 50k, 100k nodes
	if (ctx.quick)
		resolutions = {32, 100, 224, 317};

	const BodyAsset& asset = bundledBodies()[0]; // male_young
	progress(tag, "%s: load, segmentation, fit", asset.full.c_str());
	const LoadedBody body = loadBody(asset.full, 1);
	bodyfit::BodyFitOptions o;
	o.trueDistance = false;
	const bodyfit::BodyFit fit =
		bodyfit::fitSegmented(body.mesh.mesh, body.segmentation, bodyfit::FitPipelineOptions::from(o));
	const bodyfit::drape::BodyData ellBody =
		bodyData(body.mesh.full, ellipsoidsOf(fit), assetPath(asset.full), "fit at default thresholds");
	const bodyfit::drape::BodyData meshBody = bodyData(body.mesh.full, {}, assetPath(asset.full), "none");

	Table t({"resolution", "nodes", "ell_coll_ms_step", "ell_coll_ns_node_step", "ell_step_ms", "ell_inside_body",
			 "mesh_coll_ms_step", "mesh_coll_ns_node_step", "mesh_step_ms", "mesh_inside_body", "ratio",
			 "contact_nodes"});
	double meshPrevS = 0.0;
	int meshPrevNodes = 0;
	double minRatio = 1e300;
	for (int res : resolutions)
	{
		const auto t0 = std::chrono::steady_clock::now();
		PatchDrop drop;
		drop.size = 1.0;
		drop.resolution = res;
		drop.substeps = 1;
		drop.sampleEvery = 1;
		drop.steps = steps;
		bodyfit::drape::Scene scene =
			patchDropScene(assetPath(asset.full), body.mesh.full, bodyfit::drape::ColliderKind::Ellipsoids, drop);
		progress(tag, "%dx%d patch: %d steps per run", res, res, steps);
		// Large cloths: Bullet's own soft-body solve dominates the wall time, one run (of `steps` steps) is enough.
		const int ellRepeats = res * res < 20000 ? ellRepeatsSmall : (ctx.repeatsGiven ? ctx.repeats : 1);
		const DrapeResult ell = runDrape(scene, ellBody, ellRepeats, steps);
		progress(tag, "  ellipsoids: collision %.3f ms/step (%d nodes, %d in contact)", ell.collisionMsPerStep,
				 ell.nodes, ell.contactNodes);
		const double predicted = meshPrevNodes > 0 ? meshPrevS * double(ell.nodes) / meshPrevNodes : 0.0;
		std::vector<std::string> meshCells = {"skipped", "-", "-", "-", "-"};
		if (predicted <= meshBudgetS)
		{
			scene.collider.kind = bodyfit::drape::ColliderKind::MeshBvh;
			const auto tm = std::chrono::steady_clock::now();
			const DrapeResult mesh = runDrape(scene, meshBody, 1, steps);
			meshPrevS = secondsSince(tm);
			meshPrevNodes = ell.nodes;
			const double ratio = mesh.collisionMsPerStep / ell.collisionMsPerStep;
			minRatio = std::min(minRatio, ratio);
			meshCells = {fmt(mesh.collisionMsPerStep, 1), fmt(mesh.collisionNsPerNodeStep, 0), fmt(mesh.msPerStep, 1),
						 fmtInt(mesh.nodesInsideBody), fmt(ratio, 0)};
			progress(tag, "  mesh-bvh: collision %.1f ms/step (%.0f s for %d steps), ratio %.0f",
					 mesh.collisionMsPerStep, meshPrevS, steps, ratio);
		}
		else
		{
			meshCells[0] = "skipped (~" + fmt(predicted, 0) + " s predicted)";
			progress(tag, "  mesh-bvh skipped: ~%.0f s predicted from the previous size", predicted);
		}
		t.addRow({fmtInt(res) + "x" + fmtInt(res), fmtInt(ell.nodes), fmt(ell.collisionMsPerStep, 3),
				  fmt(ell.collisionNsPerNodeStep, 0), fmt(ell.msPerStep, 2), fmtInt(ell.nodesInsideBody),
				  meshCells[0], meshCells[1], meshCells[2], meshCells[3], meshCells[4], fmtInt(ell.contactNodes)});
		progress(tag, "%dx%d done in %.0f s", res, res, secondsSince(t0));
	}
	std::ostringstream notes;
	notes << "Body: male_young.obj (" << body.mesh.full.vertexCount() << " vertices, " << fit.ellipsoids.size()
		  << " ellipsoids at the default thresholds). Patch 1 m x 1 m dropped from 1 cm above the head, "
		  << steps
		  << " steps of 1/120 s (1 substep, 10 iterations): the cloth lands on the head and drapes over the "
			 "shoulders. Collision time per step = Bullet's collision detection + our collider, median over the "
			 "steps; ellipsoids: median of "
		  << ellRepeatsSmall << " runs below 20k nodes, 1 run above; mesh-bvh: 1 run; a size is skipped when the previous one predicts more than "
		  << meshBudgetS << " s for the run. Smallest ratio measured: "
		  << (minRatio < 1e300 ? fmt(minRatio, 0) : std::string("-")) << "x (goal >= 50x).";
	emitTable(ctx, "garment_resolution", "garment-resolution (paper Fig. 12): per-step collision time vs cloth nodes",
			  t, notes.str());
	plot(ctx, "garment_resolution",
		 "set title 'Collision time per step vs cloth resolution (patch on head and shoulders)'\n"
		 "set xlabel 'cloth nodes'\nset ylabel 'collision ms / step'\nset logscale x\nset logscale y\n"
		 "set y2label 'ratio mesh / ellipsoids'\nset y2tics\nset logscale y2\n"
		 "plot 'garment_resolution.csv' skip 1 using 2:3 with linespoints pt 7 lw 2 title 'ellipsoid collider (ours)', "
		 "\\\n     '' skip 1 using 2:($7 > 0 ? $7 : NaN) with linespoints pt 5 lw 2 title 'Bullet mesh collider', \\\n"
		 "     '' skip 1 using 2:($11 > 0 ? $11 : NaN) axes x1y2 with linespoints dt 2 pt 4 title 'ratio (right axis)'");
	return 0;
}

const bodyfit_bench::SuiteRegistrar registerGarmentResolution(
	"garment-resolution",
	"paper Fig. 12: cloth patch at 1k..100k nodes on male_young, per-step collision time of both colliders and the "
	"ratio",
	&runGarmentResolution);

} // namespace
