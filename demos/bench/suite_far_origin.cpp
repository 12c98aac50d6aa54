// bodyfit-bench far-origin: the skirt_drop scene (demos/scenes/skirt_drop.json) with body, ellipsoids and garment
// moved D metres from the origin along (1, 1, 1) / sqrt(3), for D from 0 to 1,000 km. Per D: the float spacing at D,
// nodes inside an ellipsoid and inside the body mesh at the end, mean |link strain| (crumpling: cloth rest length vs
// now), mean node travel over the run (a frozen cloth does not fall), NaN nodes, and what the precision check says
// (bodyfit/bullet_ext/btFloatRange.h). Run in the float build and in the float64 one (-DBODYFIT_BULLET_DOUBLE=ON) to
// see where float stops being safe (docs/ROBUSTNESS.md, section 9).
#include "bench/study_common.h"

#include <BulletSoftBody/btSoftBody.h>

#include "bodyfit/bullet_ext/btFloatRange.h"
#include "bodyfit/fitting/skin_field.h"

#include <cmath>

namespace
{

using namespace bodyfit_study;

struct FarRun
{
	int insideEllipsoids = 0, insideBody = 0, nan = 0;
	double meanStrain = 0.0, meanTravel = 0.0;
	std::string check;
};

double meanAbsStrain(const btSoftBody* cloth)
{
	double sum = 0.0;
	for (int i = 0; i < cloth->m_links.size(); ++i)
	{
		const btSoftBody::Link& l = cloth->m_links[i];
		sum += std::abs(double((l.m_n[0]->m_x - l.m_n[1]->m_x).length()) / double(l.m_rl) - 1.0);
	}
	return cloth->m_links.size() > 0 ? sum / cloth->m_links.size() : 0.0;
}

FarRun runAt(const bodyfit::drape::Scene& scene0, const bodyfit::drape::BodyData& body0, double distance, int steps)
{
	const Eigen::Vector3d offset = Eigen::Vector3d::Ones().normalized() * distance;
	bodyfit::drape::Scene scene = scene0;
	scene.garment.offset += offset;
	bodyfit::drape::BodyData body = body0;
	body.mesh.V.rowwise() += offset.transpose();
	for (bodyfit::Ellipsoid& e : body.ellipsoids)
		e.center += offset;
	if (body.skinField)
	{
		// The tight surface's field moves with the body (baked at the origin, its grid shifted: the bake's own float
		// behaviour is not what this measures; the collider reads it in float coordinates there).
		std::shared_ptr<bodyfit::SkinField> moved = std::make_shared<bodyfit::SkinField>(*body.skinField);
		moved->origin += offset;
		body.skinField = moved;
	}
	FarRun r;
	{
		// Measured past the refusal on purpose; the check's verdict is reported beside the numbers.
		bodyfit::drape::DrapeSimulation sim(scene, body, /*refuseFarFromOrigin=*/false);
		const btFloatRangeStatus status = bodyfit::drape::checkFloatRange(scene, body, sim.garment().mesh, nullptr);
		r.check = status == BT_FLOAT_RANGE_OK ? "ok" : status == BT_FLOAT_RANGE_WARN ? "warn" : "refuse";
		std::vector<btVector3> start;
		for (int i = 0; i < sim.cloth()->m_nodes.size(); ++i)
			start.push_back(sim.cloth()->m_nodes[i].m_x);
		for (int k = 0; k < steps; ++k)
			sim.step();
		const bodyfit::drape::ClothSample s = sim.sample();
		r.insideEllipsoids = s.insideEllipsoids;
		r.insideBody = s.insideBody;
		r.nan = s.nanNodes;
		r.meanStrain = meanAbsStrain(sim.cloth());
		for (int i = 0; i < sim.cloth()->m_nodes.size(); ++i)
			r.meanTravel += double((sim.cloth()->m_nodes[i].m_x - start[size_t(i)]).length());
		r.meanTravel /= std::max(1, sim.cloth()->m_nodes.size());
	}
	return r;
}

int runFarOrigin(const Context& ctx)
{
	const bodyfit::drape::Scene scene = bodyfit::drape::loadScene(assetPath("../scenes/skirt_drop.json"));
	const bodyfit::drape::BodyData body = bodyfit::drape::loadBody(scene);
	const int steps = ctx.quick ? 60 : scene.solver.steps;
	std::vector<double> distances = {0.0, 100.0, 1000.0, 1500.0, 2000.0, 4000.0, 6000.0, 10000.0, 100000.0, 1000000.0};
	Table t({"distance m", "per-axis coordinate m", "float spacing mm", "check", "inside ellipsoids", "inside body", "mean |strain|",
		"mean travel mm", "nan"});
	for (double d : distances)
	{
		progress("far-origin", "D = %.0f m, %d steps", d, steps);
		const FarRun r = runAt(scene, body, d, steps);
		const double axis = d / std::sqrt(3.0) + 1.7; // the body's top is ~1.7 m above its feet
		t.addRow({fmt(d, 0), fmt(axis, 0), fmt(btFloatSpacing(axis) * 1000.0, 4), r.check, fmtInt(r.insideEllipsoids),
			fmtInt(r.insideBody), fmt(r.meanStrain, 4), fmt(r.meanTravel * 1000.0, 1), fmtInt(r.nan)});
	}
	std::cout << "build: " << (sizeof(btScalar) == 8 ? "float64" : "float") << " Bullet, scene skirt_drop, " << steps
			  << " steps\n\n";
	return bodyfit_bench::emit(ctx, "far_origin", t);
}

const bodyfit_bench::SuiteRegistrar registerFarOrigin("far-origin",
	"skirt_drop moved 0 .. 1,000 km from the origin: where float stops being safe (precision check, inside nodes, "
	"crumpling, frozen cloth)",
	&runFarOrigin);

} // namespace
