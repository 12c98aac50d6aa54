#include "bodyfit/fitting/statistics.h"

#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace bodyfit
{

double mean(const std::vector<double>& values)
{
	double sum = 0.0;
	for (double v : values)
		sum += v;
	return values.empty() ? 0.0 : sum / double(values.size());
}

double median(std::vector<double> values)
{
	if (values.empty())
		return 0.0;
	std::sort(values.begin(), values.end());
	const std::size_t n = values.size();
	return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double quantile(std::vector<double> values, double q)
{
	if (!(q >= 0.0 && q <= 1.0))
		throw InvalidInputError("quantile: q = " + std::to_string(q) + " is outside [0, 1]");
	if (values.empty())
		return 0.0;
	std::sort(values.begin(), values.end());
	const double position = q * double(values.size() - 1);
	const std::size_t below = std::size_t(std::floor(position));
	const std::size_t above = std::min(below + 1, values.size() - 1);
	const double t = position - double(below);
	return values[below] + t * (values[above] - values[below]);
}

} // namespace bodyfit
