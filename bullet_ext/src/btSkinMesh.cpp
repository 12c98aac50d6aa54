/*
bodyfit: the skinned skin as a refitted triangle mesh. See btSkinMesh.h.
*/

#include "bodyfit/bullet_ext/btSkinMesh.h"

#include "src/btBoxSelect.h"

namespace
{
/// Triangles per leaf of the tree (at most). 4 against 8: the walk tights' skin-mesh response takes 10% fewer
/// instructions, the refit 36% more, 8% fewer in all (callgrind, 40 steps, 2026-12-04); the answers are the same.
const int kLeafSize = 4;
} // namespace

void btClosestOnTriangle(const btVector3& p, const btVector3& a, const btVector3& b, const btVector3& c,
						 btScalar bary[3])
{
	// The textbook region test: the projections of p on the edges decide which corner, edge or the face holds the
	// closest point (Ericson, Real-Time Collision Detection, 5.1.5).
	const btVector3 ab = b - a, ac = c - a, ap = p - a;
	const btScalar d1 = ab.dot(ap), d2 = ac.dot(ap);
	bary[0] = btScalar(1);
	bary[1] = bary[2] = btScalar(0);
	if (d1 <= btScalar(0) && d2 <= btScalar(0))
		return; // corner a
	const btVector3 bp = p - b;
	const btScalar d3 = ab.dot(bp), d4 = ac.dot(bp);
	if (d3 >= btScalar(0) && d4 <= d3)
	{
		bary[0] = btScalar(0);
		bary[1] = btScalar(1);
		return; // corner b
	}
	const btScalar vc = d1 * d4 - d3 * d2;
	if (vc <= btScalar(0) && d1 >= btScalar(0) && d3 <= btScalar(0))
	{
		const btScalar v = d1 / (d1 - d3);
		bary[0] = btScalar(1) - v;
		bary[1] = v;
		return; // edge ab
	}
	const btVector3 cp = p - c;
	const btScalar d5 = ab.dot(cp), d6 = ac.dot(cp);
	if (d6 >= btScalar(0) && d5 <= d6)
	{
		bary[0] = btScalar(0);
		bary[2] = btScalar(1);
		return; // corner c
	}
	const btScalar vb = d5 * d2 - d1 * d6;
	if (vb <= btScalar(0) && d2 >= btScalar(0) && d6 <= btScalar(0))
	{
		const btScalar w = d2 / (d2 - d6);
		bary[0] = btScalar(1) - w;
		bary[2] = w;
		return; // edge ac
	}
	const btScalar va = d3 * d6 - d5 * d4;
	if (va <= btScalar(0) && d4 - d3 >= btScalar(0) && d5 - d6 >= btScalar(0))
	{
		const btScalar w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
		bary[0] = btScalar(0);
		bary[1] = btScalar(1) - w;
		bary[2] = w;
		return; // edge bc
	}
	const btScalar sum = va + vb + vc;
	if (!(sum > btScalar(0)))
		return; // degenerate triangle: corner a
	bary[1] = vb / sum;
	bary[2] = vc / sum;
	bary[0] = btScalar(1) - bary[1] - bary[2];
}

btSkinMesh::btSkinMesh() : m_current(0), m_orientation(1), m_revision(0) {}

bool btSkinMesh::setTopology(int numVertices, const int* triangles, int numTriangles, const btVector3* vertices,
							 const char** error)
{
	const char* why = 0;
	if (numTriangles <= 0 || numVertices <= 0 || !triangles || !vertices)
		why = "btSkinMesh: no triangles or no vertices";
	for (int i = 0; !why && i < numTriangles * 3; ++i)
		if (triangles[i] < 0 || triangles[i] >= numVertices)
			why = "btSkinMesh: a triangle index is outside the vertices";
	if (why)
	{
		if (error)
			*error = why;
		return false;
	}
	m_triangles.resize(numTriangles * 3);
	for (int i = 0; i < numTriangles * 3; ++i)
		m_triangles[i] = triangles[i];
	m_current = 0;
	m_poses[0].resize(numVertices);
	for (int i = 0; i < numVertices; ++i)
		m_poses[0][i] = vertices[i];
	m_poses[1].copyFromArray(m_poses[0]);
	// Orientation: the enclosed volume (sum of signed tetrahedra from the origin) is positive for outward winding.
	btScalar volume = btScalar(0);
	btAlignedObjectArray<btVector3> centroids;
	centroids.resize(numTriangles);
	for (int t = 0; t < numTriangles; ++t)
	{
		const btVector3& a = vertex(t, 0);
		const btVector3& b = vertex(t, 1);
		const btVector3& c = vertex(t, 2);
		volume += a.dot(b.cross(c));
		centroids[t] = (a + b + c) / btScalar(3);
	}
	m_orientation = volume < btScalar(0) ? btScalar(-1) : btScalar(1);
	m_order.resize(numTriangles);
	for (int t = 0; t < numTriangles; ++t)
		m_order[t] = t;
	m_nodes.resize(0);
	build(0, numTriangles, centroids);
	collectLeafVertices();
	refit();
	++m_revision;
	return true;
}

int btSkinMesh::build(int first, int count, const btAlignedObjectArray<btVector3>& centroids)
{
	// Preorder: a node precedes its children, so refit() can run backwards. Median split of the centroids along the
	// box's longest axis (Hoare quickselect; any split would do, the median keeps the tree balanced).
	const int index = m_nodes.size();
	m_nodes.expand();
	m_nodes[index].m_right = -1;
	m_nodes[index].m_first = first;
	m_nodes[index].m_count = count;
	m_nodes[index].m_vertexFirst = m_nodes[index].m_vertexCount = 0;
	if (count <= kLeafSize)
		return index;
	btVector3 lo = centroids[m_order[first]], hi = lo;
	for (int i = first + 1; i < first + count; ++i)
	{
		lo.setMin(centroids[m_order[i]]);
		hi.setMax(centroids[m_order[i]]);
	}
	const int axis = (hi - lo).maxAxis();
	const int mid = first + count / 2;
	int l = first, r = first + count - 1;
	while (l < r)
	{
		const btScalar pivot = centroids[m_order[(l + r) / 2]][axis];
		int i = l, j = r;
		while (i <= j)
		{
			while (centroids[m_order[i]][axis] < pivot)
				++i;
			while (centroids[m_order[j]][axis] > pivot)
				--j;
			if (i <= j)
			{
				m_order.swap(i, j);
				++i;
				--j;
			}
		}
		if (mid <= j)
			r = j;
		else if (mid >= i)
			l = i;
		else
			break;
	}
	build(first, mid - first, centroids);
	const int right = build(mid, first + count - mid, centroids);
	m_nodes[index].m_right = right;
	return index;
}

void btSkinMesh::collectLeafVertices()
{
	m_leafVertices.resize(0);
	for (int i = 0; i < m_nodes.size(); ++i)
	{
		Node& node = m_nodes[i];
		node.m_vertexFirst = m_leafVertices.size();
		node.m_vertexCount = 0;
		if (node.m_right >= 0)
			continue;
		for (int k = 0; k < node.m_count * 3; ++k)
		{
			const int v = m_triangles[3 * m_order[node.m_first + k / 3] + k % 3];
			bool seen = false; // (a leaf has at most 3 kLeafSize corners: a linear scan)
			for (int j = node.m_vertexFirst; j < m_leafVertices.size() && !seen; ++j)
				seen = m_leafVertices[j] == v;
			if (!seen)
				m_leafVertices.push_back(v);
		}
		node.m_vertexCount = m_leafVertices.size() - node.m_vertexFirst;
	}
}

btVector3 btSkinMesh::getNormal(int t) const
{
	const btVector3& a = vertex(t, 0);
	const btVector3 cross = (vertex(t, 1) - a).cross(vertex(t, 2) - a);
	const btScalar len = cross.length();
	return len > btScalar(0) ? cross * (m_orientation / len) : btVector3(0, 0, 0);
}

void btSkinMesh::refit()
{
	for (int i = m_nodes.size() - 1; i >= 0; --i)
	{
		Node& node = m_nodes[i];
		if (node.m_right < 0)
		{
			const btVector3* pose = &m_poses[m_current][0];
			const int* corner = &m_leafVertices[node.m_vertexFirst];
			btVector3 lo = pose[corner[0]], hi = lo;
			for (int k = 1; k < node.m_vertexCount; ++k)
			{
				lo = btSelectMin(lo, pose[corner[k]]);
				hi = btSelectMax(hi, pose[corner[k]]);
			}
			node.m_min = lo;
			node.m_max = hi;
		}
		else
		{
			const Node& left = m_nodes[i + 1];
			const Node& right = m_nodes[node.m_right];
			node.m_min = btSelectMin(left.m_min, right.m_min);
			node.m_max = btSelectMax(left.m_max, right.m_max);
		}
	}
}

btVector3* btSkinMesh::beginPose()
{
	m_current = 1 - m_current;
	return m_poses[m_current].size() > 0 ? &m_poses[m_current][0] : 0;
}

void btSkinMesh::endPose()
{
	refit();
	++m_revision;
}


namespace
{
btScalar boxDistance2(const btVector3& p, const btVector3& lo, const btVector3& hi)
{
	// Per axis the gap is lo - p below the box, p - hi above it (at most one of them is positive), else 0.
	const btVector3 gap = btSelectMax(btSelectMax(lo - p, p - hi), btVector3(0, 0, 0));
	return gap.length2();
}

/// Squared distance from p to the box of the triangle a b c (0 inside it): the box holds the triangle, so no point
/// of the triangle is nearer.
btScalar triangleBoxDistance2(const btVector3& p, const btVector3& a, const btVector3& b, const btVector3& c)
{
	return boxDistance2(p, btSelectMin(btSelectMin(a, b), c), btSelectMax(btSelectMax(a, b), c));
}
} // namespace

void btSkinMesh::consider(const btVector3& p, int t, btScalar& best2, btSkinMeshPoint& out) const
{
	const btVector3& a = vertex(t, 0);
	const btVector3& b = vertex(t, 1);
	const btVector3& c = vertex(t, 2);
	if (triangleBoxDistance2(p, a, b, c) > best2)
		return;
	btScalar bary[3];
	btClosestOnTriangle(p, a, b, c, bary);
	const btVector3 q = a * bary[0] + b * bary[1] + c * bary[2];
	const btScalar d2 = (p - q).length2();
	if (d2 < best2 || (d2 == best2 && (out.m_triangle < 0 || t < out.m_triangle)))
	{
		best2 = d2;
		out.m_triangle = t;
		out.m_bary[0] = bary[0];
		out.m_bary[1] = bary[1];
		out.m_bary[2] = bary[2];
		out.m_point = q;
	}
}

bool btSkinMesh::closestPoint(const btVector3& p, btScalar radius, btSkinMeshPoint& out, int hint) const
{
	out.m_triangle = -1;
	out.m_distance = radius;
	if (m_nodes.size() == 0)
		return false;
	btScalar best2 = radius * radius;
	// The hint bounds the search; every box within that bound is still opened (the pruning below is strict), so
	// the answer, ties included, is the same as without it.
	if (hint >= 0 && hint < getNumTriangles())
		consider(p, hint, best2, out);
	// The stack holds nodes with their box distances (computed once, when their parent is opened).
	int stack[64];
	btScalar stackDistance2[64];
	int top = 0;
	stack[top] = 0;
	stackDistance2[top++] = boxDistance2(p, m_nodes[0].m_min, m_nodes[0].m_max);
	while (top > 0)
	{
		--top;
		if (stackDistance2[top] > best2)
			continue;
		const Node& node = m_nodes[stack[top]];
		if (node.m_right >= 0)
		{
			// Nearer child last (popped first); the depth is about log2(triangles / kLeafSize), far below the stack size.
			const int left = stack[top] + 1;
			const btScalar dl = boxDistance2(p, m_nodes[left].m_min, m_nodes[left].m_max);
			const btScalar dr = boxDistance2(p, m_nodes[node.m_right].m_min, m_nodes[node.m_right].m_max);
			if (top + 2 > 64)
				continue; // (unreachable for a median-split tree of < 2^60 triangles)
			const bool leftFirst = dl <= dr;
			stack[top] = leftFirst ? node.m_right : left;
			stackDistance2[top++] = leftFirst ? dr : dl;
			stack[top] = leftFirst ? left : node.m_right;
			stackDistance2[top++] = leftFirst ? dl : dr;
			continue;
		}
		for (int k = 0; k < node.m_count; ++k)
			consider(p, m_order[node.m_first + k], best2, out);
	}
	if (out.m_triangle < 0)
		return false;
	out.m_distance = btSqrt(best2);
	return true;
}

const btScalar btSkinMesh::kMinNormalCosine = btScalar(0.9);
const btScalar btSkinMesh::kOnSkin = btScalar(1e-6);
const btScalar btSkinMesh::kFoldDepth = btScalar(0.010);

bool btSkinMesh::closestSide(const btVector3& p, btScalar radius, btSkinMeshPoint& near, btScalar& side, int hint) const
{
	if (!closestPoint(p, radius, near, hint))
		return false;
	const btVector3 n = getNormal(near.m_triangle);
	if (n.length2() == btScalar(0))
		return false; // a degenerate triangle
	if (near.m_distance <= kOnSkin)
	{
		side = btScalar(0);
		return true;
	}
	const btScalar along = (p - near.m_point).dot(n);
	if (btFabs(along) < kMinNormalCosine * near.m_distance)
		return false;
	side = along > btScalar(0) ? near.m_distance : -near.m_distance;
	return true;
}

bool btSkinMesh::sideContradicted(const btSkinMeshPoint& near, btScalar side) const
{
	return side > btScalar(0) && near.m_triangle >= 0 && otherSideWithin(near.m_point, kFoldDepth, btScalar(1));
}

bool btSkinMesh::signedDistance(const btVector3& p, btScalar radius, btSkinMeshPoint& near, btScalar& side,
								int hint) const
{
	return closestSide(p, radius, near, side, hint) && !sideContradicted(near, side);
}

bool btSkinMesh::otherSideWithin(const btVector3& p, btScalar radius, btScalar sign) const
{
	if (m_nodes.size() == 0)
		return false;
	const btScalar radius2 = radius * radius;
	int stack[64];
	int top = 0;
	if (boxDistance2(p, m_nodes[0].m_min, m_nodes[0].m_max) <= radius2)
		stack[top++] = 0;
	while (top > 0)
	{
		const int index = stack[--top];
		const Node& node = m_nodes[index];
		if (node.m_right >= 0)
		{
			// Only the children within the radius are pushed (a node on the stack is known to be).
			if (top + 2 > 64)
				continue; // (unreachable, as in closestPoint)
			if (boxDistance2(p, m_nodes[node.m_right].m_min, m_nodes[node.m_right].m_max) <= radius2)
				stack[top++] = node.m_right;
			if (boxDistance2(p, m_nodes[index + 1].m_min, m_nodes[index + 1].m_max) <= radius2)
				stack[top++] = index + 1;
			continue;
		}
		for (int k = 0; k < node.m_count; ++k)
			if (putsOnOtherSide(p, m_order[node.m_first + k], radius2, sign))
				return true;
	}
	return false;
}

bool btSkinMesh::putsOnOtherSide(const btVector3& p, int t, btScalar radius2, btScalar sign) const
{
	// The closest point q lies in the triangle's plane, so (p - q).n is p's height h over the plane: the sign is
	// trusted on the other side only when -sign h >= kMinNormalCosine |p - q| >= kMinNormalCosine |h|, which the
	// height alone can rule out before q is computed.
	const btVector3& a = vertex(t, 0);
	const btVector3& b = vertex(t, 1);
	const btVector3& c = vertex(t, 2);
	const btScalar box2 = triangleBoxDistance2(p, a, b, c);
	if (box2 > radius2)
		return false;
	const btVector3 cross = (b - a).cross(c - a);
	const btScalar h = sign * m_orientation * (p - a).dot(cross); // (the height times |cross|)
	const btScalar cross2 = cross.length2();
	if (!(h < btScalar(0)) || h * h > radius2 * cross2)
		return false;
	// The box holds the triangle, so |p - q|^2 >= box2: the trusted-direction test below cannot pass unless
	// h^2 >= kMinNormalCosine^2 box2 |cross|^2 (on a convex patch p lies below its neighbours' planes, but beside
	// them, not over them: this rejects those before q is computed; the answer is the same).
	if (h * h < kMinNormalCosine * kMinNormalCosine * box2 * cross2)
		return false;
	btScalar bary[3];
	btClosestOnTriangle(p, a, b, c, bary);
	const btScalar d2 = (p - (a * bary[0] + b * bary[1] + c * bary[2])).length2();
	if (d2 > radius2 || d2 <= kOnSkin * kOnSkin)
		return false;
	// -h / |cross| >= kMinNormalCosine sqrt(d2), squared (both sides are positive)
	return h * h >= kMinNormalCosine * kMinNormalCosine * d2 * cross2;
}

btVector3 btSkinMesh::previousPoint(const btSkinMeshPoint& point) const
{
	const int t = point.m_triangle;
	const btAlignedObjectArray<btVector3>& previous = m_poses[1 - m_current];
	return previous[m_triangles[3 * t]] * point.m_bary[0] + previous[m_triangles[3 * t + 1]] * point.m_bary[1] +
		   previous[m_triangles[3 * t + 2]] * point.m_bary[2];
}
