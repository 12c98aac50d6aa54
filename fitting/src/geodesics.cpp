/// \file geodesics.cpp
/// Dijkstra on the edge graph of a triangle mesh (+ unfolded face diagonals), CSR storage, reused binary heap.

#include "bodyfit/fitting/geodesics.h"

#include "bodyfit/fitting/parallel.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace bodyfit
{

namespace
{

struct WeightedEdge
{
	int a, b;      ///< a < b
	double length;
	char mesh;     ///< 1 = mesh edge
};

/// Length of the unfolded diagonal c-d across the shared edge ab of triangles (a, b, c) and (b, a, d), or a negative
/// value when the unfolded quad is not convex (the straight segment would leave the two triangles).
double unfoldedDiagonal(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
	const Eigen::Vector3d& d)
{
	const Eigen::Vector3d ab = b - a;
	const double lab = ab.norm();
	if (!(lab > 0.0))
		return -1.0;
	const Eigen::Vector3d ex = ab / lab;
	// 2D coordinates in the plane of the unfolding: a = (0, 0), b = (lab, 0), c above the axis, d below it.
	const Eigen::Vector3d ac = c - a, ad = d - a;
	const double cx = ac.dot(ex), cy = (ac - cx * ex).norm();
	const double dx = ad.dot(ex), dy = -(ad - dx * ex).norm();
	if (!(cy > 0.0) || !(dy < 0.0))
		return -1.0;
	// Where the segment c-d crosses the x axis; it must lie strictly inside the edge.
	const double t = cy / (cy - dy);
	const double x = cx + t * (dx - cx);
	if (!(x > 0.0 && x < lab))
		return -1.0;
	return std::sqrt((cx - dx) * (cx - dx) + (cy - dy) * (cy - dy));
}

} // namespace

namespace
{

/// Half-edges a -> b (with the vertex opposite them in their face) grouped by a, by counting sort: O(F), no global
/// sort. A vertex has a handful of half-edges, so twin lookups scan a short list. Faces with an index out of range
/// or a repeated corner are skipped.
struct HalfEdges
{
	struct HalfEdge
	{
		int to, opposite;
	};
	std::vector<int> offset;     ///< half-edges of vertex a: [offset[a], offset[a + 1])
	std::vector<HalfEdge> edges;

	explicit HalfEdges(const TriMesh& mesh)
	{
		const int n = mesh.vertexCount();
		const int m = mesh.faceCount();
		offset.assign(static_cast<size_t>(n) + 1, 0);
		auto valid = [&](int f) {
			for (int k = 0; k < 3; ++k)
			{
				const int v = mesh.F(f, k);
				if (v < 0 || v >= n || v == mesh.F(f, (k + 1) % 3))
					return false;
			}
			return true;
		};
		for (int f = 0; f < m; ++f)
			if (valid(f))
				for (int k = 0; k < 3; ++k)
					++offset[size_t(mesh.F(f, k)) + 1];
		for (int v = 0; v < n; ++v)
			offset[size_t(v) + 1] += offset[size_t(v)];
		edges.resize(static_cast<size_t>(offset[size_t(n)]));
		std::vector<int> fill(offset.begin(), offset.end() - 1);
		for (int f = 0; f < m; ++f)
		{
			if (!valid(f))
				continue;
			for (int k = 0; k < 3; ++k)
				edges[size_t(fill[size_t(mesh.F(f, k))]++)] = {mesh.F(f, (k + 1) % 3), mesh.F(f, (k + 2) % 3)};
		}
		indexLongLists();
	}

	/// Number of half-edges a -> b, and the opposite vertex of the last one found.
	int find(int a, int b, int* opposite) const
	{
		if (const int first = sortedStart.empty() ? -1 : sortedStart[size_t(a)]; first >= 0)
		{
			const auto begin = sorted.begin() + first, end = begin + (offset[size_t(a) + 1] - offset[size_t(a)]);
			const auto range = std::equal_range(begin, end, b, ByTo{});
			if (range.first != range.second)
				*opposite = edges[size_t((range.second - 1)->second)].opposite; // stable: the last in list order
			return int(range.second - range.first);
		}
		int count = 0;
		for (int i = offset[size_t(a)]; i < offset[size_t(a) + 1]; ++i)
		{
			if (edges[size_t(i)].to == b)
			{
				++count;
				*opposite = edges[size_t(i)].opposite;
			}
		}
		return count;
	}

private:
	/// A vertex with more than kLongList half-edges (a fan's hub: a cone's apex, a disc's centre) is searched by
	/// bisection in its half-edges sorted by `to`, so that each of its k neighbours' twin lookups costs log k, not k.
	static constexpr int kLongList = 32;
	std::vector<int> sortedStart;             ///< per vertex: its entries in `sorted`, or -1 (a short list)
	std::vector<std::pair<int, int>> sorted;  ///< (to, half-edge index), stable-sorted by `to` per long vertex
	struct ByTo
	{
		bool operator()(const std::pair<int, int>& e, int to) const { return e.first < to; }
		bool operator()(int to, const std::pair<int, int>& e) const { return to < e.first; }
		bool operator()(const std::pair<int, int>& x, const std::pair<int, int>& y) const { return x.first < y.first; }
	};

	void indexLongLists()
	{
		const int n = int(offset.size()) - 1;
		for (int v = 0; v < n; ++v)
		{
			const int first = offset[size_t(v)], count = offset[size_t(v) + 1] - first;
			if (count <= kLongList)
				continue;
			if (sortedStart.empty())
				sortedStart.assign(size_t(n), -1);
			sortedStart[size_t(v)] = int(sorted.size());
			for (int i = first; i < first + count; ++i)
				sorted.push_back({edges[size_t(i)].to, i});
			std::stable_sort(sorted.end() - count, sorted.end(), ByTo{});
		}
	}
};

/// The graph edges found from the half-edges of vertices [begin, end): every mesh edge once (from its smaller end,
/// or from the only side that has a half-edge), plus (options.faceDiagonals) the unfolded diagonal across every
/// manifold interior edge.
void graphEdgesFrom(const TriMesh& mesh, const HalfEdges& he, const GeodesicOptions& options, int begin, int end,
	std::vector<WeightedEdge>& edges)
{
	for (int a = begin; a < end; ++a)
	{
		for (int i = he.offset[size_t(a)]; i < he.offset[size_t(a) + 1]; ++i)
		{
			const int b = he.edges[size_t(i)].to;
			int d = -1;
			const int twins = he.find(b, a, &d);
			if (a > b && twins > 0)
				continue;
			const Eigen::Vector3d pa = mesh.V.row(a).transpose(), pb = mesh.V.row(b).transpose();
			edges.push_back({std::min(a, b), std::max(a, b), (pa - pb).norm(), 1});
			// A manifold interior edge has exactly one half-edge each way; others get no diagonal.
			const int c = he.edges[size_t(i)].opposite;
			if (options.faceDiagonals && twins == 1 && c != d)
			{
				const double len = unfoldedDiagonal(pa, pb, mesh.V.row(c).transpose(), mesh.V.row(d).transpose());
				if (len > 0.0)
					edges.push_back({std::min(c, d), std::max(c, d), len, 0});
			}
		}
	}
}

/// The edges of the graph, vertex by vertex (graphEdgesFrom over every vertex; vertex ranges on `threads`,
/// concatenated in vertex order, so the list does not depend on the thread count).
std::vector<WeightedEdge> graphEdges(const TriMesh& mesh, const GeodesicOptions& options, int threads)
{
	const int n = mesh.vertexCount();
	const HalfEdges he(mesh);
	std::vector<std::vector<WeightedEdge>> parts(size_t(std::max(1, threads)));
	parallelParts(n, threads, [&](int part, int begin, int end) {
		parts[size_t(part)].reserve(size_t(he.offset[size_t(end)] - he.offset[size_t(begin)]) * 2);
		graphEdgesFrom(mesh, he, options, begin, end, parts[size_t(part)]);
	});
	std::vector<WeightedEdge> edges = std::move(parts[0]);
	for (size_t p = 1; p < parts.size(); ++p)
		edges.insert(edges.end(), parts[p].begin(), parts[p].end());
	return edges;
}

/// One directed edge of a vertex before the neighbours are sorted and merged.
struct Entry
{
	int to;
	double length;
	char mesh;
};

/// Sorts a vertex's entries by neighbour, then length, mesh edges first (a total order on distinct entries, so the
/// result does not depend on the sort), and returns the number of distinct neighbours.
int sortNeighbours(Entry* first, Entry* last)
{
	std::sort(first, last, [](const Entry& x, const Entry& y) {
		if (x.to != y.to)
			return x.to < y.to;
		if (x.length != y.length)
			return x.length < y.length;
		return x.mesh > y.mesh;
	});
	int count = 0;
	for (const Entry* it = first; it != last; ++it)
		count += it == first || it->to != (it - 1)->to ? 1 : 0;
	return count;
}

} // namespace

GeodesicSolver::GeodesicSolver(const TriMesh& mesh, const GeodesicOptions& options)
	: GeodesicSolver(mesh, options, {})
{
}

GeodesicSolver::GeodesicSolver(const TriMesh& mesh, const GeodesicOptions& options,
	const std::vector<std::pair<int, int>>& bridges)
{
	const int n = mesh.vertexCount();
	const int threads = resolveThreads(options.threads);
	std::vector<WeightedEdge> edges = graphEdges(mesh, options, threads);
	for (const auto& [a, b] : bridges)
		if (a >= 0 && a < n && b >= 0 && b < n && a != b)
			edges.push_back({std::min(a, b), std::max(a, b), (mesh.V.row(a) - mesh.V.row(b)).norm(), 1});

	// CSR adjacency; then one record per vertex pair (the shortest; a mesh edge wins a tie), sorted by neighbour.
	std::vector<int> degree(static_cast<size_t>(n) + 1, 0);
	for (const WeightedEdge& e : edges)
	{
		++degree[size_t(e.a) + 1];
		++degree[size_t(e.b) + 1];
	}
	for (int v = 0; v < n; ++v)
		degree[size_t(v) + 1] += degree[size_t(v)];
	std::vector<Entry> entries(edges.size() * 2);
	{
		std::vector<int> fill(degree.begin(), degree.end() - 1);
		for (const WeightedEdge& e : edges)
		{
			entries[size_t(fill[size_t(e.a)]++)] = {e.b, e.length, e.mesh};
			entries[size_t(fill[size_t(e.b)]++)] = {e.a, e.length, e.mesh};
		}
	}
	// Per vertex (in parallel: each vertex owns its range): sort, and count the distinct neighbours.
	std::vector<int> distinct(static_cast<size_t>(n), 0);
	parallelRanges(n, threads, [&](int begin, int end) {
		for (int v = begin; v < end; ++v)
			distinct[size_t(v)] = sortNeighbours(entries.data() + degree[size_t(v)], entries.data() + degree[size_t(v) + 1]);
	});
	offsets_.assign(static_cast<size_t>(n) + 1, 0);
	for (int v = 0; v < n; ++v)
		offsets_[size_t(v) + 1] = offsets_[size_t(v)] + distinct[size_t(v)];
	targets_.resize(size_t(offsets_[size_t(n)]));
	weights_.resize(targets_.size());
	isMeshEdge_.resize(targets_.size());
	parallelRanges(n, threads, [&](int begin, int end) {
		for (int v = begin; v < end; ++v)
		{
			const Entry* first = entries.data() + degree[size_t(v)];
			int out = offsets_[size_t(v)];
			for (const Entry* it = first; it != entries.data() + degree[size_t(v) + 1]; ++it)
			{
				if (it != first && it->to == (it - 1)->to)
					continue;
				targets_[size_t(out)] = it->to;
				weights_[size_t(out)] = it->length;
				isMeshEdge_[size_t(out)] = it->mesh;
				++out;
			}
		}
	});
	heap_.reserve(static_cast<size_t>(n));
}

namespace
{

/// Indexed 4-ary min-heap on (distance, vertex) with decrease-key: every vertex is in the heap at most once, so
/// there are no stale entries. The vertex index breaks ties, so the pop order never depends on heap internals.
struct VertexHeap
{
	std::vector<std::pair<double, int>>& items;
	std::vector<int>& position; ///< index in `items` per vertex, -1 when not in the heap

	static bool less(const std::pair<double, int>& x, const std::pair<double, int>& y) { return x < y; }

	void place(size_t i, const std::pair<double, int>& item)
	{
		items[i] = item;
		position[size_t(item.second)] = int(i);
	}
	void siftUp(size_t i, std::pair<double, int> item)
	{
		while (i > 0)
		{
			const size_t parent = (i - 1) / 4;
			if (!less(item, items[parent]))
				break;
			place(i, items[parent]);
			i = parent;
		}
		place(i, item);
	}
	void siftDown(size_t i, std::pair<double, int> item)
	{
		const size_t size = items.size();
		for (;;)
		{
			const size_t first = 4 * i + 1;
			if (first >= size)
				break;
			size_t best = first;
			const size_t last = std::min(first + 4, size);
			for (size_t c = first + 1; c < last; ++c)
				if (less(items[c], items[best]))
					best = c;
			if (!less(items[best], item))
				break;
			place(i, items[best]);
			i = best;
		}
		place(i, item);
	}
	/// Inserts v or lowers its key.
	void push(double key, int v)
	{
		const int at = position[size_t(v)];
		if (at < 0)
		{
			items.emplace_back(key, v);
			siftUp(items.size() - 1, {key, v});
		}
		else
			siftUp(size_t(at), {key, v});
	}
	std::pair<double, int> pop()
	{
		const std::pair<double, int> top = items.front();
		position[size_t(top.second)] = -1;
		const std::pair<double, int> last = items.back();
		items.pop_back();
		if (!items.empty())
			siftDown(0, last);
		return top;
	}
};

} // namespace

void GeodesicSolver::compute(const std::vector<int>& sources, std::vector<double>& distances,
	std::vector<int>* predecessors, double maxDistance)
{
	const int n = vertexCount();
	distances.assign(size_t(n), kInfinity);
	if (predecessors)
		predecessors->assign(size_t(n), -1);
	heap_.clear();
	heapPosition_.assign(size_t(n), -1);
	VertexHeap heap{heap_, heapPosition_};
	for (int s : sources)
	{
		if (s < 0 || s >= n || distances[size_t(s)] == 0.0)
			continue;
		distances[size_t(s)] = 0.0;
		heap.push(0.0, s);
	}
	while (!heap_.empty())
	{
		const auto [d, v] = heap.pop();
		for (int k = offsets_[size_t(v)]; k < offsets_[size_t(v) + 1]; ++k)
		{
			const int w = targets_[size_t(k)];
			const double dw = d + weights_[size_t(k)];
			if (dw < distances[size_t(w)] && dw <= maxDistance)
			{
				distances[size_t(w)] = dw;
				if (predecessors)
					(*predecessors)[size_t(w)] = v;
				heap.push(dw, w);
			}
		}
	}
}

void GeodesicSolver::compute(int source, std::vector<double>& distances, std::vector<int>* predecessors,
	double maxDistance)
{
	compute(std::vector<int>{source}, distances, predecessors, maxDistance);
}

std::vector<int> tracePath(const std::vector<int>& predecessors, int target)
{
	std::vector<int> path;
	if (target < 0 || target >= int(predecessors.size()))
		return path;
	// Bounded by the array both ways: a predecessor out of range ends the path, a cycle stops after size + 1 steps
	// (neither comes out of GeodesicSolver::compute; an array made elsewhere is read, never past its end).
	for (int v = target; v >= 0 && v < int(predecessors.size()) && path.size() <= predecessors.size();
		 v = predecessors[size_t(v)])
		path.push_back(v);
	std::reverse(path.begin(), path.end());
	return path;
}

std::vector<double> geodesicDistances(const TriMesh& mesh, const std::vector<int>& sources,
	const GeodesicOptions& options)
{
	GeodesicSolver solver(mesh, options);
	std::vector<double> distances;
	solver.compute(sources, distances);
	return distances;
}

} // namespace bodyfit
