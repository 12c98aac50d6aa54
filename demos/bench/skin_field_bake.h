#pragma once
// A BRUTE-FORCE skin field for the benches (not the project's bake, which lives in fitting/ on its own branch):
// the mesh's signed distance (bodyfit::metrics::BodyReference: exact unsigned distance + ray-parity inside test) is
// evaluated at every lattice point of every brick that meets the ellipsoid union grown by skin + 2 h and whose
// distance range meets (-clamp, clamp), in the shared layout of bodyfit/bullet_ext/btSkinDistanceField.h. Samples
// are rounded down; no correction makes the interpolant conservative (maxError is measured on random band points).

#include "bodyfit/bullet_ext/btSkinDistanceField.h"
#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/metrics/cloth_metrics.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

namespace bodyfit_bench
{

struct BruteForceBake
{
	std::unique_ptr<btSkinDistanceField> field;
	int storedBricks = 0;
	int bricks = 0;
	double seconds = 0.0;
	double maxError = 0.0; ///< measured on random points of the unclamped band
};

/// Smallest signed distance from p to the ellipsoids (negative inside one).
inline double unionDistance(const std::vector<bodyfit::Ellipsoid>& ellipsoids, const Eigen::Vector3d& p)
{
	double best = std::numeric_limits<double>::infinity();
	for (const bodyfit::Ellipsoid& e : ellipsoids)
		best = std::min(best, bodyfit::closestSurfacePoint(e, p).signedDistance);
	return best;
}

/// The brick's index entry: -1 / -2 when the layout lets it be absent, else the next block (samples appended).
inline int bakeBrick(const bodyfit::metrics::BodyReference& body, const std::vector<bodyfit::Ellipsoid>& ellipsoids,
					 const btSkinFieldLayout& layout, const int ijk[3], double grow, std::vector<short>& samples)
{
	const int B = btSkinDistanceField::kBrickEdge, S = btSkinDistanceField::kBrickSide;
	const double h = layout.m_voxelSize, clamp = layout.m_clamp, halfDiagonal = std::sqrt(3.0) * 0.5 * B * h;
	const Eigen::Vector3d o(layout.m_origin[0], layout.m_origin[1], layout.m_origin[2]);
	const Eigen::Vector3d centre = o + h * (B * Eigen::Vector3d(ijk[0], ijk[1], ijk[2]) + Eigen::Vector3d::Constant(0.5 * B));
	const double dc = body.signedSkinDistance(centre);
	// Entirely outside the grown union may be absent, but only outside the body: the union of a fit encloses pockets
	// under the skin (outside every ellipsoid, inside the body), which must not read far outside.
	if (dc > 0.0 && unionDistance(ellipsoids, centre) > halfDiagonal + grow)
		return btSkinDistanceField::kFarOutside;
	if (dc - halfDiagonal >= clamp)
		return btSkinDistanceField::kFarOutside;
	if (dc + halfDiagonal <= -clamp)
		return btSkinDistanceField::kFarInside;
	const int block = int(samples.size() / size_t(S * S * S));
	const double quantum = clamp / 32767.0;
	for (int c = 0; c < S; ++c)
		for (int b = 0; b < S; ++b)
			for (int a = 0; a < S; ++a)
			{
				const Eigen::Vector3d p = o + h * Eigen::Vector3d(B * ijk[0] + a, B * ijk[1] + b, B * ijk[2] + c);
				const double d = std::clamp(body.signedSkinDistance(p), -clamp, clamp);
				samples.push_back(short(std::max(-32767.0, std::floor(d / quantum))));
			}
	return block;
}

/// Largest |field - signed mesh distance| over random points near the skin (within clamp - sqrt(3) h of it).
inline double measureBakeError(const btSkinDistanceField& field, const bodyfit::metrics::BodyReference& body,
							   const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int count)
{
	std::mt19937 rng(11);
	std::uniform_real_distribution<double> u(0.0, 1.0);
	const double band = double(field.getClamp()) - std::sqrt(3.0) * double(field.getVoxelSize());
	double worst = 0.0;
	for (int found = 0, tries = 0; found < count && tries < 1000 * count; ++tries)
	{
		const Eigen::Vector3d p = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng)));
		if (field.distance(btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z()))) >= field.getClamp())
			continue; // far from the skin (cheap rejection before the exact distance)
		const double d = body.signedSkinDistance(p);
		if (std::abs(d) >= band)
			continue;
		++found;
		worst = std::max(worst, std::abs(double(field.distance(btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z())))) - d));
	}
	return worst;
}

/// Bakes the body (mesh frame = the compound's frame) with voxel h and clamp; skin is the collider's skin offset.
inline BruteForceBake bruteForceSkinField(const bodyfit::TriMesh& mesh, const std::vector<bodyfit::Ellipsoid>& ellipsoids,
										  double skin, double h = 0.005, double clamp = 0.012)
{
	const auto t0 = std::chrono::steady_clock::now();
	const bodyfit::metrics::BodyReference body(mesh);
	const double grow = skin + 2.0 * h;
	Eigen::AlignedBox3d box;
	for (const bodyfit::Ellipsoid& e : ellipsoids)
		box.extend(e.aabb());
	const Eigen::Vector3d lo = box.min() - Eigen::Vector3d::Constant(grow), hi = box.max() + Eigen::Vector3d::Constant(grow);
	btSkinFieldLayout layout;
	layout.m_voxelSize = h;
	layout.m_clamp = clamp;
	layout.m_skinOffset = skin;
	for (int k = 0; k < 3; ++k)
	{
		layout.m_origin[k] = lo[k];
		layout.m_bricks[k] = std::max(1, int(std::ceil((hi[k] - lo[k]) / (btSkinDistanceField::kBrickEdge * h))));
	}
	std::vector<int> index;
	std::vector<short> samples;
	for (int k = 0; k < layout.m_bricks[2]; ++k)
		for (int j = 0; j < layout.m_bricks[1]; ++j)
			for (int i = 0; i < layout.m_bricks[0]; ++i)
			{
				const int ijk[3] = {i, j, k};
				index.push_back(bakeBrick(body, ellipsoids, layout, ijk, grow, samples));
			}
	BruteForceBake out;
	out.bricks = int(index.size());
	out.storedBricks = int(samples.size() / size_t(btSkinDistanceField::kBrickSamples));
	out.field.reset(new btSkinDistanceField());
	const char* why = nullptr;
	if (!out.field->set(layout, index.data(), (long long)index.size(), samples.data(), (long long)samples.size(), &why))
		throw std::runtime_error(std::string("brute-force skin field: ") + why);
	out.maxError = measureBakeError(*out.field, body, lo, hi, 20000);
	layout.m_maxError = out.maxError;
	out.field->set(layout, index.data(), (long long)index.size(), samples.data(), (long long)samples.size());
	out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	return out;
}

} // namespace bodyfit_bench
