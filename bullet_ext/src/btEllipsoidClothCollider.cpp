/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidClothCollider.h.
The response follows Gong et al. 2018, sec. 4: all ellipsoids hit along the node's path are found, the entry
point nearest the start position wins (which removes the paper's Figure 6 cases 1-3), the node goes there.
This file: the collider's lifecycle (install, body pose per substep, the solver that drives it) and the node loop
that runs the phases: broad phase btEllipsoidWorldCache::PathQuery (btEllipsoidCompoundShape.cpp), narrow phase
btEarliestEntry (btEllipsoidNarrowPhase.h), response (btEllipsoidClothResponse.cpp), union push-out
(btEllipsoidUnionPushOut.cpp).
*/

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btTiming.h"

#include "src/btEllipsoidClothColliderCore.h"
#include "src/btEllipsoidClothResponse.h"

#include "BulletCollision/BroadphaseCollision/btDbvtBroadphase.h"
#include "BulletCollision/CollisionDispatch/btCollisionDispatcher.h"
#include "BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h"
#include "BulletDynamics/Dynamics/btRigidBody.h"
#include "BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h"
#include "LinearMath/btQuickprof.h"
#include "LinearMath/btTransformUtil.h"

#include <new>
#include <string.h>


namespace
{

/// True if no coordinate is NaN or infinite (inf - inf and NaN - NaN are NaN).
inline bool isFinite(const btVector3& a, const btVector3& b)
{
	const btScalar s = a.x() + a.y() + a.z() + b.x() + b.y() + b.z();
	return s - s == btScalar(0);
}

btScalar largestSemiAxis(const btEllipsoidCompoundShape& compound)
{
	btScalar largest = btScalar(0);
	for (int i = 0; i < compound.getNumEllipsoids(); ++i)
	{
		const btVector3& a = compound.getEllipsoid(i).m_semiAxes;
		largest = btMax(largest, a[a.maxAxis()]);
	}
	return largest;
}

inline bool transformsEqual(const btTransform& a, const btTransform& b)
{
	const btMatrix3x3& ba = a.getBasis();
	const btMatrix3x3& bb = b.getBasis();
	return a.getOrigin() == b.getOrigin() && ba[0] == bb[0] && ba[1] == bb[1] && ba[2] == bb[2];
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
	m_nodesLifted = 0;
	m_nodesRepaired = 0;
	m_pushOutFallbacks = 0;
	m_pushOutEnclosed = 0;
	m_collisionSeconds = 0.0;
	m_collisionCpuSeconds = 0.0;
	m_minZeta = SIMD_INFINITY;
	m_nonFiniteNodes = 0;
	m_invalidPoseSubsteps = 0;
	m_minSkinField = SIMD_INFINITY;
	m_skinFallbacks = 0;
	m_skinMarchLimits = 0;
	m_boneFieldNodes = 0;
	m_boneFieldFallbacks = 0;
	m_skinMeshNodes = 0;
}

void btEllipsoidClothStats::accumulate(const btEllipsoidClothStats& other)
{
	m_substeps += other.m_substeps;
	m_nodesTested += other.m_nodesTested;
	m_nodesCorrected += other.m_nodesCorrected;
	m_nodesPushedOut += other.m_nodesPushedOut;
	m_nodesLifted += other.m_nodesLifted;
	m_nodesRepaired += other.m_nodesRepaired;
	m_pushOutFallbacks += other.m_pushOutFallbacks;
	m_pushOutEnclosed += other.m_pushOutEnclosed;
	m_collisionSeconds += other.m_collisionSeconds;
	m_collisionCpuSeconds += other.m_collisionCpuSeconds;
	m_minZeta = btMin(m_minZeta, other.m_minZeta);
	m_nonFiniteNodes += other.m_nonFiniteNodes;
	m_invalidPoseSubsteps += other.m_invalidPoseSubsteps;
	m_minSkinField = btMin(m_minSkinField, other.m_minSkinField);
	m_skinFallbacks += other.m_skinFallbacks;
	m_skinMarchLimits += other.m_skinMarchLimits;
	m_boneFieldNodes += other.m_boneFieldNodes;
	m_boneFieldFallbacks += other.m_boneFieldFallbacks;
	m_skinMeshNodes += other.m_skinMeshNodes;
}

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidClothCollider (the public face) and btEllipsoidClothColliderCore (the substep protocol)

btEllipsoidClothCollider::btEllipsoidClothCollider(btSoftRigidDynamicsWorld* world, btCollisionObject* body,
												   const Config& config)
	: m_world(world),
	  m_body(body),
	  m_config(config),
	  m_havePose(false),
	  m_detached(false),
	  m_configWarning(0),
	  m_precisionWarning(0),
	  m_bodyExtent(0)
{
	validateConfig(config, 0, &m_configWarning);
}

bool btEllipsoidClothCollider::validateConfig(const Config& config, const char** error, const char** warning,
											  btScalar bodyExtent)
{
	const char* dummyError = 0;
	const char* dummyWarning = 0;
	const char*& e = error ? *error : dummyError;
	const char*& w = warning ? *warning : dummyWarning;
	e = 0;
	w = 0;
	const btScalar skin = config.m_skinOffset, friction = config.m_friction;
	if (!(skin - skin == btScalar(0)) || !(friction - friction == btScalar(0)))
		e = "btEllipsoidClothCollider::Config: m_skinOffset and m_friction must be finite";
	else if (skin < btScalar(0))
		e = "btEllipsoidClothCollider::Config: m_skinOffset is negative (metres outside the surface, >= 0)";
	else if (skin > btMax(btScalar(1), bodyExtent))
		e = "btEllipsoidClothCollider::Config: m_skinOffset above 1 m and above the body's largest semi-axis (it is "
			"in metres: 2 mm is 0.002)";
	else if (friction < btScalar(0) && friction != kBulletFriction())
		e = "btEllipsoidClothCollider::Config: m_friction is negative (kBulletFriction(), -1, means kDF x body friction)";
	else if (config.m_velocityRule != REMOVE_NORMAL_COULOMB && config.m_velocityRule != PAPER_EQ10)
		e = "btEllipsoidClothCollider::Config: m_velocityRule is not a VelocityRule";
	else if (config.m_surface != TIGHT_SKIN && config.m_surface != ELLIPSOIDS)
		e = "btEllipsoidClothCollider::Config: m_surface is not a SurfaceMode";
	else if (!(config.m_liftClearance > btScalar(0) && config.m_liftClearance <= btScalar(1)))
		e = "btEllipsoidClothCollider::Config: m_liftClearance must be in (0, 1] (a fraction of m_skinOffset)";
	else if (skin > btScalar(0.05))
		w = "btEllipsoidClothCollider::Config: m_skinOffset above 5 cm is implausible for cloth (metres, not mm?)";
	else if (friction > btScalar(2))
		w = "btEllipsoidClothCollider::Config: m_friction above 2 is implausible for cloth";
	return e == 0;
}

bool btEllipsoidClothCollider::setConfig(const Config& config, const char** error)
{
	const char* warning = 0;
	if (!validateConfig(config, error, &warning, m_bodyExtent))
		return false;
	if (const char* tight = btSkinFieldConfigError(config, static_cast<btEllipsoidClothColliderCore*>(this)->getCompound()))
	{
		if (error)
			*error = tight;
		return false;
	}
	m_config = config;
	m_configWarning = warning;
	return true;
}

btEllipsoidClothCollider::~btEllipsoidClothCollider()
{
}

btEllipsoidClothColliderCore::btEllipsoidClothColliderCore(btSoftRigidDynamicsWorld* world, btCollisionObject* body,
														   const btEllipsoidCompoundShape* compound,
														   btEllipsoidCompoundShape* ownedCompound, const Config& config)
	: btEllipsoidClothCollider(world, body, config),
	  m_ownedCompound(ownedCompound),
	  m_bodyInWorld(false),
	  m_worldIndex(-1),
	  m_installedShape(0),
	  m_compound(compound),
	  m_moving(false),
	  m_hadPose(false),
	  m_teleported(false),
	  m_firstSight(false),
	  m_escapeRaysReady(false),
	  m_sweeping(false),
	  m_sweepOnGrid(false),
	  m_sweepMaxPath(0),
	  m_dynamicBody(0),
	  m_substepIndex(0),
	  m_substepCount(1),
	  m_substepDt(btScalar(0)),
	  m_contactFlags(0),
	  m_escapeHints(0),
	  m_skinMeshHints(0),
	  m_nodeReadings(0),
	  m_nodeRise(0),
	  m_skinLevel(0),
	  m_contactNodeBase(0),
	  m_contactRecord(0),
	  m_boneFields(false),
	  m_skinGroup(-1),
	  m_skinMesh(0),
	  m_skinMeshRevision(-1)
{
	m_previousPose.setIdentity();
	m_currentPose.setIdentity();
	m_lastSeenWorldTransform.setIdentity();
	m_delta.setIdentity();
	m_deltaInverse.setIdentity();
	m_stepStart.setIdentity();
	m_stepTarget.setIdentity();
	const btCollisionObjectArray& objects = world->getCollisionObjectArray();
	m_worldIndex = objects.findLinearSearch(body);
	m_bodyInWorld = m_worldIndex < objects.size();
	m_installedShape = body->getCollisionShape();
	m_bodyExtent = largestSemiAxis(*compound);
}

bool btEllipsoidClothColliderCore::bodyStillPresent()
{
	if (m_detached)
		return false;
	if (m_bodyInWorld)
	{
		const btCollisionObjectArray& objects = m_world->getCollisionObjectArray();
		if (m_worldIndex >= objects.size() || objects[m_worldIndex] != m_body)
			m_worldIndex = objects.findLinearSearch(m_body); // the array is compacted on removals
		if (m_worldIndex >= objects.size())
		{
			// Ownership rule (btEllipsoidClothSoftBodySolver::installCollider): uninstall before removing the body.
			btAssert(!"btEllipsoidClothCollider: the body was removed from the world while its collider was installed");
			detach();
			return false;
		}
	}
	if (m_body->getCollisionShape() != m_installedShape)
	{
		// The collider's compound is the old shape's, which the caller may have deleted: never read it again.
		btAssert(!"btEllipsoidClothCollider: the body's collision shape was replaced while its collider was installed");
		detach();
		return false;
	}
	return true;
}

void btEllipsoidClothColliderCore::detach()
{
	m_detached = true;
	restoreResponse();
}

btEllipsoidClothColliderCore::~btEllipsoidClothColliderCore()
{
	if (m_ownedCompound)
	{
		m_ownedCompound->~btEllipsoidCompoundShape();
		btAlignedFree(m_ownedCompound);
	}
}

btTransform btEllipsoidClothColliderCore::interpolatedKinematicPose()
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

void btEllipsoidClothColliderCore::beginSubstep(btScalar dt)
{
	startSubstepCounters();
	m_lastStats.m_substeps = 1;
	btClock clock;
	const double cpu0 = btThreadCpuSeconds();
	m_substepDt = dt;
	const bool continuing = m_havePose;
	advanceBodyPose(continuing);
	updateWorldCache(continuing);
	m_escapeRaysReady = m_sweeping || m_teleported;
	if (m_escapeRaysReady)
		m_pushOut.prepareEscapeRays(m_current); // the substep runs leavePocket
	btRigidBody* rigid = btRigidBody::upcast(m_body);
	m_dynamicBody = m_config.m_applyReactionToBody && rigid && !rigid->isStaticOrKinematicObject() &&
							rigid->getInvMass() > btScalar(0)
						? rigid
						: 0;
	m_lastStats.m_collisionSeconds += double(clock.getTimeNanoseconds()) * 1e-9;
	m_lastStats.m_collisionCpuSeconds += btThreadCpuSeconds() - cpu0;
}

void btEllipsoidClothColliderCore::startSubstepCounters()
{
	m_lastStats.reset();
	for (int r = 0; r < m_contactRecords.size(); ++r) // a record not touched in this substep is dropped at its end
		m_contactRecords[r].m_current = false;
}

bool btEllipsoidClothColliderCore::bodyPoseFinite() const
{
	const btTransform& t = m_body->getWorldTransform();
	const btMatrix3x3& b = t.getBasis();
	return isFinite(t.getOrigin(), b[0]) && isFinite(b[1], b[2]);
}

void btEllipsoidClothColliderCore::skipSubstep()
{
	startSubstepCounters();
	m_lastStats.m_invalidPoseSubsteps = 1;
	endSubstep();
}

void btEllipsoidClothColliderCore::advanceBodyPose(bool continuing)
{
	const btTransform& now = m_body->getWorldTransform();
	m_teleported = !continuing && m_hadPose;
	m_hadPose = true;
	if (!continuing)
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
}

void btEllipsoidClothColliderCore::updateWorldCache(bool continuing)
{
	// The cache still holds the previous substep's ellipsoids: a changed compound with the same count is motion of
	// every ellipsoid from there (after resetBodyPose or a count change it is a jump, not a sweep).
	const int n = m_compound->getNumEllipsoids();
	m_sweeping = continuing && n > 0 && m_current.getShape() == m_compound && m_current.size() == n &&
				 m_current.getRevision() != m_compound->getAnalyticRevision();
	if (m_sweeping)
		m_sweep.capture(m_current);
	m_current.update(m_compound, m_currentPose);
	if (m_sweeping)
		m_sweeping = m_sweep.prepare(m_current);
	// The static grid's lists serve the sweep when they hold every ellipsoid at both poses of the substep (kept, or
	// only the ellipsoids that left their margins relisted, each margin holding its previous pose as well).
	m_sweepOnGrid = m_sweeping && !m_moving && m_current.listsHoldPreviousPoses() &&
					m_current.getGridMargin() > btScalar(0) && !m_sweep.hasUnbounded();
	m_sweepMaxPath = m_current.getCellSize();
	if (m_sweeping && !m_sweepOnGrid)
		m_sweep.expectEveryPath();
	// A field is baked for one shape of the body: while the ellipsoids move by themselves it no longer describes the
	// skin in the body frame (a skinned body's bind-pose field is read in its bones' frames, prepareBoneFields).
	m_skinGeometry.begin(m_sweeping || m_compound->getBindPose() ? 0 : activeSkinField(),
						 btMax(m_config.m_skinOffset, btScalar(0)), m_currentPose);
	prepareBoneFields(); // a skinned body: the field of the bind pose in each bone's frame (btSkinFieldResponse.cpp)
	prepareSkinMesh();   // ... and its skin of the instant where those frames cannot decide (btSkinMeshResponse.cpp)
}

void btEllipsoidClothColliderCore::endSubstep()
{
	m_accumulatedStats.accumulate(m_lastStats);
	dropStaleContactRecords();
}

const btAlignedObjectArray<unsigned char>* btEllipsoidClothCollider::getContactFlags(const btSoftBody* softBody) const
{
	return m_detached ? 0 : static_cast<const btEllipsoidClothColliderCore*>(this)->contactFlags(softBody);
}

const btAlignedObjectArray<unsigned char>* btEllipsoidClothColliderCore::contactFlags(const btSoftBody* softBody) const
{
	for (int r = 0; r < m_contactRecords.size(); ++r)
		if (m_contactRecords[r].m_softBody == softBody)
			return &m_contactRecords[r].m_flags;
	return 0;
}

void btEllipsoidClothColliderCore::beginContactRecord(const btSoftBody* softBody)
{
	int r = 0;
	while (r < m_contactRecords.size() && m_contactRecords[r].m_softBody != softBody)
		++r;
	m_firstSight = r == m_contactRecords.size();
	if (m_firstSight)
	{
		m_contactRecords.expand();
		m_contactRecords[r].m_softBody = softBody;
	}
	ContactRecord& record = m_contactRecords[r];
	record.m_current = true;
	const int n = softBody->m_nodes.size();
	record.m_flags.resize(n);
	m_contactFlags = n > 0 ? &record.m_flags[0] : 0;
	if (n > 0)
		memset(m_contactFlags, 0, size_t(n)); // (a byte loop here was 1.3% of the collider's instructions)
	record.m_escapeHints.resize(n, (unsigned char)btEllipsoidUnionPushOut::kNoEscapeHint);
	m_escapeHints = n > 0 ? &record.m_escapeHints[0] : 0;
	record.m_skinMeshHints.resize(n, -1);
	m_skinMeshHints = n > 0 ? &record.m_skinMeshHints[0] : 0;
	record.m_rise.resize(n, btScalar(0));
	// Levels apply only with the lift on and the static field this substep (not while the ellipsoids move by
	// themselves); otherwise no rise is read, and collideNode skips candidatesAtLevel for nodes without candidates.
	m_nodeRise = n > 0 && m_config.m_liftEdges && m_skinGeometry.field() ? &record.m_rise[0] : 0;
	m_contactNodeBase = n > 0 ? &softBody->m_nodes[0] : 0;
	m_contactRecord = &record;
	beginReadings(record, n);
}

void btEllipsoidClothColliderCore::beginReadings(ContactRecord& record, int numNodes)
{
	m_nodeReadings = 0;
	const btSkinDistanceField* field = activeSkinField();
	if (!field || numNodes == 0)
		return;
	// A point no start can be (starts are finite): no reading there.
	const btVector3 none(SIMD_INFINITY, SIMD_INFINITY, SIMD_INFINITY);
	record.m_readings.resize(numNodes, none);
	if (record.m_readingsField != field->getContentId())
	{
		for (int i = 0; i < numNodes; ++i)
			record.m_readings[i] = none;
		record.m_readingsField = field->getContentId();
	}
	m_nodeReadings = &record.m_readings[0];
}

void btEllipsoidClothColliderCore::dropStaleContactRecords()
{
	for (int r = m_contactRecords.size() - 1; r >= 0; --r)
		if (!m_contactRecords[r].m_current)
		{
			m_contactRecords.swap(r, m_contactRecords.size() - 1);
			m_contactRecords.pop_back();
		}
}

void btEllipsoidClothColliderCore::ensureResponseDisabled(btSoftBody* softBody)
{
	if (!m_config.m_disableBulletResponse)
		return;
	btAlignedObjectArray<const btCollisionObject*>& disabled = softBody->m_collisionDisabledObjects;
	if (disabled.findLinearSearch(m_body) == disabled.size())
		disabled.push_back(m_body);
}

void btEllipsoidClothColliderCore::restoreResponse()
{
	if (!m_config.m_disableBulletResponse)
		return;
	btAlignedObjectArray<btSoftBody*>& softBodies = m_world->getSoftBodyArray();
	for (int i = 0; i < softBodies.size(); ++i)
		softBodies[i]->m_collisionDisabledObjects.remove(m_body);
}

btVector3 btEllipsoidClothColliderCore::bodyVelocityAt(const btVector3& worldPoint, int ellipsoid, btScalar dt) const
{
	if (m_sweeping && ellipsoid >= 0)
		return sweptVelocityAt(worldPoint, ellipsoid, dt);
	if (!m_moving || !(dt > btScalar(0)))
		return btVector3(0, 0, 0);
	return (worldPoint - m_deltaInverse * worldPoint) / dt;
}

btVector3 btEllipsoidClothColliderCore::sweptVelocityAt(const btVector3& worldPoint, int ellipsoid, btScalar dt) const
{
	// p0 = c0 + U0 W1 (p - c1) is where the point was at the start of the substep (the rigid motion of the body is
	// part of each ellipsoid's motion).
	if (!(dt > btScalar(0)))
		return btVector3(0, 0, 0);
	return (worldPoint - m_sweep.previousPoint(m_current, ellipsoid, worldPoint)) / dt;
}

void btEllipsoidClothColliderCore::collide(btSoftBody* softBody, btScalar dt, const btVector3* startPositions)
{
	btClock clock;
	const double cpu0 = btThreadCpuSeconds();
	ensureResponseDisabled(softBody);
	beginContactRecord(softBody);
	const int ne = m_current.size();
	btEllipsoidClothStats& stats = m_lastStats;
	if (ne == 0 || softBody->m_nodes.size() == 0)
	{
		m_contactFlags = 0;
		m_escapeHints = 0;
		m_skinMeshHints = 0;
		m_nodeRise = 0;
		m_nodeReadings = 0;
		m_contactRecord = 0;
		return;
	}
	Substep substep(m_current, btMax(m_config.m_skinOffset, btScalar(0)), dt, m_sweepOnGrid ? &m_sweep : 0,
					m_sweepMaxPath);
	// Bullet's own soft-rigid contact uses kDF x the body's friction (btSoftBody's rigid contacts); Config overrides.
	substep.m_friction = m_config.m_friction >= btScalar(0) ? m_config.m_friction
															: softBody->m_cfg.kDF * m_body->getFriction();
	m_candidates.resize(ne);
	substep.m_candidates = &m_candidates[0];
	m_candidateT.resize(ne);
	substep.m_tvals = &m_candidateT[0];
	m_contactCandidates.resize(ne);
	substep.m_contactCandidates = &m_contactCandidates[0];
	if (m_sweeping)
		collideSweptNodes(softBody, startPositions, substep);
	else
	{
		// The rigid path, here rather than in a function of its own: with the Substep a local of this loop the
		// compiler keeps the query's fields in registers (3.5% fewer instructions in the node loop).
		const bool moving = m_moving;
		const btTransform delta = m_delta;
		// A node outside every ellipsoid is not yet outside the body: the union holds the skin, not the whole interior.
		// After a jump of the body, and the first time a soft body is collided (a garment placed through the body, a
		// cloth added mid-run), nodes may start in a void the union encloses; the skin field decides that itself.
		const bool pockets = (m_teleported || m_firstSight) && !m_skinGeometry.field();
		if (pockets && !m_escapeRaysReady)
		{
			m_pushOut.prepareEscapeRays(m_current);
			m_escapeRaysReady = true;
		}
		btScalar minZeta = stats.m_minZeta;
		const int numNodes = softBody->m_nodes.size();
		btSoftBody::Node* nodes = &softBody->m_nodes[0];
		for (int i = 0; i < numNodes; ++i)
		{
			btSoftBody::Node& node = nodes[i];
			if (!(node.m_im > btScalar(0)))
				continue;
			btVector3 q = startPositions ? startPositions[i] : node.m_q;
			if (!isFinite(node.m_x, q))
			{
				++stats.m_nonFiniteNodes;
				continue;
			}
			// Start carried with the body from its previous to its current pose: the path is then straight in the
			// body frame, and all tests run against the current world cache.
			if (moving)
				q = delta * q;
			btScalar zeta;
			if (collideNode(node, q, substep, zeta))
				minZeta = btMin(minZeta, zeta);
			if (pockets)
				leavePocket(node, substep, minZeta);
		}
		stats.m_minZeta = minZeta;
		if (m_skinGeometry.field() && m_config.m_liftEdges)
			liftEdgesOffSkin(softBody);
	}
	m_contactFlags = 0;
	m_escapeHints = 0;
	m_skinMeshHints = 0;
	m_nodeRise = 0;
	m_nodeReadings = 0;
	m_contactRecord = 0;
	stats.m_collisionSeconds += double(clock.getTimeNanoseconds()) * 1e-9;
	stats.m_collisionCpuSeconds += btThreadCpuSeconds() - cpu0;
}

int btEllipsoidClothColliderCore::candidatesAtLevel(const btVector3& q, const btVector3& x, btScalar rise,
													const Substep& substep)
{
	return btEllipsoidWorldCache::PathQuery(m_current, substep.m_skin + rise).candidates(q, x, substep.m_candidates);
}

void btEllipsoidClothColliderCore::collideSweptNodes(btSoftBody* softBody, const btVector3* startPositions,
													 const Substep& substep)
{
	btEllipsoidClothStats& stats = m_lastStats;
	btScalar minZeta = stats.m_minZeta;
	const int numNodes = softBody->m_nodes.size();
	btSoftBody::Node* nodes = &softBody->m_nodes[0];
	for (int i = 0; i < numNodes; ++i)
	{
		btSoftBody::Node& node = nodes[i];
		if (!(node.m_im > btScalar(0)))
			continue;
		const btVector3 q = startPositions ? startPositions[i] : node.m_q;
		if (!isFinite(node.m_x, q))
		{
			++stats.m_nonFiniteNodes;
			continue;
		}
		// Every ellipsoid moved by itself: the start is carried per candidate (collideSweptNode), not by the body.
		btScalar zeta;
		if (!collideSweptNode(node, q, substep, zeta))
			continue;
		minZeta = btMin(minZeta, zeta);
		// Outside every ellipsoid is not outside the body: the union holds the skin, not the whole interior. A void
		// of the union that closes around a node (an armpit, a thigh meeting the other) is open in every moving
		// frame, and a node placed ahead of a fast limb can land in one behind it; as after a jump, a node in an
		// enclosed void leaves it (tests/bullet_ext/test_collider_moving.cpp "[pocket]").
		leavePocket(node, substep, minZeta);
	}
	stats.m_minZeta = minZeta;
}

BT_ELLIPSOID_ALWAYS_INLINE bool btEllipsoidClothColliderCore::collideNode(btSoftBody::Node& node, const btVector3& q, const Substep& substep,
											   btScalar& zeta)
{
	const btVector3 x = node.m_x;
	// 1. Broad phase: the ellipsoids the path grown by the skin can meet.
	int nc = substep.m_query.candidates(q, x, substep.m_candidates);
	if (nc == 0)
	{
		const btScalar* rise = raisedLevel(node);
		if (!rise || (nc = candidatesAtLevel(q, x, *rise, substep)) == 0)
			return false;
	}
	++m_lastStats.m_nodesTested;
	if (m_skinGeometry.field())
		return collideOnSkin(node, q, substep, zeta); // tight mode: the contact is decided on the skin field
	// 2. Narrow phase: the earliest entry along q -> x.
	btPathEntry entry;
	btEarliestEntry(m_current.getPackedRecords(), substep.m_candidates, nc, btPathEnds(q, x), substep.m_tvals, entry);
	if (entry.m_startInside)
	{
		// The body moved into the node (or it started inside).
		zeta = respondStartInside(node, entry, q, substep);
		return true;
	}
	if (entry.m_ellipsoid < 0)
	{
		zeta = entry.m_minZetaEnd;
		return true;
	}
	// 3. Response.
	++m_lastStats.m_nodesCorrected;
	zeta = respondAtEntry(node, entry, q, nc, substep);
	return true;
}

bool btEllipsoidClothColliderCore::collideSweptNode(btSoftBody::Node& node, const btVector3& q, const Substep& substep,
													btScalar& zeta)
{
	const btVector3 x = node.m_x;
	// 1. Broad phase over the swept boxes, grown by the bound of btEllipsoidSweep.cpp: the static grid's lists when
	// they hold every pose of the substep (m_sweepOnGrid) and the path is short, else the swept grid.
	const int nc = m_sweepOnGrid && (x - q).length2() <= m_sweepMaxPath * m_sweepMaxPath
					   ? substep.m_sweptQuery.candidates(q, x, substep.m_candidates)
					   : m_sweep.candidates(q, x, substep.m_skin, substep.m_candidates);
	if (nc == 0)
		return false;
	++m_lastStats.m_nodesTested;
	if (m_boneFields && collideOnBoneField(node, q, nc, substep))
		return false; // decided on the bind field in the candidates' bone frame: no pocket test (it rests in the union)
	if (m_skinMesh && collideOnSkinMesh(node, q, nc, substep))
		return false; // decided on the skin of the instant: no pocket test either
	// 2. Narrow phase in each candidate's moving frame: u_q = W0 (q - c0) -> u_x = W1 (x - c1).
	btPathEntry entry;
	const btPathEnds ends(q, x);
	const btSweptPathWhitening whiten = {m_sweep.previousRecords(), m_current.getPackedRecords(), ends};
	btEarliestEntryWith(whiten, substep.m_candidates, nc, substep.m_tvals, entry);
	if (entry.m_startInside)
	{
		// q was inside an ellipsoid's previous pose (a bad start): as the static path, from q carried by that
		// ellipsoid's motion.
		zeta = respondStartInside(node, entry, m_sweep.carry(m_current, firstContaining(q, substep.m_candidates, nc), q),
								  substep);
		return true;
	}
	zeta = entry.m_minZetaEnd; // the candidates hold every current ellipsoid near x (swept box >= current box)
	if (entry.m_ellipsoid < 0)
		return true;
	++m_lastStats.m_nodesCorrected;
	// 3. Response from the start carried by the ellipsoid that met the node first (earliest in time: s is the same
	// in every moving frame). When the carried path q_j -> x, grown by the skin, lies in the box the candidates were
	// listed for, they hold every current ellipsoid the placement can meet; else the phases run again from q_j.
	const btVector3 start = m_sweep.carry(m_current, entry.m_ellipsoid, q);
	if (carriedPathCovered(q, x, start, substep.m_skin))
		zeta = respondAtEntry(node, entry, start, nc, substep);
	else
		zeta = respondToSweep(node, entry, q, substep);
	return true;
}

btScalar btEllipsoidClothColliderCore::respondStartInside(btSoftBody::Node& node, const btPathEntry& entry,
														  const btVector3& start, const Substep& substep)
{
	// If the solve already brought the node out, keep it; else 4. the union push-out.
	if (entry.m_minZetaEnd >= btScalar(1))
		return entry.m_minZetaEnd;
	++m_lastStats.m_nodesPushedOut;
	const btVector3 x = node.m_x;
	bool moved;
	return pushNodeOut(node, x, start, substep, moved);
}

int btEllipsoidClothColliderCore::firstContaining(const btVector3& q, const int* cand, int nc) const
{
	const btScalar* previous = m_sweep.previousRecords();
	for (int j = 0; j < nc; ++j)
	{
		btScalar u[3];
		btWhitenPacked(previous + btEllipsoidWorldCache::kPackedStride * cand[j], q.x(), q.y(), q.z(), u);
		if (u[0] * u[0] + u[1] * u[1] + u[2] * u[2] < btScalar(1))
			return cand[j];
	}
	return cand[0]; // (the SSE path test rounded differently: any candidate's motion will do)
}

bool btEllipsoidClothColliderCore::carriedPathCovered(const btVector3& q, const btVector3& x, const btVector3& start,
													  btScalar skin) const
{
	const btScalar slack = m_sweep.growth(q, x, skin) - skin;
	for (int k = 0; k < 3; ++k)
	{
		const btScalar lo = btMin(q[k], x[k]) - slack, hi = btMax(q[k], x[k]) + slack;
		if (!(start[k] >= lo && start[k] <= hi))
			return false;
	}
	return true;
}

btScalar btEllipsoidClothColliderCore::respondToSweep(btSoftBody::Node& node, const btPathEntry& swept,
													  const btVector3& q, const Substep& substep)
{
	// From the start carried by the sweeping ellipsoid the path q_j -> x is straight against its current pose and
	// enters it at the same parameter; the static phases then place the node against every current ellipsoid.
	const int j = swept.m_ellipsoid;
	const btVector3 start = m_sweep.carry(m_current, j, q);
	const btVector3 x = node.m_x;
	const int nc = substep.m_query.candidates(start, x, substep.m_candidates);
	btPathEntry entry;
	btEarliestEntry(m_current.getPackedRecords(), substep.m_candidates, nc, btPathEnds(start, x), substep.m_tvals, entry);
	if (!entry.m_startInside && entry.m_ellipsoid >= 0)
		return respondAtEntry(node, entry, start, nc, substep);
	if (!entry.m_startInside && entry.m_minZetaEnd >= btScalar(1))
		return entry.m_minZetaEnd; // the carried path only grazes j (rounding): x is outside
	// The carried start lies inside another ellipsoid (two parts moving differently), or rounding lost the entry:
	// out of the union from the sweeping ellipsoid's surface point, ahead of it (x may be behind it).
	const btEllipsoidWorldCache::Entry& e = m_current[j];
	const btScalar ul = swept.m_u.length();
	const btVector3 uHit = ul > btScalar(0) ? swept.m_u / ul : btVector3(1, 0, 0);
	const btVector3 surface = e.m_center + e.m_unwhiten * uHit;
	++m_lastStats.m_nodesPushedOut;
	bool moved;
	const btScalar zeta = pushNodeOut(node, surface, start, substep, moved);
	if (!moved)
		respondVelocity(node, btWhitenedNormal(e.m_whiten, uHit).normalized(), surface, start, e.m_center, j, substep,
						btScalar(0));
	return zeta;
}

void btEllipsoidClothColliderCore::leavePocket(btSoftBody::Node& node, const Substep& substep, btScalar& minZeta)
{
	const btVector3 lo = m_current.getAabbMin(), hi = m_current.getAabbMax();
	const btVector3& x = node.m_x;
	if (x.x() < lo.x() || x.y() < lo.y() || x.z() < lo.z() || x.x() > hi.x() || x.y() > hi.y() || x.z() > hi.z())
		return;
	unsigned char* hint = m_escapeHints ? &m_escapeHints[&node - m_contactNodeBase] : 0;
	if (hint && m_pushOut.escapesAlongHint(m_current, x, *hint))
		return; // (the common case: the ray that left last time leaves again)
	btPushOutResult out;
	m_pushOut.leavePocketPastHint(m_current, x, substep.m_skin, out, hint);
	if (!out.m_moved)
		return;
	++m_lastStats.m_nodesPushedOut;
	++m_lastStats.m_pushOutEnclosed;
	const btVector3 start = node.m_x;
	node.m_x = out.m_point;
	respondVelocity(node, out.m_normal, out.m_point - out.m_normal * substep.m_skin, start, out.m_center,
					out.m_ellipsoid, substep, btScalar(0));
	minZeta = btMin(minZeta, out.m_zeta);
}

btScalar btEllipsoidClothColliderCore::respondAtEntry(btSoftBody::Node& node, const btPathEntry& entry,
													  const btVector3& q, int nc, const Substep& substep)
{
	// A node that starts within the skin goes back to its own clearance, not out to the full skin: pushed out by
	// the skin every time its cloth's tension drew it onto the surface, resting cloth never came to rest.
	const btScalar clearance = btClearance(m_current[entry.m_ellipsoid], q);
	const btScalar skin = btMin(substep.m_skin, clearance);
	btEntryPlacement placed;
	btPlaceAtEntry(m_current, entry, substep.m_candidates, substep.m_tvals, nc, q, node.m_x, skin, placed);
	btVector3 point;
	btScalar zeta;
	if (!btKeepOutsideCandidates(m_current, substep.m_candidates, nc, placed, skin, point, zeta))
	{
		++m_lastStats.m_nodesRepaired;
		bool moved;
		zeta = pushNodeOut(node, point, q, substep, moved);
		if (!moved)
			respondVelocity(node, placed.m_normal, placed.m_surface, q, placed.m_center, entry.m_ellipsoid, substep,
							btScalar(0));
		return zeta;
	}
	node.m_x = point;
	// After a sweep the start is carried by the sweeping ellipsoid and may lie far ahead of its surface: a node
	// held there would float ahead of it, so only a start within the contact band (a resting node) holds it.
	if (respondVelocity(node, placed.m_normal, placed.m_surface, q, placed.m_center, entry.m_ellipsoid, substep,
						btScalar(1) - entry.m_t) &&
		(!m_sweeping || clearance <= substep.m_band))
	{
		// Held by static friction (or moving straight in): the node stays where it started the substep, outside
		// every candidate (the path test found q outside). The entry point lies down the path, and a node placed
		// there every substep crept downhill under any friction.
		const btScalar zetaStart = btMinZetaPacked(m_current.getPackedRecords(), substep.m_candidates, nc, q, 0);
		// (A start carried by one of several moving ellipsoids may lie inside another: then it is not held.)
		if (zetaStart >= btScalar(1))
		{
			node.m_x = q;
			zeta = zetaStart;
		}
	}
	return zeta;
}

btScalar btEllipsoidClothColliderCore::pushNodeOut(btSoftBody::Node& node, const btVector3& from,
												   const btVector3& start, const Substep& substep, bool& moved)
{
	btPushOutResult out;
	m_pushOut.pushOut(m_current, from, substep.m_skin, out);
	moved = out.m_moved;
	if (!out.m_moved)
	{
		node.m_x = from;
		return out.m_zeta;
	}
	m_lastStats.m_pushOutEnclosed += out.m_enclosed ? 1 : 0;
	m_lastStats.m_pushOutFallbacks += out.m_fallback ? 1 : 0;
	node.m_x = out.m_point;
	respondVelocity(node, out.m_normal, out.m_point - out.m_normal * substep.m_skin, start, out.m_center,
					out.m_ellipsoid, substep, btScalar(0));
	return out.m_zeta;
}

bool btEllipsoidClothColliderCore::respondVelocity(btSoftBody::Node& node, const btVector3& normal,
												   const btVector3& surface, const btVector3& start,
												   const btVector3& center, int ellipsoid, const Substep& substep,
												   btScalar remaining)
{
	// Every surface the node now touches, so no velocity into a second ellipsoid of a crease survives.
	btNodeContacts contacts;
	contacts.add(normal);
	const int nt = substep.m_contactQuery.candidates(node.m_x, node.m_x, substep.m_contactCandidates);
	btAddTouchingNormals(m_current, substep.m_contactCandidates, nt, node.m_x, substep.m_band, contacts);
	const btVector3 bodyVelocity = bodyVelocityAt(surface, ellipsoid, substep.m_dt);
	const btVector3 before = node.m_v;
	const btVector3 relative = node.m_v - bodyVelocity;
	btVector3 vr = btRelativeVelocityAfterContact(m_config.m_velocityRule, substep.m_friction, relative, contacts,
												  surface, start, center);
	const bool stopped = relative.length2() > btScalar(0) && vr.length2() == btScalar(0);
	if (remaining > btScalar(0) && !stopped)
		slideAlong(node, vr * (remaining * substep.m_dt), nt, substep);
	setContactVelocity(node, vr, normal, start, bodyVelocity, before, surface, substep.m_dt);
	return stopped;
}

void btEllipsoidClothColliderCore::setContactVelocity(btSoftBody::Node& node, btVector3 vr, const btVector3& normal,
													  const btVector3& start, const btVector3& bodyVelocity,
													  const btVector3& before, const btVector3& surface, btScalar dt)
{
	if (dt > btScalar(0))
		vr = btCapBySurfaceMotion(vr, normal, (node.m_x - start) / dt);
	node.m_v = bodyVelocity + vr;
	if (m_contactFlags)
		m_contactFlags[&node - m_contactNodeBase] = 1; // every contact response ends here (getContactFlags)
	if (m_dynamicBody)
	{
		// Two-way coupling: the body takes the opposite of the node's momentum change, at the contact.
		m_dynamicBody->applyImpulse((before - node.m_v) / node.m_im, surface - m_dynamicBody->getCenterOfMassPosition());
		m_dynamicBody->activate();
	}
}

void btEllipsoidClothColliderCore::slideAlong(btSoftBody::Node& node, const btVector3& displacement,
											  int touching, const Substep& substep)
{
	// The node met the surface after part of the substep; for the rest it moves with its new velocity, which has no
	// component into the surfaces it touches. Taken only if that short path enters no ellipsoid (else the node
	// stays at the entry, blocked, e.g. in a crease).
	const btVector3 from = node.m_x;
	const btVector3 to = from + displacement;
	const int nc = slideCovered(displacement, substep)
					   ? touching
					   : substep.m_query.candidates(from, to, substep.m_contactCandidates);
	btPathEntry entry;
	btEarliestEntry(m_current.getPackedRecords(), substep.m_contactCandidates, nc, btPathEnds(from, to), substep.m_tvals,
					entry);
	if (!entry.m_startInside && entry.m_ellipsoid < 0 && entry.m_minZetaEnd >= btScalar(1))
		node.m_x = to;
}

bool btEllipsoidClothColliderCore::slideCovered(const btVector3& displacement, const Substep& substep)
{
	// The contact list of the node's position holds every ellipsoid whose box meets the point grown by the band;
	// the slide's query would keep those whose box meets the path grown by the skin. When every component of the
	// path is shorter than band - skin (less a rounding allowance), that grown path lies in the grown point, so the
	// contact list is a superset: the extra ellipsoids' boxes miss the path, so they change neither its entry nor
	// the end's clearance, and the outcome is the same.
	const btScalar reach = (substep.m_band - substep.m_skin) * btScalar(0.99);
	return btFabs(displacement.x()) <= reach && btFabs(displacement.y()) <= reach && btFabs(displacement.z()) <= reach;
}

// ---------------------------------------------------------------------------------------------------------------
// btEllipsoidClothSoftBodySolver

btEllipsoidClothSoftBodySolver::btEllipsoidClothSoftBodySolver()
{
}

btEllipsoidClothSoftBodySolver::~btEllipsoidClothSoftBodySolver()
{
	for (int i = 0; i < m_colliders.size(); ++i)
		delete m_colliders[i];
	m_colliders.clear();
}

btEllipsoidClothCollider* btEllipsoidClothSoftBodySolver::getCollider(int i) const
{
	return m_colliders[i];
}

namespace
{

/// True for a plain btCompoundShape with at least one child, every child a btEllipsoidShape.
bool isCompoundOfEllipsoids(const btCollisionShape* shape)
{
	const btCompoundShape* compound = dynamic_cast<const btCompoundShape*>(shape);
	if (!compound || compound->getNumChildShapes() == 0)
		return false;
	for (int i = 0; i < compound->getNumChildShapes(); ++i)
		if (!dynamic_cast<const btEllipsoidShape*>(compound->getChildShape(i)))
			return false;
	return true;
}

/// The body's shape as an ellipsoid compound: the shape itself, or a new compound wrapping a bare btEllipsoidShape
/// (returned in *owned too, for the collider to delete). 0 with *reason set when the shape is neither or unusable.
btEllipsoidCompoundShape* ellipsoidCompoundOf(btCollisionShape* shape, btEllipsoidCompoundShape** owned,
											  const char** reason)
{
	*owned = 0;
	btEllipsoidCompoundShape* compound = dynamic_cast<btEllipsoidCompoundShape*>(shape);
	if (!compound)
	{
		btEllipsoidShape* single = dynamic_cast<btEllipsoidShape*>(shape);
		if (!single)
		{
			*reason = isCompoundOfEllipsoids(shape)
						  ? "btEllipsoidClothSoftBodySolver::installCollider: the body's shape is a plain btCompoundShape "
							"of btEllipsoidShape children; build a btEllipsoidCompoundShape with addEllipsoid instead"
						  : "btEllipsoidClothSoftBodySolver::installCollider: the body's shape is neither a "
							"btEllipsoidCompoundShape nor a btEllipsoidShape";
			return 0;
		}
		void* mem = btAlignedAlloc(sizeof(btEllipsoidCompoundShape), 16);
		*owned = new (mem) btEllipsoidCompoundShape(single->getMargin());
		(*owned)->addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), single->getScaledSemiAxes());
		return *owned;
	}
	if (compound->getNumChildShapes() != compound->getNumEllipsoids())
	{
		*reason = "btEllipsoidClothSoftBodySolver::installCollider: the btEllipsoidCompoundShape has children added "
				  "with addChildShape, which the collider does not see; add ellipsoids with addEllipsoid";
		return 0;
	}
	if (compound->getNumEllipsoids() == 0)
	{
		*reason = "btEllipsoidClothSoftBodySolver::installCollider: the compound has no ellipsoids (add them with "
				  "addEllipsoid)";
		return 0;
	}
	return compound;
}

/// btCheckFloatRange of the body's world AABB against max(skin offset, minPrecisionResolution()).
btFloatRangeStatus checkPrecision(const btCollisionObject* body, const btEllipsoidClothCollider::Config& config,
								  const char** why)
{
	btVector3 lo, hi;
	body->getCollisionShape()->getAabb(body->getWorldTransform(), lo, hi);
	return btCheckFloatRange(lo, hi, btMax(config.m_skinOffset, btEllipsoidClothCollider::minPrecisionResolution()),
							 why);
}

} // namespace

btEllipsoidClothCollider* btEllipsoidClothSoftBodySolver::installCollider(btDynamicsWorld* dynamicsWorld,
																		  btCollisionObject* body,
																		  const btEllipsoidClothCollider::Config& config,
																		  const char** whyNot)
{
	const char* dummy = 0;
	const char** reason = whyNot ? whyNot : &dummy;
	*reason = 0;
	if (!dynamicsWorld)
	{
		*reason = "btEllipsoidClothSoftBodySolver::installCollider: world is null";
		return 0;
	}
	// The virtual world type, not the static type of the pointer: Bullet's examples C-cast worlds, and a
	// btDeformableMultiBodyDynamicsWorld cast to btSoftRigidDynamicsWorld* is not one.
	if (dynamicsWorld->getWorldType() != BT_SOFT_RIGID_DYNAMICS_WORLD)
	{
		*reason = dynamicsWorld->getWorldType() == BT_DEFORMABLE_MULTIBODY_DYNAMICS_WORLD
					  ? "btEllipsoidClothSoftBodySolver::installCollider: btDeformableMultiBodyDynamicsWorld is not "
						"supported (its btDeformableBodySolver has no post-solve hook); use btSoftRigidDynamicsWorld"
					  : "btEllipsoidClothSoftBodySolver::installCollider: the world is not a btSoftRigidDynamicsWorld";
		return 0;
	}
	btSoftRigidDynamicsWorld* world = static_cast<btSoftRigidDynamicsWorld*>(dynamicsWorld);
	if (!body || !body->getCollisionShape())
	{
		*reason = "btEllipsoidClothSoftBodySolver::installCollider: body is null or has no collision shape";
		return 0;
	}
	// btSoftRigidDynamicsWorld keeps its solver private; addSoftBody hands it to every soft body, so a world that
	// already has soft bodies shows it there.
	const btAlignedObjectArray<btSoftBody*>& softBodies = world->getSoftBodyArray();
	if (softBodies.size() > 0 && softBodies[0]->getSoftBodySolver() != this)
	{
		*reason = "btEllipsoidClothSoftBodySolver::installCollider: the world was not created with this solver "
				  "(pass it as the 5th btSoftRigidDynamicsWorld argument, or use btEllipsoidClothWorld)";
		return 0;
	}
	for (int i = 0; i < m_colliders.size(); ++i)
		if (!m_colliders[i]->isDetached() && m_colliders[i]->getBody() == body)
		{
			*reason = "btEllipsoidClothSoftBodySolver::installCollider: a collider is already installed for this body";
			return 0;
		}
	// Far from the origin a float build cannot resolve the skin offset (btFloatRange.h): refuse, or warn.
	const char* precision = 0;
	if (config.m_skinOffset == config.m_skinOffset && checkPrecision(body, config, &precision) == BT_FLOAT_RANGE_REFUSE)
	{
		*reason = precision;
		return 0;
	}
	btEllipsoidCompoundShape* owned = 0;
	const btEllipsoidCompoundShape* compound = ellipsoidCompoundOf(body->getCollisionShape(), &owned, reason);
	if (!compound)
		return 0;
	if (!btEllipsoidClothCollider::validateConfig(config, reason, 0, largestSemiAxis(*compound)) ||
		(*reason = btSkinFieldConfigError(config, compound)) != 0)
	{
		if (owned)
		{
			owned->~btEllipsoidCompoundShape();
			btAlignedFree(owned);
		}
		return 0;
	}
	btEllipsoidClothColliderCore* collider = new btEllipsoidClothColliderCore(world, body, compound, owned, config);
	collider->setPrecisionWarning(precision);
	m_colliders.push_back(collider);
	for (int i = 0; i < softBodies.size(); ++i)
		collider->ensureResponseDisabled(softBodies[i]);
	return collider;
}

bool btEllipsoidClothSoftBodySolver::uninstallCollider(btEllipsoidClothCollider* collider)
{
	int index = 0;
	while (index < m_colliders.size() && m_colliders[index] != collider)
		++index;
	if (!collider || index == m_colliders.size())
		return false;
	btEllipsoidClothColliderCore* core = m_colliders[index];
	m_colliders.removeAtIndex(index);
	core->restoreResponse();
	delete core;
	return true;
}

void btEllipsoidClothSoftBodySolver::predictMotion(btScalar solverdt)
{
	btDefaultSoftBodySolver::predictMotion(solverdt);
	// Before this substep's collision detection (which follows predictMotion): a soft body added since the last
	// substep gets no Bullet response to an installed body even in its first step.
	for (int c = 0; c < m_colliders.size(); ++c)
		if (m_colliders[c]->bodyStillPresent())
			for (int b = 0; b < m_softBodySet.size(); ++b)
				m_colliders[c]->ensureResponseDisabled(m_softBodySet[b]);
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
		btEllipsoidClothColliderCore* collider = m_colliders[c];
		if (!collider->bodyStillPresent())
			continue;
		if (!collider->bodyPoseFinite())
		{
			collider->skipSubstep();
			continue;
		}
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
