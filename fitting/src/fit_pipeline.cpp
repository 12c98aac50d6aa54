// The one fit pipeline: load -> repair -> segmentation (or the generic fallback) -> fit. See fit_pipeline.h.
#include "bodyfit/fitting/fit_pipeline.h"

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <sstream>
#include <utility>

namespace bodyfit
{
namespace
{

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// The fit JSON records the lengths as given when every one is a fraction of H; otherwise fitBody already recorded
/// them in metres (it ran with the resolved options).
void recordGivenLengths(const FitLengths& lengths, BodyFitParams& params)
{
	if (!lengths.allRelative())
		return;
	params.relativeToHeight = true;
	params.muTorso = lengths.muTorso.value;
	params.muLimbs = lengths.muLimbs.value;
	params.sigma = lengths.sigma.value;
	params.coverSpacing = params.coverTriangles ? lengths.coverSpacing.value : 0.0;
}

/// Stage times from the fit's own timings (the fitting stage contains the cover) plus load, repair, segmentation.
FitPipelineTimings stageTimings(const BodyFit& fit, double loadMs, double repairMs, double segmentationMs)
{
	FitPipelineTimings t;
	t.load = loadMs;
	t.repair = repairMs;
	t.segmentation = segmentationMs;
	t.cover = fit.timingMs("fitting.cover");
	t.fit = std::max(0.0, fit.timingMs("fitting") - t.cover);
	t.report = fit.timingMs("report");
	return t;
}

/// A fit file holds coordinates within kMaxFitCoordinate (ellipsoid_io.h): refuse, before fitting, a mesh whose fit
/// could not be written (typically millimetres without a scale).
void requireWithinFitRange(const LoadedMesh& loaded, const FitPipelineOptions& options, const std::string& name)
{
	const double reach = loaded.full.V.size() > 0 ? loaded.full.V.cwiseAbs().maxCoeff() : 0.0;
	if (!(reach > kMaxFitCoordinate))
		return;
	std::ostringstream msg;
	msg << name << ": the mesh reaches " << reach << " m from the origin (scale " << options.load.scale
		<< "), a fit file holds coordinates within " << kMaxFitCoordinate
		<< " m: millimetres need --scale 0.001, centimetres --scale 0.01";
	throw InvalidInputError(msg.str());
}

/// Segmentation and fit of a loaded mesh; `loadMs` = 0 for an in-memory mesh. Fills everything but the total.
FitPipelineResult fitLoaded(LoadedMesh loaded, const FitPipelineOptions& options, const std::string& sourceName,
							double loadMs)
{
	requireWithinFitRange(loaded, options, sourceName);
	FitPipelineResult result;
	result.loaded = std::move(loaded);
	const TriMesh& mesh = result.loaded.mesh;
	const Clock::time_point tSegmentation = Clock::now();
	result.segmentation = segmentForFit(mesh, options);
	const double segmentationMs = options.segment ? msSince(tSegmentation) : 0.0;
	result.fallback = options.segment && !result.segmentation.ok;

	result.fit = fitSegmented(mesh, result.segmentation, options, &result.resolved);
	result.fit.source.mesh = sourceName;
	// What loading found (several meshes, detached props, far from the origin: mesh_io.h) goes into the fit file
	// too, after the segmentation fallback warning (which stays first).
	const std::vector<std::string>& loadWarnings = result.loaded.report.warnings;
	result.fit.warnings.insert(result.fit.warnings.begin() + (result.fallback ? 1 : 0), loadWarnings.begin(),
		loadWarnings.end());
	const double repairMs = result.loaded.report.repairMs;
	std::vector<StageTiming> timings = {{"load", loadMs}, {"repair", repairMs}};
	if (options.segment)
		timings.push_back({"segmentation", segmentationMs});
	timings.insert(timings.end(), result.fit.timings.begin(), result.fit.timings.end());
	result.fit.timings = std::move(timings);
	result.timings = stageTimings(result.fit, loadMs, repairMs, segmentationMs);
	return result;
}

/// Sets the total and records it in the fit's timings.
void finish(FitPipelineResult& result, Clock::time_point t0)
{
	result.timings.total = msSince(t0);
	result.fit.setTiming("total", result.timings.total);
}

/// `fit` with its four lengths and their unit at the defaults (the state FitPipelineOptions::fit must be in).
BodyFitOptions withDefaultLengths(BodyFitOptions fit)
{
	const BodyFitOptions defaults;
	fit.muTorso = defaults.muTorso;
	fit.muLimbs = defaults.muLimbs;
	fit.sigma = defaults.sigma;
	fit.coverSpacing = defaults.coverSpacing;
	fit.relativeToHeight = defaults.relativeToHeight;
	return fit;
}

/// A length set in FitPipelineOptions::fit would be ignored silently: it is an error instead.
void requireLengthsNotInFit(const BodyFitOptions& fit)
{
	const BodyFitOptions d = withDefaultLengths(fit);
	if (fit.muTorso != d.muTorso || fit.muLimbs != d.muLimbs || fit.sigma != d.sigma ||
		fit.coverSpacing != d.coverSpacing || fit.relativeToHeight != d.relativeToHeight)
		throw InvalidInputError("fit pipeline: thresholds, sigma and cover spacing go in FitPipelineOptions::lengths, "
								"not in FitPipelineOptions::fit (FitPipelineOptions::from converts a BodyFitOptions)");
}

} // namespace

FitPipelineOptions FitPipelineOptions::from(const BodyFitOptions& fit)
{
	FitPipelineOptions o;
	o.fit = withDefaultLengths(fit);
	o.lengths = FitLengths::of(fit);
	return o;
}

std::string fallbackWarning(const std::string& failureReason)
{
	return "segmentation failed (" + failureReason +
		   "); fitted the whole mesh as one region (a body must stand along +y and face +z: check the up axis)";
}

Segmentation segmentForFit(const TriMesh& mesh, const FitPipelineOptions& options)
{
	if (!options.segment)
		return wholeBodySegmentation(mesh, "segmentation switched off");
	return segmentBody(mesh, options.segmentation);
}

BodyFit fitSegmented(const TriMesh& mesh, const Segmentation& segmentation, const FitPipelineOptions& options,
					 BodyFitOptions* resolvedOut)
{
	requireLengthsNotInFit(options.fit);
	std::string heightWarning;
	const double height = bodyHeight(mesh, options.fit.height, &heightWarning);
	const BodyFitOptions resolved = resolveLengths(options.fit, options.lengths, height);
	// A failed segmentation has Region::Whole labels: the generic one-region fit.
	BodyFit fit = fitBody(mesh, segmentation.labels, resolved);
	recordGivenLengths(options.lengths, fit.params);
	if (!heightWarning.empty())
		fit.warnings.insert(fit.warnings.begin(), heightWarning);
	if (options.segment && !segmentation.ok)
		fit.warnings.insert(fit.warnings.begin(), fallbackWarning(segmentation.failureReason));
	if (resolvedOut != nullptr)
		*resolvedOut = resolved;
	return fit;
}

FitPipelineResult fitMeshFile(const std::string& path, const FitPipelineOptions& options)
{
	requireLengthsNotInFit(options.fit); // before the work (fitSegmented checks again)
	const Clock::time_point t0 = Clock::now();
	LoadedMesh loaded = loadTriMesh(path, options.load);
	const double loadMs = std::max(0.0, msSince(t0) - loaded.report.repairMs);
	FitPipelineResult result =
		fitLoaded(std::move(loaded), options, std::filesystem::path(path).filename().string(), loadMs);
	finish(result, t0);
	return result;
}

FitPipelineResult fitMesh(const TriMesh& mesh, const FitPipelineOptions& options, const std::string& name)
{
	requireLengthsNotInFit(options.fit); // before the work (fitSegmented checks again)
	const Clock::time_point t0 = Clock::now();
	FitPipelineResult result = fitLoaded(repairMesh(mesh, options.load, name), options, name, 0.0);
	finish(result, t0);
	return result;
}

} // namespace bodyfit

namespace bodyfit
{

FitPipelineResult fitLoadedMesh(LoadedMesh loaded, const FitPipelineOptions& options, const std::string& name,
								double loadMs)
{
	requireLengthsNotInFit(options.fit);
	const Clock::time_point t0 = Clock::now();
	FitPipelineResult result = fitLoaded(std::move(loaded), options, name, loadMs);
	finish(result, t0);
	result.timings.total += loadMs;
	result.fit.setTiming("total", result.timings.total);
	return result;
}

} // namespace bodyfit
