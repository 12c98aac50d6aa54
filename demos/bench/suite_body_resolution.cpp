// bodyfit-bench body-resolution (paper Fig. 11): the same cloth scene (the bundled skirt dropped onto the hips) with
// the body at 4.5k ... 214k vertices (the decimated body, the full one, and midpoint subdivisions of the full one).
// Per-step collision time of our ellipsoid collider (the body refitted at every resolution) and of Bullet's mesh
// collider (btBvhTriangleMeshShape, Bullet's default soft-body path). Goal: ours flat within 10%.
#include "bench/study_common.h"

#include "bodyfit/fitting/subdivision.h"

namespace
{

using namespace bodyfit_study;

struct Resolution
{
	std::string label;
	std::string file; ///< asset
	int subdivisions; ///< midpoint subdivisions applied after loading
};

int runBodyResolution(const bodyfit_bench::Context& ctx)
{
	const char* tag = "body-resolution";
	const int ellRepeats = ctx.repeatsGiven ? ctx.repeats : (ctx.quick ? 3 : 5);
	const int steps = ctx.quick ? 4 : 8;
	// Bullet's mesh path is skipped at a resolution when the previous one predicts more than this per run.
	const double meshBudgetS = ctx.quick ? 40.0 : 150.0;
	const std::vector<Resolution> series = {{"decimated", "male_young.4508v.obj", 0},
											{"full", "male_young.obj", 0},
											{"full x4 (midpoint)", "male_young.obj", 1},
											{"full x16 (midpoint)", "male_young.obj", 2}};
	const std::string scenePath = std::string(BODYFIT_ASSET_DIR) + "/../scenes/skirt_drop.json";

	Table t({"body", "vertices", "triangles", "ellipsoids", "seg_ms", "fit_ms", "ell_coll_ms_step", "ell_coll_ns_node_step",
			 "ell_step_ms", "ell_inside_body", "mesh_coll_ms_step", "mesh_coll_ns_node_step", "mesh_step_ms",
			 "mesh_inside_body", "ratio", "nodes"});
	double meshPrevS = 0.0;
	int meshPrevTriangles = 0;
	double ellFirst = 0.0, ellMin = 1e300, ellMax = 0.0;
	for (const Resolution& r : series)
	{
		const auto t0 = std::chrono::steady_clock::now();
		bodyfit::LoadedMesh loaded = bodyfit::loadTriMesh(assetPath(r.file));
		for (int k = 0; k < r.subdivisions; ++k)
		{
			loaded.mesh = bodyfit::midpointSubdivide(loaded.mesh);
			loaded.full = bodyfit::midpointSubdivide(loaded.full);
		}
		const bodyfit::TriMesh& mesh = loaded.mesh;
		progress(tag, "%s (%s): %d vertices, segmentation + fit", r.file.c_str(), r.label.c_str(), mesh.vertexCount());
		const auto ts = std::chrono::steady_clock::now();
		const bodyfit::Segmentation seg = bodyfit::segmentBody(mesh);
		const double segMs = secondsSince(ts) * 1e3;
		if (!seg.ok)
			throw bodyfit::InvalidInputError(r.file + ": segmentation failed: " + seg.failureReason);
		bodyfit::BodyFitOptions o;
		o.trueDistance = false;
		const bodyfit::BodyFit fit = bodyfit::fitSegmented(mesh, seg, bodyfit::FitPipelineOptions::from(o));

		bodyfit::drape::Scene scene = bodyfit::drape::loadScene(scenePath);
		scene.garment.mesh = assetPath("male_young.skirt.obj");
		scene.solver.substeps = 1;
		scene.sampleEvery = 1;
		scene.collider.kind = bodyfit::drape::ColliderKind::Ellipsoids;
		const bodyfit::drape::BodyData ellBody =
			bodyData(loaded.full, ellipsoidsOf(fit), assetPath(r.file), "fit at default thresholds");
		const DrapeResult ell = runDrape(scene, ellBody, ellRepeats, steps);
		ellFirst = ellFirst > 0.0 ? ellFirst : ell.collisionMsPerStep;
		ellMin = std::min(ellMin, ell.collisionMsPerStep);
		ellMax = std::max(ellMax, ell.collisionMsPerStep);
		progress(tag, "  ellipsoids (%zu): collision %.3f ms/step", fit.ellipsoids.size(), ell.collisionMsPerStep);

		const int triangles = loaded.full.faceCount();
		const double predicted = meshPrevTriangles > 0 ? meshPrevS * double(triangles) / meshPrevTriangles : 0.0;
		std::vector<std::string> meshCells = {"skipped", "-", "-", "-", "-"};
		if (predicted <= meshBudgetS)
		{
			scene.collider.kind = bodyfit::drape::ColliderKind::MeshBvh;
			const bodyfit::drape::BodyData meshBody = bodyData(loaded.full, {}, assetPath(r.file), "none");
			const auto tm = std::chrono::steady_clock::now();
			const DrapeResult mesh = runDrape(scene, meshBody, 1, steps);
			meshPrevS = secondsSince(tm);
			meshPrevTriangles = triangles;
			meshCells = {fmt(mesh.collisionMsPerStep, 1), fmt(mesh.collisionNsPerNodeStep, 0), fmt(mesh.msPerStep, 1),
						 fmtInt(mesh.nodesInsideBody), fmt(mesh.collisionMsPerStep / ell.collisionMsPerStep, 0)};
			progress(tag, "  mesh-bvh: collision %.1f ms/step (%.0f s for %d steps)", mesh.collisionMsPerStep,
					 meshPrevS, steps);
		}
		else
		{
			meshCells[0] = "skipped (~" + fmt(predicted, 0) + " s predicted)";
			progress(tag, "  mesh-bvh skipped: ~%.0f s predicted from the previous resolution", predicted);
		}
		t.addRow({r.label, fmtInt(mesh.vertexCount()), fmtInt(triangles), fmtInt(long(fit.ellipsoids.size())),
				  fmt(segMs, 0), fmt(fit.timingMs("fitting"), 0), fmt(ell.collisionMsPerStep, 3),
				  fmt(ell.collisionNsPerNodeStep, 0), fmt(ell.msPerStep, 2), fmtInt(ell.nodesInsideBody),
				  meshCells[0], meshCells[1], meshCells[2], meshCells[3], meshCells[4], fmtInt(ell.nodes)});
		progress(tag, "%s done in %.0f s", r.label.c_str(), secondsSince(t0));
	}
	std::ostringstream notes;
	notes << "Scene: demos/scenes/skirt_drop.json with male_young's skirt (" << steps
		  << " steps of 1/120 s, 1 substep); the body is refitted (default thresholds) at every resolution. Collision "
			 "time per step = Bullet's collision detection + our collider, median over the steps; ellipsoids: median of "
		  << ellRepeats
		  << " runs; mesh-bvh: 1 run (Bullet's concave soft-body path costs up to seconds per step; a resolution is "
			 "skipped when the previous one predicts more than "
		  << meshBudgetS << " s for the run). Our collision time varies by "
		  << fmt(100.0 * (ellMax - ellMin) / ellMin, 0)
		  << "% (max/min - 1) across the resolutions (goal: within 10%).";
	emitTable(ctx, "body_resolution", "body-resolution (paper Fig. 11): per-step collision time vs body vertices", t,
			  notes.str());
	plot(ctx, "body_resolution",
		 "set title 'Collision time per step vs body resolution (skirt drop)'\n"
		 "set xlabel 'body vertices'\nset ylabel 'collision ms / step'\nset logscale x\nset logscale y\n"
		 "plot 'body_resolution.csv' skip 1 using 2:7 with linespoints pt 7 lw 2 title 'ellipsoid collider (ours)', \\\n"
		 "     '' skip 1 using 2:($11 > 0 ? $11 : NaN) with linespoints pt 5 lw 2 title 'Bullet mesh collider "
		 "(btBvhTriangleMeshShape)'");
	return 0;
}

const bodyfit_bench::SuiteRegistrar registerBodyResolution(
	"body-resolution",
	"paper Fig. 11: skirt drop on male_young at 4.5k/13k/54k/214k vertices, per-step collision time, ellipsoids vs "
	"Bullet's mesh collider",
	&runBodyResolution);

} // namespace
