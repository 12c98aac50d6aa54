/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidShape.h.
*/

#include "bodyfit/bullet_ext/btEllipsoidShape.h"

namespace
{

btScalar sanitizeSemiAxis(btScalar a)
{
	// NaN fails every comparison: it falls through to the clamp.
	if (a >= BT_ELLIPSOID_MIN_SEMI_AXIS && a < btScalar(BT_LARGE_FLOAT))
		return a;
	btAssert(!"btEllipsoidShape: semi-axis must be positive and finite");
	return a >= btScalar(BT_LARGE_FLOAT) ? btScalar(BT_LARGE_FLOAT) : BT_ELLIPSOID_MIN_SEMI_AXIS;
}

btVector3 sanitizeSemiAxes(const btVector3& a)
{
	return btVector3(sanitizeSemiAxis(a.x()), sanitizeSemiAxis(a.y()), sanitizeSemiAxis(a.z()));
}

} // namespace

btEllipsoidShape::btEllipsoidShape(const btVector3& semiAxes, btScalar margin)
	: btConvexInternalShape(), m_semiAxes(sanitizeSemiAxes(semiAxes)), m_requestedMargin(margin)
{
	m_shapeType = CUSTOM_CONVEX_SHAPE_TYPE;
	updateImplicitDimensions();
}

void btEllipsoidShape::updateImplicitDimensions()
{
	const btVector3 scaled = getScaledSemiAxes();
	btScalar margin = m_requestedMargin;
	if (!(margin >= btScalar(0)))
		margin = btScalar(0);
	const btScalar maxMargin = btScalar(0.5) * scaled[scaled.minAxis()];
	if (margin > maxMargin)
		margin = maxMargin;
	if (scaled.x() == scaled.y() && scaled.y() == scaled.z())
		margin = scaled.x(); // a sphere: point core, the radius as margin, exactly like btSphereShape
	m_collisionMargin = margin;
	m_implicitShapeDimensions = scaled - btVector3(margin, margin, margin);
}

void btEllipsoidShape::setSemiAxes(const btVector3& semiAxes)
{
	m_semiAxes = sanitizeSemiAxes(semiAxes);
	updateImplicitDimensions();
}

void btEllipsoidShape::setLocalScaling(const btVector3& scaling)
{
	btConvexInternalShape::setLocalScaling(scaling);
	// A zero scale would collapse the shape: keep every scaled semi-axis at least the minimum.
	for (int i = 0; i < 3; ++i)
		if (m_semiAxes[i] * m_localScaling[i] < BT_ELLIPSOID_MIN_SEMI_AXIS)
			m_localScaling[i] = BT_ELLIPSOID_MIN_SEMI_AXIS / m_semiAxes[i];
	updateImplicitDimensions();
}

void btEllipsoidShape::setMargin(btScalar margin)
{
	m_requestedMargin = margin;
	updateImplicitDimensions();
}

btScalar btEllipsoidShape::zeta(const btVector3& localPoint) const
{
	const btVector3 u = localPoint / getScaledSemiAxes();
	return u.length2();
}

btVector3 btEllipsoidShape::localGetSupportingVertexWithoutMargin(const btVector3& vec) const
{
	// Support point of the core ellipsoid diag(c) * unit ball in direction d: c^2 d / |c d|.
	// d is first divided by its largest component so that tiny or huge directions neither underflow nor overflow.
	const btVector3& c = m_implicitShapeDimensions;
	const btScalar big = vec.absolute()[vec.absolute().maxAxis()];
	if (!(big > btScalar(0)) || !(big < btScalar(BT_LARGE_FLOAT)))
		return btVector3(c.x(), btScalar(0), btScalar(0)); // zero or non-finite direction: any surface point
	const btVector3 d = vec / big;
	const btVector3 cd = c * d;
	const btScalar len = cd.length();
	if (!(len > btScalar(0)))
		return btVector3(0, 0, 0); // point core (a sphere)
	return (c * cd) / len; // len >= min(c) > 0 because one component of d is +-1
}

btVector3 btEllipsoidShape::localGetSupportingVertex(const btVector3& vec) const
{
	btVector3 supVertex = localGetSupportingVertexWithoutMargin(vec);
	const btScalar margin = getMargin();
	if (margin != btScalar(0))
	{
		const btScalar big = vec.absolute()[vec.absolute().maxAxis()];
		btVector3 dir(btScalar(1), btScalar(0), btScalar(0)); // same fallback as the core support point
		if (big > btScalar(0) && big < btScalar(BT_LARGE_FLOAT))
		{
			dir = vec / big;
			dir.normalize();
		}
		supVertex += margin * dir;
	}
	return supVertex;
}

void btEllipsoidShape::batchedUnitVectorGetSupportingVertexWithoutMargin(const btVector3* vectors,
																		 btVector3* supportVerticesOut,
																		 int numVectors) const
{
	for (int i = 0; i < numVectors; ++i)
		supportVerticesOut[i] = localGetSupportingVertexWithoutMargin(vectors[i]);
}

void btEllipsoidShape::getAabb(const btTransform& t, btVector3& aabbMin, btVector3& aabbMax) const
{
	// Half-extent along world axis i of the rotated core: |row i of (B diag(c))|, then the margin sphere.
	const btMatrix3x3& b = t.getBasis();
	const btVector3& c = m_implicitShapeDimensions;
	const btScalar m = getMargin();
	btVector3 extent;
	for (int i = 0; i < 3; ++i)
	{
		const btVector3 row = b[i] * c;
		extent[i] = row.length() + m;
	}
	aabbMin = t.getOrigin() - extent;
	aabbMax = t.getOrigin() + extent;
}

void btEllipsoidShape::calculateLocalInertia(btScalar mass, btVector3& inertia) const
{
	const btVector3 a = getScaledSemiAxes();
	const btVector3 a2 = a * a;
	const btScalar k = mass / btScalar(5);
	inertia.setValue(k * (a2.y() + a2.z()), k * (a2.x() + a2.z()), k * (a2.x() + a2.y()));
}

void btEllipsoidShape::getBoundingSphere(btVector3& center, btScalar& radius) const
{
	center.setValue(btScalar(0), btScalar(0), btScalar(0));
	const btVector3 a = getScaledSemiAxes();
	radius = a[a.maxAxis()];
}
