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
#include "src/btEllipsoidSweep.h"
#include "src/btSkinFieldResponse.h"
#include "src/btEllipsoidUnionPushOut.h"

class btRigidBody;

class btEllipsoidClothColliderCore : public btEllipsoidClothCollider
{
public:
	BT_DECLARE_ALIGNED_ALLOCATOR();

	/// \param ownedCompound a compound made for a bare btEllipsoidShape body (deleted with the collider), or 0
	btEllipsoidClothColliderCore(btSoftRigidDynamicsWorld* world, btCollisionObject* body,
								 const btEllipsoidCompoundShape* compound, btEllipsoidCompoundShape* ownedCompound,
								 const Config& config);
	virtual ~btEllipsoidClothColliderCore();

	/// Once per substep before collide(): moves the body pose forward (see the class notes of the public header)
	/// and updates the world cache.
	void beginSubstep(btScalar dt);
	/// Runs the four phases on every movable node of one soft body for one substep of length dt.
	/// \param startPositions node positions at the start of the substep, or 0 to use m_q.
	void collide(btSoftBody* softBody, btScalar dt, const btVector3* startPositions);
	/// Adds the substep's counters to the accumulated ones.
	void endSubstep();
	/// False while the body's world transform holds a NaN or an infinity: the solver then calls skipSubstep() instead
	/// of the three above, so the last finite pose stays the one the next substep moves from (a NaN pose kept as the
	/// previous pose made the first substep after it write NaN into every node it swept).
	bool bodyPoseFinite() const;
	/// A substep without collision, counted in m_invalidPoseSubsteps.
	void skipSubstep();
	/// The start of every substep, run or skipped: the last substep's counters cleared, no contact record current.
	void startSubstepCounters();

	/// False once the body has left the world it was in at install, or its collision shape is no longer the one it
	/// had at install (then the collider is detached: isDetached()). Compares pointers only: a body deleted after its
	/// removal, and a shape deleted after the body was given another, are never read.
	bool bodyStillPresent();

	/// Adds the body to the soft body's m_collisionDisabledObjects (if Config says so).
	void ensureResponseDisabled(btSoftBody* softBody);
	/// Removes the body from every soft body's m_collisionDisabledObjects of the world (uninstall).
	void restoreResponse();
	/// Stops colliding for good (isDetached()) and gives the soft bodies back Bullet's own response to the body.
	void detach();
	/// Set by the solver at installation (getPrecisionWarning).
	void setPrecisionWarning(const char* warning) { m_precisionWarning = warning; }

	/// A placed node touches an ellipsoid whose surface is this close (metres): the skin plus half of it (placement
	/// in a crease and the first-order distance estimate stay within that) plus 0.5 mm.
	static btScalar contactBand(btScalar skin) { return btScalar(1.5) * skin + btScalar(0.0005); }

	const btEllipsoidCompoundShape* getCompound() const { return m_compound; }
	/// getContactFlags: the record of `softBody` from the last substep, or 0.
	const btAlignedObjectArray<unsigned char>* contactFlags(const btSoftBody* softBody) const;
	/// The skin field of tight mode for the current Config (getActiveSkinField), or 0. btSkinFieldResponse.cpp.
	const btSkinDistanceField* activeSkinField() const;
	/// getBoneFieldFallbacks: per ellipsoid, nodes it sent to the union response (skinned bodies, tight mode).
	const btAlignedObjectArray<int>& boneFieldFallbacks() const { return m_boneFallbacks; }

private:
	/// Everything one collide() call shares between its nodes.
	struct Substep
	{
		btEllipsoidWorldCache::PathQuery m_query;
		btEllipsoidWorldCache::PathQuery m_contactQuery; ///< the ellipsoids within the contact band of a point
		/// A sweep on the static grid (m_sweepOnGrid): its lists filtered by the swept boxes, every path grown by the
		/// deviation bound of the longest path it takes (m_sweepMaxPath); otherwise unused.
		btEllipsoidWorldCache::PathQuery m_sweptQuery;
		btScalar m_skin;
		btScalar m_band;     ///< contactBand(m_skin)
		btScalar m_friction; ///< Coulomb coefficient for this soft body (Config's, or kDF x body friction)
		btScalar m_dt;
		int* m_candidates;
		btScalar* m_tvals;
		int* m_contactCandidates;
		Substep(const btEllipsoidWorldCache& cache, btScalar skin, btScalar dt, const btEllipsoidSweep* sweepOnGrid,
				btScalar maxPath)
			: m_query(cache, skin),
			  m_contactQuery(cache, contactBand(skin)),
			  m_sweptQuery(sweepOnGrid ? btEllipsoidWorldCache::PathQuery(cache, skin + sweepOnGrid->growthUpTo(maxPath),
																		   sweepOnGrid->sweptBoxes(),
																		   sweepOnGrid->unionMin(),
																		   sweepOnGrid->unionMax())
									   : btEllipsoidWorldCache::PathQuery(cache, skin)),
			  m_skin(skin),
			  m_band(contactBand(skin)),
			  m_friction(0),
			  m_dt(dt),
			  m_candidates(0),
			  m_tvals(0),
			  m_contactCandidates(0)
		{
		}
	};

	/// One soft body's contact flags (getContactFlags), its nodes' escape hints (kept across substeps: the ray of the
	/// escape test that left the union last time, btEllipsoidUnionPushOut::leaveEnclosedPocket) and whether the
	/// current substep processed it.
	/// A cloth edge as the edge lift sees it (ContactRecord::m_edges).
	struct LiftEdge
	{
		/// Where the edge's midpoint was (world frame, the body still since) when liftEdgesOffSkin last read the field
		/// there, and that reading's margin above the edges' clearance (the midpoint may move that over the field's
		/// Lipschitz bound before the reading no longer proves it clear; <= 0: no reading to reuse).
		btVector3 m_mid;
		btScalar m_slack;
		btScalar m_rest; ///< the link's rest length
		int m_a, m_b;    ///< its nodes
	};
	struct ContactRecord
	{
		const btSoftBody* m_softBody;
		bool m_current;
		btAlignedObjectArray<unsigned char> m_flags;
		btAlignedObjectArray<unsigned char> m_escapeHints;
		btAlignedObjectArray<int> m_skinMeshHints; ///< per node: its closest skin-mesh triangle last time, or -1
		/// per node: how far above the skin offset its edges ask it to rest (metres, >= 0; Config::m_liftEdges)
		btAlignedObjectArray<btScalar> m_rise;
		/// Tight mode, per node: where the skin field was last read at the node's final position (body or bind frame,
		/// the frame the field is in) and the reading in w: the next substep starts there, and when its start maps to
		/// exactly that point the reading is reused (btSkinDistanceField::getContentId of m_readingsField).
		btAlignedObjectArray<btVector3> m_readings;
		unsigned m_readingsField;
		/// The cloth's edges for liftEdgesOffSkin (links that are not bending links), in one array so that the lift
		/// reads an edge's state in one place (it never touches the links): listed again when the soft body's link or
		/// node array changes size or place, or its rest length scale changes. Link order does not matter
		/// (btSoftBody::randomizeConstraints shuffles the links in place: the same edges).
		btAlignedObjectArray<LiftEdge> m_edges;
		btAlignedObjectArray<int> m_nodeEdgeStart; ///< per node, where its edges start in m_nodeEdges (one more entry)
		btAlignedObjectArray<int> m_nodeEdges;     ///< the edges at each node, node after node
		const void* m_edgeLinkData;
		const void* m_edgeNodeData;
		int m_edgeLinkCount;
		int m_edgeNodeCount;
		btScalar m_edgeRestScale; ///< the soft body's rest length scale when the rest lengths were copied
		int m_edgeRevision;       ///< the compound's analytic revision the edges' readings were taken at
		btScalar m_edgeClearance; ///< and the clearance they were measured against
		ContactRecord()
			: m_softBody(0), m_current(false), m_readingsField(0), m_edgeLinkData(0), m_edgeNodeData(0), m_edgeLinkCount(-1),
			  m_edgeNodeCount(-1), m_edgeRestScale(0), m_edgeRevision(-1), m_edgeClearance(0)
		{
		}
		/// Lists the soft body's edges again if its links or nodes changed (size, place, rest lengths); true if it did.
		bool listEdges(btSoftBody& softBody);
		/// Orders m_edges by their lower node index (listEdges).
		void sortEdgesByNode(int numNodes);
	};

	btEllipsoidCompoundShape* m_ownedCompound;
	bool m_bodyInWorld;  ///< the body was in the world's collision object array at install
	int m_worldIndex;    ///< where it was last seen there
	const btCollisionShape* m_installedShape; ///< the body's collision shape at install (compared, never read)
	const btEllipsoidCompoundShape* m_compound;
	btTransform m_previousPose;           ///< body pose used in the previous substep
	btTransform m_currentPose;            ///< body pose for this substep
	btTransform m_lastSeenWorldTransform; ///< kinematic bodies: world transform seen at the last step start
	btTransform m_delta;                  ///< previous pose -> current pose (world to world)
	btTransform m_deltaInverse;
	btTransform m_stepStart;              ///< kinematic interpolation: pose at the start of the current step
	btTransform m_stepTarget;             ///< kinematic interpolation: pose at its end
	bool m_moving;
	bool m_hadPose;    ///< some substep has run (a later resetBodyPose() is a teleport)
	bool m_teleported; ///< this substep follows resetBodyPose(): nodes left in pockets of the union are moved out
	bool m_firstSight; ///< collide() meets this soft body for the first time: its nodes may start in a pocket too
	bool m_escapeRaysReady; ///< prepareEscapeRays ran for this substep's cache
	bool m_sweeping;   ///< the ellipsoids moved by themselves since the previous substep: per-ellipsoid motion
	btEllipsoidSweep m_sweep; ///< their motion over this substep (valid while m_sweeping)
	/// The sweep may use the static grid's lists: the body did not move rigidly and the grid, built with a margin, was
	/// not rebuilt this substep, so it held every ellipsoid at its previous and current pose (within its margin, or
	/// box-tested), hence (the drift from the build pose is convex along the interpolation) at every pose in between.
	bool m_sweepOnGrid;
	btScalar m_sweepMaxPath; ///< paths up to this long (a grid cell) take the static grid; longer ones the swept grid
	btRigidBody* m_dynamicBody; ///< the body when it takes the reaction impulses this substep (else 0)
	int m_substepIndex;
	int m_substepCount;
	btScalar m_substepDt;
	btAlignedObjectArray<int> m_candidates;
	btAlignedObjectArray<btScalar> m_candidateT;
	btAlignedObjectArray<int> m_contactCandidates;
	btEllipsoidUnionPushOut m_pushOut;
	btSkinFieldGeometry m_skinGeometry; ///< tight mode this substep (its field is 0 in ELLIPSOIDS mode)
	btAlignedObjectArray<ContactRecord> m_contactRecords; ///< per soft body processed in the last substep
	unsigned char* m_contactFlags;             ///< the flags collide() fills (0 outside collide())
	unsigned char* m_escapeHints;              ///< that soft body's escape hints (0 outside collide())
	int* m_skinMeshHints;                      ///< that soft body's skin-mesh hints (0 outside collide())
	btVector3* m_nodeReadings;                 ///< that soft body's field readings (0 outside collide() and in ELLIPSOIDS)
	btScalar* m_nodeRise;                      ///< that soft body's node rises (0 outside collide(), or when no level applies)
	btScalar m_skinLevel;                      ///< collideOnSkin: the level of the node it decides
	const btSoftBody::Node* m_contactNodeBase; ///< node 0 of that soft body
	ContactRecord* m_contactRecord;            ///< that soft body's record (0 outside collide())
	btAlignedObjectArray<btScalar> m_riseAsk;   ///< liftEdgesOffSkin: per node, the largest rise its edges ask (0: none)
	btAlignedObjectArray<btScalar> m_riseSlack; ///< ... and its edges' least slack above the clearance (per call)
	btAlignedObjectArray<int> m_edgeActive;     ///< liftEdgesOffSkin: the nodes in contact this substep
	btAlignedObjectArray<int> m_liftNear;       ///< ... and the other ends of their edges that it asked to rise

	/// The soft body's record, cleared and sized to its nodes, marked current; m_contactFlags points into it.
	void beginContactRecord(const btSoftBody* softBody);
	/// Tight mode: points m_nodeReadings at the record's readings, sized to the nodes; all dropped when the field's
	/// contents changed since they were taken.
	void beginReadings(ContactRecord& record, int numNodes);
	/// Drops the records of soft bodies the substep did not process (removed from the world).
	void dropStaleContactRecords();

	// Tight mode on a skinned body (btSkinFieldResponse.cpp, "bone fields"): the field of the bind pose, read in the
	// frame of the bone that carries every ellipsoid near a node.
	bool m_boneFields;        ///< this substep sweeps and the compound has a field, a bind pose and bone frames
	int m_skinGroup;          ///< the frame collideOnSkin works in: -1 the body's, else a bone group of this substep
	btEllipsoidWorldCache m_bindCache;               ///< the bind pose's ellipsoids (compound frame)
	btAlignedObjectArray<int> m_frameBones[2];       ///< per ellipsoid: its bone in the previous / current substep
	btAlignedObjectArray<btTransform> m_frames[2];   ///< bind -> current body frame, previous / current substep
	btAlignedObjectArray<int> m_frameGroup;          ///< per ellipsoid: its bone group this substep, -1 none
	btAlignedObjectArray<int> m_bindCandidates;
	btAlignedObjectArray<btSkinFieldGeometry> m_groupGeometry; ///< per group: the field, bind frame -> world now
	btAlignedObjectArray<btTransform> m_groupPrevious;         ///< per group: bind frame -> world, previous substep
	btAlignedObjectArray<int> m_groupBone;                     ///< per group: its first bone
	btAlignedObjectArray<int> m_groupFirst;                    ///< per group: its first ellipsoid
	btAlignedObjectArray<int> m_boneFallbacks;  ///< accumulated per ellipsoid: nodes it sent to the union response
	// ... and on the skinned mesh of the instant where the bone frames cannot decide (btSkinMeshResponse.cpp).
	const btSkinMesh* m_skinMesh; ///< the compound's skin mesh when usable this substep (see prepareSkinMesh), else 0
	int m_skinMeshRevision;       ///< its revision at the previous substep (-1: none)

	btTransform interpolatedKinematicPose();
	/// Moves the body pose forward by one substep (m_previousPose, m_currentPose, m_delta).
	void advanceBodyPose(bool continuing);
	/// Updates the world cache; when the compound changed with the same count since a substep that had a pose,
	/// prepares the per-ellipsoid motion (m_sweeping).
	void updateWorldCache(bool continuing);
	/// Body surface velocity at a point of ellipsoid `ellipsoid` (-1: the body's rigid motion only).
	btVector3 bodyVelocityAt(const btVector3& worldPoint, int ellipsoid, btScalar dt) const;
	/// The same for the per-ellipsoid motion of a sweeping substep.
	btVector3 sweptVelocityAt(const btVector3& worldPoint, int ellipsoid, btScalar dt) const;
	/// A path that starts inside an ellipsoid: x kept if the solve brought it out (zeta >= 1 there), else the union
	/// push-out from x (`start` for the velocity rule). \return the node's zeta.
	btScalar respondStartInside(btSoftBody::Node& node, const btPathEntry& entry, const btVector3& start,
								const Substep& substep);
	/// The first of the candidates whose previous pose contains q (a start inside during a sweep).
	int firstContaining(const btVector3& q, const int* cand, int nc) const;
	/// The node loop of a substep whose ellipsoids moved by themselves (m_sweeping).
	void collideSweptNodes(btSoftBody* softBody, const btVector3* startPositions, const Substep& substep);
	bool collideNode(btSoftBody::Node& node, const btVector3& q, const Substep& substep, btScalar& zeta);
	/// The node with its uncarried start q when the ellipsoids moved by themselves: the path test in each
	/// candidate's moving frame (btEllipsoidSweep), then respondToSweep.
	bool collideSweptNode(btSoftBody::Node& node, const btVector3& q, const Substep& substep, btScalar& zeta);
	/// The node was swept by ellipsoid `swept.m_ellipsoid`: its start carried by that ellipsoid's motion, the static
	/// response from there against the current ellipsoids (pushed out ahead of the sweeping one if that start is
	/// inside another).
	btScalar respondToSweep(btSoftBody::Node& node, const btPathEntry& swept, const btVector3& q, const Substep& substep);
	/// The carried path start -> x grown by the skin lies in the box the swept candidates of q -> x were listed for.
	bool carriedPathCovered(const btVector3& q, const btVector3& x, const btVector3& start, btScalar skin) const;
	/// After a teleport: a node outside every ellipsoid but in a pocket the union encloses leaves it.
	void leavePocket(btSoftBody::Node& node, const Substep& substep, btScalar& minZeta);
	btScalar respondAtEntry(btSoftBody::Node& node, const btPathEntry& entry, const btVector3& q, int nc,
							const Substep& substep);
	/// Union push-out from `from`, then the velocity rule at the exit; moved = false if `from` was outside already
	/// (the node is left at `from`, its velocity unchanged).
	btScalar pushNodeOut(btSoftBody::Node& node, const btVector3& from, const btVector3& start, const Substep& substep,
						 bool& moved);
	/// The velocity rule at the node's final position (every touched surface), the slide for the `remaining`
	/// fraction of the substep after it met the surface, the cap by its real motion, and the reaction on a dynamic body.
	/// \return true if the contact stopped a moving node (zero relative velocity after it: held by static friction,
	/// or moving straight in); the caller then keeps the node at its start.
	bool respondVelocity(btSoftBody::Node& node, const btVector3& normal, const btVector3& surface,
						 const btVector3& start, const btVector3& center, int ellipsoid, const Substep& substep,
						 btScalar remaining);
	/// The end of every contact response: the relative velocity vr capped by the node's real motion along the
	/// normal, the node's velocity set to bodyVelocity + vr, and the reaction on a dynamic body (before: the node's
	/// velocity before the contact).
	void setContactVelocity(btSoftBody::Node& node, btVector3 vr, const btVector3& normal, const btVector3& start,
							const btVector3& bodyVelocity, const btVector3& before, const btVector3& surface,
							btScalar dt);
	/// Moves the node by `displacement` if that path enters no ellipsoid.
	void slideAlong(btSoftBody::Node& node, const btVector3& displacement, int touching, const Substep& substep);
	/// True when the contact list of the node's position (`touching` entries in m_contactCandidates) holds every
	/// ellipsoid a slide by `displacement` can meet.
	static bool slideCovered(const btVector3& displacement, const Substep& substep);

	// Tight mode (btSkinFieldResponse.cpp): contact decided on the skin field for a node the broad phase kept.
	/// The path against the field: no contact, placement at the first point at the skin offset, or push-out.
	/// \return false (zeta is not tracked in tight mode; the field's minimum goes to the stats).
	bool collideOnSkin(btSoftBody::Node& node, const btVector3& qStart, const Substep& substep, btScalar& zeta);
	/// The node's rise when its level is raised and applies (Config::m_liftEdges on, the static field's response, not a
	/// bone's), else 0: the one test collideOnSkin and candidatesAtLevel share.
	btScalar* raisedLevel(const btSoftBody::Node& node)
	{
		if (!m_nodeRise || m_skinGroup >= 0) // (m_nodeRise is null unless the lift is on with the static field)
			return 0;
		btScalar* rise = &m_nodeRise[&node - m_contactNodeBase];
		return *rise > btScalar(0) ? rise : 0;
	}
	/// The broad phase of a node whose level is raised by `rise` (Config::m_liftEdges, raisedLevel) and whose path
	/// grown by the skin offset meets no ellipsoid: the path grown by its level instead (where the union hugs the
	/// skin, a node resting at its level can stand beyond the offset's reach; left out, it fell and was raised in
	/// turns).
	int candidatesAtLevel(const btVector3& q, const btVector3& x, btScalar rise, const Substep& substep);
	/// collideOnSkin's level for a raised node (m_skinLevel: the skin offset plus `rise`) and where its path starts.
	/// A node that starts or ends a whole offset above its level has left the skin: its rise goes back to 0 (so the
	/// march through far bricks keeps its full far step, btSkinFieldGeometry::stepFrom). One that starts
	/// between the offset and its level (the level rose since it was placed) starts from qb taken up to the level
	/// along the gradient (true, qb moved), or is decided at the offset this substep where that fails.
	/// `ends` holds the field at qb and at the path's end, and is brought up to date when qb moves.
	bool raiseStart(btScalar& rise, btVector3& qb, btSkinPathEnds& ends);
	/// A node that starts within the skin: Newton on the field from x, else the union push-out (counted). `point` is x
	/// in the field's frame on entry (the field reads fx there) and the node's final position on return.
	/// \return the field at the node's final position.
	btScalar pushOutOfSkin(btSoftBody::Node& node, const btVector3& q, btScalar fx, const btVector3& center,
						   const Substep& substep, btVector3& point);
	/// Config::m_liftEdges, after the node responses of a substep that did not sweep: every cloth edge at a node in
	/// contact reads the field at its midpoint (or reuses an earlier reading that still proves it clear). An edge whose
	/// middle lies below the lift clearance asks the level of its nodes in contact (the field value collideOnSkin
	/// places, holds and pushes them out at) to rise by what the middle lacks, split by inverse mass; a node whose
	/// edges all clear the skin by more than twice the clearance sinks back toward the offset (updateNodeRises). The
	/// nodes move in the next substep's node phase, as contacts at their level: no position is changed here, so the
	/// links and the contacts never pull a node back and forth.
	void liftEdgesOffSkin(btSoftBody* softBody);
	/// liftEdgesOffSkin's nodes whose edges are looked at (m_edgeActive): the nodes in contact this substep.
	void listEdgeNodes(int numNodes);
	/// One edge of liftEdgesOffSkin: its midpoint read on the field unless the last reading still holds. Below the
	/// clearance each end whose level can rise (liftWeight) asks its share of the rise (m_riseAsk); else each end
	/// notes the edge's least slack (m_riseSlack).
	void liftEdge(const btSoftBody::Node* nodes, LiftEdge& edge, btScalar clearance, btScalar lipschitz);
	/// The share an edge end takes of its edge's lift: its inverse mass where its level can rise, else 0. A node in
	/// contact can; so can one the collider read this substep (its reading is at its position) within the lift's
	/// reach of the skin (below the offset plus the largest rise), held off the skin by its links: lifted from one
	/// end only, an edge over a bulge rose by half of its end's rise and stuck at the largest rise, still sagging.
	btScalar liftWeight(const btSoftBody::Node* nodes, int i) const;
	/// Node i's rise ask becomes at least `ask` (a node not in contact is listed in m_liftNear at its first ask).
	void askRise(int i, btScalar ask);
	/// liftEdgesOffSkin's last step, per node in contact and per other end asked to rise (m_liftNear): its rise
	/// grows by its largest ask (up to maxRise), or shrinks by half the slack its edges have beyond the clearance
	/// (never below 0).
	void updateNodeRises(btScalar clearance, btScalar maxRise);
	void updateNodeRise(int i, btScalar clearance, btScalar maxRise, btScalar maxStep);
	/// The field geometry collideOnSkin works with (m_skinGroup).
	const btSkinFieldGeometry& skinGeometry() const
	{
		return m_skinGroup < 0 ? m_skinGeometry : m_groupGeometry[m_skinGroup];
	}
	/// The body's surface velocity at a world point of the field's surface in the frame of m_skinGroup.
	btVector3 skinSurfaceVelocity(const btVector3& worldPoint, btScalar dt) const;
	/// Once per substep after the world cache: the bone frames of this substep, their groups (bones whose motion
	/// agrees within the field's tolerance) and a field geometry per group (m_boneFields).
	void prepareBoneFields();
	/// Groups the rigid ellipsoids of this substep by the motion of their bones (m_frameGroup, m_groupGeometry).
	void groupBoneFrames(const btSkinDistanceField& field);
	/// The group of every candidate, or -1 (the first candidate of another group or not rigid gets the fallback).
	int candidateGroup(const int* cand, int nc);
	/// Every bind ellipsoid whose box meets the bind-frame path a -> b grown by `band` is rigid in group g.
	bool bindNeighboursIn(int g, const btVector3& a, const btVector3& b, btScalar band);
	/// A node of a sweeping substep with nc swept candidates: decided on the bind field in the frame of their bone
	/// group when they share one and the checks hold (true), else nothing changes and the union response decides.
	bool collideOnBoneField(btSoftBody::Node& node, const btVector3& q, int nc, const Substep& substep);
	/// respondVelocity with the field's normal: the velocity rule, the slide along the field, the cap, the reaction.
	/// `value` (the field at the node) follows the slide.
	/// `point` is the node's body-frame position (the field reads `value` there) and follows the slide too.
	bool respondOnSkin(btSoftBody::Node& node, const btVector3& normal, const btVector3& surface, const btVector3& start,
					   const btVector3& center, const Substep& substep, btScalar remaining, btVector3& point,
					   btScalar& value);
	/// The field at the two ends of the node's path: the start's from the node's last reading when it is that exact
	/// point, else looked up (skinEnds), and the reading kept for the next substep (keepReading).
	btSkinPathEnds skinEnds(const btSoftBody::Node& node, const btVector3& qb, const btVector3& xb) const;
	/// Whether a node's reading (point in xyz, field value in w) was taken exactly at p (field frame).
	static bool isReadingAt(const btVector3& reading, const btVector3& p)
	{
		return reading.x() == p.x() && reading.y() == p.y() && reading.z() == p.z();
	}
	void keepReading(const btSoftBody::Node& node, const btVector3& point, btScalar value);

	// Tight mode on a skinned body, the skin of the instant (btSkinMeshResponse.cpp).
	/// Once per substep after prepareBoneFields: m_skinMesh is the compound's mesh when this substep sweeps in tight
	/// mode and the mesh took exactly one pose since the previous substep (its previous pose is this substep's start).
	void prepareSkinMesh();
	/// A tested node the bind field could not decide: decided on the skinned mesh (left where it is at the skin
	/// offset or more, else placed at the offset along the closest triangle's normal, with the velocity rule; a long
	/// path relative to the skin traced by traceLongPath) when the mesh query can be trusted (true); else nothing
	/// changes (false) and the union response decides.
	bool collideOnSkinMesh(btSoftBody::Node& node, const btVector3& q, int nc, const Substep& substep);
	/// A node whose path relative to the skin under it is long: that path (from `start`, body frame) sphere-traced on
	/// the distance to the skin: left at its end when no point comes within the offset, else placed at the first point
	/// that does (true); false (nothing changed) when the start is not outside or the trace runs out of steps.
	bool traceLongPath(btSoftBody::Node& node, const btVector3& start, const Substep& substep);
	/// The velocity rule at a node placed on the skin mesh: `surface` its closest skin point, `surfaceBefore` where
	/// that point was at the start of the substep (world).
	void placedOnSkinMesh(btSoftBody::Node& node, const btVector3& normal, const btVector3& surface,
						  const btVector3& surfaceBefore, const btVector3& start, const Substep& substep);
};

#endif // BT_ELLIPSOID_CLOTH_COLLIDER_CORE_H
