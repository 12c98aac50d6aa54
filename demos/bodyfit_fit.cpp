// bodyfit-fit: fit ellipsoids to a body mesh and write them as JSON (docs/DESIGN.md sec. 6).
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/skin_field.h"
#include "bodyfit/fitting/skinned_fit.h"
#include "common/cli.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <chrono>
#include <optional>
#include <utility>

namespace
{

const char* kUsage = R"(usage: bodyfit-fit MESH -o OUT.json [options]

Fits ellipsoids to a body mesh (any format assimp reads) and writes them as JSON. A rigged file (a
skinned mesh: glTF/GLB, FBX, ...) is fitted in its bind pose and the fit records the bone bindings
that let the ellipsoids follow every clip of the rig.

  -o OUT.json            output file (its directory is created if missing)
  --mu-torso R           error threshold E_j for the torso (default 0.012 = 1.2% of the height)
  --mu-limbs R           error threshold for head, arms and legs (default 0.009 = 0.9% of the height)
  --absolute             thresholds are in metres, not fractions of the height (the lengths not given:
                         a threshold left out, K-means sigma, triangle-cover spacing keep their relative
                         defaults, converted to metres with the height like everything else)
  --max-ellipsoids N     budget: stop refining at N ellipsoids (default 128)
  --up y|z               up axis of the file (default y; z files are rotated to +y up)
  --scale S              multiply coordinates by S to get metres (default 1; 0.01 for centimetres)
  --export-mesh OUT.obj|OUT.ply
                         also write the ellipsoids as a triangle mesh (coloured by region in PLY)
  --segments OUT.ply|OUT.obj
                         also write the mesh coloured by body region, with a small marker at every
                         feature point (black: head top, hands, feet; white: neck, elbows, knees;
                         magenta: perineum, armpits)
  --skinned-mesh NAME    rigged file: the skinned mesh (or its node) to fit (default: the skinned mesh
                         with the most vertices)
  --no-segmentation      fit the whole mesh as one region (generic path)
  --no-triangle-cover    skip the triangle cover: the union then encloses every vertex but not all of
                         the skin between two ellipsoids (slivers stick out, cloth can rest inside the body)
  --no-skin-field        do not bake the skin field (by default OUT.skin is written next to OUT.json: a
                         narrow-band signed distance field of the skin the collider can contact tightly,
                         fitting/include/bodyfit/fitting/skin_field.h; for a rigged file, of its bind
                         pose: the collider reads it in the frames of the bones)
  --skin-voxel M         skin field voxel size in metres (default 0.005; 0.0005 - 0.05)
  --skin-clamp M         skin field band: distances are kept within M metres of the skin (default 0.012;
                         at least 2 voxels, at most 0.1)
  -h, --help             this text

E_j is the paper's fitting error: the mean radial distance of an ellipsoid's vertices to its surface.
The whole-mesh path (--no-segmentation, or a failed segmentation) uses the torso threshold.
The body is segmented into 15 regions (head, 6 torso parts, upper/lower arms and legs; the mesh must be
+y up and face +z, so the subject's left is +x) and each region is fitted on its own. A mesh that is
not a standing human is fitted as one region, with a warning. A body made of several meshes (separate
head or hands a few mm away, eyes inside) is fitted as one body; components far from it (props) are
ignored with a warning. Exit status: 0 ok, 2 bad input (one-line reason on stderr), 1 internal error.
)";

// Large values switch to %g instead of being cut off at the buffer's end (a 1e30 m error used to print 31 digits).
std::string mm(double metres)
{
	char buf[64];
	std::snprintf(buf, sizeof buf, std::abs(metres) < 1e9 ? "%.2f mm" : "%.6g mm", metres * 1000.0);
	return buf;
}

std::string ms(double v)
{
	char buf[64];
	std::snprintf(buf, sizeof buf, v < 10.0 ? "%.2f ms" : v < 1e12 ? "%.1f ms" : "%.6g ms", v);
	return buf;
}

/// Bakes the skin field of the fitted mesh into fit.skinField (timing "skin_field").
void bakeSkinField(const bodyfit::TriMesh& mesh, const bodyfit::SkinFieldOptions& options, bodyfit::BodyFit& fit)
{
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	for (const bodyfit::FittedEllipsoid& f : fit.ellipsoids)
		ellipsoids.push_back(f.ellipsoid);
	const auto t0 = std::chrono::steady_clock::now();
	fit.skinField = std::make_shared<const bodyfit::SkinField>(bodyfit::bakeSkinField(mesh, ellipsoids, options));
	fit.setTiming("skin_field", std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

void printSkinField(const bodyfit::BodyFit& fit, const std::string& outPath, const std::string& why)
{
	if (!fit.skinField)
	{
		std::cout << "  skin      no skin field (" << why << ")\n";
		return;
	}
	const bodyfit::SkinField& f = *fit.skinField;
	char size[64];
	std::snprintf(size, sizeof size, "%.2f MB", double(bodyfit::skinFieldBytes(f).size()) / (1024.0 * 1024.0));
	std::cout << "  skin      field in " << bodyfit::skinFieldPathFor(outPath) << ": " << size << ", " << f.storedBricks()
			  << " of " << f.brickCount() << " bricks stored, voxel " << mm(f.voxel) << ", clamp " << mm(f.clamp)
			  << ", max error " << mm(f.maxError) << ", baked in " << ms(fit.timingMs("skin_field")) << "\n";
	if (f.holeBricks > 0)
		std::cout << "  warning   the skin has holes (open edges): " << f.holeBricks
				  << " bricks of the skin field close them where the inside meets the outside through them\n";
}

void printSummary(const bodyfit::LoadedMesh& loaded, const bodyfit::BodyFit& fit, const std::string& regions,
				  const std::string& out, const std::string& exportPath)
{
	const bodyfit::MeshReport& r = loaded.report;
	const double scale = fit.params.relativeToHeight ? fit.source.height : 1.0;
	std::cout << "bodyfit-fit: " << r.path << "\n";
	std::cout << "  mesh      " << loaded.mesh.vertexCount() << " vertices, " << loaded.mesh.faceCount()
			  << " faces used (file: " << r.fileVertices << " vertices, " << r.fileFaces << " faces; welded "
			  << r.weldedVertices << ", degenerate faces " << r.degenerateFaces << ", components " << r.components;
	if (r.droppedComponentVertices > 0)
		std::cout << ", " << r.droppedComponentVertices << " vertices in detached components ignored";
	std::cout << ")\n";
	std::cout << "  frame     file up " << bodyfit::toString(r.up)
			  << (r.up == bodyfit::UpAxis::Y ? " (no rotation)" : " (rotated to +y up)") << ", scale " << r.scale
			  << ", height " << fit.source.height << " m\n";
	std::cout << "  regions   " << regions << "\n";
	std::cout << "  fit       " << fit.ellipsoids.size() << " ellipsoids, refinement " << bodyfit::toString(fit.status)
			  << " (" << fit.splitsAccepted << " splits accepted, " << fit.splitsRejected << " rejected)\n";
	if (fit.timingMs("fitting.cover") > 0.0)
		std::cout << "  cover     skin between ellipsoids inside the union: " << fit.coverExtraPoints
				  << " extra points enclosed (pieces of boundary triangles), " << fit.coverRounds << " refit round(s)\n";
	else
		std::cout << "  cover     off (--no-triangle-cover)\n";
	std::cout << "  threshold mu_torso " << mm(fit.params.muTorso * scale) << ", mu_limbs "
			  << mm(fit.params.muLimbs * scale)
			  << (fit.params.relativeToHeight ? " (relative to height)" : " (absolute)") << "\n";
	std::cout << "  error     radial (paper E): mean " << mm(fit.meanRadialError()) << ", worst ellipsoid E_j "
			  << mm(fit.maxRadialError()) << "\n";
	std::cout << "  air gap   vertex to own ellipsoid surface: mean " << mm(fit.meanDistance()) << ", max "
			  << mm(fit.maxDistance()) << "\n";
	std::cout << "  timing    load " << ms(fit.timingMs("load")) << ", repair " << ms(fit.timingMs("repair"));
	if (fit.timingMs("segmentation") > 0.0)
		std::cout << ", segmentation " << ms(fit.timingMs("segmentation"));
	std::cout << ", fitting " << ms(fit.timingMs("fitting")) << " (k-means " << ms(fit.timingMs("fitting.kmeans"))
			  << ", mvee " << ms(fit.timingMs("fitting.mvee")) << ", error " << ms(fit.timingMs("fitting.error"))
			  << ", cover " << ms(fit.timingMs("fitting.cover")) << "), report " << ms(fit.timingMs("report")) << "\n";
	std::cout << "  output    " << out;
	if (!exportPath.empty())
		std::cout << ", " << exportPath;
	std::cout << "\n";
	if (fit.warnings.empty())
		std::cout << "  warnings  none\n";
	for (const std::string& w : fit.warnings)
		std::cout << "  warning   " << w << "\n";
}

bool hasExtension(const std::string& path, const char* ext)
{
	std::string e = std::filesystem::path(path).extension().string();
	for (char& c : e)
		c = char(std::tolower((unsigned char)c));
	return e == ext;
}

/// What the command line asks for, every argument checked before any work is done.
struct FitCommand
{
	std::string meshPath, outPath, exportPath, segmentsPath;
	std::string skinPath; ///< the skin field's side file ("" with --no-skin-field)
	bodyfit::SkinFieldOptions skinOptions;
	bodyfit::FitPipelineOptions options;
	std::string skinnedMesh; ///< --skinned-mesh NAME ("": the rig's largest skinned mesh)
	bool rigRequested = false;
};

/// The output paths: well-formed, writable, and none of them the input or each other (checked before the load and
/// the fit).
void checkOutputs(const bodyfit_cli::Args& args, FitCommand& c)
{
	using bodyfit_cli::UsageError;
	if (!args.has("-o"))
		throw UsageError("missing -o OUT.json (see --help)");
	c.outPath = args.value("-o");
	if (c.outPath.empty())
		throw UsageError("-o: empty file name");
	c.exportPath = args.value("--export-mesh");
	if (args.has("--export-mesh") && !hasExtension(c.exportPath, ".obj") && !hasExtension(c.exportPath, ".ply"))
		throw UsageError("--export-mesh: \"" + c.exportPath + "\" must end in .obj or .ply");
	c.segmentsPath = args.value("--segments");
	if (args.has("--segments") && !hasExtension(c.segmentsPath, ".obj") && !hasExtension(c.segmentsPath, ".ply"))
		throw UsageError("--segments: \"" + c.segmentsPath + "\" must end in .ply or .obj");
	if (args.has("--no-segmentation") && args.has("--segments"))
		throw UsageError("--segments needs the segmentation: drop --no-segmentation");
	bodyfit_cli::requireWritableOutput(c.outPath, "-o");
	if (args.has("--export-mesh"))
		bodyfit_cli::requireWritableOutput(c.exportPath, "--export-mesh");
	if (args.has("--segments"))
		bodyfit_cli::requireWritableOutput(c.segmentsPath, "--segments");
	c.skinPath = args.has("--no-skin-field") ? "" : bodyfit::skinFieldPathFor(c.outPath);
	if (!c.skinPath.empty())
		bodyfit_cli::requireWritableOutput(c.skinPath, "skin field (next to -o)");
	bodyfit_cli::requireDistinctOutputs({{"-o", c.outPath},
										 {"--export-mesh", c.exportPath},
										 {"--segments", c.segmentsPath},
										 {"skin field (next to -o)", c.skinPath}},
										{{"input mesh", c.meshPath}});
}

/// The skin field's and the fit's settings.
void readSettings(const bodyfit_cli::Args& args, FitCommand& c)
{
	using bodyfit_cli::UsageError;
	if (args.has("--no-skin-field") && (args.has("--skin-voxel") || args.has("--skin-clamp")))
		throw UsageError("--skin-voxel / --skin-clamp set the skin field: drop --no-skin-field");
	c.skinOptions.voxel = args.number("--skin-voxel", c.skinOptions.voxel, 0.0005, 0.05);
	c.skinOptions.clamp = args.number("--skin-clamp", c.skinOptions.clamp, 0.001, 0.1);
	if (!(c.skinOptions.clamp >= 2.0 * c.skinOptions.voxel))
		throw UsageError("--skin-clamp: " + std::to_string(c.skinOptions.clamp) + " m is less than 2 voxels (" +
						 std::to_string(2.0 * c.skinOptions.voxel) + " m)");

	bodyfit::FitPipelineOptions& options = c.options;
	options.load.up = args.choice("--up", {"y", "z"}, "y") == "z" ? bodyfit::UpAxis::Z : bodyfit::UpAxis::Y;
	options.load.scale = args.number("--scale", 1.0, 0.0, 1e9, /*open=*/true);
	options.segment = !args.has("--no-segmentation");
	options.fit.maxEllipsoids = args.integer("--max-ellipsoids", options.fit.maxEllipsoids, 1, 100000);
	options.fit.coverTriangles = !args.has("--no-triangle-cover");
	// Thresholds: fractions of the height, or metres with --absolute. Every length not given (the other
	// threshold, sigma, the cover spacing) keeps its relative default; the pipeline converts all of them with H.
	const bool absolute = args.has("--absolute");
	const double huge = absolute ? 10.0 : 1.0; // a threshold >= the whole body (10 m, or 100% of H) is a typo
	for (const auto& [flag, length] : {std::pair{"--mu-torso", &options.lengths.muTorso},
									   std::pair{"--mu-limbs", &options.lengths.muLimbs}})
		if (args.has(flag))
			*length = {args.number(flag, 0.0, 0.0, huge, /*open=*/true), !absolute};
	c.skinnedMesh = args.value("--skinned-mesh");
	c.rigRequested = args.has("--skinned-mesh");
}

FitCommand parseFitCommand(const bodyfit_cli::Args& args)
{
	FitCommand c;
	args.requirePositional(1, "MESH argument");
	c.meshPath = args.positional()[0];
	checkOutputs(args, c);
	readSettings(args, c);
	return c;
}

/// The fitted body, and its rig when the input is a rigged file (a skinned mesh): then its bind pose is fitted and
/// the fit records the bone bindings (skinned_fit.h).
struct FittedInput
{
	std::optional<bodyfit::Rig> rig;
	bodyfit::FitPipelineResult result;
};

FittedInput fitInput(const FitCommand& c)
{
	FittedInput in;
	if (c.rigRequested || bodyfit::hasSkinnedMesh(c.meshPath))
	{
		const auto t0 = std::chrono::steady_clock::now();
		in.rig = bodyfit::loadRig(c.meshPath, {c.options.load, c.skinnedMesh, /*requireAnimation=*/false});
		const double loadMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
		bodyfit::LoadedMesh bind{in.rig->bindMesh, in.rig->bindMesh, bodyfit::analyzeComponents(in.rig->bindMesh),
								 in.rig->report};
		in.result = bodyfit::fitLoadedMesh(std::move(bind), c.options,
										   std::filesystem::path(c.meshPath).filename().string(), loadMs);
		const auto tBind = std::chrono::steady_clock::now();
		bodyfit::BodyFit& fit = in.result.fit;
		fit.skinning = std::make_shared<const bodyfit::SkinBinding>(bodyfit::bindSkin(*in.rig, fit));
		fit.setTiming("skinning.bind",
					  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tBind).count());
	}
	else
		in.result = bodyfit::fitMeshFile(c.meshPath, c.options);
	return in;
}

/// The fit file (with the skin field beside it), the ellipsoid mesh and the segmentation preview, as asked.
void writeOutputs(const FitCommand& c, const bodyfit::FitPipelineResult& result)
{
	bodyfit_cli::ensureParentDirectory(c.outPath);
	bodyfit::writeEllipsoidJson(c.outPath, result.fit);
	if (!c.exportPath.empty())
	{
		bodyfit_cli::ensureParentDirectory(c.exportPath);
		bodyfit::exportEllipsoidMesh(c.exportPath, result.fit.ellipsoids);
	}
	if (!c.segmentsPath.empty())
	{
		bodyfit_cli::ensureParentDirectory(c.segmentsPath);
		Eigen::MatrixX3d colors;
		const bodyfit::TriMesh preview = bodyfit::segmentationPreview(result.loaded.mesh, result.segmentation, &colors);
		bodyfit::saveTriMesh(c.segmentsPath, preview, &colors);
	}
}

/// The warnings of the fit and of the load (what loading joined, kept or ignored of a body of several meshes, or
/// found far from the origin: mesh_io.h; the pipeline also puts these lines into the fit's warnings), on stderr.
void printWarnings(const bodyfit::FitPipelineResult& result)
{
	if (result.fallback)
		std::cerr << "bodyfit-fit: warning: " << result.fit.warnings.front() << "\n";
	for (const std::string& w : result.loaded.report.warnings)
		std::cerr << "bodyfit-fit: warning: " << w << "\n";
}

/// The summary on stdout: the load, the fit, the outputs, the skin field and the rig.
void printReport(const FitCommand& c, const FittedInput& in)
{
	const bodyfit::FitPipelineResult& result = in.result;
	const std::string regionSummary =
		!c.options.segment ? "whole mesh as one region (--no-segmentation)"
		: result.fallback  ? "whole mesh as one region (segmentation failed)"
						   : std::to_string(bodyfit::kBodyRegionCount) + " body regions (segmentation)";
	std::string extraOutputs = c.exportPath;
	if (!c.segmentsPath.empty())
		extraOutputs += (extraOutputs.empty() ? "" : ", ") + c.segmentsPath;
	printSummary(result.loaded, result.fit, regionSummary, c.outPath, extraOutputs);
	printSkinField(result.fit, c.outPath, "--no-skin-field");
	if (in.rig)
		std::cout << "  skinning  rig with " << in.rig->boneCount() << " bones, " << in.rig->clips.size()
				  << " clip(s): bind pose fitted, " << result.fit.skinning->vertexPoints + result.fit.skinning->coverPoints
				  << " skin points bound to the ellipsoids (" << ms(result.fit.timingMs("skinning.bind")) << ")\n";
}

} // namespace

int main(int argc, char** argv)
{
	return bodyfit_cli::runMain("bodyfit-fit", [&] {
		const bodyfit_cli::Args args(argc, argv,
									 {{"-o", true, "OUT.json"},
									  {"--mu-torso", true, "R"},
									  {"--mu-limbs", true, "R"},
									  {"--absolute", false, ""},
									  {"--max-ellipsoids", true, "N"},
									  {"--up", true, "y|z"},
									  {"--scale", true, "S"},
									  {"--export-mesh", true, "OUT.obj|OUT.ply"},
									  {"--segments", true, "OUT.ply|OUT.obj"},
									  {"--skinned-mesh", true, "NAME"},
									  {"--no-segmentation", false, ""},
									  {"--no-triangle-cover", false, ""},
									  {"--no-skin-field", false, ""},
									  {"--skin-voxel", true, "M"},
									  {"--skin-clamp", true, "M"}});
		if (args.helpRequested())
		{
			std::cout << kUsage;
			return bodyfit_cli::kExitOk;
		}
		const FitCommand command = parseFitCommand(args);
		FittedInput in = fitInput(command);
		printWarnings(in.result);
		if (!command.skinPath.empty())
			bakeSkinField(in.result.loaded.mesh, command.skinOptions, in.result.fit); // a rig's: its bind mesh
		writeOutputs(command, in.result);
		printReport(command, in);
		return bodyfit_cli::kExitOk;
	});
}
