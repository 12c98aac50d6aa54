/// \file btFloatRange.cpp
/// Float spacing far from the origin and the check of btFloatRange.h.

#include "bodyfit/bullet_ext/btFloatRange.h"

#include <cfloat>
#include <cmath>

namespace
{

/// Spacing of a type with `mantissaBits` significant bits (24 float, 53 double) near |d|; the smallest normal
/// spacing below 1 (the check only cares about large distances).
double spacingOf(double distance, int mantissaBits)
{
	const double d = std::fabs(distance);
	if (!(d >= 1.0))
		return std::ldexp(1.0, 1 - mantissaBits);
	if (!(d <= DBL_MAX))
		return HUGE_VAL;
	int exponent = 0;
	std::frexp(d, &exponent); // d = m 2^exponent, m in [0.5, 1): floor(log2 d) = exponent - 1
	return std::ldexp(1.0, exponent - mantissaBits);
}

int scalarBits() { return sizeof(btScalar) == sizeof(double) ? DBL_MANT_DIG : FLT_MANT_DIG; }

double farthestCoordinate(const btVector3& lo, const btVector3& hi)
{
	double m = 0.0;
	for (int k = 0; k < 3; ++k)
	{
		m = std::fmax(m, std::fabs(double(lo[k])));
		m = std::fmax(m, std::fabs(double(hi[k])));
		if (!std::isfinite(double(lo[k])) || !std::isfinite(double(hi[k])))
			return HUGE_VAL;
	}
	return m;
}

} // namespace

double btFloatSpacing(double distance) { return spacingOf(distance, FLT_MANT_DIG); }

double btScalarSpacing(double distance) { return spacingOf(distance, scalarBits()); }

btFloatRangeStatus btCheckFloatRange(const btVector3& aabbMin, const btVector3& aabbMax, btScalar resolution,
									 const char** whyNot)
{
	if (whyNot)
		*whyNot = 0;
	const double spacing = btScalarSpacing(farthestCoordinate(aabbMin, aabbMax));
	const double r = double(resolution);
	if (!(spacing <= double(BT_FLOAT_RANGE_REFUSE_FRACTION) * r))
	{
		if (whyNot)
			*whyNot = "too far from the origin for float coordinates: their spacing there exceeds a quarter of the skin "
					  "offset (contacts and cloth links become noise); build with float64 Bullet "
					  "(BODYFIT_BULLET_DOUBLE) or move the scene nearer the origin";
		return BT_FLOAT_RANGE_REFUSE;
	}
	if (spacing > double(BT_FLOAT_RANGE_WARN_FRACTION) * r)
	{
		if (whyNot)
			*whyNot = "far from the origin for float coordinates: their spacing there exceeds 1/32 of the skin offset "
					  "(cloth may crumple and nodes end inside the body); float64 Bullet (BODYFIT_BULLET_DOUBLE) or "
					  "a scene nearer the origin is safe";
		return BT_FLOAT_RANGE_WARN;
	}
	return BT_FLOAT_RANGE_OK;
}

double btFloatRangeLimit(btScalar resolution, btFloatRangeStatus status)
{
	const double fraction =
		double(status == BT_FLOAT_RANGE_REFUSE ? BT_FLOAT_RANGE_REFUSE_FRACTION : BT_FLOAT_RANGE_WARN_FRACTION);
	// The spacing 2^(e - bits) is constant on [2^(e-1), 2^e): the status changes at the first power of two whose
	// spacing exceeds fraction * resolution.
	const int bits = scalarBits();
	for (int e = 1; e < 1024; ++e)
		if (std::ldexp(1.0, e - bits) > fraction * double(resolution))
			return std::ldexp(1.0, e - 1);
	return std::ldexp(1.0, 1023);
}
