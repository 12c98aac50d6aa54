#pragma once
// Skin fields baked from analytic shapes for the tight-mode tests: the signed distance is evaluated at every lattice
// point of the shared layout (bodyfit/bullet_ext/btSkinDistanceField.h), bricks whose whole box lies beyond the clamp
// are marked far outside / far inside (decided from the brick centre and its half diagonal: the distances are
// 1-Lipschitz), the rest stored, rounded down (the quantised field never reads above the analytic one at a lattice point).

#include "bodyfit/bullet_ext/btSkinDistanceField.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <vector>

namespace bodyfit_test
{

using AnalyticSdf = std::function<double(const Eigen::Vector3d&)>;

inline double sphereSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& c, double r) { return (p - c).norm() - r; }

/// Axis-aligned box of half sizes `half` centred at c.
inline double boxSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& c, const Eigen::Vector3d& half)
{
	const Eigen::Vector3d q = (p - c).cwiseAbs() - half;
	return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

/// Capsule: the segment a-b grown by r.
inline double capsuleSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r)
{
	const Eigen::Vector3d ab = b - a;
	const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
	return (p - (a + t * ab)).norm() - r;
}

/// The raw arrays of a bake, before btSkinDistanceField::set.
struct BakedArrays
{
	btSkinFieldLayout layout;
	std::vector<int> brickIndex;
	std::vector<short> samples;
};

/// Bakes `sdf` on a grid covering [lo, hi] (metres, body frame).
inline BakedArrays bakeArrays(const AnalyticSdf& sdf, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
							  double h = 0.005, double clamp = 0.012)
{
	const int B = btSkinDistanceField::kBrickEdge, S = btSkinDistanceField::kBrickSide;
	BakedArrays out;
	out.layout.m_voxelSize = h;
	out.layout.m_clamp = clamp;
	for (int k = 0; k < 3; ++k)
	{
		out.layout.m_origin[k] = lo[k];
		out.layout.m_bricks[k] = std::max(1, int(std::ceil((hi[k] - lo[k]) / (B * h))));
	}
	const int nx = out.layout.m_bricks[0], ny = out.layout.m_bricks[1], nz = out.layout.m_bricks[2];
	const double quantum = clamp / 32767.0, halfDiagonal = std::sqrt(3.0) * 0.5 * B * h;
	const Eigen::Vector3d o(lo);
	out.brickIndex.assign(size_t(nx) * ny * nz, btSkinDistanceField::kFarOutside);
	for (int k = 0; k < nz; ++k)
		for (int j = 0; j < ny; ++j)
			for (int i = 0; i < nx; ++i)
			{
				const Eigen::Vector3d corner = o + B * h * Eigen::Vector3d(i, j, k);
				const double dc = sdf(corner + Eigen::Vector3d::Constant(0.5 * B * h));
				int& index = out.brickIndex[size_t(i) + size_t(nx) * (j + size_t(ny) * k)];
				if (dc - halfDiagonal >= clamp)
					continue;
				if (dc + halfDiagonal <= -clamp)
				{
					index = btSkinDistanceField::kFarInside;
					continue;
				}
				index = int(out.samples.size() / size_t(S * S * S));
				for (int c = 0; c < S; ++c)
					for (int b = 0; b < S; ++b)
						for (int a = 0; a < S; ++a)
						{
							// From the global lattice index, so neighbours compute their shared points identically.
							const Eigen::Vector3d p = o + h * Eigen::Vector3d(B * i + a, B * j + b, B * k + c);
							const double d = std::clamp(sdf(p), -clamp, clamp);
							out.samples.push_back(short(std::max(-32767.0, std::floor(d / quantum))));
						}
			}
	return out;
}

/// Largest |field - sdf| over `count` random points of the unclamped band inside [lo, hi] (deterministic seed):
/// |sdf| < clamp - sqrt(3) h, where no corner of the point's cell is clamped (nearer the clamp the interpolant
/// blends clamped samples and reads closer to the skin than the true distance: by design, conservative outside).
inline double measureMaxError(const btSkinDistanceField& field, const AnalyticSdf& sdf, const Eigen::Vector3d& lo,
							  const Eigen::Vector3d& hi, int count = 20000)
{
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> u(0.0, 1.0);
	double worst = 0.0;
	for (int found = 0, tries = 0; found < count && tries < 200 * count; ++tries)
	{
		const Eigen::Vector3d p = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng)));
		const double d = sdf(p);
		if (std::abs(d) >= double(field.getClamp()) - std::sqrt(3.0) * double(field.getVoxelSize()))
			continue;
		++found;
		const double f = double(field.distance(btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z()))));
		worst = std::max(worst, std::abs(f - d));
	}
	return worst;
}

/// A field baked from `sdf` over [lo, hi], with maxError measured (as the bake does) on random band points.
inline std::unique_ptr<btSkinDistanceField> bakeField(const AnalyticSdf& sdf, const Eigen::Vector3d& lo,
													   const Eigen::Vector3d& hi, double h = 0.005, double clamp = 0.012)
{
	BakedArrays arrays = bakeArrays(sdf, lo, hi, h, clamp);
	std::unique_ptr<btSkinDistanceField> field(new btSkinDistanceField());
	if (!field->set(arrays.layout, arrays.brickIndex.data(), (long long)arrays.brickIndex.size(), arrays.samples.data(),
					(long long)arrays.samples.size()))
		return nullptr;
	arrays.layout.m_maxError = measureMaxError(*field, sdf, lo, hi);
	field->set(arrays.layout, arrays.brickIndex.data(), (long long)arrays.brickIndex.size(), arrays.samples.data(),
			   (long long)arrays.samples.size());
	return field;
}

} // namespace bodyfit_test
