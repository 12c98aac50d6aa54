#include "bodyfit/fitting/subdivision.h"

#include <algorithm>
#include <map>
#include <utility>
#include <vector>

namespace bodyfit
{

TriMesh midpointSubdivide(const TriMesh& mesh)
{
	std::map<std::pair<int, int>, int> midpoints; // edge (low, high) -> its new vertex
	std::vector<Eigen::Vector3d> vertices;
	vertices.reserve(size_t(mesh.V.rows()) * 4);
	for (int i = 0; i < mesh.V.rows(); ++i)
		vertices.push_back(mesh.V.row(i).transpose());
	const auto midpoint = [&](int a, int b) {
		const auto inserted = midpoints.emplace(std::minmax(a, b), int(vertices.size()));
		if (inserted.second)
			vertices.push_back(0.5 * (vertices[size_t(a)] + vertices[size_t(b)]));
		return inserted.first->second;
	};
	TriMesh out;
	out.F.resize(mesh.F.rows() * 4, 3);
	for (int f = 0; f < mesh.F.rows(); ++f)
	{
		const int a = mesh.F(f, 0), b = mesh.F(f, 1), c = mesh.F(f, 2);
		const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
		out.F.row(4 * f + 0) << a, ab, ca;
		out.F.row(4 * f + 1) << ab, b, bc;
		out.F.row(4 * f + 2) << ca, bc, c;
		out.F.row(4 * f + 3) << ab, bc, ca;
	}
	out.V.resize(int(vertices.size()), 3);
	for (size_t i = 0; i < vertices.size(); ++i)
		out.V.row(int(i)) = vertices[i].transpose();
	return out;
}

} // namespace bodyfit
