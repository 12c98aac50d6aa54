// Scene files: a valid document with every section parses to the expected values; every unknown key and every bad
// value is a FormatError whose message names the file and the key path; the bundled scenes parse.
#include "bodyfit/drape/scene.h"
#include "support/paths.h"

#include "bodyfit/fitting/errors.h"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <unistd.h>

using bodyfit::FormatError;
using namespace bodyfit::drape;
using nlohmann::json;

namespace
{

const std::string kFile = "/virtual/scenes/test_scene.json";

json validDocument()
{
	json j = json::parse(R"({
		"name": "all_sections",
		"description": "every key once",
		"body": {"mesh": "MESH", "fit": {"mu_torso": 0.01}, "up": "y", "scale": 1.0},
		"collider": {"kind": "mesh-bvh", "skin_offset_m": 0.003, "sdf_voxel_m": 0.03, "shape_margin_m": 0.002,
					 "contact_hardness": 0.8, "surface": "ellipsoids", "skin_mesh": true,
					 "lift_edges": false, "lift_clearance": 0.25},
		"garment": {"type": "patch", "size_m": [1.2, 0.8], "resolution": [21, 11], "center": [0, 1.5, 0.1]},
		"material": {"stretch": 0.7, "bending": 0.1, "damping": 0.05, "mass_kg": 0.4, "margin_m": 0.006},
		"solver": {"dt": 0.01, "substeps": 2, "iterations": 12, "steps": 50},
		"effects": [
			{"type": "gravity", "acceleration": [0, -9.0, 0]},
			{"type": "wind", "velocity": [1, 0, 0], "turbulence": 0.5, "length_scale_m": 0.2, "time_scale_s": 0.3,
			 "octaves": 3, "seed": 4, "drag": 0.7},
			{"type": "aerodynamics", "model": "V_TwoSided", "lift": 0.1, "drag": 0.2, "air_density": 1.1},
			{"type": "friction", "coefficient": 0.4},
			{"type": "self_collision", "thickness_m": 0.01, "stiffness": 0.6},
			{"type": "pin", "select": "edge", "side": "+z", "attach": "body"},
			{"type": "body_motion", "pivot": [0, 1, 0], "loop": true, "keyframes": [
				{"t": 0, "translation": [0, 0, 0]},
				{"t": 1, "translation": [0, 0, 1], "axis": [0, 1, 0], "angle_deg": 30},
				{"t": 2, "translation": [0, 0, 0]}]}
		],
		"render": {"width": 640, "height": 480, "show": "ellipsoids"},
		"output": {"frame_every": 5, "sample_every": 3}
	})");
	j["body"]["mesh"] = bodyfit_test::assetPath("female_young.obj");
	return j;
}

/// The FormatError message of parsing `j`, or "" if it parsed.
std::string parseError(const json& j)
{
	try
	{
		parseScene(j, kFile);
	}
	catch (const FormatError& e)
	{
		return e.what();
	}
	return "";
}

} // namespace

TEST_CASE("a scene with every section parses to the given values", "[scene]")
{
	const Scene s = parseScene(validDocument(), kFile);
	CHECK(s.name == "all_sections");
	CHECK(s.body.fit.has_value());
	CHECK(s.collider.kind == ColliderKind::MeshBvh);
	CHECK(s.collider.sdfVoxel == 0.03);
	CHECK(s.collider.contactHardness == 0.8);
	CHECK_FALSE(s.collider.tightSurface);
	CHECK(s.collider.skinMesh);
	CHECK_FALSE(s.collider.liftEdges);
	CHECK(s.collider.liftClearance == 0.25);
	CHECK(s.garment.type == GarmentType::Patch);
	CHECK(s.garment.resolution == Eigen::Vector2i(21, 11));
	CHECK(s.garment.size == Eigen::Vector2d(1.2, 0.8));
	CHECK(s.material.stretch == 0.7);
	CHECK(s.material.mass == 0.4);
	CHECK(s.solver.substeps == 2);
	CHECK(s.solver.steps == 50);
	REQUIRE(s.effects.gravity);
	CHECK(s.effects.gravity->acceleration.y() == -9.0);
	REQUIRE(s.effects.wind);
	CHECK(s.effects.wind->octaves == 3);
	REQUIRE(s.effects.aerodynamics);
	CHECK(s.effects.aerodynamics->model == "V_TwoSided");
	REQUIRE(s.effects.friction);
	REQUIRE(s.effects.selfCollision);
	CHECK(s.effects.selfCollision->thickness == 0.01);
	REQUIRE(s.effects.pin);
	CHECK(s.effects.pin->select == PinSelect::Edge);
	CHECK(s.effects.pin->side == "+z");
	CHECK(s.effects.pin->toBody);
	REQUIRE(s.effects.bodyMotion);
	CHECK(s.effects.bodyMotion->keyframes.size() == 3); // a loop ends where it starts
	CHECK(s.effects.bodyMotion->loop);
	CHECK(s.render.showEllipsoids);
	CHECK(s.frameEvery == 5);
	CHECK(s.sampleEvery == 3);
	CHECK(s.effects.listed() ==
		  std::vector<std::string>{"gravity", "wind", "aerodynamics", "friction", "self_collision", "pin", "body_motion"});
}

TEST_CASE("a minimal scene gets the documented defaults and lists no effects", "[scene]")
{
	json j = {{"body", {{"mesh", bodyfit_test::assetPath("female_young.obj")}}},
			  {"collider", "none"},
			  {"garment", {{"type", "tube"}}}};
	const Scene s = parseScene(j, kFile);
	CHECK(s.name == "test_scene"); // the file stem
	CHECK(s.collider.kind == ColliderKind::None);
	CHECK(s.garment.type == GarmentType::Tube);
	CHECK(s.collider.sdfVoxel == 0.02);
	CHECK(s.material.margin == 0.005);
	CHECK(s.effects.listed().empty());
}

TEST_CASE("every unknown key is an error naming the file and the key path", "[scene]")
{
	struct Case
	{
		std::string pointer; // object to inject into
		std::string expected;
	};
	const std::vector<Case> cases = {
		{"", "test_scene.json: bogus: unknown key"},
		{"/body", "body.bogus: unknown key"},
		{"/collider", "collider.bogus: unknown key"},
		{"/garment", "garment.bogus: unknown key"},
		{"/material", "material.bogus: unknown key"},
		{"/solver", "solver.bogus: unknown key"},
		{"/effects/0", "effects[0].bogus: unknown key"},
		{"/effects/1", "effects[1].bogus: unknown key"},
		{"/effects/2", "effects[2].bogus: unknown key"},
		{"/effects/3", "effects[3].bogus: unknown key"},
		{"/effects/4", "effects[4].bogus: unknown key"},
		{"/effects/5", "effects[5].bogus: unknown key"},
		{"/effects/6", "effects[6].bogus: unknown key"},
		{"/effects/6/keyframes/1", "effects[6].keyframes[1].bogus: unknown key"},
		{"/render", "render.bogus: unknown key"},
		{"/output", "output.bogus: unknown key"},
	};
	for (const Case& c : cases)
	{
		json j = validDocument();
		j[json::json_pointer(c.pointer)]["bogus"] = 1;
		const std::string msg = parseError(j);
		INFO("injected at '" << c.pointer << "': " << msg);
		CHECK(msg.find(kFile) == 0);
		CHECK(msg.find(c.expected) != std::string::npos);
	}
}

TEST_CASE("every bad value is an error naming the file and the key path", "[scene]")
{
	struct Case
	{
		std::string pointer;
		json value;
		std::string expected; // key path as printed
	};
	const std::vector<Case> cases = {
		{"/name", 3, "name: expected a string"},
		{"/body", "x", "body: expected an object"},
		{"/body/mesh", "/no/such/file.obj", "body.mesh: file '/no/such/file.obj' does not exist"},
		{"/body/mesh", 5, "body.mesh: expected a string"},
		{"/body/fit", 1, "body.fit: expected an object"},
		{"/body/up", "x", "body.up: 'x' is not one of y, z"},
		{"/body/scale", 0, "body.scale: value 0 is outside (0"},
		{"/collider/kind", "spheres", "collider.kind: 'spheres' is not one of"},
		{"/collider/skin_offset_m", -0.1, "collider.skin_offset_m: value -0.1 is outside"},
		{"/collider/sdf_voxel_m", "fine", "collider.sdf_voxel_m: expected a number"},
		{"/collider/shape_margin_m", 1, "collider.shape_margin_m: value 1 is outside"},
		{"/collider/contact_hardness", 0, "collider.contact_hardness: value 0 is outside"},
		{"/collider/surface", "skin", "collider.surface: 'skin' is not one of tight, ellipsoids"},
		{"/collider/skin_mesh", 1, "collider.skin_mesh: expected true or false"},
		{"/collider/lift_edges", "yes", "collider.lift_edges: expected true or false"},
		{"/collider/lift_clearance", 0, "collider.lift_clearance: value 0 is outside (0, 1]"},
		{"/collider/lift_clearance", 1.5, "collider.lift_clearance: value 1.5 is outside (0, 1]"},
		{"/garment/type", "dress", "garment.type: 'dress' is not one of patch, bullet_patch, skirt, tights, tube"},
		{"/garment/size_m", json::array({1.0}), "garment.size_m: expected an array of 2 numbers"},
		{"/garment/size_m", json::array({1.0, -1.0}), "garment.size_m[1]: value -1 is outside"},
		{"/garment/resolution", json::array({1, 5}), "garment.resolution[0]: value 1 is outside [2, 512]"},
		{"/garment/resolution", json::array({2.5, 5}), "garment.resolution[0]: expected an integer"},
		{"/garment/center", json::array({0, "a", 0}), "garment.center[1]: expected a number"},
		{"/material/stretch", 1.5, "material.stretch: value 1.5 is outside"},
		{"/material/bending", -0.1, "material.bending: value -0.1 is outside"},
		{"/material/damping", 1, "material.damping: value 1 is outside"},
		{"/material/mass_kg", 0, "material.mass_kg: value 0 is outside"},
		{"/material/margin_m", 0, "material.margin_m: value 0 is outside"},
		{"/solver/dt", 0, "solver.dt: value 0 is outside"},
		{"/solver/substeps", 0, "solver.substeps: value 0 is outside [1, 100]"},
		{"/solver/iterations", 1000, "solver.iterations: value 1000 is outside [1, 200]"},
		{"/solver/steps", -1, "solver.steps: value -1 is outside"},
		{"/effects", json::object(), "effects: expected an array"},
		{"/effects/0/type", "magnetism", "effects[0].type: 'magnetism' is not one of"},
		{"/effects/0/acceleration", json::array({0, 0}), "effects[0].acceleration: expected an array of 3 numbers"},
		{"/effects/1/velocity", json::array({0, 1e9, 0}), "effects[1].velocity[1]: value 1e+09 is outside"},
		{"/effects/1/turbulence", -1, "effects[1].turbulence: value -1 is outside"},
		{"/effects/1/length_scale_m", 0, "effects[1].length_scale_m: value 0 is outside"},
		{"/effects/1/time_scale_s", 0, "effects[1].time_scale_s: value 0 is outside"},
		{"/effects/1/octaves", 9, "effects[1].octaves: value 9 is outside [1, 6]"},
		{"/effects/1/seed", -3, "effects[1].seed: value -3 is outside"},
		{"/effects/1/drag", -1, "effects[1].drag: value -1 is outside"},
		{"/effects/2/model", "V_Magic", "effects[2].model: 'V_Magic' is not one of"},
		{"/effects/2/lift", -1, "effects[2].lift: value -1 is outside"},
		{"/effects/2/drag", "x", "effects[2].drag: expected a number"},
		{"/effects/2/air_density", 0, "effects[2].air_density: value 0 is outside"},
		{"/effects/3/coefficient", -0.5, "effects[3].coefficient: value -0.5 is outside"},
		{"/effects/4/thickness_m", 0, "effects[4].thickness_m: value 0 is outside"},
		{"/effects/4/stiffness", 2, "effects[4].stiffness: value 2 is outside"},
		{"/effects/5/select", "random", "effects[5].select: 'random' is not one of corners, edge, top, indices"},
		{"/effects/5/side", "up", "effects[5].side: 'up' is not one of"},
		{"/effects/5/attach", "air", "effects[5].attach: 'air' is not one of world, body"},
		{"/effects/6/keyframes", json::array(), "effects[6].keyframes: expected a non-empty array"},
		{"/effects/6/keyframes/1/t", 0, "effects[6].keyframes[1].t: keyframe times must increase strictly"},
		{"/effects/6/keyframes/1/axis", json::array({0, 0, 0}), "effects[6].keyframes[1].axis: rotation axis must not be zero"},
		{"/effects/6/keyframes/1/angle_deg", 720, "effects[6].keyframes[1].angle_deg: value 720 is outside"},
		{"/effects/6/loop", "yes", "effects[6].loop: expected true or false"},
		{"/effects/6/pivot", 3, "effects[6].pivot: expected an array of 3 numbers"},
		{"/render/width", 0, "render.width: value 0 is outside"},
		{"/render/show", "skeleton", "render.show: 'skeleton' is not one of body, ellipsoids"},
		{"/output/frame_every", 0, "output.frame_every: value 0 is outside"},
		{"/output/sample_every", "often", "output.sample_every: expected an integer"},
	};
	for (const Case& c : cases)
	{
		json j = validDocument();
		j[json::json_pointer(c.pointer)] = c.value;
		const std::string msg = parseError(j);
		INFO("set '" << c.pointer << "' = " << c.value.dump() << ": " << msg);
		CHECK(msg.find(kFile + ": ") == 0);
		CHECK(msg.find(c.expected) != std::string::npos);
	}
}

TEST_CASE("structural errors name the key", "[scene]")
{
	SECTION("missing required keys")
	{
		for (const char* key : {"body", "collider", "garment"})
		{
			json j = validDocument();
			j.erase(key);
			CHECK(parseError(j) == kFile + ": " + key + ": required key is missing");
		}
		json j = validDocument();
		j["effects"][0].erase("type");
		CHECK(parseError(j) == kFile + ": effects[0].type: required key is missing");
	}
	SECTION("an effect listed twice")
	{
		json j = validDocument();
		j["effects"].push_back({{"type", "gravity"}});
		CHECK(parseError(j).find("effects[7].type: effect 'gravity' is listed twice") != std::string::npos);
	}
	SECTION("patch-only pin selections on a tube")
	{
		json j = validDocument();
		j["garment"] = {{"type", "tube"}};
		CHECK(parseError(j).find("effects[5].select: 'edge' needs a patch garment") != std::string::npos);
	}
	SECTION("a mesh garment's subdivisions")
	{
		json j = validDocument();
		j["garment"] = {{"type", "skirt"}, {"mesh", bodyfit_test::assetPath("female_young.skirt.obj")}, {"subdivide", 2}};
		j["effects"].erase(5); // (the pin selects a patch's edge)
		CHECK(parseScene(j, kFile).garment.subdivisions == 2);
		j["garment"]["subdivide"] = 4;
		CHECK(parseError(j).find("garment.subdivide: value 4 is outside [0, 3]") != std::string::npos);
		j["garment"]["subdivide"] = 1.5;
		CHECK(parseError(j).find("garment.subdivide: expected an integer") != std::string::npos);
		json patch = validDocument();
		patch["garment"]["subdivide"] = 1; // a patch has its resolution instead
		CHECK(parseError(patch).find("garment.subdivide: unknown key") != std::string::npos);
	}
	SECTION("both a fit file and fit parameters")
	{
		json j = validDocument();
		j["body"]["ellipsoids"] = bodyfit_test::assetPath("female_young.obj");
		CHECK(parseError(j).find("body.fit: give either") != std::string::npos);
	}
	SECTION("an ellipsoid collider without ellipsoids")
	{
		json j = validDocument();
		j["body"].erase("fit");
		j["collider"]["kind"] = "ellipsoids";
		CHECK(parseError(j).find("body: collider 'ellipsoids' needs fitted ellipsoids") != std::string::npos);
	}
	SECTION("the collider given as a bare string")
	{
		json j = validDocument();
		j["collider"] = "hull";
		CHECK(parseError(j).find("collider: 'hull' is not one of") != std::string::npos);
	}
}

TEST_CASE("loadScene names the file for unreadable or malformed JSON", "[scene]")
{
	CHECK_THROWS_WITH(loadScene("/no/such/scene.json"), "/no/such/scene.json: cannot open scene file: does not exist");
	const std::string path = (std::filesystem::temp_directory_path() / ("bodyfit_bad_scene_" + std::to_string(long(::getpid())) + ".json")).string();
	{
		std::ofstream out(path);
		out << "{ \"name\": \"x\", ";
	}
	CHECK_THROWS_WITH(loadScene(path), Catch::Matchers::StartsWith(path + ": invalid JSON at byte"));
	std::filesystem::remove(path);
}

TEST_CASE("the bundled scenes parse", "[scene]")
{
	int n = 0;
	for (const auto& entry : std::filesystem::directory_iterator(BODYFIT_SCENE_DIR))
	{
		if (entry.path().extension() != ".json")
			continue;
		INFO(entry.path().string());
		CHECK_NOTHROW(loadScene(entry.path().string()));
		++n;
	}
	CHECK(n >= 5); // tablecloth, skirt drop, tights, windy patch, walking skirt
}
