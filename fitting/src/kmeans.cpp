// Pruned K-means with Hamerly's bounds. See kmeans.h.
#include "bodyfit/fitting/kmeans.h"

#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace bodyfit
{

namespace
{

using RowPoints = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Nearest and second-nearest centre of p (ties: lower index wins). Distances, not squared.
inline void nearestTwo(const RowPoints& centers, const Eigen::Vector3d& p, int& best, double& d1, double& d2)
{
	double b1 = std::numeric_limits<double>::infinity(), b2 = b1;
	int arg = 0;
	for (Eigen::Index j = 0; j < centers.rows(); ++j)
	{
		const double d = (centers.row(j).transpose() - p).squaredNorm();
		if (d < b1)
		{
			b2 = b1;
			b1 = d;
			arg = int(j);
		}
		else if (d < b2)
			b2 = d;
	}
	best = arg;
	d1 = std::sqrt(b1);
	d2 = std::sqrt(b2); // +inf when k == 1
}

void requireFinite(const Eigen::MatrixX3d& m, const char* what)
{
	if (!m.allFinite())
		throw InvalidInputError(std::string("kMeans: non-finite ") + what);
}

} // namespace

KMeansResult kMeans(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& initialCenters,
					const KMeansOptions& options, const KMeansWarmStart* warm)
{
	requireFinite(points, "point");
	requireFinite(initialCenters, "initial centre");
	if (!(options.sigma >= 0.0) || !std::isfinite(options.sigma))
		throw InvalidInputError("kMeans: sigma must be finite and >= 0");
	if (options.maxIterations < 1)
		throw InvalidInputError("kMeans: maxIterations must be >= 1");

	const int n = int(points.rows());
	const int k = int(initialCenters.rows());
	if (warm != nullptr)
	{
		if (warm->assignment == nullptr || warm->lowerBounds == nullptr || warm->moved == nullptr ||
			int(warm->assignment->size()) != n || int(warm->lowerBounds->size()) != n || int(warm->moved->size()) != k)
			throw InvalidInputError("kMeans: malformed warm start (sizes must be N, N and k)");
		for (int ai : *warm->assignment)
			if (ai < 0 || ai >= k)
				throw InvalidInputError("kMeans: warm-start assignment out of range");
	}

	KMeansResult result;
	result.centers = initialCenters;
	result.counts.assign(std::size_t(k), 0);
	result.assignment.assign(std::size_t(n), 0);
	result.lowerBounds.assign(std::size_t(n), 0.0);
	if (n == 0 || k == 0)
	{
		result.status = FitStatus::TooFewPoints;
		result.emptyClusters = k;
		return result;
	}

	const RowPoints P = points; // row-major copy: the three coordinates of a point are adjacent
	RowPoints C = initialCenters;
	RowPoints sums(k, 3);
	std::vector<int>& a = result.assignment;
	std::vector<double>& lower = result.lowerBounds;
	std::vector<double> upper(static_cast<std::size_t>(n));
	std::vector<double> halfGap(static_cast<std::size_t>(k)), shift(static_cast<std::size_t>(k));
	std::vector<int>& counts = result.counts;

	// Initial assignment: the exact nearest centre of every point. Warm start: a point whose own centre did not
	// move only needs its distances to the moved centres; its old lower bound covers the unmoved ones.
	std::vector<int> movedList;
	if (warm != nullptr)
		for (int j = 0; j < k; ++j)
			if ((*warm->moved)[std::size_t(j)])
				movedList.push_back(j);
	for (int i = 0; i < n; ++i)
	{
		const std::size_t ii = std::size_t(i);
		const Eigen::Vector3d p = P.row(i).transpose();
		if (warm != nullptr && !(*warm->moved)[std::size_t((*warm->assignment)[ii])])
		{
			const int ai = (*warm->assignment)[ii];
			double lo = (*warm->lowerBounds)[ii];
			for (int j : movedList)
				lo = std::min(lo, (C.row(j).transpose() - p).norm());
			const double up = (C.row(ai).transpose() - p).norm();
			if (up < lo) // strictly nearest: no tie the full scan could break differently
			{
				a[ii] = ai;
				upper[ii] = up;
				lower[ii] = lo;
				continue;
			}
		}
		nearestTwo(C, p, a[ii], upper[ii], lower[ii]);
	}

	bool converged = false;
	for (int iter = 1;; ++iter)
	{
		result.iterations = iter;

		// Update step: centres become the means of their points (summed in point order: deterministic).
		sums.setZero();
		std::fill(counts.begin(), counts.end(), 0);
		for (int i = 0; i < n; ++i)
		{
			sums.row(a[std::size_t(i)]) += P.row(i);
			++counts[std::size_t(a[std::size_t(i)])];
		}
		double shiftSum = 0.0;
		int far1 = 0;
		for (int j = 0; j < k; ++j)
		{
			shift[std::size_t(j)] = 0.0;
			if (counts[std::size_t(j)] == 0)
				continue; // an empty cluster keeps its centre
			const Eigen::RowVector3d c = sums.row(j) / double(counts[std::size_t(j)]);
			shift[std::size_t(j)] = (c - C.row(j)).norm();
			C.row(j) = c;
			shiftSum += shift[std::size_t(j)];
			if (shift[std::size_t(j)] > shift[std::size_t(far1)])
				far1 = j;
		}
		result.lastShift = shiftSum / double(k);

		// Bound maintenance (Hamerly): the own centre moved by shift[a], any other by at most the largest shift
		// among the others. Done before the convergence test so the returned bounds are valid for `centers`.
		double far2Shift = 0.0;
		for (int j = 0; j < k; ++j)
			if (j != far1)
				far2Shift = std::max(far2Shift, shift[std::size_t(j)]);
		for (int i = 0; i < n; ++i)
		{
			const int ai = a[std::size_t(i)];
			upper[std::size_t(i)] += shift[std::size_t(ai)];
			lower[std::size_t(i)] -= (ai == far1) ? far2Shift : shift[std::size_t(far1)];
		}

		// Pruning (paper eq. 7, averaged over the k centres).
		if (result.lastShift < options.sigma || result.lastShift == 0.0)
		{
			converged = true;
			break;
		}
		if (iter >= options.maxIterations)
			break;

		// Half the distance from each centre to its nearest other centre.
		for (int j = 0; j < k; ++j)
		{
			double best = std::numeric_limits<double>::infinity();
			for (int m = 0; m < k; ++m)
				if (m != j)
					best = std::min(best, (C.row(j) - C.row(m)).squaredNorm());
			halfGap[std::size_t(j)] = 0.5 * std::sqrt(best);
		}

		// Assignment step. Strict comparisons: a point whose bounds tie is re-examined exactly, so the lower-index
		// tie rule of a plain Lloyd step is kept.
		for (int i = 0; i < n; ++i)
		{
			const std::size_t ii = std::size_t(i);
			const int ai = a[ii];
			const double bound = std::max(halfGap[std::size_t(ai)], lower[ii]);
			if (upper[ii] < bound)
				continue;
			upper[ii] = (P.row(i) - C.row(ai)).norm();
			if (upper[ii] < bound)
				continue;
			nearestTwo(C, P.row(i).transpose(), a[ii], upper[ii], lower[ii]);
		}
	}

	result.centers = C;
	result.emptyClusters = int(std::count(counts.begin(), counts.end(), 0));
	if (result.emptyClusters > 0)
		result.status = FitStatus::Degenerate;
	else
		result.status = converged ? FitStatus::Ok : FitStatus::NotConverged;
	return result;
}

} // namespace bodyfit
