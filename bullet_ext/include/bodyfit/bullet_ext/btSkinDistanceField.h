/*
bodyfit: Bullet extension for ellipsoid body colliders.
btSkinDistanceField: a narrow-band signed distance field of the body skin in bricks, in the body frame (the frame of
the mesh and of the compound's ellipsoids; metres), positive outside. The cloth collider's tight mode decides contact
against it inside the ellipsoid union (bullet_ext/README.md, "Tight skin surface").

Layout (shared with the bake that writes it):
 - grid origin o, voxel size h, brick edge B = 8 voxels, brick dimensions (nx, ny, nz); brick (i, j, k) covers
   [o + B h (i, j, k), o + B h (i + 1, j + 1, k + 1)];
 - brickIndex: nx ny nz values, brick (i, j, k) at i + nx (j + ny k): s >= 0 is block s of the samples, -1
   (kFarOutside) means every point of the brick is at distance >= +clamp, -2 (kFarInside) at <= -clamp; points
   outside the grid are far outside;
 - samples: (B + 1)^3 int16 per stored brick at its lattice points (a, b, c) in [0, B]^3, index a + (B+1)(b + (B+1) c),
   point o + h (B (i, j, k) + (a, b, c)); distance = value * quantum, quantum = clamp / 32767, clamped to +-clamp;
 - the field at a point is the trilinear interpolation of the 8 samples of its cell in its brick.
*/

#ifndef BT_SKIN_DISTANCE_FIELD_H
#define BT_SKIN_DISTANCE_FIELD_H

#include "bodyfit/bullet_ext/btBodyfitPrecision.h"

#include "LinearMath/btAlignedObjectArray.h"
#include "LinearMath/btVector3.h"

/// The header values of a skin field (the bake's file header).
struct btSkinFieldLayout
{
	double m_origin[3]; ///< grid origin o (body frame, metres)
	double m_voxelSize; ///< h (metres, the bake's default 0.005)
	int m_brickEdge;    ///< B: must be btSkinDistanceField::kBrickEdge (8)
	int m_bricks[3];    ///< nx, ny, nz
	double m_clamp;     ///< distances are accurate within |d| < clamp (metres, the bake's default 0.012)
	double m_maxError;  ///< max |field - true distance| over the band, measured at bake time (metres, >= 0)
	/// The skin offset the bake kept bricks for (metres, >= 0): every brick meeting the union grown by this + 2 h within
	/// the band is stored, so a far-outside point is at least min(clamp, this + 2 h) from the skin.
	double m_skinOffset;

	btSkinFieldLayout()
		: m_voxelSize(0.005), m_brickEdge(8), m_clamp(0.012), m_maxError(0), m_skinOffset(0.002)
	{
		m_origin[0] = m_origin[1] = m_origin[2] = 0;
		m_bricks[0] = m_bricks[1] = m_bricks[2] = 0;
	}
};

/// The field, copied from plain arrays and validated (set() returns false with a one-line reason for bad data; a
/// field that was never set successfully is empty: isValid() false, every point far outside).
/// distance() and gradient() are inline and allocate nothing. gradient() is the exact gradient of the trilinear
/// interpolant inside the point's cell (a one-sided limit on cell faces), normalised.
class btSkinDistanceField
{
public:
	enum
	{
		kBrickEdge = 8,                                                  ///< B
		kBrickSide = kBrickEdge + 1,                                     ///< lattice points along a brick edge
		kBrickSamples = kBrickSide * kBrickSide * kBrickSide,            ///< (B + 1)^3 = 729
		kFarOutside = -1,
		kFarInside = -2
	};

	btSkinDistanceField();

	/// Copies and checks the layout: finite header values (h > 0, clamp > 0, maxError >= 0, skin offset >= 0, B = 8, every brick
	/// count >= 1 and the grid under 2^31 bricks), brickIndexCount = nx ny nz, every index -2, -1 or a block
	/// in [0, sampleCount / 729), sampleCount a multiple of 729, and no far-outside brick sharing a face with a
	/// far-inside one (the field would jump by 2 clamp there). On failure the field is left empty and *error (if not 0)
	/// gets a static one-line reason.
	bool set(const btSkinFieldLayout& layout, const int* brickIndex, long long brickIndexCount, const short* samples,
			 long long sampleCount, const char** error = 0);

	bool isValid() const { return m_valid; }
	/// Names this field's contents: a new number (process-wide, never reused) at every set() and clear(), kept by a
	/// copy. A reading taken at a point stays valid while the id is the same (the collider keeps each node's last one).
	unsigned getContentId() const { return m_contentId; }
	const btSkinFieldLayout& getLayout() const { return m_layout; }
	int getNumStoredBricks() const { return m_numStored; }
	btScalar getClamp() const { return m_clamp; }
	btScalar getQuantum() const { return m_quantum; }
	btScalar getVoxelSize() const { return m_h; }
	btScalar getMaxError() const { return btScalar(m_layout.m_maxError); }
	btScalar getBakeSkinOffset() const { return btScalar(m_layout.m_skinOffset); }
	/// A Lipschitz bound of the interpolant inside every brick, measured at set(): the largest over stored cells of
	/// |(max_x |dx|, max_y |dy|, max_z |dz|)| / h, where d_ are the sample differences along the cell's edges (the
	/// partial derivatives of a trilinear function are bilinear blends of its edge differences, so each is bounded by
	/// the largest of its four). About 1 for a distance field, up to sqrt(3) near ridges. At least 1e-3.
	btScalar getLipschitz() const { return m_lipschitz; }
	/// The largest jump of the field across a face between two stored bricks (they disagree on their shared samples):
	/// 0 for a consistent bake. (Next to a far brick the field may jump to +-clamp: a far brick bounds the distance,
	/// it does not sample it.)
	btScalar getSeam() const { return m_seam; }
	/// Body-frame box of the grid.
	btVector3 getGridMin() const { return m_origin; }
	btVector3 getGridMax() const { return m_origin + m_limit * m_h; }

	/// The field at a body-frame point (metres): trilinear in the cell, +clamp far outside or off the grid, -clamp
	/// far inside.
	btScalar distance(const btVector3& p) const
	{
		const short* s;
		btVector3 t;
		const int where = locate(p, s, t);
		if (where != 0)
			return where == 1 ? m_clamp : -m_clamp;
		return trilinear(s, t);
	}

	/// The same, and whether p lies off the grid or in a far brick (whose +-clamp is a bound on the distance, not an
	/// interpolated sample).
	btScalar distance(const btVector3& p, bool& farBrick) const
	{
		const short* s;
		btVector3 t;
		const int where = locate(p, s, t);
		farBrick = where != 0;
		if (farBrick)
			return where == 1 ? m_clamp : -m_clamp;
		return trilinear(s, t);
	}

	/// The field and its unnormalised gradient at p (the interpolant's; zero in far bricks and off the grid).
	btScalar distanceAndGradient(const btVector3& p, btVector3& gradient) const
	{
		return distanceAndGradientBelow(p, SIMD_INFINITY, gradient); // (the field is finite: below it everywhere)
	}

	/// The field at p, and its gradient only where the field reads below `below` (else `gradient` is zero): for callers
	/// that need the slope only to come back up to a level (one cell lookup either way).
	btScalar distanceAndGradientBelow(const btVector3& p, btScalar below, btVector3& gradient) const
	{
		const short* s;
		btVector3 t;
		const int where = locate(p, s, t);
		if (where != 0)
		{
			gradient.setValue(0, 0, 0);
			return where == 1 ? m_clamp : -m_clamp;
		}
		const btScalar f = trilinear(s, t);
		if (f < below)
			gradient = trilinearGradient(s, t);
		else
			gradient.setValue(0, 0, 0);
		return f;
	}

	/// The normalised gradient of the interpolant at p, or (0, 0, 0) where it vanishes (below 1e-3 of a unit slope:
	/// far bricks, clamped samples, the centre of a symmetric body).
	btVector3 gradient(const btVector3& p) const
	{
		btVector3 g;
		distanceAndGradient(p, g);
		const btScalar len = g.length();
		return len > btScalar(1e-3) ? g / len : btVector3(0, 0, 0);
	}

private:
	btSkinFieldLayout m_layout;
	btAlignedObjectArray<int> m_brickIndex;
	btAlignedObjectArray<short> m_samples;
	btVector3 m_origin;
	btVector3 m_limit; ///< grid size in voxels (nx B, ny B, nz B)
	btScalar m_h;
	btScalar m_invH;
	btScalar m_clamp;
	btScalar m_quantum;
	btScalar m_gradientScale; ///< quantum / h: a difference of samples in quanta to a slope
	btScalar m_lipschitz;
	btScalar m_seam;
	int m_dims[3];
	int m_numStored;
	unsigned m_contentId;
	bool m_valid;

	bool checkLayout(const btSkinFieldLayout& layout, long long brickIndexCount, long long sampleCount,
					 const char** error) const;
	bool checkIndices(const int* brickIndex, long long count, int numStored, const char** error) const;
	void adopt(const btSkinFieldLayout& layout, const int* brickIndex, const short* samples, long long sampleCount);
	void clear();
	int brickAt(int i, int j, int k) const;
	btScalar measureLipschitz() const;
	btScalar measureSeam() const;
	btScalar faceJump(int brick, int axis, int side) const;

	/// 0: stored brick (s = the cell's first sample, t = position in the cell in [0, 1]^3); 1 far outside; 2 far inside.
	int locate(const btVector3& p, const short*& s, btVector3& t) const
	{
		const btVector3 f = (p - m_origin) * m_invH;
		if (!(f.x() >= btScalar(0) && f.y() >= btScalar(0) && f.z() >= btScalar(0) && f.x() < m_limit.x() &&
			  f.y() < m_limit.y() && f.z() < m_limit.z()))
			return 1;
		const int ix = int(f.x()), iy = int(f.y()), iz = int(f.z());
		const int bi = ix >> 3, bj = iy >> 3, bk = iz >> 3;
		const int block = m_brickIndex[bi + m_dims[0] * (bj + m_dims[1] * bk)];
		if (block < 0)
			return block == kFarOutside ? 1 : 2;
		s = &m_samples[0] + block * kBrickSamples + (ix & 7) + kBrickSide * ((iy & 7) + kBrickSide * (iz & 7));
		t.setValue(f.x() - btScalar(ix), f.y() - btScalar(iy), f.z() - btScalar(iz));
		return 0;
	}

	/// A sample in quanta: set() stores -32768 (the only value beyond the clamp) as -32767, so every sample is within
	/// +-clamp and the interpolants scale by the quantum once, at the end.
	btScalar quanta(const short* s, int offset) const { return btScalar(s[offset]); }

	btScalar trilinear(const short* s, const btVector3& t) const
	{
		const int dy = kBrickSide, dz = kBrickSide * kBrickSide;
		const btScalar c00 = quanta(s, 0) + (quanta(s, 1) - quanta(s, 0)) * t.x();
		const btScalar c10 = quanta(s, dy) + (quanta(s, dy + 1) - quanta(s, dy)) * t.x();
		const btScalar c01 = quanta(s, dz) + (quanta(s, dz + 1) - quanta(s, dz)) * t.x();
		const btScalar c11 = quanta(s, dz + dy) + (quanta(s, dz + dy + 1) - quanta(s, dz + dy)) * t.x();
		const btScalar c0 = c00 + (c10 - c00) * t.y();
		const btScalar c1 = c01 + (c11 - c01) * t.y();
		return (c0 + (c1 - c0) * t.z()) * m_quantum;
	}

	btVector3 trilinearGradient(const short* s, const btVector3& t) const
	{
		const int dy = kBrickSide, dz = kBrickSide * kBrickSide;
		const btScalar v000 = quanta(s, 0), v100 = quanta(s, 1), v010 = quanta(s, dy), v110 = quanta(s, dy + 1);
		const btScalar v001 = quanta(s, dz), v101 = quanta(s, dz + 1), v011 = quanta(s, dz + dy),
					   v111 = quanta(s, dz + dy + 1);
		const btScalar ux = btScalar(1) - t.x(), uy = btScalar(1) - t.y(), uz = btScalar(1) - t.z();
		const btScalar gx = uy * uz * (v100 - v000) + t.y() * uz * (v110 - v010) + uy * t.z() * (v101 - v001) +
							t.y() * t.z() * (v111 - v011);
		const btScalar gy = ux * uz * (v010 - v000) + t.x() * uz * (v110 - v100) + ux * t.z() * (v011 - v001) +
							t.x() * t.z() * (v111 - v101);
		const btScalar gz = ux * uy * (v001 - v000) + t.x() * uy * (v101 - v100) + ux * t.y() * (v011 - v010) +
							t.x() * t.y() * (v111 - v110);
		return btVector3(gx, gy, gz) * m_gradientScale;
	}
};

#endif // BT_SKIN_DISTANCE_FIELD_H
