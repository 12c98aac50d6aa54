#pragma once
/// \file geodesics.h
/// Approximate geodesic distances on a triangle mesh: Dijkstra on the edge graph (the paper's approximation,
/// docs/DESIGN.md sec. 2), optionally with face-diagonal edges that shorten the metrication error.
///
/// Face-diagonal edges: for two triangles (a, b, c) and (b, a, d) sharing the edge ab, the quad is unfolded into the
/// plane; when the straight segment c-d crosses ab inside the edge (the unfolded quad is convex) it is a true path on
/// the surface, so its length is added as an extra edge c-d. Every graph path is still a surface path, so distances
/// stay upper bounds of the exact geodesic distance, only tighter (measured against great-circle distances on a
/// sphere in tests/fitting/test_geodesics.cpp).

#include "bodyfit/fitting/types.h"

#include <limits>
#include <utility>
#include <vector>

namespace bodyfit
{

struct GeodesicOptions
{
	bool faceDiagonals = true; ///< add the unfolded face-diagonal edges described above
	/// Threads that build the graph (0 = every hardware thread); the graph is the same for any count.
	int threads = 0;
};

/// The edge graph of a mesh with reusable Dijkstra buffers (an indexed 4-ary heap). Build once, query many times; not thread-safe
/// (one solver per thread). Distances to vertices that cannot be reached are +infinity.
class GeodesicSolver
{
public:
	static constexpr double kInfinity = std::numeric_limits<double>::infinity();

	explicit GeodesicSolver(const TriMesh& mesh, const GeodesicOptions& options = {});
	/// With extra "bridge" edges (vertex pairs, length = their distance) that join separate components of a body
	/// (components.h); bridges count as mesh edges in isMeshEdge (they are adjacency, not face diagonals).
	GeodesicSolver(const TriMesh& mesh, const GeodesicOptions& options, const std::vector<std::pair<int, int>>& bridges);

	int vertexCount() const { return int(offsets_.size()) - 1; }
	/// Number of undirected graph edges (mesh edges + face diagonals).
	int edgeCount() const { return int(targets_.size()) / 2; }

	/// Distances from the nearest of `sources` to every vertex (multi-source Dijkstra). `distances` is resized to
	/// the vertex count; vertices farther than `maxDistance` keep +infinity (the search stops there).
	/// When `predecessors` is given, it receives for each vertex the previous vertex of its shortest path
	/// (-1 for sources and unreached vertices). Sources outside [0, vertexCount) are ignored.
	void compute(const std::vector<int>& sources, std::vector<double>& distances,
		std::vector<int>* predecessors = nullptr, double maxDistance = kInfinity);
	void compute(int source, std::vector<double>& distances, std::vector<int>* predecessors = nullptr,
		double maxDistance = kInfinity);

	/// Neighbours of vertex v in the graph (mesh edges and face diagonals), as a [begin, end) range of vertex indices.
	std::pair<const int*, const int*> neighbors(int v) const
	{
		return {targets_.data() + offsets_[v], targets_.data() + offsets_[v + 1]};
	}
	/// True when the graph edge at position `edge` (an index into the range returned by neighbors) is a mesh edge
	/// or a bridge (false for face diagonals).
	bool isMeshEdge(const int* edge) const { return isMeshEdge_[size_t(edge - targets_.data())] != 0; }

private:
	std::vector<int> offsets_;        ///< CSR row starts, size n + 1
	std::vector<int> targets_;        ///< neighbour vertex per directed edge
	std::vector<double> weights_;     ///< length per directed edge
	std::vector<char> isMeshEdge_;    ///< 1 for mesh edges, 0 for face diagonals
	std::vector<std::pair<double, int>> heap_; ///< reused 4-ary heap (distance, vertex) with decrease-key
	std::vector<int> heapPosition_;            ///< per vertex: its index in heap_, -1 when absent
};

/// Vertices of the shortest path from the source to `target`, source first, read from a predecessor array filled by
/// GeodesicSolver::compute. For a target that was not reached (infinite distance) the result is just {target}; check
/// the distance first. Empty when `target` is out of range. An array not made by compute is read safely: a
/// predecessor out of range ends the path there, and a cycle ends it after predecessors.size() + 1 vertices.
std::vector<int> tracePath(const std::vector<int>& predecessors, int target);

/// One-off convenience: distances from `sources` (builds a solver each call).
std::vector<double> geodesicDistances(const TriMesh& mesh, const std::vector<int>& sources,
	const GeodesicOptions& options = {});

} // namespace bodyfit
