/*
bodyfit: Bullet extension for ellipsoid body colliders. See btEllipsoidSweep.h.

The swept broad phase and its bound. Over the substep (s from 0 to 1) ellipsoid j's frame is taken as linearly
interpolated, c(s) = c0 + s dc, U(s) = U0 + s dU (dc = c1 - c0, dU = U1 - U0), and the node's whitened position as the
straight segment u(s) = u_q + s du (u_q = W0 (q - c0), u_x = W1 (x - c1), du = u_x - u_q): the moving-frame test asks
whether |u(s)| <= 1 for some s. The world point p(s) = c(s) + U(s) u(s) starts at q and ends at x, and expanding it,
	p(s) - (q + s (x - q)) = -s (1 - s) dU du,
so it deviates from the straight path q -> x by at most |dU|_2 |du| / 4. At a hit (|u(s*)| <= 1), p(s*) is also a
convex combination (1 - s*) (c0 + U0 u) + s* (c1 + U1 u) of a point of the previous and one of the current ellipsoid,
so it lies in the box hull of their boxes (the swept box). |du| is bounded at the hit: writing u_q = u* - s* du and
u_x = u* + (1 - s*) du gives x - q = dc + dU u* + U(1 - s*) du, so
	|du| <= (|x - q| + |dc| + |dU|_2) / sigma_min(U(1 - s*)),
and sigma_min(U(sigma)) >= max(a0min - sigma |dU|_2, a1min - (1 - sigma) |dU|_2) >= m = (a0min + a1min - |dU|_2) / 2
(a0min, a1min: the smallest semi-axes). Hence, whenever m > 0, every hit point lies in the swept box and within
	delta_j = k_j (|x - q| + e_j),  k_j = |dU|_2 / (4 m),  e_j = |dc| + |dU|_2
of the straight path: the path box grown by delta_j (plus the skin radius) overlaps the swept box. |dU|_2 is bounded by
the Frobenius norm. The query grows every path by K (|x - q| + E), K = max k_j and E = max e_j over the ellipsoids, so
it is conservative for every path q -> x of any length; an ellipsoid with m <= 0 (a rotation or a change of shape so
large in one substep that the interpolated frame can collapse, e.g. a 5 mm thin disc turned by more than ~4 degrees
per substep around a 15 cm axis) has no such bound and is listed for every path (m_always). Up to rounding: boxes
are rasterised with 1e-3 cell of slack and the growth is rounded up by 1e-5 of itself.
*/

#include "src/btEllipsoidSweep.h"

#include "src/btEllipsoidNarrowPhase.h"
#include "src/btBoxSelect.h"

namespace
{

/// Grid cells list the swept boxes meeting the cell grown by this fraction of a cell on every side; a path box that
/// fits in its midpoint's grown cell reads one list (as the static grid, btEllipsoidCompoundShape.cpp).
const btScalar kDilation = btScalar(0.25);

/// Rasterisation slack (cells): rounding of the cell coordinates.
const btScalar kCellSlack = btScalar(1e-3);

btScalar frobenius(const btMatrix3x3& m)
{
	return btSqrt(m[0].length2() + m[1].length2() + m[2].length2());
}

btScalar smallestColumn(const btMatrix3x3& m)
{
	return btMin(btMin(m.getColumn(0).length(), m.getColumn(1).length()), m.getColumn(2).length());
}

bool boxesOverlap(const btVector3& aMin, const btVector3& aMax, const btVector3& bMin, const btVector3& bMax)
{
	return !(aMin.x() > bMax.x() || aMax.x() < bMin.x() || aMin.y() > bMax.y() || aMax.y() < bMin.y() ||
			 aMin.z() > bMax.z() || aMax.z() < bMin.z());
}

int clampCell(btScalar f, int dim)
{
	return int(btMin(btMax(f, btScalar(0)), btScalar(dim - 1)));
}

/// A rotational symmetry of the unit cube (a signed permutation with determinant +1): column k of the matrix has
/// its one non-zero entry m_sign[k] in row m_row[k].
struct btAxisSymmetry
{
	int m_row[3];
	btScalar m_sign[3];
};

/// The 24 symmetries, identity first.
struct btAxisSymmetries
{
	btAxisSymmetry m_all[24];

	btAxisSymmetries()
	{
		const int perms[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {1, 0, 2}, {0, 2, 1}, {2, 1, 0}};
		int n = 0;
		for (int p = 0; p < 6; ++p)
			for (int signs = 0; signs < 8; ++signs)
			{
				btAxisSymmetry s;
				btScalar det = p < 3 ? btScalar(1) : btScalar(-1); // even / odd permutation
				for (int k = 0; k < 3; ++k)
				{
					s.m_row[k] = perms[p][k];
					s.m_sign[k] = (signs >> k) & 1 ? btScalar(-1) : btScalar(1);
					det *= s.m_sign[k];
				}
				if (det > btScalar(0))
					m_all[n++] = s;
			}
	}
};

/// The table, made once on first use. A function-local static is initialised exactly once even when worlds in
/// several threads build their sweeps at the same time (C++11); the flag it replaced was a data race.
const btAxisSymmetry* axisSymmetries()
{
	static const btAxisSymmetries table;
	return table.m_all;
}

} // namespace

btEllipsoidSweep::btEllipsoidSweep()
	: m_growthPerLength(0), m_growthOffset(0), m_origin(0, 0, 0), m_unionMax(0, 0, 0), m_invCell(1), m_listsBuilt(true),
	  m_testedQueries(0)
{
	m_dims[0] = m_dims[1] = m_dims[2] = 0;
}

void btEllipsoidSweep::capture(const btEllipsoidWorldCache& previous)
{
	const int n = previous.size();
	const int stride = btEllipsoidWorldCache::kPackedStride;
	m_previous.resize(stride * btMax(n, 1));
	m_previousUnwhiten.resize(n);
	const btScalar* packed = previous.getPackedRecords();
	for (int i = 0; i < stride * n; ++i)
		m_previous[i] = packed[i];
	for (int j = 0; j < n; ++j)
		m_previousUnwhiten[j] = previous[j].m_unwhiten;
}

bool btEllipsoidSweep::prepare(const btEllipsoidWorldCache& current)
{
	const int n = current.size();
	const int stride = btEllipsoidWorldCache::kPackedStride;
	const btScalar* packed = current.getPackedRecords();
	bool moved = false;
	for (int i = 0; i < stride * n && !moved; ++i)
		moved = packed[i] != m_previous[i];
	if (!moved)
		return false;
	for (int j = 0; j < n; ++j)
		alignPreviousFrame(current[j], j);
	m_boxes.resize(2 * n);
	m_always.resize(0);
	m_growthPerLength = btScalar(0);
	m_growthOffset = btScalar(0);
	for (int j = 0; j < n; ++j)
	{
		btScalar k = btScalar(0), e = btScalar(0);
		if (!sweptBox(current, j, k, e))
		{
			m_always.push_back(j);
			continue;
		}
		m_growthPerLength = btMax(m_growthPerLength, k);
		m_growthOffset = btMax(m_growthOffset, e);
	}
	sizeGrid(n);
	return true;
}

bool btEllipsoidSweep::keepsFrame(const btMatrix3x3& m)
{
	// The search below keeps S = I (the first of the 24, kept on ties) whenever every other trace is smaller. Each
	// term of trace(S^T m) is sign_k m[row_k][k] <= |m[row_k][k]|, so when every diagonal element exceeds the others
	// of its column by delta_k > 0, trace(m) - trace(S^T m) >= min_k delta_k for every S != I. The traces are three-
	// term sums rounded to btScalar, each within 2 ulps of trace(m) (>= every |term|): a gap above 8 epsilons of
	// trace(m) survives the rounding, so the search would give S = I bit for bit. The common case (an ellipsoid that
	// turned by much less than 45 degrees in a substep, handed over in the same frame) skips the 24 traces.
	const btScalar trace = m[0][0] + m[1][1] + m[2][2];
	btScalar gap = SIMD_INFINITY;
	for (int k = 0; k < 3; ++k)
	{
		const btScalar other = btMax(btFabs(m[(k + 1) % 3][k]), btFabs(m[(k + 2) % 3][k]));
		gap = btMin(gap, m[k][k] - other);
	}
	return gap > btScalar(8) * SIMD_EPSILON * trace; // (false for NaN)
}

void btEllipsoidSweep::alignPreviousFrame(const btEllipsoidWorldCache::Entry& now, int j)
{
	// The ball is symmetric, so an ellipsoid has many frames: U and U S for every orthogonal S. A driver that builds
	// each pose from an SVD (skinned_fit.h's transformEllipsoid, the compound's re-orthonormalisation) can hand over
	// the same ellipsoid with two axes swapped or two signs flipped, and the frames' difference would read as a half
	// turn: starts carried by it land across the body. Of the previous frame's 24 axis symmetries S, the one closest
	// to the current frame (largest trace(S^T U0^T U1), i.e. smallest |U0 S - U1|_F) is kept; S = I for any motion
	// that turns the ellipsoid by less than 45 degrees in a substep.
	btMatrix3x3& u0 = m_previousUnwhiten[j];
	const btMatrix3x3 m = u0.transpose() * now.m_unwhiten;
	if (keepsFrame(m))
		return;
	const btAxisSymmetry* sym = axisSymmetries();
	int best = 0;
	btScalar bestTrace = -SIMD_INFINITY;
	for (int i = 0; i < 24; ++i)
	{
		const btAxisSymmetry& s = sym[i];
		const btScalar trace =
			s.m_sign[0] * m[s.m_row[0]][0] + s.m_sign[1] * m[s.m_row[1]][1] + s.m_sign[2] * m[s.m_row[2]][2];
		if (trace > bestTrace)
			bestTrace = trace, best = i;
	}
	if (best == 0)
		return;
	// U0' = U0 S (column k of U0' is sign_k times column row_k of U0); W0' = S^T W0 (row k is sign_k times row
	// row_k of W0). The packed record keeps W0 by columns: element (r, c) at 4 + 4 c + r.
	const btAxisSymmetry& s = sym[best];
	btMatrix3x3 aligned;
	for (int k = 0; k < 3; ++k)
		for (int r = 0; r < 3; ++r)
			aligned[r][k] = s.m_sign[k] * u0[r][s.m_row[k]];
	u0 = aligned;
	btScalar* pk = &m_previous[btEllipsoidWorldCache::kPackedStride * j];
	btScalar w[3][3];
	for (int r = 0; r < 3; ++r)
		for (int c = 0; c < 3; ++c)
			w[r][c] = pk[4 + 4 * c + r];
	for (int k = 0; k < 3; ++k)
		for (int c = 0; c < 3; ++c)
			pk[4 + 4 * c + k] = s.m_sign[k] * w[s.m_row[k]][c];
}

bool btEllipsoidSweep::sweptBox(const btEllipsoidWorldCache& current, int j, btScalar& k, btScalar& e)
{
	const btEllipsoidWorldCache::Entry& now = current[j];
	const btScalar* pk = &m_previous[btEllipsoidWorldCache::kPackedStride * j];
	const btVector3 c0(pk[0], pk[1], pk[2]);
	const btMatrix3x3& u0 = m_previousUnwhiten[j];
	const btVector3 extent0(u0[0].length(), u0[1].length(), u0[2].length());
	btVector3 lo = c0 - extent0, hi = c0 + extent0;
	lo.setMin(now.m_aabbMin);
	hi.setMax(now.m_aabbMax);
	m_boxes[2 * j] = lo;
	m_boxes[2 * j + 1] = hi;
	const btScalar dU = frobenius(now.m_unwhiten - u0);
	const btScalar m = (smallestColumn(u0) + smallestColumn(now.m_unwhiten) - dU) * btScalar(0.5);
	e = (now.m_center - c0).length() + dU;
	if (!(m > btScalar(0)))
		return false;
	k = dU / (btScalar(4) * m);
	return k - k == btScalar(0); // finite
}

void btEllipsoidSweep::sizeGrid(int count)
{
	m_dims[0] = m_dims[1] = m_dims[2] = 0;
	m_cellStart.resize(0);
	m_cellItems.resize(0);
	btVector3 lo(SIMD_INFINITY, SIMD_INFINITY, SIMD_INFINITY), hi = -lo;
	int listed = 0;
	for (int j = 0, a = 0; j < count; ++j)
	{
		if (a < m_always.size() && m_always[a] == j)
		{
			++a;
			continue;
		}
		lo.setMin(m_boxes[2 * j]);
		hi.setMax(m_boxes[2 * j + 1]);
		++listed;
	}
	m_origin = lo;
	m_unionMax = hi;
	m_testedQueries = 0;
	m_bounded.resize(0);
	for (int j = 0, a = 0; j < count; ++j)
	{
		if (a < m_always.size() && m_always[a] == j)
			++a;
		else
			m_bounded.push_back(j);
	}
	if (listed == 0)
		return;
	const btVector3 size = hi - lo;
	const btScalar cell = btMax(size[size.maxAxis()], btScalar(1e-3)) / btScalar(kCellsLongestSide);
	m_invCell = btScalar(1) / cell;
	for (int k = 0; k < 3; ++k)
		m_dims[k] = btMax(1, btMin(int(kCellsLongestSide), int(size[k] * m_invCell) + 1));
	m_listsBuilt = false; // (buildLists, on the first path that needs them)
}

void btEllipsoidSweep::buildLists()
{
	// Built on demand: while the static grid holds every pose of the substep (the collider's m_sweepOnGrid), only
	// paths longer than a cell come here, and most substeps have none.
	m_listsBuilt = true;
	const int count = m_boxes.size() / 2;
	const int cells = m_dims[0] * m_dims[1] * m_dims[2];
	m_cellStart.resize(cells + 1);
	for (int c = 0; c <= cells; ++c)
		m_cellStart[c] = 0;
	btAlignedObjectArray<int> cursor;
	for (int pass = 0; pass < 2; ++pass)
	{
		if (pass == 1)
		{
			for (int c = 0; c < cells; ++c)
				m_cellStart[c + 1] += m_cellStart[c];
			m_cellItems.resize(m_cellStart[cells]);
			cursor.resize(cells);
			for (int c = 0; c < cells; ++c)
				cursor[c] = m_cellStart[c];
		}
		for (int j = 0, a = 0; j < count; ++j)
		{
			if (a < m_always.size() && m_always[a] == j)
			{
				++a;
				continue;
			}
			// The box grown by the dilation: it meets every grown cell the box meets.
			const btVector3 grow((kDilation + kCellSlack) / m_invCell, (kDilation + kCellSlack) / m_invCell,
								 (kDilation + kCellSlack) / m_invCell);
			int l[3], h[3];
			cellRange(m_boxes[2 * j] - grow, m_boxes[2 * j + 1] + grow, l, h);
			for (int z = l[2]; z <= h[2]; ++z)
				for (int y = l[1]; y <= h[1]; ++y)
					for (int x = l[0]; x <= h[0]; ++x)
					{
						const int c = (z * m_dims[1] + y) * m_dims[0] + x;
						if (pass == 0)
							++m_cellStart[c + 1];
						else
							m_cellItems[cursor[c]++] = j;
					}
		}
	}
}

void btEllipsoidSweep::cellRange(const btVector3& bMin, const btVector3& bMax, int lo[3], int hi[3]) const
{
	for (int k = 0; k < 3; ++k)
	{
		lo[k] = clampCell((bMin[k] - m_origin[k]) * m_invCell, m_dims[k]);
		hi[k] = clampCell((bMax[k] - m_origin[k]) * m_invCell, m_dims[k]);
	}
}

btVector3 btEllipsoidSweep::carry(const btEllipsoidWorldCache& current, int j, const btVector3& q) const
{
	const btEllipsoidWorldCache::Entry& now = current[j];
	btScalar u[3];
	btWhitenPacked(&m_previous[btEllipsoidWorldCache::kPackedStride * j], q.x(), q.y(), q.z(), u);
	return now.m_center + now.m_unwhiten * btVector3(u[0], u[1], u[2]);
}

btVector3 btEllipsoidSweep::previousPoint(const btEllipsoidWorldCache& current, int j, const btVector3& p) const
{
	const btEllipsoidWorldCache::Entry& now = current[j];
	const btScalar* pk = &m_previous[btEllipsoidWorldCache::kPackedStride * j];
	return btVector3(pk[0], pk[1], pk[2]) + m_previousUnwhiten[j] * (now.m_whiten * (p - now.m_center));
}

int btEllipsoidSweep::candidates(const btVector3& q, const btVector3& x, btScalar radius, int* out)
{
	int nc = 0;
	if (m_dims[0] > 0)
	{
		const btScalar grow = growth(q, x, radius);
		const btVector3 g(grow, grow, grow);
		const btVector3 boxMin = btSelectMin(q, x) - g, boxMax = btSelectMax(q, x) + g;
		if (boxesOverlap(boxMin, boxMax, m_origin, m_unionMax))
		{
			// Until the lists pay for themselves (kTestedQueries), every swept box is tested: the same set (the lists
			// are filtered by the same overlap test), built only in substeps with many paths for the swept grid.
			if (!m_listsBuilt && m_testedQueries < int(kTestedQueries))
			{
				++m_testedQueries;
				nc = testEveryBox(boxMin, boxMax, out);
			}
			else
			{
				if (!m_listsBuilt)
					buildLists();
				nc = walkCells(boxMin, boxMax, out);
			}
		}
	}
	for (int a = 0; a < m_always.size(); ++a)
		out[nc++] = m_always[a];
	return nc;
}

int btEllipsoidSweep::walkCells(const btVector3& boxMin, const btVector3& boxMax, int* out) const
{
	const btVector3 fLo = (boxMin - m_origin) * m_invCell, fHi = (boxMax - m_origin) * m_invCell;
	const btVector3 fMid = (fLo + fHi) * btScalar(0.5);
	int c3[3];
	bool inGrownCell = true;
	for (int k = 0; k < 3; ++k)
	{
		c3[k] = clampCell(fMid[k], m_dims[k]);
		inGrownCell = inGrownCell && fLo[k] >= btScalar(c3[k]) - kDilation && fHi[k] <= btScalar(c3[k] + 1) + kDilation;
	}
	if (inGrownCell)
	{
		// Every box meeting the path box meets this grown cell: its list has them all, each once.
		const int c = (c3[2] * m_dims[1] + c3[1]) * m_dims[0] + c3[0];
		const btEllipsoidWorldCache::PathQuery::ListIndex list = {&m_cellItems[0] + m_cellStart[c]};
		return btEllipsoidWorldCache::PathQuery::filterByBox(list, m_cellStart[c + 1] - m_cellStart[c], &m_boxes[0],
															 boxMin, boxMax, out);
	}
	int l[3], h[3];
	cellRange(boxMin, boxMax, l, h);
	int nc = 0;
	for (int z = l[2]; z <= h[2]; ++z)
		for (int y = l[1]; y <= h[1]; ++y)
			for (int x = l[0]; x <= h[0]; ++x)
			{
				const int c = (z * m_dims[1] + y) * m_dims[0] + x;
				for (int i = m_cellStart[c]; i < m_cellStart[c + 1]; ++i)
				{
					const int j = m_cellItems[i];
					if (!boxesOverlap(boxMin, boxMax, m_boxes[2 * j], m_boxes[2 * j + 1]))
						continue;
					int m = 0;
					while (m < nc && out[m] != j)
						++m; // a box over several cells is listed in each: keep it once
					if (m == nc)
						out[nc++] = j;
				}
			}
	return nc;
}

int btEllipsoidSweep::testEveryBox(const btVector3& boxMin, const btVector3& boxMax, int* out) const
{
	const btEllipsoidWorldCache::PathQuery::ListIndex list = {&m_bounded[0]};
	return btEllipsoidWorldCache::PathQuery::filterByBox(list, m_bounded.size(), &m_boxes[0], boxMin, boxMax, out);
}
