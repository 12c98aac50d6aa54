// Rigged bodies through assimp: the skinned mesh, its skeleton, weights and clips, and linear blend skinning.
// See rig.h. The file checks are mesh_io.cpp's (readCheckedScene).
#include "bodyfit/fitting/rig.h"

#include "bodyfit/fitting/errors.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <sstream>

namespace bodyfit
{

int Rig::findClip(const std::string& name) const
{
	for (std::size_t i = 0; i < clips.size(); ++i)
		if (clips[i].name == name)
			return int(i);
	if (!name.empty() && name.size() < 9 && name.find_first_not_of("0123456789") == std::string::npos)
	{
		const int index = std::stoi(name);
		if (index < int(clips.size()))
			return index;
	}
	return -1;
}

namespace
{

std::string quoted(const std::string& s)
{
	return "'" + s + "'";
}

std::string number(double d)
{
	std::ostringstream s;
	s.precision(9);
	s << d;
	return s.str();
}

Eigen::Affine3d toAffine(const aiMatrix4x4& m)
{
	Eigen::Matrix4d e;
	e << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4, m.d1, m.d2, m.d3, m.d4;
	return Eigen::Affine3d(e);
}

bool finiteAffine(const aiMatrix4x4& m)
{
	const float* p = &m.a1;
	return std::all_of(p, p + 16, [](float v) { return std::isfinite(v); });
}

/// File frame -> bodyfit frame: scale, then +z up -> +y up when asked (the rotation of repairMesh).
Eigen::Affine3d conversionOf(const LoadOptions& options)
{
	if (!(options.scale > 0.0) || !std::isfinite(options.scale))
		throw InvalidInputError("scale must be a positive finite number");
	Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
	if (options.up == UpAxis::Z) // (x, y, z) -> (x, z, -y)
		R << 1, 0, 0, 0, 0, 1, 0, -1, 0;
	Eigen::Affine3d c = Eigen::Affine3d::Identity();
	c.linear() = R * options.scale;
	return c;
}

/// Names a mesh for messages: its own name, or its index.
std::string meshLabel(const aiScene* scene, unsigned m)
{
	const std::string name = scene->mMeshes[m]->mName.C_Str();
	return name.empty() ? "mesh " + std::to_string(m) : quoted(name);
}

bool nodeUsesMesh(const aiNode* node, unsigned m, const std::string& name)
{
	if (name == node->mName.C_Str())
		for (unsigned i = 0; i < node->mNumMeshes; ++i)
			if (node->mMeshes[i] == m)
				return true;
	for (unsigned c = 0; c < node->mNumChildren; ++c)
		if (nodeUsesMesh(node->mChildren[c], m, name))
			return true;
	return false;
}

/// The body: the skinned mesh named `wanted` (mesh or node name), or the skinned mesh with most vertices.
unsigned pickSkinnedMesh(const aiScene* scene, const std::string& path, const std::string& wanted)
{
	int best = -1;
	std::string skinned;
	for (unsigned m = 0; m < scene->mNumMeshes; ++m)
	{
		const aiMesh* mesh = scene->mMeshes[m];
		if (mesh->mNumBones == 0)
			continue;
		skinned += (skinned.empty() ? "" : ", ") + meshLabel(scene, m);
		if (!wanted.empty())
		{
			if (best < 0 && (wanted == mesh->mName.C_Str() || nodeUsesMesh(scene->mRootNode, m, wanted)))
				best = int(m);
		}
		else if (best < 0 || mesh->mNumVertices > scene->mMeshes[best]->mNumVertices)
			best = int(m);
	}
	if (skinned.empty())
		throw InvalidInputError(path + ": no skinned mesh (no mesh has bones): not a rigged body");
	if (best < 0)
		throw InvalidInputError(path + ": no skinned mesh named " + quoted(wanted) + " (skinned meshes: " + skinned + ")");
	return unsigned(best);
}

/// The skeleton: the nodes of the mesh's bones and all their ancestors, parents first (depth-first order of the
/// hierarchy). `boneOfNode` maps the kept nodes to bone indices.
void collectSkeleton(const aiScene* scene, const aiMesh* mesh, const std::string& path, Rig& rig,
					 std::map<const aiNode*, int>& boneOfNode)
{
	std::map<const aiNode*, char> keep;
	for (unsigned b = 0; b < mesh->mNumBones; ++b)
	{
		const aiBone* bone = mesh->mBones[b];
		const aiNode* node = scene->mRootNode->FindNode(bone->mName);
		if (node == nullptr)
			throw InvalidInputError(path + ": bone " + quoted(bone->mName.C_Str()) + " has no node in the hierarchy");
		for (; node != nullptr; node = node->mParent)
			keep[node] = 1;
	}
	std::vector<std::pair<const aiNode*, int>> stack = {{scene->mRootNode, -1}};
	while (!stack.empty())
	{
		const auto [node, parent] = stack.back();
		stack.pop_back();
		if (keep.count(node) == 0)
			continue;
		if (!finiteAffine(node->mTransformation))
			throw InvalidInputError(path + ": node " + quoted(node->mName.C_Str()) + " has a non-finite transform");
		Bone bone;
		bone.name = node->mName.C_Str();
		bone.parent = parent;
		bone.restLocal = toAffine(node->mTransformation);
		const int index = int(rig.bones.size());
		boneOfNode[node] = index;
		rig.bones.push_back(bone);
		for (unsigned c = node->mNumChildren; c-- > 0;) // reversed: children are visited in file order
			stack.push_back({node->mChildren[c], index});
	}
}

/// Per file vertex of `mesh`: its (bone, weight) pairs, summed per bone; sets inverseBind/deforms of the bones.
std::vector<std::map<int, double>> readWeights(const aiScene* scene, const aiMesh* mesh, const std::string& path,
											   Rig& rig, const std::map<const aiNode*, int>& boneOfNode)
{
	std::vector<std::map<int, double>> weights(mesh->mNumVertices);
	const Eigen::Affine3d toFile = rig.conversion.inverse();
	for (unsigned b = 0; b < mesh->mNumBones; ++b)
	{
		const aiBone* bone = mesh->mBones[b];
		const std::string name = bone->mName.C_Str();
		if (!finiteAffine(bone->mOffsetMatrix))
			throw InvalidInputError(path + ": bone " + quoted(name) + " has a non-finite inverse bind matrix");
		Bone& target = rig.bones[std::size_t(boneOfNode.at(scene->mRootNode->FindNode(bone->mName)))];
		const Eigen::Affine3d inverseBind = toAffine(bone->mOffsetMatrix) * toFile;
		if (std::abs(inverseBind.linear().determinant()) < 1e-12)
			throw InvalidInputError(path + ": bone " + quoted(name) + " has a singular inverse bind matrix");
		target.inverseBind = inverseBind;
		target.deforms = true;
		const int index = boneOfNode.at(scene->mRootNode->FindNode(bone->mName));
		for (unsigned w = 0; w < bone->mNumWeights; ++w)
		{
			const aiVertexWeight& vw = bone->mWeights[w];
			if (vw.mVertexId >= mesh->mNumVertices)
				throw InvalidInputError(path + ": bone " + quoted(name) + ": weight for vertex " +
										std::to_string(vw.mVertexId) + " out of range");
			if (!std::isfinite(vw.mWeight) || vw.mWeight < 0.0f)
				throw InvalidInputError(path + ": vertex " + std::to_string(vw.mVertexId) + ": weight of bone " +
										quoted(name) + " is " + number(vw.mWeight) + " (must be finite and >= 0)");
			weights[vw.mVertexId][index] += double(vw.mWeight);
		}
	}
	return weights;
}

/// The frame the file draws its skin in: the rest skinning matrix C (bodyfit frame) of the deforming bone nearest the
/// skeleton's root, when it is not the identity. Skinning runs every vertex through the world transforms of its bones,
/// and those include every node above the skeleton: a skeleton under an "Armature" node scaled by 0.01 and turned
/// (Blender's export of a Mixamo character, whose vertices and inverse bind matrices stay in centimetres) draws the
/// body C v, in metres, while v itself is a 200 m body lying on its back. The bind mesh becomes C v and every
/// inverse bind matrix inverseBind C^-1 (Rig::restFrame): each skinned pose stays exactly what it was
/// (S' C v = S v), and the body that is fitted is the body the animation moves. The identity (up to the file's float
/// rounding, 1e-5) for a rig bound at rest under no such node, the bundled ones among them: nothing changes there.
/// \throws InvalidInputError when C is singular or not finite: the rest pose draws no body (a skeleton under a node
/// scaled to 0).
Eigen::Affine3d restFrameOfSkin(Rig& rig, const std::string& path)
{
	const std::vector<Eigen::Affine3d> rest = restPoseBones(rig);
	std::vector<int> depth(rig.bones.size(), 0);
	int root = -1;
	for (std::size_t b = 0; b < rig.bones.size(); ++b) // parents come first (collectSkeleton)
	{
		const int parent = rig.bones[b].parent;
		depth[b] = parent < 0 ? 0 : depth[std::size_t(parent)] + 1;
		if (rig.bones[b].deforms && (root < 0 || depth[b] < depth[std::size_t(root)]))
			root = int(b);
	}
	if (root < 0)
		return Eigen::Affine3d::Identity();
	const Eigen::Affine3d c = rest[std::size_t(root)] * rig.bones[std::size_t(root)].inverseBind;
	const double det = c.linear().determinant();
	if (!c.matrix().allFinite() || !(std::abs(det) > 1e-12))
		throw InvalidInputError(path + ": the rest pose draws the skin collapsed (bone " +
								quoted(rig.bones[std::size_t(root)].name) + " skins it through a singular matrix, " +
								"determinant " + number(det) + ": a node above it scaled to 0?)");
	const double offLinear = (c.linear() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
	if (offLinear <= 1e-5 && c.translation().cwiseAbs().maxCoeff() <= 1e-5)
		return Eigen::Affine3d::Identity();
	const Eigen::Affine3d inverse = c.inverse();
	for (Bone& bone : rig.bones)
		if (bone.deforms)
			bone.inverseBind = bone.inverseBind * inverse;
	return c;
}

/// The bind mesh in the bodyfit frame (the file's vertices drawn in rig.restFrame), repaired as loadTriMesh repairs
/// meshes, and the sparse normalised weights of its vertices (a welded vertex takes the weights of the file vertex it
/// was merged into).
void buildBindMesh(const aiMesh* mesh, const std::vector<std::map<int, double>>& weights,
				   const RigLoadOptions& options, const std::string& path, Rig& rig)
{
	TriMesh raw;
	raw.V.resize(mesh->mNumVertices, 3);
	const Eigen::Affine3d toBind = rig.restFrame * rig.conversion;
	for (unsigned i = 0; i < mesh->mNumVertices; ++i)
	{
		const Eigen::Vector3d p(mesh->mVertices[i].x, mesh->mVertices[i].y, mesh->mVertices[i].z);
		raw.V.row(i) = (toBind * p).transpose();
	}
	// A mirroring frame turns the triangles inside out: their corners are swapped back to face outwards.
	const bool mirrored = rig.restFrame.linear().determinant() < 0.0;
	std::vector<Eigen::Vector3i> faces;
	for (unsigned f = 0; f < mesh->mNumFaces; ++f)
		if (mesh->mFaces[f].mNumIndices == 3)
			faces.emplace_back(int(mesh->mFaces[f].mIndices[0]), int(mesh->mFaces[f].mIndices[mirrored ? 2 : 1]),
							   int(mesh->mFaces[f].mIndices[mirrored ? 1 : 2]));
	raw.F.resize(Eigen::Index(faces.size()), 3);
	for (std::size_t f = 0; f < faces.size(); ++f)
		raw.F.row(Eigen::Index(f)) = faces[f].transpose();
	LoadOptions repair; // already converted: the repair copies coordinates exactly
	repair.relativeWeldTolerance = options.mesh.relativeWeldTolerance;
	LoadedMesh loaded = repairMesh(raw, repair, path);
	rig.bindMesh = loaded.mesh;
	rig.report = loaded.report;
	rig.report.up = options.mesh.up;
	rig.report.scale = options.mesh.scale;

	// Repaired vertex -> the first file vertex with exactly its coordinates (the weld's representative).
	std::map<std::array<double, 3>, int> firstAt;
	for (int i = int(raw.V.rows()) - 1; i >= 0; --i)
		firstAt[{raw.V(i, 0), raw.V(i, 1), raw.V(i, 2)}] = i;
	rig.weightStart.assign(1, 0);
	for (int v = 0; v < rig.bindMesh.vertexCount(); ++v)
	{
		const int source = firstAt.at({rig.bindMesh.V(v, 0), rig.bindMesh.V(v, 1), rig.bindMesh.V(v, 2)});
		double total = 0.0;
		for (const auto& [bone, w] : weights[std::size_t(source)])
			total += w;
		if (!(total > 0.0) || !std::isfinite(total))
			throw InvalidInputError(path + ": vertex " + std::to_string(source) +
									" has no skin weight (its weights sum to " + number(total) + ")");
		for (const auto& [bone, w] : weights[std::size_t(source)])
			if (w > 0.0)
			{
				rig.weightBone.push_back(bone);
				rig.weight.push_back(w / total);
			}
		rig.weightStart.push_back(int(rig.weightBone.size()));
	}
}

/// Keys of one kind: times in seconds, values checked finite and in time order.
template <typename Key, typename Value, typename Convert>
void readKeys(const Key* keys, unsigned count, double ticksPerSecond, const std::string& what,
			  std::vector<double>& times, std::vector<Value>& values, Convert convert)
{
	for (unsigned k = 0; k < count; ++k)
	{
		const double t = keys[k].mTime / ticksPerSecond;
		bool ok = false;
		const Value v = convert(keys[k].mValue, ok);
		if (!std::isfinite(t) || !ok)
			throw InvalidInputError(what + " key " + std::to_string(k) + " is not finite");
		if (!times.empty() && t < times.back())
			throw InvalidInputError(what + " key " + std::to_string(k) + " is earlier than the key before it");
		times.push_back(t);
		values.push_back(v);
	}
}

AnimationClip readClip(const aiAnimation* anim, unsigned index, const std::string& path,
					   const std::map<std::string, int>& boneByName)
{
	AnimationClip clip;
	clip.name = anim->mName.length > 0 ? std::string(anim->mName.C_Str()) : "clip " + std::to_string(index);
	const std::string where = path + ": clip " + quoted(clip.name);
	clip.ticksPerSecond = anim->mTicksPerSecond != 0.0 ? anim->mTicksPerSecond : 25.0; // assimp's documented default
	if (!(clip.ticksPerSecond > 0.0) || !std::isfinite(clip.ticksPerSecond))
		throw InvalidInputError(where + ": ticks per second " + number(anim->mTicksPerSecond) + " is not usable");
	clip.duration = anim->mDuration / clip.ticksPerSecond;
	if (!std::isfinite(clip.duration))
		throw InvalidInputError(where + ": duration is not finite");
	if (!(clip.duration > 0.0))
		throw InvalidInputError(where + ": zero duration (" + number(anim->mDuration) + " ticks)");
	auto vec = [](const aiVector3D& v, bool& ok) {
		ok = std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
		return Eigen::Vector3d(v.x, v.y, v.z);
	};
	auto quat = [](const aiQuaternion& q, bool& ok) {
		Eigen::Quaterniond e(q.w, q.x, q.y, q.z);
		ok = e.coeffs().allFinite() && e.norm() > 1e-12;
		return ok ? e.normalized() : e;
	};
	for (unsigned c = 0; c < anim->mNumChannels; ++c)
	{
		const aiNodeAnim* na = anim->mChannels[c];
		const auto it = boneByName.find(na->mNodeName.C_Str());
		if (it == boneByName.end())
			continue; // a node that moves no bone
		BoneChannel ch;
		ch.bone = it->second;
		const std::string what = where + ": channel " + quoted(na->mNodeName.C_Str());
		readKeys(na->mPositionKeys, na->mNumPositionKeys, clip.ticksPerSecond, what + ": position", ch.positionTimes,
				 ch.positions, vec);
		readKeys(na->mRotationKeys, na->mNumRotationKeys, clip.ticksPerSecond, what + ": rotation", ch.rotationTimes,
				 ch.rotations, quat);
		readKeys(na->mScalingKeys, na->mNumScalingKeys, clip.ticksPerSecond, what + ": scale", ch.scaleTimes,
				 ch.scales, vec);
		clip.channels.push_back(std::move(ch));
	}
	return clip;
}

} // namespace

bool hasSkinnedMesh(const std::string& path)
{
	// Formats without skeletons are not read twice (the static loader reads them anyway).
	std::string ext = path.substr(std::min(path.size(), path.find_last_of('.') + 1));
	std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
	if (path.find('.') != std::string::npos && (ext == "obj" || ext == "ply" || ext == "stl" || ext == "off"))
		return false;
	Assimp::Importer importer;
	const aiScene* scene = readCheckedScene(importer, path, 0);
	for (unsigned m = 0; m < scene->mNumMeshes; ++m)
		if (scene->mMeshes[m]->mNumBones > 0)
			return true;
	return false;
}

Rig loadRig(const std::string& path, const RigLoadOptions& options)
{
	Rig rig;
	rig.path = path;
	rig.conversion = conversionOf(options.mesh);
	Assimp::Importer importer;
	const aiScene* scene = readCheckedScene(importer, path, aiProcess_Triangulate | aiProcess_SortByPType);
	if (scene->mRootNode == nullptr || scene->mNumMeshes == 0)
		throw InvalidInputError(path + ": no skinned mesh (the file has no mesh)");
	const aiMesh* mesh = scene->mMeshes[pickSkinnedMesh(scene, path, options.meshName)];
	rig.meshName = mesh->mName.C_Str();
	std::map<const aiNode*, int> boneOfNode;
	collectSkeleton(scene, mesh, path, rig, boneOfNode);
	const std::vector<std::map<int, double>> weights = readWeights(scene, mesh, path, rig, boneOfNode);
	rig.restFrame = restFrameOfSkin(rig, path);
	buildBindMesh(mesh, weights, options, path, rig);

	std::map<std::string, int> boneByName;
	for (std::size_t b = 0; b < rig.bones.size(); ++b)
		boneByName.emplace(rig.bones[b].name, int(b));
	for (unsigned a = 0; a < scene->mNumAnimations; ++a)
		rig.clips.push_back(readClip(scene->mAnimations[a], a, path, boneByName));
	if (options.requireAnimation && rig.clips.empty())
		throw InvalidInputError(path + ": no animation (the rig has no clip)");
	return rig;
}

const AnimationClip& requireClip(const Rig& rig, const std::string& name)
{
	const int index = rig.findClip(name);
	if (index >= 0)
		return rig.clips[std::size_t(index)];
	std::string names;
	for (const AnimationClip& c : rig.clips)
		names += (names.empty() ? "" : ", ") + quoted(c.name);
	throw InvalidInputError(rig.path + ": unknown clip " + quoted(name) + " (clips: " +
							(names.empty() ? std::string("none") : names) + ")");
}

} // namespace bodyfit
