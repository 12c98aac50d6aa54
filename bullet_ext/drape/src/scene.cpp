#include "bodyfit/drape/scene.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/input_files.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace bodyfit::drape
{
namespace
{

using nlohmann::json;

const char* typeName(const json& j)
{
	switch (j.type())
	{
	case json::value_t::null:
		return "null";
	case json::value_t::object:
		return "an object";
	case json::value_t::array:
		return "an array";
	case json::value_t::string:
		return "a string";
	case json::value_t::boolean:
		return "a boolean";
	case json::value_t::number_integer:
	case json::value_t::number_unsigned:
	case json::value_t::number_float:
		return "a number";
	default:
		return "an unsupported value";
	}
}

std::string formatNumber(double v)
{
	std::ostringstream s;
	s << v;
	return s.str();
}

/// Reads one JSON object, remembering which keys were consumed so that `finish()` can reject unknown ones.
/// Every error names the file and the dotted key path.
class ObjectReader
{
public:
	ObjectReader(const json& j, std::string keyPath, const std::string& file, const std::string& baseDir)
		: j_(j), path_(std::move(keyPath)), file_(file), baseDir_(baseDir)
	{
		if (!j_.is_object())
			fail(path_, std::string("expected an object, got ") + typeName(j_));
	}

	[[noreturn]] void fail(const std::string& keyPath, const std::string& reason) const
	{
		throw FormatError(file_ + ": " + keyPath + ": " + reason);
	}

	std::string keyPath(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

	bool has(const std::string& key)
	{
		allowed_.insert(key);
		return j_.contains(key);
	}

	const json& get(const std::string& key)
	{
		allowed_.insert(key);
		if (!j_.contains(key))
			fail(keyPath(key), "required key is missing");
		return j_.at(key);
	}

	double number(const std::string& key, double def, double lo, double hi, bool loOpen = false)
	{
		if (!has(key))
			return def;
		return checkNumber(get(key), keyPath(key), lo, hi, loOpen);
	}

	double checkNumber(const json& v, const std::string& where, double lo, double hi, bool loOpen = false) const
	{
		if (!v.is_number())
			fail(where, std::string("expected a number, got ") + typeName(v));
		const double x = v.get<double>();
		if (!std::isfinite(x))
			fail(where, "expected a finite number");
		if ((loOpen ? x <= lo : x < lo) || x > hi)
			fail(where, "value " + formatNumber(x) + " is outside " + (loOpen ? "(" : "[") + formatNumber(lo) + ", " +
							formatNumber(hi) + "]");
		return x;
	}

	int integer(const std::string& key, int def, int lo, int hi)
	{
		if (!has(key))
			return def;
		return checkInteger(get(key), keyPath(key), lo, hi);
	}

	int checkInteger(const json& v, const std::string& where, int lo, int hi) const
	{
		if (!v.is_number_integer() && !v.is_number_unsigned())
			fail(where, std::string("expected an integer, got ") + (v.is_number() ? "a non-integral number " + v.dump() : typeName(v)));
		if (v.is_number_unsigned() && v.get<unsigned long long>() > (unsigned long long)hi) // >= 2^63: no long long
			fail(where, "value " + std::to_string(v.get<unsigned long long>()) + " is outside [" + std::to_string(lo) +
							", " + std::to_string(hi) + "]");
		const long long x = v.get<long long>();
		if (x < lo || x > hi)
			fail(where, "value " + std::to_string(x) + " is outside [" + std::to_string(lo) + ", " +
							std::to_string(hi) + "]");
		return int(x);
	}

	bool boolean(const std::string& key, bool def)
	{
		if (!has(key))
			return def;
		const json& v = get(key);
		if (!v.is_boolean())
			fail(keyPath(key), std::string("expected true or false, got ") + typeName(v));
		return v.get<bool>();
	}

	std::string string(const std::string& key, const std::string& def, const std::vector<std::string>& choices = {})
	{
		if (!has(key))
			return def;
		const json& v = get(key);
		if (!v.is_string())
			fail(keyPath(key), std::string("expected a string, got ") + typeName(v));
		const std::string s = v.get<std::string>();
		if (!choices.empty() && std::find(choices.begin(), choices.end(), s) == choices.end())
			fail(keyPath(key), "'" + s + "' is not one of " + join(choices));
		return s;
	}

	std::string requiredString(const std::string& key, const std::vector<std::string>& choices = {})
	{
		get(key);
		return string(key, "", choices);
	}

	/// A file path relative to the scene's directory; must exist.
	std::string file(const std::string& key)
	{
		const std::string s = requiredString(key);
		if (s.empty())
			fail(keyPath(key), "empty path");
		std::filesystem::path p(s);
		if (p.is_relative())
			p = std::filesystem::path(baseDir_) / p;
		p = p.lexically_normal();
		const std::string problem = inputFileProblem(p.string());
		if (!problem.empty())
			fail(keyPath(key), "file '" + p.string() + "' " + problem);
		return p.string();
	}

	Eigen::Vector3d vec3(const std::string& key, const Eigen::Vector3d& def, double lo = -kMaxSceneCoordinate,
						 double hi = kMaxSceneCoordinate)
	{
		if (!has(key))
			return def;
		const json& v = get(key);
		if (!v.is_array() || v.size() != 3)
			fail(keyPath(key), "expected an array of 3 numbers");
		Eigen::Vector3d r;
		for (int i = 0; i < 3; ++i)
			r[i] = checkNumber(v[i], keyPath(key) + "[" + std::to_string(i) + "]", lo, hi);
		return r;
	}

	Eigen::Vector2d vec2(const std::string& key, const Eigen::Vector2d& def, double lo, double hi, bool loOpen)
	{
		if (!has(key))
			return def;
		const json& v = get(key);
		if (!v.is_array() || v.size() != 2)
			fail(keyPath(key), "expected an array of 2 numbers");
		Eigen::Vector2d r;
		for (int i = 0; i < 2; ++i)
			r[i] = checkNumber(v[i], keyPath(key) + "[" + std::to_string(i) + "]", lo, hi, loOpen);
		return r;
	}

	Eigen::Vector2i ivec2(const std::string& key, const Eigen::Vector2i& def, int lo, int hi)
	{
		if (!has(key))
			return def;
		const json& v = get(key);
		if (!v.is_array() || v.size() != 2)
			fail(keyPath(key), "expected an array of 2 integers");
		return Eigen::Vector2i(checkInteger(v[0], keyPath(key) + "[0]", lo, hi),
							   checkInteger(v[1], keyPath(key) + "[1]", lo, hi));
	}

	ObjectReader child(const std::string& key) { return ObjectReader(get(key), keyPath(key), file_, baseDir_); }

	/// Rejects every key that no accessor asked about.
	void finish() const
	{
		for (auto it = j_.begin(); it != j_.end(); ++it)
			if (!allowed_.count(it.key()))
				fail(keyPath(it.key()), "unknown key (allowed here: " + join({allowed_.begin(), allowed_.end()}) + ")");
	}

	const std::string& path() const { return path_; }
	const std::string& fileName() const { return file_; }
	const std::string& baseDir() const { return baseDir_; }

	static std::string join(const std::vector<std::string>& items)
	{
		std::string s;
		for (const std::string& i : items)
			s += (s.empty() ? "" : ", ") + i;
		return s;
	}

private:
	const json& j_;
	std::string path_;
	const std::string& file_;
	const std::string& baseDir_;
	std::set<std::string> allowed_;
};

/// A cloth edge shorter than kMinClothEdge: float rounding of the spring lengths (edges of 1e-9 m made NaN nodes).
void requireClothEdge(ObjectReader& r, const std::string& key, double edge, const std::string& formula)
{
	if (edge < kMinClothEdge)
		r.fail(r.keyPath(key), formula + " = " + formatNumber(edge) + " m per cloth edge, less than " +
								   formatNumber(kMinClothEdge) + " m");
}

AnimationSpec parseAnimation(ObjectReader r)
{
	AnimationSpec a;
	a.file = r.file("file");
	if (r.has("clip"))
	{
		const json& c = r.get("clip");
		if (c.is_string())
		{
			a.clip = c.get<std::string>();
			if (a.clip.empty())
				r.fail(r.keyPath("clip"), "empty clip name");
		}
		else if (c.is_number())
			a.clip = std::to_string(r.checkInteger(c, r.keyPath("clip"), 0, 1000000));
		else
			r.fail(r.keyPath("clip"), std::string("expected a clip name or index, got ") + typeName(c));
	}
	a.speed = r.number("speed", a.speed, 0.0, kMaxAnimationSpeed, /*loOpen=*/true);
	a.loop = r.boolean("loop", a.loop);
	a.startS = r.number("start_s", a.startS, 0.0, 1e6);
	r.finish();
	return a;
}

BodySpec parseBody(ObjectReader r)
{
	BodySpec b;
	if (r.has("animation"))
	{
		if (r.has("mesh"))
			r.fail(r.keyPath("mesh"), "an animated body is the skinned mesh of body.animation.file: give no mesh");
		b.animation = parseAnimation(r.child("animation"));
		b.mesh = b.animation->file;
	}
	else
		b.mesh = r.file("mesh");
	const bool hasEllipsoids = r.has("ellipsoids"), hasFit = r.has("fit");
	if (hasEllipsoids && hasFit)
		r.fail(r.keyPath("fit"), "give either 'ellipsoids' (a fit file) or 'fit' (fit parameters), not both");
	if (hasEllipsoids)
		b.ellipsoids = r.file("ellipsoids");
	if (hasFit)
	{
		const json& f = r.get("fit");
		if (!f.is_object())
			r.fail(r.keyPath("fit"), std::string("expected an object of fit parameters, got ") + typeName(f));
		for (auto it = f.begin(); it != f.end(); ++it) // fit parameters are plain values (checked in loadBody)
			if (it.value().is_structured())
				r.fail(r.keyPath("fit") + "." + it.key(), std::string("expected a number or true/false, got ") +
															   typeName(it.value()));
		if (f.contains("max_ellipsoids")) // a count: 0.5 used to reach the fitter as 0 (no key named), 1.9 as 1
			r.checkInteger(f["max_ellipsoids"], r.keyPath("fit") + ".max_ellipsoids", 1, 10000);
		b.fit = f;
	}
	b.up = r.string("up", "y", {"y", "z"}) == "z" ? UpAxis::Z : UpAxis::Y;
	b.scale = r.number("scale", 1.0, 0.0, 1e6, true);
	r.finish();
	return b;
}

ColliderSpec parseCollider(const json& j, ObjectReader& top)
{
	ColliderSpec c;
	const std::vector<std::string> kinds = {"ellipsoids", "mesh-bvh", "convex-hull-compound", "ellipsoids-sdf", "none"};
	if (j.is_string())
	{
		const std::string s = top.string("collider", "", kinds);
		c.kind = colliderKindFromString(s);
		return c;
	}
	ObjectReader r = top.child("collider");
	c.kind = colliderKindFromString(r.requiredString("kind", kinds));
	c.skinOffset = r.number("skin_offset_m", c.skinOffset, 0.0, 0.05);
	c.sdfVoxel = r.number("sdf_voxel_m", c.sdfVoxel, 0.001, 1.0);
	c.shapeMargin = r.number("shape_margin_m", c.shapeMargin, 0.0, 0.1);
	c.contactHardness = r.number("contact_hardness", c.contactHardness, 0.0, 1.0, true);
	c.tightSurface = r.string("surface", "tight", {"tight", "ellipsoids"}) == "tight";
	c.skinMesh = r.boolean("skin_mesh", c.skinMesh);
	c.liftEdges = r.boolean("lift_edges", c.liftEdges);
	c.liftClearance = r.number("lift_clearance", c.liftClearance, 0.0, 1.0, true);
	r.finish();
	return c;
}

GarmentSpec parseGarment(ObjectReader r)
{
	GarmentSpec g;
	const std::string type = r.requiredString("type", {"patch", "bullet_patch", "skirt", "tights", "tube"});
	if (type == "patch" || type == "bullet_patch")
	{
		g.type = type == "patch" ? GarmentType::Patch : GarmentType::BulletPatch;
		g.size = r.vec2("size_m", g.size, kMinGarmentSize, 100.0, false);
		g.resolution = r.ivec2("resolution", g.resolution, 2, 512);
		for (int i = 0; i < 2; ++i)
			requireClothEdge(r, "size_m", g.size[i] / (g.resolution[i] - 1), "size_m[" + std::to_string(i) + "] / (resolution[" + std::to_string(i) + "] - 1)");
		g.center = r.vec3("center", g.center);
	}
	else if (type == "skirt" || type == "tights")
	{
		g.type = type == "skirt" ? GarmentType::Skirt : GarmentType::Tights;
		g.mesh = r.file("mesh");
		if (r.has("scale"))
		{
			const json& s = r.get("scale");
			if (s.is_number())
				g.scale.setConstant(r.checkNumber(s, r.keyPath("scale"), kMinGarmentScale, 100.0));
			else
				g.scale = r.vec3("scale", g.scale, kMinGarmentScale, 100.0);
		}
		if (r.has("scale_center"))
			g.scaleCenter = r.vec3("scale_center", Eigen::Vector3d::Zero());
		g.offset = r.vec3("offset", g.offset);
		g.subdivisions = r.integer("subdivide", g.subdivisions, 0, kMaxGarmentSubdivisions);
	}
	else
	{
		g.type = GarmentType::Tube;
		g.radius = r.number("radius_m", g.radius, kMinGarmentSize / 2, 10.0);
		g.length = r.number("length_m", g.length, kMinGarmentSize, 100.0);
		g.segments = r.integer("segments", g.segments, 3, 1024);
		g.rings = r.integer("rings", g.rings, 2, 1024);
		requireClothEdge(r, "segments", 2.0 * M_PI * g.radius / g.segments, "2 pi radius_m / segments");
		requireClothEdge(r, "rings", g.length / (g.rings - 1), "length_m / (rings - 1)");
		g.center = r.vec3("center", g.center);
	}
	r.finish();
	return g;
}

MaterialSpec parseMaterial(ObjectReader r)
{
	MaterialSpec m;
	m.stretch = r.number("stretch", m.stretch, 0.0, 1.0, true);
	m.bending = r.number("bending", m.bending, 0.0, 1.0);
	m.damping = r.number("damping", m.damping, 0.0, 0.99);
	m.mass = r.number("mass_kg", m.mass, 0.001, 100.0);
	m.margin = r.number("margin_m", m.margin, 0.0, 0.1, true);
	r.finish();
	return m;
}

SolverSpec parseSolver(ObjectReader r)
{
	SolverSpec s;
	s.dt = r.number("dt", s.dt, 0.0, 0.1, true);
	s.substeps = r.integer("substeps", s.substeps, 1, 100);
	s.iterations = r.integer("iterations", s.iterations, 1, 200);
	s.steps = r.integer("steps", s.steps, 0, 10000000);
	r.finish();
	return s;
}

/// The body's speed between two keyframes: translation and rotation (angle between the two orientations).
void requirePhysicalKeyframeStep(ObjectReader& k, const Keyframe& a, const Keyframe& b, double dt)
{
	const double gap = b.time - a.time;
	if (gap < dt)
		k.fail(k.keyPath("t"), "keyframes " + formatNumber(gap) + " s apart, less than one step (solver.dt " +
								   formatNumber(dt) + " s): the body would jump");
	const double speed = (b.translation - a.translation).norm() / gap;
	if (speed > kMaxBodySpeed)
		k.fail(k.keyPath("t"), "the body would move at " + formatNumber(speed) + " m/s from the previous keyframe (at most " +
								   formatNumber(kMaxBodySpeed) + " m/s)");
	const Eigen::Quaterniond qa(Eigen::AngleAxisd(a.angleDeg * M_PI / 180.0, a.axis));
	const Eigen::Quaterniond qb(Eigen::AngleAxisd(b.angleDeg * M_PI / 180.0, b.axis));
	const double turn = qa.angularDistance(qb) * 180.0 / M_PI / gap;
	if (turn > kMaxBodyTurnRate)
		k.fail(k.keyPath("t"), "the body would turn at " + formatNumber(turn) + " deg/s from the previous keyframe (at most " +
								   formatNumber(kMaxBodyTurnRate) + " deg/s)");
}

BodyMotionSpec parseBodyMotion(ObjectReader& r, double dt)
{
	BodyMotionSpec m;
	const json& keys = r.get("keyframes");
	const std::string where = r.keyPath("keyframes");
	if (!keys.is_array() || keys.empty())
		r.fail(where, "expected a non-empty array of keyframes");
	for (std::size_t i = 0; i < keys.size(); ++i)
	{
		ObjectReader k(keys[i], where + "[" + std::to_string(i) + "]", r.fileName(), r.baseDir());
		Keyframe f;
		f.time = k.checkNumber(k.get("t"), k.keyPath("t"), 0.0, 1e6);
		f.translation = k.vec3("translation", f.translation);
		f.axis = k.vec3("axis", f.axis);
		f.angleDeg = k.number("angle_deg", 0.0, -360.0, 360.0);
		if (f.angleDeg != 0.0 && f.axis.norm() < 1e-9)
			k.fail(k.keyPath("axis"), "rotation axis must not be zero");
		if (f.axis.norm() >= 1e-9)
			f.axis.normalize();
		else
			f.axis = Eigen::Vector3d::UnitY();
		if (!m.keyframes.empty() && f.time <= m.keyframes.back().time)
			k.fail(k.keyPath("t"), "keyframe times must increase strictly");
		if (!m.keyframes.empty())
			requirePhysicalKeyframeStep(k, m.keyframes.back(), f, dt);
		k.finish();
		m.keyframes.push_back(f);
	}
	if (r.has("pivot"))
		m.pivot = r.vec3("pivot", Eigen::Vector3d::Zero());
	m.loop = r.boolean("loop", false);
	if (m.loop && m.keyframes.back().time <= 0.0)
		r.fail(r.keyPath("loop"), "a looping motion needs a last keyframe time > 0");
	if (m.loop) // the path wraps from the last pose to the first in no time: they must be the same pose
	{
		const Keyframe &first = m.keyframes.front(), &last = m.keyframes.back();
		const double jump = (last.translation - first.translation).norm();
		const double turn = Eigen::Quaterniond(Eigen::AngleAxisd(first.angleDeg * M_PI / 180.0, first.axis))
								.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(last.angleDeg * M_PI / 180.0, last.axis))) *
							180.0 / M_PI;
		if (jump > 1e-6 || turn > 1e-6)
			r.fail(r.keyPath("loop"), "a looping motion must end where it starts: the last keyframe is " + formatNumber(jump) +
										  " m and " + formatNumber(turn) + " deg from the first");
	}
	return m;
}

WindSpec parseWind(ObjectReader& r)
{
	WindSpec w;
	w.velocity = r.vec3("velocity", w.velocity, -kMaxWindSpeed, kMaxWindSpeed);
	w.turbulence = r.number("turbulence", w.turbulence, 0.0, kMaxTurbulence);
	w.lengthScale = r.number("length_scale_m", w.lengthScale, 0.0, 100.0, true);
	w.timeScale = r.number("time_scale_s", w.timeScale, 0.0, 1000.0, true);
	w.octaves = r.integer("octaves", w.octaves, 1, 6);
	w.seed = unsigned(r.integer("seed", int(w.seed), 0, 1 << 30));
	w.drag = r.number("drag", w.drag, 0.0, kMaxAeroCoefficient);
	return w;
}

AerodynamicsSpec parseAerodynamics(ObjectReader& r)
{
	AerodynamicsSpec a;
	a.model = r.string("model", a.model,
					   {"V_Point", "V_TwoSided", "V_TwoSidedLiftDrag", "V_OneSided", "F_TwoSided", "F_TwoSidedLiftDrag",
						"F_OneSided"});
	a.lift = r.number("lift", a.lift, 0.0, kMaxAeroCoefficient);
	a.drag = r.number("drag", a.drag, 0.0, kMaxAeroCoefficient);
	a.airDensity = r.number("air_density", a.airDensity, 0.0, kMaxAirDensity, true);
	return a;
}

/// A pin: which nodes (corners or an edge of a patch, a top band, or listed indices) and what they hold to.
PinSpec parsePin(ObjectReader& r, const Scene& scene)
{
	PinSpec p;
	const std::string sel = r.requiredString("select", {"corners", "edge", "top", "indices"});
	const bool patch = scene.garment.type == GarmentType::Patch || scene.garment.type == GarmentType::BulletPatch;
	if ((sel == "corners" || sel == "edge") && !patch)
		r.fail(r.keyPath("select"), "'" + sel + "' needs a patch garment");
	if (sel == "corners")
		p.select = PinSelect::Corners;
	else if (sel == "edge")
	{
		p.select = PinSelect::Edge;
		p.side = r.requiredString("side", {"-x", "+x", "-z", "+z"});
	}
	else if (sel == "top")
	{
		p.select = PinSelect::Top;
		p.band = r.number("band_m", p.band, 0.0, 10.0);
	}
	else
	{
		p.select = PinSelect::Indices;
		const json& idx = r.get("indices");
		if (!idx.is_array() || idx.empty())
			r.fail(r.keyPath("indices"), "expected a non-empty array of node indices");
		for (std::size_t k = 0; k < idx.size(); ++k)
			p.indices.push_back(r.checkInteger(idx[k], r.keyPath("indices") + "[" + std::to_string(k) + "]", 0, 1 << 30));
	}
	p.toBody = r.string("attach", "world", {"world", "body"}) == "body";
	return p;
}

/// One effect object of the list, by its type, into scene.effects.
void parseEffect(ObjectReader& r, const std::string& type, Scene& scene)
{
	EffectsSpec& e = scene.effects;
	if (type == "gravity")
	{
		GravitySpec g;
		g.acceleration = r.vec3("acceleration", g.acceleration, -100.0, 100.0); // 10 g
		e.gravity = g;
	}
	else if (type == "wind")
		e.wind = parseWind(r);
	else if (type == "aerodynamics")
		e.aerodynamics = parseAerodynamics(r);
	else if (type == "friction")
	{
		FrictionSpec f;
		f.coefficient = r.number("coefficient", f.coefficient, 0.0, 10.0);
		e.friction = f;
	}
	else if (type == "self_collision")
	{
		SelfCollisionSpec s;
		s.thickness = r.number("thickness_m", s.thickness, 0.0, 0.1, true);
		s.stiffness = r.number("stiffness", s.stiffness, 0.0, 1.0, true);
		e.selfCollision = s;
	}
	else if (type == "pin")
		e.pin = parsePin(r, scene);
	else
		e.bodyMotion = parseBodyMotion(r, scene.solver.dt);
}

void parseEffects(const json& list, const std::string& where, Scene& scene, const std::string& file,
				  const std::string& baseDir)
{
	if (!list.is_array())
		throw FormatError(file + ": " + where + ": expected an array of effect objects, got " + typeName(list));
	const std::vector<std::string> names = {"gravity", "wind",    "aerodynamics", "friction",
											"self_collision", "pin", "body_motion"};
	std::set<std::string> seen;
	for (std::size_t i = 0; i < list.size(); ++i)
	{
		ObjectReader r(list[i], where + "[" + std::to_string(i) + "]", file, baseDir);
		const std::string type = r.requiredString("type", names);
		if (!seen.insert(type).second)
			r.fail(r.keyPath("type"), "effect '" + type + "' is listed twice");
		parseEffect(r, type, scene);
		r.finish();
	}
}

} // namespace

const char* toString(ColliderKind kind)
{
	switch (kind)
	{
	case ColliderKind::Ellipsoids:
		return "ellipsoids";
	case ColliderKind::MeshBvh:
		return "mesh-bvh";
	case ColliderKind::ConvexHullCompound:
		return "convex-hull-compound";
	case ColliderKind::EllipsoidsSdf:
		return "ellipsoids-sdf";
	case ColliderKind::None:
		return "none";
	}
	return "?";
}

ColliderKind colliderKindFromString(const std::string& name)
{
	for (ColliderKind k : {ColliderKind::Ellipsoids, ColliderKind::MeshBvh, ColliderKind::ConvexHullCompound,
						   ColliderKind::EllipsoidsSdf, ColliderKind::None})
		if (name == toString(k))
			return k;
	throw FormatError("collider kind '" + name +
					  "' is not one of ellipsoids, mesh-bvh, convex-hull-compound, ellipsoids-sdf, none");
}

const char* toString(GarmentType type)
{
	switch (type)
	{
	case GarmentType::Patch:
		return "patch";
	case GarmentType::BulletPatch:
		return "bullet_patch";
	case GarmentType::Skirt:
		return "skirt";
	case GarmentType::Tights:
		return "tights";
	case GarmentType::Tube:
		return "tube";
	}
	return "?";
}

std::vector<std::string> EffectsSpec::listed() const
{
	std::vector<std::string> names;
	if (gravity)
		names.push_back("gravity");
	if (wind)
		names.push_back("wind");
	if (aerodynamics)
		names.push_back("aerodynamics");
	if (friction)
		names.push_back("friction");
	if (selfCollision)
		names.push_back("self_collision");
	if (pin)
		names.push_back("pin");
	if (bodyMotion)
		names.push_back("body_motion");
	return names;
}

Scene parseScene(const nlohmann::json& document, const std::string& path)
{
	const std::string baseDir = std::filesystem::path(path).parent_path().string();
	Scene scene;
	scene.path = path;
	ObjectReader top(document, "", path, baseDir);
	// Unknown top-level keys first: a wrong file (e.g. an ellipsoid set passed as a scene) is then reported by its
	// foreign keys rather than by the first missing section.
	const std::vector<std::string> sections = {"name",   "description", "body",    "collider", "garment",
											   "material", "solver",    "effects", "render",   "output"};
	for (auto it = document.begin(); it != document.end(); ++it)
		if (std::find(sections.begin(), sections.end(), it.key()) == sections.end())
			top.fail(it.key(), "unknown key (allowed here: " + ObjectReader::join(sections) + ")");
	scene.name = top.string("name", std::filesystem::path(path).stem().string());
	top.string("description", "");
	scene.body = parseBody(top.child("body"));
	scene.collider = parseCollider(top.get("collider"), top);
	if (scene.collider.kind != ColliderKind::None && scene.body.ellipsoids.empty() && !scene.body.fit &&
		!scene.body.animation && scene.collider.kind != ColliderKind::MeshBvh)
		top.fail("body", std::string("collider '") + toString(scene.collider.kind) +
							 "' needs fitted ellipsoids: give body.ellipsoids or body.fit");
	scene.garment = parseGarment(top.child("garment"));
	if (top.has("material"))
		scene.material = parseMaterial(top.child("material"));
	if (top.has("solver"))
		scene.solver = parseSolver(top.child("solver"));
	if (top.has("effects"))
		parseEffects(top.get("effects"), "effects", scene, path, baseDir);
	if (scene.body.animation && scene.effects.bodyMotion)
		top.fail("effects", "body_motion moves a rigid body; an animated body (body.animation) is moved by its clip: "
							"give one or the other");
	if (top.has("render"))
	{
		ObjectReader r = top.child("render");
		scene.render.width = r.integer("width", scene.render.width, 2, 8192);
		scene.render.height = r.integer("height", scene.render.height, 1, 8192);
		scene.render.showEllipsoids = r.string("show", "body", {"body", "ellipsoids"}) == "ellipsoids";
		r.finish();
	}
	if (top.has("output"))
	{
		ObjectReader r = top.child("output");
		scene.frameEvery = r.integer("frame_every", scene.frameEvery, 1, 1000000);
		scene.sampleEvery = r.integer("sample_every", scene.sampleEvery, 1, 1000000);
		r.finish();
	}
	top.finish();
	return scene;
}

Scene parseSceneText(const std::string& text, const std::string& path)
{
	const std::string depth = jsonDepthProblem(text);
	if (!depth.empty()) // before a tree is built: deep nesting overflows the stack of recursive JSON code
		throw FormatError(path + ": not a usable JSON document: " + depth);
	json document;
	try
	{
		document = json::parse(text, nullptr, true, /*ignore_comments=*/true);
	}
	catch (const json::parse_error& e)
	{
		throw FormatError(path + ": invalid JSON at byte " + std::to_string(e.byte) + ": " + e.what());
	}
	catch (const json::exception& e) // e.g. out_of_range.406, a number too large for a double
	{
		throw FormatError(path + ": invalid JSON: " + e.what());
	}
	return parseScene(document, path);
}

Scene loadScene(const std::string& path)
{
	return parseSceneText(readJsonInputFile(path, "scene file"), path);
}

} // namespace bodyfit::drape
