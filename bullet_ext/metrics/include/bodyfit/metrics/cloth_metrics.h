#pragma once
/// \file cloth_metrics.h
/// Cloth-quality metrics of any btSoftBody against a body, in the user's own world (the scene runner,
/// bodyfit/drape/simulation.h, computes its metrics JSON with these):
///   * nodes inside the real body mesh (MeshInsideTest: ray-parity vote per component, bodyfit/fitting/inside_test.h);
///   * nodes inside the union of the body's ellipsoids (deeper than kInsideEllipsoidDepth), the deepest such node
///     (Eberly distance) and the smallest zeta over all nodes;
///   * NaN/Inf nodes (position or velocity);
///   * contact nodes (ContactRule) and their signed gap to the skin mesh (MeshDistanceGrid, negative inside): mean,
///     median, p95, max;
///   * cloth edges (btSoftBody::m_links) that cross the skin: both ends outside the mesh, the segment through the
///     body (segment-triangle tests over a uniform grid of the mesh's triangles), and the deepest such crossing.
/// Every measure is taken in the body frame: world node positions are carried by the inverse of the body pose, so
/// the mesh and ellipsoids are prepared once (inside test and distance grid) and the body may move.
/// Bullet types appear at this API only as btSoftBody and btTransform; the geometry inside is Eigen double, like the
/// bridge (bodyfit/bridge/btEigenConversion.h). Errors are bodyfit exceptions (bodyfit/fitting/errors.h).

#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/fitting/fit_quality.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/types.h"

#include <LinearMath/btTransform.h>

#include <nlohmann/json.hpp>

#include <limits>
#include <memory>
#include <optional>
#include <vector>

class btEllipsoidClothCollider;
class btSoftBody;

namespace bodyfit::metrics
{

/// A node counts as inside an ellipsoid when it is deeper than this (metres): deeper than float rounding explains.
/// Node positions are float coordinates about 1 m from the origin (ulp 6e-8 to 1.2e-7 m), checked here in double; a
/// relative zeta tolerance would not do, since on the 3 mm thin ellipsoids of a fit one ulp is a zeta error of 4e-5.
constexpr double kInsideEllipsoidDepth = 1e-6;

/// The body a cloth is measured against: its mesh and (optional) ellipsoids in the body frame, the current pose
/// (body frame -> world, identity by default), and the inside test and distance grid built once from the mesh.
class BodyReference
{
public:
	/// \throws InvalidInputError for a mesh without faces, with bad indices or non-finite coordinates, or for an
	/// ellipsoid that is not valid (Ellipsoid::isValid), naming it.
	explicit BodyReference(TriMesh mesh, std::vector<Ellipsoid> ellipsoids = {});

	/// The body's current pose (body frame -> world); measurements use the pose set last.
	void setPose(const btTransform& bodyToWorld);
	const btTransform& pose() const { return pose_; }

	/// The body deformed (a skinned body at another instant): new positions for the mesh's vertices (same rows,
	/// same faces) and the ellipsoids of that instant; rebuilds the inside test now and the distance grid at the
	/// next distance query (each O(faces), milliseconds for a 27k-triangle body): call it when the body has
	/// changed, not per query.
	/// \throws InvalidInputError for another vertex count, non-finite coordinates or an invalid ellipsoid.
	void setShape(const Eigen::MatrixX3d& vertices, std::vector<Ellipsoid> ellipsoids);

	const TriMesh& mesh() const { return mesh_; }
	const std::vector<Ellipsoid>& ellipsoids() const { return ellipsoids_; }

	/// A world point in the body frame (double).
	Eigen::Vector3d toBodyFrame(const Eigen::Vector3d& world) const { return worldToBody_ * world; }
	/// Inside the body mesh (body frame point).
	bool isInside(const Eigen::Vector3d& bodyPoint) const { return inside_.isInside(bodyPoint); }
	/// Number of rows of `bodyPoints` (body frame) inside the mesh.
	int countInside(const Eigen::MatrixX3d& bodyPoints) const { return inside_.countInside(bodyPoints); }
	/// Signed distance from a body-frame point to the skin mesh (negative inside).
	double signedSkinDistance(const Eigen::Vector3d& bodyPoint) const;
	/// Unsigned distance from a body-frame point to the skin mesh.
	double skinDistance(const Eigen::Vector3d& bodyPoint) const { return distanceGrid().distance(bodyPoint); }
	/// Parameters t in [0, 1] where the body-frame segment a + t (b - a) meets the mesh, ascending (a hit on an edge or
	/// vertex shared by several triangles is listed once: hits closer than 1e-9 in t are merged).
	std::vector<double> segmentHits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const;

private:
	class TriangleGrid;
	TriMesh mesh_;
	std::vector<Ellipsoid> ellipsoids_;
	btTransform pose_;
	Eigen::Isometry3d worldToBody_ = Eigen::Isometry3d::Identity();
	MeshInsideTest inside_;
	/// Built with the reference; after setShape, at the first query that needs them (samples that only count nodes
	/// inside do not pay for them).
	mutable std::optional<MeshDistanceGrid> distance_;
	mutable std::shared_ptr<const TriangleGrid> triangles_; ///< uniform grid of the triangles' boxes (segmentHits)
	const MeshDistanceGrid& distanceGrid() const;
};

/// Penetration and validity counts at one instant.
struct PenetrationCounts
{
	int nodes = 0;             ///< nodes of the soft body
	int nanNodes = 0;          ///< nodes with a NaN/Inf coordinate or velocity (left out of every other measure)
	int insideBody = 0;        ///< finite nodes inside the body mesh
	int insideEllipsoids = -1; ///< finite nodes deeper than kInsideEllipsoidDepth inside some ellipsoid (-1: none)
	double minZeta = std::numeric_limits<double>::infinity(); ///< smallest zeta over nodes (inf: no ellipsoids)
	double maxEllipsoidDepth = 0.0; ///< deepest node inside an ellipsoid (metres; 0 when none is inside)
};

/// Which nodes touch the body.
enum class ContactRule
{
	/// Within ContactOptions::distance of the ellipsoid union (or inside it): the union's neighbourhood, which with
	/// the tight skin surface also holds cloth hanging in the union's bulge off the skin (reported as nodes_near_union).
	NearEllipsoids,
	RigidContacts,  ///< holding a Bullet rigid contact (btSoftBody::m_rcontacts) after the last step: Bullet's paths
	/// Flagged by bodyfit's collider in its last substep (btEllipsoidClothCollider::getContactFlags): placed on the
	/// surface, held there by friction or pushed out; the resting cloth the collider touches, in either surface mode.
	ColliderContacts,
	None, ///< no contacts (no body collider)
};

struct ContactOptions
{
	ContactRule rule = ContactRule::NearEllipsoids;
	/// NearEllipsoids: largest signed distance to the union that still counts (metres); the scene runner uses the
	/// collider's skin offset + 3 mm.
	double distance = 0.005;
	/// ColliderContacts: the collider whose contact flags are read (not owned).
	const btEllipsoidClothCollider* collider = nullptr;
};

/// Signed gaps to the skin of the contact nodes, summarised (all 0 when count is 0).
struct GapSummary
{
	int count = 0; ///< finite contact nodes with a gap
	double mean = 0.0;
	double median = 0.0;
	double p95 = 0.0; ///< 95th percentile, linear interpolation (bodyfit/fitting/statistics.h, quantile)
	double max = 0.0;
};

struct ContactMetrics
{
	int contactNodes = 0; ///< nodes the rule selected
	GapSummary gap;
};

/// Cloth edges and faces through the body: links whose two end nodes are outside the mesh but whose segment meets it,
/// and faces whose three corners are outside but whose interior reaches inside (a triangle can cut the skin between
/// its nodes while its edges clear it: the skin poking into its middle, or sagging over the skin deeper than its
/// edges).
struct EdgeCrossings
{
	bool measured = false;  ///< false: not measured (toJson writes null), e.g. a ClothMetrics built without them
	int links = 0;          ///< cloth edges (links that are not bending links) with two finite end nodes
	int crossing = 0;       ///< of those, both ends outside the body mesh and the segment meets a triangle
	double maxDepth = 0.0;  ///< deepest point inside the body along a crossing link (metres; 0 when none crosses)
	int faces = 0;          ///< cloth faces with three finite corners
	int facesCrossing = 0;  ///< of those, three corners outside the body mesh and an interior sample inside it
	double maxFaceDepth = 0.0; ///< deepest such interior sample (metres; 0 when none crosses)
};

/// Everything measured on one soft body at one instant.
struct ClothMetrics
{
	PenetrationCounts penetration;
	ContactMetrics contacts;
	EdgeCrossings crossings;
};

/// Inside/NaN counts now.
PenetrationCounts measurePenetration(const btSoftBody& cloth, const BodyReference& body);

/// Indices of the nodes the rule counts as touching the body (finite nodes only for NearEllipsoids). For
/// ColliderContacts, none when the collider has no record of the soft body (it did not step it last substep).
/// \throws InvalidInputError for NearEllipsoids on a body without ellipsoids, or a negative distance; for
/// ColliderContacts without a collider, or a record whose size is not the soft body's node count.
std::vector<int> contactNodes(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options);

/// Signed distance to the skin of each listed node with a finite position (in list order; non-finite ones skipped).
/// \throws InvalidInputError for an index outside the soft body's nodes.
std::vector<double> skinDistances(const btSoftBody& cloth, const BodyReference& body, const std::vector<int>& nodes);

/// Mean, median, p95 and max of the gaps.
GapSummary summarizeGaps(const std::vector<double>& gaps);

/// Contact nodes and their gap summary now.
ContactMetrics measureContacts(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options);

/// Cloth edges crossing the skin now: every link but the bending links (m_bbending: springs between the far corners
/// of two faces, which do not bound the cloth's surface). A link is skipped without triangle tests when its ends' distances to the skin sum
/// to more than its length (no point of the segment can then reach the surface); the others are tested against the
/// triangles in the grid cells under the segment's box. The depth of a crossing is the largest distance to the skin
/// over 9 points of each inside stretch between consecutive hits (hit pairs along the segment).
/// Faces: each face with its three corners outside is sampled at the 10 interior points (i, j, k) / 6 of barycentric
/// coordinates (i, j, k >= 1; the centroid among them), skipped without samples when its corners' distances to the
/// skin all exceed its longest edge (no point of it can then reach the surface). A sampled test: a cut smaller than
/// the samples' spacing (a sixth of the face) can be missed.
EdgeCrossings measureEdgeCrossings(const btSoftBody& cloth, const BodyReference& body);

/// Every measure now.
ClothMetrics measureCloth(const btSoftBody& cloth, const BodyReference& body, const ContactOptions& options = {});

/// The metrics as JSON: nodes, nan_nodes, nodes_inside_body, nodes_inside_ellipsoids, min_zeta,
/// ellipsoid_penetration_m, contact_nodes, mean/median/p95/max_contact_gap_m (null where undefined: no
/// ellipsoids, no contact gaps, infinite zeta), links, links_crossing_body, max_link_crossing_depth_m, faces,
/// faces_crossing_body, max_face_crossing_depth_m (null when the crossings were not measured).
nlohmann::json toJson(const ClothMetrics& metrics);

} // namespace bodyfit::metrics
