// libFuzzer target: the in-memory repair (bodyfit::repairMesh: weld, degenerate faces, unreferenced vertices,
// components: body, attached, inside, detached) on meshes decoded from the bytes, followed by the MVEE of the repaired vertices. Layout: byte 0 = vertex
// count (1..64), byte 1 = face count (0..64), byte 2 = coordinate mode; then vertices and faces. Modes mix raw doubles
// (NaN, Inf, denormals, 1e300) with small integers on a grid (exact duplicates, collinear and coplanar sets).
// Any input must be repaired into a usable mesh or raise InvalidInputError, and the MVEE of a usable mesh must be
// finite and enclose every vertex.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/mvee.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

namespace
{
struct Reader
{
	const std::uint8_t* p;
	std::size_t n;
	std::uint8_t byte()
	{
		if (n == 0)
			return 0;
		--n;
		return *p++;
	}
	double raw()
	{
		std::uint64_t bits = 0;
		for (int i = 0; i < 8; ++i)
			bits = (bits << 8) | byte();
		double d;
		std::memcpy(&d, &bits, sizeof d);
		return d;
	}
};
} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
	Reader r{data, size};
	const int nv = 1 + r.byte() % 64;
	const int nf = r.byte() % 65;
	const int mode = r.byte() % 4;
	bodyfit::TriMesh m;
	m.V.resize(nv, 3);
	for (int i = 0; i < nv; ++i)
		for (int k = 0; k < 3; ++k)
		{
			if (mode == 0 || (mode == 3 && (r.byte() & 1)))
				m.V(i, k) = r.raw();
			else if (mode == 1)
				m.V(i, k) = double(int(r.byte() % 8)) * 0.1; // grid: duplicates and flat sets
			else
				m.V(i, k) = double(std::int8_t(r.byte())) * std::ldexp(1.0, int(r.byte() % 64) - 32); // wide scales
		}
	m.F.resize(nf, 3);
	for (int f = 0; f < nf; ++f)
		for (int k = 0; k < 3; ++k)
			m.F(f, k) = int(std::int8_t(r.byte())); // negative and out-of-range indices included
	bodyfit::LoadOptions options;
	options.up = (r.byte() & 1) ? bodyfit::UpAxis::Z : bodyfit::UpAxis::Y;
	try
	{
		const bodyfit::LoadedMesh repaired = bodyfit::repairMesh(m, options, "fuzz");
		// Components (components.h): the fitted mesh is the full one minus the detached components' vertices.
		if (repaired.mesh.vertexCount() != repaired.full.vertexCount() - repaired.report.droppedComponentVertices ||
			repaired.report.components < 1)
			std::abort();
		const bodyfit::EllipsoidFit fit = bodyfit::minimumVolumeEllipsoid(repaired.full.V);
		const bodyfit::Ellipsoid& e = fit.ellipsoid;
		if (!e.center.allFinite() || !e.radii.allFinite() || !e.rotation.allFinite())
			std::abort();
		// Enclosing, with the rounding floor for coordinates far from the ellipsoid's size (see test_robust_mvee).
		const double eps = 2.220446049250313e-16;
		for (int i = 0; i < repaired.full.vertexCount(); ++i)
		{
			const Eigen::Vector3d p = repaired.full.V.row(i).transpose();
			const double tol = 1e-9 + 16 * eps * (p.norm() + e.center.norm()) / e.radii.minCoeff();
			if (!(e.zeta(p) <= 1 + tol))
				std::abort();
		}
	}
	catch (const bodyfit::InvalidInputError&)
	{
	}
	return 0;
}
