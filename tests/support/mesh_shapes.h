#pragma once
// Closed triangle meshes generated in code for the geodesic and segmentation tests: UV sphere, subdivided cube,
// flat grid, a star-shaped "animal" blob, vertex re-indexing / mirroring helpers, and the helpers that build
// bodies of several meshes (game assets) from a bundled body: detach faces as a separate mesh, append meshes.
#include "bodyfit/fitting/types.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <random>
#include <vector>

namespace bodyfit_test
{

/// Closed star-shaped surface r(direction) * direction + centre on a UV sphere with single-vertex poles (+-y).
/// Faces are CCW seen from outside.
inline bodyfit::TriMesh starShape(const std::function<double(const Eigen::Vector3d&)>& radius, int slices,
	int stacks, const Eigen::Vector3d& centre = Eigen::Vector3d::Zero())
{
	const double pi = std::acos(-1.0);
	bodyfit::TriMesh m;
	const int rings = stacks - 1;
	m.V.resize(2 + rings * slices, 3);
	auto put = [&](int i, const Eigen::Vector3d& dir) { m.V.row(i) = (centre + radius(dir) * dir).transpose(); };
	put(0, Eigen::Vector3d(0, 1, 0));
	for (int r = 0; r < rings; ++r)
	{
		const double theta = pi * (r + 1) / stacks;
		for (int s = 0; s < slices; ++s)
		{
			const double phi = 2.0 * pi * s / slices;
			put(1 + r * slices + s,
				Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)));
		}
	}
	const int south = 1 + rings * slices;
	put(south, Eigen::Vector3d(0, -1, 0));
	std::vector<Eigen::Vector3i> faces;
	auto at = [&](int r, int s) { return 1 + r * slices + (s % slices); };
	for (int s = 0; s < slices; ++s)
		faces.emplace_back(0, at(0, s + 1), at(0, s));
	for (int r = 0; r + 1 < rings; ++r)
	{
		for (int s = 0; s < slices; ++s)
		{
			faces.emplace_back(at(r, s), at(r, s + 1), at(r + 1, s));
			faces.emplace_back(at(r, s + 1), at(r + 1, s + 1), at(r + 1, s));
		}
	}
	for (int s = 0; s < slices; ++s)
		faces.emplace_back(south, at(rings - 1, s), at(rings - 1, s + 1));
	m.F.resize(int(faces.size()), 3);
	for (int f = 0; f < int(faces.size()); ++f)
		m.F.row(f) = faces[size_t(f)].transpose();
	return m;
}

inline bodyfit::TriMesh uvSphere(double radius, int slices, int stacks,
	const Eigen::Vector3d& centre = Eigen::Vector3d::Zero())
{
	return starShape([radius](const Eigen::Vector3d&) { return radius; }, slices, stacks, centre);
}

/// Axis-aligned cube [0, size]^3 with every face split into n x n quads (2 triangles each), vertices shared.
inline bodyfit::TriMesh subdividedCube(double size, int n)
{
	std::vector<Eigen::Vector3d> points;
	std::vector<Eigen::Vector3i> faces;
	// Lattice points on the surface, indexed through a dense (n+1)^3 table.
	const int k = n + 1;
	std::vector<int> index(static_cast<size_t>(k * k * k), -1);
	auto id = [&](int i, int j, int l) {
		int& slot = index[size_t((i * k + j) * k + l)];
		if (slot < 0)
		{
			slot = int(points.size());
			points.emplace_back(size * i / n, size * j / n, size * l / n);
		}
		return slot;
	};
	// For each axis and side, a grid of quads; orientation chosen so normals point outward.
	for (int axis = 0; axis < 3; ++axis)
	{
		for (int side = 0; side < 2; ++side)
		{
			for (int a = 0; a < n; ++a)
			{
				for (int b = 0; b < n; ++b)
				{
					auto corner = [&](int da, int db) {
						int c[3];
						c[axis] = side * n;
						c[(axis + 1) % 3] = a + da;
						c[(axis + 2) % 3] = b + db;
						return id(c[0], c[1], c[2]);
					};
					const int p00 = corner(0, 0), p10 = corner(1, 0), p11 = corner(1, 1), p01 = corner(0, 1);
					if (side == 1)
					{
						faces.emplace_back(p00, p10, p11);
						faces.emplace_back(p00, p11, p01);
					}
					else
					{
						faces.emplace_back(p00, p11, p10);
						faces.emplace_back(p00, p01, p11);
					}
				}
			}
		}
	}
	bodyfit::TriMesh m;
	m.V.resize(int(points.size()), 3);
	for (int i = 0; i < int(points.size()); ++i)
		m.V.row(i) = points[size_t(i)].transpose();
	m.F.resize(int(faces.size()), 3);
	for (int f = 0; f < int(faces.size()); ++f)
		m.F.row(f) = faces[size_t(f)].transpose();
	return m;
}

/// Flat n x n grid of vertices `spacing` apart in the xz plane (y = 0), each square split along the same diagonal.
inline bodyfit::TriMesh flatGrid(int n, double spacing)
{
	bodyfit::TriMesh m;
	m.V.resize(n * n, 3);
	for (int i = 0; i < n; ++i)
		for (int j = 0; j < n; ++j)
			m.V.row(i * n + j) << spacing * i, 0.0, spacing * j;
	m.F.resize(2 * (n - 1) * (n - 1), 3);
	int f = 0;
	for (int i = 0; i + 1 < n; ++i)
	{
		for (int j = 0; j + 1 < n; ++j)
		{
			const int a = i * n + j, b = (i + 1) * n + j, c = (i + 1) * n + j + 1, d = i * n + j + 1;
			m.F.row(f++) << a, c, b;
			m.F.row(f++) << a, d, c;
		}
	}
	return m;
}

/// A four-legged "animal": horizontal body along z with four legs down to y = 0, a head forward and a tail,
/// built as a star-shaped surface (Gaussian bumps on an ellipsoid). About 1.2 m long and 0.9 m tall.
inline bodyfit::TriMesh animalBlob()
{
	const std::vector<std::pair<Eigen::Vector3d, double>> bumps = {
		{Eigen::Vector3d(0.35, -1.0, 0.6).normalized(), 0.55},  // legs
		{Eigen::Vector3d(-0.35, -1.0, 0.6).normalized(), 0.55},
		{Eigen::Vector3d(0.35, -1.0, -0.6).normalized(), 0.55},
		{Eigen::Vector3d(-0.35, -1.0, -0.6).normalized(), 0.55},
		{Eigen::Vector3d(0.0, 0.6, 1.0).normalized(), 0.45},   // head
		{Eigen::Vector3d(0.0, 0.2, -1.0).normalized(), 0.35},  // tail
	};
	auto radius = [&](const Eigen::Vector3d& dir) {
		// Body: ellipsoid with semi-axes 0.25 (x), 0.22 (y), 0.55 (z) along `dir`.
		const double inv = std::sqrt(std::pow(dir.x() / 0.25, 2) + std::pow(dir.y() / 0.22, 2) +
									 std::pow(dir.z() / 0.55, 2));
		double r = 1.0 / inv;
		for (const auto& [axis, height] : bumps)
		{
			const double angle = std::acos(std::clamp(dir.dot(axis), -1.0, 1.0));
			r += height * std::exp(-std::pow(angle / 0.16, 2));
		}
		return r;
	};
	bodyfit::TriMesh m = starShape(radius, 96, 64, Eigen::Vector3d(0.0, 0.0, 0.0));
	const double yMin = m.V.col(1).minCoeff();
	m.V.col(1).array() -= yMin;
	return m;
}

/// The same surface with vertices and faces in a shuffled order. `newIndex[old]` is where vertex `old` went.
inline bodyfit::TriMesh shuffled(const bodyfit::TriMesh& mesh, unsigned seed, std::vector<int>* newIndex)
{
	std::mt19937 rng(seed);
	const int n = mesh.vertexCount();
	std::vector<int> order(static_cast<size_t>(n));
	std::iota(order.begin(), order.end(), 0);
	std::shuffle(order.begin(), order.end(), rng); // order[new] = old
	newIndex->assign(size_t(n), -1);
	bodyfit::TriMesh out;
	out.V.resize(n, 3);
	for (int i = 0; i < n; ++i)
	{
		(*newIndex)[size_t(order[size_t(i)])] = i;
		out.V.row(i) = mesh.V.row(order[size_t(i)]);
	}
	std::vector<int> faceOrder(static_cast<size_t>(mesh.faceCount()));
	std::iota(faceOrder.begin(), faceOrder.end(), 0);
	std::shuffle(faceOrder.begin(), faceOrder.end(), rng);
	out.F.resize(mesh.faceCount(), 3);
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		const int g = faceOrder[size_t(f)];
		const int rot = f % 3; // also rotate the corner order (same orientation)
		for (int k = 0; k < 3; ++k)
			out.F(f, k) = (*newIndex)[size_t(mesh.F(g, (k + rot) % 3))];
	}
	return out;
}

/// Mirror image x -> -x (faces flipped so they stay outward-facing).
inline bodyfit::TriMesh mirroredX(const bodyfit::TriMesh& mesh)
{
	bodyfit::TriMesh out = mesh;
	out.V.col(0) = -out.V.col(0);
	out.F.col(1).swap(out.F.col(2));
	return out;
}

/// The two meshes as one (b's vertices after a's; no vertex shared): b becomes a separate component.
inline bodyfit::TriMesh appended(const bodyfit::TriMesh& a, const bodyfit::TriMesh& b)
{
	bodyfit::TriMesh out;
	out.V.resize(a.V.rows() + b.V.rows(), 3);
	out.V << a.V, b.V;
	out.F.resize(a.F.rows() + b.F.rows(), 3);
	out.F << a.F, (b.F.array() + int(a.V.rows())).matrix();
	return out;
}

/// Cuts the faces for which `selected(face)` holds off the mesh as a separate mesh moved by `offset`, as a game
/// asset's separate head or hands: their vertices move, and those they share with the other faces are duplicated
/// (the copies come after the input's vertices), so the cut stays open on both sides. Vertex i of the input is
/// still vertex i (moved when only selected faces use it); `copyOf`, when given, receives for each input vertex the
/// index of its moved copy or of itself when it moved, -1 when it stays.
inline bodyfit::TriMesh detached(const bodyfit::TriMesh& mesh, const std::function<bool(int)>& selected,
	const Eigen::Vector3d& offset, std::vector<int>* copyOf = nullptr)
{
	const int n = mesh.vertexCount();
	std::vector<char> bySelected(size_t(n), 0), byRest(size_t(n), 0);
	for (int f = 0; f < mesh.faceCount(); ++f)
		for (int k = 0; k < 3; ++k)
			(selected(f) ? bySelected : byRest)[size_t(mesh.F(f, k))] = 1;
	std::vector<int> copy(size_t(n), -1);
	int next = n;
	for (int v = 0; v < n; ++v)
		if (bySelected[size_t(v)])
			copy[size_t(v)] = byRest[size_t(v)] ? next++ : v;
	bodyfit::TriMesh out;
	out.V.resize(next, 3);
	out.V.topRows(n) = mesh.V;
	for (int v = 0; v < n; ++v)
		if (copy[size_t(v)] >= 0)
			out.V.row(copy[size_t(v)]) = mesh.V.row(v) + offset.transpose();
	out.F = mesh.F;
	for (int f = 0; f < mesh.faceCount(); ++f)
		if (selected(f))
			for (int k = 0; k < 3; ++k)
				out.F(f, k) = copy[size_t(mesh.F(f, k))];
	if (copyOf)
		*copyOf = copy;
	return out;
}

/// One level of red-green refinement of the faces for which `selected(mesh, face)` holds: those are cut into four
/// at their edge midpoints, and every other face that shares a cut edge is split into two or three so that the mesh
/// stays conforming (no T-junctions). The surface does not change (midpoints lie on the flat triangles); vertex i of
/// the input stays vertex i, midpoints are appended. Orientation is kept.
inline bodyfit::TriMesh refinedWhere(const bodyfit::TriMesh& mesh,
	const std::function<bool(const bodyfit::TriMesh&, int)>& selected)
{
	std::vector<std::array<int, 3>> faces;
	std::vector<Eigen::Vector3d> added;
	std::map<std::pair<int, int>, int> midpoint;
	const int n = mesh.vertexCount();
	auto key = [](int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); };
	for (int f = 0; f < mesh.faceCount(); ++f)
		if (selected(mesh, f))
			for (int k = 0; k < 3; ++k)
			{
				const auto e = key(mesh.F(f, k), mesh.F(f, (k + 1) % 3));
				if (midpoint.emplace(e, n + int(added.size())).second)
					added.push_back(0.5 * (mesh.V.row(e.first) + mesh.V.row(e.second)).transpose());
			}
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		std::array<int, 3> v{}, m{};
		int cut = 0;
		for (int k = 0; k < 3; ++k)
		{
			v[size_t(k)] = mesh.F(f, k);
			const auto it = midpoint.find(key(mesh.F(f, k), mesh.F(f, (k + 1) % 3)));
			m[size_t(k)] = it == midpoint.end() ? -1 : it->second; // m[k] on edge v[k] -> v[k + 1]
			cut += m[size_t(k)] >= 0 ? 1 : 0;
		}
		if (cut == 0)
			faces.push_back(v);
		else if (cut == 3)
		{
			faces.push_back({v[0], m[0], m[2]});
			faces.push_back({m[0], v[1], m[1]});
			faces.push_back({m[2], m[1], v[2]});
			faces.push_back({m[0], m[1], m[2]});
		}
		else
		{
			// Rotate so that the cut edges come first: edge 0 (one cut) or edges 0 and 1 (two cuts).
			int r = 0;
			while (!(m[size_t(r)] >= 0 && (cut == 1 || m[size_t((r + 1) % 3)] >= 0)))
				++r;
			const int a = v[size_t(r)], b = v[size_t((r + 1) % 3)], c = v[size_t((r + 2) % 3)];
			const int mab = m[size_t(r)], mbc = m[size_t((r + 1) % 3)];
			if (cut == 1)
			{
				faces.push_back({a, mab, c});
				faces.push_back({mab, b, c});
			}
			else
			{
				faces.push_back({mab, b, mbc});
				faces.push_back({a, mab, mbc});
				faces.push_back({a, mbc, c});
			}
		}
	}
	bodyfit::TriMesh out;
	out.V.resize(n + int(added.size()), 3);
	out.V.topRows(n) = mesh.V;
	for (size_t i = 0; i < added.size(); ++i)
		out.V.row(n + int(i)) = added[i].transpose();
	out.F.resize(int(faces.size()), 3);
	for (size_t f = 0; f < faces.size(); ++f)
		out.F.row(int(f)) << faces[f][0], faces[f][1], faces[f][2];
	return out;
}

} // namespace bodyfit_test

