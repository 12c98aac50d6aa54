// Mesh input and repair. The only file of the library that includes assimp.
#include "bodyfit/fitting/mesh_io.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/input_files.h"
#include "bodyfit/fitting/statistics.h"

#include <Eigen/Geometry>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <sstream>
#include <unordered_map>
#include <vector>

namespace bodyfit
{

const char* toString(UpAxis up)
{
	return up == UpAxis::Y ? "+y" : "+z";
}

const char* toString(FitStatus status)
{
	switch (status)
	{
	case FitStatus::Ok: return "ok";
	case FitStatus::TooFewPoints: return "too-few-points";
	case FitStatus::Degenerate: return "degenerate";
	case FitStatus::NotConverged: return "not-converged";
	case FitStatus::NumericalIssue: return "numerical-issue";
	}
	return "unknown";
}

namespace
{

struct UnionFind
{
	std::vector<int> parent;
	explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
	int find(int a)
	{
		while (parent[a] != a)
		{
			parent[a] = parent[parent[a]];
			a = parent[a];
		}
		return a;
	}
	void unite(int a, int b)
	{
		a = find(a);
		b = find(b);
		if (a != b)
			parent[std::max(a, b)] = std::min(a, b); // deterministic: the smaller index is the root
	}
};

/// Keep only the listed vertices/faces, renumbering vertices in their original order.
TriMesh extract(const TriMesh& m, const std::vector<char>& keepVertex)
{
	std::vector<int> newIndex(m.V.rows(), -1);
	int nv = 0;
	for (int i = 0; i < m.V.rows(); ++i)
		if (keepVertex[i])
			newIndex[i] = nv++;
	TriMesh out;
	out.V.resize(nv, 3);
	for (int i = 0; i < m.V.rows(); ++i)
		if (newIndex[i] >= 0)
			out.V.row(newIndex[i]) = m.V.row(i);
	int nf = 0;
	for (int f = 0; f < m.F.rows(); ++f)
		nf += keepVertex[m.F(f, 0)] ? 1 : 0;
	out.F.resize(nf, 3);
	nf = 0;
	for (int f = 0; f < m.F.rows(); ++f)
		if (keepVertex[m.F(f, 0)])
		{
			for (int k = 0; k < 3; ++k)
				out.F(nf, k) = newIndex[m.F(f, k)];
			++nf;
		}
	return out;
}

double bboxDiagonal(const Eigen::MatrixX3d& V)
{
	if (V.rows() == 0)
		return 0.0;
	return (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
}

/// "" or, when one vertex lies more than 1000 times farther from the vertices' per-axis median than half of the
/// vertices do (a single wild coordinate stretches the bounding box, and with it the weld and area tolerances, until
/// every face collapses), a description of the farthest one.
std::string strayVertex(const Eigen::MatrixX3d& V)
{
	const Eigen::Index n = V.rows();
	if (n < 2)
		return "";
	Eigen::RowVector3d middle;
	for (int k = 0; k < 3; ++k)
		middle[k] = median(std::vector<double>(V.col(k).data(), V.col(k).data() + n));
	std::vector<double> distance(static_cast<std::size_t>(n));
	for (Eigen::Index i = 0; i < n; ++i)
		distance[std::size_t(i)] = (V.row(i) - middle).norm();
	const Eigen::Index farthest = std::max_element(distance.begin(), distance.end()) - distance.begin();
	const double far = distance[std::size_t(farthest)];
	const double half = median(distance);
	if (!(far > 1000.0 * half))
		return "";
	std::ostringstream out;
	out.precision(3);
	out << "vertex " << farthest << " at (" << V(farthest, 0) << ", " << V(farthest, 1) << ", " << V(farthest, 2)
		<< ") lies " << far << " m from the middle of the mesh, where half of the vertices lie within " << half << " m";
	return out.str();
}

/// Distance between consecutive 32-bit floats near |x| (assimp 5.2 as packaged stores coordinates as float).
double floatSpacing(double x)
{
	int exponent = 0;
	std::frexp(std::max(std::abs(x), 1.0), &exponent);
	return std::ldexp(1.0, exponent - 24);
}

/// assimp hands us 32-bit floats: far from the origin they are coarser than the mesh. Compares the float spacing
/// at the farthest coordinate with the typical edge length, bounding-box diagonal / sqrt(faces) (11.7 mm for
/// female_young, whose median edge is 6.1 mm; unlike the median it survives the quantisation it is about): above 1/4 of it
/// vertices merge and faces collapse (female_young 100 km away along (1, 1, 1): 3,214 vertices welded wrongly, 6,344
/// faces degenerate) and the file is refused; above 1/64 it is a warning (female_young 10 km away: 3 vertices merge).
/// Units of the file. \throws InvalidInputError naming the distance, the spacing and the edge length.
std::string checkFloatPrecision(const TriMesh& raw, const std::string& path)
{
	if (raw.V.rows() == 0 || raw.F.rows() == 0 || !raw.V.allFinite())
		return {}; // repairMesh reports these
	const double typicalEdge = bboxDiagonal(raw.V) / std::sqrt(double(raw.F.rows()));
	if (!(typicalEdge > 0.0))
		return {}; // every vertex identical: repairMesh reports the degenerate faces
	const double far = raw.V.cwiseAbs().maxCoeff();
	const double spacing = floatSpacing(far);
	char buf[400];
	std::snprintf(buf, sizeof buf,
		"coordinates reach %.6g from the origin, where the 32-bit floats assimp reads are %.3g apart, %s of the "
		"typical edge (bounding-box diagonal / sqrt(faces) = %.3g)",
		far, spacing, spacing > typicalEdge / 4 ? "more than 1/4" : "more than 1/64", typicalEdge);
	if (spacing > typicalEdge / 4)
		throw InvalidInputError(path + ": " + buf + ": vertices merge and faces collapse; move the mesh nearer the "
			"origin");
	if (spacing > typicalEdge / 64)
		return std::string(buf) + ": the shape is quantised (vertices may merge); a mesh nearer the origin is exact";
	return {};
}

/// Sorts out the components of `out.full` (components.h): `out.mesh` = everything but the detached ones, with its
/// own layout; the report counts each role and carries one warning line per role.
void keepBody(LoadedMesh& out, const ComponentOptions& options)
{
	MeshReport& r = out.report;
	const ComponentLayout fullLayout = analyzeComponents(out.full, options);
	r.components = int(fullLayout.components.size());
	r.attachedComponents = fullLayout.count(ComponentRole::Attached);
	r.insideComponents = fullLayout.count(ComponentRole::Inside);
	r.insideComponentVertices = fullLayout.vertexCount(ComponentRole::Inside);
	r.detachedComponents = fullLayout.count(ComponentRole::Detached);
	r.droppedComponentVertices = fullLayout.vertexCount(ComponentRole::Detached);
	r.warnings = componentWarnings(fullLayout);
	if (r.detachedComponents > 0)
	{
		std::vector<char> keep(size_t(out.full.vertexCount()));
		for (int v = 0; v < out.full.vertexCount(); ++v)
			keep[size_t(v)] = fullLayout.kept(v);
		out.mesh = extract(out.full, keep);
		out.components = analyzeComponents(out.mesh, options);
	}
	else
	{
		out.mesh = out.full;
		out.components = fullLayout;
	}
}

} // namespace

void requireUsable(const TriMesh& mesh, const std::string& name)
{
	if (mesh.F.rows() == 0)
		throw InvalidInputError(name + ": mesh has no faces");
	if (!mesh.V.allFinite())
	{
		for (int i = 0; i < mesh.V.rows(); ++i)
			if (!mesh.V.row(i).allFinite())
				throw InvalidInputError(name + ": vertex " + std::to_string(i) + " has a non-finite coordinate");
	}
	if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= mesh.V.rows())
		throw InvalidInputError(name + ": face index out of range");
	// At least 4 distinct points, and not all on one plane within the weld tolerance (volume needed by MVEE).
	const double tol = std::max(1e-6 * bboxDiagonal(mesh.V), 1e-12);
	int distinct = 0;
	std::vector<Eigen::Vector3d> seen;
	for (int i = 0; i < mesh.V.rows() && distinct < 4; ++i)
	{
		const Eigen::Vector3d p = mesh.V.row(i);
		bool isNew = true;
		for (const auto& s : seen)
			isNew = isNew && (p - s).norm() > tol;
		if (isNew)
		{
			seen.push_back(p);
			++distinct;
		}
	}
	if (distinct < 4)
		throw InvalidInputError(name + ": fewer than 4 distinct points (" + std::to_string(distinct) + ")");
}

std::vector<int> connectedComponents(const TriMesh& mesh, int* count)
{
	const int n = int(mesh.V.rows());
	UnionFind uf(n);
	for (int f = 0; f < mesh.F.rows(); ++f)
	{
		uf.unite(mesh.F(f, 0), mesh.F(f, 1));
		uf.unite(mesh.F(f, 1), mesh.F(f, 2));
	}
	std::vector<int> root(n), size(n, 0);
	for (int i = 0; i < n; ++i)
	{
		root[i] = uf.find(i);
		++size[root[i]];
	}
	// Order components by size (descending), ties by smallest vertex index: deterministic.
	std::vector<int> roots;
	for (int i = 0; i < n; ++i)
		if (root[i] == i)
			roots.push_back(i);
	std::stable_sort(roots.begin(), roots.end(), [&](int a, int b) { return size[a] > size[b]; });
	std::vector<int> id(n, -1), rootId(n, -1);
	for (int k = 0; k < int(roots.size()); ++k)
		rootId[roots[k]] = k;
	for (int i = 0; i < n; ++i)
		id[i] = rootId[root[i]];
	if (count)
		*count = int(roots.size());
	return id;
}

namespace
{

/// The input's problems that no repair can fix: a bad scale, no vertices or faces, a non-finite coordinate, a face
/// index out of range.
void checkRepairable(const TriMesh& input, const LoadOptions& options, const std::string& name)
{
	if (!(options.scale > 0.0) || !std::isfinite(options.scale))
		throw InvalidInputError(name + ": scale must be a positive finite number");
	if (input.V.rows() == 0 || input.F.rows() == 0)
		throw InvalidInputError(name + ": mesh is empty (" + std::to_string(input.V.rows()) + " vertices, " +
			std::to_string(input.F.rows()) + " faces)");
	for (int i = 0; i < input.V.rows(); ++i)
		if (!input.V.row(i).allFinite())
			throw InvalidInputError(name + ": vertex " + std::to_string(i) + " has a non-finite coordinate");
	if (input.F.minCoeff() < 0 || input.F.maxCoeff() >= input.V.rows())
		throw InvalidInputError(name + ": face index out of range");
}

/// The vertices in metres, +y up: units and up axis from the explicit options only, never guessed.
Eigen::MatrixX3d toMetresYUp(const Eigen::MatrixX3d& V, const LoadOptions& options)
{
	Eigen::MatrixX3d out = V * options.scale;
	if (options.up == UpAxis::Z)
	{
		// (x, y, z) -> (x, z, -y): +z becomes +y, right-handed.
		Eigen::MatrixX3d W(out.rows(), 3);
		W.col(0) = out.col(0);
		W.col(1) = out.col(2);
		W.col(2) = -out.col(1);
		out = W;
	}
	return out;
}

/// Welds the vertices within `tol` of an earlier kept one (a hash grid of cell size tol, the 27 neighbouring cells
/// searched): remap[i] is vertex i's index among the kept ones, whose original indices are returned in order.
std::vector<int> weldVertices(const Eigen::MatrixX3d& V, double tol, std::vector<int>& remap)
{
	const Eigen::RowVector3d lo = V.colwise().minCoeff();
	auto cellOf = [&](const Eigen::RowVector3d& p) {
		const Eigen::RowVector3d c = ((p - lo) / tol).array().floor();
		return Eigen::Vector3i(int64_t(c.x()) & 0x1fffff, int64_t(c.y()) & 0x1fffff, int64_t(c.z()) & 0x1fffff);
	};
	auto key = [](const Eigen::Vector3i& c) {
		return (uint64_t(uint32_t(c.x())) << 42) | (uint64_t(uint32_t(c.y())) << 21) | uint64_t(uint32_t(c.z()));
	};
	std::unordered_map<uint64_t, std::vector<int>> grid;
	grid.reserve(size_t(V.rows()) * 2);
	remap.assign(size_t(V.rows()), 0);
	std::vector<int> representatives;
	for (int i = 0; i < V.rows(); ++i)
	{
		const Eigen::Vector3i c = cellOf(V.row(i));
		int found = -1;
		for (int dx = -1; dx <= 1 && found < 0; ++dx)
			for (int dy = -1; dy <= 1 && found < 0; ++dy)
				for (int dz = -1; dz <= 1 && found < 0; ++dz)
				{
					auto it = grid.find(key(Eigen::Vector3i(c.x() + dx, c.y() + dy, c.z() + dz)));
					if (it == grid.end())
						continue;
					for (int j : it->second)
						if ((V.row(representatives[j]) - V.row(i)).norm() <= tol)
						{
							found = j;
							break;
						}
				}
		if (found < 0)
		{
			found = int(representatives.size());
			representatives.push_back(i);
			grid[key(c)].push_back(found);
		}
		remap[size_t(i)] = found;
	}
	return representatives;
}

/// The input's faces on the welded vertices, without the degenerate ones (repeated indices after welding, or double
/// area <= minDoubleArea), which are counted in *degenerate.
std::vector<Eigen::Vector3i> nonDegenerateFaces(const Eigen::MatrixX3i& F, const std::vector<int>& remap,
												const Eigen::MatrixX3d& welded, double minDoubleArea, int* degenerate)
{
	std::vector<Eigen::Vector3i> faces;
	faces.reserve(size_t(F.rows()));
	for (int f = 0; f < F.rows(); ++f)
	{
		const Eigen::Vector3i t(remap[size_t(F(f, 0))], remap[size_t(F(f, 1))], remap[size_t(F(f, 2))]);
		if (t.x() == t.y() || t.y() == t.z() || t.x() == t.z())
		{
			++*degenerate;
			continue;
		}
		const Eigen::Vector3d a = welded.row(t.x()), b = welded.row(t.y()), c = welded.row(t.z());
		if ((b - a).cross(c - a).norm() <= minDoubleArea)
		{
			++*degenerate;
			continue;
		}
		faces.push_back(t);
	}
	return faces;
}

} // namespace

LoadedMesh repairMesh(const TriMesh& input, const LoadOptions& options, const std::string& name)
{
	const std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
	checkRepairable(input, options, name);
	LoadedMesh out;
	MeshReport& r = out.report;
	r.path = name;
	r.fileVertices = int(input.V.rows());
	r.fileFaces = int(input.F.rows());
	r.up = options.up;
	r.scale = options.scale;

	const Eigen::MatrixX3d V = toMetresYUp(input.V, options);
	const double diag = bboxDiagonal(V);
	std::vector<int> remap;
	const std::vector<int> representatives =
		weldVertices(V, std::max(options.relativeWeldTolerance * diag, 1e-12), remap);
	r.weldedVertices = int(V.rows()) - int(representatives.size());
	TriMesh welded;
	welded.V.resize(Eigen::Index(representatives.size()), 3);
	for (int j = 0; j < int(representatives.size()); ++j)
		welded.V.row(j) = V.row(representatives[size_t(j)]);

	const std::vector<Eigen::Vector3i> faces =
		nonDegenerateFaces(input.F, remap, welded.V, 1e-14 * diag * diag, &r.degenerateFaces);
	if (faces.empty())
	{
		const std::string stray = strayVertex(V);
		throw InvalidInputError(name + ": " +
								(stray.empty() ? std::string("every face is degenerate (zero area)")
											   : stray + " (a corrupt coordinate?): every face is degenerate at that scale"));
	}
	welded.F.resize(Eigen::Index(faces.size()), 3);
	for (size_t f = 0; f < faces.size(); ++f)
		welded.F.row(Eigen::Index(f)) = faces[f].transpose();

	// Unreferenced vertices are dropped (they would distort the fit and the height).
	std::vector<char> used(welded.V.rows(), 0);
	for (int f = 0; f < welded.F.rows(); ++f)
		for (int k = 0; k < 3; ++k)
			used[welded.F(f, k)] = 1;
	r.unreferencedVertices = int(std::count(used.begin(), used.end(), 0));
	out.full = extract(welded, used);

	keepBody(out, options.components);

	requireUsable(out.mesh, name);
	r.bboxDiagonal = bboxDiagonal(out.mesh.V);
	r.height = out.mesh.V.col(1).maxCoeff() - out.mesh.V.col(1).minCoeff();
	r.repairMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
	return out;
}

const aiScene* readCheckedScene(Assimp::Importer& importer, const std::string& path, unsigned int postProcessing)
{
	// Only regular files (a FIFO blocks open forever, a directory fails deep inside assimp), and the format checks
	// of input_files.h for what assimp 5.2 cannot read safely.
	const std::string problem = inputFileProblem(path);
	if (!problem.empty())
		throw MeshLoadError(path + ": cannot open file: " + problem);
	{
		std::ifstream probe(path, std::ios::binary | std::ios::ate);
		if (probe.tellg() <= 0)
			throw MeshLoadError(path + ": file is empty");
	}
	requireSafeMeshFile(path);
	// Points and lines are removed; we only want triangles.
	importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
	// Two phases, so that corrupt data never reaches assimp's post-processing steps (which crash or abort on it):
	// 1. read + ValidateDataStructure (rejects out-of-range indices: a truncated binary PLY, tests/data/
	//    robust_truncated.ply, otherwise segfaults assimp 5.2 in a later step);
	// 2. our own check of the one inconsistency validation lets through and TriangulateProcess asserts on
	//    (abort): a mesh flagged as having polygons without any face of more than 3 indices (a truncated ASCII
	//    PLY, tests/data/robust_truncated_ascii.ply);
	// 3. the post-processing proper.
	const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
	auto readFailed = [&]() {
		std::string why = importer.GetErrorString();
		std::replace(why.begin(), why.end(), '\n', ' ');
		return MeshLoadError(path + ": cannot read mesh: " + why);
	};
	if (scene == nullptr)
		throw readFailed();
	for (unsigned m = 0; m < scene->mNumMeshes; ++m)
	{
		const aiMesh* mesh = scene->mMeshes[m];
		if ((mesh->mPrimitiveTypes & aiPrimitiveType_POLYGON) == 0)
			continue;
		bool polygon = false;
		for (unsigned f = 0; f < mesh->mNumFaces && !polygon; ++f)
			polygon = mesh->mFaces[f].mNumIndices > 3;
		if (!polygon)
			throw MeshLoadError(path + ": corrupt or truncated face data (mesh " + std::to_string(m) +
								" declares polygons it does not have)");
	}
	scene = importer.ApplyPostProcessing(postProcessing);
	if (scene == nullptr)
		throw readFailed();
	return scene;
}

LoadedMesh loadTriMesh(const std::string& path, const LoadOptions& options)
{
	Assimp::Importer importer;
	const aiScene* scene =
		readCheckedScene(importer, path, aiProcess_Triangulate | aiProcess_PreTransformVertices | aiProcess_SortByPType);
	// (PreTransformVertices bakes the node transforms: glTF, FBX.)
	if ((scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0 || scene->mNumMeshes == 0)
		throw MeshLoadError(path + ": file contains no triangle mesh");

	size_t nv = 0, nf = 0;
	for (unsigned m = 0; m < scene->mNumMeshes; ++m)
	{
		const aiMesh* mesh = scene->mMeshes[m];
		nv += mesh->mNumVertices;
		for (unsigned f = 0; f < mesh->mNumFaces; ++f)
			nf += mesh->mFaces[f].mNumIndices == 3 ? 1 : 0;
	}
	if (nf == 0)
		throw MeshLoadError(path + ": file contains no triangles");

	TriMesh raw;
	raw.V.resize(Eigen::Index(nv), 3);
	raw.F.resize(Eigen::Index(nf), 3);
	size_t vBase = 0, fi = 0;
	for (unsigned m = 0; m < scene->mNumMeshes; ++m)
	{
		const aiMesh* mesh = scene->mMeshes[m];
		for (unsigned i = 0; i < mesh->mNumVertices; ++i)
			raw.V.row(Eigen::Index(vBase + i)) << mesh->mVertices[i].x, mesh->mVertices[i].y, mesh->mVertices[i].z;
		for (unsigned f = 0; f < mesh->mNumFaces; ++f)
		{
			const aiFace& face = mesh->mFaces[f];
			if (face.mNumIndices != 3)
				continue;
			for (int k = 0; k < 3; ++k)
				raw.F(Eigen::Index(fi), k) = int(vBase + face.mIndices[k]);
			++fi;
		}
		vBase += mesh->mNumVertices;
	}
	const std::string precision = checkFloatPrecision(raw, path);
	LoadedMesh loaded = repairMesh(raw, options, path);
	if (!precision.empty())
		loaded.report.warnings.insert(loaded.report.warnings.begin(), precision);
	return loaded;
}

void saveTriMesh(const std::string& path, const TriMesh& mesh, const Eigen::MatrixX3d* colors)
{
	std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
	std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
	const bool ply = ext == ".ply"; // X.PLY too (it used to get OBJ text)
	std::ofstream out(path);
	if (!out)
		throw MeshLoadError(path + ": cannot open for writing");
	out.precision(9);
	const bool hasColors = colors != nullptr && colors->rows() == mesh.V.rows();
	auto byte = [](double c) { return int(std::lround(std::clamp(c, 0.0, 1.0) * 255.0)); };
	if (ply)
	{
		out << "ply\nformat ascii 1.0\nelement vertex " << mesh.V.rows() << "\nproperty float x\nproperty float y\n"
			<< "property float z\n";
		if (hasColors)
			out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
		out << "element face " << mesh.F.rows() << "\nproperty list uchar int vertex_indices\nend_header\n";
		for (int i = 0; i < mesh.V.rows(); ++i)
		{
			out << mesh.V(i, 0) << ' ' << mesh.V(i, 1) << ' ' << mesh.V(i, 2);
			if (hasColors)
				out << ' ' << byte((*colors)(i, 0)) << ' ' << byte((*colors)(i, 1)) << ' ' << byte((*colors)(i, 2));
			out << '\n';
		}
		for (int f = 0; f < mesh.F.rows(); ++f)
			out << "3 " << mesh.F(f, 0) << ' ' << mesh.F(f, 1) << ' ' << mesh.F(f, 2) << '\n';
	}
	else
	{
		for (int i = 0; i < mesh.V.rows(); ++i)
		{
			out << "v " << mesh.V(i, 0) << ' ' << mesh.V(i, 1) << ' ' << mesh.V(i, 2);
			if (hasColors) // the common "v x y z r g b" extension
				out << ' ' << (*colors)(i, 0) << ' ' << (*colors)(i, 1) << ' ' << (*colors)(i, 2);
			out << '\n';
		}
		for (int f = 0; f < mesh.F.rows(); ++f)
			out << "f " << mesh.F(f, 0) + 1 << ' ' << mesh.F(f, 1) + 1 << ' ' << mesh.F(f, 2) + 1 << '\n';
	}
	if (!out)
		throw MeshLoadError(path + ": write failed");
}

} // namespace bodyfit
