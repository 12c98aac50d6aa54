// The bridge from the fitter's skin field (fitting/include/bodyfit/fitting/skin_field.h) to btSkinDistanceField:
// the Bullet side reads what the fitting side's reference sample() reads, accepts a real body's bake, and a loaded fit
// with a field gives a compound with the field attached.
#include "bodyfit/bridge/btBodyFitToBullet.h"

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/skin_field.h"

#include "support/mesh_shapes.h"
#include "support/paths.h"
#include "support/temp_files.h"

#include <catch2/catch.hpp>

#include <random>

namespace
{

/// Largest |btSkinDistanceField::distance - bodyfit::sample| over random points of the grid and a margin around it.
double largestDisagreement(const bodyfit::SkinField& field, const btSkinDistanceField& bt, int count, unsigned seed)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> u(-0.05, 1.05);
	const Eigen::Vector3d size =
		field.voxel * bodyfit::kSkinBrickEdge * Eigen::Vector3d(double(field.nx), double(field.ny), double(field.nz));
	double worst = 0.0;
	for (int i = 0; i < count; ++i)
	{
		const Eigen::Vector3d p = field.origin + Eigen::Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(size);
		const double a = bodyfit::sample(field, p);
		const double b = double(bt.distance(btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z()))));
		worst = std::max(worst, std::abs(a - b));
	}
	return worst;
}

} // namespace

TEST_CASE("bridge: the Bullet-side skin field reads what bodyfit::sample reads", "[bridge][skin_field]")
{
	const bodyfit::TriMesh sphere = bodyfit_test::uvSphere(0.1, 48, 24, Eigen::Vector3d(0.2, 1.2, -0.1));
	const bodyfit::SkinField field = bodyfit::bakeSkinField(sphere, {});
	const std::unique_ptr<btSkinDistanceField> bt = bodyfit::createSkinDistanceField(field);
	REQUIRE(bt->isValid());
	CHECK(bt->getNumStoredBricks() == field.storedBricks());
	CHECK(bt->getSeam() == 0); // every shared lattice point has one value in all its bricks
	CHECK(double(bt->getMaxError()) == Approx(field.maxError));
	// The same trilinear interpolation of the same samples; the float build rounds the point (2.4e-7 m at 2 m) and
	// the arithmetic (~1e-7 relative): 10 um covers both with room.
	CHECK(largestDisagreement(field, *bt, 20000, 1u) < 1e-5);

	bodyfit::SkinField bad = field;
	bad.brickIndex[0] = bad.storedBricks() + 3;
	CHECK_THROWS_WITH(bodyfit::createSkinDistanceField(bad), Catch::StartsWith("skin field: "));
}

TEST_CASE("bridge: a bundled body's bake passes btSkinDistanceField's checks", "[bridge][skin_field]")
{
	bodyfit::FitPipelineOptions options;
	options.fit.trueDistance = false;
	const bodyfit::FitPipelineResult fitted = bodyfit::fitMeshFile(bodyfit_test::assetPath("male_young.4508v.obj"), options);
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	for (const bodyfit::FittedEllipsoid& f : fitted.fit.ellipsoids)
		ellipsoids.push_back(f.ellipsoid);
	const bodyfit::SkinField field = bodyfit::bakeSkinField(fitted.loaded.mesh, ellipsoids);
	// set() refuses, among others, a far-outside brick next to a far-inside one: the bake keeps every brick with a
	// point inside the skin, even where the union leaves a pocket under it.
	const std::unique_ptr<btSkinDistanceField> bt = bodyfit::createSkinDistanceField(field);
	CHECK(bt->isValid());
	CHECK(bt->getSeam() == 0);
	CHECK(largestDisagreement(field, *bt, 20000, 2u) < 1e-5);
}

TEST_CASE("bridge: a body with holes (open crown, soles, a window in the belly) bakes a field set() accepts",
		  "[bridge][skin_field]")
{
	// Scans are often open at the crown and the soles. Through a hole the signs come from its rim, and a brick left
	// far inside could meet one left far outside, which set() refuses: bodyfit-drape stopped on such a body ("a
	// far-outside brick shares a face with a far-inside one"). The bake stores such pairs (holeBricks), closing the
	// hole where inside meets outside.
	// Cut from the bundled body, then fitted as bodyfit-fit fits it (the crown's ellipsoid then ends below the hole).
	const bodyfit::TriMesh closed = bodyfit::loadTriMesh(bodyfit_test::assetPath("female_young.obj")).mesh;
	const double top = closed.V.col(1).maxCoeff(), bottom = closed.V.col(1).minCoeff();
	bodyfit::TriMesh open;
	open.V = closed.V;
	std::vector<Eigen::Vector3i> kept;
	for (int f = 0; f < closed.faceCount(); ++f)
	{
		const Eigen::Vector3d c = (closed.V.row(closed.F(f, 0)) + closed.V.row(closed.F(f, 1)) + closed.V.row(closed.F(f, 2))).transpose() / 3.0;
		const bool crown = c.y() > top - 0.03, soles = c.y() < bottom + 0.01;
		const bool belly = std::abs(c.x()) < 0.02 && std::abs(c.y() - 1.05) < 0.02 && c.z() > 0.05;
		if (!crown && !soles && !belly)
			kept.push_back(closed.F.row(f).transpose());
	}
	REQUIRE(int(kept.size()) < closed.faceCount() - 1000);
	open.F.resize(Eigen::Index(kept.size()), 3);
	for (std::size_t f = 0; f < kept.size(); ++f)
		open.F.row(Eigen::Index(f)) = kept[f].transpose();
	bodyfit::FitPipelineOptions options;
	options.fit.trueDistance = false;
	const bodyfit::FitPipelineResult fitted = bodyfit::fitMesh(open, options, "open body");
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	for (const bodyfit::FittedEllipsoid& f : fitted.fit.ellipsoids)
		ellipsoids.push_back(f.ellipsoid);
	open = fitted.loaded.mesh;
	const bodyfit::SkinField field = bodyfit::bakeSkinField(open, ellipsoids);
	CHECK(field.holeBricks > 0); // (the closed body needs none: the test above checks its seam is 0)
	const std::unique_ptr<btSkinDistanceField> bt = bodyfit::createSkinDistanceField(field);
	REQUIRE(bt->isValid());
	CHECK(largestDisagreement(field, *bt, 20000, 3u) < 1e-5);
	// Still a body: deep in the chest reads far inside, a metre in front of it far outside.
	Eigen::Vector3d chest = Eigen::Vector3d::Zero();
	int n = 0;
	for (int v = 0; v < closed.vertexCount(); ++v)
		if (std::abs(closed.V(v, 1) - (bottom + 0.72 * (top - bottom))) < 0.02)
			chest += closed.V.row(v).transpose(), ++n;
	REQUIRE(n > 10);
	chest /= n;
	CHECK(bodyfit::sample(field, chest) == Approx(-field.clamp).margin(1e-3));
	CHECK(bodyfit::sample(field, chest + Eigen::Vector3d(0, 0, 1)) == Approx(field.clamp).margin(1e-3));
}

TEST_CASE("bridge: a fit file with a skin field gives a compound with the field attached", "[bridge][skin_field]")
{
	const bodyfit_test::TempDir dir("bridge_skin_field");
	bodyfit::BodyFit fit;
	bodyfit::FittedEllipsoid e;
	e.ellipsoid.radii = Eigen::Vector3d::Constant(0.11);
	fit.ellipsoids.push_back(e);
	bodyfit::writeEllipsoidJson(dir.path("plain.json"), fit);
	fit.skinField = std::make_shared<const bodyfit::SkinField>(
		bodyfit::bakeSkinField(bodyfit_test::uvSphere(0.1, 32, 16), {e.ellipsoid}));
	bodyfit::writeEllipsoidJson(dir.path("tight.json"), fit);

	const auto tight = bodyfit::loadEllipsoidCompound(dir.path("tight.json"));
	REQUIRE(tight->getSkinField() != nullptr);
	CHECK(tight->getSkinField()->getNumStoredBricks() == fit.skinField->storedBricks());
	// On the sphere's skin the attached field reads <= 0 (the bake's conservative pass), 1 cm out about +1 cm.
	CHECK(double(tight->getSkinField()->distance(btVector3(0, btScalar(0.1), 0))) <= 1e-6);
	CHECK(double(tight->getSkinField()->distance(btVector3(btScalar(0.11), 0, 0))) == Approx(0.01).margin(0.001));

	bodyfit::CompoundOptions without;
	without.attachSkinField = false;
	CHECK(bodyfit::loadEllipsoidCompound(dir.path("tight.json"), without)->getSkinField() == nullptr);
	CHECK(bodyfit::loadEllipsoidCompound(dir.path("plain.json"))->getSkinField() == nullptr);
	CHECK(bodyfit::createBodyFitCompound(fit)->getSkinField() != nullptr);
}
