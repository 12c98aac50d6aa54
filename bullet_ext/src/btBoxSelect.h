/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
Per-component minimum and maximum of two vectors, written as selects. btVector3::setMin / setMax compare and branch per
component when Bullet's SSE API is off (Debian's build): in the per-node box tests and the skin mesh's refit the
outcome of each compare is a coin toss, and those branches mispredicted (the refit of the walk skirt's 26,756-triangle
skin ran 5x faster with selects: bullet_ext/README.md, "Tight skin surface"). The compiler turns a select into
minss / maxss (minsd / maxsd in a float64 build). The values are those of setMin / setMax, NaN included: the first
argument is kept unless the second compares below (above) it.
*/

#ifndef BT_BOX_SELECT_H
#define BT_BOX_SELECT_H

#include "LinearMath/btVector3.h"

inline btScalar btSelectMin(btScalar a, btScalar b) { return b < a ? b : a; }
inline btScalar btSelectMax(btScalar a, btScalar b) { return a < b ? b : a; }

inline btVector3 btSelectMin(const btVector3& a, const btVector3& b)
{
	return btVector3(btSelectMin(a.x(), b.x()), btSelectMin(a.y(), b.y()), btSelectMin(a.z(), b.z()));
}

inline btVector3 btSelectMax(const btVector3& a, const btVector3& b)
{
	return btVector3(btSelectMax(a.x(), b.x()), btSelectMax(a.y(), b.y()), btSelectMax(a.z(), b.z()));
}

#endif // BT_BOX_SELECT_H
