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

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btFloatRange.h"

class btCollisionObject;

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
	int m_invalidPoseSubsteps; ///< substeps skipped because the body's world transform held a NaN or infinity (an
							   ///< animation gone wrong): the collider keeps the last finite pose and moves on from it
							   ///< once the pose is finite again, pushing out the nodes that fell in meanwhile
	// Tight mode (Config::m_surface TIGHT_SKIN with a skin field): m_nodesCorrected counts nodes whose path met the
	// skin, m_nodesPushedOut nodes that started within it; zeta is not tracked (nodes rest inside the union).
	btScalar m_minSkinField; ///< smallest field value over nodes the field decided, after the response (>= skin
							 ///< offset - the field tolerance when the guarantee holds); SIMD_INFINITY if none
	int m_skinFallbacks;     ///< push-outs the field could not do (vanishing gradient, deep in the clamp, no
							 ///< convergence): the union push-out moved the node instead
	int m_skinMarchLimits;   ///< path marches that reached their step limit: the node stopped at the last point
							 ///< known outside (conservative)
	int m_nodesLifted;       ///< nodes lifted so their edges clear the skin (Config::m_liftEdges)
	// Tight mode on a skinned body (the compound has a bind pose and bone frames), substeps whose ellipsoids moved:
	int m_boneFieldNodes;     ///< tested nodes decided on the bind-pose field in the frame of their candidates' bone
	int m_boneFieldFallbacks; ///< tested nodes the union response decided instead (a joint: a candidate refitted or
							  ///< of a bone moving differently, near in the current or the bind pose); where:
							  ///< btEllipsoidClothCollider::getBoneFieldFallbacks
	int m_skinMeshNodes;      ///< of those, the nodes decided on the skinned mesh of the instant (the compound's
							  ///< btSkinMesh); the union decided the others

	btEllipsoidClothStats() { reset(); }
	void reset();
	void accumulate(const btEllipsoidClothStats& other);
};

/// The cloth collider for one body whose collision shape is a btEllipsoidCompoundShape.
///
/// Per substep, after Bullet's soft-body solve (x solved, q = start of the substep, v final), for every node with
/// inverse mass > 0 of every soft body in the world, in four phases (bullet_ext/README.md says where each lives):
///  1. broad phase: btEllipsoidWorldCache::PathQuery lists the ellipsoids the node's path q -> x, grown by the skin,
///     can meet (the start q is first carried with the body from its previous to its current pose);
///  2. narrow phase: the path is intersected with every candidate analytically, in each ellipsoid's whitened
///     coordinates where it is the unit ball; the earliest entry (nearest q) wins;
///  3. response: the node goes to that entry point plus the skin offset along the outward normal (shortened in a
///     crease so it stays outside the neighbours), and its velocity relative to the body follows Config's rule;
///  4. union push-out: a node whose q is already inside (the body moved into the cloth, or a bad start) is pushed
///     along the shortest candidate direction to the exit of the union of all ellipsoids (exact interval sweep
///     along that ray) that is connected to the outside; the result is deterministic (no oscillation).
/// Guarantee: every processed node ends with zeta >= 1 for every ellipsoid (the smallest value is in the stats);
/// NaN/Inf nodes are counted and left alone.
/// Bullet's own soft response to the body is turned off by adding the body to every soft body's
/// m_collisionDisabledObjects (soft bodies added later are handled too); rigid bodies keep colliding with it.
///
/// Body motion: static, kinematic (btRigidBody with CF_KINEMATIC_OBJECT: its pose is interpolated across the
/// substeps of one stepSimulation call from the velocity Bullet computes in saveKinematicState) and dynamic
/// bodies (pose read every substep). A plain btCollisionObject moved by hand jumps to its new pose in the first
/// substep after the move, and its previous pose is still used for the path test.
/// Moving ellipsoids (a skinned body posed every substep through btEllipsoidCompoundShape::setEllipsoids or
/// setEllipsoid, e.g. from an internal pre-tick callback): when the compound's analytic revision changed since the
/// previous substep and its ellipsoid count did not, every ellipsoid j is taken to move from its previous world
/// geometry (c0, U0 = R0 diag(a0)) to its current one (c1, U1), the body's rigid motion included. The path test of
/// candidate j runs in j's moving frame (u_q = W0 (q - c0) to u_x = W1 (x - c1) against the unit ball), so a node
/// an ellipsoid sweeps over is pushed out ahead of it; the body-surface velocity at a contact on j is (p - p0) / dt,
/// p0 = c0 + U0 W1 (p - c1). The broad phase grows each path by a bound on how far the moving-frame path strays from
/// q -> x (bullet_ext/README.md, "Moving ellipsoids"); push-out and the guarantee use the current ellipsoids.
/// resetBodyPose() and a count change forget the previous geometry (the next substep is a jump, not a sweep).
///
/// Installed and driven by btEllipsoidClothSoftBodySolver (installCollider); the substep protocol is internal.
/// Supported worlds: btSoftRigidDynamicsWorld (and subclasses) built with btEllipsoidClothSoftBodySolver.
/// btDeformableMultiBodyDynamicsWorld is not supported: it uses btDeformableBodySolver, where x and q swap
/// meaning and the update happens in applyTransforms.
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

	/// The surface the collider keeps the cloth off (bullet_ext/README.md, "Tight skin surface").
	enum SurfaceMode
	{
		/// The skin: the union of ellipsoids is only the broad phase, contact is decided on the body's skin distance
		/// field (btEllipsoidCompoundShape::setSkinField). A compound without a field uses ELLIPSOIDS.
		TIGHT_SKIN = 0,
		/// The union of ellipsoids (Gong et al. 2018), whether or not the compound has a field.
		ELLIPSOIDS = 1
	};

	/// The Config::m_friction value that means "as Bullet combines it" (kDF x body friction).
	static btScalar kBulletFriction() { return btScalar(-1); }

	struct Config
	{
		btScalar m_skinOffset;   ///< metres the node is placed outside the surface (default 2 mm)
		/// Coulomb coefficient for REMOVE_NORMAL_COULOMB. The default, kBulletFriction (-1), combines the cloth's and
		/// the body's settings as Bullet does for its own soft-rigid contacts: soft body m_cfg.kDF times the body's
		/// getFriction() (per soft body, read every substep); any value >= 0 overrides them.
		btScalar m_friction;
		VelocityRule m_velocityRule; ///< default REMOVE_NORMAL_COULOMB
		bool m_disableBulletResponse; ///< add the body to m_collisionDisabledObjects of every soft body (default true)
		/// A dynamic btRigidBody (inverse mass > 0, not kinematic) receives the reaction of every velocity change
		/// the collider gives a node: -m_node (v_after - v_before) at the node (default true; static and kinematic
		/// bodies are never affected).
		bool m_applyReactionToBody;
		/// TIGHT_SKIN (default; takes effect when the compound has a skin field) or ELLIPSOIDS.
		SurfaceMode m_surface;
		/// TIGHT_SKIN on a body that moves rigidly or not at all: after the node responses of a substep, every cloth
		/// edge (a link that is not a bending link) at a node in contact whose midpoint lies within m_liftClearance x
		/// the skin offset of the skin raises the level its nodes rest at (split by inverse mass, at most 3 skin
		/// offsets above the offset), and the next substep's contact response keeps them there, so cloth faces do not
		/// cut into the skin between nodes. Nodes then rest where their edges clear the skin: on skin curved under an
		/// edge, higher than the offset (by the edge's sag, about L^2 / 8R for an edge of length L on skin of radius
		/// R, less the offset minus the clearance). Default true; false keeps nodes at the offset, and edges longer
		/// than about sqrt(8 R offset) then sag into the skin between them.
		bool m_liftEdges;
		/// With m_liftEdges: how far lifted edges clear the skin, as a fraction of m_skinOffset, in (0, 1]. Lower
		/// lets cloth rest closer (smaller contact gap) and lets more edges graze the skin where the field is not
		/// exact (README, "Edges off the skin": 0.25 against the default 0.5 on the bundled scenes). Default 0.5.
		btScalar m_liftClearance;

		Config()
			: m_skinOffset(btScalar(0.002)),
			  m_friction(kBulletFriction()),
			  m_velocityRule(REMOVE_NORMAL_COULOMB),
			  m_disableBulletResponse(true),
			  m_applyReactionToBody(true),
			  m_surface(TIGHT_SKIN),
			  m_liftEdges(true),
			  m_liftClearance(btScalar(0.5))
		{
		}
	};

	/// Checks a Config: a non-finite value, a negative skin offset or friction, a skin offset above both 1 m and the
	/// body's largest semi-axis `bodyExtent` (metres taken for millimetres) or an unknown velocity rule
	/// is an error (returns false, *error gets a one-line reason); an implausible but usable value (skin offset above
	/// 5 cm, friction above 2) returns true with *warning set. error / warning may be 0; on success *error is 0, and
	/// *warning is 0 when nothing is implausible.
	static bool validateConfig(const Config& config, const char** error, const char** warning,
							   btScalar bodyExtent = btScalar(0));

	/// The body, or 0 once the collider has detached from it (see isDetached()).
	btCollisionObject* getBody() const { return m_detached ? 0 : m_body; }
	btSoftRigidDynamicsWorld* getWorld() const { return m_world; }
	const Config& getConfig() const { return m_config; }
	/// A static one-line warning when installCollider found the body far from the origin for this build's btScalar
	/// (BT_FLOAT_RANGE_WARN of btFloatRange.h), 0 otherwise.
	const char* getPrecisionWarning() const { return m_precisionWarning; }
	/// The smallest length btCheckFloatRange is asked to resolve: the skin offset, but at least this (1 mm), so a
	/// skin offset of 0 still needs coordinates that resolve cloth motion.
	static btScalar minPrecisionResolution() { return btScalar(0.001); }
	/// Replaces the Config if validateConfig accepts it; otherwise keeps the old one and returns false with the
	/// reason in *error (if error is not 0).
	bool setConfig(const Config& config, const char** error = 0);
	/// The warning of validateConfig for the current Config (0 if none).
	const char* getConfigWarning() const { return m_configWarning; }

	/// The skin field the collider decides contact on: the compound's (btEllipsoidCompoundShape::getSkinField) when
	/// Config::m_surface is TIGHT_SKIN, else 0 (the ellipsoid response; also once detached). Read again every substep.
	const btSkinDistanceField* getActiveSkinField() const;
	/// How far below the skin offset a node decided by `field` may end (the guarantee's tolerance): the field's seam,
	/// four quanta and the rounding of btScalar coordinates over the grid.
	static btScalar skinFieldTolerance(const btSkinDistanceField& field);
	/// Skinned bodies in tight mode: per ellipsoid, the nodes it sent to the union response since installation (the
	/// first candidate that was refitted or of another bone group, see btEllipsoidClothStats::m_boneFieldFallbacks);
	/// empty until the first such substep.
	const btAlignedObjectArray<int>& getBoneFieldFallbacks() const;

	/// True once the body was found removed from the world it was in at install, or given another collision shape
	/// than the one it had at install: the collider then stops colliding, gives the soft bodies back Bullet's own
	/// response to the body, and never reads the body (removed: it may be deleted) or the old shape (replaced: it may
	/// be deleted) again; uninstallCollider still removes the collider. To change a body's shape, uninstall, set the
	/// shape and install again.
	bool isDetached() const { return m_detached; }

	/// Counters of the most recent substep.
	const btEllipsoidClothStats& getLastSubstepStats() const { return m_lastStats; }
	/// Counters summed over substeps since the last resetStats() (e.g. per stepSimulation call).
	const btEllipsoidClothStats& getAccumulatedStats() const { return m_accumulatedStats; }
	void resetStats() { m_accumulatedStats.reset(); }

	/// The collider's contacts with `softBody` in the last substep it processed it, one flag per node (like
	/// btSoftBody::m_rcontacts for Bullet's own contacts): non-zero for every node a response of that substep placed
	/// on the surface, held there by friction or pushed out (ellipsoid or skin-field surface alike), 0 for the nodes
	/// it left alone. Cleared at the start of every substep. 0 when the collider has not processed that soft body in
	/// its last substep (not stepped by this collider's solver, added since, removed) or is detached.
	const btAlignedObjectArray<unsigned char>* getContactFlags(const btSoftBody* softBody) const;

	/// World-space ellipsoids at the body's current pose (as used in the last substep).
	const btEllipsoidWorldCache& getWorldCache() const { return m_current; }

	/// Forget the body's previous pose and its ellipsoids' previous geometry: call after teleporting the body or
	/// jumping its pose, so the next substep does not treat the jump as motion that sweeps the cloth along.
	void resetBodyPose() { m_havePose = false; }

	virtual ~btEllipsoidClothCollider();

protected:
	btEllipsoidClothCollider(btSoftRigidDynamicsWorld* world, btCollisionObject* body, const Config& config);

	btSoftRigidDynamicsWorld* m_world;
	btCollisionObject* m_body;
	Config m_config;
	btEllipsoidWorldCache m_current;
	btEllipsoidClothStats m_lastStats;
	btEllipsoidClothStats m_accumulatedStats;
	bool m_havePose; ///< false: the next substep takes the body's pose as it is (no motion)
	bool m_detached; ///< the body left the world or changed its shape (see isDetached())
	const char* m_configWarning;
	const char* m_precisionWarning; ///< see getPrecisionWarning
	btScalar m_bodyExtent; ///< largest semi-axis of the body's ellipsoids (for validateConfig)

private:
	btEllipsoidClothCollider(const btEllipsoidClothCollider&);
	btEllipsoidClothCollider& operator=(const btEllipsoidClothCollider&);
};

class btEllipsoidClothColliderCore;

/// btDefaultSoftBodySolver that runs every installed btEllipsoidClothCollider after the soft-body solve of each
/// substep. Pass it as the 5th argument of btSoftRigidDynamicsWorld (the world does not own it), then install the
/// colliders through it; or use btEllipsoidClothWorld, which builds and owns everything.
class btEllipsoidClothSoftBodySolver : public btDefaultSoftBodySolver
{
public:
	btEllipsoidClothSoftBodySolver();
	virtual ~btEllipsoidClothSoftBodySolver();

	/// Installs the collider for `body` in `world`, which must be a btSoftRigidDynamicsWorld (getWorldType()
	/// BT_SOFT_RIGID_DYNAMICS_WORLD; any other world, btDeformableMultiBodyDynamicsWorld included, is refused) built
	/// with this solver (Bullet 3.24's btSoftRigidDynamicsWorld does not tell its solver; when the world already has
	/// soft bodies, their solver is checked). The body's collision shape must be a btEllipsoidCompoundShape (or a
	/// single btEllipsoidShape); the Config must pass validateConfig (its warning is in getConfigWarning()). The body
	/// need not be in the world. The collider acts on every soft body this solver steps.
	/// Ownership: the solver owns the collider; the caller owns the body, which must outlive the collider. Removing
	/// the body from the world it was in at install detaches the collider (it stops colliding and never reads the
	/// body again, so the body may then be deleted); debug builds assert on it, since the intended order is
	/// uninstallCollider first. A body that was never in the world cannot be watched: uninstall before deleting it.
	/// \return the collider, owned by this solver (removed with uninstallCollider or when the solver is destroyed),
	/// or 0 when a precondition fails; the reason is written to *whyNot (a static one-line string) if whyNot is not 0.
	btEllipsoidClothCollider* installCollider(btDynamicsWorld* world, btCollisionObject* body,
											  const btEllipsoidClothCollider::Config& config = btEllipsoidClothCollider::Config(),
											  const char** whyNot = 0);
	/// Removes and deletes the collider; re-enables Bullet's own response for the body. \return false if not found.
	bool uninstallCollider(btEllipsoidClothCollider* collider);

	int getNumColliders() const { return m_colliders.size(); }
	btEllipsoidClothCollider* getCollider(int i) const;

	virtual void predictMotion(btScalar solverdt);
	virtual void solveConstraints(btScalar solverdt);

private:
	btAlignedObjectArray<btEllipsoidClothColliderCore*> m_colliders;
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

	/// btEllipsoidClothSoftBodySolver::installCollider for this world.
	btEllipsoidClothCollider* installCollider(btCollisionObject* body,
											  const btEllipsoidClothCollider::Config& config = btEllipsoidClothCollider::Config(),
											  const char** whyNot = 0)
	{
		return m_softBodySolver->installCollider(m_world, body, config, whyNot);
	}

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
