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

} // namespace

int main(int argc, char** argv)
{
	return bodyfit_cli::runMain("bodyfit-fit", [&] {
		using bodyfit_cli::UsageError;
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

		// Arguments: everything is checked before any work is done.
		args.requirePositional(1, "MESH argument");
		const std::string meshPath = args.positional()[0];
		if (!args.has("-o"))
			throw UsageError("missing -o OUT.json (see --help)");
		const std::string outPath = args.value("-o");
		if (outPath.empty())
			throw UsageError("-o: empty file name");
		const std::string exportPath = args.value("--export-mesh");
		if (args.has("--export-mesh") && !hasExtension(exportPath, ".obj") && !hasExtension(exportPath, ".ply"))
			throw UsageError("--export-mesh: \"" + exportPath + "\" must end in .obj or .ply");
		const std::string segmentsPath = args.value("--segments");
		if (args.has("--segments") && !hasExtension(segmentsPath, ".obj") && !hasExtension(segmentsPath, ".ply"))
			throw UsageError("--segments: \"" + segmentsPath + "\" must end in .ply or .obj");
		if (args.has("--no-segmentation") && args.has("--segments"))
			throw UsageError("--segments needs the segmentation: drop --no-segmentation");
		// Outputs: writable, and none of them the input or each other (checked before the load and the fit).
		bodyfit_cli::requireWritableOutput(outPath, "-o");
		if (args.has("--export-mesh"))
			bodyfit_cli::requireWritableOutput(exportPath, "--export-mesh");
		if (args.has("--segments"))
			bodyfit_cli::requireWritableOutput(segmentsPath, "--segments");
		const std::string skinPath = args.has("--no-skin-field") ? "" : bodyfit::skinFieldPathFor(outPath);
		if (!skinPath.empty())
			bodyfit_cli::requireWritableOutput(skinPath, "skin field (next to -o)");
		bodyfit_cli::requireDistinctOutputs({{"-o", outPath},
											 {"--export-mesh", exportPath},
											 {"--segments", segmentsPath},
											 {"skin field (next to -o)", skinPath}},
											{{"input mesh", meshPath}});

		const bool skinField = !args.has("--no-skin-field");
		if (!skinField && (args.has("--skin-voxel") || args.has("--skin-clamp")))
			throw UsageError("--skin-voxel / --skin-clamp set the skin field: drop --no-skin-field");
		bodyfit::SkinFieldOptions skinOptions;
		skinOptions.voxel = args.number("--skin-voxel", skinOptions.voxel, 0.0005, 0.05);
		skinOptions.clamp = args.number("--skin-clamp", skinOptions.clamp, 0.001, 0.1);
		if (!(skinOptions.clamp >= 2.0 * skinOptions.voxel))
			throw UsageError("--skin-clamp: " + std::to_string(skinOptions.clamp) + " m is less than 2 voxels (" +
							 std::to_string(2.0 * skinOptions.voxel) + " m)");

		bodyfit::FitPipelineOptions options;
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

		// A rigged file (a skinned mesh): fit its bind pose and record the bone bindings (skinned_fit.h).
		std::optional<bodyfit::Rig> rig;
		bodyfit::FitPipelineResult result;
		if (args.has("--skinned-mesh") || bodyfit::hasSkinnedMesh(meshPath))
		{
			const auto t0 = std::chrono::steady_clock::now();
			rig = bodyfit::loadRig(meshPath, {options.load, args.value("--skinned-mesh"), /*requireAnimation=*/false});
			const double loadMs =
				std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
			bodyfit::LoadedMesh bind{rig->bindMesh, rig->bindMesh, bodyfit::analyzeComponents(rig->bindMesh),
									 rig->report};
			result = bodyfit::fitLoadedMesh(std::move(bind), options,
											std::filesystem::path(meshPath).filename().string(), loadMs);
		}
		else
			result = bodyfit::fitMeshFile(meshPath, options);
		bodyfit::BodyFit& fit = result.fit;
		const bodyfit::TriMesh& mesh = result.loaded.mesh;
		const std::string regionSummary =
			!options.segment ? "whole mesh as one region (--no-segmentation)"
			: result.fallback ? "whole mesh as one region (segmentation failed)"
							  : std::to_string(bodyfit::kBodyRegionCount) + " body regions (segmentation)";
		if (result.fallback)
			std::cerr << "bodyfit-fit: warning: " << fit.warnings.front() << "\n";
		// What loading joined, kept or ignored of a body of several meshes, or found far from the origin (mesh_io.h);
		// the pipeline also puts these lines into the fit's warnings.
		for (const std::string& w : result.loaded.report.warnings)
			std::cerr << "bodyfit-fit: warning: " << w << "\n";

		if (rig)
		{
			const auto tBind = std::chrono::steady_clock::now();
			fit.skinning = std::make_shared<const bodyfit::SkinBinding>(bodyfit::bindSkin(*rig, fit));
			const auto bindTime = std::chrono::steady_clock::now() - tBind;
			fit.setTiming("skinning.bind", std::chrono::duration<double, std::milli>(bindTime).count());
		}

		if (skinField)
			bakeSkinField(mesh, skinOptions, fit); // a rig's bind mesh with the bind-pose fit

		// Outputs.
		bodyfit_cli::ensureParentDirectory(outPath);
		bodyfit::writeEllipsoidJson(outPath, fit);
		if (!exportPath.empty())
		{
			bodyfit_cli::ensureParentDirectory(exportPath);
			bodyfit::exportEllipsoidMesh(exportPath, fit.ellipsoids);
		}
		if (!segmentsPath.empty())
		{
			bodyfit_cli::ensureParentDirectory(segmentsPath);
			Eigen::MatrixX3d colors;
			const bodyfit::TriMesh preview = bodyfit::segmentationPreview(mesh, result.segmentation, &colors);
			bodyfit::saveTriMesh(segmentsPath, preview, &colors);
		}
		std::string extraOutputs = exportPath;
		if (!segmentsPath.empty())
			extraOutputs += (extraOutputs.empty() ? "" : ", ") + segmentsPath;
		printSummary(result.loaded, fit, regionSummary, outPath, extraOutputs);
		printSkinField(fit, outPath, "--no-skin-field");
		if (rig)
			std::cout << "  skinning  rig with " << rig->boneCount() << " bones, " << rig->clips.size()
					  << " clip(s): bind pose fitted, " << fit.skinning->vertexPoints + fit.skinning->coverPoints
					  << " skin points bound to the ellipsoids (" << ms(fit.timingMs("skinning.bind")) << ")\n";
		return bodyfit_cli::kExitOk;
	});
}
