#pragma once
/// \file fit_pipeline.h
/// The one fit pipeline every caller uses (bodyfit-fit, the scene runner, the benchmarks): mesh file or in-memory
/// mesh -> load and repair (mesh_io.h) -> segmentation (segmentation.h), or the generic one-region fit with a
/// warning when the mesh is not a standing human -> fit (body_fitter.h), with per-stage timings.
///
/// Units are resolved in one place, resolveLengths (body_fitter.h): each length-valued parameter (thresholds,
/// K-means pruning sigma, triangle-cover spacing) is given as a fraction of the body height H or in metres
/// (FitLengths) and becomes metres there, once H is known. The fit JSON records the lengths as given when all of
/// them are relative to H, and in metres otherwise.

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/segmentation.h"

#include <string>
#include <vector>

namespace bodyfit
{

struct FitPipelineOptions
{
	LoadOptions load; ///< up axis, scale, weld tolerance: for the file and for the repair of an in-memory mesh
	/// false: the generic path (the whole mesh as one region, on purpose: no warning).
	bool segment = true;
	SegmentationOptions segmentation;
	/// Every fit option except the lengths (budget, split rules, cover on/off, true distances, height override, ...).
	/// Its muTorso, muLimbs, sigma, coverSpacing and relativeToHeight must stay at their defaults (`lengths` holds
	/// them; the pipeline throws InvalidInputError otherwise, so that a length set here is never ignored silently).
	BodyFitOptions fit;
	FitLengths lengths; ///< each relative to H or in metres; defaults: BodyFitOptions' relative defaults

	/// Options that fit with `fit` as a caller of fitBody would: lengths taken from `fit` in its unit (and reset to
	/// their defaults in `fit`).
	static FitPipelineOptions from(const BodyFitOptions& fit);
};

/// Wall time of each stage in ms. Every stage is >= 0, and they sum to at most `total`.
struct FitPipelineTimings
{
	double load = 0.0;         ///< reading the file (0 for an in-memory mesh)
	double repair = 0.0;       ///< unit / up-axis conversion, weld, degenerate faces, components
	double segmentation = 0.0; ///< 0 when segmentation is switched off
	double fit = 0.0;          ///< refinement (K-means + MVEEs), without the triangle cover
	double cover = 0.0;        ///< the triangle cover (0 when off)
	double report = 0.0;       ///< the true-distance statistics of the final ellipsoids (0 when off)
	double total = 0.0;        ///< the whole pipeline call
};

struct FitPipelineResult
{
	LoadedMesh loaded;         ///< `mesh` (largest component, what was fitted), `full`, and the repair report
	/// The segmentation the fit used: a successful one, or Region::Whole labels with ok = false (switched off, or
	/// failed: then `fallback`).
	Segmentation segmentation;
	/// The segmentation was asked for and failed: the whole mesh was fitted as one region and the first warning
	/// says why.
	bool fallback = false;
	/// The fit. fit.warnings (what the fit JSON writes) holds every warning of the pipeline; fit.timings the stages
	/// in the fit JSON's keys ("load", "repair", "segmentation", "fitting", "fitting.cover", "report", ...).
	BodyFit fit;
	BodyFitOptions resolved;   ///< the options the fitter ran with, every length in metres
	FitPipelineTimings timings;

	const std::vector<std::string>& warnings() const { return fit.warnings; }
};

/// Loads `path` (options.load), repairs it, segments it (or falls back) and fits it. fit.source.mesh is the file
/// name without its directory.
/// \throws MeshLoadError / InvalidInputError as loadTriMesh and fitBody.
FitPipelineResult fitMeshFile(const std::string& path, const FitPipelineOptions& options = {});

/// The same from an in-memory mesh (repaired as loadTriMesh repairs a file; `name` goes into messages and
/// fit.source.mesh).
/// \throws InvalidInputError as repairMesh and fitBody.
FitPipelineResult fitMesh(const TriMesh& mesh, const FitPipelineOptions& options = {},
						  const std::string& name = "<memory>");

/// The segmentation step: segmentBody with options.segmentation, or Region::Whole labels when options.segment is
/// off. Never throws for a usable mesh (a failed segmentation has ok = false and its reason).
Segmentation segmentForFit(const TriMesh& mesh, const FitPipelineOptions& options);

/// The fit step on a repaired mesh and its segmentation (for callers that keep a loaded, segmented mesh, e.g. a
/// benchmark timing the fit alone): resolves the lengths for the body height, fits, records the lengths in the
/// JSON units (see the file comment) and, when options.segment is on and `segmentation` failed, fits the whole
/// mesh as one region with the fallback warning first in fit.warnings.
/// \throws InvalidInputError as fitBody (labels that do not match the mesh, bad options), or for a length set in
/// options.fit instead of options.lengths.
BodyFit fitSegmented(const TriMesh& mesh, const Segmentation& segmentation, const FitPipelineOptions& options,
					 BodyFitOptions* resolved = nullptr);

/// The warning of the non-human fallback for a segmentation failure reason.
std::string fallbackWarning(const std::string& failureReason);

} // namespace bodyfit
