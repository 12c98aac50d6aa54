/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
btEllipsoidSweep: the motion of every ellipsoid of a compound over one substep, when the compound's analytic data
changed between two substeps with the same ellipsoid count (a skinned character posed by a driver). Each ellipsoid j
moves by its own affine map from its previous world geometry (centre c0, unwhiten U0 = R0 diag(a0), whiten
W0 = U0^-1) to its current one (c1, U1, W1); the rigid motion of the body is part of it. The collider's path test then
runs in j's moving frame (btSweptPathWhitening), with the broad phase below. See btEllipsoidSweep.cpp for the bound.
*/

#ifndef BT_ELLIPSOID_SWEEP_H
#define BT_ELLIPSOID_SWEEP_H

#include "LinearMath/btAlignedObjectArray.h"
#include "LinearMath/btMatrix3x3.h"
#include "LinearMath/btVector3.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

class btEllipsoidSweep
{
public:
	btEllipsoidSweep();

	/// Keeps the previous substep's world geometry: call with the cache before it is updated to the new state.
	void capture(const btEllipsoidWorldCache& previous);
	/// Prepares the swept broad phase for the updated cache (same entry count as the captured one).
	/// \return false when no ellipsoid moved (the geometry is bit-identical): then the static path applies.
	bool prepare(const btEllipsoidWorldCache& current);

	/// Packed records {c0, columns of W0} of the previous substep (btEllipsoidWorldCache::getPackedRecords layout).
	const btScalar* previousRecords() const { return m_previous.size() ? &m_previous[0] : 0; }
	/// q carried by ellipsoid j's motion: q_j = c1 + U1 W0 (q - c0) (same whitened coordinates, current frame).
	btVector3 carry(const btEllipsoidWorldCache& current, int j, const btVector3& q) const;
	/// The point of ellipsoid j's previous frame that its motion took to p: p0 = c0 + U0 W1 (p - c1).
	btVector3 previousPoint(const btEllipsoidWorldCache& current, int j, const btVector3& p) const;

	/// Every ellipsoid whose moving-frame path test can meet the node path q -> x grown by `radius` on every side
	/// (see btEllipsoidSweep.cpp for when this is conservative), each once, written to out (room for all entries).
	/// The first kTestedQueries calls after prepare() test every swept box; the grid's lists are built by the next.
	int candidates(const btVector3& q, const btVector3& x, btScalar radius, int* out);
	/// Every path of this substep will ask candidates() (the static grid cannot serve the sweep): the lists are built by
	/// the first call instead of after kTestedQueries box-tested ones.
	void expectEveryPath() { m_testedQueries = int(kTestedQueries); }
	/// How far candidates() grows the path box of q -> x on every side: the radius plus the deviation bound.
	btScalar growth(const btVector3& q, const btVector3& x, btScalar radius) const
	{
		return (radius + m_growthPerLength * ((x - q).length() + m_growthOffset)) * btScalar(1 + 1e-5);
	}

	/// The swept boxes ([2j] min, [2j + 1] max) and their union, for the static grid's lists (see the collider).
	const btVector3* sweptBoxes() const { return m_boxes.size() ? &m_boxes[0] : 0; }
	const btVector3& unionMin() const { return m_origin; }
	const btVector3& unionMax() const { return m_unionMax; }
	/// Some ellipsoid has no deviation bound (listed for every path).
	bool hasUnbounded() const { return m_always.size() > 0; }
	/// The growth of candidates() for any path no longer than `length` (radius excluded).
	btScalar growthUpTo(btScalar length) const
	{
		return m_growthPerLength * (length + m_growthOffset) * btScalar(1 + 1e-5);
	}

	/// True only when the symmetry search of the previous frame's alignment would keep the frame (S = I, bit for
	/// bit) for m = U0^T U1: shown without the search (the common case of a small turn in the same frame).
	static bool keepsFrame(const btMatrix3x3& m);

	/// Cells along the longest side of the swept grid.
	enum
	{
		kCellsLongestSide = 32
	};
	/// Queries of a substep answered by testing every swept box before the grid's lists are built: a build costs
	/// about as many instructions as 600 such queries (85 ellipsoids), and most substeps have a few long paths only.
	enum
	{
		kTestedQueries = 256
	};

private:
	btAlignedObjectArray<btScalar> m_previous;          ///< packed previous records
	btAlignedObjectArray<btMatrix3x3> m_previousUnwhiten; ///< U0 per entry
	btAlignedObjectArray<btVector3> m_boxes;            ///< swept box per entry (hull of both boxes): [2j] min, [2j+1] max
	btAlignedObjectArray<int> m_always;                 ///< entries listed for every path (degenerate interpolation)
	btScalar m_growthPerLength; ///< K: the deviation bound is K (|x - q| + E)
	btScalar m_growthOffset;    ///< E
	// Uniform grid over the union of the swept boxes (world axes), CSR lists of the boxes meeting each grown cell.
	btVector3 m_origin;
	btVector3 m_unionMax;
	btScalar m_invCell;
	int m_dims[3];
	btAlignedObjectArray<int> m_cellStart;
	btAlignedObjectArray<int> m_cellItems;
	bool m_listsBuilt; ///< m_cellStart / m_cellItems are those of the current boxes
	int m_testedQueries; ///< queries since prepare() answered by testing every box (m_bounded)
	btAlignedObjectArray<int> m_bounded; ///< the entries not in m_always, in order

	/// Replaces the previous frame of entry j by its axis symmetry closest to the current frame (same ellipsoid).
	void alignPreviousFrame(const btEllipsoidWorldCache::Entry& now, int j);
	/// Swept box of entry j and its contribution to the deviation bound; false for a degenerate interpolation.
	bool sweptBox(const btEllipsoidWorldCache& current, int j, btScalar& k, btScalar& e);
	/// The grid over the union of the swept boxes of `count` entries (its lists wait for buildLists).
	void sizeGrid(int count);
	/// Lists every swept box in each grown cell it meets (CSR).
	void buildLists();
	/// Cell range [lo, hi] per axis under the world box [bMin, bMax] (clamped to the grid).
	void cellRange(const btVector3& bMin, const btVector3& bMax, int lo[3], int hi[3]) const;
	int walkCells(const btVector3& boxMin, const btVector3& boxMax, int* out) const;
	/// The entries of m_bounded whose swept box overlaps [boxMin, boxMax], in order (the lists' answer, unsorted).
	int testEveryBox(const btVector3& boxMin, const btVector3& boxMax, int* out) const;
};

#endif // BT_ELLIPSOID_SWEEP_H
