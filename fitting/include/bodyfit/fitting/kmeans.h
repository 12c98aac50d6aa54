#pragma once
/// \file kmeans.h
/// Pruned K-means (paper sec. 3.3): Lloyd iterations from given initial centres, stopped early when the mean
/// centre shift of an iteration falls below `sigma` (the paper's pruning, eq. 7 averaged over the k centres).
/// Exact assignment steps use Hamerly's bounds (G. Hamerly, "Making k-means even faster", SDM 2010), which skip
/// distance computations without changing the result of a plain Lloyd step.
///
/// Deterministic: no randomness (the caller supplies the centres), ties go to the lower cluster index, sums are
/// accumulated in point order. Empty clusters keep their centre and are reported, never reseeded at random.

#include "bodyfit/fitting/types.h"

#include <vector>

namespace bodyfit
{

struct KMeansOptions
{
	double sigma = 1e-3;    ///< pruning threshold on the mean centre shift per iteration (metres, >= 0)
	int maxIterations = 100; ///< cap on Lloyd iterations (>= 1)
};

struct KMeansResult
{
	std::vector<int> assignment; ///< cluster in [0, k) of every point (the centre nearest at the last step)
	Eigen::MatrixX3d centers;    ///< k by 3: mean of each cluster's points; an empty cluster keeps its last centre
	std::vector<int> counts;     ///< points per cluster
	int iterations = 0;          ///< assignment steps performed
	double lastShift = 0.0;      ///< mean centre shift of the last iteration (metres)
	int emptyClusters = 0;       ///< clusters without points at the end
	/// Ok: converged (shift < sigma); NotConverged: iteration cap; Degenerate: converged or capped with at least
	/// one empty cluster (k > n, duplicate points, or duplicate centres); TooFewPoints: no points or no centres.
	FitStatus status = FitStatus::Ok;
	/// Per point: a lower bound on its distance to every centre other than its own, valid for `centers`
	/// (Hamerly's bound). Pass it back through KMeansWarmStart to continue from this result.
	std::vector<double> lowerBounds;
};

/// Continue from a previous result on the same points after some centres were moved or appended (a split).
/// The result is the same as a cold start from the same initial centres; only distance computations are saved.
struct KMeansWarmStart
{
	const std::vector<int>* assignment = nullptr;   ///< previous KMeansResult::assignment
	const std::vector<double>* lowerBounds = nullptr; ///< previous KMeansResult::lowerBounds
	/// Per centre of the new initial centres: true when it differs from the previous final centre of that index,
	/// or is new (index >= previous k). Centres not flagged must equal the previous final centres exactly.
	const std::vector<bool>* moved = nullptr;
};

/// \param points N by 3, one point per row (finite).
/// \param initialCenters k by 3 initial centres (finite).
/// \param warm optional warm start (all three vectors set, sizes N, N and k); nullptr = cold start.
/// \throws InvalidInputError for non-finite input, a negative sigma, maxIterations < 1 or a malformed warm start.
KMeansResult kMeans(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& initialCenters,
					const KMeansOptions& options = {}, const KMeansWarmStart* warm = nullptr);

} // namespace bodyfit
