// Outside consumer of the whole installed bodyfit package (every public header is included): builds a compound from ellipsoids through the bridge, drops a
// small cloth on it with the collider installed, and checks the precision define matches the installed package.
#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/bridge/btEigenConversion.h"
#include "bodyfit/bridge/btSkinnedBodyDriver.h"
#include "bodyfit/drape/effects.h"
#include "bodyfit/drape/garment.h"
#include "bodyfit/drape/gltf_animation.h"
#include "bodyfit/drape/scene.h"
#include "bodyfit/drape/simulation.h"
#include "bodyfit/drape/stability.h"
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btEllipsoidShape.h"
#include "bodyfit/bullet_ext/btFloatRange.h"
#include "bodyfit/bullet_ext/btSkinDistanceField.h"
#include "bodyfit/bullet_ext/btTiming.h"
#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/components.h"
#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/fit_error.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/fit_quality.h"
#include "bodyfit/fitting/geodesics.h"
#include "bodyfit/fitting/input_files.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/kmeans.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/mvee.h"
#include "bodyfit/fitting/parallel.h"
#include "bodyfit/fitting/rig.h"
#include "bodyfit/fitting/segmentation.h"
#include "bodyfit/fitting/skinned_fit.h"
#include "bodyfit/fitting/skin_field.h"
#include "bodyfit/fitting/triangle_cover.h"
#include "bodyfit/fitting/statistics.h"
#include "bodyfit/metrics/cloth_metrics.h"
#include "bodyfit/fitting/types.h"

#include "BulletSoftBody/btSoftBodyHelpers.h"

#include <cstdio>
#include <vector>

int main()
{
	const bool compilerDouble = sizeof(btScalar) == 8;
	if (compilerDouble != bool(BODYFIT_PACKAGE_DOUBLE))
	{
		std::printf("precision mismatch: btScalar has %d bytes, package double = %d\n", int(sizeof(btScalar)),
					int(BODYFIT_PACKAGE_DOUBLE));
		return 1;
	}
	std::vector<bodyfit::Ellipsoid> ellipsoids(2);
	ellipsoids[0].radii = Eigen::Vector3d(0.25, 0.1, 0.15);
	ellipsoids[1].center = Eigen::Vector3d(0.15, 0.05, 0);
	ellipsoids[1].radii = Eigen::Vector3d(0.12, 0.12, 0.12);
	std::unique_ptr<btEllipsoidCompoundShape> shape = bodyfit::createEllipsoidCompound(ellipsoids);

	btEllipsoidClothWorld world;
	btCollisionObject body;
	body.setCollisionShape(shape.get());
	world.getWorld()->addCollisionObject(&body);
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(world.getWorldInfo(), btVector3(-0.4, 0.3, -0.4),
													   btVector3(0.4, 0.3, -0.4), btVector3(-0.4, 0.3, 0.4),
													   btVector3(0.4, 0.3, 0.4), 15, 15, 0, true);
	cloth->getCollisionShape()->setMargin(0.005);
	cloth->setTotalMass(0.2);
	world.getWorld()->addSoftBody(cloth);
	// Friction 0.5 holds the cloth on the two ellipsoids for the contact metrics below (Bullet's own combination of
	// its default kDF 0.2 and body friction 0.5, 0.1, lets it slide off within the 60 steps).
	btEllipsoidClothCollider::Config config;
	config.m_friction = btScalar(0.5);
	btEllipsoidClothCollider* collider = world.installCollider(&body, config);
	if (!collider)
		return 2;
	for (int i = 0; i < 60; ++i)
		world.getWorld()->stepSimulation(btScalar(1.0 / 60), 1, btScalar(1.0 / 60));
	const btEllipsoidClothStats& stats = collider->getAccumulatedStats();
	// The cloth metrics of the installed bodyfit::metrics, against the ellipsoids' own surface mesh.
	std::vector<bodyfit::FittedEllipsoid> fitted(ellipsoids.size());
	for (std::size_t i = 0; i < ellipsoids.size(); ++i)
		fitted[i].ellipsoid = ellipsoids[i];
	const bodyfit::metrics::BodyReference reference(bodyfit::ellipsoidMesh(fitted), ellipsoids);
	const bodyfit::metrics::ClothMetrics metrics = bodyfit::metrics::measureCloth(*cloth, reference);
	// The cloth reached the body and no node ended inside (a layout mismatch would scramble the nodes instead).
	const bool ok = stats.m_nodesCorrected > 0 && stats.m_minZeta >= btScalar(1) && stats.m_nonFiniteNodes == 0 &&
					metrics.contacts.contactNodes > 0 && metrics.penetration.insideEllipsoids == 0 &&
					metrics.penetration.nanNodes == 0;
	std::printf("outside project: btScalar %d bytes, %d substeps, %d corrections, min zeta %.6f, %d contact nodes "
				"-> %s\n",
				int(sizeof(btScalar)), stats.m_substeps, stats.m_nodesCorrected, double(stats.m_minZeta),
				metrics.contacts.contactNodes, ok ? "ok" : "FAILED");
	world.getWorld()->removeSoftBody(cloth);
	delete cloth;
	world.getWorld()->removeCollisionObject(&body);
	return ok ? 0 : 3;
}
