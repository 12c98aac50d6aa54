// The "skinning" section of a fit file (skinned_fit.h): write, parse with one-line errors, check against a rig.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/skinned_fit.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace bodyfit
{

namespace
{

using Json = nlohmann::ordered_json;

/// Field-naming failures of the section: "<name>: skinning.<field>: <problem>".
struct SectionReader
{
	std::string name;

	[[noreturn]] void fail(const std::string& field, const std::string& problem) const
	{
		throw FormatError(name + ": skinning" + (field.empty() ? "" : "." + field) + ": " + problem);
	}
	const Json& get(const Json& obj, const char* key, const std::string& prefix) const
	{
		const std::string field = prefix.empty() ? std::string(key) : prefix + "." + key;
		if (!obj.is_object() || !obj.contains(key))
			fail(field, "missing");
		return obj[key];
	}
	int integer(const Json& v, const std::string& field, long long lo, long long hi) const
	{
		if (!v.is_number_integer() || v.get<long long>() < lo || v.get<long long>() > hi)
			fail(field, "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
		return int(v.get<long long>());
	}
	double number(const Json& v, const std::string& field) const
	{
		if (!v.is_number() || !std::isfinite(v.get<double>()))
			fail(field, "must be a finite number");
		return v.get<double>();
	}
	const Json& array(const Json& v, const std::string& field, std::size_t size) const
	{
		if (!v.is_array() || (size != std::size_t(-1) && v.size() != size))
			fail(field, size == std::size_t(-1) ? "must be an array" : "must be an array of " + std::to_string(size));
		return v;
	}
};

Json matrixJson(const Eigen::Affine3d& m)
{
	Json a = Json::array();
	for (int r = 0; r < 3; ++r)
		for (int c = 0; c < 4; ++c)
			a.push_back(m.matrix()(r, c));
	return a;
}

SkinBinding::BoneRecord readBone(const SectionReader& r, const Json& j, int index)
{
	const std::string field = "bones[" + std::to_string(index) + "]";
	SkinBinding::BoneRecord b;
	const Json& name = r.get(j, "name", field);
	if (!name.is_string())
		r.fail(field + ".name", "must be a string");
	b.name = name.get<std::string>();
	b.parent = r.integer(r.get(j, "parent", field), field + ".parent", -1, index - 1); // parents come first
	if (j.contains("inverse_bind"))
	{
		const Json& m = r.array(j["inverse_bind"], field + ".inverse_bind", 12);
		for (int k = 0; k < 12; ++k)
			b.inverseBind.matrix()(k / 4, k % 4) = r.number(m[std::size_t(k)], field + ".inverse_bind[" + std::to_string(k) + "]");
		b.deforms = true;
	}
	return b;
}

EllipsoidBinding readEllipsoidBinding(const SectionReader& r, const Json& j, int index, int boneCount)
{
	const std::string field = "ellipsoids[" + std::to_string(index) + "]";
	EllipsoidBinding e;
	const Json& mode = r.get(j, "mode", field);
	if (mode != "rigid" && mode != "refit")
		r.fail(field + ".mode", "must be \"rigid\" or \"refit\"");
	e.mode = mode == "rigid" ? EllipsoidMotion::Rigid : EllipsoidMotion::Refit;
	const Json& bones = r.array(r.get(j, "bones", field), field + ".bones", std::size_t(-1));
	for (std::size_t k = 0; k < bones.size(); ++k)
		e.bones.push_back(r.integer(bones[k], field + ".bones[" + std::to_string(k) + "]", 0, boneCount - 1));
	return e;
}

} // namespace

std::string skinBindingJson(const SkinBinding& b)
{
	Json s;
	s["version"] = b.version;
	s["mesh"] = {{"name", b.mesh}, {"vertices", b.vertices}, {"faces", b.faces}};
	Json bones = Json::array();
	for (const SkinBinding::BoneRecord& bone : b.bones)
	{
		Json j = {{"name", bone.name}, {"parent", bone.parent}};
		if (bone.deforms)
			j["inverse_bind"] = matrixJson(bone.inverseBind); // rows of the 3x4 affine part
		bones.push_back(std::move(j));
	}
	s["bones"] = std::move(bones);
	s["cover_spacing"] = b.coverSpacing;
	s["points"] = {{"vertices", b.vertexPoints}, {"cover", b.coverPoints}};
	Json ellipsoids = Json::array();
	for (const EllipsoidBinding& e : b.ellipsoids)
		ellipsoids.push_back({{"mode", toString(e.mode)}, {"bones", e.bones}});
	s["ellipsoids"] = std::move(ellipsoids);
	s["vertex_ellipsoid"] = b.vertexEllipsoid;
	return s.dump();
}

std::shared_ptr<const SkinBinding> parseSkinBinding(const std::string& text, const std::string& name, int ellipsoidCount)
{
	const SectionReader r{name};
	const Json s = Json::parse(text, nullptr, false);
	if (!s.is_object())
		r.fail("", "must be an object");
	auto b = std::make_shared<SkinBinding>();
	b->version = r.integer(r.get(s, "version", ""), "version", 0, 1 << 30);
	if (b->version != kSkinBindingVersion)
		r.fail("version", "unsupported version " + std::to_string(b->version) + " (this build reads version " +
							  std::to_string(kSkinBindingVersion) + ")");
	const Json& mesh = r.get(s, "mesh", "");
	if (!r.get(mesh, "name", "mesh").is_string())
		r.fail("mesh.name", "must be a string");
	b->mesh = mesh["name"].get<std::string>();
	b->vertices = r.integer(r.get(mesh, "vertices", "mesh"), "mesh.vertices", 1, 1 << 30);
	b->faces = r.integer(r.get(mesh, "faces", "mesh"), "mesh.faces", 1, 1 << 30);
	const Json& bones = r.array(r.get(s, "bones", ""), "bones", std::size_t(-1));
	for (std::size_t i = 0; i < bones.size(); ++i)
		b->bones.push_back(readBone(r, bones[i], int(i)));
	b->coverSpacing = r.number(r.get(s, "cover_spacing", ""), "cover_spacing");
	// 0.1 mm: far below any useful piece size (the fitter's default is 0.3% of the height, ~5 mm), and it keeps a
	// hostile file from asking for the 64 x 64 pieces per triangle of the cap on every triangle for nothing.
	if (!(b->coverSpacing >= kMinCoverSpacing))
		r.fail("cover_spacing", "must be >= " + std::to_string(kMinCoverSpacing) + " m (got " + std::to_string(b->coverSpacing) + ")");
	const Json& points = r.get(s, "points", "");
	b->vertexPoints = r.integer(r.get(points, "vertices", "points"), "points.vertices", 0, 1 << 30);
	b->coverPoints = r.integer(r.get(points, "cover", "points"), "points.cover", 0, 1 << 30);
	const Json& ellipsoids = r.array(r.get(s, "ellipsoids", ""), "ellipsoids", std::size_t(ellipsoidCount));
	for (std::size_t i = 0; i < ellipsoids.size(); ++i)
		b->ellipsoids.push_back(readEllipsoidBinding(r, ellipsoids[i], int(i), int(b->bones.size())));
	const Json& owner = r.array(r.get(s, "vertex_ellipsoid", ""), "vertex_ellipsoid", std::size_t(b->vertices));
	for (std::size_t v = 0; v < owner.size(); ++v)
		b->vertexEllipsoid.push_back(r.integer(owner[v], "vertex_ellipsoid[" + std::to_string(v) + "]", -1, ellipsoidCount - 1));
	return b;
}

void checkBinding(const Rig& rig, const BodyFit& fit, const SkinBinding& recorded, const std::string& name)
{
	const SectionReader r{name};
	if (recorded.ellipsoids.size() != fit.ellipsoids.size())
		r.fail("ellipsoids", "has " + std::to_string(recorded.ellipsoids.size()) + " entries for " +
								 std::to_string(fit.ellipsoids.size()) + " ellipsoids");
	if (recorded.vertices != rig.bindMesh.vertexCount() || recorded.faces != rig.bindMesh.faceCount())
		r.fail("mesh", "the fit was made on a mesh of " + std::to_string(recorded.vertices) + " vertices, " +
						   std::to_string(recorded.faces) + " faces; the rig's has " +
						   std::to_string(rig.bindMesh.vertexCount()) + ", " + std::to_string(rig.bindMesh.faceCount()));
	if (int(recorded.bones.size()) != rig.boneCount())
		r.fail("bones", "the fit has " + std::to_string(recorded.bones.size()) + " bones, the rig " +
							std::to_string(rig.boneCount()));
	for (int i = 0; i < rig.boneCount(); ++i)
	{
		const SkinBinding::BoneRecord& a = recorded.bones[std::size_t(i)];
		const Bone& b = rig.bones[std::size_t(i)];
		const std::string field = "bones[" + std::to_string(i) + "]";
		if (a.name != b.name || a.parent != b.parent || a.deforms != b.deforms)
			r.fail(field, "'" + a.name + "' (parent " + std::to_string(a.parent) + ") does not match the rig's '" +
							  b.name + "' (parent " + std::to_string(b.parent) + ")");
		// Written with round-trip precision, so equal to the bit; 1e-9 admits files rewritten by other tools.
		if (a.deforms && !((a.inverseBind.matrix() - b.inverseBind.matrix()).cwiseAbs().maxCoeff() <= 1e-9))
			r.fail(field + ".inverse_bind", "does not match the rig's bind pose");
	}
	BodyFit labelled = fit;
	labelled.vertexEllipsoid = recorded.vertexEllipsoid;
	const SkinBinding again = bindSkin(rig, labelled, recorded.coverSpacing);
	for (std::size_t j = 0; j < again.ellipsoids.size(); ++j)
		if (again.ellipsoids[j].mode != recorded.ellipsoids[j].mode || again.ellipsoids[j].bones != recorded.ellipsoids[j].bones)
			r.fail("ellipsoids[" + std::to_string(j) + "]", "bones or mode do not match the rig's skin weights");
	if (again.vertexPoints != recorded.vertexPoints || again.coverPoints != recorded.coverPoints)
		r.fail("points", "the bound points do not match the rig and the ellipsoids (" + std::to_string(again.vertexPoints) +
							 " vertex, " + std::to_string(again.coverPoints) + " cover points recomputed)");
}

} // namespace bodyfit
