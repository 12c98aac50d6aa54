#pragma once
// Writes small rigged glTF 2.0 files for the loader tests: one skinned triangle mesh, a joint hierarchy with rest
// transforms, inverse bind matrices and animation channels (LINEAR), all in one .gltf + .bin pair.
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
#include <unistd.h>

namespace bodyfit_test
{

struct GltfJoint
{
	std::string name;
	int parent = -1; ///< index into the joint list, -1: child of the scene root
	Eigen::Vector3f translation = Eigen::Vector3f::Zero();
	Eigen::Quaternionf rotation = Eigen::Quaternionf::Identity(); ///< rest rotation
};

struct GltfChannel
{
	int joint = 0;
	std::string path; ///< "translation", "rotation" or "scale"
	std::vector<float> times; ///< seconds
	std::vector<float> values; ///< 3 (translation, scale) or 4 (rotation x, y, z, w) floats per key
};

struct GltfClip
{
	std::string name;
	std::vector<GltfChannel> channels;
};

struct GltfRig
{
	std::vector<Eigen::Vector3f> positions;
	std::vector<std::uint32_t> indices;
	std::vector<std::array<std::uint16_t, 4>> joints0, joints1; ///< joints1/weights1 optional (> 4 influences)
	std::vector<std::array<float, 4>> weights0, weights1;
	bool skinned = true;
	std::vector<GltfJoint> joints;
	std::vector<Eigen::Matrix4f> inverseBind; ///< one per joint
	std::vector<GltfClip> clips;
	bool hat = false; ///< also a second skinned mesh "hat" (a tetrahedron on joint 0, fewer vertices than the body)
	/// An "Armature" node above the root joints, as Blender and Mixamo export: not a joint, its transform is part of
	/// every joint's world transform (and of the mesh node's, which skinning ignores).
	bool armature = false;
	Eigen::Vector3f armatureTranslation = Eigen::Vector3f::Zero();
	Eigen::Quaternionf armatureRotation = Eigen::Quaternionf::Identity();
	Eigen::Vector3f armatureScale = Eigen::Vector3f::Ones();
};

/// `rig` as Blender exports a Mixamo character: every length in centimetres (vertices, joint offsets, inverse bind
/// translations, animated translations) under an "Armature" node at 0.01 (`scale` per axis, which may mirror) that
/// turns by `rotation` and moves by `translation`: every pose draws as that node's image of the metre pose.
inline GltfRig inCentimetresUnderArmature(GltfRig rig, const Eigen::Quaternionf& rotation, const Eigen::Vector3f& scale,
										  const Eigen::Vector3f& translation = Eigen::Vector3f::Zero())
{
	for (Eigen::Vector3f& p : rig.positions)
		p *= 100.0f;
	for (GltfJoint& j : rig.joints)
		j.translation *= 100.0f;
	for (Eigen::Matrix4f& m : rig.inverseBind)
		m.block<3, 1>(0, 3) *= 100.0f;
	for (GltfClip& clip : rig.clips)
		for (GltfChannel& ch : clip.channels)
			if (ch.path == "translation")
				for (float& v : ch.values)
					v *= 100.0f;
	rig.armature = true;
	rig.armatureTranslation = translation;
	rig.armatureRotation = rotation;
	rig.armatureScale = scale;
	return rig;
}

/// Writes `rig` as DIR/NAME.gltf (+ NAME.bin) and returns the .gltf path.
inline std::string writeGltfRig(const GltfRig& rig, const std::string& name)
{
	using Json = nlohmann::json;
	const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("bodyfit_test_rigs_" + std::to_string(long(::getpid()))); // per process: ctest runs tests in parallel
	std::filesystem::create_directories(dir);
	std::vector<unsigned char> bin;
	Json views = Json::array(), accessors = Json::array();
	// Appends raw data as a buffer view + accessor; returns the accessor index.
	auto add = [&](const void* data, std::size_t bytes, int componentType, const char* type, std::size_t count,
				   Json extra = Json::object()) {
		while (bin.size() % 4 != 0)
			bin.push_back(0);
		const std::size_t offset = bin.size();
		bin.resize(offset + bytes);
		std::memcpy(bin.data() + offset, data, bytes);
		views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}});
		Json a = {{"bufferView", views.size() - 1}, {"componentType", componentType}, {"count", count}, {"type", type}};
		a.update(extra);
		accessors.push_back(a);
		return int(accessors.size() - 1);
	};
	constexpr int kFloat = 5126, kUShort = 5123, kUInt = 5125;
	Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = Eigen::Vector3f::Constant(-1e30f);
	for (const Eigen::Vector3f& p : rig.positions)
	{
		lo = lo.cwiseMin(p);
		hi = hi.cwiseMax(p);
	}
	Json attributes;
	attributes["POSITION"] = add(rig.positions.data(), rig.positions.size() * 12, kFloat, "VEC3", rig.positions.size(),
								 {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}});
	if (rig.skinned)
	{
		attributes["JOINTS_0"] = add(rig.joints0.data(), rig.joints0.size() * 8, kUShort, "VEC4", rig.joints0.size());
		attributes["WEIGHTS_0"] = add(rig.weights0.data(), rig.weights0.size() * 16, kFloat, "VEC4", rig.weights0.size());
		if (!rig.joints1.empty())
		{
			attributes["JOINTS_1"] = add(rig.joints1.data(), rig.joints1.size() * 8, kUShort, "VEC4", rig.joints1.size());
			attributes["WEIGHTS_1"] =
				add(rig.weights1.data(), rig.weights1.size() * 16, kFloat, "VEC4", rig.weights1.size());
		}
	}
	const int indices = add(rig.indices.data(), rig.indices.size() * 4, kUInt, "SCALAR", rig.indices.size());
	Json doc;
	doc["asset"] = {{"version", "2.0"}};
	doc["meshes"] = Json::array({{{"name", "body"}, {"primitives", Json::array({{{"attributes", attributes}, {"indices", indices}, {"mode", 4}}})}}});
	if (rig.hat)
	{
		const std::vector<float> p = {0, 2.1f, 0, 0.1f, 2.1f, 0, 0, 2.2f, 0, 0, 2.1f, 0.1f};
		const std::vector<std::uint16_t> j(16, 0);
		const std::vector<float> w = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
		const std::vector<std::uint32_t> f = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
		Json a;
		a["POSITION"] = add(p.data(), p.size() * 4, kFloat, "VEC3", 4, {{"min", {0, 2.1, 0}}, {"max", {0.1, 2.2, 0.1}}});
		a["JOINTS_0"] = add(j.data(), j.size() * 2, kUShort, "VEC4", 4);
		a["WEIGHTS_0"] = add(w.data(), w.size() * 4, kFloat, "VEC4", 4);
		const int hatIndices = add(f.data(), f.size() * 4, kUInt, "SCALAR", f.size());
		doc["meshes"].push_back({{"name", "hat"}, {"primitives", Json::array({{{"attributes", a}, {"indices", hatIndices}, {"mode", 4}}})}});
	}
	// Nodes: 0 = the mesh, 1.. = the joints, then the hat.
	Json nodes = Json::array();
	Json meshNode = {{"name", "body"}, {"mesh", 0}};
	if (rig.skinned)
		meshNode["skin"] = 0;
	nodes.push_back(meshNode);
	std::vector<std::vector<int>> children(rig.joints.size());
	Json roots = Json::array({0});
	for (std::size_t j = 0; j < rig.joints.size(); ++j)
	{
		const GltfJoint& g = rig.joints[j];
		nodes.push_back({{"name", g.name},
						 {"translation", {g.translation.x(), g.translation.y(), g.translation.z()}},
						 {"rotation", {g.rotation.x(), g.rotation.y(), g.rotation.z(), g.rotation.w()}}});
		if (g.parent < 0)
			roots.push_back(int(j) + 1);
		else
			children[std::size_t(g.parent)].push_back(int(j) + 1);
	}
	for (std::size_t j = 0; j < rig.joints.size(); ++j)
		if (!children[j].empty())
			nodes[j + 1]["children"] = children[j];
	if (rig.armature)
	{
		Json rootJoints = Json::array(), rest = Json::array();
		for (const Json& r : roots)
			(r.get<int>() == 0 ? rest : rootJoints).push_back(r);
		const Eigen::Vector3f& t = rig.armatureTranslation;
		const Eigen::Quaternionf& q = rig.armatureRotation;
		const Eigen::Vector3f& sc = rig.armatureScale;
		nodes.push_back({{"name", "Armature"}, {"translation", {t.x(), t.y(), t.z()}}, {"rotation", {q.x(), q.y(), q.z(), q.w()}},
						 {"scale", {sc.x(), sc.y(), sc.z()}}, {"children", rootJoints}});
		rest.push_back(int(nodes.size()) - 1);
		roots = rest;
	}
	if (rig.hat)
	{
		nodes.push_back({{"name", "hat"}, {"mesh", 1}, {"skin", 0}});
		roots.push_back(int(nodes.size()) - 1);
	}
	doc["nodes"] = nodes;
	doc["scenes"] = Json::array({{{"nodes", roots}}});
	doc["scene"] = 0;
	if (rig.skinned)
	{
		std::vector<float> ibm;
		for (const Eigen::Matrix4f& m : rig.inverseBind)
			for (int k = 0; k < 16; ++k)
				ibm.push_back(m.data()[k]); // column-major, as glTF stores matrices
		Json jointList = Json::array();
		for (std::size_t j = 0; j < rig.joints.size(); ++j)
			jointList.push_back(int(j) + 1);
		const int ibmAccessor = add(ibm.data(), ibm.size() * 4, kFloat, "MAT4", rig.inverseBind.size());
		doc["skins"] = Json::array({{{"joints", jointList}, {"inverseBindMatrices", ibmAccessor}}});
	}
	Json animations = Json::array();
	for (const GltfClip& clip : rig.clips)
	{
		Json samplers = Json::array(), channels = Json::array();
		for (const GltfChannel& ch : clip.channels)
		{
			const float tmin = ch.times.empty() ? 0.0f : ch.times.front(), tmax = ch.times.empty() ? 0.0f : ch.times.back();
			const int in = add(ch.times.data(), ch.times.size() * 4, kFloat, "SCALAR", ch.times.size(),
							   {{"min", {tmin}}, {"max", {tmax}}});
			const bool rotation = ch.path == "rotation";
			const int out = add(ch.values.data(), ch.values.size() * 4, kFloat, rotation ? "VEC4" : "VEC3", ch.times.size());
			samplers.push_back({{"input", in}, {"output", out}, {"interpolation", "LINEAR"}});
			channels.push_back({{"sampler", samplers.size() - 1}, {"target", {{"node", ch.joint + 1}, {"path", ch.path}}}});
		}
		animations.push_back({{"name", clip.name}, {"samplers", samplers}, {"channels", channels}});
	}
	if (!animations.empty())
		doc["animations"] = animations;
	doc["accessors"] = accessors;
	doc["bufferViews"] = views;
	doc["buffers"] = Json::array({{{"uri", name + ".bin"}, {"byteLength", bin.size()}}});
	std::ofstream(dir / (name + ".bin"), std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
	const std::string path = (dir / (name + ".gltf")).string();
	std::ofstream(path) << doc.dump(1);
	return path;
}

} // namespace bodyfit_test
