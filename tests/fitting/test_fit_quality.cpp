// Fit-quality metrics (air gap, skin outside the union, voxel IoU) on meshes whose exact answer is known: a sphere
// tessellation fitted by its own circumscribed sphere, scaled versions of it, a rotated ellipsoid tessellation, and
// a redundant inner ellipsoid that must not change anything.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/fit_quality.h"
#include "support/mesh_shapes.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <random>

using namespace bodyfit;

namespace
{

/// Icosahedron subdivided `levels` times (midpoint split, new points pushed onto the sphere): every vertex lies
/// exactly on the sphere of radius r, faces are nearly uniform (CCW seen from outside).
TriMesh icosphere(double r, int levels)
{
	const double t = (1.0 + std::sqrt(5.0)) / 2.0;
	std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
									  {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
	std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
									  {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
									  {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
									  {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
	for (auto& p : v)
		p = p.normalized() * r;
	for (int l = 0; l < levels; ++l)
	{
		std::map<std::pair<int, int>, int> mid;
		auto midpoint = [&](int a, int b) {
			const auto key = std::minmax(a, b);
			auto it = mid.find(key);
			if (it != mid.end())
				return it->second;
			v.push_back((v[size_t(a)] + v[size_t(b)]).normalized() * r);
			mid[key] = int(v.size()) - 1;
			return int(v.size()) - 1;
		};
		std::vector<Eigen::Vector3i> g;
		for (const auto& tri : f)
		{
			const int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
			g.emplace_back(tri[0], a, c);
			g.emplace_back(tri[1], b, a);
			g.emplace_back(tri[2], c, b);
			g.emplace_back(a, b, c);
		}
		f.swap(g);
	}
	TriMesh m;
	m.V.resize(int(v.size()), 3);
	for (size_t i = 0; i < v.size(); ++i)
		m.V.row(int(i)) = v[i].transpose();
	m.F.resize(int(f.size()), 3);
	for (size_t i = 0; i < f.size(); ++i)
		m.F.row(int(i)) = f[i].transpose();
	return m;
}

/// Largest face sagitta max_f (r - d_f), d_f = distance from the centre to the face plane: no point of the sphere
/// is farther than this from the inscribed polyhedron (it bounds the air gap of the exact fit from above).
double maxSagitta(const TriMesh& m, double r)
{
	double s = 0.0;
	for (int f = 0; f < m.F.rows(); ++f)
	{
		const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
		const double d = std::abs((b - a).cross(c - a).normalized().dot(a));
		s = std::max(s, r - d);
	}
	return s;
}

/// Volume of a closed, consistently oriented mesh (divergence theorem).
double meshVolume(const TriMesh& m)
{
	double v = 0.0;
	for (int f = 0; f < m.F.rows(); ++f)
	{
		const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
		v += a.dot(b.cross(c)) / 6.0;
	}
	return std::abs(v);
}

double bruteDistance(const TriMesh& m, const Eigen::Vector3d& p)
{
	double best = 1e300;
	for (int f = 0; f < m.F.rows(); ++f)
		best = std::min(best, (MeshDistanceGrid::closestPointOnTriangle(p, m.V.row(m.F(f, 0)).transpose(),
																		m.V.row(m.F(f, 1)).transpose(),
																		m.V.row(m.F(f, 2)).transpose()) -
							   p)
								  .norm());
	return best;
}

Ellipsoid sphereEllipsoid(double r)
{
	Ellipsoid e;
	e.radii = Eigen::Vector3d::Constant(r);
	return e;
}

} // namespace

TEST_CASE("fit_quality: grid distance equals brute force", "[fitting][fit_quality]")
{
	const TriMesh m = icosphere(1.0, 3);
	const MeshDistanceGrid grid(m);
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> u(-3.0, 3.0);
	for (int i = 0; i < 400; ++i)
	{
		// Points inside, near and far outside the grid box (|p| up to 5.2, the box is [-1, 1]^3).
		const Eigen::Vector3d p(u(rng), u(rng), u(rng));
		// The grid visits a superset of the triangles that can be closest and evaluates the same closest-point
		// formula, so the answers are the same numbers: 1e-15 allows nothing but a different summation order.
		CHECK(grid.distance(p) == Approx(bruteDistance(m, p)).margin(1e-15));
	}
	// Closest point of a triangle: the three Voronoi region kinds.
	const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
	CHECK((MeshDistanceGrid::closestPointOnTriangle({-1, -1, 2}, a, b, c) - a).norm() == Approx(0.0).margin(1e-15));
	CHECK((MeshDistanceGrid::closestPointOnTriangle({0.5, -1, 2}, a, b, c) - Eigen::Vector3d(0.5, 0, 0)).norm() ==
		  Approx(0.0).margin(1e-15));
	CHECK((MeshDistanceGrid::closestPointOnTriangle({0.2, 0.3, 2}, a, b, c) - Eigen::Vector3d(0.2, 0.3, 0)).norm() ==
		  Approx(0.0).margin(1e-15));
}

TEST_CASE("fit_quality: a sphere mesh fitted by its exact sphere", "[fitting][fit_quality]")
{
	const double r = 1.0;
	const TriMesh m = icosphere(r, 4); // 2562 vertices, 5120 faces
	const double sag = maxSagitta(m, r);
	REQUIRE(sag > 0.0);
	REQUIRE(sag < 0.01); // ~3 mm on a unit sphere at this level: the exact fit is a near-perfect cover

	FitQualityOptions opt;
	opt.sampleSpacing = 0.01; // ~1.3e5 samples: several per face (faces are ~0.06 across)
	const FitQualityReference ref(m, 80);
	const FitQuality q = measureFitQuality(ref, {sphereEllipsoid(r)}, opt);

	// Every vertex is on the sphere (zeta = 1 up to rounding, well within the 1e-9 tolerance): none outside.
	CHECK(q.skinOutsideVertices == 0);
	CHECK(q.skinOutsideMax == 0.0);

	// The inscribed polyhedron lies inside the sphere, so the sphere surface is all air, and no point of it is
	// farther from the polyhedron than the largest sagitta (the ray from the centre through a sphere point x meets
	// its face f at distance >= d_f, so |x - polyhedron| <= r - d_f). The worst point of a face (above its
	// circumcentre) is in a flat maximum, and samples are ~0.01 apart on faces ~0.06 across, so some sample gets
	// within 80% of the bound. Over one face the gap is about s_f (1 - rho^2 / a^2) (rho: distance from the
	// circumcentre, a: circumradius), whose average over an equilateral triangle is 0.75 s_f; faces smaller than
	// the largest one and closest points on neighbouring faces near the edges lower it: [0.4, 0.8] x sag.
	CHECK(q.unionInsideBodyFraction < 1e-3);
	CHECK(q.airGapSamples >= q.exposedSamples * 0.999);
	CHECK(q.airGapMax <= sag + 1e-12);
	CHECK(q.airGapMax >= 0.8 * sag);
	CHECK(q.airGapMean > 0.4 * sag);
	CHECK(q.airGapMean < 0.8 * sag);
	CHECK(q.airGapP95 <= q.airGapMax);
	CHECK(q.airGapP95 >= q.airGapMean);

	// Area weights of the Fibonacci lattice are exact for a sphere (constant): they sum to 4 pi r^2.
	CHECK(q.exposedArea == Approx(4.0 * M_PI * r * r).epsilon(1e-12));
	CHECK(q.exposedSamples == q.totalSamples);

	// IoU of ball vs inscribed polyhedron is V_poly / V_ball in the continuum. The voxel estimate counts lattice
	// points (h = 2/80 = 0.025) in both sets; the two counts differ from the volumes by lattice-point discrepancies
	// of order sqrt(boundary cells) ~ sqrt(4 pi / h^2) ~ 140 points out of ~2.7e5 (5e-4), and both boundaries are
	// within 0.003 of each other, so the errors largely cancel: 0.005 is a safe bound.
	const double expected = meshVolume(m) / (4.0 / 3.0 * M_PI * r * r * r);
	CHECK(q.voxelIoU == Approx(expected).margin(0.005));
	CHECK(q.voxelIoU > 0.98);
	CHECK(q.voxelSize <= 2.0 * r / 80.0 + 1e-12); // longest side of the mesh box (<= the diameter) / 80
}

TEST_CASE("fit_quality: scaled fits, a redundant inner ellipsoid, determinism", "[fitting][fit_quality]")
{
	const double r = 1.0;
	const TriMesh m = icosphere(r, 4);
	const double sag = maxSagitta(m, r);
	FitQualityOptions opt;
	opt.sampleSpacing = 0.02;
	const FitQualityReference ref(m, 64);
	const double polyVolume = meshVolume(m);

	SECTION("10% too large: the gap grows by 0.1, nothing is outside")
	{
		const FitQuality q = measureFitQuality(ref, {sphereEllipsoid(1.1 * r)}, opt);
		// Every point of the big sphere is 0.1 from the unit sphere and at most sag farther from the polyhedron.
		CHECK(q.skinOutsideVertices == 0);
		CHECK(q.airGapMean >= 0.1 - 1e-12);
		CHECK(q.airGapMax <= 0.1 + sag + 1e-12);
		CHECK(q.unionInsideBodyFraction == 0.0);
		// IoU = V_poly / V_big; lattice error as in the exact case (h = 2/64), 0.005.
		CHECK(q.voxelIoU == Approx(polyVolume / (4.0 / 3.0 * M_PI * std::pow(1.1 * r, 3))).margin(0.005));
	}

	SECTION("10% too small: all skin is outside, by exactly 0.1")
	{
		const FitQuality q = measureFitQuality(ref, {sphereEllipsoid(0.9 * r)}, opt);
		CHECK(q.skinOutsideVertices == m.V.rows());
		CHECK(q.skinOutsideFraction == 1.0);
		// Vertices are at radius 1 (to ~1e-16): distance to the 0.9 sphere is 0.1; 1e-12 covers Eberly's solve.
		CHECK(q.skinOutsideMax == Approx(0.1).margin(1e-12));
		CHECK(q.skinOutsideMean == Approx(0.1).margin(1e-12));
		// The 0.9 sphere lies inside the polyhedron (its inradius is >= 1 - sag > 0.99): no air at all.
		CHECK(q.unionInsideBodyFraction == 1.0);
		CHECK(q.airGapSamples == 0);
		CHECK(q.voxelIoU == Approx(std::pow(0.9, 3) * (4.0 / 3.0 * M_PI) / polyVolume).margin(0.005));
	}

	SECTION("an ellipsoid inside another changes no metric")
	{
		Ellipsoid inner;
		inner.center = Eigen::Vector3d(0.2, -0.1, 0.05);
		inner.radii = Eigen::Vector3d(0.5, 0.3, 0.2);
		inner.rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
		const FitQuality one = measureFitQuality(ref, {sphereEllipsoid(r)}, opt);
		const FitQuality two = measureFitQuality(ref, {inner, sphereEllipsoid(r)}, opt);
		// The inner ellipsoid's samples are all covered by the sphere and its voxels are already in the union: the
		// statistics are computed from the very same samples and voxels, hence equal exactly.
		CHECK(two.totalSamples > one.totalSamples);
		CHECK(two.exposedSamples == one.exposedSamples);
		CHECK(two.airGapMean == one.airGapMean);
		CHECK(two.airGapP95 == one.airGapP95);
		CHECK(two.airGapMax == one.airGapMax);
		CHECK(two.voxelIoU == one.voxelIoU);
		CHECK(two.skinOutsideVertices == one.skinOutsideVertices);
	}

	SECTION("two half-overlapping spheres: the covered caps are not sampled")
	{
		// Spheres of radius 1 at x = +-0.5 overlap in a lens; each loses the cap inside the other, of area
		// 2 pi r h with h = 1 - 0.5 = 0.5: the exposed area is 2 (4 pi - pi) = 6 pi. The Fibonacci quadrature of the
		// cap's indicator is accurate to about the spacing times the rim length over the area (0.02 * 2 pi *
		// 0.87 / 6 pi ~ 0.6%): 1%.
		Ellipsoid a = sphereEllipsoid(r), b = sphereEllipsoid(r);
		a.center.x() = -0.5;
		b.center.x() = 0.5;
		const FitQuality q = measureFitQuality(ref, {a, b}, opt);
		CHECK(q.exposedArea == Approx(6.0 * M_PI).epsilon(0.01));
		CHECK(q.exposedSamples < q.totalSamples);
	}

	SECTION("deterministic")
	{
		const FitQuality a = measureFitQuality(ref, {sphereEllipsoid(1.05 * r)}, opt);
		const FitQuality b = measureFitQuality(m, {sphereEllipsoid(1.05 * r)}, opt, 64);
		CHECK(a.airGapMean == b.airGapMean);
		CHECK(a.airGapP95 == b.airGapP95);
		CHECK(a.airGapMax == b.airGapMax);
		CHECK(a.voxelIoU == b.voxelIoU);
		CHECK(a.exposedArea == b.exposedArea);
	}
}

TEST_CASE("fit_quality: rotated ellipsoid tessellation fitted by its exact ellipsoid", "[fitting][fit_quality]")
{
	const Eigen::Vector3d radii(0.12, 0.4, 0.08); // limb-like proportions (5:1)
	Ellipsoid e;
	e.radii = radii;
	e.rotation = Eigen::AngleAxisd(0.5, Eigen::Vector3d(0.3, 0.2, 1.0).normalized()).toRotationMatrix();
	e.center = Eigen::Vector3d(0.3, 1.1, -0.2);
	// Tessellate in the principal frame (vertices exactly on the surface), then move to the world pose.
	TriMesh m = bodyfit_test::starShape([&](const Eigen::Vector3d& d) { return 1.0 / d.cwiseQuotient(radii).norm(); },
										96, 64);
	for (int i = 0; i < m.V.rows(); ++i)
		m.V.row(i) = e.toWorld(m.V.row(i).transpose()).transpose();

	FitQualityOptions opt;
	opt.sampleSpacing = 0.003;
	const FitQualityReference ref(m, 100);
	const FitQuality q = measureFitQuality(ref, {e}, opt);
	// Vertices on the surface to rounding (zeta within ~1e-15 of 1, tolerance 1e-9).
	CHECK(q.skinOutsideVertices == 0);
	// The area-weighted quadrature of the ellipsoid's area agrees with Knud Thomsen's formula within its own
	// worst-case error (1.1%) plus the quadrature's (well below 0.1% at this density): 1.2%.
	CHECK(q.exposedArea == Approx(ellipsoidSurfaceArea(e)).epsilon(0.012));
	// The gap is the tessellation error. Its largest value is at the poles of the long axis: the first ring of the
	// radial 96 x 64 grid lies ~2 cm from the pole, where the surface's radius of curvature is only
	// r_z^2 / r_y = 16 mm, a sagitta of L^2 / (8 rho) ~ 3 mm. Cross-check against an independent estimate: the
	// largest brute-force distance (every triangle) of 4000 random surface points. Both sample the same continuous
	// function near its flat maximum; random points are sparser, so the lattice's max may be a little higher:
	// within [0.9, 1.25] of the brute-force max. The mean is far below the max (the error is concentrated at the
	// poles): < 0.25 of it.
	std::mt19937 rng(3);
	std::normal_distribution<double> gauss;
	double bruteMax = 0.0;
	for (int i = 0; i < 4000; ++i)
	{
		const Eigen::Vector3d u = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
		bruteMax = std::max(bruteMax, bruteDistance(m, e.toWorld(u.cwiseProduct(radii))));
	}
	CHECK(q.airGapMax < 5e-3);
	CHECK(q.airGapMax >= 0.9 * bruteMax);
	CHECK(q.airGapMax <= 1.25 * bruteMax);
	CHECK(q.airGapMean < 0.25 * q.airGapMax);
	// IoU vs the exact volume ratio; h = 0.8 / 100 and the thinnest axis is 20 voxels across: lattice error ~1%.
	const double ellVolume = 4.0 / 3.0 * M_PI * radii.prod();
	CHECK(q.voxelIoU == Approx(meshVolume(m) / ellVolume).margin(0.015));
}

TEST_CASE("fit_quality: bad input is rejected with a one-line reason", "[fitting][fit_quality]")
{
	const TriMesh m = icosphere(1.0, 1);
	const FitQualityReference ref(m, 16);
	CHECK_THROWS_AS(measureFitQuality(ref, {}), InvalidInputError);
	Ellipsoid bad;
	bad.radii = Eigen::Vector3d(1.0, 0.0, 1.0);
	CHECK_THROWS_WITH(measureFitQuality(ref, {sphereEllipsoid(1.0), bad}), Catch::Contains("ellipsoid 1"));
	FitQualityOptions opt;
	opt.sampleSpacing = 0.0;
	CHECK_THROWS_AS(measureFitQuality(ref, {sphereEllipsoid(1.0)}, opt), InvalidInputError);
	CHECK_THROWS_AS(FitQualityReference(m, -1), InvalidInputError);
	CHECK_THROWS_AS(FitQualityReference(TriMesh{}), InvalidInputError);
}

TEST_CASE("fit_quality: skin between two ellipsoids is found on the surface, not at the vertices", "[fitting][fit_quality]")
{
	// One triangle whose corners are all inside the union of two unit spheres centred at (+-0.9, 0, 0), while the
	// middle of its top edge, (0, 0.99, 0), is outside both: the sliver the vertex test cannot see.
	TriMesh m;
	m.V.resize(3, 3);
	m.V << -0.9, 0.99, 0.0, 0.9, 0.99, 0.0, 0.0, -0.2, 0.0;
	m.F.resize(1, 3);
	m.F << 0, 1, 2;
	Ellipsoid left, right;
	left.center = Eigen::Vector3d(-0.9, 0.0, 0.0);
	right.center = Eigen::Vector3d(0.9, 0.0, 0.0);
	FitQualityOptions opt;
	opt.computeAirGap = false;
	opt.computeIoU = false;
	opt.skinSurfaceSpacing = 0.1; // 18 pieces on the 1.8 m top edge: its midpoint is a sample
	const FitQuality q = measureFitQuality(FitQualityReference(m, 0), {left, right}, opt);
	CHECK(q.skinOutsideVertices == 0);
	CHECK(q.skinSurfaceSamples == 19 * 20 / 2); // (level + 1)(level + 2) / 2 grid points, level 18
	CHECK(q.skinSurfaceOutside > 0);
	CHECK(q.skinSurfaceOutside < q.skinSurfaceSamples);
	// The farthest point of the edge from both spheres is its midpoint: sqrt(0.9^2 + 0.99^2) - 1 from each centre's
	// sphere; 1e-12 covers Eberly's solve on a sphere.
	CHECK(q.skinSurfaceOutsideMax == Approx(std::sqrt(0.81 + 0.9801) - 1.0).margin(1e-12));
	CHECK(q.skinSurfaceOutsideFraction == Approx(double(q.skinSurfaceOutside) / double(q.skinSurfaceSamples)));

	opt.skinSurfaceSpacing = 0.0; // switched off: vertices only
	const FitQuality off = measureFitQuality(FitQualityReference(m, 0), {left, right}, opt);
	CHECK(off.skinSurfaceSamples == 0);
	CHECK(off.skinSurfaceOutsideMax == 0.0);
}
