/*
bodyfit: Bullet extension for ellipsoid body colliders.
btEllipsoidClothCollider: analytic cloth-vs-ellipsoid-compound response (Gong et al. 2018, sec. 4) applied
after Bullet's soft-body position solve, through a btDefaultSoftBodySolver subclass.
*/

#ifndef BT_ELLIPSOID_CLOTH_COLLIDER_H
#define BT_ELLIPSOID_CLOTH_COLLIDER_H

#include "bodyfit/bullet_ext/btBodyfitPrecision.h"

#include "BulletSoftBody/btDefaultSoftBodySolver.h"
#include "BulletSoftBody/btSoftBody.h"
#include "BulletSoftBody/btSoftRigidDynamicsWorld.h"
#include "LinearMath/btAlignedObjectArray.h"
#include "LinearMath/btTransformUtil.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btFloatRange.h"

class btCollisionObject;
class btEllipsoidClothSoftBodySolver;

/// Counters of the collider. Per substep they are reset; the accumulated copy sums them until resetStats().
struct btEllipsoidClothStats
{
	int m_substeps;          ///< substeps processed
	int m_nodesTested;       ///< nodes (inverse mass > 0) whose path reached at least one candidate ellipsoid
	int m_nodesCorrected;    ///< nodes whose path q -> x entered the union: placed at the earliest entry
	int m_nodesPushedOut;    ///< nodes that started the substep inside (or ended inside after correction): pushed out
	int m_nodesRepaired;     ///< nodes the final guarantee check had to move again (should stay 0)
	int m_pushOutFallbacks;  ///< push-outs that no candidate ray could realise: moved out of the union's box (stays 0)
	int m_pushOutEnclosed;   ///< push-outs whose nearest exits all led into pockets enclosed by the union: the node
							 ///< left along the ray past its last chord instead
	double m_collisionSeconds; ///< wall time spent in the collider (world-cache update + node loop)
	double m_collisionCpuSeconds; ///< the same as thread CPU time (robust on a busy machine; 0 where unsupported)
	btScalar m_minZeta;      ///< smallest zeta over processed nodes after the response (>= 1 when the guarantee holds)
	int m_nonFiniteNodes;    ///< nodes found with NaN/Inf coordinates (left untouched, not counted elsewhere)

	btEllipsoidClothStats() { reset(); }
	void reset();
	void accumulate(const btEllipsoidClothStats& other);
};

/// The cloth collider for one body whose collision shape is a btEllipsoidCompoundShape.
///
/// Per substep, after Bullet's soft-body solve (x solved, q = start of the substep, v final), for every node with
/// inverse mass > 0 of every soft body in the world:
///  1. broadphase: grid cells of the body's world cache overlapping the node's path box;
///  2. path test in the body frame: the start q is carried with the body from its previous to its current pose,
///     then for every candidate ellipsoid the segment q -> x is intersected analytically (unit-ball form);
///  3. earliest entry (smallest parameter along q -> x, i.e. nearest q) wins: the node is put there, plus the skin
///     offset along the outward normal, and its velocity relative to the body is corrected (Config);
///  4. q already inside (the body moved into the cloth, or a bad start): the node is pushed along the shortest
///     candidate direction to the exit of the union of all ellipsoids (exact interval sweep along that ray), so it
///     lands on the union surface inside no other ellipsoid; the result is deterministic (no oscillation);
///  5. guarantee: the final position is checked against every nearby ellipsoid, zeta >= 1, no NaN/Inf.
/// Bullet's own soft response to the body is turned off by adding the body to every soft body's
/// m_collisionDisabledObjects (soft bodies added later are handled too); rigid bodies keep colliding with it.
///
/// Body motion: static, kinematic (btRigidBody with CF_KINEMATIC_OBJECT: its pose is interpolated across the
/// substeps of one stepSimulation call from the velocity Bullet computes in saveKinematicState) and dynamic
/// bodies (pose read every substep). A plain btCollisionObject moved by hand jumps to its new pose in the first
/// substep after the move, and its previous pose is still used for the path test.
///
/// Supported worlds: btSoftRigidDynamicsWorld (and subclasses) built with btEllipsoidClothSoftBodySolver.
/// btDeformableMultiBodyDynamicsWorld is not supported: it uses btDeformableBodySolver, where x and q swap
/// meaning and the update happens in applyTransforms; install() takes a btSoftRigidDynamicsWorld, which it is not.
class btEllipsoidClothCollider
{
public:
	/// Velocity rule after a node is placed on the surface.
	enum VelocityRule
	{
		/// Remove the inward normal velocity (relative to the body surface) and apply Coulomb friction:
		/// the tangential relative speed drops by friction * |removed normal speed| (not below zero).
		REMOVE_NORMAL_COULOMB = 0,
		/// The paper's eq. 10: v <- v * |c P0| / (|c P0| + |P0 q|), c = ellipsoid centre, P0 = entry point.
		PAPER_EQ10 = 1
	};

	struct Config
	{
		btScalar m_skinOffset;   ///< metres the node is placed outside the surface (default 2 mm)
		btScalar m_friction;     ///< Coulomb coefficient for REMOVE_NORMAL_COULOMB (default 0.3)
		VelocityRule m_velocityRule;
		bool m_useEq10;          ///< shortcut for m_velocityRule = PAPER_EQ10 (either one selects it)
		bool m_disableBulletResponse; ///< add the body to m_collisionDisabledObjects of every soft body (default true)

		Config()
			: m_skinOffset(btScalar(0.002)),
			  m_friction(btScalar(0.3)),
			  m_velocityRule(REMOVE_NORMAL_COULOMB),
			  m_useEq10(false),
			  m_disableBulletResponse(true)
		{
		}
	};

	/// Installs the collider for `body` in `world`. The world must have been created with a
	/// btEllipsoidClothSoftBodySolver (see btEllipsoidClothWorld), and the body's collision shape must be a
	/// btEllipsoidCompoundShape (or a single btEllipsoidShape). The body need not be in the world.
	/// \return the collider, owned by the solver (removed with uninstall or when the solver is destroyed), or 0 when
	/// a precondition fails; the reason is written to *whyNot (a static one-line string) if whyNot is not 0.
	/// In a float build the body must be near enough the origin for float coordinates to resolve the skin offset
	/// (at least 1 mm): beyond BT_FLOAT_RANGE_REFUSE of btCheckFloatRange (btFloatRange.h; 8,192 m for the default
	/// 2 mm skin) install refuses with the reason; beyond BT_FLOAT_RANGE_WARN (1,024 m) it installs and
	/// getPrecisionWarning() says why the result may be degraded. The check uses the body's pose at install().
	static btEllipsoidClothCollider* install(btSoftRigidDynamicsWorld* world, btCollisionObject* body,
											 const Config& config = Config(), const char** whyNot = 0);
	/// Removes and deletes the collider; re-enables Bullet's own response for the body. \return false if not found.
	static bool uninstall(btSoftRigidDynamicsWorld* world, btEllipsoidClothCollider* collider);

	btCollisionObject* getBody() const { return m_body; }
	const Config& getConfig() const { return m_config; }
	/// A static one-line warning when install() found the body far from the origin for this build's btScalar
	/// (BT_FLOAT_RANGE_WARN of btFloatRange.h), 0 otherwise.
	const char* getPrecisionWarning() const { return m_precisionWarning; }
	/// The smallest length btCheckFloatRange is asked to resolve: the skin offset, but at least this (1 mm), so a
	/// skin offset of 0 still needs coordinates that resolve cloth motion.
	static btScalar minPrecisionResolution() { return kMinPrecisionResolution; }
	void setConfig(const Config& config) { m_config = config; }

	/// Counters of the most recent substep.
	const btEllipsoidClothStats& getLastSubstepStats() const { return m_lastStats; }
	/// Counters summed over substeps since the last resetStats() (e.g. per stepSimulation call).
	const btEllipsoidClothStats& getAccumulatedStats() const { return m_accumulatedStats; }
	void resetStats() { m_accumulatedStats.reset(); }

	/// World-space ellipsoids at the body's current pose (as used in the last substep).
	const btEllipsoidWorldCache& getWorldCache() const { return m_current; }

	/// Runs the response on one soft body for one substep of length dt (called by the solver; public for tests
	/// and for custom pipelines). \param startPositions node positions at the start of the substep, or 0 to use m_q.
	void collide(btSoftBody* softBody, btScalar dt, const btVector3* startPositions);

	/// Called by the solver once per substep before collide(): moves the body pose forward (see class notes).
	void beginSubstep(btScalar dt);
	void endSubstep();

	/// Forget the body's previous pose: call after teleporting the body, so the next substep does not treat the
	/// jump as motion that sweeps the cloth along.
	void resetBodyPose();

	~btEllipsoidClothCollider();

private:
	friend class btEllipsoidClothSoftBodySolver;
	btEllipsoidClothCollider(btCollisionObject* body, const Config& config);
	static constexpr btScalar kMinPrecisionResolution = btScalar(0.001);
	/// btCheckFloatRange of the body's world AABB against max(skin offset, kMinPrecisionResolution).
	static btFloatRangeStatus checkPrecision(const btCollisionObject* body, const Config& config, const char** why);

	btCollisionObject* m_body;
	Config m_config;
	btEllipsoidCompoundShape* m_ownedCompound; ///< wraps a bare btEllipsoidShape body shape
	const btEllipsoidCompoundShape* m_compound;
	btEllipsoidWorldCache m_current;
	btTransform m_previousPose;           ///< body pose used in the previous substep
	btTransform m_currentPose;            ///< body pose for this substep
	btTransform m_lastSeenWorldTransform; ///< kinematic bodies: world transform seen at the last step start
	btTransform m_delta;                  ///< previous pose -> current pose (world to world)
	btTransform m_deltaInverse;
	btTransform m_stepStart;              ///< kinematic interpolation: pose at the start of the current step
	btTransform m_stepTarget;             ///< kinematic interpolation: pose at its end
	bool m_havePose;
	bool m_moving;
	int m_substepIndex;
	int m_substepCount;
	btScalar m_substepDt;
	const char* m_precisionWarning; ///< see getPrecisionWarning
	btEllipsoidClothStats m_lastStats;
	btEllipsoidClothStats m_accumulatedStats;
	btAlignedObjectArray<int> m_candidates;
	btAlignedObjectArray<btScalar> m_candidateT;
	btAlignedObjectArray<btScalar> m_intervals;
	btAlignedObjectArray<int> m_intervalOwner;

	btTransform interpolatedKinematicPose();
	void ensureResponseDisabled(btSoftBody* softBody);
	btVector3 bodyVelocityAt(const btVector3& worldPoint, btScalar dt) const;
	void applyVelocityRule(btSoftBody::Node& node, const btVector3& surfacePoint, const btVector3& normal,
						   const btVector3& start, const btVector3& center, btScalar dt) const;
	void collectRayIntervals(const btVector3& origin, const btVector3& dir, btScalar skin);
	btScalar firstUncovered(btScalar from, btScalar scale, int* exitEllipsoid) const;
	btScalar unionExitAlongRay(const btVector3& origin, const btVector3& dir, btScalar skin, int* exitEllipsoid);
	btScalar realiseExit(const btVector3& origin, const btVector3& dir, btScalar skin, btVector3& out,
						 int* exitEllipsoid, bool lastExit = false);
	bool escapesUnion(const btVector3& p, const btVector3& preferred) const;
	btScalar minZetaAll(const btVector3& p, int* which) const;
	btScalar minZetaOver(const int* candidates, int count, const btVector3& p, int* which) const;
	btScalar nudgeOut(const int* candidates, int count, btVector3& p, const btVector3& fallbackDir) const;
	btScalar pushOut(btSoftBody::Node& node, const btVector3& from, const btVector3& start, btScalar dt);
};

/// btDefaultSoftBodySolver that runs every installed btEllipsoidClothCollider after the soft-body solve of each
/// substep. Pass it as the 5th argument of btSoftRigidDynamicsWorld (the world does not own it), or use
/// btEllipsoidClothWorld which builds and owns everything.
class btEllipsoidClothSoftBodySolver : public btDefaultSoftBodySolver
{
public:
	btEllipsoidClothSoftBodySolver();
	virtual ~btEllipsoidClothSoftBodySolver();

	virtual void predictMotion(btScalar solverdt);
	virtual void solveConstraints(btScalar solverdt);

	int getNumColliders() const { return m_colliders.size(); }
	btEllipsoidClothCollider* getCollider(int i) const { return m_colliders[i]; }

private:
	friend class btEllipsoidClothCollider;
	btAlignedObjectArray<btEllipsoidClothCollider*> m_colliders;
	btAlignedObjectArray<btAlignedObjectArray<btVector3> > m_startPositions; ///< per soft body, only if diterations > 0
};

/// A complete btSoftRigidDynamicsWorld with the collider's solver: collision configuration
/// (btSoftBodyRigidBodyCollisionConfiguration), dispatcher, btDbvtBroadphase, btSequentialImpulseConstraintSolver,
/// btEllipsoidClothSoftBodySolver. Owns those parts (not the bodies the user adds).
class btEllipsoidClothWorld
{
public:
	btEllipsoidClothWorld();
	~btEllipsoidClothWorld();

	btSoftRigidDynamicsWorld* getWorld() { return m_world; }
	btSoftBodyWorldInfo& getWorldInfo() { return m_world->getWorldInfo(); }
	btEllipsoidClothSoftBodySolver* getSoftBodySolver() { return m_softBodySolver; }

private:
	btEllipsoidClothWorld(const btEllipsoidClothWorld&);
	btEllipsoidClothWorld& operator=(const btEllipsoidClothWorld&);

	class btCollisionConfiguration* m_collisionConfiguration;
	class btCollisionDispatcher* m_dispatcher;
	class btBroadphaseInterface* m_broadphase;
	class btConstraintSolver* m_constraintSolver;
	btEllipsoidClothSoftBodySolver* m_softBodySolver;
	btSoftRigidDynamicsWorld* m_world;
};

#endif // BT_ELLIPSOID_CLOTH_COLLIDER_H
