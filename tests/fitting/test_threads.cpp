// Fits and bakes in threads of their own (a server fitting several bodies at once), each also using threads of its
// own inside: the same fit file and the same skin field, to the byte, as one after the other. The ThreadSanitizer
// job of tools/ci-extra.sh runs this file.
#include "bodyfit/fitting/fit_pipeline.h"
#include "bodyfit/fitting/skin_field.h"
#include "support/paths.h"

#include <catch2/catch.hpp>

#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

using namespace bodyfit;

namespace
{

/// The ellipsoids' and the skin field's bytes of a body fitted and baked on two threads.
std::string fitAndBake(const std::string& path)
{
	FitPipelineOptions options;
	options.fit.threads = 2;
	const FitPipelineResult r = fitMeshFile(path, options);
	std::vector<Ellipsoid> ellipsoids;
	for (const FittedEllipsoid& f : r.fit.ellipsoids)
		ellipsoids.push_back(f.ellipsoid);
	SkinFieldOptions bake;
	bake.threads = 2;
	std::string out; // every ellipsoid's numbers as bytes, then the field's
	for (const Ellipsoid& e : ellipsoids)
		for (const double* data : {e.center.data(), e.radii.data(), e.rotation.data()})
			out.append(reinterpret_cast<const char*>(data), (data == e.rotation.data() ? 9 : 3) * sizeof(double));
	return out + skinFieldBytes(bakeSkinField(r.loaded.mesh, ellipsoids, bake));
}

} // namespace

TEST_CASE("threads: bodies fitted and baked in threads at the same time match one after the other", "[fitting][threads]")
{
	// The decimated bodies: the same pipeline at a third of the cost (the ThreadSanitizer build runs it too).
	const std::vector<std::string> paths = {bodyfit_test::assetPath("male_young.4508v.obj"),
											bodyfit_test::assetPath("female_young.8650v.obj")};
	// Together first: what the library makes once per process on first use is then made by threads at the same time.
	std::vector<std::string> alone, together(paths.size()), failed(paths.size());
	std::vector<std::thread> threads;
	for (std::size_t i = 0; i < paths.size(); ++i)
		threads.emplace_back([&, i] {
			try
			{
				together[i] = fitAndBake(paths[i]);
			}
			catch (const std::exception& e) // reported below: an exception leaving a thread would end the process
			{
				failed[i] = e.what();
			}
		});
	for (std::thread& t : threads)
		t.join();
	for (const std::string& path : paths)
		alone.push_back(fitAndBake(path));
	for (std::size_t i = 0; i < paths.size(); ++i)
	{
		INFO(paths[i]);
		CHECK(failed[i] == "");
		REQUIRE(alone[i].size() > 1000);
		CHECK(together[i] == alone[i]); // a fit and a bake are deterministic whatever runs beside them
	}
}
