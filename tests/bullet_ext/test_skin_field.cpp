// The skin distance field (bodyfit/bullet_ext/btSkinDistanceField.h) and the collider's tight mode
// (Config::m_surface TIGHT_SKIN, src/btSkinFieldResponse.cpp): fields baked in the tests from analytic shapes
// (tests/bullet_ext/skin_field_fixtures.h) inside bigger ellipsoid unions, as a fit's MVEEs enclose the real skin.
#include "bullet_ext/cloth_test_scene.h"
#include "bullet_ext/skin_field_fixtures.h"
#include "src/btSkinFieldResponse.h" // the slide, asked directly

#include <catch2/catch.hpp>

#include <cstring>
#include <random>
#include <string>

using namespace bodyfit_test;

namespace
{

const double kSkin = 0.002; // the collider's default skin offset

btVector3 toBt(const Eigen::Vector3d& p) { return btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z())); }

/// The sphere body: radius 0.1 at the origin; its union is one sphere 15 mm bigger (the MVEE gap).
double sphereBody(const Eigen::Vector3d& p) { return sphereSdf(p, Eigen::Vector3d::Zero(), 0.1); }

std::unique_ptr<btEllipsoidCompoundShape> sphereUnionWithField(bool attach = true)
{
	std::unique_ptr<btEllipsoidCompoundShape> shape =
		singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.115f, 0.115f, 0.115f));
	if (attach)
	{
		std::unique_ptr<btSkinDistanceField> field =
			bakeField(sphereBody, Eigen::Vector3d::Constant(-0.14), Eigen::Vector3d::Constant(0.14));
		REQUIRE(field != nullptr);
		REQUIRE(shape->setSkinField(field.release(), true));
	}
	return shape;
}

/// The guarantee's tolerance in analytic terms: the collider keeps field >= skin - skinFieldTolerance, and the field
/// is within maxError of the analytic distance (measured at the bake).
double analyticTolerance(const btSkinDistanceField& field)
{
	return double(btEllipsoidClothCollider::skinFieldTolerance(field)) + double(field.getMaxError());
}

} // namespace

TEST_CASE("skin field: distance and gradient of a baked sphere", "[bullet_ext][skinfield]")
{
	std::unique_ptr<btSkinDistanceField> field =
		bakeField(sphereBody, Eigen::Vector3d::Constant(-0.14), Eigen::Vector3d::Constant(0.14));
	REQUIRE(field != nullptr);
	// A consistent bake: stored neighbours share their face samples exactly.
	CHECK(double(field->getSeam()) == 0.0);
	// A distance field's interpolant has slope about 1; the per-cell bound can reach sqrt(3) only where the edge
	// differences of all three axes are at their largest at once (ridges); a sphere's band has none.
	CHECK(double(field->getLipschitz()) >= 0.95);
	CHECK(double(field->getLipschitz()) <= 1.75);
	// Trilinear interpolation of |p| - R errs by at most (h^2 / 8) x (sum of curvatures 2 / r) ~ 3 h^2 / (8 r) in the
	// unclamped band (r >= 0.096): 1e-4 m, plus the quantum (rounding down).
	CHECK(double(field->getMaxError()) < 1.1e-4 + double(field->getQuantum()));
	CHECK(double(field->getMaxError()) > 0.0);
	// Far outside and far inside, and off the grid.
	CHECK(double(field->distance(btVector3(0.135f, 0.135f, 0.135f))) == Approx(0.012).margin(1e-7));
	CHECK(double(field->distance(btVector3(0, 0, 0))) == Approx(-0.012).margin(1e-7));
	CHECK(double(field->distance(btVector3(5, 0, 0))) == Approx(0.012).margin(1e-7));
	// The normalised gradient follows the radial direction: the interpolant's gradient errs by about h / (2 r) in
	// direction (its bilinear blend of edge differences lags the curvature over one cell): 0.026 at r = 0.097, in the
	// unclamped band (|d| < 3 mm).
	std::mt19937 rng(3);
	std::normal_distribution<double> n(0.0, 1.0);
	double worstDirection = 0.0;
	for (int i = 0; i < 2000; ++i)
	{
		const Eigen::Vector3d dir = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
		const Eigen::Vector3d p = dir * (0.1 + 0.003 * (i % 11 - 5) / 5.0);
		const btVector3 g = field->gradient(toBt(p));
		worstDirection = std::max(worstDirection, (toE(g) - dir).norm());
	}
	CHECK(worstDirection < 0.04); // 0.026 is the first-order estimate; 0.04 leaves room for the second-order terms
	// At the centre (a far-inside brick) the gradient vanishes.
	CHECK(field->gradient(btVector3(0, 0, 0)).length2() == btScalar(0));
}

TEST_CASE("skin field: bad data is refused with a reason", "[bullet_ext][skinfield]")
{
	const BakedArrays good = bakeArrays(sphereBody, Eigen::Vector3d::Constant(-0.14), Eigen::Vector3d::Constant(0.14));
	struct Case
	{
		const char* what;
		const char* reasonMentions;
		std::function<void(BakedArrays&)> damage;
	};
	const std::vector<Case> cases = {
		{"NaN origin", "origin", [](BakedArrays& a) { a.layout.m_origin[1] = std::nan(""); }},
		{"zero voxel size", "voxel size", [](BakedArrays& a) { a.layout.m_voxelSize = 0; }},
		{"negative clamp", "clamp", [](BakedArrays& a) { a.layout.m_clamp = -0.012; }},
		{"infinite maxError", "maxError", [](BakedArrays& a) { a.layout.m_maxError = 1.0 / 0.0; }},
		{"negative bake skin offset", "skin offset", [](BakedArrays& a) { a.layout.m_skinOffset = -0.001; }},
		{"brick edge 4", "brick edge", [](BakedArrays& a) { a.layout.m_brickEdge = 4; }},
		{"zero bricks", "brick count", [](BakedArrays& a) { a.layout.m_bricks[2] = 0; }},
		{"short brick index", "nx * ny * nz", [](BakedArrays& a) { a.brickIndex.pop_back(); }},
		{"partial brick of samples", "multiple of", [](BakedArrays& a) { a.samples.pop_back(); }},
		{"index past the samples", "past the stored", [](BakedArrays& a) { a.brickIndex[0] = 1 << 20; }},
		{"index -3", "below -2", [](BakedArrays& a) { a.brickIndex[0] = -3; }},
		{"far outside next to far inside", "far-inside",
		 [](BakedArrays& a) {
			 // The centre brick of the grid and its +x neighbour are far inside; the neighbour made far outside.
			 const int nx = a.layout.m_bricks[0], ny = a.layout.m_bricks[1];
			 const int centre = int(0.14 / 0.04); // the brick holding the origin on every axis
			 const int c = centre + nx * (centre + ny * centre);
			 REQUIRE(a.brickIndex[size_t(c)] == btSkinDistanceField::kFarInside);
			 REQUIRE(a.brickIndex[size_t(c) + 1] == btSkinDistanceField::kFarInside);
			 a.brickIndex[size_t(c) + 1] = btSkinDistanceField::kFarOutside;
		 }},
	};
	for (const Case& c : cases)
	{
		BakedArrays a = good;
		c.damage(a);
		btSkinDistanceField field;
		const char* reason = nullptr;
		INFO(c.what);
		CHECK_FALSE(field.set(a.layout, a.brickIndex.data(), (long long)a.brickIndex.size(), a.samples.data(),
							  (long long)a.samples.size(), &reason));
		REQUIRE(reason != nullptr);
		INFO(reason);
		CHECK(std::string(reason).find(c.reasonMentions) != std::string::npos);
		CHECK_FALSE(field.isValid());
		CHECK(double(field.distance(btVector3(0, 0, 0))) > 0.0); // an empty field is far outside everywhere
	}
	// Null arrays with a non-zero count.
	btSkinDistanceField field;
	const char* reason = nullptr;
	CHECK_FALSE(field.set(good.layout, nullptr, (long long)good.brickIndex.size(), good.samples.data(),
						  (long long)good.samples.size(), &reason));
	CHECK(reason != nullptr);
	// The undamaged arrays pass.
	CHECK(field.set(good.layout, good.brickIndex.data(), (long long)good.brickIndex.size(), good.samples.data(),
					(long long)good.samples.size(), &reason));
	CHECK(reason == nullptr);
	// The compound refuses an invalid field and a field under local scaling.
	btSkinDistanceField empty;
	btEllipsoidCompoundShape shape;
	shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.115f, 0.115f, 0.115f));
	CHECK_FALSE(shape.setSkinField(&empty, false, &reason));
	CHECK(std::string(reason).find("not valid") != std::string::npos);
	shape.setLocalScaling(btVector3(2, 1, 1));
	CHECK_FALSE(shape.setSkinField(&field, false, &reason));
	CHECK(std::string(reason).find("local scaling") != std::string::npos);
}

TEST_CASE("tight mode: the surface mode, its default and local scaling", "[bullet_ext][skinfield]")
{
	// With a field, TIGHT_SKIN (the default) uses it; ELLIPSOIDS does not; a compound without one never does.
	{
		ClothScene scene(sphereUnionWithField());
		const int revision = scene.shape()->getAnalyticRevision();
		btEllipsoidClothCollider* collider = scene.install();
		REQUIRE(collider != nullptr);
		CHECK(btEllipsoidClothCollider::Config().m_surface == btEllipsoidClothCollider::TIGHT_SKIN);
		CHECK(collider->getActiveSkinField() == scene.shape()->getSkinField());
		CHECK(collider->getActiveSkinField() != nullptr);
		btEllipsoidClothCollider::Config config;
		config.m_surface = btEllipsoidClothCollider::ELLIPSOIDS;
		REQUIRE(collider->setConfig(config));
		CHECK(collider->getActiveSkinField() == nullptr);
		// A skin offset the field cannot represent (half its 12 mm clamp or more) is refused in tight mode.
		config.m_surface = btEllipsoidClothCollider::TIGHT_SKIN;
		config.m_skinOffset = btScalar(0.007);
		const char* error = nullptr;
		CHECK_FALSE(collider->setConfig(config, &error));
		CHECK(std::string(error).find("clamp") != std::string::npos);
		// Non-uniform local scaling: the field no longer describes the body; the collider falls back to the union.
		config.m_skinOffset = btScalar(kSkin);
		REQUIRE(collider->setConfig(config));
		scene.shape()->setLocalScaling(btVector3(1.5f, 1, 1));
		CHECK(scene.shape()->getAnalyticRevision() > revision);
		CHECK(collider->getActiveSkinField() == nullptr);
		scene.shape()->setLocalScaling(btVector3(1, 1, 1));
		CHECK(collider->getActiveSkinField() != nullptr);
	}
	{
		ClothScene scene(sphereUnionWithField(false));
		btEllipsoidClothCollider* collider = scene.install();
		REQUIRE(collider != nullptr);
		CHECK(collider->getActiveSkinField() == nullptr);
	}
}

namespace
{

/// Drops a 0.3 m patch of `resolution` x `resolution` nodes from just above the sphere body and runs 2 s (120 steps of
/// 1/60 s) with `config`; `minDistance` gets the smallest analytic distance of any node to the skin after any step, and
/// `atEnd(scene, cloth)` sees the final state.
template <class AtEnd>
void settleOnSphere(const btEllipsoidClothCollider::Config& config, int resolution, double& minDistance, AtEnd atEnd)
{
	ClothScene scene(sphereUnionWithField());
	REQUIRE(scene.install(config) != nullptr);
	btSoftBody* cloth = scene.addPatch(btVector3(0, btScalar(0.125), 0), btScalar(0.3), resolution);
	for (int step = 0; step < 120; ++step)
	{
		scene.step(btScalar(1.0 / 60));
		for (int i = 0; i < cloth->m_nodes.size(); ++i)
			minDistance = std::min(minDistance, sphereBody(toE(cloth->m_nodes[i].m_x)));
	}
	atEnd(scene, cloth);
}

/// Drops a 0.3 m patch (21 x 21) on the sphere body for 2 s; returns the analytic distances of the nodes in the top
/// cap (within 30 degrees of +y: the part of the cloth that rests on the sphere) and the smallest distance overall.
struct DropResult
{
	std::vector<double> capDistances;
	double minDistance = 1e30;
	btEllipsoidClothStats stats;
	std::vector<double> distances;     ///< every node at the end: analytic distance to the skin
	std::vector<bool> inCap;           ///< every node at the end: within 30 degrees of +y
	std::vector<unsigned char> flags;  ///< getContactFlags at the end (empty when the collider had no record)
};

DropResult dropOnSphere(btEllipsoidClothCollider::SurfaceMode mode)
{
	btEllipsoidClothCollider::Config config;
	config.m_surface = mode;
	DropResult out;
	settleOnSphere(config, 21, out.minDistance, [&](ClothScene& scene, btSoftBody* cloth) {
		for (int i = 0; i < cloth->m_nodes.size(); ++i)
		{
			const Eigen::Vector3d p = toE(cloth->m_nodes[i].m_x);
			const bool cap = p.normalized().y() > std::cos(M_PI / 6);
			if (cap)
				out.capDistances.push_back(sphereBody(p));
			out.distances.push_back(sphereBody(p));
			out.inCap.push_back(cap);
		}
		out.stats = scene.collider()->getAccumulatedStats();
		if (const btAlignedObjectArray<unsigned char>* flags = scene.collider()->getContactFlags(cloth))
			for (int i = 0; i < flags->size(); ++i)
				out.flags.push_back((*flags)[i]);
	});
	return out;
}

} // namespace

TEST_CASE("tight mode: a cloth dropped on a sphere rests on the skin, not on the ellipsoid", "[bullet_ext][skinfield]")
{
	const DropResult tight = dropOnSphere(btEllipsoidClothCollider::TIGHT_SKIN);
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	REQUIRE(tight.capDistances.size() >= 9); // the cap holds the patch's central 3 x 3 nodes at least
	for (double d : tight.capDistances)
	{
		// Resting on the skin: at the offset, within the field's tolerance below and 1 mm above (issue 14's bound;
		// the march stops within 50 um above the level, the rest is the cloth's sag between substeps).
		CHECK(d >= kSkin - tol);
		CHECK(d <= kSkin + 0.001);
	}
	// No node of the cloth ever ended inside the skin (checked after every step).
	CHECK(tight.minDistance >= kSkin - tol);
	CHECK(double(tight.stats.m_minSkinField) >= kSkin - double(btEllipsoidClothCollider::skinFieldTolerance(*probe->getSkinField())));
	CHECK(tight.stats.m_nodesCorrected > 0);
	CHECK(tight.stats.m_skinFallbacks == 0);
	// The same drop in ELLIPSOIDS mode rests on the union, 15 mm + skin off the sphere: the test tells them apart.
	const DropResult ellipsoids = dropOnSphere(btEllipsoidClothCollider::ELLIPSOIDS);
	REQUIRE(!ellipsoids.capDistances.empty());
	for (double d : ellipsoids.capDistances)
		CHECK(d > 0.015);
}

namespace
{

/// A coarse cloth (0.3 m; 7 x 7 nodes: 5 cm edges, 7 cm diagonals; 11 x 11: 3 and 4.2 cm) dropped on the 0.1 m
/// sphere, with or without Config::m_liftEdges: per edge, the smallest analytic distance to the skin over 9 points of
/// it at the end; per node, the smallest distance it ever had.
struct CoarseDrop
{
	double minEdgeDistance = 1e30; ///< over the cloth's edges at the end (negative: an edge cuts into the sphere)
	/// ... over those the lift can clear: sagging at most 7 mm over the sphere (L^2 / 8R, L <= 7.4 cm; a lifted node's
	/// level stands at most 3 offsets above the offset, btSkinFieldGeometry::maxRise, 8 mm off the skin, and the
	/// edge's middle 1 mm clear; the 7 x 7 cloth's diagonals stretch to 9.6 cm: 11.5 mm of sag) and stretched at most
	/// 1.5x (a longer edge spans something and asks nothing)
	double minFittingEdgeDistance = 1e30;
	double minNodeDistance = 1e30; ///< over every node after every step
	double maxCapDistance = 0;     ///< over the nodes within 30 degrees of +y at the end (resting on the sphere)
	double meanCapDistance = 0;    ///< the same nodes' mean
	int edgesTested = 0;           ///< edges with both nodes within 1 cm of the skin at the end
	int nodesLifted = 0;
};

CoarseDrop dropCoarseOnSphere(bool liftEdges, btScalar liftClearance = btScalar(0.5), int resolution = 7)
{
	btEllipsoidClothCollider::Config config;
	config.m_liftEdges = liftEdges;
	config.m_liftClearance = liftClearance;
	CoarseDrop out;
	settleOnSphere(config, resolution, out.minNodeDistance, [&](ClothScene& scene, btSoftBody* cloth) {
		for (int l = 0; l < cloth->m_links.size(); ++l)
		{
			const Eigen::Vector3d a = toE(cloth->m_links[l].m_n[0]->m_x), b = toE(cloth->m_links[l].m_n[1]->m_x);
			if (cloth->m_links[l].m_bbending || sphereBody(a) > 0.01 || sphereBody(b) > 0.01)
				continue;
			++out.edgesTested;
			double m = 1e30;
			for (int k = 1; k <= 9; ++k)
				m = std::min(m, sphereBody(a + (b - a) * (k / 10.0)));
			out.minEdgeDistance = std::min(out.minEdgeDistance, m);
			if ((b - a).norm() <= std::min(0.074, 1.5 * double(cloth->m_links[l].m_rl)))
				out.minFittingEdgeDistance = std::min(out.minFittingEdgeDistance, m);
		}
		int capNodes = 0;
		for (int i = 0; i < cloth->m_nodes.size(); ++i)
		{
			const Eigen::Vector3d p = toE(cloth->m_nodes[i].m_x);
			if (p.normalized().y() > std::cos(M_PI / 6))
			{
				out.maxCapDistance = std::max(out.maxCapDistance, sphereBody(p));
				out.meanCapDistance += sphereBody(p);
				++capNodes;
			}
		}
		out.meanCapDistance /= std::max(capNodes, 1);
		out.nodesLifted = scene.collider()->getAccumulatedStats().m_nodesLifted;
	});
	return out;
}

} // namespace

TEST_CASE("tight mode: lifted edges clear the skin between nodes, and nodes stay outside", "[bullet_ext][skinfield][edges]")
{
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	// Without the lift the nodes rest at the 2 mm offset and a 5 cm edge over the 0.1 m sphere sags L^2 / 8R = 3.1 mm
	// between them: its middle is about 1 mm inside the skin. This is what the lift is for (the case is not vacuous).
	const CoarseDrop sag = dropCoarseOnSphere(false);
	REQUIRE(sag.edgesTested >= 12); // the cap's edges at least
	CHECK(sag.minEdgeDistance < -0.0005);
	CHECK(sag.nodesLifted == 0);
	// With it the middle of every edge that fits under the highest level rises to half the offset (1 mm) above the
	// field's zero level, which encloses the skin; 9 points per edge on a convex skin are at least as far as the
	// middle, up to the field's tolerance.
	const CoarseDrop lifted = dropCoarseOnSphere(true);
	REQUIRE(lifted.edgesTested >= 12);
	CHECK(lifted.nodesLifted > 0);
	CHECK(lifted.minFittingEdgeDistance >= -tol);
	CHECK(sag.minFittingEdgeDistance < -0.0005); // (and those edges did cut without the lift)
	// Nodes never end inside the skin offset (the guarantee, lift or not) ...
	CHECK(sag.minNodeDistance >= kSkin - tol);
	CHECK(lifted.minNodeDistance >= kSkin - tol);
	// ... and the lift raises the cap (within 30 degrees of the top) by at most the highest level, 6 mm above the
	// offset, plus the 0.3 mm the march may stop above a level (the coarse cloth does not conform to the cap either
	// way: its nodes there rest up to ~9 mm off).
	CHECK(lifted.maxCapDistance <= sag.maxCapDistance + 0.0063);
}

TEST_CASE("tight mode: a lower lift clearance rests the cloth closer and its edges still clear the skin", "[bullet_ext][skinfield][edges]")
{
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	// 11 x 11 nodes: the 4.2 cm diagonals sag 2.2 mm over the sphere, so the nodes rest about 1.2 mm (clearance 0.5)
	// or 0.7 mm (0.25) above the offset where they are lifted, well under the highest level.
	const CoarseDrop half = dropCoarseOnSphere(true, btScalar(0.5), 11);
	const CoarseDrop quarter = dropCoarseOnSphere(true, btScalar(0.25), 11);
	REQUIRE(quarter.edgesTested >= 12);
	CHECK(quarter.nodesLifted > 0);
	// The edges' middles rise to half (1 mm) or a quarter of the offset (0.5 mm) above the zero level: none reaches
	// the skin, up to the field's tolerance (an edge stretched past 1.5x asks nothing: 11 x 11 has one, 6.6 cm for
	// 4.2, 0.7 mm deep).
	CHECK(half.minFittingEdgeDistance >= -tol);
	CHECK(quarter.minFittingEdgeDistance >= -tol);
	CHECK(quarter.minNodeDistance >= kSkin - tol);
	INFO("mean cap distance: clearance 0.5 " << half.meanCapDistance << ", 0.25 " << quarter.meanCapDistance);
	// The cap's nodes, lifted by their sagging edges, rest lower by up to the 0.5 mm of clearance given up; a quarter
	// of it (0.125 mm) is far above the run-to-run noise of a settled cloth (deterministic here) and below the most.
	CHECK(quarter.meanCapDistance < half.meanCapDistance - 0.000125);
}

TEST_CASE("tight mode: an edge with one end held off the skin by its links is lifted from both ends", "[bullet_ext][skinfield][edges]")
{
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	// 7 x 7 nodes at clearance 0.25 on the sphere: where the cap's edges meet the cloth falling away from it, an edge
	// joins a node in contact to one the links hold a few millimetres above its level. Lifted from its contact end
	// only (the lift before 2026-12-07), the middle rose by half of that end's rise and an edge stayed 1.5 mm inside
	// the skin (this check failed); lifted from both ends, every edge that fits under the highest level clears it.
	const CoarseDrop drop = dropCoarseOnSphere(true, btScalar(0.25), 7);
	REQUIRE(drop.edgesTested >= 12);
	CHECK(drop.nodesLifted > 0);
	CHECK(drop.minFittingEdgeDistance >= -tol);
	CHECK(drop.minNodeDistance >= kSkin - tol);
	// And no cap node climbs to the highest level (6 mm above the 2 mm offset) to do it: 8 mm less the 0.5 mm
	// contact band (the highest cap node: 6.75 mm with the one-sided lift, 5.3 mm now).
	CHECK(drop.maxCapDistance < kSkin + 0.006 - 0.0005);
}

TEST_CASE("tight mode: the edge lift follows links shuffled by randomizeConstraints mid-run", "[bullet_ext][skinfield][edges]")
{
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	ClothScene scene(sphereUnionWithField());
	REQUIRE(scene.install() != nullptr);
	btSoftBody* cloth = scene.addPatch(btVector3(0, btScalar(0.125), 0), btScalar(0.3), 11);
	for (int step = 0; step < 60; ++step)
		scene.step(btScalar(1.0 / 60));
	// SoftDemo's scenes call this; it permutes m_links in place (same size, same array), after the lift listed them.
	cloth->randomizeConstraints();
	for (int step = 0; step < 60; ++step)
		scene.step(btScalar(1.0 / 60));
	// Every edge at the skin (both ends within 1 cm), at most 1.5x stretched, clears it as without the shuffle.
	double minEdge = 1e30;
	int tested = 0;
	for (int l = 0; l < cloth->m_links.size(); ++l)
	{
		const btSoftBody::Link& link = cloth->m_links[l];
		const Eigen::Vector3d a = toE(link.m_n[0]->m_x), b = toE(link.m_n[1]->m_x);
		if (link.m_bbending || sphereBody(a) > 0.01 || sphereBody(b) > 0.01 || (b - a).norm() > 1.5 * double(link.m_rl))
			continue;
		++tested;
		for (int k = 1; k <= 9; ++k)
			minEdge = std::min(minEdge, sphereBody(a + (b - a) * (k / 10.0)));
	}
	REQUIRE(tested >= 12);
	CHECK(minEdge >= -tol);
	CHECK(scene.collider()->getAccumulatedStats().m_nodesLifted > 0);
}

TEST_CASE("tight mode: switching the edge lift off brings raised nodes back to the skin offset", "[bullet_ext][skinfield][edges]")
{
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	btEllipsoidClothCollider::Config config;
	ClothScene scene(sphereUnionWithField());
	btEllipsoidClothCollider* collider = scene.install(config);
	REQUIRE(collider != nullptr);
	// 11 x 11 nodes on the sphere: the 4.2 cm diagonals sag 2.2 mm, so the lift raises nodes about 1.2 mm.
	btSoftBody* cloth = scene.addPatch(btVector3(0, btScalar(0.125), 0), btScalar(0.3), 11);
	const auto highestContact = [&]() {
		double highest = 0;
		const btAlignedObjectArray<unsigned char>* flags = collider->getContactFlags(cloth);
		REQUIRE(flags != nullptr);
		REQUIRE(flags->size() == cloth->m_nodes.size());
		for (int i = 0; i < cloth->m_nodes.size(); ++i)
			if ((*flags)[i])
				highest = std::max(highest, sphereBody(toE(cloth->m_nodes[i].m_x)));
		return highest;
	};
	for (int step = 0; step < 120; ++step)
		scene.step(btScalar(1.0 / 60));
	const double lifted = highestContact();
	REQUIRE(collider->getAccumulatedStats().m_nodesLifted > 0);
	config.m_liftEdges = false;
	REQUIRE(collider->setConfig(config));
	for (int step = 0; step < 60; ++step)
		scene.step(btScalar(1.0 / 60));
	const double after = highestContact();
	INFO("highest contact node: lifted " << lifted << ", 1 s after the lift was switched off " << after);
	// Raised, some contact rests more than 1 mm above the 2 mm offset; without the lift every contact rests at the
	// offset again, within the 0.5 mm contact band above it and the field's tolerance below.
	CHECK(lifted > kSkin + 0.001);
	CHECK(after <= kSkin + 0.0005 + tol);
}

TEST_CASE("tight mode: a field whose contents change in place is read afresh, not from the nodes' last readings",
		  "[bullet_ext][skinfield]")
{
	// The collider keeps each node's last field reading and reuses it when the next substep starts at that point;
	// the field's content id ties the readings to the contents they were taken on.
	std::unique_ptr<btEllipsoidCompoundShape> shape =
		singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.115f, 0.115f, 0.115f));
	std::unique_ptr<btSkinDistanceField> owned =
		bakeField(sphereBody, Eigen::Vector3d::Constant(-0.14), Eigen::Vector3d::Constant(0.14));
	REQUIRE(owned != nullptr);
	btSkinDistanceField* field = owned.get();
	REQUIRE(shape->setSkinField(owned.release(), true));
	// The body grown by 4 mm: a node resting 2 mm above the first skin is 2 mm inside it (its level 4 mm below).
	const double grown = 0.104;
	const auto grownBody = [&](const Eigen::Vector3d& p) { return sphereSdf(p, Eigen::Vector3d::Zero(), grown); };
	std::unique_ptr<btSkinDistanceField> bigger =
		bakeField(grownBody, Eigen::Vector3d::Constant(-0.14), Eigen::Vector3d::Constant(0.14));
	REQUIRE(bigger != nullptr);
	const double tol = analyticTolerance(*bigger);
	ClothScene scene(std::move(shape));
	REQUIRE(scene.install() != nullptr);
	btSoftBody* cloth = scene.addPatch(btVector3(0, btScalar(0.125), 0), btScalar(0.3), 21);
	for (int step = 0; step < 90; ++step)
		scene.step(btScalar(1.0 / 60));
	int resting = 0;
	for (int i = 0; i < cloth->m_nodes.size(); ++i)
		resting += sphereBody(toE(cloth->m_nodes[i].m_x)) < 0.004 ? 1 : 0;
	REQUIRE(resting >= 20);
	const unsigned before = field->getContentId();
	*field = *bigger; // the same object the compound holds, new contents
	CHECK(field->getContentId() != before);
	scene.step(btScalar(1.0 / 60));
	// Every node is pushed out to the grown skin's offset in the first step (within the field's tolerance); with the
	// old readings the resting nodes would have stayed where they were, 2 mm inside.
	double deepest = 1e30;
	for (int i = 0; i < cloth->m_nodes.size(); ++i)
		deepest = std::min(deepest, grownBody(toE(cloth->m_nodes[i].m_x)));
	CHECK(deepest >= kSkin - tol);
}

TEST_CASE("tight mode: a slide along the field stays on its side of a sheet thinner than its pieces", "[bullet_ext][skinfield]")
{
	// A sheet 0.5 mm thick across the whole grid (the field is |y| - 0.25 mm, slope 1), baked at 0.5 mm voxels. A slide
	// piece is tried at 1.5 offset / L = 3 mm: straight down from the top level (2.25 mm) it would end 0.75 mm below
	// the sheet's middle, outside the skin on the far side, where Newton would take it to the far level. The piece's
	// clearance test (both ends' clear balls cover it, else the start's ball alone) keeps every slide on its side.
	const Eigen::Vector3d half(1.0, 0.00025, 1.0);
	const auto plate = [&](const Eigen::Vector3d& p) { return boxSdf(p, Eigen::Vector3d::Zero(), half); };
	std::unique_ptr<btSkinDistanceField> field =
		bakeField(plate, Eigen::Vector3d(-0.03, -0.006, -0.03), Eigen::Vector3d(0.03, 0.006, 0.03), 0.0005, 0.004);
	REQUIRE(field != nullptr);
	REQUIRE(field->getLipschitz() < btScalar(1.01));
	const double tol = analyticTolerance(*field);
	const btScalar offset = btScalar(kSkin);
	btSkinFieldGeometry geometry;
	geometry.begin(field.get(), offset, btTransform::getIdentity());
	std::mt19937 rng(11);
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	int moved = 0;
	for (int k = 0; k < 500; ++k)
	{
		// A start on the top level within 5 mm of the grid's middle, and a displacement of 1-15 mm pointing into the
		// sheet at any angle (the slide stays inside the grid).
		const btVector3 above(btScalar(0.005 * u(rng)), btScalar(half.y() + kSkin + 0.0005), btScalar(0.005 * u(rng)));
		btVector3 start;
		btScalar value;
		REQUIRE(geometry.pushOut(above, offset, start, value));
		btVector3 d(btScalar(u(rng)), btScalar(-2.0 * std::abs(u(rng)) - 0.05), btScalar(u(rng)));
		d *= btScalar(0.001 + 0.007 * (u(rng) + 1.0)) / d.length();
		const btVector3 end = geometry.slide(start, d, offset, value);
		moved += (end - start).length() > btScalar(1e-4) ? 1 : 0;
		const Eigen::Vector3d e = toE(end);
		INFO("slide " << k << " from y " << start.y() << " by (" << d.x() << ", " << d.y() << ", " << d.z() << ")");
		CHECK(e.y() > 0.0);                       // on the top side
		CHECK(plate(e) >= double(offset) - tol); // at the level or above it
		// The value the slide hands back is the field where it left the node (the collider keeps it as a reading).
		CHECK(value == field->distance(end));
	}
	CHECK(moved > 400); // the slides went somewhere (along the surface; the rest met a flat spot and stopped)
}

TEST_CASE("contact flags: set for the cloth resting on the sphere, not for the cloth hanging free", "[bullet_ext][skinfield]")
{
	std::unique_ptr<btEllipsoidCompoundShape> probe = sphereUnionWithField();
	const double tol = analyticTolerance(*probe->getSkinField());
	// The surface each mode keeps the cloth off, as an analytic distance: the skin (radius 0.1) or the union (0.115).
	const double unionGrowth = 0.015;
	for (const btEllipsoidClothCollider::SurfaceMode mode : {btEllipsoidClothCollider::TIGHT_SKIN,
															 btEllipsoidClothCollider::ELLIPSOIDS})
	{
		const bool tight = mode == btEllipsoidClothCollider::TIGHT_SKIN;
		const DropResult r = dropOnSphere(mode);
		REQUIRE(r.flags.size() == r.distances.size());
		int flagged = 0, clear = 0;
		for (std::size_t i = 0; i < r.flags.size(); ++i)
		{
			const double d = r.distances[i] - (tight ? 0.0 : unionGrowth);
			// A flagged node touches the surface: placed at the skin offset (the tight march stops within 0.5 mm
			// above it; the ellipsoid mode may place a node that started closer at its own clearance, never below
			// the union) or held at its start, which after 2 s of rest is that placement; 1 mm above is issue 14's
			// bound for resting cloth, tol below the field's guarantee.
			if (r.flags[i])
			{
				++flagged;
				CHECK(d >= (tight ? kSkin - tol : -tol));
				CHECK(d <= kSkin + 0.001);
			}
			// Cloth hanging clear of the sphere (1 cm away: five skin offsets) is never a contact.
			if (d > 0.01)
			{
				++clear;
				CHECK(!r.flags[i]);
			}
			// The cap rests on the sphere, pressed by the cloth's weight: every one of its nodes is a contact.
			if (r.inCap[i])
				CHECK(r.flags[i]);
		}
		CHECK(flagged >= 9); // the cap's central 3 x 3 nodes at least
		CHECK(clear > 0);    // the hanging corners: the check above is not vacuous
	}
}

namespace
{

/// Free nodes at rest at `starts` inside a body; one step of the world without gravity (the push-out alone moves
/// them); their final positions.
std::vector<Eigen::Vector3d> stepNodes(std::unique_ptr<btEllipsoidCompoundShape> shape, const std::vector<btVector3>& starts,
									   btEllipsoidClothStats* stats = nullptr)
{
	ClothScene scene(std::move(shape));
	scene.world()->setGravity(btVector3(0, 0, 0));
	scene.world()->getWorldInfo().m_gravity.setValue(0, 0, 0);
	REQUIRE(scene.install() != nullptr);
	REQUIRE(scene.collider()->getActiveSkinField() != nullptr);
	btSoftBody* probe = scene.addNodes(starts);
	scene.step(btScalar(1.0 / 60));
	std::vector<Eigen::Vector3d> out;
	for (int i = 0; i < probe->m_nodes.size(); ++i)
		out.push_back(toE(probe->m_nodes[i].m_x));
	if (stats)
		*stats = scene.collider()->getAccumulatedStats();
	return out;
}

double boxBody(const Eigen::Vector3d& p) { return boxSdf(p, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(0.1)); }

} // namespace

TEST_CASE("tight mode: nodes inside a box leave through the nearest face, edge or corner", "[bullet_ext][skinfield]")
{
	// The box [-0.1, 0.1]^3 inside the sphere union of radius 0.2 (it encloses the corners at 0.173).
	std::unique_ptr<btEllipsoidCompoundShape> shape =
		singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.2f, 0.2f, 0.2f));
	std::unique_ptr<btSkinDistanceField> field =
		bakeField(boxBody, Eigen::Vector3d::Constant(-0.13), Eigen::Vector3d::Constant(0.13));
	REQUIRE(field != nullptr);
	const double tol = analyticTolerance(*field);
	REQUIRE(shape->setSkinField(field.release(), true));
	// Within the clamp (12 mm) of the surface, so the field's gradient is there: near the +z face, the -x face, the
	// bottom face, an edge and a corner. Expected exit direction for each.
	const std::vector<btVector3> starts = {btVector3(0.02f, 0.01f, 0.095f), btVector3(-0.094f, 0.03f, -0.02f),
										   btVector3(0.0f, -0.092f, 0.04f), btVector3(0.096f, 0.096f, 0.0f),
										   btVector3(-0.096f, -0.096f, 0.096f)};
	const std::vector<Eigen::Vector3d> exits = {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(-1, 0, 0),
												Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(1, 1, 0).normalized(),
												Eigen::Vector3d(-1, -1, 1).normalized()};
	btEllipsoidClothStats stats;
	const std::vector<Eigen::Vector3d> ends = stepNodes(std::move(shape), starts, &stats);
	for (size_t i = 0; i < ends.size(); ++i)
	{
		INFO("node " << i << " at " << ends[i].transpose());
		CHECK(boxBody(ends[i]) >= kSkin - tol);   // outside the box, at the skin offset
		CHECK(boxBody(ends[i]) <= kSkin + 0.001); // and not thrown off it
		// Moved the way out: along the nearest feature's outward direction (an edge or corner at equal depths is a
		// ridge of the interior distance; the interpolant's gradient there is the symmetric blend). 0.1 rad: the
		// Newton steps follow the interpolant's gradient, which leans by up to h / 2 over a cell near the ridge.
		const Eigen::Vector3d moved = ends[i] - toE(starts[i]);
		CHECK(moved.normalized().dot(exits[i]) > std::cos(0.1));
	}
	CHECK(stats.m_nodesPushedOut == int(starts.size()));
	CHECK(stats.m_skinFallbacks == 0);
}

TEST_CASE("tight mode: push-out in the crease of two capsules leaves both", "[bullet_ext][skinfield]")
{
	// An L of two capsules (radius 4 cm) meeting at the origin; each in an ellipsoid of its own (the union encloses them).
	const Eigen::Vector3d o(0, 0, 0), ex(0.2, 0, 0), ey(0, 0.2, 0);
	const AnalyticSdf body = [&](const Eigen::Vector3d& p) {
		return std::min(capsuleSdf(p, o, ex, 0.04), capsuleSdf(p, o, ey, 0.04));
	};
	std::unique_ptr<btEllipsoidCompoundShape> shape(new btEllipsoidCompoundShape());
	shape->addEllipsoid(btVector3(0.1f, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.17f, 0.06f, 0.06f));
	shape->addEllipsoid(btVector3(0, 0.1f, 0), btMatrix3x3::getIdentity(), btVector3(0.06f, 0.17f, 0.06f));
	std::unique_ptr<btSkinDistanceField> field =
		bakeField(body, Eigen::Vector3d(-0.08, -0.08, -0.08), Eigen::Vector3d(0.28, 0.28, 0.08));
	REQUIRE(field != nullptr);
	const double tol = analyticTolerance(*field);
	const double maxError = double(field->getMaxError());
	REQUIRE(shape->setSkinField(field.release(), true));
	// In the inner corner, inside both capsules or one of them, a few mm deep.
	const std::vector<btVector3> starts = {btVector3(0.038f, 0.038f, 0.0f), btVector3(0.045f, 0.036f, 0.005f),
										   btVector3(0.036f, 0.05f, -0.01f), btVector3(0.039f, 0.041f, 0.012f)};
	btEllipsoidClothStats stats;
	const std::vector<Eigen::Vector3d> ends = stepNodes(std::move(shape), starts, &stats);
	for (size_t i = 0; i < ends.size(); ++i)
	{
		INFO("node " << i << " at " << ends[i].transpose());
		CHECK(body(ends[i]) >= kSkin - tol);
		// Not thrown off: the interpolant of the crease's min() reads below the true distance there (the bake's
		// maxError says by how much), the push stops within the hit band (50 um) above the offset.
		CHECK(body(ends[i]) <= kSkin + maxError + 1e-4);
		// Out of the crease into the open quadrant (x, y > 0), not through a capsule to the far side.
		CHECK(ends[i].x() > 0.0);
		CHECK(ends[i].y() > 0.0);
	}
	CHECK(stats.m_skinFallbacks == 0);
}

TEST_CASE("tight mode: a node at the field's extremum (the centre) falls back to the union push-out",
		  "[bullet_ext][skinfield]")
{
	std::unique_ptr<btEllipsoidCompoundShape> shape = sphereUnionWithField();
	const double tol = analyticTolerance(*shape->getSkinField());
	// The centre (a far-inside brick, gradient zero) and a point 5 cm deep (clamped samples, gradient zero).
	const std::vector<btVector3> starts = {btVector3(0, 0, 0), btVector3(0.03f, 0.02f, -0.01f)};
	btEllipsoidClothStats stats;
	const std::vector<Eigen::Vector3d> ends = stepNodes(std::move(shape), starts, &stats);
	for (size_t i = 0; i < ends.size(); ++i)
	{
		INFO("node " << i << " at " << ends[i].transpose());
		CHECK(sphereBody(ends[i]) >= kSkin - tol); // out of the body: at the union's surface plus the skin
		CHECK(std::isfinite(ends[i].norm()));
	}
	CHECK(stats.m_skinFallbacks == int(starts.size()));
	CHECK(stats.m_nonFiniteNodes == 0);
}

TEST_CASE("tight mode: a kinematic box rising and turning through a pinned cloth carries it, none inside",
		  "[bullet_ext][skinfield]")
{
	// The box (half sizes 0.12, 0.05, 0.08 in the body frame) in one ellipsoid that encloses it; the body rises at
	// 0.6 m/s and turns about y, so the field is read through a moving, rotated body frame, 4 substeps per step.
	const Eigen::Vector3d half(0.12, 0.05, 0.08);
	const AnalyticSdf box = [&](const Eigen::Vector3d& p) { return boxSdf(p, Eigen::Vector3d::Zero(), half); };
	std::unique_ptr<btEllipsoidCompoundShape> shape =
		singleEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.22f, 0.095f, 0.15f));
	std::unique_ptr<btSkinDistanceField> field =
		bakeField(box, Eigen::Vector3d(-0.25, -0.13, -0.18), Eigen::Vector3d(0.25, 0.13, 0.18));
	REQUIRE(field != nullptr);
	const double tol = analyticTolerance(*field);
	REQUIRE(shape->setSkinField(field.release(), true));
	ClothScene scene(std::move(shape), btTransform::getIdentity(), true);
	btSoftBody* cloth = scene.addPatch(btVector3(0, 0.3f, 0), btScalar(0.8), 21);
	for (int corner : {0, 20, 420, 440})
		cloth->setMass(corner, 0);
	btEllipsoidClothCollider* collider = scene.install();
	REQUIRE(collider != nullptr);
	REQUIRE(collider->getActiveSkinField() != nullptr);
	double worst = 1e30;
	btTransform pose = btTransform::getIdentity();
	for (int i = 0; i < 60; ++i)
	{
		pose.setOrigin(btVector3(0, btScalar(0.6 * (i + 1) / 60.0), 0));
		pose.setRotation(btQuaternion(btVector3(0, 1, 0), btScalar(0.02 * (i + 1))));
		scene.motion()->setWorldTransform(pose);
		scene.step(btScalar(1.0 / 60), 4, btScalar(1.0 / 240));
		// In the body frame of the pose the collider used last.
		const btTransform toBody = collider->getWorldCache().getTransform().inverse();
		for (int n = 0; n < cloth->m_nodes.size(); ++n)
			worst = std::min(worst, box(toE(toBody * cloth->m_nodes[n].m_x)));
	}
	// No node ever ended a step inside the skin (the pinned corners are far from the box).
	CHECK(worst >= kSkin - tol);
	// The cloth was carried: its centre node rests on the box top (centre 0.6, top 0.65), within 1 mm above the skin.
	const Eigen::Vector3d centre = toE(cloth->m_nodes[10 * 21 + 10].m_x);
	CHECK(centre.y() > 0.65 + kSkin - tol);
	CHECK(centre.y() < 0.65 + kSkin + 0.001);
	const btEllipsoidClothStats& stats = collider->getAccumulatedStats();
	// The start q is carried with the body, so the box moving into a node is a path that meets the skin, not a start
	// inside it.
	CHECK(stats.m_nodesCorrected > 0);
	CHECK(stats.m_skinFallbacks == 0);
	CHECK(double(stats.m_minSkinField) >= kSkin - double(btEllipsoidClothCollider::skinFieldTolerance(*scene.shape()->getSkinField())));
}

