// Pruned K-means: correctness against a plain Lloyd implementation, warm start = cold start, determinism, and
// termination with a status on pathological input.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/kmeans.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <random>

using namespace bodyfit;

namespace
{

Eigen::MatrixX3d randomBlobs(int perBlob, const std::vector<Eigen::Vector3d>& centres, double spread, unsigned seed)
{
	std::mt19937 rng(seed);
	std::normal_distribution<double> n(0.0, spread);
	Eigen::MatrixX3d p(perBlob * int(centres.size()), 3);
	for (std::size_t c = 0; c < centres.size(); ++c)
		for (int i = 0; i < perBlob; ++i)
			p.row(Eigen::Index(c) * perBlob + i) = (centres[c] + Eigen::Vector3d(n(rng), n(rng), n(rng))).transpose();
	return p;
}

/// Reference: textbook Lloyd (full scan every step, ties to the lower index) with the same pruning rule.
KMeansResult naiveLloyd(const Eigen::MatrixX3d& p, Eigen::MatrixX3d c, double sigma, int maxIterations)
{
	const int n = int(p.rows()), k = int(c.rows());
	KMeansResult r;
	r.assignment.assign(std::size_t(n), 0);
	for (int iter = 1; iter <= maxIterations; ++iter)
	{
		for (int i = 0; i < n; ++i)
		{
			double best = std::numeric_limits<double>::infinity();
			for (int j = 0; j < k; ++j)
			{
				const double d = (p.row(i) - c.row(j)).squaredNorm();
				if (d < best)
				{
					best = d;
					r.assignment[std::size_t(i)] = j;
				}
			}
		}
		Eigen::MatrixX3d sums = Eigen::MatrixX3d::Zero(k, 3);
		std::vector<int> counts(std::size_t(k), 0);
		for (int i = 0; i < n; ++i)
		{
			sums.row(r.assignment[std::size_t(i)]) += p.row(i);
			++counts[std::size_t(r.assignment[std::size_t(i)])];
		}
		double shift = 0.0;
		for (int j = 0; j < k; ++j)
			if (counts[std::size_t(j)] > 0)
			{
				const Eigen::RowVector3d m = sums.row(j) / double(counts[std::size_t(j)]);
				shift += (m - c.row(j)).norm();
				c.row(j) = m;
			}
		r.iterations = iter;
		if (shift / k < sigma || shift == 0.0)
			break;
	}
	r.centers = c;
	return r;
}

} // namespace

TEST_CASE("kmeans: separated blobs are recovered and centres are the cluster means", "[fitting][kmeans]")
{
	const std::vector<Eigen::Vector3d> truth = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
	const Eigen::MatrixX3d p = randomBlobs(200, truth, 0.05, 7);
	Eigen::MatrixX3d init(3, 3);
	init << 0.2, 0.1, 0, 0.8, -0.1, 0, 0.1, 0.7, 0.1;
	KMeansOptions o;
	o.sigma = 0.0; // run to the fixed point
	const KMeansResult r = kMeans(p, init, o);
	CHECK(r.status == FitStatus::Ok);
	CHECK(r.emptyClusters == 0);
	for (int c = 0; c < 3; ++c)
	{
		// Blobs are 1 apart with sd 0.05 (20 sd): every point belongs to its own blob's cluster.
		for (int i = 0; i < 200; ++i)
			CHECK(r.assignment[std::size_t(c * 200 + i)] == c);
		// The centre is the mean of its points; 1e-12 covers the summation rounding of 200 terms of size ~1.
		const Eigen::RowVector3d mean = p.middleRows(c * 200, 200).colwise().mean();
		CHECK((r.centers.row(c) - mean).norm() < 1e-12);
	}
}

TEST_CASE("kmeans: Hamerly bounds give the same result as plain Lloyd", "[fitting][kmeans]")
{
	// Overlapping blobs so that many points change clusters over the iterations.
	std::vector<Eigen::Vector3d> truth;
	for (int i = 0; i < 8; ++i)
		truth.push_back(Eigen::Vector3d(std::cos(i), std::sin(1.3 * i), 0.2 * i));
	const Eigen::MatrixX3d p = randomBlobs(150, truth, 0.4, 11);
	Eigen::MatrixX3d init(8, 3);
	for (int j = 0; j < 8; ++j)
		init.row(j) = p.row(j * 137);
	for (double sigma : {0.0, 1e-3, 1e-2})
	{
		KMeansOptions o;
		o.sigma = sigma;
		o.maxIterations = 200;
		const KMeansResult fast = kMeans(p, init, o);
		const KMeansResult slow = naiveLloyd(p, init, sigma, 200);
		CAPTURE(sigma);
		CHECK(fast.iterations == slow.iterations);
		CHECK(fast.assignment == slow.assignment);
		// Same assignment, same summation order -> the same means bit for bit.
		CHECK(fast.centers == slow.centers);
	}
}

TEST_CASE("kmeans: a warm start after a split equals the cold start", "[fitting][kmeans]")
{
	std::vector<Eigen::Vector3d> truth;
	for (int i = 0; i < 6; ++i)
		truth.push_back(Eigen::Vector3d(0.5 * i, std::sin(i), 0.0));
	const Eigen::MatrixX3d p = randomBlobs(300, truth, 0.2, 3);
	Eigen::MatrixX3d init(5, 3);
	for (int j = 0; j < 5; ++j)
		init.row(j) = p.row(j * 311);
	KMeansOptions o;
	o.sigma = 1e-4;
	const KMeansResult first = kMeans(p, init, o);

	// Split cluster 2: move its centre and append a new one, as the refinement does.
	Eigen::MatrixX3d split(6, 3);
	split.topRows(5) = first.centers;
	split.row(2) = first.centers.row(2) + Eigen::RowVector3d(0.3, 0.0, 0.0);
	split.row(5) = first.centers.row(2) - Eigen::RowVector3d(0.3, 0.0, 0.0);
	std::vector<bool> moved = {false, false, true, false, false, true};
	KMeansWarmStart warm;
	warm.assignment = &first.assignment;
	warm.lowerBounds = &first.lowerBounds;
	warm.moved = &moved;
	const KMeansResult hot = kMeans(p, split, o, &warm);
	const KMeansResult cold = kMeans(p, split, o);
	CHECK(hot.iterations == cold.iterations);
	CHECK(hot.assignment == cold.assignment);
	CHECK(hot.centers == cold.centers);
}

TEST_CASE("kmeans: deterministic bit for bit", "[fitting][kmeans]")
{
	const Eigen::MatrixX3d p = randomBlobs(500, {{0, 0, 0}, {0.3, 0.2, 0.1}, {0.1, 0.5, 0.3}}, 0.2, 5);
	const Eigen::MatrixX3d init = p.topRows(4);
	const KMeansResult a = kMeans(p, init);
	const KMeansResult b = kMeans(p, init);
	CHECK(a.assignment == b.assignment);
	CHECK(a.centers == b.centers);
	CHECK(a.iterations == b.iterations);
	CHECK(a.lowerBounds == b.lowerBounds);
}

TEST_CASE("kmeans: pathological input terminates with a status", "[fitting][kmeans]")
{
	SECTION("all points identical, k = 3: one cluster takes everything, two are empty")
	{
		const Eigen::MatrixX3d p = Eigen::MatrixX3d::Constant(50, 3, 0.25);
		Eigen::MatrixX3d init(3, 3);
		init << 0, 0, 0, 1, 1, 1, 0.25, 0.25, 0.25;
		const KMeansResult r = kMeans(p, init);
		CHECK(r.status == FitStatus::Degenerate);
		CHECK(r.emptyClusters == 2);
		CHECK(r.counts[2] == 50);
		CHECK(r.centers.row(2) == Eigen::RowVector3d::Constant(0.25));
		CHECK(r.iterations <= 2);
	}
	SECTION("identical points and identical centres: ties go to the lower index")
	{
		const Eigen::MatrixX3d p = Eigen::MatrixX3d::Zero(10, 3);
		const Eigen::MatrixX3d init = Eigen::MatrixX3d::Zero(4, 3);
		const KMeansResult r = kMeans(p, init);
		CHECK(r.counts[0] == 10);
		CHECK(r.emptyClusters == 3);
		CHECK(r.status == FitStatus::Degenerate);
	}
	SECTION("k > n")
	{
		Eigen::MatrixX3d p(2, 3);
		p << 0, 0, 0, 1, 0, 0;
		Eigen::MatrixX3d init(5, 3);
		init << 0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0, 4, 0, 0;
		const KMeansResult r = kMeans(p, init);
		CHECK(r.status == FitStatus::Degenerate);
		CHECK(r.emptyClusters == 3);
		CHECK(r.assignment == std::vector<int>{0, 1});
	}
	SECTION("one point, k = 1")
	{
		Eigen::MatrixX3d p(1, 3);
		p << 1, 2, 3;
		const KMeansResult r = kMeans(p, Eigen::MatrixX3d::Zero(1, 3));
		CHECK(r.status == FitStatus::Ok);
		CHECK(r.centers.row(0) == p.row(0));
	}
	SECTION("no points or no centres")
	{
		CHECK(kMeans(Eigen::MatrixX3d(0, 3), Eigen::MatrixX3d::Zero(2, 3)).status == FitStatus::TooFewPoints);
		CHECK(kMeans(Eigen::MatrixX3d::Zero(3, 3), Eigen::MatrixX3d(0, 3)).status == FitStatus::TooFewPoints);
	}
	SECTION("the iteration cap is reported")
	{
		const Eigen::MatrixX3d p = randomBlobs(100, {{0, 0, 0}, {0.2, 0, 0}}, 0.3, 9);
		KMeansOptions o;
		o.sigma = 0.0;
		o.maxIterations = 1;
		const KMeansResult r = kMeans(p, p.topRows(2), o);
		CHECK(r.iterations == 1);
		CHECK(r.status == FitStatus::NotConverged);
	}
}

TEST_CASE("kmeans: bad arguments throw InvalidInputError", "[fitting][kmeans]")
{
	Eigen::MatrixX3d p = Eigen::MatrixX3d::Zero(3, 3);
	const Eigen::MatrixX3d c = Eigen::MatrixX3d::Zero(1, 3);
	KMeansOptions o;
	o.sigma = -1.0;
	CHECK_THROWS_AS(kMeans(p, c, o), InvalidInputError);
	o = {};
	o.maxIterations = 0;
	CHECK_THROWS_AS(kMeans(p, c, o), InvalidInputError);
	p(1, 2) = std::numeric_limits<double>::quiet_NaN();
	CHECK_THROWS_WITH(kMeans(p, c), Catch::Contains("non-finite"));
}
