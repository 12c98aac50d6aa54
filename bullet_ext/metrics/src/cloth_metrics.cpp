#include "bodyfit/metrics/cloth_metrics.h"

#include "bodyfit/bridge/btEigenConversion.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/statistics.h"

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include <BulletSoftBody/btSoftBody.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace bodyfit::metrics
{
namespace
{

const std::vector<Ellipsoid>& checkedEllipsoids(const std::vector<Ellipsoid>& ellipsoids)
{
	for (std::size_t i = 0; i < ellipsoids.size(); ++i)
		if (!ellipsoids[i].isValid())
			throw InvalidInputError("body reference: ellipsoid " + std::to_string(i) +
									" is not valid (non-finite, non-positive radii or not a rotation)");
	return ellipsoids;
}

bool nodeIsFinite(const btSoftBody::Node& n) { return toEigen(n.m_x).allFinite() && toEigen(n.m_v).allFinite(); }

/// Smallest zeta over the ellipsoids and the depth of the deepest one containing p (0 when none does).
void ellipsoidDepth(const std::vector<Ellipsoid>& ellipsoids, const Eigen::Vector3d& p, double* minZeta,
					double* depth)
{
	double z = std::numeric_limits<double>::infinity();
	double d = 0.0;
	for (const Ellipsoid& e : ellipsoids)
	{
		const double ze = e.zeta(p);
		z = std::min(z, ze);
		if (ze < 1.0)
			d = std::max(d, -closestSurfacePoint(e, p).signedDistance);
	}
	*minZeta = z;
	*depth = d;
}

/// Signed distance from p to the ellipsoid union's surface as the collider sees it: the smallest signed distance
/// over the ellipsoids whose box lies within `threshold` (inf when none does).
double nearUnionDistance(const std::vector<Ellipsoid>& ellipsoids, const Eigen::Vector3d& p, double threshold)
{
	double best = std::numeric_limits<double>::infinity();
	for (const Ellipsoid& e : ellipsoids)
	{
		if (e.aabb().exteriorDistance(p) > threshold)
			continue;
		best = std::min(best, closestSurfacePoint(e, p).signedDistance);
	}
	return best;
}

std::vector<int> nodesNearEllipsoids(const btSoftBody& cloth, const BodyReference& body, double threshold)
{
	std::vector<int> nodes;
	for (int i = 0; i < cloth.m_nodes.size(); ++i)
	{
		const Eigen::Vector3d p = body.toBodyFrame(toEigen(cloth.m_nodes[i].m_x));
		if (p.allFinite() && nearUnionDistance(body.ellipsoids(), p, threshold) <= threshold)
			nodes.push_back(i);
	}
	return nodes;
}

std::vector<int> nodesWithRigidContacts(const btSoftBody& cloth)
{
	std::vector<char> flag(std::size_t(cloth.m_nodes.size()), 0);
	if (flag.empty())
		return {};
	const btSoftBody::Node* base = &cloth.m_nodes[0];
	for (int c = 0; c < cloth.m_rcontacts.size(); ++c)
		flag[std::size_t(cloth.m_rcontacts[c].m_node - base)] = 1;
	std::vector<int> nodes;
	for (std::size_t i = 0; i < flag.size(); ++i)
		if (flag[i])
			nodes.push_back(int(i));
	return nodes;
}

std::vector<int> nodesWithColliderContacts(const btSoftBody& cloth, const btEllipsoidClothCollider& collider)
{
	const btAlignedObjectArray<unsigned char>* flags = collider.getContactFlags(&cloth);
	if (!flags)
		return {};
	if (flags->size() != cloth.m_nodes.size())
		throw InvalidInputError("contact rule ColliderContacts: the collider's record has " +
								std::to_string(flags->size()) + " nodes, the soft body " +
								std::to_string(cloth.m_nodes.size()) + " (nodes added since its last substep)");
	std::vector<int> nodes;
	for (int i = 0; i < flags->size(); ++i)
		if ((*flags)[i])
			nodes.push_back(i);
	return nodes;
}

nlohmann::json finiteOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

/// Segment a + t (b - a), t in [0, 1], against triangle (p0, p1, p2), closed (edges and vertices count); Moeller and
/// Trumbore's barycentric solve. \return t, or a negative value when they do not meet (parallel: no hit).
double segmentTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& p0,
					   const Eigen::Vector3d& p1, const Eigen::Vector3d& p2)
{
	const Eigen::Vector3d d = b - a, e1 = p1 - p0, e2 = p2 - p0;
	const Eigen::Vector3d h = d.cross(e2);
	const double det = e1.dot(h);
	const double scale = e1.norm() * e2.norm() * d.norm();
	if (!(std::abs(det) > 1e-14 * scale))
		return -1.0;
	const Eigen::Vector3d s = a - p0;
	const double u = s.dot(h) / det;
	if (u < 0.0 || u > 1.0)
		return -1.0;
	const Eigen::Vector3d q = s.cross(e1);
	const double v = d.dot(q) / det;
	if (v < 0.0 || u + v > 1.0)
		return -1.0;
	const double t = e2.dot(q) / det;
	return t >= 0.0 && t <= 1.0 ? t : -1.0;
}

} // namespace

/// The mesh's triangles binned by their boxes into cubic cells (CSR lists), for segment queries.
class BodyReference::TriangleGrid
{
public:
	explicit TriangleGrid(const TriMesh& mesh);
	/// Hit parameters of the segment a-b against the triangles of the cells under its box, one per triangle, sorted.
	std::vector<double> hits(const TriMesh& mesh, const Eigen::Vector3d& a, const Eigen::Vector3d& b) const;

private:
	Eigen::Vector3d origin_;
	double cell_ = 1.0;
	int dims_[3] = {1, 1, 1};
	std::vector<int> start_;
	std::vector<int> faces_;

	int cellOf(double x, int k) const { return std::clamp(int(std::floor((x - origin_[k]) / cell_)), 0, dims_[k] - 1); }
	int index(int x, int y, int z) const { return (z * dims_[1] + y) * dims_[0] + x; }
	/// Calls f(cell) for every cell under the box [lo, hi].
	template <class F>
	void forCells(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, F f) const
	{
		for (int z = cellOf(lo.z(), 2); z <= cellOf(hi.z(), 2); ++z)
			for (int y = cellOf(lo.y(), 1); y <= cellOf(hi.y(), 1); ++y)
				for (int x = cellOf(lo.x(), 0); x <= cellOf(hi.x(), 0); ++x)
					f(index(x, y, z));
	}
};

BodyReference::TriangleGrid::TriangleGrid(const TriMesh& mesh)
{
	const Eigen::Vector3d lo = mesh.V.colwise().minCoeff().transpose(), hi = mesh.V.colwise().maxCoeff().transpose();
	const Eigen::Vector3d extent = (hi - lo).cwiseMax(1e-9);
	double meanEdge = 0.0;
	for (int f = 0; f < mesh.F.rows(); ++f)
		meanEdge += (mesh.V.row(mesh.F(f, 0)) - mesh.V.row(mesh.F(f, 1))).norm();
	meanEdge /= double(mesh.F.rows());
	// Cells of two mean edges (a triangle spans few), but no more than 128 along the longest side.
	cell_ = std::max(2.0 * meanEdge, extent.maxCoeff() / 128.0);
	origin_ = lo;
	for (int k = 0; k < 3; ++k)
		dims_[k] = std::max(1, int(std::ceil(extent[k] / cell_)));
	std::vector<std::vector<int>> lists(size_t(dims_[0]) * dims_[1] * dims_[2]);
	for (int f = 0; f < mesh.F.rows(); ++f)
	{
		Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose(), b = a;
		for (int j = 1; j < 3; ++j)
		{
			a = a.cwiseMin(mesh.V.row(mesh.F(f, j)).transpose());
			b = b.cwiseMax(mesh.V.row(mesh.F(f, j)).transpose());
		}
		forCells(a, b, [&](int c) { lists[size_t(c)].push_back(f); });
	}
	start_.assign(lists.size() + 1, 0);
	for (size_t c = 0; c < lists.size(); ++c)
	{
		start_[c + 1] = start_[c] + int(lists[c].size());
		faces_.insert(faces_.end(), lists[c].begin(), lists[c].end());
	}
}

std::vector<double> BodyReference::TriangleGrid::hits(const TriMesh& mesh, const Eigen::Vector3d& a,
													  const Eigen::Vector3d& b) const
{
	std::vector<std::pair<int, double>> found; // (face, t): a face listed in several cells is tested once per cell
	forCells(a.cwiseMin(b), a.cwiseMax(b), [&](int c) {
		for (int i = start_[size_t(c)]; i < start_[size_t(c) + 1]; ++i)
		{
			const int f = faces_[size_t(i)];
			const double t = segmentTriangle(a, b, mesh.V.row(mesh.F(f, 0)).transpose(), mesh.V.row(mesh.F(f, 1)).transpose(),
											 mesh.V.row(mesh.F(f, 2)).transpose());
			if (t >= 0.0)
				found.emplace_back(f, t);
		}
	});
	std::sort(found.begin(), found.end());
	found.erase(std::unique(found.begin(), found.end(), [](const auto& x, const auto& y) { return x.first == y.first; }),
				found.end());
	std::vector<double> out;
	for (const auto& hit : found)
		out.push_back(hit.second);
	std::sort(out.begin(), out.end());
	// A hit on an edge or vertex shared by several triangles is one crossing of the surface.
	out.erase(std::unique(out.begin(), out.end(), [](double x, double y) { return y - x < 1e-9; }), out.end());
	return out;
}

BodyReference::BodyReference(TriMesh mesh, std::vector<Ellipsoid> ellipsoids)
	: mesh_(std::move(mesh)),
	  ellipsoids_(checkedEllipsoids(ellipsoids)),
	  pose_(btTransform::getIdentity()),
	  inside_(mesh_),
	  distance_(std::in_place, mesh_),
	  triangles_(std::make_shared<const TriangleGrid>(mesh_))
{
}

void BodyReference::setShape(const Eigen::MatrixX3d& vertices, std::vector<Ellipsoid> ellipsoids)
{
	if (vertices.rows() != mesh_.V.rows())
		throw InvalidInputError("BodyReference::setShape: " + std::to_string(vertices.rows()) +
								" vertices given, the body mesh has " + std::to_string(mesh_.V.rows()));
	TriMesh moved = mesh_;
	moved.V = vertices;
	MeshInsideTest inside(moved); // validates the coordinates before anything is replaced
	ellipsoids_ = checkedEllipsoids(ellipsoids);
	mesh_ = std::move(moved);
	inside_ = std::move(inside);
	distance_.reset(); // both rebuilt from mesh_ at the next query that needs them
	triangles_.reset();
}

const MeshDistanceGrid& BodyReference::distanceGrid() const
{
	if (!distance_)
		distance_.emplace(mesh_);
	return *distance_;
}

std::vector<double> BodyReference::segmentHits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const
{
	if (!triangles_)
		triangles_ = std::make_shared<const TriangleGrid>(mesh_);
	return triangles_->hits(mesh_, a, b);
}

void BodyReference::setPose(const btTransform& bodyToWorld)
{
	pose_ = bodyToWorld;
	worldToBody_ = toEigen(bodyToWorld).inverse();
}

double BodyReference::signedSkinDistance(const Eigen::Vector3d& bodyPoint) const
{
	const double unsignedDistance = distanceGrid().distance(bodyPoint);
	return inside_.isInside(bodyPoint) ? -unsignedDistance : unsignedDistance;
}

PenetrationCounts measurePenetration(const btSoftBody& cloth, const BodyReference& body)
{
	PenetrationCounts s;
	s.nodes = cloth.m_nodes.size();
	Eigen::MatrixX3d local(s.nodes, 3);
	int finite = 0;
	for (int i = 0; i < s.nodes; ++i)
	{
		if (!nodeIsFinite(cloth.m_nodes[i]))
		{
			++s.nanNodes;
			continue;
		}
		local.row(finite++) = body.toBodyFrame(toEigen(cloth.m_nodes[i].m_x)).transpose();
	}
	local.conservativeResize(finite, 3);
	s.insideBody = body.countInside(local);
	if (body.ellipsoids().empty())
		return s;
	s.insideEllipsoids = 0;
	for (int i = 0; i < local.rows(); ++i)
	{
		double zeta = 0.0, depth = 0.0;
		ellipsoidDepth(body.ellipsoids(), local.row(i).transpose(), &zeta, &depth);
		s.minZeta = std::min(s.minZeta, zeta);
		s.maxEllipsoidDepth = std::max(s.maxEllipsoidDepth, depth);
		if (depth > kInsideEllipsoidDepth)
			++s.insideEllipsoids;
	}
	return s;
}

std::vector<int> contactNodes(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options)
{
	switch (options.rule)
	{
	case ContactRule::NearEllipsoids:
		if (body.ellipsoids().empty())
			throw InvalidInputError("contact rule NearEllipsoids needs a body reference with ellipsoids");
		if (!(options.distance >= 0.0))
			throw InvalidInputError("contact distance " + std::to_string(options.distance) + " m is not >= 0");
		return nodesNearEllipsoids(cloth, body, options.distance);
	case ContactRule::RigidContacts:
		return nodesWithRigidContacts(cloth);
	case ContactRule::ColliderContacts:
		if (!options.collider)
			throw InvalidInputError("contact rule ColliderContacts needs the collider (ContactOptions::collider)");
		return nodesWithColliderContacts(cloth, *options.collider);
	case ContactRule::None:
		break;
	}
	return {};
}

std::vector<double> skinDistances(const btSoftBody& cloth, const BodyReference& body, const std::vector<int>& nodes)
{
	std::vector<double> d;
	d.reserve(nodes.size());
	for (int i : nodes)
	{
		if (i < 0 || i >= cloth.m_nodes.size())
			throw InvalidInputError("skin distance of node " + std::to_string(i) + ": the soft body has " +
									std::to_string(cloth.m_nodes.size()) + " nodes");
		const Eigen::Vector3d p = body.toBodyFrame(toEigen(cloth.m_nodes[i].m_x));
		if (p.allFinite())
			d.push_back(body.signedSkinDistance(p));
	}
	return d;
}

GapSummary summarizeGaps(const std::vector<double>& gaps)
{
	GapSummary g;
	g.count = int(gaps.size());
	if (gaps.empty())
		return g;
	g.mean = mean(gaps);
	g.median = median(gaps);
	g.p95 = quantile(gaps, 0.95);
	g.max = *std::max_element(gaps.begin(), gaps.end());
	return g;
}

ContactMetrics measureContacts(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options)
{
	ContactMetrics c;
	const std::vector<int> nodes = contactNodes(cloth, body, options);
	c.contactNodes = int(nodes.size());
	c.gap = summarizeGaps(skinDistances(cloth, body, nodes));
	return c;
}

namespace
{

/// Deepest point inside the body along the segment a-b whose triangle hits are `hits` (ascending): the stretches
/// between hits 1-2, 3-4, ... are inside (both ends are outside), 9 points of each are measured.
double crossingDepth(const BodyReference& body, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
					 const std::vector<double>& hits)
{
	double depth = 0.0;
	for (size_t k = 0; k + 1 < hits.size(); k += 2)
		for (int j = 1; j <= 9; ++j)
		{
			const double t = hits[k] + (hits[k + 1] - hits[k]) * double(j) / 10.0;
			const Eigen::Vector3d p = a + t * (b - a);
			if (body.isInside(p))
				depth = std::max(depth, body.skinDistance(p));
		}
	return depth;
}

/// Deepest of the 10 interior samples (i a + j b + k c) / 6, i, j, k >= 1, that lie inside the body; -1 when none does.
double faceCrossingDepth(const BodyReference& body, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
						 const Eigen::Vector3d& c)
{
	double depth = -1.0;
	for (int i = 1; i <= 4; ++i)
		for (int j = 1; i + j <= 5; ++j)
		{
			const Eigen::Vector3d p = (double(i) * a + double(j) * b + double(6 - i - j) * c) / 6.0;
			if (body.isInside(p))
				depth = std::max(depth, body.skinDistance(p));
		}
	return depth;
}

} // namespace

EdgeCrossings measureEdgeCrossings(const btSoftBody& cloth, const BodyReference& body)
{
	EdgeCrossings out;
	out.measured = true;
	const int n = cloth.m_nodes.size();
	std::vector<Eigen::Vector3d> local(static_cast<size_t>(n));
	std::vector<double> distance(static_cast<size_t>(n), -1.0); // -1: non-finite or inside (such links are not crossings)
	for (int i = 0; i < n; ++i)
	{
		local[size_t(i)] = body.toBodyFrame(toEigen(cloth.m_nodes[i].m_x));
		if (local[size_t(i)].allFinite() && !body.isInside(local[size_t(i)]))
			distance[size_t(i)] = body.skinDistance(local[size_t(i)]);
	}
	const btSoftBody::Node* base = n > 0 ? &cloth.m_nodes[0] : nullptr;
	for (int l = 0; l < cloth.m_links.size(); ++l)
	{
		if (cloth.m_links[l].m_bbending)
			continue; // a spring across two faces (btSoftBody::generateBendingConstraints), not an edge of the cloth
		const int i = int(cloth.m_links[l].m_n[0] - base), j = int(cloth.m_links[l].m_n[1] - base);
		const Eigen::Vector3d &a = local[size_t(i)], &b = local[size_t(j)];
		if (!a.allFinite() || !b.allFinite())
			continue;
		++out.links;
		if (distance[size_t(i)] < 0.0 || distance[size_t(j)] < 0.0 ||
			distance[size_t(i)] + distance[size_t(j)] > (b - a).norm())
			continue;
		const std::vector<double> hits = body.segmentHits(a, b);
		if (hits.empty())
			continue;
		++out.crossing;
		out.maxDepth = std::max(out.maxDepth, crossingDepth(body, a, b, hits));
	}
	for (int f = 0; f < cloth.m_faces.size(); ++f)
	{
		const btSoftBody::Face& face = cloth.m_faces[f];
		const size_t i = size_t(face.m_n[0] - base), j = size_t(face.m_n[1] - base), k = size_t(face.m_n[2] - base);
		if (!local[i].allFinite() || !local[j].allFinite() || !local[k].allFinite())
			continue;
		++out.faces;
		const double longest = std::max({(local[j] - local[i]).norm(), (local[k] - local[j]).norm(),
										 (local[i] - local[k]).norm()});
		if (distance[i] < 0.0 || distance[j] < 0.0 || distance[k] < 0.0 ||
			std::min({distance[i], distance[j], distance[k]}) > longest)
			continue;
		const double depth = faceCrossingDepth(body, local[i], local[j], local[k]);
		if (depth < 0.0)
			continue;
		++out.facesCrossing;
		out.maxFaceDepth = std::max(out.maxFaceDepth, depth);
	}
	return out;
}

ClothMetrics measureCloth(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options)
{
	return ClothMetrics{measurePenetration(cloth, body), measureContacts(cloth, body, options),
						measureEdgeCrossings(cloth, body)};
}

nlohmann::json toJson(const ClothMetrics& m)
{
	const PenetrationCounts& p = m.penetration;
	const GapSummary& g = m.contacts.gap;
	const bool ellipsoids = p.insideEllipsoids >= 0;
	auto gap = [&](double v) { return g.count > 0 ? nlohmann::json(v) : nlohmann::json(nullptr); };
	nlohmann::json j;
	j["nodes"] = p.nodes;
	j["nan_nodes"] = p.nanNodes;
	j["nodes_inside_body"] = p.insideBody;
	j["nodes_inside_ellipsoids"] = ellipsoids ? nlohmann::json(p.insideEllipsoids) : nlohmann::json(nullptr);
	j["min_zeta"] = finiteOrNull(p.minZeta);
	j["ellipsoid_penetration_m"] = ellipsoids ? nlohmann::json(p.maxEllipsoidDepth) : nlohmann::json(nullptr);
	j["contact_nodes"] = m.contacts.contactNodes;
	j["mean_contact_gap_m"] = gap(g.mean);
	j["median_contact_gap_m"] = gap(g.median);
	j["p95_contact_gap_m"] = gap(g.p95);
	j["max_contact_gap_m"] = gap(g.max);
	const auto crossing = [&](auto v) { return m.crossings.measured ? nlohmann::json(v) : nlohmann::json(nullptr); };
	j["links"] = crossing(m.crossings.links);
	j["links_crossing_body"] = crossing(m.crossings.crossing);
	j["max_link_crossing_depth_m"] = crossing(m.crossings.maxDepth);
	j["faces"] = crossing(m.crossings.faces);
	j["faces_crossing_body"] = crossing(m.crossings.facesCrossing);
	j["max_face_crossing_depth_m"] = crossing(m.crossings.maxFaceDepth);
	return j;
}

} // namespace bodyfit::metrics
