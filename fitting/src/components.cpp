/// \file components.cpp
/// Bodies made of several meshes: component roles, bridges between the body's components (see components.h).

#include "bodyfit/fitting/components.h"

#include "bodyfit/fitting/fit_quality.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/mesh_io.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <tuple>
#include <unordered_map>

namespace bodyfit
{

const char* toString(ComponentRole role)
{
	switch (role)
	{
	case ComponentRole::Body: return "body";
	case ComponentRole::Attached: return "attached";
	case ComponentRole::Inside: return "inside";
	case ComponentRole::Detached: return "detached";
	}
	return "unknown";
}

bool ComponentLayout::onBody(int vertex) const
{
	const ComponentRole r = components[size_t(vertexComponent[size_t(vertex)])].role;
	return r == ComponentRole::Body || r == ComponentRole::Attached;
}

bool ComponentLayout::kept(int vertex) const
{
	return components[size_t(vertexComponent[size_t(vertex)])].role != ComponentRole::Detached;
}

int ComponentLayout::count(ComponentRole role) const
{
	return int(std::count_if(components.begin(), components.end(), [&](const MeshComponent& c) { return c.role == role; }));
}

int ComponentLayout::vertexCount(ComponentRole role) const
{
	int n = 0;
	for (const MeshComponent& c : components)
		n += c.role == role ? c.vertices : 0;
	return n;
}

namespace
{

Eigen::Vector3d point(const TriMesh& mesh, int v) { return mesh.V.row(v).transpose(); }

/// A uniform grid over a subset of the vertices: cell key -> the vertices in it (ascending index).
class VertexGrid
{
public:
	VertexGrid(const TriMesh& mesh, const std::vector<char>& include, double cell)
		: inverseCell_(1.0 / cell), origin_(mesh.V.colwise().minCoeff().transpose())
	{
		std::vector<std::pair<uint64_t, int>> keyed;
		for (int v = 0; v < mesh.vertexCount(); ++v)
			if (include[size_t(v)])
				keyed.emplace_back(key(cellOf(point(mesh, v))), v);
		std::sort(keyed.begin(), keyed.end());
		order_.reserve(keyed.size());
		for (size_t i = 0; i < keyed.size(); ++i)
		{
			if (i == 0 || keyed[i].first != keyed[i - 1].first)
				ranges_[keyed[i].first] = {int(i), int(i)};
			++ranges_[keyed[i].first].second;
			order_.push_back(keyed[i].second);
		}
	}

	Eigen::Vector3i cellOf(const Eigen::Vector3d& p) const
	{
		const Eigen::Vector3d c = ((p - origin_) * inverseCell_).array().floor();
		return Eigen::Vector3i(int(int64_t(c.x()) & 0x1fffff), int(int64_t(c.y()) & 0x1fffff),
			int(int64_t(c.z()) & 0x1fffff));
	}
	static uint64_t key(const Eigen::Vector3i& c)
	{
		return (uint64_t(uint32_t(c.x()) & 0x1fffff) << 42) | (uint64_t(uint32_t(c.y()) & 0x1fffff) << 21) |
			   uint64_t(uint32_t(c.z()) & 0x1fffff);
	}
	/// The vertices of one cell as a [begin, end) range (empty when the cell has none).
	std::pair<const int*, const int*> cell(const Eigen::Vector3i& c) const
	{
		const auto it = ranges_.find(key(c));
		if (it == ranges_.end())
			return {nullptr, nullptr};
		return {order_.data() + it->second.first, order_.data() + it->second.second};
	}
	/// Calls f(vertex) for every vertex in the cells at Chebyshev cell distance exactly `ring` from p's cell.
	template <class F> void forEachInShell(const Eigen::Vector3d& p, int ring, F&& f) const
	{
		const Eigen::Vector3i c = cellOf(p);
		for (int dx = -ring; dx <= ring; ++dx)
			for (int dy = -ring; dy <= ring; ++dy)
				for (int dz = -ring; dz <= ring; ++dz)
				{
					if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring)
						continue;
					const auto [first, last] = cell(c + Eigen::Vector3i(dx, dy, dz));
					for (const int* v = first; v != last; ++v)
						f(*v);
				}
	}
	double cellSize() const { return 1.0 / inverseCell_; }
	const std::vector<int>& vertices() const { return order_; }

private:
	double inverseCell_;
	Eigen::Vector3d origin_;
	std::unordered_map<uint64_t, std::pair<int, int>> ranges_;
	std::vector<int> order_;
};

struct UnionFind
{
	std::vector<int> parent;
	explicit UnionFind(int n) : parent(size_t(n)) { std::iota(parent.begin(), parent.end(), 0); }
	int find(int a)
	{
		while (parent[size_t(a)] != a)
			a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
		return a;
	}
	void unite(int a, int b)
	{
		a = find(a);
		b = find(b);
		if (a != b)
			parent[size_t(std::max(a, b))] = std::min(a, b); // the smaller index is the root: deterministic
	}
};

/// What the pairwise tests found, before the roles are resolved.
struct Links
{
	UnionFind groups;
	std::vector<int> insideHost;   ///< per component: the component enclosing it, or -1
	std::vector<int> partner;      ///< per component: the nearest other component found (for MeshComponent::host)
	std::vector<double> partnerGap;
	std::map<std::pair<int, int>, char> bridges; ///< ordered: deterministic output
	explicit Links(int k)
		: groups(k), insideHost(size_t(k), -1), partner(size_t(k), -1),
		  partnerGap(size_t(k), std::numeric_limits<double>::infinity())
	{
	}
	void link(int a, int b, double gap)
	{
		groups.unite(a, b);
		for (const auto& [c, other] : {std::make_pair(a, b), std::make_pair(b, a)})
			if (gap < partnerGap[size_t(c)])
			{
				partnerGap[size_t(c)] = gap;
				partner[size_t(c)] = other;
			}
	}
};

/// Per component: 1 when it has a face (a lone, unreferenced vertex is a component without: it encloses nothing and
/// has no surface to measure a gap to).
std::vector<char> componentsWithFaces(const TriMesh& mesh, const std::vector<int>& component, int count)
{
	std::vector<char> has(static_cast<size_t>(count), 0);
	for (int f = 0; f < mesh.faceCount(); ++f)
		has[size_t(component[size_t(mesh.F(f, 0))])] = 1;
	return has;
}

/// The faces of component `id` with only its own vertices (compact: grids over it span its box only).
TriMesh componentMesh(const TriMesh& mesh, const std::vector<int>& component, const std::vector<int>& members, int id)
{
	std::vector<int> local(size_t(mesh.vertexCount()), -1);
	TriMesh out;
	out.V.resize(Eigen::Index(members.size()), 3);
	for (size_t i = 0; i < members.size(); ++i)
	{
		local[size_t(members[i])] = int(i);
		out.V.row(Eigen::Index(i)) = mesh.V.row(members[i]);
	}
	std::vector<int> faces;
	for (int f = 0; f < mesh.faceCount(); ++f)
		if (component[size_t(mesh.F(f, 0))] == id)
			faces.push_back(f);
	out.F.resize(Eigen::Index(faces.size()), 3);
	for (size_t i = 0; i < faces.size(); ++i)
		for (int k = 0; k < 3; ++k)
			out.F(Eigen::Index(i), k) = local[size_t(mesh.F(faces[i], k))];
	return out;
}

/// The nearest vertex of the grid to p: shells of cells outwards, then a linear scan when none is within
/// `maxRing` cells. -1 for an empty grid.
int nearestInGrid(const TriMesh& mesh, const VertexGrid& grid, const Eigen::Vector3d& p, int maxRing = 6)
{
	double best = std::numeric_limits<double>::infinity();
	int found = -1;
	auto consider = [&](int w) {
		const double d2 = (point(mesh, w) - p).squaredNorm();
		if (d2 < best || (d2 == best && w < found))
		{
			best = d2;
			found = w;
		}
	};
	bool done = false;
	for (int ring = 0; ring <= maxRing && !done; ++ring)
	{
		grid.forEachInShell(p, ring, consider);
		done = found >= 0 && std::sqrt(best) <= ring * grid.cellSize(); // the rest is >= ring cells away
	}
	if (!done)
		for (int w : grid.vertices())
			consider(w);
	return found;
}

/// Inside / passing-through tests of every component against the larger ones whose box overlaps its box. A component
/// all of whose samples are inside gets insideHost; one with only some samples inside is linked to its host with a
/// bridge from each inside sample to the host's nearest vertex.
void findEnclosed(const TriMesh& mesh, const std::vector<std::vector<int>>& members, const ComponentLayout& layout,
	int samples, Links& links)
{
	const int k = int(members.size());
	std::vector<Eigen::AlignedBox3d> box(static_cast<size_t>(k));
	for (int c = 0; c < k; ++c)
		for (int v : members[size_t(c)])
			box[size_t(c)].extend(point(mesh, v));
	const std::vector<char> hasFaces = componentsWithFaces(mesh, layout.vertexComponent, k);
	std::map<int, MeshInsideTest> tests; // built on demand
	for (int c = 1; c < k; ++c)
	{
		const std::vector<int>& m = members[size_t(c)];
		const int s = std::min<int>(std::max(samples, 1), int(m.size()));
		std::vector<int> sample(static_cast<size_t>(s));
		for (int i = 0; i < s; ++i)
			sample[size_t(i)] = m[size_t((int64_t(i) * int64_t(m.size())) / s)];
		for (int j = 0; j < c; ++j)
		{
			if (!hasFaces[size_t(j)] || !box[size_t(j)].intersects(box[size_t(c)]))
				continue;
			auto it = tests.find(j);
			if (it == tests.end())
				it = tests.emplace(j, MeshInsideTest(componentMesh(mesh, layout.vertexComponent, members[size_t(j)], j)))
						 .first;
			std::vector<int> inside;
			for (int v : sample)
				if (it->second.isInside(point(mesh, v)))
					inside.push_back(v);
			if (int(inside.size()) == s)
			{
				links.insideHost[size_t(c)] = j;
				break;
			}
			for (int v : inside)
			{
				int nearest = -1;
				double best = std::numeric_limits<double>::infinity();
				for (int w : members[size_t(j)])
				{
					const double d2 = (point(mesh, w) - point(mesh, v)).squaredNorm();
					if (d2 < best)
					{
						best = d2;
						nearest = w;
					}
				}
				links.bridges[{std::min(v, nearest), std::max(v, nearest)}] = 1;
			}
			if (!inside.empty())
				links.link(c, j, 0.0);
		}
	}
}

/// Proximity: a component whose vertices come closer than the gap to the surface of a larger one (exact
/// point-to-triangle distance, MeshDistanceGrid) is linked to it, with a bridge from each such vertex to the
/// nearest vertex of the larger one. Enclosed components take no part.
void findNearby(const TriMesh& mesh, const std::vector<std::vector<int>>& members, const ComponentLayout& layout,
	Links& links)
{
	const int k = int(members.size());
	std::vector<Eigen::AlignedBox3d> reach(static_cast<size_t>(k)); // box grown by the gap
	for (int c = 0; c < k; ++c)
	{
		for (int v : members[size_t(c)])
			reach[size_t(c)].extend(point(mesh, v));
		reach[size_t(c)].extend(reach[size_t(c)].min() - Eigen::Vector3d::Constant(layout.gap));
		reach[size_t(c)].extend(reach[size_t(c)].max() + Eigen::Vector3d::Constant(layout.gap));
	}
	const std::vector<char> hasFaces = componentsWithFaces(mesh, layout.vertexComponent, k);
	std::map<int, std::pair<MeshDistanceGrid, VertexGrid>> grids; // built on demand
	for (int c = 1; c < k; ++c)
	{
		if (links.insideHost[size_t(c)] >= 0)
			continue;
		for (int j = 0; j < c; ++j)
		{
			if (links.insideHost[size_t(j)] >= 0 || !hasFaces[size_t(j)] || !reach[size_t(j)].intersects(reach[size_t(c)]))
				continue;
			auto it = grids.find(j);
			if (it == grids.end())
			{
				std::vector<char> own(size_t(mesh.vertexCount()), 0);
				for (int v : members[size_t(j)])
					own[size_t(v)] = 1;
				it = grids.emplace(std::piecewise_construct, std::forward_as_tuple(j),
						 std::forward_as_tuple(componentMesh(mesh, layout.vertexComponent, members[size_t(j)], j),
							 VertexGrid(mesh, own, layout.gap)))
						 .first;
			}
			double closest = std::numeric_limits<double>::infinity();
			for (int v : members[size_t(c)])
			{
				const Eigen::Vector3d p = point(mesh, v);
				if (!reach[size_t(j)].contains(p))
					continue;
				const double d = it->second.first.distance(p);
				if (!(d < layout.gap))
					continue;
				closest = std::min(closest, d);
				const int w = nearestInGrid(mesh, it->second.second, p);
				links.bridges[{std::min(v, w), std::max(v, w)}] = 1;
			}
			if (closest < layout.gap)
				links.link(c, j, closest);
		}
	}
}

/// Roles from the links: the group of component 0 is the body; an enclosed component takes the fate of the
/// outermost component enclosing it.
void resolveRoles(const Links& constLinks, ComponentLayout& layout)
{
	Links links = constLinks;
	const int k = int(layout.components.size());
	const int body = links.groups.find(0);
	for (int c = 0; c < k; ++c)
	{
		MeshComponent& mc = layout.components[size_t(c)];
		int outer = c;
		while (links.insideHost[size_t(outer)] >= 0)
			outer = links.insideHost[size_t(outer)]; // hosts have lower indices: terminates
		const bool inBody = links.groups.find(outer) == body;
		if (outer != c)
		{
			mc.role = inBody ? ComponentRole::Inside : ComponentRole::Detached;
			mc.host = links.insideHost[size_t(c)];
		}
		else
		{
			mc.role = c == 0 ? ComponentRole::Body : inBody ? ComponentRole::Attached : ComponentRole::Detached;
			mc.host = c == 0 ? -1 : links.partner[size_t(c)];
		}
	}
	for (const auto& bridge : links.bridges)
		if (layout.onBody(bridge.first.first) && layout.onBody(bridge.first.second))
			layout.bridges.push_back(bridge.first);
}

} // namespace

ComponentLayout analyzeComponents(const TriMesh& mesh, const ComponentOptions& options)
{
	ComponentLayout layout;
	int k = 0;
	layout.vertexComponent = connectedComponents(mesh, &k);
	layout.components.assign(size_t(std::max(k, 1)), MeshComponent{});
	std::vector<std::vector<int>> members(size_t(std::max(k, 1)));
	for (int v = 0; v < mesh.vertexCount(); ++v)
		members[size_t(layout.vertexComponent[size_t(v)])].push_back(v);
	for (int c = 0; c < k; ++c)
		layout.components[size_t(c)].vertices = int(members[size_t(c)].size());
	if (k <= 1)
		return layout;
	Eigen::AlignedBox3d bodyBox;
	for (int v : members[0])
		bodyBox.extend(point(mesh, v));
	layout.gap = options.relativeGap * bodyBox.sizes().maxCoeff();

	Links links(k);
	findEnclosed(mesh, members, layout, options.insideSamples, links);
	if (layout.gap > 0.0)
		findNearby(mesh, members, layout, links);
	resolveRoles(links, layout);
	return layout;
}

std::vector<int> nearestBodyVertex(const TriMesh& mesh, const ComponentLayout& layout)
{
	const int n = mesh.vertexCount();
	std::vector<int> nearest(static_cast<size_t>(n));
	std::iota(nearest.begin(), nearest.end(), 0);
	std::vector<char> body(size_t(n), 0);
	bool any = false, all = true;
	for (int v = 0; v < n; ++v)
	{
		body[size_t(v)] = layout.onBody(v);
		any = any || body[size_t(v)];
		all = all && body[size_t(v)];
	}
	if (!any || all)
		return nearest;
	const VertexGrid grid(mesh, body, layout.gap > 0.0 ? layout.gap : 1.0);
	for (int v = 0; v < n; ++v)
		if (!body[size_t(v)])
			nearest[size_t(v)] = nearestInGrid(mesh, grid, point(mesh, v));
	return nearest;
}

std::vector<std::string> componentWarnings(const ComponentLayout& layout)
{
	std::vector<std::string> warnings;
	char gap[32];
	std::snprintf(gap, sizeof gap, "%.1f mm", layout.gap * 1000.0);
	auto counted = [&](ComponentRole role, const char* one, const char* many) {
		const int c = layout.count(role);
		return std::to_string(c) + " " + (c == 1 ? one : many) + " (" + std::to_string(layout.vertexCount(role)) +
			   " vertices)";
	};
	if (layout.count(ComponentRole::Attached) > 0)
		warnings.push_back("the body is made of several meshes: " +
						   counted(ComponentRole::Attached, "separate part", "separate parts") +
						   " closer than " + gap + " to the body or passing through it joined to it "
						   "(bridged for the segmentation, fitted with it)");
	if (layout.count(ComponentRole::Inside) > 0)
		warnings.push_back(counted(ComponentRole::Inside, "component", "components") +
						   " inside the body (eyes, teeth?) fitted with the region around them");
	if (layout.count(ComponentRole::Detached) > 0)
		warnings.push_back(counted(ComponentRole::Detached, "detached component", "detached components") +
						   " farther than " + gap + " from the body ignored (not fitted)");
	return warnings;
}

} // namespace bodyfit
