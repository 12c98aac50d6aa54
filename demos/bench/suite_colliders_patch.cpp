// bodyfit-bench colliders_patch: the issue-4 measurement. One process, one scene: a 100 x 100-node cloth patch
// dropped onto the bundled body (female_young), 2 s at 60 Hz (120 steps, one substep each), same cloth and solver
// settings for every collider:
//   (a) btEllipsoidClothCollider on the fitted ellipsoid compound (Bullet's own response to the body turned off);
//   (b) Bullet's default soft-body path (SDF_RS) against a btBvhTriangleMeshShape of the body mesh;
//   (c) Bullet's default path against the same ellipsoid compound (sparse SDF on each btEllipsoidShape child);
//   (t) btEllipsoidClothCollider in TIGHT_SKIN mode: (a)'s compound with a skin distance field attached (issue 14;
//       bullet_ext/README.md, "Tight skin surface"). The field is the project's bake (bodyfit::bakeSkinField, default
//       options, converted by the bridge). (a) is the same collider in ELLIPSOIDS mode (no field). With both, (a) and (t) are stepped
//       in turn in one loop, so their cost ratio is measured under the same machine load.
// Per step: wall time of stepSimulation, collision time (soft-rigid collision detection inside
// performDiscreteCollisionDetection + the collider's own time), and the number of nodes inside the real body mesh
// (MeshInsideTest: ray parity per component, 3-axis vote, against the original mesh, not the ellipsoids).
// Reported: medians over the steps, nodes inside at the end and at worst, NaN nodes, mean gap of resting nodes,
// contact nodes and their gap to the skin (bodyfit::metrics, the scene runner's contact rule of each collider).
// The three worlds are the scene runner's (bodyfit::drape::DrapeSimulation: colliders ellipsoids, mesh-bvh and
// ellipsoids-sdf, Bullet's own btSoftBodyHelpers::CreatePatch cloth as garment bullet_patch); suite options
// (bodyfit-bench --help lists them) pick cases, steps, resolution and the Bullet paths' tuning, e.g.
//   bodyfit-bench colliders_patch --cases b --steps 12 --voxel 0.05
// --moving MM times (a) twice on the same garment: the body static, then every ellipsoid moved every step by up to
// MM mm and 0.05 rad (setEllipsoids before each step, as a skinning driver does; issue 13 asks for the moving
// collider within 1.5x of the static one), e.g.
//   bodyfit-bench colliders_patch --cases a --moving 2 --repeats 5
// (the moving row's inside counts are "-": the mesh is at rest; its min zeta is the collider's own check.)
#include "bench/bench_common.h"

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/segmentation.h"
#include "bodyfit/fitting/skin_field.h"
#include "bodyfit/fitting/statistics.h"

#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btEllipsoidShape.h"
#include "bodyfit/bullet_ext/btSkinDistanceField.h"
#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/drape/garment.h"
#include "bodyfit/drape/simulation.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <tuple>
#include <stdexcept>

namespace
{

using bodyfit::drape::ColliderKind;

struct Settings
{
	int resolution = 100;
	double size = 1.2;       // metres: 12 mm node spacing
	double drop = 0.03;      // metres above the head top
	int steps = 120;         // 2 s at 60 Hz
	double dt = 1.0 / 60.0;
	int iterations = 10;     // piterations
	double friction = 0.5;   // Coulomb coefficient (collider) = kDF * body friction (Bullet paths)
	double clothMargin = 0.005;
	double skin = 0.002;     // collider skin offset
	double voxel = 0.02;     // sparse-SDF voxel for the Bullet paths
	double meshMargin = 0.0; // btBvhTriangleMeshShape margin (also the margin of Bullet's extruded prisms)
	double kKHR = 1.0;       // Bullet's contact hardness for static bodies (default 0.1 lets nodes sink)
	std::string cases = "abc"; // and t (tight mode, on a field baked here), not in the default set
	double movingMm = 0.0;   // > 0: case (a) also with every ellipsoid moved every step by up to this (--moving)
	int repeats = 1;         // runs per timed case (the median of their per-step medians is reported)
};

struct Result
{
	std::string name;
	std::string settings;
	int nodes = 0;
	double msPerStep = 0.0;          // thread CPU
	double collisionMsPerStep = 0.0; // thread CPU
	double colliderMsPerStep = 0.0;  // thread CPU of btEllipsoidClothCollider alone ((a) only; the rest is Bullet's)
	double wallMsPerStep = 0.0;
	double wallCollisionMsPerStep = 0.0;
	int insideEnd = 0;
	int insideWorst = 0;
	int nanNodes = 0;
	double meanGapMm = 0.0; // mean distance of resting nodes (within 10 cm of the skin) above the mesh surface
	int nearSkin = 0;       // nodes within 5 mm of the skin at the end (issue 14: on the union they float 11-15 mm off)
	double nearSkinMedianMm = 0.0; // their median gap
	double minZeta = 0.0;   // smallest zeta over all nodes and ellipsoids at the end (ellipsoid runs)
	bodyfit::metrics::ContactMetrics contacts; // at the end (the scene runner's contact rule for the collider)
	int firstMedianStep = 0; // medians are over steps [firstMedianStep, steps)
	bool moving = false;     // --moving run: the mesh and the fit's ellipsoids are at rest, the collider's are not
	double correctedPerStep = 0.0; // (a): median over the steps of the nodes the collider placed on the surface
};

const char* caseName(ColliderKind kind, bool tight)
{
	if (tight)
		return "(t) btEllipsoidClothCollider, TIGHT_SKIN (baked field)";
	switch (kind)
	{
	case ColliderKind::Ellipsoids:
		return "(a) btEllipsoidClothCollider";
	case ColliderKind::MeshBvh:
		return "(b) Bullet SDF_RS vs btBvhTriangleMeshShape";
	default:
		return "(c) Bullet SDF_RS vs ellipsoid compound";
	}
}

/// The scene of one case: Bullet's own patch (btSoftBodyHelpers::CreatePatch) over the head, gravity, friction, the
/// collider of the case; the inside count is sampled after every step.
bodyfit::drape::Scene patchScene(ColliderKind kind, const Settings& s, const bodyfit::TriMesh& body)
{
	bodyfit::drape::Scene scene;
	scene.path = "colliders_patch(generated)";
	scene.name = "colliders_patch";
	scene.collider.kind = kind;
	scene.collider.skinOffset = s.skin;
	scene.collider.sdfVoxel = s.voxel;
	scene.collider.shapeMargin = kind == ColliderKind::MeshBvh ? s.meshMargin : double(BT_ELLIPSOID_DEFAULT_MARGIN);
	scene.collider.contactHardness = s.kKHR;
	scene.garment.type = bodyfit::drape::GarmentType::BulletPatch;
	scene.garment.size = Eigen::Vector2d(s.size, s.size);
	scene.garment.resolution = Eigen::Vector2i(s.resolution, s.resolution);
	scene.garment.center = bodyfit::drape::patchCenterAboveHead(body, s.drop);
	scene.material.stretch = 0.9;
	scene.material.damping = 0.01;
	scene.material.mass = 0.25;
	scene.material.margin = s.clothMargin;
	scene.solver.dt = s.dt;
	scene.solver.substeps = 1;
	scene.solver.iterations = s.iterations;
	scene.solver.steps = s.steps;
	scene.effects.gravity = bodyfit::drape::GravitySpec{};
	bodyfit::drape::FrictionSpec friction;
	friction.coefficient = s.friction;
	scene.effects.friction = friction;
	scene.sampleEvery = 1;
	return scene;
}

std::string caseSettings(ColliderKind kind, const Settings& s, std::size_t ellipsoids)
{
	using bodyfit_bench::fmtGeneral;
	if (kind == ColliderKind::Ellipsoids)
		return "skin " + fmtGeneral(s.skin * 1e3) + " mm; friction " + fmtGeneral(s.friction) + "; " +
			   std::to_string(ellipsoids) + " ellipsoids";
	return "voxel " + fmtGeneral(s.voxel * 1e3) + " mm; cloth margin " + fmtGeneral(s.clothMargin * 1e3) + " mm; kKHR " +
		   fmtGeneral(s.kKHR) +
		   (kind == ColliderKind::MeshBvh
				? "; mesh margin " + fmtGeneral(s.meshMargin * 1e3) + " mm (+ Bullet's fixed 60 mm prism extrusion)"
				: "; child margin " + fmtGeneral(double(BT_ELLIPSOID_DEFAULT_MARGIN) * 1e3) + " mm");
}

/// Mean signed gap of the resting nodes: every 16th node within 10 cm of the skin (negative inside).
double restingGapMm(const bodyfit::drape::DrapeSimulation& sim)
{
	std::vector<int> sampled;
	for (int i = 0; i < sim.nodeCount(); i += 16)
		sampled.push_back(i);
	double sum = 0.0;
	int count = 0;
	for (double d : sim.skinDistances(sampled))
		if (std::abs(d) < 0.1)
		{
			sum += d;
			++count;
		}
	return count ? 1e3 * sum / count : 0.0;
}

/// Nodes within 5 mm of the skin (outside or in) at the end, and their median signed gap in mm.
std::pair<int, double> nearSkinNodes(const bodyfit::drape::DrapeSimulation& sim)
{
	std::vector<int> all(std::size_t(sim.nodeCount()));
	for (int i = 0; i < sim.nodeCount(); ++i)
		all[std::size_t(i)] = i;
	std::vector<double> near;
	for (double d : sim.skinDistances(all))
		if (std::abs(d) <= 0.005)
			near.push_back(d);
	return {int(near.size()), near.empty() ? 0.0 : 1e3 * bodyfit::median(near)};
}

/// Attaches the field to the collider's compound (the collider reads it from the next substep on).
void attachSkinField(bodyfit::drape::DrapeSimulation& sim, const btSkinDistanceField* field)
{
	btEllipsoidClothCollider* collider = sim.ellipsoidCollider();
	btEllipsoidCompoundShape* compound =
		collider ? dynamic_cast<btEllipsoidCompoundShape*>(collider->getBody()->getCollisionShape()) : nullptr;
	const char* why = "no ellipsoid collider";
	if (!compound || !compound->setSkinField(field, false, &why) || collider->getActiveSkinField() != field)
		throw std::runtime_error(std::string("colliders_patch (t): the skin field was not taken: ") + why);
}

/// Every ellipsoid of the collider's compound moved every step, as a skinning driver would: its centre by up to
/// `amplitude` metres and its axes turned by up to 0.05 rad, at about 1 Hz with a phase of its own (setEllipsoids).
class EllipsoidWiggle
{
public:
	EllipsoidWiggle(bodyfit::drape::DrapeSimulation& sim, double amplitude) : amplitude_(amplitude)
	{
		btEllipsoidClothCollider* collider = sim.ellipsoidCollider();
		compound_ = collider ? dynamic_cast<btEllipsoidCompoundShape*>(collider->getBody()->getCollisionShape()) : 0;
		if (!compound_ || !(compound_->getLocalScaling() == btVector3(1, 1, 1)))
			throw std::runtime_error("colliders_patch --moving: the body is not an unscaled btEllipsoidCompoundShape");
		for (int i = 0; i < compound_->getNumEllipsoids(); ++i)
			rest_.push_back(compound_->getEllipsoid(i));
		centers_.resize(rest_.size());
		bases_.resize(rest_.size());
		axes_.resize(rest_.size());
	}

	void apply(double t)
	{
		const double w = 2 * M_PI * t;
		for (std::size_t i = 0; i < rest_.size(); ++i)
		{
			const double phase = 0.7 * double(i);
			const btVector3 offset(btScalar(std::sin(w + phase)), btScalar(std::sin(1.3 * w + 2 * phase)),
								   btScalar(std::sin(0.7 * w + 3 * phase)));
			const btQuaternion turn(btVector3(1, btScalar(i % 3), 2).normalized(), btScalar(0.05 * std::sin(w + phase)));
			centers_[i] = rest_[i].m_center + offset * btScalar(amplitude_);
			bases_[i] = btMatrix3x3(turn) * rest_[i].m_basis;
			axes_[i] = rest_[i].m_semiAxes;
		}
		compound_->setEllipsoids(int(rest_.size()), centers_.data(), bases_.data(), axes_.data());
	}

private:
	double amplitude_;
	btEllipsoidCompoundShape* compound_ = nullptr;
	std::vector<btEllipsoidLocalData> rest_;
	std::vector<btVector3> centers_;
	std::vector<btMatrix3x3> bases_;
	std::vector<btVector3> axes_;
};

/// One case's simulation and its per-step records; `field` (not 0) runs (a)'s collider in TIGHT_SKIN mode on it.
class CaseRun
{
public:
	/// `moving`: every ellipsoid moved every step by up to s.movingMm (EllipsoidWiggle).
	CaseRun(ColliderKind kind, const Settings& s, const bodyfit::drape::BodyData& body, const btSkinDistanceField* field,
			bool moving = false)
		: s_(s), sim_(patchScene(kind, s, body.mesh), body)
	{
		if (field)
			attachSkinField(sim_, field);
		if (moving)
			wiggle_.reset(new EllipsoidWiggle(sim_, s.movingMm * 1e-3));
		r_.name = std::string(caseName(kind, field != nullptr)) + (moving ? ", every ellipsoid moving" : "");
		r_.settings = caseSettings(kind, s, body.ellipsoids.size()) + (field ? "; TIGHT_SKIN" : "");
		r_.nodes = sim_.nodeCount();
	}

	/// One step of the simulation and its records.
	void step()
	{
		if (wiggle_)
			wiggle_->apply(double(stepMs_.size() + 1) * s_.dt);
		const bodyfit::drape::StepStats st = sim_.step();
		stepMs_.push_back(st.cpuSeconds * 1e3);
		wallStepMs_.push_back(st.seconds * 1e3);
		collMs_.push_back(st.collisionCpuSeconds * 1e3);
		colliderMs_.push_back(st.colliderCpuSeconds * 1e3);
		wallCollMs_.push_back(st.collisionSeconds * 1e3);
		if (sim_.ellipsoidCollider())
			corrected_.push_back(sim_.ellipsoidCollider()->getLastSubstepStats().m_nodesCorrected);
		r_.insideWorst = std::max(r_.insideWorst, sim_.sample().insideBody);
		std::cerr << "  " << r_.name << ": step " << stepMs_.size() << "/" << s_.steps << ", "
				  << bodyfit_bench::fmt(stepMs_.back(), 1) << " ms CPU\n";
	}

	/// The end state and the medians over the steps after the cloth can first touch the head (free fall over
	/// `drop`), so short runs are not dominated by contact-free steps.
	Result finish()
	{
		const bodyfit::drape::ClothSample end = sim_.sample();
		r_.insideEnd = end.insideBody;
		r_.nanNodes = end.nanNodes;
		r_.minZeta = end.minZeta;
		const int firstContact = std::min(s_.steps - 1, int(std::ceil(std::sqrt(2.0 * s_.drop / 9.81) / s_.dt)));
		auto contactMedian = [&](const std::vector<double>& v) {
			return bodyfit::median(std::vector<double>(v.begin() + firstContact, v.end()));
		};
		r_.msPerStep = contactMedian(stepMs_);
		r_.collisionMsPerStep = contactMedian(collMs_);
		r_.colliderMsPerStep = contactMedian(colliderMs_);
		r_.wallMsPerStep = contactMedian(wallStepMs_);
		r_.wallCollisionMsPerStep = contactMedian(wallCollMs_);
		r_.firstMedianStep = firstContact;
		r_.correctedPerStep = corrected_.empty() ? 0.0 : contactMedian(corrected_);
		if (wiggle_)
		{
			// The scene runner's samples measure against the body at rest; the moved ellipsoids' own check is the
			// collider's smallest zeta of the last substep.
			r_.moving = true;
			r_.minZeta = double(sim_.ellipsoidCollider()->getLastSubstepStats().m_minZeta);
		}
		r_.meanGapMm = restingGapMm(sim_);
		std::tie(r_.nearSkin, r_.nearSkinMedianMm) = nearSkinNodes(sim_);
		r_.contacts = sim_.contacts();
		return r_;
	}

private:
	const Settings& s_;
	bodyfit::drape::DrapeSimulation sim_;
	Result r_;
	std::unique_ptr<EllipsoidWiggle> wiggle_;
	std::vector<double> stepMs_, collMs_, colliderMs_, wallStepMs_, wallCollMs_, corrected_;
};

Result runCase(ColliderKind kind, const Settings& s, const bodyfit::drape::BodyData& body,
			   const btSkinDistanceField* field = nullptr, bool moving = false)
{
	CaseRun run(kind, s, body, field, moving);
	for (int step = 0; step < s.steps; ++step)
		run.step();
	return run.finish();
}

/// Case (a) run s.repeats times: the last run's result with the median of the runs' collider and collision times.
Result repeatedCase(const Settings& s, const bodyfit::drape::BodyData& body, bool moving)
{
	std::vector<double> collider, collision;
	Result r;
	for (int i = 0; i < s.repeats; ++i)
	{
		r = runCase(ColliderKind::Ellipsoids, s, body, nullptr, moving);
		collider.push_back(r.colliderMsPerStep);
		collision.push_back(r.collisionMsPerStep);
	}
	r.colliderMsPerStep = bodyfit::median(collider);
	r.collisionMsPerStep = bodyfit::median(collision);
	return r;
}

/// (a) and (t) stepped in turn (which goes first alternates per step), so both see the same machine load: their
/// per-node cost ratio is the measurement.
std::pair<Result, Result> runPaired(const Settings& s, const bodyfit::drape::BodyData& body, const btSkinDistanceField* field)
{
	CaseRun loose(ColliderKind::Ellipsoids, s, body, nullptr);
	CaseRun tight(ColliderKind::Ellipsoids, s, body, field);
	for (int step = 0; step < s.steps; ++step)
	{
		CaseRun& first = step % 2 ? tight : loose;
		CaseRun& second = step % 2 ? loose : tight;
		first.step();
		second.step();
	}
	return {loose.finish(), tight.finish()};
}

Settings settingsFrom(const bodyfit_bench::Context& ctx)
{
	Settings s;
	if (ctx.quick)
	{
		s.resolution = 50;
		s.steps = 60;
	}
	s.steps = ctx.integer("--steps", s.steps, 1, 100000);
	s.resolution = ctx.integer("--resolution", s.resolution, 2, 1000);
	s.voxel = ctx.number("--voxel", s.voxel, 1e-4, 1.0);
	s.meshMargin = ctx.number("--mesh-margin", s.meshMargin, 0.0, 1.0);
	s.kKHR = ctx.number("--kkhr", s.kKHR, 0.0, 1.0);
	s.cases = ctx.text("--cases", s.cases);
	if (s.cases.empty() || s.cases.find_first_not_of("abct") != std::string::npos)
		throw bodyfit_cli::UsageError("--cases: expected letters from \"abct\", got \"" + s.cases + "\"");
	s.movingMm = ctx.number("--moving", s.movingMm, 0.0, 100.0);
	s.repeats = ctx.repeatsGiven ? ctx.repeats : 1;
	return s;
}

/// A contact-gap statistic in mm, "-" when no contact node has a gap.
std::string gapCell(const bodyfit::metrics::GapSummary& gap, double metres)
{
	return gap.count ? bodyfit_bench::fmt(metres * 1e3, 1) : std::string("-");
}

} // namespace

BODYFIT_BENCH_SUITE_WITH_OPTIONS(colliders_patch,
								 "issue 4: 100x100 patch dropped on the body, 2 s at 60 Hz: ellipsoid collider vs Bullet "
								 "SDF_RS on the BVH mesh and on the same compound (--quick: 50x50, 1 s)",
								 {"--cases", "LETTERS", "subset of abct to run (default abc; t = (a) in TIGHT_SKIN mode on the baked skin field)"},
								 {"--steps", "N", "steps of 1/60 s (default 120, --quick 60)"},
								 {"--resolution", "N", "patch nodes per side (default 100, --quick 50)"},
								 {"--voxel", "M", "sparse-SDF voxel of the Bullet paths, metres (default 0.02)"},
								 {"--mesh-margin", "M", "btBvhTriangleMeshShape margin of (b), metres (default 0)"},
								 {"--kkhr", "K", "Bullet's static contact hardness kKHR, 0..1 (default 1)"},
								 {"--moving", "MM", "also time (a) with every ellipsoid moved every step by up to MM mm "
													"(setEllipsoids, 1 Hz; default 0: off); with --repeats"})
{
	const Settings s = settingsFrom(ctx);
	const std::string& cases = s.cases;
	const std::string meshFile = "female_young.obj";
	const std::string meshPath = std::string(BODYFIT_ASSET_DIR) + "/" + meshFile;
	std::cerr << "colliders_patch: loading " << meshPath << "\n";
	const bodyfit::LoadedMesh mesh = bodyfit::loadTriMesh(meshPath);

	// Ellipsoids: the bundled fit of this body if present, else fit now (same default options as bodyfit-fit).
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	std::string source;
	const std::string fitPath = std::string(BODYFIT_ASSET_DIR) + "/fits/female_young.json";
	if (std::filesystem::exists(fitPath))
	{
		for (const bodyfit::FittedEllipsoid& f : bodyfit::readEllipsoidJson(fitPath).ellipsoids)
			ellipsoids.push_back(f.ellipsoid);
		source = "fits/female_young.json";
	}
	else
	{
		std::cerr << "colliders_patch: no " << fitPath << ", fitting the body\n";
		const bodyfit::FitPipelineResult fitted = bodyfit::fitMeshFile(meshPath);
		for (const bodyfit::FittedEllipsoid& f : fitted.fit.ellipsoids)
			ellipsoids.push_back(f.ellipsoid);
		source = "fitted in process (default options)";
	}
	std::cout << "body " << meshFile << " (" << mesh.full.V.rows() << " vertices, " << mesh.full.F.rows()
			  << " triangles), " << ellipsoids.size() << " ellipsoids (" << source << "); patch " << s.resolution << "x"
			  << s.resolution << " nodes, " << s.size << " m, " << s.steps << " steps of 1/60 s, 1 substep, piterations "
			  << s.iterations << "; btScalar " << (sizeof(btScalar) == 8 ? "double" : "float") << "\n\n";

	bodyfit::drape::BodyData body;
	body.mesh = mesh.full;
	body.ellipsoids = ellipsoids;
	body.meshPath = meshPath;
	body.ellipsoidSource = source;
	std::vector<Result> results;
	std::unique_ptr<btSkinDistanceField> skinField;
	if (cases.find('t') != std::string::npos)
	{
		bodyfit::SkinFieldOptions skinOptions;
		skinOptions.skinOffset = s.skin;
		std::cerr << "colliders_patch: skin field bake (bodyfit::bakeSkinField, h 5 mm, clamp 12 mm)\n";
		const auto t0 = std::chrono::steady_clock::now();
		const bodyfit::SkinField baked = bodyfit::bakeSkinField(mesh.full, ellipsoids, skinOptions);
		const double bakeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
		skinField = bodyfit::createSkinDistanceField(baked);
		std::cout << "(t) field: bodyfit::bakeSkinField, " << baked.storedBricks() << " of " << baked.brickCount()
				  << " bricks stored, " << bodyfit_bench::fmt(bakeSeconds * 1e3, 1) << " ms; Lipschitz bound "
				  << bodyfit_bench::fmt(double(skinField->getLipschitz()), 3) << ", seam "
				  << bodyfit_bench::fmt(double(skinField->getSeam()) * 1e3, 4) << " mm, max error (band and skin samples) "
				  << bodyfit_bench::fmt(baked.maxError * 1e3, 3) << " mm\n\n";
	}
	const bool paired = cases.find('a') != std::string::npos && skinField;
	Result pairedTight;
	if (paired)
	{
		const std::pair<Result, Result> both = runPaired(s, body, skinField.get());
		results.push_back(both.first);
		pairedTight = both.second;
	}
	else if (cases.find('a') != std::string::npos)
		results.push_back(repeatedCase(s, body, false));
	if (cases.find('a') != std::string::npos && s.movingMm > 0)
		results.push_back(repeatedCase(s, body, true));
	if (cases.find('b') != std::string::npos)
		results.push_back(runCase(ColliderKind::MeshBvh, s, body));
	if (cases.find('c') != std::string::npos)
		results.push_back(runCase(ColliderKind::EllipsoidsSdf, s, body));
	if (paired)
		results.push_back(pairedTight);
	else if (skinField)
		results.push_back(runCase(ColliderKind::Ellipsoids, s, body, skinField.get()));

	bodyfit_bench::Table t({"collider", "ms/step (CPU)", "collision ms/step (CPU)", "collision ns/node",
							"of which our collider ns/node", "ms/step (wall)", "collision ms/step (wall)", "inside mesh (end)", "inside mesh (worst)",
							"NaN nodes", "mean gap of resting nodes (mm)", "nodes within 5 mm of the skin", "their median gap (mm)", "contact nodes", "contact gap mean (mm)",
							"contact gap p95 (mm)", "contact gap max (mm)",
							"min zeta (end)", "settings"});
	for (const Result& r : results)
		t.addRow({r.name, bodyfit_bench::fmt(r.msPerStep, 3), bodyfit_bench::fmt(r.collisionMsPerStep, 3),
				  bodyfit_bench::fmt(r.collisionMsPerStep * 1e6 / std::max(1, r.nodes), 1),
				  r.name.rfind("(a)", 0) == 0 || r.name.rfind("(t)", 0) == 0 ? bodyfit_bench::fmt(r.colliderMsPerStep * 1e6 / std::max(1, r.nodes), 1)
											: std::string("-"),
				  bodyfit_bench::fmt(r.wallMsPerStep, 3), bodyfit_bench::fmt(r.wallCollisionMsPerStep, 3),
				  r.moving ? std::string("-") : bodyfit_bench::fmtInt(r.insideEnd),
				  r.moving ? std::string("-") : bodyfit_bench::fmtInt(r.insideWorst), bodyfit_bench::fmtInt(r.nanNodes), bodyfit_bench::fmt(r.meanGapMm, 1),
				  bodyfit_bench::fmtInt(r.nearSkin), bodyfit_bench::fmt(r.nearSkinMedianMm, 2),
				  bodyfit_bench::fmtInt(r.contacts.contactNodes),
				  gapCell(r.contacts.gap, r.contacts.gap.mean), gapCell(r.contacts.gap, r.contacts.gap.p95),
				  gapCell(r.contacts.gap, r.contacts.gap.max),
				  bodyfit_bench::fmt(r.minZeta, 4), r.settings});
	bodyfit_bench::emit(ctx, "colliders_patch", t);
	std::cout << "\nTimes are medians over steps " << (results.empty() ? 0 : results[0].firstMedianStep) + 1 << ".."
			  << s.steps << " (from the first possible contact); CPU = this thread's CPU time, wall = elapsed.\n";
	if (s.movingMm > 0 && cases.find('a') != std::string::npos)
		std::cout << "\ncollider with every ellipsoid moving (up to " << s.movingMm << " mm per step) vs static: "
				  << bodyfit_bench::fmt(results[1].colliderMsPerStep / std::max(1e-9, results[0].colliderMsPerStep), 2)
				  << "x (" << bodyfit_bench::fmt(results[1].colliderMsPerStep * 1e6 / std::max(1, results[1].nodes), 1)
				  << " vs " << bodyfit_bench::fmt(results[0].colliderMsPerStep * 1e6 / std::max(1, results[0].nodes), 1)
				  << " ns/node; median of " << s.repeats << " run(s)); nodes placed on the surface per step (median) "
				  << bodyfit_bench::fmt(results[1].correctedPerStep, 0) << " vs " << bodyfit_bench::fmt(results[0].correctedPerStep, 0)
				  << "\n";
	if (cases == "abc" && s.movingMm <= 0)
		std::cout << "\ncollision speed-up of (a): "
				  << bodyfit_bench::fmt(results[1].collisionMsPerStep / std::max(1e-9, results[0].collisionMsPerStep), 1)
				  << "x over (b), "
				  << bodyfit_bench::fmt(results[2].collisionMsPerStep / std::max(1e-9, results[0].collisionMsPerStep), 1)
				  << "x over (c)\n";
	const auto tight = std::find_if(results.begin(), results.end(), [](const Result& r) { return r.name.rfind("(t)", 0) == 0; });
	const auto loose = std::find_if(results.begin(), results.end(), [](const Result& r) { return r.name.rfind("(a)", 0) == 0; });
	if (tight != results.end() && loose != results.end())
		std::cout << "\ncollider cost, TIGHT_SKIN (t) / ELLIPSOIDS (a): "
				  << bodyfit_bench::fmt(tight->colliderMsPerStep / std::max(1e-9, loose->colliderMsPerStep), 2)
				  << "x per node (" << bodyfit_bench::fmt(tight->colliderMsPerStep * 1e6 / std::max(1, tight->nodes), 1)
				  << " vs " << bodyfit_bench::fmt(loose->colliderMsPerStep * 1e6 / std::max(1, loose->nodes), 1)
				  << " ns/node)\n";
	return 0;
}
