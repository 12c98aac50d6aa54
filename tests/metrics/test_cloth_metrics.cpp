// bodyfit::metrics on a hand-built btSoftBody in a plain btSoftRigidDynamicsWorld, measured against a closed-form
// body: a sphere of radius R, as a UV-sphere mesh and as one ellipsoid, moved by a pose. Nodes sit at known signed
// distances d from the sphere, so inside counts, depths, zeta and gaps are known up to the mesh's chordal error.
#include "bodyfit/metrics/cloth_metrics.h"

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/statistics.h"

#include "support/mesh_shapes.h"

#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h>
#include <BulletSoftBody/btDefaultSoftBodySolver.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

using namespace bodyfit::metrics;

namespace
{

constexpr double kRadius = 0.3;
constexpr int kSlices = 96;
constexpr int kStacks = 48;
const double kPi = std::acos(-1.0);

/// Chordal error of the UV sphere: every edge spans at most delta = dTheta + dPhi of arc, and a planar triangle whose
/// edges span at most delta stays within R (1 - cos delta) inside the sphere (its closest point to the centre is its
/// circumcentre, at circumradius <= R sin delta, or a point of an edge). So the mesh lies in the shell
/// [R - kChordal, R]: 2.6 mm here.
const double kChordal = kRadius * (1.0 - std::cos(kPi / kStacks + 2.0 * kPi / kSlices));

/// Node coordinates are float, about 1.5 m from the origin: rounding moves a node by <= 1.2e-7 m per coordinate;
/// 1e-6 m covers the three coordinates and the pose applied in float and undone in double.
constexpr double kFloatTolerance = 1e-6;

/// Signed distances of the nodes from the sphere (cycled over the directions), all farther than the chordal error
/// from the surface, so inside/outside of the mesh is the same as of the sphere.
const std::vector<double> kOffsets = {-0.04, -0.015, 0.004, 0.012, 0.03, 0.08, -0.007, 0.045};

/// A plain soft-rigid world holding one soft body made node by node (no links: nothing moves it).
struct World
{
	btSoftBodyRigidBodyCollisionConfiguration configuration;
	btCollisionDispatcher dispatcher{&configuration};
	btDbvtBroadphase broadphase;
	btSequentialImpulseConstraintSolver solver;
	btDefaultSoftBodySolver softSolver;
	btSoftRigidDynamicsWorld world{&dispatcher, &broadphase, &solver, &configuration, &softSolver};
	std::unique_ptr<btSoftBody> cloth;

	explicit World(const std::vector<btVector3>& nodes)
	{
		const std::vector<btScalar> masses(nodes.size(), btScalar(1));
		cloth = std::make_unique<btSoftBody>(&world.getWorldInfo(), int(nodes.size()), nodes.data(), masses.data());
		world.addSoftBody(cloth.get());
	}
	~World() { world.removeSoftBody(cloth.get()); }
};

/// Deterministic directions spread over the sphere (spherical Fibonacci lattice).
Eigen::Vector3d direction(int i, int n)
{
	const double y = 1.0 - (2.0 * i + 1.0) / n;
	const double r = std::sqrt(1.0 - y * y);
	const double phi = i * kPi * (3.0 - std::sqrt(5.0));
	return Eigen::Vector3d(r * std::cos(phi), y, r * std::sin(phi));
}

btTransform bodyPose()
{
	return btTransform(btQuaternion(btVector3(1, 2, 3).normalized(), btScalar(0.7)), btVector3(0.4, 1.1, -0.3));
}

struct Placed
{
	std::vector<btVector3> world; ///< node positions in the world
	std::vector<double> offsets;  ///< their signed distance from the sphere
};

Placed placeNodes(int n, const btTransform& pose)
{
	Placed p;
	for (int i = 0; i < n; ++i)
	{
		const double d = kOffsets[std::size_t(i) % kOffsets.size()];
		const Eigen::Vector3d local = (kRadius + d) * direction(i, n);
		p.world.push_back(pose * btVector3(btScalar(local.x()), btScalar(local.y()), btScalar(local.z())));
		p.offsets.push_back(d);
	}
	return p;
}

BodyReference sphereBody(bool withEllipsoid)
{
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	if (withEllipsoid)
	{
		bodyfit::Ellipsoid e;
		e.radii = Eigen::Vector3d::Constant(kRadius);
		ellipsoids.push_back(e);
	}
	BodyReference body(bodyfit_test::uvSphere(kRadius, kSlices, kStacks), ellipsoids);
	body.setPose(bodyPose());
	return body;
}

int countIf(const std::vector<double>& v, bool (*pred)(double))
{
	return int(std::count_if(v.begin(), v.end(), pred));
}

} // namespace

TEST_CASE("metrics: inside counts, depth and zeta of nodes at known distances from a posed sphere", "[metrics]")
{
	const Placed nodes = placeNodes(400, bodyPose());
	World w(nodes.world);
	const BodyReference body = sphereBody(true);
	const PenetrationCounts p = measurePenetration(*w.cloth, body);
	const int inside = countIf(nodes.offsets, [](double d) { return d < 0.0; });
	CHECK(p.nodes == 400);
	CHECK(p.nanNodes == 0);
	// Every offset is >= 4 mm from the sphere, beyond the 2.6 mm chordal error: the mesh test agrees with the sphere.
	CHECK(p.insideBody == inside);
	CHECK(p.insideEllipsoids == inside);
	// Deepest: 40 mm; zeta of the deepest node ((R - 0.04) / R)^2; both up to float rounding of the positions.
	CHECK(p.maxEllipsoidDepth == Approx(0.04).margin(kFloatTolerance));
	// d zeta / d r = 2 r / R^2 < 2 / R at r = R - 0.04.
	CHECK(p.minZeta == Approx(std::pow((kRadius - 0.04) / kRadius, 2)).margin(2.0 * kFloatTolerance / kRadius));

	// The same nodes measured with the body left at the identity pose are elsewhere: the pose is used.
	BodyReference unposed(bodyfit_test::uvSphere(kRadius, kSlices, kStacks));
	CHECK(measurePenetration(*w.cloth, unposed).insideBody != inside);
}

TEST_CASE("metrics: contact nodes near the ellipsoids and their gaps to the skin mesh", "[metrics]")
{
	const Placed nodes = placeNodes(400, bodyPose());
	World w(nodes.world);
	const BodyReference body = sphereBody(true);
	ContactOptions options;
	options.distance = 0.005; // picks the offsets -0.04, -0.015, -0.007 and 0.004
	const std::vector<int> contacts = contactNodes(*w.cloth, body, options);
	std::vector<double> expected;
	for (int i : contacts)
		expected.push_back(nodes.offsets[std::size_t(i)]);
	CHECK(int(contacts.size()) == countIf(nodes.offsets, [](double d) { return d <= 0.005; }));
	CHECK(std::all_of(expected.begin(), expected.end(), [](double d) { return d <= 0.005; }));

	// The mesh lies in the shell [R - kChordal, R], so the signed distance s of a node at offset d from the sphere is
	// in [d, d + kChordal] (inside and outside alike); order statistics and means inherit the bounds.
	const std::vector<double> gaps = skinDistances(*w.cloth, body, contacts);
	REQUIRE(gaps.size() == contacts.size());
	for (std::size_t k = 0; k < gaps.size(); ++k)
	{
		CHECK(gaps[k] >= expected[k] - kFloatTolerance);
		CHECK(gaps[k] <= expected[k] + kChordal + kFloatTolerance);
	}
	const ContactMetrics m = measureContacts(*w.cloth, body, options);
	CHECK(m.contactNodes == int(contacts.size()));
	CHECK(m.gap.count == int(contacts.size()));
	const double lo = -kFloatTolerance, hi = kChordal + kFloatTolerance;
	CHECK(m.gap.mean >= bodyfit::mean(expected) + lo);
	CHECK(m.gap.mean <= bodyfit::mean(expected) + hi);
	CHECK(m.gap.p95 >= bodyfit::quantile(expected, 0.95) + lo);
	CHECK(m.gap.p95 <= bodyfit::quantile(expected, 0.95) + hi);
	CHECK(m.gap.max >= 0.004 + lo);
	CHECK(m.gap.max <= 0.004 + hi);
	CHECK(m.gap.median <= m.gap.p95);
}

TEST_CASE("metrics: NaN nodes are counted and left out of every other measure", "[metrics]")
{
	const Placed nodes = placeNodes(64, bodyPose());
	World w(nodes.world);
	// Broken after the soft body joined the world (Bullet's bounds stay finite); nothing steps it.
	w.cloth->m_nodes[5].m_x.setX(std::numeric_limits<btScalar>::quiet_NaN());
	w.cloth->m_nodes[9].m_v.setX(std::numeric_limits<btScalar>::infinity());
	const BodyReference body = sphereBody(true);
	const ClothMetrics m = measureCloth(*w.cloth, body);
	CHECK(m.penetration.nanNodes == 2);
	int inside = 0;
	for (int i = 0; i < 64; ++i)
		if (i != 5 && i != 9 && nodes.offsets[std::size_t(i)] < 0.0)
			++inside;
	CHECK(m.penetration.insideBody == inside);
	CHECK(std::isfinite(m.penetration.minZeta));
	// Contacts and gaps use positions: node 5 (NaN position, offset 0.08) is neither; node 9 (finite position at
	// offset -0.015, infinite velocity) is a contact with a gap.
	const std::vector<int> contacts = contactNodes(*w.cloth, body, ContactOptions{});
	CHECK(std::find(contacts.begin(), contacts.end(), 5) == contacts.end());
	CHECK(std::find(contacts.begin(), contacts.end(), 9) != contacts.end());
	CHECK(m.contacts.gap.count == m.contacts.contactNodes);
}

TEST_CASE("metrics: rigid-contact rule lists each node holding a Bullet contact once", "[metrics]")
{
	const Placed nodes = placeNodes(20, bodyPose());
	World w(nodes.world);
	for (int i : {7, 3, 7, 12})
	{
		btSoftBody::RContact c;
		c.m_node = &w.cloth->m_nodes[i];
		w.cloth->m_rcontacts.push_back(c);
	}
	const BodyReference body = sphereBody(false);
	ContactOptions options;
	options.rule = ContactRule::RigidContacts;
	CHECK(contactNodes(*w.cloth, body, options) == std::vector<int>{3, 7, 12});
	options.rule = ContactRule::None;
	CHECK(contactNodes(*w.cloth, body, options).empty());
}

TEST_CASE("metrics: collider-contact rule lists the nodes bodyfit's collider touched in its last substep", "[metrics]")
{
	// The sphere as the collider's one ellipsoid at the body pose; free nodes moving straight at it at 0.5 m/s, every
	// other one 1 mm off the surface (one substep of 1/60 s carries it 8 mm in: the collider places it, a contact), the
	// others 10 cm off (they move 8 mm and touch nothing).
	btEllipsoidClothWorld world;
	world.getWorld()->setGravity(btVector3(0, 0, 0));
	world.getWorldInfo().m_gravity.setValue(0, 0, 0);
	btEllipsoidCompoundShape shape;
	shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(kRadius, kRadius, kRadius));
	btRigidBody body(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, &shape));
	body.setWorldTransform(bodyPose());
	world.getWorld()->addRigidBody(&body);
	btEllipsoidClothCollider* collider = world.installCollider(&body);
	REQUIRE(collider != nullptr);
	std::vector<btVector3> positions;
	std::vector<int> expected;
	const int n = 40;
	std::vector<btVector3> directions;
	for (int i = 0; i < n; ++i)
	{
		const Eigen::Vector3d dir = direction(i, n);
		directions.push_back(btVector3(btScalar(dir.x()), btScalar(dir.y()), btScalar(dir.z())));
		const double d = i % 2 == 0 ? 0.001 : 0.1;
		positions.push_back(bodyPose().getOrigin() + directions.back() * btScalar(kRadius + d));
		if (i % 2 == 0)
			expected.push_back(i);
	}
	const std::vector<btScalar> masses(positions.size(), btScalar(0.01));
	btSoftBody cloth(&world.getWorldInfo(), n, positions.data(), masses.data());
	for (int i = 0; i < n; ++i)
		cloth.m_nodes[i].m_v = directions[std::size_t(i)] * btScalar(-0.5);
	world.getWorld()->addSoftBody(&cloth);
	const BodyReference reference = sphereBody(true);
	ContactOptions options;
	options.rule = ContactRule::ColliderContacts;
	options.collider = collider;
	CHECK(contactNodes(cloth, reference, options).empty()); // no substep has run: no record yet
	world.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	CHECK(contactNodes(cloth, reference, options) == expected);
	options.collider = nullptr;
	CHECK_THROWS_AS(contactNodes(cloth, reference, options), bodyfit::InvalidInputError);
	world.getWorld()->removeSoftBody(&cloth);
	world.getSoftBodySolver()->uninstallCollider(collider);
	world.getWorld()->removeRigidBody(&body);
}

TEST_CASE("metrics: JSON mirrors the typed result, null where a measure is undefined", "[metrics]")
{
	const Placed nodes = placeNodes(100, bodyPose());
	World w(nodes.world);
	const ClothMetrics with = measureCloth(*w.cloth, sphereBody(true));
	const nlohmann::json j = toJson(with);
	CHECK(j["nodes"] == 100);
	CHECK(j["nodes_inside_body"] == with.penetration.insideBody);
	CHECK(j["nodes_inside_ellipsoids"] == with.penetration.insideEllipsoids);
	CHECK(j["min_zeta"].get<double>() == with.penetration.minZeta);
	CHECK(j["ellipsoid_penetration_m"].get<double>() == with.penetration.maxEllipsoidDepth);
	CHECK(j["contact_nodes"] == with.contacts.contactNodes);
	CHECK(j["mean_contact_gap_m"].get<double>() == with.contacts.gap.mean);
	CHECK(j["p95_contact_gap_m"].get<double>() == with.contacts.gap.p95);
	CHECK(j["max_contact_gap_m"].get<double>() == with.contacts.gap.max);

	ContactOptions none;
	none.rule = ContactRule::None;
	const nlohmann::json k = toJson(measureCloth(*w.cloth, sphereBody(false), none));
	CHECK(k["nodes_inside_ellipsoids"].is_null());
	CHECK(k["min_zeta"].is_null());
	CHECK(k["ellipsoid_penetration_m"].is_null());
	CHECK(k["contact_nodes"] == 0);
	CHECK(k["mean_contact_gap_m"].is_null());
	CHECK(k["max_contact_gap_m"].is_null());
}

TEST_CASE("metrics: bad input is a one-line InvalidInputError", "[metrics]")
{
	const Placed nodes = placeNodes(10, bodyPose());
	World w(nodes.world);
	const BodyReference body = sphereBody(false);
	CHECK_THROWS_AS(contactNodes(*w.cloth, body, ContactOptions{}), bodyfit::InvalidInputError);
	CHECK_THROWS_AS(skinDistances(*w.cloth, body, {10}), bodyfit::InvalidInputError);
	bodyfit::Ellipsoid flat;
	flat.radii = Eigen::Vector3d(0.1, 0.0, 0.1);
	CHECK_THROWS_WITH(BodyReference(bodyfit_test::uvSphere(kRadius, 8, 4), {flat}),
					  Catch::Contains("ellipsoid 0 is not valid"));
	CHECK_THROWS_AS(BodyReference(bodyfit::TriMesh{}), bodyfit::InvalidInputError);
}

namespace
{

/// The cube [-0.1, 0.1]^3 written out by hand: 8 corners, 2 triangles per face.
bodyfit::TriMesh handMadeCube()
{
	bodyfit::TriMesh m;
	m.V.resize(8, 3);
	for (int i = 0; i < 8; ++i)
		m.V.row(i) << ((i & 1) ? 0.1 : -0.1), ((i & 2) ? 0.1 : -0.1), ((i & 4) ? 0.1 : -0.1);
	m.F.resize(12, 3);
	m.F << 0, 2, 1, 1, 2, 3, // z = -0.1
		4, 5, 6, 5, 7, 6,    // z = +0.1
		0, 1, 4, 1, 5, 4,    // y = -0.1
		2, 6, 3, 3, 6, 7,    // y = +0.1
		0, 4, 2, 2, 4, 6,    // x = -0.1
		1, 3, 5, 3, 7, 5;    // x = +0.1
	return m;
}

/// A hand-made cloth: node pairs joined by links, in the body frame, carried into the world by `pose`.
struct LinkedCloth
{
	btSoftBodyWorldInfo info;
	std::unique_ptr<btSoftBody> cloth;

	LinkedCloth(const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& links, const btTransform& pose)
	{
		std::vector<btVector3> nodes;
		for (const auto& l : links)
			for (const Eigen::Vector3d& p : {l.first, l.second})
				nodes.push_back(pose * btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z())));
		const std::vector<btScalar> masses(nodes.size(), btScalar(1));
		cloth = std::make_unique<btSoftBody>(&info, int(nodes.size()), nodes.data(), masses.data());
		for (int i = 0; i < int(links.size()); ++i)
			cloth->appendLink(2 * i, 2 * i + 1);
	}
};

} // namespace

TEST_CASE("metrics: a cloth face the cube's corner pokes through, though its edges clear it", "[metrics][crossings]")
{
	// The cube's corner (0.1, 0.1, 0.1) pokes 5.8 mm through the plane x + y + z = 0.29 (the corner is at 0.3 /
	// sqrt(3) along the diagonal, the plane 0.29 / sqrt(3)): the plane cuts the cube in a small triangle (1.4 cm sides)
	// around its centroid c = (0.29 / 3)(1, 1, 1). A face of that plane around c with corners 5 cm from c has its
	// corners outside (each has a coordinate above 0.1) and its edges 2.5 cm from c, clear of the cut; its centroid, c
	// itself, is inside, 0.1 - 0.29 / 3 = 3.33 mm from the nearest face of the cube.
	const Eigen::Vector3d c = Eigen::Vector3d::Constant(0.29 / 3.0);
	const Eigen::Vector3d u = Eigen::Vector3d(2, -1, -1).normalized(), v = Eigen::Vector3d(0, 1, -1).normalized();
	std::vector<Eigen::Vector3d> corners;
	for (int k = 0; k < 3; ++k)
	{
		const double angle = 2.0 * M_PI * k / 3.0;
		corners.push_back(c + 0.05 * (std::cos(angle) * u + std::sin(angle) * v));
	}
	// A second face far off (skipped by the distance test) and a third with a corner inside (a penetrating node).
	const std::vector<Eigen::Vector3d> far = {{0.5, 0.5, 0.5}, {0.52, 0.5, 0.5}, {0.5, 0.52, 0.5}};
	const std::vector<Eigen::Vector3d> oneInside = {{0.0, 0.0, 0.0}, {0.2, 0.0, 0.0}, {0.0, 0.2, 0.0}};
	for (const btTransform& pose : {btTransform::getIdentity(), bodyPose()})
	{
		BodyReference body(handMadeCube());
		body.setPose(pose);
		std::vector<btVector3> nodes;
		const std::vector<const std::vector<Eigen::Vector3d>*> faces = {&corners, &far, &oneInside};
		for (const std::vector<Eigen::Vector3d>* face : faces)
			for (const Eigen::Vector3d& p : *face)
				nodes.push_back(pose * btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z())));
		const std::vector<btScalar> masses(nodes.size(), btScalar(1));
		btSoftBodyWorldInfo info;
		btSoftBody cloth(&info, int(nodes.size()), nodes.data(), masses.data());
		for (int f = 0; f < 3; ++f)
			cloth.appendFace(3 * f, 3 * f + 1, 3 * f + 2);
		for (int n = 0; n < 3; ++n)
			cloth.appendLink(n, (n + 1) % 3); // the first face's edges
		for (int n = 0; n < 3; ++n)
			REQUIRE_FALSE(body.isInside(corners[size_t(n)]));
		const EdgeCrossings e = measureEdgeCrossings(cloth, body);
		CHECK(e.faces == 3);
		CHECK(e.facesCrossing == 1);
		// The centroid is one of the 10 samples and the deepest of them: 3.33 mm (float node coordinates).
		CHECK(e.maxFaceDepth == Approx(0.1 - 0.29 / 3.0).margin(kFloatTolerance));
		// None of the first face's edges crosses: the cut is in its middle.
		CHECK(e.links == 3);
		CHECK(e.crossing == 0);
		const nlohmann::json j = toJson(measureCloth(cloth, body, ContactOptions{ContactRule::None, 0.0}));
		CHECK(j["faces"].get<int>() == 3);
		CHECK(j["faces_crossing_body"].get<int>() == 1);
		CHECK(j["max_face_crossing_depth_m"].get<double>() == Approx(0.1 - 0.29 / 3.0).margin(kFloatTolerance));
	}
}

TEST_CASE("metrics: cloth edges crossing a hand-made cube, and the deepest crossing", "[metrics][crossings]")
{
	using Segment = std::pair<Eigen::Vector3d, Eigen::Vector3d>;
	const std::vector<Segment> links = {
		{{-0.2, 0, 0}, {0.2, 0, 0}},          // through the centre (and the faces' diagonals): 0.1 deep at its midpoint
		{{-0.2, 0.08, 0}, {0.2, 0.08, 0}},    // 2 cm under the top face: crosses, 0.02 deep
		{{0.12, 0.05, 0.01}, {0.05, 0.12, 0.01}}, // across the corner region of the +x +y edge: 0.015 deep
		{{-0.2, 0.15, 0}, {0.2, 0.15, 0}},    // above the cube: its ends are close enough to be tested, no hit
		{{0, 0, 0}, {0.2, 0, 0}},             // one end inside: a penetrating node, not a crossing edge
		{{0.3, 0.3, 0.3}, {0.31, 0.3, 0.3}},  // far and short: skipped by the distance test
	};
	for (const btTransform& pose : {btTransform::getIdentity(), bodyPose()})
	{
		BodyReference body(handMadeCube());
		body.setPose(pose);
		LinkedCloth cloth(links, pose);
		const EdgeCrossings c = measureEdgeCrossings(*cloth.cloth, body);
		CHECK(c.measured);
		CHECK(c.links == 6);
		CHECK(c.crossing == 3);
		// The depth is sampled at 9 points of the inside stretch; the deepest of these is the stretch's midpoint for
		// the first link (0.1 from every face it meets). Float node coordinates: kFloatTolerance.
		CHECK(c.maxDepth == Approx(0.1).margin(kFloatTolerance));
		// The JSON carries them.
		const nlohmann::json j = toJson(measureCloth(*cloth.cloth, body, ContactOptions{ContactRule::None, 0.0}));
		CHECK(j["links"].get<int>() == 6);
		CHECK(j["links_crossing_body"].get<int>() == 3);
		CHECK(j["max_link_crossing_depth_m"].get<double>() == Approx(0.1).margin(kFloatTolerance));
	}
	// Without the deep link the deepest crossing is the next one: 2 cm under the top face.
	BodyReference body(handMadeCube());
	LinkedCloth shallow({links[1], links[2]}, btTransform::getIdentity());
	const EdgeCrossings c = measureEdgeCrossings(*shallow.cloth, body);
	CHECK(c.crossing == 2);
	CHECK(c.maxDepth == Approx(0.02).margin(kFloatTolerance));
	// A bending link (a spring between the far corners of two faces, m_bbending) is not an edge of the cloth's surface:
	// the same deep segment marked bending is neither counted nor measured.
	LinkedCloth bending({links[0], links[1]}, btTransform::getIdentity());
	bending.cloth->m_links[0].m_bbending = 1;
	const EdgeCrossings b = measureEdgeCrossings(*bending.cloth, body);
	CHECK(b.links == 1);
	CHECK(b.crossing == 1);
	CHECK(b.maxDepth == Approx(0.02).margin(kFloatTolerance));
	// A ClothMetrics built without the crossings writes null for them.
	const nlohmann::json none = toJson(ClothMetrics{});
	CHECK(none["links_crossing_body"].is_null());
}
