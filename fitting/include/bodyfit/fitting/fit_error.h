#pragma once
/// \file fit_error.h
/// How well an ellipsoid approximates a set of surface vertices (paper sec. 3.2, eq. 6).
///
/// Two measures:
///   * the paper's radial error |v - v_phi|, v_phi = c + (v - c)/sqrt(zeta(v)) the radial projection of v onto the
///     surface (cheap: a few flops per vertex; this is what refinement compares with its thresholds);
///   * the true Euclidean distance from v to the ellipsoid surface (Eberly's method via closestSurfacePoint),
///     which is what a user sees as the "air gap" between skin and ellipsoid.
/// The radial distance is never smaller than the true distance (it is the length of one particular path to the
/// surface), so the radial mean bounds the true mean from above.

#include "bodyfit/fitting/ellipsoid.h"

#include <vector>

namespace bodyfit
{

/// Error statistics of one ellipsoid over a set of vertices. All distances in metres.
struct FitError
{
	int vertexCount = 0;
	double radialMean = 0.0;   ///< E_j of eq. 6: mean |v - v_phi|
	double radialMax = 0.0;    ///< max |v - v_phi|
	double distanceMean = 0.0; ///< mean |true distance to the surface| (0 when not computed)
	double distanceMax = 0.0;  ///< max |true distance to the surface| (0 when not computed)
};

/// |p - radialProjection(p)| computed in the principal frame: |u| * |1 - 1/|u/r||, u = R^T (p - c).
/// For p at the centre this is the longest semi-axis (radialProjection's answer for that case).
double radialDistance(const Ellipsoid& e, const Eigen::Vector3d& p);

/// Mean radial error E_j over the rows `indices` of `points` (N by 3). Returns 0 for an empty index list.
double meanRadialError(const Ellipsoid& e, const Eigen::MatrixX3d& points, const std::vector<int>& indices);

/// Radial mean/max and, when `trueDistance` is set, the true-distance mean/max over the rows `indices` of `points`.
FitError fitError(const Ellipsoid& e, const Eigen::MatrixX3d& points, const std::vector<int>& indices,
				  bool trueDistance = true);

} // namespace bodyfit
