/*
bodyfit: Bullet extension for ellipsoid body colliders.
btEllipsoidShape: a convex, axis-aligned solid ellipsoid for Bullet's GJK/EPA, ray tests and rigid bodies.
*/

#ifndef BT_ELLIPSOID_SHAPE_H
#define BT_ELLIPSOID_SHAPE_H

#include "bodyfit/bullet_ext/btBodyfitPrecision.h"

#include "BulletCollision/CollisionShapes/btConvexInternalShape.h"

/// Smallest semi-axis the shape accepts (metres). Non-positive or non-finite semi-axes are clamped to it.
#define BT_ELLIPSOID_MIN_SEMI_AXIS btScalar(1e-4)

/// Default collision margin of an ellipsoid (metres): small against a 5 cm limb, so the
/// Minkowski-sum rounding (see below) stays under 1 mm for axis ratios up to 6:1.
#define BT_ELLIPSOID_DEFAULT_MARGIN btScalar(0.004)

/// Solid ellipsoid {p : (p_x/a_x)^2 + (p_y/a_y)^2 + (p_z/a_z)^2 <= 1} in its own frame (axis-aligned).
/// Rotation and centre live in the parent transform (a compound child transform or the body transform).
///
/// Bullet convention for the margin: GJK works on the core ellipsoid with semi-axes
/// c = a * localScaling - margin and adds a sphere of radius `margin` back. The result E(c) + B(margin)
/// equals the true ellipsoid on the three axes and is slightly fatter in between; it is exact for a sphere.
/// The margin is clamped to half the smallest scaled semi-axis so the core never degenerates. A sphere (three
/// equal scaled semi-axes) uses a point core and its radius as margin, exactly like btSphereShape: GJK is exact on
/// a point core, while on a curved core it stops at a relative tolerance (a resting body can creep by mm/s).
/// The shape type is CUSTOM_CONVEX_SHAPE_TYPE, so Bullet dispatches it through GJK/EPA (convex-convex,
/// convex-plane, convex-concave), ray tests use the support-function path, and soft bodies reach it through
/// btSoftRigidCollisionAlgorithm (sparse SDF). btCollisionWorld::debugDrawObject does not draw it.
ATTRIBUTE_ALIGNED16(class)
btEllipsoidShape : public btConvexInternalShape
{
protected:
	btVector3 m_semiAxes;       ///< unscaled semi-axes as given by the user
	btScalar m_requestedMargin; ///< margin as requested; the effective one is clamped after each size change

	void updateImplicitDimensions();

public:
	BT_DECLARE_ALIGNED_ALLOCATOR();

	/// \param semiAxes semi-axes along local x, y, z (metres, > 0; bad values are clamped, see BT_ELLIPSOID_MIN_SEMI_AXIS)
	/// \param margin collision margin (>= 0), clamped to half the smallest semi-axis
	btEllipsoidShape(const btVector3& semiAxes, btScalar margin = BT_ELLIPSOID_DEFAULT_MARGIN);

	/// Unscaled semi-axes.
	const btVector3& getSemiAxes() const { return m_semiAxes; }
	/// Semi-axes times the local scaling: the true size of the shape.
	btVector3 getScaledSemiAxes() const { return m_semiAxes * m_localScaling; }
	/// Semi-axes of the GJK core (scaled semi-axes minus the margin).
	btVector3 getCoreSemiAxes() const { return m_implicitShapeDimensions; }
	/// Changes the size. Callers holding the shape in a soft-body world must purge it from the sparse SDF
	/// (btSoftBodyWorldInfo::m_sparsesdf.RemoveReferences(shape)).
	void setSemiAxes(const btVector3& semiAxes);

	/// zeta(p) = sum_i (p_i / a_i)^2 with the scaled semi-axes: < 1 inside, 1 on the surface, > 1 outside.
	btScalar zeta(const btVector3& localPoint) const;

	virtual btVector3 localGetSupportingVertexWithoutMargin(const btVector3& vec) const;
	virtual btVector3 localGetSupportingVertex(const btVector3& vec) const;
	virtual void batchedUnitVectorGetSupportingVertexWithoutMargin(const btVector3* vectors, btVector3* supportVerticesOut,
																   int numVectors) const;
	/// Analytic, tight box of the full ellipsoid (core plus margin).
	virtual void getAabb(const btTransform& t, btVector3& aabbMin, btVector3& aabbMax) const;
	/// Solid ellipsoid: I_x = m (b^2 + c^2) / 5, etc. (scaled semi-axes).
	virtual void calculateLocalInertia(btScalar mass, btVector3& inertia) const;
	virtual void setLocalScaling(const btVector3& scaling);
	virtual void setMargin(btScalar margin);
	virtual void getBoundingSphere(btVector3& center, btScalar& radius) const;
	virtual const char* getName() const { return "Ellipsoid"; }
};

#endif // BT_ELLIPSOID_SHAPE_H
