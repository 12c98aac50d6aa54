#pragma once
// Shared helpers for the moving-ellipsoid tests (test_collider_moving.cpp): a compound whose ellipsoids a driver poses
// from an internal pre-tick callback at every substep (setEllipsoid or setEllipsoids, as a skinning driver does),
// the guarantee checked in double after every substep, and the surface velocity of the analytic motion.

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include "BulletSoftBody/btSoftBodyHelpers.h"

#include <Eigen/Core>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

namespace bodyfit_test
{

/// One ellipsoid's pose in world space (the body stays at the identity), double precision.
struct MovingPose
{
	Eigen::Vector3d center = Eigen::Vector3d::Zero();
	Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity(); // columns = axes
	Eigen::Vector3d radii = Eigen::Vector3d::Ones();

	double zeta(const Eigen::Vector3d& p) const
	{
		return (rotation.transpose() * (p - center)).cwiseQuotient(radii).squaredNorm();
	}
	Eigen::Matrix3d unwhiten() const { return rotation * radii.asDiagonal(); }
};

/// Poses of every ellipsoid at a time (seconds).
using MovingMotion = std::function<std::vector<MovingPose>(double)>;

inline btVector3 toBt(const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }

inline btMatrix3x3 toBt(const Eigen::Matrix3d& m)
{
	return btMatrix3x3(btScalar(m(0, 0)), btScalar(m(0, 1)), btScalar(m(0, 2)), btScalar(m(1, 0)), btScalar(m(1, 1)),
					   btScalar(m(1, 2)), btScalar(m(2, 0)), btScalar(m(2, 1)), btScalar(m(2, 2)));
}

inline Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(double(v.x()), double(v.y()), double(v.z())); }

/// The nearest point of the ellipsoid's surface to an outside point p (bisection on the Lagrange parameter t of
/// y_k = a_k^2 x_k / (a_k^2 + t), to double precision); p itself for a point inside.
inline Eigen::Vector3d nearestSurfacePoint(const MovingPose& e, const Eigen::Vector3d& p)
{
	const Eigen::Vector3d y = e.rotation.transpose() * (p - e.center);
	const Eigen::Vector3d a2 = e.radii.cwiseProduct(e.radii);
	if (y.cwiseQuotient(e.radii).squaredNorm() <= 1.0)
		return p;
	double lo = 0.0, hi = e.radii.maxCoeff() * y.norm();
	for (int it = 0; it < 200; ++it)
	{
		const double t = 0.5 * (lo + hi);
		double f = 0.0;
		for (int k = 0; k < 3; ++k)
			f += std::pow(e.radii[k] * y[k] / (a2[k] + t), 2);
		(f > 1.0 ? lo : hi) = t;
	}
	Eigen::Vector3d local;
	for (int k = 0; k < 3; ++k)
		local[k] = a2[k] * y[k] / (a2[k] + hi);
	return e.center + e.rotation * local;
}

/// A static body (identity pose) whose compound ellipsoids follow `motion`, posed at every substep from the internal
/// pre-tick callback; the callback first checks the state the previous substep left (zeta over every movable node of
/// every soft body and every ellipsoid, in double) and hands it to `inspect`.
class MovingScene
{
public:
	/// \param bulk pose with setEllipsoids (else one setEllipsoid call per ellipsoid)
	MovingScene(const MovingMotion& motion, bool bulk, double gravity) : motion_(motion), bulk_(bulk)
	{
		world_.getWorld()->setGravity(btVector3(0, btScalar(gravity), 0));
		world_.getWorldInfo().m_gravity.setValue(0, btScalar(gravity), 0);
		shape_.reset(new btEllipsoidCompoundShape());
		for (const MovingPose& e : motion(0.0))
			shape_->addEllipsoid(toBt(e.center), toBt(e.rotation), toBt(e.radii));
		body_.setCollisionShape(shape_.get());
		world_.getWorld()->addCollisionObject(&body_);
		world_.getWorld()->setInternalTickCallback(&MovingScene::preTick, this, true);
	}

	~MovingScene()
	{
		for (btSoftBody* psb : softBodies_)
		{
			world_.getWorld()->removeSoftBody(psb);
			delete psb;
		}
		world_.getWorld()->removeCollisionObject(&body_);
	}

	btSoftBody* addSoftBody(btSoftBody* psb)
	{
		world_.getWorld()->addSoftBody(psb);
		softBodies_.push_back(psb);
		return psb;
	}

	btEllipsoidClothCollider* install(const btEllipsoidClothCollider::Config& config)
	{
		collider_ = world_.installCollider(&body_, config);
		return collider_;
	}

	/// Substeps of length dt, one per stepSimulation call; then the final state is checked too.
	void run(int substeps, double dt)
	{
		dt_ = dt;
		for (int i = 0; i < substeps; ++i)
			world_.getWorld()->stepSimulation(btScalar(dt), 1, btScalar(dt));
		check();
	}

	/// The poses used in substep k (k = 1 is the first): the motion at time k dt.
	std::vector<MovingPose> posesAt(int k) const { return motion_(k * dt_); }

	btEllipsoidClothWorld& world() { return world_; }
	/// The compound's current ellipsoids in double (see compoundPoses).
	std::vector<MovingPose> current() const { return compoundPoses(); }
	btEllipsoidCompoundShape& shape() { return *shape_; }
	btEllipsoidClothCollider* collider() { return collider_; }
	int substepsDone() const { return substep_; }
	double dt() const { return dt_; }

	double minZeta = std::numeric_limits<double>::infinity(); ///< over all checks
	int nonFinite = 0;
	int crossings = 0; ///< node paths through an ellipsoid's core (countCrossings), over all substeps
	/// Called after each check with the index of the substep whose result it sees (1 = the first).
	std::function<void(int)> inspect;

private:
	static void preTick(btDynamicsWorld* world, btScalar)
	{
		MovingScene* self = static_cast<MovingScene*>(world->getWorldUserInfo());
		if (self->substep_ > 0)
			self->check();
		++self->substep_;
		self->pose(self->motion_(self->substep_ * self->dt_));
	}

	void pose(const std::vector<MovingPose>& poses)
	{
		std::vector<btVector3> c, a;
		std::vector<btMatrix3x3> r;
		for (const MovingPose& e : poses)
			c.push_back(toBt(e.center)), r.push_back(toBt(e.rotation)), a.push_back(toBt(e.radii));
		if (bulk_)
			shape_->setEllipsoids(int(c.size()), c.data(), r.data(), a.data());
		else
			for (int i = 0; i < int(c.size()); ++i)
				shape_->setEllipsoid(i, c[i], r[i], a[i]);
	}

	/// The compound's ellipsoids as the collider reads them (the float pose of a float build), in double.
	std::vector<MovingPose> compoundPoses() const
	{
		std::vector<MovingPose> out;
		for (int i = 0; i < shape_->getNumEllipsoids(); ++i)
		{
			const btEllipsoidLocalData& d = shape_->getEllipsoid(i);
			MovingPose e;
			e.center = toEigen(d.m_center);
			for (int r = 0; r < 3; ++r)
				for (int c = 0; c < 3; ++c)
					e.rotation(r, c) = double(d.m_basis[r][c]);
			e.radii = toEigen(d.m_semiAxes);
			out.push_back(e);
		}
		return out;
	}

	void check()
	{
		const std::vector<MovingPose> poses = compoundPoses();
		std::vector<Eigen::Vector3d> positions;
		for (const btSoftBody* psb : softBodies_)
			for (int i = 0; i < psb->m_nodes.size(); ++i)
			{
				const Eigen::Vector3d p = toEigen(psb->m_nodes[i].m_x);
				positions.push_back(p);
				if (!(psb->m_nodes[i].m_im > 0))
					continue;
				if (!p.allFinite())
				{
					++nonFinite;
					continue;
				}
				for (const MovingPose& e : poses)
					minZeta = std::min(minZeta, e.zeta(p));
			}
		if (previousPositions_.size() == positions.size() && previousPoses_.size() == poses.size())
			for (std::size_t e = 0; e < poses.size(); ++e)
				countCrossings(previousPoses_[e], poses[e], positions);
		previousPoses_ = poses;
		previousPositions_ = positions;
		if (inspect)
			inspect(substep_);
	}

	/// A node whose straight path in the ellipsoid's moving frame, from W0 (x_prev - c0) to W1 (x - c1), comes within
	/// half the unit ball's radius of its centre went through the ellipsoid's core: tunnelled. (Nodes that slide
	/// around the surface, or wrap around an arm, stay near |u| = 1; a path through the middle half needs a slide
	/// over 120 degrees of arc in one substep.)
	void countCrossings(const MovingPose& before, const MovingPose& now, const std::vector<Eigen::Vector3d>& x)
	{
		const Eigen::Matrix3d w0 = before.unwhiten().inverse(), w1 = now.unwhiten().inverse();
		for (std::size_t i = 0; i < x.size(); ++i)
		{
			const Eigen::Vector3d a = w0 * (previousPositions_[i] - before.center);
			const Eigen::Vector3d d = w1 * (x[i] - now.center) - a;
			const double s = d.squaredNorm() > 0 ? std::min(1.0, std::max(0.0, -a.dot(d) / d.squaredNorm())) : 0.0;
			crossings += (a + s * d).norm() < 0.5 ? 1 : 0;
		}
	}

	MovingMotion motion_;
	bool bulk_;
	double dt_ = 1.0 / 120.0;
	int substep_ = 0;
	btEllipsoidClothWorld world_;
	std::unique_ptr<btEllipsoidCompoundShape> shape_;
	btCollisionObject body_;
	std::vector<btSoftBody*> softBodies_;
	btEllipsoidClothCollider* collider_ = nullptr;
	std::vector<MovingPose> previousPoses_;
	std::vector<Eigen::Vector3d> previousPositions_;
};

} // namespace bodyfit_test
