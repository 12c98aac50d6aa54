#ifndef BT_FLOAT_RANGE_H
#define BT_FLOAT_RANGE_H

/// \file btFloatRange.h
/// Where single precision stops being safe far from the origin.
///
/// A float has 24 significant bits: coordinates near distance D from the origin are btFloatSpacing(D) =
/// 2^(floor(log2 D) - 23) apart (61 um at 1 km, 0.98 mm at 10 km, 7.8 mm at 100 km, 62.5 mm at 1,000 km). A cloth
/// solver in float resolves nothing finer: links a few mm to cm long get strain noise of spacing / length, the
/// collider's skin offset (2 mm by default) is quantised, and a node falling from rest moves g dt^2 = 43 um in the
/// first substep at 480 Hz, which rounds to no motion at all once the spacing is twice that.
///
/// btCheckFloatRange compares the spacing at the farthest coordinate of a box with a length the simulation must
/// resolve (`resolution`: the collider's skin offset; the scene runner also passes the cloth margin): warning beyond
/// BT_FLOAT_RANGE_WARN_FRACTION of it, refusal beyond BT_FLOAT_RANGE_REFUSE_FRACTION (thresholds and the
/// measurements behind them: bullet_ext/README.md, docs/ROBUSTNESS.md section 9). In a float64 build
/// (BT_USE_DOUBLE_PRECISION) the spacing of btScalar at 1,000 km is 1.2e-10 m and the check passes.

#include "bodyfit/bullet_ext/btBodyfitPrecision.h"

#include <LinearMath/btVector3.h>

enum btFloatRangeStatus
{
	BT_FLOAT_RANGE_OK = 0,
	BT_FLOAT_RANGE_WARN = 1,   ///< usable, but the spacing is a visible fraction of `resolution`
	BT_FLOAT_RANGE_REFUSE = 2, ///< the spacing exceeds a quarter of `resolution`: contacts and links are noise
};

/// Spacing / resolution above which btCheckFloatRange warns (1/32) and refuses (1/4): for the default 2 mm skin,
/// beyond 1,024 m and beyond 8,192 m.
#define BT_FLOAT_RANGE_WARN_FRACTION btScalar(0.03125)
#define BT_FLOAT_RANGE_REFUSE_FRACTION btScalar(0.25)

/// Distance between consecutive 32-bit floats near `distance` (whatever btScalar is): 2^(floor(log2 |d|) - 23).
double btFloatSpacing(double distance);

/// Distance between consecutive btScalar values near `distance` (the float spacing, or the double one in a float64
/// build).
double btScalarSpacing(double distance);

/// Status of a box (world coordinates) for a simulation that must resolve `resolution` metres, in this build's
/// btScalar. `whyNot` (optional) receives a static one-line reason for WARN and REFUSE, 0 for OK.
btFloatRangeStatus btCheckFloatRange(const btVector3& aabbMin, const btVector3& aabbMax, btScalar resolution,
									 const char** whyNot = 0);

/// The smallest distance from the origin at which btCheckFloatRange gives `status` (WARN or REFUSE) for
/// `resolution` in this build (float64: 2^39 m = 5.5e8 km for a 2 mm skin, i.e. never in practice).
double btFloatRangeLimit(btScalar resolution, btFloatRangeStatus status);

#endif
