/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
The collider's response to a node whose path q -> x entered the union: placement at the earliest entry plus the skin
(with the crease rules) and the velocity rule. Header only: it runs inside the collider's node loop.
*/

#ifndef BT_ELLIPSOID_CLOTH_RESPONSE_H
#define BT_ELLIPSOID_CLOTH_RESPONSE_H

#include "BulletSoftBody/btSoftBody.h"

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include "src/btEllipsoidNarrowPhase.h"

/// Where a node whose path entered the union goes.
struct btEntryPlacement
{
	btVector3 m_surface; ///< the earliest entry point, on the surface of the entered ellipsoid
	btVector3 m_normal;	 ///< outward normal there (the normalised sum over tied entries in a crease)
	btVector3 m_placed;	 ///< m_surface + skin * m_normal
	btVector3 m_center;	 ///< centre of the entered ellipsoid (for eq. 10)
};

namespace btEllipsoidClothResponseDetail
{

/// Rounding repair: at most this many steps out along a normal, starting at 2 ulps of the coordinates and
/// doubling (30 ulps in total); anything that needs more is a geometric problem for the union push-out.
static const int kMaxNudges = 4;

/// Bisection steps when a crease shortens the skin offset: the offset is then exact to skin / 2^6 (0.03 mm at 2 mm).
static const int kCreaseBisections = 6;

/// Two entries along one path closer than this (metres) are a tie (the path meets a crease of the union).
static const btScalar kTieDistance = btScalar(1e-6);

/// The normalised sum of the outward normals at `surface` of the candidates whose entry parameter ties with tBest
/// (within tieTolerance), or `normal` if fewer than two tie.
BT_ELLIPSOID_ALWAYS_INLINE btVector3 creaseNormal(const btEllipsoidWorldCache &cache, const int *cand,
												  const btScalar *tvals, int nc, btScalar tBest, btScalar tieTolerance,
												  const btVector3 &surface, const btVector3 &normal)
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
		const btEllipsoidWorldCache::Entry &ej = cache[cand[j]];
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
inline btScalar nudgeOut(const btEllipsoidWorldCache &cache, const int *cand, int nc, btVector3 &p,
						 const btVector3 &fallbackDir)
{
	const btScalar *packed = cache.getPackedRecords();
	int worst = -1;
	btScalar z = btMinZetaPacked(packed, cand, nc, p, &worst);
	btScalar step = SIMD_EPSILON * btScalar(2) * (p.absolute()[p.absolute().maxAxis()] + btScalar(1e-3));
	for (int attempt = 0; attempt < kMaxNudges && z < btScalar(1) && worst >= 0; ++attempt)
	{
		const btEllipsoidWorldCache::Entry &e = cache[worst];
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
inline void shortenSkin(const btScalar *packed, const int *cand, int nc, const btEntryPlacement &placed, btScalar skin,
						btVector3 &point, btScalar &zeta)
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

} // namespace btEllipsoidClothResponseDetail

/// The placement for the earliest entry of the path test over the candidates cand[0, nc) with entry parameters
/// tvals (btEarliestEntry): entries within 1 micrometre of the earliest along the path are a tie (the path meets a
/// crease of the union, Gong et al. 2018 Figure 6 case 1), and the skin offset then goes along the sum of their
/// normals, so the answer does not depend on the order of the ellipsoids.
BT_ELLIPSOID_ALWAYS_INLINE void btPlaceAtEntry(const btEllipsoidWorldCache &cache, const btPathEntry &entry,
											   const int *cand, const btScalar *tvals, int nc, const btVector3 &q,
											   const btVector3 &x, btScalar skin, btEntryPlacement &out)
{
	// The surface point is exactly on the unit sphere in whitened space, then mapped back.
	const btEllipsoidWorldCache::Entry &e = cache[entry.m_ellipsoid];
	const btScalar ul = entry.m_u.length();
	const btVector3 uHit = ul > btScalar(0) ? entry.m_u / ul : btVector3(1, 0, 0);
	out.m_surface = e.m_center + e.m_unwhiten * uHit;
	btVector3 normal = btWhitenedNormal(e.m_whiten, uHit);
	normal.normalize(); // |W^T u| >= 1 / max(a) > 0 for |u| = 1
	const btScalar tieTolerance = nc > 1 ? btEllipsoidClothResponseDetail::kTieDistance /
											   btMax((x - q).length(), btEllipsoidClothResponseDetail::kTieDistance)
										 : btScalar(0);
	out.m_normal = btEllipsoidClothResponseDetail::creaseNormal(cache, cand, tvals, nc, entry.m_t, tieTolerance,
																out.m_surface, normal);
	out.m_placed = out.m_surface + out.m_normal * skin;
	out.m_center = e.m_center;
}

/// Makes the placed point outside every candidate: the entry point is outside the others (it is the earliest
/// entry), but in a crease the skin offset can reach into a neighbour; the offset is then shortened (bisection) to
/// the largest part that stays outside, and a surface point that rounds to inside is stepped out by a few ulps.
/// \return true with `point` and its smallest zeta over the candidates `zeta` (>= 1) if that worked; false with the
/// point reached (the caller pushes out of the union from there).
BT_ELLIPSOID_ALWAYS_INLINE bool btKeepOutsideCandidates(const btEllipsoidWorldCache &cache, const int *cand, int nc,
														const btEntryPlacement &placed, btScalar skin, btVector3 &point,
														btScalar &zeta)
{
	// The candidates cover the path box grown by the skin, which contains every point tried here.
	const btScalar *packed = cache.getPackedRecords();
	point = placed.m_placed;
	zeta = btMinZetaPacked(packed, cand, nc, placed.m_placed, 0);
	if (zeta >= btScalar(1))
		return true;
	zeta = btMinZetaPacked(packed, cand, nc, placed.m_surface, 0);
	if (zeta >= btScalar(1))
		btEllipsoidClothResponseDetail::shortenSkin(packed, cand, nc, placed, skin, point, zeta);
	else
	{
		// The surface point itself rounds to inside (skin 0, or far from the origin): step out along the normal of
		// the ellipsoid that contains it by a few ulps of the coordinates.
		point = placed.m_surface;
		zeta = btEllipsoidClothResponseDetail::nudgeOut(cache, cand, nc, point, placed.m_normal);
	}
	return zeta >= btScalar(1);
}

/// The velocity rule after a node is placed on the surface at `surfacePoint` with outward `normal`; velocities are
/// relative to the body surface, whose velocity there is `bodyVelocity`. `start` is the node's start of the substep
/// and `center` the centre of the ellipsoid it met (eq. 10). Config::m_velocityRule selects the rule.
BT_ELLIPSOID_ALWAYS_INLINE void btApplyVelocityRule(const btEllipsoidClothCollider::Config &config,
													const btVector3 &bodyVelocity, btSoftBody::Node &node,
													const btVector3 &surfacePoint, const btVector3 &normal,
													const btVector3 &start, const btVector3 &center)
{
	btVector3 vr = node.m_v - bodyVelocity;
	if (config.m_velocityRule == btEllipsoidClothCollider::PAPER_EQ10)
	{
		// Gong et al. 2018, eq. 10: v_c = v_n |c P0| / (|c P0| + |P0 p0|).
		const btScalar cp = (surfacePoint - center).length();
		const btScalar pq = (start - surfacePoint).length();
		const btScalar denom = cp + pq;
		if (denom > btScalar(0))
			vr *= cp / denom;
	}
	else
	{
		// Remove the inward normal velocity; Coulomb friction reduces the tangential part by friction * |vn|.
		const btScalar vn = vr.dot(normal);
		if (vn < btScalar(0))
		{
			btVector3 vt = vr - normal * vn;
			const btScalar vtLen = vt.length();
			const btScalar drop = btMax(config.m_friction, btScalar(0)) * (-vn);
			if (vtLen <= drop)
				vt.setValue(0, 0, 0);
			else
				vt *= (vtLen - drop) / vtLen;
			vr = vt;
		}
	}
	node.m_v = bodyVelocity + vr;
}

#endif // BT_ELLIPSOID_CLOTH_RESPONSE_H
