/*
bodyfit: Bullet extension for ellipsoid body colliders. See btSkinDistanceField.h (the layout) and
bullet_ext/README.md, "Tight skin surface".
*/

#include "bodyfit/bullet_ext/btSkinDistanceField.h"

#include <atomic>
#include <cmath>
#include <cstdlib>

namespace
{

bool isFiniteValue(double v) { return std::isfinite(v); }

/// Sample index of lattice point (a, b, c) in a brick.
inline int latticeIndex(int a, int b, int c)
{
	return a + btSkinDistanceField::kBrickSide * (b + btSkinDistanceField::kBrickSide * c);
}

/// The lattice point of face `side` (0: coordinate 0, 1: coordinate B) of axis `axis` at face coordinates (u, v).
inline int faceIndex(int axis, int side, int u, int v)
{
	const int w = side ? int(btSkinDistanceField::kBrickEdge) : 0;
	if (axis == 0)
		return latticeIndex(w, u, v);
	if (axis == 1)
		return latticeIndex(u, w, v);
	return latticeIndex(u, v, w);
}

/// A content id no field had before (getContentId); 2^32 set() calls before one repeats.
unsigned nextContentId()
{
	static std::atomic<unsigned> counter(0);
	return ++counter;
}

} // namespace

btSkinDistanceField::btSkinDistanceField()
{
	clear();
}

void btSkinDistanceField::clear()
{
	m_layout = btSkinFieldLayout();
	m_brickIndex.clear();
	m_samples.clear();
	m_origin.setValue(0, 0, 0);
	m_limit.setValue(0, 0, 0);
	m_h = btScalar(1);
	m_invH = btScalar(1);
	m_clamp = btScalar(m_layout.m_clamp); // an empty field reads far outside everywhere
	m_quantum = btScalar(0);
	m_gradientScale = btScalar(0);
	m_lipschitz = btScalar(1);
	m_seam = btScalar(0);
	m_dims[0] = m_dims[1] = m_dims[2] = 0;
	m_numStored = 0;
	m_contentId = nextContentId();
	m_valid = false;
}

bool btSkinDistanceField::checkLayout(const btSkinFieldLayout& layout, long long brickIndexCount,
									  long long sampleCount, const char** error) const
{
	const char* e = 0;
	const long long nx = layout.m_bricks[0], ny = layout.m_bricks[1], nz = layout.m_bricks[2];
	if (!isFiniteValue(layout.m_origin[0]) || !isFiniteValue(layout.m_origin[1]) || !isFiniteValue(layout.m_origin[2]))
		e = "btSkinDistanceField: the grid origin is not finite";
	else if (!isFiniteValue(layout.m_voxelSize) || !(layout.m_voxelSize > 0))
		e = "btSkinDistanceField: the voxel size h must be finite and > 0";
	else if (!isFiniteValue(layout.m_clamp) || !(layout.m_clamp > 0))
		e = "btSkinDistanceField: the clamp distance must be finite and > 0";
	else if (!isFiniteValue(layout.m_maxError) || layout.m_maxError < 0)
		e = "btSkinDistanceField: maxError must be finite and >= 0";
	else if (!isFiniteValue(layout.m_skinOffset) || layout.m_skinOffset < 0)
		e = "btSkinDistanceField: the bake's skin offset must be finite and >= 0";
	else if (layout.m_brickEdge != kBrickEdge)
		e = "btSkinDistanceField: the brick edge B must be 8 voxels";
	else if (nx < 1 || ny < 1 || nz < 1)
		e = "btSkinDistanceField: every brick count (nx, ny, nz) must be >= 1";
	else if (nx * ny * nz >= (1LL << 31) || nx * kBrickEdge >= (1LL << 24) || ny * kBrickEdge >= (1LL << 24) ||
			 nz * kBrickEdge >= (1LL << 24))
		e = "btSkinDistanceField: the grid is too large (2^31 bricks, 2^24 voxels per axis at most)";
	else if (!isFiniteValue(layout.m_origin[0] + layout.m_voxelSize * double(kBrickEdge) * double(nx + ny + nz)))
		e = "btSkinDistanceField: the grid's extent is not finite";
	else if (brickIndexCount != nx * ny * nz)
		e = "btSkinDistanceField: the brick index does not have nx * ny * nz entries";
	else if (sampleCount < 0 || sampleCount % kBrickSamples != 0)
		e = "btSkinDistanceField: the sample count is not a multiple of (B + 1)^3 = 729";
	else if (sampleCount / kBrickSamples >= (1LL << 31) / kBrickSamples)
		e = "btSkinDistanceField: too many stored bricks";
	if (error)
		*error = e;
	return e == 0;
}

bool btSkinDistanceField::checkIndices(const int* brickIndex, long long count, int numStored, const char** error) const
{
	for (long long i = 0; i < count; ++i)
	{
		const int s = brickIndex[i];
		if (s < kFarInside || s >= numStored)
		{
			if (error)
				*error = s < kFarInside ? "btSkinDistanceField: a brick index is below -2 (only -1 far outside and -2 "
										  "far inside are allowed)"
										: "btSkinDistanceField: a brick index points past the stored sample blocks";
			return false;
		}
	}
	return true;
}

bool btSkinDistanceField::set(const btSkinFieldLayout& layout, const int* brickIndex, long long brickIndexCount,
							  const short* samples, long long sampleCount, const char** error)
{
	const char* dummy = 0;
	const char*& e = error ? *error : dummy;
	e = 0;
	clear();
	if ((brickIndexCount > 0 && !brickIndex) || (sampleCount > 0 && !samples))
	{
		e = "btSkinDistanceField: a non-empty array is given as a null pointer";
		return false;
	}
	if (!checkLayout(layout, brickIndexCount, sampleCount, &e))
		return false;
	if (!checkIndices(brickIndex, brickIndexCount, int(sampleCount / kBrickSamples), &e))
		return false;
	adopt(layout, brickIndex, samples, sampleCount);
	m_seam = measureSeam();
	if (m_seam > btScalar(3) * m_clamp) // stored faces differ by 2 clamp at most; far-far conflicts are marked 4 clamp
	{
		clear();
		e = "btSkinDistanceField: a far-outside brick shares a face with a far-inside one";
		return false;
	}
	m_lipschitz = measureLipschitz();
	m_contentId = nextContentId();
	m_valid = true;
	return true;
}

void btSkinDistanceField::adopt(const btSkinFieldLayout& layout, const int* brickIndex, const short* samples,
								long long sampleCount)
{
	m_layout = layout;
	for (int k = 0; k < 3; ++k)
		m_dims[k] = layout.m_bricks[k];
	const int count = m_dims[0] * m_dims[1] * m_dims[2];
	m_brickIndex.resize(count);
	for (int i = 0; i < count; ++i)
		m_brickIndex[i] = brickIndex[i];
	m_samples.resize(int(sampleCount));
	for (int i = 0; i < int(sampleCount); ++i)
		m_samples[i] = samples[i] < -32767 ? short(-32767) : samples[i]; // -32768 reads as -clamp, like -32767
	m_numStored = int(sampleCount / kBrickSamples);
	m_origin.setValue(btScalar(layout.m_origin[0]), btScalar(layout.m_origin[1]), btScalar(layout.m_origin[2]));
	m_limit.setValue(btScalar(m_dims[0] * kBrickEdge), btScalar(m_dims[1] * kBrickEdge),
					 btScalar(m_dims[2] * kBrickEdge));
	m_h = btScalar(layout.m_voxelSize);
	m_invH = btScalar(1.0 / layout.m_voxelSize);
	m_clamp = btScalar(layout.m_clamp);
	m_quantum = btScalar(layout.m_clamp / 32767.0);
	m_gradientScale = btScalar(layout.m_clamp / 32767.0 / layout.m_voxelSize);
}

int btSkinDistanceField::brickAt(int i, int j, int k) const
{
	if (i < 0 || j < 0 || k < 0 || i >= m_dims[0] || j >= m_dims[1] || k >= m_dims[2])
		return kFarOutside; // off the grid: far outside
	return m_brickIndex[i + m_dims[0] * (j + m_dims[1] * k)];
}

btScalar btSkinDistanceField::measureLipschitz() const
{
	// Per cell, the largest |difference| along each axis over the cell's four edges of that axis.
	long long worstSquared = 0; // in quantum units (differences up to 65534: the squares need 64 bits)
	for (int block = 0; block < m_numStored; ++block)
	{
		const short* s = &m_samples[0] + block * kBrickSamples;
		for (int c = 0; c < kBrickEdge; ++c)
			for (int b = 0; b < kBrickEdge; ++b)
				for (int a = 0; a < kBrickEdge; ++a)
				{
					long long m[3] = {0, 0, 0};
					const int step[3] = {1, kBrickSide, kBrickSide * kBrickSide};
					for (int axis = 0; axis < 3; ++axis)
						for (int corner = 0; corner < 4; ++corner)
						{
							// The two other axes' offsets of this edge.
							const int o1 = (axis + 1) % 3, o2 = (axis + 2) % 3;
							const int base = latticeIndex(a, b, c) + ((corner & 1) ? step[o1] : 0) +
											 ((corner & 2) ? step[o2] : 0);
							const long long lo = s[base], hi = s[base + step[axis]];
							const long long d = std::llabs(hi - lo);
							m[axis] = d > m[axis] ? d : m[axis];
						}
					const long long n2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
					worstSquared = n2 > worstSquared ? n2 : worstSquared;
				}
	}
	const double slope = std::sqrt(double(worstSquared)) * (m_layout.m_clamp / 32767.0) / m_layout.m_voxelSize;
	return btScalar(slope > 1e-3 ? slope : 1e-3);
}

btScalar btSkinDistanceField::faceJump(int brick, int axis, int side) const
{
	int ijk[3] = {brick % m_dims[0], (brick / m_dims[0]) % m_dims[1], brick / (m_dims[0] * m_dims[1])};
	const int self = m_brickIndex[brick];
	ijk[axis] += side ? 1 : -1;
	const int other = brickAt(ijk[0], ijk[1], ijk[2]);
	if (self < 0 || other < 0)
	{
		// A far brick promises a bound, not values: no seam next to it (btSkinFieldGeometry steps through far-outside
		// bricks by the true distance's bound). Far outside against far inside contradicts itself: marked 4 clamp.
		return self < 0 && other < 0 && self != other ? btScalar(4) * m_clamp : btScalar(0);
	}
	const short* s = &m_samples[0] + self * kBrickSamples;
	const short* n = &m_samples[0] + other * kBrickSamples;
	btScalar jump = btScalar(0);
	for (int v = 0; v < kBrickSide; ++v)
		for (int u = 0; u < kBrickSide; ++u)
			jump = btMax(jump, btFabs(quanta(s, faceIndex(axis, side, u, v)) - quanta(n, faceIndex(axis, 1 - side, u, v))) *
								   m_quantum);
	return jump;
}

btScalar btSkinDistanceField::measureSeam() const
{
	btScalar seam = btScalar(0);
	const int count = m_dims[0] * m_dims[1] * m_dims[2];
	for (int brick = 0; brick < count; ++brick)
		for (int axis = 0; axis < 3; ++axis)
			for (int side = 0; side < 2; ++side)
				seam = btMax(seam, faceJump(brick, axis, side));
	return seam;
}
