#pragma once
/// \file inside_test.h
/// "Is this point inside the body mesh?" against the original triangle mesh (not the ellipsoids), for the
/// cloth metrics (nodes inside the body). Ray parity along the three coordinate axes, counted per connected
/// component (a point is inside the union of the closed components, so nested or overlapping parts such as eyes
/// or a separate head do not flip the answer), with a majority vote over the three axes so that a small hole
/// or a ray grazing an edge changes at most one vote. Each axis has a 2D grid over the projected triangles,
/// so one query costs a few dozen triangle tests.

#include "bodyfit/fitting/types.h"

#include <vector>

namespace bodyfit
{

class MeshInsideTest
{
public:
	/// \param mesh triangle mesh (closed components give exact answers; open ones are handled by the vote)
	/// \param threads the three axis grids are built on up to this many threads (0 = every hardware thread); the
	///        test is the same whatever the count
	/// \throws InvalidInputError if the mesh has no faces, non-finite coordinates or bad indices.
	explicit MeshInsideTest(const TriMesh& mesh, int threads = 1);

	/// True if p is inside (majority of the three axis-ray parity votes).
	bool isInside(const Eigen::Vector3d& p) const;

	/// Number of rows of `points` (N by 3) that are inside.
	int countInside(const Eigen::MatrixX3d& points) const;

	/// Parity vote of one axis (0 = x, 1 = y, 2 = z): inside the union of components along a ray in +axis.
	bool parityInside(const Eigen::Vector3d& p, int axis) const;

private:
	struct AxisGrid
	{
		int axis = 0;                    ///< ray direction
		int u = 1, v = 2;                ///< projected coordinates
		double originU = 0, originV = 0; ///< grid origin in the projection plane
		double invCell = 1;
		int nu = 1, nv = 1;
		std::vector<int> cellStart;      ///< CSR, size nu * nv + 1
		std::vector<int> cellFaces;
	};

	/// The grid of the projections along `axis` (square cells, about kFacesPerCell projected triangles per cell on
	/// average over the box's extent), each cell listing the faces whose projected box meets it. faceMin/faceMax:
	/// every face's box (row f), found once for the three grids.
	void buildGrid(int axis, const Eigen::Vector3d& extent, const Eigen::MatrixX3d& faceMin,
				   const Eigen::MatrixX3d& faceMax);

	Eigen::MatrixX3d V_;
	Eigen::MatrixX3i F_;
	std::vector<int> faceComponent_;
	int componentCount_ = 0;
	Eigen::Vector3d boxMin_, boxMax_;
	AxisGrid grids_[3];
};

} // namespace bodyfit
