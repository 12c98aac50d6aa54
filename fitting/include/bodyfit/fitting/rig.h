#pragma once
/// \file rig.h
/// A body skinned to a skeleton and its animation clips, read through assimp (glTF/GLB, FBX, Collada, ...), and
/// linear blend skinning.
///
/// Frames. Everything is in the bodyfit frame (metres, +y up): the file's coordinates go through the conversion
/// C = (up-axis rotation) * scale of LoadOptions, applied to the root of the node hierarchy, so bone world matrices
/// and the bind mesh are in metres/+y and the inverse bind matrices map that frame to bone space.
///
/// Bind pose vs rest pose. The bind pose is the pose the skin was bound in: bone i's world matrix is
/// inverse(inverseBind[i]) and skinning gives the stored mesh (glTF convention: the skinned mesh node's own transform
/// is not applied). The rest pose is what the node hierarchy holds without animation; it may differ from the bind
/// pose (a rig exported in a T-pose with the skin bound in an A-pose). Fitting uses the bind mesh; posing uses the
/// hierarchy's local transforms, with the animated channels replacing the local transform of their node.
///
/// Skinning. v(t) = sum_i w_i S_i(t) v_bind with S_i(t) = world_i(t) * inverseBind[i]; S_i = I in the bind pose.
/// Weights are per vertex, any number of influences, normalised to sum 1 at load.

#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/types.h"

#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace bodyfit
{

/// A node of the skeleton hierarchy: a joint that influences the skin, or one of their ancestors (an armature node,
/// a root), which moves the joints below it. Parents come before their children.
struct Bone
{
	std::string name;
	int parent = -1;                                             ///< index into Rig::bones, -1 for a root
	Eigen::Affine3d restLocal = Eigen::Affine3d::Identity();    ///< transform relative to the parent (file units)
	Eigen::Affine3d inverseBind = Eigen::Affine3d::Identity();  ///< bodyfit frame -> bone space in the bind pose
	bool deforms = false; ///< some vertex has a weight on this bone (inverseBind is meaningful only then)
};

/// Keys of one animated node, times in seconds (ascending). A channel may have any number (>= 1) of each kind.
struct BoneChannel
{
	int bone = -1;
	std::vector<double> positionTimes, rotationTimes, scaleTimes;
	std::vector<Eigen::Vector3d> positions, scales;
	std::vector<Eigen::Quaterniond> rotations;
};

struct AnimationClip
{
	std::string name;
	double duration = 0.0;         ///< seconds (> 0)
	double ticksPerSecond = 0.0;   ///< as the file stated it (assimp's default 25 when the file gave none)
	std::vector<BoneChannel> channels;
};

struct Rig
{
	std::string path;
	std::string meshName;   ///< the skinned mesh used as the body
	TriMesh bindMesh;       ///< skin in the bind pose, bodyfit frame (drawn in restFrame), repaired as loadTriMesh repairs meshes
	MeshReport report;      ///< what loading found and repaired
	std::vector<Bone> bones;
	/// Sparse weights, per vertex of bindMesh: influences weightStart[v] .. weightStart[v+1]-1 of weightBone /
	/// weight, normalised to sum 1, ordered by bone index.
	std::vector<int> weightStart;
	std::vector<int> weightBone;
	std::vector<double> weight;
	Eigen::Affine3d conversion = Eigen::Affine3d::Identity(); ///< file frame -> bodyfit frame (scale, up axis)
	/// Where the file draws its stored vertices (bodyfit frame, after conversion): the rest skinning matrix of the root
	/// bone when the skeleton hangs under a scaled or turned node, else the identity. bindMesh holds the vertices
	/// mapped by it and every inverseBind is composed with its inverse, so skinned poses are the file's (rig_io.cpp).
	Eigen::Affine3d restFrame = Eigen::Affine3d::Identity();
	std::vector<AnimationClip> clips;

	int boneCount() const { return int(bones.size()); }
	int influenceCount(int vertex) const { return weightStart[std::size_t(vertex) + 1] - weightStart[std::size_t(vertex)]; }
	/// Index of the clip named `name`, or of clip number `name` when it is a decimal index; -1 if there is none.
	int findClip(const std::string& name) const;
};

struct RigLoadOptions
{
	LoadOptions mesh;       ///< up axis, scale and weld tolerance (as for static meshes)
	std::string meshName;   ///< the skinned mesh (or its node) to use; empty: the skinned mesh with most vertices
	bool requireAnimation = true; ///< no clip in the file is an error
};

/// True when `path` holds at least one mesh with bones (a rigged body), false for a static mesh.
/// \throws MeshLoadError as loadTriMesh when the file cannot be read.
bool hasSkinnedMesh(const std::string& path);

/// Loads the skinned body, its skeleton, weights and clips.
/// \throws MeshLoadError (file unreadable, as loadTriMesh) and InvalidInputError with one line naming what is wrong:
/// no skinned mesh, unknown mesh name, a vertex with zero / negative / non-finite weights, a non-finite inverse
/// bind matrix or key, no animation, a clip of zero duration.
Rig loadRig(const std::string& path, const RigLoadOptions& options = {});

/// The clip named `name` (or numbered, see Rig::findClip). \throws InvalidInputError "unknown clip" listing the clips.
const AnimationClip& requireClip(const Rig& rig, const std::string& name);

/// World matrices (bodyfit frame) of every bone of `rig` at time t seconds of `clip` (t clamped to
/// [0, duration]); linear interpolation of positions and scales, slerp of rotations, keys held before the first and
/// after the last. Bones without a channel keep their rest transform. \throws InvalidInputError for a NaN time.
std::vector<Eigen::Affine3d> poseBones(const Rig& rig, const AnimationClip& clip, double t);

/// World matrices (bodyfit frame) of every bone in the rest pose: the node transforms of the file, no clip.
std::vector<Eigen::Affine3d> restPoseBones(const Rig& rig);

/// World matrices of the bind pose: inverse(inverseBind) for deforming bones; the rest pose for the others.
std::vector<Eigen::Affine3d> bindPoseBones(const Rig& rig);

/// Skinning matrices S_i = world_i * inverseBind_i (identity in the bind pose).
std::vector<Eigen::Affine3d> skinningMatrices(const Rig& rig, const std::vector<Eigen::Affine3d>& boneWorld);

/// Linear blend skinning of rig.bindMesh with the skinning matrices: out gets one row per vertex.
void skinVertices(const Rig& rig, const std::vector<Eigen::Affine3d>& skinning, Eigen::MatrixX3d& out);

} // namespace bodyfit
