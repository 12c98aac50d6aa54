#pragma once
/// \file mesh_io.h
/// Mesh input through assimp (OBJ, PLY, STL, glTF/GLB, FBX, ...) and the repairs every mesh gets:
/// triangulate, convert to metres / +y up, weld duplicate vertices, drop degenerate faces, sort out components
/// (a body made of several meshes is kept whole, detached props are left out: see components.h).

#include "bodyfit/fitting/components.h"
#include "bodyfit/fitting/types.h"

#include <string>
#include <vector>

struct aiScene;
namespace Assimp
{
class Importer;
}

namespace bodyfit
{

enum class UpAxis
{
	Y, ///< file is already +y up (no rotation)
	Z, ///< file is +z up: rotated -90 degrees about x so that +z becomes +y
};

struct LoadOptions
{
	UpAxis up = UpAxis::Y;
	double scale = 1.0;                    ///< multiply coordinates by this (0.01 for centimetres, 0.001 for mm)
	double relativeWeldTolerance = 1e-6;   ///< vertices closer than this fraction of the bbox diagonal are merged
	ComponentOptions components;           ///< which components form the body (components.h)
};

/// What loading found and repaired. Printed by the demos.
struct MeshReport
{
	std::string path;
	int fileVertices = 0;        ///< vertices as stored in the file (all meshes of the scene)
	int fileFaces = 0;           ///< triangles after triangulation
	int weldedVertices = 0;      ///< vertices removed by welding
	int degenerateFaces = 0;     ///< zero-area / repeated-index faces dropped
	int unreferencedVertices = 0;///< vertices used by no face, dropped
	int components = 0;          ///< connected components of the repaired mesh
	int attachedComponents = 0;  ///< separate parts joined to the body (touching, a few mm away, passing through)
	int insideComponents = 0;    ///< components enclosed by the body (eyes, teeth), kept and fitted with it
	int insideComponentVertices = 0;
	int detachedComponents = 0;  ///< components that are not part of the body (props): not used for fitting
	int droppedComponentVertices = 0; ///< vertices of the detached components
	std::vector<std::string> warnings; ///< one line each: what the components analysis joined, kept or dropped
	double bboxDiagonal = 0.0;   ///< metres, after scale
	double height = 0.0;         ///< y extent, metres, after up-axis conversion and scale
	UpAxis up = UpAxis::Y;
	double scale = 1.0;
	double repairMs = 0.0;       ///< wall time of the repair (conversion, weld, faces, components) in ms
};

struct LoadedMesh
{
	TriMesh mesh;      ///< the body (every component except detached ones), repaired: what the fitter uses
	TriMesh full;      ///< every component, repaired (e.g. for inside tests against the whole body)
	ComponentLayout components; ///< of `mesh` (vertex indices of `mesh`; its bridges join its separate parts)
	MeshReport report;
};

/// Load, convert and repair a mesh file.
/// \throws MeshLoadError if the file is missing, unreadable, empty, truncated or not a mesh format assimp reads.
/// \throws InvalidInputError if coordinates are non-finite or fewer than 4 distinct points remain.
LoadedMesh loadTriMesh(const std::string& path, const LoadOptions& options = {});

/// The file checks of loadTriMesh (missing or empty file, malformed PLY header, assimp's validation, polygon data
/// that post-processing would abort on), then `postProcessing` (aiPostProcessSteps flags). For other assimp-based
/// readers of the library (rig_io.cpp); the scene belongs to `importer`. \throws MeshLoadError as loadTriMesh.
const aiScene* readCheckedScene(Assimp::Importer& importer, const std::string& path, unsigned int postProcessing);

/// Repairs an in-memory mesh exactly as loadTriMesh does (weld, degenerate faces, unreferenced vertices).
/// \throws InvalidInputError as loadTriMesh.
LoadedMesh repairMesh(const TriMesh& input, const LoadOptions& options = {}, const std::string& name = "<memory>");

/// Checks the preconditions of the fitter: finite coordinates, >= 4 distinct points, >= 1 face, valid indices.
/// \throws InvalidInputError naming the first violated condition.
void requireUsable(const TriMesh& mesh, const std::string& name = "<mesh>");

/// Component id per vertex (0 = the component with the most vertices), and the number of components.
std::vector<int> connectedComponents(const TriMesh& mesh, int* count = nullptr);

/// Writes a PLY (extension .ply, any case) or else an OBJ, with optional per-vertex colours (#V by 3, 0..1).
/// Throws MeshLoadError.
void saveTriMesh(const std::string& path, const TriMesh& mesh, const Eigen::MatrixX3d* colors = nullptr);

const char* toString(UpAxis up);

} // namespace bodyfit
