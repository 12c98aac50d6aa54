#pragma once
/// \file statistics.h
/// Summary statistics of a list of numbers (timings, distances): mean, median, quantile. Deterministic; an empty
/// list gives 0 for every statistic (callers that must tell "no data" apart check emptiness themselves).

#include <vector>

namespace bodyfit
{

/// Arithmetic mean (0 for an empty list).
double mean(const std::vector<double>& values);

/// Middle value of the sorted list; the mean of the two middle values for an even count (0 for an empty list).
double median(std::vector<double> values);

/// Quantile q in [0, 1] with linear interpolation between order statistics: position q * (n - 1) in the sorted list
/// (q = 0.5 is the median, q = 1 the maximum). 0 for an empty list.
/// \throws InvalidInputError when q is outside [0, 1] or NaN.
double quantile(std::vector<double> values, double q);

} // namespace bodyfit
