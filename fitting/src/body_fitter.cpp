// Pruned bisecting K-means refinement with MVEEs (paper sec. 3.3; docs/DESIGN.md sec. 2). See body_fitter.h.
#include "bodyfit/fitting/body_fitter.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/kmeans.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/parallel.h"
#include "bodyfit/fitting/triangle_cover.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace bodyfit
{

const char* toString(RefineStatus status)
{
	switch (status)
	{
	case RefineStatus::Converged: return "converged";
	case RefineStatus::Frozen: return "frozen";
	case RefineStatus::BudgetReached: return "budget-reached";
	case RefineStatus::SplitCapReached: return "split-cap-reached";
	}
	return "unknown";
}

double BodyFit::meanRadialError() const
{
	double sum = 0.0;
	long long count = 0;
	for (const FittedEllipsoid& e : ellipsoids)
	{
		sum += e.radialError * e.vertexCount;
		count += e.vertexCount;
	}
	return count > 0 ? sum / double(count) : 0.0;
}

double BodyFit::maxRadialError() const
{
	double m = 0.0;
	for (const FittedEllipsoid& e : ellipsoids)
		m = std::max(m, e.radialError);
	return m;
}

double BodyFit::meanDistance() const
{
	double sum = 0.0;
	long long count = 0;
	for (const FittedEllipsoid& e : ellipsoids)
	{
		sum += e.meanDistance * e.vertexCount;
		count += e.vertexCount;
	}
	return count > 0 ? sum / double(count) : 0.0;
}

double BodyFit::maxDistance() const
{
	double m = 0.0;
	for (const FittedEllipsoid& e : ellipsoids)
		m = std::max(m, e.maxDistance);
	return m;
}

double BodyFit::timingMs(const std::string& stage) const
{
	for (const StageTiming& t : timings)
		if (t.stage == stage)
			return t.ms;
	return 0.0;
}

void BodyFit::setTiming(const std::string& stage, double ms)
{
	for (StageTiming& t : timings)
		if (t.stage == stage)
		{
			t.ms = ms;
			return;
		}
	timings.push_back({stage, ms});
}

namespace
{

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct Cluster
{
	std::vector<int> members; ///< indices into the group's points, ascending
	EllipsoidFit fit;
	double error = 0.0; ///< E_j
	bool frozen = false;
	/// Points of triangles across a cluster boundary that this ellipsoid also encloses so that the union covers the
	/// skin there (coverTriangles); in insertion order, after `members` in the MVEE input.
	std::vector<Eigen::Vector3d> extras;
};

/// A set of vertices refined together: the torso (k0 = its parts), or one other region (k0 = 1).
struct Group
{
	Region region = Region::Whole; ///< for the torso group: its first part (clusters get their majority part)
	bool torso = false;
	double mu = 0.0;               ///< threshold on E_j, metres
	std::vector<int> vertices;     ///< mesh vertex indices, ascending
	Eigen::MatrixX3d points;       ///< their positions
	Eigen::MatrixX3d centers;      ///< K-means centres, one per cluster
	std::vector<int> assignment;   ///< cluster of every point
	std::vector<double> lowerBounds; ///< K-means warm-start bounds for `centers`
	std::vector<Cluster> clusters;
	bool localSplits = false;      ///< split with K-means on the split cluster's points only (see reclusterGroup)
};

/// MVEE and E_j of one cluster at a time, with scratch of its own: one per thread, so that clusters whose fits are
/// independent can be fitted at once.
class ClusterFitter
{
public:
	explicit ClusterFitter(const MveeOptions& mvee) : mvee_(mvee) {}

	double mveeMs = 0.0, errorMs = 0.0;

	/// MVEE and E_j of a cluster. With `parent`, the parent's MVEE core points that are also in this cluster
	/// seed the active set (mvee.h warm start).
	void fit(const Group& g, Cluster& c, const Cluster* parent = nullptr)
	{
		buffer_.resize(Eigen::Index(c.members.size()), 3);
		for (std::size_t r = 0; r < c.members.size(); ++r)
			buffer_.row(Eigen::Index(r)) = g.points.row(c.members[r]);
		warm_.clear();
		if (parent != nullptr)
		{
			if (rowOf_.size() < std::size_t(g.points.rows()))
				rowOf_.assign(std::size_t(g.points.rows()), -1);
			for (std::size_t r = 0; r < c.members.size(); ++r)
				rowOf_[std::size_t(c.members[r])] = int(r);
			for (int core : parent->fit.coreIndices)
			{
				const int row = rowOf_[std::size_t(parent->members[std::size_t(core)])];
				if (row >= 0)
					warm_.push_back(row);
			}
			for (int m : c.members)
				rowOf_[std::size_t(m)] = -1;
		}
		solve(g, c);
	}

	/// Refits cluster c on its members plus its extra points; E_j stays the error over its own members.
	/// Extras are only ever appended, so the previous core indices are still valid rows and seed the active set.
	void refitWithExtras(const Group& g, Cluster& c)
	{
		const Eigen::Index n = Eigen::Index(c.members.size());
		buffer_.resize(n + Eigen::Index(c.extras.size()), 3);
		for (Eigen::Index r = 0; r < n; ++r)
			buffer_.row(r) = g.points.row(c.members[std::size_t(r)]);
		for (std::size_t e = 0; e < c.extras.size(); ++e)
			buffer_.row(n + Eigen::Index(e)) = c.extras[e].transpose();
		warm_.clear();
		for (int core : c.fit.coreIndices)
			if (core >= 0 && core < buffer_.rows())
				warm_.push_back(core);
		solve(g, c);
	}

private:
	/// The MVEE of buffer_ (warm-started from warm_ when it is not empty) and E_j over c's members.
	void solve(const Group& g, Cluster& c)
	{
		Clock::time_point t0 = Clock::now();
		c.fit = warm_.empty() ? minimumVolumeEllipsoid(buffer_, mvee_) : minimumVolumeEllipsoid(buffer_, mvee_, warm_);
		Clock::time_point t1 = Clock::now();
		mveeMs += std::chrono::duration<double, std::milli>(t1 - t0).count();
		c.error = meanRadialError(c.fit.ellipsoid, g.points, c.members);
		errorMs += msSince(t1);
	}

	MveeOptions mvee_;
	Eigen::MatrixX3d buffer_;
	std::vector<int> warm_;  ///< warm-start rows of the cluster being fitted
	std::vector<int> rowOf_; ///< group point -> row in the cluster being fitted, -1 elsewhere (kept all -1 between uses)
};

/// One cluster fit of a batch: cluster c of group g, warm-started from `parent` (may be null).
struct FitTask
{
	const Group* g = nullptr;
	Cluster* c = nullptr;
	const Cluster* parent = nullptr;
	bool withExtras = false; ///< refitWithExtras instead of fit
};

class Refiner
{
public:
	/// `threads` >= 1: independent cluster fits of one step run on that many threads (fitAll).
	Refiner(const KMeansOptions& kmeans, const MveeOptions& mvee, int threads)
		: kmeans_(kmeans), fitters_(std::size_t(std::max(1, threads)), ClusterFitter(mvee))
	{
	}

	double kmeansMs = 0.0;
	double mveeMs() const
	{
		double ms = 0.0;
		for (const ClusterFitter& f : fitters_)
			ms += f.mveeMs;
		return ms;
	}
	double errorMs() const
	{
		double ms = 0.0;
		for (const ClusterFitter& f : fitters_)
			ms += f.errorMs;
		return ms;
	}

	/// Runs the fits of `tasks` (independent: each writes its own cluster only) on the threads; the result is the
	/// same for any thread count.
	void fitAll(const std::vector<FitTask>& tasks)
	{
		parallelParts(int(tasks.size()), int(fitters_.size()), [&](int part, int begin, int end) {
			ClusterFitter& fitter = fitters_[std::size_t(part)];
			for (int t = begin; t < end; ++t)
			{
				const FitTask& task = tasks[std::size_t(t)];
				if (task.withExtras)
					fitter.refitWithExtras(*task.g, *task.c);
				else
					fitter.fit(*task.g, *task.c, task.parent);
			}
		});
	}

	/// Pruned K-means from `initialCenters`, then an MVEE per non-empty cluster (empty ones are dropped).
	void initialise(Group& g, const Eigen::MatrixX3d& initialCenters)
	{
		Clock::time_point t0 = Clock::now();
		KMeansResult km = kMeans(g.points, initialCenters, kmeans_);
		kmeansMs += msSince(t0);
		// Drop empty clusters; removing centres keeps the lower bounds valid (distances to the rest only grow).
		std::vector<int> remap(std::size_t(initialCenters.rows()), -1);
		int k = 0;
		for (std::size_t j = 0; j < remap.size(); ++j)
			if (km.counts[j] > 0)
				remap[j] = k++;
		g.centers.resize(k, 3);
		for (std::size_t j = 0; j < remap.size(); ++j)
			if (remap[j] >= 0)
				g.centers.row(remap[j]) = km.centers.row(Eigen::Index(j));
		g.assignment = std::move(km.assignment);
		for (int& a : g.assignment)
			a = remap[std::size_t(a)];
		g.lowerBounds = std::move(km.lowerBounds);
		g.clusters.assign(std::size_t(k), Cluster{});
		for (std::size_t i = 0; i < g.assignment.size(); ++i)
			g.clusters[std::size_t(g.assignment[i])].members.push_back(int(i));
		std::vector<FitTask> tasks;
		for (Cluster& c : g.clusters)
			tasks.push_back({&g, &c, nullptr, false});
		fitAll(tasks);
	}

	/// Seeds for splitting cluster w: the two end points of one of its axes (`axisRank` 0 = longest, the paper), or
	/// with `quad` the four end points of its two longest axes.
	static std::vector<Eigen::Vector3d> splitSeeds(const Cluster& c, int axisRank, bool quad)
	{
		const Ellipsoid& e = c.fit.ellipsoid;
		std::array<Eigen::Index, 3> order = {0, 1, 2};
		std::stable_sort(order.begin(), order.end(),
						 [&](Eigen::Index a, Eigen::Index b) { return e.radii(a) > e.radii(b); });
		std::vector<Eigen::Vector3d> seeds;
		for (int r = quad ? 0 : axisRank; r <= (quad ? 1 : axisRank); ++r)
		{
			const Eigen::Index axis = order[std::size_t(r)];
			const Eigen::Vector3d half = e.rotation.col(axis) * e.radii(axis);
			seeds.push_back(e.center + half);
			seeds.push_back(e.center - half);
		}
		return seeds;
	}

	/// Splits cluster w into seeds.size() clusters (paper steps b-d): w keeps the first, the others are appended.
	/// Returns false, leaving the group untouched, when a cluster ends up empty or when the split lowers neither
	/// the worst nor the summed (vertex-weighted) error E_j of the clusters whose points changed.
	bool trySplit(Group& g, int w, const std::vector<Eigen::Vector3d>& seeds)
	{
		const int k = int(g.clusters.size());
		const int m = int(seeds.size());
		const Cluster& src = g.clusters[std::size_t(w)];
		auto slot = [&](int s) { return s == 0 ? w : k + s - 1; }; // cluster index of seed s

		KMeansResult km;
		if (!splitAssignment(g, w, seeds, km))
			return false;
		const int kNew = k + m - 1;

		// Clusters whose point set changed: the split one, the new ones, and any that gained or lost points.
		std::vector<char> dirty(static_cast<std::size_t>(kNew), 0);
		for (int s = 0; s < m; ++s)
			dirty[std::size_t(slot(s))] = 1;
		for (std::size_t i = 0; i < km.assignment.size(); ++i)
			if (km.assignment[i] != g.assignment[i])
				dirty[std::size_t(g.assignment[i])] = dirty[std::size_t(km.assignment[i])] = 1;

		std::vector<Cluster> fresh(static_cast<std::size_t>(kNew));
		for (std::size_t i = 0; i < km.assignment.size(); ++i)
			if (dirty[std::size_t(km.assignment[i])])
				fresh[std::size_t(km.assignment[i])].members.push_back(int(i));
		// Warm start from the cluster these points came from: the old cluster j, or the split one.
		std::vector<FitTask> tasks;
		for (int j = 0; j < kNew; ++j)
			if (dirty[std::size_t(j)])
				tasks.push_back({&g, &fresh[std::size_t(j)], j < k ? &g.clusters[std::size_t(j)] : &src, false});
		fitAll(tasks);
		double oldWorst = 0.0, newWorst = 0.0, oldTotal = 0.0, newTotal = 0.0;
		for (int j = 0; j < kNew; ++j)
		{
			if (!dirty[std::size_t(j)])
				continue;
			if (j < k)
			{
				const Cluster& old = g.clusters[std::size_t(j)];
				oldWorst = std::max(oldWorst, old.error);
				oldTotal += old.error * double(old.members.size());
			}
			const Cluster& c = fresh[std::size_t(j)];
			newWorst = std::max(newWorst, c.error);
			newTotal += c.error * double(c.members.size());
		}
		if (!(newWorst < oldWorst) && !(newTotal < oldTotal))
			return false;

		// Accept: commit the new clusters, centres and bounds. Frozen flags of surviving clusters are kept.
		for (int j = 0; j < k; ++j)
			if (dirty[std::size_t(j)])
			{
				fresh[std::size_t(j)].frozen = g.clusters[std::size_t(j)].frozen;
				g.clusters[std::size_t(j)] = std::move(fresh[std::size_t(j)]);
			}
		for (int j = k; j < kNew; ++j)
			g.clusters.push_back(std::move(fresh[std::size_t(j)]));
		g.centers = km.centers;
		g.assignment = std::move(km.assignment);
		g.lowerBounds = std::move(km.lowerBounds);
		return true;
	}

	/// K-means of a split (paper steps b-c): the split cluster's centre replaced by `seeds` (w keeps the first, the
	/// others are appended). Locally (g.localSplits: on the cluster's own points, the other clusters keep theirs) or
	/// on the whole group, warm-started. Returns false when a cluster ends up empty.
	bool splitAssignment(const Group& g, int w, const std::vector<Eigen::Vector3d>& seeds, KMeansResult& km)
	{
		const int k = int(g.clusters.size());
		const int m = int(seeds.size());
		const Cluster& src = g.clusters[std::size_t(w)];
		auto slot = [&](int s) { return s == 0 ? w : k + s - 1; }; // cluster index of seed s
		if (g.localSplits)
		{
			// Classic bisecting step: m-means on the cluster's own points; the other clusters keep theirs.
			buffer_.resize(Eigen::Index(src.members.size()), 3);
			for (std::size_t r = 0; r < src.members.size(); ++r)
				buffer_.row(Eigen::Index(r)) = g.points.row(src.members[r]);
			Eigen::MatrixX3d init(m, 3);
			for (int s = 0; s < m; ++s)
				init.row(s) = seeds[std::size_t(s)].transpose();
			Clock::time_point t0 = Clock::now();
			const KMeansResult local = kMeans(buffer_, init, kmeans_);
			kmeansMs += msSince(t0);
			if (local.emptyClusters > 0)
				return false;
			km.assignment = g.assignment;
			for (std::size_t r = 0; r < src.members.size(); ++r)
				km.assignment[std::size_t(src.members[r])] = slot(local.assignment[r]);
			km.centers.resize(k + m - 1, 3);
			km.centers.topRows(k) = g.centers;
			for (int s = 0; s < m; ++s)
				km.centers.row(slot(s)) = local.centers.row(s);
			km.lowerBounds = g.lowerBounds; // only the global path uses them
		}
		else
		{
			// Paper step c: K-means on all points of the group with the split cluster's centre replaced by the
			// seeds; warm-started from the previous run (only the seeded centres are new).
			Eigen::MatrixX3d centers(k + m - 1, 3);
			centers.topRows(k) = g.centers;
			std::vector<bool> moved(std::size_t(k + m - 1), false);
			for (int s = 0; s < m; ++s)
			{
				centers.row(slot(s)) = seeds[std::size_t(s)].transpose();
				moved[std::size_t(slot(s))] = true;
			}
			KMeansWarmStart warm;
			warm.assignment = &g.assignment;
			warm.lowerBounds = &g.lowerBounds;
			warm.moved = &moved;
			Clock::time_point t0 = Clock::now();
			km = kMeans(g.points, centers, kmeans_, &warm);
			kmeansMs += msSince(t0);
			if (km.emptyClusters > 0)
				return false;
		}
		return true;
	}

private:
	KMeansOptions kmeans_;
	Eigen::MatrixX3d buffer_; ///< a split cluster's points for its local K-means
	std::vector<ClusterFitter> fitters_; ///< one per thread
};

void validate(const TriMesh& mesh, const std::vector<Region>& labels, const BodyFitOptions& o)
{
	requireUsable(mesh, "fitBody mesh");
	if (labels.size() != std::size_t(mesh.vertexCount()))
		throw InvalidInputError("fitBody: " + std::to_string(labels.size()) + " region labels for " +
								std::to_string(mesh.vertexCount()) + " vertices");
	for (Region r : labels)
		if (int(r) < 0 || int(r) > int(Region::Whole))
			throw InvalidInputError("fitBody: region label out of range: " + std::to_string(int(r)));
	auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
	if (!positive(o.muTorso))
		throw InvalidInputError("fitBody: mu_torso must be finite and > 0");
	if (!positive(o.muLimbs))
		throw InvalidInputError("fitBody: mu_limbs must be finite and > 0");
	if (!(std::isfinite(o.sigma) && o.sigma >= 0.0))
		throw InvalidInputError("fitBody: sigma must be finite and >= 0");
	if (o.maxEllipsoids < 1)
		throw InvalidInputError("fitBody: max ellipsoids must be >= 1");
	if (o.splitAxes < 1 || o.splitAxes > 3)
		throw InvalidInputError("fitBody: splitAxes must be 1, 2 or 3");
	if (o.maxSplits < 0 || o.kmeansMaxIterations < 1)
		throw InvalidInputError("fitBody: maxSplits must be >= 0 and kmeansMaxIterations >= 1");
	if (o.coverTriangles && !positive(o.coverSpacing))
		throw InvalidInputError("fitBody: coverSpacing must be finite and > 0");
	if (!positive(o.minRadiusFraction) || !positive(o.mveeTolerance))
		throw InvalidInputError("fitBody: minRadiusFraction and mveeTolerance must be finite and > 0");
	if (!std::isfinite(o.height))
		throw InvalidInputError("fitBody: height must be finite");
	if (o.threads < 0)
		throw InvalidInputError("fitBody: threads must be >= 0 (0 = every hardware thread)");
}

/// Groups in output order: head, torso, arms, legs (Region order, torso parts merged), whole.
/// `o` has its lengths in metres (resolveLengths).
std::vector<Group> makeGroups(const TriMesh& mesh, const std::vector<Region>& labels, const BodyFitOptions& o,
							  std::vector<Eigen::MatrixX3d>& initialCenters)
{
	constexpr int kRegions = int(Region::Whole) + 1;
	std::array<std::vector<int>, kRegions> byRegion;
	for (std::size_t v = 0; v < labels.size(); ++v)
		byRegion[std::size_t(labels[v])].push_back(int(v));

	auto mean = [&](const std::vector<int>& verts) {
		Eigen::RowVector3d s = Eigen::RowVector3d::Zero();
		for (int v : verts)
			s += mesh.V.row(v);
		return Eigen::RowVector3d(s / double(verts.size()));
	};

	std::vector<Group> groups;
	initialCenters.clear();
	bool torsoDone = false;
	for (int r = 0; r < kRegions; ++r)
	{
		const Region region = Region(r);
		if (byRegion[std::size_t(r)].empty())
			continue;
		Group g;
		g.region = region;
		if (isTorso(region))
		{
			if (torsoDone)
				continue;
			torsoDone = true;
			g.torso = true;
			std::vector<Eigen::RowVector3d> partMeans;
			for (int t = r; t < kRegions; ++t)
				if (isTorso(Region(t)) && !byRegion[std::size_t(t)].empty())
				{
					g.vertices.insert(g.vertices.end(), byRegion[std::size_t(t)].begin(), byRegion[std::size_t(t)].end());
					partMeans.push_back(mean(byRegion[std::size_t(t)]));
				}
			std::sort(g.vertices.begin(), g.vertices.end());
			Eigen::MatrixX3d c(Eigen::Index(partMeans.size()), 3);
			for (std::size_t j = 0; j < partMeans.size(); ++j)
				c.row(Eigen::Index(j)) = partMeans[j];
			initialCenters.push_back(c);
		}
		else
		{
			g.vertices = byRegion[std::size_t(r)];
			initialCenters.push_back(mean(g.vertices));
		}
		g.mu = g.torso || region == Region::Whole ? o.muTorso : o.muLimbs;
		g.localSplits = region == Region::Whole || !o.reclusterGroup;
		g.points.resize(Eigen::Index(g.vertices.size()), 3);
		for (std::size_t i = 0; i < g.vertices.size(); ++i)
			g.points.row(Eigen::Index(i)) = mesh.V.row(g.vertices[i]);
		groups.push_back(std::move(g));
	}
	return groups;
}

/// Majority torso part among a torso cluster's vertices (ties: lower Region value).
Region majorityRegion(const Group& g, const Cluster& c, const std::vector<Region>& labels)
{
	std::array<int, int(Region::Whole) + 1> votes{};
	for (int m : c.members)
		++votes[std::size_t(labels[std::size_t(g.vertices[std::size_t(m)])])];
	return Region(int(std::max_element(votes.begin(), votes.end()) - votes.begin()));
}

struct CoverStats
{
	int rounds = 0;       ///< refit rounds that added points
	int extraPoints = 0;  ///< sum of the clusters' extra points
	int uncovered = 0;    ///< pieces not inside one ellipsoid when the round cap was hit (expected 0)
	double ms = 0.0;
};

/// Triangle cover (coverTriangles, see body_fitter.h). The clusters partition the vertices, so every ellipsoid
/// encloses its own vertices and, by convexity, every triangle whose corners are all its own. A triangle whose corners
/// belong to different clusters can bulge out between two ellipsoids. Every such triangle is cut on a barycentric grid
/// into pieces whose edges are at most `spacing`; a piece that no single ellipsoid contains hands its corners outside
/// the closest corner cluster to that cluster (TriangleCover, triangle_cover.h, has the rules), and the clusters that
/// received points are refitted (in parallel over `threads`: each refit depends only on its own cluster).
/// Extra points stay in their cluster's MVEE input, so a piece handed to a cluster stays inside it; refits move
/// ellipsoids, so the check repeats until every piece lies inside one ellipsoid. Each round adds at least one new
/// point (a piece whose corners were all enclosed would be contained), so the loop ends; `maxRounds` is a safety cap.
/// Pieces instead of whole triangles let the ellipsoids grow less (body_fitter.h has the numbers).
CoverStats coverTriangles(const TriMesh& mesh, std::vector<Group>& groups, Refiner& refiner, double spacing,
						  int threads)
{
	constexpr int maxRounds = 50;
	const Clock::time_point t0 = Clock::now();
	CoverStats stats;
	struct Ref
	{
		int g, j;
	};
	std::vector<Ref> refs;
	std::vector<int> owner(std::size_t(mesh.vertexCount()), -1);
	for (std::size_t gi = 0; gi < groups.size(); ++gi)
		for (std::size_t j = 0; j < groups[gi].clusters.size(); ++j)
		{
			const int id = int(refs.size());
			refs.push_back({int(gi), int(j)});
			for (int m : groups[gi].clusters[j].members)
				owner[std::size_t(groups[gi].vertices[std::size_t(m)])] = id;
		}
	auto cluster = [&](int id) -> Cluster& {
		return groups[std::size_t(refs[std::size_t(id)].g)].clusters[std::size_t(refs[std::size_t(id)].j)];
	};

	TriangleCover cover(mesh, owner, spacing);
	const int k = int(refs.size());
	std::vector<Ellipsoid> ellipsoids(refs.size());
	std::vector<char> grew(refs.size(), 0), targeted;
	std::vector<TriangleCover::Handout> handouts;
	std::vector<FitTask> refit;
	for (int round = 0;; ++round)
	{
		for (int id = 0; id < k; ++id)
			ellipsoids[std::size_t(id)] = cluster(id).fit.ellipsoid;
		handouts.clear();
		stats.uncovered = cover.check(ellipsoids, grew, handouts, targeted, threads);
		if (stats.uncovered == 0 || round == maxRounds)
			break;
		for (const TriangleCover::Handout& h : handouts)
			cluster(h.cluster).extras.push_back(h.point);
		grew = targeted; // every cluster an uncovered piece went to is refitted
		refit.clear();
		for (int id = 0; id < k; ++id)
			if (grew[std::size_t(id)])
				refit.push_back({&groups[std::size_t(refs[std::size_t(id)].g)], &cluster(id), nullptr, true});
		refiner.fitAll(refit);
		++stats.rounds;
	}
	for (int id = 0; id < k; ++id)
		stats.extraPoints += int(cluster(id).extras.size());
	stats.ms = msSince(t0);
	return stats;
}

/// Number of clusters (= ellipsoids) over all groups.
int clusterCount(const std::vector<Group>& groups)
{
	std::size_t n = 0;
	for (const Group& g : groups)
		n += g.clusters.size();
	return int(n);
}

/// The cluster to split next (see body_fitter.h): the largest E_j / mu among the clusters above their threshold
/// that are not frozen; ties: lower group, then lower cluster index.
struct SplitTarget
{
	int group = -1, cluster = -1; ///< -1: none left to split
	bool anyAbove = false;        ///< some cluster (frozen or not) is above its threshold
};

SplitTarget worstCluster(const std::vector<Group>& groups)
{
	SplitTarget t;
	double bestScore = 1.0;
	for (std::size_t gi = 0; gi < groups.size(); ++gi)
		for (std::size_t j = 0; j < groups[gi].clusters.size(); ++j)
		{
			const Cluster& c = groups[gi].clusters[j];
			const double score = c.error / groups[gi].mu;
			if (score <= 1.0)
				continue;
			t.anyAbove = true;
			if (!c.frozen && score > bestScore)
			{
				bestScore = score;
				t.group = int(gi);
				t.cluster = int(j);
			}
		}
	return t;
}

/// One split attempt on cluster j of g: the longest axis (the paper), then the next axes, then a four-way split
/// across the two longest axes within the budget (a cluster wrapped around a corner, e.g. chest + upper arms, often
/// needs two cuts before its error drops). `ellipsoids` is the current total. Returns whether a split was accepted.
bool splitCluster(Refiner& refiner, Group& g, int j, const BodyFitOptions& options, int ellipsoids)
{
	const Cluster& target = g.clusters[std::size_t(j)];
	bool accepted = false;
	for (int rank = 0; rank < options.splitAxes && !accepted; ++rank)
		accepted = refiner.trySplit(g, j, Refiner::splitSeeds(target, rank, false));
	if (!accepted && options.quadSplit && ellipsoids + 3 <= options.maxEllipsoids)
		accepted = refiner.trySplit(g, j, Refiner::splitSeeds(target, 0, true));
	return accepted;
}

/// Refinement (paper steps b-e): splits the worst cluster relative to its threshold until every cluster meets its
/// threshold or is frozen, the budget is reached or the split attempts are used up. Counts the splits in `result`.
RefineStatus refine(std::vector<Group>& groups, Refiner& refiner, const BodyFitOptions& options, BodyFit& result)
{
	for (int attempts = 0;; ++attempts)
	{
		const SplitTarget t = worstCluster(groups);
		if (t.group < 0)
			return t.anyAbove ? RefineStatus::Frozen : RefineStatus::Converged;
		if (clusterCount(groups) >= options.maxEllipsoids)
			return RefineStatus::BudgetReached;
		if (attempts >= options.maxSplits)
			return RefineStatus::SplitCapReached;
		Group& g = groups[std::size_t(t.group)];
		if (splitCluster(refiner, g, t.cluster, options, clusterCount(groups)))
			++result.splitsAccepted;
		else
		{
			g.clusters[std::size_t(t.cluster)].frozen = true;
			++result.splitsRejected;
		}
	}
}

/// Runs the triangle cover with pieces of at most `spacing` metres and records its statistics in `result`.
void applyCover(const TriMesh& mesh, std::vector<Group>& groups, Refiner& refiner, double spacing, int threads,
				BodyFit& result)
{
	const CoverStats cover = coverTriangles(mesh, groups, refiner, spacing, threads);
	result.coverRounds = cover.rounds;
	result.coverExtraPoints = cover.extraPoints;
	result.setTiming("fitting.cover", cover.ms);
	if (cover.uncovered > 0)
		result.warnings.push_back(std::to_string(cover.uncovered) +
								  " piece(s) of skin across ellipsoid boundaries are not inside any ellipsoid");
}

/// Final clusters that deserve a warning.
struct ReportCounts
{
	int degenerate = 0;   ///< flat or tiny clusters (axes floored to the minimum radius)
	int notConverged = 0; ///< MVEEs that hit their iteration cap
	int frozenAbove = 0;  ///< frozen above their threshold
};

/// The fitted ellipsoids in group order with their error statistics (true distances with `trueDistance`), their
/// regions and the vertex -> ellipsoid map.
ReportCounts reportEllipsoids(const TriMesh& mesh, const std::vector<Group>& groups, const std::vector<Region>& labels,
							  bool trueDistance, BodyFit& result)
{
	ReportCounts counts;
	result.vertexEllipsoid.assign(std::size_t(mesh.vertexCount()), -1);
	for (const Group& g : groups)
		for (const Cluster& c : g.clusters)
		{
			FittedEllipsoid f;
			f.ellipsoid = c.fit.ellipsoid;
			f.region = g.torso ? majorityRegion(g, c, labels) : g.region;
			f.mveeStatus = c.fit.status;
			const FitError err = fitError(c.fit.ellipsoid, g.points, c.members, trueDistance);
			f.vertexCount = err.vertexCount;
			f.radialError = c.error;
			f.maxRadialError = err.radialMax;
			f.meanDistance = err.distanceMean;
			f.maxDistance = err.distanceMax;
			const int index = int(result.ellipsoids.size());
			for (int m : c.members)
				result.vertexEllipsoid[std::size_t(g.vertices[std::size_t(m)])] = index;
			counts.degenerate += (c.fit.status == FitStatus::Degenerate || c.fit.status == FitStatus::TooFewPoints);
			counts.notConverged += (c.fit.status == FitStatus::NotConverged || c.fit.status == FitStatus::NumericalIssue);
			counts.frozenAbove += (c.frozen && c.error > g.mu);
			result.ellipsoids.push_back(f);
		}
	return counts;
}

/// Warnings about the final ellipsoids and about why the refinement stopped.
void addResultWarnings(const ReportCounts& counts, double minRadius, const BodyFitOptions& options, BodyFit& result)
{
	if (counts.degenerate > 0)
	{
		char radius[32];
		std::snprintf(radius, sizeof radius, "%.2f mm", minRadius * 1000.0);
		result.warnings.push_back(std::to_string(counts.degenerate) +
								  " ellipsoid(s) fitted to flat or tiny clusters: thin axes floored to " + radius);
	}
	if (counts.notConverged > 0)
		result.warnings.push_back(std::to_string(counts.notConverged) +
								  " MVEE(s) hit the iteration cap (rescaled to enclose their points)");
	if (result.status == RefineStatus::BudgetReached)
		result.warnings.push_back("ellipsoid budget of " + std::to_string(options.maxEllipsoids) +
								  " reached before every ellipsoid met its threshold");
	if (result.status == RefineStatus::SplitCapReached)
		result.warnings.push_back("split cap of " + std::to_string(options.maxSplits) + " attempts reached");
	if (counts.frozenAbove > 0)
		result.warnings.push_back(std::to_string(counts.frozenAbove) +
								  " ellipsoid(s) stay above their threshold: splitting them did not lower the error");
}

/// The source size and height and the parameters in the units they were given in (`options`).
void recordParams(const BodyFitOptions& options, int vertices, double height, double minRadius, BodyFit& result)
{
	result.source.vertices = vertices;
	result.source.height = height;
	result.params.muTorso = options.muTorso;
	result.params.muLimbs = options.muLimbs;
	result.params.relativeToHeight = options.relativeToHeight;
	result.params.sigma = options.sigma;
	result.params.maxEllipsoids = options.maxEllipsoids;
	result.params.minRadius = minRadius;
	result.params.reclusterGroup = options.reclusterGroup;
	result.params.coverTriangles = options.coverTriangles;
	result.params.coverSpacing = options.coverTriangles ? options.coverSpacing : 0.0;
}

} // namespace

FitLengths FitLengths::of(const BodyFitOptions& options)
{
	const bool rel = options.relativeToHeight;
	return {{options.muTorso, rel}, {options.muLimbs, rel}, {options.sigma, rel}, {options.coverSpacing, rel}};
}

bool FitLengths::allRelative() const
{
	return muTorso.relativeToHeight && muLimbs.relativeToHeight && sigma.relativeToHeight &&
		   coverSpacing.relativeToHeight;
}

BodyFitOptions resolveLengths(const BodyFitOptions& options, const FitLengths& lengths, double height)
{
	BodyFitOptions out = options;
	out.muTorso = lengths.muTorso.toMetres(height);
	out.muLimbs = lengths.muLimbs.toMetres(height);
	out.sigma = lengths.sigma.toMetres(height);
	out.coverSpacing = lengths.coverSpacing.toMetres(height);
	out.relativeToHeight = false;
	out.height = height;
	return out;
}

double bodyHeight(const TriMesh& mesh, double height, std::string* warning)
{
	if (height > 0.0)
		return height;
	height = mesh.V.col(1).maxCoeff() - mesh.V.col(1).minCoeff();
	if (height > 0.0)
		return height;
	if (warning != nullptr)
		*warning = "mesh has no y extent: using the bounding-box diagonal as the height";
	return (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).norm();
}

BodyFit fitBody(const TriMesh& mesh, const std::vector<Region>& labels, const BodyFitOptions& options)
{
	const Clock::time_point t0 = Clock::now();
	validate(mesh, labels, options);
	BodyFit result;
	std::string heightWarning;
	const double height = bodyHeight(mesh, options.height, &heightWarning);
	if (!heightWarning.empty())
		result.warnings.push_back(heightWarning);
	const BodyFitOptions metres = resolveLengths(options, FitLengths::of(options), height);

	KMeansOptions kmeans;
	kmeans.sigma = metres.sigma;
	kmeans.maxIterations = metres.kmeansMaxIterations;
	MveeOptions mvee;
	mvee.minRadius = metres.minRadiusFraction * height;
	mvee.tolerance = metres.mveeTolerance;
	recordParams(options, mesh.vertexCount(), height, mvee.minRadius, result);

	// (a) Initial clusters: torso k = number of its parts (means of the parts), every other region k = 1.
	std::vector<Eigen::MatrixX3d> initialCenters;
	std::vector<Group> groups = makeGroups(mesh, labels, metres, initialCenters);
	const int threads = resolveThreads(metres.threads);
	Refiner refiner(kmeans, mvee, threads);
	for (std::size_t gi = 0; gi < groups.size(); ++gi)
		refiner.initialise(groups[gi], initialCenters[gi]);
	if (clusterCount(groups) > metres.maxEllipsoids)
		result.warnings.push_back("max ellipsoids " + std::to_string(metres.maxEllipsoids) + " is below the " +
								  std::to_string(clusterCount(groups)) +
								  " initial ellipsoids of the regions: no refinement");

	// (b)-(e) Refinement, then the triangle cover.
	result.status = refine(groups, refiner, metres, result);
	if (metres.coverTriangles)
		applyCover(mesh, groups, refiner, metres.coverSpacing, threads, result);
	const double fittingMs = msSince(t0);

	const Clock::time_point tReport = Clock::now();
	const ReportCounts counts = reportEllipsoids(mesh, groups, labels, metres.trueDistance, result);
	const double reportMs = msSince(tReport);
	addResultWarnings(counts, mvee.minRadius, metres, result);

	result.setTiming("fitting", fittingMs);
	result.setTiming("fitting.kmeans", refiner.kmeansMs);
	result.setTiming("fitting.mvee", refiner.mveeMs());
	result.setTiming("fitting.error", refiner.errorMs());
	if (metres.trueDistance)
		result.setTiming("report", reportMs);
	return result;
}

BodyFit fitBody(const TriMesh& mesh, const BodyFitOptions& options)
{
	return fitBody(mesh, std::vector<Region>(std::size_t(mesh.vertexCount()), Region::Whole), options);
}

int coverCutLevel(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double spacing)
{
	constexpr int kMaxCoverLevel = 64;
	const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
	return std::clamp(int(std::ceil(longest / spacing)), 1, kMaxCoverLevel);
}

} // namespace bodyfit
