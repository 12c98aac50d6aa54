// Fit-quality metrics of a union of ellipsoids against a body mesh (docs/DESIGN.md sec. 5): air gap, skin outside the
// union, voxel IoU. See fit_quality.h for the definitions.
#include "bodyfit/fitting/fit_quality.h"

#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_set>

namespace bodyfit
{

namespace
{

/// Target average number of triangles per cell (over the whole box; cells the surface crosses hold more).
constexpr double kFacesPerCell = 1.0;
/// Cap on the grid size (cells), whatever the mesh.
constexpr double kMaxCells = 4.0e6;

double elapsedMs(std::chrono::steady_clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void requireMesh(const TriMesh& mesh, const char* what)
{
	if (mesh.F.rows() == 0)
		throw InvalidInputError(std::string(what) + ": the mesh has no faces");
	if (!mesh.V.allFinite())
		throw InvalidInputError(std::string(what) + ": the mesh has non-finite vertex coordinates");
	if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= mesh.V.rows())
		throw InvalidInputError(std::string(what) + ": a face index is out of range (" +
								std::to_string(mesh.F.maxCoeff()) + " with " + std::to_string(mesh.V.rows()) +
								" vertices)");
}

/// Weighted quantile: smallest value whose cumulative weight (values sorted ascending) reaches q of the total.
double weightedQuantile(std::vector<std::pair<double, double>> valueWeight, double q)
{
	if (valueWeight.empty())
		return 0.0;
	std::sort(valueWeight.begin(), valueWeight.end());
	double total = 0.0;
	for (const auto& vw : valueWeight)
		total += vw.second;
	const double target = q * total;
	double acc = 0.0;
	for (const auto& vw : valueWeight)
	{
		acc += vw.second;
		if (acc >= target)
			return vw.first;
	}
	return valueWeight.back().first;
}

/// Squared distance from p to an axis-aligned box (0 inside).
double boxDistanceSquared(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& p)
{
	const Eigen::Vector3d d = (box.min() - p).cwiseMax(p - box.max()).cwiseMax(0.0);
	return d.squaredNorm();
}

} // namespace

// ------------------------------------------------------------------------------------------------ MeshDistanceGrid

MeshDistanceGrid::MeshDistanceGrid(const TriMesh& mesh) : V_(mesh.V), F_(mesh.F)
{
	requireMesh(mesh, "MeshDistanceGrid");
	const Eigen::Vector3d lo = V_.colwise().minCoeff().transpose();
	const Eigen::Vector3d hi = V_.colwise().maxCoeff().transpose();
	const Eigen::Vector3d extent = (hi - lo).cwiseMax(1e-9);
	// Cubic cells, about kFacesPerCell faces per cell over the box, never finer than the mean edge length (a
	// triangle then spans at most a few cells).
	double meanEdge = 0.0;
	for (int f = 0; f < F_.rows(); ++f)
		meanEdge += (V_.row(F_(f, 0)) - V_.row(F_(f, 1))).norm();
	meanEdge /= double(F_.rows());
	const double volume = extent.prod();
	double cell = std::cbrt(volume * kFacesPerCell / double(F_.rows()));
	cell = std::max({cell, meanEdge, extent.maxCoeff() * 1e-4});
	while ((extent / cell).array().ceil().prod() > kMaxCells)
		cell *= 1.25;
	cell_ = cell;
	origin_ = lo;
	for (int k = 0; k < 3; ++k)
		dims_[k] = std::max(1, int(std::ceil(extent[k] / cell_)));

	const auto cellOf = [&](double x, int k) { return std::clamp(int((x - origin_[k]) / cell_), 0, dims_[k] - 1); };
	const size_t cells = size_t(dims_[0]) * size_t(dims_[1]) * size_t(dims_[2]);
	std::vector<int> count(cells + 1, 0);
	std::vector<std::array<int, 6>> range(size_t(F_.rows()));
	for (int f = 0; f < F_.rows(); ++f)
	{
		Eigen::Vector3d a = V_.row(F_(f, 0)).transpose(), b = a;
		for (int j = 1; j < 3; ++j)
		{
			a = a.cwiseMin(V_.row(F_(f, j)).transpose());
			b = b.cwiseMax(V_.row(F_(f, j)).transpose());
		}
		auto& r = range[size_t(f)];
		for (int k = 0; k < 3; ++k)
		{
			r[size_t(k)] = cellOf(a[k], k);
			r[size_t(k) + 3] = cellOf(b[k], k);
		}
		for (int z = r[2]; z <= r[5]; ++z)
			for (int y = r[1]; y <= r[4]; ++y)
				for (int x = r[0]; x <= r[3]; ++x)
					++count[size_t(cellIndex(x, y, z)) + 1];
	}
	std::partial_sum(count.begin(), count.end(), count.begin());
	cellStart_ = count;
	cellFaces_.resize(size_t(cellStart_.back()));
	std::vector<int> fill(cellStart_.begin(), cellStart_.end() - 1);
	for (int f = 0; f < F_.rows(); ++f)
	{
		const auto& r = range[size_t(f)];
		for (int z = r[2]; z <= r[5]; ++z)
			for (int y = r[1]; y <= r[4]; ++y)
				for (int x = r[0]; x <= r[3]; ++x)
					cellFaces_[size_t(fill[size_t(cellIndex(x, y, z))]++)] = f;
	}
}

Eigen::Vector3d MeshDistanceGrid::closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
														 const Eigen::Vector3d& b, const Eigen::Vector3d& c)
{
	// Voronoi regions of the vertices, then the edges, then the face (barycentric form).
	const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
	const double d1 = ab.dot(ap), d2 = ac.dot(ap);
	if (d1 <= 0.0 && d2 <= 0.0)
		return a;
	const Eigen::Vector3d bp = p - b;
	const double d3 = ab.dot(bp), d4 = ac.dot(bp);
	if (d3 >= 0.0 && d4 <= d3)
		return b;
	const double vc = d1 * d4 - d3 * d2;
	if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
		return a + ab * (d1 / (d1 - d3));
	const Eigen::Vector3d cp = p - c;
	const double d5 = ab.dot(cp), d6 = ac.dot(cp);
	if (d6 >= 0.0 && d5 <= d6)
		return c;
	const double vb = d5 * d2 - d1 * d6;
	if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
		return a + ac * (d2 / (d2 - d6));
	const double va = d3 * d6 - d5 * d4;
	if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
		return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
	const double denom = va + vb + vc;
	if (!(std::abs(denom) > 0.0)) // degenerate (zero-area) triangle: nearest of the three edges' end points
	{
		const double da = (p - a).squaredNorm(), db = (p - b).squaredNorm(), dc = (p - c).squaredNorm();
		return da <= db && da <= dc ? a : (db <= dc ? b : c);
	}
	const double v = vb / denom, w = vc / denom;
	return a + ab * v + ac * w;
}

double MeshDistanceGrid::distance(const Eigen::Vector3d& p, Eigen::Vector3d* closest) const
{
	int c[3];
	for (int k = 0; k < 3; ++k)
		c[k] = std::clamp(int(std::floor((p[k] - origin_[k]) / cell_)), 0, dims_[k] - 1);
	double best = std::numeric_limits<double>::infinity();
	Eigen::Vector3d bestPoint = p;
	const int maxRing = std::max({dims_[0], dims_[1], dims_[2]});
	for (int r = 0; r <= maxRing; ++r)
	{
		const int lo[3] = {std::max(0, c[0] - r), std::max(0, c[1] - r), std::max(0, c[2] - r)};
		const int hi[3] = {std::min(dims_[0] - 1, c[0] + r), std::min(dims_[1] - 1, c[1] + r),
						   std::min(dims_[2] - 1, c[2] + r)};
		for (int z = lo[2]; z <= hi[2]; ++z)
			for (int y = lo[1]; y <= hi[1]; ++y)
			{
				const bool innerYZ = std::abs(z - c[2]) < r && std::abs(y - c[1]) < r;
				for (int x = lo[0]; x <= hi[0]; ++x)
				{
					if (innerYZ && std::abs(x - c[0]) < r)
					{
						x = c[0] + r - 1; // skip the already visited inside of the shell
						continue;
					}
					const int cell = cellIndex(x, y, z);
					for (int i = cellStart_[size_t(cell)]; i < cellStart_[size_t(cell) + 1]; ++i)
					{
						const int f = cellFaces_[size_t(i)];
						const Eigen::Vector3d q = closestPointOnTriangle(p, V_.row(F_(f, 0)).transpose(),
																		 V_.row(F_(f, 1)).transpose(),
																		 V_.row(F_(f, 2)).transpose());
						const double d = (q - p).squaredNorm();
						if (d < best)
						{
							best = d;
							bestPoint = q;
						}
					}
				}
			}
		// Lower bound on the distance to any cell outside the visited box [c - r, c + r]: along each axis and side
		// that still has cells, the distance from p to that face of the box.
		double bound = std::numeric_limits<double>::infinity();
		for (int k = 0; k < 3; ++k)
		{
			if (c[k] - r > 0)
				bound = std::min(bound, std::max(0.0, p[k] - (origin_[k] + (c[k] - r) * cell_)));
			if (c[k] + r < dims_[k] - 1)
				bound = std::min(bound, std::max(0.0, (origin_[k] + (c[k] + r + 1) * cell_) - p[k]));
		}
		if (bound * bound >= best) // also true when every cell was visited (bound = inf)
			break;
	}
	if (closest)
		*closest = bestPoint;
	return std::sqrt(best);
}

// ------------------------------------------------------------------------------------------------ ellipsoid area

double ellipsoidSurfaceArea(const Ellipsoid& e)
{
	// Knud Thomsen: S ~ 4 pi ((a^p b^p + a^p c^p + b^p c^p) / 3)^(1/p), p = 1.6075.
	constexpr double p = 1.6075;
	const double a = std::pow(e.radii[0], p), b = std::pow(e.radii[1], p), c = std::pow(e.radii[2], p);
	return 4.0 * M_PI * std::pow((a * b + a * c + b * c) / 3.0, 1.0 / p);
}

// ------------------------------------------------------------------------------------------------ reference

FitQualityReference::FitQualityReference(const TriMesh& mesh, int voxelResolution)
	: mesh_(mesh), distance_((requireMesh(mesh, "FitQualityReference"), mesh)), inside_(mesh),
	  resolution_(voxelResolution)
{
	const auto t0 = std::chrono::steady_clock::now();
	if (voxelResolution < 0)
		throw InvalidInputError("FitQualityReference: voxel resolution must be >= 0 (got " +
								std::to_string(voxelResolution) + ")");
	if (voxelResolution > 0)
	{
		const Eigen::Vector3d lo = mesh.V.colwise().minCoeff().transpose();
		const Eigen::Vector3d hi = mesh.V.colwise().maxCoeff().transpose();
		const Eigen::Vector3d extent = (hi - lo).cwiseMax(1e-12);
		voxel_ = extent.maxCoeff() / double(voxelResolution);
		origin_ = lo;
		for (int k = 0; k < 3; ++k)
			dims_[k] = std::max(1, int(std::ceil(extent[k] / voxel_)));
		body_.assign(size_t(dims_[0]) * size_t(dims_[1]) * size_t(dims_[2]), 0);
		size_t i = 0;
		for (int z = 0; z < dims_[2]; ++z)
			for (int y = 0; y < dims_[1]; ++y)
				for (int x = 0; x < dims_[0]; ++x, ++i)
				{
					const Eigen::Vector3d p = origin_ + voxel_ * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5);
					if (inside_.isInside(p))
					{
						body_[i] = 1;
						++bodyVoxelCount_;
					}
				}
	}
	milliseconds_ = elapsedMs(t0);
}

// ------------------------------------------------------------------------------------------------ measure

namespace
{

void validateQualityInput(const std::vector<Ellipsoid>& ellipsoids, const FitQualityOptions& options)
{
	if (ellipsoids.empty())
		throw InvalidInputError("measureFitQuality: the ellipsoid list is empty");
	for (size_t j = 0; j < ellipsoids.size(); ++j)
		if (!ellipsoids[j].isValid())
			throw InvalidInputError("measureFitQuality: ellipsoid " + std::to_string(j) +
									" is not valid (non-finite, non-positive radius or not a rotation)");
	if (!(options.sampleSpacing > 0.0) || !std::isfinite(options.sampleSpacing))
		throw InvalidInputError("measureFitQuality: sample spacing must be a positive number");
	if (options.minSamplesPerEllipsoid < 1)
		throw InvalidInputError("measureFitQuality: minSamplesPerEllipsoid must be >= 1");
}

/// The ellipsoids with their boxes, and the two questions every measure asks of their union.
struct EllipsoidUnion
{
	const std::vector<Ellipsoid>& ellipsoids;
	std::vector<Eigen::AlignedBox3d> boxes;

	explicit EllipsoidUnion(const std::vector<Ellipsoid>& e) : ellipsoids(e)
	{
		boxes.reserve(e.size());
		for (const Ellipsoid& el : e)
			boxes.push_back(el.aabb());
	}

	int size() const { return int(ellipsoids.size()); }

	/// p is inside (or within `tolerance` in zeta of) some ellipsoid.
	bool covers(const Eigen::Vector3d& p, double tolerance) const
	{
		for (size_t j = 0; j < ellipsoids.size(); ++j)
			if (boxes[j].contains(p) && ellipsoids[j].zeta(p) <= 1.0 + tolerance)
				return true;
		return false;
	}

	/// The distance from p, outside every ellipsoid, to the union: the least distance to one of them. Box distances
	/// are lower bounds, so the ellipsoids are visited nearest box first until the next box is no nearer than the
	/// best found. `order` is scratch.
	double distanceFromOutside(const Eigen::Vector3d& p, std::vector<std::pair<double, int>>& order) const
	{
		order.resize(ellipsoids.size());
		for (int j = 0; j < size(); ++j)
			order[size_t(j)] = {boxDistanceSquared(boxes[size_t(j)], p), j};
		std::sort(order.begin(), order.end());
		double best = std::numeric_limits<double>::infinity();
		for (const auto& [bound2, j] : order)
		{
			if (bound2 >= best * best)
				break;
			best = std::min(best, std::abs(closestSurfacePoint(ellipsoids[size_t(j)], p).signedDistance));
		}
		return best;
	}
};

/// Air gap: area-weighted samples on the exposed union surface (inside no other ellipsoid), measured to the skin
/// where they lie outside the body.
void measureAirGap(const FitQualityReference& ref, const EllipsoidUnion& U, const FitQualityOptions& options,
				   FitQuality& q)
{
	constexpr double kGolden = 2.399963229728653; // pi (3 - sqrt 5)
	std::vector<std::pair<double, double>> gapWeight;
	double exposedArea = 0.0, insideBodyArea = 0.0, gapSum = 0.0, weightSum = 0.0;
	std::vector<int> others;
	for (int j = 0; j < U.size(); ++j)
	{
		const Ellipsoid& e = U.ellipsoids[size_t(j)];
		others.clear();
		for (int k = 0; k < U.size(); ++k)
			if (k != j && U.boxes[size_t(k)].intersects(U.boxes[size_t(j)]))
				others.push_back(k);
		const double area = ellipsoidSurfaceArea(e);
		const int count = std::max(options.minSamplesPerEllipsoid,
								   int(std::ceil(area / (options.sampleSpacing * options.sampleSpacing))));
		const double rProd = e.radii.prod();
		const double solidAngle = 4.0 * M_PI / double(count);
		for (int i = 0; i < count; ++i)
		{
			// Spherical Fibonacci point u (equal solid angle each), mapped to x = c + R diag(r) u. The area
			// element of that map is r1 r2 r3 |diag(1/r) u| per unit solid angle (exact).
			const double zc = 1.0 - (2.0 * i + 1.0) / double(count);
			const double rho = std::sqrt(std::max(0.0, 1.0 - zc * zc));
			const double phi = kGolden * double(i);
			const Eigen::Vector3d u(rho * std::cos(phi), rho * std::sin(phi), zc);
			const double weight = solidAngle * rProd * u.cwiseQuotient(e.radii).norm();
			const Eigen::Vector3d x = e.toWorld(u.cwiseProduct(e.radii));
			++q.totalSamples;
			const bool covered = std::any_of(others.begin(), others.end(), [&](int k) {
				return U.ellipsoids[size_t(k)].zeta(x) < 1.0 - 1e-9;
			});
			if (covered)
				continue;
			++q.exposedSamples;
			exposedArea += weight;
			if (ref.insideTest().isInside(x))
			{
				insideBodyArea += weight;
				continue;
			}
			const double d = ref.distanceGrid().distance(x);
			++q.airGapSamples;
			gapWeight.emplace_back(d, weight);
			gapSum += d * weight;
			weightSum += weight;
			q.airGapMax = std::max(q.airGapMax, d);
		}
	}
	q.exposedArea = exposedArea;
	q.unionInsideBodyFraction = exposedArea > 0.0 ? insideBodyArea / exposedArea : 0.0;
	q.airGapMean = weightSum > 0.0 ? gapSum / weightSum : 0.0;
	q.airGapP95 = weightedQuantile(std::move(gapWeight), 0.95);
}

/// Skin outside the union, at the mesh's vertices: how many, how far.
void measureSkinVerticesOutside(const TriMesh& mesh, const EllipsoidUnion& U, const FitQualityOptions& options,
								FitQuality& q)
{
	std::vector<std::pair<double, int>> order;
	double sum = 0.0;
	for (int v = 0; v < mesh.V.rows(); ++v)
	{
		const Eigen::Vector3d p = mesh.V.row(v).transpose();
		if (U.covers(p, options.outsideTolerance))
			continue;
		const double d = U.distanceFromOutside(p, order);
		++q.skinOutsideVertices;
		sum += d;
		q.skinOutsideMax = std::max(q.skinOutsideMax, d);
	}
	q.skinOutsideFraction = mesh.V.rows() > 0 ? double(q.skinOutsideVertices) / double(mesh.V.rows()) : 0.0;
	q.skinOutsideMean = q.skinOutsideVertices > 0 ? sum / double(q.skinOutsideVertices) : 0.0;
}

/// Skin outside the union over the whole surface: a barycentric grid on every triangle, its longest edge cut into
/// pieces no longer than options.skinSurfaceSpacing (> 0).
void measureSkinSurfaceOutside(const TriMesh& mesh, const EllipsoidUnion& U, const FitQualityOptions& options,
							   FitQuality& q)
{
	std::vector<std::pair<double, int>> order;
	for (int f = 0; f < mesh.F.rows(); ++f)
	{
		const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
		const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
		const int level = std::clamp(int(std::ceil(longest / options.skinSurfaceSpacing)), 1, 1000);
		for (int i = 0; i <= level; ++i)
			for (int k = 0; i + k <= level; ++k)
			{
				const Eigen::Vector3d p = (double(i) * a + double(k) * b + double(level - i - k) * c) / double(level);
				++q.skinSurfaceSamples;
				if (U.covers(p, options.outsideTolerance))
					continue;
				++q.skinSurfaceOutside;
				q.skinSurfaceOutsideMax = std::max(q.skinSurfaceOutsideMax, U.distanceFromOutside(p, order));
			}
	}
}

/// The reference's voxel lattice, for the IoU: voxel (x, y, z) has its centre at origin + (x + 0.5, y + 0.5, z + 0.5)
/// h; body[i] = 1 where that centre is inside the body, x fastest.
struct BodyVoxels
{
	Eigen::Vector3d origin;
	double h;
	const int* dims;
	const std::vector<unsigned char>& body;
	long long bodyCount;
};

/// Voxel IoU of the union and the body on the body's lattice (union voxels beyond the lattice count too: they are
/// never body).
void measureVoxelIoU(const BodyVoxels& lattice, const EllipsoidUnion& U, FitQuality& q)
{
	const double h = lattice.h;
	const int* dims = lattice.dims;
	std::vector<unsigned char> unionMark(lattice.body.size(), 0);
	std::unordered_set<long long> outsideBox; // union voxels beyond the mesh box (never body)
	for (int j = 0; j < U.size(); ++j)
	{
		const Ellipsoid& e = U.ellipsoids[size_t(j)];
		int lo[3], hi[3];
		for (int k = 0; k < 3; ++k)
		{
			// voxel i has its centre at origin + (i + 0.5) h
			lo[k] = int(std::ceil((U.boxes[size_t(j)].min()[k] - lattice.origin[k]) / h - 0.5));
			hi[k] = int(std::floor((U.boxes[size_t(j)].max()[k] - lattice.origin[k]) / h - 0.5));
		}
		for (int z = lo[2]; z <= hi[2]; ++z)
			for (int y = lo[1]; y <= hi[1]; ++y)
				for (int x = lo[0]; x <= hi[0]; ++x)
				{
					const Eigen::Vector3d p = lattice.origin + h * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5);
					if (e.zeta(p) > 1.0)
						continue;
					if (x >= 0 && y >= 0 && z >= 0 && x < dims[0] && y < dims[1] && z < dims[2])
						unionMark[(size_t(z) * size_t(dims[1]) + size_t(y)) * size_t(dims[0]) + size_t(x)] = 1;
					else
					{
						// unique key for lattice coordinates within +-2^20 of the origin
						const long long key = ((long long)(z + (1 << 20)) << 42) | ((long long)(y + (1 << 20)) << 21) |
											  (long long)(x + (1 << 20));
						outsideBox.insert(key);
					}
				}
	}
	long long unionCount = (long long)outsideBox.size(), inter = 0;
	for (size_t i = 0; i < unionMark.size(); ++i)
	{
		unionCount += unionMark[i];
		inter += unionMark[i] & lattice.body[i];
	}
	q.voxelSize = h;
	q.unionVoxels = unionCount;
	q.bodyVoxels = lattice.bodyCount;
	q.intersectionVoxels = inter;
	const long long uni = unionCount + lattice.bodyCount - inter;
	q.voxelIoU = uni > 0 ? double(inter) / double(uni) : 0.0;
}

} // namespace

FitQuality measureFitQuality(const FitQualityReference& ref, const std::vector<Ellipsoid>& ellipsoids,
							 const FitQualityOptions& options)
{
	const auto t0 = std::chrono::steady_clock::now();
	validateQualityInput(ellipsoids, options);
	const EllipsoidUnion U(ellipsoids);
	FitQuality q;
	q.ellipsoidCount = U.size();
	if (options.computeAirGap)
		measureAirGap(ref, U, options, q);
	if (options.computeSkinOutside)
	{
		measureSkinVerticesOutside(ref.mesh(), U, options, q);
		if (options.skinSurfaceSpacing > 0.0)
			measureSkinSurfaceOutside(ref.mesh(), U, options, q);
		q.skinSurfaceOutsideFraction =
			q.skinSurfaceSamples > 0 ? double(q.skinSurfaceOutside) / double(q.skinSurfaceSamples) : 0.0;
	}
	if (options.computeIoU && ref.resolution_ > 0)
		measureVoxelIoU(BodyVoxels{ref.origin_, ref.voxel_, ref.dims_, ref.body_, ref.bodyVoxelCount_}, U, q);
	q.milliseconds = elapsedMs(t0);
	return q;
}

FitQuality measureFitQuality(const TriMesh& mesh, const std::vector<Ellipsoid>& ellipsoids,
							 const FitQualityOptions& options, int voxelResolution)
{
	const FitQualityReference reference(mesh, options.computeIoU ? voxelResolution : 0);
	return measureFitQuality(reference, ellipsoids, options);
}

} // namespace bodyfit
