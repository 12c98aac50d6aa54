// Suite `mvee`: minimum-volume enclosing ellipsoid speed and accuracy on several point distributions.
// For each distribution and size: median time of minimumVolumeEllipsoid (default options), Khachiyan iterations,
// active-set and core-set sizes, the volume relative to a long-run reference (same solver at tolerance 1e-7), the
// largest zeta over all points after the final rescale (must be <= 1 + 1e-9), and the time of a warm start from the
// run's own core set.
#include "bench/bench_common.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/mvee.h"

#include <Eigen/Geometry>

#include <random>

namespace
{

using bodyfit::Ellipsoid;

Eigen::Matrix3d fixedRotation()
{
	return (Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()) *
	        Eigen::AngleAxisd(-0.4, Eigen::Vector3d::UnitY()))
		.toRotationMatrix();
}

Eigen::MatrixX3d box(int n, std::mt19937& rng)
{
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
		P.row(i) = (fixedRotation() * Eigen::Vector3d(0.3 * u(rng), 0.2 * u(rng), 0.1 * u(rng))).transpose();
	return P;
}

Eigen::MatrixX3d gaussian(int n, std::mt19937& rng)
{
	std::normal_distribution<double> g(0.0, 1.0);
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
		P.row(i) = (fixedRotation() * Eigen::Vector3d(0.2 * g(rng), 0.1 * g(rng), 0.05 * g(rng))).transpose();
	return P;
}

/// Exactly on the surface of the ellipsoid with radii (0.3, 0.12, 0.05): every point is (nearly) active.
Eigen::MatrixX3d surface(int n, std::mt19937& rng)
{
	std::normal_distribution<double> g(0.0, 1.0);
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
	{
		const Eigen::Vector3d u = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
		P.row(i) = (fixedRotation() * u.cwiseProduct(Eigen::Vector3d(0.3, 0.12, 0.05))).transpose();
	}
	return P;
}

/// Area-uniform samples on the right leg of the bundled body (triangles with every vertex in 0.12 < y < 0.80 m, x > 0).
Eigen::MatrixX3d limb(int n, std::mt19937& rng)
{
	static const bodyfit::TriMesh mesh = bodyfit::loadTriMesh(std::string(BODYFIT_ASSET_DIR) + "/male_young.obj").mesh;
	std::vector<Eigen::Vector3i> tris;
	std::vector<double> cumulative;
	double area = 0.0;
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		bool in = true;
		for (int k = 0; k < 3; ++k)
		{
			const Eigen::Vector3d v = mesh.V.row(mesh.F(f, k)).transpose();
			in = in && v.y() > 0.12 && v.y() < 0.80 && v.x() > 0.0;
		}
		if (!in)
			continue;
		const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
		area += 0.5 * (b - a).cross(c - a).norm();
		tris.push_back(mesh.F.row(f).transpose());
		cumulative.push_back(area);
	}
	if (tris.empty())
		throw bodyfit::InvalidInputError("bench mvee: no leg triangles found in male_young.obj");
	std::uniform_real_distribution<double> u(0.0, 1.0);
	Eigen::MatrixX3d P(n, 3);
	for (int i = 0; i < n; ++i)
	{
		const size_t t = size_t(std::lower_bound(cumulative.begin(), cumulative.end(), u(rng) * area) - cumulative.begin());
		const Eigen::Vector3i& f = tris[std::min(t, tris.size() - 1)];
		double s = u(rng), r = u(rng);
		if (s + r > 1.0)
		{
			s = 1.0 - s;
			r = 1.0 - r;
		}
		P.row(i) = (1.0 - s - r) * mesh.V.row(f[0]) + s * mesh.V.row(f[1]) + r * mesh.V.row(f[2]);
	}
	return P;
}

/// The box distribution 1 km from the origin: enclosure must still hold to 1e-9.
Eigen::MatrixX3d boxFar(int n, std::mt19937& rng)
{
	return box(n, rng).rowwise() + Eigen::RowVector3d(1000.0, 20.0, -700.0);
}

double maxZeta(const Ellipsoid& e, const Eigen::MatrixX3d& P)
{
	double z = 0.0;
	for (int i = 0; i < P.rows(); ++i)
		z = std::max(z, e.zeta(P.row(i).transpose()));
	return z;
}

} // namespace

BODYFIT_BENCH_SUITE(mvee, "minimum-volume enclosing ellipsoid: time, iterations, active set, volume vs reference")
{
	struct Distribution
	{
		const char* name;
		Eigen::MatrixX3d (*make)(int, std::mt19937&);
	};
	const Distribution dists[] = {
		{"box", box}, {"gaussian", gaussian}, {"surface", surface}, {"limb", limb}, {"box@1km", boxFar}};
	bodyfit::MveeOptions reference;
	reference.tolerance = 1e-7;
	reference.maxIterations = 50'000'000;

	bodyfit_bench::Table t({"distribution", "n", "median ms", "iterations", "active set", "core", "status",
	                        "volume / ref", "max zeta - 1", "warm ms", "warm iterations", "ref iterations", "ref ms"});
	bool enclosureOk = true;
	for (const Distribution& d : dists)
		for (int n : {500, 2000, 10000})
		{
			std::mt19937 rng(1234u + unsigned(n));
			const Eigen::MatrixX3d P = d.make(n, rng);
			bodyfit::EllipsoidFit fit;
			const double ms = bodyfit_bench::medianMs(ctx.repeats, [&] { fit = bodyfit::minimumVolumeEllipsoid(P); });
			bodyfit::EllipsoidFit ref;
			const double refMs = bodyfit_bench::medianMs(1, [&] { ref = bodyfit::minimumVolumeEllipsoid(P, reference); });
			// Warm start from the cold run's core set (what a refit after a small change would pass).
			bodyfit::EllipsoidFit warm;
			const double warmMs = bodyfit_bench::medianMs(
				ctx.repeats, [&] { warm = bodyfit::minimumVolumeEllipsoid(P, {}, fit.coreIndices); });
			const double z = std::max(maxZeta(fit.ellipsoid, P), maxZeta(warm.ellipsoid, P));
			enclosureOk = enclosureOk && z <= 1.0 + 1e-9;
			t.addRow({d.name, bodyfit_bench::fmtInt(n), bodyfit_bench::fmt(ms, 3), bodyfit_bench::fmtInt(fit.iterations),
			          bodyfit_bench::fmtInt(fit.activeSetSize), bodyfit_bench::fmtInt(long(fit.coreIndices.size())),
			          bodyfit::toString(fit.status),
			          bodyfit_bench::fmt(fit.ellipsoid.volume() / ref.ellipsoid.volume(), 5),
			          bodyfit_bench::fmt(z - 1.0, 2), bodyfit_bench::fmt(warmMs, 3),
			          bodyfit_bench::fmtInt(warm.iterations), bodyfit_bench::fmtInt(ref.iterations),
			          bodyfit_bench::fmt(refMs, 2)});
		}
	const int rc = bodyfit_bench::emit(ctx, "mvee", t);
	std::cout << "\nenclosure (every point zeta <= 1 + 1e-9): " << (enclosureOk ? "yes" : "NO") << "\n\n";

	// Tolerance sweep: what the optimality gap costs and buys (volume excess over the reference).
	bodyfit_bench::Table sweep({"distribution", "n", "tolerance", "median ms", "iterations", "volume / ref"});
	for (const Distribution& d : {dists[0], dists[3]})
	{
		const int n = 10000;
		std::mt19937 rng(1234u + unsigned(n));
		const Eigen::MatrixX3d P = d.make(n, rng);
		const double refVolume = bodyfit::minimumVolumeEllipsoid(P, reference).ellipsoid.volume();
		for (double tol : {1e-2, 1e-3, 1e-4, 1e-5})
		{
			bodyfit::MveeOptions o;
			o.tolerance = tol;
			bodyfit::EllipsoidFit fit;
			const double ms = bodyfit_bench::medianMs(ctx.repeats, [&] { fit = bodyfit::minimumVolumeEllipsoid(P, o); });
			enclosureOk = enclosureOk && maxZeta(fit.ellipsoid, P) <= 1.0 + 1e-9;
			sweep.addRow({d.name, bodyfit_bench::fmtInt(n), bodyfit_bench::fmtGeneral(tol), bodyfit_bench::fmt(ms, 3),
			              bodyfit_bench::fmtInt(fit.iterations),
			              bodyfit_bench::fmt(fit.ellipsoid.volume() / refVolume, 5)});
		}
	}
	bodyfit_bench::emit(ctx, "mvee_tolerance", sweep);
	return enclosureOk ? rc : 1;
}
