// Geodesic distances: Dijkstra on the edge graph (+ unfolded face diagonals) against exact distances on a plane and
// a sphere, multi-source and truncated queries, buffer reuse, shortest-path tracing, unreachable vertices.
#include "bodyfit/fitting/geodesics.h"
#include "support/mesh_shapes.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

using namespace bodyfit;
using bodyfit_test::flatGrid;
using bodyfit_test::uvSphere;

namespace
{

struct ErrorStats
{
	double meanAbs = 0.0;                                     ///< mean |approx - exact| / exact
	double max = -std::numeric_limits<double>::infinity();    ///< largest (approx - exact) / exact
	double min = std::numeric_limits<double>::infinity();     ///< smallest (approx - exact) / exact
};

/// Relative errors over the vertices whose exact distance is at least `minExact` (very short distances have large
/// relative errors from the first edge alone and say nothing about the method).
ErrorStats relativeErrors(const std::vector<double>& approx, const std::vector<double>& exact, double minExact)
{
	ErrorStats s;
	int count = 0;
	for (size_t i = 0; i < exact.size(); ++i)
	{
		if (exact[i] < minExact)
			continue;
		const double e = (approx[i] - exact[i]) / exact[i];
		s.meanAbs += std::abs(e);
		s.max = std::max(s.max, e);
		s.min = std::min(s.min, e);
		++count;
	}
	s.meanAbs /= std::max(count, 1);
	return s;
}

ErrorStats gridErrors(bool faceDiagonals)
{
	const int n = 41, centre = 20 * n + 20;
	const TriMesh grid = flatGrid(n, 0.01);
	GeodesicOptions options;
	options.faceDiagonals = faceDiagonals;
	GeodesicSolver solver(grid, options);
	std::vector<double> d;
	solver.compute(centre, d);
	std::vector<double> exact(d.size());
	for (int v = 0; v < grid.vertexCount(); ++v)
		exact[size_t(v)] = (grid.V.row(v) - grid.V.row(centre)).norm();
	return relativeErrors(d, exact, 0.05);
}

ErrorStats sphereErrors(bool faceDiagonals)
{
	// Source on the equator, where no mesh edge follows most great circles.
	const TriMesh sphere = uvSphere(1.0, 64, 32);
	const int source = 1 + 15 * 64;
	GeodesicOptions options;
	options.faceDiagonals = faceDiagonals;
	GeodesicSolver solver(sphere, options);
	std::vector<double> d;
	solver.compute(source, d);
	const Eigen::Vector3d p = sphere.V.row(source).normalized();
	std::vector<double> exact(d.size());
	for (int v = 0; v < sphere.vertexCount(); ++v)
		exact[size_t(v)] = std::acos(std::clamp(Eigen::Vector3d(sphere.V.row(v)).normalized().dot(p), -1.0, 1.0));
	return relativeErrors(d, exact, 0.2);
}

} // namespace

TEST_CASE("geodesics: flat grid distances are upper bounds within the graph's angular error", "[fitting][geodesics]")
{
	// Edge graph of a grid split along one diagonal: directions 0/45/90 degrees only, so the anti-diagonal is walked
	// as a staircase: worst case sqrt(2) - 1 = 41.4% too long. Face diagonals add the other diagonal (8 directions):
	// worst case 1 / cos(22.5 deg) - 1 = 8.24%.
	const ErrorStats plain = gridErrors(false);
	const ErrorStats diag = gridErrors(true);
	CHECK(plain.min >= -1e-12); // every graph path is a surface path: never shorter than the straight line
	CHECK(diag.min >= -1e-12);
	CHECK(plain.max == Approx(std::sqrt(2.0) - 1.0).margin(1e-9));
	CHECK(diag.max <= 1.0 / std::cos(std::acos(-1.0) / 8.0) - 1.0 + 1e-9);
	// Measured means: 17.4% and 3.3%; the diagonals must cut the mean error at least 4x.
	CHECK(diag.meanAbs < plain.meanAbs / 4.0);
}

TEST_CASE("geodesics: sphere distances follow great circles", "[fitting][geodesics]")
{
	const ErrorStats plain = sphereErrors(false);
	const ErrorStats diag = sphereErrors(true);
	// The mesh is an inscribed polyhedron (64 x 32), so a path may be shorter than the great circle by the chord /
	// arc ratio of its edges: 1 - cos(pi/64) ~ 0.12%. Allow 0.2% below.
	CHECK(diag.min > -0.002);
	CHECK(plain.min > -0.002);
	// Measured: mean 7.8% / max 40% without diagonals, mean 2.0% / max 7.8% with them (the 8-direction bound).
	CHECK(diag.meanAbs < 0.03);
	CHECK(diag.max < 0.0824 + 0.005);
	CHECK(diag.meanAbs < plain.meanAbs / 3.0);
}

TEST_CASE("geodesics: several sources give the minimum of the single-source fields", "[fitting][geodesics]")
{
	const TriMesh sphere = uvSphere(1.0, 48, 24);
	GeodesicSolver solver(sphere);
	const std::vector<int> sources = {0, 300, 777};
	std::vector<double> multi, single;
	solver.compute(sources, multi);
	std::vector<double> expected(multi.size(), std::numeric_limits<double>::infinity());
	for (int s : sources)
	{
		solver.compute(s, single); // the same solver: buffers are reused between queries
		for (size_t v = 0; v < single.size(); ++v)
			expected[v] = std::min(expected[v], single[v]);
	}
	// Both are exact minima over the same graph paths: only the summation order can differ (last-bit rounding).
	for (size_t v = 0; v < multi.size(); ++v)
		REQUIRE(multi[v] == Approx(expected[v]).margin(1e-12));
	for (int s : sources)
		CHECK(multi[size_t(s)] == 0.0);
}

TEST_CASE("geodesics: repeated queries are identical and maxDistance truncates", "[fitting][geodesics]")
{
	const TriMesh sphere = uvSphere(1.0, 48, 24);
	GeodesicSolver solver(sphere);
	std::vector<double> a, b, truncated;
	std::vector<int> pa, pb;
	solver.compute(5, a, &pa);
	solver.compute(400, b); // something else in between
	solver.compute(5, b, &pb);
	CHECK(a == b); // bit for bit
	CHECK(pa == pb);
	solver.compute(5, truncated, nullptr, 1.0);
	for (size_t v = 0; v < a.size(); ++v)
	{
		if (a[v] <= 1.0)
			REQUIRE(truncated[v] == a[v]); // the search below the limit is the same search
		else
			REQUIRE(std::isinf(truncated[v]));
	}
}

TEST_CASE("geodesics: traced paths are edge paths whose length is the distance", "[fitting][geodesics]")
{
	const TriMesh sphere = uvSphere(1.0, 48, 24);
	GeodesicSolver solver(sphere);
	std::vector<double> d;
	std::vector<int> pred;
	solver.compute(10, d, &pred);
	for (int target : {0, 200, 600, sphere.vertexCount() - 1})
	{
		const std::vector<int> path = tracePath(pred, target);
		REQUIRE(path.size() >= 2);
		CHECK(path.front() == 10);
		CHECK(path.back() == target);
		double length = 0.0;
		for (size_t i = 1; i < path.size(); ++i)
		{
			// Each step is a graph edge: a neighbour of the previous vertex.
			const auto [begin, end] = solver.neighbors(path[i - 1]);
			CHECK(std::find(begin, end, path[i]) != end);
			length += (sphere.V.row(path[i]) - sphere.V.row(path[i - 1])).norm();
		}
		// Face-diagonal steps are straight lines across two triangles, not chords of the sphere: their unfolded
		// length is at least the 3D chord, so the summed chords can only be shorter (by well under 1%).
		CHECK(length <= d[size_t(target)] + 1e-12);
		CHECK(length >= 0.99 * d[size_t(target)]);
	}
	CHECK(tracePath(pred, -1).empty());
	// Arrays not made by compute: a predecessor past the end ends the path (it was read out of bounds), a cycle is cut.
	CHECK(tracePath({1, 7}, 0) == std::vector<int>{1, 0});
	CHECK(tracePath({1, 0}, 0).size() == 3);
}

TEST_CASE("geodesics: other components stay unreachable", "[fitting][geodesics]")
{
	// Two spheres, no shared vertex.
	const TriMesh a = uvSphere(1.0, 16, 8), b = uvSphere(1.0, 16, 8, Eigen::Vector3d(5, 0, 0));
	TriMesh both;
	both.V.resize(a.vertexCount() + b.vertexCount(), 3);
	both.V << a.V, b.V;
	both.F.resize(a.faceCount() + b.faceCount(), 3);
	both.F << a.F, (b.F.array() + a.vertexCount()).matrix();
	const std::vector<double> d = geodesicDistances(both, {0});
	for (int v = 0; v < both.vertexCount(); ++v)
		REQUIRE(std::isfinite(d[size_t(v)]) == (v < a.vertexCount()));
	// Out-of-range sources are ignored rather than read out of bounds.
	const std::vector<double> none = geodesicDistances(both, {-3, both.vertexCount()});
	for (double x : none)
		REQUIRE(std::isinf(x));
}

TEST_CASE("geodesics: the graph is the same for any thread count", "[fitting][geodesics][threads]")
{
	// The graph is built on GeodesicOptions::threads (vertex ranges, merged in vertex order): 1, 2 and 3 threads
	// give the same neighbours in the same order (so the same distances and predecessors, bit for bit). The shuffled
	// sphere has its edges in no particular vertex order, so the ranges really split the work unevenly.
	std::vector<int> newIndex;
	const TriMesh mesh = bodyfit_test::shuffled(uvSphere(1.0, 48, 24), 7, &newIndex);
	GeodesicOptions one;
	one.threads = 1;
	GeodesicSolver reference(mesh, one);
	std::vector<double> d1;
	std::vector<int> p1;
	reference.compute(0, d1, &p1);
	for (const int threads : {2, 3})
	{
		GeodesicOptions o;
		o.threads = threads;
		GeodesicSolver solver(mesh, o);
		REQUIRE(solver.edgeCount() == reference.edgeCount());
		for (int v = 0; v < mesh.vertexCount(); ++v)
		{
			const auto [a, b] = solver.neighbors(v);
			const auto [c, d] = reference.neighbors(v);
			REQUIRE(std::vector<int>(a, b) == std::vector<int>(c, d));
		}
		std::vector<double> dn;
		std::vector<int> pn;
		solver.compute(0, dn, &pn);
		CHECK(dn == d1);
		CHECK(pn == p1);
	}
}
