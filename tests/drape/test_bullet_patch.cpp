// The scene runner's pieces for comparisons with stock Bullet: garment bullet_patch is Bullet's own
// btSoftBodyHelpers::CreatePatch cloth, collider ellipsoids-sdf runs the ellipsoid compound through Bullet's default
// soft-body path, and the patch placement over a body's head.
#include "bodyfit/drape/garment.h"
#include "bodyfit/drape/simulation.h"
#include "drape/sphere_scene.h"

#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>

#include <catch2/catch.hpp>

#include <memory>

using namespace bodyfit::drape;
using nlohmann::json;

namespace
{

GarmentSpec bulletPatchSpec()
{
	GarmentSpec g;
	g.type = GarmentType::BulletPatch;
	g.size = Eigen::Vector2d(0.8, 0.6);
	g.resolution = Eigen::Vector2i(9, 7);
	g.center = Eigen::Vector3d(0.1, 1.3, -0.2);
	return g;
}

} // namespace

TEST_CASE("bullet_patch: Bullet's CreatePatch cloth node for node, link for link", "[scene][bullet_patch]")
{
	const GarmentSpec spec = bulletPatchSpec();
	MaterialSpec material;
	material.stretch = 0.7;
	material.mass = 0.5;
	material.bending = 0.3; // not used by bullet_patch
	btSoftBodyWorldInfo info;
	const std::unique_ptr<btSoftBody> ours(buildBulletPatch(info, spec, material, SolverSpec{}));
	const btScalar cx = btScalar(0.1), y = btScalar(1.3), cz = btScalar(-0.2), hx = btScalar(0.4), hz = btScalar(0.3);
	const std::unique_ptr<btSoftBody> bullet(btSoftBodyHelpers::CreatePatch(
		info, btVector3(cx - hx, y, cz - hz), btVector3(cx + hx, y, cz - hz), btVector3(cx - hx, y, cz + hz),
		btVector3(cx + hx, y, cz + hz), 9, 7, 0, true));
	REQUIRE(ours->m_nodes.size() == bullet->m_nodes.size());
	for (int i = 0; i < ours->m_nodes.size(); ++i)
		CHECK(ours->m_nodes[i].m_x == bullet->m_nodes[i].m_x); // bit for bit: same float arithmetic
	// Structural links along x and z plus one diagonal per quad, no bending links.
	CHECK(ours->m_links.size() == 8 * 7 + 9 * 6 + 8 * 6);
	for (int l = 0; l < ours->m_links.size(); ++l)
		CHECK(ours->m_links[l].m_bbending == 0);
	CHECK(ours->m_faces.size() == 2 * 8 * 6);
	// Equal node masses summing to material.mass (relative 1e-6: float sums of 63 masses).
	for (int i = 0; i < ours->m_nodes.size(); ++i)
		CHECK(ours->getMass(i) == Approx(0.5 / 63).epsilon(1e-6));
	CHECK(ours->m_materials[0]->m_kLST == Approx(0.7));

	// buildGarmentMesh gives the same nodes and faces, with the patch layout used by pins.
	const GarmentMesh g = buildGarmentMesh(spec);
	CHECK(g.resX == 9);
	CHECK(g.resZ == 7);
	REQUIRE(g.mesh.V.rows() == 63);
	CHECK(g.mesh.V(8, 0) == Approx(0.1 + 0.4)); // node (ix = 8, iz = 0) is the +x, -z corner
	CHECK(g.mesh.V(8, 2) == Approx(-0.2 - 0.3));
	CHECK(g.mesh.F.rows() == ours->m_faces.size());
}

TEST_CASE("scene files accept garment bullet_patch and collider ellipsoids-sdf", "[scene][bullet_patch]")
{
	const json j = {{"body", {{"mesh", bodyfit_test::dataPath("tetra.obj")}, {"fit", json::object()}}},
					{"collider", "ellipsoids-sdf"},
					{"garment", {{"type", "bullet_patch"}, {"size_m", {0.8, 0.6}}, {"resolution", {9, 7}}}},
					{"effects", json::array({{{"type", "pin"}, {"select", "corners"}}})}};
	const Scene s = parseScene(j, "/virtual/bullet_patch.json");
	CHECK(s.collider.kind == ColliderKind::EllipsoidsSdf);
	CHECK(s.garment.type == GarmentType::BulletPatch);
	CHECK(s.garment.resolution == Eigen::Vector2i(9, 7));
	CHECK(std::string(toString(s.garment.type)) == "bullet_patch");
	CHECK(colliderKindFromString("ellipsoids-sdf") == ColliderKind::EllipsoidsSdf);
}

TEST_CASE("ellipsoids-sdf: Bullet's default path holds a bullet_patch on the compound with rigid contacts",
		  "[scene][bullet_patch]")
{
	Scene scene = bodyfit_test::patchScene(json::array({{{"type", "gravity"}}}), 1.27);
	scene.collider.kind = ColliderKind::EllipsoidsSdf;
	scene.collider.sdfVoxel = 0.02;
	scene.garment.type = GarmentType::BulletPatch;
	const BodyData body = bodyfit_test::sphereBody();
	DrapeSimulation sim(scene, body);
	CHECK(sim.ellipsoidCollider() == nullptr);
	CHECK(sim.colliderDescription().find("btEllipsoidCompoundShape of 1 ellipsoids") != std::string::npos);
	CHECK(sim.contactOptions().rule == bodyfit::metrics::ContactRule::RigidContacts);
	for (int k = 0; k < 60; ++k)
		sim.step();
	// Half a second after a 2 cm drop the cloth lies on the sphere (top at 1.25 m): Bullet holds the centre node
	// (index 8 * 17 + 8) within 1 cm of the top (falling through, it would be 1.2 m lower by now).
	const ClothSample s = sim.sample();
	CHECK(s.nanNodes == 0);
	CHECK(sim.clothMesh().V(8 * 17 + 8, 1) > 1.24);
	const bodyfit::metrics::ContactMetrics c = sim.contacts();
	CHECK(c.contactNodes > 0);
	// Contact nodes hold Bullet contacts against the sphere, kept about the margins outside it: their gap to the
	// skin mesh is at most the cloth margin (5 mm) plus the child margin (4 mm) plus the mesh's chordal error
	// (32 x 16 UV sphere of 0.25 m: R (1 - cos(pi / 16 + 2 pi / 32)) = 1.9 cm), and positive on average.
	CHECK(c.gap.max < 0.005 + 0.004 + 0.019);
	CHECK(c.gap.mean > 0.0);
}

TEST_CASE("patchCenterAboveHead: over the mean of the top 10% of the vertices, drop above the top",
		  "[scene][bullet_patch]")
{
	const BodyData body = bodyfit_test::sphereBody();
	const Eigen::Vector3d c = patchCenterAboveHead(body.mesh, 0.03);
	// The sphere's top cap is symmetric about the y axis through its centre (0, 1, 0); its top is at 1.25 m.
	CHECK(c.x() == Approx(0.0).margin(1e-12));
	CHECK(c.z() == Approx(0.0).margin(1e-12));
	CHECK(c.y() == Approx(1.25 + 0.03));
}
