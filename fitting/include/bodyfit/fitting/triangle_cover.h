#pragma once
/// \file triangle_cover.h
/// The pieces of the triangle cover (body_fitter.h, BodyFitOptions::coverTriangles) and the check of which of them
/// lie inside one ellipsoid. The fitter owns the ellipsoids and refits them; this class cuts the triangles across a
/// cluster boundary into pieces once and, round after round, says which pieces no single ellipsoid contains and
/// which corners each of them hands to which cluster.
///
/// Rules (the ones body_fitter.h states): a piece is inside ellipsoid j when its three corners lie in j's bounding box
/// and at zeta_j <= 1 + 1e-9 (the MVEE's own enclosure guarantee, mvee.h). An uncovered piece goes to the corner
/// cluster whose ellipsoid comes closest (smallest max zeta of the piece's corners; ties: lower cluster id); its
/// corners outside that ellipsoid are handed to that cluster, in piece order.
///
/// Cost. Pieces share their grid points, so the zeta of each grid point is evaluated once per corner cluster of its
/// triangle (not once per piece and corner); a piece found inside ellipsoid j at one check is not checked again
/// while j is unchanged (its answer cannot change); the pieces no corner cluster contains are checked only against
/// the ellipsoids whose bounding box overlaps the grid cell of the piece's first corner. None of these changes an
/// answer: the result is the one of checking every piece against every ellipsoid.
///
/// Threads: the check of the triangles is split into contiguous ranges; the handouts are merged in piece order, so
/// the result is the same for any thread count.

#include "bodyfit/fitting/ellipsoid.h"

#include <array>
#include <vector>

namespace bodyfit
{

/// Whether face f of `mesh` crosses a cluster boundary (`owner`: cluster per vertex, -1 unfitted): its corners'
/// clusters in `clusters`, true when all three are fitted and not all the same (the faces the cover cuts; the skin
/// binding of skinned_fit.h picks the same faces).
bool crossesClusters(const TriMesh& mesh, const std::vector<int>& owner, int f, std::array<int, 3>& clusters);

class TriangleCover
{
public:
	/// A corner of an uncovered piece that cluster `cluster` must enclose from now on.
	struct Handout
	{
		int cluster = -1;
		Eigen::Vector3d point = Eigen::Vector3d::Zero();
	};

	/// The triangles of `mesh` whose corners belong to different clusters (`owner`: cluster id per vertex, -1 for a
	/// vertex no cluster fitted: its triangles are skipped), each cut on a barycentric grid whose longest edge is in
	/// pieces no longer than `spacing` (coverCutLevel, body_fitter.h).
	TriangleCover(const TriMesh& mesh, const std::vector<int>& owner, double spacing);

	/// Checks the pieces against `ellipsoids` (indexed by cluster id). `changed`: per cluster, whether its ellipsoid
	/// changed since the previous check (ignored at the first check, which checks every piece). Appends to `handouts`
	/// (in piece order) the corners of every uncovered piece that lie outside the cluster it goes to, each grid point
	/// once per cluster, and sets `targeted` (resized to one flag per cluster) for every cluster some uncovered piece
	/// goes to. Returns the number of uncovered pieces. `threads` >= 1.
	int check(const std::vector<Ellipsoid>& ellipsoids, const std::vector<char>& changed,
			  std::vector<Handout>& handouts, std::vector<char>& targeted, int threads = 1);

	int pieceCount() const { return int(pieces_.size()); }
	int triangleCount() const { return int(triangles_.size()); }

private:
	struct Triangle
	{
		std::array<int, 3> clusters; ///< cluster of each corner
		int firstPoint = 0;          ///< its grid points: [firstPoint, firstPoint + (level + 1)(level + 2) / 2)
		int firstPiece = 0;          ///< its pieces: [firstPiece, next triangle's firstPiece)
		int pieceEnd = 0;
	};
	/// What the check found for one piece (written by the thread that checked its triangle).
	struct Verdict
	{
		int coveredBy = -1; ///< an ellipsoid containing it; -1 when none
		int target = -1;    ///< uncovered: the cluster it goes to
		char outside = 0;   ///< uncovered: bit k set when corner k lies outside the target's ellipsoid
	};
	class Checker;

	/// After a check: appends the outside corners of the uncovered pieces to `handouts` (each grid point once per
	/// cluster it goes to), flags their target clusters in `targeted`, and returns the number of uncovered pieces.
	int collectHandouts(std::vector<Handout>& handouts, std::vector<char>& targeted);

	std::vector<Eigen::Vector3d> points_;   ///< grid points, triangle by triangle
	std::vector<std::array<int, 3>> pieces_; ///< corners of each piece (indices into points_)
	std::vector<Triangle> triangles_;
	std::vector<Verdict> verdicts_;
	std::vector<char> handedTo_; ///< per grid point: bit s set once it was handed to corner slot s's cluster
	bool checked_ = false;
};

} // namespace bodyfit
