/*
bodyfit: Bullet extension for ellipsoid body colliders. See btSkinFieldResponse.h and bullet_ext/README.md,
"Tight skin surface".
The collider's tight mode: the union of ellipsoids stays the broad phase (a node with no candidate ellipsoid is
never looked at); a candidate node's contact is decided on the skin distance field, in the body frame: the path
q -> x is sphere-traced to the first point at field = skin offset, a node that starts within the skin is pushed out
along the field's gradient (Newton), and the existing velocity rule and friction apply with the field's normal.
*/

#include "src/btSkinFieldResponse.h"

#include "src/btEllipsoidClothColliderCore.h"
#include "src/btEllipsoidClothResponse.h"

#include "BulletDynamics/Dynamics/btRigidBody.h"

#include <cmath>
#include <cstdint>
#include <cstring>

namespace
{

/// Steps of the path march before it stops at the last point known outside (a straight approach needs about 10:
/// each step closes a fraction 1 / Lipschitz of the remaining gap; only paths grazing the surface need more).
const int kMaxMarchSteps = 64;
/// After this many steps a path still within the contact band of the surface is grazing it: the node is in contact
/// there (the slide of the response carries it on along the surface). Without it such paths crept in steps of a
/// fraction of the band (colliders_patch: 4% of the marches took 16-64 steps).
const int kGrazingSteps = 3;
/// Newton steps of the push-out (a distance field converges in one or two: its slope is about 1).
const int kMaxNewtonSteps = 8;
/// Pieces of one slide; a longer slide stops after them (conservative: the node stays outside).
const int kMaxSlidePieces = 8;

} // namespace

// ---------------------------------------------------------------------------------------------------------------
// btSkinFieldGeometry

btScalar btEllipsoidClothCollider::skinFieldTolerance(const btSkinDistanceField& field)
{
	// Coordinates over the grid are rounded to btScalar: about SIMD_EPSILON x the largest coordinate per operation;
	// the field's slope (about 1) carries that into its value. 16 of those cover the march's few operations.
	const btVector3 lo = field.getGridMin().absolute(), hi = field.getGridMax().absolute();
	const btScalar extent = btMax(lo[lo.maxAxis()], hi[hi.maxAxis()]);
	return field.getSeam() + btScalar(4) * field.getQuantum() + btScalar(16) * SIMD_EPSILON * extent * field.getLipschitz();
}

void btSkinFieldGeometry::begin(const btSkinDistanceField* field, btScalar offset, const btTransform& bodyToWorld)
{
	m_field = field;
	if (!field)
		return;
	m_offset = offset;
	m_invLipschitz = btScalar(1) / field->getLipschitz();
	m_margin = field->getSeam();
	// Within 1% of a voxel (50 um for the bake's 5 mm) above the offset level is on the surface.
	m_hitBand = btMax(btScalar(4) * field->getQuantum(), btScalar(0.01) * field->getVoxelSize());
	// Grazing: within 0.1 of a voxel (0.5 mm for the bake's 5 mm) above the offset level, a fifth of the 1 mm that
	// tests/bullet_ext/test_skin_field.cpp allows resting cloth above the skin (issue 14).
	m_contactBand = btScalar(10) * m_hitBand;
	m_tolerance = btEllipsoidClothCollider::skinFieldTolerance(*field);
	// Where the field reads +clamp the layout promises a true distance >= min(clamp, s + 2 h), s the bake's skin
	// offset: stored bricks cover every brick that meets the union grown by s + 2 h within the band (and the union
	// encloses the skin). The true distance is 1-Lipschitz and the field is within maxError of it, so no point within
	// min(clamp, s + 2 h) - offset - maxError reads below the offset (0 when the collider's offset is too large for
	// the bake: the march then stops at the first far point, conservatively).
	const btScalar farBound = btMin(field->getClamp(), field->getBakeSkinOffset() + btScalar(2) * field->getVoxelSize());
	m_farStep = btMax(btScalar(0), farBound - offset - field->getMaxError() - m_margin);
	m_toWorld = bodyToWorld;
	m_toBody = bodyToWorld.inverse();
}

bool btSkinFieldGeometry::leavesSurface(const btVector3& q, const btVector3& x, btScalar fx, btScalar level,
										btVector3& normal) const
{
	btVector3 g;
	m_field->distanceAndGradient(q, g);
	const btScalar slope = g.length();
	normal = slope > btScalar(1e-3) ? g / slope : btVector3(0, 0, 0);
	return fx >= level && g.dot(x - q) >= btScalar(0);
}

void btSkinFieldGeometry::march(const btVector3& q, const btVector3& x, const btSkinPathEnds& ends, btScalar level,
								btSkinPathHit& out) const
{
	out.m_outcome = btSkinPathHit::CLEAR;
	out.m_t = btScalar(0);
	out.m_point = x;
	out.m_normal.setValue(0, 0, 0);
	out.m_limited = false;
	bool far;
	const btScalar fq = ends.m_fq;
	out.m_startValue = fq;
	out.m_value = fq;
	if (fq - level < -m_tolerance)
	{
		out.m_outcome = btSkinPathHit::START_INSIDE;
		out.m_point = q;
		return;
	}
	const btVector3 d = x - q;
	const btScalar len = d.length();
	if (!(len > btScalar(0)))
		return;
	// Sphere tracing: at a point with clearance g (field - level - seam) no point within g / L of it reads below the
	// level (the interpolant is L-Lipschitz inside bricks and jumps by at most the seam between stored bricks; where
	// it reads +clamp, m_farStep less the rise bounds the step too, see begin() and stepFrom). So the march steps that
	// far along the path and cannot pass the first crossing. First the cheap case: the clear balls around both ends
	// cover the path.
	btScalar g, gx;
	btScalar f = fq, stepQ = stepFrom(fq, ends.m_farQ, level, g);
	const btScalar fx = ends.m_fx;
	const btScalar stepX = stepFrom(fx, ends.m_farX, level, gx);
	out.m_value = fx;
	if (stepQ >= btScalar(0) && stepQ + btMax(stepX, btScalar(0)) >= len)
		return;
	btScalar s = btScalar(0);
	for (int step = 0; step < kMaxMarchSteps; ++step)
	{
		if (g <= m_hitBand || (step >= kGrazingSteps && g <= m_contactBand))
		{
			// A node on the surface moving away from it or along it is not a contact.
			if (s == btScalar(0) && leavesSurface(q, x, fx, level, out.m_normal))
				return;
			break;
		}
		s += stepQ;
		if (s >= len || s + stepX >= len) // past x, or the clear ball around x covers the rest of the path
			return;
		f = m_field->distance(q + d * (s / len), far);
		stepQ = stepFrom(f, far, level, g);
		out.m_limited = step + 1 == kMaxMarchSteps; // out of steps: stop at the last point known outside
	}
	out.m_outcome = btSkinPathHit::HIT;
	out.m_t = s / len;
	out.m_point = q + d * out.m_t;
	out.m_value = f;
}

bool btSkinFieldGeometry::pushOut(const btVector3& p, btScalar level, btVector3& out, btScalar& value) const
{
	btVector3 g;
	const btScalar f = m_field->distanceAndGradient(p, g);
	return newton(p, f, g, level, out, value);
}

bool btSkinFieldGeometry::newton(const btVector3& p, btScalar f, const btVector3& gradient, btScalar level,
								 btVector3& out, btScalar& value) const
{
	const btScalar target = level + m_margin + btScalar(0.5) * m_hitBand;
	btVector3 point = p, g = gradient;
	for (int step = 0;; ++step)
	{
		if (btFabs(f - target) <= btScalar(0.5) * m_hitBand)
		{
			out = point;
			value = f;
			return true;
		}
		const btScalar slope2 = g.length2();
		if (step == kMaxNewtonSteps || !(slope2 > btScalar(0.01))) // a slope below 0.1: the gradient vanishes
			return false;
		point += g * ((target - f) / slope2);
		f = m_field->distanceAndGradient(point, g);
	}
}

btVector3 btSkinFieldGeometry::slide(const btVector3& from, const btVector3& displacement, btScalar level,
									 btScalar& value) const
{
	// Pieces that cannot cross the field's zero level, each brought back to the level by Newton (whose step follows
	// the gradient, away from the skin), so no piece crosses the body. A piece of length len from p to c is clear when
	// its two ends' clear balls cover it: (f(p) - seam) + (f(c) - seam) >= L len (the field is L-Lipschitz and jumps by
	// at most the seam between bricks). Each piece is first tried at 1.5 offset / L, which a slide along the surface
	// (both ends near the level, level >= offset) passes; where it does not (the piece dips into a crease), the piece
	// is retaken at the clear ball of p alone, (f(p) - seam) / L >= offset / L, clear by itself.
	const btScalar len = displacement.length();
	if (!(len > btScalar(0)))
		return from;
	const btScalar piece = btMax(m_offset * m_invLipschitz, btScalar(4) * m_hitBand);
	const btScalar taken = btMin(len, piece * btScalar(kMaxSlidePieces));
	const btVector3 direction = displacement / len;
	btVector3 p = from;
	btScalar fp = value, done = btScalar(0);
	for (int i = 0; i < kMaxSlidePieces; ++i)
	{
		const btScalar left = taken - done;
		const btScalar clearP = btMax(fp - m_margin, btScalar(0));
		btScalar step = btMin(left, btScalar(1.5) * piece);
		btVector3 c = p + direction * step, g;
		btScalar f = m_field->distanceAndGradientBelow(c, level + m_margin, g); // the slope only to come back up
		// c's clearance to the zero level, as the march takes it (a reading of +clamp bounds the distance by less; not
		// knowing whether c lies in a far brick, it is taken as one: the smaller bound).
		btScalar clearC;
		stepFrom(f, f >= m_field->getClamp(), btScalar(0), clearC);
		if (clearP + clearC < step * m_field->getLipschitz())
		{
			step = btMin(left, btMax(clearP * m_invLipschitz, piece));
			c = p + direction * step;
			f = m_field->distanceAndGradientBelow(c, level + m_margin, g);
		}
		if (f - level - m_margin < btScalar(0) && !newton(c, f, g, level, c, f))
			break;
		p = c;
		fp = f;
		value = f;
		if (step == left)
			break;
		done += step;
	}
	return p;
}

// ---------------------------------------------------------------------------------------------------------------
// The node response in tight mode (members of btEllipsoidClothColliderCore)

const btSkinDistanceField* btEllipsoidClothCollider::getActiveSkinField() const
{
	return m_detached ? 0 : static_cast<const btEllipsoidClothColliderCore*>(this)->activeSkinField();
}

const char* btSkinFieldConfigError(const btEllipsoidClothCollider::Config& config, const btEllipsoidCompoundShape* compound)
{
	const btSkinDistanceField* field = compound ? compound->getSkinField() : 0;
	if (config.m_surface != btEllipsoidClothCollider::TIGHT_SKIN || !field)
		return 0;
	if (!(config.m_skinOffset < btScalar(0.5) * field->getClamp()))
		return "btEllipsoidClothCollider::Config: m_skinOffset must be below half the skin field's clamp distance in "
			   "TIGHT_SKIN mode (the field is exact only within the clamp; use ELLIPSOIDS or bake a wider band)";
	return 0;
}

const btSkinDistanceField* btEllipsoidClothColliderCore::activeSkinField() const
{
	if (m_config.m_surface != TIGHT_SKIN || btSkinFieldConfigError(m_config, m_compound))
		return 0;
	return m_compound->getSkinField();
}

btVector3 btEllipsoidClothColliderCore::skinSurfaceVelocity(const btVector3& worldPoint, btScalar dt) const
{
	if (m_skinGroup < 0)
		return bodyVelocityAt(worldPoint, -1, dt);
	if (!(dt > btScalar(0)))
		return btVector3(0, 0, 0);
	// Where the bind-frame point under worldPoint was at the start of the substep: carried by the group's motion.
	const btVector3 bindPoint = m_groupGeometry[m_skinGroup].toBody() * worldPoint;
	return (worldPoint - m_groupPrevious[m_skinGroup] * bindPoint) / dt;
}

bool btEllipsoidClothColliderCore::raiseStart(btScalar& rise, btVector3& qb, btSkinPathEnds& ends)
{
	const btSkinFieldGeometry& geometry = skinGeometry();
	const btScalar offset = geometry.offset();
	const btScalar fq = ends.m_fq;
	// A whole offset above its level at the start or the end of the substep: it has left the skin (or is leaving
	// it), and its edges no longer hold it up.
	if (fq > btScalar(2) * offset + rise || ends.m_fx > btScalar(2) * offset + rise)
		rise = btScalar(0);
	m_skinLevel = offset + rise;
	if (!(fq < m_skinLevel - geometry.tolerance() && fq >= offset - geometry.tolerance()))
		return false; // at or above its level, or within the skin offset (the push-out's case)
	// The level rose since the node was placed: it starts from its start taken up to the level.
	btVector3 raised;
	btScalar value;
	if (geometry.pushOut(qb, m_skinLevel, raised, value))
	{
		qb = raised;
		ends.m_fq = geometry.field()->distance(qb, ends.m_farQ);
		return true;
	}
	m_skinLevel = offset; // no way up there (the gradient vanishes): decided at the skin offset this substep
	return false;
}

bool btEllipsoidClothColliderCore::collideOnSkin(btSoftBody::Node& node, const btVector3& qStart,
												 const Substep& substep, btScalar& zeta)
{
	zeta = SIMD_INFINITY;
	const btSkinFieldGeometry& geometry = skinGeometry();
	btVector3 qb = geometry.toBody() * qStart;
	const btVector3 xb = geometry.toBody() * node.m_x;
	// The node's level: the skin offset, raised where its edges sag into the skin (liftEdgesOffSkin; not on a bone's
	// field, whose substeps never lift, nor once the lift is switched off).
	btVector3 q = qStart;
	btSkinPathEnds ends = skinEnds(node, qb, xb);
	if (btScalar* rise = raisedLevel(node))
	{
		if (raiseStart(*rise, qb, ends))
			q = geometry.toWorld() * qb;
	}
	else
		m_skinLevel = geometry.offset();
	btSkinPathHit hit;
	geometry.march(qb, xb, ends, m_skinLevel, hit);
	if (hit.m_outcome == btSkinPathHit::CLEAR)
	{
		keepReading(node, xb, ends.m_fx);
		return false; // the march verified field >= level at x (its cheap test and its last ball both contain x)
	}
	m_lastStats.m_skinMarchLimits += hit.m_limited ? 1 : 0;
	const btVector3& center = m_current[substep.m_candidates[0]].m_center; // for PAPER_EQ10
	// The node's final position in the field's frame and the field there, tracked through the response.
	btVector3 point = hit.m_point;
	btScalar value = hit.m_value;
	if (hit.m_outcome == btSkinPathHit::START_INSIDE)
	{
		point = xb;
		value = pushOutOfSkin(node, q, ends.m_fx, center, substep, point);
	}
	else
	{
		++m_lastStats.m_nodesCorrected;
		node.m_x = geometry.toWorld() * hit.m_point;
		btVector3 n = hit.m_normal.length2() > btScalar(0) ? hit.m_normal : geometry.normal(hit.m_point);
		if (n.length2() == btScalar(0))
			n = (qb - xb).normalized(); // a flat spot of the field at the offset level: back along the path
		const btVector3 normal = geometry.toWorld().getBasis() * n;
		if (respondOnSkin(node, normal, node.m_x - normal * m_skinLevel, q, center, substep, btScalar(1) - hit.m_t,
						  point, value))
		{
			node.m_x = q; // held by static friction: stays at its start, outside (the march found field(q) >= level)
			point = qb;
			value = hit.m_startValue;
			// A start above the contact band (its level fell since, or links pulling hard into the skin stopped it
			// far up its path) comes down along the normal to where it touches: held there, not hovering.
			btVector3 down;
			btScalar downValue;
			if (value > m_skinLevel + geometry.contactBand() && geometry.pushOut(qb, m_skinLevel, down, downValue))
			{
				node.m_x = geometry.toWorld() * down;
				point = down;
				value = downValue;
			}
		}
	}
	keepReading(node, point, value);
	m_lastStats.m_minSkinField = btMin(m_lastStats.m_minSkinField, value);
	return false;
}

btSkinPathEnds btEllipsoidClothColliderCore::skinEnds(const btSoftBody::Node& node, const btVector3& qb,
													  const btVector3& xb) const
{
	const btSkinDistanceField& field = *skinGeometry().field();
	btSkinPathEnds ends;
	ends.m_fx = field.distance(xb, ends.m_farX);
	// Bullet starts a substep where the last one left the node (btSoftBody::predictMotion: q = x), so its start is
	// mostly the point of its last reading: the same point of the same field reads the same.
	const btVector3* reading = m_nodeReadings ? &m_nodeReadings[&node - m_contactNodeBase] : 0;
	if (reading && isReadingAt(*reading, qb))
	{
		ends.m_fq = reading->w();
		// (A stored brick that reads exactly +clamp counts as far here: a shorter march step, never a longer one.)
		ends.m_farQ = ends.m_fq >= field.getClamp();
	}
	else
		ends.m_fq = field.distance(qb, ends.m_farQ);
	return ends;
}

void btEllipsoidClothColliderCore::keepReading(const btSoftBody::Node& node, const btVector3& point, btScalar value)
{
	if (!m_nodeReadings)
		return;
	btVector3& reading = m_nodeReadings[&node - m_contactNodeBase];
	reading = point;
	reading.setW(value);
}

btScalar btEllipsoidClothColliderCore::pushOutOfSkin(btSoftBody::Node& node, const btVector3& q, btScalar fx,
													 const btVector3& center, const Substep& substep, btVector3& point)
{
	const btSkinFieldGeometry& geometry = skinGeometry();
	// The body moved into the node (or it started within the skin). If the solve already brought it out, keep it.
	btScalar value = fx;
	if (value >= m_skinLevel)
		return value;
	++m_lastStats.m_nodesPushedOut;
	btVector3 out;
	if (geometry.pushOut(point, m_skinLevel, out, value))
	{
		node.m_x = geometry.toWorld() * out;
		point = out;
		const btVector3 normal = geometry.toWorld().getBasis() * geometry.normal(out);
		respondOnSkin(node, normal, node.m_x - normal * m_skinLevel, q, center, substep, btScalar(0), point, value);
		return value;
	}
	// The gradient vanishes (deeper than the clamp, the field's extremum) or Newton did not converge: the union
	// push-out, whose exit is outside every ellipsoid and so outside the skin they enclose.
	++m_lastStats.m_skinFallbacks;
	bool moved;
	pushNodeOut(node, node.m_x, q, substep, moved);
	if (!moved)
	{
		btScalar ignored = SIMD_INFINITY;
		leavePocket(node, substep, ignored); // outside every ellipsoid already: a pocket the union encloses
	}
	point = geometry.toBody() * node.m_x;
	return geometry.field()->distance(point);
}

bool btEllipsoidClothColliderCore::respondOnSkin(btSoftBody::Node& node, const btVector3& normal,
												 const btVector3& surface, const btVector3& start,
												 const btVector3& center, const Substep& substep, btScalar remaining,
												 btVector3& point, btScalar& value)
{
	btNodeContacts contacts;
	contacts.add(normal);
	const btVector3 bodyVelocity = skinSurfaceVelocity(surface, substep.m_dt);
	const btVector3 before = node.m_v;
	const btVector3 relative = node.m_v - bodyVelocity;
	btVector3 vr = btRelativeVelocityAfterContact(m_config.m_velocityRule, substep.m_friction, relative, contacts,
												  surface, start, center);
	const bool stopped = relative.length2() > btScalar(0) && vr.length2() == btScalar(0);
	if (remaining > btScalar(0) && !stopped)
	{
		// The rest of the substep along the surface, with the new velocity.
		const btSkinFieldGeometry& geometry = skinGeometry();
		const btVector3 displacement = geometry.toBody().getBasis() * (vr * (remaining * substep.m_dt));
		point = geometry.slide(point, displacement, m_skinLevel, value);
		node.m_x = geometry.toWorld() * point;
	}
	setContactVelocity(node, vr, normal, start, bodyVelocity, before, surface, substep.m_dt);
	return stopped;
}

void btEllipsoidClothColliderCore::ContactRecord::sortEdgesByNode(int numNodes)
{
	// Counting sort by the lower node index, stable (link order within a node): the lift's pass over the edges then
	// reads the nodes about in order, as the node phase does.
	btAlignedObjectArray<int> start;
	start.resize(numNodes + 1);
	for (int i = 0; i <= numNodes; ++i)
		start[i] = 0;
	for (int e = 0; e < m_edges.size(); ++e)
		++start[btMin(m_edges[e].m_a, m_edges[e].m_b) + 1];
	for (int i = 0; i < numNodes; ++i)
		start[i + 1] += start[i];
	btAlignedObjectArray<LiftEdge> sorted;
	sorted.resize(m_edges.size());
	for (int e = 0; e < m_edges.size(); ++e)
		sorted[start[btMin(m_edges[e].m_a, m_edges[e].m_b)]++] = m_edges[e];
	m_edges.copyFromArray(sorted);
}

bool btEllipsoidClothColliderCore::ContactRecord::listEdges(btSoftBody& softBody)
{
	const int numLinks = softBody.m_links.size(), numNodes = softBody.m_nodes.size();
	const void* linkData = numLinks > 0 ? &softBody.m_links[0] : 0;
	const void* nodeData = numNodes > 0 ? &softBody.m_nodes[0] : 0;
	const btScalar restScale = softBody.getRestLengthScale();
	if (numLinks == m_edgeLinkCount && numNodes == m_edgeNodeCount && linkData == m_edgeLinkData &&
		nodeData == m_edgeNodeData && restScale == m_edgeRestScale)
		return false;
	m_edgeLinkCount = numLinks;
	m_edgeNodeCount = numNodes;
	m_edgeLinkData = linkData;
	m_edgeNodeData = nodeData;
	m_edgeRestScale = restScale;
	m_edges.resize(0);
	const btSoftBody::Node* base = static_cast<const btSoftBody::Node*>(nodeData);
	for (int l = 0; l < numLinks; ++l)
	{
		const btSoftBody::Link& link = softBody.m_links[l];
		if (link.m_bbending)
			continue; // a spring between the far corners of two faces, not an edge of the cloth
		LiftEdge edge;
		edge.m_mid.setValue(0, 0, 0);
		edge.m_slack = btScalar(0);
		edge.m_rest = link.m_rl;
		edge.m_a = int(link.m_n[0] - base);
		edge.m_b = int(link.m_n[1] - base);
		m_edges.push_back(edge);
	}
	sortEdgesByNode(numNodes);
	// The edges at each node (counting sort by node).
	m_nodeEdgeStart.resize(numNodes + 1);
	for (int i = 0; i <= numNodes; ++i)
		m_nodeEdgeStart[i] = 0;
	for (int e = 0; e < m_edges.size(); ++e)
	{
		++m_nodeEdgeStart[m_edges[e].m_a + 1];
		++m_nodeEdgeStart[m_edges[e].m_b + 1];
	}
	for (int i = 0; i < numNodes; ++i)
		m_nodeEdgeStart[i + 1] += m_nodeEdgeStart[i];
	m_nodeEdges.resize(2 * m_edges.size());
	btAlignedObjectArray<int> fill;
	fill.resize(numNodes);
	for (int i = 0; i < numNodes; ++i)
		fill[i] = m_nodeEdgeStart[i];
	for (int e = 0; e < m_edges.size(); ++e)
	{
		m_nodeEdges[fill[m_edges[e].m_a]++] = e;
		m_nodeEdges[fill[m_edges[e].m_b]++] = e;
	}
	return true;
}

namespace
{
/// Eight flag bytes as one word (memcpy: no alignment or aliasing assumption).
inline std::uint64_t readWord(const unsigned char* p)
{
	std::uint64_t w;
	std::memcpy(&w, p, sizeof(w));
	return w;
}
} // namespace

void btEllipsoidClothColliderCore::liftEdgesOffSkin(btSoftBody* softBody)
{
	const btSkinFieldGeometry& geometry = m_skinGeometry;
	const btSkinDistanceField& field = *geometry.field();
	// Edges clear the skin by a fraction of the skin offset (Config::m_liftClearance, below 1): an edge at the offset
	// on a flat skin is untouched, and its nodes rest higher only by what the edge's sag over a curved skin takes
	// below that.
	const btScalar clearance = m_config.m_liftClearance * geometry.offset();
	const int numNodes = softBody->m_nodes.size();
	if (!(clearance > btScalar(0)) || numNodes == 0)
		return;
	const btScalar maxRise = geometry.maxRise();
	ContactRecord* record = m_contactRecord; // (collide() began it)
	const bool relisted = record->listEdges(*softBody);
	const int numEdges = record->m_edges.size();
	LiftEdge* edges = numEdges > 0 ? &record->m_edges[0] : 0;
	if (relisted || m_moving || record->m_edgeRevision != m_compound->getAnalyticRevision() ||
		record->m_edgeClearance != clearance)
	{
		// Other edges, another field, another clearance, or the body moved: no reading is reusable.
		for (int e = 0; e < numEdges; ++e)
			edges[e].m_slack = btScalar(0);
		record->m_edgeRevision = m_compound->getAnalyticRevision();
		record->m_edgeClearance = clearance;
	}
	const btSoftBody::Node* nodes = &softBody->m_nodes[0];
	const btScalar lipschitz = field.getLipschitz();
	m_riseAsk.resize(numNodes, btScalar(0));
	m_riseSlack.resize(numNodes, SIMD_INFINITY);
	listEdgeNodes(numNodes);
	// Every edge with an end in contact, once (the order does not matter: asks and slacks combine by max and min).
	// Where a quarter of the nodes or more touch (a tight garment), one pass over the edge array in order: the per-node
	// lists below jump about the edge array, and their "looked at from the other end" test is a coin toss (the walk
	// tights' lift took 48% of the tight collider's mispredicted branches and 37% of its level-2 cache misses that way,
	// callgrind --branch-sim / --cache-sim). Where few touch, only the edges of those nodes.
	if (4 * m_edgeActive.size() >= numNodes)
	{
		for (int e = 0; e < numEdges; ++e)
			if (m_contactFlags[edges[e].m_a] | m_contactFlags[edges[e].m_b])
				liftEdge(nodes, edges[e], clearance, lipschitz);
	}
	else
	{
		const int* edgeStart = &record->m_nodeEdgeStart[0];
		const int* nodeEdges = numEdges > 0 ? &record->m_nodeEdges[0] : 0;
		for (int k = 0; k < m_edgeActive.size(); ++k)
		{
			const int i = m_edgeActive[k];
			for (int s = edgeStart[i]; s < edgeStart[i + 1]; ++s)
			{
				LiftEdge& edge = edges[nodeEdges[s]];
				const int j = edge.m_a == i ? edge.m_b : edge.m_a;
				if (j < i && m_contactFlags[j])
					continue; // looked at from j
				liftEdge(nodes, edge, clearance, lipschitz);
			}
		}
	}
	updateNodeRises(clearance, maxRise);
}

void btEllipsoidClothColliderCore::listEdgeNodes(int numNodes)
{
	m_edgeActive.resize(0);
	for (int i = 0; i < numNodes;)
	{
		if (i + 8 <= numNodes && !readWord(m_contactFlags + i))
		{
			i += 8; // most of a cloth touches nothing: eight nodes at a time
			continue;
		}
		if (m_contactFlags[i])
			m_edgeActive.push_back(i);
		++i;
	}
}

void btEllipsoidClothColliderCore::updateNodeRises(btScalar clearance, btScalar maxRise)
{
	// A level rises by at most a quarter of the skin offset per substep: the node phase pushes the node up by what
	// its level rose, and a push of several millimetres in one substep stretched its links enough to throw the
	// cloth about (a coarse cloth on a sphere bounced off it).
	const btScalar maxStep = btScalar(0.25) * m_skinGeometry.offset();
	for (int k = 0; k < m_edgeActive.size(); ++k)
		updateNodeRise(m_edgeActive[k], clearance, maxRise, maxStep);
	for (int k = 0; k < m_liftNear.size(); ++k)
		updateNodeRise(m_liftNear[k], clearance, maxRise, maxStep);
	m_liftNear.resize(0);
}

void btEllipsoidClothColliderCore::updateNodeRise(int i, btScalar clearance, btScalar maxRise, btScalar maxStep)
{
	btScalar& rise = m_nodeRise[i];
	if (m_riseAsk[i] > btScalar(0))
	{
		rise = btMin(rise + btMin(m_riseAsk[i], maxStep), maxRise);
		++m_lastStats.m_nodesLifted;
	}
	else if (rise > btScalar(0) && m_riseSlack[i] > clearance)
	{
		// Every edge's middle stands more than twice the clearance off the skin: half of the excess goes (the
		// next substep reads the edges again, so the level settles where its most sagging edge just clears).
		rise = btMax(btScalar(0), rise - btScalar(0.5) * (m_riseSlack[i] - clearance));
	}
	m_riseAsk[i] = btScalar(0);
	m_riseSlack[i] = SIMD_INFINITY;
}

void btEllipsoidClothColliderCore::askRise(int i, btScalar ask)
{
	if (!(ask > btScalar(0)))
		return;
	if (!m_contactFlags[i] && m_riseAsk[i] == btScalar(0))
		m_liftNear.push_back(i); // (updateNodeRises takes it up with the nodes in contact)
	m_riseAsk[i] = btMax(m_riseAsk[i], ask);
}

btScalar btEllipsoidClothColliderCore::liftWeight(const btSoftBody::Node* nodes, int i) const
{
	if (m_contactFlags[i])
		return nodes[i].m_im;
	if (!m_nodeReadings)
		return btScalar(0);
	const btSkinFieldGeometry& geometry = m_skinGeometry;
	const btVector3& reading = m_nodeReadings[i];
	// (as collideOnSkin maps it: the same point when it was read)
	if (!isReadingAt(reading, geometry.toBody() * nodes[i].m_x))
		return btScalar(0);
	return reading.w() < geometry.offset() + geometry.maxRise() ? nodes[i].m_im : btScalar(0);
}

void btEllipsoidClothColliderCore::liftEdge(const btSoftBody::Node* nodes, LiftEdge& edge, btScalar clearance,
											btScalar lipschitz)
{
	const btSkinFieldGeometry& geometry = m_skinGeometry;
	const btSkinDistanceField& field = *geometry.field();
	const int ia = edge.m_a, ib = edge.m_b;
	if (!(nodes[ia].m_im + nodes[ib].m_im > btScalar(0)))
		return; // (pinned at both ends)
	const btVector3& xa = nodes[ia].m_x;
	const btVector3& xb = nodes[ib].m_x;
	const btVector3 mid = (xa + xb) * btScalar(0.5);
	// The field is L-Lipschitz (up to its seam, which the slack keeps): a midpoint that read `slack` above the
	// clearance and has since moved less than slack / L (the body still) still reads above it, by at least what is left.
	const btScalar slack = edge.m_slack;
	const btScalar moved2 = slack > btScalar(0) ? (mid - edge.m_mid).length2() * lipschitz * lipschitz : SIMD_INFINITY;
	if (moved2 < slack * slack)
	{
		if (m_nodeRise[ia] > btScalar(0) || m_nodeRise[ib] > btScalar(0))
		{
			const btScalar left = slack - btSqrt(moved2);
			m_riseSlack[ia] = btMin(m_riseSlack[ia], left);
			m_riseSlack[ib] = btMin(m_riseSlack[ib], left);
		}
		return;
	}
	// An edge stretched past 1.5x its rest length spans something (a limb between nodes on both sides): a rise of
	// its nodes cannot free it without carrying them far from the skin.
	if ((xb - xa).length2() > btScalar(2.25) * edge.m_rest * edge.m_rest)
		return;
	const btVector3 midBody = geometry.toBody() * mid;
	btVector3 g;
	const btScalar f = field.distanceAndGradientBelow(midBody, clearance, g); // the slope only to ask for a rise
	edge.m_mid = mid;
	edge.m_slack = f - clearance - geometry.margin();
	if (f >= clearance)
	{
		m_riseSlack[ia] = btMin(m_riseSlack[ia], edge.m_slack);
		m_riseSlack[ib] = btMin(m_riseSlack[ib], edge.m_slack);
		return;
	}
	const btScalar slope = g.length();
	if (!(slope > btScalar(0.1)))
		return;
	// The ends whose level can rise: in contact or resting near the skin, movable.
	const btScalar wa = liftWeight(nodes, ia);
	const btScalar wb = liftWeight(nodes, ib);
	if (!(wa + wb > btScalar(0)))
		return;
	// Raising both levels by d raises the middle by about d (the skin under a short edge is nearly parallel to it);
	// split by inverse mass, each end that can rise asks its share of what the middle lacks.
	const btScalar lack = (clearance - f) / slope;
	const btScalar askA = lack * btScalar(2) * wa / (wa + wb), askB = lack * btScalar(2) * wb / (wa + wb);
	askRise(ia, askA);
	askRise(ib, askB);
}

// ---------------------------------------------------------------------------------------------------------------
// Skinned bodies: the bind-pose field in the frame of a bone (members of btEllipsoidClothColliderCore)
//
// The field is baked once on the bind mesh. A rigid ellipsoid moves with its bone's skinning motion T (a rotation and
// a translation, btEllipsoidCompoundShape::setBoneFrames), and so does every skin point it owns (all its bound points
// depend on that bone alone, bodyfit/fitting/skinned_fit.h). A node is decided on the field at its back-mapped
// position T^-1 x when (1) every swept candidate of its path is rigid in one bone group: no other skin comes within
// the skin offset of the path during the substep, and (2) every bind ellipsoid whose box meets the back-mapped path
// grown by the contact band is rigid in that group: each skin point lies in the bind ellipsoid of the cluster that owns
// it, so within that band the bind field measures only skin that moved with the group (no skin of a neighbouring
// cluster that has moved since the bake). The path q -> x back-mapped through the previous and the current T is the
// path in the bone's frame, where that skin is still: the static tight response runs there and its result is mapped
// forward. When the response moved the node (placement, slide, push-out), (1) and (2) are checked again at its end
// (else it is undone). Every other node keeps the union response of the sweep: the fallback, counted per ellipsoid.

const btAlignedObjectArray<int>& btEllipsoidClothCollider::getBoneFieldFallbacks() const
{
	return static_cast<const btEllipsoidClothColliderCore*>(this)->boneFieldFallbacks();
}

void btEllipsoidClothColliderCore::prepareBoneFields()
{
	m_boneFields = false;
	m_skinGroup = -1;
	const btSkinDistanceField* field = activeSkinField();
	const btEllipsoidCompoundShape* bind = m_compound->getBindPose();
	const int n = m_compound->getNumEllipsoids();
	const bool frames = field && bind && m_compound->hasBoneFrames() && bind->getNumEllipsoids() == n;
	const bool hadFrames = n > 0 && m_frameBones[1].size() == n;
	m_frameBones[0].copyFromArray(m_frameBones[1]);
	// (copyFromArray would copy an uninitialised default transform into the new slots first)
	m_frames[0].resize(m_frames[1].size(), btTransform::getIdentity());
	for (int i = 0; i < m_frames[1].size(); ++i)
		m_frames[0][i] = m_frames[1][i];
	m_frameBones[1].resize(frames ? n : 0);
	m_frames[1].resize(frames ? n : 0, btTransform::getIdentity());
	for (int i = 0; frames && i < n; ++i)
	{
		m_frameBones[1][i] = m_compound->getFrameBone(i);
		m_frames[1][i] = m_compound->getBindToCurrent(i);
	}
	if (!frames || !hadFrames || !m_sweeping)
		return;
	m_bindCache.update(bind, btTransform::getIdentity());
	if (m_boneFallbacks.size() != n)
		m_boneFallbacks.resize(n, 0);
	groupBoneFrames(*field);
	m_boneFields = m_groupGeometry.size() > 0;
}

namespace
{
/// An upper bound of |a p - b p| over the ball of `radius` about c.
btScalar frameDeviation(const btTransform& a, const btTransform& b, const btVector3& c, btScalar radius)
{
	btScalar rotation2 = btScalar(0); // Frobenius norm of the basis difference (>= its spectral norm)
	for (int r = 0; r < 3; ++r)
		rotation2 += (a.getBasis()[r] - b.getBasis()[r]).length2();
	return btSqrt(rotation2) * radius + (a * c - b * c).length();
}
} // namespace

void btEllipsoidClothColliderCore::groupBoneFrames(const btSkinDistanceField& field)
{
	// Bones that move alike share a group: deciding on one bone's frame for skin that moves with another displaces
	// that skin by at most the deviation of the two motions over the bind union, so a deviation within the tolerance
	// the tight response already allows below the offset (skinFieldTolerance) keeps its guarantee up to twice that.
	const btScalar tolerance = skinFieldTolerance(field);
	const btVector3 lo = m_bindCache.getAabbMin(), hi = m_bindCache.getAabbMax();
	const btVector3 c = (lo + hi) * btScalar(0.5);
	const btScalar radius = (hi - lo).length() * btScalar(0.5);
	const int n = m_frameBones[1].size();
	m_frameGroup.resize(n);
	m_groupGeometry.resize(0);
	m_groupPrevious.resize(0, btTransform::getIdentity()); // (a default fill value would be an uninitialised transform)
	m_groupBone.resize(0);
	m_groupFirst.resize(0);
	const btScalar offset = btMax(m_config.m_skinOffset, btScalar(0));
	for (int i = 0; i < n; ++i)
	{
		m_frameGroup[i] = -1;
		const int bone = m_frameBones[1][i];
		if (bone < 0 || m_frameBones[0][i] != bone)
			continue;
		int g = 0;
		for (; g < m_groupBone.size(); ++g)
		{
			const int first = m_groupFirst[g];
			if (m_groupBone[g] == bone ||
				(frameDeviation(m_frames[0][first], m_frames[0][i], c, radius) <= tolerance &&
				 frameDeviation(m_frames[1][first], m_frames[1][i], c, radius) <= tolerance))
				break;
		}
		if (g == m_groupBone.size())
		{
			m_groupBone.push_back(bone);
			m_groupFirst.push_back(i);
			m_groupPrevious.push_back(m_previousPose * m_frames[0][i]);
			m_groupGeometry.push_back(btSkinFieldGeometry());
			m_groupGeometry[g].begin(&field, offset, m_currentPose * m_frames[1][i]);
		}
		m_frameGroup[i] = g;
	}
}

int btEllipsoidClothColliderCore::candidateGroup(const int* cand, int nc)
{
	const int g = m_frameGroup[cand[0]];
	int other = g < 0 ? cand[0] : -1;
	for (int j = 1; j < nc && other < 0; ++j)
		if (m_frameGroup[cand[j]] != g)
			other = cand[j];
	if (other < 0)
		return g;
	++m_boneFallbacks[other];
	return -1;
}

bool btEllipsoidClothColliderCore::bindNeighboursIn(int g, const btVector3& a, const btVector3& b, btScalar band)
{
	const btEllipsoidWorldCache::PathQuery query(m_bindCache, band);
	m_bindCandidates.resize(m_bindCache.size());
	const int nb = query.candidates(a, b, &m_bindCandidates[0]);
	for (int k = 0; k < nb; ++k)
		if (m_frameGroup[m_bindCandidates[k]] != g)
		{
			++m_boneFallbacks[m_bindCandidates[k]];
			return false;
		}
	return true;
}

bool btEllipsoidClothColliderCore::collideOnBoneField(btSoftBody::Node& node, const btVector3& q, int nc,
													  const Substep& substep)
{
	// (A dynamic body would take reaction impulses that an undone response could not take back.)
	const int g = m_dynamicBody ? -1 : candidateGroup(substep.m_candidates, nc);
	if (g < 0)
	{
		++m_lastStats.m_boneFieldFallbacks;
		return false;
	}
	const btSkinFieldGeometry& geometry = m_groupGeometry[g];
	const btScalar band = substep.m_band; // within it a placed node touches a surface (contactBand)
	const btVector3 qb = m_groupPrevious[g].invXform(q); // previous world -> bind frame
	if (!bindNeighboursIn(g, qb, geometry.toBody() * node.m_x, band))
	{
		++m_lastStats.m_boneFieldFallbacks;
		return false;
	}
	const btVector3 x0 = node.m_x, v0 = node.m_v;
	const btEllipsoidClothStats before = m_lastStats;
	m_skinGroup = g;
	btScalar zeta;
	collideOnSkin(node, geometry.toWorld() * qb, substep, zeta); // the start carried with the group
	m_skinGroup = -1;
	if (!(node.m_x == x0))
	{
		// Checks (1) and (2) at the node's end: the response may have moved it beyond the path.
		const int nEnd = substep.m_contactQuery.candidates(node.m_x, node.m_x, substep.m_contactCandidates);
		const btVector3 xb = geometry.toBody() * node.m_x;
		if ((nEnd > 0 && candidateGroup(substep.m_contactCandidates, nEnd) != g) || !bindNeighboursIn(g, xb, xb, band))
		{
			node.m_x = x0;
			node.m_v = v0;
			m_lastStats = before;
			++m_lastStats.m_boneFieldFallbacks;
			return false;
		}
	}
	++m_lastStats.m_boneFieldNodes;
	return true;
}
