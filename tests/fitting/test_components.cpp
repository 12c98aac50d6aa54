// Bodies made of several meshes (components.h): game assets built from a bundled body (separate head and forearms
// a few mm from it, eyes inside the head, a prop far away) are segmented and fitted as one body, and what is left
// out is reported. Also the synthetic cases of each component role.

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/components.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/segmentation.h"
#include "support/mesh_shapes.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <limits>

using namespace bodyfit;
using bodyfit_test::appended;
using bodyfit_test::assetPath;
using bodyfit_test::detached;
using bodyfit_test::subdividedCube;
using bodyfit_test::uvSphere;

namespace
{

/// female_young split like a game asset: head and both forearms (with the hands) as separate meshes moved 3 mm
/// off the body (head up, forearms outward), two eyes (spheres of 10 mm radius) inside the head and, optionally,
/// a prop (a 20 cm box) 1.5 m to the side.
struct GameAsset
{
	TriMesh mesh;
	std::vector<int> origin;     ///< per vertex: the vertex of the bundled body it was made from (-1: eyes, prop)
	std::vector<Region> labels;  ///< the bundled body's segmentation, per vertex of the bundled body
	int bodyVertices = 0;        ///< vertices before the eyes and the prop were appended
	int eyeVertices = 0;
	int propVertices = 0;
};

const GameAsset& gameAsset()
{
	static const GameAsset asset = [] {
		GameAsset a;
		const TriMesh body = loadTriMesh(assetPath("female_young.obj")).mesh;
		const Segmentation seg = segmentBody(body);
		REQUIRE(seg.ok);
		a.labels = seg.labels;
		auto allLabelled = [&](const TriMesh& m, int f, Region r) {
			for (int k = 0; k < 3; ++k)
			{
				const int v = m.F(f, k);
				if (v >= body.vertexCount() || seg.labels[size_t(v)] != r)
					return false;
			}
			return true;
		};
		std::vector<int> copy;
		TriMesh m = detached(body, [&](int f) { return allLabelled(body, f, Region::Head); },
			Eigen::Vector3d(0, 0.003, 0), &copy);
		a.origin.assign(size_t(m.vertexCount()), -1);
		for (int v = 0; v < body.vertexCount(); ++v)
		{
			a.origin[size_t(v)] = v;
			if (copy[size_t(v)] >= 0)
				a.origin[size_t(copy[size_t(v)])] = v;
		}
		// Forearms: the faces of the original vertices labelled lower arm (copies of head vertices are never).
		for (const auto& [region, side] : {std::make_pair(Region::ArmLowerLeft, 1.0), {Region::ArmLowerRight, -1.0}})
		{
			const TriMesh before = m;
			m = detached(before, [&](int f) { return allLabelled(before, f, region); },
				Eigen::Vector3d(0.003 * side, 0, 0), &copy);
			a.origin.resize(size_t(m.vertexCount()), -1);
			for (int v = 0; v < before.vertexCount(); ++v)
				if (copy[size_t(v)] >= before.vertexCount())
					a.origin[size_t(copy[size_t(v)])] = a.origin[size_t(v)];
		}
		a.bodyVertices = m.vertexCount();
		// Eyes: 8 cm below the head top, 3 cm to each side, 3 cm behind the face (female_young's skull spans
		// z = -0.04 .. 0.14 m there; it faces +z).
		const double top = body.V.col(1).maxCoeff();
		for (double side : {-1.0, 1.0})
		{
			const TriMesh eye = uvSphere(0.010, 12, 8, Eigen::Vector3d(0.03 * side, top - 0.08, 0.10));
			a.eyeVertices += eye.vertexCount();
			m = appended(m, eye);
		}
		a.origin.resize(size_t(m.vertexCount()), -1);
		a.mesh = m;
		return a;
	}();
	return asset;
}

TriMesh withProp(const GameAsset& a, int* propVertices)
{
	TriMesh prop = subdividedCube(0.2, 4);
	prop.V.rowwise() += Eigen::RowVector3d(1.5, 0.0, 0.0);
	*propVertices = prop.vertexCount();
	return appended(a.mesh, prop);
}

/// Largest zeta of a vertex over its best ellipsoid: <= 1 means every vertex is inside the union.
double worstZeta(const TriMesh& mesh, const BodyFit& fit)
{
	double worst = 0.0;
	for (int v = 0; v < mesh.vertexCount(); ++v)
	{
		double best = std::numeric_limits<double>::infinity();
		for (const FittedEllipsoid& e : fit.ellipsoids)
			best = std::min(best, e.ellipsoid.zeta(mesh.V.row(v).transpose()));
		worst = std::max(worst, best);
	}
	return worst;
}

} // namespace

TEST_CASE("components: a game asset's separate parts, eyes and prop get their roles", "[fitting][components]")
{
	const GameAsset& a = gameAsset();
	int propVertices = 0;
	const TriMesh mesh = withProp(a, &propVertices);
	// The eyes really are inside the head (the premise of the test).
	const MeshInsideTest inside(a.mesh);
	for (int v = a.bodyVertices; v < a.mesh.vertexCount(); ++v)
		REQUIRE(inside.isInside(a.mesh.V.row(v).transpose()));

	const ComponentLayout layout = analyzeComponents(mesh);
	REQUIRE(layout.components.size() == 7); // body, head, two forearms, two eyes, prop
	CHECK(layout.count(ComponentRole::Body) == 1);
	CHECK(layout.count(ComponentRole::Attached) == 3);
	CHECK(layout.count(ComponentRole::Inside) == 2);
	CHECK(layout.vertexCount(ComponentRole::Inside) == a.eyeVertices);
	CHECK(layout.count(ComponentRole::Detached) == 1);
	CHECK(layout.vertexCount(ComponentRole::Detached) == propVertices);
	// The eyes' host is the head (the component that holds the head top), itself attached.
	const int headTop = int(std::max_element(mesh.V.col(1).data(), mesh.V.col(1).data() + a.bodyVertices) -
							mesh.V.col(1).data());
	for (const MeshComponent& c : layout.components)
		if (c.role == ComponentRole::Inside)
			CHECK(c.host == layout.vertexComponent[size_t(headTop)]);
	// Bridges join different body components: a vertex within the gap (1% of the body's extent, 14 mm here) of the
	// other's surface to the nearest vertex there, so no longer than the gap plus the longest edge. The parts are
	// 3 mm off, so there are bridges on every seam: the head's and both elbows'.
	REQUIRE(!layout.bridges.empty());
	double longestEdge = 0.0;
	for (int f = 0; f < mesh.faceCount(); ++f)
		for (int e = 0; e < 3; ++e)
			longestEdge = std::max(longestEdge, (mesh.V.row(mesh.F(f, e)) - mesh.V.row(mesh.F(f, (e + 1) % 3))).norm());
	std::vector<char> bridged(layout.components.size(), 0);
	for (const auto& [p, q] : layout.bridges)
	{
		CHECK(layout.vertexComponent[size_t(p)] != layout.vertexComponent[size_t(q)]);
		CHECK(layout.onBody(p));
		CHECK(layout.onBody(q));
		CHECK((mesh.V.row(p) - mesh.V.row(q)).norm() <= layout.gap + longestEdge);
		bridged[size_t(layout.vertexComponent[size_t(p)])] = bridged[size_t(layout.vertexComponent[size_t(q)])] = 1;
	}
	for (size_t c = 0; c < layout.components.size(); ++c)
		CHECK(bool(bridged[c]) == (layout.components[c].role == ComponentRole::Attached ||
									  layout.components[c].role == ComponentRole::Body));
}

TEST_CASE("components: loading keeps the body whole, drops the prop and says so", "[fitting][components][mesh]")
{
	const GameAsset& a = gameAsset();
	int propVertices = 0;
	const LoadedMesh loaded = repairMesh(withProp(a, &propVertices));
	const MeshReport& r = loaded.report;
	CHECK(r.components == 7);
	CHECK(r.attachedComponents == 3);
	CHECK(r.insideComponents == 2);
	CHECK(r.insideComponentVertices == a.eyeVertices);
	CHECK(r.detachedComponents == 1);
	CHECK(r.droppedComponentVertices == propVertices);
	// The fitted mesh is everything but the prop (appended last, so the vertex order is unchanged).
	REQUIRE(loaded.mesh.vertexCount() == a.mesh.vertexCount());
	CHECK(loaded.mesh.V == a.mesh.V);
	CHECK(loaded.full.vertexCount() == a.mesh.vertexCount() + propVertices);
	REQUIRE(r.warnings.size() == 3);
	CHECK_THAT(r.warnings[0], Catch::Contains("3 separate parts"));
	CHECK_THAT(r.warnings[1], Catch::Contains("2 components (" + std::to_string(a.eyeVertices) + " vertices) inside"));
	CHECK_THAT(r.warnings[2], Catch::Contains("1 detached component (" + std::to_string(propVertices) + " vertices)"));
	// The layout of the fitted mesh: the same roles without the prop.
	CHECK(loaded.components.count(ComponentRole::Detached) == 0);
	CHECK(loaded.components.count(ComponentRole::Attached) == 3);
}

TEST_CASE("components: a game asset segments like the body it was cut from and the union encloses all of it",
	"[fitting][components][segmentation]")
{
	const GameAsset& a = gameAsset();
	const Segmentation seg = segmentBody(a.mesh);
	REQUIRE(seg.ok);
	// Labels of the parts agree with the bundled body's segmentation. The seams shift the cuts by a vertex ring at
	// most (the 3 mm bridges lengthen geodesics across them by < 1% of a limb): 97% agreement, measured 99.4%.
	int same = 0, compared = 0;
	for (int v = 0; v < a.bodyVertices; ++v)
	{
		++compared;
		same += seg.labels[size_t(v)] == a.labels[size_t(a.origin[size_t(v)])] ? 1 : 0;
	}
	CHECK(double(same) / compared > 0.97);
	// The eyes are head (labelled by the nearest body vertex).
	for (int v = a.bodyVertices; v < a.mesh.vertexCount(); ++v)
		CHECK(seg.labels[size_t(v)] == Region::Head);
	for (int r = 0; r < kBodyRegionCount; ++r)
		CHECK(regionVertexCounts(seg.labels)[size_t(r)] > 0);

	// Fitted as one body: every vertex of every part, eyes included, is inside the union (the MVEE guarantee,
	// mvee.h: zeta <= 1 + 1e-9).
	const BodyFit fit = fitBody(a.mesh, seg.labels);
	CHECK(worstZeta(a.mesh, fit) <= 1.0 + 1e-9);
	// Every region has its own ellipsoids, the head included (a head left out would have none).
	std::vector<int> perRegion(size_t(kBodyRegionCount) + 1, 0);
	for (const FittedEllipsoid& e : fit.ellipsoids)
		++perRegion[size_t(e.region)];
	for (int r = 0; r < kBodyRegionCount; ++r)
		CHECK(perRegion[size_t(r)] > 0);
}

TEST_CASE("components: a coarse body whose parts are far apart vertex to vertex but 3 mm apart surface to surface",
	"[fitting][components][robust]")
{
	// tests/data/robust_components.obj: torso box, head box 3 mm above it (its corners 10 cm from the torso's), an
	// eye box inside the head, a prop box 2 m away. The gap is measured to the surface, not between vertices.
	const LoadedMesh loaded = loadTriMesh(bodyfit_test::dataPath("robust_components.obj"));
	CHECK(loaded.report.components == 4);
	CHECK(loaded.report.attachedComponents == 1);
	CHECK(loaded.report.insideComponents == 1);
	CHECK(loaded.report.detachedComponents == 1);
	CHECK(loaded.mesh.vertexCount() == 24);
	CHECK(loaded.report.warnings.size() == 3);
	const BodyFit fit = fitBody(loaded.mesh);
	CHECK(worstZeta(loaded.mesh, fit) <= 1.0 + 1e-9); // the MVEE guarantee (mvee.h)
}

TEST_CASE("components: synthetic roles (touching, passing through, enclosed, far)", "[fitting][components]")
{
	const TriMesh big = uvSphere(1.0, 24, 12);
	SECTION("a single component is the body, with no bridges and no warnings")
	{
		const ComponentLayout layout = analyzeComponents(big);
		REQUIRE(layout.components.size() == 1);
		CHECK(layout.components[0].role == ComponentRole::Body);
		CHECK(layout.bridges.empty());
		CHECK(componentWarnings(layout).empty());
	}
	SECTION("a sphere 5 mm off a 2 m sphere is attached (gap 20 mm), at 50 mm it is detached")
	{
		for (const auto& [offset, role] : {std::make_pair(1.005, ComponentRole::Attached),
				 std::make_pair(1.05, ComponentRole::Detached)})
		{
			const TriMesh small = uvSphere(0.2, 12, 6, Eigen::Vector3d(offset + 0.2, 0, 0));
			const ComponentLayout layout = analyzeComponents(appended(big, small));
			REQUIRE(layout.components.size() == 2);
			CHECK(layout.gap == Approx(0.02).epsilon(1e-6));
			CHECK(layout.components[1].role == role);
			CHECK(layout.bridges.empty() == (role == ComponentRole::Detached));
		}
	}
	SECTION("a sphere passing through the surface is attached, with bridges from its inside vertices")
	{
		const TriMesh small = uvSphere(0.3, 12, 6, Eigen::Vector3d(1.0, 0, 0));
		const ComponentLayout layout = analyzeComponents(appended(big, small));
		CHECK(layout.components[1].role == ComponentRole::Attached);
		CHECK(!layout.bridges.empty());
	}
	SECTION("lone vertices (no faces, as an API caller may pass) are classified without throwing")
	{
		bodyfit::TriMesh withPoints = big;
		withPoints.V.conservativeResize(big.vertexCount() + 2, 3);
		withPoints.V.row(big.vertexCount()) << 0.1, 0.2, 0.0;     // inside the sphere
		withPoints.V.row(big.vertexCount() + 1) << 9.0, 0.0, 0.0; // far away
		const ComponentLayout layout = analyzeComponents(withPoints);
		REQUIRE(layout.components.size() == 3);
		CHECK(layout.components[1].role == ComponentRole::Inside);
		CHECK(layout.components[2].role == ComponentRole::Detached);
		const Segmentation seg = segmentBody(withPoints); // not a human, but no throw
		CHECK_FALSE(seg.ok);
	}
	SECTION("a sphere inside is enclosed; one inside a detached prop is detached")
	{
		const TriMesh eye = uvSphere(0.2, 12, 6, Eigen::Vector3d(0.3, 0.2, 0));
		const TriMesh prop = uvSphere(0.5, 16, 8, Eigen::Vector3d(5, 0, 0));
		const TriMesh propCore = uvSphere(0.1, 8, 4, Eigen::Vector3d(5, 0, 0));
		const ComponentLayout layout = analyzeComponents(appended(appended(appended(big, eye), prop), propCore));
		REQUIRE(layout.components.size() == 4); // by size: body, prop (16x8), eye (12x6), core (8x4)
		CHECK(layout.components[1].role == ComponentRole::Detached);
		CHECK(layout.components[2].role == ComponentRole::Inside);
		CHECK(layout.components[2].host == 0);
		CHECK(layout.components[3].role == ComponentRole::Detached);
		CHECK(layout.bridges.empty()); // enclosed parts are not bridged: geodesics stay on the skin
		const std::vector<int> nearest = nearestBodyVertex(appended(appended(appended(big, eye), prop), propCore),
			layout);
		for (int v = 0; v < int(nearest.size()); ++v)
			CHECK(layout.onBody(nearest[size_t(v)]));
	}
}
