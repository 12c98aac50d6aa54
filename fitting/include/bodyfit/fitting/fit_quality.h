#pragma once
/// \file fit_quality.h
/// How well a union of ellipsoids stands in for a body mesh (docs/DESIGN.md sec. 5, "Fit quality"):
///   * air gap: distance from the union's outer surface to the skin. Points are sampled deterministically on every
///     ellipsoid surface (a spherical Fibonacci lattice mapped onto the ellipsoid, each sample weighted by its exact
///     area element so the statistics are per unit of surface area); samples inside another ellipsoid are not on the
///     union's surface and are dropped; each remaining sample's distance to the mesh is measured exactly (closest
///     point on the closest triangle, uniform grid over the triangles). Samples inside the body mesh (the union dips
///     under the skin there) are not air: they are reported as an area fraction instead.
///   * skin outside the union: mesh vertices with min_j zeta_j(v) > 1, their fraction and their largest distance to
///     the union (= the smallest true distance to any ellipsoid, Eberly); the same over samples of the whole skin
///     surface (triangles sampled every skinSurfaceSpacing).
///   * voxel IoU of the union against the body interior: voxel centres of a regular grid over both, the body side
///     decided by MeshInsideTest (inside_test.h).
/// Deterministic: same input and options -> same numbers, bit for bit (no randomness, fixed iteration order).

#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/types.h"

#include <vector>

namespace bodyfit
{

/// Exact unsigned distance from points to a triangle mesh: closest point per triangle (Voronoi-region test),
/// accelerated by a uniform grid over the triangles' bounding boxes, searched in growing shells of cells until no
/// unvisited cell can hold a closer triangle. Queries are const and thread-safe.
class MeshDistanceGrid
{
public:
	/// \throws InvalidInputError for a mesh without faces, with bad indices or non-finite coordinates.
	explicit MeshDistanceGrid(const TriMesh& mesh);

	/// Distance from p to the mesh surface (metres). `closest` (optional) receives the closest surface point.
	double distance(const Eigen::Vector3d& p, Eigen::Vector3d* closest = nullptr) const;

	/// Closest point of the triangle (a, b, c) to p.
	static Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
												  const Eigen::Vector3d& b, const Eigen::Vector3d& c);

private:
	Eigen::MatrixX3d V_;
	Eigen::MatrixX3i F_;
	Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
	double cell_ = 1.0;
	int dims_[3] = {1, 1, 1};
	std::vector<int> cellStart_; ///< CSR: faces of cell i are cellFaces_[cellStart_[i] .. cellStart_[i + 1])
	std::vector<int> cellFaces_;

	int cellIndex(int x, int y, int z) const { return (z * dims_[1] + y) * dims_[0] + x; }
};

struct FitQualityOptions
{
	/// Target spacing of the air-gap samples on each ellipsoid surface (metres): an ellipsoid of area A gets
	/// ceil(A / spacing^2) samples (at least minSamplesPerEllipsoid). 5 mm gives ~1.5e5 samples on an adult body.
	double sampleSpacing = 0.005;
	int minSamplesPerEllipsoid = 64;
	/// A vertex counts as outside the union when min_j zeta_j(v) > 1 + outsideTolerance (vertices exactly on an
	/// ellipsoid surface, as in exact fits, are not reported because of rounding).
	double outsideTolerance = 1e-9;
	/// Spacing of the skin samples for the surface version of "skin outside the union" (metres): every triangle is
	/// sampled on a barycentric grid with its longest edge cut into pieces no longer than this; 0 = skip. Vertices
	/// alone can miss the slivers of skin that bulge out between two ellipsoids (each vertex is inside its own).
	double skinSurfaceSpacing = 0.002;
	bool computeAirGap = true;
	bool computeSkinOutside = true;
	bool computeIoU = true;
};

struct FitQuality
{
	int ellipsoidCount = 0;

	// Air gap (metres): statistics weighted by surface area over the exposed union surface outside the body.
	int airGapSamples = 0;            ///< exposed samples outside the body (the statistics' support)
	int exposedSamples = 0;           ///< samples on the union surface (inside no other ellipsoid)
	int totalSamples = 0;             ///< all samples drawn on all ellipsoid surfaces
	double airGapMean = 0.0;
	double airGapP95 = 0.0;
	double airGapMax = 0.0;
	double exposedArea = 0.0;         ///< estimated area of the union surface (m^2)
	double unionInsideBodyFraction = 0.0; ///< area fraction of the union surface that lies inside the body mesh

	// Skin outside the union.
	int skinOutsideVertices = 0;
	double skinOutsideFraction = 0.0; ///< of all mesh vertices
	double skinOutsideMax = 0.0;      ///< largest distance of an outside vertex to the union (metres)
	double skinOutsideMean = 0.0;     ///< mean over the outside vertices (0 when none)
	long long skinSurfaceSamples = 0;    ///< samples on the triangles (skinSurfaceSpacing; edges shared by two
										 ///< triangles are sampled by both)
	long long skinSurfaceOutside = 0;    ///< of those, outside every ellipsoid
	double skinSurfaceOutsideFraction = 0.0;
	double skinSurfaceOutsideMax = 0.0;  ///< largest distance of an outside sample to the union (metres)

	// Voxel IoU (union vs body interior); -1 when not computed.
	double voxelIoU = -1.0;
	double voxelSize = 0.0;           ///< metres
	long long unionVoxels = 0;
	long long bodyVoxels = 0;
	long long intersectionVoxels = 0;

	double milliseconds = 0.0;        ///< wall time of measureFitQuality (not counting the reference)
};

/// Everything about the body that does not depend on the ellipsoids: the distance grid, the inside test and the
/// body's voxel occupancy. Build it once per mesh and measure many fits against it.
///
/// Voxels: cubic cells of size h = (longest side of the mesh's bounding box) / voxelResolution, on a lattice anchored
/// at the box's minimum corner; the body occupancy is decided at every voxel centre inside the box (outside the box
/// nothing is body). Union voxels are counted on the same lattice, also beyond the box, so the IoU is exact for the
/// lattice whatever the ellipsoids' extent.
class FitQualityReference
{
public:
	/// \param voxelResolution cells along the longest side of the mesh box; 0 = no voxel IoU. 160 gives ~1.1 cm
	/// voxels on a 1.75 m body.
	/// 	hrows InvalidInputError for a mesh without faces, bad indices, non-finite coordinates or a negative resolution.
	explicit FitQualityReference(const TriMesh& mesh, int voxelResolution = 160);

	const TriMesh& mesh() const { return mesh_; }
	const MeshDistanceGrid& distanceGrid() const { return distance_; }
	const MeshInsideTest& insideTest() const { return inside_; }
	int voxelResolution() const { return resolution_; }
	double voxelSize() const { return voxel_; }
	long long bodyVoxelCount() const { return bodyVoxelCount_; }
	double milliseconds() const { return milliseconds_; } ///< construction time

private:
	friend FitQuality measureFitQuality(const FitQualityReference&, const std::vector<Ellipsoid>&,
										const FitQualityOptions&);
	TriMesh mesh_;
	MeshDistanceGrid distance_;
	MeshInsideTest inside_;
	int resolution_ = 0;
	double voxel_ = 0.0;
	Eigen::Vector3d origin_ = Eigen::Vector3d::Zero(); ///< minimum corner of the lattice (voxel (0,0,0) starts here)
	int dims_[3] = {0, 0, 0};
	std::vector<unsigned char> body_; ///< 1 = voxel centre inside the body, x fastest
	long long bodyVoxelCount_ = 0;
	double milliseconds_ = 0.0;
};

/// Measures the fit quality of `ellipsoids` against the reference body.
/// 	hrows InvalidInputError for an empty ellipsoid list, an invalid ellipsoid (Ellipsoid::isValid, named by index)
/// or bad options (spacing <= 0, minSamplesPerEllipsoid < 1).
FitQuality measureFitQuality(const FitQualityReference& reference, const std::vector<Ellipsoid>& ellipsoids,
							 const FitQualityOptions& options = {});

/// Convenience: builds the reference (voxelResolution as in FitQualityReference) and measures once.
FitQuality measureFitQuality(const TriMesh& mesh, const std::vector<Ellipsoid>& ellipsoids,
							 const FitQualityOptions& options = {}, int voxelResolution = 160);

/// Surface area of an ellipsoid (Knud Thomsen's approximation, relative error < 1.1%); used to size the sampling.
double ellipsoidSurfaceArea(const Ellipsoid& e);

} // namespace bodyfit
