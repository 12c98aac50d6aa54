#pragma once
/// \file body_fitter.h
/// The fitting pipeline after segmentation: initial clusters per region, pruned bisecting K-means refinement with
/// MVEEs (paper sec. 3.3, made precise in docs/DESIGN.md sec. 2), and the error report of the result.
///
/// Groups. Torso regions form one group: k starts at the number of torso parts present (6 after a successful
/// segmentation), initialised with the means of those parts. Every other region (head, each limb part, or
/// Region::Whole for the generic path) is its own group with k = 1.
///
/// Refinement loop. Among the ellipsoids whose E_j exceeds their group's threshold mu (mu_torso for the torso group,
/// mu_limbs for head and limbs; Region::Whole uses mu_torso) and that are not frozen, take the one with the largest
/// E_j / mu (ties: lower group, then lower cluster index). Seed two new centres at the end points of its longest
/// axis (replacing its centre), run pruned K-means (on the cluster's points, or on the whole group with
/// `reclusterGroup`), refit the MVEEs of the clusters whose points changed. The split is accepted when it lowers
/// the worst E_j or the summed (vertex-weighted) E_j of the clusters it changed; otherwise the group is left as it
/// was and the next axis is tried, then a four-way split across the two longest axes; when none helps, the
/// ellipsoid is frozen (docs/DESIGN.md sec. 2: a split that does not lower the error is rejected). A split that
/// leaves a cluster empty is rejected. Stops when every ellipsoid meets its threshold or is frozen, at
/// `maxEllipsoids`, or after `maxSplits` attempts. Termination is guaranteed: every attempt adds at least one
/// ellipsoid (bounded by the budget) or freezes one.
///
/// Triangle cover (after refinement, on by default). The clusters partition the vertices, so the union of the
/// MVEEs contains every vertex but not every triangle: a triangle whose corners lie in different clusters can bulge
/// out between two ellipsoids (up to 20 mm on female_young), and cloth resting on the union then sits inside the
/// skin there. Every such triangle is cut into pieces (edges <= coverSpacing); a piece that no single ellipsoid
/// contains is handed to the corner cluster whose ellipsoid comes closest (smallest max zeta of the piece's
/// corners), which then also encloses those corners and is refitted, until every piece lies inside one ellipsoid.
/// An ellipsoid is convex, so the whole skin then lies inside the union, exactly (not only at samples). E_j stays the
/// error over a cluster's own vertices. Measured on female_young (13,380 vertices, 85 ellipsoids, `bodyfit-fit`):
/// ~73k extra points, 3 rounds; mean E_j 14.1 -> 15.5 mm (whole triangles as pieces: 15.8 mm). The thresholds bind
/// the refinement before the cover. The piece checks are in triangle_cover.h (about 18 ms of CPU time with the
/// refits, `bodyfit-bench skinning --part fit --threads 1`).
///
/// Deterministic bit for bit: no randomness, ordered containers only, fixed tie rules; the same for any thread count
/// (BodyFitOptions::threads: independent cluster fits and the cover checks run in parallel, merged in a fixed order).

#include "bodyfit/fitting/fit_error.h"
#include "bodyfit/fitting/mvee.h"
#include "bodyfit/fitting/segmentation.h"

#include <memory>
#include <string>
#include <vector>

namespace bodyfit
{

struct SkinBinding; // skinned_fit.h
struct SkinField;   // skin_field.h

/// How many pieces the triangle cover cuts each edge of the triangle (a, b, c) into: the longest edge in pieces no
/// longer than `spacing`, between 1 and 64. The fitter's cover and the skin binding (skinned_fit.h) cut alike
/// through this one function.
int coverCutLevel(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double spacing);

struct BodyFitOptions
{
	/// Thresholds on E_j. Fractions of the body height H when `relativeToHeight`, metres otherwise.
	/// Defaults: 1.2% H (torso) and 0.9% H (head, limbs), 21 mm and 16 mm on a 1.75 m body. With the
	/// segmentation they give 75-93 ellipsoids on the four bundled full-resolution bodies (13,380 vertices) and
	/// 69 on the 4,508-vertex one. An MVEE around a limb segment leaves a radial gap of roughly 0.1-0.2 of the
	/// limb radius in the middle of the segment, which is why much lower thresholds need many more ellipsoids.
	double muTorso = 0.012;
	double muLimbs = 0.009;
	bool relativeToHeight = true;
	/// K-means pruning threshold on the mean centre shift (fraction of H when relativeToHeight, else metres).
	double sigma = 0.001;
	int maxEllipsoids = 128;  ///< budget: refinement stops when this many ellipsoids exist (>= number of groups)
	int maxSplits = 1000;     ///< cap on split attempts (accepted + rejected)
	/// Axes tried per split attempt, longest first: 1 = the paper (longest axis only); 2 or 3 also try the next
	/// axes before the ellipsoid is frozen (a cluster that wraps around a corner often splits well across it).
	int splitAxes = 3;
	/// After the axes failed, try a four-way split with the end points of the two longest axes before freezing.
	bool quadSplit = true;
	int kmeansMaxIterations = 50;
	/// false (default): after each split, K-means runs on the split cluster's points only (classic bisecting
	/// K-means); the other clusters of the group keep their points and ellipsoids.
	/// true: K-means runs on all points of the group with the other clusters' centres kept (paper sec. 3.3 step c,
	/// warm-started); points may move between any clusters of the group and every changed cluster is refitted.
	/// Measured on the bundled bodies (see README) the group variant is several times slower for no lower error.
	/// Region::Whole (the generic path) always splits locally: group re-clustering of a whole body makes clusters
	/// that straddle limbs and torso and freezes early.
	bool reclusterGroup = false;
	/// Minimum MVEE semi-axis as a fraction of H (degenerate clusters: flat patches, < 4 points).
	double minRadiusFraction = 0.002;
	double mveeTolerance = 1e-3;
	/// H used for the relative quantities; <= 0 means the y extent of the mesh.
	double height = 0.0;
	/// Triangle cover: after refinement, the triangles whose corners lie in different clusters are made to lie inside
	/// the union (piece by piece, each piece inside one ellipsoid, see above), so the union of the ellipsoids contains
	/// the whole mesh surface, not only its vertices. Without it, skin between two ellipsoids bulges out of the union
	/// in thin slivers and cloth resting on the union ends inside the body.
	bool coverTriangles = true;
	/// Largest edge of the triangle cover's pieces (fraction of H when relativeToHeight, else metres). Smaller
	/// pieces let ellipsoids grow less (0.006 H: mean E_j 15.6 mm on female_young, 0.003 H: 15.5, 0.0015 H: 15.4)
	/// for more points and time (15 / 31 / ~200 ms). Coverage is exact for any value.
	double coverSpacing = 0.003;
	/// Compute the true (Eberly) distance statistics of the final ellipsoids (costs ~1 closest-point query/vertex).
	bool trueDistance = true;
	/// Threads of the fit (0 = every hardware thread). The result is the same bit for bit for any count: the work
	/// is split into independent parts whose results are merged in a fixed order (parallel.h).
	int threads = 0;
};

/// A length-valued fit parameter: a fraction of the body height H, or metres.
struct Length
{
	double value = 0.0;
	bool relativeToHeight = true; ///< value is a fraction of H (else metres)

	static Length ofHeight(double fraction) { return {fraction, true}; }
	static Length inMetres(double metres) { return {metres, false}; }
	double toMetres(double height) const { return relativeToHeight ? value * height : value; }
};

/// The length-valued parameters of a fit, each in its own unit. Defaults: the relative defaults of BodyFitOptions.
struct FitLengths
{
	Length muTorso = Length::ofHeight(BodyFitOptions().muTorso);
	Length muLimbs = Length::ofHeight(BodyFitOptions().muLimbs);
	Length sigma = Length::ofHeight(BodyFitOptions().sigma);
	Length coverSpacing = Length::ofHeight(BodyFitOptions().coverSpacing);

	/// The lengths of `options` in its unit (options.relativeToHeight).
	static FitLengths of(const BodyFitOptions& options);
	bool allRelative() const;
};

/// The one place where a fit's units are resolved: `options` with its four lengths (mu_torso, mu_limbs, sigma,
/// cover spacing) taken from `lengths` and converted to metres for a body of height `height`; relativeToHeight =
/// false and height = `height` (so minRadiusFraction, always a fraction of H, refers to the same H). fitBody runs
/// its options through it, and so does the fit pipeline (fit_pipeline.h).
BodyFitOptions resolveLengths(const BodyFitOptions& options, const FitLengths& lengths, double height);

/// The height H of the relative quantities: `height` when > 0, else the y extent of the mesh, else (a flat mesh)
/// the bounding-box diagonal, with a warning in `*warning` (when given; left untouched otherwise).
double bodyHeight(const TriMesh& mesh, double height, std::string* warning = nullptr);

/// One fitted ellipsoid and how well it covers its vertices.
struct FittedEllipsoid
{
	Ellipsoid ellipsoid;
	Region region = Region::Whole; ///< its group's region; torso clusters take their majority torso part
	int vertexCount = 0;
	double radialError = 0.0;      ///< E_j (paper eq. 6), metres
	double maxRadialError = 0.0;   ///< max |v - v_phi| over its vertices
	double meanDistance = 0.0;     ///< mean true distance of its vertices to the surface ("air gap")
	double maxDistance = 0.0;      ///< max true distance
	FitStatus mveeStatus = FitStatus::Ok;
};

/// Parameters a fit was made with, in the units of the JSON file (see ellipsoid_io.h).
struct BodyFitParams
{
	double muTorso = 0.0;
	double muLimbs = 0.0;
	bool relativeToHeight = true;
	double sigma = 0.0;
	int maxEllipsoids = 0;
	double minRadius = 0.0; ///< metres
	bool reclusterGroup = false;
	bool coverTriangles = false; ///< the triangle cover ran (the union contains the whole skin surface)
	double coverSpacing = 0.0;   ///< its piece size, in the units of the thresholds (0 when it did not run)
};

struct SourceInfo
{
	std::string mesh;  ///< file name of the source mesh (no directory)
	int vertices = 0;
	double height = 0.0; ///< metres
};

struct StageTiming
{
	std::string stage; ///< "load", "segmentation", "fitting", ... (JSON key)
	double ms = 0.0;
};

enum class RefineStatus
{
	Converged,       ///< every ellipsoid meets its threshold
	Frozen,          ///< thresholds not met by some ellipsoids whose splits did not help (they were frozen)
	BudgetReached,   ///< maxEllipsoids reached with some ellipsoid above its threshold
	SplitCapReached, ///< maxSplits attempts used
};
const char* toString(RefineStatus status);

/// Result of a fit, and the content of an ellipsoid JSON file.
struct BodyFit
{
	std::vector<FittedEllipsoid> ellipsoids;
	std::vector<int> vertexEllipsoid; ///< per mesh vertex: index into `ellipsoids` (empty when read from a file)
	SourceInfo source;
	BodyFitParams params;
	std::vector<StageTiming> timings; ///< in pipeline order
	std::vector<std::string> warnings;
	RefineStatus status = RefineStatus::Converged;
	int splitsAccepted = 0;
	int splitsRejected = 0;
	/// Triangle cover (BodyFitOptions::coverTriangles): refit rounds, and the triangle sample points the ellipsoids
	/// enclose in addition to their own vertices (summed over ellipsoids).
	int coverRounds = 0;
	int coverExtraPoints = 0;
	/// Bone bindings of a fit made on a rig's bind pose (skinned_fit.h; the fit file's "skinning" section), or null.
	std::shared_ptr<const SkinBinding> skinning;
	/// The tight skin surface baked for this fit (skin_field.h), or null. The fit file's "skin_field" section names
	/// its side file; readEllipsoidJson loads it, writeEllipsoidJson writes it next to the fit file.
	std::shared_ptr<const SkinField> skinField;
	/// The side file's name as the fit file gives it (a file in the fit file's directory), or empty.
	std::string skinFieldFile;

	/// Vertex-weighted mean of E_j (= mean radial error over all fitted vertices), max E_j, and the
	/// vertex-weighted mean / max of the true distance. Ellipsoids with vertexCount 0 contribute nothing.
	double meanRadialError() const;
	double maxRadialError() const;
	double meanDistance() const;
	double maxDistance() const;
	/// Time of `stage` in ms, or 0 when not recorded.
	double timingMs(const std::string& stage) const;
	/// Adds or replaces the time of `stage`.
	void setTiming(const std::string& stage, double ms);
};

/// Fits ellipsoids to `mesh` given one region label per vertex (Region::Whole everywhere = the generic path).
/// Records the "fitting" timing plus its parts ("fitting.kmeans", "fitting.mvee", "fitting.error": summed over the
/// threads, so with several threads they can add up to more than "fitting") and, when
/// options.trueDistance is set, "report" (the closest-point queries).
/// \throws InvalidInputError when labels.size() != vertex count, the mesh is unusable or options are invalid.
BodyFit fitBody(const TriMesh& mesh, const std::vector<Region>& labels, const BodyFitOptions& options = {});

/// Generic path: the whole mesh is one region.
BodyFit fitBody(const TriMesh& mesh, const BodyFitOptions& options = {});

} // namespace bodyfit
