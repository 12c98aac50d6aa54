#pragma once
/// \file subdivision.h
/// Midpoint subdivision of a triangle mesh: every triangle becomes four, whose corners are its own and the midpoints
/// of its edges (shared between the triangles on either side). The surface does not change, every edge is halved:
/// a garment refined this way keeps its shape and drapes with edges half as long (bodyfit-drape's garment.subdivide),
/// and a body refined this way has ~4x the vertices on the same surface (bodyfit-bench body-resolution).

#include "bodyfit/fitting/types.h"

namespace bodyfit
{

/// One midpoint subdivision of `mesh`: vertices first as they were, then one per edge in the order the faces meet
/// them; faces 4f .. 4f + 3 replace face f and keep its orientation. Deterministic.
TriMesh midpointSubdivide(const TriMesh& mesh);

} // namespace bodyfit
