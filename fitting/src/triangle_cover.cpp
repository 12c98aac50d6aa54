// The pieces of the triangle cover and their check against the ellipsoids. See triangle_cover.h.
#include "bodyfit/fitting/triangle_cover.h"

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/parallel.h"

#include <algorithm>
#include <cmath>

namespace bodyfit
{
namespace
{

constexpr double kInside = 1.0 + 1e-9; // the MVEE's own enclosure guarantee (mvee.h)

/// Row-major index of grid point (i, j) of a triangle cut `level` times (i + j <= level).
int gridIndex(int i, int j, int level)
{
	return i * (level + 1) - i * (i - 1) / 2 + j;
}

/// A uniform grid over the grid points' bounding box with, per cell, the clusters whose ellipsoid's bounding box
/// overlaps the cell (ascending). A box that contains a point overlaps the point's cell: cellOf is monotone in
/// each coordinate (correctly rounded subtraction and division by a positive constant are), so the cell range of
/// a box's corners brackets the cell of every point inside it.
class BoxGrid
{
public:
	BoxGrid(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::AlignedBox3d>& boxes)
	{
		Eigen::AlignedBox3d all;
		for (const Eigen::Vector3d& p : points)
			all.extend(p);
		lo_ = all.min();
		const double extent = std::max(all.sizes().maxCoeff(), 1e-12);
		cell_ = extent / kCellsPerAxis;
		offsets_.assign(std::size_t(kCellCount) + 1, 0);
		// Two passes (count, fill) into CSR lists: clusters ascend within a cell because they are visited in order.
		for (int pass = 0; pass < 2; ++pass)
		{
			std::vector<int> fill(offsets_.begin(), offsets_.end() - 1);
			for (int id = 0; id < int(boxes.size()); ++id)
			{
				const std::array<int, 3> a = cellOf(boxes[std::size_t(id)].min()), b = cellOf(boxes[std::size_t(id)].max());
				for (int x = a[0]; x <= b[0]; ++x)
					for (int y = a[1]; y <= b[1]; ++y)
						for (int z = a[2]; z <= b[2]; ++z)
						{
							const int c = (x * kCellsPerAxis + y) * kCellsPerAxis + z;
							if (pass == 0)
								++offsets_[std::size_t(c) + 1];
							else
								clusters_[std::size_t(fill[std::size_t(c)]++)] = id;
						}
			}
			if (pass == 0)
			{
				for (int c = 0; c < kCellCount; ++c)
					offsets_[std::size_t(c) + 1] += offsets_[std::size_t(c)];
				clusters_.resize(std::size_t(offsets_.back()));
			}
		}
	}

	/// The clusters whose box overlaps the cell of p.
	std::pair<const int*, const int*> candidates(const Eigen::Vector3d& p) const
	{
		const std::array<int, 3> c = cellOf(p);
		const int cell = (c[0] * kCellsPerAxis + c[1]) * kCellsPerAxis + c[2];
		return {clusters_.data() + offsets_[std::size_t(cell)], clusters_.data() + offsets_[std::size_t(cell) + 1]};
	}

private:
	static constexpr int kCellsPerAxis = 24;
	static constexpr int kCellCount = kCellsPerAxis * kCellsPerAxis * kCellsPerAxis;

	std::array<int, 3> cellOf(const Eigen::Vector3d& p) const
	{
		std::array<int, 3> c{};
		for (int k = 0; k < 3; ++k)
		{
			const double t = std::floor((p[k] - lo_[k]) / cell_);
			c[std::size_t(k)] = t < 0.0 ? 0 : (t >= kCellsPerAxis ? kCellsPerAxis - 1 : int(t));
		}
		return c;
	}

	Eigen::Vector3d lo_ = Eigen::Vector3d::Zero();
	double cell_ = 1.0;
	std::vector<int> offsets_, clusters_;
};

} // namespace

/// One check: the ellipsoids, their boxes and the grid of boxes, shared read-only by the threads.
class TriangleCover::Checker
{
public:
	Checker(const TriangleCover& cover, const std::vector<Ellipsoid>& ellipsoids)
		: cover_(cover), ellipsoids_(ellipsoids), boxes_(boxesOf(ellipsoids)), grid_(cover.points_, boxes_)
	{
	}

	/// Checks the pieces of triangles [begin, end) that need it (`recheck`), writing their verdicts.
	void run(int begin, int end, const std::vector<char>& recheck, std::vector<Verdict>& verdicts) const
	{
		std::vector<double> zeta;
		std::vector<char> inside;
		for (int t = begin; t < end; ++t)
		{
			const Triangle& tri = cover_.triangles_[std::size_t(t)];
			bool any = false;
			for (int p = tri.firstPiece; p < tri.pieceEnd && !any; ++p)
				any = recheck[std::size_t(p)] != 0;
			if (!any)
				continue;
			const int whole = coveringCornerCluster(tri);
			if (whole >= 0)
			{
				for (int p = tri.firstPiece; p < tri.pieceEnd; ++p)
					if (recheck[std::size_t(p)])
						verdicts[std::size_t(p)] = Verdict{whole, -1, 0};
				continue;
			}
			cornerValues(tri, zeta, inside);
			const int count = pointCount(tri);
			for (int p = tri.firstPiece; p < tri.pieceEnd; ++p)
				if (recheck[std::size_t(p)])
					verdicts[std::size_t(p)] = judge(tri, p, count, zeta, inside);
		}
	}

private:
	static std::vector<Eigen::AlignedBox3d> boxesOf(const std::vector<Ellipsoid>& ellipsoids)
	{
		std::vector<Eigen::AlignedBox3d> boxes;
		boxes.reserve(ellipsoids.size());
		for (const Ellipsoid& e : ellipsoids)
			boxes.push_back(e.aabb());
		return boxes;
	}

	int pointCount(const Triangle& tri) const
	{
		const std::size_t t = std::size_t(&tri - cover_.triangles_.data());
		const int next = t + 1 < cover_.triangles_.size() ? cover_.triangles_[t + 1].firstPoint : int(cover_.points_.size());
		return next - tri.firstPoint;
	}

	/// A corner cluster whose ellipsoid contains the whole triangle with a margin, or -1. Every grid point lies in
	/// the convex hull of the triangle's three corner grid points up to rounding (~1e-16 of the coordinates), and box
	/// and ellipsoid are convex: with the corners 1 nm inside the box and at zeta <= kInside - 1e-9, every grid point
	/// is inside the box and at zeta <= kInside however it rounds (zeta's rounding error is ~1e-12 even at the
	/// thinnest axis: |grad zeta| <= 2 / minimum radius, a few hundred per metre, times 1e-15 m), so each piece gets
	/// the verdict the per-point check would give, without evaluating its points.
	int coveringCornerCluster(const Triangle& tri) const
	{
		constexpr double kBoxMargin = 1e-9, kZetaMargin = 1e-9;
		const int level = levelOf(tri);
		const std::array<int, 3> corners = {gridIndex(level, 0, level), gridIndex(0, level, level), gridIndex(0, 0, level)};
		for (int s = 0; s < 3; ++s)
		{
			const int id = tri.clusters[std::size_t(s)];
			if ((s > 0 && id == tri.clusters[0]) || (s > 1 && id == tri.clusters[1]))
				continue;
			const Eigen::AlignedBox3d& box = boxes_[std::size_t(id)];
			const Ellipsoid& e = ellipsoids_[std::size_t(id)];
			bool all = true;
			for (int k = 0; k < 3 && all; ++k)
			{
				const Eigen::Vector3d& q = cover_.points_[std::size_t(tri.firstPoint + corners[std::size_t(k)])];
				all = ((q - box.min()).array() > kBoxMargin).all() && ((box.max() - q).array() > kBoxMargin).all() &&
					  e.zeta(q) <= kInside - kZetaMargin;
			}
			if (all)
				return id;
		}
		return -1;
	}

	/// The cut level of a triangle, from its grid point count (level + 1)(level + 2) / 2.
	int levelOf(const Triangle& tri) const
	{
		const int count = pointCount(tri);
		int level = 1;
		while ((level + 1) * (level + 2) / 2 < count)
			++level;
		return level;
	}

	/// Per corner slot s (the triangle's corner clusters) and grid point q: zeta_s(q) and whether q lies in s's box
	/// at zeta <= kInside. Slot s reuses an earlier slot's values when their clusters are the same.
	void cornerValues(const Triangle& tri, std::vector<double>& zeta, std::vector<char>& inside) const
	{
		const int count = pointCount(tri);
		zeta.resize(std::size_t(3 * count));
		inside.resize(std::size_t(3 * count));
		for (int s = 0; s < 3; ++s)
		{
			const int id = tri.clusters[std::size_t(s)];
			const int same = s > 0 && tri.clusters[0] == id ? 0 : (s > 1 && tri.clusters[1] == id ? 1 : -1);
			if (same >= 0)
			{
				std::copy_n(zeta.begin() + same * count, count, zeta.begin() + s * count);
				std::copy_n(inside.begin() + same * count, count, inside.begin() + s * count);
				continue;
			}
			const Ellipsoid& e = ellipsoids_[std::size_t(id)];
			const Eigen::AlignedBox3d& box = boxes_[std::size_t(id)];
			for (int q = 0; q < count; ++q)
			{
				const Eigen::Vector3d& point = cover_.points_[std::size_t(tri.firstPoint + q)];
				const double z = e.zeta(point);
				zeta[std::size_t(s * count + q)] = z;
				inside[std::size_t(s * count + q)] = box.contains(point) && z <= kInside;
			}
		}
	}

	static bool isCornerCluster(const Triangle& tri, int id)
	{
		return id == tri.clusters[0] || id == tri.clusters[1] || id == tri.clusters[2];
	}

	bool contains(int id, const std::array<int, 3>& corners) const
	{
		const Eigen::AlignedBox3d& box = boxes_[std::size_t(id)];
		const Ellipsoid& e = ellipsoids_[std::size_t(id)];
		for (int k = 0; k < 3; ++k)
			if (!box.contains(cover_.points_[std::size_t(corners[std::size_t(k)])]))
				return false;
		for (int k = 0; k < 3; ++k)
			if (!(e.zeta(cover_.points_[std::size_t(corners[std::size_t(k)])]) <= kInside))
				return false;
		return true;
	}

	/// The verdict on piece p of `tri`: a corner cluster containing it, else any ellipsoid containing it, else the
	/// corner cluster it goes to and which of its corners that cluster must take.
	Verdict judge(const Triangle& tri, int p, int count, const std::vector<double>& zeta,
				  const std::vector<char>& inside) const
	{
		const std::array<int, 3>& corners = cover_.pieces_[std::size_t(p)];
		std::array<int, 3> local{};
		for (int k = 0; k < 3; ++k)
			local[std::size_t(k)] = corners[std::size_t(k)] - tri.firstPoint;
		Verdict v;
		for (int s = 0; s < 3; ++s)
		{
			const char* in = inside.data() + s * count;
			if (in[local[0]] && in[local[1]] && in[local[2]])
			{
				v.coveredBy = tri.clusters[std::size_t(s)];
				return v;
			}
		}
		// The corner clusters fail `contains` here (it is the `inside` test above), so only the others are tried.
		const auto [first, last] = grid_.candidates(cover_.points_[std::size_t(corners[0])]);
		for (const int* id = first; id != last; ++id)
			if (!isCornerCluster(tri, *id) && contains(*id, corners))
			{
				v.coveredBy = *id;
				return v;
			}
		double bestZeta = 0.0;
		int bestSlot = -1;
		for (int s = 0; s < 3; ++s)
		{
			const double* z = zeta.data() + s * count;
			const double m = std::max({z[local[0]], z[local[1]], z[local[2]]});
			const int id = tri.clusters[std::size_t(s)];
			if (bestSlot < 0 || m < bestZeta || (m == bestZeta && id < v.target))
			{
				bestSlot = s;
				bestZeta = m;
				v.target = id;
			}
		}
		const double* z = zeta.data() + bestSlot * count;
		for (int k = 0; k < 3; ++k)
			if (!(z[local[std::size_t(k)]] <= kInside))
				v.outside = char(v.outside | (1 << k));
		return v;
	}

	const TriangleCover& cover_;
	const std::vector<Ellipsoid>& ellipsoids_;
	const std::vector<Eigen::AlignedBox3d> boxes_;
	const BoxGrid grid_;
};

bool crossesClusters(const TriMesh& mesh, const std::vector<int>& owner, int f, std::array<int, 3>& clusters)
{
	for (int k = 0; k < 3; ++k)
		clusters[std::size_t(k)] = owner[std::size_t(mesh.F(f, k))];
	const std::array<int, 3>& c = clusters;
	return c[0] >= 0 && c[1] >= 0 && c[2] >= 0 && !(c[0] == c[1] && c[1] == c[2]);
}

TriangleCover::TriangleCover(const TriMesh& mesh, const std::vector<int>& owner, double spacing)
{
	// The cut level of every triangle that crosses clusters (-1 for the others), so that the storage is sized once.
	std::vector<int> levels(std::size_t(mesh.F.rows()), -1);
	std::size_t pointTotal = 0, pieceTotal = 0, triangleTotal = 0;
	for (int f = 0; f < mesh.F.rows(); ++f)
	{
		std::array<int, 3> c{};
		if (!crossesClusters(mesh, owner, f, c))
			continue;
		const int level = coverCutLevel(mesh.V.row(mesh.F(f, 0)), mesh.V.row(mesh.F(f, 1)), mesh.V.row(mesh.F(f, 2)), spacing);
		levels[std::size_t(f)] = level;
		pointTotal += std::size_t((level + 1) * (level + 2) / 2);
		pieceTotal += std::size_t(level * level);
		++triangleTotal;
	}
	points_.reserve(pointTotal);
	pieces_.reserve(pieceTotal);
	triangles_.reserve(triangleTotal);
	for (int f = 0; f < mesh.F.rows(); ++f)
	{
		const int level = levels[std::size_t(f)];
		if (level < 0)
			continue;
		std::array<int, 3> c{};
		crossesClusters(mesh, owner, f, c);
		const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), d = mesh.V.row(mesh.F(f, 2));
		Triangle tri;
		tri.clusters = c;
		tri.firstPoint = int(points_.size());
		tri.firstPiece = int(pieces_.size());
		for (int i = 0; i <= level; ++i)
			for (int j = 0; i + j <= level; ++j)
				points_.push_back((double(i) * a + double(j) * b + double(level - i - j) * d) / double(level));
		auto at = [&](int i, int j) { return tri.firstPoint + gridIndex(i, j, level); };
		for (int i = 0; i < level; ++i)
			for (int j = 0; i + j < level; ++j)
			{
				pieces_.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
				if (i + j + 2 <= level)
					pieces_.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
			}
		tri.pieceEnd = int(pieces_.size());
		triangles_.push_back(tri);
	}
	verdicts_.assign(pieces_.size(), Verdict{});
}

int TriangleCover::check(const std::vector<Ellipsoid>& ellipsoids, const std::vector<char>& changed,
						 std::vector<Handout>& handouts, std::vector<char>& targeted, int threads)
{
	targeted.assign(ellipsoids.size(), 0);
	std::vector<char> recheck(pieces_.size(), 1);
	if (checked_)
		for (std::size_t p = 0; p < pieces_.size(); ++p)
		{
			const int by = verdicts_[p].coveredBy;
			recheck[p] = by < 0 || changed[std::size_t(by)] != 0;
		}
	checked_ = true;
	const Checker checker(*this, ellipsoids);
	parallelRanges(int(triangles_.size()), std::max(1, threads),
				   [&](int begin, int end) { checker.run(begin, end, recheck, verdicts_); });
	return collectHandouts(handouts, targeted);
}

int TriangleCover::collectHandouts(std::vector<Handout>& handouts, std::vector<char>& targeted)
{
	// A grid point is a corner of up to six pieces of its triangle: it is handed to each cluster once (an MVEE does
	// not depend on how often a point is repeated, only its cost does). Every target is one of the triangle's corner
	// clusters, so handedTo_ keeps, per grid point, one bit per corner slot.
	handedTo_.assign(points_.size(), 0);
	int uncovered = 0;
	for (const Triangle& tri : triangles_)
		for (int p = tri.firstPiece; p < tri.pieceEnd; ++p)
		{
			const Verdict& v = verdicts_[std::size_t(p)];
			if (v.coveredBy >= 0)
				continue;
			++uncovered;
			targeted[std::size_t(v.target)] = 1;
			const int slot = v.target == tri.clusters[0] ? 0 : (v.target == tri.clusters[1] ? 1 : 2);
			for (int k = 0; k < 3; ++k)
			{
				const int q = pieces_[std::size_t(p)][std::size_t(k)];
				if (!(v.outside & (1 << k)) || (handedTo_[std::size_t(q)] & (1 << slot)))
					continue;
				handedTo_[std::size_t(q)] = char(handedTo_[std::size_t(q)] | (1 << slot));
				handouts.push_back({v.target, points_[std::size_t(q)]});
			}
		}
	return uncovered;
}

} // namespace bodyfit
