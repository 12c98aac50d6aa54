/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
The collider's response to a node whose path q -> x entered the union: placement at the earliest entry plus the skin
(with the crease rules) and the velocity rule. See btEllipsoidClothResponse.cpp.
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
	btVector3 m_normal;  ///< outward normal there (the normalised sum over tied entries in a crease)
	btVector3 m_placed;  ///< m_surface + skin * m_normal
	btVector3 m_center;  ///< centre of the entered ellipsoid (for eq. 10)
};

/// First-order distance of p outside ellipsoid e: (|u| - 1) / |grad |u|| with u = W (p - c) (exact for a sphere;
/// 0 inside or at the centre).
btScalar btClearance(const btEllipsoidWorldCache::Entry& e, const btVector3& p);

/// The placement for the earliest entry of the path test over the candidates cand[0, nc) with entry parameters
/// tvals (btEarliestEntry): entries within 1 micrometre of the earliest along the path are a tie (the path meets a
/// crease of the union, Gong et al. 2018 Figure 6 case 1), and the skin offset then goes along the sum of their
/// normals, so the answer does not depend on the order of the ellipsoids.
void btPlaceAtEntry(const btEllipsoidWorldCache& cache, const btPathEntry& entry, const int* cand, const btScalar* tvals,
					int nc, const btVector3& q, const btVector3& x, btScalar skin, btEntryPlacement& out);

/// Makes the placed point outside every candidate: the entry point is outside the others (it is the earliest
/// entry), but in a crease the skin offset can reach into a neighbour; the offset is then shortened (bisection) to
/// the largest part that stays outside, and a surface point that rounds to inside is stepped out by a few ulps.
/// \return true with `point` and its smallest zeta over the candidates `zeta` (>= 1) if that worked; false with the
/// point reached (the caller pushes out of the union from there).
bool btKeepOutsideCandidates(const btEllipsoidWorldCache& cache, const int* cand, int nc, const btEntryPlacement& placed,
							 btScalar skin, btVector3& point, btScalar& zeta);

/// The surfaces a placed node touches, for the velocity rule: the outward normals of the ellipsoids within a contact
/// band of its final position (the placement normal first).
struct btNodeContacts
{
	enum
	{
		kMaxContacts = 8 ///< more than 4 ellipsoids within a few millimetres of one point do not occur on fitted bodies
	};
	btVector3 m_normals[kMaxContacts];
	int m_count;
	btNodeContacts() : m_count(0) {}
	void add(const btVector3& n)
	{
		if (m_count < kMaxContacts)
			m_normals[m_count++] = n;
	}
};

/// Adds the outward normal of every candidate cand[0, nc) whose surface is within `band` metres of p (first-order
/// distance (|u| - 1) / |grad |u||, exact for spheres) to contacts.
void btAddTouchingNormals(const btEllipsoidWorldCache& cache, const int* cand, int nc, const btVector3& p, btScalar band,
						  btNodeContacts& contacts);

/// The Euclidean projection of v onto the cone {w : w . n >= 0 for every contact normal n}: the nearest velocity
/// that moves into none of the touched ellipsoids (exact in 3D: the nearest feasible one among v, its projections
/// onto each plane and onto each line where two planes meet, and 0).
btVector3 btProjectOntoContactCone(const btVector3& v, const btNodeContacts& contacts);

/// The velocity rule after a node is placed, touching the surfaces in `contacts` (at least the placement normal):
/// takes and returns the velocity relative to the body surface. `start` is the node's start of the substep,
/// `surfacePoint` the entry point and `center` the centre of the ellipsoid it met (eq. 10). `rule`
/// (Config::m_velocityRule): REMOVE_NORMAL_COULOMB projects the relative velocity onto the contact cone and reduces
/// what is left by `friction` * |removed part|; PAPER_EQ10 scales it by eq. 10, then projects it onto the cone (no
/// friction). Either way the result moves into no ellipsoid the node touches: a velocity into a second ellipsoid of
/// a crease is never kept (issue 12 item 1: it grew without bound).
btVector3 btRelativeVelocityAfterContact(btEllipsoidClothCollider::VelocityRule rule, btScalar friction,
										 const btVector3& relative, const btNodeContacts& contacts,
										 const btVector3& surfacePoint, const btVector3& start, const btVector3& center);

/// The relative velocity shortened to the node's real motion along the surface: `motion` is (final position -
/// start carried with the body) / dt, and its part tangential to `normal` bounds the result's length (a node that
/// could not slide, blocked in a crease, keeps no speed it does not have).
btVector3 btCapBySurfaceMotion(const btVector3& relative, const btVector3& normal, const btVector3& motion);

#endif // BT_ELLIPSOID_CLOTH_RESPONSE_H
