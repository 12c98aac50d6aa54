/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
The collider's narrow phase: a segment or ray against one ellipsoid, in its whitened coordinates u = W (p - c) where
the ellipsoid is the unit ball and a segment stays a segment. One quadratic, used by the node path test
(btEarliestEntry), the push-out's ray intervals and its escape test (btEllipsoidUnionPushOut.cpp).
Every expression keeps the operation order of the collider before the split, so results are bit-identical.
*/

#ifndef BT_ELLIPSOID_NARROW_PHASE_H
#define BT_ELLIPSOID_NARROW_PHASE_H

#include "LinearMath/btMatrix3x3.h"
#include "LinearMath/btScalar.h"
#include "LinearMath/btVector3.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#if defined(__SSE__) && !defined(BT_USE_DOUBLE_PRECISION)
#include <xmmintrin.h>
#define BT_ELLIPSOID_SSE_PATH 1 ///< float build on x86: SSE for the whitening products of the path test
#endif

/// The line u(s) = u0 + s d against the unit ball: |u(s)|^2 = 1 <=> a s^2 + 2 b s + c = 0 with a = |d|^2, b = u0 . d,
/// c = |u0|^2 - 1; real roots exist where the discriminant b^2 - a c is >= 0.
struct btUnitBallQuadratic
{
	btScalar m_a;
	btScalar m_b;
	btScalar m_c;

	btUnitBallQuadratic(btScalar a, btScalar b, btScalar c) : m_a(a), m_b(b), m_c(c) {}

	/// The quadratic of the whitened line u0 + s d.
	static btUnitBallQuadratic ofLine(const btVector3 &u0, const btVector3 &d)
	{
		return btUnitBallQuadratic(d.length2(), u0.dot(d), u0.length2() - btScalar(1));
	}

	btScalar discriminant() const { return m_b * m_b - m_a * m_c; }

	/// The smaller root in the cancellation-free form c / (sqrt(disc) - b), for a start outside (c >= 0) heading
	/// in (b < 0): the entry parameter. \param disc discriminant() (>= 0)
	btScalar entryRoot(btScalar disc) const { return m_c / (btSqrt(disc) - m_b); }

	/// Both roots s0 <= s1 (needs m_a > 0 and disc >= 0): the chord of the ball along the line.
	void roots(btScalar disc, btScalar &s0, btScalar &s1) const
	{
		const btScalar sq = btSqrt(disc);
		s1 = (-m_b + sq) / m_a;
		s0 = (-m_b - sq) / m_a;
	}

	/// The far root is ahead of u0 (s1 > 0; needs m_a > 0 and disc >= 0): a ray from u0 along d is blocked.
	bool exitAhead(btScalar disc) const { return btSqrt(disc) - m_b > btScalar(0); }
};

/// Parameter of no entry along a path (outside [0, 1]).
const btScalar kNoEntry = btScalar(2);

/// Entry parameter of the whitened segment u_q -> u_q + d (d = u_x - u_q) into the unit ball for a start outside
/// (zq = |u_q|^2 >= 1): the smaller root when the segment heads in (b < 0) and the line meets the ball, else kNoEntry.
/// The root may exceed 1 (the line enters past the end).
inline btScalar btSegmentEntry(btScalar uq0, btScalar uq1, btScalar uq2, btScalar d0, btScalar d1, btScalar d2,
							   btScalar zq)
{
	const btScalar b = uq0 * d0 + uq1 * d1 + uq2 * d2;
	if (!(b < btScalar(0)))
		return kNoEntry;
	const btUnitBallQuadratic quadratic(d0 * d0 + d1 * d1 + d2 * d2, b, zq - btScalar(1));
	const btScalar disc = quadratic.discriminant();
	return disc >= btScalar(0) ? quadratic.entryRoot(disc) : kNoEntry;
}

/// Whitened coordinates u = W (p - c) of a point for one packed record {c, columns of W}
/// (btEllipsoidWorldCache::getPackedRecords), scalar arithmetic.
inline void btWhitenPacked(const btScalar *pk, btScalar px, btScalar py, btScalar pz, btScalar u[3])
{
	const btScalar dx = px - pk[0], dy = py - pk[1], dz = pz - pk[2];
	u[0] = pk[4] * dx + pk[8] * dy + pk[12] * dz;
	u[1] = pk[5] * dx + pk[9] * dy + pk[13] * dz;
	u[2] = pk[6] * dx + pk[10] * dy + pk[14] * dz;
}

/// Smallest zeta = |W (p - c)|^2 at p over the listed packed records; \param which receives its index or -1.
inline btScalar btMinZetaPacked(const btScalar *packed, const int *candidates, int count, const btVector3 &p,
								int *which)
{
	const btScalar px = p.x(), py = p.y(), pz = p.z();
	btScalar best = SIMD_INFINITY;
	int bestIndex = -1;
	for (int j = 0; j < count; ++j)
	{
		btScalar u[3];
		btWhitenPacked(packed + btEllipsoidWorldCache::kPackedStride * candidates[j], px, py, pz, u);
		const btScalar z = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
		if (z < best)
		{
			best = z;
			bestIndex = candidates[j];
		}
	}
	if (which)
		*which = bestIndex;
	return best;
}

/// The two ends of a node path, prepared once per node for btWhitenPath.
struct btPathEnds
{
	btScalar m_q[3];
	btScalar m_x[3];
#ifdef BT_ELLIPSOID_SSE_PATH
	__m128 m_qVec, m_xVec;
#endif
	btPathEnds(const btVector3 &q, const btVector3 &x)
	{
		m_q[0] = q.x(), m_q[1] = q.y(), m_q[2] = q.z();
		m_x[0] = x.x(), m_x[1] = x.y(), m_x[2] = x.z();
#ifdef BT_ELLIPSOID_SSE_PATH
		m_qVec = _mm_setr_ps(m_q[0], m_q[1], m_q[2], btScalar(0));
		m_xVec = _mm_setr_ps(m_x[0], m_x[1], m_x[2], btScalar(0));
#endif
	}
};

#ifdef BT_ELLIPSOID_SSE_PATH
/// W (p - c) in four lanes at once; each lane the same products and sums in the same order as btWhitenPacked.
inline __m128 btWhitenLanes(__m128 p, __m128 centre, __m128 col0, __m128 col1, __m128 col2)
{
	const __m128 d = _mm_sub_ps(p, centre);
	return _mm_add_ps(_mm_add_ps(_mm_mul_ps(col0, _mm_shuffle_ps(d, d, _MM_SHUFFLE(0, 0, 0, 0))),
								 _mm_mul_ps(col1, _mm_shuffle_ps(d, d, _MM_SHUFFLE(1, 1, 1, 1)))),
					  _mm_mul_ps(col2, _mm_shuffle_ps(d, d, _MM_SHUFFLE(2, 2, 2, 2))));
}
#endif

/// Both ends of a node path in the whitened coordinates of one packed record.
inline void btWhitenPath(const btPathEnds &ends, const btScalar *pk, btScalar uq[3], btScalar ux[3])
{
#ifdef BT_ELLIPSOID_SSE_PATH
	const __m128 centre = _mm_loadu_ps(pk);
	const __m128 col0 = _mm_loadu_ps(pk + 4), col1 = _mm_loadu_ps(pk + 8), col2 = _mm_loadu_ps(pk + 12);
	float uqs[4], uxs[4];
	_mm_storeu_ps(uqs, btWhitenLanes(ends.m_qVec, centre, col0, col1, col2));
	_mm_storeu_ps(uxs, btWhitenLanes(ends.m_xVec, centre, col0, col1, col2));
	uq[0] = uqs[0], uq[1] = uqs[1], uq[2] = uqs[2];
	ux[0] = uxs[0], ux[1] = uxs[1], ux[2] = uxs[2];
#else
	btWhitenPacked(pk, ends.m_q[0], ends.m_q[1], ends.m_q[2], uq);
	btWhitenPacked(pk, ends.m_x[0], ends.m_x[1], ends.m_x[2], ux);
#endif
}

/// Result of the path test of one node over its candidates.
struct btPathEntry
{
	int m_ellipsoid;	   ///< the earliest entered ellipsoid (nearest q), -1 if the path enters none
	btScalar m_t;		   ///< its entry parameter along q -> x (kNoEntry if none)
	btVector3 m_u;		   ///< the entry point in that ellipsoid's whitened coordinates
	bool m_startInside;	   ///< q is inside some candidate (the path test does not apply then)
	btScalar m_minZetaEnd; ///< smallest zeta at x over the candidates
};

/// Both ends of the path in the whitened coordinates of entry k: the static path, both ends with the same record.
struct btStaticPathWhitening
{
	const btScalar *m_packed;
	const btPathEnds &m_ends;
	BT_ELLIPSOID_ALWAYS_INLINE void operator()(int k, btScalar uq[3], btScalar ux[3]) const
	{
		btWhitenPath(m_ends, m_packed + btEllipsoidWorldCache::kPackedStride * k, uq, ux);
	}
};

/// The path in the moving frame of entry k (an ellipsoid that moved by itself over the substep): the start in the
/// ellipsoid's previous coordinates u_q = W0 (q - c0), the end in its current ones u_x = W1 (x - c1).
struct btSweptPathWhitening
{
	const btScalar *m_previous; ///< packed records of the previous substep (same layout as the cache's)
	const btScalar *m_current;
	const btPathEnds &m_ends;
	BT_ELLIPSOID_ALWAYS_INLINE void operator()(int k, btScalar uq[3], btScalar ux[3]) const
	{
		const int o = btEllipsoidWorldCache::kPackedStride * k;
#ifdef BT_ELLIPSOID_SSE_PATH
		const btScalar *p = m_previous + o, *c = m_current + o;
		float uqs[4], uxs[4];
		_mm_storeu_ps(uqs, btWhitenLanes(m_ends.m_qVec, _mm_loadu_ps(p), _mm_loadu_ps(p + 4), _mm_loadu_ps(p + 8),
										 _mm_loadu_ps(p + 12)));
		_mm_storeu_ps(uxs, btWhitenLanes(m_ends.m_xVec, _mm_loadu_ps(c), _mm_loadu_ps(c + 4), _mm_loadu_ps(c + 8),
										 _mm_loadu_ps(c + 12)));
		uq[0] = uqs[0], uq[1] = uqs[1], uq[2] = uqs[2];
		ux[0] = uxs[0], ux[1] = uxs[1], ux[2] = uxs[2];
#else
		btWhitenPacked(m_previous + o, m_ends.m_q[0], m_ends.m_q[1], m_ends.m_q[2], uq);
		btWhitenPacked(m_current + o, m_ends.m_x[0], m_ends.m_x[1], m_ends.m_x[2], ux);
#endif
	}
};

/// The path test of one node: for every candidate the entry parameter t of the whitened segment u_q -> u_x into the
/// unit ball (kNoEntry for none or a start inside it, written to tvals[j]); the earliest entry in [0, 1] wins (the
/// first listed on exact ties). An end inside whose root rounding lost counts as an entry at t = 1. `whiten` gives
/// u_q and u_x of a candidate (btStaticPathWhitening or btSweptPathWhitening).
template <class Whitening>
BT_ELLIPSOID_ALWAYS_INLINE void btEarliestEntryWith(const Whitening &whiten, const int *cand, int nc, btScalar *tvals,
													btPathEntry &out)
{
	// Locals in the loop (out is written once at the end: stores to tvals could alias its fields).
	int best = -1;
	btScalar tBest = kNoEntry;
	btVector3 uBest(0, 0, 0);
	bool startInside = false;
	btScalar zMinX = SIMD_INFINITY;
	for (int j = 0; j < nc; ++j)
	{
		btScalar uq[3], ux[3];
		whiten(cand[j], uq, ux);
		const btScalar zx = ux[0] * ux[0] + ux[1] * ux[1] + ux[2] * ux[2];
		const btScalar zq = uq[0] * uq[0] + uq[1] * uq[1] + uq[2] * uq[2];
		zMinX = btMin(zMinX, zx);
		tvals[j] = kNoEntry;
		if (zq < btScalar(1))
		{
			startInside = true;
			continue;
		}
		const btScalar d0 = ux[0] - uq[0], d1 = ux[1] - uq[1], d2 = ux[2] - uq[2];
		btScalar t = btSegmentEntry(uq[0], uq[1], uq[2], d0, d1, d2, zq);
		if (t > btScalar(1) && zx < btScalar(1))
			t = btScalar(1); // the end is inside but rounding lost the root
		tvals[j] = t;
		if (t <= btScalar(1) && t < tBest)
		{
			tBest = t;
			best = cand[j];
			uBest.setValue(uq[0] + d0 * t, uq[1] + d1 * t, uq[2] + d2 * t);
		}
	}
	out.m_ellipsoid = best;
	out.m_t = tBest;
	out.m_u = uBest;
	out.m_startInside = startInside;
	out.m_minZetaEnd = zMinX;
}

/// The static path test (btEarliestEntryWith): both ends against the cache's current ellipsoids.
BT_ELLIPSOID_ALWAYS_INLINE void btEarliestEntry(const btScalar *packed, const int *cand, int nc, const btPathEnds &ends,
												btScalar *tvals, btPathEntry &out)
{
	const btStaticPathWhitening whiten = {packed, ends};
	btEarliestEntryWith(whiten, cand, nc, tvals, out);
}

/// W^T u for a matrix W stored by rows: the (unnormalised) outward normal at the point whose whitened coordinates
/// are u (the gradient of |W (p - c)|^2 is 2 W^T W (p - c)).
inline btVector3 btWhitenedNormal(const btMatrix3x3 &w, const btVector3 &u)
{
	return w[0] * u.x() + w[1] * u.y() + w[2] * u.z();
}

#endif // BT_ELLIPSOID_NARROW_PHASE_H
