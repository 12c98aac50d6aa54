#pragma once
// Shared helpers of the scene-runner tests: a sphere body (mesh + one-ellipsoid fit) and a patch scene over it.
#include "bodyfit/drape/simulation.h"
#include "support/mesh_shapes.h"
#include "support/paths.h"

#include <nlohmann/json.hpp>

namespace bodyfit_test
{

/// A sphere body of radius 0.25 m centred at (0, 1, 0): mesh (slightly inside the sphere: its vertices lie on it)
/// and the one-ellipsoid "fit".
inline bodyfit::drape::BodyData sphereBody()
{
	bodyfit::drape::BodyData b;
	b.mesh = bodyfit_test::starShape([](const Eigen::Vector3d&) { return 0.25; }, 32, 16, Eigen::Vector3d(0, 1, 0));
	bodyfit::Ellipsoid e;
	e.center = Eigen::Vector3d(0, 1, 0);
	e.radii = Eigen::Vector3d::Constant(0.25);
	b.ellipsoids = {e};
	b.meshPath = "<sphere>";
	b.ellipsoidSource = "<sphere>";
	return b;
}

/// A 0.8 m patch of 17 x 17 nodes at height `y`, offset in x by `dx`, over the sphere body, with `effects`.
inline bodyfit::drape::Scene patchScene(const nlohmann::json& effects, double y = 1.35, double dx = 0.0)
{
	using nlohmann::json;
	json j = {{"body", {{"mesh", bodyfit_test::dataPath("tetra.obj")}, {"fit", json::object()}}},
			  {"collider", {{"kind", "ellipsoids"}}},
			  {"garment",
			   {{"type", "patch"}, {"size_m", {0.8, 0.8}}, {"resolution", {17, 17}}, {"center", {dx, y, 0.0}}}},
			  {"solver", {{"dt", 1.0 / 120.0}, {"iterations", 8}}},
			  {"effects", effects}};
	return bodyfit::drape::parseScene(j, "/virtual/effects.json");
}

} // namespace bodyfit_test
