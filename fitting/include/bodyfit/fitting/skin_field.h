#pragma once
/// \file skin_field.h
/// The tight skin surface of a body (issue 14): a narrow-band signed distance field of the body mesh, baked once per
/// body at fit time, so that cloth contact can be decided against the real skin while the union of ellipsoids stays
/// the conservative bound and the broad phase (every MVEE encloses its cluster, so the union stands 11-15 mm off the
/// skin on average).
///
/// Layout (shared with the Bullet-side field class; keep to it exactly). BODY frame (the frame of the mesh and of the
/// fit's ellipsoids; metres, +y up). Positive outside the skin, negative inside.
///  - Grid: origin o, voxel size h, brick edge B = 8 voxels, brick dimensions (nx, ny, nz). Brick (i, j, k) covers the
///    box [o + B h (i, j, k), o + B h (i+1, j+1, k+1)].
///  - brickIndex: nx*ny*nz int32, brick (i, j, k) at i + nx*(j + ny*k). s >= 0: the brick's samples are block s of
///    `samples`; kFarOutside (-1): every point of the brick is at signed distance >= +clamp (or the brick lies
///    entirely outside the ellipsoid union grown by skinOffset + 2h, where the union already bounds the skin);
///    kFarInside (-2): every point is at <= -clamp. Points outside the whole grid are far outside.
///  - samples: per stored brick (B+1)^3 int16 at the brick's lattice points (a, b, c) in [0, B]^3, index
///    a + (B+1)*(b + (B+1)*c), point o + h*(B*(i,j,k) + (a,b,c)). Signed distance = value * quantum, clamped to
///    [-clamp, +clamp]; quantum = clamp / 32767. A lattice point shared by neighbouring bricks has the same value in
///    every copy, so the field is continuous across brick faces.
///  - The field at a point = trilinear interpolation of the 8 lattice samples of its cell in its brick (the brick is
///    floor((p - o) / (B h)) per axis, so a point on a shared face reads the brick above it; both copies agree
///    there). The grid is [o, o + B h (nx, ny, nz)): its upper faces are outside, as in btSkinDistanceField.
///
/// The bake (bakeSkinField):
///  1. Bricks: a brick is "near" when its box is within `clamp` of the bounding box of some triangle (so every brick
///     holding a point with |d| < clamp is near). Near bricks that meet the ellipsoid union grown by skinOffset + 2h
///     (tested conservatively from the brick's centre and half-diagonal), that have a lattice point inside the skin
///     (a union can leave pockets under the skin uncovered), or that hold a skin sample of step 4, are stored; the
///     other near bricks lie outside the body and the grown union and are kFarOutside.
///  2. Exact distances: every lattice point within clamp of the skin gets the distance to its nearest triangle. The
///     point's nearest skin point lies in the interior of a face, of an edge, or at a vertex, and the point then lies
///     in that feature's region (Mauch's closest point transform scan-converts the same regions): for a face, the
///     prism over it (its projection is inside the face, |plane distance| < clamp); for an edge, between the planes
///     normal to it at its ends and, for each face on it, not on the face's side of the edge in the face's plane;
///     for a vertex, (p - v) . e <= 0 for every edge direction e leaving it. Each region (a convex set of half-spaces
///     in a box) is scanned row by row, and its points are measured against a face holding the feature (in the face's
///     plane frame: 2D closest point, then the out-of-plane offset), keeping the nearest. A smooth skin's regions
///     barely overlap, so each band point is measured about 1.3 times (a triangle's whole clamp neighbourhood would
///     be ~40 times).
///  3. Sign: for those points, the sign of (p - c) . N where c is the closest point and N the pseudo-normal of the
///     nearest feature (Baerentzen and Aanaes, "Signed distance computation using the angle weighted
///     pseudonormal", 2005): the face normal, the sum of the two face normals of an edge, the angle-weighted sum of
///     the face normals at a vertex. It is exact for closed, consistently oriented (CCW = outward) meshes, which the
///     load-and-repair step produces for the bundled bodies. It fails where the mesh passes through itself (the
///     bundled bodies' toes): there two neighbouring points differ by more than the voxel, which a distance field
///     cannot, and the ray-parity test of fitting/inside_test.h (the union of the closed components, a vote over
///     three axes) decides their signs, spreading to their neighbours while it changes signs (repairedSigns). Every
///     other point (|d| >= clamp) only needs its sign: along each lattice row a run of
///     such points takes the sign of the exact point that ends it on the nearer side, or + where it reaches the grid
///     border (a flood fill along rows: a pocket of outside air enclosed by the band, e.g. under an arm, is outside).
///     Two neighbouring points at |d| >= clamp > h, or such a point and a neighbour, cannot lie on the two sides of
///     the skin, so a run never crosses it. A brick with no point within clamp takes the sign of a row through it.
///  4. Conservative: the skin is sampled (skinSamplePoints: every vertex, every edge and every face interior at
///     points at most a voxel apart, at least in thirds); wherever
///     the interpolated field reads r > 0 the 8 lattice samples of that cell are lowered by the least change that
///     brings it to 0 (corner i by w_i r / sum w^2, w the trilinear weights, rounded up to whole quanta). Lowering
///     never raises another reading, so after one pass no skin sample reads > 0. Between samples the reading is not
///     proven <= 0 (the interpolant is only Lipschitz): tests/fitting/test_skin_field.cpp measures the excess at
///     random skin points: at most 0.014 mm on the sphere, box and cylinder tests, 0.16 mm on the decimated body
///     (where the skin is thinner than a voxel: fingers, ears).
///  5. maxError = the largest |field - true distance| at the points where the bake knows the true distance: every
///     stored lattice point of the band (|d| < clamp) and every skin sample (d = 0). It includes the quantisation,
///     the conservative lowering and, at the skin samples, the interpolation error.
///
/// Guarantees (for a closed, consistently oriented mesh): field(p) <= 0 at every skin sample of step 4; field = true
/// distance within maxError at the band's lattice points and the skin samples; every lattice point beyond the band
/// and every unstored brick has the true sign (a lattice point in the band too, unless the conservative pass lowered
/// it through zero next to skin thinner than a voxel); points outside the grid and in kFarOutside bricks read +clamp,
/// in kFarInside bricks -clamp. Not guaranteed: the 1 mm of issue 14 where the skin is thinner than a voxel (the
/// measured errors are in tests/fitting/test_skin_field.cpp and README.md). Deterministic, the same bytes for any
/// thread count (SkinFieldOptions::threads): in step 2 the threads take slabs of lattice layers in y and in step 3
/// of brick layers; each writes only its slab's points, meeting the features in the same fixed order; in step 4 the
/// samples go by brick layer, the even layers in parallel, then the odd ones (a sample changes only its own layer's
/// cells); everything else is per point, per brick or per sample, or sums in a fixed order.

#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/fitting/types.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace bodyfit
{

/// Bake parameters. \see validateSkinFieldOptions for the accepted ranges.
struct SkinFieldOptions
{
	double voxel = 0.005;      ///< lattice spacing h (metres)
	double clamp = 0.012;      ///< distances are accurate within |d| < clamp; beyond, only the sign (metres)
	double skinOffset = 0.002; ///< the collider's skin offset: bricks meeting the union grown by this + 2h are kept
	/// Threads of the bake (0 = every hardware thread; parallel.h). The field is the same bit for bit for any count.
	int threads = 0;
};

/// Brick index values that are not sample blocks.
constexpr std::int32_t kFarOutside = -1;
constexpr std::int32_t kFarInside = -2;
/// Brick edge B in voxels, and lattice points per stored brick ((B+1)^3).
constexpr int kSkinBrickEdge = 8;
constexpr int kSkinBrickSamples = (kSkinBrickEdge + 1) * (kSkinBrickEdge + 1) * (kSkinBrickEdge + 1);
/// The skin samples of the conservative pass (step 4 above): every vertex; every edge (from the face where it runs
/// from the lower to the higher vertex index: each edge of a closed, consistently oriented mesh once) at i / n of
/// its length, 0 < i < n; every face's interior at the barycentric points (i, j, n - i - j) / n, i, j, n - i - j >= 1.
/// n = ceil(length / voxel) in [3, 64], the length being the edge's, or the face's longest edge.
std::vector<Eigen::Vector3d> skinSamplePoints(const TriMesh& mesh, double voxel);
/// The number of points skinSamplePoints gives, counted face by face without making them (the bake sizes its sample
/// arrays by it and fills each face's slots as it makes that face's points: the two must agree exactly).
std::size_t skinSampleCount(const TriMesh& mesh, double voxel);

struct SkinField
{
	// The layout (see the file comment).
	Eigen::Vector3d origin = Eigen::Vector3d::Zero(); ///< o (metres, body frame)
	double voxel = 0.005;                             ///< h (metres)
	double clamp = 0.012;                             ///< metres; quantum = clamp / 32767
	int nx = 0, ny = 0, nz = 0;                       ///< brick dimensions of the grid
	std::vector<std::int32_t> brickIndex;             ///< nx*ny*nz: block number, kFarOutside or kFarInside
	std::vector<std::int16_t> samples;                ///< storedBricks() * kSkinBrickSamples

	// What the bake used and measured.
	double skinOffset = 0.002; ///< SkinFieldOptions::skinOffset of the bake (metres)
	double maxError = 0.0;     ///< max |field - true distance| measured at bake time (metres; step 5 above)
	int loweredSamples = 0;    ///< skin samples that read > 0 before the conservative pass (step 4)
	int repairedSigns = 0;     ///< band points whose pseudo-normal sign the inside test corrected (step 3)
	/// bricks stored only because they would have been left far inside next to far outside: where the mesh has a hole
	/// (0 on a closed skin; bakeSkinField's storeSignConflicts)
	int holeBricks = 0;

	double quantum() const { return clamp / 32767.0; }
	int brickCount() const { return nx * ny * nz; }
	int storedBricks() const { return int(samples.size() / std::size_t(kSkinBrickSamples)); }
	/// Bytes held by the layout (index + samples + the header fields).
	std::size_t bytes() const;
	/// True when there is no grid (a default-constructed field).
	bool empty() const { return brickIndex.empty(); }
};

/// \throws InvalidInputError naming the first bad option: voxel in [0.0005, 0.05] m, clamp in [2 voxel, 0.1] m (a
/// cell's corners lie within sqrt(3) h of a point in it, so they carry real distances only if clamp > sqrt(3) h),
/// skinOffset in [0, 0.1] m, all finite; threads in [0, 256].
void validateSkinFieldOptions(const SkinFieldOptions& options);

/// Bakes the field of `mesh` (body frame; closed, CCW = outward) for a fit with `ellipsoids` (steps 1-5 above).
/// \throws InvalidInputError for bad options, a mesh without faces, non-finite coordinates, bad indices, a grid that
/// would exceed kMaxSkinFieldBricks (a mesh not in metres), or a bake whose working memory would exceed
/// kMaxSkinSamples or kMaxNearSkinBricks (far too many or too large triangles for the voxel).
SkinField bakeSkinField(const TriMesh& mesh, const std::vector<Ellipsoid>& ellipsoids,
						const SkinFieldOptions& options = {});

/// Limit on nx*ny*nz (a 2 m body at the finest voxel, 0.5 mm, needs ~1.6e6; 1.6e7 index entries are 64 MB).
constexpr long long kMaxSkinFieldBricks = 16LL * 1024 * 1024;
/// Limit on the bake's skin samples (step 4), 56 bytes each while it runs: a 13k-vertex body needs ~0.26e6 at 5 mm
/// and ~6e6 at 0.5 mm, a million-vertex body ~9e6 at 5 mm; a triangle longer than 64 voxels adds ~2,000.
constexpr long long kMaxSkinSamples = 16LL * 1024 * 1024;
/// Limit on the bricks within clamp of a triangle's box (step 1), 3.5 kB each while the bake runs (and up to 1.5 kB
/// each in the field): a 2 m body needs ~2,500 at 5 mm and ~250,000 at 0.5 mm; a 40 m ground plane ~1e6.
constexpr long long kMaxNearSkinBricks = 256LL * 1024;

/// The field at p (metres, body frame): the reference the Bullet side must match. +clamp outside the grid.
double sample(const SkinField& field, const Eigen::Vector3d& p);

// ---------------------------------------------------------------------------------------------------------------
// The side file. A fit file (ellipsoid_io.h) names it in its "skin_field" section; it sits next to the fit file as
// <fit stem>.skin. A side file rather than embedded data keeps the JSON readable (3 MB of samples would be ~8 MB of
// base64) and lets a reader that has no use for the field skip it. Binary, little-endian:
//   offset 0   magic "BFSKINF" + NUL (8 bytes)
//          8   u32 version (kSkinFieldFileVersion), u32 brick edge (must be 8)
//         16   f64 origin x, y, z; f64 voxel, clamp, skin offset, max error
//         72   i32 nx, ny, nz, stored bricks, lowered samples; u32 0 (reserved)
//         96   i32 brick index [nx*ny*nz]; i16 samples [stored * 729]
//        end   u64 FNV-1a (64 bit) of every byte before it
// Read back validated: sizes against the file's length before anything is allocated, the checksum, every header
// value in the range a bake can produce, every index entry -2, -1 or a block number used once, every sample in
// [-32767, 32767].

constexpr const char kSkinFieldMagic[8] = {'B', 'F', 'S', 'K', 'I', 'N', 'F', '\0'};
constexpr std::uint32_t kSkinFieldFileVersion = 1;
/// Largest side file read: the brick limit's index alone is 64 MB; a body's file is ~3-5 MB.
constexpr std::size_t kMaxSkinFieldFileBytes = std::size_t(256) << 20;

/// The side file's bytes.
std::string skinFieldBytes(const SkinField& field);
/// 	hrows FormatError "<name>: skin field: <problem>" (one line) for anything but a valid file.
SkinField parseSkinField(const std::string& bytes, const std::string& name);
/// 	hrows FormatError naming the file when it cannot be written.
void writeSkinField(const std::string& path, const SkinField& field);
/// 	hrows FormatError naming the file: missing, not a regular file, larger than kMaxSkinFieldFileBytes, or invalid.
SkinField readSkinField(const std::string& path);

} // namespace bodyfit
