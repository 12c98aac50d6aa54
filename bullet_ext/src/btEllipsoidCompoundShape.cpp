/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidCompoundShape.h.
*/

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include <new>

namespace
{

/// Grid cells list the ellipsoids meeting the cell grown by this fraction of a cell on every side (see the header):
/// a cloth node's path box (its step plus the skin) almost always fits in one grown cell, so the collider reads one
/// list. A quarter of a 5.6 cm cell (1.4 cm for a 1.8 m body) covers steps of 0.8 m/s at 60 Hz from anywhere in
/// the cell; larger dilations lengthen every list.
const double kCellDilation = 0.25;

/// The wide lists: the cell grown by a whole cell on every side (a 3 x 3 x 3 block), for path boxes that leave the
/// grown cell (fast nodes, cell corners) but not the block.
const double kWideCellDilation = 1.0;

/// The smallest margin of an animated compound's lists, in cells: a driver posing a skinned body every substep moves
/// most ellipsoids by well under this (1.4 cm for a 1.8 m body), so the lists are rebuilt only when one has drifted
/// beyond its margin since the last build; the longer lists cost less than rebuilding them every substep
/// (bodyfit-bench colliders_patch --moving: about 250 us per rebuild for 85 ellipsoids, a quarter of the collider's
/// substep).
const double kAnimatedMargin = 0.25;

/// Each ellipsoid's margin at a rebuild: its mean drift per update since the last build times this many updates,
/// within [kAnimatedMargin, kAnimatedMarginMax] cells. One margin for all made the fastest part (a foot, a hand in a
/// walk) rebuild the lists every third substep; per ellipsoid, only the fast ones get the longer lists.
const double kAnimatedMarginUpdates = 16.0;
const double kAnimatedMarginMax = 1.0;

/// Hands the refusal `e` (null: none) to the caller's `error` when it asked for one; true when there is none.
bool reportRefusal(const char* e, const char** error)
{
	if (error)
		*error = e;
	return !e;
}

/// Points `current` at `next`, deleting the object it pointed at when it owned it and `next` is another one.
template <class T>
void replaceOwned(const T*& current, bool& ownsCurrent, const T* next, bool owned)
{
	if (ownsCurrent && current != next)
		delete current;
	current = next;
	ownsCurrent = next && owned;
}

/// R diag(a) of a local ellipsoid.
btMatrix3x3 unwhitenOf(const btEllipsoidLocalData& e)
{
	return e.m_basis.scaled(e.m_semiAxes);
}

/// Of the frames u0 S of the same ellipsoid (S a signed permutation: S ball = ball, so c + u0 S ball is the same set),
/// the one closest to u in the Frobenius norm: the S that maximises trace(S^T u0^T u) = sum_k sign_k m[row_k][k] for
/// m = u0^T u, i.e. the permutation with the largest sum of |m[row_k][k]| and the signs of those entries. A driver
/// that builds each pose from an SVD can hand over the same ellipsoid with axes swapped or signs flipped; compared
/// with u0 itself, that read as a drift of up to twice a semi-axis in one substep.
btMatrix3x3 closestFrame(const btMatrix3x3& u0, const btMatrix3x3& u)
{
	const btMatrix3x3 m = u0.transpose() * u;
	static const int kPermutations[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
	int best = 0;
	btScalar bestSum = -SIMD_INFINITY;
	for (int p = 0; p < 6; ++p)
	{
		const int* row = kPermutations[p];
		const btScalar sum = btFabs(m[row[0]][0]) + btFabs(m[row[1]][1]) + btFabs(m[row[2]][2]);
		if (sum > bestSum)
			bestSum = sum, best = p;
	}
	// Column k of u0 S is sign_k times column row_k of u0.
	btMatrix3x3 out;
	for (int k = 0; k < 3; ++k)
	{
		const int r = kPermutations[best][k];
		const btScalar sign = m[r][k] < btScalar(0) ? btScalar(-1) : btScalar(1);
		for (int j = 0; j < 3; ++j)
			out[j][k] = sign * u0[j][r];
	}
	return out;
}

/// Columns orthonormalised (Gram-Schmidt, column 0 first) and det +1. A degenerate input becomes the identity.
btMatrix3x3 sanitizeBasis(const btMatrix3x3& basis)
{
	btVector3 c0 = basis.getColumn(0);
	btVector3 c1 = basis.getColumn(1);
	const btVector3 c2in = basis.getColumn(2);
	const btScalar l0 = c0.length();
	if (!(l0 > SIMD_EPSILON) || !(l0 < btScalar(BT_LARGE_FLOAT)))
		return btMatrix3x3::getIdentity();
	c0 /= l0;
	c1 -= c0 * c0.dot(c1);
	btScalar l1 = c1.length();
	if (!(l1 > SIMD_EPSILON) || !(l1 < btScalar(BT_LARGE_FLOAT)))
	{
		btVector3 p, q;
		btPlaneSpace1(c0, p, q);
		c1 = p;
		l1 = c1.length();
	}
	c1 /= l1;
	btVector3 c2 = c0.cross(c1);
	if (c2.dot(c2in) < btScalar(0))
	{
		// A reflection was given: the ellipsoid is symmetric, so flipping an axis describes the same set.
		c1 = -c1;
		c2 = c0.cross(c1);
	}
	btMatrix3x3 out;
	out.setValue(c0.x(), c1.x(), c2.x(), c0.y(), c1.y(), c2.y(), c0.z(), c1.z(), c2.z());
	return out;
}

bool isUniform(const btVector3& s)
{
	return s.x() == s.y() && s.y() == s.z();
}

bool transformsEqual(const btTransform& a, const btTransform& b)
{
	const btMatrix3x3& ba = a.getBasis();
	const btMatrix3x3& bb = b.getBasis();
	return a.getOrigin() == b.getOrigin() && ba[0] == bb[0] && ba[1] == bb[1] && ba[2] == bb[2];
}

} // namespace

btEllipsoidCompoundShape::btEllipsoidCompoundShape(btScalar childMargin, bool dynamicAabbTree)
	: btCompoundShape(dynamicAabbTree, 0),
	  m_childMargin(childMargin),
	  m_analyticRevision(0),
	  m_skinField(0),
	  m_ownsSkinField(false),
	  m_bindPose(0),
	  m_ownsBindPose(false),
	  m_skinMesh(0)
{
}

bool btEllipsoidCompoundShape::setBindPose(const btEllipsoidCompoundShape* bindPose, bool owned, const char** error)
{
	const char* e = 0;
	if (bindPose && (bindPose == this || bindPose->getNumEllipsoids() != getNumEllipsoids()))
		e = "btEllipsoidCompoundShape::setBindPose: the bind pose must be another compound with the same ellipsoid count";
	if (!reportRefusal(e, error))
		return false;
	replaceOwned(m_bindPose, m_ownsBindPose, bindPose, owned);
	m_frameBones.clear();
	m_bindToCurrent.clear();
	return true;
}

bool btEllipsoidCompoundShape::setBoneFrames(int count, const int* bones, const btTransform* bindToCurrent,
											 const char** error)
{
	const char* e = 0;
	if (count != getNumEllipsoids() || count <= 0)
		e = "btEllipsoidCompoundShape::setBoneFrames: count differs from getNumEllipsoids()";
	else if (!bones || !bindToCurrent)
		e = "btEllipsoidCompoundShape::setBoneFrames: bones and bindToCurrent must not be null";
	for (int i = 0; !e && i < count; ++i)
	{
		if (bones[i] < 0)
			continue;
		// A rotation: R^T R = I and det R = 1 (the field's distances are only carried by a rigid motion).
		const btMatrix3x3& r = bindToCurrent[i].getBasis();
		const btMatrix3x3 rtr = r.transposeTimes(r);
		btScalar worst = btFabs(r.determinant() - btScalar(1));
		for (int a = 0; a < 3; ++a)
			for (int b = 0; b < 3; ++b)
				worst = btMax(worst, btFabs(rtr[a][b] - (a == b ? btScalar(1) : btScalar(0))));
		if (!(worst <= btScalar(1e-4)) || !(bindToCurrent[i].getOrigin().length2() < BT_LARGE_FLOAT))
			e = "btEllipsoidCompoundShape::setBoneFrames: a rigid ellipsoid's motion is not a finite rotation and "
				"translation (use bone -1 for it)";
	}
	if (!reportRefusal(e, error))
		return false;
	m_frameBones.resize(count);
	m_bindToCurrent.resize(count, btTransform::getIdentity());
	for (int i = 0; i < count; ++i)
	{
		m_frameBones[i] = bones[i];
		m_bindToCurrent[i] = bones[i] >= 0 ? bindToCurrent[i] : btTransform::getIdentity();
	}
	return true;
}

bool btEllipsoidCompoundShape::setSkinField(const btSkinDistanceField* field, bool owned, const char** error)
{
	const char* e = 0;
	if (field && !field->isValid())
		e = "btEllipsoidCompoundShape::setSkinField: the field is not valid (btSkinDistanceField::set failed or never ran)";
	else if (field && !(m_localScaling == btVector3(1, 1, 1)))
		e = "btEllipsoidCompoundShape::setSkinField: the compound has a local scaling other than (1, 1, 1); the field "
			"describes the unscaled body";
	if (!reportRefusal(e, error))
		return false;
	replaceOwned(m_skinField, m_ownsSkinField, field, owned);
	++m_analyticRevision;
	return true;
}

btEllipsoidCompoundShape::~btEllipsoidCompoundShape()
{
	if (m_ownsSkinField)
		delete m_skinField;
	if (m_ownsBindPose)
		delete m_bindPose;
	for (int i = 0; i < m_children.size(); ++i)
	{
		btCollisionShape* child = m_children[i].m_childShape;
		if (child)
		{
			child->~btCollisionShape();
			btAlignedFree(child);
		}
	}
}

int btEllipsoidCompoundShape::addEllipsoid(const btVector3& center, const btMatrix3x3& basis, const btVector3& semiAxes)
{
	const int index = m_ellipsoids.size();
	m_frameBones.clear(); // a new ellipsoid has no frame yet
	m_bindToCurrent.clear();
	m_unscaledCenters.push_back(center);
	m_unscaledBases.push_back(sanitizeBasis(basis));
	btEllipsoidShape probe(semiAxes, m_childMargin); // sanitises the semi-axes the same way the child does
	m_unscaledSemiAxes.push_back(probe.getSemiAxes());
	m_ellipsoids.expand();

	// The child goes in at its final (scaled) transform: btCompoundShape::addChildShape then grows the local AABB by
	// the child's box and inserts that box into the dynamic tree, O(log n). Adding it at identity and moving it would
	// need recalculateLocalAabb, a loop over all children per add (O(n^2) for a whole compound: 100k took ~290 s).
	btVector3 scaledAxes;
	btMatrix3x3 scaledBasis;
	scaledGeometry(index, &scaledAxes, &scaledBasis);
	void* mem = btAlignedAlloc(sizeof(btEllipsoidShape), 16);
	btEllipsoidShape* child = new (mem) btEllipsoidShape(scaledAxes, m_childMargin);
	const btTransform t(scaledBasis, m_unscaledCenters[index] * m_localScaling);
	addChildShape(t, child);
	storeLocalData(index, t);
	++m_analyticRevision;
	return index;
}

void btEllipsoidCompoundShape::setEllipsoid(int index, const btVector3& center, const btMatrix3x3& basis,
										   const btVector3& semiAxes)
{
	btAssert(index >= 0 && index < m_ellipsoids.size());
	if (index < 0 || index >= m_ellipsoids.size())
		return;
	storeUnscaled(index, center, basis, semiAxes);
	applyScaledGeometry(index, true);
	++m_analyticRevision;
}

bool btEllipsoidCompoundShape::setEllipsoids(int count, const btVector3* centers, const btMatrix3x3* bases,
											 const btVector3* semiAxes, const char** error)
{
	const char* dummy = 0;
	const char*& reason = error ? *error : dummy;
	reason = 0;
	if (count != m_ellipsoids.size())
		reason = "btEllipsoidCompoundShape::setEllipsoids: count differs from getNumEllipsoids() (use addEllipsoid / "
				 "removeEllipsoid to change it)";
	else if (count > 0 && (!centers || !bases || !semiAxes))
		reason = "btEllipsoidCompoundShape::setEllipsoids: centers, bases and semiAxes must not be null";
	if (reason)
		return false;
	for (int i = 0; i < count; ++i)
	{
		storeUnscaled(i, centers[i], bases[i], semiAxes[i]);
		applyScaledGeometry(i, false); // the tree leaf now; the local AABB once below
	}
	recalculateLocalAabb();
	++m_analyticRevision;
	return true;
}

void btEllipsoidCompoundShape::removeEllipsoid(int index)
{
	btAssert(index >= 0 && index < m_ellipsoids.size());
	if (index < 0 || index >= m_ellipsoids.size())
		return;
	btCollisionShape* child = m_children[index].m_childShape;
	removeChildShapeByIndex(index); // swaps the last child into index
	const int last = m_ellipsoids.size() - 1;
	m_ellipsoids[index] = m_ellipsoids[last];
	m_unscaledCenters[index] = m_unscaledCenters[last];
	m_unscaledBases[index] = m_unscaledBases[last];
	m_unscaledSemiAxes[index] = m_unscaledSemiAxes[last];
	m_ellipsoids.pop_back();
	m_frameBones.clear(); // the indices changed: the frames no longer match
	m_bindToCurrent.clear();
	m_unscaledCenters.pop_back();
	m_unscaledBases.pop_back();
	m_unscaledSemiAxes.pop_back();
	if (child)
	{
		child->~btCollisionShape();
		btAlignedFree(child);
	}
	recalculateLocalAabb();
	++m_analyticRevision;
}

void btEllipsoidCompoundShape::removeChildShape(btCollisionShape* shape)
{
	for (int i = m_children.size() - 1; i >= 0; --i)
		if (m_children[i].m_childShape == shape)
			removeEllipsoid(i);
}

void btEllipsoidCompoundShape::storeUnscaled(int index, const btVector3& center, const btMatrix3x3& basis,
											 const btVector3& semiAxes)
{
	m_unscaledCenters[index] = center;
	m_unscaledBases[index] = sanitizeBasis(basis);
	btEllipsoidShape probe(semiAxes, m_childMargin); // sanitises the semi-axes the same way the child does
	m_unscaledSemiAxes[index] = probe.getSemiAxes();
}

void btEllipsoidCompoundShape::scaledGeometry(int index, btVector3* scaledAxes, btMatrix3x3* scaledBasis) const
{
	// Affine image of {p : |diag(1/a) R^T (p - c)| <= 1} under p -> S p:
	// centre S c, matrix Q' = S^-1 R diag(1/a^2) R^T S^-1 = R' diag(1/a'^2) R'^T.
	const btVector3& s = m_localScaling;
	const btVector3& a = m_unscaledSemiAxes[index];
	const btMatrix3x3& r = m_unscaledBases[index];
	if (isUniform(s))
	{
		*scaledAxes = a * s.x();
		*scaledBasis = r;
		return;
	}
	const btVector3 invA2(btScalar(1) / (a.x() * a.x()), btScalar(1) / (a.y() * a.y()), btScalar(1) / (a.z() * a.z()));
	const btMatrix3x3 invS = btMatrix3x3::getIdentity().scaled(btVector3(1, 1, 1) / s);
	btMatrix3x3 q = invS * r.scaled(invA2) * r.transpose() * invS;
	btMatrix3x3 rot;
	q.diagonalize(rot, btScalar(1e-12), 64);
	for (int i = 0; i < 3; ++i)
		(*scaledAxes)[i] = btScalar(1) / btSqrt(btMax(q[i][i], SIMD_EPSILON));
	*scaledBasis = sanitizeBasis(rot);
}

void btEllipsoidCompoundShape::storeLocalData(int index, const btTransform& t)
{
	btEllipsoidLocalData& e = m_ellipsoids[index];
	e.m_center = t.getOrigin();
	e.m_basis = t.getBasis();
	e.m_semiAxes = getEllipsoidShape(index)->getSemiAxes();
	computeLocalData(index);
}

void btEllipsoidCompoundShape::applyScaledGeometry(int index, bool recalcAabb)
{
	btVector3 scaledAxes;
	btMatrix3x3 scaledBasis;
	scaledGeometry(index, &scaledAxes, &scaledBasis);
	getEllipsoidShape(index)->setSemiAxes(scaledAxes);
	const btTransform t(scaledBasis, m_unscaledCenters[index] * m_localScaling);
	updateChildTransform(index, t, recalcAabb);
	storeLocalData(index, t);
}

void btEllipsoidCompoundShape::computeLocalData(int index)
{
	btEllipsoidLocalData& e = m_ellipsoids[index];
	const btVector3 invA2(btScalar(1) / (e.m_semiAxes.x() * e.m_semiAxes.x()),
						  btScalar(1) / (e.m_semiAxes.y() * e.m_semiAxes.y()),
						  btScalar(1) / (e.m_semiAxes.z() * e.m_semiAxes.z()));
	e.m_Q = e.m_basis.scaled(invA2) * e.m_basis.transpose();
	btVector3 extent;
	for (int i = 0; i < 3; ++i)
		extent[i] = (e.m_basis[i] * e.m_semiAxes).length();
	e.m_aabbMin = e.m_center - extent;
	e.m_aabbMax = e.m_center + extent;
}

void btEllipsoidCompoundShape::setLocalScaling(const btVector3& scaling)
{
	btVector3 s = scaling.absolute();
	for (int i = 0; i < 3; ++i)
		if (!(s[i] > SIMD_EPSILON) || !(s[i] < btScalar(BT_LARGE_FLOAT)))
		{
			btAssert(!"btEllipsoidCompoundShape: local scaling must be positive and finite");
			s[i] = btScalar(1);
		}
	m_localScaling = s;
	for (int i = 0; i < m_ellipsoids.size(); ++i)
		applyScaledGeometry(i, false);
	recalculateLocalAabb();
	++m_analyticRevision;
}

btScalar btEllipsoidCompoundShape::zeta(int index, const btVector3& localPoint) const
{
	const btEllipsoidLocalData& e = m_ellipsoids[index];
	const btVector3 d = localPoint - e.m_center;
	return d.dot(e.m_Q * d);
}

btScalar btEllipsoidCompoundShape::minZeta(const btVector3& localPoint, int* which) const
{
	btScalar best = SIMD_INFINITY;
	int bestIndex = -1;
	for (int i = 0; i < m_ellipsoids.size(); ++i)
	{
		const btScalar z = zeta(i, localPoint);
		if (z < best)
		{
			best = z;
			bestIndex = i;
		}
	}
	if (which)
		*which = bestIndex;
	return best;
}

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidWorldCache

btEllipsoidWorldCache::btEllipsoidWorldCache()
	: m_shape(0),
	  m_revision(-1),
	  m_invCell(btScalar(1)),
	  m_cell(btScalar(1)),
	  m_cellDilation(btScalar(0)),
	  m_wideDilation(btScalar(0)),
	  m_stampCounter(0),
	  m_gridMargin(btScalar(0)),
	  m_gridBuilds(0),
	  m_updatesSinceBuild(0),
	  m_listsHoldPrevious(false)
{
	m_transform.setIdentity();
	m_inverse.setIdentity();
	m_aabbMin.setValue(0, 0, 0);
	m_aabbMax.setValue(0, 0, 0);
	m_gridOrigin.setValue(0, 0, 0);
	m_dims[0] = m_dims[1] = m_dims[2] = 0;
}

namespace
{

/// Ellipsoid e (body frame) placed by bodyTransform: its world entry, and the narrow phase's packed record {centre,
/// 0, the columns of the whitening matrix each followed by 0} (kPackedStride floats at `packed`).
void placeEntry(const btEllipsoidLocalData& e, const btTransform& bodyTransform, btEllipsoidWorldCache::Entry& w,
				btScalar* packed)
{
	const btMatrix3x3 r = bodyTransform.getBasis() * e.m_basis;
	const btVector3 invA(btScalar(1) / e.m_semiAxes.x(), btScalar(1) / e.m_semiAxes.y(), btScalar(1) / e.m_semiAxes.z());
	w.m_center = bodyTransform * e.m_center;
	w.m_unwhiten = r.scaled(e.m_semiAxes); // R diag(a)
	w.m_whiten = r.transpose();           // then rows scaled by 1/a
	w.m_whiten[0] *= invA.x();
	w.m_whiten[1] *= invA.y();
	w.m_whiten[2] *= invA.z();
	const btVector3 extent(w.m_unwhiten[0].length(), w.m_unwhiten[1].length(), w.m_unwhiten[2].length());
	w.m_aabbMin = w.m_center - extent;
	w.m_aabbMax = w.m_center + extent;
	for (int k = 0; k < 3; ++k)
	{
		packed[k] = w.m_center[k];
		for (int j = 0; j < 3; ++j)
			packed[4 + 4 * j + k] = w.m_whiten[k][j];
	}
	packed[3] = packed[7] = packed[11] = packed[15] = btScalar(0);
}

} // namespace

bool btEllipsoidWorldCache::update(const btEllipsoidCompoundShape* shape, const btTransform& bodyTransform)
{
	const bool sameShape = shape == m_shape && shape && shape->getAnalyticRevision() == m_revision;
	if (sameShape && transformsEqual(bodyTransform, m_transform))
		return false;
	const bool animated = !sameShape && shape && shape == m_shape && shape->getNumEllipsoids() == m_entries.size() &&
						  m_entries.size() > 0;
	m_shape = shape;
	m_transform = bodyTransform;
	m_inverse = bodyTransform.inverse();
	const int n = shape ? shape->getNumEllipsoids() : 0;
	m_revision = shape ? shape->getAnalyticRevision() : -1;
	m_entries.resize(n);
	m_boxes.resize(2 * n);
	m_packed.resize(kPackedStride * btMax(n, 1));
	for (int i = 0; i < n; ++i)
	{
		Entry& w = m_entries[i];
		placeEntry(shape->getEllipsoid(i), bodyTransform, w, &m_packed[kPackedStride * i]);
		m_boxes[2 * i] = w.m_aabbMin;
		m_boxes[2 * i + 1] = w.m_aabbMax;
		if (i == 0)
		{
			m_aabbMin = w.m_aabbMin;
			m_aabbMax = w.m_aabbMax;
		}
		else
		{
			m_aabbMin.setMin(w.m_aabbMin);
			m_aabbMax.setMax(w.m_aabbMax);
		}
	}
	if (n == 0)
	{
		m_aabbMin.setValue(0, 0, 0);
		m_aabbMax.setValue(0, 0, 0);
	}
	// The grid lives in the body frame: a moving body does not rebuild it, nor does an animated compound whose
	// ellipsoids stay within the lists' margin (or, a few, are box-tested since they left it).
	m_listsHoldPrevious = false;
	if (!sameShape && !(animated && gridCovers()))
		buildGrid(animated);
	else if (animated)
	{
		++m_updatesSinceBuild;
		// The lists held every ellipsoid's previous pose at the last update (within its margin there, or box-tested),
		// and nothing was taken from them since.
		m_listsHoldPrevious = true;
	}
	return true;
}

bool btEllipsoidWorldCache::gridCovers()
{
	const int n = m_shape->getNumEllipsoids();
	if (!(m_gridMargin > btScalar(0)) || m_gridCenters.size() != n || m_gridMargins.size() != n ||
		m_isBoxTested.size() != n)
		return false;
	// A fast part (a foot in its swing) leaves its margin long before the rest: it joins the box-tested set, a box
	// test per query, instead of a build of every list (about 3.7 M instructions for 85 ellipsoids).
	const int before = m_boxTested.size();
	for (int i = 0; i < n; ++i)
		if (!m_isBoxTested[i] && !withinGridMargin(i))
		{
			if (m_boxTested.size() == kMaxBoxTested)
			{
				for (int k = before; k < m_boxTested.size(); ++k)
					m_isBoxTested[m_boxTested[k]] = 0;
				m_boxTested.resize(before);
				return false;
			}
			m_boxTested.push_back(i);
			m_isBoxTested[i] = 1;
		}
	return true;
}

bool btEllipsoidWorldCache::withinGridMargin(int i) const
{
	// The drift measured in the build's own frame bounds it as well (any frame of the ellipsoid gives a bound), and
	// it is cheaper: the frame search of driftSinceBuild runs only for an ellipsoid that this bound puts outside.
	const btEllipsoidLocalData& e = m_shape->getEllipsoid(i);
	const btMatrix3x3 d = unwhitenOf(e) - m_gridUnwhiten[i];
	const btScalar drift =
		(e.m_center - m_gridCenters[i]).length() + btSqrt(d[0].length2() + d[1].length2() + d[2].length2());
	return drift <= m_gridMargins[i] || driftSinceBuild(i) <= m_gridMargins[i];
}

btScalar btEllipsoidWorldCache::driftSinceBuild(int i) const
{
	const btEllipsoidLocalData& e = m_shape->getEllipsoid(i);
	const btMatrix3x3 u = unwhitenOf(e), d = u - closestFrame(m_gridUnwhiten[i], u);
	return (e.m_center - m_gridCenters[i]).length() + btSqrt(d[0].length2() + d[1].length2() + d[2].length2());
}

void btEllipsoidWorldCache::chooseGridMargins(bool animated, btScalar cell)
{
	// Each ellipsoid's margin from its mean drift per update since the last build (the first build of an animated
	// compound, and any build after a count change, give every ellipsoid the smallest margin). Deterministic: it
	// depends only on the poses handed in.
	const int n = m_shape->getNumEllipsoids();
	const btScalar smallest = animated ? btScalar(kAnimatedMargin) * cell : btScalar(0);
	const bool haveRates = animated && m_updatesSinceBuild > 0 && m_gridCenters.size() == n;
	m_gridMargins.resize(n);
	m_gridMargin = smallest;
	for (int i = 0; i < n; ++i)
	{
		btScalar margin = smallest;
		if (haveRates)
		{
			// (A NaN drift gets the smallest margin: btMax keeps its second argument, and gridCovers rebuilds.)
			const btScalar perUpdate = driftSinceBuild(i) / btScalar(m_updatesSinceBuild + 1);
			margin = btMin(btMax(perUpdate * btScalar(kAnimatedMarginUpdates), smallest),
						   btScalar(kAnimatedMarginMax) * cell);
		}
		m_gridMargins[i] = margin;
		m_gridMargin = btMax(m_gridMargin, margin);
	}
}

void btEllipsoidWorldCache::buildGrid(bool animated)
{
	const int n = m_shape ? m_shape->getNumEllipsoids() : 0;
	m_cellStart.resize(0);
	m_cellItems.resize(0);
	m_wideStart.resize(0);
	m_wideItems.resize(0);
	m_stamp.resize(n);
	for (int i = 0; i < n; ++i)
		m_stamp[i] = 0;
	m_stampCounter = 0;
	++m_gridBuilds;
	m_boxTested.resize(0);
	m_isBoxTested.resize(n);
	for (int i = 0; i < n; ++i)
		m_isBoxTested[i] = 0;
	if (n == 0)
	{
		m_dims[0] = m_dims[1] = m_dims[2] = 0;
		return;
	}
	btVector3 lo = m_shape->getEllipsoid(0).m_aabbMin, hi = m_shape->getEllipsoid(0).m_aabbMax;
	for (int i = 1; i < n; ++i)
	{
		lo.setMin(m_shape->getEllipsoid(i).m_aabbMin);
		hi.setMax(m_shape->getEllipsoid(i).m_aabbMax);
	}
	// About 32 cells along the longest side of the compound's box (5.6 cm for a 1.8 m body; the arrays stay in L1):
	// a node on the body then meets one to three ellipsoids. Built once per compound revision, in its frame (an
	// animated compound: the box grown by the largest margin, so the ellipsoids stay inside while they stay within
	// theirs).
	btVector3 size = hi - lo;
	chooseGridMargins(animated, btMax(size[size.maxAxis()], btScalar(1e-3)) / btScalar(kGridCellsLongestSide));
	m_updatesSinceBuild = 0;
	const btScalar margin = m_gridMargin;
	lo -= btVector3(margin, margin, margin);
	size += btVector3(2 * margin, 2 * margin, 2 * margin);
	const btScalar longest = btMax(size[size.maxAxis()], btScalar(1e-3));
	const btScalar cell = longest / btScalar(kGridCellsLongestSide);
	m_cell = cell;
	m_invCell = btScalar(1) / cell;
	m_gridOrigin = lo;
	m_cellDilation = btScalar(kCellDilation);
	m_wideDilation = btScalar(kWideCellDilation);
	for (int k = 0; k < 3; ++k)
		m_dims[k] = btMax(1, btMin(int(kGridCellsLongestSide), int(size[k] * m_invCell) + 1));
	// The lists of an animated compound hold each ellipsoid grown by its margin: E within `margin` of E_b meets a
	// grown cell only if E_b meets that cell grown by `margin` more.
	buildLists();
	m_gridCenters.resize(n);
	m_gridUnwhiten.resize(n);
	for (int i = 0; i < n; ++i)
	{
		m_gridCenters[i] = m_shape->getEllipsoid(i).m_center;
		m_gridUnwhiten[i] = unwhitenOf(m_shape->getEllipsoid(i));
	}
}

namespace
{
/// Whether an ellipsoid may meet a grown cell: the cell of the grid grown by `half` - cell/2 on every side (a cube of
/// half-size `half` around the cell centre m). Three conservative tests, each necessary for a meeting:
///  1. the ellipsoid's box overlaps the grown cell;
///  2. the grown cell's circumscribed sphere (radius rc = h sqrt(3)) meets it, i.e. m is in E + ball(rc). Tested
///     in the norm |x|_G of the ellipsoid G with semi-axes a + rc: for x = e + d, e in E, |d| <= rc, the triangle
///     inequality gives |x|_G <= max_k a_k / (a_k + rc) + rc / (min_k a_k + rc). (G alone does not contain
///     E + ball(rc) for thin ellipsoids: the rim of a 1000:1 disc displaced along its normal leaves G, which lost
///     candidates in the collider's property test.)
///  3. in E's whitened coordinates u = W (p - c) the cube is a parallelepiped around W (m - c) whose points are
///     within r = h max_s |W s| of it (s over the corner directions (+-1, +-1, +-1)), so it meets the unit ball
///     only if |W (m - c)| <= 1 + r (tighter than 2 along the long axes of elongated ellipsoids).
/// Everything is relative to the grid origin (no large coordinates 1 km from the origin); the tests get a slack
/// for rounding.
struct GrownCellTest
{
	btScalar m_half, m_slack, m_limit2, m_limitW2;
	btMatrix3x3 m_whitenGrown, m_whiten;
	btVector3 m_centreRel, m_boxMid, m_boxHalf;
	int m_lo[3], m_hi[3]; ///< the cells whose grown cell the ellipsoid's box can overlap

	GrownCellTest(const btEllipsoidLocalData& e, btScalar half, btScalar cell, const btVector3& gridOrigin,
				  const int dims[3])
		: m_half(half), m_slack(cell * btScalar(1e-4))
	{
		const btScalar rc = half * btSqrt(btScalar(3));
		const btVector3 grown = e.m_semiAxes + btVector3(rc, rc, rc);
		m_whitenGrown = e.m_basis.transpose();
		m_whiten = e.m_basis.transpose();
		for (int k = 0; k < 3; ++k)
		{
			m_whitenGrown[k] *= btScalar(1) / grown[k];
			m_whiten[k] *= btScalar(1) / e.m_semiAxes[k];
		}
		const btScalar alpha = btMax(btMax(e.m_semiAxes.x() / grown.x(), e.m_semiAxes.y() / grown.y()),
									 e.m_semiAxes.z() / grown.z());
		const btScalar beta = rc / (e.m_semiAxes[e.m_semiAxes.minAxis()] + rc);
		m_limit2 = (alpha + beta) * (alpha + beta) * btScalar(1.0001); // + rounding slack
		btScalar reach = btScalar(0);
		for (int corner = 0; corner < 4; ++corner)
		{
			const btVector3 s(btScalar(1), (corner & 1) ? btScalar(-1) : btScalar(1),
							  (corner & 2) ? btScalar(-1) : btScalar(1));
			reach = btMax(reach, (m_whiten * s).length());
		}
		const btScalar limitW = btScalar(1) + half * reach;
		m_limitW2 = limitW * limitW * btScalar(1.0001); // + rounding slack
		m_centreRel = e.m_center - gridOrigin;
		const btVector3 boxLo = e.m_aabbMin - gridOrigin, boxHi = e.m_aabbMax - gridOrigin;
		m_boxMid = (boxLo + boxHi) * btScalar(0.5);
		m_boxHalf = (boxHi - boxLo) * btScalar(0.5);
		const btScalar invCell = btScalar(1) / cell;
		for (int k = 0; k < 3; ++k)
		{
			const btScalar fLo = (boxLo[k] - half + cell * btScalar(0.5)) * invCell - btScalar(1e-3);
			const btScalar fHi = (boxHi[k] + half - cell * btScalar(0.5)) * invCell + btScalar(1e-3);
			m_lo[k] = fLo > btScalar(0) ? btMin(int(fLo), dims[k] - 1) : 0;
			m_hi[k] = fHi > btScalar(0) ? btMin(int(fHi), dims[k] - 1) : 0;
		}
	}

	bool inRange(int x, int y, int z) const
	{
		return x >= m_lo[0] && x <= m_hi[0] && y >= m_lo[1] && y <= m_hi[1] && z >= m_lo[2] && z <= m_hi[2];
	}

	/// The cells [x0, x1] of row (y, z) in range whose grown cells the ellipsoid may meet; false when none. Each test
	/// of meets() is a convex set of centres (a box, two ellipsoids), so the cells that pass along a row are an
	/// interval: it is found from both ends, and the cells between are listed without a test (where rounding would
	/// fail one inside, listing it anyway only lengthens the list). A build tests about half the cells it did.
	bool rowSpan(int y, int z, btScalar cell, int& x0, int& x1) const
	{
		const btScalar cy = (btScalar(y) + btScalar(0.5)) * cell, cz = (btScalar(z) + btScalar(0.5)) * cell;
		x0 = m_lo[0];
		while (x0 <= m_hi[0] && !meets(btVector3((btScalar(x0) + btScalar(0.5)) * cell, cy, cz)))
			++x0;
		if (x0 > m_hi[0])
			return false;
		x1 = m_hi[0];
		while (x1 > x0 && !meets(btVector3((btScalar(x1) + btScalar(0.5)) * cell, cy, cz)))
			--x1;
		return true;
	}

	/// The ellipsoid may meet the grown cell centred at `centre` (relative to the grid origin).
	bool meets(const btVector3& centre) const
	{
		const btVector3 gap = (centre - m_boxMid).absolute() - m_boxHalf;
		if (gap.x() > m_half + m_slack || gap.y() > m_half + m_slack || gap.z() > m_half + m_slack)
			return false;
		if ((m_whitenGrown * (centre - m_centreRel)).length2() > m_limit2)
			return false;
		return (m_whiten * (centre - m_centreRel)).length2() <= m_limitW2;
	}
};

/// CSR lists from (cell, item) pairs in item order: start has cells + 1 entries, each cell's items stay in order.
void listsFromPairs(const btAlignedObjectArray<int>& pairs, int cells, btAlignedObjectArray<int>& start,
					btAlignedObjectArray<int>& items, btAlignedObjectArray<int>& cursor)
{
	start.resize(cells + 1);
	for (int c = 0; c <= cells; ++c)
		start[c] = 0;
	const int count = pairs.size() / 2;
	for (int p = 0; p < count; ++p)
		++start[pairs[2 * p] + 1];
	for (int c = 0; c < cells; ++c)
		start[c + 1] += start[c];
	items.resize(count);
	cursor.resize(cells);
	for (int c = 0; c < cells; ++c)
		cursor[c] = start[c];
	for (int p = 0; p < count; ++p)
		items[cursor[pairs[2 * p]]++] = pairs[2 * p + 1];
}

/// Whether k is among the first n entries of a candidate list (a handful long: a linear scan beats a stamp array).
bool listedIn(const int* out, int n, int k)
{
	for (int m = 0; m < n; ++m)
		if (out[m] == k)
			return true;
	return false;
}
} // namespace

void btEllipsoidWorldCache::buildLists()
{
	// A cell lists an ellipsoid if the ellipsoid may meet the cell grown by the dilation (and the ellipsoid's margin)
	// on every side (GrownCellTest). One walk over each ellipsoid's wide range fills both lists: the narrow grown cell
	// is tested only where its range holds the cell.
	const int n = m_shape->getNumEllipsoids();
	const btScalar cell = m_cell;
	const int cells = m_dims[0] * m_dims[1] * m_dims[2];
	m_cellPairs.resize(0);
	m_widePairs.resize(0);
	for (int i = 0; i < n; ++i)
	{
		const btEllipsoidLocalData& e = m_shape->getEllipsoid(i);
		const btScalar margin = m_gridMargins.size() == n ? m_gridMargins[i] : btScalar(0);
		const GrownCellTest narrow(e, cell * (btScalar(0.5) + m_cellDilation) + margin, cell, m_gridOrigin, m_dims);
		const GrownCellTest wide(e, cell * (btScalar(0.5) + m_wideDilation) + margin, cell, m_gridOrigin, m_dims);
		for (int z = wide.m_lo[2]; z <= wide.m_hi[2]; ++z)
			for (int y = wide.m_lo[1]; y <= wide.m_hi[1]; ++y)
			{
				const int row = (z * m_dims[1] + y) * m_dims[0];
				int x0, x1;
				if (wide.rowSpan(y, z, cell, x0, x1))
					for (int x = x0; x <= x1; ++x)
					{
						m_widePairs.push_back(row + x);
						m_widePairs.push_back(i);
					}
				if (narrow.inRange(narrow.m_lo[0], y, z) && narrow.rowSpan(y, z, cell, x0, x1))
					for (int x = x0; x <= x1; ++x)
					{
						m_cellPairs.push_back(row + x);
						m_cellPairs.push_back(i);
					}
			}
	}
	listsFromPairs(m_cellPairs, cells, m_cellStart, m_cellItems, m_pairCursor);
	listsFromPairs(m_widePairs, cells, m_wideStart, m_wideItems, m_pairCursor);
}

btScalar btEllipsoidWorldCache::zeta(int i, const btVector3& worldPoint) const
{
	const Entry& w = m_entries[i];
	return (w.m_whiten * (worldPoint - w.m_center)).length2();
}

void btEllipsoidWorldCache::query(const btVector3& aabbMin, const btVector3& aabbMax, btAlignedObjectArray<int>& out) const
{
	out.resize(0);
	const int n = m_entries.size();
	if (n == 0)
		return;
	for (int k = 0; k < 3; ++k)
		if (aabbMin[k] > m_aabbMax[k] || aabbMax[k] < m_aabbMin[k])
			return;
	// World box -> body-frame box (the 8 transformed corners), then the grid cells under it.
	btVector3 localMin(SIMD_INFINITY, SIMD_INFINITY, SIMD_INFINITY), localMax = -localMin;
	for (int corner = 0; corner < 8; ++corner)
	{
		const btVector3 p((corner & 1) ? aabbMax.x() : aabbMin.x(), (corner & 2) ? aabbMax.y() : aabbMin.y(),
						  (corner & 4) ? aabbMax.z() : aabbMin.z());
		const btVector3 l = m_inverse * p;
		localMin.setMin(l);
		localMax.setMax(l);
	}
	int lo[3], hi[3];
	for (int k = 0; k < 3; ++k)
	{
		lo[k] = cellCoord(localMin[k], k);
		hi[k] = cellCoord(localMax[k], k);
	}
	if (++m_stampCounter == 0)
	{
		for (int i = 0; i < n; ++i)
			m_stamp[i] = 0;
		m_stampCounter = 1;
	}
	for (int z = lo[2]; z <= hi[2]; ++z)
		for (int y = lo[1]; y <= hi[1]; ++y)
			for (int x = lo[0]; x <= hi[0]; ++x)
			{
				const int c = (z * m_dims[1] + y) * m_dims[0] + x;
				for (int j = m_cellStart[c]; j < m_cellStart[c + 1]; ++j)
				{
					const int i = m_cellItems[j];
					if (m_stamp[i] == m_stampCounter)
						continue;
					m_stamp[i] = m_stampCounter;
					const Entry& w = m_entries[i];
					if (aabbMin.x() > w.m_aabbMax.x() || aabbMax.x() < w.m_aabbMin.x() ||
						aabbMin.y() > w.m_aabbMax.y() || aabbMax.y() < w.m_aabbMin.y() ||
						aabbMin.z() > w.m_aabbMax.z() || aabbMax.z() < w.m_aabbMin.z())
						continue;
					out.push_back(i);
				}
			}
	for (int b = 0; b < m_boxTested.size(); ++b)
	{
		const int i = m_boxTested[b];
		const Entry& w = m_entries[i];
		if (m_stamp[i] == m_stampCounter || aabbMin.x() > w.m_aabbMax.x() || aabbMax.x() < w.m_aabbMin.x() ||
			aabbMin.y() > w.m_aabbMax.y() || aabbMax.y() < w.m_aabbMin.y() || aabbMin.z() > w.m_aabbMax.z() ||
			aabbMax.z() < w.m_aabbMin.z())
			continue;
		m_stamp[i] = m_stampCounter;
		out.push_back(i);
	}
}

btScalar btEllipsoidWorldCache::minZeta(const btVector3& worldPoint, int* which) const
{
	btAlignedObjectArray<int> candidates;
	query(worldPoint, worldPoint, candidates);
	btScalar best = SIMD_INFINITY;
	int bestIndex = -1;
	for (int j = 0; j < candidates.size(); ++j)
	{
		const btScalar z = zeta(candidates[j], worldPoint);
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

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidWorldCache::PathQuery

btEllipsoidWorldCache::PathQuery::PathQuery(const btEllipsoidWorldCache& cache, btScalar radius)
	: m_count(cache.m_entries.size()),
	  m_boxes(cache.m_boxes.size() ? &cache.m_boxes[0] : 0),
	  m_cellStart(cache.m_cellStart.size() ? &cache.m_cellStart[0] : 0),
	  m_cellItems(cache.m_cellItems.size() ? &cache.m_cellItems[0] : 0),
	  m_wideStart(cache.m_wideStart.size() ? &cache.m_wideStart[0] : 0),
	  m_wideItems(cache.m_wideItems.size() ? &cache.m_wideItems[0] : 0),
	  m_boxTested(cache.m_boxTested.size() ? &cache.m_boxTested[0] : 0),
	  m_numBoxTested(cache.m_boxTested.size()),
	  m_unionMin(cache.m_aabbMin),
	  m_unionMax(cache.m_aabbMax),
	  m_invCell(cache.m_invCell),
	  m_axisAligned(false),
	  m_radius(radius)
{
	for (int k = 0; k < 3; ++k)
		m_dims[k] = cache.m_dims[k];
	if (m_count == 0)
	{
		m_unionMin.setValue(SIMD_INFINITY, SIMD_INFINITY, SIMD_INFINITY);
		m_unionMax = -m_unionMin;
	}
	const btScalar invCell = cache.m_invCell;
	m_radiusBox.setValue(radius, radius, radius);
	m_radiusCells = m_radiusBox * invCell;
	setBoxTestedBounds();
	const btTransform& toLocal = cache.getInverseTransform();
	// World -> grid units in one affine map: f = (toLocal * p - gridOrigin) / cell.
	m_toGrid = btTransform(toLocal.getBasis().scaled(btVector3(invCell, invCell, invCell)),
						   (toLocal.getOrigin() - cache.m_gridOrigin) * invCell);
	// A body without rotation (the common static case) needs no matrix product: f = (p - (o - t)) / cell, the same
	// value up to rounding, which the allowance below covers.
	m_axisAligned = toLocal.getBasis() == btMatrix3x3::getIdentity();
	m_gridShift = cache.m_gridOrigin - toLocal.getOrigin();
	// The fast path's containment test runs on body-frame coordinates, whose rounding (the world -> body transform
	// of a point near the union: a few ulps of the largest coordinate in play) is taken off the dilation; where that
	// leaves nothing (tiny ellipsoids far from the origin in float) every path takes the cell walk.
	btVector3 farCorner = cache.m_aabbMin.absolute();
	farCorner.setMax(cache.m_aabbMax.absolute());
	const btVector3 origin = toLocal.getOrigin().absolute();
	const btScalar farthest = farCorner[farCorner.maxAxis()] + origin[origin.maxAxis()];
	const btScalar roundingCells = SIMD_EPSILON * btScalar(16) * farthest * invCell;
	m_dilation = cache.m_cellDilation - roundingCells;
	m_wideDilation = cache.m_wideDilation - roundingCells;
}

btEllipsoidWorldCache::PathQuery::PathQuery(const btEllipsoidWorldCache& cache, btScalar radius, const btVector3* boxes,
											 const btVector3& unionMin, const btVector3& unionMax)
	: PathQuery(cache, radius)
{
	m_boxes = boxes;
	if (m_count > 0)
	{
		m_unionMin = unionMin;
		m_unionMax = unionMax;
	}
	setBoxTestedBounds();
}

void btEllipsoidWorldCache::PathQuery::setBoxTestedBounds()
{
	// One test of the path box against the box around the box-tested ellipsoids skips them all for most paths (the
	// fast parts that leave their margins are few and close together: a foot and its shin).
	m_boxTestedMin.setValue(SIMD_INFINITY, SIMD_INFINITY, SIMD_INFINITY);
	m_boxTestedMax = -m_boxTestedMin;
	for (int b = 0; b < m_numBoxTested; ++b)
	{
		m_boxTestedMin.setMin(m_boxes[2 * m_boxTested[b]]);
		m_boxTestedMax.setMax(m_boxes[2 * m_boxTested[b] + 1]);
	}
}

int btEllipsoidWorldCache::PathQuery::walkCells(const btVector3& q, const btVector3& x, const btVector3& boxMin,
												const btVector3& boxMax, int* out) const
{
	const int ne = m_count;
	const int dimX = m_dims[0], dimY = m_dims[1], dimZ = m_dims[2];
	const int dimXY = dimX * dimY;
	const int* cellStart = m_cellStart;
	const btVector3 fq = m_toGrid * q, fx = m_toGrid * x;
	btVector3 fMin = fx, fMax = fx;
	fMin.setMin(fq);
	fMax.setMax(fq);
	fMin -= m_radiusCells;
	fMax += m_radiusCells;
	const int x0 = cellIndex(fMin.x(), dimX), x1 = cellIndex(fMax.x(), dimX);
	const int y0 = cellIndex(fMin.y(), dimY), y1 = cellIndex(fMax.y(), dimY);
	const int z0 = cellIndex(fMin.z(), dimZ), z1 = cellIndex(fMax.z(), dimZ);
	// A long path (a corner of the cloth whipping) spans many cells whose lists repeat the same few ellipsoids: when
	// they hold more entries than there are ellipsoids, every ellipsoid's box is tested once instead (no duplicates).
	int listed = 0;
	for (int iz = z0; iz <= z1 && listed < ne; ++iz)
		for (int iy = y0; iy <= y1; ++iy)
		{
			const int row = iz * dimXY + iy * dimX;
			listed += cellStart[row + x1 + 1] - cellStart[row + x0];
		}
	if (listed >= ne)
		return filterByBox(AllIndices(), ne, m_boxes, boxMin, boxMax, out);
	int nc = 0;
	for (int iz = z0; iz <= z1; ++iz)
		for (int iy = y0; iy <= y1; ++iy)
			for (int ix = x0; ix <= x1; ++ix)
			{
				const int cc = iz * dimXY + iy * dimX + ix;
				for (int j = cellStart[cc]; j < cellStart[cc + 1]; ++j)
				{
					const int k = m_cellItems[j];
					if (!boxesOverlap(boxMin, boxMax, m_boxes[2 * k], m_boxes[2 * k + 1]))
						continue;
					// A box spanning several cells meets an ellipsoid in each: keep the first.
					if (!listedIn(out, nc, k))
						out[nc++] = k;
				}
			}
	return m_numBoxTested > 0 && boxesOverlap(boxMin, boxMax, m_boxTestedMin, m_boxTestedMax)
			   ? addBoxTested(boxMin, boxMax, out, nc)
			   : nc;
}

int btEllipsoidWorldCache::PathQuery::addBoxTested(const btVector3& boxMin, const btVector3& boxMax, int* out,
												   int nc) const
{
	// Their lists hold them at their poses at the build, so one may be listed already: each is added once (out has
	// room for every entry, and holds each at most once).
	const int listed = nc;
	for (int b = 0; b < m_numBoxTested; ++b)
	{
		const int k = m_boxTested[b];
		if (!boxesOverlap(boxMin, boxMax, m_boxes[2 * k], m_boxes[2 * k + 1]))
			continue;
		if (!listedIn(out, listed, k))
			out[nc++] = k;
	}
	return nc;
}
