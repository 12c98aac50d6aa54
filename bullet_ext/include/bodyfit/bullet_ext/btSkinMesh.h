/*
bodyfit: Bullet extension for ellipsoid body colliders. The skin of a skinned body as a triangle mesh of the instant
(bullet_ext/README.md, "Tight skin surface", animated bodies): the bind topology, the vertices of the current and the
previous pose, an AABB tree built once on the bind pose and refitted per pose, and the exact closest point.
*/

#ifndef BT_SKIN_MESH_H
#define BT_SKIN_MESH_H

#include "LinearMath/btAlignedObjectArray.h"
#include "LinearMath/btVector3.h"

/// The closest point of a btSkinMesh to a query point.
struct btSkinMeshPoint
{
	int m_triangle;      ///< -1: no triangle within the search radius
	btScalar m_bary[3];  ///< barycentric coordinates of the closest point in its triangle
	btVector3 m_point;   ///< the closest point, current pose
	btScalar m_distance; ///< its distance to the query point
};

class btSkinMesh
{
public:
	BT_DECLARE_ALIGNED_ALLOCATOR();

	btSkinMesh();

	/// Takes the topology (numTriangles x 3 vertex indices) and the bind vertices, and builds the tree on them.
	/// The triangles' orientation is taken from the sign of the enclosed volume (outward normals either way).
	/// \return false (*error set to a one-line reason, nothing changed) for no triangles or an index out of range.
	bool setTopology(int numVertices, const int* triangles, int numTriangles, const btVector3* vertices,
					 const char** error = 0);
	/// Starts a new pose: the current vertices become the previous ones; write the new ones into the returned array
	/// (getNumVertices() entries), then call endPose().
	btVector3* beginPose();
	/// Refits the tree; bumps the revision.
	void endPose();

	/// The closest point of the current pose to p if one lies within `radius` (else out.m_triangle = -1 and false).
	/// Ties go to the lowest triangle index: the result depends on p and the pose only. `hint` (a triangle, e.g. the
	/// last answer for a point that moved little; -1 none) only starts the search with its distance, so fewer boxes
	/// are opened.
	bool closestPoint(const btVector3& p, btScalar radius, btSkinMeshPoint& out, int hint = -1) const;
	/// The signed distance of p to the skin (positive outside), with `near` its closest point, when a triangle lies
	/// within `radius` and the closest triangle's sign can be trusted: the direction from the closest point to p is
	/// within acos(kMinNormalCosine) of that triangle's outward normal (or p is on the skin: side 0). \return false
	/// otherwise (near still holds the closest point, if any). `hint` as closestPoint. It reads the nearest sheet
	/// only: see sideContradicted for skin pushed into itself.
	bool closestSide(const btVector3& p, btScalar radius, btSkinMeshPoint& near, btScalar& side, int hint = -1) const;
	/// True when p, outside the nearest sheet by `side` > 0 with `near` its closest point (closestSide), is inside
	/// another part of the skin all the same: where the skinned skin runs into itself (an arm pressed into the hip),
	/// the nearest sheet can lie inside another part. Then so does p, for no skin comes between p and `near`; the
	/// test is on `near`: a triangle within kFoldDepth of it puts it on its inner side with a trusted direction.
	/// An inside claim (side <= 0) is not contradicted: a point inside the nearest sheet is inside the body.
	bool sideContradicted(const btSkinMeshPoint& near, btScalar side) const;
	/// closestSide, false also when sideContradicted.
	bool signedDistance(const btVector3& p, btScalar radius, btSkinMeshPoint& near, btScalar& side,
						int hint = -1) const;
	/// The direction from a closest point to the query point must be within acos(0.9) = 26 degrees of the
	/// triangle's normal for its sign to be trusted: exact at a face's interior point; at an edge or a corner the
	/// direction lies in the (outward or inward) cone of the normals of the faces there, so the sign agrees with the
	/// pseudo-normal unless two of those faces fold back by more than 154 degrees.
	static const btScalar kMinNormalCosine;
	/// Below this distance (metres) a point is on the skin: side 0, whatever the direction.
	static const btScalar kOnSkin;
	/// How far from the nearest skin point (metres) sideContradicted looks for a part it lies in.
	static const btScalar kFoldDepth;
	/// The same barycentric point in the previous pose.
	btVector3 previousPoint(const btSkinMeshPoint& point) const;
	/// Unit outward normal of a triangle in the current pose ((0, 0, 0) for a degenerate one).
	btVector3 getNormal(int triangle) const;

	int getNumVertices() const { return m_poses[0].size(); }
	int getNumTriangles() const { return m_triangles.size() / 3; }
	/// Increases with every endPose() (and setTopology()).
	int getRevision() const { return m_revision; }

private:
	struct Node
	{
		btVector3 m_min, m_max;
		int m_right; ///< inner node: index of the right child (the left one follows the node); leaf: -1
		int m_first, m_count; ///< leaf: its triangles m_order[first .. first + count)
		int m_vertexFirst, m_vertexCount; ///< leaf: the distinct corners of its triangles, m_leafVertices[first ..)
	};
	btAlignedObjectArray<int> m_triangles;
	btAlignedObjectArray<btVector3> m_poses[2]; ///< the current pose is m_poses[m_current], the previous the other
	int m_current;
	btAlignedObjectArray<int> m_order;
	btAlignedObjectArray<int> m_leafVertices; ///< per leaf, its distinct corners (the refit reads only these)
	btAlignedObjectArray<Node> m_nodes;
	btScalar m_orientation; ///< +1, or -1 when the triangles wind inwards
	int m_revision;

	int build(int first, int count, const btAlignedObjectArray<btVector3>& centroids);
	/// Takes triangle t as out's closest point when it is nearer than best2 (or as near, with a lower index).
	void consider(const btVector3& p, int t, btScalar& best2, btSkinMeshPoint& out) const;
	/// True when a triangle within `radius` of p puts p on the side opposite to `sign` (+1 outside, -1 inside)
	/// with a trusted direction (within acos(kMinNormalCosine) of its normal, p not on it).
	bool otherSideWithin(const btVector3& p, btScalar radius, btScalar sign) const;
	/// Whether triangle t, if within radius2 (squared) of p, puts p on the side opposite to sign (otherSideWithin).
	bool putsOnOtherSide(const btVector3& p, int t, btScalar radius2, btScalar sign) const;
	/// The leaves' corner lists (m_leafVertices), once after build().
	void collectLeafVertices();
	const btVector3& vertex(int t, int corner) const { return m_poses[m_current][m_triangles[3 * t + corner]]; }
	void refit();
};

/// The closest point of triangle (a, b, c) to p, as barycentric coordinates (Voronoi regions of the corners, edges
/// and face).
void btClosestOnTriangle(const btVector3& p, const btVector3& a, const btVector3& b, const btVector3& c,
						 btScalar bary[3]);

#endif // BT_SKIN_MESH_H
