/*
bodyfit: Bullet extension for ellipsoid body colliders.
btEllipsoidCompoundShape: a btCompoundShape of btEllipsoidShape children plus packed analytic data,
and btEllipsoidWorldCache: the same ellipsoids in world space for one body pose, with a grid broadphase.
*/

#ifndef BT_ELLIPSOID_COMPOUND_SHAPE_H
#define BT_ELLIPSOID_COMPOUND_SHAPE_H

#include "bodyfit/bullet_ext/btBodyfitPrecision.h"

#include "BulletCollision/CollisionShapes/btCompoundShape.h"
#include "LinearMath/btAlignedObjectArray.h"
#include "LinearMath/btMatrix3x3.h"
#include "LinearMath/btTransform.h"

#include "bodyfit/bullet_ext/btEllipsoidShape.h"
#include "bodyfit/bullet_ext/btSkinDistanceField.h"
#include "bodyfit/bullet_ext/btSkinMesh.h"

#if defined(__SSE__) && !defined(BT_USE_DOUBLE_PRECISION)
#include <xmmintrin.h>
#define BT_ELLIPSOID_SSE_BOXES 1 ///< float build on x86: SSE for the path query's box filter
#endif

/// Inlined even into a large caller (the collider's node loop): SIMD_FORCE_INLINE is a plain inline on Linux.
#if defined(__GNUC__)
#define BT_ELLIPSOID_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define BT_ELLIPSOID_ALWAYS_INLINE inline
#endif

/// One ellipsoid in compound-local space: {p : (p - c)^T Q (p - c) <= 1}, Q = R diag(a^-2) R^T.
/// The columns of m_basis are the principal axes; m_semiAxes are the (scaled) semi-axes along them.
ATTRIBUTE_ALIGNED16(struct)
btEllipsoidLocalData
{
	BT_DECLARE_ALIGNED_ALLOCATOR();

	btVector3 m_center;
	btMatrix3x3 m_basis;  ///< proper rotation, columns = principal axes
	btVector3 m_semiAxes; ///< true semi-axes (local scaling of the compound already applied)
	btMatrix3x3 m_Q;      ///< R diag(1/a^2) R^T
	btVector3 m_aabbMin;  ///< tight local box
	btVector3 m_aabbMax;

	btEllipsoidLocalData()
		: m_center(0, 0, 0),
		  m_basis(btMatrix3x3::getIdentity()),
		  m_semiAxes(1, 1, 1),
		  m_Q(btMatrix3x3::getIdentity()),
		  m_aabbMin(-1, -1, -1),
		  m_aabbMax(1, 1, 1)
	{
	}
};

/// A btCompoundShape whose children are btEllipsoidShape (centre and rotation in the child transform).
/// Keeps COMPOUND_SHAPE_PROXYTYPE, so every Bullet path for compounds works (rigid-rigid through GJK/EPA on
/// each child, ray tests, the soft-body SDF path child by child). Next to the children it keeps the packed
/// analytic array {c, R, a, Q} that the cloth collider reads; both always describe the same ellipsoids.
///
/// Use addEllipsoid / setEllipsoid / setEllipsoids / removeEllipsoid to edit. Do not call the non-virtual
/// btCompoundShape::addChildShape / removeChildShapeByIndex / updateChildTransform on it: they would bypass
/// the analytic array (addChildShape with a non-ellipsoid child is rejected by the collider's checks).
/// The compound owns its child shapes and deletes them.
ATTRIBUTE_ALIGNED16(class)
btEllipsoidCompoundShape : public btCompoundShape
{
protected:
	btAlignedObjectArray<btEllipsoidLocalData> m_ellipsoids; ///< index i <-> child i
	btAlignedObjectArray<btVector3> m_unscaledCenters;       ///< as given, before compound local scaling
	btAlignedObjectArray<btVector3> m_unscaledSemiAxes;
	btAlignedObjectArray<btMatrix3x3> m_unscaledBases;
	btScalar m_childMargin;
	int m_analyticRevision;
	const btSkinDistanceField* m_skinField; ///< the skin's distance field in this compound's frame, or 0
	bool m_ownsSkinField;
	const btEllipsoidCompoundShape* m_bindPose; ///< skinned body: the ellipsoids the field was baked with, or 0
	bool m_ownsBindPose;
	btAlignedObjectArray<int> m_frameBones;            ///< skinned body: per ellipsoid its bone, -1 not rigid
	btAlignedObjectArray<btTransform> m_bindToCurrent; ///< per ellipsoid: bind body frame -> current body frame
	const btSkinMesh* m_skinMesh; ///< skinned body: its skin of the instant in this compound's frame, or 0 (not owned)

	void computeLocalData(int index);
	/// The as-given geometry of ellipsoid `index` (basis and semi-axes sanitised as addEllipsoid does).
	void storeUnscaled(int index, const btVector3& center, const btMatrix3x3& basis, const btVector3& semiAxes);
	/// Semi-axes and basis of ellipsoid `index` under the current local scaling.
	void scaledGeometry(int index, btVector3* scaledAxes, btMatrix3x3* scaledBasis) const;
	/// The packed analytic data of ellipsoid `index` from its child transform `t` and child semi-axes.
	void storeLocalData(int index, const btTransform& t);
	void applyScaledGeometry(int index, bool recalcAabb);

public:
	BT_DECLARE_ALIGNED_ALLOCATOR();

	/// \param childMargin collision margin of every child btEllipsoidShape (see btEllipsoidShape)
	/// \param dynamicAabbTree keep btCompoundShape's dynamic AABB tree of the children (Bullet's rigid-body
	/// collision algorithms use it; the cloth collider does not). addEllipsoid is O(1) plus the tree insert, which
	/// dominates for large compounds (bodyfit-bench compound-build: 100k ellipsoids in ~1.2 s with the tree,
	/// ~0.14 s without).
	explicit btEllipsoidCompoundShape(btScalar childMargin = BT_ELLIPSOID_DEFAULT_MARGIN, bool dynamicAabbTree = true);
	virtual ~btEllipsoidCompoundShape();

	/// Appends an ellipsoid. \param basis rotation whose columns are the principal axes (re-orthonormalised
	/// if slightly off; a reflection is turned into a rotation by flipping the third axis)
	/// \return its index (equal to the child index)
	int addEllipsoid(const btVector3& center, const btMatrix3x3& basis, const btVector3& semiAxes);
	/// Replaces ellipsoid i (child shape, child transform, analytic data, local AABB, dynamic AABB tree). The local
	/// AABB is recomputed over all children, so n calls cost O(n^2); setEllipsoids does the same in O(n).
	void setEllipsoid(int index, const btVector3& center, const btMatrix3x3& basis, const btVector3& semiAxes);
	/// Replaces every ellipsoid in one pass, for a driver that poses the body every substep (a skinned character):
	/// each child's semi-axes and transform, its leaf of the dynamic AABB tree and its analytic data; then the local
	/// AABB once and one revision bump (the cloth collider then treats the change as motion of every ellipsoid from
	/// its previous pose, see btEllipsoidClothCollider.h). The arguments are as for setEllipsoid, one per ellipsoid.
	/// \return false (nothing changed, *error set to a one-line reason if error is not 0) when count differs from
	/// getNumEllipsoids() or an array is null.
	bool setEllipsoids(int count, const btVector3* centers, const btMatrix3x3* bases, const btVector3* semiAxes,
					   const char** error = 0);
	/// Removes ellipsoid i; the last ellipsoid takes index i (as btCompoundShape::removeChildShapeByIndex).
	void removeEllipsoid(int index);

	int getNumEllipsoids() const { return m_ellipsoids.size(); }
	const btEllipsoidLocalData& getEllipsoid(int index) const { return m_ellipsoids[index]; }
	const btEllipsoidLocalData* getEllipsoidData() const { return m_ellipsoids.size() ? &m_ellipsoids[0] : 0; }
	btEllipsoidShape* getEllipsoidShape(int index) { return static_cast<btEllipsoidShape*>(getChildShape(index)); }
	const btEllipsoidShape* getEllipsoidShape(int index) const
	{
		return static_cast<const btEllipsoidShape*>(getChildShape(index));
	}
	btScalar getChildMargin() const { return m_childMargin; }

	/// Increases whenever the analytic data changes (add, set, remove, local scaling, skin field).
	int getAnalyticRevision() const { return m_analyticRevision; }

	/// Attaches the body's skin distance field (body frame = this compound's frame), kept with the ellipsoids so the
	/// cloth collider's tight mode finds it (bullet_ext/README.md, "Tight skin surface"); 0 detaches. \param owned the
	/// compound deletes the field (with `delete`) when it is replaced, detached or the compound is destroyed.
	/// Refused (false, *error set to a one-line reason, nothing taken: the caller still owns the field) for a field
	/// that is not valid (btSkinDistanceField::set failed or never ran) or while the local scaling is not (1, 1, 1):
	/// the field describes the unscaled body.
	bool setSkinField(const btSkinDistanceField* field, bool owned, const char** error = 0);
	/// The attached field, or 0 when there is none or the local scaling is not (1, 1, 1) (a scaled compound keeps
	/// its field but does not use it: distances do not scale with a non-uniform scaling; set the scaling back to use
	/// it again).
	const btSkinDistanceField* getSkinField() const
	{
		return m_skinField && m_localScaling == btVector3(1, 1, 1) ? m_skinField : 0;
	}

	/// A skinned body whose skin field was baked in the bind pose (bullet_ext/README.md, "Tight skin surface",
	/// animated bodies): `bindPose` holds the bind ellipsoids (same count and order; its frame is this compound's);
	/// 0 detaches (and drops the bone frames). \param owned the compound deletes it as setSkinField does its field.
	/// Refused (false, *error set, nothing taken) for a count that differs from getNumEllipsoids().
	bool setBindPose(const btEllipsoidCompoundShape* bindPose, bool owned, const char** error = 0);
	const btEllipsoidCompoundShape* getBindPose() const { return m_bindPose; }
	/// The bone frames of the current pose, written by a skinning driver after setEllipsoids: per ellipsoid the bone
	/// whose rigid motion carries it from the bind pose (-1: not rigid, e.g. refitted at a joint) and that motion
	/// (bind body frame -> current body frame; ignored for -1). Refused (false, *error set) for a count that
	/// differs, null arrays, or a bone >= 0 whose basis is not a rotation (within 1e-4).
	bool setBoneFrames(int count, const int* bones, const btTransform* bindToCurrent, const char** error = 0);
	/// True when setBoneFrames ran since the last change of the ellipsoid count or of the bind pose.
	bool hasBoneFrames() const { return m_frameBones.size() == m_ellipsoids.size() && m_ellipsoids.size() > 0; }
	int getFrameBone(int index) const { return m_frameBones[index]; }
	/// A skinned body's skin of the current pose (and the previous one) in this compound's frame, written by the
	/// skinning driver in the same update as the ellipsoids; the cloth collider's tight mode decides there the nodes
	/// the bind field in a bone's frame cannot (btSkinMeshResponse.cpp). Not owned: it must outlive its use; 0 detaches.
	void setSkinMesh(const btSkinMesh* mesh) { m_skinMesh = mesh; }
	const btSkinMesh* getSkinMesh() const { return m_skinMesh; }
	const btTransform& getBindToCurrent(int index) const { return m_bindToCurrent[index]; }

	/// zeta of ellipsoid i at a compound-local point.
	btScalar zeta(int index, const btVector3& localPoint) const;
	/// Smallest zeta over all ellipsoids (SIMD_INFINITY if there are none); \param which receives its index or -1.
	btScalar minZeta(const btVector3& localPoint, int* which = 0) const;

	/// Removing a child by shape keeps the analytic array in sync.
	virtual void removeChildShape(btCollisionShape* shape);
	/// Exact for any scaling: each ellipsoid is replaced by its affine image (new axes and rotation).
	virtual void setLocalScaling(const btVector3& scaling);
	virtual const char* getName() const { return "EllipsoidCompound"; }
};

/// World-space copy of a compound's ellipsoids for one body transform, plus the broadphase: a uniform grid in the
/// body frame whose cells list the ellipsoids that (conservatively) meet them, so a moving body only re-places the
/// entries, not the grid. update() is cheap when nothing changed (compares the transform and the compound's
/// analytic revision). A compound that changes with the same count (animated: posed every substep) gets lists built
/// with a margin, kept while every ellipsoid stays within it of its pose at the build.
class btEllipsoidWorldCache
{
public:
	/// Per ellipsoid, world space. u = m_whiten * (p - m_center) maps the ellipsoid to the unit ball
	/// (zeta = |u|^2); p = m_center + m_unwhiten * u maps back.
	ATTRIBUTE_ALIGNED16(struct)
	Entry
	{
		BT_DECLARE_ALIGNED_ALLOCATOR();
		btVector3 m_center;
		btMatrix3x3 m_whiten;   ///< diag(1/a) R_world^T
		btMatrix3x3 m_unwhiten; ///< R_world diag(a)
		btVector3 m_aabbMin;
		btVector3 m_aabbMax;

		Entry()
			: m_center(0, 0, 0),
			  m_whiten(btMatrix3x3::getIdentity()),
			  m_unwhiten(btMatrix3x3::getIdentity()),
			  m_aabbMin(-1, -1, -1),
			  m_aabbMax(1, 1, 1)
		{
		}
	};

	btEllipsoidWorldCache();

	/// Recomputes the entries if the transform or the compound changed. \return true if anything was recomputed.
	bool update(const btEllipsoidCompoundShape* shape, const btTransform& bodyTransform);
	/// Forces the next update() to recompute.
	void invalidate() { m_shape = 0; }

	int size() const { return m_entries.size(); }
	const Entry& operator[](int i) const { return m_entries[i]; }
	const btTransform& getTransform() const { return m_transform; }
	const btEllipsoidCompoundShape* getShape() const { return m_shape; }
	/// The compound's analytic revision the entries were computed from (-1 before the first update).
	int getRevision() const { return m_revision; }
	/// Union of all entry boxes.
	const btVector3& getAabbMin() const { return m_aabbMin; }
	const btVector3& getAabbMax() const { return m_aabbMax; }

	/// zeta of entry i at a world point.
	btScalar zeta(int i, const btVector3& worldPoint) const;
	/// Smallest zeta over all entries (uses the grid); SIMD_INFINITY when far from every ellipsoid.
	btScalar minZeta(const btVector3& worldPoint, int* which = 0) const;

	/// Floats per entry in the packed narrow-phase array, four blocks of four: the centre, then the columns of
	/// m_whiten (element (i, j) at 4 + 4 j + i); the fourth float of each block is 0.
	enum
	{
		kPackedStride = 16
	};

	/// World -> body frame (the grid's frame).
	const btTransform& getInverseTransform() const { return m_inverse; }
	/// Grid builds so far (an update that kept the grid leaves it unchanged, as does one that only moved ellipsoids to
	/// the box-tested set).
	int getGridBuilds() const { return m_gridBuilds; }
	/// The ellipsoids of an animated compound that left their margins since the last build (at most
	/// kMaxBoxTested): the queries test their world boxes on every call instead of trusting their (stale) lists.
	int getNumBoxTested() const { return m_boxTested.size(); }
	/// The last update() kept the grid (no build): every ellipsoid's pose before that update was held by the lists as
	/// its current pose is (within its margin of its pose at the build, or box-tested), hence, the drift being convex
	/// along the linear interpolation of centre and frame, every pose between.
	bool listsHoldPreviousPoses() const { return m_listsHoldPrevious; }
	/// The margin the grid lists were built with (metres; 0 unless the compound is animated, see gridCovers).
	btScalar getGridMargin() const { return m_gridMargin; }
	/// Edge of a grid cell (metres).
	btScalar getCellSize() const { return m_cell; }

	/// Grid broadphase: indices of entries whose world box overlaps the world box [aabbMin, aabbMax], each once.
	void query(const btVector3& aabbMin, const btVector3& aabbMax, btAlignedObjectArray<int>& out) const;

	/// The cloth collider's broadphase: candidates for node paths q -> x (world space) grown by a radius on every
	/// side. Prepared once per cache state and radius (the constructor), then asked per node. candidates() writes every
	/// entry whose world box overlaps the path's box [min(q, x) - radius, max(q, x) + radius] and that the grid
	/// lists near the path, each once; it returns a superset of the entries whose ellipsoid the grown path meets
	/// (the grid's lists are conservative, see buildLists). 0 when the box misses the union's box.
	/// The object reads the cache: it is valid until the next update() that recomputes.
	class PathQuery
	{
	public:
		/// Prepares the query for the cache's current state and a radius >= 0 (the collider's skin offset).
		PathQuery(const btEllipsoidWorldCache& cache, btScalar radius);
		/// The same grid lists, filtered by other per-entry world boxes ([2i] min, [2i + 1] max, e.g. the region an
		/// ellipsoid swept over a substep) inside the union box [unionMin, unionMax]: a superset of the entries whose
		/// region meets the grown path, provided the lists hold every entry near its region (see gridCovers).
		PathQuery(const btEllipsoidWorldCache& cache, btScalar radius, const btVector3* boxes, const btVector3& unionMin,
				  const btVector3& unionMax);
		/// Writes the candidates to out (room for size() indices) and returns their number; q and x must be finite
		/// (the collider skips NaN/Inf nodes before). Inline (below): it
		/// runs once per cloth node and substep.
		int candidates(const btVector3& q, const btVector3& x, int* out) const;

		/// The world box test without branches (the outcome is a coin toss per candidate): writes index(j) for
		/// j < n to out, keeping those whose box overlaps [boxMin, boxMax] (closed intervals on x, y and z; four
		/// lanes compared at once where SSE is available, the fourth ignored). \return the number kept.
		/// (Public for the collider's swept broad phase, which filters its own lists the same way.)
		template <class Index>
		static int filterByBox(Index index, int n, const btVector3* boxes, const btVector3& boxMin,
							   const btVector3& boxMax, int* out);
		/// Adds the box-tested ellipsoids (getNumBoxTested) whose box overlaps [boxMin, boxMax] and that are not yet
		/// among out[0, nc) (room for size() indices); returns the new count.
		int addBoxTested(const btVector3& boxMin, const btVector3& boxMax, int* out, int nc) const;
		/// Sets m_boxTestedMin and m_boxTestedMax from m_boxes (an inverted box when there are none).
		void setBoxTestedBounds();
		/// Indices of a cell list.
		struct ListIndex
		{
			const int* m_list;
			int operator()(int j) const { return m_list[j]; }
		};

	private:
		// Copies of the cache's grid (plain pointers and values: the per-node call reads no array objects).
		int m_count;              ///< number of entries
		int m_dims[3];
		const btVector3* m_boxes; ///< entry boxes, [2i] min and [2i + 1] max
		const int* m_cellStart;
		const int* m_cellItems;
		const int* m_wideStart;
		const int* m_wideItems;
		const int* m_boxTested;   ///< the cache's box-tested ellipsoids (m_numBoxTested of them)
		int m_numBoxTested;
		btVector3 m_boxTestedMin; ///< the box around their boxes (in m_boxes)
		btVector3 m_boxTestedMax;
		btVector3 m_unionMin;     ///< the union's box (inverted when the cache is empty)
		btVector3 m_unionMax;
		btScalar m_invCell;
		btVector3 m_radiusBox;    ///< (radius, radius, radius)
		btVector3 m_radiusCells;  ///< the same in cell units
		btTransform m_toGrid;     ///< world -> grid units: f = (toLocal * p - gridOrigin) / cell
		btVector3 m_gridShift;    ///< axis-aligned bodies: f = (p - m_gridShift) / cell
		bool m_axisAligned;       ///< the body has no rotation (the common static case)
		btScalar m_radius;
		btScalar m_dilation;      ///< the cell lists' dilation less the rounding allowance (cells)
		btScalar m_wideDilation;  ///< the same for the wide lists

		/// The path box leaves the grown cell of its midpoint: every cell under it, each ellipsoid once.
		int walkCells(const btVector3& q, const btVector3& x, const btVector3& boxMin, const btVector3& boxMax,
					  int* out) const;

		/// Cell index along one axis of a coordinate in cell units, clamped to [0, dim - 1] (f finite).
		static int cellIndex(btScalar f, int dim)
		{
			// Clamped in floating point (max, min: no branches), then truncated.
			return int(btMin(btMax(f, btScalar(0)), btScalar(dim - 1)));
		}
		static bool boxesOverlap(const btVector3& aMin, const btVector3& aMax, const btVector3& bMin,
								 const btVector3& bMax)
		{
			return !(aMin.x() > bMax.x() || aMax.x() < bMin.x() || aMin.y() > bMax.y() || aMax.y() < bMin.y() ||
					 aMin.z() > bMax.z() || aMax.z() < bMin.z());
		}
		/// Every entry: 0, 1, ..., n - 1.
		struct AllIndices
		{
			int operator()(int j) const { return j; }
		};
	};
	/// Packed narrow-phase records, kPackedStride floats per entry (0 when the cache is empty).
	const btScalar* getPackedRecords() const { return m_packed.size() ? &m_packed[0] : 0; }

private:
	btAlignedObjectArray<Entry> m_entries;
	btAlignedObjectArray<btVector3> m_boxes; ///< entry i's world box: [2i] min, [2i+1] max (compact, for the broadphase)
	btAlignedObjectArray<btScalar> m_packed; ///< entry i's {centre, whitening rows} at [kPackedStride i] (narrow phase)
	btTransform m_transform;
	btTransform m_inverse; ///< world -> body frame
	const btEllipsoidCompoundShape* m_shape;
	int m_revision;
	btVector3 m_aabbMin;
	btVector3 m_aabbMax;

	// uniform grid in the body (compound) frame, CSR lists; rebuilt only when the compound changes (an animated
	// compound: only when an ellipsoid left the lists' margin, see gridCovers)
	enum
	{
		kGridCellsLongestSide = 32
	};
	btVector3 m_gridOrigin;
	btScalar m_invCell;
	btScalar m_cell;
	/// Each cell lists the ellipsoids that meet the cell grown by this fraction of a cell on every side, so a query
	/// box that lies within one grown cell needs only that cell's list (no merging of several lists).
	btScalar m_cellDilation;
	btScalar m_wideDilation; ///< the same for the wide lists (m_wideStart / m_wideItems)
	int m_dims[3];
	btAlignedObjectArray<int> m_cellStart; ///< size cells + 1
	btAlignedObjectArray<int> m_cellItems;
	btAlignedObjectArray<int> m_wideStart; ///< wide lists (cells grown by m_wideDilation), CSR like m_cellStart
	btAlignedObjectArray<int> m_wideItems;
	mutable btAlignedObjectArray<unsigned> m_stamp;
	mutable unsigned m_stampCounter;
	/// An animated compound (changed with the same count) gets lists built for every ellipsoid grown by a margin of
	/// its own (metres, chooseGridMargins; all 0 for a compound seen once), so they stay valid while each ellipsoid
	/// stays within its margin of its pose at the build (gridCovers). m_gridMargin is the largest; then the
	/// build-time poses, in the body frame:
	btScalar m_gridMargin;
	btAlignedObjectArray<btScalar> m_gridMargins;
	int m_gridBuilds;
	int m_updatesSinceBuild; ///< animated updates the lists covered since they were built
	bool m_listsHoldPrevious; ///< see listsHoldPreviousPoses
	/// Ellipsoids that left their margins since the last build, in the order they left (their list entries stay, for
	/// their poses at the build; the queries add them by their boxes), and a flag per ellipsoid.
	btAlignedObjectArray<int> m_boxTested;
	btAlignedObjectArray<unsigned char> m_isBoxTested;
	enum
	{
		/// Box-tested ellipsoids are a box test per query each: beyond this many a build is cheaper.
		kMaxBoxTested = 12
	};
	btAlignedObjectArray<btVector3> m_gridCenters;
	btAlignedObjectArray<btMatrix3x3> m_gridUnwhiten; ///< R diag(a)

	/// \param animated the compound changed with the same count: build with margins (chooseGridMargins)
	void buildGrid(bool animated);
	/// Every ellipsoid i of m_shape lies within m_gridMargins[i] of its pose at the last build (driftSinceBuild), so
	/// the lists still hold it, or is box-tested. Those that left their margins are added to the box-tested set; false
	/// (the grid must be built) when they would be more than kMaxBoxTested (or the lists have no margins).
	bool gridCovers();
	/// An upper bound of how far any point of ellipsoid i moved since the last build: |c - c_b| + |U - U_b|_2 <=
	/// |c - c_b| + |U - U_b|_F (U = R diag(a)).
	btScalar driftSinceBuild(int i) const;
	/// Ellipsoid i lies within its margin of its pose at the last build (driftSinceBuild(i) <= m_gridMargins[i], or
	/// the same bound in the build's frame, skipping the frame search).
	bool withinGridMargin(int i) const;
	/// Sets m_gridMargins and m_gridMargin for a build (`cell`: the cell size before the grid grows by the margin).
	void chooseGridMargins(bool animated, btScalar cell);
	/// The cell lists (cells grown by m_cellDilation) and the wide lists (by m_wideDilation), each ellipsoid grown by
	/// its margin as well.
	void buildLists();
	btAlignedObjectArray<int> m_cellPairs; ///< scratch of buildLists: (cell, ellipsoid) pairs of each list
	btAlignedObjectArray<int> m_widePairs;
	btAlignedObjectArray<int> m_pairCursor;
	/// Cell index along axis k of a world coordinate, clamped to the grid (NaN and huge values included).
	int cellCoord(btScalar value, int k) const
	{
		const btScalar f = (value - m_gridOrigin[k]) * m_invCell;
		if (!(f > btScalar(0)))
			return 0;
		if (f >= btScalar(m_dims[k] - 1))
			return m_dims[k] - 1;
		return int(f);
	}
};

template <class Index>
BT_ELLIPSOID_ALWAYS_INLINE int btEllipsoidWorldCache::PathQuery::filterByBox(Index index, int n, const btVector3* boxes,
																			const btVector3& boxMin,
																			const btVector3& boxMax, int* out)
{
#ifdef BT_ELLIPSOID_SSE_BOXES
	const __m128 mn = _mm_setr_ps(boxMin.x(), boxMin.y(), boxMin.z(), btScalar(0));
	const __m128 mx = _mm_setr_ps(boxMax.x(), boxMax.y(), boxMax.z(), btScalar(0));
#endif
	int nc = 0;
	for (int j = 0; j < n; ++j)
	{
		const int k = index(j);
		const btVector3& lo = boxes[2 * k];
		const btVector3& hi = boxes[2 * k + 1];
		out[nc] = k;
#ifdef BT_ELLIPSOID_SSE_BOXES
		const __m128 a = _mm_cmple_ps(mn, _mm_loadu_ps(&hi.x()));
		const __m128 b = _mm_cmpge_ps(mx, _mm_loadu_ps(&lo.x()));
		nc += (_mm_movemask_ps(_mm_and_ps(a, b)) & 7) == 7 ? 1 : 0;
#else
		nc += ((boxMin.x() <= hi.x()) & (boxMax.x() >= lo.x()) & (boxMin.y() <= hi.y()) & (boxMax.y() >= lo.y()) &
			   (boxMin.z() <= hi.z()) & (boxMax.z() >= lo.z()))
				  ? 1
				  : 0;
#endif
	}
	return nc;
}

BT_ELLIPSOID_ALWAYS_INLINE int btEllipsoidWorldCache::PathQuery::candidates(const btVector3& q, const btVector3& x, int* out) const
{
	// The path box, as btVector3::setMin / setMax would give it, written as selects (branch-free min/max; the
	// branches of btSetMin are a coin toss per node).
	btVector3 boxMin(q.x() < x.x() ? q.x() : x.x(), q.y() < x.y() ? q.y() : x.y(), q.z() < x.z() ? q.z() : x.z());
	btVector3 boxMax(x.x() < q.x() ? q.x() : x.x(), x.y() < q.y() ? q.y() : x.y(), x.z() < q.z() ? q.z() : x.z());
	boxMin -= m_radiusBox;
	boxMax += m_radiusBox;
	if (!boxesOverlap(boxMin, boxMax, m_unionMin, m_unionMax))
		return 0; // (an empty cache has an inverted union box: every path misses it)
	// In cell units f = (p - origin) / cell of the body frame (the grid's). The path grown by the radius lies in the
	// cube of half-size |x - q| / 2 + radius around its midpoint m (a rotation keeps lengths). Fast path: that cube
	// lies within the grown cell of m's cell (the cell plus the dilation on every side, less the rounding allowance),
	// so that cell's list holds every ellipsoid the path can meet; its entries are then filtered by their world
	// boxes. Next, the same with the wide lists (a 3 x 3 x 3 block). Otherwise (a node moving about a cell in one
	// substep) every cell under the box.
	const btScalar invCell = m_invCell;
	const int dimX = m_dims[0], dimY = m_dims[1], dimZ = m_dims[2];
	const btVector3 mid = (x + q) * btScalar(0.5);
	const btVector3 fm = m_axisAligned ? (mid - m_gridShift) * invCell : m_toGrid * mid;
	const int cx = cellIndex(fm.x(), dimX), cy = cellIndex(fm.y(), dimY), cz = cellIndex(fm.z(), dimZ);
	const btVector3 frac = fm - btVector3(btScalar(cx), btScalar(cy), btScalar(cz));
	const btScalar faceGap = btMin(btMin(btMin(frac.x(), frac.y()), frac.z()),
								   btScalar(1) - btMax(btMax(frac.x(), frac.y()), frac.z()));
	// |x - q| / 2 rounded up a little (the midpoint and the length carry rounding too).
	const btScalar halfPath = btSqrt((x - q).length2()) * btScalar(0.5 + 1e-5) + m_radius;
	const btScalar reach = halfPath * invCell - faceGap;
	const int c = cz * dimX * dimY + cy * dimX + cx;
	const int* start;
	const int* items;
	if (reach <= m_dilation)
		start = m_cellStart, items = m_cellItems;
	else if (reach <= m_wideDilation)
		start = m_wideStart, items = m_wideItems;
	else
		return walkCells(q, x, boxMin, boxMax, out);
	const ListIndex list = {items + start[c]};
	const int nc = filterByBox(list, start[c + 1] - start[c], m_boxes, boxMin, boxMax, out);
	return m_numBoxTested > 0 && boxesOverlap(boxMin, boxMax, m_boxTestedMin, m_boxTestedMax)
			   ? addBoxTested(boxMin, boxMax, out, nc)
			   : nc;
}

#endif // BT_ELLIPSOID_COMPOUND_SHAPE_H
