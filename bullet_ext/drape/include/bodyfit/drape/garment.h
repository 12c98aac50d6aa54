#pragma once
/// \file garment.h
/// Garment geometry (patch, skirt/tights from the assets, tube) and the Bullet soft body built from it node by node
/// (appendNode/appendLink/appendFace with a hash set of edges: Bullet's CreateFromTriMesh allocates a
/// vertices^2 table and generateBendingConstraints a nodes^2 matrix).

#include "bodyfit/drape/scene.h"

#include "bodyfit/fitting/types.h"

#include <vector>

class btSoftBody;
struct btSoftBodyWorldInfo;

namespace bodyfit::drape
{

struct GarmentMesh
{
	TriMesh mesh;
	int resX = 0; ///< patch only: node (ix, iz) has index iz * resX + ix
	int resZ = 0;
};

/// Builds the garment in world coordinates as the scene says.
/// \throws MeshLoadError / InvalidInputError for unreadable garment meshes.
GarmentMesh buildGarmentMesh(const GarmentSpec& spec);

struct SoftBodyBuildInfo
{
	int nodes = 0;
	int structuralLinks = 0;
	int bendingLinks = 0;
	int faces = 0;
};

/// Creates the cloth: one node per vertex, one structural link per unique edge (material kLST = stretch), one
/// bending link across each interior edge between the two opposite vertices (kLST = bending, m_bbending set),
/// one face per triangle, total mass spread by face area, piterations/kDP/margin from the scene. Nothing else
/// (friction, aerodynamics, gravity) is set here: effects own those.
btSoftBody* buildSoftBody(btSoftBodyWorldInfo& worldInfo, const TriMesh& mesh, const MaterialSpec& material,
						  const SolverSpec& solver, SoftBodyBuildInfo* info = nullptr);

/// Node indices selected by a pin effect. \throws FormatError naming `effects.pin` when the selection is empty or an
/// index is out of range.
std::vector<int> selectPinnedNodes(const PinSpec& pin, const GarmentMesh& garment, const std::string& sceneFile);

} // namespace bodyfit::drape
