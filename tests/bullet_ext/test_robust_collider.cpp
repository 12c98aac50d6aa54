// Randomised property tests of the cloth collider's per-node response (issue 7, item 1).
//
// For random node paths q -> x against random sets of 1-8 ellipsoids (general, nested, touching, intersecting
// chains, 1000:1 thin, tiny 1e-4 m, huge 1e3 m, and any of them 1 km from the origin), one node at a time through
// the public btEllipsoidClothCollider::collide (a one-node btSoftBody, the collider installed in a
// btEllipsoidClothWorld on a static btCollisionObject), the result must be
//   1. finite (position and velocity);
//   2. outside every ellipsoid: zeta >= 1 - 1e-6, zeta evaluated in long double from the compound's analytic data
//      (centre, orthonormal basis, semi-axes), not from the collider's own whitened cache;
//   3. no farther from the start than the path plus what the push-out needs:
//        untouched node            -> exactly x (bit for bit);
//        entry on the path         -> |result - q| <= |x - q| + skin (+ rounding);
//        start inside / repaired   -> |result - x| <= sum over ellipsoids of (2 max semi-axis + 2 skin) (+ rounding),
//      since the push-out ray crosses each ellipsoid's skin-widened chord at most once.
// Fixed seeds. Default: 100,000 node paths (BODYFIT_PROPERTY_CASES overrides the count); the hidden test
// "[.slow]" runs 10,000,000. The same file runs in the float and the float64 Bullet builds.
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "src/btEllipsoidClothColliderCore.h" // drives collide() on crafted node paths
#include "bullet_ext/cloth_test_scene.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

namespace
{

typedef long double Real;

/// splitmix64: a fixed, platform-independent stream (std:: distributions differ between standard libraries).
struct Rng
{
	std::uint64_t s;
	explicit Rng(std::uint64_t seed) : s(seed) {}
	std::uint64_t next()
	{
		std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
		z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
		z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
		return z ^ (z >> 31);
	}
	double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); } // [0, 1)
	double uniform(double a, double b) { return a + (b - a) * uniform(); }
	int index(int n) { return int(next() % std::uint64_t(n)); }
	/// log-uniform in [a, b], a > 0
	double logUniform(double a, double b) { return a * std::pow(b / a, uniform()); }
	btVector3 unit()
	{
		for (;;)
		{
			const double x = uniform(-1, 1), y = uniform(-1, 1), z = uniform(-1, 1);
			const double l2 = x * x + y * y + z * z;
			if (l2 > 1e-4 && l2 <= 1.0)
			{
				const double l = std::sqrt(l2);
				return btVector3(btScalar(x / l), btScalar(y / l), btScalar(z / l));
			}
		}
	}
	btMatrix3x3 rotation()
	{
		const btVector3 axis = unit();
		return btMatrix3x3(btQuaternion(axis, btScalar(uniform(0.0, 6.283185307179586))));
	}
};

struct SetSpec
{
	struct E
	{
		btVector3 c;
		btMatrix3x3 R;
		btVector3 a;
	};
	std::vector<E> e;
	const char* kind = "";
	bool thin = false;     ///< 1000:1 ellipsoids (see the float limitation in runSet)
	bool tinyFar = false;  ///< 1e-4 m ellipsoids 1 km from the origin: float spacing there (6e-5 m) ~ their size
};

enum SetKind
{
	kGeneral,
	kNested,
	kTouching,
	kChain,
	kThin,
	kTiny,
	kHuge,
	kNumKinds
};

const char* kindName(int k)
{
	static const char* names[] = {"general", "nested", "touching", "chain", "thin-1000:1", "tiny-1e-4m", "huge-1e3m"};
	return names[k];
}

/// A random ellipsoid set of 1-8 ellipsoids of the given kind, scaled by `scale`, shifted by `offset`.
SetSpec makeSet(Rng& rng, int kind, const btVector3& offset)
{
	SetSpec s;
	s.kind = kindName(kind);
	s.thin = kind == kThin;
	s.tinyFar = kind == kTiny && offset.length2() > btScalar(0);
	const int n = 1 + rng.index(8);
	double scale = 0.3;
	if (kind == kTiny)
		scale = 1e-4;
	else if (kind == kHuge)
		scale = 1e3;
	auto add = [&](const btVector3& c, const btMatrix3x3& R, const btVector3& a) {
		SetSpec::E e;
		e.c = c + offset;
		e.R = R;
		e.a = a;
		s.e.push_back(e);
	};
	auto randomAxes = [&](double lo, double hi) {
		return btVector3(btScalar(rng.logUniform(lo, hi)), btScalar(rng.logUniform(lo, hi)),
						 btScalar(rng.logUniform(lo, hi)));
	};
	auto randomPoint = [&](double half) {
		return btVector3(btScalar(rng.uniform(-half, half)), btScalar(rng.uniform(-half, half)),
						 btScalar(rng.uniform(-half, half)));
	};
	switch (kind)
	{
		case kNested:
		{
			// A chain of ellipsoids each strictly inside the previous one (same or shifted centre).
			btVector3 c = randomPoint(0.1);
			btVector3 a = randomAxes(0.1, 0.4);
			btMatrix3x3 R = rng.rotation();
			add(c, R, a);
			for (int i = 1; i < n; ++i)
			{
				// Inner sphere of radius f * min(a) centred within (1 - f) * min(a) of c: inside the outer ellipsoid.
				const btScalar amin = btMin(a.x(), btMin(a.y(), a.z()));
				const btScalar f = btScalar(rng.uniform(0.3, 0.9));
				const btVector3 shift = rng.unit() * (amin * (btScalar(1) - f) * btScalar(rng.uniform(0.0, 0.99)));
				const btScalar r = amin * f;
				const btVector3 ratios(btScalar(rng.uniform(0.5, 1.0)), btScalar(rng.uniform(0.5, 1.0)),
									   btScalar(rng.uniform(0.5, 1.0)));
				c = c + shift;
				a = ratios * r;
				R = rng.rotation();
				add(c, R, a);
			}
			break;
		}
		case kTouching:
		{
			// Spheres and ellipsoids that touch a first ellipsoid at one point: the second sits on the first's
			// outward normal at a surface point, at exactly its own extent along that normal.
			const btVector3 c0 = randomPoint(0.05);
			const btVector3 a0 = randomAxes(0.05, 0.3);
			const btMatrix3x3 R0 = rng.rotation();
			add(c0, R0, a0);
			for (int i = 1; i < n; ++i)
			{
				const btVector3 u = rng.unit(); // direction in the unit ball of ellipsoid 0
				const btVector3 pLocal = u * a0;
				const btVector3 nLocal = (u / a0).normalized();
				const btVector3 p = c0 + R0 * pLocal;
				const btVector3 nrm = R0 * nLocal;
				const btScalar r = btScalar(rng.logUniform(0.01, 0.3));
				if (rng.uniform() < 0.5)
					add(p + nrm * r, btMatrix3x3::getIdentity(), btVector3(r, r, r));
				else
				{
					// Ellipsoid with one principal axis along the normal: its extent along the normal is that axis.
					btVector3 t1 = nrm.cross(btVector3(1, 0, 0));
					if (t1.length2() < btScalar(1e-4))
						t1 = nrm.cross(btVector3(0, 1, 0));
					t1.normalize();
					const btVector3 t2 = nrm.cross(t1);
					btMatrix3x3 R(nrm.x(), t1.x(), t2.x(), nrm.y(), t1.y(), t2.y(), nrm.z(), t1.z(), t2.z());
					const btScalar b = btScalar(rng.logUniform(0.01, 0.3)), c = btScalar(rng.logUniform(0.01, 0.3));
					add(p + nrm * r, R, btVector3(r, b, c));
				}
			}
			break;
		}
		case kChain:
		{
			// Strongly intersecting, body-like: a random walk of elongated ellipsoids overlapping their neighbours.
			btVector3 c = randomPoint(0.1);
			for (int i = 0; i < n; ++i)
			{
				const btVector3 a = randomAxes(0.04, 0.25);
				add(c, rng.rotation(), a);
				c += rng.unit() * btScalar(rng.uniform(0.2, 1.2) * btMin(a.x(), btMin(a.y(), a.z())) * 2);
			}
			break;
		}
		case kThin:
		{
			// 1000:1 plates and needles, crossing each other.
			for (int i = 0; i < n; ++i)
			{
				const btScalar big = btScalar(rng.uniform(0.1, 0.5));
				btVector3 a(big, big, big);
				a[rng.index(3)] = big * btScalar(1e-3);
				if (rng.uniform() < 0.5)
					a[(rng.index(2) + 1) % 3] = big * btScalar(1e-3); // needle (the other thin axis may repeat)
				add(randomPoint(0.2), rng.rotation(), a);
			}
			break;
		}
		default:
		{
			// General (also the tiny and huge kinds, scaled): random centres, axes over one decade, random rotations.
			for (int i = 0; i < n; ++i)
			{
				const btVector3 c = randomPoint(btScalar(scale));
				const btVector3 a = randomAxes(0.1 * scale, scale);
				add(c, rng.rotation(), a);
			}
			break;
		}
	}
	return s;
}

using bodyfit_test::refZeta; // cloth_test_scene.h

/// Largest amount by which p is inside an ellipsoid beyond what btScalar can resolve: max_k (1 - zeta_k(p)) - tol_k,
/// tol_k = 1e-6 + 16 eps |p - c_k| / a_min,k. The second term is the rounding floor of any btScalar evaluation of
/// zeta (the collider's included): the whitened coordinate (p - c) / a carries an error of about eps |p - c| / a_min,
/// and zeta = |u|^2 doubles it near the surface (x 8 for the three components and the two products). It is
/// < 1e-11 in double everywhere here; in float it matters only for the 1000:1 ellipsoids (|p - c| / a_min ~ 1e3).
Real insideExcess(const btEllipsoidCompoundShape& s, const btVector3& p, Real* worstZeta)
{
	Real excess = -INFINITY;
	for (int k = 0; k < s.getNumEllipsoids(); ++k)
	{
		const btEllipsoidLocalData& e = s.getEllipsoid(k);
		const Real z = refZeta(e, p);
		*worstZeta = std::min(*worstZeta, z);
		const Real amin = Real(btMin(e.m_semiAxes.x(), btMin(e.m_semiAxes.y(), e.m_semiAxes.z())));
		const Real d = Real((p - e.m_center).length());
		const Real tol = Real(1e-6) + 16 * Real(SIMD_EPSILON) * d / amin;
		excess = std::max(excess, (1 - z) - tol);
	}
	return excess;
}

Real dist(const btVector3& a, const btVector3& b)
{
	const Real dx = Real(a.x()) - Real(b.x()), dy = Real(a.y()) - Real(b.y()), dz = Real(a.z()) - Real(b.z());
	return std::sqrt(dx * dx + dy * dy + dz * dz);
}

bool finite3(const btVector3& v)
{
	return std::isfinite(double(v.x())) && std::isfinite(double(v.y())) && std::isfinite(double(v.z()));
}

struct Tally
{
	long long cases = 0;
	long long untouched = 0;
	long long corrected = 0;
	long long pushedOut = 0;
	long long repaired = 0;
	long long fallbacks = 0; ///< push-outs that left through the union's box (the collider's safe fallback)
	long long failures = 0;
	long long floatLimit = 0; ///< float build, 1000:1 sets: entry-point failures counted, not asserted (see below)
	Real worstZeta = INFINITY;
	long long byType[4] = {0, 0, 0, 0}; // non-finite / inside / moved too far (entry) / moved too far (push-out)
	std::string firstFailure[4];
};

/// One random node path for a set: q outside (usually) or inside (a bad start), x near q, anywhere, on a surface or
/// at a centre.
void randomPath(Rng& rng, const SetSpec& s, const btVector3& lo, const btVector3& hi, btScalar extent, btVector3& q,
				btVector3& x)
{
	auto inBox = [&]() {
		return btVector3(btScalar(rng.uniform(lo.x(), hi.x())), btScalar(rng.uniform(lo.y(), hi.y())),
						 btScalar(rng.uniform(lo.z(), hi.z())));
	};
	auto onSurface = [&](btScalar inflate) {
		const SetSpec::E& e = s.e[rng.index(int(s.e.size()))];
		return e.c + e.R * (rng.unit() * e.a * inflate);
	};
	const double r = rng.uniform();
	if (r < 0.15)
		q = onSurface(btScalar(rng.uniform(1.0, 1.05)));
	else if (r < 0.2)
		q = onSurface(btScalar(rng.uniform(0.0, 1.0))); // a bad start inside
	else
		q = inBox();
	const double m = rng.uniform();
	if (m < 0.35)
		x = q + rng.unit() * (extent * btScalar(rng.logUniform(1e-4, 0.1))); // a typical short cloth step
	else if (m < 0.6)
		x = inBox();
	else if (m < 0.75)
		x = onSurface(btScalar(rng.uniform(0.99, 1.01)));
	else if (m < 0.85)
		x = s.e[rng.index(int(s.e.size()))].c; // the centre: the gradient vanishes there
	else if (m < 0.9)
		x = q; // no motion
	else
		x = onSurface(btScalar(rng.uniform(0.0, 0.999)));
}

void runSet(Rng& rng, btEllipsoidClothWorld& world, const SetSpec& spec, int paths, Tally& tally)
{
	btEllipsoidCompoundShape shape;
	for (size_t i = 0; i < spec.e.size(); ++i)
		shape.addEllipsoid(spec.e[i].c, spec.e[i].R, spec.e[i].a);
	btCollisionObject body;
	body.setCollisionShape(&shape);
	body.setWorldTransform(btTransform::getIdentity());

	btEllipsoidClothCollider::Config config;
	const btScalar extentGuess = spec.e[0].a.length();
	const double skinPick = rng.uniform();
	// Skin: none (the exact surface is the hardest case), the default 2 mm, or 1% of the set's size.
	config.m_skinOffset = skinPick < 0.3 ? btScalar(0) : (skinPick < 0.6 ? btScalar(0.002) : extentGuess * btScalar(0.01));
	config.m_friction = btScalar(rng.uniform(0.0, 1.0));
	config.m_velocityRule = rng.uniform() < 0.5 ? btEllipsoidClothCollider::REMOVE_NORMAL_COULOMB
												 : btEllipsoidClothCollider::PAPER_EQ10;
	const char* whyNot = 0;
	btEllipsoidClothColliderCore* collider =
		static_cast<btEllipsoidClothColliderCore*>(world.installCollider(&body, config, &whyNot));
	REQUIRE(collider != 0);
	const btScalar dt = btScalar(1.0 / 120.0);
	collider->beginSubstep(dt);

	// Sampling box: the union's AABB grown by half its size (paths start and end around the set).
	btVector3 lo = collider->getWorldCache().getAabbMin(), hi = collider->getWorldCache().getAabbMax();
	const btVector3 grow = (hi - lo) * btScalar(0.5);
	lo -= grow;
	hi += grow;
	const btScalar extent = (hi - lo).length();

	// Push-out budget: the push-out ray leaves the union after crossing each ellipsoid's skin-widened chord at most
	// once (the sweep merges overlapping chords), so it moves at most sum_k (2 max a_k + 2 skin).
	Real pushBudget = 0;
	Real scaleMax = 0;
	for (int k = 0; k < shape.getNumEllipsoids(); ++k)
	{
		const btVector3& a = shape.getEllipsoid(k).m_semiAxes;
		const Real amax = Real(btMax(a.x(), btMax(a.y(), a.z())));
		pushBudget += 2 * amax + 2 * Real(config.m_skinOffset);
		scaleMax = std::max(scaleMax, amax + Real(shape.getEllipsoid(k).m_center.length()));
	}
	// Rounding allowance for distances: positions are btScalar, so a few ulps of the largest coordinate in play,
	// plus the collider's fixed 1e-7 m nudge budget (8 attempts growing x4: < 1e-7 * 4^8 * 4/3 m worst case is far
	// more than it ever needs; we allow 64 ulps of the coordinate magnitude and 1e-6 m).
	const Real ulp = Real(SIMD_EPSILON);

	btVector3 x0(0, 0, 0);
	btScalar mass = 1;
	btSoftBody cloth(&world.getWorldInfo(), 1, &x0, &mass);
	btSoftBody::Node& node = cloth.m_nodes[0];

	for (int p = 0; p < paths; ++p)
	{
		btVector3 q, x;
		randomPath(rng, spec, lo, hi, extent, q, x);
		node.m_x = x;
		node.m_q = q;
		node.m_v = (x - q) / dt;
		node.m_im = 1;
		const btEllipsoidClothStats before = collider->getLastSubstepStats();
		collider->collide(&cloth, dt, &q);
		const btEllipsoidClothStats& after = collider->getLastSubstepStats();
		const bool corrected = after.m_nodesCorrected > before.m_nodesCorrected;
		const bool pushed = after.m_nodesPushedOut > before.m_nodesPushedOut;
		const bool repaired = after.m_nodesRepaired > before.m_nodesRepaired;
		const btVector3 result = node.m_x;

		++tally.cases;
		tally.untouched += (!corrected && !pushed) ? 1 : 0;
		tally.corrected += corrected ? 1 : 0;
		tally.pushedOut += pushed ? 1 : 0;
		tally.repaired += repaired ? 1 : 0;
		tally.fallbacks += after.m_pushOutFallbacks - before.m_pushOutFallbacks;

		const Real coordMag = std::max(Real(std::max(q.length(), x.length())), scaleMax);
		const Real tol = 64 * ulp * coordMag + Real(1e-6);
		Real z = INFINITY;
		const Real excess = insideExcess(shape, result, &z);
		tally.worstZeta = std::min(tally.worstZeta, z);
		const Real skin = Real(config.m_skinOffset);
		std::string problem;
		int type = -1;
		if (!finite3(result) || !finite3(node.m_v))
			problem = "non-finite result", type = 0;
		else if (excess > 0)
			problem = "inside (zeta " + std::to_string(double(z)) + ")", type = 1;
		else if (!corrected && !pushed && !(result == x))
			problem = "untouched node moved", type = 2;
		else if (corrected && !repaired && !pushed && dist(result, q) > dist(x, q) + skin + tol)
			problem = "entry farther than path + skin (" + std::to_string(double(dist(result, q))) + " > " +
					  std::to_string(double(dist(x, q) + skin)) + ")", type = 2;
		else if (pushed && dist(result, x) > pushBudget + tol)
			problem = "push-out farther than the union allows (" + std::to_string(double(dist(result, x))) + " > " +
					  std::to_string(double(pushBudget)) + ")", type = 3;
		else if (repaired && !pushed && dist(result, q) > dist(x, q) + skin + pushBudget + tol)
			problem = "repaired entry farther than path + skin + push-out (" + std::to_string(double(dist(result, q))) +
					  " > " + std::to_string(double(dist(x, q) + skin + pushBudget)) + ")", type = 3;
		// Known float limitation (documented in docs/ROBUSTNESS.md): for a path grazing a 1000:1 ellipsoid from far
		// away, the whitened start u_q has |u_q| ~ 1e3-1e4, the entry quadratic loses all digits in float
		// (b^2 - a c cancels at |u_q|^4 ~ 1e14), and the collider's entry point can land off the path; its final
		// check only looks at ellipsoids under the path box, so the misplaced node can stay inside a neighbour.
		// Likewise 1e-4 m ellipsoids 1 km away: float positions there are 6e-5 m apart, the size of the ellipsoid.
		// In the float64 build every case is asserted.
		if (type >= 1 && (spec.thin || spec.tinyFar) && sizeof(btScalar) == 4)
		{
			++tally.floatLimit;
			type = -1;
		}
		if (type >= 0)
		{
			++tally.failures;
			++tally.byType[type];
			if (tally.firstFailure[type].empty())
			{
				char buf[512];
				std::snprintf(buf, sizeof(buf),
							  "%s set (%d ellipsoids), skin %g: q (%.9g %.9g %.9g) x (%.9g %.9g %.9g) -> (%.9g %.9g %.9g)",
							  spec.kind, int(spec.e.size()), double(config.m_skinOffset), double(q.x()), double(q.y()),
							  double(q.z()), double(x.x()), double(x.y()), double(x.z()), double(result.x()),
							  double(result.y()), double(result.z()));
				tally.firstFailure[type] = problem + ": " + buf;
				std::snprintf(buf, sizeof(buf), " [entry %d, start-inside %d, repaired %d]", int(corrected), int(pushed),
							  int(repaired));
				tally.firstFailure[type] += buf;
				if (std::getenv("BODYFIT_ROBUST_VERBOSE"))
				{
					// Exact inputs (hexadecimal floats) for a regression test: addEllipsoid arguments, q, x.
					std::snprintf(buf, sizeof(buf), "\n  exact: q {%a, %a, %a} x {%a, %a, %a}", double(q.x()),
								  double(q.y()), double(q.z()), double(x.x()), double(x.y()), double(x.z()));
					tally.firstFailure[type] += buf;
					for (size_t k = 0; k < spec.e.size(); ++k)
					{
						const SetSpec::E& e = spec.e[k];
						std::snprintf(buf, sizeof(buf),
									  "\n  exact e%d: c {%a, %a, %a} a {%a, %a, %a} R {%a, %a, %a, %a, %a, %a, %a, %a, %a}",
									  int(k), double(e.c.x()), double(e.c.y()), double(e.c.z()), double(e.a.x()),
									  double(e.a.y()), double(e.a.z()), double(e.R[0][0]), double(e.R[0][1]),
									  double(e.R[0][2]), double(e.R[1][0]), double(e.R[1][1]), double(e.R[1][2]),
									  double(e.R[2][0]), double(e.R[2][1]), double(e.R[2][2]));
						tally.firstFailure[type] += buf;
					}
				}
				if (std::getenv("BODYFIT_ROBUST_VERBOSE"))
					for (int k = 0; k < shape.getNumEllipsoids(); ++k)
					{
						const btEllipsoidLocalData& e = shape.getEllipsoid(k);
						std::snprintf(buf, sizeof(buf),
									  "\n  e%d c (%.9g %.9g %.9g) a (%.9g %.9g %.9g) zeta(result) %.9g zeta(x) %.9g zeta(q) %.9g",
									  k, double(e.m_center.x()), double(e.m_center.y()), double(e.m_center.z()),
									  double(e.m_semiAxes.x()), double(e.m_semiAxes.y()), double(e.m_semiAxes.z()),
									  double(refZeta(e, result)), double(refZeta(e, x)), double(refZeta(e, q)));
						tally.firstFailure[type] += buf;
						std::snprintf(buf, sizeof(buf), " R [%.9g %.9g %.9g; %.9g %.9g %.9g; %.9g %.9g %.9g]",
									  double(e.m_basis[0][0]), double(e.m_basis[0][1]), double(e.m_basis[0][2]),
									  double(e.m_basis[1][0]), double(e.m_basis[1][1]), double(e.m_basis[1][2]),
									  double(e.m_basis[2][0]), double(e.m_basis[2][1]), double(e.m_basis[2][2]));
						tally.firstFailure[type] += buf;
					}
			}
		}
	}
	world.getSoftBodySolver()->uninstallCollider(collider);
}

long long casesFromEnvironment(long long fallback)
{
	const char* v = std::getenv("BODYFIT_PROPERTY_CASES");
	if (!v || !*v)
		return fallback;
	const long long n = std::atoll(v);
	return n > 0 ? n : fallback;
}

void runProperty(long long totalCases, std::uint64_t seed)
{
	Rng rng(seed);
	btEllipsoidClothWorld world;
	const int pathsPerSet = 100;
	Tally perKind[kNumKinds * 2];
	long long done = 0;
	long long set = 0;
	while (done < totalCases)
	{
		const int kind = int(set % kNumKinds);
		// Every other round of kinds is moved 1 km from the origin in a random direction.
		const bool far = (set / kNumKinds) % 2 == 1;
		const btVector3 offset = far ? rng.unit() * btScalar(1000) : btVector3(0, 0, 0);
		const SetSpec spec = makeSet(rng, kind, offset);
		const int paths = int(std::min<long long>(pathsPerSet, totalCases - done));
		runSet(rng, world, spec, paths, perKind[kind * 2 + (far ? 1 : 0)]);
		done += paths;
		++set;
	}
	long long failures = 0;
	for (int k = 0; k < kNumKinds * 2; ++k)
	{
		const Tally& t = perKind[k];
		if (t.cases == 0)
			continue;
		char line[400];
		std::snprintf(line, sizeof(line),
					  "%-12s %-6s cases %lld: untouched %lld, entry %lld, start-inside %lld, repaired %lld, "
					  "box fallbacks %lld, min zeta %.9f, failures %lld (non-finite %lld, inside %lld, entry too far %lld, push too far %lld)",
					  kindName(k / 2), (k % 2) ? "+1km" : "origin", t.cases, t.untouched, t.corrected, t.pushedOut,
					  t.repaired, t.fallbacks, double(t.worstZeta), t.failures, t.byType[0], t.byType[1], t.byType[2], t.byType[3]);
		UNSCOPED_INFO(line);
		if (t.floatLimit)
			WARN(kindName(k / 2) << ((k % 2) ? " +1km" : " origin") << ": " << t.floatLimit
								  << " paths beyond float precision (known limitation, not asserted in float builds)");
		for (int f = 0; f < 4; ++f)
			if (!t.firstFailure[f].empty())
				UNSCOPED_INFO("first failure: " << t.firstFailure[f]);
		failures += t.failures;
	}
	UNSCOPED_INFO("btScalar is " << (sizeof(btScalar) == 8 ? "double" : "float") << ", total cases " << done);
	CHECK(failures == 0);
}

} // namespace

TEST_CASE("robust: collider response on random paths vs random ellipsoid sets", "[robust][collider][property]")
{
	// 1e5 node paths by default (about a second in Release); BODYFIT_PROPERTY_CASES=10000000 for the long run.
	runProperty(casesFromEnvironment(100000), 0x5EED0001ull);
}

TEST_CASE("robust: collider response, 1e7 paths", "[.slow][robust][collider][property]")
{
	runProperty(casesFromEnvironment(10000000), 0x5EED0002ull);
}

namespace
{

/// One ellipsoid of a regression case, as passed to addEllipsoid (exact float values, hexadecimal).
struct ExactEllipsoid
{
	double c[3];
	double a[3];
	double R[9]; ///< rows
};

/// Runs one node path q -> x (skin 0) through collide() against the given set and checks the property test's
/// assertions: finite, outside every ellipsoid (same tolerance as insideExcess), within the push-out budget.
void runRegressionPath(const ExactEllipsoid* ells, int count, const double* q3, const double* x3)
{
	btEllipsoidCompoundShape shape;
	for (int i = 0; i < count; ++i)
	{
		const ExactEllipsoid& e = ells[i];
		const btMatrix3x3 R(btScalar(e.R[0]), btScalar(e.R[1]), btScalar(e.R[2]), btScalar(e.R[3]), btScalar(e.R[4]),
							btScalar(e.R[5]), btScalar(e.R[6]), btScalar(e.R[7]), btScalar(e.R[8]));
		shape.addEllipsoid(btVector3(btScalar(e.c[0]), btScalar(e.c[1]), btScalar(e.c[2])), R,
						   btVector3(btScalar(e.a[0]), btScalar(e.a[1]), btScalar(e.a[2])));
	}
	btCollisionObject body;
	body.setCollisionShape(&shape);
	body.setWorldTransform(btTransform::getIdentity());
	btEllipsoidClothWorld world;
	btEllipsoidClothCollider::Config config;
	config.m_skinOffset = btScalar(0);
	btEllipsoidClothColliderCore* collider =
		static_cast<btEllipsoidClothColliderCore*>(world.installCollider(&body, config));
	REQUIRE(collider != 0);
	const btScalar dt = btScalar(1.0 / 120.0);
	collider->beginSubstep(dt);

	const btVector3 q = btVector3(btScalar(q3[0]), btScalar(q3[1]), btScalar(q3[2]));
	const btVector3 x = btVector3(btScalar(x3[0]), btScalar(x3[1]), btScalar(x3[2]));
	btVector3 x0(0, 0, 0);
	btScalar mass = 1;
	btSoftBody cloth(&world.getWorldInfo(), 1, &x0, &mass);
	btSoftBody::Node& node = cloth.m_nodes[0];
	node.m_x = x;
	node.m_q = q;
	node.m_v = (x - q) / dt;
	collider->collide(&cloth, dt, &q);
	const btVector3 result = node.m_x;

	Real z = INFINITY;
	const Real excess = insideExcess(shape, result, &z);
	Real pushBudget = 0;
	for (int k = 0; k < shape.getNumEllipsoids(); ++k)
	{
		const btVector3& a = shape.getEllipsoid(k).m_semiAxes;
		pushBudget += 2 * Real(btMax(a.x(), btMax(a.y(), a.z())));
	}
	INFO("result (" << double(result.x()) << ", " << double(result.y()) << ", " << double(result.z()) << "), min zeta "
					<< double(z) << ", pushed " << collider->getLastSubstepStats().m_nodesPushedOut << ", moved "
					<< double(dist(result, x)) << " of budget " << double(pushBudget));
	CHECK(finite3(result));
	CHECK(finite3(node.m_v));
	// Same tolerance as the property test: 1e-6 plus the btScalar rounding floor of zeta (insideExcess).
	CHECK(excess <= 0);
	// Push-out budget: the ray crosses each ellipsoid's chord at most once; 64 ulps of 1 km + 1e-6 m for rounding.
	CHECK(dist(result, x) <= pushBudget + 64 * Real(SIMD_EPSILON) * 1000 + Real(1e-6));
	CHECK(collider->getLastSubstepStats().m_minZeta >= btScalar(1));
	world.getSoftBodySolver()->uninstallCollider(collider);
}

} // namespace

// The two failures of the [.slow] float run (seed 0x5EED0002, before the fix): a node that starts inside, 1 km from
// the origin, skin 0, whose push-out ended inside a neighbour. Exact inputs printed by BODYFIT_ROBUST_VERBOSE=1.
// In the float64 build the same (float-representable) inputs are a valid, nearby case.
TEST_CASE("robust regression: push-out of a touching pair 1 km from the origin ends outside both",
		  "[robust][collider][regression]")
{
	const ExactEllipsoid ells[] = {
		{{0x1.75811p+8, 0x1.821fc2p+9, -0x1.00e9b6p+9},
		 {0x1.346258p-3, 0x1.2156dep-2, 0x1.7ee36ap-4},
		 {0x1.51692cp-1, -0x1.5d4eeep-1, -0x1.443b68p-2, -0x1.5a62a6p-1, -0x1.71794p-1, 0x1.2cacfp-3, -0x1.508abcp-2,
		  0x1.e11f5p-4, -0x1.dfcdd8p-1}},
		{{0x1.75880ep+8, 0x1.82205p+9, -0x1.0104a6p+9},
		 {0x1.b7effap-4, 0x1.b7effap-4, 0x1.b7effap-4},
		 {1, 0, 0, 0, 1, 0, 0, 0, 1}}};
	const double q[3] = {0x1.758c8ap+8, 0x1.821ecep+9, -0x1.00e8d6p+9};
	const double x[3] = {0x1.7589dap+8, 0x1.82207ep+9, -0x1.00f6fp+9};
	runRegressionPath(ells, 2, q, x);
}

TEST_CASE("robust regression: push-out in an 8-ellipsoid chain 1 km from the origin ends outside all",
		  "[robust][collider][regression]")
{
	const ExactEllipsoid ells[] = {
		{{0x1.902b72p+9, 0x1.6e7abcp+8, 0x1.da783ep+8},
		 {0x1.449f96p-4, 0x1.1b9214p-3, 0x1.572bap-4},
		 {0x1.ac109ep-1, 0x1.458564p-3, 0x1.0cda4p-1, 0x1.801c8cp-3, 0x1.a21f2cp-1, -0x1.177548p-1, -0x1.07f9bcp-1,
		  0x1.1c11c8p-1, 0x1.4e503cp-1}},
		{{0x1.903622p+9, 0x1.6e6ac2p+8, 0x1.da6b34p+8},
		 {0x1.1a75d4p-4, 0x1.5e0aaap-4, 0x1.f677e4p-4},
		 {-0x1.42f938p-1, 0x1.52bb9ap-1, -0x1.9f2c52p-2, 0x1.5cfe0ap-1, 0x1.71bd0cp-1, 0x1.e2c732p-4, 0x1.7baa56p-2,
		  -0x1.9db72p-3, -0x1.d01f74p-1}},
		{{0x1.902ef4p+9, 0x1.6e8e22p+8, 0x1.da638p+8},
		 {0x1.dd3ff6p-3, 0x1.578774p-5, 0x1.ae43cep-3},
		 {0x1.602638p-1, 0x1.c16274p-4, 0x1.6f6542p-1, -0x1.ede084p-2, 0x1.9d9e54p-1, 0x1.5ae6c2p-2, -0x1.15c52ap-1,
		  -0x1.287e52p-1, 0x1.37936p-1}},
		{{0x1.902b1ap+9, 0x1.6e89cap+8, 0x1.da5a6ap+8},
		 {0x1.e2b6dep-5, 0x1.687b5p-4, 0x1.06a0bep-3},
		 {0x1.aaff7cp-2, 0x1.5a4022p-1, -0x1.36ec26p-1, -0x1.44b96cp-2, -0x1.0929f4p-1, -0x1.96c7e4p-1, -0x1.b41ebep-1,
		  0x1.0c38acp-1, -0x1.8a4p-10}},
		{{0x1.903768p+9, 0x1.6e8296p+8, 0x1.da6b3p+8},
		 {0x1.b31aa6p-3, 0x1.170302p-3, 0x1.d3b3a4p-4},
		 {-0x1.daa73p-3, -0x1.2af188p-1, -0x1.8e5dcep-1, 0x1.cb83eep-2, -0x1.8c323p-1, 0x1.c9c066p-2, -0x1.b9e60ep-1,
		  -0x1.f6e134p-3, 0x1.c3f27cp-2}},
		{{0x1.90335ep+9, 0x1.6e83dcp+8, 0x1.da80dap+8},
		 {0x1.b67ce2p-5, 0x1.95eef4p-5, 0x1.03e7ccp-4},
		 {-0x1.b7738p-3, 0x1.20bbccp-4, -0x1.f2c522p-1, -0x1.14c3ccp-1, 0x1.a4efaap-1, 0x1.6dafeep-3, 0x1.a080f6p-1,
		  0x1.213aeep-1, -0x1.1b40ap-3}},
		{{0x1.902ef8p+9, 0x1.6e7ee2p+8, 0x1.da901ap+8},
		 {0x1.4cbea8p-5, 0x1.d92f88p-4, 0x1.4c094ap-3},
		 {-0x1.709e54p-1, -0x1.e69848p-5, -0x1.62087ap-1, -0x1.f719dcp-2, 0x1.7ea0eap-1, 0x1.ca1728p-2, 0x1.f5f16ap-2,
		  0x1.52d7c4p-1, -0x1.226b14p-1}},
		{{0x1.903444p+9, 0x1.6e7f7p+8, 0x1.da92a4p+8},
		 {0x1.674ed2p-3, 0x1.5a5184p-3, 0x1.f4279ep-5},
		 {0x1.b027a2p-1, -0x1.b5e7ccp-4, -0x1.0d0dc8p-1, 0x1.372828p-7, 0x1.f72b3cp-1, -0x1.7a3c88p-3, 0x1.1285cp-1,
		  0x1.35082cp-3, 0x1.a9387ep-1}}};
	const double q[3] = {0x1.903e6ep+9, 0x1.6e8568p+8, 0x1.da8104p+8};
	const double x[3] = {0x1.9033fcp+9, 0x1.6e86e4p+8, 0x1.da8338p+8};
	runRegressionPath(ells, 8, q, x);
}
