#include "mesh_distance.h"

#include "bodyfit/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace bodyfit::drape
{

Eigen::Vector3d MeshDistance::closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
													 const Eigen::Vector3d& b, const Eigen::Vector3d& c)
{
	const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
	const double d1 = ab.dot(ap), d2 = ac.dot(ap);
	if (d1 <= 0.0 && d2 <= 0.0)
		return a;
	const Eigen::Vector3d bp = p - b;
	const double d3 = ab.dot(bp), d4 = ac.dot(bp);
	if (d3 >= 0.0 && d4 <= d3)
		return b;
	const double vc = d1 * d4 - d3 * d2;
	if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
		return a + ab * (d1 / (d1 - d3));
	const Eigen::Vector3d cp = p - c;
	const double d5 = ab.dot(cp), d6 = ac.dot(cp);
	if (d6 >= 0.0 && d5 <= d6)
		return c;
	const double vb = d5 * d2 - d1 * d6;
	if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
		return a + ac * (d2 / (d2 - d6));
	const double va = d3 * d6 - d5 * d4;
	if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
		return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
	const double denom = va + vb + vc;
	if (!(std::abs(denom) > 0.0))
		return a; // degenerate triangle: any vertex is as good as the edges tested above
	return a + ab * (vb / denom) + ac * (vc / denom);
}

MeshDistance::MeshDistance(const TriMesh& mesh) : mesh_(mesh)
{
	if (mesh_.F.rows() == 0)
		throw InvalidInputError("mesh distance: the mesh has no faces");
	const Eigen::Vector3d lo = mesh_.V.colwise().minCoeff().transpose();
	const Eigen::Vector3d hi = mesh_.V.colwise().maxCoeff().transpose();
	double edge = 0.0;
	for (int f = 0; f < mesh_.F.rows(); ++f)
		edge += (mesh_.V.row(mesh_.F(f, 0)) - mesh_.V.row(mesh_.F(f, 1))).norm();
	edge /= double(mesh_.F.rows());
	// Cells of about three edge lengths, at most 128 per axis.
	const Eigen::Vector3d ext = (hi - lo).cwiseMax(Eigen::Vector3d::Constant(1e-9));
	cell_ = std::max(3.0 * edge, ext.maxCoeff() / 128.0);
	origin_ = lo;
	for (int d = 0; d < 3; ++d)
		dims_[d] = std::max(1, int(std::ceil(ext[d] / cell_)));
	const int cells = dims_[0] * dims_[1] * dims_[2];
	auto clampCell = [&](double v, int d) { return std::clamp(int(std::floor((v - origin_[d]) / cell_)), 0, dims_[d] - 1); };
	std::vector<int> counts(std::size_t(cells) + 1, 0);
	for (int pass = 0; pass < 2; ++pass)
	{
		std::vector<int> fill;
		if (pass == 1)
		{
			cellStart_.assign(std::size_t(cells) + 1, 0);
			for (int i = 0; i < cells; ++i)
				cellStart_[i + 1] = cellStart_[i] + counts[i];
			cellFaces_.resize(std::size_t(cellStart_[cells]));
			fill.assign(cellStart_.begin(), cellStart_.end() - 1);
		}
		for (int f = 0; f < mesh_.F.rows(); ++f)
		{
			Eigen::Vector3d a = mesh_.V.row(mesh_.F(f, 0)).transpose(), tlo = a, thi = a;
			for (int k = 1; k < 3; ++k)
			{
				const Eigen::Vector3d v = mesh_.V.row(mesh_.F(f, k)).transpose();
				tlo = tlo.cwiseMin(v);
				thi = thi.cwiseMax(v);
			}
			int c0[3], c1[3];
			for (int d = 0; d < 3; ++d)
			{
				c0[d] = clampCell(tlo[d], d);
				c1[d] = clampCell(thi[d], d);
			}
			for (int z = c0[2]; z <= c1[2]; ++z)
				for (int y = c0[1]; y <= c1[1]; ++y)
					for (int x = c0[0]; x <= c1[0]; ++x)
					{
						const int ci = cellIndex(x, y, z);
						if (pass == 0)
							++counts[ci];
						else
							cellFaces_[fill[ci]++] = f;
					}
		}
	}
}

double MeshDistance::distance(const Eigen::Vector3d& p) const
{
	int c[3];
	for (int d = 0; d < 3; ++d)
		c[d] = std::clamp(int(std::floor((p[d] - origin_[d]) / cell_)), 0, dims_[d] - 1);
	double best2 = std::numeric_limits<double>::max();
	const int maxRing = std::max({dims_[0], dims_[1], dims_[2]});
	for (int r = 0; r <= maxRing; ++r)
	{
		// Cells at Chebyshev distance exactly r from c.
		for (int z = c[2] - r; z <= c[2] + r; ++z)
			for (int y = c[1] - r; y <= c[1] + r; ++y)
				for (int x = c[0] - r; x <= c[0] + r; ++x)
				{
					if (std::max({std::abs(x - c[0]), std::abs(y - c[1]), std::abs(z - c[2])}) != r)
						continue;
					if (x < 0 || y < 0 || z < 0 || x >= dims_[0] || y >= dims_[1] || z >= dims_[2])
						continue;
					const int ci = cellIndex(x, y, z);
					for (int k = cellStart_[ci]; k < cellStart_[ci + 1]; ++k)
					{
						const int f = cellFaces_[k];
						const Eigen::Vector3d q = closestPointOnTriangle(p, mesh_.V.row(mesh_.F(f, 0)).transpose(),
																		 mesh_.V.row(mesh_.F(f, 1)).transpose(),
																		 mesh_.V.row(mesh_.F(f, 2)).transpose());
						best2 = std::min(best2, (q - p).squaredNorm());
					}
				}
		// Every unvisited cell is at least r cells away from p's (clamped) cell, so at least r * cell_ from p.
		const double bound = r * cell_;
		if (best2 <= bound * bound)
			break;
	}
	return std::sqrt(best2);
}

} // namespace bodyfit::drape
