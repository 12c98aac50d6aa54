// Suite `skinning`: the per-frame body update of a rigged body (skinned_fit.h) and the bind-pose fit.
// Per bundled animated body and clip, over every 30 fps frame: median and worst ms per frame of the whole update
// (poseBones + skinningMatrices + skinVertices + ellipsoid update), the median of its skinning part alone
// (poseBones + skinningMatrices + skinVertices), and the growth of the refitted ellipsoids (enclosing scale: mean and
// max over ellipsoids and frames; 1 = the moved bind ellipsoid already fits). Then the bind-pose fit (segmentation +
// fitBody, as bodyfit-fit) and the binding time. Single thread.
#include "bench/bench_common.h"

#include "bodyfit/fitting/segmentation.h"
#include "bodyfit/fitting/skinned_fit.h"

#include <chrono>

namespace
{

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
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
	double updateMedian = 0.0, updateWorst = 0.0, skinMedian = 0.0, meanScale = 0.0, maxScale = 0.0;
};

ClipTiming timeClip(bodyfit::SkinnedBody& body, const bodyfit::AnimationClip& clip, int repeats)
{
	const bodyfit::Rig& rig = body.rig();
	ClipTiming out;
	out.frames = int(clip.duration * 30.0) + 1;
	std::vector<double> update, skin;
	double scaleSum = 0.0;
	int scaleCount = 0;
	Eigen::MatrixX3d skinned;
	for (int r = 0; r < std::max(1, repeats); ++r)
		for (int f = 0; f < out.frames; ++f)
		{
			const double t = f / 30.0;
			Clock::time_point t0 = Clock::now();
			body.pose(clip, t);
			update.push_back(msSince(t0));
			t0 = Clock::now();
			bodyfit::skinVertices(rig, bodyfit::skinningMatrices(rig, bodyfit::poseBones(rig, clip, t)), skinned);
			skin.push_back(msSince(t0));
			if (r == 0)
				for (int j = 0; j < int(body.ellipsoids().size()); ++j)
					if (body.mode(j) == bodyfit::EllipsoidMotion::Refit)
					{
						scaleSum += body.lastScale(j);
						++scaleCount;
						out.maxScale = std::max(out.maxScale, body.lastScale(j));
					}
		}
	out.updateMedian = median(update);
	out.updateWorst = *std::max_element(update.begin(), update.end());
	out.skinMedian = median(skin);
	out.meanScale = scaleCount > 0 ? scaleSum / scaleCount : 1.0;
	return out;
}

} // namespace

BODYFIT_BENCH_SUITE(skinning, "rigged body: per-frame update (pose, skin, ellipsoids) and the bind-pose fit")
{
	bodyfit_bench::Table frames({"body", "clip", "frames", "update ms median", "update ms worst", "skinning ms median",
								 "refit scale mean", "refit scale max"});
	bodyfit_bench::Table fits({"body", "vertices", "ellipsoids", "rigid", "bound points", "fit ms median", "bind ms"});
	const int repeats = ctx.repeatsGiven ? ctx.repeats : (ctx.quick ? 1 : 5);
	for (const char* name : {"female_young", "male_young"})
	{
		const bodyfit::Rig rig =
			bodyfit::loadRig(std::string(BODYFIT_ASSET_DIR) + "/animated/" + name + ".animated.glb");
		bodyfit::BodyFit fit;
		const double fitMs = bodyfit_bench::medianMs(ctx.quick ? 1 : 3, [&] {
			fit = bodyfit::fitBody(rig.bindMesh, bodyfit::segmentBody(rig.bindMesh).labels);
		});
		bodyfit::SkinBinding binding;
		const Clock::time_point t0 = Clock::now();
		binding = bodyfit::bindSkin(rig, fit);
		const double bindMs = msSince(t0);
		bodyfit::SkinnedBody body(rig, fit, binding);
		int rigid = 0;
		for (const bodyfit::EllipsoidBinding& e : binding.ellipsoids)
			rigid += e.mode == bodyfit::EllipsoidMotion::Rigid;
		fits.addRow({name, bodyfit_bench::fmtInt(rig.bindMesh.vertexCount()), bodyfit_bench::fmtInt(long(fit.ellipsoids.size())),
					 bodyfit_bench::fmtInt(rigid), bodyfit_bench::fmtInt(binding.vertexPoints + binding.coverPoints),
					 bodyfit_bench::fmt(fitMs, 1), bodyfit_bench::fmt(bindMs, 1)});
		for (const bodyfit::AnimationClip& clip : rig.clips)
		{
			const ClipTiming c = timeClip(body, clip, repeats);
			frames.addRow({name, clip.name, bodyfit_bench::fmtInt(c.frames), bodyfit_bench::fmt(c.updateMedian, 3),
						   bodyfit_bench::fmt(c.updateWorst, 3), bodyfit_bench::fmt(c.skinMedian, 3),
						   bodyfit_bench::fmt(c.meanScale, 3), bodyfit_bench::fmt(c.maxScale, 3)});
		}
	}
	const int rc = bodyfit_bench::emit(ctx, "skinning_frames", frames);
	return std::max(rc, bodyfit_bench::emit(ctx, "skinning_fit", fits));
}
