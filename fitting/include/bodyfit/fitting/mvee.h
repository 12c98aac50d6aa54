#pragma once
/// \file mvee.h
/// Minimum-volume enclosing ellipsoid (paper sec. 3.1): Khachiyan's algorithm with Todd-Yildirim away steps and
/// Kumar-Yildirim initialisation, solved on an active set, followed by an exact rescale so every point is enclosed.

#include "bodyfit/fitting/ellipsoid.h"

#include <vector>

namespace bodyfit
{

struct MveeOptions
{
	double tolerance = 1e-3;   ///< relative optimality gap (Khachiyan epsilon) before the exact rescale
	int maxIterations = 20000; ///< cap on Khachiyan iterations (summed over active-set rounds)
	double minRadius = 1e-3;   ///< floor for semi-axes of degenerate sets (metres; callers scale it with H)
};

struct EllipsoidFit
{
	Ellipsoid ellipsoid;
	FitStatus status = FitStatus::Ok;
	int iterations = 0;    ///< Khachiyan iterations performed
	int activeSetSize = 0; ///< points in the final active set
	/// Indices (rows of the input) of the points that carry weight in the final Khachiyan iterate: the core set that
	/// touches (or nearly touches) the ellipsoid. At most a few dozen. Feed them (mapped to a subset's rows) back
	/// through the warm-start overload when refitting a subset, e.g. a child cluster after a split.
	std::vector<int> coreIndices;
};

/// \param points N by 3, one point per row. N may be anything >= 1; non-finite points throw InvalidInputError.
/// \return an ellipsoid that contains every point (zeta <= 1 + 1e-9) and has finite, positive radii.
///
/// Algorithm: the points are centred on their mean and rotated/scaled into a frame built from the Kumar-Yildirim
/// directions (MVEE is affine-equivariant, so this only improves conditioning: 1000:1 sets stay well posed). Khachiyan's
/// barycentric ascent with Todd-Yildirim away/drop steps runs on an active set (KY points + extreme points along 7
/// directions), with Sherman-Morrison updates of the (d+1)x(d+1) inverse and of diag(M) only. When the active set is
/// optimal within `tolerance`, all N points are checked in O(N); the worst violators join and the solve continues.
/// Finally the shape is rescaled in world coordinates so that max zeta over all points is 1 (to rounding).
/// Degenerate sets (rank < 3 within 1e-10 of the extent, or fewer than 4 distinct points) are solved in their
/// subspace (2-D MVEE, or the segment) and the missing semi-axes get `minRadius`. Radii are never below `minRadius`.
/// Status: TooFewPoints (< 4 distinct points), Degenerate (collinear/coplanar, or a radius was floored),
/// NotConverged (maxIterations hit; still enclosing), NumericalIssue (fallback: the ellipsoid around the bounding
/// box in the Kumar-Yildirim frame, still enclosing).
/// Deterministic: no randomness, the same input gives the same output bit for bit.
/// \throws InvalidInputError for an empty point set, a non-finite coordinate, or a non-positive/non-finite
///         minRadius or tolerance.
EllipsoidFit minimumVolumeEllipsoid(const Eigen::MatrixX3d& points, const MveeOptions& options = {});

/// Warm-started variant: `warmStart` lists rows of `points` expected to be in the core set (typically the parent's
/// EllipsoidFit::coreIndices restricted to this subset and renumbered). They join the initial active set and share
/// the initial weight with the Kumar-Yildirim points, which typically saves active-set rounds. Out-of-range or
/// duplicate indices throw InvalidInputError. The result satisfies the same guarantees as the cold start.
EllipsoidFit minimumVolumeEllipsoid(const Eigen::MatrixX3d& points, const MveeOptions& options,
                                    const std::vector<int>& warmStart);

} // namespace bodyfit
