// Fitting error of an ellipsoid over a vertex set (paper eq. 6) and the true air gap.
#include "bodyfit/fitting/fit_error.h"

#include <algorithm>
#include <cmath>

namespace bodyfit
{

double radialDistance(const Ellipsoid& e, const Eigen::Vector3d& p)
{
	const Eigen::Vector3d u = e.rotation.transpose() * (p - e.center);
	const double len = u.norm();
	if (len == 0.0)
		return e.radii.maxCoeff(); // same answer as Ellipsoid::radialProjection for the centre
	// |p - v_phi| = |u| * |1 - 1/sqrt(zeta)| = | |u| - |u|/|u/r| |. The second term is the distance from the centre
	// to the surface along u, computed from the unit direction so it stays finite for tiny |u|.
	const Eigen::Vector3d dir = u / len;
	const double surface = 1.0 / dir.cwiseQuotient(e.radii).norm();
	return std::abs(len - surface);
}

double meanRadialError(const Ellipsoid& e, const Eigen::MatrixX3d& points, const std::vector<int>& indices)
{
	if (indices.empty())
		return 0.0;
	double sum = 0.0;
	for (int i : indices)
		sum += radialDistance(e, points.row(i).transpose());
	return sum / double(indices.size());
}

FitError fitError(const Ellipsoid& e, const Eigen::MatrixX3d& points, const std::vector<int>& indices,
				  bool trueDistance)
{
	FitError err;
	err.vertexCount = int(indices.size());
	if (indices.empty())
		return err;
	double radialSum = 0.0, distanceSum = 0.0;
	for (int i : indices)
	{
		const Eigen::Vector3d p = points.row(i).transpose();
		const double r = radialDistance(e, p);
		radialSum += r;
		err.radialMax = std::max(err.radialMax, r);
		if (trueDistance)
		{
			const double d = std::abs(closestSurfacePoint(e, p).signedDistance);
			distanceSum += d;
			err.distanceMax = std::max(err.distanceMax, d);
		}
	}
	err.radialMean = radialSum / double(indices.size());
	err.distanceMean = trueDistance ? distanceSum / double(indices.size()) : 0.0;
	return err;
}

} // namespace bodyfit
