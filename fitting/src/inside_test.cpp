#include "bodyfit/fitting/inside_test.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/parallel.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>

namespace bodyfit
{

namespace
{

/// Fixed sub-nanometre-scale offsets (fractions of the bbox diagonal) applied to the projected query point so that a
/// query exactly on a projected edge or vertex (common for grid-aligned points) is moved off it deterministically.
constexpr double kOffsetU = 0.7071067811865476e-9;
constexpr double kOffsetV = 0.3183098861837907e-9;

/// Target average number of projected triangles per grid cell.
constexpr double kFacesPerCell = 4.0;

} // namespace

MeshInsideTest::MeshInsideTest(const TriMesh& mesh, int threads) : V_(mesh.V), F_(mesh.F)
{
	if (F_.rows() == 0)
		throw InvalidInputError("MeshInsideTest: the mesh has no faces");
	if (!V_.allFinite())
		throw InvalidInputError("MeshInsideTest: the mesh has non-finite vertex coordinates");
	if (F_.minCoeff() < 0 || F_.maxCoeff() >= V_.rows())
		throw InvalidInputError("MeshInsideTest: a face index is out of range (" + std::to_string(F_.maxCoeff()) +
								" with " + std::to_string(V_.rows()) + " vertices)");

	const std::vector<int> vertexComponent = connectedComponents(mesh, &componentCount_);
	faceComponent_.resize(size_t(F_.rows()));
	for (int f = 0; f < F_.rows(); ++f)
		faceComponent_[size_t(f)] = vertexComponent[size_t(F_(f, 0))];

	boxMin_ = V_.colwise().minCoeff().transpose();
	boxMax_ = V_.colwise().maxCoeff().transpose();
	const Eigen::Vector3d extent = (boxMax_ - boxMin_).cwiseMax(1e-12);

	Eigen::MatrixX3d faceMin(F_.rows(), 3), faceMax(F_.rows(), 3);
	for (int f = 0; f < F_.rows(); ++f)
	{
		const auto a = V_.row(F_(f, 0)), b = V_.row(F_(f, 1)), c = V_.row(F_(f, 2));
		faceMin.row(f) = a.cwiseMin(b).cwiseMin(c);
		faceMax.row(f) = a.cwiseMax(b).cwiseMax(c);
	}
	// Each grid is written by one thread only (threads < 1 is every hardware thread, as the library's options read).
	parallelRanges(3, resolveThreads(threads), [&](int first, int end) {
		for (int axis = first; axis < end; ++axis)
			buildGrid(axis, extent, faceMin, faceMax);
	});
}

void MeshInsideTest::buildGrid(int axis, const Eigen::Vector3d& extent, const Eigen::MatrixX3d& faceMin,
							   const Eigen::MatrixX3d& faceMax)
{
	AxisGrid& g = grids_[axis];
	g.axis = axis;
	g.u = (axis + 1) % 3;
	g.v = (axis + 2) % 3;
	const double area = extent[g.u] * extent[g.v];
	const double cell = std::sqrt(area * kFacesPerCell / double(F_.rows()));
	g.invCell = 1.0 / cell;
	g.originU = boxMin_[g.u];
	g.originV = boxMin_[g.v];
	g.nu = std::clamp(int(extent[g.u] * g.invCell) + 1, 1, 4096);
	g.nv = std::clamp(int(extent[g.v] * g.invCell) + 1, 1, 4096);
	const int faces = int(F_.rows());
	// The cells [u0, u1] x [v0, v1] that each face's projected box meets, found once for both passes below.
	std::vector<std::array<int, 4>> range(static_cast<std::size_t>(faces));
	auto cellOf = [](double x, double origin, double invCell, int n) {
		return std::clamp(int((x - origin) * invCell), 0, n - 1);
	};
	for (int f = 0; f < faces; ++f)
		range[size_t(f)] = {cellOf(faceMin(f, g.u), g.originU, g.invCell, g.nu),
							cellOf(faceMax(f, g.u), g.originU, g.invCell, g.nu),
							cellOf(faceMin(f, g.v), g.originV, g.invCell, g.nv),
							cellOf(faceMax(f, g.v), g.originV, g.invCell, g.nv)};
	const int cells = g.nu * g.nv;
	std::vector<int> count(size_t(cells) + 1, 0);
	for (const std::array<int, 4>& r : range)
		for (int v = r[2]; v <= r[3]; ++v)
			for (int u = r[0]; u <= r[1]; ++u)
				++count[size_t(v * g.nu + u) + 1];
	for (int c = 0; c < cells; ++c)
		count[size_t(c) + 1] += count[size_t(c)];
	g.cellFaces.resize(size_t(count[size_t(cells)]));
	std::vector<int> cursor(count.begin(), count.end() - 1);
	for (int f = 0; f < faces; ++f)
	{
		const std::array<int, 4>& r = range[size_t(f)];
		for (int v = r[2]; v <= r[3]; ++v)
			for (int u = r[0]; u <= r[1]; ++u)
				g.cellFaces[size_t(cursor[size_t(v * g.nu + u)]++)] = f;
	}
	g.cellStart = std::move(count);
}

bool MeshInsideTest::parityInside(const Eigen::Vector3d& p, int axis) const
{
	if (!p.allFinite())
		return false;
	for (int k = 0; k < 3; ++k)
		if (p[k] < boxMin_[k] || p[k] > boxMax_[k])
			return false;
	const AxisGrid& g = grids_[axis];
	const double diag = (boxMax_ - boxMin_).norm();
	const double pu = p[g.u] + kOffsetU * diag;
	const double pv = p[g.v] + kOffsetV * diag;
	const int cu = std::clamp(int((pu - g.originU) * g.invCell), 0, g.nu - 1);
	const int cv = std::clamp(int((pv - g.originV) * g.invCell), 0, g.nv - 1);
	const int cell = cv * g.nu + cu;

	// Crossings of the ray p + s e_axis (s > 0), parity per connected component: a bit per component below 64 (no
	// allocation on the common path; a body has a handful), a list of the others with an odd count so far.
	std::uint64_t oddLow = 0;
	std::vector<int> oddHigh;
	for (int j = g.cellStart[size_t(cell)]; j < g.cellStart[size_t(cell) + 1]; ++j)
	{
		const int f = g.cellFaces[size_t(j)];
		const Eigen::Vector3d a = V_.row(F_(f, 0)).transpose();
		const Eigen::Vector3d b = V_.row(F_(f, 1)).transpose();
		const Eigen::Vector3d c = V_.row(F_(f, 2)).transpose();
		// 2D edge functions in the projection plane.
		const double ea = (b[g.u] - pu) * (c[g.v] - pv) - (b[g.v] - pv) * (c[g.u] - pu);
		const double eb = (c[g.u] - pu) * (a[g.v] - pv) - (c[g.v] - pv) * (a[g.u] - pu);
		const double ec = (a[g.u] - pu) * (b[g.v] - pv) - (a[g.v] - pv) * (b[g.u] - pu);
		const bool allPos = ea > 0 && eb > 0 && ec > 0;
		const bool allNeg = ea < 0 && eb < 0 && ec < 0;
		if (!allPos && !allNeg)
			continue;
		const double sum = ea + eb + ec;
		const double hit = (ea * a[axis] + eb * b[axis] + ec * c[axis]) / sum;
		if (hit <= p[axis])
			continue;
		const int comp = faceComponent_[size_t(f)];
		if (comp < 64)
		{
			oddLow ^= std::uint64_t(1) << comp;
			continue;
		}
		auto it = std::find(oddHigh.begin(), oddHigh.end(), comp);
		if (it == oddHigh.end())
			oddHigh.push_back(comp);
		else
			oddHigh.erase(it);
	}
	return oddLow != 0 || !oddHigh.empty();
}

bool MeshInsideTest::isInside(const Eigen::Vector3d& p) const
{
	int votes = 0;
	for (int axis = 0; axis < 3; ++axis)
		votes += parityInside(p, axis) ? 1 : 0;
	return votes >= 2;
}

int MeshInsideTest::countInside(const Eigen::MatrixX3d& points) const
{
	int count = 0;
	for (int i = 0; i < points.rows(); ++i)
		count += isInside(points.row(i).transpose()) ? 1 : 0;
	return count;
}

} // namespace bodyfit
