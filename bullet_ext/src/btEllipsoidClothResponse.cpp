/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidClothResponse.h.
*/

#include "src/btEllipsoidClothResponse.h"

namespace
{

/// Rounding repair: at most this many steps out along a normal, starting at 2 ulps of the coordinates and
/// doubling (30 ulps in total); anything that needs more is a geometric problem for the union push-out.
const int kMaxNudges = 4;

/// Bisection steps when a crease shortens the skin offset: the offset is then exact to skin / 2^6 (0.03 mm at 2 mm).
const int kCreaseBisections = 6;

/// Two entries along one path closer than this (metres) are a tie (the path meets a crease of the union).
const btScalar kTieDistance = btScalar(1e-6);

/// The normalised sum of the outward normals at `surface` of the candidates whose entry parameter ties with tBest
/// (within tieTolerance), or `normal` if fewer than two tie.
btVector3 creaseNormal(const btEllipsoidWorldCache& cache, const int* cand, const btScalar* tvals, int nc,
					   btScalar tBest, btScalar tieTolerance, const btVector3& surface, const btVector3& normal)
{
	int tied = 0;
	for (int j = 0; j < nc && nc > 1; ++j)
		tied += tvals[j] <= tBest + tieTolerance ? 1 : 0;
	int ties = 0;
	btVector3 normalSum(0, 0, 0);
	for (int j = 0; j < nc && tied > 1; ++j)
	{
		if (!(tvals[j] <= tBest + tieTolerance))
			continue;
		const btEllipsoidWorldCache::Entry& ej = cache[cand[j]];
		btVector3 uj = ej.m_whiten * (surface - ej.m_center);
		const btScalar ujl = uj.length();
		if (ujl > btScalar(0))
			uj /= ujl;
		normalSum += btWhitenedNormal(ej.m_whiten, uj).normalized();
		++ties;
	}
	if (ties > 1 && normalSum.length2() > SIMD_EPSILON)
		return normalSum.normalized();
	return normal;
}

/// Steps p out along the normal of the candidate containing it, from 2 ulps of the coordinates, doubling, at most
/// kMaxNudges times. \return the smallest zeta over the candidates at the final p.
btScalar nudgeOut(const btEllipsoidWorldCache& cache, const int* cand, int nc, btVector3& p, const btVector3& fallbackDir)
{
	const btScalar* packed = cache.getPackedRecords();
	int worst = -1;
	btScalar z = btMinZetaPacked(packed, cand, nc, p, &worst);
	btScalar step = SIMD_EPSILON * btScalar(2) * (p.absolute()[p.absolute().maxAxis()] + btScalar(1e-3));
	for (int attempt = 0; attempt < kMaxNudges && z < btScalar(1) && worst >= 0; ++attempt)
	{
		const btEllipsoidWorldCache::Entry& e = cache[worst];
		const btVector3 g = btWhitenedNormal(e.m_whiten, e.m_whiten * (p - e.m_center));
		const btScalar gl = g.length();
		p += (gl > SIMD_EPSILON ? g / gl : fallbackDir) * step;
		step *= btScalar(2);
		z = btMinZetaPacked(packed, cand, nc, p, &worst);
	}
	return z;
}

/// The largest skin offset along the normal from the surface point (an outside point) that stays outside every
/// candidate, by bisection on [0, skin]; point and zeta receive it (the surface point itself if none does).
void shortenSkin(const btScalar* packed, const int* cand, int nc, const btEntryPlacement& placed, btScalar skin,
				 btVector3& point, btScalar& zeta)
{
	btScalar lo = btScalar(0), hi = skin;
	point = placed.m_surface;
	for (int it = 0; it < kCreaseBisections; ++it)
	{
		const btScalar mid = btScalar(0.5) * (lo + hi);
		const btVector3 trial = placed.m_surface + placed.m_normal * mid;
		const btScalar zt = btMinZetaPacked(packed, cand, nc, trial, 0);
		if (zt >= btScalar(1))
		{
			lo = mid;
			point = trial;
			zeta = zt;
		}
		else
			hi = mid;
	}
}

} // namespace

void btPlaceAtEntry(const btEllipsoidWorldCache& cache, const btPathEntry& entry, const int* cand, const btScalar* tvals,
					int nc, const btVector3& q, const btVector3& x, btScalar skin, btEntryPlacement& out)
{
	// The surface point is exactly on the unit sphere in whitened space, then mapped back.
	const btEllipsoidWorldCache::Entry& e = cache[entry.m_ellipsoid];
	const btScalar ul = entry.m_u.length();
	const btVector3 uHit = ul > btScalar(0) ? entry.m_u / ul : btVector3(1, 0, 0);
	out.m_surface = e.m_center + e.m_unwhiten * uHit;
	btVector3 normal = btWhitenedNormal(e.m_whiten, uHit);
	normal.normalize(); // |W^T u| >= 1 / max(a) > 0 for |u| = 1
	const btScalar tieTolerance = nc > 1 ? kTieDistance / btMax((x - q).length(), kTieDistance) : btScalar(0);
	out.m_normal = creaseNormal(cache, cand, tvals, nc, entry.m_t, tieTolerance, out.m_surface, normal);
	out.m_placed = out.m_surface + out.m_normal * skin;
	out.m_center = e.m_center;
}

bool btKeepOutsideCandidates(const btEllipsoidWorldCache& cache, const int* cand, int nc, const btEntryPlacement& placed,
							 btScalar skin, btVector3& point, btScalar& zeta)
{
	// The candidates cover the path box grown by the skin, which contains every point tried here.
	const btScalar* packed = cache.getPackedRecords();
	point = placed.m_placed;
	zeta = btMinZetaPacked(packed, cand, nc, placed.m_placed, 0);
	if (zeta >= btScalar(1))
		return true;
	zeta = btMinZetaPacked(packed, cand, nc, placed.m_surface, 0);
	if (zeta >= btScalar(1))
		shortenSkin(packed, cand, nc, placed, skin, point, zeta);
	else
	{
		// The surface point itself rounds to inside (skin 0, or far from the origin): step out along the normal of
		// the ellipsoid that contains it by a few ulps of the coordinates.
		point = placed.m_surface;
		zeta = nudgeOut(cache, cand, nc, point, placed.m_normal);
	}
	return zeta >= btScalar(1);
}

btScalar btClearance(const btEllipsoidWorldCache::Entry& e, const btVector3& p)
{
	const btVector3 u = e.m_whiten * (p - e.m_center);
	const btScalar r = u.length();
	if (!(r > btScalar(1)))
		return btScalar(0);
	const btScalar gl = btWhitenedNormal(e.m_whiten, u).length() / r;
	return gl > btScalar(0) ? (r - btScalar(1)) / gl : btScalar(0);
}

void btAddTouchingNormals(const btEllipsoidWorldCache& cache, const int* cand, int nc, const btVector3& p, btScalar band,
						  btNodeContacts& contacts)
{
	for (int j = 0; j < nc; ++j)
	{
		const btEllipsoidWorldCache::Entry& e = cache[cand[j]];
		const btVector3 u = e.m_whiten * (p - e.m_center);
		const btScalar r = u.length();
		if (!(r > btScalar(0)))
			continue;
		const btVector3 g = btWhitenedNormal(e.m_whiten, u) / r; // gradient of |u| at p
		const btScalar gl = g.length();
		if (gl > btScalar(0) && r - btScalar(1) <= band * gl)
			contacts.add(g / gl);
	}
}

namespace
{

bool insideCone(const btVector3& v, const btNodeContacts& contacts)
{
	// A small negative slack: projections computed in btScalar land on the planes up to rounding.
	const btScalar slack = btScalar(-8) * SIMD_EPSILON * v.length();
	for (int k = 0; k < contacts.m_count; ++k)
		if (v.dot(contacts.m_normals[k]) < slack)
			return false;
	return true;
}

/// Keeps candidate c if it is feasible and nearer to v than best so far.
void keepNearest(const btVector3& v, const btVector3& c, const btNodeContacts& contacts, btVector3& best,
				 btScalar& bestDistance)
{
	const btScalar d = (v - c).length2();
	if (d < bestDistance && insideCone(c, contacts))
	{
		best = c;
		bestDistance = d;
	}
}

} // namespace

btVector3 btProjectOntoContactCone(const btVector3& v, const btNodeContacts& contacts)
{
	if (insideCone(v, contacts))
		return v;
	// The projection lies in the relative interior of a face of the cone: a plane (one active normal), an edge (two)
	// or the apex; each candidate is the projection onto that face's span, and the nearest feasible one is it.
	btVector3 best(0, 0, 0);
	btScalar bestDistance = v.length2();
	const int n = contacts.m_count;
	for (int i = 0; i < n; ++i)
	{
		const btVector3& ni = contacts.m_normals[i];
		keepNearest(v, v - ni * v.dot(ni), contacts, best, bestDistance);
		for (int j = i + 1; j < n; ++j)
		{
			btVector3 edge = ni.cross(contacts.m_normals[j]);
			const btScalar el = edge.length();
			if (el < SIMD_EPSILON)
				continue;
			edge /= el;
			keepNearest(v, edge * v.dot(edge), contacts, best, bestDistance);
		}
	}
	return best;
}

btVector3 btRelativeVelocityAfterContact(btEllipsoidClothCollider::VelocityRule rule, btScalar friction,
										 const btVector3& relative, const btNodeContacts& contacts,
										 const btVector3& surfacePoint, const btVector3& start, const btVector3& center)
{
	btVector3 vr = relative;
	if (rule == btEllipsoidClothCollider::PAPER_EQ10)
	{
		// Gong et al. 2018, eq. 10: v_c = v_n |c P0| / (|c P0| + |P0 p0|).
		const btScalar cp = (surfacePoint - center).length();
		const btScalar pq = (start - surfacePoint).length();
		const btScalar denom = cp + pq;
		if (denom > btScalar(0))
			vr *= cp / denom;
		return btProjectOntoContactCone(vr, contacts);
	}
	// Remove the velocity into the touched surfaces; Coulomb friction reduces what is left (tangential to the active
	// surfaces) by friction * |removed|. With one contact this is the normal/tangential split.
	const btVector3 vt = btProjectOntoContactCone(vr, contacts);
	const btScalar removed = (vr - vt).length();
	const btScalar vtLen = vt.length();
	const btScalar drop = btMax(friction, btScalar(0)) * removed;
	return vtLen <= drop ? btVector3(0, 0, 0) : vt * ((vtLen - drop) / vtLen);
}

btVector3 btCapBySurfaceMotion(const btVector3& relative, const btVector3& normal, const btVector3& motion)
{
	const btScalar along = (motion - normal * motion.dot(normal)).length();
	const btScalar speed = relative.length();
	return speed > along ? relative * (along / speed) : relative;
}
