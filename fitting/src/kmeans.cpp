// Pruned K-means with Hamerly's bounds. See kmeans.h.
#include "bodyfit/fitting/kmeans.h"

#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

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

/// \throws InvalidInputError for non-finite input, bad options or a warm start that does not fit n points / k centres.
void validate(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& initialCenters, const KMeansOptions& options,
			  const KMeansWarmStart* warm)
{
	requireFinite(points, "point");
	requireFinite(initialCenters, "initial centre");
	if (!(options.sigma >= 0.0) || !std::isfinite(options.sigma))
		throw InvalidInputError("kMeans: sigma must be finite and >= 0");
	if (options.maxIterations < 1)
		throw InvalidInputError("kMeans: maxIterations must be >= 1");
	if (warm == nullptr)
		return;
	const int n = int(points.rows());
	const int k = int(initialCenters.rows());
	if (warm->assignment == nullptr || warm->lowerBounds == nullptr || warm->moved == nullptr ||
		int(warm->assignment->size()) != n || int(warm->lowerBounds->size()) != n || int(warm->moved->size()) != k)
		throw InvalidInputError("kMeans: malformed warm start (sizes must be N, N and k)");
	for (int ai : *warm->assignment)
		if (ai < 0 || ai >= k)
			throw InvalidInputError("kMeans: warm-start assignment out of range");
}

/// The working state of one run: row-major copies (the three coordinates of a point are adjacent), the result's
/// assignment and lower bounds, Hamerly's upper bounds and the per-centre scratch.
struct KMeansState
{
	KMeansState(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& initialCenters, KMeansResult& result)
		: P(points), C(initialCenters), sums(initialCenters.rows(), 3), a(result.assignment),
		  lower(result.lowerBounds), counts(result.counts), upper(std::size_t(points.rows())),
		  halfGap(std::size_t(initialCenters.rows())), shift(std::size_t(initialCenters.rows()))
	{
	}
	const RowPoints P;
	RowPoints C;
	RowPoints sums;
	std::vector<int>& a;
	std::vector<double>& lower;
	std::vector<int>& counts;
	std::vector<double> upper;
	std::vector<double> halfGap, shift;
	int n() const { return int(P.rows()); }
	int k() const { return int(C.rows()); }
};

/// Initial assignment: the exact nearest centre of every point. Warm start: a point whose own centre did not move
/// only needs its distances to the moved centres; its old lower bound covers the unmoved ones.
void initialAssignment(KMeansState& s, const KMeansWarmStart* warm)
{
	std::vector<int> movedList;
	if (warm != nullptr)
		for (int j = 0; j < s.k(); ++j)
			if ((*warm->moved)[std::size_t(j)])
				movedList.push_back(j);
	for (int i = 0; i < s.n(); ++i)
	{
		const std::size_t ii = std::size_t(i);
		const Eigen::Vector3d p = s.P.row(i).transpose();
		if (warm != nullptr && !(*warm->moved)[std::size_t((*warm->assignment)[ii])])
		{
			const int ai = (*warm->assignment)[ii];
			double lo = (*warm->lowerBounds)[ii];
			for (int j : movedList)
				lo = std::min(lo, (s.C.row(j).transpose() - p).norm());
			const double up = (s.C.row(ai).transpose() - p).norm();
			if (up < lo) // strictly nearest: no tie the full scan could break differently
			{
				s.a[ii] = ai;
				s.upper[ii] = up;
				s.lower[ii] = lo;
				continue;
			}
		}
		nearestTwo(s.C, p, s.a[ii], s.upper[ii], s.lower[ii]);
	}
}

/// Update step: centres become the means of their points (summed in point order: deterministic); an empty cluster
/// keeps its centre. Fills s.shift; returns the summed shift and sets `*far1` to the centre that moved most.
double updateCenters(KMeansState& s, int* far1)
{
	s.sums.setZero();
	std::fill(s.counts.begin(), s.counts.end(), 0);
	for (int i = 0; i < s.n(); ++i)
	{
		s.sums.row(s.a[std::size_t(i)]) += s.P.row(i);
		++s.counts[std::size_t(s.a[std::size_t(i)])];
	}
	double shiftSum = 0.0;
	*far1 = 0;
	for (int j = 0; j < s.k(); ++j)
	{
		s.shift[std::size_t(j)] = 0.0;
		if (s.counts[std::size_t(j)] == 0)
			continue;
		const Eigen::RowVector3d c = s.sums.row(j) / double(s.counts[std::size_t(j)]);
		s.shift[std::size_t(j)] = (c - s.C.row(j)).norm();
		s.C.row(j) = c;
		shiftSum += s.shift[std::size_t(j)];
		if (s.shift[std::size_t(j)] > s.shift[std::size_t(*far1)])
			*far1 = j;
	}
	return shiftSum;
}

/// Bound maintenance (Hamerly): the own centre moved by shift[a], any other by at most the largest shift among the
/// others (`far1` moved most).
void updateBounds(KMeansState& s, int far1)
{
	double far2Shift = 0.0;
	for (int j = 0; j < s.k(); ++j)
		if (j != far1)
			far2Shift = std::max(far2Shift, s.shift[std::size_t(j)]);
	for (int i = 0; i < s.n(); ++i)
	{
		const int ai = s.a[std::size_t(i)];
		s.upper[std::size_t(i)] += s.shift[std::size_t(ai)];
		s.lower[std::size_t(i)] -= (ai == far1) ? far2Shift : s.shift[std::size_t(far1)];
	}
}

/// Assignment step. Half the distance from each centre to its nearest other centre first; then strict comparisons:
/// a point whose bounds tie is re-examined exactly, so the lower-index tie rule of a plain Lloyd step is kept.
void reassign(KMeansState& s)
{
	for (int j = 0; j < s.k(); ++j)
	{
		double best = std::numeric_limits<double>::infinity();
		for (int m = 0; m < s.k(); ++m)
			if (m != j)
				best = std::min(best, (s.C.row(j) - s.C.row(m)).squaredNorm());
		s.halfGap[std::size_t(j)] = 0.5 * std::sqrt(best);
	}
	for (int i = 0; i < s.n(); ++i)
	{
		const std::size_t ii = std::size_t(i);
		const int ai = s.a[ii];
		const double bound = std::max(s.halfGap[std::size_t(ai)], s.lower[ii]);
		if (s.upper[ii] < bound)
			continue;
		s.upper[ii] = (s.P.row(i) - s.C.row(ai)).norm();
		if (s.upper[ii] < bound)
			continue;
		nearestTwo(s.C, s.P.row(i).transpose(), s.a[ii], s.upper[ii], s.lower[ii]);
	}
}

} // namespace

KMeansResult kMeans(const Eigen::MatrixX3d& points, const Eigen::MatrixX3d& initialCenters,
					const KMeansOptions& options, const KMeansWarmStart* warm)
{
	validate(points, initialCenters, options, warm);
	const int n = int(points.rows());
	const int k = int(initialCenters.rows());
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

	KMeansState s(points, initialCenters, result);
	initialAssignment(s, warm);
	bool converged = false;
	for (int iter = 1;; ++iter)
	{
		result.iterations = iter;
		int far1 = 0;
		result.lastShift = updateCenters(s, &far1) / double(k);
		// Before the convergence test, so the returned bounds are valid for `centers`.
		updateBounds(s, far1);
		// Pruning (paper eq. 7, averaged over the k centres).
		if (result.lastShift < options.sigma || result.lastShift == 0.0)
		{
			converged = true;
			break;
		}
		if (iter >= options.maxIterations)
			break;
		reassign(s);
	}

	result.centers = s.C;
	result.emptyClusters = int(std::count(result.counts.begin(), result.counts.end(), 0));
	if (result.emptyClusters > 0)
		result.status = FitStatus::Degenerate;
	else
		result.status = converged ? FitStatus::Ok : FitStatus::NotConverged;
	return result;
}

} // namespace bodyfit
