#pragma once
/// \file mvee.h
/// Minimum-volume enclosing ellipsoid (paper sec. 3.1): Khachiyan's algorithm with Todd-Yildirim away steps and
/// Kumar-Yildirim initialisation, solved on an active set, followed by an exact rescale so every point is enclosed.

#include "bodyfit/ellipsoid.h"

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
};

/// \param points N by 3, one point per row. N may be anything >= 1; non-finite points throw InvalidInputError.
/// \return an ellipsoid that contains every point (zeta <= 1 + 1e-9) and has finite, positive radii.
EllipsoidFit minimumVolumeEllipsoid(const Eigen::MatrixX3d& points, const MveeOptions& options = {});

} // namespace bodyfit
