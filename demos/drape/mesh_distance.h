#pragma once
/// \file mesh_distance.h
/// Unsigned distance from points to a triangle mesh (exact closest point per triangle, Ericson's "Real-Time
/// Collision Detection" sec. 5.1.5 region test) accelerated by a uniform grid over the triangles' boxes, searched
/// in growing shells until no unvisited cell can hold a closer triangle.

#include "bodyfit/types.h"

#include <vector>

namespace bodyfit::drape
{

class MeshDistance
{
public:
	/// \throws InvalidInputError for a mesh without faces.
	explicit MeshDistance(const TriMesh& mesh);

	/// Distance from p to the closest point of the mesh surface (metres).
	double distance(const Eigen::Vector3d& p) const;

	/// Closest point of triangle (a, b, c) to p.
	static Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
												  const Eigen::Vector3d& b, const Eigen::Vector3d& c);

private:
	TriMesh mesh_;
	Eigen::Vector3d origin_;
	double cell_ = 1.0;
	int dims_[3] = {1, 1, 1};
	std::vector<int> cellStart_; ///< CSR over cells
	std::vector<int> cellFaces_;

	int cellIndex(int x, int y, int z) const { return (z * dims_[1] + y) * dims_[0] + x; }
};

} // namespace bodyfit::drape
