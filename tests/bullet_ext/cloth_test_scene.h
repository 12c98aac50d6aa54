#pragma once
// Shared helpers for the cloth-collider tests: a world with the collider's solver, a body with an ellipsoid
// compound, a cloth patch, and the guarantee check evaluated in double precision after every substep.

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include "BulletDynamics/Dynamics/btRigidBody.h"
#include "BulletSoftBody/btSoftBodyHelpers.h"
#include "LinearMath/btDefaultMotionState.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

namespace bodyfit_test
{

/// One ellipsoid in world space, double precision (the reference the guarantee is checked against).
struct RefEllipsoid
{
	Eigen::Vector3d center;
	Eigen::Matrix3d rotation; // columns = axes
	Eigen::Vector3d radii;

	double zeta(const Eigen::Vector3d& p) const
	{
		const Eigen::Vector3d u = (rotation.transpose() * (p - center)).cwiseQuotient(radii);
		return u.squaredNorm();
	}
};

/// zeta(p) of one compound ellipsoid (its local data) in long double: sum_i ((R^T (p - c))_i / a_i)^2, the reference
/// the robustness tests compare btScalar results with.
inline long double refZeta(const btEllipsoidLocalData& e, const btVector3& p)
{
	typedef long double Real;
	const Real d[3] = {Real(p.x()) - Real(e.m_center.x()), Real(p.y()) - Real(e.m_center.y()),
					   Real(p.z()) - Real(e.m_center.z())};
	Real z = 0;
	for (int i = 0; i < 3; ++i)
	{
		const Real l = Real(e.m_basis[0][i]) * d[0] + Real(e.m_basis[1][i]) * d[1] + Real(e.m_basis[2][i]) * d[2];
		const Real r = l / Real(e.m_semiAxes[i]);
		z += r * r;
	}
	return z;
}

inline Eigen::Vector3d toE(const btVector3& v) { return Eigen::Vector3d(double(v.x()), double(v.y()), double(v.z())); }

inline Eigen::Matrix3d toE(const btMatrix3x3& m)
{
	Eigen::Matrix3d out;
	for (int r = 0; r < 3; ++r)
		for (int c = 0; c < 3; ++c)
			out(r, c) = double(m[r][c]);
	return out;
}

/// The compound's ellipsoids placed by a body transform, in double.
inline std::vector<RefEllipsoid> worldEllipsoids(const btEllipsoidCompoundShape& shape, const btTransform& t)
{
	std::vector<RefEllipsoid> out;
	const Eigen::Matrix3d r = toE(t.getBasis());
	const Eigen::Vector3d o = toE(t.getOrigin());
	for (int i = 0; i < shape.getNumEllipsoids(); ++i)
	{
		const btEllipsoidLocalData& d = shape.getEllipsoid(i);
		RefEllipsoid e;
		e.center = o + r * toE(d.m_center);
		e.rotation = r * toE(d.m_basis);
		e.radii = toE(d.m_semiAxes);
		out.push_back(e);
	}
	return out;
}

struct GuaranteeReport
{
	double minZeta = std::numeric_limits<double>::infinity();
	int nonFinite = 0;
	int checks = 0; // substeps checked
};

/// Smallest zeta over all movable nodes and all ellipsoids; counts non-finite coordinates.
inline void checkNodes(const btSoftBody* psb, const std::vector<RefEllipsoid>& ells, GuaranteeReport& report)
{
	for (int i = 0; i < psb->m_nodes.size(); ++i)
	{
		const btSoftBody::Node& n = psb->m_nodes[i];
		if (!(n.m_im > 0))
			continue;
		const Eigen::Vector3d p = toE(n.m_x);
		if (!p.allFinite())
		{
			++report.nonFinite;
			continue;
		}
		for (const RefEllipsoid& e : ells)
			report.minZeta = std::min(report.minZeta, e.zeta(p));
	}
}

/// A world with the collider solver, one body (static unless made kinematic), one or more cloth patches.
/// The guarantee is checked from a pre-tick callback (state after the previous substep) and after each step.
class ClothScene
{
public:
	explicit ClothScene(std::unique_ptr<btEllipsoidCompoundShape> shape, const btTransform& bodyPose = btTransform::getIdentity(),
						bool kinematic = false)
		: shape_(std::move(shape))
	{
		world_.getWorldInfo().m_gravity.setValue(0, -9.81, 0);
		world_.getWorld()->setGravity(btVector3(0, -9.81, 0));
		motion_.reset(new btDefaultMotionState(bodyPose));
		btRigidBody::btRigidBodyConstructionInfo info(0, motion_.get(), shape_.get());
		body_.reset(new btRigidBody(info));
		if (kinematic)
		{
			body_->setCollisionFlags(body_->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
			body_->setActivationState(DISABLE_DEACTIVATION);
		}
		world_.getWorld()->addRigidBody(body_.get());
		world_.getWorld()->setInternalTickCallback(&ClothScene::preTick, this, true);
	}

	~ClothScene()
	{
		for (btSoftBody* psb : cloths_)
		{
			world_.getWorld()->removeSoftBody(psb);
			delete psb;
		}
		world_.getWorld()->removeRigidBody(body_.get());
	}

	/// resolution x resolution patch of side `size`, centred at `center`, horizontal (normal +y), no pinned nodes.
	btSoftBody* addPatch(const btVector3& center, btScalar size, int resolution, btScalar mass = 0.2)
	{
		const btScalar h = size / 2;
		btSoftBody* psb = btSoftBodyHelpers::CreatePatch(world_.getWorldInfo(), center + btVector3(-h, 0, -h),
														 center + btVector3(h, 0, -h), center + btVector3(-h, 0, h),
														 center + btVector3(h, 0, h), resolution, resolution, 0, true);
		psb->getCollisionShape()->setMargin(btScalar(0.005));
		psb->m_cfg.piterations = 4;
		psb->m_cfg.kDP = btScalar(0.005);
		psb->m_materials[0]->m_kLST = btScalar(0.9);
		// Friction kDF 0.6 x the body's 0.5 (Bullet's default) = 0.3, the collider's default before it honoured
		// Bullet's combination (issue 12 item 10).
		psb->m_cfg.kDF = btScalar(0.6);
		psb->setTotalMass(mass);
		world_.getWorld()->addSoftBody(psb);
		cloths_.push_back(psb);
		return psb;
	}

	/// Free nodes (mass 0.01 each, no links) at `positions`, at rest: probes for the collider inside a world.
	btSoftBody* addNodes(const std::vector<btVector3>& positions)
	{
		std::vector<btScalar> masses(positions.size(), btScalar(0.01));
		btSoftBody* psb = new btSoftBody(&world_.getWorldInfo(), int(positions.size()), positions.data(), masses.data());
		psb->getCollisionShape()->setMargin(btScalar(0.005));
		world_.getWorld()->addSoftBody(psb);
		cloths_.push_back(psb);
		return psb;
	}

	btEllipsoidClothCollider* install(const btEllipsoidClothCollider::Config& config = btEllipsoidClothCollider::Config())
	{
		collider_ = world_.installCollider(body_.get(), config);
		return collider_;
	}

	/// One stepSimulation call; the guarantee is checked after every substep.
	void step(btScalar dt, int maxSubSteps = 1, btScalar fixedStep = 0)
	{
		world_.getWorld()->stepSimulation(dt, maxSubSteps, fixedStep > 0 ? fixedStep : dt);
		checkNow();
	}

	void checkNow()
	{
		const std::vector<RefEllipsoid> ells = worldEllipsoids(*shape_, collider_ ? collider_->getWorldCache().getTransform()
																				 : body_->getWorldTransform());
		for (btSoftBody* psb : cloths_)
			checkNodes(psb, ells, report);
		++report.checks;
	}

	btSoftRigidDynamicsWorld* world() { return world_.getWorld(); }
	btEllipsoidClothSoftBodySolver* solver() { return world_.getSoftBodySolver(); }
	btRigidBody* body() { return body_.get(); }
	btDefaultMotionState* motion() { return motion_.get(); }
	btEllipsoidCompoundShape* shape() { return shape_.get(); }
	btEllipsoidClothCollider* collider() { return collider_; }
	const std::vector<btSoftBody*>& cloths() const { return cloths_; }

	GuaranteeReport report;

private:
	static void preTick(btDynamicsWorld* world, btScalar)
	{
		ClothScene* self = static_cast<ClothScene*>(world->getWorldUserInfo());
		if (self->collider_ && self->collider_->getAccumulatedStats().m_substeps > 0)
			self->checkNow();
	}

	btEllipsoidClothWorld world_;
	std::unique_ptr<btEllipsoidCompoundShape> shape_;
	std::unique_ptr<btDefaultMotionState> motion_;
	std::unique_ptr<btRigidBody> body_;
	std::vector<btSoftBody*> cloths_;
	btEllipsoidClothCollider* collider_ = nullptr;
};

inline std::unique_ptr<btEllipsoidCompoundShape> singleEllipsoid(const btVector3& center, const btMatrix3x3& basis,
																const btVector3& axes)
{
	std::unique_ptr<btEllipsoidCompoundShape> s(new btEllipsoidCompoundShape());
	s->addEllipsoid(center, basis, axes);
	return s;
}

} // namespace bodyfit_test
