// Hostile and careless input, round 2 (docs/ROBUSTNESS.md section 7), fitting side: deeply nested JSON, files that
// are not regular files (also when a mesh only names them), glTF node trees and buffers, PLY and GLB headers that
// declare more than the file holds, OBJ statement counts that make assimp quadratic, fit files with values no
// float (or no body) has. Each input is refused with a typed one-line error naming the file, before any parser or
// allocation of the declared size; what a legitimate file at the limit looks like still loads.
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/input_files.h"
#include "bodyfit/fitting/mesh_io.h"

#include "support/paths.h"
#include "support/temp_files.h"

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>
#include <string>
#include <typeinfo>

namespace
{

using namespace bodyfit;
using bodyfit_test::dataPath;
using bodyfit_test::nestedArrays;
using bodyfit_test::TempDir;

const std::string kValidFit = R"({"format": "bodyfit.ellipsoids", "version": 1, "ellipsoids": [{"region": "head",)"
							  R"( "center": [0, 1.6, 0], "rotation": [1, 0, 0, 0], "axes": [0.1, 0.12, 0.1]}])";

/// kValidFit with one more member `"extra": value` (the reader ignores members it does not know).
std::string fitWithExtra(const std::string& value) { return kValidFit + ", \"extra\": " + value + "}"; }

template <class Error, class F>
std::string errorOf(F&& f)
{
	try
	{
		f();
	}
	catch (const Error& e)
	{
		const std::string what = e.what();
		CHECK(what.find('\n') == std::string::npos);
		return what;
	}
	FAIL("no " << typeid(Error).name());
	return "";
}

/// The message of an Error thrown by f, "other exception: ..." or "no exception"; no Catch assertion, so that it can
/// run on another thread (finishesWithin).
template <class Error, class F>
std::string quietErrorOf(F&& f)
{
	try
	{
		f();
	}
	catch (const Error& e)
	{
		return e.what();
	}
	catch (const std::exception& e)
	{
		return std::string("other exception: ") + e.what();
	}
	return "no exception";
}

std::string meshError(const std::string& path)
{
	const std::string what = errorOf<MeshLoadError>([&] { loadTriMesh(path); });
	CHECK(what.find(path) != std::string::npos);
	return what;
}

std::string slurp(const std::string& path)
{
	std::ifstream in(path, std::ios::binary);
	std::ostringstream s;
	s << in.rdbuf();
	return s.str();
}

const std::string kTetraObj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// A glTF 2.0 file with `nodes` (JSON array text) over one embedded triangle mesh.
std::string gltfWithNodes(const std::string& nodes)
{
	const std::string valid = slurp(dataPath("robust_gltf_deep_nodes.gltf"));
	const std::size_t a = valid.find("\"nodes\": [{"), b = valid.find("], \"buffers\"");
	REQUIRE(a != std::string::npos);
	REQUIRE(b != std::string::npos);
	return valid.substr(0, a) + "\"nodes\": " + nodes + valid.substr(b + 1);
}

/// A chain of `n` glTF nodes, the last one holding mesh 0.
std::string nodeChain(int n)
{
	std::string s = "[";
	for (int i = 0; i + 1 < n; ++i)
		s += "{\"children\": [" + std::to_string(i + 1) + "]}, ";
	return s + "{\"mesh\": 0}]";
}

} // namespace

TEST_CASE("robust hostile: deeply nested JSON is refused before a tree is built", "[robust][hostile][json]")
{
	// Issue 15 class 1: a 100,000-deep array as an extra member segfaulted the fit reader (recursive JSON code).
	const std::string deep = fitWithExtra(nestedArrays(100000));
	CHECK_THAT(errorOf<FormatError>([&] { parseEllipsoidJson(deep, "deep.json"); }),
			   Catch::StartsWith("deep.json: not a usable JSON document: arrays/objects nested deeper than 64 levels"));
	// Objects nest the same way.
	std::string objects;
	for (int i = 0; i < 100000; ++i)
		objects += "{\"a\": ";
	objects += "1" + std::string(100000, '}');
	CHECK_THAT(errorOf<FormatError>([&] { parseEllipsoidJson(fitWithExtra(objects), "o.json"); }),
			   Catch::Contains("nested deeper than 64"));
	// The limit: the document is level 1, so an extra member of 63 arrays reaches 64 (read), 64 arrays 65 (refused).
	CHECK(parseEllipsoidJson(fitWithExtra(nestedArrays(63))).ellipsoids.size() == 1);
	CHECK_THROWS_AS(parseEllipsoidJson(fitWithExtra(nestedArrays(64))), FormatError);
	// Brackets inside strings (with escaped quotes) and comments are not nesting.
	CHECK(parseEllipsoidJson(fitWithExtra("\"\\\"" + std::string(1000, '[') + "\"")).ellipsoids.size() == 1);
	CHECK(jsonDepthProblem("// [[[[\n/* {{{{ */ [1]", 1).empty());
	CHECK_FALSE(jsonDepthProblem("[[1]]", 1).empty());
	// From a file (tests/data: 1,000 levels).
	CHECK_THAT(errorOf<FormatError>([&] { readEllipsoidJson(dataPath("robust_fit_deep_nesting.json")); }),
			   Catch::Contains("robust_fit_deep_nesting.json: not a usable JSON document"));
}

TEST_CASE("robust hostile: non-regular files are refused without blocking", "[robust][hostile][files]")
{
	// Issue 15 class 4: a FIFO blocked open() forever; directories and devices gave misleading messages (class 14).
	TempDir tmp("bodyfit_robust_files");
	const std::string fifo = tmp.fifo("pipe.obj");
	std::string what;
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietErrorOf<MeshLoadError>([&] { loadTriMesh(fifo); }); }));
	CHECK_THAT(what, Catch::EndsWith("pipe.obj: cannot open file: is a FIFO (named pipe), not a regular file"));
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] {
		what = quietErrorOf<FormatError>([&] { readEllipsoidJson(fifo); });
	}));
	CHECK_THAT(what, Catch::EndsWith("pipe.obj: cannot open fit file: is a FIFO (named pipe), not a regular file"));
	CHECK_THAT(meshError(tmp.path("")), Catch::Contains("is a directory, not a file"));
	CHECK_THAT(meshError("/dev/null"), Catch::EndsWith("/dev/null: cannot open file: is a character device, not a regular file"));
	CHECK_THAT(meshError(dataPath("robust_does_not_exist.obj")), Catch::EndsWith(": cannot open file: does not exist"));
	CHECK_THAT(meshError(dataPath("tetra.obj/x.obj")), Catch::Contains("a parent of it is not a directory"));
	CHECK_THAT(errorOf<FormatError>([&] { readEllipsoidJson(tmp.path("")); }), Catch::Contains("is a directory"));
}

TEST_CASE("robust hostile: files a mesh names must be regular files", "[robust][hostile][files]")
{
	TempDir tmp("bodyfit_robust_refs");
	const std::string fifo = tmp.fifo("pipe.mtl");
	// OBJ: the material library, named relatively, and assimp's fallback (the OBJ's name with .mtl).
	const std::string viaMtllib = tmp.write("a.obj", kTetraObj + "mtllib pipe.mtl\n");
	std::string what;
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietErrorOf<MeshLoadError>([&] { loadTriMesh(viaMtllib); }); }));
	CHECK_THAT(what, Catch::Contains("OBJ mtllib names '" + fifo + "' is a FIFO"));
	const std::string viaFallback = tmp.write("pipe.obj", kTetraObj + "mtllib missing.mtl\n");
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietErrorOf<MeshLoadError>([&] { loadTriMesh(viaFallback); }); }));
	CHECK_THAT(what, Catch::Contains("OBJ material fallback '" + fifo + "' is a FIFO"));
	// A missing material library is only a warning of assimp's: the mesh loads.
	CHECK(loadTriMesh(tmp.write("b.obj", kTetraObj + "mtllib missing.mtl\n")).mesh.vertexCount() == 4);
	// glTF: a buffer uri (also percent-encoded) and an image uri naming the FIFO, and a buffer whose file is missing.
	const std::string gltf = slurp(dataPath("robust_gltf_buffer_too_long.gltf"));
	for (const char* uri : {"pipe.mtl", "pipe%2Emtl"})
	{
		std::string text = gltf;
		text.replace(text.find("data:"), text.find('"', text.find("data:")) - text.find("data:"), uri);
		const std::string path = tmp.write("buffer.gltf", text);
		CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietErrorOf<MeshLoadError>([&] { loadTriMesh(path); }); }));
		CHECK_THAT(what, Catch::Contains("glTF buffers[0].uri names '" + fifo + "' is a FIFO"));
	}
	std::string missing = gltf;
	missing.replace(missing.find("data:"), missing.find('"', missing.find("data:")) - missing.find("data:"), "no.bin");
	CHECK_THAT(meshError(tmp.write("missing.gltf", missing)), Catch::Contains("glTF buffers[0].uri names '" +
																			   tmp.path("no.bin") + "' does not exist"));
	const std::string image = tmp.write("image.gltf", gltfWithNodes("[{\"mesh\": 0}]").insert(1, "\"images\": [{\"uri\": \"pipe.mtl\"}], "));
	CHECK(bodyfit_test::finishesWithin(2.0, fifo, [&] { what = quietErrorOf<MeshLoadError>([&] { loadTriMesh(image); }); }));
	CHECK_THAT(what, Catch::Contains("glTF images[0].uri names '" + fifo + "' is a FIFO"));
}

TEST_CASE("robust hostile: glTF node trees and buffers are checked before assimp", "[robust][hostile][gltf]")
{
	// Issue 15 class 3: a 20,000-deep node chain overflowed the stack inside assimp's glTF reader.
	TempDir tmp("bodyfit_robust_gltf");
	const std::string deep = meshError(tmp.write("deep.gltf", gltfWithNodes(nodeChain(20000))));
	CHECK_THAT(deep, Catch::EndsWith("deep.gltf: glTF node hierarchy is deeper than 256 levels"));
	CHECK_THAT(meshError(dataPath("robust_gltf_deep_nodes.gltf")), Catch::Contains("deeper than 256 levels"));
	// At the limit the file loads (one triangle: too few points for the fitter, an InvalidInputError after reading).
	CHECK_THROWS_WITH(loadTriMesh(tmp.write("256.gltf", gltfWithNodes(nodeChain(256)))),
					  Catch::Contains("fewer than 4 distinct points (3)"));
	CHECK_THAT(meshError(tmp.write("257.gltf", gltfWithNodes(nodeChain(257)))), Catch::Contains("deeper than 256"));
	// Not a tree: a cycle without a root (assimp would recurse forever), a node with two parents.
	CHECK_THAT(meshError(dataPath("robust_gltf_node_cycle.gltf")), Catch::Contains("glTF nodes form a cycle"));
	CHECK_THAT(meshError(dataPath("robust_gltf_two_parents.gltf")), Catch::Contains("glTF node 3 has more than one parent"));
	CHECK_THAT(meshError(tmp.write("child.gltf", gltfWithNodes("[{\"children\": [7]}]"))),
			   Catch::Contains("glTF node 0: child 7 is not a node"));
	// A buffer declaring 4 GB backed by 36 bytes (assimp allocates the declared length first).
	CHECK_THAT(meshError(dataPath("robust_gltf_buffer_too_long.gltf")),
			   Catch::Contains("glTF buffers[0].byteLength is 4000000000 but its data has only 36 bytes"));
	// Nesting inside glTF JSON (assimp parses it with a recursive parser).
	CHECK_THAT(meshError(tmp.write("nest.gltf", "{\"asset\": " + nestedArrays(100000) + "}")),
			   Catch::Contains("JSON text (read as glTF): arrays/objects nested deeper than 64 levels"));
}

TEST_CASE("robust hostile: GLB and PLY headers must fit in the file", "[robust][hostile][glb][ply]")
{
	// Issue 15 class 11: 592 bytes declaring a 4 GB JSON chunk took 17 s and 4.2 GB before "No suitable reader".
	CHECK_THAT(meshError(dataPath("robust_glb_huge_json_chunk.glb")),
			   Catch::EndsWith("GLB header declares a JSON chunk of 4026531840 bytes in a file of 592"));
	// A well-formed GLB (JSON + BIN chunk) still loads: the tetrahedron.
	const LoadedMesh glb = loadTriMesh(dataPath("robust_valid_tetra.glb"));
	CHECK(glb.mesh.vertexCount() == 4);
	CHECK(glb.mesh.faceCount() == 4);
	TempDir tmp("bodyfit_robust_glb");
	std::string cut = slurp(dataPath("robust_valid_tetra.glb"));
	CHECK_THAT(meshError(tmp.write("cut.glb", cut.substr(0, cut.size() - 8))),
			   Catch::Contains("GLB header declares " + std::to_string(cut.size()) + " bytes but the file has"));
	// Issue 15 class 14: a PLY claiming 4 billion vertices was std::bad_alloc (exit 1, "internal error").
	CHECK_THAT(meshError(dataPath("robust_ply_huge_count.ply")),
			   Catch::Contains("PLY header declares 4000000000 'vertex' elements (ASCII, at least 6 bytes each) but the "
							   "file has only 26 bytes of data"));
	CHECK_THAT(meshError(dataPath("robust_ply_huge_count_binary.ply")),
			   Catch::Contains("4000000000 'face' elements (binary, at least 1 bytes each)"));
	// A face whose list count claims 4e9 indices (assimp reserves them: std::bad_alloc), binary and ASCII.
	CHECK_THAT(meshError(dataPath("robust_ply_list_bomb.ply")),
			   Catch::EndsWith("PLY 'face' 0 declares a list of 4000000000 entries but only 12 bytes follow"));
	CHECK_THAT(meshError(dataPath("robust_ply_list_bomb_ascii.ply")),
			   Catch::EndsWith("PLY 'face' 0 declares a list of 4000000000 entries but only 6 bytes follow"));
	// Found by fuzz_mesh_file from the ASCII seed: the count followed by NUL bytes (assimp reads the leading digits).
	CHECK_THAT(meshError(dataPath("robust_fuzz_ply_list_nul.ply")),
			   Catch::Contains("PLY 'face' 0 declares a list of 4000000000 entries"));
	// Found next: the count where assimp's line reading (NUL ends a line) puts it and a token scan does not.
	CHECK_THAT(meshError(dataPath("robust_fuzz_ply_list_nul2.ply")),
			   Catch::Contains("PLY body holds the count-like number 4000000000 at byte 182"));
	// A negative count of a signed count type (assimp converts -1 to 4294967295), while negative coordinates with a
	// signed count type still load.
	const std::string header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
							   "property float z\nelement face 4\nproperty list int int vertex_indices\nend_header\n"
							   "-1 -1 -1\n1 0 0\n0 1 0\n0 0 1\n";
	CHECK_THAT(meshError(tmp.write("neg.ply", header + "-1 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")),
			   Catch::Contains("PLY 'face' 0 declares a list of -1 entries"));
	CHECK(loadTriMesh(tmp.write("signed.ply", header + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")).mesh.faceCount() == 4);
	// The counts of a file that holds its data pass: the tetrahedron written as PLY (ASCII) reloads.
	const LoadedMesh tetra = loadTriMesh(dataPath("tetra.obj"));
	const std::string ply = tmp.path("tetra.ply");
	saveTriMesh(ply, tetra.mesh);
	CHECK(loadTriMesh(ply).mesh.faceCount() == 4);
}

TEST_CASE("robust hostile: OBJ object, group and material counts are bounded", "[robust][hostile][obj]")
{
	// Issue 15 class 11: 100k distinct `usemtl` (3.5 GB) or 200k `o` lines (killed at 100 s) in assimp 5.2.
	TempDir tmp("bodyfit_robust_obj");
	auto objWith = [&](const std::string& name, int n, const std::string& statement) {
		std::string text = kTetraObj;
		for (int i = 0; i < n; ++i)
			text += statement + " s" + std::to_string(i) + "\n";
		return tmp.write(name, text);
	};
	CHECK_THAT(meshError(objWith("o.obj", 10001, "o")),
			   Catch::EndsWith("OBJ has more than 10000 object/group/material statements (o, g, usemtl)"));
	CHECK_THAT(meshError(objWith("m.obj", 1001, "usemtl")), Catch::EndsWith("OBJ uses more than 1000 distinct materials"));
	// At the limits the files load.
	CHECK(loadTriMesh(objWith("g.obj", 10000, "g")).mesh.vertexCount() == 4);
	CHECK(loadTriMesh(objWith("m1000.obj", 1000, "usemtl")).mesh.vertexCount() == 4);
	// Switching between two materials is cheap in assimp and counts as statements only.
	std::string twoMaterials = kTetraObj;
	for (int i = 0; i < 5000; ++i)
		twoMaterials += i % 2 ? "usemtl a\n" : "usemtl b\n";
	CHECK(loadTriMesh(tmp.write("two.obj", twoMaterials)).mesh.vertexCount() == 4);
}

TEST_CASE("robust hostile: fit files hold only geometry a float and a body have", "[robust][hostile][json]")
{
	// Issue 15 class 8: axes 1e39 became inf in Bullet's float, 1e-40 became 0, 1e12 threw every cloth node 1e12 m
	// away while the metrics said 0 inside, 0 NaN. The range is [1e-6, 1000] m for semi-axes, |centre| <= 1000 m.
	auto withAxes = [](const std::string& axes) {
		std::string text = kValidFit + "}";
		return text.replace(text.find("[0.1, 0.12, 0.1]"), 16, axes);
	};
	auto fitError = [](const std::string& text) {
		return errorOf<FormatError>([&] { parseEllipsoidJson(text, "f.json"); });
	};
	CHECK_THAT(fitError(withAxes("[0.1, 1e39, 0.1]")), Catch::EndsWith("f.json: ellipsoids[0].axes[1]: must be in [1e-06, 1000] m (got 1e+39)"));
	CHECK_THAT(fitError(withAxes("[0.1, 1e-40, 0.1]")), Catch::EndsWith("axes[1]: must be in [1e-06, 1000] m (got 1e-40)"));
	CHECK_THAT(fitError(withAxes("[1e12, 0.1, 0.1]")), Catch::EndsWith("axes[0]: must be in [1e-06, 1000] m (got 1000000000000)"));
	CHECK_THAT(fitError(withAxes("[0.1, 0.1, 0]")), Catch::EndsWith("axes[2]: must be > 0 (got 0)"));
	std::string far = kValidFit + "}";
	far.replace(far.find("[0, 1.6, 0]"), 11, "[0, 1.6, -1000.5]");
	CHECK_THAT(fitError(far), Catch::EndsWith("ellipsoids[0].center[2]: must be in [-1000, 1000] m (got -1000.5)"));
	// The limits themselves are read.
	CHECK(parseEllipsoidJson(withAxes("[1e-6, 1000, 0.1]")).ellipsoids[0].ellipsoid.radii.y() == 1000.0);
	// Issue 15 class 14: an integer >= 2^63 was reported as "got -1" (wrapped to a signed value).
	std::string big = kValidFit + "}";
	big.replace(big.find("\"version\": 1"), 12, "\"version\": 18446744073709551615");
	CHECK_THAT(fitError(big), Catch::EndsWith("version: must be an integer >= 0 and < 2^31 (got 18446744073709551615)"));
	// The writer holds fits to the same range and writes nothing otherwise (a millimetre body fitted unscaled).
	TempDir tmp("bodyfit_robust_fitrange");
	BodyFit fit = parseEllipsoidJson(kValidFit + "}");
	fit.ellipsoids[0].ellipsoid.radii.x() = 1278.0;
	CHECK_THAT(errorOf<FormatError>([&] { writeEllipsoidJson(tmp.path("o.json"), fit); }),
			   Catch::Contains("o.json: not written, the fit is outside a fit file's range: ellipsoids[0].axes[0]: must be "
							   "in [1e-06, 1000] m (got 1278)"));
	CHECK_FALSE(std::ifstream(tmp.path("o.json")).good());
}

TEST_CASE("robust hostile: output extensions are case-insensitive", "[robust][hostile][files]")
{
	// Issue 15 class 14: `--export-mesh X.OBJ` passed the CLI check and then failed in the export (after the JSON was
	// written), `--segments X.PLY` got OBJ text.
	TempDir tmp("bodyfit_robust_ext");
	const LoadedMesh tetra = loadTriMesh(dataPath("tetra.obj"));
	saveTriMesh(tmp.path("T.PLY"), tetra.mesh);
	CHECK(slurp(tmp.path("T.PLY")).rfind("ply\nformat ascii 1.0\n", 0) == 0);
	CHECK(loadTriMesh(tmp.path("T.PLY")).mesh.faceCount() == 4);
	const BodyFit fit = parseEllipsoidJson(kValidFit + "}");
	exportEllipsoidMesh(tmp.path("E.OBJ"), fit.ellipsoids, 0);
	CHECK(loadTriMesh(tmp.path("E.OBJ")).mesh.faceCount() == 20); // one icosahedron (subdivision 0)
	CHECK_THROWS_WITH(exportEllipsoidMesh(tmp.path("E.stl"), fit.ellipsoids), Catch::Contains("needs a .obj or .ply"));
}
