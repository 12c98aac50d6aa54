// The fit pipeline (fit_pipeline.h): one unit resolution for every length, the non-human fallback and its warning,
// stage timings, and the file and in-memory entry points giving the same fit.
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/fit_pipeline.h"
#include "support/mesh_shapes.h"
#include "support/paths.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

using namespace bodyfit;

namespace
{

/// The decimated bundled body (4,508 vertices): small enough to fit several times in a test.
std::string bodyPath()
{
	return bodyfit_test::assetPath("male_young.4508v.obj");
}

/// Bit-for-bit equality of two fits' ellipsoids (the fitter is deterministic, so equal inputs give equal bits).
void requireSameEllipsoids(const BodyFit& a, const BodyFit& b)
{
	REQUIRE(a.ellipsoids.size() == b.ellipsoids.size());
	for (std::size_t i = 0; i < a.ellipsoids.size(); ++i)
	{
		CAPTURE(i);
		CHECK(a.ellipsoids[i].region == b.ellipsoids[i].region);
		CHECK(a.ellipsoids[i].ellipsoid.center == b.ellipsoids[i].ellipsoid.center);
		CHECK(a.ellipsoids[i].ellipsoid.rotation == b.ellipsoids[i].ellipsoid.rotation);
		CHECK(a.ellipsoids[i].ellipsoid.radii == b.ellipsoids[i].ellipsoid.radii);
	}
	CHECK(a.vertexEllipsoid == b.vertexEllipsoid);
}

double yExtent(const TriMesh& m)
{
	return m.V.col(1).maxCoeff() - m.V.col(1).minCoeff();
}

} // namespace

TEST_CASE("fit_pipeline: resolveLengths converts every length, each in its own unit", "[fitting][fit_pipeline]")
{
	BodyFitOptions rest;
	rest.maxEllipsoids = 17;
	FitLengths lengths;
	lengths.muTorso = Length::inMetres(0.02);
	lengths.muLimbs = Length::ofHeight(0.01);
	lengths.sigma = Length::ofHeight(0.001);
	lengths.coverSpacing = Length::inMetres(0.004);
	const double h = 1.5;
	const BodyFitOptions m = resolveLengths(rest, lengths, h);
	// Products of two doubles: exact up to one rounding, hence the 1e-15 relative margin.
	CHECK(m.muTorso == 0.02);
	CHECK(m.muLimbs == Approx(0.015).epsilon(1e-15));
	CHECK(m.sigma == Approx(0.0015).epsilon(1e-15));
	CHECK(m.coverSpacing == 0.004);
	CHECK_FALSE(m.relativeToHeight);
	CHECK(m.height == h);
	CHECK(m.maxEllipsoids == 17); // the other options pass through
	CHECK_FALSE(lengths.allRelative());
	CHECK(FitLengths().allRelative());

	// fitBody's own options in metres stay as they are; relative ones scale with H.
	BodyFitOptions abs;
	abs.relativeToHeight = false;
	abs.coverSpacing = 0.005;
	CHECK(resolveLengths(abs, FitLengths::of(abs), h).coverSpacing == 0.005);
	CHECK(resolveLengths(BodyFitOptions(), FitLengths::of(BodyFitOptions()), h).coverSpacing ==
		  BodyFitOptions().coverSpacing * h);
}

TEST_CASE("fit_pipeline: lengths in metres equal to the relative ones times H give the same fit",
		  "[fitting][fit_pipeline]")
{
	const FitPipelineResult relative = fitMeshFile(bodyPath());
	const double h = relative.fit.source.height;
	REQUIRE(h == yExtent(relative.loaded.mesh));

	FitPipelineOptions metres;
	metres.lengths.muTorso = Length::inMetres(BodyFitOptions().muTorso * h);
	metres.lengths.muLimbs = Length::inMetres(BodyFitOptions().muLimbs * h);
	metres.lengths.sigma = Length::inMetres(BodyFitOptions().sigma * h);
	metres.lengths.coverSpacing = Length::inMetres(BodyFitOptions().coverSpacing * h);
	const FitPipelineResult absolute = fitMeshFile(bodyPath(), metres);

	requireSameEllipsoids(relative.fit, absolute.fit);
	// The triangle cover ran with the same piece size: the same points were added (the measured bug: the cover
	// spacing left relative under --absolute gave 291,440 points instead of 100,504 on this body).
	CHECK(absolute.fit.coverExtraPoints == relative.fit.coverExtraPoints);
	CHECK(absolute.fit.coverRounds == relative.fit.coverRounds);
	CHECK(relative.fit.coverExtraPoints > 0);
	CHECK(absolute.resolved.coverSpacing == relative.resolved.coverSpacing);
	CHECK(absolute.resolved.sigma == relative.resolved.sigma);

	// The JSON records the lengths as given: fractions when all are relative, metres otherwise.
	CHECK(relative.fit.params.relativeToHeight);
	CHECK(relative.fit.params.muTorso == BodyFitOptions().muTorso);
	CHECK(relative.fit.params.coverSpacing == BodyFitOptions().coverSpacing);
	CHECK_FALSE(absolute.fit.params.relativeToHeight);
	CHECK(absolute.fit.params.muTorso == BodyFitOptions().muTorso * h);
	CHECK(absolute.fit.params.coverSpacing == BodyFitOptions().coverSpacing * h);
}

TEST_CASE("fit_pipeline: a threshold in metres alone keeps the other lengths relative", "[fitting][fit_pipeline]")
{
	// What `bodyfit-fit --absolute --mu-torso X` asks for: only mu_torso is metres.
	FitPipelineOptions o;
	o.lengths.muTorso = Length::inMetres(0.03);
	const FitPipelineResult r = fitMeshFile(bodyPath(), o);
	const double h = r.fit.source.height;
	CHECK(r.resolved.muTorso == 0.03);
	CHECK(r.resolved.muLimbs == BodyFitOptions().muLimbs * h);
	CHECK(r.resolved.sigma == BodyFitOptions().sigma * h);
	CHECK(r.resolved.coverSpacing == BodyFitOptions().coverSpacing * h);
	CHECK_FALSE(r.fit.params.relativeToHeight);
	CHECK(r.fit.params.muTorso == 0.03);
	CHECK(r.fit.params.muLimbs == BodyFitOptions().muLimbs * h);
}

TEST_CASE("fit_pipeline: the file and the in-memory entry points give the same fit", "[fitting][fit_pipeline]")
{
	FitPipelineOptions o;
	o.fit.maxEllipsoids = 30;
	const FitPipelineResult fromFile = fitMeshFile(bodyPath(), o);
	const FitPipelineResult fromMemory = fitMesh(fromFile.loaded.full, o, "male_young(memory)");
	requireSameEllipsoids(fromFile.fit, fromMemory.fit);
	CHECK(fromFile.fit.source.mesh == "male_young.4508v.obj");
	CHECK(fromMemory.fit.source.mesh == "male_young(memory)");
	CHECK(fromMemory.timings.load == 0.0);
	CHECK(fromFile.segmentation.ok);
	CHECK_FALSE(fromFile.fallback);

	// The same as calling the fitter directly on the segmentation (the pipeline adds no fit of its own).
	const BodyFit direct = fitBody(fromFile.loaded.mesh, fromFile.segmentation.labels, o.fit);
	requireSameEllipsoids(fromFile.fit, direct);
}

TEST_CASE("fit_pipeline: a non-human mesh falls back to one region with a warning in the result and the JSON",
		  "[fitting][fit_pipeline]")
{
	const TriMesh sphere = bodyfit_test::uvSphere(0.3, 48, 24);
	const FitPipelineResult r = fitMesh(sphere);
	CHECK(r.fallback);
	CHECK_FALSE(r.segmentation.ok);
	REQUIRE_FALSE(r.warnings().empty());
	const std::string& w = r.warnings().front();
	CHECK(w.rfind("segmentation failed (", 0) == 0);
	CHECK(w.find(r.segmentation.failureReason) != std::string::npos);
	CHECK(w.find("fitted the whole mesh as one region") != std::string::npos);
	REQUIRE_FALSE(r.fit.ellipsoids.empty());
	for (const FittedEllipsoid& e : r.fit.ellipsoids)
		CHECK(e.region == Region::Whole);

	const nlohmann::json doc = nlohmann::json::parse(toEllipsoidJson(r.fit));
	REQUIRE(doc["warnings"].is_array());
	REQUIRE_FALSE(doc["warnings"].empty());
	CHECK(doc["warnings"][0].get<std::string>() == w);

	// Switched off on purpose: the same generic fit without the warning.
	FitPipelineOptions generic;
	generic.segment = false;
	const FitPipelineResult off = fitMesh(sphere, generic);
	CHECK_FALSE(off.fallback);
	for (const std::string& warning : off.warnings())
		CHECK(warning.find("segmentation failed") == std::string::npos);
	requireSameEllipsoids(r.fit, off.fit);
	CHECK(off.timings.segmentation == 0.0);
	CHECK(off.fit.timingMs("segmentation") == 0.0);
}

TEST_CASE("fit_pipeline: stage timings are >= 0 and sum to at most the total", "[fitting][fit_pipeline]")
{
	const bool cover = GENERATE(true, false);
	FitPipelineOptions o;
	o.fit.coverTriangles = cover;
	const FitPipelineResult r = fitMeshFile(bodyPath(), o);
	const FitPipelineTimings& t = r.timings;
	for (double ms : {t.load, t.repair, t.segmentation, t.fit, t.cover, t.report})
		CHECK(ms >= 0.0);
	// The stages are disjoint intervals inside the total; the sum can only be smaller.
	CHECK(t.load + t.repair + t.segmentation + t.fit + t.cover + t.report <= t.total);
	// Every stage that ran took time (steady clock: at least one tick).
	CHECK(t.load > 0.0);
	CHECK(t.repair > 0.0);
	CHECK(t.segmentation > 0.0);
	CHECK(t.fit > 0.0);
	CHECK((t.cover > 0.0) == cover);
	CHECK(t.report > 0.0);
	// The fit JSON carries the same stages under its keys, in pipeline order.
	CHECK(r.fit.timingMs("load") == t.load);
	CHECK(r.fit.timingMs("repair") == t.repair);
	CHECK(r.fit.timingMs("segmentation") == t.segmentation);
	CHECK(r.fit.timingMs("fitting") == Approx(t.fit + t.cover).margin(1e-9)); // fitting contains the cover
	CHECK(r.fit.timingMs("total") == t.total);
	REQUIRE(r.fit.timings.size() >= 3);
	CHECK(r.fit.timings[0].stage == "load");
	CHECK(r.fit.timings[1].stage == "repair");
	CHECK(r.fit.timings[2].stage == "segmentation");
}

TEST_CASE("fit_pipeline: bad input throws with a one-line reason", "[fitting][fit_pipeline]")
{
	CHECK_THROWS_AS(fitMeshFile(bodyfit_test::dataPath("does_not_exist.obj")), MeshLoadError);
	FitPipelineOptions o;
	o.lengths.muTorso = Length::inMetres(-0.01);
	CHECK_THROWS_WITH(fitMeshFile(bodyPath(), o), Catch::Contains("mu_torso must be finite and > 0"));

	// A length set in the fit options instead of the lengths would be ignored: it is refused.
	FitPipelineOptions misplaced;
	misplaced.fit.muTorso = 0.02;
	CHECK_THROWS_WITH(fitMeshFile(bodyPath(), misplaced), Catch::Contains("go in FitPipelineOptions::lengths"));
	misplaced = FitPipelineOptions();
	misplaced.fit.relativeToHeight = false;
	CHECK_THROWS_AS(fitMeshFile(bodyPath(), misplaced), InvalidInputError);
	// from() moves them where they belong.
	BodyFitOptions direct;
	direct.muTorso = 0.02;
	direct.relativeToHeight = false;
	const FitPipelineOptions converted = FitPipelineOptions::from(direct);
	CHECK(converted.lengths.muTorso.value == 0.02);
	CHECK_FALSE(converted.lengths.muTorso.relativeToHeight);
	CHECK(converted.fit.muTorso == BodyFitOptions().muTorso);
	CHECK(converted.fit.relativeToHeight);
}
