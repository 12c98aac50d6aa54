// bodyfit-bench compound-build: building a btEllipsoidCompoundShape of n ellipsoids with addEllipsoid, n = 1k, 10k,
// 100k (random centres in a 10 m box, random orientations and semi-axes 1-10 cm). Median wall time of the repeats,
// per build and per ellipsoid, with and without btCompoundShape's dynamic AABB tree: addEllipsoid grows the local
// AABB by the new child's box (it recomputed it over all children before, O(n) per add: 10k took 1.8 s, 100k
// ~290 s) and inserts the box into the tree (btDbvt::insert, which never rebalances and dominates at 100k).
#include "bench/bench_common.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

#include <memory>
#include <random>
#include <vector>

namespace
{

struct Spec
{
	btVector3 center, semiAxes;
	btMatrix3x3 basis;
};

std::vector<Spec> randomSpecs(int n)
{
	std::mt19937 rng(12345u);
	std::uniform_real_distribution<double> box(-5.0, 5.0), axis(0.01, 0.1), angle(-3.14159, 3.14159);
	std::vector<Spec> specs(static_cast<size_t>(n));
	for (Spec& s : specs)
	{
		s.center = btVector3(btScalar(box(rng)), btScalar(box(rng)), btScalar(box(rng)));
		s.semiAxes = btVector3(btScalar(axis(rng)), btScalar(axis(rng)), btScalar(axis(rng)));
		s.basis.setEulerZYX(btScalar(angle(rng)), btScalar(angle(rng)), btScalar(angle(rng)));
	}
	return specs;
}

int runCompoundBuild(const bodyfit_bench::Context& ctx)
{
	bodyfit_bench::Table t({"ellipsoids", "AABB tree", "repeats", "median build ms", "us per ellipsoid",
		"median destroy ms"});
	for (int n : {1000, 10000, 100000})
		for (bool tree : {true, false})
	{
		const std::vector<Spec> specs = randomSpecs(n);
		const int repeats = n >= 100000 ? std::min(ctx.repeats, 5) : ctx.repeats;
		// Built shapes are kept until the build timing is done, and destroyed in a second timed loop.
		std::vector<std::unique_ptr<btEllipsoidCompoundShape>> built;
		const double ms = bodyfit_bench::medianMs(repeats, [&] {
			built.push_back(std::make_unique<btEllipsoidCompoundShape>(BT_ELLIPSOID_DEFAULT_MARGIN, tree));
			for (const Spec& s : specs)
				built.back()->addEllipsoid(s.center, s.basis, s.semiAxes);
		});
		const double destroyMs = bodyfit_bench::medianMs(int(built.size()) - 1, [&] { built.pop_back(); });
		t.addRow({bodyfit_bench::fmtInt(n), tree ? "yes" : "no", bodyfit_bench::fmtInt(repeats), bodyfit_bench::fmt(ms, 2),
			bodyfit_bench::fmt(ms * 1000.0 / n, 3), bodyfit_bench::fmt(destroyMs, 2)});
	}
	return bodyfit_bench::emit(ctx, "compound_build", t);
}

const bodyfit_bench::SuiteRegistrar registerCompoundBuild("compound-build",
	"btEllipsoidCompoundShape::addEllipsoid x 1k / 10k / 100k: median build time (O(n) overall)", &runCompoundBuild);

} // namespace
