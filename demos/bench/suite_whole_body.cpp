// Suite `whole-body`: the generic fitting path (the whole mesh as one region, no segmentation) on the bundled
// full-resolution bodies, plus the refinement variants on segmented input for comparison.
// Reported per body: ellipsoid count, the paper's mean radial error E (vertex-weighted) and the worst E_j, the true
// vertex-to-own-ellipsoid distance ("air gap", mean and max), and the median fitting time (true distances off, as in
// a timing run of bodyfit-fit without the report; wall and thread-CPU time), with the k-means / MVEE shares of one
// run. "gap" here is the distance from each vertex to the surface of its own ellipsoid, not the union air gap of
// docs/DESIGN.md sec. 5.
#include "bench/bench_common.h"

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/fit_quality.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/segmentation.h"


namespace
{

const std::vector<std::string>& fullBodies()
{
	static const std::vector<std::string> names = {"male_young.obj", "female_young.obj", "male_heavy.obj",
												   "female_short.obj"};
	return names;
}

std::string mm(double metres)
{
	return bodyfit_bench::fmt(metres * 1000.0, 2);
}

struct Measured
{
	bodyfit::BodyFit fit; ///< with true distances
	double medianMs = 0.0;
	double medianCpuMs = 0.0;
	bodyfit::FitQuality skin; ///< skin outside the union, sampled on the whole surface every 2 mm
};

/// Fits through the pipeline's fit step; `segmentation` is a successful one or the generic Region::Whole labels
/// (chosen on purpose here: no fallback warning).
Measured measure(const bodyfit_bench::Context& ctx, const bodyfit::TriMesh& mesh,
				 const bodyfit::Segmentation& segmentation, const bodyfit::BodyFitOptions& options)
{
	Measured m;
	bodyfit::FitPipelineOptions pipeline = bodyfit::FitPipelineOptions::from(options);
	pipeline.segment = segmentation.ok;
	m.fit = bodyfit::fitSegmented(mesh, segmentation, pipeline);
	pipeline.fit.trueDistance = false;
	m.medianMs = bodyfit_bench::medianMs(ctx.repeats, [&] { bodyfit::fitSegmented(mesh, segmentation, pipeline); });
	m.medianCpuMs = bodyfit_bench::medianCpuMs(ctx.repeats, [&] { bodyfit::fitSegmented(mesh, segmentation, pipeline); });
	bodyfit::FitQualityOptions q;
	q.computeAirGap = false;
	q.computeIoU = false;
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	for (const bodyfit::FittedEllipsoid& f : m.fit.ellipsoids)
		ellipsoids.push_back(f.ellipsoid);
	m.skin = bodyfit::measureFitQuality(bodyfit::FitQualityReference(mesh, 0), ellipsoids, q);
	return m;
}

void addRow(bodyfit_bench::Table& t, const std::string& body, const std::string& variant, int vertices,
			const Measured& m)
{
	using bodyfit_bench::fmt;
	using bodyfit_bench::fmtInt;
	const bodyfit::BodyFit& f = m.fit;
	t.addRow({body, variant, fmtInt(vertices), fmtInt(int(f.ellipsoids.size())), bodyfit::toString(f.status),
			  mm(f.meanRadialError()), mm(f.maxRadialError()), mm(f.meanDistance()), mm(f.maxDistance()),
			  fmt(m.medianMs, 1), fmt(m.medianCpuMs, 1), fmt(f.timingMs("fitting.kmeans"), 1),
			  fmt(f.timingMs("fitting.mvee"), 1), fmt(m.skin.skinSurfaceOutsideFraction * 100.0, 2),
			  fmt(m.skin.skinSurfaceOutsideMax * 1e3, 2)});
}

int runWholeBody(const bodyfit_bench::Context& ctx)
{
	using namespace bodyfit;
	using namespace bodyfit_bench;
	const std::vector<std::string> header = {"body", "variant", "vertices", "ellipsoids", "status", "mean E mm",
											 "worst E_j mm", "gap mean mm", "gap max mm", "median fit ms",
											 "median fit cpu ms", "k-means ms (1 run)", "mvee ms (1 run)",
											 "skin outside union %", "skin outside max mm"};
	const BodyFitOptions defaults;

	// 1. The generic path: the whole mesh as one region (bodyfit-fit --no-segmentation), default options.
	Table whole(header);
	for (const std::string& name : fullBodies())
	{
		std::cerr << "whole-body: " << name << "\n";
		const TriMesh mesh = loadTriMesh(std::string(BODYFIT_ASSET_DIR) + "/" + name).mesh;
		const Segmentation generic = wholeBodySegmentation(mesh, "generic path");
		addRow(whole, name, "whole (defaults)", mesh.vertexCount(), measure(ctx, mesh, generic, defaults));
	}
	std::cout << "## whole-body: generic path (no segmentation), mu_torso " << defaults.muTorso
			  << " H, budget " << defaults.maxEllipsoids << "\n\n";
	emit(ctx, "whole_body", whole);

	// 2. Refinement variants on male_young.obj: generic path at the budget, segmented input with bisecting
	//    K-means (default) and with the paper's K-means over the whole group after each split.
	Table variants(header);
	{
		const std::string name = "male_young.obj";
		const TriMesh mesh = loadTriMesh(std::string(BODYFIT_ASSET_DIR) + "/" + name).mesh;
		const Segmentation whole = wholeBodySegmentation(mesh, "generic path");
		BodyFitOptions budget = defaults;
		budget.muTorso = 1e-4; // unreachable: the count is the budget
		budget.maxEllipsoids = 100;
		addRow(variants, name, "whole (budget 100)", mesh.vertexCount(), measure(ctx, mesh, whole, budget));
		const Segmentation seg = segmentBody(mesh);
		if (seg.ok)
		{
			addRow(variants, name, "segmented (bisecting)", mesh.vertexCount(),
				   measure(ctx, mesh, seg, defaults));
			BodyFitOptions noCover = defaults;
			noCover.coverTriangles = false;
			addRow(variants, name, "segmented, no triangle cover", mesh.vertexCount(),
				   measure(ctx, mesh, seg, noCover));
			BodyFitOptions group = defaults;
			group.reclusterGroup = true;
			addRow(variants, name, "segmented (group k-means)", mesh.vertexCount(),
				   measure(ctx, mesh, seg, group));
		}
		else
			std::cerr << "whole-body: segmentation failed on " << name << ": " << seg.failureReason << "\n";
	}
	std::cout << "\n## whole-body: refinement variants on male_young.obj\n\n";
	return emit(ctx, "whole_body_variants", variants);
}

const bodyfit_bench::SuiteRegistrar kWholeBodyRegistrar(
	"whole-body", "generic fit (no segmentation) of the full-resolution bodies + refinement variants", &runWholeBody);

} // namespace
