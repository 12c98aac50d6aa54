// The cloth collider's phases on their own: the broad phase (btEllipsoidWorldCache::PathQuery, the exact call the
// collider makes per node) against brute force on random node paths, and the narrow-phase kernel
// (src/btEllipsoidNarrowPhase.h: segment / ray vs the whitened unit ball) against closed forms.
#include "bullet_ext/cloth_test_scene.h"
#include "src/btEllipsoidNarrowPhase.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <random>
#include <set>

using namespace bodyfit_test;

namespace
{

btVector3 randomUnitVector(std::mt19937 &rng)
{
	std::normal_distribution<double> n(0.0, 1.0);
	btVector3 v(btScalar(n(rng)), btScalar(n(rng)), btScalar(n(rng)));
	return v.length2() > btScalar(1e-12) ? v.normalized() : btVector3(1, 0, 0);
}

/// A random compound of `count` ellipsoids in a 1.8 m tall box, a quarter of them thin (down to 1000:1).
std::unique_ptr<btEllipsoidCompoundShape> randomCompound(std::mt19937 &rng, int count)
{
	std::uniform_real_distribution<double> u(0.0, 1.0);
	std::unique_ptr<btEllipsoidCompoundShape> s(new btEllipsoidCompoundShape());
	for (int i = 0; i < count; ++i)
	{
		const btVector3 c(btScalar(0.4 * u(rng) - 0.2), btScalar(1.8 * u(rng)), btScalar(0.3 * u(rng) - 0.15));
		btVector3 a(btScalar(0.02 + 0.15 * u(rng)), btScalar(0.02 + 0.15 * u(rng)), btScalar(0.02 + 0.1 * u(rng)));
		if (i % 4 == 0)
			a[i % 3] = a[(i + 1) % 3] * btScalar(0.001 + 0.01 * u(rng)); // thin: a disc or a needle axis
		const btMatrix3x3 r(btQuaternion(randomUnitVector(rng), btScalar(6.283 * u(rng))));
		s->addEllipsoid(c, r, a);
	}
	return s;
}

/// Smallest zeta of a reference ellipsoid along the segment q -> x (closed form in whitened coordinates, double).
double minZetaOnSegment(const RefEllipsoid &e, const Eigen::Vector3d &q, const Eigen::Vector3d &x)
{
	const Eigen::Vector3d u0 = (e.rotation.transpose() * (q - e.center)).cwiseQuotient(e.radii);
	const Eigen::Vector3d u1 = (e.rotation.transpose() * (x - e.center)).cwiseQuotient(e.radii);
	const Eigen::Vector3d d = u1 - u0;
	const double dd = d.squaredNorm();
	const double t = dd > 0 ? std::min(1.0, std::max(0.0, -u0.dot(d) / dd)) : 0.0;
	return (u0 + t * d).squaredNorm();
}

bool boxesOverlap(const btVector3 &aMin, const btVector3 &aMax, const btVector3 &bMin, const btVector3 &bMax)
{
	for (int k = 0; k < 3; ++k)
		if (aMin[k] > bMax[k] || aMax[k] < bMin[k])
			return false;
	return true;
}

struct QueryTally
{
	long long paths = 0;
	long long metPairs = 0;	 // (path, ellipsoid) pairs the grown path certainly meets
	long long longPaths = 0; // paths longer than 4 grid cells (the cell walk / every-box branch)
};

/// One random node path around the union: a start near the surface of a random ellipsoid (half the paths; cloth
/// lies there) or anywhere in the union's box grown by 20 cm, and a step of 0 to 40 mm (a cloth node at 60 Hz), or
/// every eighth path, a jump of up to 1.5 m (a whipping corner, many cells).
void randomPath(std::mt19937 &rng, const std::vector<RefEllipsoid> &ref, const btVector3 &lo, const btVector3 &hi,
				btVector3 &q, btVector3 &x)
{
	std::uniform_real_distribution<double> u(0.0, 1.0);
	const btVector3 grow(btScalar(0.2), btScalar(0.2), btScalar(0.2));
	const btVector3 a = lo - grow, b = hi + grow;
	q = btVector3(btScalar(a.x() + (b.x() - a.x()) * u(rng)), btScalar(a.y() + (b.y() - a.y()) * u(rng)),
				  btScalar(a.z() + (b.z() - a.z()) * u(rng)));
	if (u(rng) < 0.5)
	{
		const RefEllipsoid &e = ref[size_t(u(rng) * double(ref.size())) % ref.size()];
		const btVector3 dir = randomUnitVector(rng);
		const Eigen::Vector3d p = e.center + e.rotation * (toE(dir).cwiseProduct(e.radii) * (0.8 + 0.5 * u(rng)) +
														   Eigen::Vector3d::Constant(0.01 * (u(rng) - 0.5)));
		q = btVector3(btScalar(p.x()), btScalar(p.y()), btScalar(p.z()));
	}
	const int kind = int(8 * u(rng));
	const double length = kind == 0 ? 1.5 * u(rng) : (kind == 1 ? 0.0 : 0.04 * u(rng));
	x = q + randomUnitVector(rng) * btScalar(length);
}

/// Checks one path: the query's list has no duplicates, holds only entries whose world box overlaps the grown path
/// box (the brute-force box filter), and holds every ellipsoid that the path, moved by any offset o with
/// |o|_inf <= radius (the 8 corners and the centre of the radius cube), meets by more than the rounding margin.
void checkPath(const btEllipsoidWorldCache &cache, const btEllipsoidWorldCache::PathQuery &query,
			   const std::vector<RefEllipsoid> &ref, btScalar radius, const btVector3 &q, const btVector3 &x,
			   std::vector<int> &buffer, QueryTally &tally)
{
	const int n = query.candidates(q, x, buffer.data());
	REQUIRE(n >= 0);
	REQUIRE(n <= cache.size());
	const std::set<int> got(buffer.begin(), buffer.begin() + n);
	CHECK(int(got.size()) == n); // each once
	btVector3 boxMin = q, boxMax = q;
	boxMin.setMin(x);
	boxMax.setMax(x);
	const btVector3 r(radius, radius, radius);
	boxMin -= r;
	boxMax += r;
	for (int k : got)
	{
		REQUIRE(k >= 0);
		REQUIRE(k < cache.size());
		CHECK(boxesOverlap(boxMin, boxMax, cache[k].m_aabbMin, cache[k].m_aabbMax));
	}
	// Rounding margin: the cache's world entries and boxes are btScalar images of the double reference, a few ulps
	// of the largest coordinate off; a world displacement delta moves whitened points by at most delta / a_min. So a
	// path counts as meeting an ellipsoid only where its closest whitened point is inside the ball shrunk by that:
	// |u| <= 1 - delta / a_min with delta = 64 ulps of the coordinates (plus 1 um).
	const double scale = double(std::max(q.absolute()[q.absolute().maxAxis()], x.absolute()[x.absolute().maxAxis()]));
	const double delta = 64.0 * double(SIMD_EPSILON) * (scale + 1.0) + 1e-6;
	for (int k = 0; k < int(ref.size()); ++k)
	{
		const double shrunk = 1.0 - delta / ref[k].radii.minCoeff();
		if (shrunk <= 0)
			continue; // below what btScalar resolves here
		bool meets = false;
		for (int corner = 0; corner < 9 && !meets; ++corner)
		{
			Eigen::Vector3d o = Eigen::Vector3d::Zero();
			if (corner < 8)
				o = double(radius) *
					Eigen::Vector3d((corner & 1) ? 1 : -1, (corner & 2) ? 1 : -1, (corner & 4) ? 1 : -1);
			meets = minZetaOnSegment(ref[k], toE(q) + o, toE(x) + o) <= shrunk * shrunk;
		}
		if (!meets)
			continue;
		++tally.metPairs;
		INFO("path (" << q.x() << ", " << q.y() << ", " << q.z() << ") -> (" << x.x() << ", " << x.y() << ", " << x.z()
					  << "), radius " << radius << ", ellipsoid " << k << " met but not listed");
		CHECK(got.count(k) == 1);
	}
}

} // namespace

TEST_CASE("broad phase: the collider's path query lists every ellipsoid a grown node path meets",
		  "[bullet_ext][collider][broadphase]")
{
	std::mt19937 rng(20261201);
	std::uniform_real_distribution<double> u(0.0, 1.0);
	QueryTally tally;
	// Offsets from the origin: none, 10 m, 1 km (float resolves 6e-5 m there; the margin above grows with it).
	const double offsets[] = {0.0, 10.0, 1000.0};
	for (int set = 0; set < 24; ++set)
	{
		std::unique_ptr<btEllipsoidCompoundShape> shape = randomCompound(rng, 5 + int(55 * u(rng)));
		const double offset = offsets[set % 3];
		// Every other set rotated (the grid lives in the body frame: the general affine path), the rest only moved
		// (the axis-aligned fast path).
		const btQuaternion rotation =
			set % 2 ? btQuaternion(randomUnitVector(rng), btScalar(6.283 * u(rng))) : btQuaternion::getIdentity();
		const btTransform pose(rotation, btVector3(btScalar(offset), btScalar(-0.5 * offset), btScalar(0.3 * offset)));
		btEllipsoidWorldCache cache;
		REQUIRE(cache.update(shape.get(), pose));
		const std::vector<RefEllipsoid> ref = worldEllipsoids(*shape, pose);
		const btScalar radius = set % 4 == 3 ? btScalar(0.01) : (set % 4 == 1 ? btScalar(0) : btScalar(0.002));
		const btEllipsoidWorldCache::PathQuery query(cache, radius);
		const btScalar cell = (cache.getAabbMax() - cache.getAabbMin()).length() / btScalar(32); // an upper bound
		std::vector<int> buffer(size_t(cache.size()));
		for (int p = 0; p < 1500; ++p)
		{
			btVector3 q, x;
			randomPath(rng, ref, cache.getAabbMin(), cache.getAabbMax(), q, x);
			tally.longPaths += (x - q).length() > 4 * cell ? 1 : 0;
			++tally.paths;
			checkPath(cache, query, ref, radius, q, x, buffer, tally);
		}
	}
	INFO("paths " << tally.paths << ", met pairs " << tally.metPairs << ", long paths " << tally.longPaths);
	// The run must exercise what it checks: many met pairs, and long paths through the cell walk.
	CHECK(tally.metPairs > 10000);
	CHECK(tally.longPaths > 1000);
}

TEST_CASE("broad phase: an animated compound's lists stay conservative between rebuilds, which frame flips do not cause",
		  "[bullet_ext][collider][broadphase][moving]")
{
	// A compound moved by its own ellipsoids every update (setEllipsoids, as a skinning driver does): most drift
	// slowly, a few move fast (10 mm per update, a foot in a walk's swing at 2 ms substeps), and every update hands
	// over some ellipsoids in another of their frames (axes swapped, signs flipped: the same set). The lists are
	// rebuilt only when an ellipsoid left its own margin (btEllipsoidWorldCache::gridCovers); every path query in
	// between must still list every ellipsoid the path meets (checkPath, as for a fresh cache).
	std::mt19937 rng(20261202);
	std::uniform_real_distribution<double> u(0.0, 1.0);
	const int count = 40, updates = 120;
	std::unique_ptr<btEllipsoidCompoundShape> shape = randomCompound(rng, count);
	std::vector<btVector3> centers(count), axes(count), velocity(count);
	std::vector<btMatrix3x3> bases(count);
	for (int i = 0; i < count; ++i)
	{
		const btEllipsoidLocalData& e = shape->getEllipsoid(i);
		centers[i] = e.m_center;
		bases[i] = e.m_basis;
		axes[i] = e.m_semiAxes;
		velocity[i] = randomUnitVector(rng) * btScalar(i < 4 ? 0.010 : 0.0005);
	}
	btEllipsoidWorldCache cache;
	REQUIRE(cache.update(shape.get(), btTransform::getIdentity()));
	const int firstBuilds = cache.getGridBuilds();
	QueryTally tally;
	std::vector<int> buffer(static_cast<size_t>(count));
	const btScalar radius(0.002);
	int flipOnlyBuilds = 0;
	int maxBoxTested = 0;
	for (int step = 0; step < updates; ++step)
	{
		// The first 20 updates only flip frames (no motion at all): no rebuild may follow from them but the first.
		const bool flipOnly = step < 20;
		for (int i = 0; i < count; ++i)
		{
			if (!flipOnly)
				centers[i] += velocity[i] * btScalar(0.75 + 0.5 * u(rng));
			if (u(rng) < 0.3)
			{
				// Columns 0 and 1 swapped and column 2 negated: a proper rotation, the same ellipsoid.
				const btVector3 c0 = bases[i].getColumn(0), c1 = bases[i].getColumn(1), c2 = bases[i].getColumn(2);
				bases[i] = btMatrix3x3(c1.x(), c0.x(), -c2.x(), c1.y(), c0.y(), -c2.y(), c1.z(), c0.z(), -c2.z());
				axes[i] = btVector3(axes[i].y(), axes[i].x(), axes[i].z());
			}
		}
		REQUIRE(shape->setEllipsoids(count, centers.data(), bases.data(), axes.data()));
		cache.update(shape.get(), btTransform::getIdentity());
		maxBoxTested = std::max(maxBoxTested, cache.getNumBoxTested());
		if (flipOnly)
			flipOnlyBuilds = cache.getGridBuilds() - firstBuilds;
		const std::vector<RefEllipsoid> ref = worldEllipsoids(*shape, btTransform::getIdentity());
		const btEllipsoidWorldCache::PathQuery query(cache, radius);
		for (int p = 0; p < 200; ++p)
		{
			btVector3 q, x;
			randomPath(rng, ref, cache.getAabbMin(), cache.getAabbMax(), q, x);
			++tally.paths;
			checkPath(cache, query, ref, radius, q, x, buffer, tally);
		}
	}
	const int builds = cache.getGridBuilds() - firstBuilds;
	INFO("rebuilds " << builds << " over " << updates << " updates, met pairs " << tally.metPairs
					  << ", most box-tested at once " << maxBoxTested);
	CHECK(tally.metPairs > 2000); // the run exercises what it checks
	// Frame flips are no drift (closestFrame): the one build is the first animated update's, which gives the lists
	// their margins (a compound seen once has none). Before, each flip read as a drift of up to twice a semi-axis
	// and 30% of the ellipsoids flip per update: a rebuild every time.
	CHECK(flipOnlyBuilds == 1);
	// The fast ellipsoids get margins of 16 of their updates (up to a cell, 4.5-5.6 cm here): after the first
	// rebuild they last about 5 updates at 10 mm, where the smallest margin (a quarter cell) lasted one. A rebuild
	// per update would be 100; at most one per 3 updates leaves room for the slow start and the jitter of the speeds.
	CHECK(builds <= (updates - 20) / 3);
	CHECK(builds >= 1); // (and the fast ones did leave their first margins: the rebuild path ran)
	// Between builds an ellipsoid that left its margin is box-tested (every query tests its box, its lists being
	// stale); the paths above were checked with some of them so.
	CHECK(maxBoxTested >= 1);
}

TEST_CASE("broad phase: an empty cache and a path far from the union list nothing",
		  "[bullet_ext][collider][broadphase]")
{
	btEllipsoidWorldCache empty;
	const btEllipsoidWorldCache::PathQuery none(empty, btScalar(0.002));
	int out[1] = {-1};
	CHECK(none.candidates(btVector3(0, 0, 0), btVector3(1, 0, 0), out) == 0);

	btEllipsoidCompoundShape shape;
	shape.addEllipsoid(btVector3(0, 0, 0), btMatrix3x3::getIdentity(), btVector3(0.1, 0.2, 0.3));
	btEllipsoidWorldCache cache;
	cache.update(&shape, btTransform::getIdentity());
	const btEllipsoidWorldCache::PathQuery query(cache, btScalar(0.002));
	CHECK(query.candidates(btVector3(1, 1, 1), btVector3(1.1, 1, 1), out) == 0);
	CHECK(query.candidates(btVector3(0, 0.5, 0), btVector3(0, 0.25, 0), out) == 0);	 // ends 50 mm above the top
	CHECK(query.candidates(btVector3(0, 0.5, 0), btVector3(0, 0.201, 0), out) == 1); // 1 mm above: within the radius
	CHECK(out[0] == 0);
}

namespace
{

/// A world cache over a compound of axis-aligned ellipsoids (identity pose), for the narrow-phase kernel.
struct AxisAlignedSet
{
	btEllipsoidCompoundShape shape;
	btEllipsoidWorldCache cache;
	std::vector<int> all;
	void add(const btVector3 &c, const btVector3 &a)
	{
		shape.addEllipsoid(c, btMatrix3x3::getIdentity(), a);
		cache.update(&shape, btTransform::getIdentity());
		all.push_back(int(all.size()));
	}
	btPathEntry entry(const btVector3 &q, const btVector3 &x, std::vector<btScalar> &tvals) const
	{
		tvals.assign(all.size(), btScalar(-1));
		btPathEntry out;
		btEarliestEntry(cache.getPackedRecords(), all.data(), int(all.size()), btPathEnds(q, x), tvals.data(), out);
		return out;
	}
};

/// Tolerance of a float-computed root of order 1: a few ulps of the operands (2e-6 in float, far tighter in double).
const double kRootTol = 16.0 * double(SIMD_EPSILON);

} // namespace

TEST_CASE("narrow phase: segment entry into the unit ball against the closed form",
		  "[bullet_ext][collider][narrowphase]")
{
	SECTION("axis-aligned through the centre: entry at u = -1")
	{
		// q = (-2, 0, 0), d = (4, 0, 0): |q + t d| = 1 at t = 1/4 and 3/4.
		CHECK(double(btSegmentEntry(-2, 0, 0, 4, 0, 0, 4)) == Approx(0.25).margin(kRootTol));
		// Heading away (b >= 0): no entry even though the line meets the ball behind q.
		CHECK(btSegmentEntry(-2, 0, 0, -4, 0, 0, 4) == kNoEntry);
	}
	SECTION("random segments: the smaller root of |u_q + t d|^2 = 1")
	{
		std::mt19937 rng(7);
		std::uniform_real_distribution<double> u(-3.0, 3.0);
		int entered = 0;
		for (int i = 0; i < 20000; ++i)
		{
			const btVector3 uq(btScalar(u(rng)), btScalar(u(rng)), btScalar(u(rng)));
			const btVector3 d(btScalar(u(rng)), btScalar(u(rng)), btScalar(u(rng)));
			const btScalar zq = uq.length2();
			if (zq < btScalar(1.01))
				continue; // the kernel is for starts outside
			const double a = double(d.length2()), b = double(uq.dot(d)), c = double(zq) - 1.0;
			const double disc = b * b - a * c;
			const btScalar t = btSegmentEntry(uq.x(), uq.y(), uq.z(), d.x(), d.y(), d.z(), zq);
			if (b >= 0 || disc < 0)
			{
				// No entry; near-grazing lines (disc within rounding of 0) may go either way.
				if (std::fabs(disc) > 1e-4 * (b * b + std::fabs(a * c)))
					CHECK(t == kNoEntry);
				continue;
			}
			const double t0 = (-b - std::sqrt(disc)) / a;
			// Relative to the root's conditioning: the root moves by about |d t| / sqrt(disc) per unit of rounding.
			CHECK(double(t) == Approx(t0).margin(kRootTol * (1.0 + std::fabs(t0)) * (1.0 + a / std::sqrt(disc))));
			++entered;
		}
		CHECK(entered > 500);
	}
	SECTION("grazing: a tangent line touches at one point, a line 1e-3 outside misses, 1e-3 inside enters")
	{
		// Line y = h, z = 0 from x = -2 to x = 2: the tangent (h = 1) touches at t = 1/2.
		CHECK(double(btSegmentEntry(-2, 1, 0, 4, 0, 0, 5)) == Approx(0.5).margin(1e-3));
		const btScalar above = btScalar(1.001), below = btScalar(0.999);
		CHECK(btSegmentEntry(-2, above, 0, 4, 0, 0, 4 + above * above) == kNoEntry);
		// Entry at x = -sqrt(1 - h^2): t = (2 - sqrt(1 - h^2)) / 4.
		const double t = (2.0 - std::sqrt(1.0 - double(below) * double(below))) / 4.0;
		CHECK(double(btSegmentEntry(-2, below, 0, 4, 0, 0, 4 + below * below)) == Approx(t).margin(1e-5));
	}
	SECTION("zero-length path: outside stays outside; on the surface is not an entry")
	{
		CHECK(btSegmentEntry(2, 0, 0, 0, 0, 0, 4) == kNoEntry);
		CHECK(btSegmentEntry(1, 0, 0, 0, 0, 0, 1) == kNoEntry);
	}
}

TEST_CASE("narrow phase: earliest entry over packed records, start inside, ties to the first listed",
		  "[bullet_ext][collider][narrowphase]")
{
	AxisAlignedSet set;
	set.add(btVector3(0, 0, 0), btVector3(0.5, 0.2, 0.1));	 // 0
	set.add(btVector3(0.8, 0, 0), btVector3(0.2, 0.2, 0.2)); // 1: x in [0.6, 1.0]
	std::vector<btScalar> tvals;
	SECTION("along x through both: ellipsoid 0 first, entry at x = -0.5")
	{
		const btPathEntry e = set.entry(btVector3(-1, 0, 0), btVector3(1, 0, 0), tvals);
		REQUIRE(e.m_ellipsoid == 0);
		CHECK_FALSE(e.m_startInside);
		CHECK(double(e.m_t) == Approx(0.25).margin(kRootTol));	 // x = -1 + 2 t = -0.5
		CHECK(double(tvals[1]) == Approx(0.8).margin(kRootTol)); // x = 0.6
		// The entry point lies on the unit sphere of ellipsoid 0's whitened coordinates, at u = (-1, 0, 0).
		CHECK(double(e.m_u.x()) == Approx(-1.0).margin(kRootTol));
		CHECK(double(e.m_u.length()) == Approx(1.0).margin(kRootTol));
		CHECK(double(e.m_minZetaEnd) == Approx(1.0).margin(kRootTol)); // x = (1, 0, 0) is on ellipsoid 1's surface
	}
	SECTION("reverse direction: ellipsoid 1 first")
	{
		const btPathEntry e = set.entry(btVector3(1.5, 0, 0), btVector3(-1, 0, 0), tvals);
		REQUIRE(e.m_ellipsoid == 1);
		CHECK(double(e.m_t) == Approx(0.5 / 2.5).margin(kRootTol)); // x = 1.0
	}
	SECTION("start inside ellipsoid 0: flagged, no entry parameter for it")
	{
		const btPathEntry e = set.entry(btVector3(0.1, 0, 0), btVector3(0.3, 0, 0), tvals);
		CHECK(e.m_startInside);
		CHECK(tvals[0] == kNoEntry);
		CHECK(double(e.m_minZetaEnd) == Approx(0.36).margin(kRootTol)); // (0.3 / 0.5)^2
	}
	SECTION("a path that stays outside: no entry, the smallest zeta at its end")
	{
		const btPathEntry e = set.entry(btVector3(0, 0.5, 0), btVector3(0, 0.4, 0), tvals);
		CHECK(e.m_ellipsoid == -1);
		CHECK(e.m_t == kNoEntry);
		CHECK(double(e.m_minZetaEnd) == Approx(4.0).margin(1e-5)); // (0.4 / 0.2)^2
	}
	SECTION("zero-length path inside: start inside; outside: nothing")
	{
		CHECK(set.entry(btVector3(0.2, 0, 0), btVector3(0.2, 0, 0), tvals).m_startInside);
		const btPathEntry e = set.entry(btVector3(0, 1, 0), btVector3(0, 1, 0), tvals);
		CHECK_FALSE(e.m_startInside);
		CHECK(e.m_ellipsoid == -1);
	}
}

TEST_CASE("narrow phase: ray chords and the escape test of the push-out", "[bullet_ext][collider][narrowphase]")
{
	// Ray from (-3, 0, 0) along +x through the unit ball: chord s in [2, 4].
	const btUnitBallQuadratic through = btUnitBallQuadratic::ofLine(btVector3(-3, 0, 0), btVector3(1, 0, 0));
	const btScalar disc = through.discriminant();
	REQUIRE(disc >= 0);
	btScalar s0, s1;
	through.roots(disc, s0, s1);
	CHECK(double(s0) == Approx(2.0).margin(kRootTol));
	CHECK(double(s1) == Approx(4.0).margin(kRootTol));
	CHECK(through.exitAhead(disc)); // the ball blocks the ray
	// The same ray from (3, 0, 0) has the ball behind it: not blocked.
	const btUnitBallQuadratic past = btUnitBallQuadratic::ofLine(btVector3(3, 0, 0), btVector3(1, 0, 0));
	CHECK_FALSE(past.exitAhead(past.discriminant()));
	// From inside (origin) every ray is blocked: the exit is ahead at s = 1 for a unit direction.
	const btUnitBallQuadratic inside = btUnitBallQuadratic::ofLine(btVector3(0, 0, 0), btVector3(0, 0, -1));
	inside.roots(inside.discriminant(), s0, s1);
	CHECK(double(s1) == Approx(1.0).margin(kRootTol));
	CHECK(inside.exitAhead(inside.discriminant()));
	// A line that misses: negative discriminant. A longer direction scales the parameters (s = 1 / |d| per unit).
	CHECK(btUnitBallQuadratic::ofLine(btVector3(-3, 2, 0), btVector3(1, 0, 0)).discriminant() < 0);
	const btUnitBallQuadratic scaled = btUnitBallQuadratic::ofLine(btVector3(-3, 0, 0), btVector3(2, 0, 0));
	scaled.roots(scaled.discriminant(), s0, s1);
	CHECK(double(s0) == Approx(1.0).margin(kRootTol));
	// The entry root of the cancellation-free form equals s0 for a start outside heading in.
	CHECK(double(through.entryRoot(disc)) == Approx(2.0).margin(kRootTol));
}
