// Posing a rig (key interpolation down the bone hierarchy) and linear blend skinning. See rig.h.
#include "bodyfit/fitting/rig.h"

#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <cmath>

namespace bodyfit
{

namespace
{

/// Segment of `times` around t and the blend factor: value = (1 - a) keys[k] + a keys[k + 1]; held outside.
struct KeySpan
{
	std::size_t k = 0, next = 0;
	double a = 0.0;
};

KeySpan span(const std::vector<double>& times, double t)
{
	if (times.size() <= 1 || t <= times.front())
		return {0, 0, 0.0};
	if (t >= times.back())
		return {times.size() - 1, times.size() - 1, 0.0};
	const std::size_t next = std::size_t(std::upper_bound(times.begin(), times.end(), t) - times.begin());
	const std::size_t k = next - 1;
	const double dt = times[next] - times[k];
	return {k, next, dt > 0.0 ? (t - times[k]) / dt : 1.0};
}

Eigen::Vector3d lerpKeys(const std::vector<double>& times, const std::vector<Eigen::Vector3d>& keys, double t)
{
	const KeySpan s = span(times, t);
	return (1.0 - s.a) * keys[s.k] + s.a * keys[s.next];
}

/// Local transform of an animated bone: translation * rotation * scale; a kind without keys keeps the rest value.
Eigen::Affine3d channelLocal(const BoneChannel& ch, const Eigen::Affine3d& rest, double t)
{
	Eigen::Matrix3d restRotation, restScaling;
	rest.computeRotationScaling(&restRotation, &restScaling);
	const Eigen::Vector3d translation = ch.positions.empty() ? rest.translation() : lerpKeys(ch.positionTimes, ch.positions, t);
	const Eigen::Vector3d scale = ch.scales.empty() ? restScaling.diagonal() : lerpKeys(ch.scaleTimes, ch.scales, t);
	Eigen::Quaterniond rotation(restRotation);
	if (!ch.rotations.empty())
	{
		const KeySpan s = span(ch.rotationTimes, t);
		rotation = ch.rotations[s.k].slerp(s.a, ch.rotations[s.next]).normalized();
	}
	Eigen::Affine3d local = Eigen::Affine3d::Identity();
	local.linear() = rotation.toRotationMatrix() * scale.asDiagonal();
	local.translation() = translation;
	return local;
}

std::vector<Eigen::Affine3d> worldFromLocals(const Rig& rig, const std::vector<Eigen::Affine3d>& local)
{
	std::vector<Eigen::Affine3d> world(rig.bones.size());
	for (std::size_t b = 0; b < rig.bones.size(); ++b)
	{
		const int parent = rig.bones[b].parent;
		world[b] = (parent < 0 ? rig.conversion : world[std::size_t(parent)]) * local[b];
	}
	return world;
}

} // namespace

std::vector<Eigen::Affine3d> poseBones(const Rig& rig, const AnimationClip& clip, double t)
{
	// NaN passes std::clamp and every comparison of the key search, which then read past the keys.
	if (std::isnan(t))
		throw InvalidInputError("poseBones: the clip time is NaN (clip '" + clip.name + "')");
	t = std::clamp(t, 0.0, clip.duration);
	std::vector<Eigen::Affine3d> local(rig.bones.size());
	for (std::size_t b = 0; b < rig.bones.size(); ++b)
		local[b] = rig.bones[b].restLocal;
	for (const BoneChannel& ch : clip.channels)
		local[std::size_t(ch.bone)] = channelLocal(ch, rig.bones[std::size_t(ch.bone)].restLocal, t);
	return worldFromLocals(rig, local);
}

std::vector<Eigen::Affine3d> restPoseBones(const Rig& rig)
{
	std::vector<Eigen::Affine3d> local(rig.bones.size());
	for (std::size_t b = 0; b < rig.bones.size(); ++b)
		local[b] = rig.bones[b].restLocal;
	return worldFromLocals(rig, local);
}

std::vector<Eigen::Affine3d> bindPoseBones(const Rig& rig)
{
	std::vector<Eigen::Affine3d> world = restPoseBones(rig);
	for (std::size_t b = 0; b < rig.bones.size(); ++b)
		if (rig.bones[b].deforms)
			world[b] = rig.bones[b].inverseBind.inverse();
	return world;
}

std::vector<Eigen::Affine3d> skinningMatrices(const Rig& rig, const std::vector<Eigen::Affine3d>& boneWorld)
{
	std::vector<Eigen::Affine3d> skin(rig.bones.size());
	for (std::size_t b = 0; b < rig.bones.size(); ++b)
		skin[b] = rig.bones[b].deforms ? Eigen::Affine3d(boneWorld[b] * rig.bones[b].inverseBind)
									   : Eigen::Affine3d::Identity();
	return skin;
}

void skinVertices(const Rig& rig, const std::vector<Eigen::Affine3d>& skinning, Eigen::MatrixX3d& out)
{
	const Eigen::MatrixX3d& V = rig.bindMesh.V;
	out.resize(V.rows(), 3);
	for (Eigen::Index v = 0; v < V.rows(); ++v)
	{
		const Eigen::Vector3d p = V.row(v).transpose();
		Eigen::Vector3d sum = Eigen::Vector3d::Zero();
		for (int k = rig.weightStart[std::size_t(v)]; k < rig.weightStart[std::size_t(v) + 1]; ++k)
		{
			const Eigen::Affine3d& S = skinning[std::size_t(rig.weightBone[std::size_t(k)])];
			sum += rig.weight[std::size_t(k)] * (S.linear() * p + S.translation());
		}
		out.row(v) = sum.transpose();
	}
}

} // namespace bodyfit
