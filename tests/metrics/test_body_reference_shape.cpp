// BodyReference::setShape (a deforming body, e.g. a skinned body at another instant): the inside test and the skin
// distance follow the new vertex positions, the ellipsoids are replaced, and bad input changes nothing.
#include "bodyfit/metrics/cloth_metrics.h"

#include "bodyfit/fitting/errors.h"
#include "support/mesh_shapes.h"

#include <catch2/catch.hpp>

using bodyfit::metrics::BodyReference;

TEST_CASE("BodyReference::setShape: inside test and skin distance follow the moved vertices", "[metrics]")
{
	const bodyfit::TriMesh sphere = bodyfit_test::uvSphere(0.2, 48, 24);
	BodyReference body(sphere);
	const Eigen::Vector3d p(0.5, 0.0, 0.0);
	CHECK_FALSE(body.isInside(p));
	// The sphere moved by +0.5 m in x: its centre is now at p.
	Eigen::MatrixX3d moved = sphere.V;
	moved.col(0).array() += 0.5;
	bodyfit::Ellipsoid e;
	e.center = Eigen::Vector3d(0.5, 0.0, 0.0);
	e.radii = Eigen::Vector3d::Constant(0.2);
	body.setShape(moved, {e});
	CHECK(body.isInside(p));
	CHECK(body.ellipsoids().size() == 1);
	// At the centre the distance to the skin is the radius; the polygonal sphere's faces lie inside the true
	// sphere by at most r (1 - cos(pi/24)) = 1.7 mm, so 2 mm bounds it.
	CHECK(body.signedSkinDistance(p) == Approx(-0.2).margin(0.002));
	CHECK(body.signedSkinDistance(Eigen::Vector3d::Zero()) == Approx(0.3).margin(0.002));

	CHECK(body.skinDistance(Eigen::Vector3d::Zero()) == Approx(0.3).margin(0.002));
	// The segment from the new centre out along +x leaves the moved sphere once, at x = 0.7 (t = 0.4 of 0.5 m);
	// the polygonal sphere's vertex on that axis lies on the true sphere, so the hit is exact to rounding.
	const std::vector<double> hits = body.segmentHits(p, Eigen::Vector3d(1.0, 0.0, 0.0));
	REQUIRE(hits.size() == 1);
	CHECK(hits.front() == Approx(0.4).margin(1e-9));

	// A wrong vertex count or a non-finite coordinate is refused and leaves the reference as it was.
	CHECK_THROWS_WITH(body.setShape(moved.topRows(10), {}), Catch::Contains("10 vertices given"));
	Eigen::MatrixX3d bad = moved;
	bad(3, 1) = std::nan("");
	CHECK_THROWS_AS(body.setShape(bad, {}), bodyfit::InvalidInputError);
	bodyfit::Ellipsoid flat = e;
	flat.radii.z() = 0.0;
	CHECK_THROWS_WITH(body.setShape(sphere.V, {flat}), Catch::Contains("ellipsoid 0 is not valid"));
	CHECK(body.isInside(p));
	CHECK(body.ellipsoids().size() == 1);
}
