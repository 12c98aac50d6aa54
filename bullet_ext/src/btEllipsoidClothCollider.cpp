/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidClothCollider.h.
The response follows Gong et al. 2018, sec. 4: all ellipsoids hit along the node's path are found, the entry
point nearest the start position wins (which removes the paper's Figure 6 cases 1-3), the node goes there.
*/

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include "BulletCollision/BroadphaseCollision/btDbvtBroadphase.h"
#include "BulletCollision/CollisionDispatch/btCollisionDispatcher.h"
#include "BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h"
#include "BulletDynamics/Dynamics/btRigidBody.h"
#include "BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h"
#include "LinearMath/btQuickprof.h"

#include <new>

#if defined(__SSE__) && !defined(BT_USE_DOUBLE_PRECISION)
#include <xmmintrin.h>
#define BT_ELLIPSOID_SSE_BOXES 1 ///< float build on x86: SSE for the box filter and the whitening products
#endif

#if defined(__unix__) || defined(__APPLE__)
#include <time.h>
#endif

namespace
{

/// Largest number of exit-direction candidates tried when a node is pushed out of the union
/// (7 per containing ellipsoid: the normal and both directions of each principal axis).
const int kMaxPushDirections = 56;

/// Rounding repair: at most this many steps out along a normal, starting at 2 ulps of the coordinates and
/// doubling (30 ulps in total); anything that needs more is a geometric problem for the union push-out.
const int kMaxNudges = 4;

/// Push-out: at most this many steps along one ray while its rounded exit point is still inside an ellipsoid (the
/// margin doubles from 2 ulps of the coordinates, so 2^40 ulps is far past any union).
const int kMaxRealiseSteps = 40;

/// Bisection steps when a crease shortens the skin offset: the offset is then exact to skin / 2^6 (0.03 mm at 2 mm).
const int kCreaseBisections = 6;

/// Two entries along one path closer than this (metres) are a tie (the path meets a crease of the union).
const btScalar kTieDistance = btScalar(1e-6);

/// CPU time of the calling thread in seconds (0 where the platform has no per-thread clock).
double threadCpuSeconds()
{
#if defined(CLOCK_THREAD_CPUTIME_ID)
	timespec ts;
	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0)
		return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
#endif
	return 0.0;
}

/// True if no coordinate is NaN or infinite (inf - inf and NaN - NaN are NaN).
inline bool isFinite(const btVector3& a, const btVector3& b)
{
	const btScalar s = a.x() + a.y() + a.z() + b.x() + b.y() + b.z();
	return s - s == btScalar(0);
}

inline bool transformsEqual(const btTransform& a, const btTransform& b)
{
	const btMatrix3x3& ba = a.getBasis();
	const btMatrix3x3& bb = b.getBasis();
	return a.getOrigin() == b.getOrigin() && ba[0] == bb[0] && ba[1] == bb[1] && ba[2] == bb[2];
}

/// Cell index along one axis of a coordinate in cell units, clamped to [0, dim - 1].
inline int cellIndex(btScalar f, int dim)
{
	// Clamped in floating point (max, min: no branches), then truncated; f is finite here.
	return int(btMin(btMax(f, btScalar(0)), btScalar(dim - 1)));
}

/// A node's path box for the branch-free world box filter: overlaps(box) is exactly the closed-interval overlap test
/// on x, y and z (four lanes compared at once where SSE is available, the fourth ignored).
struct btPathBox
{
#ifdef BT_ELLIPSOID_SSE_BOXES
	__m128 m_min, m_max;
	btPathBox(const btVector3& mn, const btVector3& mx)
		: m_min(_mm_setr_ps(mn.x(), mn.y(), mn.z(), btScalar(0))), m_max(_mm_setr_ps(mx.x(), mx.y(), mx.z(), btScalar(0)))
	{
	}
	bool overlaps(const btVector3& lo, const btVector3& hi) const
	{
		const __m128 a = _mm_cmple_ps(m_min, _mm_loadu_ps(&hi.x()));
		const __m128 b = _mm_cmpge_ps(m_max, _mm_loadu_ps(&lo.x()));
		return (_mm_movemask_ps(_mm_and_ps(a, b)) & 7) == 7;
	}
#else
	btScalar m_x0, m_y0, m_z0, m_x1, m_y1, m_z1;
	btPathBox(const btVector3& mn, const btVector3& mx)
		: m_x0(mn.x()), m_y0(mn.y()), m_z0(mn.z()), m_x1(mx.x()), m_y1(mx.y()), m_z1(mx.z())
	{
	}
	bool overlaps(const btVector3& lo, const btVector3& hi) const
	{
		return (m_x0 <= hi.x()) & (m_x1 >= lo.x()) & (m_y0 <= hi.y()) & (m_y1 >= lo.y()) & (m_z0 <= hi.z()) &
			   (m_z1 >= lo.z());
	}
#endif
};

inline bool boxesOverlap(const btVector3& aMin, const btVector3& aMax, const btVector3& bMin, const btVector3& bMax)
{
	return !(aMin.x() > bMax.x() || aMax.x() < bMin.x() || aMin.y() > bMax.y() || aMax.y() < bMin.y() ||
			 aMin.z() > bMax.z() || aMax.z() < bMin.z());
}

/// W^T u for a matrix W stored by rows: the (unnormalised) outward normal at the point whose whitened
/// coordinates are u (gradient of |W (p - c)|^2 is 2 W^T W (p - c)).
inline btVector3 transposeTimes(const btMatrix3x3& w, const btVector3& u)
{
	return w[0] * u.x() + w[1] * u.y() + w[2] * u.z();
}

} // namespace

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidClothStats

void btEllipsoidClothStats::reset()
{
	m_substeps = 0;
	m_nodesTested = 0;
	m_nodesCorrected = 0;
	m_nodesPushedOut = 0;
	m_nodesRepaired = 0;
	m_pushOutFallbacks = 0;
	m_pushOutEnclosed = 0;
	m_collisionSeconds = 0.0;
	m_collisionCpuSeconds = 0.0;
	m_minZeta = SIMD_INFINITY;
	m_nonFiniteNodes = 0;
}

void btEllipsoidClothStats::accumulate(const btEllipsoidClothStats& other)
{
	m_substeps += other.m_substeps;
	m_nodesTested += other.m_nodesTested;
	m_nodesCorrected += other.m_nodesCorrected;
	m_nodesPushedOut += other.m_nodesPushedOut;
	m_nodesRepaired += other.m_nodesRepaired;
	m_pushOutFallbacks += other.m_pushOutFallbacks;
	m_pushOutEnclosed += other.m_pushOutEnclosed;
	m_collisionSeconds += other.m_collisionSeconds;
	m_collisionCpuSeconds += other.m_collisionCpuSeconds;
	m_minZeta = btMin(m_minZeta, other.m_minZeta);
	m_nonFiniteNodes += other.m_nonFiniteNodes;
}

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidClothCollider

btEllipsoidClothCollider::btEllipsoidClothCollider(btCollisionObject* body, const Config& config)
	: m_body(body),
	  m_config(config),
	  m_ownedCompound(0),
	  m_compound(0),
	  m_havePose(false),
	  m_moving(false),
	  m_substepIndex(0),
	  m_substepCount(1),
	  m_substepDt(btScalar(0)),
	  m_precisionWarning(0)
{
	m_previousPose.setIdentity();
	m_currentPose.setIdentity();
	m_lastSeenWorldTransform.setIdentity();
	m_delta.setIdentity();
	m_deltaInverse.setIdentity();
	m_stepStart.setIdentity();
	m_stepTarget.setIdentity();
}

btEllipsoidClothCollider::~btEllipsoidClothCollider()
{
	if (m_ownedCompound)
	{
		m_ownedCompound->~btEllipsoidCompoundShape();
		btAlignedFree(m_ownedCompound);
	}
}

void btEllipsoidClothCollider::resetBodyPose()
{
	m_havePose = false;
}

btTransform btEllipsoidClothCollider::interpolatedKinematicPose()
{
	// A kinematic body sits at its end-of-step pose during all substeps of one stepSimulation call
	// (btDiscreteDynamicsWorld::saveKinematicState runs once per call). Interpolate between the pose used in the
	// previous substep and that target; the substep count is recovered from the velocity Bullet computed for the
	// whole interval (|displacement| / |velocity|).
	const btTransform& now = m_body->getWorldTransform();
	if (!transformsEqual(now, m_lastSeenWorldTransform))
	{
		m_lastSeenWorldTransform = now;
		m_stepStart = m_currentPose;
		m_stepTarget = now;
		m_substepIndex = 0;
		m_substepCount = 1;
		const btRigidBody* rb = btRigidBody::upcast(m_body);
		const btScalar dt = m_substepDt;
		btScalar duration = btScalar(0);
		const btScalar linearSpeed = rb->getLinearVelocity().length();
		const btScalar angularSpeed = rb->getAngularVelocity().length();
		const btScalar distance = (now.getOrigin() - m_stepStart.getOrigin()).length();
		btVector3 axis;
		btScalar angle = btScalar(0);
		btTransformUtil::calculateDiffAxisAngle(m_stepStart, now, axis, angle);
		// Compare both motions on the same scale: a rotation by angle moves points 1 m away by about angle metres.
		if (linearSpeed * dt > SIMD_EPSILON && distance >= angle)
			duration = distance / linearSpeed;
		else if (angularSpeed * dt > SIMD_EPSILON)
			duration = btFabs(angle) / angularSpeed;
		if (dt > btScalar(0) && duration > btScalar(0))
		{
			const btScalar steps = duration / dt + btScalar(0.5);
			m_substepCount = steps >= btScalar(1e6) ? 1000000 : btMax(1, int(steps));
		}
	}
	++m_substepIndex;
	if (m_substepIndex >= m_substepCount)
		return m_stepTarget;
	const btScalar f = btScalar(m_substepIndex) / btScalar(m_substepCount);
	btTransform out;
	out.setOrigin(m_stepStart.getOrigin().lerp(m_stepTarget.getOrigin(), f));
	btQuaternion q0, q1;
	m_stepStart.getBasis().getRotation(q0);
	m_stepTarget.getBasis().getRotation(q1);
	if (q0.dot(q1) < btScalar(0))
		q1 = -q1;
	out.setRotation(q0.slerp(q1, f));
	return out;
}

void btEllipsoidClothCollider::beginSubstep(btScalar dt)
{
	m_lastStats.reset();
	m_lastStats.m_substeps = 1;
	btClock clock;
	const double cpu0 = threadCpuSeconds();
	m_substepDt = dt;
	const btTransform& now = m_body->getWorldTransform();
	if (!m_havePose)
	{
		m_previousPose = now;
		m_currentPose = now;
		m_lastSeenWorldTransform = now;
		m_stepStart = now;
		m_stepTarget = now;
		m_substepIndex = 0;
		m_substepCount = 1;
		m_havePose = true;
	}
	else
	{
		// Continuity: the nodes were made valid against the pose of the previous substep.
		m_previousPose = m_currentPose;
		const btRigidBody* rb = btRigidBody::upcast(m_body);
		if (rb && rb->isKinematicObject())
			m_currentPose = interpolatedKinematicPose();
		else
			m_currentPose = now;
	}
	m_moving = !transformsEqual(m_previousPose, m_currentPose);
	if (m_moving)
	{
		m_delta = m_currentPose * m_previousPose.inverse();
		m_deltaInverse = m_delta.inverse();
	}
	else
	{
		m_delta.setIdentity();
		m_deltaInverse.setIdentity();
	}
	m_current.update(m_compound, m_currentPose);
	m_lastStats.m_collisionSeconds += double(clock.getTimeNanoseconds()) * 1e-9;
	m_lastStats.m_collisionCpuSeconds += threadCpuSeconds() - cpu0;
}

void btEllipsoidClothCollider::endSubstep()
{
	m_accumulatedStats.accumulate(m_lastStats);
}

void btEllipsoidClothCollider::ensureResponseDisabled(btSoftBody* softBody)
{
	if (!m_config.m_disableBulletResponse)
		return;
	btAlignedObjectArray<const btCollisionObject*>& disabled = softBody->m_collisionDisabledObjects;
	if (disabled.findLinearSearch(m_body) == disabled.size())
		disabled.push_back(m_body);
}

btVector3 btEllipsoidClothCollider::bodyVelocityAt(const btVector3& worldPoint, btScalar dt) const
{
	if (!m_moving || !(dt > btScalar(0)))
		return btVector3(0, 0, 0);
	return (worldPoint - m_deltaInverse * worldPoint) / dt;
}

void btEllipsoidClothCollider::applyVelocityRule(btSoftBody::Node& node, const btVector3& surfacePoint,
												 const btVector3& normal, const btVector3& start,
												 const btVector3& center, btScalar dt) const
{
	const btVector3 vb = bodyVelocityAt(surfacePoint, dt);
	btVector3 vr = node.m_v - vb;
	if (m_config.m_useEq10 || m_config.m_velocityRule == PAPER_EQ10)
	{
		// Gong et al. 2018, eq. 10: v_c = v_n |c P0| / (|c P0| + |P0 p0|).
		const btScalar cp = (surfacePoint - center).length();
		const btScalar pq = (start - surfacePoint).length();
		const btScalar denom = cp + pq;
		if (denom > btScalar(0))
			vr *= cp / denom;
	}
	else
	{
		const btScalar vn = vr.dot(normal);
		if (vn < btScalar(0))
		{
			btVector3 vt = vr - normal * vn;
			const btScalar vtLen = vt.length();
			const btScalar drop = btMax(m_config.m_friction, btScalar(0)) * (-vn);
			if (vtLen <= drop)
				vt.setValue(0, 0, 0);
			else
				vt *= (vtLen - drop) / vtLen;
			vr = vt;
		}
	}
	node.m_v = vb + vr;
}

void btEllipsoidClothCollider::collectRayIntervals(const btVector3& origin, const btVector3& dir, btScalar skin)
{
	// Every ellipsoid's interval along the ray, widened by the skin on both sides, sorted by start. The quadratic is
	// set up relative to each ellipsoid's centre (origin - c is exact or nearly so for nearby points, also 1 km out).
	const btEllipsoidWorldCache& cache = m_current;
	const int ne = cache.size();
	m_intervals.resize(0);
	m_intervalOwner.resize(0);
	for (int k = 0; k < ne; ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		const btVector3 u0 = e.m_whiten * (origin - e.m_center);
		const btVector3 w = e.m_whiten * dir;
		const btScalar a = w.length2();
		if (!(a > btScalar(0)))
			continue;
		const btScalar b = u0.dot(w);
		const btScalar c = u0.length2() - btScalar(1);
		const btScalar disc = b * b - a * c;
		if (disc < btScalar(0))
			continue;
		const btScalar sq = btSqrt(disc);
		const btScalar s1 = (-b + sq) / a;
		if (s1 + skin < btScalar(0))
			continue;
		const btScalar s0 = (-b - sq) / a;
		m_intervals.push_back(s0 - skin);
		m_intervals.push_back(s1 + skin);
		m_intervalOwner.push_back(k);
	}
	const int count = m_intervalOwner.size();
	// Insertion sort by start (few intervals).
	for (int i = 1; i < count; ++i)
	{
		const btScalar s0 = m_intervals[2 * i], s1 = m_intervals[2 * i + 1];
		const int owner = m_intervalOwner[i];
		int j = i - 1;
		while (j >= 0 && m_intervals[2 * j] > s0)
		{
			m_intervals[2 * j + 2] = m_intervals[2 * j];
			m_intervals[2 * j + 3] = m_intervals[2 * j + 1];
			m_intervalOwner[j + 1] = m_intervalOwner[j];
			--j;
		}
		m_intervals[2 * j + 2] = s0;
		m_intervals[2 * j + 3] = s1;
		m_intervalOwner[j + 1] = owner;
	}
}

btScalar btEllipsoidClothCollider::firstUncovered(btScalar from, btScalar scale, int* exitEllipsoid) const
{
	// Sweep over the sorted intervals: the first parameter s >= from that no interval covers. Intervals that start
	// within a few ulps of the current s count as overlapping: two ellipsoids that touch share a boundary point, and
	// stopping there would leave the node on (rounding: inside) the second one.
	const int count = m_intervalOwner.size();
	btScalar s = from;
	int exit = -1;
	for (int i = 0; i < count; ++i)
	{
		if (m_intervals[2 * i] > s + SIMD_EPSILON * btScalar(8) * (scale + btFabs(s)))
			break;
		if (m_intervals[2 * i + 1] > s)
		{
			s = m_intervals[2 * i + 1];
			exit = m_intervalOwner[i];
		}
	}
	if (exitEllipsoid)
		*exitEllipsoid = exit;
	return s;
}

btScalar btEllipsoidClothCollider::unionExitAlongRay(const btVector3& origin, const btVector3& dir, btScalar skin,
													 int* exitEllipsoid)
{
	collectRayIntervals(origin, dir, skin);
	const btScalar scale = origin.absolute()[origin.absolute().maxAxis()] + btScalar(1e-3);
	return firstUncovered(btScalar(0), scale, exitEllipsoid);
}

btScalar btEllipsoidClothCollider::realiseExit(const btVector3& origin, const btVector3& dir, btScalar skin,
											   btVector3& out, int* exitEllipsoid, bool lastExit)
{
	// The exact union exit s along the ray is a real number; the node needs a btScalar point. Rounding
	// origin + dir * s to the coordinate grid (6e-5 m at 1 km in float) can land a hair inside the ellipsoid the ray
	// leaves, or, where the exit sits on a crease or a touching point, inside the neighbour. The point is therefore
	// checked with the same zeta evaluation as the guarantee, against every ellipsoid near it; while one contains it,
	// the parameter moves on along the same ray, past that ellipsoid's chord (and then to the next uncovered
	// parameter of the union), by a margin that starts at 2 ulps of the coordinates and doubles. s only grows, so
	// this cannot oscillate between two ellipsoids (stepping along surface normals did: in a crease the normal of
	// one points into the other). Past the last chord every point of the ray is outside the union in exact
	// arithmetic, and the doubling margin outgrows the rounding, so the loop ends outside; kMaxRealiseSteps bounds it.
	collectRayIntervals(origin, dir, skin);
	const btScalar scale = origin.absolute()[origin.absolute().maxAxis()] + btScalar(1e-3);
	int exit = -1;
	// With lastExit, start past the last chord along the ray (the end of the ray is then free of the union, so the
	// point cannot be in a pocket the union encloses); otherwise at the first uncovered parameter.
	btScalar start = btScalar(0);
	if (lastExit)
		for (int i = 0; i < m_intervalOwner.size(); ++i)
			if (m_intervals[2 * i + 1] > start)
			{
				start = m_intervals[2 * i + 1];
				exit = m_intervalOwner[i];
			}
	int firstExit = -1;
	btScalar s = firstUncovered(start, scale, &firstExit);
	if (firstExit >= 0)
		exit = firstExit;
	btScalar margin = SIMD_EPSILON * btScalar(2) * (scale + btFabs(s));
	btScalar z = SIMD_INFINITY;
	for (int attempt = 0; attempt < kMaxRealiseSteps; ++attempt)
	{
		out = origin + dir * s;
		int worst = -1;
		z = minZetaAll(out, &worst);
		if (z >= btScalar(1))
			break;
		btScalar next = s + margin;
		for (int i = 0; i < m_intervalOwner.size(); ++i)
			if (m_intervalOwner[i] == worst)
				next = btMax(next, m_intervals[2 * i + 1] + margin);
		int nextExit = -1;
		s = firstUncovered(next, scale, &nextExit);
		if (nextExit >= 0)
			exit = nextExit;
		else if (exit < 0)
			exit = worst;
		margin *= btScalar(2);
	}
	if (exitEllipsoid)
		*exitEllipsoid = exit;
	return z >= btScalar(1) ? s : SIMD_INFINITY;
}

bool btEllipsoidClothCollider::escapesUnion(const btVector3& p, const btVector3& preferred) const
{
	// A point outside every ellipsoid can still sit in a pocket that the union encloses (fitted bodies have them
	// under the skin, where neighbouring ellipsoids meet near the surface but not deeper in). Such a point is not
	// reachable from outside. It is certainly not in a pocket if some ray from it misses the union: try the
	// preferred direction, then the 26 directions of the 3x3x3 lattice. A ray is blocked when the far root of an
	// ellipsoid's quadratic lies ahead (s1 > 0); the quadratic is set up relative to each centre.
	const btEllipsoidWorldCache& cache = m_current;
	const int ne = cache.size();
	for (int d = -1; d < 26; ++d)
	{
		btVector3 dir = preferred;
		if (d >= 0)
		{
			const int i = d < 13 ? d : d + 1; // lattice index 0..26 without the centre (13)
			dir = btVector3(btScalar(i % 3 - 1), btScalar((i / 3) % 3 - 1), btScalar(i / 9 - 1)).normalized();
		}
		bool blocked = false;
		for (int k = 0; k < ne && !blocked; ++k)
		{
			const btEllipsoidWorldCache::Entry& e = cache[k];
			const btVector3 u0 = e.m_whiten * (p - e.m_center);
			const btVector3 w = e.m_whiten * dir;
			const btScalar a = w.length2();
			const btScalar b = u0.dot(w);
			const btScalar c = u0.length2() - btScalar(1);
			const btScalar disc = b * b - a * c;
			if (!(a > btScalar(0)) || disc < btScalar(0))
				continue;
			blocked = btSqrt(disc) - b > btScalar(0);
		}
		if (!blocked)
			return true;
	}
	return false;
}

btScalar btEllipsoidClothCollider::minZetaAll(const btVector3& p, int* which) const
{
	const btEllipsoidWorldCache& cache = m_current;
	btScalar best = SIMD_INFINITY;
	int bestIndex = -1;
	for (int k = 0; k < cache.size(); ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		if (!boxesOverlap(p, p, e.m_aabbMin, e.m_aabbMax))
			continue;
		const btScalar z = (e.m_whiten * (p - e.m_center)).length2();
		if (z < best)
		{
			best = z;
			bestIndex = k;
		}
	}
	if (which)
		*which = bestIndex;
	return best;
}

btScalar btEllipsoidClothCollider::minZetaOver(const int* candidates, int count, const btVector3& p, int* which) const
{
	// The packed {c, W} records, same arithmetic as (W (p - c)).length2().
	const btScalar* packed = &m_current.m_packed[0];
	const btScalar px = p.x(), py = p.y(), pz = p.z();
	btScalar best = SIMD_INFINITY;
	int bestIndex = -1;
	for (int j = 0; j < count; ++j)
	{
		const btScalar* pk = packed + btEllipsoidWorldCache::kPackedStride * candidates[j];
		const btScalar dx = px - pk[0], dy = py - pk[1], dz = pz - pk[2];
		const btScalar u0 = pk[4] * dx + pk[8] * dy + pk[12] * dz;
		const btScalar u1 = pk[5] * dx + pk[9] * dy + pk[13] * dz;
		const btScalar u2 = pk[6] * dx + pk[10] * dy + pk[14] * dz;
		const btScalar z = u0 * u0 + u1 * u1 + u2 * u2;
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

btScalar btEllipsoidClothCollider::nudgeOut(const int* candidates, int count, btVector3& p,
											const btVector3& fallbackDir) const
{
	int worst = -1;
	btScalar z = minZetaOver(candidates, count, p, &worst);
	btScalar step = SIMD_EPSILON * btScalar(2) * (p.absolute()[p.absolute().maxAxis()] + btScalar(1e-3));
	for (int attempt = 0; attempt < kMaxNudges && z < btScalar(1) && worst >= 0; ++attempt)
	{
		const btEllipsoidWorldCache::Entry& e = m_current[worst];
		const btVector3 g = transposeTimes(e.m_whiten, e.m_whiten * (p - e.m_center));
		const btScalar gl = g.length();
		p += (gl > SIMD_EPSILON ? g / gl : fallbackDir) * step;
		step *= btScalar(2);
		z = minZetaOver(candidates, count, p, &worst);
	}
	return z;
}

btScalar btEllipsoidClothCollider::pushOut(btSoftBody::Node& node, const btVector3& from, const btVector3& start,
										   btScalar dt)
{
	const btEllipsoidWorldCache& cache = m_current;
	const btScalar skin = btMax(m_config.m_skinOffset, btScalar(0));
	// Candidate directions, for each ellipsoid containing the point: its outward normal there (the direction to its
	// nearest surface point for shallow penetrations) and both directions of its three principal axes (the way out
	// of a thin ellipsoid near its mid-plane). The exit of the whole union is measured along each; the shortest wins.
	btVector3 dirs[kMaxPushDirections];
	int ndirs = 0;
	for (int k = 0; k < cache.size() && ndirs + 7 <= kMaxPushDirections; ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		if (!boxesOverlap(from, from, e.m_aabbMin, e.m_aabbMax))
			continue;
		const btVector3 u = e.m_whiten * (from - e.m_center);
		const btScalar z = u.length2();
		if (!(z < btScalar(1)))
			continue;
		const btVector3 g = transposeTimes(e.m_whiten, u);
		const btScalar gl = g.length();
		if (gl > SIMD_EPSILON)
			dirs[ndirs++] = g / gl;
		for (int axis = 0; axis < 3; ++axis)
		{
			btVector3 column(e.m_unwhiten[0][axis], e.m_unwhiten[1][axis], e.m_unwhiten[2][axis]);
			column.normalize();
			dirs[ndirs++] = column;
			dirs[ndirs++] = -column;
		}
	}
	if (ndirs == 0)
		return minZetaAll(from, 0); // not inside anything (caller's tolerance): nothing to do

	// Nominal exit of the union along every candidate direction, then the shortest that a btScalar point realises
	// (realiseExit; a realised exit is never shorter than the nominal one, so directions are tried in nominal order
	// until the next nominal exit is longer than the best realised one).
	btScalar nominal[kMaxPushDirections];
	for (int d = 0; d < ndirs; ++d)
		nominal[d] = unionExitAlongRay(from, dirs[d], skin, 0);
	btScalar bestS = SIMD_INFINITY;
	int bestDir = -1, bestExit = -1;
	btVector3 out = from;
	bool tried[kMaxPushDirections];
	for (int d = 0; d < ndirs; ++d)
		tried[d] = false;
	for (int round = 0; round < ndirs; ++round)
	{
		int next = -1;
		for (int d = 0; d < ndirs; ++d)
			if (!tried[d] && (next < 0 || nominal[d] < nominal[next]))
				next = d;
		if (next < 0 || !(nominal[next] < bestS))
			break;
		tried[next] = true;
		btVector3 p;
		int exit = -1;
		const btScalar s = realiseExit(from, dirs[next], skin, p, &exit);
		// An exit into a pocket enclosed by the union is not an exit: the node would rest outside every ellipsoid
		// but inside the body. Only exits from which some ray escapes the union are taken.
		if (s < bestS && escapesUnion(p, dirs[next]))
		{
			bestS = s;
			bestDir = next;
			bestExit = exit;
			out = p;
		}
	}
	if (bestDir < 0)
	{
		// Every nearest exit led into a pocket (or was not realised): leave along each ray past its last chord,
		// which no pocket can contain, and keep the shortest.
		for (int d = 0; d < ndirs; ++d)
		{
			btVector3 p;
			int exit = -1;
			const btScalar s = realiseExit(from, dirs[d], skin, p, &exit, true);
			if (s < bestS)
			{
				bestS = s;
				bestDir = d;
				bestExit = exit;
				out = p;
			}
		}
		if (bestDir >= 0)
			++m_lastStats.m_pushOutEnclosed;
	}
	btScalar z;
	btVector3 normal;
	if (bestDir >= 0)
	{
		z = minZetaAll(out, 0);
		normal = dirs[bestDir];
		if (bestExit >= 0)
		{
			const btEllipsoidWorldCache::Entry& e = cache[bestExit];
			const btVector3 g = transposeTimes(e.m_whiten, e.m_whiten * (out - e.m_center));
			const btScalar gl = g.length();
			if (gl > SIMD_EPSILON)
				normal = g / gl;
		}
	}
	else
	{
		// Safe fallback (no direction realised an exit; not seen in 1e7 random cases): leave the box of the whole
		// union along the nominally shortest direction, grown by the skin and a margin of 1e-5 of its size plus
		// 8 ulps of the coordinates. A point outside an ellipsoid's box is outside the ellipsoid (|p - c|_i >
		// extent_i implies zeta > 1 by Cauchy-Schwarz), and the margin is far above zeta's rounding error.
		int d0 = 0;
		for (int d = 1; d < ndirs; ++d)
			if (nominal[d] < nominal[d0])
				d0 = d;
		const btVector3& dir = dirs[d0];
		const btVector3 lo = cache.getAabbMin(), hi = cache.getAabbMax();
		const btScalar big = btMax(lo.absolute()[lo.absolute().maxAxis()], hi.absolute()[hi.absolute().maxAxis()]);
		const btScalar grow = skin + (hi - lo).length() * btScalar(1e-5) + SIMD_EPSILON * btScalar(8) * big;
		// Leaving one slab of the grown box leaves the box: the smallest slab exit (|dir| = 1, so its largest
		// component is >= 1/sqrt(3) and at least one slab is crossed).
		btScalar sBox = SIMD_INFINITY;
		for (int k = 0; k < 3; ++k)
		{
			if (dir[k] > btScalar(0.01))
				sBox = btMin(sBox, (hi[k] + grow - from[k]) / dir[k]);
			else if (dir[k] < btScalar(-0.01))
				sBox = btMin(sBox, (lo[k] - grow - from[k]) / dir[k]);
		}
		out = from + dir * btMax(sBox, btScalar(0));
		z = minZetaAll(out, 0);
		normal = dir;
		++m_lastStats.m_pushOutFallbacks;
	}
	const btVector3 center = bestExit >= 0 ? cache[bestExit].m_center : from;
	applyVelocityRule(node, out - normal * skin, normal, start, center, dt);
	node.m_x = out;
	return z;
}

void btEllipsoidClothCollider::collide(btSoftBody* softBody, btScalar dt, const btVector3* startPositions)
{
	btClock clock;
	const double cpu0 = threadCpuSeconds();
	ensureResponseDisabled(softBody);
	const btEllipsoidWorldCache& cache = m_current;
	const int ne = cache.size();
	btEllipsoidClothStats& stats = m_lastStats;
	if (ne == 0 || softBody->m_nodes.size() == 0)
		return;

	const btScalar skin = btMax(m_config.m_skinOffset, btScalar(0));
	const btVector3 skinBox(skin, skin, skin);
	const btVector3 unionMin = cache.getAabbMin();
	const btVector3 unionMax = cache.getAabbMax();
	const btEllipsoidWorldCache::Entry* entries = &cache.m_entries[0];
	const int kPackedStride = btEllipsoidWorldCache::kPackedStride;
	const btScalar* packed = &cache.m_packed[0];
	const btVector3* boxes = &cache.m_boxes[0];
	const int* cellStart = &cache.m_cellStart[0];
	const int* cellItems = cache.m_cellItems.size() ? &cache.m_cellItems[0] : 0;
	const int* wideStart = &cache.m_wideStart[0];
	const int* wideItems = cache.m_wideItems.size() ? &cache.m_wideItems[0] : 0;
	const int dimX = cache.m_dims[0], dimY = cache.m_dims[1], dimZ = cache.m_dims[2];
	const int dimXY = dimX * dimY;
	const btVector3 gridOrigin = cache.m_gridOrigin;
	const btScalar invCell = cache.m_invCell;
	const btVector3 skinCells = skinBox * invCell;
	m_candidates.resize(ne);
	int* candBuffer = &m_candidates[0];
	m_candidateT.resize(ne);
	btScalar* tvals = &m_candidateT[0];
	const bool moving = m_moving;
	const btTransform delta = m_delta;
	const btTransform& toLocal = cache.getInverseTransform();
	// World -> grid units in one affine map: f = (toLocal * p - gridOrigin) / cell.
	const btTransform toGrid(toLocal.getBasis().scaled(btVector3(invCell, invCell, invCell)),
							 (toLocal.getOrigin() - gridOrigin) * invCell);
	// A body without rotation (the common static case) needs no matrix product: f = (p - (o - t)) / cell, the same
	// value up to rounding, which the allowance below covers.
	const bool axisAligned = toLocal.getBasis() == btMatrix3x3::getIdentity();
	const btVector3 gridShift = gridOrigin - toLocal.getOrigin();
	// The fast path's containment test runs on body-frame coordinates, whose rounding (the world -> body transform
	// of a point near the union: a few ulps of the largest coordinate in play) is taken off the dilation; where that
	// leaves nothing (tiny ellipsoids far from the origin in float) every node takes the general path.
	btVector3 farCorner = unionMin.absolute();
	farCorner.setMax(unionMax.absolute());
	const btScalar farthest = farCorner[farCorner.maxAxis()] + toLocal.getOrigin().absolute()[toLocal.getOrigin().absolute().maxAxis()];
	const btScalar roundingCells = SIMD_EPSILON * btScalar(16) * farthest * invCell;
	const btScalar dilation = cache.m_cellDilation - roundingCells;
	const btScalar wideDilation = cache.m_wideDilation - roundingCells;

	btScalar minZeta = stats.m_minZeta;
	const int numNodes = softBody->m_nodes.size();
	btSoftBody::Node* nodes = &softBody->m_nodes[0];
	for (int i = 0; i < numNodes; ++i)
	{
		btSoftBody::Node& node = nodes[i];
		if (!(node.m_im > btScalar(0)))
			continue;
		const btVector3 x = node.m_x;
		btVector3 q = startPositions ? startPositions[i] : node.m_q;
		if (!isFinite(x, q))
		{
			++stats.m_nonFiniteNodes;
			continue;
		}
		// Start carried with the body from its previous to its current pose: the path is then straight in the
		// body frame, and all tests run against the current world cache.
		if (moving)
			q = delta * q;
		btVector3 boxMin = x, boxMax = x;
		boxMin.setMin(q);
		boxMax.setMax(q);
		boxMin -= skinBox;
		boxMax += skinBox;
		if (!boxesOverlap(boxMin, boxMax, unionMin, unionMax))
			continue;

		// Broadphase in the body frame (the grid's), in cell units f = (p - origin) / cell. The path grown by the
		// skin lies in the cube of half-size |x - q| / 2 + skin around its midpoint m (a rotation keeps lengths).
		// Fast path: that cube lies within the grown cell of m's cell (the cell plus the dilation on every side,
		// less the rounding allowance), so that cell's list holds every ellipsoid the path can meet. Next, the same with the wide lists
		// (a 3 x 3 x 3 block). Either list is then filtered by the world box test without branches (the outcome is
		// a coin toss per candidate): two thirds of the listed ellipsoids are dropped for a few compares each.
		// Otherwise (a node moving about a cell in one substep) every cell under the box, each ellipsoid once.
		int nc = 0;
		const int* cand = candBuffer;
		{
			const btVector3 mid = (x + q) * btScalar(0.5);
			const btVector3 fm = axisAligned ? (mid - gridShift) * invCell : toGrid * mid;
			const int cx = cellIndex(fm.x(), dimX), cy = cellIndex(fm.y(), dimY), cz = cellIndex(fm.z(), dimZ);
			const btVector3 frac = fm - btVector3(btScalar(cx), btScalar(cy), btScalar(cz));
			const btScalar faceGap = btMin(btMin(btMin(frac.x(), frac.y()), frac.z()),
										   btScalar(1) - btMax(btMax(frac.x(), frac.y()), frac.z()));
			// |x - q| / 2 rounded up a little (the midpoint and the length carry rounding too).
			const btScalar halfPath = btSqrt((x - q).length2()) * btScalar(0.5 + 1e-5) + skin;
			const btScalar reach = halfPath * invCell - faceGap;
			const int c = cz * dimXY + cy * dimX + cx;
			const int* list = 0;
			int listSize = -1;
			if (reach <= dilation)
			{
				list = cellItems + cellStart[c];
				listSize = cellStart[c + 1] - cellStart[c];
			}
			else if (reach <= wideDilation)
			{
				list = wideItems + wideStart[c];
				listSize = wideStart[c + 1] - wideStart[c];
			}
			if (listSize >= 0)
			{
				const btPathBox pathBox(boxMin, boxMax);
				for (int j = 0; j < listSize; ++j)
				{
					const int k = list[j];
					candBuffer[nc] = k;
					nc += pathBox.overlaps(boxes[2 * k], boxes[2 * k + 1]) ? 1 : 0;
				}
			}
			else
			{
				const btVector3 fq = toGrid * q, fx = toGrid * x;
				btVector3 fMin = fx, fMax = fx;
				fMin.setMin(fq);
				fMax.setMax(fq);
				fMin -= skinCells;
				fMax += skinCells;
				const int x0 = cellIndex(fMin.x(), dimX), x1 = cellIndex(fMax.x(), dimX);
				const int y0 = cellIndex(fMin.y(), dimY), y1 = cellIndex(fMax.y(), dimY);
				const int z0 = cellIndex(fMin.z(), dimZ), z1 = cellIndex(fMax.z(), dimZ);
				// A long path (a corner of the cloth whipping) spans many cells whose lists repeat the same few
				// ellipsoids: when they hold more entries than there are ellipsoids, every ellipsoid's box is
				// tested once instead (no duplicates to remove).
				int listed = 0;
				for (int iz = z0; iz <= z1 && listed < ne; ++iz)
					for (int iy = y0; iy <= y1; ++iy)
					{
						const int row = iz * dimXY + iy * dimX;
						listed += cellStart[row + x1 + 1] - cellStart[row + x0];
					}
				if (listed >= ne)
				{
					const btPathBox pathBox(boxMin, boxMax);
					for (int k = 0; k < ne; ++k)
					{
						candBuffer[nc] = k;
						nc += pathBox.overlaps(boxes[2 * k], boxes[2 * k + 1]) ? 1 : 0;
					}
				}
				else
				{
					for (int iz = z0; iz <= z1; ++iz)
						for (int iy = y0; iy <= y1; ++iy)
							for (int ix = x0; ix <= x1; ++ix)
							{
								const int cc = iz * dimXY + iy * dimX + ix;
								for (int j = cellStart[cc]; j < cellStart[cc + 1]; ++j)
								{
									const int k = cellItems[j];
									if (!boxesOverlap(boxMin, boxMax, boxes[2 * k], boxes[2 * k + 1]))
										continue;
									// A box spanning several cells meets an ellipsoid in each: keep the first (the
									// candidate list is a handful long, a linear scan beats a stamp array here).
									int m = 0;
									while (m < nc && candBuffer[m] != k)
										++m;
									if (m == nc)
										candBuffer[nc++] = k;
								}
							}
				}
			}
		}
		if (nc == 0)
			continue;
		++stats.m_nodesTested;

		// Narrow phase in whitened coordinates u = W (p - c): the ellipsoid is the unit ball and the path stays
		// a segment, so the entry parameter is the smaller root of |u_q + t (u_x - u_q)|^2 = 1.
		int best = -1;
		btScalar tBest = btScalar(2);
		btVector3 uBest(0, 0, 0);
		bool startInside = false;
		btScalar zMinX = SIMD_INFINITY;
		const btScalar qx = q.x(), qy = q.y(), qz = q.z(), xx = x.x(), xy = x.y(), xz = x.z();
#ifdef BT_ELLIPSOID_SSE_BOXES
		const __m128 qVec = _mm_setr_ps(qx, qy, qz, btScalar(0)), xVec = _mm_setr_ps(xx, xy, xz, btScalar(0));
#endif
		for (int j = 0; j < nc; ++j)
		{
			// Scalar arithmetic on the packed {c, W} record: no horizontal SIMD sums on this hot path.
			const btScalar* pk = packed + kPackedStride * cand[j];
#ifdef BT_ELLIPSOID_SSE_BOXES
			// Four lanes at once, each lane the same products and sums in the same order as the scalar code below.
			const __m128 centre = _mm_loadu_ps(pk);
			const __m128 col0 = _mm_loadu_ps(pk + 4), col1 = _mm_loadu_ps(pk + 8), col2 = _mm_loadu_ps(pk + 12);
			const __m128 dq = _mm_sub_ps(qVec, centre), dx = _mm_sub_ps(xVec, centre);
			const __m128 uqv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(col0, _mm_shuffle_ps(dq, dq, _MM_SHUFFLE(0, 0, 0, 0))),
													 _mm_mul_ps(col1, _mm_shuffle_ps(dq, dq, _MM_SHUFFLE(1, 1, 1, 1)))),
										  _mm_mul_ps(col2, _mm_shuffle_ps(dq, dq, _MM_SHUFFLE(2, 2, 2, 2))));
			const __m128 uxv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(col0, _mm_shuffle_ps(dx, dx, _MM_SHUFFLE(0, 0, 0, 0))),
													 _mm_mul_ps(col1, _mm_shuffle_ps(dx, dx, _MM_SHUFFLE(1, 1, 1, 1)))),
										  _mm_mul_ps(col2, _mm_shuffle_ps(dx, dx, _MM_SHUFFLE(2, 2, 2, 2))));
			float uqs[4], uxs[4];
			_mm_storeu_ps(uqs, uqv);
			_mm_storeu_ps(uxs, uxv);
			const btScalar uq0 = uqs[0], uq1 = uqs[1], uq2 = uqs[2];
			const btScalar ux0 = uxs[0], ux1 = uxs[1], ux2 = uxs[2];
#else
			const btScalar dqx = qx - pk[0], dqy = qy - pk[1], dqz = qz - pk[2];
			const btScalar dxx = xx - pk[0], dxy = xy - pk[1], dxz = xz - pk[2];
			const btScalar uq0 = pk[4] * dqx + pk[8] * dqy + pk[12] * dqz;
			const btScalar uq1 = pk[5] * dqx + pk[9] * dqy + pk[13] * dqz;
			const btScalar uq2 = pk[6] * dqx + pk[10] * dqy + pk[14] * dqz;
			const btScalar ux0 = pk[4] * dxx + pk[8] * dxy + pk[12] * dxz;
			const btScalar ux1 = pk[5] * dxx + pk[9] * dxy + pk[13] * dxz;
			const btScalar ux2 = pk[6] * dxx + pk[10] * dxy + pk[14] * dxz;
#endif
			const btScalar zx = ux0 * ux0 + ux1 * ux1 + ux2 * ux2;
			const btScalar zq = uq0 * uq0 + uq1 * uq1 + uq2 * uq2;
			zMinX = btMin(zMinX, zx);
			tvals[j] = btScalar(2);
			if (zq < btScalar(1))
			{
				startInside = true;
				continue;
			}
			const btScalar d0 = ux0 - uq0, d1 = ux1 - uq1, d2 = ux2 - uq2;
			const btScalar b = uq0 * d0 + uq1 * d1 + uq2 * d2;
			btScalar t = btScalar(2);
			if (b < btScalar(0))
			{
				const btScalar a = d0 * d0 + d1 * d1 + d2 * d2;
				const btScalar c = zq - btScalar(1);
				const btScalar disc = b * b - a * c;
				if (disc >= btScalar(0))
					t = c / (btSqrt(disc) - b); // smaller root, cancellation-free form
			}
			if (t > btScalar(1) && zx < btScalar(1))
				t = btScalar(1); // the end is inside but rounding lost the root
			tvals[j] = t;
			if (t <= btScalar(1) && t < tBest)
			{
				tBest = t;
				best = cand[j];
				uBest.setValue(uq0 + d0 * t, uq1 + d1 * t, uq2 + d2 * t);
			}
		}

		if (startInside)
		{
			// The body moved into the node (or it started inside). If the solve already brought it out, keep it.
			if (zMinX >= btScalar(1))
			{
				minZeta = btMin(minZeta, zMinX);
				continue;
			}
			++stats.m_nodesPushedOut;
			minZeta = btMin(minZeta, pushOut(node, x, q, dt));
			continue;
		}
		if (best < 0)
		{
			minZeta = btMin(minZeta, zMinX);
			continue;
		}

		// Earliest entry: the surface point (exactly on the unit sphere in whitened space), then the skin.
		++stats.m_nodesCorrected;
		const btEllipsoidWorldCache::Entry& e = entries[best];
		const btScalar ul = uBest.length();
		const btVector3 uHit = ul > btScalar(0) ? uBest / ul : btVector3(1, 0, 0);
		const btVector3 surface = e.m_center + e.m_unwhiten * uHit;
		btVector3 normal = transposeTimes(e.m_whiten, uHit);
		normal.normalize(); // |W^T u| >= 1 / max(a) > 0 for |u| = 1
		// Entries tied with the earliest one (the path meets a crease, Figure 6 case 1): the skin offset goes along
		// the sum of their normals, so the answer does not depend on the order of the ellipsoids.
		int ties = 0;
		btVector3 normalSum(0, 0, 0);
		const btScalar tieTolerance = nc > 1 ? kTieDistance / btMax((x - q).length(), kTieDistance) : btScalar(0);
		int tied = 0;
		for (int j = 0; j < nc && nc > 1; ++j)
			tied += tvals[j] <= tBest + tieTolerance ? 1 : 0;
		for (int j = 0; j < nc && tied > 1; ++j)
		{
			if (!(tvals[j] <= tBest + tieTolerance))
				continue;
			const btEllipsoidWorldCache::Entry& ej = entries[cand[j]];
			btVector3 uj = ej.m_whiten * (surface - ej.m_center);
			const btScalar ujl = uj.length();
			if (ujl > btScalar(0))
				uj /= ujl;
			normalSum += transposeTimes(ej.m_whiten, uj).normalized();
			++ties;
		}
		if (ties > 1 && normalSum.length2() > SIMD_EPSILON)
			normal = normalSum.normalized();
		const btVector3 placed = surface + normal * skin;
		applyVelocityRule(node, surface, normal, q, e.m_center, dt);
		node.m_x = placed;

		// Guarantee: the placed node must be outside every nearby ellipsoid. The entry point itself is outside the
		// others (it is the earliest entry), but in a crease the skin offset can reach into a neighbour: then the
		// offset is shortened (bisection) to the largest part that stays outside. The candidates cover the path
		// box grown by the skin, which contains every point tried here.
		btScalar zPlaced = minZetaOver(cand, nc, placed, 0);
		if (zPlaced < btScalar(1))
		{
			btVector3 fixedPoint = placed;
			btScalar zFixed = minZetaOver(cand, nc, surface, 0);
			if (zFixed >= btScalar(1))
			{
				btScalar lo = btScalar(0), hi = skin;
				fixedPoint = surface;
				for (int it = 0; it < kCreaseBisections; ++it)
				{
					const btScalar mid = btScalar(0.5) * (lo + hi);
					const btVector3 trial = surface + normal * mid;
					const btScalar zt = minZetaOver(cand, nc, trial, 0);
					if (zt >= btScalar(1))
					{
						lo = mid;
						fixedPoint = trial;
						zFixed = zt;
					}
					else
						hi = mid;
				}
			}
			else
			{
				// The surface point itself rounds to inside (skin 0, or far from the origin): step out along the
				// normal of the ellipsoid that contains it by a few ulps of the coordinates.
				fixedPoint = surface;
				zFixed = nudgeOut(cand, nc, fixedPoint, normal);
			}
			if (zFixed >= btScalar(1))
			{
				node.m_x = fixedPoint;
				zPlaced = zFixed;
			}
			else
			{
				++stats.m_nodesRepaired;
				zPlaced = pushOut(node, fixedPoint, q, dt);
			}
		}
		minZeta = btMin(minZeta, zPlaced);
	}
	stats.m_minZeta = minZeta;
	stats.m_collisionSeconds += double(clock.getTimeNanoseconds()) * 1e-9;
	stats.m_collisionCpuSeconds += threadCpuSeconds() - cpu0;
}

btFloatRangeStatus btEllipsoidClothCollider::checkPrecision(const btCollisionObject* body, const Config& config,
															const char** why)
{
	btVector3 lo, hi;
	body->getCollisionShape()->getAabb(body->getWorldTransform(), lo, hi);
	return btCheckFloatRange(lo, hi, btMax(config.m_skinOffset, kMinPrecisionResolution), why);
}

btEllipsoidClothCollider* btEllipsoidClothCollider::install(btSoftRigidDynamicsWorld* world, btCollisionObject* body,
															 const Config& config, const char** whyNot)
{
	const char* dummy = 0;
	const char** reason = whyNot ? whyNot : &dummy;
	*reason = 0;
	if (!world)
	{
		*reason = "btEllipsoidClothCollider::install: world is null";
		return 0;
	}
	if (!body || !body->getCollisionShape())
	{
		*reason = "btEllipsoidClothCollider::install: body is null or has no collision shape";
		return 0;
	}

	// Which soft-body solver does the world use? btSoftRigidDynamicsWorld keeps it private, but addSoftBody
	// hands it to every soft body: read it from an existing one, or from a temporary empty soft body.
	btSoftBodySolver* solver = 0;
	if (world->getSoftBodyArray().size() > 0)
		solver = world->getSoftBodyArray()[0]->getSoftBodySolver();
	else
	{
		btSoftBody probe(&world->getWorldInfo(), 0, 0, 0);
		world->addSoftBody(&probe);
		solver = probe.getSoftBodySolver();
		world->removeSoftBody(&probe);
	}
	btEllipsoidClothSoftBodySolver* ours = dynamic_cast<btEllipsoidClothSoftBodySolver*>(solver);
	if (!ours)
	{
		*reason = "btEllipsoidClothCollider::install: the world was not created with a btEllipsoidClothSoftBodySolver "
				  "(pass one as the 5th btSoftRigidDynamicsWorld argument, or use btEllipsoidClothWorld)";
		return 0;
	}
	for (int i = 0; i < ours->m_colliders.size(); ++i)
		if (ours->m_colliders[i]->m_body == body)
		{
			*reason = "btEllipsoidClothCollider::install: a collider is already installed for this body";
			return 0;
		}

	btCollisionShape* shape = body->getCollisionShape();
	btEllipsoidCompoundShape* compound = dynamic_cast<btEllipsoidCompoundShape*>(shape);
	btEllipsoidCompoundShape* owned = 0;
	if (!compound)
	{
		btEllipsoidShape* single = dynamic_cast<btEllipsoidShape*>(shape);
		if (!single)
		{
			*reason = "btEllipsoidClothCollider::install: the body's shape is neither a btEllipsoidCompoundShape nor "
					  "a btEllipsoidShape";
			return 0;
		}
		void* mem = btAlignedAlloc(sizeof(btEllipsoidCompoundShape), 16);
		owned = new (mem) btEllipsoidCompoundShape(single->getMargin());
		owned->addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), single->getScaledSemiAxes());
		compound = owned;
	}
	if (compound->getNumEllipsoids() == 0 || compound->getNumChildShapes() != compound->getNumEllipsoids())
	{
		if (owned)
		{
			owned->~btEllipsoidCompoundShape();
			btAlignedFree(owned);
		}
		*reason = compound->getNumEllipsoids() == 0
					  ? "btEllipsoidClothCollider::install: the compound has no ellipsoids"
					  : "btEllipsoidClothCollider::install: the compound has children that are not ellipsoids "
						"(added with addChildShape instead of addEllipsoid)";
		return 0;
	}

	// Far from the origin a float build cannot resolve the skin offset (btFloatRange.h): refuse, or warn.
	const char* precision = 0;
	const btFloatRangeStatus range = checkPrecision(body, config, &precision);
	if (range == BT_FLOAT_RANGE_REFUSE)
	{
		if (owned)
		{
			owned->~btEllipsoidCompoundShape();
			btAlignedFree(owned);
		}
		*reason = precision;
		return 0;
	}

	void* mem = btAlignedAlloc(sizeof(btEllipsoidClothCollider), 16);
	btEllipsoidClothCollider* collider = new (mem) btEllipsoidClothCollider(body, config);
	collider->m_precisionWarning = precision;
	collider->m_ownedCompound = owned;
	collider->m_compound = compound;
	ours->m_colliders.push_back(collider);
	btAlignedObjectArray<btSoftBody*>& softBodies = world->getSoftBodyArray();
	for (int i = 0; i < softBodies.size(); ++i)
		collider->ensureResponseDisabled(softBodies[i]);
	return collider;
}

bool btEllipsoidClothCollider::uninstall(btSoftRigidDynamicsWorld* world, btEllipsoidClothCollider* collider)
{
	if (!world || !collider)
		return false;
	btAlignedObjectArray<btSoftBody*>& softBodies = world->getSoftBodyArray();
	btEllipsoidClothSoftBodySolver* ours = 0;
	if (softBodies.size() > 0)
		ours = dynamic_cast<btEllipsoidClothSoftBodySolver*>(softBodies[0]->getSoftBodySolver());
	else
	{
		btSoftBody probe(&world->getWorldInfo(), 0, 0, 0);
		world->addSoftBody(&probe);
		ours = dynamic_cast<btEllipsoidClothSoftBodySolver*>(probe.getSoftBodySolver());
		world->removeSoftBody(&probe);
	}
	if (!ours)
		return false;
	const int index = ours->m_colliders.findLinearSearch(collider);
	if (index == ours->m_colliders.size())
		return false;
	ours->m_colliders.removeAtIndex(index);
	if (collider->m_config.m_disableBulletResponse)
		for (int i = 0; i < softBodies.size(); ++i)
			softBodies[i]->m_collisionDisabledObjects.remove(collider->m_body);
	collider->~btEllipsoidClothCollider();
	btAlignedFree(collider);
	return true;
}

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidClothSoftBodySolver

btEllipsoidClothSoftBodySolver::btEllipsoidClothSoftBodySolver()
{
}

btEllipsoidClothSoftBodySolver::~btEllipsoidClothSoftBodySolver()
{
	for (int i = 0; i < m_colliders.size(); ++i)
	{
		m_colliders[i]->~btEllipsoidClothCollider();
		btAlignedFree(m_colliders[i]);
	}
	m_colliders.clear();
}

void btEllipsoidClothSoftBodySolver::predictMotion(btScalar solverdt)
{
	btDefaultSoftBodySolver::predictMotion(solverdt);
	// With drift iterations (diterations > 0) btSoftBody::solveConstraints overwrites m_q mid-solve, so the start
	// of the substep is saved here (predictMotion has just set q = x_start).
	m_startPositions.resize(m_softBodySet.size());
	if (m_colliders.size() == 0)
		return;
	for (int b = 0; b < m_softBodySet.size(); ++b)
	{
		btSoftBody* psb = m_softBodySet[b];
		btAlignedObjectArray<btVector3>& starts = m_startPositions[b];
		if (psb->m_cfg.diterations <= 0)
		{
			starts.resize(0);
			continue;
		}
		starts.resize(psb->m_nodes.size());
		for (int i = 0; i < psb->m_nodes.size(); ++i)
			starts[i] = psb->m_nodes[i].m_q;
	}
}

void btEllipsoidClothSoftBodySolver::solveConstraints(btScalar solverdt)
{
	btDefaultSoftBodySolver::solveConstraints(solverdt);
	for (int c = 0; c < m_colliders.size(); ++c)
	{
		btEllipsoidClothCollider* collider = m_colliders[c];
		collider->beginSubstep(solverdt);
		for (int b = 0; b < m_softBodySet.size(); ++b)
		{
			btSoftBody* psb = m_softBodySet[b];
			const bool haveStarts = b < m_startPositions.size() &&
									m_startPositions[b].size() == psb->m_nodes.size() && psb->m_nodes.size() > 0;
			collider->collide(psb, solverdt, haveStarts ? &m_startPositions[b][0] : 0);
		}
		collider->endSubstep();
	}
}

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidClothWorld

btEllipsoidClothWorld::btEllipsoidClothWorld()
{
	m_collisionConfiguration = new btSoftBodyRigidBodyCollisionConfiguration();
	m_dispatcher = new btCollisionDispatcher(m_collisionConfiguration);
	m_broadphase = new btDbvtBroadphase();
	m_constraintSolver = new btSequentialImpulseConstraintSolver();
	m_softBodySolver = new btEllipsoidClothSoftBodySolver();
	m_world = new btSoftRigidDynamicsWorld(m_dispatcher, m_broadphase, m_constraintSolver, m_collisionConfiguration,
										   m_softBodySolver);
	m_world->getWorldInfo().m_sparsesdf.Initialize();
}

btEllipsoidClothWorld::~btEllipsoidClothWorld()
{
	delete m_world;
	delete m_softBodySolver;
	delete m_constraintSolver;
	delete m_broadphase;
	delete m_dispatcher;
	delete m_collisionConfiguration;
}
