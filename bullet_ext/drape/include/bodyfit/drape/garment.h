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

/// Builds the garment in world coordinates as the scene says (bullet_patch: the nodes and faces
/// btSoftBodyHelpers::CreatePatch makes, read back from a soft body built for the purpose).
/// \throws MeshLoadError / InvalidInputError for unreadable garment meshes.
GarmentMesh buildGarmentMesh(const GarmentSpec& spec);

/// Centre of a horizontal patch held `drop` metres above the top of `body` (y up), over the head: mean x and z of
/// the vertices in the top 10% of the body's height.
Eigen::Vector3d patchCenterAboveHead(const TriMesh& body, double drop);

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

/// Bullet's own patch (garment type bullet_patch), for comparisons with stock Bullet: btSoftBodyHelpers::CreatePatch
/// over the spec's rectangle (float corners centre -/+ size / 2) with its diagonal links (one per quad, alternating),
/// no bending links (material.bending is not used), one Bullet material with kLST = material.stretch (kAST, kVST
/// stay 1), equal node masses summing to material.mass, margin set after the nodes exist, piterations and kDP from
/// the scene. Node (ix, iz) has index iz * resolution.x + ix, as for `patch`.
btSoftBody* buildBulletPatch(btSoftBodyWorldInfo& worldInfo, const GarmentSpec& spec, const MaterialSpec& material,
							 const SolverSpec& solver);

/// The garment as it is in a soft body: node positions and faces (resX/resZ as given, 0 for no grid).
GarmentMesh garmentMeshOf(const btSoftBody& softBody, int resX = 0, int resZ = 0);

/// The cloth of a scene: buildGarmentMesh + buildSoftBody, or buildBulletPatch for a bullet_patch (its garment mesh
/// then read back with garmentMeshOf). Returns the soft body (owned by the caller) and fills `garment`.
btSoftBody* buildCloth(btSoftBodyWorldInfo& worldInfo, const Scene& scene, GarmentMesh& garment);

/// Node indices selected by a pin effect. \throws FormatError naming `effects.pin` when the selection is empty or an
/// index is out of range.
std::vector<int> selectPinnedNodes(const PinSpec& pin, const GarmentMesh& garment, const std::string& sceneFile);

} // namespace bodyfit::drape
