#pragma once
// Settling measures of a cloth (issue 12 item 1), shared by the collider and scene tests: per scene step, every
// movable node's actual speed from its positions (|x_now - x_before| / step), the mean of those speeds, and how far
// Bullet's m_v exceeds the actual speed (the collider must not leave velocities the node does not have).

#include "BulletSoftBody/btSoftBody.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace bodyfit_test
{

struct SettleSample
{
	double meanSpeed = 0.0;     ///< mean over movable nodes of |dx| / step (m/s)
	double maxSpeed = 0.0;      ///< largest such speed
	double maxVelocity = 0.0;   ///< largest |m_v|
	double maxExcess = 0.0;     ///< largest |m_v| - actual speed over nodes (m/s)
	int nodesOverHalf = 0;      ///< nodes whose |m_v| exceeds their actual speed by more than 0.5 m/s
};

class SettleMeter
{
public:
	explicit SettleMeter(const btSoftBody& cloth) : m_cloth(cloth) { remember(); }

	/// Call after each scene step of `seconds`; returns the sample of that step.
	SettleSample sample(double seconds)
	{
		SettleSample s;
		int movable = 0;
		for (int i = 0; i < m_cloth.m_nodes.size(); ++i)
		{
			const btSoftBody::Node& n = m_cloth.m_nodes[i];
			if (!(n.m_im > 0))
				continue;
			const double dx = double(n.m_x.x()) - m_previous[3 * i], dy = double(n.m_x.y()) - m_previous[3 * i + 1],
						 dz = double(n.m_x.z()) - m_previous[3 * i + 2];
			const double speed = std::sqrt(dx * dx + dy * dy + dz * dz) / seconds;
			const double v = double(n.m_v.length());
			s.meanSpeed += speed;
			s.maxSpeed = std::max(s.maxSpeed, speed);
			s.maxVelocity = std::max(s.maxVelocity, v);
			s.maxExcess = std::max(s.maxExcess, v - speed);
			s.nodesOverHalf += v - speed > 0.5 ? 1 : 0;
			++movable;
		}
		s.meanSpeed /= double(std::max(1, movable));
		remember();
		return s;
	}

private:
	const btSoftBody& m_cloth;
	std::vector<double> m_previous;

	void remember()
	{
		m_previous.resize(3 * size_t(m_cloth.m_nodes.size()));
		for (int i = 0; i < m_cloth.m_nodes.size(); ++i)
			for (int k = 0; k < 3; ++k)
				m_previous[3 * i + k] = double(m_cloth.m_nodes[i].m_x[k]);
	}
};

} // namespace bodyfit_test
