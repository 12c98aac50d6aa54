#include "bodyfit/drape/garment.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/subdivision.h"

#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <unordered_set>

namespace bodyfit::drape
{
namespace
{

std::uint64_t edgeKey(int a, int b)
{
	if (a > b)
		std::swap(a, b);
	return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

GarmentMesh makePatch(const GarmentSpec& s)
{
	GarmentMesh g;
	g.resX = s.resolution.x();
	g.resZ = s.resolution.y();
	const int nx = g.resX, nz = g.resZ;
	g.mesh.V.resize(nx * nz, 3);
	for (int iz = 0; iz < nz; ++iz)
		for (int ix = 0; ix < nx; ++ix)
			g.mesh.V.row(iz * nx + ix) << s.center.x() + s.size.x() * (double(ix) / (nx - 1) - 0.5), s.center.y(),
				s.center.z() + s.size.y() * (double(iz) / (nz - 1) - 0.5);
	g.mesh.F.resize(2 * (nx - 1) * (nz - 1), 3);
	int f = 0;
	for (int iz = 0; iz + 1 < nz; ++iz)
		for (int ix = 0; ix + 1 < nx; ++ix)
		{
			const int a = iz * nx + ix, b = a + 1, c = a + nx, d = c + 1;
			// Alternate the diagonal so the patch has no preferred shear direction; faces point +y (CCW from above).
			if ((ix + iz) % 2 == 0)
			{
				g.mesh.F.row(f++) << a, c, d;
				g.mesh.F.row(f++) << a, d, b;
			}
			else
			{
				g.mesh.F.row(f++) << a, c, b;
				g.mesh.F.row(f++) << b, c, d;
			}
		}
	return g;
}

GarmentMesh makeTube(const GarmentSpec& s)
{
	GarmentMesh g;
	const int ns = s.segments, nr = s.rings;
	g.mesh.V.resize(ns * nr, 3);
	for (int r = 0; r < nr; ++r)
		for (int k = 0; k < ns; ++k)
		{
			const double phi = 2.0 * M_PI * k / ns;
			g.mesh.V.row(r * ns + k) << s.center.x() + s.radius * std::cos(phi),
				s.center.y() + s.length * (double(r) / (nr - 1) - 0.5), s.center.z() - s.radius * std::sin(phi);
		}
	g.mesh.F.resize(2 * ns * (nr - 1), 3);
	int f = 0;
	for (int r = 0; r + 1 < nr; ++r)
		for (int k = 0; k < ns; ++k)
		{
			const int a = r * ns + k, b = r * ns + (k + 1) % ns, c = a + ns, d = b + ns;
			g.mesh.F.row(f++) << a, b, d; // outward normals
			g.mesh.F.row(f++) << a, d, c;
		}
	return g;
}

GarmentMesh loadGarment(const GarmentSpec& s)
{
	GarmentMesh g;
	g.mesh = loadTriMesh(s.mesh).full;
	Eigen::Vector3d centre = s.scaleCenter ? *s.scaleCenter : Eigen::Vector3d(g.mesh.V.colwise().mean().transpose());
	for (int i = 0; i < g.mesh.V.rows(); ++i)
	{
		const Eigen::Vector3d p = g.mesh.V.row(i).transpose();
		g.mesh.V.row(i) = (centre + s.scale.cwiseProduct(p - centre) + s.offset).transpose();
	}
	for (int k = 0; k < s.subdivisions; ++k)
		g.mesh = midpointSubdivide(g.mesh);
	return g;
}

} // namespace

GarmentMesh buildGarmentMesh(const GarmentSpec& spec)
{
	switch (spec.type)
	{
	case GarmentType::Patch:
		return makePatch(spec);
	case GarmentType::BulletPatch:
	{
		btSoftBodyWorldInfo info;
		const std::unique_ptr<btSoftBody> cloth(buildBulletPatch(info, spec, MaterialSpec{}, SolverSpec{}));
		return garmentMeshOf(*cloth, spec.resolution.x(), spec.resolution.y());
	}
	case GarmentType::Tube:
		return makeTube(spec);
	case GarmentType::Skirt:
	case GarmentType::Tights:
		return loadGarment(spec);
	}
	throw InvalidInputError("unknown garment type");
}

Eigen::Vector3d patchCenterAboveHead(const TriMesh& body, double drop)
{
	const double top = body.V.col(1).maxCoeff();
	const double h = top - body.V.col(1).minCoeff();
	Eigen::Vector2d c(0, 0);
	int n = 0;
	for (int i = 0; i < body.V.rows(); ++i)
		if (body.V(i, 1) > top - 0.1 * h)
		{
			c += Eigen::Vector2d(body.V(i, 0), body.V(i, 2));
			++n;
		}
	c /= double(std::max(1, n));
	return Eigen::Vector3d(c.x(), top + drop, c.y());
}

btSoftBody* buildBulletPatch(btSoftBodyWorldInfo& worldInfo, const GarmentSpec& spec, const MaterialSpec& material,
							 const SolverSpec& solver)
{
	const btScalar cx = btScalar(spec.center.x()), y = btScalar(spec.center.y()), cz = btScalar(spec.center.z());
	const btScalar hx = btScalar(spec.size.x() / 2), hz = btScalar(spec.size.y() / 2);
	btSoftBody* psb = btSoftBodyHelpers::CreatePatch(worldInfo, btVector3(cx - hx, y, cz - hz),
													 btVector3(cx + hx, y, cz - hz), btVector3(cx - hx, y, cz + hz),
													 btVector3(cx + hx, y, cz + hz), spec.resolution.x(),
													 spec.resolution.y(), 0, true);
	psb->getCollisionShape()->setMargin(btScalar(material.margin));
	psb->m_cfg.piterations = solver.iterations;
	psb->m_cfg.kDP = btScalar(material.damping);
	psb->m_materials[0]->m_kLST = btScalar(material.stretch);
	psb->setTotalMass(btScalar(material.mass));
	return psb;
}

GarmentMesh garmentMeshOf(const btSoftBody& softBody, int resX, int resZ)
{
	GarmentMesh g;
	g.resX = resX;
	g.resZ = resZ;
	g.mesh.V.resize(softBody.m_nodes.size(), 3);
	for (int i = 0; i < softBody.m_nodes.size(); ++i)
	{
		const btVector3& x = softBody.m_nodes[i].m_x;
		g.mesh.V.row(i) << double(x.x()), double(x.y()), double(x.z());
	}
	g.mesh.F.resize(softBody.m_faces.size(), 3);
	if (softBody.m_nodes.size() == 0)
		return g;
	const btSoftBody::Node* base = &softBody.m_nodes[0];
	for (int f = 0; f < softBody.m_faces.size(); ++f)
		for (int k = 0; k < 3; ++k)
			g.mesh.F(f, k) = int(softBody.m_faces[f].m_n[k] - base);
	return g;
}

btSoftBody* buildCloth(btSoftBodyWorldInfo& worldInfo, const Scene& scene, GarmentMesh& garment)
{
	if (scene.garment.type == GarmentType::BulletPatch)
	{
		btSoftBody* psb = buildBulletPatch(worldInfo, scene.garment, scene.material, scene.solver);
		garment = garmentMeshOf(*psb, scene.garment.resolution.x(), scene.garment.resolution.y());
		return psb;
	}
	garment = buildGarmentMesh(scene.garment);
	return buildSoftBody(worldInfo, garment.mesh, scene.material, scene.solver);
}

namespace
{

/// A soft-body material of linear and area stiffness k (volume 1, default flags).
btSoftBody::Material* appendStiffness(btSoftBody* psb, double k)
{
	btSoftBody::Material* m = psb->appendMaterial();
	m->m_kLST = btScalar(k);
	m->m_kAST = btScalar(k);
	m->m_kVST = 1;
	m->m_flags = btSoftBody::fMaterial::Default;
	return m;
}

/// A mesh edge with the vertices opposite to it in its faces (-1 = none yet); two opposites: an interior edge.
struct EdgeInfo
{
	int a, b;
	int opposite[2];
};

/// The mesh's unique edges in the order faces first meet them, each with its key (edgeKey) in `keys`.
std::vector<EdgeInfo> uniqueEdges(const TriMesh& mesh, std::unordered_map<std::uint64_t, int>& keys)
{
	keys.clear();
	keys.reserve(std::size_t(mesh.F.rows()) * 2);
	std::vector<EdgeInfo> edges;
	edges.reserve(std::size_t(mesh.F.rows()) * 2);
	for (int f = 0; f < mesh.F.rows(); ++f)
		for (int k = 0; k < 3; ++k)
		{
			const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3), c = mesh.F(f, (k + 2) % 3);
			auto [it, inserted] = keys.emplace(edgeKey(a, b), int(edges.size()));
			if (inserted)
				edges.push_back({a, b, {c, -1}});
			else if (edges[std::size_t(it->second)].opposite[1] < 0)
				edges[std::size_t(it->second)].opposite[1] = c;
		}
	return edges;
}

/// A bending link across every interior edge (between its two opposite vertices), unless those are already linked
/// (by an edge or an earlier bending link). Returns how many were added.
int appendBendingLinks(btSoftBody* psb, const std::vector<EdgeInfo>& edges,
					   const std::unordered_map<std::uint64_t, int>& edgeKeys, btSoftBody::Material* bend)
{
	std::unordered_set<std::uint64_t> linked;
	linked.reserve(edges.size() * 2);
	for (const auto& kv : edgeKeys)
		linked.insert(kv.first);
	int added = 0;
	for (const EdgeInfo& e : edges)
	{
		if (e.opposite[1] < 0 || e.opposite[0] == e.opposite[1])
			continue;
		if (!linked.insert(edgeKey(e.opposite[0], e.opposite[1])).second)
			continue;
		psb->appendLink(e.opposite[0], e.opposite[1], bend, false);
		psb->m_links[psb->m_links.size() - 1].m_bbending = 1;
		++added;
	}
	return added;
}

/// Mass, solver iterations, damping, no friction, SDF_RS collisions; the links shuffled and the normals updated.
void configureSoftBody(btSoftBody* psb, const MaterialSpec& material, const SolverSpec& solver)
{
	psb->setTotalMass(btScalar(material.mass), true);
	psb->m_cfg.piterations = solver.iterations;
	psb->m_cfg.kDP = btScalar(material.damping);
	psb->m_cfg.kDF = 0; // no friction unless the scene lists the `friction` effect
	psb->m_cfg.collisions = btSoftBody::fCollision::SDF_RS;
	// Deterministic (Bullet seeds its own generator) shuffle of link order: better Gauss-Seidel convergence.
	psb->randomizeConstraints();
	psb->updateNormals();
}

} // namespace

btSoftBody* buildSoftBody(btSoftBodyWorldInfo& worldInfo, const TriMesh& mesh, const MaterialSpec& material,
						  const SolverSpec& solver, SoftBodyBuildInfo* info)
{
	btSoftBody* psb = new btSoftBody(&worldInfo);
	// This constructor creates no material; appendNode gives every node m_materials[0], so create it first.
	btSoftBody::Material* stretch = appendStiffness(psb, material.stretch);
	// The margin must be set before appendNode: it sizes each node's leaf in the node tree.
	psb->getCollisionShape()->setMargin(btScalar(material.margin));
	psb->m_nodes.reserve(int(mesh.V.rows()));
	for (int i = 0; i < mesh.V.rows(); ++i)
		psb->appendNode(btVector3(btScalar(mesh.V(i, 0)), btScalar(mesh.V(i, 1)), btScalar(mesh.V(i, 2))), 1);
	btSoftBody::Material* bend = material.bending > 0.0 ? appendStiffness(psb, material.bending) : nullptr;

	std::unordered_map<std::uint64_t, int> edgeKeys;
	const std::vector<EdgeInfo> edges = uniqueEdges(mesh, edgeKeys);
	psb->m_links.reserve(int(edges.size() * (bend ? 2 : 1)));
	for (const EdgeInfo& e : edges)
		psb->appendLink(e.a, e.b, stretch, false);
	const int bendingLinks = bend ? appendBendingLinks(psb, edges, edgeKeys, bend) : 0;
	psb->m_faces.reserve(int(mesh.F.rows()));
	for (int f = 0; f < mesh.F.rows(); ++f)
		psb->appendFace(mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2), stretch);
	configureSoftBody(psb, material, solver);
	if (info)
	{
		info->nodes = psb->m_nodes.size();
		info->structuralLinks = int(edges.size());
		info->bendingLinks = bendingLinks;
		info->faces = psb->m_faces.size();
	}
	return psb;
}

std::vector<int> selectPinnedNodes(const PinSpec& pin, const GarmentMesh& garment, const std::string& sceneFile)
{
	std::vector<int> nodes;
	const TriMesh& m = garment.mesh;
	const int n = m.vertexCount();
	switch (pin.select)
	{
	case PinSelect::Corners:
		nodes = {0, garment.resX - 1, (garment.resZ - 1) * garment.resX, garment.resZ * garment.resX - 1};
		break;
	case PinSelect::Edge:
		if (pin.side == "-x" || pin.side == "+x")
			for (int iz = 0; iz < garment.resZ; ++iz)
				nodes.push_back(iz * garment.resX + (pin.side == "-x" ? 0 : garment.resX - 1));
		else
			for (int ix = 0; ix < garment.resX; ++ix)
				nodes.push_back((pin.side == "-z" ? 0 : garment.resZ - 1) * garment.resX + ix);
		break;
	case PinSelect::Top:
	{
		const double top = m.V.col(1).maxCoeff();
		for (int i = 0; i < n; ++i)
			if (m.V(i, 1) >= top - pin.band)
				nodes.push_back(i);
		break;
	}
	case PinSelect::Indices:
		for (int i : pin.indices)
		{
			if (i >= n)
				throw FormatError(sceneFile + ": effects.pin.indices: node " + std::to_string(i) +
								  " does not exist (the garment has " + std::to_string(n) + " nodes)");
			nodes.push_back(i);
		}
		break;
	}
	if (nodes.empty())
		throw FormatError(sceneFile + ": effects.pin: the selection is empty");
	return nodes;
}

} // namespace bodyfit::drape
