// The glTF 2.0 animation writer (bodyfit/drape/gltf_animation.h): the GLB container (header, 4-byte aligned JSON and
// BIN chunks, lengths that add up), one node per frame whose STEP scale keys show it from its time to the next
// frame's, POSITION min/max, indices stored once per part, and the one-line errors. The Khronos validator checks
// the files bodyfit-drape writes (tests/demos/test_scene_cli.cpp).
#include "bodyfit/drape/gltf_animation.h"

#include "bodyfit/fitting/errors.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstring>

using namespace bodyfit::drape;

namespace
{

std::uint32_t u32(const std::string& s, std::size_t at)
{
	std::uint32_t v = 0;
	std::memcpy(&v, s.data() + at, 4);
	return v;
}

/// A unit triangle part and its vertices moved by `dy`.
GltfPart trianglePart(const std::string& name)
{
	GltfPart p;
	p.name = name;
	p.faces.resize(1, 3);
	p.faces << 0, 1, 2;
	return p;
}

Eigen::MatrixX3d triangle(double dy)
{
	Eigen::MatrixX3d V(3, 3);
	V << 0, dy, 0, 1, dy, 0, 0, 1 + dy, 0;
	return V;
}

} // namespace

TEST_CASE("glTF animation: a valid GLB container with one STEP-keyed node per frame", "[gltf]")
{
	GltfAnimationRecorder rec({trianglePart("body"), trianglePart("cloth")});
	const Eigen::MatrixX3d a0 = triangle(0.0), a1 = triangle(0.5), a2 = triangle(1.0);
	rec.addFrame(0.0, {&a0, &a0});
	rec.addFrame(0.25, {&a1, &a0});
	rec.addFrame(0.5, {&a2, &a0});
	const std::string glb = rec.glb();
	REQUIRE(glb.size() > 20);
	CHECK(u32(glb, 0) == 0x46546C67u); // "glTF"
	CHECK(u32(glb, 4) == 2u);
	CHECK(u32(glb, 8) == glb.size());
	const std::uint32_t jsonLength = u32(glb, 12);
	CHECK(u32(glb, 16) == 0x4E4F534Au);
	CHECK(jsonLength % 4 == 0);
	const std::size_t binAt = 20 + jsonLength;
	CHECK(u32(glb, binAt + 4) == 0x004E4942u);
	CHECK(binAt + 8 + u32(glb, binAt) == glb.size());
	const nlohmann::json doc = nlohmann::json::parse(glb.substr(20, jsonLength));
	CHECK(doc["asset"]["version"] == "2.0");
	CHECK(doc["meshes"].size() == 3);
	CHECK(doc["nodes"].size() == 4); // 3 frames + the root
	CHECK(doc["scenes"][0]["nodes"][0] == 3);
	CHECK(doc["buffers"][0]["byteLength"].get<std::size_t>() <= u32(glb, binAt));
	// Indices once per part: two index accessors shared by every frame's primitives.
	CHECK(doc["meshes"][2]["primitives"][0]["indices"] == doc["meshes"][0]["primitives"][0]["indices"]);
	// POSITION min/max of frame 2's body (moved up by 1).
	const int pos = doc["meshes"][2]["primitives"][0]["attributes"]["POSITION"];
	CHECK(doc["accessors"][pos]["min"][1].get<double>() == 1.0);
	CHECK(doc["accessors"][pos]["max"][1].get<double>() == 2.0);
	// First frame visible without animation, the others hidden.
	CHECK(doc["nodes"][0]["scale"][0] == 1.0);
	CHECK(doc["nodes"][1]["scale"][0] == 0.0);
	const nlohmann::json& anim = doc["animations"][0];
	REQUIRE(anim["channels"].size() == 3);
	for (int f = 0; f < 3; ++f)
	{
		CHECK(anim["channels"][f]["target"]["node"] == f);
		CHECK(anim["channels"][f]["target"]["path"] == "scale");
		CHECK(anim["samplers"][f]["interpolation"] == "STEP");
	}
	// The middle frame has keys 0 (hidden), 0.25 (shown), 0.5 (hidden again).
	const int input = anim["samplers"][1]["input"];
	CHECK(doc["accessors"][input]["count"] == 3);
	CHECK(doc["accessors"][input]["min"][0] == 0.0);
	CHECK(doc["accessors"][input]["max"][0] == 0.5);
	// Every buffer view starts 4-byte aligned and lies inside the buffer.
	for (const nlohmann::json& v : doc["bufferViews"])
	{
		CHECK(v["byteOffset"].get<std::size_t>() % 4 == 0);
		CHECK(v["byteOffset"].get<std::size_t>() + v["byteLength"].get<std::size_t>() <=
			  doc["buffers"][0]["byteLength"].get<std::size_t>());
	}
}

TEST_CASE("glTF animation: bad frames are one-line errors", "[gltf]")
{
	CHECK_THROWS_WITH(GltfAnimationRecorder({}), Catch::Contains("no parts"));
	GltfAnimationRecorder rec({trianglePart("body")});
	CHECK_THROWS_WITH(rec.glb(), Catch::Contains("no frame recorded"));
	const Eigen::MatrixX3d a = triangle(0.0);
	rec.addFrame(0.1, {&a});
	CHECK_THROWS_WITH(rec.addFrame(0.1, {&a}), Catch::Contains("is not after the previous frame"));
	CHECK_THROWS_WITH(rec.addFrame(0.2, {&a, &a}), Catch::Contains("2 vertex arrays for 1 parts"));
	const Eigen::MatrixX3d two = a.topRows(2);
	CHECK_THROWS_WITH(rec.addFrame(0.2, {&two}), Catch::Contains("fewer vertices than its faces use"));
	Eigen::MatrixX3d nan = a;
	nan(0, 0) = std::nan("");
	CHECK_THROWS_WITH(rec.addFrame(0.2, {&nan}), Catch::Contains("non-finite coordinates"));
	CHECK(rec.frameCount() == 1);
	// One frame: a still file (no animation, nothing to switch).
	const std::string glb = rec.glb();
	const nlohmann::json doc = nlohmann::json::parse(glb.substr(20, u32(glb, 12)));
	CHECK_FALSE(doc.contains("animations"));
}
