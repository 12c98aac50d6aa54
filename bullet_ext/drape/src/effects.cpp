#include "bodyfit/drape/effects.h"

#include <BulletDynamics/Dynamics/btRigidBody.h>
#include <BulletSoftBody/btSoftBody.h>
#include <LinearMath/btDefaultMotionState.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace bodyfit::drape
{
namespace
{

btVector3 toBt(const Eigen::Vector3d& v) { return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z())); }
Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

/// 32-bit integer hash (Wang-style avalanche), used to give each lattice point a value.
inline unsigned hashInt(unsigned x)
{
	x = (x ^ 61u) ^ (x >> 16);
	x *= 9u;
	x ^= x >> 4;
	x *= 0x27d4eb2du;
	x ^= x >> 15;
	return x;
}

inline double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

} // namespace

int aeroModelFromName(const std::string& name)
{
	using M = btSoftBody::eAeroModel;
	if (name == "V_Point")
		return M::V_Point;
	if (name == "V_TwoSided")
		return M::V_TwoSided;
	if (name == "V_TwoSidedLiftDrag")
		return M::V_TwoSidedLiftDrag;
	if (name == "V_OneSided")
		return M::V_OneSided;
	if (name == "F_TwoSided")
		return M::F_TwoSided;
	if (name == "F_TwoSidedLiftDrag")
		return M::F_TwoSidedLiftDrag;
	return M::F_OneSided;
}

// --- KeyframePath ---------------------------------------------------------------------------------------------

KeyframePath::KeyframePath(const BodyMotionSpec& spec, const Eigen::Vector3d& defaultPivot)
	: spec_(spec), pivot_(spec.pivot ? *spec.pivot : defaultPivot)
{
}

btTransform KeyframePath::at(double time) const
{
	const std::vector<Keyframe>& k = spec_.keyframes;
	if (spec_.loop && k.back().time > 0.0)
		time = std::fmod(std::max(time, 0.0), k.back().time);
	Eigen::Vector3d translation;
	Eigen::Quaterniond rotation;
	auto quat = [](const Keyframe& f) {
		return Eigen::Quaterniond(Eigen::AngleAxisd(f.angleDeg * M_PI / 180.0, f.axis));
	};
	if (time <= k.front().time)
	{
		translation = k.front().translation;
		rotation = quat(k.front());
	}
	else if (time >= k.back().time)
	{
		translation = k.back().translation;
		rotation = quat(k.back());
	}
	else
	{
		std::size_t i = 1;
		while (k[i].time < time)
			++i;
		const double s = (time - k[i - 1].time) / (k[i].time - k[i - 1].time);
		translation = (1.0 - s) * k[i - 1].translation + s * k[i].translation;
		rotation = quat(k[i - 1]).slerp(s, quat(k[i]));
	}
	// p' = pivot + R (p - pivot) + T  =  R p + (pivot - R pivot + T)
	const Eigen::Matrix3d R = rotation.toRotationMatrix();
	const Eigen::Vector3d origin = pivot_ - R * pivot_ + translation;
	btMatrix3x3 basis;
	for (int r = 0; r < 3; ++r)
		for (int c = 0; c < 3; ++c)
			basis[r][c] = btScalar(R(r, c));
	return btTransform(basis, toBt(origin));
}

// --- TurbulenceField ------------------------------------------------------------------------------------------

TurbulenceField::TurbulenceField(double lengthScale, double timeScale, int octaves, unsigned seed)
	: invLength_(1.0 / lengthScale), invTime_(1.0 / timeScale), octaves_(std::max(1, octaves)), seed_(seed)
{
}

double TurbulenceField::valueNoise(const double p[4], unsigned channelSeed) const
{
	int cell[4];
	double f[4];
	for (int d = 0; d < 4; ++d)
	{
		const double fl = std::floor(p[d]);
		cell[d] = int(fl);
		f[d] = fade(p[d] - fl);
	}
	// Multilinear interpolation (with quintic weights) of the 16 lattice values of the 4D cell.
	double sum = 0.0;
	for (int corner = 0; corner < 16; ++corner)
	{
		unsigned h = channelSeed;
		double w = 1.0;
		for (int d = 0; d < 4; ++d)
		{
			const int bit = (corner >> d) & 1;
			h = hashInt(h ^ unsigned(cell[d] + bit) * 0x9e3779b1u);
			w *= bit ? f[d] : 1.0 - f[d];
		}
		sum += w * (double(h & 0xffffffu) / double(0xffffff) * 2.0 - 1.0);
	}
	return sum;
}

Eigen::Vector3d TurbulenceField::sample(const Eigen::Vector3d& x, double t) const
{
	Eigen::Vector3d out = Eigen::Vector3d::Zero();
	double amplitude = 1.0, total = 0.0, freq = 1.0;
	for (int o = 0; o < octaves_; ++o)
	{
		const double p[4] = {x.x() * invLength_ * freq, x.y() * invLength_ * freq, x.z() * invLength_ * freq,
							 t * invTime_ * freq};
		for (int c = 0; c < 3; ++c)
			out[c] += amplitude * valueNoise(p, hashInt(seed_ * 3u + unsigned(c) + 101u * unsigned(o + 1)));
		total += amplitude;
		amplitude *= 0.5;
		freq *= 2.0;
	}
	return out / total;
}

// --- WindEffect -------------------------------------------------------------------------------------------------

WindEffect::WindEffect(const WindSpec& wind, const std::optional<AerodynamicsSpec>& aero, btSoftBody* cloth,
					   EffectCounters& counters)
	: wind_(wind), field_(wind.lengthScale, wind.timeScale, wind.octaves, wind.seed), cloth_(cloth),
	  counters_(counters)
{
	if (aero)
	{
		model_ = aeroModelFromName(aero->model);
		lift_ = aero->lift;
		drag_ = aero->drag;
	}
	else
	{
		model_ = btSoftBody::eAeroModel::V_TwoSided;
		lift_ = 0.0;
		drag_ = wind.drag;
	}
	// Bullet's own per-step aerodynamics (applyForces) would add a second, still-air force: this effect applies
	// the aerodynamic model itself, so the body's coefficients stay 0 outside beforeSubstep.
	cloth_->m_cfg.kLF = 0;
	cloth_->m_cfg.kDG = 0;
	cloth_->m_cfg.aeromodel = btSoftBody::eAeroModel::_(model_);
}

Eigen::Vector3d WindEffect::airVelocity(const Eigen::Vector3d& x, double t) const
{
	// Frozen turbulence carried by the mean wind (Taylor's hypothesis) that also evolves on its own time scale.
	const Eigen::Vector3d advected = x - wind_.velocity * t;
	return wind_.velocity + wind_.turbulence * field_.sample(advected, t);
}

void WindEffect::beforeSubstep(double t, double dt)
{
	++counters_.windSubsteps;
	btSoftBody& sb = *cloth_;
	sb.m_cfg.kLF = btScalar(lift_);
	sb.m_cfg.kDG = btScalar(drag_);
	sb.m_sst.sdt = btScalar(dt); // addAero* clamp the drag with the step length
	if (model_ >= btSoftBody::eAeroModel::F_TwoSided)
	{
		for (int f = 0; f < sb.m_faces.size(); ++f)
		{
			const btSoftBody::Face& face = sb.m_faces[f];
			const btVector3 c = (face.m_n[0]->m_x + face.m_n[1]->m_x + face.m_n[2]->m_x) / btScalar(3);
			sb.addAeroForceToFace(toBt(airVelocity(toEigen(c), t)), f);
		}
		counters_.windNodeForces += sb.m_faces.size();
	}
	else
	{
		for (int i = 0; i < sb.m_nodes.size(); ++i)
			sb.addAeroForceToNode(toBt(airVelocity(toEigen(sb.m_nodes[i].m_x), t)), i);
		counters_.windNodeForces += sb.m_nodes.size();
	}
	sb.m_cfg.kLF = 0;
	sb.m_cfg.kDG = 0;
}

// --- SelfCollisionEffect ----------------------------------------------------------------------------------------

SelfCollisionEffect::SelfCollisionEffect(const SelfCollisionSpec& spec, btSoftBody* cloth, EffectCounters& counters)
	: spec_(spec), cloth_(cloth), counters_(counters)
{
	const int n = cloth->m_nodes.size();
	rest_.resize(n);
	for (int i = 0; i < n; ++i)
		rest_[i] = toEigen(cloth->m_nodes[i].m_x);
	linked_.assign(n, {});
	const btSoftBody::Node* base = &cloth->m_nodes[0];
	for (int l = 0; l < cloth->m_links.size(); ++l)
	{
		const int a = int(cloth->m_links[l].m_n[0] - base), b = int(cloth->m_links[l].m_n[1] - base);
		linked_[a].push_back(b);
		linked_[b].push_back(a);
	}
	for (auto& v : linked_)
		std::sort(v.begin(), v.end());
}

namespace
{

/// The key of grid cell (x, y, z): 21 bits per coordinate (wrapping: cells 2^21 apart share a key, which only costs
/// a distance test).
std::uint64_t cellKey(int x, int y, int z)
{
	return (std::uint64_t(std::uint32_t(x) & 0x1fffffu) << 42) | (std::uint64_t(std::uint32_t(y) & 0x1fffffu) << 21) |
		   std::uint64_t(std::uint32_t(z) & 0x1fffffu);
}

/// The grid cell of p for cells of edge 1 / inv.
void cellOf(const btVector3& p, double inv, int out[3])
{
	for (int d = 0; d < 3; ++d)
		out[d] = int(std::floor(double(p[d]) * inv));
}

} // namespace

double SelfCollisionEffect::searchRadius(double dt) const
{
	// Thickness plus what two nodes can close in one substep at the current speeds (capped so the grid stays fine;
	// faster pairs are caught over the following substeps).
	double maxSpeed = 0.0;
	for (int i = 0; i < cloth_->m_nodes.size(); ++i)
		maxSpeed = std::max(maxSpeed, double(cloth_->m_nodes[i].m_v.length()));
	return spec_.thickness + std::min(2.0 * maxSpeed * dt, 4.0 * spec_.thickness);
}

void SelfCollisionEffect::binNodes(double inv)
{
	const btSoftBody& sb = *cloth_;
	const int n = sb.m_nodes.size();
	keys_.resize(std::size_t(n));
	for (int i = 0; i < n; ++i)
	{
		int c[3];
		cellOf(sb.m_nodes[i].m_x, inv, c);
		keys_[std::size_t(i)] = {cellKey(c[0], c[1], c[2]), i};
	}
	std::sort(keys_.begin(), keys_.end());
	cells_.clear();
	cells_.reserve(std::size_t(n));
	for (int s = 0; s < n;)
	{
		int e = s;
		while (e < n && keys_[std::size_t(e)].first == keys_[std::size_t(s)].first)
			++e;
		cells_.emplace(keys_[std::size_t(s)].first, std::make_pair(s, e));
		s = e;
	}
}

void SelfCollisionEffect::repel(int i, int j, double radius, double dt)
{
	btSoftBody::Node& a = cloth_->m_nodes[i];
	btSoftBody::Node& b = cloth_->m_nodes[j];
	const double h = spec_.thickness;
	const btVector3 d = b.m_x - a.m_x;
	const double dist = d.length();
	if (dist >= radius || dist < 1e-12)
		return;
	++counters_.selfCollisionPairs;
	if ((rest_[std::size_t(i)] - rest_[std::size_t(j)]).squaredNorm() < h * h)
		return; // this close at rest: not a collision
	if (std::binary_search(linked_[std::size_t(i)].begin(), linked_[std::size_t(i)].end(), j))
		return;
	const double imSum = double(a.m_im + b.m_im);
	if (imSum <= 0.0)
		return;
	const btVector3 nrm = d / btScalar(dist);
	const double predicted = dist + double((b.m_v - a.m_v).dot(nrm)) * dt;
	if (predicted >= h)
		return;
	const double dv = spec_.stiffness * (h - predicted) / dt; // relative normal speed to add
	a.m_v -= nrm * btScalar(dv * a.m_im / imSum);
	b.m_v += nrm * btScalar(dv * b.m_im / imSum);
	++counters_.selfCollisionImpulses;
}

void SelfCollisionEffect::beforeSubstep(double /*t*/, double dt)
{
	++counters_.selfCollisionSubsteps;
	const double radius = searchRadius(dt);
	const double inv = 1.0 / radius;
	binNodes(inv);
	for (int i = 0; i < cloth_->m_nodes.size(); ++i)
	{
		int c[3];
		cellOf(cloth_->m_nodes[i].m_x, inv, c);
		for (int dx = -1; dx <= 1; ++dx)
			for (int dy = -1; dy <= 1; ++dy)
				for (int dz = -1; dz <= 1; ++dz)
				{
					const auto it = cells_.find(cellKey(c[0] + dx, c[1] + dy, c[2] + dz));
					if (it == cells_.end())
						continue;
					for (int s = it->second.first; s < it->second.second; ++s)
						if (keys_[std::size_t(s)].second > i) // each pair once
							repel(i, keys_[std::size_t(s)].second, radius, dt);
				}
	}
}

// --- BodyMotionEffect -------------------------------------------------------------------------------------------

BodyMotionEffect::BodyMotionEffect(const KeyframePath& path, btRigidBody* body, EffectCounters& counters)
	: path_(path), body_(body), counters_(counters)
{
}

void BodyMotionEffect::beforeSubstep(double t, double dt)
{
	++counters_.bodyMotionSubsteps;
	const btTransform pose = path_.at(t + dt);
	if (body_->getMotionState())
		body_->getMotionState()->setWorldTransform(pose);
	else
		body_->setWorldTransform(pose);
}

// --- BodyPinEffect ----------------------------------------------------------------------------------------------

BodyPinEffect::BodyPinEffect(const std::vector<int>& nodes, const KeyframePath& path, btSoftBody* cloth,
							 EffectCounters& counters)
	: nodes_(nodes), path_(path), cloth_(cloth), counters_(counters)
{
	const btTransform inv0 = path_.at(0.0).inverse();
	for (int i : nodes_)
		local_.push_back(inv0 * cloth_->m_nodes[i].m_x);
}

void BodyPinEffect::beforeSubstep(double t, double dt)
{
	++counters_.pinSubsteps;
	const btTransform pose = path_.at(t + dt);
	for (std::size_t k = 0; k < nodes_.size(); ++k)
	{
		btSoftBody::Node& n = cloth_->m_nodes[nodes_[k]];
		n.m_v = (pose * local_[k] - n.m_x) / btScalar(dt);
	}
}

} // namespace bodyfit::drape
