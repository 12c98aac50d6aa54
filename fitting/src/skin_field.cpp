// The skin field: layout queries and the bake. The method and its guarantees are in skin_field.h.
#include "bodyfit/fitting/skin_field.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/parallel.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <utility>

namespace bodyfit
{

namespace
{

constexpr int B = kSkinBrickEdge;
constexpr int kOwned = B * B * B;    ///< lattice points a brick owns: local (a, b, c) in [0, B)^3
constexpr int kMaxQuanta = 32767;

/// A length in metres as "5 mm" (3 significant digits), for the errors.
std::string millimetres(double metres)
{
	char text[32];
	std::snprintf(text, sizeof text, "%.3g mm", metres * 1e3);
	return text;
}

/// Where a point falls in the grid: its brick, its cell in the brick, and the trilinear weights.
struct CellLocation
{
	int brick[3];
	int cell[3];   ///< in [0, B)
	double frac[3]; ///< in [0, 1]
};

/// The brick and cell that the field at p reads (skin_field.h: floor per axis). False when p is outside the grid
/// [o, o + B h (nx, ny, nz)) (or not finite).
bool locateCell(const Eigen::Vector3d& origin, double h, const int dims[3], const Eigen::Vector3d& p, CellLocation& out)
{
	for (int k = 0; k < 3; ++k)
	{
		const double u = (p[k] - origin[k]) / h; // voxel units
		if (!(u >= 0.0 && u < double(dims[k]) * B)) // the grid's upper faces are outside, as in btSkinDistanceField
			return false;
		out.brick[k] = std::min(int(u / B), dims[k] - 1); // u >= 0: truncation is floor
		const double local = u - double(out.brick[k]) * B;
		out.cell[k] = std::min(int(local), B - 1);
		out.frac[k] = std::clamp(local - out.cell[k], 0.0, 1.0);
	}
	return true;
}

/// Trilinear interpolation of the 8 corners of a cell; value(dx, dy, dz) returns the corner's quanta.
template <class CornerValue>
double trilinear(const CellLocation& c, CornerValue value)
{
	double sum = 0.0;
	for (int dz = 0; dz < 2; ++dz)
		for (int dy = 0; dy < 2; ++dy)
			for (int dx = 0; dx < 2; ++dx)
			{
				const double w = (dx ? c.frac[0] : 1.0 - c.frac[0]) * (dy ? c.frac[1] : 1.0 - c.frac[1]) *
								 (dz ? c.frac[2] : 1.0 - c.frac[2]);
				if (w != 0.0)
					sum += w * double(value(dx, dy, dz));
			}
	return sum;
}

// ---------------------------------------------------------------------------------------------------------------
// The bake's grid and its per-point work arrays.

/// The grid of the bake: the mesh's box grown by clamp + (B+1) h on every side, so that the outermost brick layer
/// holds no point within clamp of a triangle's box (the fill's seeds) and no lattice point of the band sits on the
/// grid's upper faces (which no brick owns).
struct Lattice
{
	Eigen::Vector3d origin;
	double h = 0.0;
	int dims[3] = {0, 0, 0};

	long long brickCount() const { return (long long)dims[0] * dims[1] * dims[2]; }
	int brickId(int i, int j, int k) const { return i + dims[0] * (j + dims[1] * k); }
	Eigen::Vector3d point(long long X, long long Y, long long Z) const
	{
		return origin + h * Eigen::Vector3d(double(X), double(Y), double(Z));
	}
	/// Lattice points per axis that bricks own (B per brick; the upper grid face is owned by none).
	int ownedExtent(int k) const { return dims[k] * B; }
};

Lattice makeLattice(const TriMesh& mesh, const SkinFieldOptions& o)
{
	const Eigen::Vector3d lo = mesh.V.colwise().minCoeff().transpose();
	const Eigen::Vector3d hi = mesh.V.colwise().maxCoeff().transpose();
	const double pad = o.clamp + (B + 1) * o.voxel;
	Lattice L;
	L.origin = lo - Eigen::Vector3d::Constant(pad);
	L.h = o.voxel;
	long long count = 1;
	for (int k = 0; k < 3; ++k)
	{
		const double n = std::ceil((hi[k] - lo[k] + 2.0 * pad) / (B * o.voxel));
		if (!(n <= double(kMaxSkinFieldBricks)))
			throw InvalidInputError("bakeSkinField: the mesh is too large for the grid (" + std::to_string(hi[k] - lo[k]) +
									" m along an axis at a voxel of " + std::to_string(o.voxel) + " m; is it in metres?)");
		L.dims[k] = std::max(1, int(n));
		count *= L.dims[k]; // each factor and the running product <= the limit: no overflow
		if (count > kMaxSkinFieldBricks)
			throw InvalidInputError("bakeSkinField: the grid would have more than " + std::to_string(kMaxSkinFieldBricks) +
									" bricks (is the mesh in metres?)");
	}
	return L;
}

/// An allocator that default-initialises the elements a vector is sized with (arithmetic types, CellLocation and the
/// Eigen vectors of PlaneTriangle stay unset), so that the bake's large arrays are written once, on all threads, where
/// their pages are first touched, instead of zeroed on one thread first.
template <class T>
struct UnsetAllocator : std::allocator<T>
{
	template <class U>
	struct rebind
	{
		using other = UnsetAllocator<U>;
	};
	UnsetAllocator() = default;
	template <class U>
	UnsetAllocator(const UnsetAllocator<U>&) noexcept
	{
	}
	template <class U>
	void construct(U* at) noexcept
	{
		::new (static_cast<void*>(at)) U;
	}
	template <class U, class... Args>
	void construct(U* at, Args&&... args)
	{
		::new (static_cast<void*>(at)) U(std::forward<Args>(args)...);
	}
};
template <class T>
using UnsetArray = std::vector<T, UnsetAllocator<T>>;

/// Per owned lattice point of the near bricks: the nearest squared distance found (clamp^2 = none within clamp), its
/// sign (0 = not known yet), and later the stored value in quanta.
struct OwnedPoints
{
	std::vector<int> brickSlot; ///< per brick: slot of a near brick, -1 for the others
	std::vector<int> slotBrick; ///< per slot: its brick
	UnsetArray<float> best2;
	UnsetArray<std::int8_t> sign;
	UnsetArray<std::int16_t> quanta;
	float clamp2 = 0.0f;

	bool touched(long long p) const { return best2[std::size_t(p)] < clamp2; }
	/// Index of the owned point at global lattice (X, Y, Z), or -1 when its brick is not near or off the grid.
	long long index(const Lattice& L, long long X, long long Y, long long Z) const
	{
		if (X < 0 || Y < 0 || Z < 0 || X >= L.ownedExtent(0) || Y >= L.ownedExtent(1) || Z >= L.ownedExtent(2))
			return -1;
		const int slot = brickSlot[std::size_t(L.brickId(int(X / B), int(Y / B), int(Z / B)))];
		if (slot < 0)
			return -1;
		return (long long)slot * kOwned + (X % B) + B * ((Y % B) + B * (Z % B));
	}
};

// ---------------------------------------------------------------------------------------------------------------
// Triangles in their plane frames, with the pseudo-normals of their features.

enum Feature
{
	kFace = 0,
	kEdge0 = 1, // v0 v1
	kEdge1 = 2, // v1 v2
	kEdge2 = 3, // v2 v0
	kVertex0 = 4,
	kVertex1 = 5,
	kVertex2 = 6
};

/// A triangle in its plane frame: origin v0, axes u (along v0 v1), v, n (the unit normal); its corners are (0, 0),
/// (x1, 0), (x2, y2) with x1 > 0, y2 > 0. featureNormal[f] is the pseudo-normal of feature f in (u, v, n) coordinates.
struct PlaneTriangle
{
	Eigen::Vector3d v0, u, v, n;
	double x1 = 0, x2 = 0, y2 = 0;
	Eigen::Vector3d featureNormal[7];
	Eigen::Vector3d boxMin, boxMax;
};

/// The mesh around each vertex (faces in CSR form), unit face normals (zero for a degenerate face) and the
/// pseudo-normals of the features: angle-weighted at vertices, per face edge k (corners k, k+1) the sum of the normals
/// of every face holding that edge (two on a closed manifold; one on a boundary edge, where the sign is then only as
/// good as that face's).
struct MeshTopology
{
	std::vector<int> start, faces; ///< faces of vertex v: faces[start[v] .. start[v+1])
	/// The mesh's edges: edgeOf[3 f + k] is the edge of face f's corners k, k + 1 (-1 where they are the same vertex),
	/// and edge e is held by the faces edgeFaces[edgeStart[e] .. edgeStart[e + 1]), in increasing order (two on a
	/// closed manifold). Found once here: the bake needs them for the pseudo-normals and the edge regions.
	std::vector<int> edgeOf, edgeStart, edgeFaces;
	std::vector<Eigen::Vector3d> faceN, vertexN, edgeN; ///< edgeN per edge: the sum of its faces' normals

	MeshTopology(const TriMesh& mesh, int threads)
	{
		const int nv = mesh.vertexCount(), nf = mesh.faceCount();
		start.assign(std::size_t(nv) + 1, 0);
		faces.resize(std::size_t(nf) * 3);
		for (int f = 0; f < nf; ++f)
			for (int k = 0; k < 3; ++k)
				++start[std::size_t(mesh.F(f, k)) + 1];
		for (int v = 0; v < nv; ++v)
			start[std::size_t(v) + 1] += start[std::size_t(v)];
		std::vector<int> fill(start.begin(), start.end() - 1);
		for (int f = 0; f < nf; ++f)
			for (int k = 0; k < 3; ++k)
				faces[std::size_t(fill[std::size_t(mesh.F(f, k))]++)] = f;
		// The normals and the edge lists need only the fans, and not each other: on two threads, side by side (the
		// edge lists are a serial pass).
		parallelRanges(2, std::min(threads, 2), [&](int first, int end) {
			for (int job = first; job < end; ++job)
				job == 0 ? edges(mesh) : normals(mesh, 1);
		});
		edgeN.assign(edgeStart.size() - 1, Eigen::Vector3d::Zero()); // in face order
		for (std::size_t e = 0; e + 1 < edgeStart.size(); ++e)
			for (int s = edgeStart[e]; s < edgeStart[e + 1]; ++s)
				edgeN[e] += faceN[std::size_t(edgeFaces[std::size_t(s)])];
	}

	/// The pseudo-normal of face f's edge k (zero where its corners are the same vertex).
	Eigen::Vector3d edgeNormal(int f, int k) const
	{
		return at(f, k) < 0 ? Eigen::Vector3d::Zero() : edgeN[std::size_t(at(f, k))];
	}

	/// The faces holding face f's edge k: [first, end) of edgeFaces.
	int edgeBegin(int f, int k) const { return at(f, k) < 0 ? 0 : edgeStart[std::size_t(at(f, k))]; }
	int edgeEnd(int f, int k) const { return at(f, k) < 0 ? 0 : edgeStart[std::size_t(at(f, k)) + 1]; }

private:
	int at(int f, int k) const { return edgeOf[std::size_t(f) * 3 + std::size_t(k)]; }

	/// edgeOf, edgeStart, edgeFaces. An edge is listed by the first face that holds it, from the fan of its end with
	/// fewer faces (a fan lists its faces in increasing order; searching the larger one made a hub of valence 50,000
	/// cost 50,000^2 steps), so each edge's list is made once (an edge held by 20,000 faces listed per face took
	/// 20,000^2 entries).
	void edges(const TriMesh& mesh)
	{
		const int nf = mesh.faceCount();
		edgeOf.assign(std::size_t(nf) * 3, -1);
		edgeStart.assign(1, 0);
		edgeFaces.clear();
		edgeFaces.reserve(std::size_t(nf) * 3);
		auto holds = [&](int g, int v) { return mesh.F(g, 0) == v || mesh.F(g, 1) == v || mesh.F(g, 2) == v; };
		// The first of g's corners k whose edge (k, k + 1) joins a and b, either way round (one exists).
		auto cornerOf = [&](int g, int a, int b) {
			for (int k = 0; k < 3; ++k)
			{
				const int x = mesh.F(g, k), y = mesh.F(g, (k + 1) % 3);
				if ((x == a && y == b) || (x == b && y == a))
					return k;
			}
			return -1;
		};
		for (int f = 0; f < nf; ++f)
			for (int k = 0; k < 3; ++k)
			{
				const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
				if (a == b)
					continue;
				const int fanA = start[std::size_t(a) + 1] - start[std::size_t(a)];
				const int fanB = start[std::size_t(b) + 1] - start[std::size_t(b)];
				const int searched = fanA <= fanB ? a : b, other = searched == a ? b : a;
				const int first = start[std::size_t(searched)], end = start[std::size_t(searched) + 1];
				int s = first;
				while (!holds(faces[std::size_t(s)], other)) // ends at f or before: f holds both
					++s;
				const int g = faces[std::size_t(s)], kg = cornerOf(g, a, b);
				if (g != f || kg != k)
				{
					edgeOf[std::size_t(f) * 3 + std::size_t(k)] = edgeOf[std::size_t(g) * 3 + std::size_t(kg)];
					continue; // listed by an earlier face, or an earlier corner of this one
				}
				edgeOf[std::size_t(f) * 3 + std::size_t(k)] = int(edgeStart.size()) - 1;
				for (int previous = -1; s < end; ++s) // a face is in a fan once per corner there, consecutively
				{
					const int h = faces[std::size_t(s)];
					if (h != previous && holds(h, other))
						edgeFaces.push_back(h);
					previous = h;
				}
				edgeStart.push_back(int(edgeFaces.size()));
			}
	}

	/// faceN and vertexN. Each face's normal and corner angles on `threads` threads, then summed into the vertices in
	/// face order (so the sums do not depend on the thread count).
	void normals(const TriMesh& mesh, int threads)
	{
		const int nf = mesh.faceCount();
		faceN.assign(std::size_t(nf), Eigen::Vector3d::Zero());
		vertexN.assign(std::size_t(mesh.vertexCount()), Eigen::Vector3d::Zero());
		std::vector<double> angle(std::size_t(nf) * 3, 0.0);
		parallelRanges(nf, threads, [&](int first, int end) {
			for (int f = first; f < end; ++f)
			{
				const Eigen::Vector3d p[3] = {mesh.V.row(mesh.F(f, 0)).transpose(), mesh.V.row(mesh.F(f, 1)).transpose(),
											  mesh.V.row(mesh.F(f, 2)).transpose()};
				const Eigen::Vector3d c = (p[1] - p[0]).cross(p[2] - p[0]);
				if (!(c.norm() > 0.0))
					continue;
				faceN[std::size_t(f)] = c.normalized();
				for (int k = 0; k < 3; ++k)
				{
					const Eigen::Vector3d a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
					angle[std::size_t(f) * 3 + std::size_t(k)] = std::atan2(a.cross(b).norm(), a.dot(b));
				}
			}
		});
		for (int f = 0; f < nf; ++f)
			if (!faceN[std::size_t(f)].isZero())
				for (int k = 0; k < 3; ++k)
					vertexN[std::size_t(mesh.F(f, k))] += angle[std::size_t(f) * 3 + std::size_t(k)] * faceN[std::size_t(f)];
	}
};

/// The non-degenerate faces in their plane frames; planeOf[f] is face f's entry, -1 for a degenerate face. On `threads`
/// threads.
UnsetArray<PlaneTriangle> planeTriangles(const TriMesh& mesh, const MeshTopology& topo, std::vector<int>& planeOf,
											int threads)
{
	planeOf.assign(std::size_t(mesh.faceCount()), -1);
	int count = 0;
	for (int f = 0; f < mesh.faceCount(); ++f) // none for a degenerate face: its edges and corners are its neighbours'
		if (!topo.faceN[std::size_t(f)].isZero())
			planeOf[std::size_t(f)] = count++;
	UnsetArray<PlaneTriangle> out(static_cast<std::size_t>(count));
	parallelRanges(mesh.faceCount(), threads, [&](int first, int end) {
		for (int f = first; f < end; ++f)
		{
			if (planeOf[std::size_t(f)] < 0)
				continue;
			PlaneTriangle& T = out[std::size_t(planeOf[std::size_t(f)])];
			T.v0 = mesh.V.row(mesh.F(f, 0)).transpose();
			const Eigen::Vector3d e0 = mesh.V.row(mesh.F(f, 1)).transpose() - T.v0;
			const Eigen::Vector3d e1 = mesh.V.row(mesh.F(f, 2)).transpose() - T.v0;
			T.n = topo.faceN[std::size_t(f)];
			T.u = e0.normalized();
			T.v = T.n.cross(T.u);
			T.x1 = e0.norm();
			T.x2 = e1.dot(T.u);
			T.y2 = e1.dot(T.v);
			auto local = [&](const Eigen::Vector3d& w) { return Eigen::Vector3d(w.dot(T.u), w.dot(T.v), w.dot(T.n)); };
			T.featureNormal[kFace] = Eigen::Vector3d(0, 0, 1);
			for (int k = 0; k < 3; ++k)
			{
				T.featureNormal[kEdge0 + k] = local(topo.edgeNormal(f, k));
				T.featureNormal[kVertex0 + k] = local(topo.vertexN[std::size_t(mesh.F(f, k))]);
			}
			T.boxMin = T.v0.cwiseMin(T.v0 + e0).cwiseMin(T.v0 + e1);
			T.boxMax = T.v0.cwiseMax(T.v0 + e0).cwiseMax(T.v0 + e1);
		}
	});
	return out;
}

/// Closest point of a plane triangle to (s, t) in its plane: squared distance, feature, the point.
struct Closest2D
{
	double d2;
	int feature;
	double cs, ct;
};

inline void closerOnSegment(double s, double t, double ax, double ay, double bx, double by, int edge, int va, int vb,
							Closest2D& best)
{
	const double dx = bx - ax, dy = by - ay;
	const double len2 = dx * dx + dy * dy;
	double tau = len2 > 0.0 ? ((s - ax) * dx + (t - ay) * dy) / len2 : 0.0;
	int feature = edge;
	if (tau <= 0.0)
		tau = 0.0, feature = va;
	else if (tau >= 1.0)
		tau = 1.0, feature = vb;
	const double cs = ax + tau * dx, ct = ay + tau * dy;
	const double d2 = (s - cs) * (s - cs) + (t - ct) * (t - ct);
	if (d2 < best.d2)
		best = {d2, feature, cs, ct};
}

/// Inside: distance 0 (the face). Outside: the nearest point lies on an edge that faces (s, t) (negative edge
/// function), so only those are measured.
inline Closest2D closest2D(const PlaneTriangle& T, double s, double t)
{
	const double f0 = t;
	const double f1 = (T.x2 - T.x1) * t - T.y2 * (s - T.x1);
	const double f2 = T.y2 * (s - T.x2) - T.x2 * (t - T.y2);
	if (f0 >= 0.0 && f1 >= 0.0 && f2 >= 0.0)
		return {0.0, kFace, s, t};
	Closest2D best{std::numeric_limits<double>::infinity(), kFace, s, t};
	if (f0 < 0.0)
		closerOnSegment(s, t, 0.0, 0.0, T.x1, 0.0, kEdge0, kVertex0, kVertex1, best);
	if (f1 < 0.0)
		closerOnSegment(s, t, T.x1, 0.0, T.x2, T.y2, kEdge1, kVertex1, kVertex2, best);
	if (f2 < 0.0)
		closerOnSegment(s, t, T.x2, T.y2, 0.0, 0.0, kEdge2, kVertex2, kVertex0, best);
	return best;
}

// ---------------------------------------------------------------------------------------------------------------
// Steps 1-2 of skin_field.h: near bricks, exact distances.

/// Lattice index range [lo, hi] of the points of a box grown by `grow` (clipped to the owned lattice).
void latticeRange(const Lattice& L, const Eigen::Vector3d& boxMin, const Eigen::Vector3d& boxMax, double grow,
				  long long lo[3], long long hi[3])
{
	for (int k = 0; k < 3; ++k)
	{
		lo[k] = std::max(0LL, (long long)std::ceil((boxMin[k] - grow - L.origin[k]) / L.h));
		hi[k] = std::min((long long)L.ownedExtent(k) - 1, (long long)std::floor((boxMax[k] + grow - L.origin[k]) / L.h));
	}
}

/// The threads of the bake split the lattice into slabs of lattice layers across y (the body's long axis, so that
/// the parts hold about the same skin).
constexpr int kSlabAxis = 1;

/// Lattice layers [lo, hi] along kSlabAxis: the part of the lattice one thread of the bake writes.
struct LatticeSlab
{
	long long lo = 0, hi = -1;

	/// The slab of lattice layers [first, end).
	static LatticeSlab ofLayers(int first, int end) { return {(long long)first, (long long)end - 1}; }
	/// The box [boxLo, boxHi] grown by `grow` meets the slab's layers.
	bool meets(const Lattice& L, const Eigen::Vector3d& boxLo, const Eigen::Vector3d& boxHi, double grow) const
	{
		const double o = L.origin[kSlabAxis];
		return boxHi[kSlabAxis] + grow >= o + L.h * double(lo) && boxLo[kSlabAxis] - grow <= o + L.h * double(hi);
	}
};

/// Marks the bricks within `clamp` of a triangle's box as near and gives each a slot of owned points (set to "not
/// measured" on `threads` threads).
OwnedPoints nearBricks(const Lattice& L, const UnsetArray<PlaneTriangle>& triangles, double clamp, int threads)
{
	OwnedPoints owned;
	owned.brickSlot.assign(std::size_t(L.brickCount()), -1);
	for (const PlaneTriangle& T : triangles)
	{
		long long lo[3], hi[3];
		latticeRange(L, T.boxMin, T.boxMax, clamp, lo, hi);
		for (long long k = lo[2] / B; k <= hi[2] / B; ++k)
			for (long long j = lo[1] / B; j <= hi[1] / B; ++j)
				for (long long i = lo[0] / B; i <= hi[0] / B; ++i)
					owned.brickSlot[std::size_t(L.brickId(int(i), int(j), int(k)))] = 0;
	}
	for (std::size_t b = 0; b < owned.brickSlot.size(); ++b)
		if (owned.brickSlot[b] == 0)
		{
			owned.brickSlot[b] = int(owned.slotBrick.size());
			owned.slotBrick.push_back(int(b));
		}
	if ((long long)owned.slotBrick.size() > kMaxNearSkinBricks)
		throw InvalidInputError("bakeSkinField: " + std::to_string(owned.slotBrick.size()) +
								" bricks lie near the skin, more than the limit of " + std::to_string(kMaxNearSkinBricks) +
								" (far too much skin, or too large triangles, for a " + millimetres(L.h) + " voxel)");
	owned.clamp2 = float(clamp * clamp);
	owned.best2.resize(owned.slotBrick.size() * kOwned);
	owned.sign.resize(owned.slotBrick.size() * kOwned);
	parallelRanges(int(owned.slotBrick.size()), threads, [&](int first, int end) {
		const std::size_t from = std::size_t(first) * kOwned, to = std::size_t(end) * kOwned;
		std::fill(owned.best2.begin() + std::ptrdiff_t(from), owned.best2.begin() + std::ptrdiff_t(to), owned.clamp2);
		std::fill(owned.sign.begin() + std::ptrdiff_t(from), owned.sign.begin() + std::ptrdiff_t(to), std::int8_t(0));
	});
	return owned;
}

/// Lowers the nearest distance found at owned point p to its distance to T when that is smaller, recording the sign
/// from the pseudo-normal of T's nearest feature. (s, t, w): the point in T's plane frame. A point's sign is nonzero
/// exactly when it has been measured (touched()).
inline void measure(const PlaneTriangle& T, double s, double t, double w, long long p, OwnedPoints& owned)
{
	if (p < 0)
		return; // cannot happen: the point is within clamp of T's box, so its brick is near
	float& best = owned.best2[std::size_t(p)];
	if (w * w >= double(best))
		return;
	const Closest2D c = closest2D(T, s, t);
	const double d2 = c.d2 + w * w;
	if (d2 >= double(best))
		return;
	const float rounded = float(d2);
	if (rounded >= owned.clamp2)
		return; // below the clamp in double, at it in float: not measured, as beyond it (the sign stays 0)
	best = rounded;
	const Eigen::Vector3d& N = T.featureNormal[c.feature];
	owned.sign[std::size_t(p)] = (s - c.cs) * N.x() + (t - c.ct) * N.y() + w * N.z() < 0.0 ? -1 : 1;
}

/// The half-spaces of a region that scan() uses: more (a vertex of valence > 32, an edge of more than 30 faces) are
/// dropped, and the region only grows.
constexpr int kMaxRegionPlanes = 32;

/// A convex region, half-spaces n . p <= b inside a box, holding every point within clamp whose nearest point on the
/// skin is one feature: the interior of a face, of an edge, or a vertex (the feature's characteristic region, over-
/// estimated by necessary conditions; Mauch's closest point transform scan-converts the same regions).
struct FeatureRegion
{
	Eigen::Vector3d lo, hi;
	int axis = 0;                   ///< the rows of the scan run along this axis
	std::vector<Eigen::Vector3d> n; ///< unit normals
	std::vector<double> b;
	std::vector<Eigen::Vector3d> rays; ///< scratch of vertexConeBox, kept to reuse its storage
	std::vector<int> next, prev;       ///< scratch of vertexRegion: per face at the vertex, its next and previous corner

	/// Box, and rows along the axis nearest `normal`.
	void reset(const Eigen::Vector3d& boxLo, const Eigen::Vector3d& boxHi, const Eigen::Vector3d& normal)
	{
		lo = boxLo, hi = boxHi;
		normal.cwiseAbs().maxCoeff(&axis);
		n.clear(), b.clear();
	}
	/// The half-space normal . (p - through) <= offset.
	void add(const Eigen::Vector3d& normal, const Eigen::Vector3d& through, double offset = 0.0)
	{
		n.push_back(normal);
		b.push_back(normal.dot(through) + offset);
	}
};

/// Measures T at every lattice point of R: per lattice row along R.axis, the interval its half-spaces leave
/// (widened by a nanometre, so a point on a boundary is kept). Rows run along the axis nearest the feature's normal,
/// which crosses the thin regions of a smooth skin in few rows. A half-space reads c + dr r + du u + dv v <= 0 at the
/// lattice point with coordinate r along the row and u, v across it. Only the points of `slab` are measured (one
/// thread's part of the lattice); a row starts where the whole region's row starts, so every point gets the same
/// coordinates, to the bit, whatever the slabs.
void scan(const FeatureRegion& R, const PlaneTriangle& T, const Lattice& L, const LatticeSlab& slab, OwnedPoints& owned)
{
	constexpr double kSlack = 1e-9; // metres
	const int ra = R.axis, ua = (R.axis + 1) % 3, va = (R.axis + 2) % 3;
	long long lo[3], hi[3], P[3];
	latticeRange(L, R.lo, R.hi, 0.0, lo, hi);
	const int sa = kSlabAxis;
	if (ra != sa) // the slab's axis runs across the rows: keep the rows in the slab (a row does not depend on others)
		lo[sa] = std::max(lo[sa], slab.lo), hi[sa] = std::min(hi[sa], slab.hi);
	else if (lo[sa] > slab.hi || hi[sa] < slab.lo)
		return;
	if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2])
		return; // the box holds no lattice point of the slab (a narrow vertex cone, a thin edge wedge)
	const int planes = std::min(int(R.n.size()), kMaxRegionPlanes);
	// The planes sorted by kind: [0, upper) bound r above, [upper, lower) below, [lower, planes) do not depend on r,
	// so that a row's interval is a branch-free min and max (both exact, so the order of the planes does not matter).
	double c[kMaxRegionPlanes], du[kMaxRegionPlanes], dv[kMaxRegionPlanes], inv[kMaxRegionPlanes], atV[kMaxRegionPlanes];
	int upper = 0, lower = 0;
	// A row's bounds are exact to ~1e-15 m / |dr| lattice steps; with every |dr| >= kSteep that is < 1e-8 steps, far
	// below kMissR (lattice steps), and the planes that do not depend on r are exact to far below kMissC (metres).
	constexpr double kSteep = 1e-6, kMissR = 1e-6, kMissC = 1e-9;
	bool steep = true;
	for (int kind = 1; kind >= -1; kind -= 2)
	{
		for (int k = 0; k < planes; ++k)
		{
			const Eigen::Vector3d& n = R.n[std::size_t(k)];
			const double dr = L.h * n[ra];
			if (!(kind > 0 ? dr > 1e-15 : dr < -1e-15))
				continue;
			c[lower] = n.dot(L.origin) - R.b[std::size_t(k)] - kSlack;
			du[lower] = L.h * n[ua];
			dv[lower] = L.h * n[va];
			inv[lower++] = -1.0 / dr;
			steep = steep && std::abs(dr) >= kSteep;
		}
		if (kind > 0)
			upper = lower;
	}
	const int constant = lower;
	for (int k = 0; k < planes; ++k)
	{
		const Eigen::Vector3d& n = R.n[std::size_t(k)];
		const double dr = L.h * n[ra];
		if (dr > 1e-15 || dr < -1e-15)
			continue;
		c[lower] = n.dot(L.origin) - R.b[std::size_t(k)] - kSlack;
		du[lower] = L.h * n[ua];
		dv[lower++] = L.h * n[va];
	}
	const double step[3] = {L.h * T.u[ra], L.h * T.v[ra], L.h * T.n[ra]};
	const long long stride = ra == 0 ? 1 : ra == 1 ? B : B * B; // of the owned index, within a brick
	for (long long V = lo[va]; V <= hi[va]; ++V)
	{
		for (int k = 0; k < lower; ++k)
			atV[k] = c[k] + dv[k] * double(V);
		// The rows of this V that meet the region are consecutive in U (the region is convex): ra0 - ra1 and each
		// plane that does not depend on r are convex in U, so once a row met the region, a row that misses it by a
		// margin above the rounding is followed by rows that miss it too, and the scan of this V ends.
		bool met = false;
		for (long long U = lo[ua]; U <= hi[ua]; ++U)
		{
			double ra0 = double(lo[ra]), ra1 = double(hi[ra]);
			double worst = -std::numeric_limits<double>::infinity(); // of the planes that do not depend on r
			for (int k = constant; k < lower; ++k)
				worst = std::max(worst, atV[k] + du[k] * double(U));
			for (int k = 0; k < upper; ++k) // c0 + dr r <= 0 with c0 = atV + du U
				ra1 = std::min(ra1, (atV[k] + du[k] * double(U)) * inv[k]);
			for (int k = upper; k < constant; ++k)
				ra0 = std::max(ra0, (atV[k] + du[k] * double(U)) * inv[k]);
			if (worst > 0.0 || ra0 > ra1) // a plane that does not depend on r excludes the row, or the interval is empty
			{
				if (met && steep && (worst > kMissC || ra0 - ra1 > kMissR))
					break;
				continue;
			}
			met = true;
			// The row's points in T's plane frame: from its first point, one lattice step along ra at a time. ra1 >=
			// ra0 >= lo >= 0 here, so truncation is floor, and ceil is truncation stepped up for a fraction.
			const long long whole = (long long)ra0;
			P[ua] = U, P[va] = V, P[ra] = double(whole) < ra0 ? whole + 1 : whole;
			const Eigen::Vector3d d = L.point(P[0], P[1], P[2]) - T.v0;
			double s = d.dot(T.u), t = d.dot(T.v), w = d.dot(T.n);
			const long long last = ra == sa ? std::min((long long)ra1, slab.hi) : (long long)ra1;
			// The owned index found through the brick index where the row enters a brick, then a stride along it.
			long long p = -1;
			for (const long long first = P[ra]; P[ra] <= last; ++P[ra], s += step[0], t += step[1], w += step[2])
			{
				if (P[ra] == first || P[ra] % B == 0)
					p = owned.index(L, P[0], P[1], P[2]);
				else if (p >= 0)
					p += stride;
				if (ra != sa || P[sa] >= slab.lo)
					measure(T, s, t, w, p, owned);
			}
		}
	}
}

/// Unit vector of `a` without its component along the unit vector `e`.
Eigen::Vector3d perpendicular(const Eigen::Vector3d& a, const Eigen::Vector3d& e)
{
	return (a - a.dot(e) * e).normalized();
}

/// Face region: the projection is inside the face (the three in-plane edge normals), the plane within clamp.
void faceRegion(const TriMesh& mesh, int f, const PlaneTriangle& T, double clamp, FeatureRegion& R)
{
	R.reset(T.boxMin - clamp * T.n.cwiseAbs(), T.boxMax + clamp * T.n.cwiseAbs(), T.n); // the box of the prism
	R.add(T.n, T.v0, clamp);
	R.add(-T.n, T.v0, clamp);
	for (int k = 0; k < 3; ++k)
	{
		const Eigen::Vector3d a = mesh.V.row(mesh.F(f, k)).transpose(), b = mesh.V.row(mesh.F(f, (k + 1) % 3)).transpose(),
							  c = mesh.V.row(mesh.F(f, (k + 2) % 3)).transpose();
		R.add(-perpendicular(c - a, (b - a).normalized()), a); // inward: (p - a) . m >= 0
	}
}

/// Edge region: between the planes normal to the edge at its ends, and for every face on the edge, not on that
/// face's side of the edge in its plane (else the face would hold a nearer point).
void edgeRegion(const TriMesh& mesh, const MeshTopology& topo, int a, int b, const std::vector<int>& faces,
				double clamp, FeatureRegion& R)
{
	const Eigen::Vector3d pa = mesh.V.row(a).transpose(), pb = mesh.V.row(b).transpose();
	const Eigen::Vector3d e = (pb - pa).normalized();
	// The region lies in the wedge between the normals of the faces (in the plane normal to the edge), within clamp of
	// the edge: its box is the edge's grown by clamp times the normals' extents, plus the bulge of the arc between
	// the two normals beyond its chord (1 - cos of half the largest angle between them).
	Eigen::Vector3d extent = Eigen::Vector3d::Zero(), sum = Eigen::Vector3d::Zero();
	const bool pairwise = faces.size() <= std::size_t(kMaxRegionPlanes); // else the full bulge, 1
	double minCos = pairwise ? 1.0 : -1.0;
	for (int g : faces)
	{
		const Eigen::Vector3d& n = topo.faceN[std::size_t(g)];
		extent = extent.cwiseMax(n.cwiseAbs());
		sum += n;
		for (std::size_t h = 0; pairwise && h < faces.size(); ++h)
			minCos = std::min(minCos, n.dot(topo.faceN[std::size_t(faces[h])]));
	}
	const double bulge = 1.0 - std::sqrt(std::max(0.0, 0.5 * (1.0 + minCos)));
	const Eigen::Vector3d across = clamp * (extent + Eigen::Vector3d::Constant(faces.size() >= 2 ? bulge : 1.0));
	R.reset(pa.cwiseMin(pb) - across, pa.cwiseMax(pb) + across, sum);
	R.add(-e, pa);
	R.add(e, pb);
	for (int g : faces)
		for (int k = 0; k < 3; ++k)
			if (mesh.F(g, k) != a && mesh.F(g, k) != b)
				R.add(perpendicular(mesh.V.row(mesh.F(g, k)).transpose() - pa, e), pa);
}

/// The box around v of the cone {d : d . e <= 0 for every e in `edges`} within clamp: the cone is spanned by its
/// extreme rays (cross products of two edges that meet every constraint), so it lies in the circular cone around
/// their mean a with the half-angle t of the widest, where |d_i| <= clamp (|a_i| + sin t). False when the cone is
/// {0} (a saddle: no point but v has v as its nearest point). A wide cone (or one holding a line) gets the ball's box,
/// and so does one without extreme rays whose edges are all parallel (a half-space or a plane: a boundary vertex of
/// one face, whose other edge its fan does not list; taken for {0} before, which left the points beyond the rim of
/// an open mesh unmeasured, reading +clamp at 8-10 mm).
bool vertexConeBox(const Eigen::Vector3d& pv, const std::vector<Eigen::Vector3d>& edges, double clamp,
				   std::vector<Eigen::Vector3d>& rays, Eigen::Vector3d& lo, Eigen::Vector3d& hi)
{
	constexpr double kTolerance = 1e-9;
	Eigen::Vector3d sum = Eigen::Vector3d::Zero();
	rays.clear();
	bool crossing = false; // two edges that are not parallel
	for (std::size_t i = 0; i < edges.size(); ++i)
		for (std::size_t j = i + 1; j < edges.size(); ++j)
		{
			const Eigen::Vector3d r = edges[i].cross(edges[j]);
			const double length = r.norm();
			if (!(length > 1e-12))
				continue;
			crossing = true;
			// Both directions of the line at once: (-r) . e is exactly -(r . e) (rounding is symmetric in sign).
			const Eigen::Vector3d ray = r / length; // what r.normalized() gives, without a second square root
			bool plus = true, minus = true;
			for (std::size_t k = 0; k < edges.size() && (plus || minus); ++k)
			{
				const double d = ray.dot(edges[k]);
				plus = plus && d <= kTolerance;
				minus = minus && -d <= kTolerance;
			}
			if (plus)
				rays.push_back(ray), sum += ray;
			if (minus)
				rays.push_back(-ray), sum += -ray;
		}
	Eigen::Vector3d extent = Eigen::Vector3d::Constant(clamp);
	if (rays.empty())
	{
		if (crossing)
			return false; // the cone is {0}: a pointed cone has rays, one holding a line has that line
		lo = pv - extent, hi = pv + extent; // parallel edges (one face at a boundary vertex): a half-space or plane
		return true;
	}
	if (sum.norm() > 0.5 * double(rays.size()))
	{
		const Eigen::Vector3d a = sum.normalized();
		double minCos = 1.0;
		for (const Eigen::Vector3d& r : rays)
			minCos = std::min(minCos, r.dot(a));
		if (minCos > 0.3)
			extent = clamp * (a.cwiseAbs() + Eigen::Vector3d::Constant(std::sqrt(1.0 - minCos * minCos))).cwiseMin(1.0);
	}
	lo = pv - extent, hi = pv + extent;
	return true;
}

/// The box around v of the cone {d : d . e <= 0 for every e in `edges`} within clamp, in O(k^2) for k faces instead of
/// vertexConeBox's O(k^3), when the fan of v closes once around the unit vector N without folding: face i runs from
/// edges[i] (to corner next[i]) to the edge to its corner prev[i], which is another face's edge, and the projections
/// of those two edges on the plane normal to N turn the same way, by less than pi. Then every direction u in that
/// plane is within G / 2 of a projected edge, G the largest turn, and a direction d at angle g from the line of N has
/// d . e >= sin g |e - (e . N) N| cos(G / 2) - |cos g| |e . N| for that edge e, which is > 0 when tan g > S / (h
/// cos(G / 2)), with S the largest |e . N| and h = sqrt(1 - S^2) the shortest projection: the cone lies in the double
/// cone of that half-angle around N, whose box is vertexConeBox's formula. False when the fan does not qualify or
/// the bound is no tighter than sin g = 0.7 (vertexConeBox decides).
bool vertexConeBoxNearNormal(const Eigen::Vector3d& pv, const Eigen::Vector3d& N, const std::vector<Eigen::Vector3d>& edges,
							 const std::vector<int>& next, const std::vector<int>& prev, double clamp, Eigen::Vector3d& lo,
							 Eigen::Vector3d& hi)
{
	const std::size_t k = edges.size();
	if (k < 3)
		return false;
	double S = 0.0;
	for (const Eigen::Vector3d& e : edges)
		S = std::max(S, std::abs(e.dot(N)));
	double minCos = 1.0; // of the turns
	for (std::size_t i = 0; i < k; ++i)
	{
		std::size_t j = k; // the face whose edge runs to prev[i]: exactly one
		for (std::size_t m = 0; m < k; ++m)
			if (next[m] == prev[i])
			{
				if (j != k)
					return false; // two faces share the edge on the same side: not a fan that closes once
				j = m;
			}
		if (j == k)
			return false; // an open fan (a boundary, or a degenerate face left out)
		const Eigen::Vector3d a = edges[i] - edges[i].dot(N) * N, b = edges[j] - edges[j].dot(N) * N;
		if (!(a.cross(b).dot(N) > 0.0))
			return false; // folded, or a turn of pi or more
		minCos = std::min(minCos, a.dot(b) / std::sqrt(a.squaredNorm() * b.squaredNorm()));
	}
	const double across = std::sqrt(std::max(0.0, 1.0 - S * S)) * std::sqrt(std::max(0.0, 0.5 * (1.0 + minCos)));
	const double sinG = S / std::sqrt(S * S + across * across);
	if (!(sinG < 0.7))
		return false;
	// A margin far above the rounding of the bound, so that a lattice point on the box's face is kept.
	const Eigen::Vector3d extent =
		(clamp * (N.cwiseAbs() + Eigen::Vector3d::Constant(sinG))).cwiseMin(clamp) * (1.0 + 1e-9);
	lo = pv - extent, hi = pv + extent;
	return true;
}

/// Vertex region: (p - v) . e <= 0 for every edge direction e leaving v (else the edge would hold a nearer point).
/// False when it is known to hold no point but v (a saddle, found by vertexConeBox).
bool vertexRegion(const TriMesh& mesh, const MeshTopology& topo, const std::vector<int>& planeOf, int v, double clamp,
				  FeatureRegion& R)
{
	const Eigen::Vector3d pv = mesh.V.row(v).transpose();
	R.reset(pv, pv, topo.vertexN[std::size_t(v)]);
	R.next.clear(), R.prev.clear();
	for (int s = topo.start[std::size_t(v)]; s < topo.start[std::size_t(v) + 1]; ++s)
	{
		const int g = topo.faces[std::size_t(s)];
		if (planeOf[std::size_t(g)] < 0)
			continue;
		for (int k = 0; k < 3; ++k) // the edge to the next corner: each neighbour once on a closed manifold
			if (mesh.F(g, k) == v)
			{
				R.add((mesh.V.row(mesh.F(g, (k + 1) % 3)).transpose() - pv).normalized(), pv);
				R.next.push_back(mesh.F(g, (k + 1) % 3));
				R.prev.push_back(mesh.F(g, (k + 2) % 3));
			}
	}
	// Above kMaxRegionPlanes edges the scan keeps the first ones, whose cone holds the vertex's: its box, from their
	// extreme rays (so that a vertex of valence 10,000 costs 32^3, not 10,000^3, steps).
	if (R.n.size() > std::size_t(kMaxRegionPlanes))
	{
		const std::vector<Eigen::Vector3d> first(R.n.begin(), R.n.begin() + kMaxRegionPlanes);
		return vertexConeBox(pv, first, clamp, R.rays, R.lo, R.hi);
	}
	// The pseudo-normal's cone bound first (about 9 in 10 vertices of a body); the extreme rays where it fails. The box
	// only bounds the scan: the region is the edges' half-spaces either way.
	const double length = topo.vertexN[std::size_t(v)].norm();
	if (length > 0.0 &&
		vertexConeBoxNearNormal(pv, topo.vertexN[std::size_t(v)] / length, R.n, R.next, R.prev, clamp, R.lo, R.hi))
		return true;
	return vertexConeBox(pv, R.n, clamp, R.rays, R.lo, R.hi);
}

/// Step 2 for the points of one slab: every lattice point within clamp of the skin gets its exact nearest distance
/// and sign, by scanning each feature's region with a face that holds the feature (the face is at least as near as
/// the feature, and no nearer than the skin). The features come in a fixed order (faces with their edges, then
/// vertices), so a point meets the same measurements in the same order whatever the slabs.
void exactDistancesInSlab(const TriMesh& mesh, const MeshTopology& topo, const UnsetArray<PlaneTriangle>& planes,
						  const std::vector<int>& planeOf, const Lattice& L, double clamp, const LatticeSlab& slab,
						  OwnedPoints& owned)
{
	FeatureRegion R;
	std::vector<int> faces;
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		const int plane = planeOf[std::size_t(f)];
		if (plane < 0)
			continue;
		const PlaneTriangle& T = planes[std::size_t(plane)];
		if (!slab.meets(L, T.boxMin, T.boxMax, 2.0 * clamp)) // the face's and its edges' regions reach 2 clamp out
			continue;
		faceRegion(mesh, f, T, clamp, R);
		scan(R, T, L, slab, owned);
		for (int k = 0; k < 3; ++k)
		{
			const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
			// Each edge once, from its first non-degenerate face (found before the faces are listed: an edge of a
			// book of 20,000 pages has 20,000 faces).
			int first = -1;
			for (int s = topo.edgeBegin(f, k); s < topo.edgeEnd(f, k) && first < 0; ++s)
				if (planeOf[std::size_t(topo.edgeFaces[std::size_t(s)])] >= 0)
					first = topo.edgeFaces[std::size_t(s)];
			if (first != f)
				continue;
			faces.clear(); // the non-degenerate faces on the edge
			for (int s = topo.edgeBegin(f, k); s < topo.edgeEnd(f, k); ++s)
				if (planeOf[std::size_t(topo.edgeFaces[std::size_t(s)])] >= 0)
					faces.push_back(topo.edgeFaces[std::size_t(s)]);
			edgeRegion(mesh, topo, a, b, faces, clamp, R);
			scan(R, T, L, slab, owned);
		}
	}
	for (int v = 0; v < mesh.vertexCount(); ++v)
	{
		const Eigen::Vector3d pv = mesh.V.row(v).transpose();
		if (!slab.meets(L, pv, pv, clamp))
			continue;
		for (int s = topo.start[std::size_t(v)]; s < topo.start[std::size_t(v) + 1]; ++s)
		{
			const int plane = planeOf[std::size_t(topo.faces[std::size_t(s)])];
			if (plane < 0)
				continue;
			if (vertexRegion(mesh, topo, planeOf, v, clamp, R))
				scan(R, planes[std::size_t(plane)], L, slab, owned);
			break;
		}
	}
}

/// Step 2 on `threads` threads, each on a slab of lattice layers of its own, the slabs cut so that each holds about
/// as much work: each triangle counts in the layer of its box's centre, by its area (the band's volume, which its
/// region scans fill) plus kTriangleOverhead (setting up its face, edge and vertex regions), in whole square
/// millimetres so that the cut is exact arithmetic.
void exactDistances(const TriMesh& mesh, const MeshTopology& topo, const UnsetArray<PlaneTriangle>& planes,
					const std::vector<int>& planeOf, const Lattice& L, double clamp, int threads, OwnedPoints& owned)
{
	// mm^2: set on the bundled bodies, whose two slabs then differ by 0.1-0.8 ms of 15-17 ms (1-2 ms by area alone,
	// 1.2-4 ms with whole brick layers)
	constexpr long long kTriangleOverhead = 150;
	const int layers = L.ownedExtent(kSlabAxis);
	std::vector<long long> before(std::size_t(layers) + 1, 0); // work below each lattice layer
	for (const PlaneTriangle& T : planes)
	{
		const double u = (0.5 * (T.boxMin + T.boxMax)[kSlabAxis] - L.origin[kSlabAxis]) / L.h;
		before[std::size_t(std::clamp(int(u), 0, layers - 1)) + 1] +=
			kTriangleOverhead + (long long)(0.5e6 * T.x1 * T.y2);
	}
	for (int j = 0; j < layers; ++j)
		before[std::size_t(j) + 1] += before[std::size_t(j)];
	const int parts = std::max(1, std::min(threads, layers));
	std::vector<int> cut(std::size_t(parts) + 1, layers); // slab p: lattice layers [cut[p], cut[p + 1])
	cut[0] = 0;
	for (int p = 1; p < parts; ++p)
	{
		const long long target = before.back() * p / parts;
		cut[std::size_t(p)] = int(std::lower_bound(before.begin(), before.end(), target) - before.begin());
		cut[std::size_t(p)] = std::clamp(cut[std::size_t(p)], cut[std::size_t(p) - 1], layers);
	}
	parallelRanges(parts, parts, [&](int first, int end) {
		for (int p = first; p < end; ++p)
			if (cut[std::size_t(p)] < cut[std::size_t(p) + 1])
				exactDistancesInSlab(mesh, topo, planes, planeOf, L, clamp,
									 LatticeSlab::ofLayers(cut[std::size_t(p)], cut[std::size_t(p) + 1]), owned);
	});
}

// ---------------------------------------------------------------------------------------------------------------
// Step 3: signs where the pseudo-normal fails, then the sign of the points at |d| >= clamp and of the bricks that
// are not near.

/// Global lattice coordinates of owned point p.
void latticeOf(const Lattice& L, const OwnedPoints& owned, long long p, long long P[3])
{
	const int brick = owned.slotBrick[std::size_t(p / kOwned)], local = int(p % kOwned);
	P[0] = (long long)(brick % L.dims[0]) * B + local % B;
	P[1] = (long long)((brick / L.dims[0]) % L.dims[1]) * B + (local / B) % B;
	P[2] = (long long)(brick / (L.dims[0] * L.dims[1])) * B + local / (B * B);
}

/// Opposite nonzero signs: as bytes, -1 ^ 1 == 0xFE, and no other pair of signs in {-1, 0, 1} xors to it.
inline bool oppositeSigns(std::int8_t a, std::int8_t b)
{
	return std::int8_t(a ^ b) == std::int8_t(-2);
}

/// Eight signs (bytes of the sign array, in memory order) as one word.
inline std::uint64_t signWord(const std::int8_t* first, std::size_t count = 8)
{
	std::uint64_t word = 0;
	std::memcpy(&word, first, count);
	return word;
}

/// Calls pair(i) for each i in [0, 8) where byte i of the sign words x and y holds opposite nonzero signs
/// (oppositeSigns). The word test finds the bytes of x ^ y equal to 0xFE (a zero byte of x ^ y ^ 0xFE..FE), a
/// superset of them at worst (the borrow of the zero-byte test can flag a byte above a true one), which the byte test
/// confirms. Most words of a brick hold no such byte.
template <class Pair>
inline void forOppositeBytes(std::uint64_t x, std::uint64_t y, Pair pair)
{
	constexpr std::uint64_t kOnes = 0x0101010101010101ull, kHighs = 0x8080808080808080ull;
	const std::uint64_t t = x ^ y ^ (kOnes * 0xFEu);
	if (((t - kOnes) & ~t & kHighs) == 0)
		return;
	std::int8_t a[8], b[8];
	std::memcpy(a, &x, 8);
	std::memcpy(b, &y, 8);
	for (int i = 0; i < 8; ++i)
		if (oppositeSigns(a[i], b[i]))
			pair(i);
}

/// Calls pair(p, q) for each owned point p of `slot` whose +axis lattice neighbour q is owned and has the opposite
/// nonzero sign: within the brick, and across its upper faces into the slots `above[axis]` (-1: none). A brick's
/// points lie x fastest in rows of B = 8 bytes, so the signs of a row are one word and the +x neighbours of a row's
/// first 7 points are the word read one byte later.
template <class Pair>
void forOppositeSignPairs(const UnsetArray<std::int8_t>& sign, int slot, const int above[3], Pair pair)
{
	static_assert(B == 8, "the sign rows are read as 8-byte words");
	const long long base = (long long)slot * kOwned;
	const std::int8_t* s = sign.data() + base;
	for (int row = 0; row < B * B; ++row) // +x within the row; +y and +z to the next row and layer
	{
		const long long p = base + (long long)row * B;
		const std::uint64_t word = signWord(s + row * B);
		forOppositeBytes(word, signWord(s + row * B + 1, B - 1), [&](int i) { pair(p + i, p + i + 1); });
		if (row % B < B - 1)
			forOppositeBytes(word, signWord(s + (row + 1) * B), [&](int i) { pair(p + i, p + B + i); });
		if (row < B * (B - 1))
			forOppositeBytes(word, signWord(s + (row + B) * B), [&](int i) { pair(p + i, p + B * B + i); });
	}
	if (above[0] >= 0) // +x: local a = B - 1 against a = 0 of the brick above
	{
		const long long next = (long long)above[0] * kOwned;
		for (int row = 0; row < B * B; ++row)
		{
			const long long p = base + (long long)row * B + (B - 1), q = next + (long long)row * B;
			if (oppositeSigns(sign[std::size_t(p)], sign[std::size_t(q)]))
				pair(p, q);
		}
	}
	if (above[1] >= 0) // +y: the last row of every layer against the first row of the brick above
	{
		const long long next = (long long)above[1] * kOwned;
		for (int c = 0; c < B; ++c)
		{
			const long long p = base + (long long)(c * B + B - 1) * B, q = next + (long long)c * B * B;
			forOppositeBytes(signWord(sign.data() + p), signWord(sign.data() + q), [&](int i) { pair(p + i, q + i); });
		}
	}
	if (above[2] >= 0) // +z: the last layer against the first layer of the brick above
	{
		const long long next = (long long)above[2] * kOwned;
		for (int b = 0; b < B; ++b)
		{
			const long long p = base + (long long)((B - 1) * B + b) * B, q = next + (long long)b * B;
			forOppositeBytes(signWord(sign.data() + p), signWord(sign.data() + q), [&](int i) { pair(p + i, q + i); });
		}
	}
}

/// Step 3a. A distance field is 1-Lipschitz: two neighbouring exact points whose signed distances differ by more than
/// the voxel have a wrong sign between them. The pseudo-normal sign fails where the mesh passes through itself (toes
/// or fingers pressed into each other): there the ray-parity test of fitting/inside_test.h (inside the union of the
/// closed components, a vote over three axes) decides both points' signs, and a point whose sign it changes has its
/// exact neighbours decided the same way in turn. Returns the number of signs changed. On `threads` threads.
/// Per slot and axis, the slot of the brick above it on that axis (-1: not near, or off the grid): where a point on
/// a brick's upper face finds its +axis neighbour.
std::vector<int> slotsAbove(const Lattice& L, const OwnedPoints& owned)
{
	const int slots = int(owned.slotBrick.size());
	std::vector<int> above(std::size_t(slots) * 3, -1);
	for (int slot = 0; slot < slots; ++slot)
	{
		const int brick = owned.slotBrick[std::size_t(slot)];
		const int id[3] = {brick % L.dims[0], (brick / L.dims[0]) % L.dims[1], brick / (L.dims[0] * L.dims[1])};
		for (int axis = 0; axis < 3; ++axis)
		{
			int next[3] = {id[0], id[1], id[2]};
			if (++next[axis] < L.dims[axis])
				above[std::size_t(slot) * 3 + std::size_t(axis)] = owned.brickSlot[std::size_t(L.brickId(next[0], next[1], next[2]))];
		}
	}
	return above;
}

/// The points of the neighbour pairs whose signed distances differ by more than the voxel (both points of each pair,
/// in slot order), found per part of the slots on `threads` threads. The unsigned distance is 1-Lipschitz whatever
/// the signs: only a pair of opposite signs can break the bound. Straight after the exact distances a point has a
/// nonzero sign exactly when it was measured (touched), so those pairs are the measured points with opposite signs.
std::vector<long long> suspectPoints(const Lattice& L, const OwnedPoints& owned, int threads)
{
	const double limit = L.h * (1.0 + 1e-5) + 1e-9; // the distances went through float
	auto signedDistance = [&](long long p) { return owned.sign[std::size_t(p)] * std::sqrt(double(owned.best2[std::size_t(p)])); };
	const int slots = int(owned.slotBrick.size());
	const std::vector<int> above = slotsAbove(L, owned);
	std::vector<std::vector<long long>> pairs(std::size_t(std::max(1, std::min(threads, slots))));
	parallelParts(slots, threads, [&](int part, int first, int end) {
		std::vector<long long>& found = pairs[std::size_t(part)];
		for (int slot = first; slot < end; ++slot)
			forOppositeSignPairs(owned.sign, slot, &above[std::size_t(slot) * 3], [&](long long p, long long q) {
				if (std::abs(signedDistance(p) - signedDistance(q)) > limit)
					found.push_back(p), found.push_back(q);
			});
	});
	std::vector<long long> points;
	for (const std::vector<long long>& partPairs : pairs)
		points.insert(points.end(), partPairs.begin(), partPairs.end());
	return points;
}

/// Step 3a. A distance field is 1-Lipschitz: two neighbouring exact points whose signed distances differ by more than
/// the voxel have a wrong sign between them. The pseudo-normal sign fails where the mesh passes through itself (toes
/// or fingers pressed into each other): there the ray-parity test of fitting/inside_test.h (inside the union of the
/// closed components, a vote over three axes) decides both points' signs, and a point whose sign it changes has its
/// exact neighbours decided the same way in turn. Returns the number of signs changed. On `threads` threads.
int repairSigns(const TriMesh& mesh, const Lattice& L, int threads, OwnedPoints& owned)
{
	auto exactNeighbour = [&](const long long P[3], int axis, int dir) {
		long long Q[3] = {P[0], P[1], P[2]};
		Q[axis] += dir;
		const long long q = owned.index(L, Q[0], Q[1], Q[2]);
		return q >= 0 && owned.touched(q) ? q : -1;
	};
	std::vector<long long> queue;
	std::vector<char> queued(owned.best2.size(), 0);
	auto push = [&](long long q) {
		if (!queued[std::size_t(q)])
			queued[std::size_t(q)] = 1, queue.push_back(q);
	};
	for (long long p : suspectPoints(L, owned, threads))
		push(p);
	if (queue.empty())
		return 0;
	// Breadth first, a round at a time: the inside test of a round's points in parallel, then in queue order each
	// point whose sign it changes queues its exact neighbours for the next round. Every point is decided once, by
	// the inside test alone, so the signs do not depend on the order (nor on the thread count).
	const MeshInsideTest inside(mesh, threads);
	int changed = 0;
	std::vector<std::int8_t> decided;
	long long P[3];
	for (std::size_t head = 0; head < queue.size();)
	{
		const std::size_t roundEnd = queue.size();
		decided.assign(roundEnd - head, 0);
		parallelRanges(int(roundEnd - head), threads, [&](int first, int end) {
			long long Q[3];
			for (int r = first; r < end; ++r)
			{
				latticeOf(L, owned, queue[head + std::size_t(r)], Q);
				decided[std::size_t(r)] = inside.isInside(L.point(Q[0], Q[1], Q[2])) ? -1 : 1;
			}
		});
		for (std::size_t r = 0; head < roundEnd; ++head, ++r)
		{
			const long long p = queue[head];
			if (decided[r] == owned.sign[std::size_t(p)])
				continue;
			owned.sign[std::size_t(p)] = decided[r];
			++changed;
			latticeOf(L, owned, p, P);
			for (int axis = 0; axis < 3; ++axis)
				for (int dir = -1; dir <= 1; dir += 2)
					if (const long long q = exactNeighbour(P, axis, dir); q >= 0)
						push(q);
		}
	}
	return changed;
}

/// Sign of a far point at X of a row from the exact points of the row (sorted X, their signs): the one that ends its
/// run on the nearer side, or + where the run reaches the grid's border. `next` is the first exact point after X.
std::int8_t runSign(const std::vector<long long>& exactX, const std::vector<std::int8_t>& exactSign, std::size_t next,
					long long X, long long rowLength)
{
	const long long left = next > 0 ? X - exactX[next - 1] : X + 1;
	const long long right = next < exactX.size() ? exactX[next] - X : rowLength - X;
	const std::int8_t leftSign = next > 0 ? exactSign[next - 1] : 1;
	const std::int8_t rightSign = next < exactX.size() ? exactSign[next] : 1;
	return left <= right ? leftSign : rightSign;
}

/// One sweep along a lattice row in x over the near bricks of its brick row: the far points since the last exact
/// point wait in `pending` (as runs of consecutive points in one brick) until the next exact point (or the row's end)
/// decides them, as runSign would.
struct FarRowSweep
{
	struct FarRun
	{
		long long p, X; ///< the first point's owned index and x lattice coordinate
		int count;
	};
	OwnedPoints& owned;
	std::vector<FarRun> pending;        ///< the row's far points not decided yet
	std::vector<long long> exactX;      ///< the row's exact points, when kept (keepExact)
	std::vector<std::int8_t> exactSign; ///< and their signs
	long long lastX = -1;               ///< the last exact point (-1: none yet, whose run reads +)
	std::int8_t lastSign = 1;

	explicit FarRowSweep(OwnedPoints& points) : owned(points) {}

	/// runSign's rule, left <= right, is X - lastX <= nextX - X (with lastX = -1 before the first exact point: left =
	/// X + 1), i.e. X <= (lastX + nextX) / 2 in integers (lastX + nextX >= 0): the pending points up to that split
	/// take lastSign, the rest nextSign.
	void decide(long long nextX, std::int8_t nextSign)
	{
		const long long split = (lastX + nextX) / 2;
		for (const FarRun& run : pending)
		{
			const int before = int(std::clamp(split - run.X + 1, 0LL, (long long)run.count));
			std::int8_t* sign = owned.sign.data() + run.p;
			std::fill(sign, sign + before, lastSign);
			std::fill(sign + before, sign + run.count, nextSign);
		}
		pending.clear();
	}

	/// Signs the far points of row (b, c) of the near bricks nearI (slots nearSlot) of one brick row; keeps the exact
	/// points in exactX / exactSign when keepExact.
	void sweep(int b, int c, const std::vector<int>& nearI, const std::vector<int>& nearSlot, long long rowLength,
			   bool keepExact)
	{
		exactX.clear(), exactSign.clear(), pending.clear();
		lastX = -1, lastSign = 1;
		for (std::size_t n = 0; n < nearI.size(); ++n)
		{
			const long long row = (long long)nearSlot[n] * kOwned + B * (b + B * c);
			const long long X0 = (long long)nearI[n] * B;
			int runStart = 0; // the far points [runStart, a) of this brick's row wait
			for (int a = 0; a < B; ++a)
			{
				if (!owned.touched(row + a))
					continue;
				if (runStart < a)
					pending.push_back({row + runStart, X0 + runStart, a - runStart});
				runStart = a + 1;
				const std::int8_t sign = owned.sign[std::size_t(row + a)];
				decide(X0 + a, sign);
				lastX = X0 + a, lastSign = sign;
				if (keepExact)
					exactX.push_back(X0 + a), exactSign.push_back(sign);
			}
			if (runStart < B)
				pending.push_back({row + runStart, X0 + runStart, B - runStart});
		}
		decide(rowLength, 1);
	}
};

/// signFarPoints for the rows of brick layers y in [firstJ, endJ).
void signFarPointsInSlab(const Lattice& L, int firstJ, int endJ, OwnedPoints& owned, std::vector<std::int8_t>& brickSign)
{
	const long long rowLength = L.ownedExtent(0);
	std::vector<int> nearI, nearSlot; // the near bricks of the brick row, and their slots
	FarRowSweep row(owned);
	for (int k = 0; k < L.dims[2]; ++k)
		for (int j = firstJ; j < endJ; ++j)
		{
			nearI.clear(), nearSlot.clear();
			for (int i = 0; i < L.dims[0]; ++i)
				if (const int slot = owned.brickSlot[std::size_t(L.brickId(i, j, k))]; slot >= 0)
					nearI.push_back(i), nearSlot.push_back(slot);
			for (int c = 0; c < B; ++c)
				for (int b = 0; b < B; ++b)
				{
					const bool brickRow = b == 0 && c == 0; // the row that also signs the bricks that are not near
					row.sweep(b, c, nearI, nearSlot, rowLength, brickRow);
					if (!brickRow)
						continue;
					std::size_t next = 0;
					for (int i = 0; i < L.dims[0]; ++i)
					{
						const long long X = (long long)i * B;
						while (next < row.exactX.size() && row.exactX[next] < X)
							++next;
						if (owned.brickSlot[std::size_t(L.brickId(i, j, k))] < 0)
							brickSign[std::size_t(L.brickId(i, j, k))] =
								runSign(row.exactX, row.exactSign, next, X, rowLength);
					}
				}
		}
}

/// Step 3 for the far points (no triangle within clamp; every point of a brick that is not near): along every
/// lattice row in x, a run of far points takes the sign of the exact point ending it on the nearer side, or + where
/// it reaches the border (the border bricks are far outside). Two neighbouring points at |d| >= clamp > h, or such a
/// point and its neighbour, are never on the two sides of the skin, so both ends of a run agree (the nearer one
/// decides if a wrong sign made them differ). A brick that is not near takes the sign of its row at y = z = 0.
/// The rows are independent: `threads` threads take slabs of brick layers in y.
void signFarPoints(const Lattice& L, int threads, OwnedPoints& owned, std::vector<std::int8_t>& brickSign)
{
	parallelRanges(L.dims[1], threads, [&](int firstJ, int endJ) { signFarPointsInSlab(L, firstJ, endJ, owned, brickSign); });
}

// ---------------------------------------------------------------------------------------------------------------
// Steps 4-5: quanta, the conservative pass, the stored bricks.

/// Quanta of the global lattice point (X, Y, Z) during the bake: its owned value, or the sign of the brick holding
/// it at full clamp (not near: |d| >= clamp), or +clamp off the grid.
int latticeQuanta(const Lattice& L, const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign, long long X,
				  long long Y, long long Z)
{
	const long long p = owned.index(L, X, Y, Z);
	if (p >= 0)
		return owned.quanta[std::size_t(p)];
	if (X < 0 || Y < 0 || Z < 0 || X >= L.ownedExtent(0) || Y >= L.ownedExtent(1) || Z >= L.ownedExtent(2))
		return kMaxQuanta;
	return brickSign[std::size_t(L.brickId(int(X / B), int(Y / B), int(Z / B)))] < 0 ? -kMaxQuanta : kMaxQuanta;
}

/// std::round of x in [0, 2^52) without the library call: the fraction x - floor(x) is exact in floating point, so
/// this is round half away from zero, to the bit. The step up is added as 0 or 1, not branched on: the fractions
/// are random, and a branch mispredicted on half the points made quantise() twice as slow.
inline double roundNonNegative(double x)
{
	const double whole = double((long long)x); // x >= 0: truncation is floor
	return whole + double(x - whole >= 0.5);
}

/// The owned points' signed distances in quanta (on `threads` threads: each point on its own).
void quantise(OwnedPoints& owned, double quantum, int threads)
{
	owned.quanta.resize(owned.best2.size());
	parallelRanges(int(owned.slotBrick.size()), threads, [&](int first, int end) {
		for (std::size_t p = std::size_t(first) * kOwned; p < std::size_t(end) * kOwned; ++p)
		{
			const double magnitude = owned.touched((long long)p)
										 ? std::min(double(kMaxQuanta), roundNonNegative(std::sqrt(double(owned.best2[p])) / quantum))
										 : double(kMaxQuanta);
			owned.quanta[p] = std::int16_t(owned.sign[p] < 0 ? -magnitude : magnitude);
		}
	});
}

/// The trilinear weights of a cell's 8 corners (corner n at +(n & 1, n >> 1 & 1, n >> 2)), formed as trilinear() forms
/// them: (x y) z.
void cornerWeights(const CellLocation& c, double weight[8])
{
	const double x[2] = {1.0 - c.frac[0], c.frac[0]}, y[2] = {1.0 - c.frac[1], c.frac[1]};
	const double z[2] = {1.0 - c.frac[2], c.frac[2]};
	const double xy[4] = {x[0] * y[0], x[1] * y[0], x[0] * y[1], x[1] * y[1]};
	for (int n = 0; n < 8; ++n)
		weight[n] = xy[n & 3] * z[n >> 2];
}

/// The owned index of corner 0 of a cell whose 8 corners are all owned points of its own near brick (the cell is not
/// on the brick's upper faces), else -1: the common case, which reads the quanta without CellCorners.
long long interiorCellBase(const Lattice& L, const OwnedPoints& owned, const CellLocation& c)
{
	if (c.cell[0] >= B - 1 || c.cell[1] >= B - 1 || c.cell[2] >= B - 1)
		return -1;
	const int slot = owned.brickSlot[std::size_t(L.brickId(c.brick[0], c.brick[1], c.brick[2]))];
	return slot < 0 ? -1 : (long long)slot * kOwned + c.cell[0] + B * (c.cell[1] + B * c.cell[2]);
}

/// Per near brick, what its cells' corners read from itself and the 7 bricks above it (m = 1 x + 2 y + 4 z for the
/// brick at +(x, y, z)): a near brick's slot, or kFarOutsideCode / kFarInsideCode for a brick that is not near (its
/// sign at full clamp) or off the grid (outside). Found once for the skin samples' cells.
struct BrickNeighbours
{
	static constexpr int kFarOutsideCode = -1, kFarInsideCode = -2;
	const Lattice& L;
	const OwnedPoints& owned;
	const std::vector<std::int8_t>& brickSign;
	std::vector<int> code; ///< slot s's: code[8 s .. 8 s + 8)

	BrickNeighbours(const Lattice& lattice, const OwnedPoints& points, const std::vector<std::int8_t>& sign)
		: L(lattice), owned(points), brickSign(sign)
	{
		code.resize(owned.slotBrick.size() * 8);
		for (std::size_t slot = 0; slot < owned.slotBrick.size(); ++slot)
			codes(owned.slotBrick[slot], &code[slot * 8]);
	}

	/// The 8 codes of `brick`: from the table for a near brick, else found into `scratch`.
	const int* of(int brick, int scratch[8]) const
	{
		const int slot = owned.brickSlot[std::size_t(brick)];
		if (slot >= 0)
			return code.data() + std::size_t(slot) * 8;
		codes(brick, scratch); // not met by a skin sample, whose brick is within clamp of a triangle (near)
		return scratch;
	}

private:
	void codes(int brick, int out[8]) const
	{
		const int i = brick % L.dims[0], j = (brick / L.dims[0]) % L.dims[1], k = brick / (L.dims[0] * L.dims[1]);
		for (int m = 0; m < 8; ++m)
		{
			const int a = i + (m & 1), b = j + ((m >> 1) & 1), c = k + (m >> 2);
			if (a >= L.dims[0] || b >= L.dims[1] || c >= L.dims[2])
			{
				out[m] = kFarOutsideCode;
				continue;
			}
			const int id = L.brickId(a, b, c);
			const int slot = owned.brickSlot[std::size_t(id)];
			out[m] = slot >= 0 ? slot : brickSign[std::size_t(id)] < 0 ? kFarInsideCode : kFarOutsideCode;
		}
	}
};

/// The owned points at the 8 corners of a cell (corner n at +(n & 1, n >> 1 & 1, n >> 2) lattice steps; -1 for a
/// corner in a brick that is not near, whose quanta are then in `constant`), and the trilinear reading in quanta.
struct CellCorners
{
	long long point[8];
	int constant[8];
	double weight[8];

	CellCorners(const Lattice& L, const BrickNeighbours& neighbours, const CellLocation& c)
	{
		cornerWeights(c, weight);
		// A corner at local B is local 0 of the brick above on that axis (the same values as owned.index and
		// latticeQuanta give, without the lattice divisions). Per axis, whether the cell's upper corner carries into
		// the brick above, and the local coordinates of its lower (0) and upper (1) corners.
		int scratch[8];
		const int* code = neighbours.of(L.brickId(c.brick[0], c.brick[1], c.brick[2]), scratch);
		int carry[3], local[3][2];
		for (int k = 0; k < 3; ++k)
		{
			carry[k] = c.cell[k] == B - 1 ? 1 : 0;
			local[k][0] = c.cell[k];
			local[k][1] = carry[k] ? 0 : c.cell[k] + 1;
		}
		for (int n = 0; n < 8; ++n)
		{
			const int x = n & 1, y = (n >> 1) & 1, z = n >> 2;
			const int s = code[(x & carry[0]) | (y & carry[1]) << 1 | (z & carry[2]) << 2];
			point[n] = s >= 0 ? (long long)s * kOwned + local[0][x] + B * (local[1][y] + B * local[2][z]) : -1;
			constant[n] = s == BrickNeighbours::kFarInsideCode ? -kMaxQuanta : kMaxQuanta;
		}
	}

	/// The reading in quanta: the same sum, in the same order, as trilinear() in sample().
	double reading(const OwnedPoints& owned) const
	{
		double sum = 0.0;
		for (int n = 0; n < 8; ++n)
			if (weight[n] != 0.0)
				sum += weight[n] * double(point[n] >= 0 ? owned.quanta[std::size_t(point[n])] : constant[n]);
		return sum;
	}
};

/// The reading in quanta of an interior cell (interiorCellBase): the same sum, in the same order, as
/// CellCorners::reading. The corners of zero weight are added too: w q is then +-0, which leaves the sum (never -0,
/// as it starts at +0) unchanged.
double interiorReading(const OwnedPoints& owned, long long base, const CellLocation& c)
{
	double weight[8];
	cornerWeights(c, weight);
	const std::int16_t* q = owned.quanta.data() + base;
	constexpr int offset[8] = {0, 1, B, B + 1, B * B, B * B + 1, B * B + B, B * B + B + 1};
	double sum = 0.0;
	for (int n = 0; n < 8; ++n)
		sum += weight[n] * double(q[offset[n]]);
	return sum;
}

/// The reading in quanta of a skin sample's cell, whose interiorCellBase is `base`: interiorReading where it applies,
/// else through CellCorners.
double cellReading(const Lattice& L, const OwnedPoints& owned, const BrickNeighbours& neighbours, const CellLocation& c,
				   long long base)
{
	return base >= 0 ? interiorReading(owned, base, c) : CellCorners(L, neighbours, c).reading(owned);
}

/// Step 4 for one skin sample: when it reads r > 0 the 8 corners of its cell are lowered by the least change that
/// brings it to 0 (corner i by w_i r / sum w^2, w the trilinear weights, rounded up to whole quanta). True when it
/// read > 0.
bool lowerSkinReading(const Lattice& L, const CellLocation& c, long long base, OwnedPoints& owned,
					  const BrickNeighbours& neighbours)
{
	if (cellReading(L, owned, neighbours, c, base) <= 0.0)
		return false; // most samples: read once, cheaply
	const CellCorners corners(L, neighbours, c);
	const double reading = corners.reading(owned);
	if (reading <= 0.0)
		return false;
	double sum2 = 0.0;
	for (double w : corners.weight)
		sum2 += w * w;
	for (int n = 0; n < 8; ++n)
	{
		const long long q = corners.point[n];
		if (q < 0 || corners.weight[n] == 0.0) // q >= 0 always: a corner is within sqrt(3) h < clamp of the skin
			continue;
		const int by = int(std::ceil(corners.weight[n] * reading / sum2));
		owned.quanta[std::size_t(q)] = std::int16_t(std::max(-kMaxQuanta, owned.quanta[std::size_t(q)] - by));
	}
	return true;
}

/// Divisions n of a skin sample segment of this length (skinSamplePoints).
int sampleDivisions(double length, double voxel)
{
	return int(std::clamp(std::ceil(length / voxel), 3.0, 64.0));
}

/// Length of edge k (corner k to corner k + 1) of face f, the one computation behind both the counting
/// (faceSampleCount) and the visiting (forEachFaceSample) of a face's samples. The divisions are ceil(length / voxel):
/// two ways of computing a length (a row expression of V and a copied vector) rounded apart at a whole number of voxels
/// (the 2 cm edges of a cube at a 2 mm voxel), the face had a sample more or fewer than its slots, and the bake read
/// cells no sample had written (a crash, depending on what the heap held).
double faceEdgeLength(const TriMesh& mesh, int f, int k)
{
	const Eigen::Vector3d a = mesh.V.row(mesh.F(f, k)).transpose();
	const Eigen::Vector3d b = mesh.V.row(mesh.F(f, (k + 1) % 3)).transpose();
	return (b - a).norm();
}

/// The number of skinSamplePoints that face f adds after the vertices: the inner points of the edges it runs up the
/// indices along (each edge once), then its own inner points.
std::size_t faceSampleCount(const TriMesh& mesh, int f, double voxel)
{
	std::size_t count = 0;
	double longest = 0.0;
	for (int k = 0; k < 3; ++k)
	{
		const double length = faceEdgeLength(mesh, f, k);
		longest = std::max(longest, length);
		if (mesh.F(f, k) < mesh.F(f, (k + 1) % 3))
			count += std::size_t(sampleDivisions(length, voxel) - 1);
	}
	const std::size_t n = std::size_t(sampleDivisions(longest, voxel));
	return count + (n - 1) * (n - 2) / 2; // i, j >= 1, i + j <= n - 1
}

/// Where each face's points start in skinSamplePoints (after the vertices), with the total at the end; counted on
/// `threads` threads. \throws InvalidInputError when the total exceeds kMaxSkinSamples.
std::vector<std::size_t> faceSampleStarts(const TriMesh& mesh, double voxel, int threads)
{
	const int nf = mesh.faceCount();
	std::vector<std::size_t> start(std::size_t(nf) + 1, std::size_t(mesh.vertexCount()));
	parallelRanges(nf, threads, [&](int first, int end) {
		for (int f = first; f < end; ++f)
			start[std::size_t(f) + 1] = faceSampleCount(mesh, f, voxel);
	});
	for (int f = 0; f < nf; ++f)
		start[std::size_t(f) + 1] += start[std::size_t(f)];
	if ((long long)start.back() > kMaxSkinSamples)
		throw InvalidInputError("bakeSkinField: the mesh needs more skin samples than the limit of " +
								std::to_string(kMaxSkinSamples) + " at a " + millimetres(voxel) +
								" voxel (far too many or too large triangles)");
	return start;
}

/// Calls visit(p) for the faceSampleCount points face f adds to skinSamplePoints, in their order.
template <class Visit>
void forEachFaceSample(const TriMesh& mesh, int f, double voxel, Visit visit)
{
	const Eigen::Vector3d p[3] = {mesh.V.row(mesh.F(f, 0)).transpose(), mesh.V.row(mesh.F(f, 1)).transpose(),
								  mesh.V.row(mesh.F(f, 2)).transpose()};
	double longest = 0.0;
	for (int k = 0; k < 3; ++k)
	{
		const double length = faceEdgeLength(mesh, f, k); // (as faceSampleCount counts)
		longest = std::max(longest, length);
		if (mesh.F(f, k) < mesh.F(f, (k + 1) % 3)) // each edge once: from the face where it runs up the indices
		{
			const Eigen::Vector3d &a = p[k], &b = p[(k + 1) % 3];
			const int n = sampleDivisions(length, voxel);
			for (int i = 1; i < n; ++i)
				visit(Eigen::Vector3d((double(n - i) * a + double(i) * b) / double(n)));
		}
	}
	const int n = sampleDivisions(longest, voxel);
	for (int i = 1; i < n; ++i)
		for (int j = 1; i + j < n; ++j)
			visit(Eigen::Vector3d((double(i) * p[0] + double(j) * p[1] + double(n - i - j) * p[2]) / double(n)));
}

/// The cells the skin samples read, located once (the lowering and the final reading both need them), in sample
/// order, and the order of the lowering: by brick layer in y, in sample order within a layer (a counting sort). A
/// sample off the grid (which cannot happen: the grid holds the mesh's box) is left out, as sample() would read +clamp
/// there.
struct SkinCells
{
	UnsetArray<CellLocation> cell;
	std::vector<long long> base; ///< per cell, its interiorCellBase (found once: both readings need it)
	std::vector<int> order;      ///< cells by layer: layer j's are order[layerStart[j] .. layerStart[j + 1])
	std::vector<int> layerStart;

	/// The cells of skinSamplePoints(mesh, L.h), located as the points are made, on `threads` threads: each face's
	/// points go to the slots faceStart (faceSampleStarts) gives it, so the order is that of skinSamplePoints whatever
	/// the thread count.
	SkinCells(const Lattice& L, const TriMesh& mesh, const OwnedPoints& owned, const std::vector<std::size_t>& faceStart,
			  int threads)
	{
		const int nv = mesh.vertexCount(), nf = mesh.faceCount();
		cell.resize(faceStart.back());
		base.resize(faceStart.back());
		std::vector<char> onGrid(faceStart.back(), 0);
		std::atomic<bool> allOnGrid{true};
		auto locate = [&](std::size_t i, const Eigen::Vector3d& p) {
			if (locateCell(L.origin, L.h, L.dims, p, cell[i]))
				base[i] = interiorCellBase(L, owned, cell[i]), onGrid[i] = 1;
			else
				allOnGrid.store(false, std::memory_order_relaxed);
		};
		// Parts of about as many samples each: item i < nv is vertex i, item nv + f is face f's samples.
		const std::size_t total = faceStart.back();
		auto firstItem = [&](int part, int parts) {
			const std::size_t at = total * std::size_t(part) / std::size_t(parts);
			if (at <= std::size_t(nv))
				return int(at);
			return nv + int(std::lower_bound(faceStart.begin(), faceStart.end() - 1, at) - faceStart.begin());
		};
		const int parts = std::max(1, std::min(threads, nv + nf));
		parallelRanges(parts, parts, [&](int firstPart, int endPart) {
			for (int item = firstItem(firstPart, parts); item < firstItem(endPart, parts); ++item)
				if (item < nv)
					locate(std::size_t(item), mesh.V.row(item).transpose());
				else
				{
					std::size_t i = faceStart[std::size_t(item - nv)];
					forEachFaceSample(mesh, item - nv, L.h, [&](const Eigen::Vector3d& p) { locate(i++, p); });
				}
		});
		if (!allOnGrid.load())
			keepOnGrid(onGrid);
		sortByLayer(L.dims[kSlabAxis]);
	}

private:
	/// Drops the samples off the grid, keeping the order of the others.
	void keepOnGrid(const std::vector<char>& onGrid)
	{
		std::size_t kept = 0;
		for (std::size_t i = 0; i < cell.size(); ++i)
			if (onGrid[i])
				cell[kept] = cell[i], base[kept] = base[i], ++kept;
		cell.resize(kept);
		base.resize(kept);
	}

	/// order and layerStart: a counting sort of the cells by their brick layer along kSlabAxis.
	void sortByLayer(int layers)
	{
		layerStart.assign(std::size_t(layers) + 1, 0);
		for (const CellLocation& c : cell)
			++layerStart[std::size_t(c.brick[kSlabAxis]) + 1];
		for (int j = 0; j < layers; ++j)
			layerStart[std::size_t(j) + 1] += layerStart[std::size_t(j)];
		order.resize(cell.size());
		std::vector<int> fill(layerStart.begin(), layerStart.end() - 1);
		for (std::size_t i = 0; i < cell.size(); ++i)
			order[std::size_t(fill[std::size_t(cell[i].brick[kSlabAxis])]++)] = int(i);
	}
};

/// Step 4: every skin sample that reads > 0 is lowered to 0 (lowerSkinReading). Lowering never raises a reading, so
/// one pass leaves no sample > 0, in any order. The order is fixed by the samples' brick layers in y: a sample reads
/// and lowers lattice layers [j B, (j + 1) B] of its layer j, so the even layers are done in parallel (each in sample
/// order), then the odd ones; the result is the same for any thread count. Marks the brick each sample is read from
/// in `holdsSkin`; returns the number of samples that read > 0.
int lowerSkinReadings(const Lattice& L, const SkinCells& skin, OwnedPoints& owned, const BrickNeighbours& neighbours,
					  int threads, std::vector<char>& holdsSkin)
{
	const int layers = L.dims[kSlabAxis];
	std::vector<int> lowered(std::size_t(layers), 0);
	for (int parity = 0; parity < 2; ++parity)
	{
		const int count = (layers - parity + 1) / 2; // layers parity, parity + 2, ...
		parallelRanges(count, threads, [&](int first, int end) {
			for (int j = parity + 2 * first; j < parity + 2 * end; j += 2)
				for (int r = skin.layerStart[std::size_t(j)]; r < skin.layerStart[std::size_t(j) + 1]; ++r)
				{
					const std::size_t i = std::size_t(skin.order[std::size_t(r)]);
					const CellLocation& c = skin.cell[i];
					holdsSkin[std::size_t(L.brickId(c.brick[0], c.brick[1], c.brick[2]))] = 1;
					lowered[std::size_t(j)] += lowerSkinReading(L, c, skin.base[i], owned, neighbours) ? 1 : 0;
				}
		});
	}
	int total = 0;
	for (int n : lowered)
		total += n;
	return total;
}

/// The largest |reading| at the skin samples (metres; the true distance there is 0), read as sample() reads the
/// stored field: the bricks holding skin samples are stored, with the owned points' values. On `threads` threads (a
/// maximum does not depend on the order).
double largestSkinReading(const Lattice& L, const SkinCells& skin, const OwnedPoints& owned,
						  const BrickNeighbours& neighbours, double quantum, double clamp, int threads)
{
	const int n = int(skin.cell.size());
	std::vector<double> worst(std::size_t(std::max(1, std::min(threads, n))), 0.0);
	parallelParts(n, threads, [&](int part, int first, int end) {
		double largest = 0.0; // kept in a register: the parts' slots share a cache line
		for (std::size_t i = std::size_t(first); i < std::size_t(end); ++i)
			largest = std::max(largest, std::abs(std::clamp(
											cellReading(L, owned, neighbours, skin.cell[i], skin.base[i]) * quantum,
											-clamp, clamp)));
		worst[std::size_t(part)] = largest;
	});
	return *std::max_element(worst.begin(), worst.end());
}

/// The ellipsoid union grown by r, for the test of a brick: the boxes, the smallest semi-axes.
struct GrownUnion
{
	const std::vector<Ellipsoid>& ellipsoids;
	double r;
	std::vector<Eigen::AlignedBox3d> boxes;
	std::vector<double> minAxis;

	GrownUnion(const std::vector<Ellipsoid>& e, double grow) : ellipsoids(e), r(grow)
	{
		for (const Ellipsoid& el : e)
			boxes.push_back(el.aabb()), minAxis.push_back(el.radii.minCoeff());
	}

	/// The brick (centre, half-diagonal) meets the grown union (conservative: the distance from a point to an
	/// ellipsoid is at least (sqrt(zeta) - 1) times its smallest semi-axis). No ellipsoids: true (nothing bounds the
	/// skin, every near brick is kept).
	bool meets(const Eigen::Vector3d& centre, double halfDiagonal) const
	{
		if (ellipsoids.empty())
			return true;
		const double reach = r + halfDiagonal;
		for (std::size_t i = 0; i < ellipsoids.size(); ++i)
		{
			if ((centre.array() < boxes[i].min().array() - reach).any() ||
				(centre.array() > boxes[i].max().array() + reach).any())
				continue;
			if ((std::sqrt(ellipsoids[i].zeta(centre)) - 1.0) * minAxis[i] <= reach)
				return true;
		}
		return false;
	}
};

/// A lattice point of the brick is inside the skin: the brick must be stored even outside the grown union (a fit's
/// union can leave pockets under the skin uncovered; far outside there would be wrong, and would put a far-outside
/// brick next to a far-inside one, which btSkinDistanceField refuses).
bool holdsInside(const Lattice& L, const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign, int brick)
{
	const long long X0 = (long long)(brick % L.dims[0]) * B, Y0 = (long long)((brick / L.dims[0]) % L.dims[1]) * B,
					Z0 = (long long)(brick / (L.dims[0] * L.dims[1])) * B;
	for (int c = 0; c <= B; ++c)
		for (int b = 0; b <= B; ++b)
			for (int a = 0; a <= B; ++a)
				if (latticeQuanta(L, owned, brickSign, X0 + a, Y0 + b, Z0 + c) <= 0)
					return true;
	return false;
}

/// One stored brick's samples, written to `out` (kSkinBrickSamples of them). Returns the largest |quantised - exact|
/// distance among the touched points it copies (metres).
double fillBlock(const Lattice& L, const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign, int brick,
				 double quantum, std::int16_t* out)
{
	double worst = 0.0;
	const int id[3] = {brick % L.dims[0], (brick / L.dims[0]) % L.dims[1], brick / (L.dims[0] * L.dims[1])};
	// The brick's samples come from the points it owns and, on its upper faces (a, b or c = B), from the points
	// of the 7 bricks above it: their slots, or the quanta of a brick that is not near (or off the grid).
	int slot[8], constant[8];
	for (int n = 0; n < 8; ++n)
	{
		const int i = id[0] + (n & 1), j = id[1] + ((n >> 1) & 1), k = id[2] + (n >> 2);
		const bool onGrid = i < L.dims[0] && j < L.dims[1] && k < L.dims[2];
		slot[n] = onGrid ? owned.brickSlot[std::size_t(L.brickId(i, j, k))] : -1;
		constant[n] = onGrid && brickSign[std::size_t(L.brickId(i, j, k))] < 0 ? -kMaxQuanta : kMaxQuanta;
	}
	// Row by row: a row (b, c) reads its first B points from one brick (n) and its last from the brick after it
	// in x (n + 1).
	auto copy = [&](int n, std::size_t p) {
		if (slot[n] < 0)
		{
			*out++ = std::int16_t(constant[n]);
			return;
		}
		p += std::size_t(slot[n]) * kOwned;
		const int q = owned.quanta[p];
		*out++ = std::int16_t(q);
		if (owned.touched((long long)p))
		{
			const double exact = owned.sign[p] * std::sqrt(double(owned.best2[p]));
			worst = std::max(worst, std::abs(q * quantum - exact));
		}
	};
	for (int c = 0; c <= B; ++c)
		for (int b = 0; b <= B; ++b)
		{
			const int n = 2 * (b == B) + 4 * (c == B);
			const std::size_t row = std::size_t(B * (b % B + B * (c % B)));
			for (int a = 0; a < B; ++a)
				copy(n, row + std::size_t(a));
			copy(n + 1, row);
		}
	return worst;
}

/// Marks as stored (beside the bricks the skin samples read) every near brick whose box meets the union grown by
/// the skin offset and two voxels, or that holds a lattice point inside the skin. On `threads` threads: each slot
/// decides its own brick.
void storeBricksNearUnion(const Lattice& L, const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign,
						  const GrownUnion& grown, int threads, std::vector<char>& stored)
{
	const double halfDiagonal = 0.5 * std::sqrt(3.0) * B * L.h;
	parallelRanges(int(owned.slotBrick.size()), threads, [&](int first, int end) {
		for (int slot = first; slot < end; ++slot)
		{
			const int brick = owned.slotBrick[std::size_t(slot)];
			const int i = brick % L.dims[0], j = (brick / L.dims[0]) % L.dims[1], k = brick / (L.dims[0] * L.dims[1]);
			const Eigen::Vector3d centre = L.point((long long)i * B, (long long)j * B, (long long)k * B) +
										   Eigen::Vector3d::Constant(0.5 * B * L.h);
			if (!stored[std::size_t(brick)] &&
				(grown.meets(centre, halfDiagonal) || holdsInside(L, owned, brickSign, brick)))
				stored[std::size_t(brick)] = 1;
		}
	});
}

/// What the brick index says of a brick that is not stored: far inside only for a brick that is not near and whose
/// row sign is inside; a near brick left unstored has every point outside (storeBricksNearUnion keeps the others).
int unstoredCode(const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign, int brick)
{
	return owned.brickSlot[std::size_t(brick)] < 0 && brickSign[std::size_t(brick)] < 0 ? kFarInside : kFarOutside;
}

/// Marks as stored both bricks of every face-neighbouring pair that would otherwise be left far inside and far outside.
/// On a closed skin such a pair cannot occur (the skin passes between them, within clamp of both); where the mesh has
/// a hole (a scan open at the soles or the crown), the signs through the hole come from its rim and a far-inside brick
/// can meet a far-outside one, which btSkinDistanceField refuses. Stored, the two read from -clamp to +clamp across
/// their shared face: the hole is closed there, as a seam the field already has where stored bricks meet far ones.
/// Returns the number of bricks it stored.
int storeSignConflicts(const Lattice& L, const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign,
					   std::vector<char>& stored)
{
	auto farCode = [&](int brick) { return stored[std::size_t(brick)] ? 0 : unstoredCode(owned, brickSign, brick); };
	int added = 0;
	for (int k = 0; k < L.dims[2]; ++k)
		for (int j = 0; j < L.dims[1]; ++j)
			for (int i = 0; i < L.dims[0]; ++i)
			{
				const int brick = L.brickId(i, j, k);
				const int above[3] = {i + 1 < L.dims[0] ? L.brickId(i + 1, j, k) : -1,
									  j + 1 < L.dims[1] ? L.brickId(i, j + 1, k) : -1,
									  k + 1 < L.dims[2] ? L.brickId(i, j, k + 1) : -1};
				for (int other : above)
				{
					const int a = farCode(brick);
					if (other < 0 || a == 0)
						continue;
					const int b = farCode(other);
					if (b == 0 || a == b)
						continue;
					stored[std::size_t(brick)] = stored[std::size_t(other)] = 1;
					added += 2;
				}
			}
	return added;
}

/// Step 5 and the layout: brick index, samples of the stored bricks, and the largest error at their band points.
void gatherBricks(const Lattice& L, const OwnedPoints& owned, const std::vector<std::int8_t>& brickSign,
				  const std::vector<char>& stored, int threads, SkinField& field)
{
	field.brickIndex.assign(std::size_t(L.brickCount()), kFarOutside);
	std::vector<int> blockBrick; // per block, its brick (blocks in brick order)
	for (int brick = 0; brick < int(L.brickCount()); ++brick)
	{
		if (!stored[std::size_t(brick)])
		{
			field.brickIndex[std::size_t(brick)] = unstoredCode(owned, brickSign, brick);
			continue;
		}
		field.brickIndex[std::size_t(brick)] = int(blockBrick.size());
		blockBrick.push_back(brick);
	}
	field.samples.resize(blockBrick.size() * kSkinBrickSamples);
	const int blocks = int(blockBrick.size());
	std::vector<double> worst(std::size_t(std::max(1, std::min(threads, blocks))), 0.0);
	parallelParts(blocks, threads, [&](int part, int first, int end) {
		for (int block = first; block < end; ++block)
			worst[std::size_t(part)] = std::max(
				worst[std::size_t(part)],
				fillBlock(L, owned, brickSign, blockBrick[std::size_t(block)], field.quantum(),
						  field.samples.data() + std::size_t(block) * kSkinBrickSamples));
	});
	for (double w : worst)
		field.maxError = std::max(field.maxError, w);
}

void checkMesh(const TriMesh& mesh)
{
	if (mesh.faceCount() == 0)
		throw InvalidInputError("bakeSkinField: the mesh has no faces");
	if (!mesh.V.allFinite())
		throw InvalidInputError("bakeSkinField: the mesh has non-finite vertex coordinates");
	if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= mesh.vertexCount())
		throw InvalidInputError("bakeSkinField: a face index is out of range (" + std::to_string(mesh.F.maxCoeff()) +
								" with " + std::to_string(mesh.vertexCount()) + " vertices)");
}

} // namespace

std::size_t skinSampleCount(const TriMesh& mesh, double voxel)
{
	std::size_t count = std::size_t(mesh.vertexCount());
	for (int f = 0; f < mesh.faceCount(); ++f)
		count += faceSampleCount(mesh, f, voxel);
	return count;
}

std::vector<Eigen::Vector3d> skinSamplePoints(const TriMesh& mesh, double voxel)
{
	std::vector<Eigen::Vector3d> out;
	out.reserve(skinSampleCount(mesh, voxel)); // ~20 per face at a 5 mm voxel: growing the vector would copy them
	for (int v = 0; v < mesh.vertexCount(); ++v)
		out.push_back(mesh.V.row(v).transpose());
	for (int f = 0; f < mesh.faceCount(); ++f)
		forEachFaceSample(mesh, f, voxel, [&](const Eigen::Vector3d& p) { out.push_back(p); });
	return out;
}

std::size_t SkinField::bytes() const
{
	return sizeof(SkinField) + brickIndex.size() * sizeof(std::int32_t) + samples.size() * sizeof(std::int16_t);
}

void validateSkinFieldOptions(const SkinFieldOptions& o)
{
	auto check = [](double v, double lo, double hi, const char* name) {
		if (!(std::isfinite(v) && v >= lo && v <= hi))
			throw InvalidInputError(std::string("skin field: ") + name + " must be in [" + std::to_string(lo) + ", " +
									std::to_string(hi) + "] m (got " + std::to_string(v) + ")");
	};
	check(o.voxel, 0.0005, 0.05, "voxel");
	check(o.clamp, 2.0 * o.voxel, 0.1, "clamp (at least 2 voxels)");
	check(o.skinOffset, 0.0, 0.1, "skin offset");
	if (o.threads < 0 || o.threads > 256)
		throw InvalidInputError("skin field: threads must be in [0, 256] (0 = every hardware thread; got " +
								std::to_string(o.threads) + ")");
}

SkinField bakeSkinField(const TriMesh& mesh, const std::vector<Ellipsoid>& ellipsoids, const SkinFieldOptions& options)
{
	validateSkinFieldOptions(options);
	checkMesh(mesh);
	const int threads = resolveThreads(options.threads);
	const Lattice L = makeLattice(mesh, options);
	const std::vector<std::size_t> faceStart = faceSampleStarts(mesh, L.h, threads); // refuses too many samples
	const MeshTopology topo(mesh, threads);
	std::vector<int> planeOf;
	const UnsetArray<PlaneTriangle> planes = planeTriangles(mesh, topo, planeOf, threads);

	OwnedPoints owned = nearBricks(L, planes, options.clamp, threads);
	exactDistances(mesh, topo, planes, planeOf, L, options.clamp, threads, owned);
	const int repaired = repairSigns(mesh, L, threads, owned);
	std::vector<std::int8_t> brickSign(std::size_t(L.brickCount()), 0);
	signFarPoints(L, threads, owned, brickSign);

	SkinField field;
	field.repairedSigns = repaired;
	field.origin = L.origin;
	field.voxel = L.h;
	field.clamp = options.clamp;
	field.skinOffset = options.skinOffset;
	field.nx = L.dims[0], field.ny = L.dims[1], field.nz = L.dims[2];
	quantise(owned, field.quantum(), threads);

	const SkinCells skin(L, mesh, owned, faceStart, threads);
	std::vector<char> stored(std::size_t(L.brickCount()), 0);
	const BrickNeighbours neighbours(L, owned, brickSign);
	field.loweredSamples = lowerSkinReadings(L, skin, owned, neighbours, threads, stored);
	storeBricksNearUnion(L, owned, brickSign, GrownUnion(ellipsoids, options.skinOffset + 2.0 * L.h), threads, stored);
	field.holeBricks = storeSignConflicts(L, owned, brickSign, stored);
	gatherBricks(L, owned, brickSign, stored, threads, field);
	field.maxError =
		std::max(field.maxError, largestSkinReading(L, skin, owned, neighbours, field.quantum(), field.clamp, threads));
	return field;
}

double sample(const SkinField& field, const Eigen::Vector3d& p)
{
	const int dims[3] = {field.nx, field.ny, field.nz};
	CellLocation c;
	if (field.empty() || !locateCell(field.origin, field.voxel, dims, p, c))
		return field.clamp;
	const std::int32_t s = field.brickIndex[std::size_t(c.brick[0] + field.nx * (c.brick[1] + field.ny * c.brick[2]))];
	if (s == kFarOutside)
		return field.clamp;
	if (s < 0)
		return -field.clamp;
	const std::int16_t* block = field.samples.data() + std::size_t(s) * kSkinBrickSamples;
	const double quanta = trilinear(c, [&](int dx, int dy, int dz) {
		return block[(c.cell[0] + dx) + (B + 1) * ((c.cell[1] + dy) + (B + 1) * (c.cell[2] + dz))];
	});
	return std::clamp(quanta * field.quantum(), -field.clamp, field.clamp);
}

} // namespace bodyfit
