/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
The union push-out of the cloth collider: a node that starts a substep inside the union of the ellipsoids (the body
moved into it, or a bad start) is moved to the surface of the union along the shortest candidate direction whose
exit is connected to the outside; and the escape test, which moves a point outside every ellipsoid out of a pocket
the union encloses. See btEllipsoidUnionPushOut.cpp.
*/

#ifndef BT_ELLIPSOID_UNION_PUSH_OUT_H
#define BT_ELLIPSOID_UNION_PUSH_OUT_H

#include "LinearMath/btAlignedObjectArray.h"
#include "LinearMath/btVector3.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

/// Where a push-out leaves the union.
struct btPushOutResult
{
	bool m_moved;       ///< false: the point was inside no ellipsoid (caller's tolerance), nothing to do
	btVector3 m_point;  ///< the node's new position (outside every ellipsoid, the skin included)
	btVector3 m_normal; ///< outward normal at the exit
	btVector3 m_center; ///< centre of the ellipsoid the node left (the start point when unknown), for eq. 10
	int m_ellipsoid;    ///< index of that ellipsoid, -1 when unknown (not moved, or the union-box fallback)
	btScalar m_zeta;    ///< smallest zeta at the final point over the ellipsoids whose box holds it
	bool m_enclosed;    ///< every nearest exit led into a pocket enclosed by the union: left past the last chord
	bool m_fallback;    ///< no ray realised an exit: left the union's box (not seen in 1e7 random cases)
};

/// The push-out, with its scratch arrays (one per collider, reused across nodes).
class btEllipsoidUnionPushOut
{
public:
	btEllipsoidUnionPushOut() : m_cache(0), m_escapeRaysCache(0), m_escapeRaysCount(0) {}

	/// Pushes the point `from` out of the union of the cache's ellipsoids, `skin` (>= 0) beyond its surface.
	void pushOut(const btEllipsoidWorldCache& cache, const btVector3& from, btScalar skin, btPushOutResult& out);

	/// Builds the escape test's broad phase (the axis-ray bins) for the cache's current state; leaveEnclosedPocket
	/// needs it after every update of the cache that recomputed it (once per substep that runs the escape test).
	void prepareEscapeRays(const btEllipsoidWorldCache& cache);

	/// A point outside every ellipsoid may still sit in a pocket the union encloses (a gap under the skin of a fitted
	/// body, where the cloth can land when the body is teleported). If no ray of the escape test leaves the union
	/// from `from`, the point leaves along the shortest of the 26 lattice directions past the last chord (m_moved and
	/// m_enclosed set, m_zeta at the exit); otherwise nothing moves (m_moved false; m_zeta is not computed then).
	/// Call prepareEscapeRays for the cache's current state first.
	/// \param hint (may be 0) the ray that escaped from this node last time (kNoEscapeHint at first), tried first and
	/// updated. Only the order of the rays depends on it, never the outcome: a node escapes if any ray does.
	void leaveEnclosedPocket(const btEllipsoidWorldCache& cache, const btVector3& from, btScalar skin,
							 btPushOutResult& out, unsigned char* hint = 0);

	/// The first step of leaveEnclosedPocket alone: true when the ray `hint` names leaves the union from `from` (then
	/// leaveEnclosedPocket would move nothing and keep the hint); false decides nothing (call leavePocketPastHint).
	/// Most calls of a substep end here, without the result record.
	bool escapesAlongHint(const btEllipsoidWorldCache& cache, const btVector3& from, int hint);
	/// The rest of leaveEnclosedPocket, for a caller whose escapesAlongHint just returned false (the hinted ray is not
	/// tested again).
	void leavePocketPastHint(const btEllipsoidWorldCache& cache, const btVector3& from, btScalar skin,
							 btPushOutResult& out, unsigned char* hint);

	/// Escape hints: 0 none; 1 + 2 k + (1 for -e_k) an axis ray; kLatticeHint + d lattice direction d (0..25).
	enum
	{
		kNoEscapeHint = 0,
		kLatticeHint = 7
	};

	/// Smallest zeta at p over every ellipsoid whose world box holds p (SIMD_INFINITY if none: then p is outside all);
	/// \param which receives its index or -1.
	static btScalar minZetaAll(const btEllipsoidWorldCache& cache, const btVector3& p, int* which);

private:
	/// Largest number of exit-direction candidates (7 per containing ellipsoid: the normal and both directions of
	/// each principal axis).
	enum
	{
		kMaxDirections = 56
	};

	/// Bins along the longer side of an axis-ray grid (see AxisBins).
	enum
	{
		kEscapeBinsLongestSide = 16
	};

	/// The escape test's broad phase for rays along world axis k (prepareEscapeRays): square bins over the union
	/// box's two other coordinates (m_axes), each listing every ellipsoid whose world box meets the bin (closed), so
	/// the ellipsoids a ray p +- s e_k can meet are all in the list of p's bin.
	struct AxisBins
	{
		int m_axes[2];
		int m_dims[2];
		btScalar m_lo[2];
		btScalar m_invBin;
		btAlignedObjectArray<int> m_start; ///< CSR: bin b lists m_items[m_start[b]] .. m_items[m_start[b + 1] - 1]
		btAlignedObjectArray<int> m_items;
		/// Bin coordinate along m_axes[i], clamped (monotone in v, so a box holding v lists the bin holding v; NaN: 0).
		int binCoord(btScalar v, int i) const
		{
			return int(btMin(btMax((v - m_lo[i]) * m_invBin, btScalar(0)), btScalar(m_dims[i] - 1)));
		}
	};

	const btEllipsoidWorldCache* m_cache;
	AxisBins m_axisBins[3];
	const btEllipsoidWorldCache* m_escapeRaysCache; ///< the cache the bins were built for (0: none)
	int m_escapeRaysCount;                          ///< its size then
	btAlignedObjectArray<int> m_binFill;            ///< scratch of prepareEscapeRays
	btAlignedObjectArray<int> m_binRanges;          ///< scratch of buildAxisBins: each ellipsoid's bins, 4 ints
	/// The axis-ray bins were built for this cache in its current state (prepareEscapeRays).
	bool binsReadyFor(const btEllipsoidWorldCache& cache) const
	{
		return m_escapeRaysCache == &cache && m_escapeRaysCount == cache.size();
	}
	btAlignedObjectArray<btScalar> m_intervals; ///< chord of ellipsoid m_intervalOwner[i] along the current ray:
												///< [2i] start, [2i + 1] end (widened by the skin), sorted by start
	btAlignedObjectArray<int> m_intervalOwner;

	int candidateDirections(const btVector3& from, btVector3* dirs) const;
	static btVector3 latticeDirection(int d);
	void finishExit(const btVector3& point, const btVector3& dir, int exitEllipsoid, const btVector3& from,
					btPushOutResult& out) const;
	int bestEscapingExit(const btVector3& from, const btVector3* dirs, const btScalar* nominal, int ndirs, btScalar skin,
						 btVector3& out, int& bestExit);
	int shortestLastChordExit(const btVector3& from, const btVector3* dirs, int ndirs, btScalar skin, btVector3& out,
							  int& bestExit);
	void leaveUnionBox(const btVector3& from, const btVector3& dir, btScalar skin, btVector3& out) const;
	void collectRayIntervals(const btVector3& origin, const btVector3& dir, btScalar skin);
	btScalar firstUncovered(btScalar from, btScalar scale, int* exitEllipsoid) const;
	btScalar unionExitAlongRay(const btVector3& origin, const btVector3& dir, btScalar skin, int* exitEllipsoid);
	btScalar realiseExit(const btVector3& origin, const btVector3& dir, btScalar skin, btVector3& out,
						 int* exitEllipsoid, bool lastExit);
	/// \param escaped (may be 0) gets the lattice index of the ray that left (-1: the preferred direction).
	bool escapesUnion(const btVector3& p, const btVector3& preferred, int* escaped = 0) const;
	/// The one ray p + s dir (s > 0) against every ellipsoid: true when none blocks it.
	bool rayEscapes(const btVector3& p, const btVector3& dir) const;
	void buildAxisBins(int axis);
	/// The two rays p +- s e_axis on the bins: +1 when the + ray leaves the union, -1 when only the - ray does, 0
	/// when both are blocked.
	int axisRaysEscape(int axis, const btVector3& p) const;
	/// The one ray p + s sign e_axis (sign +-1) on the bins.
	bool axisRayEscapes(int axis, int sign, const btVector3& p) const;
	/// The hint of the first axis ray that leaves the union (kNoEscapeHint: all six are blocked).
	int someAxisRayEscapes(const btVector3& p) const;
	/// The ray a hint names leaves the union (false for kNoEscapeHint or a hint out of range).
	bool hintedRayEscapes(int hint, const btVector3& p) const;
};

#endif // BT_ELLIPSOID_UNION_PUSH_OUT_H
