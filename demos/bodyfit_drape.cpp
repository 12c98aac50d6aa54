// bodyfit-drape: runs a drape scene headless (docs/DESIGN.md sec. 6).
//   bodyfit-drape SCENE.json [--body MESH] [--ellipsoids FIT.json] [--collider KIND] [--steps N] [--surface S]
//                 [--frames DIR] [--metrics OUT.json] [--png OUT.png] [--show body|ellipsoids]
// Exit status: 0 success, 2 bad input (one-line reason on stderr), 1 failure while running or writing.

#ifdef BODYFIT_HAVE_RENDER
#include "render/offscreen_renderer.h"
#endif
#include "bodyfit/drape/gltf_animation.h"
#include "bodyfit/drape/scene.h"
#include "bodyfit/drape/simulation.h"
#include "bodyfit/drape/stability.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/input_files.h"
#include "bodyfit/fitting/mesh_io.h"
#include "common/cli.h"

#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>

namespace
{

const char* kUsage =
	"usage: bodyfit-drape SCENE.json [--body MESH] [--ellipsoids FIT.json] [--collider KIND] [--steps N]\n"
	"                     [--surface tight|ellipsoids] [--frames DIR] [--metrics OUT.json] [--png OUT.png] [--show body|ellipsoids]\n"
	"                     [--png-zoom X,Y,Z,R] [--skin-mesh] [--no-lift-edges]\n"
	"\n"
	"Runs a cloth scene (demos/scenes/*.json) headless with Bullet and writes metrics and pictures.\n"
	"  --body MESH          body mesh instead of the scene's body.mesh\n"
	"  --ellipsoids FIT     fitted ellipsoid JSON (from bodyfit-fit) instead of the scene's body.ellipsoids/fit\n"
	"  --collider KIND      ellipsoids | mesh-bvh | convex-hull-compound | ellipsoids-sdf | none\n"
	"                       (overrides collider.kind)\n"
	"  --surface S          tight (the skin field inside the union, default) | ellipsoids (the paper's\n"
	"                       pure ellipsoid response); overrides collider.surface\n"
	"  --skin-mesh          animated body, tight surface: also decide the joints on the skinned mesh of\n"
	"                       the instant (opt-in, collider.skin_mesh; tighter, ~5x the collider's cost)\n"
	"  --no-lift-edges      tight surface, static or rigidly moving body: keep nodes at the skin offset\n"
	"                       and let long edges sag into curved skin between them (collider.lift_edges:\n"
	"                       false; by default such edges are lifted off the skin)\n"
	"  --steps N            number of steps (default: the scene's solver.steps)\n"
	"  --frames DIR         write the cloth as DIR/frame_NNNNN.obj every output.frame_every steps (and\n"
	"                       an animated body's skinned mesh as DIR/body_NNNNN.obj), DIR/frames.json\n"
	"                       (step, time, body pose per frame) and DIR/animation.glb: body + cloth of\n"
	"                       every frame as one glTF 2.0 animation that any glTF viewer plays\n"
	"  --metrics OUT.json   write the metrics (steps, nodes, ms_per_step, collision_ms_per_step,\n"
	"                       nodes_inside_body, max_nodes_inside_body, mean_contact_gap_m, nan_nodes, ...)\n"
	"  --png OUT.png        picture of the final state: front and side views, body (or ellipsoids) + cloth\n"
	"  --show WHAT          draw the body mesh (default) or the ellipsoids in the picture\n"
	"  --png-zoom X,Y,Z,R   close-up: both views frame the square of half size R around the world point\n"
	"                       (X, Y, Z) instead of the whole scene (metres; R in 0.01..10)\n"
	"Progress goes to stderr, a summary to stdout. Exit status: 0 ok, 2 bad input, 1 failure.\n";

/// A run stopped by BlowUpWatch (exit 1: the scene passed every range check, so this is a failure, not bad input).
struct BlownUp : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

[[noreturn]] void badInput(const std::string& message)
{
	std::cerr << "bodyfit-drape: error: " << message << "\n";
	std::exit(2);
}

struct Args
{
	std::string scene, body, ellipsoids, collider, surface, frames, metrics, png, show;
	int steps = -1;
	bool skinMesh = false; ///< --skin-mesh
	bool noLiftEdges = false; ///< --no-lift-edges
	std::optional<Eigen::Vector4d> pngZoom; ///< --png-zoom: centre x, y, z and half size R (metres)
};

/// --png-zoom X,Y,Z,R: four finite numbers, |X|, |Y|, |Z| <= 1000 m, R in 0.01..10 m.
Eigen::Vector4d parsePngZoom(const std::string& v)
{
	const std::string what = "--png-zoom: '" + v + "' is not X,Y,Z,R";
	if (std::count(v.begin(), v.end(), ',') != 3)
		badInput(what + " (four comma-separated numbers in metres)");
	Eigen::Vector4d out;
	std::size_t pos = 0;
	for (int k = 0; k < 4; ++k)
	{
		const std::size_t comma = k < 3 ? v.find(',', pos) : v.size();
		const std::string field = v.substr(pos, comma - pos);
		char* end = nullptr;
		out[k] = std::strtod(field.c_str(), &end);
		if (field.empty() || *end != '\0' || !std::isfinite(out[k]))
			badInput(what + " (field " + std::to_string(k + 1) + " is not a finite number)");
		pos = comma + 1;
	}
	if (out.head<3>().cwiseAbs().maxCoeff() > 1000.0)
		badInput(what + " (the centre must lie within 1000 m of the origin)");
	if (!(out[3] >= 0.01 && out[3] <= 10.0))
		badInput(what + " (R must be in 0.01..10 m)");
	return out;
}

Args parseArgs(int argc, char** argv)
{
	Args a;
	for (int i = 1; i < argc; ++i)
	{
		const std::string s = argv[i];
		auto value = [&]() -> std::string {
			if (i + 1 >= argc)
				badInput("option " + s + " needs a value (see --help)");
			return argv[++i];
		};
		if (s == "--help" || s == "-h")
		{
			std::cout << kUsage;
			std::exit(0);
		}
		else if (s == "--body")
			a.body = value();
		else if (s == "--ellipsoids")
			a.ellipsoids = value();
		else if (s == "--collider")
			a.collider = value();
		else if (s == "--surface")
			a.surface = value();
		else if (s == "--skin-mesh")
			a.skinMesh = true;
		else if (s == "--no-lift-edges")
			a.noLiftEdges = true;
		else if (s == "--frames")
			a.frames = value();
		else if (s == "--metrics")
			a.metrics = value();
		else if (s == "--png")
			a.png = value();
		else if (s == "--png-zoom")
			a.pngZoom = parsePngZoom(value());
		else if (s == "--show")
		{
			a.show = value();
			if (a.show != "body" && a.show != "ellipsoids")
				badInput("--show: '" + a.show + "' is not one of body, ellipsoids");
		}
		else if (s == "--steps")
		{
			const std::string v = value();
			char* end = nullptr;
			const long n = std::strtol(v.c_str(), &end, 10);
			if (v.empty() || *end != '\0' || n < 0 || n > 10000000)
				badInput("--steps: '" + v + "' is not an integer in 0..10000000");
			a.steps = int(n);
		}
		else if (!s.empty() && s[0] == '-')
			badInput("unknown option " + s + " (see --help)");
		else if (a.scene.empty())
			a.scene = s;
		else
			badInput("unexpected argument '" + s + "' (one scene file only)");
	}
	if (a.scene.empty())
		badInput("missing SCENE.json (see --help)");
	if (a.pngZoom && a.png.empty())
		badInput("--png-zoom: needs --png OUT.png (it frames that picture)");
#ifndef BODYFIT_HAVE_RENDER
	if (!a.png.empty())
		badInput("--png: this build has no renderer (OSMesa and libpng were not found when it was configured)");
#endif
	return a;
}

/// --metrics, --png and --frames can be written, and none of them is an input of the run: checked after the scene
/// is read and before the body is loaded, so that a bad output path is not found after the whole simulation.
/// \throws bodyfit_cli::UsageError naming the option.
void requireOutputs(const Args& a, const bodyfit::drape::Scene& scene)
{
	if (!a.metrics.empty())
		bodyfit_cli::requireWritableOutput(a.metrics, "--metrics");
	if (!a.png.empty())
		bodyfit_cli::requireWritableOutput(a.png, "--png");
	if (!a.frames.empty())
		bodyfit_cli::requireWritableOutput(a.frames, "--frames", /*directory=*/true);
	bodyfit_cli::requireDistinctOutputs({{"--metrics", a.metrics}, {"--png", a.png}, {"--frames", a.frames}},
										{{"scene file", scene.path},
										 {"body mesh", a.body.empty() ? scene.body.mesh : a.body},
										 {"ellipsoid file", a.ellipsoids.empty() ? scene.body.ellipsoids : a.ellipsoids},
										 {"garment mesh", scene.garment.mesh}});
}

#ifdef BODYFIT_HAVE_RENDER
bodyfit::render::DrawMesh toDraw(const bodyfit::TriMesh& m, const Eigen::Vector3f& color, bool twoSided)
{
	bodyfit::render::DrawMesh d;
	d.V = m.V;
	d.F = m.F;
	d.color = color;
	d.twoSided = twoSided;
	return d;
}
#endif

/// The parts of DIR/animation.glb: the body (skinned when animated, posed otherwise) and the cloth.
bodyfit::drape::GltfAnimationRecorder gltfRecorder(const bodyfit::drape::DrapeSimulation& sim)
{
	bodyfit::drape::GltfPart body{"body", Eigen::Vector3f(0.86f, 0.72f, 0.62f), false, sim.body().mesh.F};
	bodyfit::drape::GltfPart cloth{"cloth", Eigen::Vector3f(0.22f, 0.42f, 0.78f), true, sim.garment().mesh.F};
	return bodyfit::drape::GltfAnimationRecorder({body, cloth});
}

void writeFrame(const std::string& dir, const bodyfit::drape::DrapeSimulation& sim, nlohmann::json& index,
				bodyfit::drape::GltfAnimationRecorder& gltf)
{
	char name[64], bodyName[64];
	std::snprintf(name, sizeof(name), "frame_%05d.obj", sim.stepsDone());
	std::snprintf(bodyName, sizeof(bodyName), "body_%05d.obj", sim.stepsDone());
	const bodyfit::TriMesh cloth = sim.clothMesh(), body = sim.bodyMeshWorld();
	bodyfit::saveTriMesh((std::filesystem::path(dir) / name).string(), cloth);
	if (sim.skinnedDriver())
		bodyfit::saveTriMesh((std::filesystem::path(dir) / bodyName).string(), body);
	gltf.addFrame(sim.time(), {&body.V, &cloth.V});
	const Eigen::Isometry3d pose = sim.bodyPose();
	nlohmann::json m = nlohmann::json::array();
	for (int r = 0; r < 4; ++r)
		m.push_back({pose.matrix()(r, 0), pose.matrix()(r, 1), pose.matrix()(r, 2), pose.matrix()(r, 3)});
	index["frames"].push_back({{"step", sim.stepsDone()}, {"time_s", sim.time()}, {"file", name}, {"body_pose", m}});
	if (sim.skinnedDriver())
		index["frames"].back()["body_file"] = bodyName;
}

/// The run's summary on stdout: scene, collider, cloth, steps, cost, quality, contacts (and an animated body's clip).
void printSummary(const bodyfit::drape::Scene& scene, const bodyfit::drape::DrapeSimulation& sim,
				  const nlohmann::json& metrics, int steps)
{
	using bodyfit::drape::toString;
	std::cout << "scene      " << scene.name << " (" << scene.path << ")\n"
			  << "collider   " << sim.colliderDescription() << "\n"
			  << "cloth      " << toString(scene.garment.type) << ", " << sim.nodeCount() << " nodes, effects:";
	for (const std::string& e : scene.effects.listed())
		std::cout << " " << e;
	std::cout << "\n";
	std::printf("steps      %d x %.5f s (%d substeps), %.3f s simulated\n", steps, scene.solver.dt,
				scene.solver.substeps, sim.time());
	std::printf("cost       %.3f ms/step (median %.3f), collision %.3f ms/step, %.0f ns/node/step\n",
				metrics["ms_per_step"].get<double>(), metrics["ms_per_step_median"].get<double>(),
				metrics["collision_ms_per_step"].get<double>(), metrics["ns_per_node_step"].get<double>());
	std::cout << "quality    nodes inside body: end " << metrics["nodes_inside_body"] << ", max "
			  << metrics["max_nodes_inside_body"] << " (sampled every " << scene.sampleEvery
			  << " steps); inside ellipsoids " << metrics["nodes_inside_ellipsoids"] << "; NaN nodes "
			  << metrics["nan_nodes"] << "\n"
			  << "contact    " << metrics["contact_nodes"] << " nodes, mean gap to skin "
			  << metrics["mean_contact_gap_m"] << " m\n";
	if (metrics.contains("animation"))
		std::printf("body       clip '%s' x %.3g (loop %s), posed every substep: %.3f ms/step pose + skin + ellipsoids, "
					"%.3f ms/step shape write (medians)\n",
					metrics["animation"]["clip"].get<std::string>().c_str(), metrics["animation"]["speed"].get<double>(),
					metrics["animation"]["loop"].get<bool>() ? "on" : "off",
					metrics["body_skin_ms_per_step_median"].get<double>(),
					metrics["body_write_ms_per_step_median"].get<double>());
	if (metrics.contains("bone_field"))
	{
		const nlohmann::json& b = metrics["bone_field"];
		std::printf("tight      %.1f%% of the tested nodes decided on the bind-pose field in a bone's frame, %.1f%% on the "
					"skinned mesh, %lld by the union (fallback)",
					100.0 * b["field_share"].get<double>(), 100.0 * b.value("mesh_share", 0.0),
					b["fallback_nodes"].get<long long>());
		for (std::size_t k = 0; k < b["fallback_at"].size() && k < 4; ++k)
		{
			const nlohmann::json& w = b["fallback_at"][k];
			std::printf("%s ellipsoid %d (%s, %s) %.0f%%", k == 0 ? ", most at" : ",", w["ellipsoid"].get<int>(),
						w["mode"].get<std::string>().c_str(), w["bone"].get<std::string>().c_str(),
						100.0 * w["share"].get<double>());
		}
		std::printf("\n");
	}
}

/// --metrics (the JSON) and --frames (frames.json and animation.glb; the OBJ files were written while stepping).
void writeOutputs(const Args& args, const bodyfit::drape::DrapeSimulation& sim, const nlohmann::json& metrics,
				  const nlohmann::json& frameIndex, const std::optional<bodyfit::drape::GltfAnimationRecorder>& gltf)
{
	if (!args.metrics.empty())
	{
		std::ofstream out(args.metrics);
		if (!out)
			throw std::runtime_error(args.metrics + ": cannot open for writing");
		out << metrics.dump(2) << "\n";
		if (!out)
			throw std::runtime_error(args.metrics + ": write failed");
		std::cout << "metrics    " << args.metrics << "\n";
	}
	if (!args.frames.empty())
	{
		std::ofstream out((std::filesystem::path(args.frames) / "frames.json").string());
		out << frameIndex.dump(1) << "\n";
		if (!out)
			throw std::runtime_error(args.frames + "/frames.json: write failed");
		const std::string glb = (std::filesystem::path(args.frames) / "animation.glb").string();
		gltf->writeGlb(glb);
		std::cout << "frames     " << frameIndex["frames"].size() << " frames in " << args.frames
				  << (sim.skinnedDriver() ? " (cloth and body OBJ)" : " (cloth OBJ)") << ", all in " << glb
				  << "\n";
	}
}

/// --png: front and side views of the final state, body (or ellipsoids) and cloth.
void writePicture(const Args& args, const bodyfit::drape::Scene& scene, const bodyfit::drape::DrapeSimulation& sim)
{
#ifdef BODYFIT_HAVE_RENDER
	using namespace bodyfit;
	if (!args.png.empty())
	{
		std::vector<render::DrawMesh> meshes;
		if (scene.render.showEllipsoids && !sim.body().ellipsoids.empty())
		{
			for (const Ellipsoid& e : sim.ellipsoidsWorld())
			{
				meshes.push_back(render::ellipsoidMesh(e.center, e.rotation, e.radii));
				meshes.back().color = Eigen::Vector3f(0.85f, 0.68f, 0.55f);
			}
		}
		else
			meshes.push_back(toDraw(sim.bodyMeshWorld(), Eigen::Vector3f(0.86f, 0.72f, 0.62f), false));
		meshes.push_back(toDraw(sim.clothMesh(), Eigen::Vector3f(0.22f, 0.42f, 0.78f), true));
		render::RenderOptions ro;
		ro.width = scene.render.width;
		ro.height = scene.render.height;
		if (args.pngZoom)
		{
			ro.zoomCenter = args.pngZoom->head<3>();
			ro.zoomHalfSize = (*args.pngZoom)[3];
		}
		render::writePng(args.png, render::renderTwoViews(meshes, ro));
		std::cout << "picture    " << args.png << " (" << ro.width << "x" << ro.height << ", front | side)\n";
	}
#else
	(void)args, (void)scene, (void)sim; // parseArgs refuses --png in a build without the renderer
#endif
}

/// The scene file with the command line's overrides (collider, surface, skin mesh, edge lift, what to show), the
/// extra input files checked, and the outputs checked (requireOutputs).
bodyfit::drape::Scene sceneWithOverrides(const Args& args)
{
	using namespace bodyfit;
	using namespace bodyfit::drape;
	Scene scene = loadScene(args.scene);
	if (!args.collider.empty())
		scene.collider.kind = colliderKindFromString(args.collider);
	if (!args.surface.empty() && args.surface != "tight" && args.surface != "ellipsoids")
		throw InvalidInputError("--surface: '" + args.surface + "' is not one of tight, ellipsoids");
	if (!args.surface.empty())
		scene.collider.tightSurface = args.surface == "tight";
	if (args.skinMesh)
		scene.collider.skinMesh = true;
	if (args.noLiftEdges)
		scene.collider.liftEdges = false;
	if (!args.show.empty())
		scene.render.showEllipsoids = args.show == "ellipsoids";
	for (const std::string* p : {&args.body, &args.ellipsoids})
		if (!p->empty() && !inputFileProblem(*p).empty())
			throw InvalidInputError(*p + ": cannot open file: " + inputFileProblem(*p));
	requireOutputs(args, scene);
	return scene;
}

/// The scene's body (or --body / --ellipsoids), its load and fit warnings on stderr.
bodyfit::drape::BodyData loadBodyReporting(const Args& args, const bodyfit::drape::Scene& scene)
{
	std::cerr << "bodyfit-drape: loading body " << (args.body.empty() ? scene.body.mesh : args.body) << "\n";
	bodyfit::drape::BodyData body = bodyfit::drape::loadBody(scene, args.body, args.ellipsoids);
	for (const std::string& w : body.loadWarnings)
		std::cerr << "bodyfit-drape: warning: mesh: " << w << "\n";
	for (const std::string& w : body.fitWarnings) // the fit repeats the load warnings: print those once
		if (std::find(body.loadWarnings.begin(), body.loadWarnings.end(), w) == body.loadWarnings.end())
			std::cerr << "bodyfit-drape: warning: fit: " << w << "\n";
	return body;
}

/// Runs the steps with progress on stderr, stops on a blow-up, writes the frames as they come, then the summary,
/// the metrics and the picture. Returns the exit status.
int runScene(const Args& args, const bodyfit::drape::Scene& scene, bodyfit::drape::DrapeSimulation& sim)
{
	using namespace bodyfit::drape;
	const int steps = args.steps >= 0 ? args.steps : scene.solver.steps;
	nlohmann::json frameIndex;
	std::optional<GltfAnimationRecorder> gltf;
	try
	{
		// Output directories are created as needed (e.g. --png out/skirt.png on a fresh checkout).
		for (const std::string* p : {&args.metrics, &args.png})
			if (!p->empty() && std::filesystem::path(*p).has_parent_path())
				std::filesystem::create_directories(std::filesystem::path(*p).parent_path());
		if (!args.frames.empty())
		{
			std::filesystem::create_directories(args.frames);
			frameIndex["scene"] = scene.path;
			frameIndex["frames"] = nlohmann::json::array();
			gltf.emplace(gltfRecorder(sim));
			writeFrame(args.frames, sim, frameIndex, *gltf);
		}
		std::cerr << "bodyfit-drape: " << scene.name << ", " << sim.nodeCount() << " cloth nodes, "
				  << sim.colliderDescription() << "\n";
		for (const std::string& w : sim.warnings()) // also in the metrics JSON ("warnings")
			std::cerr << "bodyfit-drape: warning: " << w << "\n";
		auto lastPrint = std::chrono::steady_clock::now() - std::chrono::seconds(1);
		auto progress = [&](int done, int total, const StepStats& st) {
			const auto now = std::chrono::steady_clock::now();
			if (done != total && now - lastPrint < std::chrono::milliseconds(250))
				return;
			lastPrint = now;
			std::fprintf(stderr, "\rstep %d/%d  t=%.3f s  %.2f ms/step (collision %.2f)   ", done, total, sim.time(),
						 st.seconds * 1e3, st.collisionSeconds * 1e3);
			if (done == total)
				std::fprintf(stderr, "\n");
		};
		const BlowUpWatch watch(sim);
		auto afterStep = [&](int k) {
			const std::string blowUp = watch.check(sim);
			if (!blowUp.empty()) // a run must not end with exit 0 and plausible metrics after NaN or a launch
				throw BlownUp("the simulation blew up at step " + std::to_string(k) + ": " + blowUp);
			if (!args.frames.empty() && (k % scene.frameEvery == 0 || k == steps))
				writeFrame(args.frames, sim, frameIndex, *gltf);
		};
		nlohmann::json metrics = runAndMeasure(sim, steps, progress, afterStep);

		printSummary(scene, sim, metrics, steps);
		writeOutputs(args, sim, metrics, frameIndex, gltf);
		writePicture(args, scene, sim);
	}
	catch (const BlownUp& e)
	{
		std::cerr << "\nbodyfit-drape: error: " << e.what() << "\n";
		return 1;
	}
	catch (const std::exception& e)
	{
		std::cerr << "\nbodyfit-drape: " << e.what() << "\n";
		return 1;
	}
	return 0;
}

} // namespace

int main(int argc, char** argv)
{
	using namespace bodyfit;
	using namespace bodyfit::drape;
	const Args args = parseArgs(argc, argv);

	Scene scene;
	BodyData body;
	std::unique_ptr<DrapeSimulation> sim;
	try
	{
		scene = sceneWithOverrides(args);
		body = loadBodyReporting(args, scene);
		sim = std::make_unique<DrapeSimulation>(scene, body);
	}
	catch (const bodyfit_cli::UsageError& e)
	{
		badInput(e.what());
	}
	catch (const FormatError& e)
	{
		badInput(e.what());
	}
	catch (const MeshLoadError& e)
	{
		badInput(e.what());
	}
	catch (const InvalidInputError& e)
	{
		badInput(e.what());
	}
	catch (const std::exception& e) // a bug: every bad input above is a typed error
	{
		std::cerr << "bodyfit-drape: internal error: " << e.what() << "\n";
		return 1;
	}
	return runScene(args, scene, *sim);
}
