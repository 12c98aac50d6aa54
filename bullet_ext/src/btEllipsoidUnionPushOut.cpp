/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidUnionPushOut.h.
*/

#include "src/btEllipsoidUnionPushOut.h"

#include "src/btEllipsoidNarrowPhase.h"

namespace
{

/// Push-out: at most this many steps along one ray while its rounded exit point is still inside an ellipsoid (the
/// margin doubles from 2 ulps of the coordinates, so 2^40 ulps is far past any union).
const int kMaxRealiseSteps = 40;

inline bool containsPoint(const btEllipsoidWorldCache::Entry& e, const btVector3& p)
{
	return !(p.x() > e.m_aabbMax.x() || p.x() < e.m_aabbMin.x() || p.y() > e.m_aabbMax.y() || p.y() < e.m_aabbMin.y() ||
			 p.z() > e.m_aabbMax.z() || p.z() < e.m_aabbMin.z());
}

/// Largest absolute coordinate of p plus 1 mm: the scale of the rounding tolerances along a ray from p.
inline btScalar coordinateScale(const btVector3& p)
{
	return p.absolute()[p.absolute().maxAxis()] + btScalar(1e-3);
}

} // namespace

btScalar btEllipsoidUnionPushOut::minZetaAll(const btEllipsoidWorldCache& cache, const btVector3& p, int* which)
{
	btScalar best = SIMD_INFINITY;
	int bestIndex = -1;
	for (int k = 0; k < cache.size(); ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		if (!containsPoint(e, p))
			continue;
		const btScalar z = (e.m_whiten * (p - e.m_center)).length2();
		if (z < best)
		{
			best = z;
			bestIndex = k;
		}
	}
	if (which)
		*which = bestIndex;
	return best;
}

void btEllipsoidUnionPushOut::pushOut(const btEllipsoidWorldCache& cache, const btVector3& from, btScalar skin,
									  btPushOutResult& out)
{
	m_cache = &cache;
	out.m_enclosed = false;
	out.m_fallback = false;
	out.m_ellipsoid = -1;
	btVector3 dirs[kMaxDirections];
	const int ndirs = candidateDirections(from, dirs);
	if (ndirs == 0)
	{
		// Not inside anything (the caller's tolerance): nothing to do.
		out.m_moved = false;
		out.m_point = from;
		out.m_zeta = minZetaAll(cache, from, 0);
		return;
	}
	out.m_moved = true;
	// Nominal exit of the union along every candidate direction, then the shortest that a btScalar point realises
	// and that is connected to the outside.
	btScalar nominal[kMaxDirections];
	for (int d = 0; d < ndirs; ++d)
		nominal[d] = unionExitAlongRay(from, dirs[d], skin, 0);
	btVector3 point = from;
	int bestExit = -1;
	int bestDir = bestEscapingExit(from, dirs, nominal, ndirs, skin, point, bestExit);
	if (bestDir < 0)
	{
		bestDir = shortestLastChordExit(from, dirs, ndirs, skin, point, bestExit);
		out.m_enclosed = bestDir >= 0;
	}
	if (bestDir >= 0)
	{
		finishExit(point, dirs[bestDir], bestExit, from, out);
		return;
	}
	int d0 = 0;
	for (int d = 1; d < ndirs; ++d)
		if (nominal[d] < nominal[d0])
			d0 = d;
	leaveUnionBox(from, dirs[d0], skin, point);
	out.m_fallback = true;
	finishExit(point, dirs[d0], -1, from, out);
}

btVector3 btEllipsoidUnionPushOut::latticeDirection(int d)
{
	const int i = d < 13 ? d : d + 1; // lattice index 0..26 without the centre (13)
	return btVector3(btScalar(i % 3 - 1), btScalar((i / 3) % 3 - 1), btScalar(i / 9 - 1)).normalized();
}

void btEllipsoidUnionPushOut::finishExit(const btVector3& point, const btVector3& dir, int exitEllipsoid,
										 const btVector3& from, btPushOutResult& out) const
{
	out.m_point = point;
	out.m_zeta = minZetaAll(*m_cache, point, 0);
	out.m_normal = dir;
	out.m_center = exitEllipsoid >= 0 ? (*m_cache)[exitEllipsoid].m_center : from;
	out.m_ellipsoid = exitEllipsoid;
	if (exitEllipsoid >= 0)
	{
		const btEllipsoidWorldCache::Entry& e = (*m_cache)[exitEllipsoid];
		const btVector3 g = btWhitenedNormal(e.m_whiten, e.m_whiten * (point - e.m_center));
		const btScalar gl = g.length();
		if (gl > SIMD_EPSILON)
			out.m_normal = g / gl;
	}
}

namespace
{
/// The escape test's result before anything moves: `from` kept, no ellipsoid, zeta not computed (the caller only reads
/// it after a move).
void staysInPlace(const btVector3& from, btPushOutResult& out)
{
	out.m_moved = false;
	out.m_enclosed = false;
	out.m_fallback = false;
	out.m_ellipsoid = -1;
	out.m_point = from;
	out.m_zeta = SIMD_INFINITY;
}
} // namespace

void btEllipsoidUnionPushOut::leaveEnclosedPocket(const btEllipsoidWorldCache& cache, const btVector3& from,
												  btScalar skin, btPushOutResult& out, unsigned char* hint)
{
	// The ray that left last time first (a resting node mostly leaves the same way every substep), then the rest.
	if (escapesAlongHint(cache, from, hint ? int(*hint) : int(kNoEscapeHint)))
	{
		staysInPlace(from, out);
		return;
	}
	leavePocketPastHint(cache, from, skin, out, hint);
}

void btEllipsoidUnionPushOut::leavePocketPastHint(const btEllipsoidWorldCache& cache, const btVector3& from,
												  btScalar skin, btPushOutResult& out, unsigned char* hint)
{
	m_cache = &cache;
	staysInPlace(from, out);
	// The axis rays on the bins (cheap), then the full test when all six are blocked (or the bins are not ready).
	int escaped = binsReadyFor(cache) ? someAxisRayEscapes(from) : int(kNoEscapeHint);
	int lattice = -2;
	if (escaped == kNoEscapeHint && escapesUnion(from, latticeDirection(0), &lattice))
		escaped = kLatticeHint + btMax(lattice, 0); // (the preferred direction here is lattice direction 0)
	if (hint)
		*hint = (unsigned char)escaped;
	if (escaped != kNoEscapeHint)
		return;
	btVector3 dirs[26];
	for (int d = 0; d < 26; ++d)
		dirs[d] = latticeDirection(d);
	btVector3 point;
	int exit = -1;
	const int best = shortestLastChordExit(from, dirs, 26, skin, point, exit);
	if (best < 0)
		return;
	out.m_moved = true;
	out.m_enclosed = true;
	finishExit(point, dirs[best], exit, from, out);
}

int btEllipsoidUnionPushOut::candidateDirections(const btVector3& from, btVector3* dirs) const
{
	// For each ellipsoid containing the point: its outward normal there (the direction to its nearest surface point
	// for shallow penetrations) and both directions of its three principal axes (the way out of a thin ellipsoid near
	// its mid-plane). The exit of the whole union is measured along each; the shortest wins.
	const btEllipsoidWorldCache& cache = *m_cache;
	int ndirs = 0;
	for (int k = 0; k < cache.size() && ndirs + 7 <= kMaxDirections; ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		if (!containsPoint(e, from))
			continue;
		const btVector3 u = e.m_whiten * (from - e.m_center);
		const btScalar z = u.length2();
		if (!(z < btScalar(1)))
			continue;
		const btVector3 g = btWhitenedNormal(e.m_whiten, u);
		const btScalar gl = g.length();
		if (gl > SIMD_EPSILON)
			dirs[ndirs++] = g / gl;
		for (int axis = 0; axis < 3; ++axis)
		{
			btVector3 column(e.m_unwhiten[0][axis], e.m_unwhiten[1][axis], e.m_unwhiten[2][axis]);
			column.normalize();
			dirs[ndirs++] = column;
			dirs[ndirs++] = -column;
		}
	}
	return ndirs;
}

int btEllipsoidUnionPushOut::bestEscapingExit(const btVector3& from, const btVector3* dirs, const btScalar* nominal,
											  int ndirs, btScalar skin, btVector3& out, int& bestExit)
{
	// A realised exit is never shorter than the nominal one, so directions are tried in nominal order until the next
	// nominal exit is longer than the best realised one. An exit into a pocket enclosed by the union is not an exit:
	// the node would rest outside every ellipsoid but inside the body. Only exits from which some ray escapes the
	// union are taken.
	btScalar bestS = SIMD_INFINITY;
	int bestDir = -1;
	bool tried[kMaxDirections];
	for (int d = 0; d < ndirs; ++d)
		tried[d] = false;
	for (int round = 0; round < ndirs; ++round)
	{
		int next = -1;
		for (int d = 0; d < ndirs; ++d)
			if (!tried[d] && (next < 0 || nominal[d] < nominal[next]))
				next = d;
		if (next < 0 || !(nominal[next] < bestS))
			break;
		tried[next] = true;
		btVector3 p;
		int exit = -1;
		const btScalar s = realiseExit(from, dirs[next], skin, p, &exit, false);
		if (s < bestS && escapesUnion(p, dirs[next]))
		{
			bestS = s;
			bestDir = next;
			bestExit = exit;
			out = p;
		}
	}
	return bestDir;
}

int btEllipsoidUnionPushOut::shortestLastChordExit(const btVector3& from, const btVector3* dirs, int ndirs,
												   btScalar skin, btVector3& out, int& bestExit)
{
	// Every nearest exit led into a pocket (or was not realised): leave along each ray past its last chord, which no
	// pocket can contain, and keep the shortest.
	btScalar bestS = SIMD_INFINITY;
	int bestDir = -1;
	for (int d = 0; d < ndirs; ++d)
	{
		btVector3 p;
		int exit = -1;
		const btScalar s = realiseExit(from, dirs[d], skin, p, &exit, true);
		if (s < bestS)
		{
			bestS = s;
			bestDir = d;
			bestExit = exit;
			out = p;
		}
	}
	return bestDir;
}

void btEllipsoidUnionPushOut::leaveUnionBox(const btVector3& from, const btVector3& dir, btScalar skin,
											btVector3& out) const
{
	// Safe fallback (no direction realised an exit): leave the box of the whole union along dir, grown by the skin
	// and a margin of 1e-5 of its size plus 8 ulps of the coordinates. A point outside an ellipsoid's box is outside
	// the ellipsoid (|p - c|_i > extent_i implies zeta > 1 by Cauchy-Schwarz), and the margin is far above zeta's
	// rounding error. Leaving one slab of the grown box leaves the box: the smallest slab exit (|dir| = 1, so its
	// largest component is >= 1/sqrt(3) and at least one slab is crossed).
	const btVector3 lo = m_cache->getAabbMin(), hi = m_cache->getAabbMax();
	const btScalar big = btMax(lo.absolute()[lo.absolute().maxAxis()], hi.absolute()[hi.absolute().maxAxis()]);
	const btScalar grow = skin + (hi - lo).length() * btScalar(1e-5) + SIMD_EPSILON * btScalar(8) * big;
	btScalar sBox = SIMD_INFINITY;
	for (int k = 0; k < 3; ++k)
	{
		if (dir[k] > btScalar(0.01))
			sBox = btMin(sBox, (hi[k] + grow - from[k]) / dir[k]);
		else if (dir[k] < btScalar(-0.01))
			sBox = btMin(sBox, (lo[k] - grow - from[k]) / dir[k]);
	}
	out = from + dir * btMax(sBox, btScalar(0));
}

void btEllipsoidUnionPushOut::collectRayIntervals(const btVector3& origin, const btVector3& dir, btScalar skin)
{
	// Every ellipsoid's chord along the ray, widened by the skin on both sides, sorted by start. The quadratic is set
	// up relative to each ellipsoid's centre (origin - c is exact or nearly so for nearby points, also 1 km out).
	const btEllipsoidWorldCache& cache = *m_cache;
	m_intervals.resize(0);
	m_intervalOwner.resize(0);
	// (Cheap skip: an ellipsoid lies in its world box. Along an axis the ray moves forward on, a box whose far side
	// lies more than the skin behind the origin holds only points of the line at s < -skin, whose chords are dropped
	// below; along an axis the ray keeps, a box beside the origin misses the line. A few ulps of the coordinates
	// keep rounding out of it; realiseExit checks the point it places on every ellipsoid near it anyway.)
	const btScalar tolerance = btScalar(16) * SIMD_EPSILON * coordinateScale(origin);
	btVector3 lo, hi;
	for (int a = 0; a < 3; ++a)
	{
		const btScalar reach = skin * btFabs(dir[a]) + tolerance;
		lo[a] = dir[a] > btScalar(0) ? origin[a] - reach : -SIMD_INFINITY; // the far side must reach past lo
		hi[a] = dir[a] < btScalar(0) ? origin[a] + reach : SIMD_INFINITY;  // the near side must stay below hi
		if (dir[a] == btScalar(0))
			lo[a] = origin[a] - tolerance, hi[a] = origin[a] + tolerance;
	}
	for (int k = 0; k < cache.size(); ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		if (e.m_aabbMax.x() < lo.x() || e.m_aabbMax.y() < lo.y() || e.m_aabbMax.z() < lo.z() ||
			e.m_aabbMin.x() > hi.x() || e.m_aabbMin.y() > hi.y() || e.m_aabbMin.z() > hi.z())
			continue;
		const btUnitBallQuadratic quadratic =
			btUnitBallQuadratic::ofLine(e.m_whiten * (origin - e.m_center), e.m_whiten * dir);
		if (!(quadratic.m_a > btScalar(0)))
			continue;
		const btScalar disc = quadratic.discriminant();
		if (disc < btScalar(0))
			continue;
		btScalar s0, s1;
		quadratic.roots(disc, s0, s1);
		if (s1 + skin < btScalar(0))
			continue;
		m_intervals.push_back(s0 - skin);
		m_intervals.push_back(s1 + skin);
		m_intervalOwner.push_back(k);
	}
	const int count = m_intervalOwner.size();
	// Insertion sort by start (few intervals).
	for (int i = 1; i < count; ++i)
	{
		const btScalar s0 = m_intervals[2 * i], s1 = m_intervals[2 * i + 1];
		const int owner = m_intervalOwner[i];
		int j = i - 1;
		while (j >= 0 && m_intervals[2 * j] > s0)
		{
			m_intervals[2 * j + 2] = m_intervals[2 * j];
			m_intervals[2 * j + 3] = m_intervals[2 * j + 1];
			m_intervalOwner[j + 1] = m_intervalOwner[j];
			--j;
		}
		m_intervals[2 * j + 2] = s0;
		m_intervals[2 * j + 3] = s1;
		m_intervalOwner[j + 1] = owner;
	}
}

btScalar btEllipsoidUnionPushOut::firstUncovered(btScalar from, btScalar scale, int* exitEllipsoid) const
{
	// Sweep over the sorted intervals: the first parameter s >= from that no interval covers. Intervals that start
	// within a few ulps of the current s count as overlapping: two ellipsoids that touch share a boundary point, and
	// stopping there would leave the node on (rounding: inside) the second one.
	const int count = m_intervalOwner.size();
	btScalar s = from;
	int exit = -1;
	for (int i = 0; i < count; ++i)
	{
		if (m_intervals[2 * i] > s + SIMD_EPSILON * btScalar(8) * (scale + btFabs(s)))
			break;
		if (m_intervals[2 * i + 1] > s)
		{
			s = m_intervals[2 * i + 1];
			exit = m_intervalOwner[i];
		}
	}
	if (exitEllipsoid)
		*exitEllipsoid = exit;
	return s;
}

btScalar btEllipsoidUnionPushOut::unionExitAlongRay(const btVector3& origin, const btVector3& dir, btScalar skin,
													int* exitEllipsoid)
{
	collectRayIntervals(origin, dir, skin);
	return firstUncovered(btScalar(0), coordinateScale(origin), exitEllipsoid);
}

btScalar btEllipsoidUnionPushOut::realiseExit(const btVector3& origin, const btVector3& dir, btScalar skin,
											  btVector3& out, int* exitEllipsoid, bool lastExit)
{
	// The exact union exit s along the ray is a real number; the node needs a btScalar point. Rounding
	// origin + dir * s to the coordinate grid (6e-5 m at 1 km in float) can land a hair inside the ellipsoid the ray
	// leaves, or, where the exit sits on a crease or a touching point, inside the neighbour. The point is therefore
	// checked with the same zeta evaluation as the guarantee, against every ellipsoid near it; while one contains it,
	// the parameter moves on along the same ray, past that ellipsoid's chord (and then to the next uncovered
	// parameter of the union), by a margin that starts at 2 ulps of the coordinates and doubles. s only grows, so
	// this cannot oscillate between two ellipsoids (stepping along surface normals did: in a crease the normal of
	// one points into the other). Past the last chord every point of the ray is outside the union in exact
	// arithmetic, and the doubling margin outgrows the rounding, so the loop ends outside; kMaxRealiseSteps bounds it.
	collectRayIntervals(origin, dir, skin);
	const btScalar scale = coordinateScale(origin);
	int exit = -1;
	// With lastExit, start past the last chord along the ray (the end of the ray is then free of the union, so the
	// point cannot be in a pocket the union encloses); otherwise at the first uncovered parameter.
	btScalar start = btScalar(0);
	if (lastExit)
		for (int i = 0; i < m_intervalOwner.size(); ++i)
			if (m_intervals[2 * i + 1] > start)
			{
				start = m_intervals[2 * i + 1];
				exit = m_intervalOwner[i];
			}
	int firstExit = -1;
	btScalar s = firstUncovered(start, scale, &firstExit);
	if (firstExit >= 0)
		exit = firstExit;
	btScalar margin = SIMD_EPSILON * btScalar(2) * (scale + btFabs(s));
	btScalar z = SIMD_INFINITY;
	for (int attempt = 0; attempt < kMaxRealiseSteps; ++attempt)
	{
		out = origin + dir * s;
		int worst = -1;
		z = minZetaAll(*m_cache, out, &worst);
		if (z >= btScalar(1))
			break;
		btScalar next = s + margin;
		for (int i = 0; i < m_intervalOwner.size(); ++i)
			if (m_intervalOwner[i] == worst)
				next = btMax(next, m_intervals[2 * i + 1] + margin);
		int nextExit = -1;
		s = firstUncovered(next, scale, &nextExit);
		if (nextExit >= 0)
			exit = nextExit;
		else if (exit < 0)
			exit = worst;
		margin *= btScalar(2);
	}
	if (exitEllipsoid)
		*exitEllipsoid = exit;
	return z >= btScalar(1) ? s : SIMD_INFINITY;
}

bool btEllipsoidUnionPushOut::escapesUnion(const btVector3& p, const btVector3& preferred, int* escaped) const
{
	// A point outside every ellipsoid can still sit in a pocket that the union encloses (fitted bodies have them
	// under the skin, where neighbouring ellipsoids meet near the surface but not deeper in). Such a point is not
	// reachable from outside. It is certainly not in a pocket if some ray from it misses the union: try the
	// preferred direction, then the 26 directions of the 3x3x3 lattice. A ray is blocked when the far root of an
	// ellipsoid's quadratic lies ahead; the quadratic is set up relative to each centre.
	for (int d = -1; d < 26; ++d)
		if (rayEscapes(p, d >= 0 ? latticeDirection(d) : preferred))
		{
			if (escaped)
				*escaped = d;
			return true;
		}
	return false;
}

namespace
{
/// The ellipsoid meets the ray p + s dir, s > 0 (given as W dir, dir's image in its whitened coordinates): the far
/// root of the line's quadratic lies ahead. The quadratic is set up relative to the centre.
bool blocksRay(const btEllipsoidWorldCache::Entry& e, const btVector3& p, const btVector3& whitenedDir)
{
	const btUnitBallQuadratic quadratic = btUnitBallQuadratic::ofLine(e.m_whiten * (p - e.m_center), whitenedDir);
	const btScalar disc = quadratic.discriminant();
	if (!(quadratic.m_a > btScalar(0)) || disc < btScalar(0))
		return false;
	return quadratic.exitAhead(disc);
}
} // namespace

bool btEllipsoidUnionPushOut::rayEscapes(const btVector3& p, const btVector3& dir) const
{
	// (Cheap skip, not needed for soundness, as in axisRayEscapes: an ellipsoid lies in its world box, and a box that
	// lies behind p along an axis the ray moves forward on, or beside p along an axis it keeps, cannot meet the ray.
	// Most of the 26 lattice rays keep one or two coordinates.)
	const btEllipsoidWorldCache& cache = *m_cache;
	for (int k = 0; k < cache.size(); ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		bool behind = false;
		for (int a = 0; a < 3; ++a)
			behind = behind || (dir[a] >= btScalar(0) && e.m_aabbMax[a] < p[a]) ||
					 (dir[a] <= btScalar(0) && e.m_aabbMin[a] > p[a]);
		if (!behind && blocksRay(e, p, e.m_whiten * dir))
			return false;
	}
	return true;
}

bool btEllipsoidUnionPushOut::escapesAlongHint(const btEllipsoidWorldCache& cache, const btVector3& from, int hint)
{
	if (!(binsReadyFor(cache) || hint >= kLatticeHint))
		return false;
	m_cache = &cache;
	return hintedRayEscapes(hint, from);
}

bool btEllipsoidUnionPushOut::hintedRayEscapes(int hint, const btVector3& p) const
{
	if (hint >= kLatticeHint && hint < kLatticeHint + 26)
		return rayEscapes(p, latticeDirection(hint - kLatticeHint));
	if (hint < 1 || hint > 6)
		return false;
	return axisRayEscapes((hint - 1) / 2, (hint - 1) % 2 ? -1 : 1, p);
}

void btEllipsoidUnionPushOut::prepareEscapeRays(const btEllipsoidWorldCache& cache)
{
	m_cache = &cache;
	for (int axis = 0; axis < 3; ++axis)
		buildAxisBins(axis);
	m_escapeRaysCache = &cache;
	m_escapeRaysCount = cache.size();
}

void btEllipsoidUnionPushOut::buildAxisBins(int axis)
{
	// Square bins, kEscapeBinsLongestSide along the longer of the two other sides of the union box; every ellipsoid
	// is listed in each bin its world box meets (CSR: count, prefix sums, fill).
	const btEllipsoidWorldCache& cache = *m_cache;
	AxisBins& bins = m_axisBins[axis];
	const btVector3 lo = cache.getAabbMin(), hi = cache.getAabbMax();
	bins.m_axes[0] = (axis + 1) % 3;
	bins.m_axes[1] = (axis + 2) % 3;
	const btScalar extent[2] = {hi[bins.m_axes[0]] - lo[bins.m_axes[0]], hi[bins.m_axes[1]] - lo[bins.m_axes[1]]};
	const btScalar longest = btMax(extent[0], extent[1]);
	const btScalar size = longest > btScalar(0) ? longest / btScalar(kEscapeBinsLongestSide) : btScalar(1);
	bins.m_invBin = btScalar(1) / size;
	for (int i = 0; i < 2; ++i)
	{
		bins.m_lo[i] = lo[bins.m_axes[i]];
		bins.m_dims[i] = btMax(1, btMin(int(kEscapeBinsLongestSide), int(extent[i] * bins.m_invBin) + 1));
	}
	const int nbins = bins.m_dims[0] * bins.m_dims[1];
	const int n = cache.size();
	// Each ellipsoid's range of bins once (four ints: i0, i1, j0, j1), then count, prefix sums and fill.
	m_binRanges.resize(4 * n);
	int* range = n > 0 ? &m_binRanges[0] : 0;
	for (int k = 0; k < n; ++k)
	{
		const btEllipsoidWorldCache::Entry& e = cache[k];
		range[4 * k] = bins.binCoord(e.m_aabbMin[bins.m_axes[0]], 0);
		range[4 * k + 1] = bins.binCoord(e.m_aabbMax[bins.m_axes[0]], 0);
		range[4 * k + 2] = bins.binCoord(e.m_aabbMin[bins.m_axes[1]], 1);
		range[4 * k + 3] = bins.binCoord(e.m_aabbMax[bins.m_axes[1]], 1);
	}
	bins.m_start.resize(nbins + 1);
	int* start = &bins.m_start[0];
	for (int b = 0; b <= nbins; ++b)
		start[b] = 0;
	const int dimX = bins.m_dims[0];
	for (int k = 0; k < n; ++k)
		for (int j = range[4 * k + 2]; j <= range[4 * k + 3]; ++j)
			for (int i = range[4 * k]; i <= range[4 * k + 1]; ++i)
				++start[j * dimX + i + 1];
	for (int b = 0; b < nbins; ++b)
		start[b + 1] += start[b];
	bins.m_items.resizeNoInitialize(start[nbins]);
	m_binFill.resizeNoInitialize(nbins);
	int* fill = &m_binFill[0];
	for (int b = 0; b < nbins; ++b)
		fill[b] = start[b];
	int* items = start[nbins] > 0 ? &bins.m_items[0] : 0;
	for (int k = 0; k < n; ++k)
		for (int j = range[4 * k + 2]; j <= range[4 * k + 3]; ++j)
			for (int i = range[4 * k]; i <= range[4 * k + 1]; ++i)
				items[fill[j * dimX + i]++] = k;
}

int btEllipsoidUnionPushOut::axisRaysEscape(int axis, const btVector3& p) const
{
	// The two rays p + s e_k and p - s e_k (s > 0) at once. An ellipsoid lies in its world box, so only one whose box
	// holds p's two other coordinates can meet the line, and every such ellipsoid is listed in p's bin (the box meets
	// the bin). For each listed one the line's quadratic (as escapesUnion sets it up; W e_k is column k of W): the +
	// ray is blocked when the far root lies ahead, the - ray when the near root lies behind. A ray blocked by no
	// listed ellipsoid is blocked by none: it leaves the union, so p is connected to the outside.
	const btEllipsoidWorldCache& cache = *m_cache;
	const AxisBins& bins = m_axisBins[axis];
	const int b = bins.binCoord(p[bins.m_axes[1]], 1) * bins.m_dims[0] + bins.binCoord(p[bins.m_axes[0]], 0);
	bool plusBlocked = false, minusBlocked = false;
	for (int i = bins.m_start[b]; i < bins.m_start[b + 1]; ++i)
	{
		const btEllipsoidWorldCache::Entry& e = cache[bins.m_items[i]];
		// (Cheap skips, not needed for soundness: the box misses the line, or lies only on an already blocked side.)
		const int a0 = bins.m_axes[0], a1 = bins.m_axes[1];
		if (p[a0] < e.m_aabbMin[a0] || p[a0] > e.m_aabbMax[a0] || p[a1] < e.m_aabbMin[a1] || p[a1] > e.m_aabbMax[a1])
			continue;
		if ((plusBlocked || e.m_aabbMax[axis] < p[axis]) && (minusBlocked || e.m_aabbMin[axis] > p[axis]))
			continue;
		const btVector3 d(e.m_whiten[0][axis], e.m_whiten[1][axis], e.m_whiten[2][axis]);
		const btUnitBallQuadratic quadratic = btUnitBallQuadratic::ofLine(e.m_whiten * (p - e.m_center), d);
		const btScalar disc = quadratic.discriminant();
		if (!(quadratic.m_a > btScalar(0)) || disc < btScalar(0))
			continue;
		plusBlocked = plusBlocked || quadratic.exitAhead(disc);
		minusBlocked = minusBlocked || btSqrt(disc) + quadratic.m_b > btScalar(0); // exitAhead of the reversed line
		if (plusBlocked && minusBlocked)
			return 0;
	}
	return plusBlocked ? -1 : 1;
}

bool btEllipsoidUnionPushOut::axisRayEscapes(int axis, int sign, const btVector3& p) const
{
	// One side of axisRaysEscape: the ray p + s sign e_k, s > 0.
	const btEllipsoidWorldCache& cache = *m_cache;
	const AxisBins& bins = m_axisBins[axis];
	const int b = bins.binCoord(p[bins.m_axes[1]], 1) * bins.m_dims[0] + bins.binCoord(p[bins.m_axes[0]], 0);
	const int a0 = bins.m_axes[0], a1 = bins.m_axes[1];
	for (int i = bins.m_start[b]; i < bins.m_start[b + 1]; ++i)
	{
		const btEllipsoidWorldCache::Entry& e = cache[bins.m_items[i]];
		if (p[a0] < e.m_aabbMin[a0] || p[a0] > e.m_aabbMax[a0] || p[a1] < e.m_aabbMin[a1] || p[a1] > e.m_aabbMax[a1])
			continue;
		if (sign > 0 ? e.m_aabbMax[axis] < p[axis] : e.m_aabbMin[axis] > p[axis])
			continue; // (the box lies behind the ray)
		const btVector3 d(e.m_whiten[0][axis], e.m_whiten[1][axis], e.m_whiten[2][axis]);
		if (blocksRay(e, p, sign > 0 ? d : -d))
			return false;
	}
	return true;
}

int btEllipsoidUnionPushOut::someAxisRayEscapes(const btVector3& p) const
{
	// The cheap part of the escape test: the six axis rays on the bins, the axis whose nearer face of the union box
	// is closest to p first (the way out of a point on the body's surface is mostly towards its nearest side).
	// Sound: a ray that leaves the union proves p is not in an enclosed void (see axisRaysEscape); when all six are
	// blocked the full test of escapesUnion decides.
	const btVector3 lo = m_cache->getAabbMin(), hi = m_cache->getAabbMax();
	btScalar gap[3];
	for (int k = 0; k < 3; ++k)
		gap[k] = btMin(p[k] - lo[k], hi[k] - p[k]);
	int order[3] = {0, 1, 2};
	for (int i = 1; i < 3; ++i)
		for (int j = i; j > 0 && gap[order[j]] < gap[order[j - 1]]; --j)
			btSwap(order[j], order[j - 1]);
	for (int i = 0; i < 3; ++i)
		if (const int side = axisRaysEscape(order[i], p))
			return 1 + 2 * order[i] + (side < 0 ? 1 : 0);
	return kNoEscapeHint;
}
