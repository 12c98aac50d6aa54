/*
bodyfit: Bullet extension for ellipsoid body colliders. See bullet_ext/README.md, "Tight skin surface" (animated
bodies) and btSkinMesh.h.
Tight mode on a skinned body, where the bind-pose field in a bone's frame cannot decide (joints: a candidate refitted
or of another bone group): a node the union's swept broad phase kept is decided on the skinned mesh of the instant,
which the skinning driver writes with the ellipsoids. Every case the mesh query cannot vouch for keeps the swept
union response, the conservative one: no triangle within kSearchRadius, a closest-point direction far from the
triangle's normal (the sign), an end deeper than kMaxDepth, a long relative path whose start is not outside or whose
trace runs out of steps, and a node left outside the nearest sheet whose closest skin point lies inside another part
of the skin (btSkinMesh::sideContradicted: skinning pushes the skin into itself, e.g. an arm into the hip).

Why the nearest skin is the skin the node met: the node starts outside the skin (the previous substep left it there)
and its path relative to the skin under it (the start carried by the motion of its closest skin point) is at most
kMaxRelativePath long, and its end at most kMaxDepth deep. A wrong side needs the node to pass a part of the body
thinner than that within one substep; the union response it replaces does not tell such parts apart either. A longer
relative path is sphere-traced from its carried start on the distance to the skin (traceOnSkin), which cannot pass
the offset surface; the carried start approximates the skin's motion near the node by that of one skin point.
*/

#include "src/btEllipsoidClothColliderCore.h"
#include "src/btEllipsoidClothResponse.h"

namespace
{

/// Nodes farther than this from the skin of the instant (metres) keep the union response.
const btScalar kSearchRadius = btScalar(0.03);
/// The longest node path relative to the skin under it, and the deepest end below the skin, that the mesh decides.
const btScalar kMaxRelativePath = btScalar(0.010);
const btScalar kMaxDepth = btScalar(0.010);
/// A placed node lands this far (metres) above the skin offset (the distance is recomputed there; rounding of
/// coordinates of a few metres in float is ~1e-6 m).
const btScalar kLift = btScalar(1e-4);
/// Projections onto the offset surface before a placement gives up (a crease: each step can meet another triangle).
const int kMaxProjections = 4;

/// Steps of the sphere trace of a long relative path before it gives up (the union then decides).
const int kMaxTraceSteps = 32;

/// Sphere tracing of the path a -> b (body frame) on the distance to the skin, from a start outside it by at least
/// the offset (sign trusted): a point at distance d has no skin within d, so every point within d - offset of it is
/// at least the offset from the skin, and the trace steps that far. \return false when the start is not outside or
/// the steps run out; else `hit` is the first point found within kLift above the offset (clear = false, `near` its
/// closest point) or b (clear = true: no point of the path comes within the offset).
bool traceOnSkin(const btSkinMesh& mesh, const btVector3& a, const btVector3& b, btScalar offset, btVector3& hit,
				 btSkinMeshPoint& near, bool& clear)
{
	btScalar side;
	if (!mesh.closestSide(a, kSearchRadius, near, side) || side < offset || mesh.sideContradicted(near, side))
		return false; // (the path never comes within the offset of the skin: its end is on its start's side)
	const btVector3 d = b - a;
	const btScalar len = d.length();
	btScalar s = btScalar(0), dist = side;
	for (int i = 0; i < kMaxTraceSteps; ++i)
	{
		const btScalar step = dist - offset;
		if (step <= kLift)
		{
			if (near.m_triangle < 0)
				return false; // (a distance of kSearchRadius is never this small)
			hit = a + d * (s / len);
			clear = false;
			return true;
		}
		s += step;
		if (s >= len)
		{
			hit = b;
			clear = true;
			return true;
		}
		const btVector3 p = a + d * (s / len);
		const int hint = near.m_triangle;
		dist = mesh.closestPoint(p, kSearchRadius, near, hint) ? near.m_distance : kSearchRadius;
	}
	return false;
}

} // namespace

void btEllipsoidClothColliderCore::prepareSkinMesh()
{
	const btSkinMesh* mesh = m_compound->getSkinMesh();
	const int revision = mesh ? mesh->getRevision() : -1;
	const bool onePose = mesh && m_skinMeshRevision >= 0 && revision == m_skinMeshRevision + 1;
	m_skinMesh = onePose && m_sweeping && activeSkinField() && mesh->getNumTriangles() > 0 ? mesh : 0;
	m_skinMeshRevision = revision;
}

bool btEllipsoidClothColliderCore::traceLongPath(btSoftBody::Node& node, const btVector3& start, const Substep& substep)
{
	const btScalar offset = btMax(m_config.m_skinOffset, btScalar(0));
	btVector3 hit;
	btSkinMeshPoint near;
	bool clear;
	if (!traceOnSkin(*m_skinMesh, start, m_currentPose.invXform(node.m_x), offset, hit, near, clear))
		return false;
	++m_lastStats.m_skinMeshNodes;
	if (clear)
		return true;
	++m_lastStats.m_nodesCorrected;
	node.m_x = m_currentPose * hit;
	const btVector3 surface = m_currentPose * near.m_point;
	placedOnSkinMesh(node, (node.m_x - surface).normalized(), surface, m_previousPose * m_skinMesh->previousPoint(near),
					 m_currentPose * start, substep);
	return true;
}

bool btEllipsoidClothColliderCore::collideOnSkinMesh(btSoftBody::Node& node, const btVector3& q, int nc,
													 const Substep& substep)
{
	// (A dynamic body would take reaction impulses of a mesh that does not move it.)
	(void)nc; // (every tested node: its sign comes from the mesh, not from the union)
	if (m_dynamicBody)
		return false;
	const btSkinMesh& mesh = *m_skinMesh;
	const btScalar offset = btMax(m_config.m_skinOffset, btScalar(0));
	btSkinMeshPoint near;
	btScalar side;
	int* hint = m_skinMeshHints ? &m_skinMeshHints[&node - m_contactNodeBase] : 0;
	const bool signedNear =
		mesh.closestSide(m_currentPose.invXform(node.m_x), kSearchRadius, near, side, hint ? *hint : -1);
	if (hint)
		*hint = near.m_triangle; // (-1 when no skin is near)
	if (!signedNear)
		return false;
	if (side < -kMaxDepth)
		return false;
	// The start carried with the skin under the node: the path relative to that skin.
	const btVector3 start = q + (m_currentPose * near.m_point - m_previousPose * mesh.previousPoint(near));
	if ((node.m_x - start).length2() > kMaxRelativePath * kMaxRelativePath)
		return traceLongPath(node, m_currentPose.invXform(start), substep);
	if (side >= offset)
	{
		if (mesh.sideContradicted(near, side))
			return false;
		++m_lastStats.m_skinMeshNodes;
		return true; // outside the skin by the offset: no contact
	}
	// Placement at the offset along the closest triangle's normal, repeated from there while another triangle is
	// nearer (a crease).
	const btScalar startSide = side;
	btVector3 p = near.m_point;
	for (int i = 0; side < offset; ++i)
	{
		p = near.m_point + mesh.getNormal(near.m_triangle) * (offset + kLift);
		if (i == kMaxProjections || !mesh.closestSide(p, kSearchRadius, near, side, near.m_triangle))
			return false;
	}
	if (mesh.sideContradicted(near, side))
		return false;
	++m_lastStats.m_skinMeshNodes;
	if (startSide < btScalar(0))
		++m_lastStats.m_nodesPushedOut;
	else
		++m_lastStats.m_nodesCorrected;
	node.m_x = m_currentPose * p;
	const btVector3 surface = m_currentPose * near.m_point;
	placedOnSkinMesh(node, m_currentPose.getBasis() * mesh.getNormal(near.m_triangle), surface,
					 m_previousPose * mesh.previousPoint(near), start, substep);
	return true;
}

void btEllipsoidClothColliderCore::placedOnSkinMesh(btSoftBody::Node& node, const btVector3& normal,
												   const btVector3& surface, const btVector3& surfaceBefore,
												   const btVector3& start, const Substep& substep)
{
	const btVector3 bodyVelocity =
		substep.m_dt > btScalar(0) ? (surface - surfaceBefore) / substep.m_dt : btVector3(0, 0, 0);
	btNodeContacts contacts;
	contacts.add(normal);
	const btVector3 before = node.m_v;
	const btVector3 center = m_current[substep.m_candidates[0]].m_center; // for PAPER_EQ10
	const btVector3 vr = btRelativeVelocityAfterContact(m_config.m_velocityRule, substep.m_friction,
														node.m_v - bodyVelocity, contacts, surface, start, center);
	setContactVelocity(node, vr, normal, start, bodyVelocity, before, surface, substep.m_dt);
}
