#include "bodyfit/drape/gltf_animation.h"

#include "bodyfit/fitting/errors.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>

namespace bodyfit::drape
{
namespace
{

using nlohmann::json;

constexpr int kFloat = 5126;        // glTF componentType FLOAT
constexpr int kUnsignedInt = 5125;  // UNSIGNED_INT
constexpr int kArrayBuffer = 34962; // bufferView target: vertex attributes
constexpr int kElementArrayBuffer = 34963;

/// The BIN chunk and its buffer views / accessors, built together.
class BinaryBuilder
{
public:
	explicit BinaryBuilder(json& doc) : doc_(doc)
	{
		doc_["bufferViews"] = json::array();
		doc_["accessors"] = json::array();
	}

	/// A buffer view of `bytes` bytes (4-byte aligned, as every accessor here needs); target 0: none.
	int addView(const void* data, std::size_t bytes, int target)
	{
		while (bin_.size() % 4 != 0)
			bin_.push_back('\0');
		json view = {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", bytes}};
		if (target != 0)
			view["target"] = target;
		bin_.append(static_cast<const char*>(data), bytes);
		doc_["bufferViews"].push_back(view);
		return int(doc_["bufferViews"].size()) - 1;
	}

	int addAccessor(int view, int componentType, std::size_t count, const char* type, json extra = json::object())
	{
		json a = {{"bufferView", view}, {"componentType", componentType}, {"count", count}, {"type", type}};
		a.update(extra);
		doc_["accessors"].push_back(a);
		return int(doc_["accessors"].size()) - 1;
	}

	/// VEC3 float positions with the min/max that glTF requires of POSITION.
	int addPositions(const std::vector<float>& xyz)
	{
		std::vector<float> lo(3, INFINITY), hi(3, -INFINITY);
		for (std::size_t i = 0; i < xyz.size(); ++i)
		{
			lo[i % 3] = std::min(lo[i % 3], xyz[i]);
			hi[i % 3] = std::max(hi[i % 3], xyz[i]);
		}
		const int view = addView(xyz.data(), xyz.size() * sizeof(float), kArrayBuffer);
		return addAccessor(view, kFloat, xyz.size() / 3, "VEC3", {{"min", lo}, {"max", hi}});
	}

	/// Animation data (no buffer-view target): SCALAR times with min/max (required of sampler inputs) or VEC3 values.
	int addKeys(const std::vector<float>& values, const char* type)
	{
		const int view = addView(values.data(), values.size() * sizeof(float), 0);
		const std::size_t width = std::strcmp(type, "VEC3") == 0 ? 3 : 1;
		json extra = json::object();
		if (width == 1)
			extra = {{"min", {values.front()}}, {"max", {values.back()}}};
		return addAccessor(view, kFloat, values.size() / width, type, extra);
	}

	const std::string& bin() const { return bin_; }

private:
	json& doc_;
	std::string bin_;
};

/// STEP keys of frame f's scale: 1 from its time until the next frame's, 0 before and after.
void frameScaleKeys(const std::vector<double>& times, std::size_t f, std::vector<float>& keyTimes,
					std::vector<float>& scales)
{
	keyTimes.clear();
	scales.clear();
	auto key = [&](double t, float s) {
		keyTimes.push_back(float(t));
		scales.insert(scales.end(), {s, s, s});
	};
	if (f > 0)
		key(times.front(), 0.0f);
	key(times[f], 1.0f);
	if (f + 1 < times.size())
		key(times[f + 1], 0.0f);
}

void appendChunk(std::string& out, const std::string& payload, std::uint32_t type, char pad)
{
	std::string data = payload;
	while (data.size() % 4 != 0)
		data.push_back(pad);
	const std::uint32_t header[2] = {std::uint32_t(data.size()), type};
	out.append(reinterpret_cast<const char*>(header), sizeof header);
	out += data;
}

} // namespace

GltfAnimationRecorder::GltfAnimationRecorder(std::vector<GltfPart> parts) : parts_(std::move(parts))
{
	if (parts_.empty())
		throw InvalidInputError("glTF animation: no parts to draw");
	for (const GltfPart& p : parts_)
		if (p.faces.rows() == 0 || p.faces.minCoeff() < 0)
			throw InvalidInputError("glTF animation: part '" + p.name + "' has no faces or a negative face index");
}

void GltfAnimationRecorder::addFrame(double time, const std::vector<const Eigen::MatrixX3d*>& vertices)
{
	if (!std::isfinite(time) || (!times_.empty() && !(time > times_.back())))
		throw InvalidInputError("glTF animation: frame time " + std::to_string(time) +
								" s is not after the previous frame's");
	if (vertices.size() != parts_.size())
		throw InvalidInputError("glTF animation: " + std::to_string(vertices.size()) + " vertex arrays for " +
								std::to_string(parts_.size()) + " parts");
	std::vector<std::vector<float>> frame(parts_.size());
	for (std::size_t p = 0; p < parts_.size(); ++p)
	{
		const Eigen::MatrixX3d& V = *vertices[p];
		if (parts_[p].faces.maxCoeff() >= V.rows() || !V.allFinite())
			throw InvalidInputError("glTF animation: part '" + parts_[p].name +
									"': non-finite coordinates or fewer vertices than its faces use");
		frame[p].reserve(std::size_t(V.rows()) * 3);
		for (int i = 0; i < V.rows(); ++i)
			for (int k = 0; k < 3; ++k)
				frame[p].push_back(float(V(i, k)));
	}
	times_.push_back(time);
	positions_.push_back(std::move(frame));
}

std::string GltfAnimationRecorder::glb() const
{
	if (times_.empty())
		throw InvalidInputError("glTF animation: no frame recorded");
	json doc;
	doc["asset"] = {{"version", "2.0"}, {"generator", "bodyfit-drape (bodyfit/drape/gltf_animation.h)"}};
	BinaryBuilder bin(doc);
	doc["materials"] = json::array();
	std::vector<int> indexAccessor;
	for (const GltfPart& p : parts_)
	{
		doc["materials"].push_back({{"name", p.name},
									{"doubleSided", p.doubleSided},
									{"pbrMetallicRoughness",
									 {{"baseColorFactor", {p.color.x(), p.color.y(), p.color.z(), 1.0f}},
									  {"metallicFactor", 0.0f},
									  {"roughnessFactor", 0.8f}}}});
		std::vector<std::uint32_t> idx(std::size_t(p.faces.rows()) * 3);
		for (int f = 0; f < p.faces.rows(); ++f)
			for (int k = 0; k < 3; ++k)
				idx[std::size_t(f) * 3 + std::size_t(k)] = std::uint32_t(p.faces(f, k));
		const int view = bin.addView(idx.data(), idx.size() * sizeof(std::uint32_t), kElementArrayBuffer);
		indexAccessor.push_back(bin.addAccessor(view, kUnsignedInt, idx.size(), "SCALAR"));
	}
	doc["meshes"] = json::array();
	doc["nodes"] = json::array();
	json children = json::array(), samplers = json::array(), channels = json::array();
	std::vector<float> keyTimes, scales;
	for (std::size_t f = 0; f < times_.size(); ++f)
	{
		json primitives = json::array();
		for (std::size_t p = 0; p < parts_.size(); ++p)
			primitives.push_back({{"attributes", {{"POSITION", bin.addPositions(positions_[f][p])}}},
								  {"indices", indexAccessor[p]},
								  {"material", p}});
		doc["meshes"].push_back({{"name", "frame " + std::to_string(f)}, {"primitives", primitives}});
		const float s = f == 0 ? 1.0f : 0.0f;
		doc["nodes"].push_back({{"name", "frame " + std::to_string(f) + " (t = " + std::to_string(times_[f]) + " s)"},
								{"mesh", f},
								{"scale", {s, s, s}}});
		children.push_back(f);
		if (times_.size() < 2)
			continue;
		frameScaleKeys(times_, f, keyTimes, scales);
		samplers.push_back(
			{{"input", bin.addKeys(keyTimes, "SCALAR")}, {"output", bin.addKeys(scales, "VEC3")}, {"interpolation", "STEP"}});
		channels.push_back({{"sampler", samplers.size() - 1}, {"target", {{"node", f}, {"path", "scale"}}}});
	}
	doc["nodes"].push_back({{"name", "drape"}, {"children", children}});
	doc["scenes"] = json::array({{{"nodes", {times_.size()}}}});
	doc["scene"] = 0;
	if (!channels.empty())
		doc["animations"] = json::array({{{"name", "drape"}, {"samplers", samplers}, {"channels", channels}}});
	doc["buffers"] = json::array({{{"byteLength", bin.bin().size()}}});

	std::string out;
	const std::uint32_t header[3] = {0x46546C67u /* "glTF" */, 2u, 0u};
	out.append(reinterpret_cast<const char*>(header), sizeof header);
	appendChunk(out, doc.dump(), 0x4E4F534Au /* "JSON" */, ' ');
	appendChunk(out, bin.bin(), 0x004E4942u /* "BIN" */, '\0');
	const std::uint32_t total = std::uint32_t(out.size());
	std::memcpy(&out[8], &total, sizeof total);
	return out;
}

void GltfAnimationRecorder::writeGlb(const std::string& path) const
{
	const std::string data = glb();
	std::ofstream out(path, std::ios::binary);
	if (!out)
		throw MeshLoadError(path + ": cannot open for writing");
	out.write(data.data(), std::streamsize(data.size()));
	if (!out)
		throw MeshLoadError(path + ": write failed");
}

} // namespace bodyfit::drape
