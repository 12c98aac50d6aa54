#include "bodyfit/metrics/cloth_metrics.h"

#include "bodyfit/bridge/btEigenConversion.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/statistics.h"

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

nlohmann::json finiteOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

} // namespace

BodyReference::BodyReference(TriMesh mesh, std::vector<Ellipsoid> ellipsoids)
	: mesh_(std::move(mesh)),
	  ellipsoids_(checkedEllipsoids(ellipsoids)),
	  pose_(btTransform::getIdentity()),
	  inside_(mesh_),
	  distance_(std::in_place, mesh_)
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
	distance_.reset(); // rebuilt from mesh_ at the next distance query
}

void BodyReference::setPose(const btTransform& bodyToWorld)
{
	pose_ = bodyToWorld;
	worldToBody_ = toEigen(bodyToWorld).inverse();
}

double BodyReference::signedSkinDistance(const Eigen::Vector3d& bodyPoint) const
{
	if (!distance_)
		distance_.emplace(mesh_);
	const double unsignedDistance = distance_->distance(bodyPoint);
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

ClothMetrics measureCloth(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options)
{
	return ClothMetrics{measurePenetration(cloth, body), measureContacts(cloth, body, options)};
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
	return j;
}

} // namespace bodyfit::metrics
