#include "bodyfit/drape/stability.h"

#include "bodyfit/drape/simulation.h"

#include <BulletSoftBody/btSoftBody.h>

#include <cmath>
#include <sstream>

namespace bodyfit::drape
{
namespace
{

/// Fastest speed (m/s) of any point of `box` under the keyframed motion: translation plus rotation rate times the
/// box's largest distance from the pivot (default: the body box centre, as in the simulation).
double bodySpeed(const BodyMotionSpec& motion, const Eigen::Vector3d& defaultPivot, const Eigen::AlignedBox3d& box)
{
	const Eigen::Vector3d pivot = motion.pivot ? *motion.pivot : defaultPivot;
	double radius = 0.0;
	for (int corner = 0; corner < 8; ++corner)
		radius = std::max(radius, (box.corner(Eigen::AlignedBox3d::CornerType(corner)) - pivot).norm());
	double fastest = 0.0;
	const std::vector<Keyframe>& k = motion.keyframes;
	for (std::size_t i = 1; i < k.size(); ++i)
	{
		const double gap = k[i].time - k[i - 1].time;
		const Eigen::Quaterniond a(Eigen::AngleAxisd(k[i - 1].angleDeg * M_PI / 180.0, k[i - 1].axis));
		const Eigen::Quaterniond b(Eigen::AngleAxisd(k[i].angleDeg * M_PI / 180.0, k[i].axis));
		fastest = std::max(fastest, ((k[i].translation - k[i - 1].translation).norm() + a.angularDistance(b) * radius) / gap);
	}
	return fastest;
}

} // namespace

BlowUpWatch::BlowUpWatch(const DrapeSimulation& sim)
{
	const TriMesh cloth = sim.clothMesh();
	for (int i = 0; i < cloth.V.rows(); ++i)
		start_.extend(Eigen::Vector3d(cloth.V.row(i).transpose()));
	Eigen::AlignedBox3d bodyBox;
	const TriMesh& body = sim.body().mesh;
	for (int i = 0; i < body.V.rows(); ++i)
		bodyBox.extend(Eigen::Vector3d(body.V.row(i).transpose()));
	start_.extend(bodyBox);
	const EffectsSpec& e = sim.scene().effects;
	const double wind = e.wind ? e.wind->velocity.norm() + std::sqrt(3.0) * e.wind->turbulence : 0.0;
	const double moving = e.bodyMotion ? bodySpeed(*e.bodyMotion, bodyBox.center(), start_) : 0.0;
	speed_ = 10.0 + 3.0 * wind + 2.0 * moving;
	gravity_ = e.gravity ? e.gravity->acceleration.norm() : 0.0;
}

double BlowUpWatch::reach(double seconds) const { return 1.0 + speed_ * seconds + gravity_ * seconds * seconds; }

std::string BlowUpWatch::check(const DrapeSimulation& sim) const
{
	const btSoftBody* cloth = sim.cloth();
	const double limit = reach(sim.time());
	for (int i = 0; i < cloth->m_nodes.size(); ++i)
	{
		const btSoftBody::Node& n = cloth->m_nodes[i];
		const Eigen::Vector3d x(n.m_x.x(), n.m_x.y(), n.m_x.z());
		const Eigen::Vector3d v(n.m_v.x(), n.m_v.y(), n.m_v.z());
		const bool finite = x.allFinite() && v.allFinite();
		const double away = finite ? start_.exteriorDistance(x) : 0.0;
		if (finite && !(away > limit))
			continue; // (the common case: no message, no stream; one per node and step cost 3% of a tights run)
		std::ostringstream why;
		if (!finite)
			why << "cloth node " << i << " has a non-finite " << (x.allFinite() ? "velocity" : "position");
		else
			why << "cloth node " << i << " is " << away << " m from the scene's start box after " << sim.time()
				<< " s (a physical run stays within " << limit << " m)";
		return why.str();
	}
	return "";
}

} // namespace bodyfit::drape
