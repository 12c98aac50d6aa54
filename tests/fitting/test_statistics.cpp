// statistics.h: mean, median and linearly interpolated quantiles against hand-computed values.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/statistics.h"

#include <catch2/catch.hpp>

using namespace bodyfit;

TEST_CASE("statistics: mean, median and quantiles of small lists", "[statistics]")
{
	// Exact in binary floating point (halves and quarters of small integers), so compared with ==.
	const std::vector<double> odd = {5.0, 1.0, 4.0, 2.0, 3.0};
	const std::vector<double> even = {4.0, 1.0, 3.0, 2.0};
	CHECK(mean(odd) == 3.0);
	CHECK(median(odd) == 3.0);
	CHECK(median(even) == 2.5);
	CHECK(quantile(odd, 0.0) == 1.0);
	CHECK(quantile(odd, 1.0) == 5.0);
	CHECK(quantile(odd, 0.5) == median(odd));
	CHECK(quantile(even, 0.5) == median(even));
	// Position 0.95 * 4 = 3.8 between the sorted values 4 and 5.
	CHECK(quantile(odd, 0.95) == Approx(4.8).epsilon(1e-15));
	CHECK(quantile({7.0}, 0.95) == 7.0);
	CHECK(mean({}) == 0.0);
	CHECK(median({}) == 0.0);
	CHECK(quantile({}, 0.5) == 0.0);
}

TEST_CASE("statistics: a quantile outside [0, 1] is an InvalidInputError", "[statistics]")
{
	CHECK_THROWS_AS(quantile({1.0}, 1.5), InvalidInputError);
	CHECK_THROWS_AS(quantile({1.0}, -0.1), InvalidInputError);
	CHECK_THROWS_AS(quantile({1.0}, std::nan("")), InvalidInputError);
}
