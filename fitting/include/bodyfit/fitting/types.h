#pragma once
/// \file types.h
/// Core value types of the fitting library. Units are metres, +y is up, frames are right-handed.

#include <Eigen/Core>

#include <string>
#include <vector>

namespace bodyfit
{

/// An indexed triangle mesh: V is #V by 3 (one vertex per row), F is #F by 3 (vertex indices, CCW = outward).
struct TriMesh
{
	Eigen::MatrixX3d V;
	Eigen::MatrixX3i F;

	int vertexCount() const { return int(V.rows()); }
	int faceCount() const { return int(F.rows()); }
};

/// How a stage of the pipeline ended. Every loop that converges reports one of these.
enum class FitStatus
{
	Ok,             ///< converged within tolerance
	TooFewPoints,   ///< fewer than 4 distinct points: a finite fallback was returned
	Degenerate,     ///< points are (nearly) collinear or coplanar: thin axes floored to the minimum semi-axis
	NotConverged,   ///< iteration cap reached: the last iterate, rescaled to enclose every point, was returned
	NumericalIssue, ///< a non-finite value appeared: the fallback was returned
};

const char* toString(FitStatus status);

} // namespace bodyfit
