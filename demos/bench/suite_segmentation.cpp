// Suite `segmentation`: semantic segmentation of every bundled body (A-pose, full and decimated) and the posed ones.
// Per body: median segmentation time, feature-point sanity (each hand point against the arm vertex farthest from
// the armpit, geodesically), region sizes, connectivity, agreement with the A-pose labels of the same subject
// (posed bodies share its vertex order), and the geodesic solver's own cost.
#include "bench/bench_common.h"

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/geodesics.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/segmentation.h"

#include <Eigen/Geometry>

#include <cmath>
#include <map>
#include <random>

namespace
{

const std::vector<std::string>& bodyNames()
{
	static const std::vector<std::string> names = {"male_young.obj", "male_young.4508v.obj", "female_young.obj",
		"female_young.8650v.obj", "male_heavy.obj", "male_heavy.8750v.obj", "female_short.obj",
		"female_short.8850v.obj", "posed/male_young.tpose.obj", "posed/male_young.walk.obj",
		"posed/female_young.tpose.obj", "posed/female_young.walk.obj"};
	return names;
}

/// Geodesic distance from the armpit to the hand point divided by the largest one over the arm's vertices
/// (1 = the hand point is the vertex farthest along its arm).
double handFarthestRatio(const bodyfit::TriMesh& mesh, const bodyfit::Segmentation& seg, bool left)
{
	using bodyfit::Region;
	const int armpit = left ? seg.features.armpitLeft : seg.features.armpitRight;
	const int hand = left ? seg.features.handLeft : seg.features.handRight;
	const Region upper = left ? Region::ArmUpperLeft : Region::ArmUpperRight;
	const Region lower = left ? Region::ArmLowerLeft : Region::ArmLowerRight;
	std::vector<double> d;
	bodyfit::GeodesicSolver(mesh).compute(armpit, d);
	double farthest = 0.0;
	for (int v = 0; v < mesh.vertexCount(); ++v)
		if (seg.labels[size_t(v)] == upper || seg.labels[size_t(v)] == lower)
			farthest = std::max(farthest, d[size_t(v)]);
	return farthest > 0.0 ? d[size_t(hand)] / farthest : 0.0;
}

std::string subjectOf(const std::string& name)
{
	const size_t slash = name.find('/');
	const std::string file = slash == std::string::npos ? name : name.substr(slash + 1);
	return file.substr(0, file.find('.'));
}

} // namespace

BODYFIT_BENCH_SUITE(segmentation, "semantic segmentation of every bundled and posed body: time, feature points, regions")
{
	using namespace bodyfit;
	using namespace bodyfit_bench;
	Table summary({"body", "vertices", "ok", "median ms", "median CPU ms", "hand L farthest", "hand R farthest", "arm L/H", "leg L/H",
		"elbow frac", "knee frac", "neck/H", "smallest region", "largest region", "pieces", "agree A-pose"});
	std::vector<std::string> regionHeader = {"body"};
	for (int r = 0; r < kBodyRegionCount; ++r)
		regionHeader.push_back(regionName(Region(r)));
	Table regions(regionHeader);
	std::map<std::string, std::vector<Region>> restLabels;
	for (const std::string& name : bodyNames())
	{
		std::cerr << "segmentation: " << name << "\n";
		const TriMesh mesh = loadTriMesh(std::string(BODYFIT_ASSET_DIR) + "/" + name).mesh;
		Segmentation seg;
		const double ms = medianMs(ctx.repeats, [&] { seg = segmentBody(mesh); });
		const double cpuMs = medianCpuMs(ctx.repeats, [&] { seg = segmentBody(mesh); });
		if (!seg.ok)
		{
			summary.addRow({name, fmtInt(mesh.vertexCount()), "no: " + seg.failureReason, fmt(ms, 2), fmt(cpuMs, 2),
				"", "", "", "", "", "", "", "", "", "", ""});
			continue;
		}
		const std::vector<int> counts = regionVertexCounts(seg.labels);
		const std::vector<int> pieces = regionComponentCounts(mesh, seg.labels);
		const auto [smallest, largest] = std::minmax_element(counts.begin(), counts.begin() + kBodyRegionCount);
		const int maxPieces = *std::max_element(pieces.begin(), pieces.begin() + kBodyRegionCount);
		std::string agree = "-";
		const std::string subject = subjectOf(name);
		if (name.find('/') == std::string::npos && name.find("v.obj") == std::string::npos)
			restLabels[subject] = seg.labels;
		else if (name.find('/') != std::string::npos && restLabels.count(subject))
		{
			const std::vector<Region>& rest = restLabels[subject];
			int same = 0;
			for (size_t i = 0; i < rest.size(); ++i)
				same += rest[i] == seg.labels[i] ? 1 : 0;
			agree = fmt(100.0 * same / double(rest.size()), 1) + "%";
		}
		const SegmentationMeasures& m = seg.measures;
		const double H = seg.height;
		summary.addRow({name, fmtInt(mesh.vertexCount()), "yes", fmt(ms, 2), fmt(cpuMs, 2),
			fmt(handFarthestRatio(mesh, seg, true), 4),
			fmt(handFarthestRatio(mesh, seg, false), 4),
			fmt(m.armLengthLeft / H, 3) + " / " + fmt(m.armLengthRight / H, 3),
			fmt(m.legLengthLeft / H, 3) + " / " + fmt(m.legLengthRight / H, 3),
			fmt(m.elbowDistanceLeft / m.armLengthLeft, 3) + " / " + fmt(m.elbowDistanceRight / m.armLengthRight, 3),
			fmt(m.kneeDistanceLeft / m.legLengthLeft, 3) + " / " + fmt(m.kneeDistanceRight / m.legLengthRight, 3),
			fmt(m.neckDistance / H, 3), fmtInt(*smallest), fmtInt(*largest),
			maxPieces == 1 ? "all 1" : "max " + fmtInt(maxPieces), agree});
		std::vector<std::string> row = {name};
		for (int r = 0; r < kBodyRegionCount; ++r)
			row.push_back(fmtInt(counts[size_t(r)]));
		regions.addRow(row);
	}
	std::cout << "\nSegmentation (time = median of " << ctx.repeats << " runs, single thread; wall clock and thread CPU "
			  << "time). 'hand farthest' = "
			  << "geodesic armpit->hand point / max over the arm's vertices (1 = the hand point is the farthest).\n\n";
	emit(ctx, "segmentation", summary);
	std::cout << "\nVertices per region\n\n";
	emit(ctx, "segmentation_regions", regions);

	// The geodesic solver alone on the full-resolution body.
	const TriMesh mesh = loadTriMesh(std::string(BODYFIT_ASSET_DIR) + "/male_young.obj").mesh;
	Table geo({"face diagonals", "graph edges", "build ms", "Dijkstra ms (one source)"});
	for (bool diagonals : {false, true})
	{
		GeodesicOptions options;
		options.faceDiagonals = diagonals;
		int edges = 0;
		const double buildMs = medianMs(ctx.repeats, [&] { edges = GeodesicSolver(mesh, options).edgeCount(); });
		GeodesicSolver solver(mesh, options);
		std::vector<double> d;
		std::vector<int> pred;
		const double runMs = medianMs(ctx.repeats, [&] { solver.compute(0, d, &pred); });
		geo.addRow({diagonals ? "yes" : "no", fmtInt(edges), fmt(buildMs, 2), fmt(runMs, 2)});
	}
	std::cout << "\nGeodesic solver on male_young.obj (" << mesh.vertexCount() << " vertices)\n\n";
	return emit(ctx, "segmentation_geodesics", geo);
}
