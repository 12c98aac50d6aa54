#pragma once
// Independent, deliberately plain reference for the MVEE tests: Khachiyan with Todd-Yildirim away steps on ALL points,
// recomputing X, X^-1 and every M_i from scratch at every iteration (no active set, no whitening, no rank-one updates).
// O(n) per iteration with a large constant: for test sizes (<= a few hundred points) only.
#include <Eigen/Dense>

#include <cmath>

namespace bodyfit_test
{

struct ReferenceMvee
{
	Eigen::Vector3d center;
	Eigen::Matrix3d shape; ///< ellipsoid {x : (x - center)^T shape (x - center) <= 1}, rescaled to enclose every point
	double volume = 0.0;
	int iterations = 0;
};

/// \param P N by 3, points in general position (affinely spanning R^3).
inline ReferenceMvee referenceMvee(const Eigen::MatrixX3d& P, double tolerance = 1e-9, int maxIterations = 200000)
{
	const int n = int(P.rows());
	Eigen::MatrixXd Q(4, n);
	Q.topRows<3>() = P.transpose();
	Q.row(3).setOnes();
	Eigen::VectorXd u = Eigen::VectorXd::Constant(n, 1.0 / n);
	ReferenceMvee r;
	for (r.iterations = 0; r.iterations < maxIterations; ++r.iterations)
	{
		const Eigen::Matrix4d X = Q * u.asDiagonal() * Q.transpose();
		const Eigen::Matrix4d Xinv = X.inverse();
		const Eigen::VectorXd M = (Q.transpose() * Xinv).cwiseProduct(Q.transpose()).rowwise().sum();
		int j = 0, k = -1;
		M.maxCoeff(&j);
		for (int i = 0; i < n; ++i)
			if (u[i] > 0.0 && (k < 0 || M[i] < M[k]))
				k = i;
		const double plus = M[j] / 4.0 - 1.0, minus = 1.0 - M[k] / 4.0;
		if (plus <= tolerance && minus <= tolerance)
			break;
		int t = j;
		double tau = (M[j] - 4.0) / (4.0 * (M[j] - 1.0));
		if (minus > plus)
		{
			t = k;
			tau = std::max((M[k] - 4.0) / (4.0 * (M[k] - 1.0)), -u[k] / (1.0 - u[k]));
		}
		u *= 1.0 - tau;
		u[t] += tau;
		if (u[t] < 1e-300)
			u[t] = 0.0;
	}
	r.center = P.transpose() * u;
	const Eigen::Matrix3d S = P.transpose() * u.asDiagonal() * P - r.center * r.center.transpose();
	r.shape = S.inverse() / 3.0;
	double zmax = 0.0;
	for (int i = 0; i < n; ++i)
	{
		const Eigen::Vector3d d = P.row(i).transpose() - r.center;
		zmax = std::max(zmax, d.dot(r.shape * d));
	}
	r.shape /= zmax;
	r.volume = 4.0 / 3.0 * M_PI / std::sqrt(r.shape.determinant());
	return r;
}

} // namespace bodyfit_test
