// Ellipsoid-set JSON (docs/DESIGN.md sec. 2) and the triangle-mesh export. See ellipsoid_io.h.
#include "bodyfit/fitting/ellipsoid_io.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/input_files.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/skin_field.h"
#include "bodyfit/fitting/skinned_fit.h"

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace bodyfit
{

namespace
{

using Json = nlohmann::ordered_json; // keeps the key order of ellipsoid_io.h when writing and the file's when reading

/// Tolerance on |q| - 1 for a stored quaternion: files are written with round-trip precision, so a unit quaternion
/// read back has |q| = 1 within a few ulp; 1e-6 still accepts files written by tools that print ~7 digits.
constexpr double kUnitQuaternionTolerance = 1e-6;

Json vec3(const Eigen::Vector3d& v)
{
	return Json::array({v.x(), v.y(), v.z()});
}

/// Adds `key: value` only for a finite value (NaN = unknown is omitted).
void putFinite(Json& obj, const char* key, double value)
{
	if (std::isfinite(value))
		obj[key] = value;
}

/// Validating accessors; every failure names the document and the field.
class Reader
{
public:
	explicit Reader(std::string name) : name_(std::move(name)) {}

	[[noreturn]] void fail(const std::string& field, const std::string& problem) const
	{
		throw FormatError(name_ + ": " + field + ": " + problem);
	}

	const Json& require(const Json& obj, const char* key, const std::string& prefix) const
	{
		const std::string field = prefix.empty() ? std::string(key) : prefix + "." + key;
		if (!obj.contains(key))
			fail(field, "missing");
		return obj[key];
	}

	double number(const Json& v, const std::string& field) const
	{
		if (!v.is_number())
			fail(field, "must be a number (got " + typeName(v) + ")");
		const double d = v.get<double>();
		if (!std::isfinite(d))
			fail(field, "must be finite");
		return d;
	}

	double nonNegative(const Json& v, const std::string& field) const
	{
		const double d = number(v, field);
		if (d < 0.0)
			fail(field, "must be >= 0 (got " + format(d) + ")");
		return d;
	}

	int integer(const Json& v, const std::string& field, int minimum) const
	{
		if (!v.is_number_integer())
			fail(field, "must be an integer (got " + typeName(v) + ")");
		if (v.is_number_unsigned() && v.get<unsigned long long>() > 2147483647ULL) // >= 2^63 is no long long
			fail(field, "must be an integer >= " + std::to_string(minimum) + " and < 2^31 (got " +
							std::to_string(v.get<unsigned long long>()) + ")");
		const long long i = v.get<long long>();
		if (i < minimum || i > 2147483647LL)
			fail(field, "must be an integer >= " + std::to_string(minimum) + " (got " + std::to_string(i) + ")");
		return int(i);
	}

	std::string string(const Json& v, const std::string& field) const
	{
		if (!v.is_string())
			fail(field, "must be a string (got " + typeName(v) + ")");
		return v.get<std::string>();
	}

	bool boolean(const Json& v, const std::string& field) const
	{
		if (!v.is_boolean())
			fail(field, "must be true or false (got " + typeName(v) + ")");
		return v.get<bool>();
	}

	/// Array of exactly n finite numbers.
	std::vector<double> numbers(const Json& v, const std::string& field, std::size_t n) const
	{
		if (!v.is_array() || v.size() != n)
			fail(field, "must be an array of " + std::to_string(n) + " numbers");
		std::vector<double> out;
		for (std::size_t i = 0; i < n; ++i)
			out.push_back(number(v[i], field + "[" + std::to_string(i) + "]"));
		return out;
	}

	const Json& object(const Json& v, const std::string& field) const
	{
		if (!v.is_object())
			fail(field, "must be an object (got " + typeName(v) + ")");
		return v;
	}

	/// The shortest text that reads back as d (1e-06, not 9.9999999999999995e-07).
	static std::string format(double d)
	{
		if (d == std::floor(d) && std::abs(d) < 1e15)
			return std::to_string((long long)d);
		for (int precision = 1;; ++precision)
		{
			std::ostringstream s;
			s.precision(precision);
			s << d;
			if (precision >= 17 || std::strtod(s.str().c_str(), nullptr) == d)
				return s.str();
		}
	}

private:
	static std::string typeName(const Json& v) { return v.type_name(); }
	std::string name_;
};

/// "" for x in [lo, hi] (metres), else "must be in [lo, hi] m (got x)": the fit-file range of ellipsoid_io.h.
std::string rangeProblem(double x, double lo, double hi)
{
	if (x >= lo && x <= hi)
		return "";
	return "must be in [" + Reader::format(lo) + ", " + Reader::format(hi) + "] m (got " + Reader::format(x) + ")";
}

/// The first centre coordinate or semi-axis of `fit` outside the fit-file range, as "ellipsoids[i].axes[k]: ...".
std::string fitRangeProblem(const BodyFit& fit)
{
	for (std::size_t e = 0; e < fit.ellipsoids.size(); ++e)
	{
		const Ellipsoid& el = fit.ellipsoids[e].ellipsoid;
		const std::string at = "ellipsoids[" + std::to_string(e) + "].";
		for (int i = 0; i < 3; ++i)
		{
			const std::string c = rangeProblem(el.center[i], -kMaxFitCoordinate, kMaxFitCoordinate);
			if (!c.empty())
				return at + "center[" + std::to_string(i) + "]: " + c;
			const std::string a = rangeProblem(el.radii[i], kMinFitAxis, kMaxFitAxis);
			if (!a.empty())
				return at + "axes[" + std::to_string(i) + "]: " + a;
		}
	}
	return "";
}

FittedEllipsoid readEllipsoid(const Reader& r, const Json& e, const std::string& field)
{
	r.object(e, field);
	FittedEllipsoid f;
	const std::string regionName_ = r.string(r.require(e, "region", field), field + ".region");
	if (!regionFromName(regionName_, &f.region))
		r.fail(field + ".region", "unknown region \"" + regionName_ + "\"");

	const std::vector<double> c = r.numbers(r.require(e, "center", field), field + ".center", 3);
	f.ellipsoid.center = Eigen::Vector3d(c[0], c[1], c[2]);
	for (int i = 0; i < 3; ++i)
		if (const std::string problem = rangeProblem(c[std::size_t(i)], -kMaxFitCoordinate, kMaxFitCoordinate);
			!problem.empty())
			r.fail(field + ".center[" + std::to_string(i) + "]", problem);

	const std::vector<double> q = r.numbers(r.require(e, "rotation", field), field + ".rotation", 4);
	const Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]); // [w, x, y, z]
	const double norm = quat.norm();
	if (std::abs(norm - 1.0) > kUnitQuaternionTolerance)
		r.fail(field + ".rotation", "must be a unit quaternion [w,x,y,z] (norm " + Reader::format(norm) + ")");
	f.ellipsoid.rotation = quat.normalized().toRotationMatrix();

	const std::vector<double> a = r.numbers(r.require(e, "axes", field), field + ".axes", 3);
	for (int i = 0; i < 3; ++i)
	{
		const std::string where = field + ".axes[" + std::to_string(i) + "]";
		if (!(a[std::size_t(i)] > 0.0))
			r.fail(where, "must be > 0 (got " + Reader::format(a[std::size_t(i)]) + ")");
		if (const std::string problem = rangeProblem(a[std::size_t(i)], kMinFitAxis, kMaxFitAxis); !problem.empty())
			r.fail(where, problem);
	}
	f.ellipsoid.radii = Eigen::Vector3d(a[0], a[1], a[2]);

	auto optional = [&](const char* key, double& out) {
		out = std::numeric_limits<double>::quiet_NaN();
		if (e.contains(key))
			out = r.nonNegative(e[key], field + "." + key);
	};
	optional("radial_error", f.radialError);
	optional("max_radial_error", f.maxRadialError);
	optional("mean_distance", f.meanDistance);
	optional("max_distance", f.maxDistance);
	f.vertexCount = e.contains("vertices") ? r.integer(e["vertices"], field + ".vertices", 0) : 0;
	return f;
}

Json skinFieldSection(const BodyFit& fit)
{
	const SkinField& f = *fit.skinField;
	return {{"file", fit.skinFieldFile},
			{"version", kSkinFieldFileVersion},
			{"voxel", f.voxel},
			{"clamp", f.clamp},
			{"bricks", f.storedBricks()},
			{"bytes", (long long)skinFieldBytes(f).size()},
			{"max_error", f.maxError}};
}

/// The skin_field section: the side file's name (a plain file name, next to the fit file) into fit.skinFieldFile; the
/// other members are checked when the side file is read (checkSkinFieldSection).
void readSkinFieldSection(const Reader& r, const Json& doc, BodyFit& fit)
{
	const Json& s = r.object(doc["skin_field"], "skin_field");
	const std::string file = r.string(r.require(s, "file", "skin_field"), "skin_field.file");
	if (file.empty() || file.find('/') != std::string::npos || file.find('\\') != std::string::npos ||
		file == "." || file == "..")
		r.fail("skin_field.file", "must be a file name in the fit file's directory (got \"" + file + "\")");
	if (s.contains("version") && r.integer(s["version"], "skin_field.version", 0) != int(kSkinFieldFileVersion))
		r.fail("skin_field.version", "unsupported version " + s["version"].dump() + " (this build reads version " +
										 std::to_string(kSkinFieldFileVersion) + ")");
	for (const char* key : {"voxel", "clamp", "max_error"})
		if (s.contains(key))
			r.nonNegative(s[key], std::string("skin_field.") + key);
	for (const char* key : {"bricks", "bytes"})
		if (s.contains(key))
			r.integer(s[key], std::string("skin_field.") + key, 0);
	fit.skinFieldFile = file;
}

/// The side file's grid agrees with what the section says about it (when it says it).
void checkSkinFieldSection(const Json& section, const SkinField& f, const std::string& where)
{
	auto mismatch = [&](const char* key, const std::string& file, const std::string& side) {
		throw FormatError(where + ": the fit file says " + key + " " + file + ", the side file has " + side);
	};
	if (section.contains("voxel") && section["voxel"].get<double>() != f.voxel)
		mismatch("voxel", Reader::format(section["voxel"].get<double>()), Reader::format(f.voxel));
	if (section.contains("clamp") && section["clamp"].get<double>() != f.clamp)
		mismatch("clamp", Reader::format(section["clamp"].get<double>()), Reader::format(f.clamp));
	if (section.contains("bricks") && section["bricks"].get<long long>() != f.storedBricks())
		mismatch("bricks", section["bricks"].dump(), std::to_string(f.storedBricks()));
}

RefineStatus refineStatusFromName(const Reader& r, const std::string& s, const std::string& field)
{
	for (RefineStatus st : {RefineStatus::Converged, RefineStatus::Frozen, RefineStatus::BudgetReached,
							RefineStatus::SplitCapReached})
		if (s == toString(st))
			return st;
	r.fail(field, "unknown status \"" + s + "\"");
}

/// The document tree of `text`, refused before parsing when it nests too deep, with nlohmann's message (without its
/// exception tag) when it is not JSON.
Json parseJsonText(const std::string& text, const std::string& name)
{
	const std::string depth = jsonDepthProblem(text);
	if (!depth.empty()) // before a tree is built: deep nesting overflows the stack of recursive JSON code
		throw FormatError(name + ": not a usable JSON document: " + depth);
	try
	{
		return Json::parse(text);
	}
	catch (const nlohmann::json::exception& e)
	{
		// nlohmann's messages: "[json.exception.parse_error.101] parse error at line L, column C: ...",
		// "[json.exception.out_of_range.406] number overflow parsing '1e999'".
		std::string what = e.what();
		const std::size_t pos = what.find("] ");
		throw FormatError(name + ": not valid JSON: " + (pos == std::string::npos ? what : what.substr(pos + 2)));
	}
}

/// format, version, units and up: a fit file of this build's version, in metres, +y up.
void checkFitHeader(const Reader& r, const Json& doc)
{
	const std::string format = r.string(r.require(doc, "format", ""), "format");
	if (format != kEllipsoidFormat)
		r.fail("format", "must be \"" + std::string(kEllipsoidFormat) + "\" (got \"" + format + "\")");
	const int version = r.integer(r.require(doc, "version", ""), "version", 0);
	if (version != kEllipsoidFormatVersion)
		r.fail("version", "unsupported version " + std::to_string(version) + " (this build reads version " +
							  std::to_string(kEllipsoidFormatVersion) + ")");
	if (doc.contains("units") && r.string(doc["units"], "units") != "m")
		r.fail("units", "must be \"m\"");
	if (doc.contains("up") && r.string(doc["up"], "up") != "+y")
		r.fail("up", "must be \"+y\"");
}

/// The optional "source" and "params" sections (what was fitted, with which settings).
void readSourceAndParams(const Reader& r, const Json& doc, BodyFit& fit)
{
	if (doc.contains("source"))
	{
		const Json& s = r.object(doc["source"], "source");
		if (s.contains("mesh"))
			fit.source.mesh = r.string(s["mesh"], "source.mesh");
		if (s.contains("vertices"))
			fit.source.vertices = r.integer(s["vertices"], "source.vertices", 0);
		if (s.contains("height"))
			fit.source.height = r.nonNegative(s["height"], "source.height");
	}
	if (doc.contains("params"))
	{
		const Json& p = r.object(doc["params"], "params");
		if (p.contains("mu_torso"))
			fit.params.muTorso = r.nonNegative(p["mu_torso"], "params.mu_torso");
		if (p.contains("mu_limbs"))
			fit.params.muLimbs = r.nonNegative(p["mu_limbs"], "params.mu_limbs");
		if (p.contains("relative_to_height"))
			fit.params.relativeToHeight = r.boolean(p["relative_to_height"], "params.relative_to_height");
		if (p.contains("sigma"))
			fit.params.sigma = r.nonNegative(p["sigma"], "params.sigma");
		if (p.contains("max_ellipsoids"))
			fit.params.maxEllipsoids = r.integer(p["max_ellipsoids"], "params.max_ellipsoids", 0);
		if (p.contains("min_radius"))
			fit.params.minRadius = r.nonNegative(p["min_radius"], "params.min_radius");
		if (p.contains("recluster_group"))
			fit.params.reclusterGroup = r.boolean(p["recluster_group"], "params.recluster_group");
		if (p.contains("cover_triangles"))
			fit.params.coverTriangles = r.boolean(p["cover_triangles"], "params.cover_triangles");
		if (p.contains("cover_spacing"))
			fit.params.coverSpacing = r.nonNegative(p["cover_spacing"], "params.cover_spacing");
	}
}

/// The optional report sections: "timing_ms", "stats" (its count must match the list), "refinement", "warnings".
void readFitReport(const Reader& r, const Json& doc, BodyFit& fit)
{
	if (doc.contains("timing_ms"))
		for (const auto& item : r.object(doc["timing_ms"], "timing_ms").items())
			fit.timings.push_back({item.key(), r.nonNegative(item.value(), "timing_ms." + item.key())});
	if (doc.contains("stats"))
	{
		const Json& s = r.object(doc["stats"], "stats");
		if (s.contains("count") && r.integer(s["count"], "stats.count", 0) != int(fit.ellipsoids.size()))
			r.fail("stats.count", "is " + std::to_string(s["count"].get<long long>()) + " but the file has " +
									  std::to_string(fit.ellipsoids.size()) + " ellipsoids");
	}
	if (doc.contains("refinement"))
	{
		const Json& s = r.object(doc["refinement"], "refinement");
		if (s.contains("status"))
			fit.status = refineStatusFromName(r, r.string(s["status"], "refinement.status"), "refinement.status");
		if (s.contains("splits_accepted"))
			fit.splitsAccepted = r.integer(s["splits_accepted"], "refinement.splits_accepted", 0);
		if (s.contains("splits_rejected"))
			fit.splitsRejected = r.integer(s["splits_rejected"], "refinement.splits_rejected", 0);
	}
	if (doc.contains("warnings"))
	{
		const Json& w = doc["warnings"];
		if (!w.is_array())
			r.fail("warnings", "must be an array of strings");
		for (std::size_t i = 0; i < w.size(); ++i)
			fit.warnings.push_back(r.string(w[i], "warnings[" + std::to_string(i) + "]"));
	}
}

} // namespace

std::string toEllipsoidJson(const BodyFit& fit)
{
	Json doc;
	doc["format"] = kEllipsoidFormat;
	doc["version"] = kEllipsoidFormatVersion;
	doc["units"] = "m";
	doc["up"] = "+y";
	doc["source"] = {{"mesh", fit.source.mesh}, {"vertices", fit.source.vertices}, {"height", fit.source.height}};
	doc["params"] = {{"mu_torso", fit.params.muTorso},
					 {"mu_limbs", fit.params.muLimbs},
					 {"relative_to_height", fit.params.relativeToHeight},
					 {"sigma", fit.params.sigma},
					 {"max_ellipsoids", fit.params.maxEllipsoids},
					 {"min_radius", fit.params.minRadius},
					 {"recluster_group", fit.params.reclusterGroup},
					 {"cover_triangles", fit.params.coverTriangles},
					 {"cover_spacing", fit.params.coverSpacing}};
	Json list = Json::array();
	for (const FittedEllipsoid& f : fit.ellipsoids)
	{
		Eigen::Quaterniond q = toQuaternion(f.ellipsoid.rotation).normalized();
		if (q.w() < 0.0) // q and -q are the same rotation; store the one with w >= 0
			q.coeffs() = -q.coeffs();
		Json e;
		e["region"] = regionName(f.region);
		e["center"] = vec3(f.ellipsoid.center);
		e["rotation"] = Json::array({q.w(), q.x(), q.y(), q.z()});
		e["axes"] = vec3(f.ellipsoid.radii);
		putFinite(e, "radial_error", f.radialError);
		putFinite(e, "max_radial_error", f.maxRadialError);
		putFinite(e, "mean_distance", f.meanDistance);
		putFinite(e, "max_distance", f.maxDistance);
		e["vertices"] = f.vertexCount;
		list.push_back(std::move(e));
	}
	doc["ellipsoids"] = std::move(list);
	Json timing = Json::object();
	for (const StageTiming& t : fit.timings)
		timing[t.stage] = t.ms;
	doc["timing_ms"] = std::move(timing);
	Json stats;
	stats["count"] = int(fit.ellipsoids.size());
	putFinite(stats, "mean_radial_error", fit.meanRadialError());
	putFinite(stats, "max_radial_error", fit.maxRadialError());
	putFinite(stats, "mean_distance", fit.meanDistance());
	putFinite(stats, "max_distance", fit.maxDistance());
	doc["stats"] = std::move(stats);
	doc["refinement"] = {{"status", toString(fit.status)},
						 {"splits_accepted", fit.splitsAccepted},
						 {"splits_rejected", fit.splitsRejected}};
	doc["warnings"] = fit.warnings;
	if (fit.skinning)
		doc["skinning"] = Json::parse(skinBindingJson(*fit.skinning));
	if (fit.skinField && !fit.skinFieldFile.empty())
		doc["skin_field"] = skinFieldSection(fit);
	return doc.dump(2) + "\n";
}

void writeEllipsoidJson(const std::string& path, const BodyFit& fit)
{
	const std::string range = fitRangeProblem(fit);
	if (!range.empty())
		throw FormatError(path + ": not written, the fit is outside a fit file's range: " + range +
						  " (a mesh in millimetres or centimetres needs a scale)");
	std::string text;
	if (fit.skinField)
	{
		const std::string side = skinFieldPathFor(path);
		writeSkinField(side, *fit.skinField);
		BodyFit named = fit;
		named.skinFieldFile = std::filesystem::path(side).filename().string();
		text = toEllipsoidJson(named);
	}
	else
		text = toEllipsoidJson(fit);
	std::ofstream out(path, std::ios::binary);
	if (!out)
		throw FormatError(path + ": cannot open for writing");
	out << text;
	out.close();
	if (!out)
		throw FormatError(path + ": write failed");
}

BodyFit parseEllipsoidJson(const std::string& text, const std::string& name)
{
	const Reader r(name);
	const Json doc = parseJsonText(text, name);
	r.object(doc, "document");
	checkFitHeader(r, doc);
	BodyFit fit;
	readSourceAndParams(r, doc, fit);
	const Json& list = r.require(doc, "ellipsoids", "");
	if (!list.is_array())
		r.fail("ellipsoids", "must be an array");
	for (std::size_t i = 0; i < list.size(); ++i)
		fit.ellipsoids.push_back(readEllipsoid(r, list[i], "ellipsoids[" + std::to_string(i) + "]"));
	readFitReport(r, doc, fit);
	if (doc.contains("skinning"))
		fit.skinning = parseSkinBinding(doc["skinning"].dump(), name, int(fit.ellipsoids.size()));
	if (doc.contains("skin_field"))
		readSkinFieldSection(r, doc, fit);
	return fit;
}

BodyFit readEllipsoidJson(const std::string& path)
{
	const std::string text = readJsonInputFile(path, "fit file");
	BodyFit fit = parseEllipsoidJson(text, path);
	if (fit.skinFieldFile.empty())
		return fit;
	const std::string side = (std::filesystem::path(path).parent_path() / fit.skinFieldFile).string();
	const std::string where = path + ": skin_field";
	try
	{
		fit.skinField = std::make_shared<const SkinField>(readSkinField(side));
	}
	catch (const FormatError& e)
	{
		throw FormatError(where + ": " + e.what());
	}
	checkSkinFieldSection(Json::parse(text)["skin_field"], *fit.skinField, where + ": " + side);
	return fit;
}

std::string skinFieldPathFor(const std::string& fitPath)
{
	std::filesystem::path side(fitPath);
	side.replace_extension(".skin");
	return side.string() == fitPath ? fitPath + ".skin" : side.string();
}

TriMesh ellipsoidMesh(const std::vector<FittedEllipsoid>& ellipsoids, int subdivisions, Eigen::MatrixX3d* colors)
{
	if (subdivisions < 0 || subdivisions > 6)
		throw InvalidInputError("ellipsoidMesh: subdivisions must be in [0, 6]");
	// Unit icosahedron, then midpoint subdivision projected back onto the sphere.
	const double t = (1.0 + std::sqrt(5.0)) / 2.0;
	std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
									  {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
	for (Eigen::Vector3d& p : v)
		p.normalize();
	std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
									  {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
									  {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
	for (int level = 0; level < subdivisions; ++level)
	{
		std::map<std::pair<int, int>, int> midpoints;
		auto midpoint = [&](int a, int b) {
			const std::pair<int, int> key(std::min(a, b), std::max(a, b));
			const auto it = midpoints.find(key);
			if (it != midpoints.end())
				return it->second;
			v.push_back((v[std::size_t(a)] + v[std::size_t(b)]).normalized());
			const int id = int(v.size()) - 1;
			midpoints.emplace(key, id);
			return id;
		};
		std::vector<Eigen::Vector3i> next;
		next.reserve(f.size() * 4);
		for (const Eigen::Vector3i& tri : f)
		{
			const int ab = midpoint(tri[0], tri[1]), bc = midpoint(tri[1], tri[2]), ca = midpoint(tri[2], tri[0]);
			next.push_back({tri[0], ab, ca});
			next.push_back({tri[1], bc, ab});
			next.push_back({tri[2], ca, bc});
			next.push_back({ab, bc, ca});
		}
		f.swap(next);
	}

	const Eigen::Index nv = Eigen::Index(v.size()), nf = Eigen::Index(f.size());
	const Eigen::Index count = Eigen::Index(ellipsoids.size());
	TriMesh mesh;
	mesh.V.resize(nv * count, 3);
	mesh.F.resize(nf * count, 3);
	if (colors != nullptr)
		colors->resize(nv * count, 3);
	for (Eigen::Index e = 0; e < count; ++e)
	{
		const Ellipsoid& el = ellipsoids[std::size_t(e)].ellipsoid;
		const Eigen::Vector3d color = regionColor(ellipsoids[std::size_t(e)].region);
		for (Eigen::Index i = 0; i < nv; ++i)
		{
			mesh.V.row(e * nv + i) = el.toWorld(el.radii.cwiseProduct(v[std::size_t(i)])).transpose();
			if (colors != nullptr)
				colors->row(e * nv + i) = color.transpose();
		}
		for (Eigen::Index j = 0; j < nf; ++j)
			mesh.F.row(e * nf + j) = (f[std::size_t(j)].array() + int(e * nv)).transpose();
	}
	return mesh;
}

void exportEllipsoidMesh(const std::string& path, const std::vector<FittedEllipsoid>& ellipsoids, int subdivisions)
{
	auto endsWith = [&](const char* ext) { // case-insensitive: X.OBJ passed the CLI check and then failed here
		const std::string e(ext);
		if (path.size() < e.size())
			return false;
		for (std::size_t i = 0; i < e.size(); ++i)
			if (std::tolower((unsigned char)path[path.size() - e.size() + i]) != e[i])
				return false;
		return true;
	};
	if (!endsWith(".obj") && !endsWith(".ply"))
		throw InvalidInputError(path + ": ellipsoid mesh export needs a .obj or .ply file name");
	Eigen::MatrixX3d colors;
	const TriMesh mesh = ellipsoidMesh(ellipsoids, subdivisions, &colors);
	saveTriMesh(path, mesh, &colors);
}

} // namespace bodyfit
