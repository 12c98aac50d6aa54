// bodyfit-drape end to end: a short run of a bundled scene writes the metrics JSON (docs/DESIGN.md sec. 6 fields), the
// two-view PNG of the scene's size and the OBJ frames; bad input exits 2 with a one-line reason naming the problem.
#include "support/run_program.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace
{

using bodyfit_test::readFile;

bodyfit_test::ProgramRun drape(const std::string& args)
{
	return bodyfit_test::runProgram(BODYFIT_DRAPE_EXE, args);
}

fs::path freshDir(const std::string& name)
{
	const fs::path d = fs::temp_directory_path() / name;
	fs::remove_all(d);
	fs::create_directories(d);
	return d;
}

} // namespace

TEST_CASE("bodyfit-drape runs a bundled scene and writes metrics, picture and frames", "[scene][cli]")
{
	const fs::path dir = freshDir("bodyfit_drape_cli");
	const std::string scene = std::string(BODYFIT_SCENE_DIR) + "/skirt_drop.json";
	const bodyfit_test::ProgramRun r =
		drape(bodyfit_test::quoted(scene) + " --steps 12 --metrics " + bodyfit_test::quoted((dir / "m.json").string()) +
			  " --png " + bodyfit_test::quoted((dir / "p.png").string()) + " --frames " +
			  bodyfit_test::quoted((dir / "frames").string()));
	INFO(r.err);
	REQUIRE(r.exitCode == 0);
	const nlohmann::json m = nlohmann::json::parse(readFile(dir / "m.json"));
	for (const char* key : {"steps", "nodes", "ms_per_step", "collision_ms_per_step", "nodes_inside_body",
							"max_nodes_inside_body", "mean_contact_gap_m", "nan_nodes"})
		CHECK(m.contains(key));
	CHECK(m["steps"] == 12);
	CHECK(m["nodes"] == 720); // the bundled skirt mesh has 720 vertices
	CHECK(m["nan_nodes"] == 0);
	CHECK(m["collider"] == "ellipsoids");
	// PNG of the scene's render size (skirt_drop uses the default 1200 x 900).
	const std::string png = readFile(dir / "p.png");
	REQUIRE(png.size() > 24);
	auto be32 = [&](int at) {
		return (unsigned(std::uint8_t(png[at])) << 24) | (unsigned(std::uint8_t(png[at + 1])) << 16) |
			   (unsigned(std::uint8_t(png[at + 2])) << 8) | unsigned(std::uint8_t(png[at + 3]));
	};
	CHECK(be32(16) == 1200u);
	CHECK(be32(20) == 900u);
	// Frames every 10 steps (output.frame_every default), plus the first and the last.
	CHECK(fs::exists(dir / "frames" / "frame_00000.obj"));
	CHECK(fs::exists(dir / "frames" / "frame_00010.obj"));
	CHECK(fs::exists(dir / "frames" / "frame_00012.obj"));
	const nlohmann::json frames = nlohmann::json::parse(readFile(dir / "frames" / "frames.json"));
	CHECK(frames["frames"].size() == 3);
	CHECK(r.err.find("step 12/12") != std::string::npos); // progress line on stderr
	fs::remove_all(dir);
}

TEST_CASE("bodyfit-drape: bad input exits 2 with one line naming the problem", "[scene][cli]")
{
	const fs::path dir = freshDir("bodyfit_drape_cli_bad");
	const std::string scene = std::string(BODYFIT_SCENE_DIR) + "/skirt_drop.json";
	struct Case
	{
		std::string args, expected;
	};
	const fs::path badScene = dir / "bad.json";
	{
		std::ofstream out(badScene);
		out << R"({"body": {"mesh": "x.obj"}, "collider": "none", "garment": {"type": "patch"}})";
	}
	const std::vector<Case> cases = {
		{"", "missing SCENE.json"},
		{"\"" + scene + "\" --frobnicate", "unknown option --frobnicate"},
		{"\"" + scene + "\" --collider spheres", "collider kind 'spheres'"},
		{"\"" + scene + "\" --steps -3", "--steps: '-3'"},
		{"\"" + scene + "\" --body /no/such.obj", "/no/such.obj"},
		{"/no/such/scene.json", "/no/such/scene.json: cannot open scene file"},
		{"\"" + badScene.string() + "\"", "bad.json: body.mesh: file"},
	};
	for (const Case& c : cases)
	{
		const bodyfit_test::ProgramRun r = drape(c.args);
		INFO(c.args << " -> " << r.err);
		CHECK(r.exitCode == 2);
		CHECK(r.err.find(c.expected) != std::string::npos);
		CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
	}
	const bodyfit_test::ProgramRun help = drape("--help");
	CHECK(help.exitCode == 0);
	CHECK(help.out.find("usage: bodyfit-drape SCENE.json") == 0);
	fs::remove_all(dir);
}
