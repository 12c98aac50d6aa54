/*
bodyfit: Bullet extension for ellipsoid body colliders. Private to bodyfit::bullet_ext (not installed).
The collider's tight mode: inside the ellipsoid union (the broad phase), contact is decided on the body's skin
distance field. This header: the geometry on the field (path march, push-out, slide), in the body frame. The node
response that uses it is btEllipsoidClothColliderCore::collideOnSkin (btSkinFieldResponse.cpp).
*/

#ifndef BT_SKIN_FIELD_RESPONSE_H
#define BT_SKIN_FIELD_RESPONSE_H

#include "LinearMath/btTransform.h"

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btSkinDistanceField.h"

/// Where a node's path q -> x meets the level set field = skin offset.
struct btSkinPathHit
{
	enum Outcome
	{
		CLEAR = 0,        ///< the path stays at field >= offset: no contact
		HIT = 1,          ///< the first point at the offset level (within the hit band above it) is m_point
		START_INSIDE = 2  ///< field(q) < offset - tolerance: the node starts within the skin
	};
	int m_outcome;
	btScalar m_t;       ///< fraction of the path at m_point
	btVector3 m_point;  ///< body frame
	btVector3 m_normal; ///< HIT at the start: the field's unit normal there (body frame), else zero (not computed)
	btScalar m_value;      ///< the field at m_point (CLEAR: at x)
	btScalar m_startValue; ///< the field at q
	bool m_limited;     ///< the march ran out of steps: m_point is the last point known to be outside
};

/// The field at the two ends of a node's path (body frame), read once (btEllipsoidClothColliderCore::skinEnds): the
/// edge lift's level test and the march both need them. m_farQ / m_farX: the end lies off the grid or in a far brick
/// (btSkinDistanceField::distance).
struct btSkinPathEnds
{
	btScalar m_fq, m_fx;
	bool m_farQ, m_farX;
};

/// The field for one substep with everything the tight response needs, in the body frame.
class btSkinFieldGeometry
{
public:
	btSkinFieldGeometry()
		: m_field(0), m_offset(0), m_invLipschitz(1), m_margin(0), m_hitBand(0), m_contactBand(0), m_farStep(0), m_tolerance(0),
		  m_toBody(btTransform::getIdentity()), m_toWorld(btTransform::getIdentity())
	{
	}

	/// Prepares for a field (0: tight mode off) and a skin offset; bodyToWorld is the body pose of the substep.
	void begin(const btSkinDistanceField* field, btScalar offset, const btTransform& bodyToWorld);
	const btSkinDistanceField* field() const { return m_field; }
	btScalar offset() const { return m_offset; }
	btScalar margin() const { return m_margin; }
	btScalar tolerance() const { return m_tolerance; }
	btScalar contactBand() const { return m_contactBand; }
	const btTransform& toBody() const { return m_toBody; }
	const btTransform& toWorld() const { return m_toWorld; }
	/// The highest a node's level may stand above offset(): 3 offsets (the sag of a 5 cm edge over skin of radius
	/// 5 cm is 6 mm; an edge that asks more spans something narrower than itself, an ear or a finger, which no rise of
	/// its nodes clears), and never within an offset of the clamp (where the field stops measuring distance).
	btScalar maxRise() const
	{
		return btMax(btScalar(0), btMin(btScalar(3) * m_offset, m_field->getClamp() - btScalar(2) * m_offset));
	}

	/// Every query below works on one node's level: the field value it rests at, offset() plus the rise its edges
	/// asked (Config::m_liftEdges; btEllipsoidClothColliderCore::liftEdgesOffSkin), never below offset().
	/// The path q -> x (body frame) against the level set field = level, by sphere tracing (see the .cpp); `ends` is
	/// the field at q and x.
	void march(const btVector3& q, const btVector3& x, const btSkinPathEnds& ends, btScalar level,
			   btSkinPathHit& out) const;
	/// Newton steps on field = level along the gradient from p (body frame). \return true with the point at
	/// field in [level + seam, level + seam + hit band] and its field value; false where the gradient vanishes or
	/// it does not converge.
	bool pushOut(const btVector3& p, btScalar level, btVector3& out, btScalar& value) const;
	/// Moves from `from` (field >= level) by `displacement` along the surface: pieces short enough that none can
	/// cross the field's zero level, each brought back to the level; stops where that fails. Body frame.
	/// `value` (the field at `from` on entry) becomes the field at the returned point.
	btVector3 slide(const btVector3& from, const btVector3& displacement, btScalar level, btScalar& value) const;
	/// The outward unit normal (body frame) at p, or zero where the gradient vanishes.
	btVector3 normal(const btVector3& p) const { return m_field->gradient(p); }

private:
	const btSkinDistanceField* m_field;
	btScalar m_offset;
	btScalar m_invLipschitz; ///< 1 / the field's Lipschitz bound
	btScalar m_margin;       ///< the field's seam: the march keeps this much above the offset
	btScalar m_hitBand;      ///< the march stops this close above the offset level
	btScalar m_contactBand;  ///< a path that stays this close above the level for a few steps grazes it: contact
	btScalar m_farStep;      ///< the step from a point where the field reads +clamp (far brick, saturated, off the grid)
	btScalar m_tolerance;    ///< below the offset that still counts as on the surface
	btTransform m_toBody;
	btTransform m_toWorld;

	/// pushOut from a point where the field f and its gradient are known.
	bool newton(const btVector3& p, btScalar f, const btVector3& gradient, btScalar level, btVector3& out,
				btScalar& value) const;
	/// How far the march may step from a point where the field is f (farBrick: off the grid or in a far brick)
	/// without passing the level field = level (see the .cpp); `clear` gets the clearance the hit test compares with
	/// the hit band. Where the field reads +clamp the far step bounds the step (it shrinks by what the level stands
	/// above the offset: it bounds the distance to the offset level); in a stored brick the field's own clearance
	/// over L does too, and the larger of the two holds.
	btScalar stepFrom(btScalar f, bool farBrick, btScalar level, btScalar& clear) const
	{
		if (f >= m_field->getClamp())
		{
			const btScalar far = btMax(btScalar(0), m_farStep - (level - m_offset));
			clear = farBrick ? far : btMax(far, f - level - m_margin);
			return farBrick ? far : btMax(far, (f - level - m_margin) * m_invLipschitz);
		}
		clear = f - level - m_margin;
		return clear * m_invLipschitz;
	}
	/// The march ended at s = 0 with field(q) at the level: leaving (or moving along) the surface is not a contact.
	/// fx is the field at x; `normal` gets the unit normal at q (zero where the gradient vanishes).
	bool leavesSurface(const btVector3& q, const btVector3& x, btScalar fx, btScalar level, btVector3& normal) const;
};

/// Why `config` cannot run in TIGHT_SKIN mode on the compound's skin field (a skin offset the field cannot
/// represent: at or above half its clamp distance), or 0 (also when there is no field or the mode is ELLIPSOIDS).
const char* btSkinFieldConfigError(const btEllipsoidClothCollider::Config& config, const btEllipsoidCompoundShape* compound);

#endif // BT_SKIN_FIELD_RESPONSE_H
