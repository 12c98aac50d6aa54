// A scene's "fit" object goes through the fit pipeline (fitting/fit_pipeline.h): "absolute": true makes the
// thresholds metres, and every other length still follows the body height.
#include "bodyfit/drape/scene.h"
#include "bodyfit/drape/simulation.h"
#include "bodyfit/fitting/mesh_io.h"
#include "support/paths.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

using namespace bodyfit::drape;
using nlohmann::json;

namespace
{

std::string bodyPath()
{
	return bodyfit_test::assetPath("male_young.4508v.obj");
}

/// The body of a scene on the 4,508-vertex bundled body whose "fit" object is `fit`.
BodyData fittedBody(const json& fit)
{
	const json j = {{"body", {{"mesh", bodyPath()}, {"fit", fit}}},
					{"collider", {{"kind", "ellipsoids"}}},
					{"garment", {{"type", "patch"}, {"size_m", {0.5, 0.5}}, {"resolution", {5, 5}}, {"center", {0, 2, 0}}}}};
	return loadBody(parseScene(j, "/virtual/fit_units.json"));
}

/// Bit-for-bit equality (the fitter is deterministic: equal resolved options give equal bits).
bool sameEllipsoids(const BodyData& a, const BodyData& b)
{
	if (a.ellipsoids.size() != b.ellipsoids.size())
		return false;
	for (std::size_t i = 0; i < a.ellipsoids.size(); ++i)
		if (a.ellipsoids[i].center != b.ellipsoids[i].center || a.ellipsoids[i].radii != b.ellipsoids[i].radii ||
			a.ellipsoids[i].rotation != b.ellipsoids[i].rotation)
			return false;
	return true;
}

} // namespace

TEST_CASE("scene fit: \"absolute\": true means metres, for the thresholds and nothing else", "[scene][fit]")
{
	const bodyfit::TriMesh mesh = bodyfit::loadTriMesh(bodyPath()).mesh;
	const double h = mesh.V.col(1).maxCoeff() - mesh.V.col(1).minCoeff();
	REQUIRE(h > 1.5); // a standing adult (1.75 m): metres and fractions of H differ by that factor

	const BodyData relative = fittedBody({{"mu_torso", 0.02}, {"mu_limbs", 0.015}});
	// The same thresholds in metres: r * H (the products the pipeline computes itself, so bit-identical).
	const BodyData metresOfRelative =
		fittedBody({{"mu_torso", 0.02 * h}, {"mu_limbs", 0.015 * h}, {"absolute", true}});
	CHECK(sameEllipsoids(relative, metresOfRelative));

	// 0.02 m is less than 0.02 H (35 mm): tighter thresholds, more ellipsoids.
	const BodyData absolute = fittedBody({{"mu_torso", 0.02}, {"mu_limbs", 0.015}, {"absolute", true}});
	CHECK(absolute.ellipsoids.size() > relative.ellipsoids.size());

	// "absolute" alone gives no length in metres: the relative defaults, converted as always (before the pipeline
	// it left the default thresholds, sigma and cover spacing as raw numbers in metres: 12 mm, 1 mm, 3 mm).
	CHECK(sameEllipsoids(fittedBody({{"absolute", true}}), fittedBody(json::object())));
	CHECK_FALSE(relative.ellipsoids.empty());
	CHECK(relative.fitSeconds > 0.0);
	CHECK(relative.fitWarnings.empty()); // a standing human: no fallback
}

TEST_CASE("scene fit: a non-human body falls back to one region and keeps the warning", "[scene][fit]")
{
	const json j = {{"body", {{"mesh", bodyfit_test::dataPath("cube_quads.obj")}, {"fit", json::object()}}},
					{"collider", {{"kind", "ellipsoids"}}},
					{"garment", {{"type", "patch"}, {"size_m", {0.5, 0.5}}, {"resolution", {5, 5}}, {"center", {0, 2, 0}}}}};
	const BodyData body = loadBody(parseScene(j, "/virtual/cube.json"));
	CHECK_FALSE(body.ellipsoids.empty());
	REQUIRE_FALSE(body.fitWarnings.empty());
	CHECK(body.fitWarnings.front().rfind("segmentation failed (", 0) == 0);
}
