// bodyfit-bench colliders_patch: the issue-4 measurement. One process, one scene: a 100 x 100-node cloth patch
// dropped onto the bundled body (female_young), 2 s at 60 Hz (120 steps, one substep each), same cloth and solver
// settings for every collider:
//   (a) btEllipsoidClothCollider on the fitted ellipsoid compound (Bullet's own response to the body turned off);
//   (b) Bullet's default soft-body path (SDF_RS) against a btBvhTriangleMeshShape of the body mesh;
//   (c) Bullet's default path against the same ellipsoid compound (sparse SDF on each btEllipsoidShape child).
// Per step: wall time of stepSimulation, collision time (soft-rigid collision detection inside
// performDiscreteCollisionDetection + the collider's own time), and the number of nodes inside the real body mesh
// (MeshInsideTest: ray parity per component, 3-axis vote, against the original mesh, not the ellipsoids).
// Reported: medians over the steps, nodes inside at the end and at worst, NaN nodes, mean gap of resting nodes.
#include "bench/bench_common.h"

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/inside_test.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/fit_pipeline.h"

#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/bullet_ext/btEllipsoidClothCollider.h"

#include "BulletCollision/BroadphaseCollision/btDbvtBroadphase.h"
#include "BulletCollision/CollisionDispatch/btCollisionDispatcher.h"
#include "BulletCollision/CollisionShapes/btBvhTriangleMeshShape.h"
#include "BulletCollision/CollisionShapes/btTriangleIndexVertexArray.h"
#include "BulletDynamics/ConstraintSolver/btSequentialImpulseConstraintSolver.h"
#include "BulletSoftBody/btSoftBodyHelpers.h"
#include "BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <memory>

namespace
{

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// CPU time of this thread in ms: the primary timing here, because wall time on a shared, busy machine mostly
/// measures the other processes (the wall-clock medians are reported next to it).
double cpuMs()
{
	timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
}

/// btSoftRigidDynamicsWorld that times its collision-detection phase (where Bullet's soft-rigid contacts are made).
class TimedWorld : public btSoftRigidDynamicsWorld
{
public:
	using btSoftRigidDynamicsWorld::btSoftRigidDynamicsWorld;
	double collisionMs = 0.0;
	double collisionCpuMs = 0.0;
	void performDiscreteCollisionDetection() override
	{
		const Clock::time_point t0 = Clock::now();
		const double c0 = cpuMs();
		btSoftRigidDynamicsWorld::performDiscreteCollisionDetection();
		collisionCpuMs += cpuMs() - c0;
		collisionMs += msSince(t0);
	}
};

enum class Kind
{
	Ellipsoids,   // (a)
	MeshSdf,      // (b)
	CompoundSdf,  // (c)
};

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
	double minZeta = 0.0;   // smallest zeta over all nodes and ellipsoids at the end (ellipsoid runs)
	int firstMedianStep = 0; // medians are over steps [firstMedianStep, steps)
};

double median(std::vector<double> v)
{
	std::sort(v.begin(), v.end());
	const size_t m = v.size() / 2;
	return v.empty() ? 0.0 : (v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]));
}

/// Unsigned distance from p to the mesh surface (brute force; only used for the gap of a node sample).
double distanceToMesh(const bodyfit::TriMesh& m, const Eigen::Vector3d& p)
{
	double best = 1e300;
	for (int f = 0; f < m.F.rows(); ++f)
	{
		const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
		// Closest point on triangle (Ericson, Real-Time Collision Detection 5.1.5).
		const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
		const double d1 = ab.dot(ap), d2 = ac.dot(ap);
		Eigen::Vector3d q;
		if (d1 <= 0 && d2 <= 0)
			q = a;
		else
		{
			const Eigen::Vector3d bp = p - b;
			const double d3 = ab.dot(bp), d4 = ac.dot(bp);
			const Eigen::Vector3d cp = p - c;
			const double d5 = ab.dot(cp), d6 = ac.dot(cp);
			const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
			if (d3 >= 0 && d4 <= d3)
				q = b;
			else if (d6 >= 0 && d5 <= d6)
				q = c;
			else if (vc <= 0 && d1 >= 0 && d3 <= 0)
				q = a + ab * (d1 / (d1 - d3));
			else if (vb <= 0 && d2 >= 0 && d6 <= 0)
				q = a + ac * (d2 / (d2 - d6));
			else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
				q = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
			else
			{
				const double denom = 1.0 / (va + vb + vc);
				q = a + ab * (vb * denom) + ac * (vc * denom);
			}
		}
		best = std::min(best, (p - q).squaredNorm());
	}
	return std::sqrt(best);
}

Result runCase(Kind kind, const Settings& s, const bodyfit::TriMesh& body, const bodyfit::MeshInsideTest& inside,
			   const std::vector<bodyfit::Ellipsoid>& ellipsoids)
{
	btSoftBodyRigidBodyCollisionConfiguration config;
	btCollisionDispatcher dispatcher(&config);
	btDbvtBroadphase broadphase;
	btSequentialImpulseConstraintSolver solver;
	btEllipsoidClothSoftBodySolver softSolver; // same solver class for all runs; only (a) installs a collider
	TimedWorld world(&dispatcher, &broadphase, &solver, &config, &softSolver);
	world.setGravity(btVector3(0, btScalar(-9.81), 0));
	btSoftBodyWorldInfo& info = world.getWorldInfo();
	info.m_gravity.setValue(0, btScalar(-9.81), 0);
	info.m_sparsesdf.setDefaultVoxelsz(btScalar(s.voxel));
	info.m_sparsesdf.Reset();

	Result r;
	// Body collider.
	std::unique_ptr<btEllipsoidCompoundShape> compound;
	std::unique_ptr<btTriangleIndexVertexArray> triangles;
	std::unique_ptr<btBvhTriangleMeshShape> meshShape;
	std::vector<int> indices;
	std::vector<btScalar> vertices;
	btCollisionShape* shape = nullptr;
	if (kind == Kind::MeshSdf)
	{
		indices.resize(size_t(body.F.size()));
		for (int f = 0; f < body.F.rows(); ++f)
			for (int k = 0; k < 3; ++k)
				indices[size_t(3 * f + k)] = body.F(f, k);
		vertices.resize(size_t(body.V.size()));
		for (int v = 0; v < body.V.rows(); ++v)
			for (int k = 0; k < 3; ++k)
				vertices[size_t(3 * v + k)] = btScalar(body.V(v, k));
		triangles.reset(new btTriangleIndexVertexArray(int(body.F.rows()), indices.data(), 3 * int(sizeof(int)),
													   int(body.V.rows()), vertices.data(), 3 * int(sizeof(btScalar))));
		meshShape.reset(new btBvhTriangleMeshShape(triangles.get(), true));
		meshShape->setMargin(btScalar(s.meshMargin));
		shape = meshShape.get();
		r.name = "(b) Bullet SDF_RS vs btBvhTriangleMeshShape";
	}
	else
	{
		compound = bodyfit::createEllipsoidCompound(ellipsoids);
		shape = compound.get();
		r.name = kind == Kind::Ellipsoids ? "(a) btEllipsoidClothCollider" : "(c) Bullet SDF_RS vs ellipsoid compound";
	}
	btCollisionObject bodyObject;
	bodyObject.setCollisionShape(shape);
	bodyObject.setFriction(btScalar(1.0));
	world.addCollisionObject(&bodyObject, btBroadphaseProxy::StaticFilter,
							 btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter);

	// Cloth: centred over the head (mean x, z of the top 10% of the vertices).
	const double top = body.V.col(1).maxCoeff();
	const double h = top - body.V.col(1).minCoeff();
	Eigen::Vector2d c(0, 0);
	int n = 0;
	for (int i = 0; i < body.V.rows(); ++i)
		if (body.V(i, 1) > top - 0.1 * h)
		{
			c += Eigen::Vector2d(body.V(i, 0), body.V(i, 2));
			++n;
		}
	c /= double(std::max(1, n));
	const btScalar y = btScalar(top + s.drop), hs = btScalar(s.size / 2);
	const btScalar cx = btScalar(c.x()), cz = btScalar(c.y());
	btSoftBody* cloth = btSoftBodyHelpers::CreatePatch(info, btVector3(cx - hs, y, cz - hs), btVector3(cx + hs, y, cz - hs),
													   btVector3(cx - hs, y, cz + hs), btVector3(cx + hs, y, cz + hs),
													   s.resolution, s.resolution, 0, true);
	cloth->getCollisionShape()->setMargin(btScalar(s.clothMargin));
	cloth->m_cfg.piterations = s.iterations;
	cloth->m_cfg.kDP = btScalar(0.01);
	cloth->m_cfg.kDF = btScalar(s.friction);
	cloth->m_cfg.kKHR = btScalar(s.kKHR);
	cloth->m_materials[0]->m_kLST = btScalar(0.9);
	cloth->setTotalMass(btScalar(0.25));
	world.addSoftBody(cloth);
	r.nodes = cloth->m_nodes.size();

	btEllipsoidClothCollider* collider = nullptr;
	if (kind == Kind::Ellipsoids)
	{
		btEllipsoidClothCollider::Config cc;
		cc.m_skinOffset = btScalar(s.skin);
		cc.m_friction = btScalar(s.friction);
		const char* why = nullptr;
		collider = btEllipsoidClothCollider::install(&world, &bodyObject, cc, &why);
		if (!collider)
			throw std::runtime_error(why ? why : "collider install failed");
		r.settings = "skin " + bodyfit_bench::fmtGeneral(s.skin * 1e3) + " mm; friction " +
					 bodyfit_bench::fmtGeneral(s.friction) + "; " + std::to_string(ellipsoids.size()) + " ellipsoids";
	}
	else
		r.settings = "voxel " + bodyfit_bench::fmtGeneral(s.voxel * 1e3) + " mm; cloth margin " +
					 bodyfit_bench::fmtGeneral(s.clothMargin * 1e3) + " mm; kKHR " + bodyfit_bench::fmtGeneral(s.kKHR) +
					 (kind == Kind::MeshSdf ? "; mesh margin " + bodyfit_bench::fmtGeneral(s.meshMargin * 1e3) +
												  " mm (+ Bullet's fixed 60 mm prism extrusion)"
											: "; child margin " +
												  bodyfit_bench::fmtGeneral(double(compound->getChildMargin()) * 1e3) +
												  " mm");

	std::vector<double> stepMs, collMs, colliderMs, wallStepMs, wallCollMs;
	Eigen::MatrixX3d nodes(r.nodes, 3);
	auto countInside = [&]() {
		for (int i = 0; i < r.nodes; ++i)
			nodes.row(i) = Eigen::Vector3d(cloth->m_nodes[i].m_x.x(), cloth->m_nodes[i].m_x.y(), cloth->m_nodes[i].m_x.z());
		return inside.countInside(nodes);
	};
	for (int step = 0; step < s.steps; ++step)
	{
		world.collisionMs = 0.0;
		world.collisionCpuMs = 0.0;
		if (collider)
			collider->resetStats();
		const Clock::time_point t0 = Clock::now();
		const double c0 = cpuMs();
		world.stepSimulation(btScalar(s.dt), 1, btScalar(s.dt));
		stepMs.push_back(cpuMs() - c0);
		wallStepMs.push_back(msSince(t0));
		const btEllipsoidClothStats* cs = collider ? &collider->getAccumulatedStats() : nullptr;
		collMs.push_back(world.collisionCpuMs + (cs ? cs->m_collisionCpuSeconds * 1e3 : 0.0));
		colliderMs.push_back(cs ? cs->m_collisionCpuSeconds * 1e3 : 0.0);
		wallCollMs.push_back(world.collisionMs + (cs ? cs->m_collisionSeconds * 1e3 : 0.0));
		r.insideWorst = std::max(r.insideWorst, countInside());
		std::cerr << "  " << r.name << ": step " << step + 1 << "/" << s.steps << ", " << bodyfit_bench::fmt(stepMs.back(), 1)
				  << " ms CPU\n";
	}
	r.insideEnd = countInside();
	// Medians over the steps after the cloth can first touch the head (free fall over `drop`), so short runs are
	// not dominated by contact-free steps.
	const int firstContact = std::min(s.steps - 1, int(std::ceil(std::sqrt(2.0 * s.drop / 9.81) / s.dt)));
	auto contactMedian = [&](const std::vector<double>& v) {
		return median(std::vector<double>(v.begin() + firstContact, v.end()));
	};
	r.msPerStep = contactMedian(stepMs);
	r.collisionMsPerStep = contactMedian(collMs);
	r.colliderMsPerStep = contactMedian(colliderMs);
	r.wallMsPerStep = contactMedian(wallStepMs);
	r.wallCollisionMsPerStep = contactMedian(wallCollMs);
	r.firstMedianStep = firstContact;
	for (int i = 0; i < r.nodes; ++i)
		if (!nodes.row(i).allFinite())
			++r.nanNodes;
	// Gap of resting nodes: distance to the skin of every 16th node that is within 10 cm of it.
	double gapSum = 0.0;
	int gapCount = 0;
	for (int i = 0; i < r.nodes; i += 16)
	{
		const Eigen::Vector3d p = nodes.row(i).transpose();
		if (!p.allFinite())
			continue;
		const double d = distanceToMesh(body, p);
		if (d < 0.1)
		{
			gapSum += inside.isInside(p) ? -d : d;
			++gapCount;
		}
	}
	r.meanGapMm = gapCount ? 1e3 * gapSum / gapCount : 0.0;
	r.minZeta = 1e30;
	for (const bodyfit::Ellipsoid& e : ellipsoids)
		for (int i = 0; i < r.nodes; ++i)
			if (nodes.row(i).allFinite())
				r.minZeta = std::min(r.minZeta, e.zeta(nodes.row(i).transpose()));

	world.removeSoftBody(cloth);
	delete cloth;
	world.removeCollisionObject(&bodyObject);
	return r;
}

} // namespace

BODYFIT_BENCH_SUITE(colliders_patch, "issue 4: 100x100 patch dropped on the body, 2 s at 60 Hz: ellipsoid collider "
									 "vs Bullet SDF_RS on the BVH mesh and on the same compound (--quick: 50x50, 1 s)")
{
	Settings s;
	if (ctx.quick)
	{
		s.resolution = 50;
		s.steps = 60;
	}
	// Tuning knobs for the Bullet paths and partial runs (environment, so the command line stays the bench's):
	// BODYFIT_COLLIDERS_CASES=abc subset, BODYFIT_COLLIDERS_STEPS=N, BODYFIT_COLLIDERS_RES=N, BODYFIT_COLLIDERS_VOXEL=m,
	// BODYFIT_COLLIDERS_MESH_MARGIN=m, BODYFIT_COLLIDERS_KKHR=k.
	auto envNumber = [](const char* name, double fallback, double lo, double hi) {
		const char* v = std::getenv(name);
		if (!v || !*v)
			return fallback;
		char* end = nullptr;
		const double d = std::strtod(v, &end);
		if (*end != '\0' || !(d >= lo && d <= hi))
			throw std::runtime_error(std::string(name) + ": expected a number in [" + std::to_string(lo) + ", " +
									 std::to_string(hi) + "], got \"" + v + "\"");
		return d;
	};
	s.steps = int(envNumber("BODYFIT_COLLIDERS_STEPS", s.steps, 1, 100000));
	s.resolution = int(envNumber("BODYFIT_COLLIDERS_RES", s.resolution, 2, 1000));
	s.voxel = envNumber("BODYFIT_COLLIDERS_VOXEL", s.voxel, 1e-4, 1.0);
	s.meshMargin = envNumber("BODYFIT_COLLIDERS_MESH_MARGIN", s.meshMargin, 0.0, 1.0);
	s.kKHR = envNumber("BODYFIT_COLLIDERS_KKHR", s.kKHR, 0.0, 1.0);
	const std::string cases = std::getenv("BODYFIT_COLLIDERS_CASES") ? std::getenv("BODYFIT_COLLIDERS_CASES") : "abc";
	if (cases.empty() || cases.find_first_not_of("abc") != std::string::npos)
		throw std::runtime_error("BODYFIT_COLLIDERS_CASES: expected letters from \"abc\", got \"" + cases + "\"");
	const std::string meshFile = "female_young.obj";
	const std::string meshPath = std::string(BODYFIT_ASSET_DIR) + "/" + meshFile;
	std::cerr << "colliders_patch: loading " << meshPath << "\n";
	const bodyfit::LoadedMesh mesh = bodyfit::loadTriMesh(meshPath);
	const bodyfit::MeshInsideTest inside(mesh.full);

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

	std::vector<Result> results;
	if (cases.find('a') != std::string::npos)
		results.push_back(runCase(Kind::Ellipsoids, s, mesh.full, inside, ellipsoids));
	if (cases.find('b') != std::string::npos)
		results.push_back(runCase(Kind::MeshSdf, s, mesh.full, inside, ellipsoids));
	if (cases.find('c') != std::string::npos)
		results.push_back(runCase(Kind::CompoundSdf, s, mesh.full, inside, ellipsoids));

	bodyfit_bench::Table t({"collider", "ms/step (CPU)", "collision ms/step (CPU)", "collision ns/node",
							"of which our collider ns/node", "ms/step (wall)", "collision ms/step (wall)", "inside mesh (end)", "inside mesh (worst)",
							"NaN nodes", "mean gap of resting nodes (mm)", "min zeta (end)", "settings"});
	for (const Result& r : results)
		t.addRow({r.name, bodyfit_bench::fmt(r.msPerStep, 3), bodyfit_bench::fmt(r.collisionMsPerStep, 3),
				  bodyfit_bench::fmt(r.collisionMsPerStep * 1e6 / std::max(1, r.nodes), 1),
				  r.name.rfind("(a)", 0) == 0 ? bodyfit_bench::fmt(r.colliderMsPerStep * 1e6 / std::max(1, r.nodes), 1)
											: std::string("-"),
				  bodyfit_bench::fmt(r.wallMsPerStep, 3), bodyfit_bench::fmt(r.wallCollisionMsPerStep, 3),
				  bodyfit_bench::fmtInt(r.insideEnd),
				  bodyfit_bench::fmtInt(r.insideWorst), bodyfit_bench::fmtInt(r.nanNodes), bodyfit_bench::fmt(r.meanGapMm, 1),
				  bodyfit_bench::fmt(r.minZeta, 4), r.settings});
	bodyfit_bench::emit(ctx, "colliders_patch", t);
	std::cout << "\nTimes are medians over steps " << (results.empty() ? 0 : results[0].firstMedianStep) + 1 << ".."
			  << s.steps << " (from the first possible contact); CPU = this thread's CPU time, wall = elapsed.\n";
	if (cases == "abc")
		std::cout << "\ncollision speed-up of (a): "
				  << bodyfit_bench::fmt(results[1].collisionMsPerStep / std::max(1e-9, results[0].collisionMsPerStep), 1)
				  << "x over (b), "
				  << bodyfit_bench::fmt(results[2].collisionMsPerStep / std::max(1e-9, results[0].collisionMsPerStep), 1)
				  << "x over (c)\n";
	return 0;
}
