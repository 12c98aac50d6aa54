/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
btEllipsoidClothColliderCore: the collider with its substep protocol, driven by btEllipsoidClothSoftBodySolver
(beginSubstep, collide for every soft body of the world, endSubstep). Every installed collider is one of these; the
public header shows only btEllipsoidClothCollider. Tests that craft node paths by hand drive it through this header.
*/

#ifndef BT_ELLIPSOID_CLOTH_COLLIDER_CORE_H
#define BT_ELLIPSOID_CLOTH_COLLIDER_CORE_H

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include "src/btEllipsoidNarrowPhase.h"
#include "src/btEllipsoidUnionPushOut.h"

class btEllipsoidClothColliderCore : public btEllipsoidClothCollider
{
public:
	BT_DECLARE_ALIGNED_ALLOCATOR();

	/// \param ownedCompound a compound made for a bare btEllipsoidShape body (deleted with the collider), or 0
	btEllipsoidClothColliderCore(btSoftRigidDynamicsWorld *world, btCollisionObject *body,
								 const btEllipsoidCompoundShape *compound, btEllipsoidCompoundShape *ownedCompound,
								 const Config &config);
	virtual ~btEllipsoidClothColliderCore();

	/// Once per substep before collide(): moves the body pose forward (see the class notes of the public header)
	/// and updates the world cache.
	void beginSubstep(btScalar dt);
	/// Runs the four phases on every movable node of one soft body for one substep of length dt.
	/// \param startPositions node positions at the start of the substep, or 0 to use m_q.
	void collide(btSoftBody *softBody, btScalar dt, const btVector3 *startPositions);
	/// Adds the substep's counters to the accumulated ones.
	void endSubstep();

	/// Adds the body to the soft body's m_collisionDisabledObjects (if Config says so).
	void ensureResponseDisabled(btSoftBody *softBody);
	/// Removes the body from every soft body's m_collisionDisabledObjects of the world (uninstall).
	void restoreResponse();
	/// Set by the solver at installation (getPrecisionWarning).
	void setPrecisionWarning(const char* warning) { m_precisionWarning = warning; }

private:
	/// Everything one collide() call shares between its nodes.
	struct Substep
	{
		btEllipsoidWorldCache::PathQuery m_query;
		btScalar m_skin;
		btScalar m_dt;
		int *m_candidates;
		btScalar *m_tvals;
		Substep(const btEllipsoidWorldCache &cache, btScalar skin, btScalar dt)
			: m_query(cache, skin), m_skin(skin), m_dt(dt), m_candidates(0), m_tvals(0)
		{
		}
	};

	btEllipsoidCompoundShape *m_ownedCompound;
	const btEllipsoidCompoundShape *m_compound;
	btTransform m_previousPose;			  ///< body pose used in the previous substep
	btTransform m_currentPose;			  ///< body pose for this substep
	btTransform m_lastSeenWorldTransform; ///< kinematic bodies: world transform seen at the last step start
	btTransform m_delta;				  ///< previous pose -> current pose (world to world)
	btTransform m_deltaInverse;
	btTransform m_stepStart;  ///< kinematic interpolation: pose at the start of the current step
	btTransform m_stepTarget; ///< kinematic interpolation: pose at its end
	bool m_moving;
	int m_substepIndex;
	int m_substepCount;
	btScalar m_substepDt;
	btAlignedObjectArray<int> m_candidates;
	btAlignedObjectArray<btScalar> m_candidateT;
	btEllipsoidUnionPushOut m_pushOut;

	btTransform interpolatedKinematicPose();
	btVector3 bodyVelocityAt(const btVector3 &worldPoint, btScalar dt) const;
	bool collideNode(btSoftBody::Node &node, const btVector3 &q, const Substep &substep, btScalar &zeta);
	btScalar respondAtEntry(btSoftBody::Node &node, const btPathEntry &entry, const btVector3 &q, int nc,
							const Substep &substep);
	btScalar pushNodeOut(btSoftBody::Node &node, const btVector3 &from, const btVector3 &start, btScalar skin,
						 btScalar dt);
};

#endif // BT_ELLIPSOID_CLOTH_COLLIDER_CORE_H
