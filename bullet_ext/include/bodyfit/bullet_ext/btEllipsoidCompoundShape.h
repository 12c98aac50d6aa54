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
/// Use addEllipsoid / setEllipsoid / removeEllipsoid to edit. Do not call the non-virtual
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

	void computeLocalData(int index);
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
	/// Replaces ellipsoid i (child shape, child transform, analytic data, local AABB, dynamic AABB tree).
	void setEllipsoid(int index, const btVector3& center, const btMatrix3x3& basis, const btVector3& semiAxes);
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

	/// Increases whenever the analytic data changes (add, set, remove, local scaling).
	int getAnalyticRevision() const { return m_analyticRevision; }

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
/// analytic revision).
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

	/// Grid broadphase: indices of entries whose world box overlaps the world box [aabbMin, aabbMax], each once.
	void query(const btVector3& aabbMin, const btVector3& aabbMax, btAlignedObjectArray<int>& out) const;

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

	// uniform grid in the body (compound) frame, CSR lists; rebuilt only when the compound changes
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

	void buildGrid();
	void buildLists(btScalar dilation, btAlignedObjectArray<int>& start, btAlignedObjectArray<int>& items) const;
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
	friend class btEllipsoidClothCollider;
};

#endif // BT_ELLIPSOID_COMPOUND_SHAPE_H
