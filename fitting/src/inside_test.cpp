#include "bodyfit/fitting/inside_test.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"

#include <algorithm>
#include <cmath>
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

MeshInsideTest::MeshInsideTest(const TriMesh& mesh) : V_(mesh.V), F_(mesh.F)
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

	for (int axis = 0; axis < 3; ++axis)
		buildGrid(axis, extent);
}

void MeshInsideTest::cellRange(const AxisGrid& g, int f, int& u0, int& u1, int& v0, int& v1) const
{
	double minU = 1e300, maxU = -1e300, minV = 1e300, maxV = -1e300;
	for (int k = 0; k < 3; ++k)
	{
		const Eigen::Vector3d p = V_.row(F_(f, k)).transpose();
		minU = std::min(minU, p[g.u]);
		maxU = std::max(maxU, p[g.u]);
		minV = std::min(minV, p[g.v]);
		maxV = std::max(maxV, p[g.v]);
	}
	u0 = std::clamp(int((minU - g.originU) * g.invCell), 0, g.nu - 1);
	u1 = std::clamp(int((maxU - g.originU) * g.invCell), 0, g.nu - 1);
	v0 = std::clamp(int((minV - g.originV) * g.invCell), 0, g.nv - 1);
	v1 = std::clamp(int((maxV - g.originV) * g.invCell), 0, g.nv - 1);
}

void MeshInsideTest::buildGrid(int axis, const Eigen::Vector3d& extent)
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
	const int cells = g.nu * g.nv;
	std::vector<int> count(size_t(cells) + 1, 0);
	for (int f = 0; f < F_.rows(); ++f)
	{
		int u0, u1, v0, v1;
		cellRange(g, f, u0, u1, v0, v1);
		for (int v = v0; v <= v1; ++v)
			for (int u = u0; u <= u1; ++u)
				++count[size_t(v * g.nu + u) + 1];
	}
	for (int c = 0; c < cells; ++c)
		count[size_t(c) + 1] += count[size_t(c)];
	g.cellStart = count;
	g.cellFaces.assign(size_t(count[size_t(cells)]), 0);
	std::vector<int> cursor(count.begin(), count.end() - 1);
	for (int f = 0; f < F_.rows(); ++f)
	{
		int u0, u1, v0, v1;
		cellRange(g, f, u0, u1, v0, v1);
		for (int v = v0; v <= v1; ++v)
			for (int u = u0; u <= u1; ++u)
				g.cellFaces[size_t(cursor[size_t(v * g.nu + u)]++)] = f;
	}
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

	// Crossings of the ray p + s e_axis (s > 0), parity per connected component.
	std::vector<int> oddComponents; // components with an odd number of crossings so far (small)
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
		auto it = std::find(oddComponents.begin(), oddComponents.end(), comp);
		if (it == oddComponents.end())
			oddComponents.push_back(comp);
		else
			oddComponents.erase(it);
	}
	return !oddComponents.empty();
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
