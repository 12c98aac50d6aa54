/*
bodyfit: the skinned-body driver. At simulation time t it poses a rig on a clip (speed, loop or clamp, start time),
updates the bone-bound ellipsoids (bodyfit/fitting/skinned_fit.h: the union contains the skinned skin at every pose)
and writes them into the body's btEllipsoidCompoundShape; optionally it also writes the skinned vertices into a
btBvhTriangleMeshShape and refits its tree (Bullet's own alternative for an animated body, measured beside ours).

Call update(t) once per Bullet substep, before the substep is solved, with t = the time at the end of the substep
(the pose the body has when the collider runs, as keyframed kinematic bodies are posed: bodyfit/drape/effects.h
BodyMotionEffect). The ellipsoid collider re-reads a changed compound every substep (its analytic revision) and
pushes out the nodes a grown or moved ellipsoid now contains.

Eigen -> Bullet conversion lives here (the bridge is the only layer that sees both).
*/

#ifndef BT_SKINNED_BODY_DRIVER_H
#define BT_SKINNED_BODY_DRIVER_H

#include "bodyfit/fitting/rig.h"
#include "bodyfit/fitting/skinned_fit.h"

#include <LinearMath/btAlignedObjectArray.h>
#include <LinearMath/btMatrix3x3.h>
#include <LinearMath/btScalar.h>
#include <LinearMath/btTransform.h>
#include <LinearMath/btVector3.h>

#include <memory>
#include <string>
#include <vector>

class btEllipsoidCompoundShape;
class btSkinMesh;
class btBvhTriangleMeshShape;
class btTriangleIndexVertexArray;

namespace bodyfit
{

/// How simulation time maps to clip time: clip t = start + speed * sim t, wrapped into [0, duration) when looping,
/// clamped to [0, duration] (the last pose held) otherwise.
struct AnimationTiming
{
	double speed = 1.0;  ///< > 0
	bool loop = true;
	double startS = 0.0; ///< clip time at simulation time 0, in [0, duration]

	/// Clip time (seconds) at simulation time `simSeconds` for a clip of `duration` seconds.
	double clipTime(double simSeconds, double duration) const;
};

/// A triangle mesh as Bullet's btBvhTriangleMeshShape whose vertices can be replaced and its tree refitted
/// (setVertices). The static mesh collider of the scene runner and Bullet's refitted animated body are both this.
class btRefitTriangleMesh
{
public:
	/// \throws InvalidInputError for a mesh without faces, with a face index outside the vertices or a non-finite
	///         coordinate, or a margin that is negative or not finite.
	btRefitTriangleMesh(const TriMesh& mesh, double margin);
	~btRefitTriangleMesh();
	btRefitTriangleMesh(const btRefitTriangleMesh&) = delete;
	btRefitTriangleMesh& operator=(const btRefitTriangleMesh&) = delete;

	btBvhTriangleMeshShape* shape() const { return m_shape.get(); }
	int triangleCount() const { return int(m_indices.size() / 3); }
	int vertexCount() const { return int(m_vertices.size() / 3); }

	/// Replaces every vertex (rows = the mesh's vertices, same order) and refits the BVH over the new bounds
	/// (btBvhTriangleMeshShape::refitTree, which also recomputes the shape's local AABB).
	/// \throws InvalidInputError when the row count differs from the mesh's, or a coordinate is NaN or infinite (the
	///         mesh then keeps its vertices).
	void setVertices(const Eigen::MatrixX3d& vertices);

private:
	std::vector<btScalar> m_vertices;
	std::vector<int> m_indices;
	std::unique_ptr<btTriangleIndexVertexArray> m_array;
	std::unique_ptr<btBvhTriangleMeshShape> m_shape;
};

/// Cost of the driver's updates (accumulated since the last resetStats).
struct SkinnedDriverStats
{
	long long updates = 0;
	double bodySeconds = 0.0;     ///< poseBones + skinningMatrices + skinVertices + ellipsoid update
	double compoundSeconds = 0.0; ///< writing the ellipsoids into the compound (setEllipsoid per ellipsoid)
	double meshSeconds = 0.0;     ///< writing the vertices into the triangle mesh and refitting its tree, and the
								  ///< same for the compound's skin mesh (tight surface)
	double lastBodySeconds = 0.0, lastCompoundSeconds = 0.0, lastMeshSeconds = 0.0; ///< of the last update
};

/// Poses a skinned body over time and writes it into Bullet shapes (see the file comment).
class btSkinnedBodyDriver
{
public:
	/// Keeps references to `rig` and `clip` (they must outlive the driver); the fit and binding are copied into the
	/// SkinnedBody. The body starts at simulation time 0 (update(0) is called here).
	/// \throws InvalidInputError as SkinnedBody, or for a speed <= 0 / non-finite, or a start outside the clip.
	btSkinnedBodyDriver(const Rig& rig, const BodyFit& fit, const SkinBinding& binding, const AnimationClip& clip,
						const AnimationTiming& timing, const SkinnedBodyOptions& options = {});
	~btSkinnedBodyDriver();
	btSkinnedBodyDriver(const btSkinnedBodyDriver&) = delete;
	btSkinnedBodyDriver& operator=(const btSkinnedBodyDriver&) = delete;

	/// The compound whose ellipsoids are replaced at every update (child i = ellipsoid i of the fit); null: none.
	/// When the compound has a bind pose (btEllipsoidCompoundShape::setBindPose: the tight skin surface of an
	/// animated body), every update also writes its bone frames: per ellipsoid its dominant bone and that bone's
	/// skinning motion when its skin moves with it: a rigid ellipsoid, or one whose bones all move like the dominant
	/// one within frameTolerance() over its bind ellipsoid (-1 otherwise: a bending joint).
	/// With setSkinMeshEnabled(true), a bind pose and a skin field (the tight surface) the driver also gives the
	/// compound the skinned mesh of each pose (btEllipsoidCompoundShape::setSkinMesh: rig.bindMesh's triangles, owned by the driver, detached from
	/// the compound by the next setCompound and the destructor, so the compound must outlive the driver or be
	/// replaced first), written in the same update as the ellipsoids.
	/// \throws InvalidInputError when its ellipsoid count differs from the fit's. Writes the current pose at once.
	void setCompound(btEllipsoidCompoundShape* compound);
	/// Whether setCompound gives the compound the skinned mesh of each pose (default false). Opt-in: the collider
	/// then decides the tight surface's joint nodes on that mesh (contact gap ~3.5 mm instead of ~15 mm on the
	/// bundled walk) at ~5x the collider's cost per node and ~1 ms more per pose, and without the default's
	/// guarantee: 1 node inside the body at one sample of the walk tights (README "Animated bodies"). Takes effect
	/// at the next setCompound.
	void setSkinMeshEnabled(bool enabled) { m_skinMeshEnabled = enabled; }
	bool isSkinMeshEnabled() const { return m_skinMeshEnabled; }
	/// The triangle mesh (of rig.bindMesh) whose vertices are replaced at every update; null: none.
	/// \throws InvalidInputError when its vertex count differs. Writes the current pose at once.
	void setMesh(btRefitTriangleMesh* mesh);

	/// Poses the body at simulation time `simSeconds` and writes the shapes. A call with the time of the previous
	/// update does nothing (the body is already there).
	/// \throws InvalidInputError for a time that is NaN or infinite (the body keeps its pose).
	void update(double simSeconds);

	double time() const { return m_time; }          ///< simulation time of the current pose
	double clipTime() const { return m_clipTime; }  ///< clip time of the current pose
	const SkinnedBody& body() const { return *m_body; }
	const AnimationClip& clip() const { return *m_clip; }
	const AnimationTiming& timing() const { return m_timing; }
	/// Increases whenever the pose changes (the metrics rebuild their skin reference only then).
	long long poseRevision() const { return m_revision; }

	/// How far (metres) the skin of an ellipsoid may move away from its dominant bone's rigid motion and still be
	/// handed to the collider in that bone's frame (default 0.5 mm: a quarter of the default 2 mm skin offset, so a
	/// node placed on the bind field stays at least 1.5 mm outside the moved skin). Takes effect at the next update.
	/// \throws InvalidInputError for a negative or non-finite tolerance.
	double frameTolerance() const { return m_frameTolerance; }
	void setFrameTolerance(double metres);

	const SkinnedDriverStats& stats() const { return m_stats; }
	void resetStats() { m_stats = SkinnedDriverStats(); }

private:
	void writeCompound();
	/// The bone frames of the current pose into the compound (see setCompound).
	void writeBoneFrames();
	/// Every bone with weight on ellipsoid j moves like `bone` within m_frameTolerance (see frameTolerance).
	bool movesWithBone(int j, int bone, const std::vector<Eigen::Affine3d>& skinning) const;
	void writeMesh();
	/// The skinned vertices into the skin mesh (a new pose of it).
	void writeSkinMesh();

	const AnimationClip* m_clip;
	AnimationTiming m_timing;
	std::unique_ptr<SkinnedBody> m_body;
	btEllipsoidCompoundShape* m_compound = nullptr;
	btRefitTriangleMesh* m_mesh = nullptr;
	std::unique_ptr<btSkinMesh> m_skinMesh; ///< given to m_compound when enabled and it has a bind pose and a skin field
	bool m_skinMeshEnabled = false;
	double m_time = 0.0;
	double m_clipTime = 0.0;
	long long m_revision = 0;
	SkinnedDriverStats m_stats;
	btAlignedObjectArray<btVector3> m_centers, m_semiAxes; ///< the pose in Bullet types, for setEllipsoids
	btAlignedObjectArray<btMatrix3x3> m_bases;
	double m_frameTolerance = 0.0005;
	btAlignedObjectArray<int> m_frameBones; ///< the bone frames in Bullet types, for setBoneFrames
	btAlignedObjectArray<btTransform> m_bindToCurrent;
};

} // namespace bodyfit

#endif // BT_SKINNED_BODY_DRIVER_H
