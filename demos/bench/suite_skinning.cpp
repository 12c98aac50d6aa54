// Suite `skinning`: the per-frame body update of a rigged body (skinned_fit.h) and the bind-pose fit.
// Per bundled animated body and clip, over every 30 fps frame: median and worst ms per frame of the whole update
// (poseBones + skinningMatrices + skinVertices + ellipsoid update), the median of its skinning part alone
// (poseBones + skinningMatrices + skinVertices), and how far the enclosing step pushes the refitted ellipsoids out
// beyond their moved bind shape (largest semi-axis growth, mm: mean and max over ellipsoids and frames), the mean
// radial distance of the skinned vertices to their own ellipsoid (paper E over the body, mean over frames; the fit
// table has the bind-pose value), with the
// default per-axis growth and with uniform growth. The update is also timed in thread CPU time (steadier than wall
// time on a loaded machine). Then the bind-pose fit as bodyfit-fit makes it (fit_pipeline.h: segmentForFit +
// fitSegmented, default options) with the median of each phase over the repeats: segmentation, fit (refinement:
// K-means + MVEEs), triangle cover, their sum (the bind-pose fit; also as CPU time over every thread, which is the
// single-core time), the true-distance report, and the binding time.
// Then the skinned-body driver of the scene runner (bodyfit/bridge/btSkinnedBodyDriver.h), as it runs at every
// substep: the same update plus writing the ellipsoids into the body's btEllipsoidCompoundShape, timed apart
// (goal: <= 2 ms per frame for the 13,380-vertex body on one core).
// `--part fit` runs only the bind-pose fit table; `--threads N` sets the fit's threads (BodyFitOptions::threads).
// The per-frame update and the driver are single-threaded.
#include "bench/bench_common.h"

#include "bodyfit/bridge/btBodyFitToBullet.h"
#include "bodyfit/bridge/btSkinnedBodyDriver.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/segmentation.h"
#include "bodyfit/fitting/skinned_fit.h"

#include <chrono>
#include <ctime>

namespace
{

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// CPU time of the whole process (every thread): the work of a multi-threaded step.
double processCpuMs()
{
	timespec ts{};
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

double threadCpuMs()
{
	timespec ts{};
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

double median(std::vector<double> v)
{
	std::sort(v.begin(), v.end());
	const std::size_t m = v.size() / 2;
	return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

struct ClipTiming
{
	int frames = 0;
	double updateMedian = 0.0, updateWorst = 0.0, updateCpu = 0.0, skinMedian = 0.0, meanGrowth = 0.0, maxGrowth = 0.0;
	double radialError = 0.0; ///< mean over frames of the mean radial distance of the skinned vertices to their ellipsoid
};

/// Mean over the clustered vertices of |v - radial projection of v onto its own ellipsoid| (the paper's E, over the
/// whole body): how loosely the moved ellipsoids fit the skin at this frame.
double meanRadialError(const bodyfit::SkinnedBody& body, const std::vector<int>& cluster)
{
	double sum = 0.0;
	int n = 0;
	for (int v = 0; v < int(cluster.size()); ++v)
		if (cluster[std::size_t(v)] >= 0)
		{
			const Eigen::Vector3d p = body.vertices().row(v).transpose();
			sum += (p - body.ellipsoids()[std::size_t(cluster[std::size_t(v)])].radialProjection(p)).norm();
			++n;
		}
	return n > 0 ? sum / n : 0.0;
};

ClipTiming timeClip(bodyfit::SkinnedBody& body, const bodyfit::AnimationClip& clip, const std::vector<int>& cluster,
					int repeats)
{
	const bodyfit::Rig& rig = body.rig();
	ClipTiming out;
	out.frames = int(clip.duration * 30.0) + 1;
	std::vector<double> update, cpu, skin;
	double growthSum = 0.0;
	int growthCount = 0;
	Eigen::MatrixX3d skinned;
	for (int r = 0; r < std::max(1, repeats); ++r)
		for (int f = 0; f < out.frames; ++f)
		{
			const double t = f / 30.0;
			Clock::time_point t0 = Clock::now();
			const double c0 = threadCpuMs();
			body.pose(clip, t);
			cpu.push_back(threadCpuMs() - c0);
			update.push_back(msSince(t0));
			t0 = Clock::now();
			bodyfit::skinVertices(rig, bodyfit::skinningMatrices(rig, bodyfit::poseBones(rig, clip, t)), skinned);
			skin.push_back(msSince(t0));
			if (r == 0)
				out.radialError += meanRadialError(body, cluster) / out.frames;
			if (r == 0)
				for (int j = 0; j < int(body.ellipsoids().size()); ++j)
					if (body.mode(j) == bodyfit::EllipsoidMotion::Refit)
					{
						growthSum += body.lastGrowth(j);
						++growthCount;
						out.maxGrowth = std::max(out.maxGrowth, body.lastGrowth(j));
					}
		}
	out.updateMedian = median(update);
	out.updateWorst = *std::max_element(update.begin(), update.end());
	out.updateCpu = median(cpu);
	out.skinMedian = median(skin);
	out.meanGrowth = growthCount > 0 ? growthSum / growthCount : 0.0;
	return out;
}

/// The bind-pose fit's phases, each the median over the repeats (ms), and the fit of the last repeat.
struct BindFitTiming
{
	double segmentation = 0.0, fit = 0.0, cover = 0.0, bindFit = 0.0, report = 0.0;
	double bindFitCpu = 0.0; ///< CPU time of segmentation + fit + cover summed over the threads (the work)
	bodyfit::BodyFit result;
};

BindFitTiming timeBindFit(const bodyfit::TriMesh& mesh, int repeats, int threads)
{
	bodyfit::FitPipelineOptions options;
	options.fit.threads = threads;
	options.segmentation.geodesics.threads = threads;
	std::vector<double> segmentation, fit, cover, bindFit, report, bindFitCpu;
	BindFitTiming out;
	for (int r = 0; r < std::max(1, repeats); ++r)
	{
		options.fit.trueDistance = false; // the report is timed apart, below
		const double c0 = processCpuMs();
		const Clock::time_point t0 = Clock::now();
		const bodyfit::Segmentation seg = bodyfit::segmentForFit(mesh, options);
		segmentation.push_back(msSince(t0));
		out.result = bodyfit::fitSegmented(mesh, seg, options);
		bindFitCpu.push_back(processCpuMs() - c0);
		options.fit.trueDistance = true;
		out.result = bodyfit::fitSegmented(mesh, seg, options);
		// Phases of the run with the report (same fit: the report runs after it).
		cover.push_back(out.result.timingMs("fitting.cover"));
		fit.push_back(out.result.timingMs("fitting") - cover.back());
		bindFit.push_back(segmentation.back() + out.result.timingMs("fitting"));
		report.push_back(out.result.timingMs("report"));
	}
	out.segmentation = median(segmentation);
	out.fit = median(fit);
	out.cover = median(cover);
	out.bindFit = median(bindFit);
	out.report = median(report);
	out.bindFitCpu = median(bindFitCpu);
	return out;
}

struct DriverTiming
{
	int frames = 0;
	double bodyMedian = 0.0, writeMedian = 0.0, totalMedian = 0.0, totalWorst = 0.0, totalCpu = 0.0;
};

/// The driver posing the body at every 30 fps frame of the clip and writing the compound, `repeats` times.
DriverTiming timeDriver(const bodyfit::Rig& rig, const bodyfit::BodyFit& fit, const bodyfit::SkinBinding& binding,
						const bodyfit::AnimationClip& clip, int repeats)
{
	std::vector<bodyfit::Ellipsoid> ellipsoids;
	for (const bodyfit::FittedEllipsoid& e : fit.ellipsoids)
		ellipsoids.push_back(e.ellipsoid);
	const auto compound = bodyfit::createEllipsoidCompound(ellipsoids);
	bodyfit::AnimationTiming timing;
	timing.loop = false;
	bodyfit::btSkinnedBodyDriver driver(rig, fit, binding, clip, timing);
	driver.setCompound(compound.get());
	DriverTiming out;
	out.frames = int(clip.duration * 30.0) + 1;
	std::vector<double> body, write, total, cpu;
	for (int r = 0; r < std::max(1, repeats); ++r)
		for (int f = 0; f < out.frames; ++f)
		{
			// Distinct times across repeats (the driver skips a call at the time it is already posed at).
			const double t = f / 30.0 + (r % 2 == 1 ? 1e-6 : 0.0);
			const double c0 = threadCpuMs();
			driver.update(t);
			cpu.push_back(threadCpuMs() - c0);
			body.push_back(driver.stats().lastBodySeconds * 1e3);
			write.push_back(driver.stats().lastCompoundSeconds * 1e3);
			total.push_back(body.back() + write.back());
		}
	out.bodyMedian = median(body);
	out.writeMedian = median(write);
	out.totalMedian = median(total);
	out.totalWorst = *std::max_element(total.begin(), total.end());
	out.totalCpu = median(cpu);
	return out;
}

} // namespace

BODYFIT_BENCH_SUITE_WITH_OPTIONS(skinning, "rigged body: per-frame update (pose, skin, ellipsoids) and the bind-pose fit",
								 {"--part", "all|fit", "fit: only the bind-pose fit table (default all)"},
								 {"--threads", "N", "threads of the bind-pose fit (default 0 = every hardware thread)"})
{
	const std::string part = ctx.text("--part", "all");
	if (part != "all" && part != "fit")
		throw bodyfit_cli::UsageError("--part: " + part + " is not all or fit");
	bodyfit_bench::Table frames({"body", "clip", "growth", "frames", "update ms median", "update ms worst",
								 "update cpu ms median", "skinning ms median", "growth mm mean", "growth mm max",
								 "radial error mm"});
	bodyfit_bench::Table fits({"body", "vertices", "ellipsoids", "rigid", "bound points", "segmentation ms",
							   "fit ms", "cover ms", "bind-pose fit ms", "bind-pose fit cpu ms", "report ms", "bind ms",
							   "radial error mm (bind)"});
	bodyfit_bench::Table driverTable({"body", "clip", "frames", "update ms median", "compound write ms median",
									  "update + write ms median", "update + write ms worst",
									  "update + write cpu ms median"});
	const int repeats = ctx.repeatsGiven ? ctx.repeats : (ctx.quick ? 1 : 5);
	for (const char* name : {"female_young", "male_young"})
	{
		const bodyfit::Rig rig =
			bodyfit::loadRig(std::string(BODYFIT_ASSET_DIR) + "/animated/" + name + ".animated.glb");
		const BindFitTiming timing = timeBindFit(rig.bindMesh, ctx.repeatsGiven ? ctx.repeats : (ctx.quick ? 3 : 9),
												 int(ctx.integer("--threads", 0, 0, 64)));
		const bodyfit::BodyFit& fit = timing.result;
		bodyfit::SkinBinding binding;
		const Clock::time_point t0 = Clock::now();
		binding = bodyfit::bindSkin(rig, fit);
		const double bindMs = msSince(t0);
		int rigid = 0;
		for (const bodyfit::EllipsoidBinding& e : binding.ellipsoids)
			rigid += e.mode == bodyfit::EllipsoidMotion::Rigid;
		fits.addRow({name, bodyfit_bench::fmtInt(rig.bindMesh.vertexCount()), bodyfit_bench::fmtInt(long(fit.ellipsoids.size())),
					 bodyfit_bench::fmtInt(rigid), bodyfit_bench::fmtInt(binding.vertexPoints + binding.coverPoints),
					 bodyfit_bench::fmt(timing.segmentation, 1), bodyfit_bench::fmt(timing.fit, 1),
					 bodyfit_bench::fmt(timing.cover, 1), bodyfit_bench::fmt(timing.bindFit, 1),
					 bodyfit_bench::fmt(timing.bindFitCpu, 1),
					 bodyfit_bench::fmt(timing.report, 1), bodyfit_bench::fmt(bindMs, 1),
					 bodyfit_bench::fmt(fit.meanRadialError() * 1000.0, 2)});
		if (part == "fit")
			continue;
		for (const bodyfit::AnimationClip& clip : rig.clips)
		{
			const DriverTiming d = timeDriver(rig, fit, binding, clip, repeats);
			driverTable.addRow({name, clip.name, bodyfit_bench::fmtInt(d.frames), bodyfit_bench::fmt(d.bodyMedian, 3),
								bodyfit_bench::fmt(d.writeMedian, 3), bodyfit_bench::fmt(d.totalMedian, 3),
								bodyfit_bench::fmt(d.totalWorst, 3), bodyfit_bench::fmt(d.totalCpu, 3)});
		}
		for (const bool perAxis : {true, false})
		{
			bodyfit::SkinnedBody body(rig, fit, binding, {perAxis});
			for (const bodyfit::AnimationClip& clip : rig.clips)
			{
				const ClipTiming c = timeClip(body, clip, binding.vertexEllipsoid, repeats);
				frames.addRow({name, clip.name, perAxis ? "per-axis" : "uniform", bodyfit_bench::fmtInt(c.frames),
							   bodyfit_bench::fmt(c.updateMedian, 3), bodyfit_bench::fmt(c.updateWorst, 3),
							   bodyfit_bench::fmt(c.updateCpu, 3), bodyfit_bench::fmt(c.skinMedian, 3),
							   bodyfit_bench::fmt(c.meanGrowth * 1000.0, 2), bodyfit_bench::fmt(c.maxGrowth * 1000.0, 1),
							   bodyfit_bench::fmt(c.radialError * 1000.0, 2)});
			}
		}
	}
	if (part == "fit")
		return bodyfit_bench::emit(ctx, "skinning_fit", fits);
	int rc = bodyfit_bench::emit(ctx, "skinning_frames", frames);
	rc = std::max(rc, bodyfit_bench::emit(ctx, "skinning_driver", driverTable));
	return std::max(rc, bodyfit_bench::emit(ctx, "skinning_fit", fits));
}
