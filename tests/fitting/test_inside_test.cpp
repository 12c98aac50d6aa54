// The inside test of fitting/include/bodyfit/fitting/inside_test.h on meshes of many closed parts: the parity is
// counted per component (a bit per component below 64, a list above), and the grids it builds on several threads
// give the answers they give on one.

#include "bodyfit/fitting/inside_test.h"
#include "support/mesh_shapes.h"

#include <catch2/catch.hpp>

using namespace bodyfit;
using bodyfit_test::appended;
using bodyfit_test::subdividedCube;

namespace
{

/// `count` unit cubes of side 0.1 in a row along x, 0.05 apart (cube i spans [0.15 i, 0.15 i + 0.1] in x), each a
/// component of its own; a smaller cube nested inside every other one (the union holds the nested one: inside).
TriMesh rowOfCubes(int count)
{
	TriMesh mesh;
	for (int i = 0; i < count; ++i)
	{
		TriMesh cube = subdividedCube(0.1, 2);
		cube.V.col(0).array() += 0.15 * i;
		mesh = i == 0 ? cube : appended(mesh, cube);
		if (i % 2 == 0)
		{
			TriMesh inner = subdividedCube(0.04, 1);
			inner.V.array() += 0.03;
			inner.V.col(0).array() += 0.15 * i;
			mesh = appended(mesh, inner);
		}
	}
	return mesh;
}

} // namespace

TEST_CASE("inside test: a row of 80 closed cubes, rays through many components", "[inside_test]")
{
	// 80 cubes and 40 nested ones: 120 components, so the components from 64 on take the list. A ray along x from
	// a cube's centre crosses every cube after it twice (even: no vote) and its own once (odd: inside); a ray from
	// a gap between two cubes crosses each later cube twice (outside).
	const TriMesh mesh = rowOfCubes(80);
	const MeshInsideTest one(mesh, 1), two(mesh, 2);
	for (int i = 0; i < 80; ++i)
	{
		INFO("cube " << i);
		// In an even cube the centre is also inside its nested cube: odd in both components, inside either way.
		const Eigen::Vector3d centre(0.15 * i + 0.05, 0.05, 0.05);
		const Eigen::Vector3d gap(0.15 * i + 0.125, 0.05, 0.05);   // halfway between cube i and cube i + 1
		const Eigen::Vector3d beside(0.15 * i + 0.05, 0.05, 0.2);  // next to the row, in z
		CHECK(one.isInside(centre));
		CHECK_FALSE(one.isInside(gap));
		CHECK_FALSE(one.isInside(beside));
		for (int axis = 0; axis < 3; ++axis)
		{
			CHECK(one.parityInside(centre, axis));
			CHECK_FALSE(one.parityInside(gap, axis));
		}
		// The grids built on two threads are the same grids: the same answer at every point.
		CHECK(two.isInside(centre));
		CHECK_FALSE(two.isInside(gap));
	}
	// Points on a lattice through the whole row (cube faces, edges and gaps included): the same answers on both.
	int differ = 0, inside = 0;
	for (double x = -0.02; x < 0.15 * 80; x += 0.0137)
		for (double y = -0.02; y < 0.12; y += 0.0173)
			for (double z = -0.02; z < 0.12; z += 0.0191)
			{
				const Eigen::Vector3d p(x, y, z);
				const bool a = one.isInside(p);
				differ += a != two.isInside(p) ? 1 : 0;
				inside += a ? 1 : 0;
			}
	CHECK(differ == 0);
	CHECK(inside > 0);
}
