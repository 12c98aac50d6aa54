// bodyfit-bench SUITE [--out DIR] [--repeats N]: runs one benchmark suite (or `all`) and prints median timings.
// Suites live in demos/bench/suite_<name>.cpp and register themselves (see bench/bench_common.h).
#include "bench/bench_common.h"
#include "common/cli.h"

#include <algorithm>
#include <iostream>

namespace
{

std::string usage()
{
	std::vector<bodyfit_bench::Suite> suites = bodyfit_bench::registry();
	std::sort(suites.begin(), suites.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
	std::string s = "usage: bodyfit-bench SUITE [--out DIR] [--repeats N] [--quick]\n"
	                "Runs a benchmark suite (Release build, single thread) and prints markdown tables of medians.\n"
	                "  SUITE          one of the suites below, or `all`\n"
	                "  --out DIR      also write each table as DIR/<table>.csv (DIR is created)\n"
	                "  --repeats N    timed repetitions per measurement, median reported (default 15, 1..10000;\n"
	                "                 the study suites have their own defaults, see their descriptions)\n"
	                "  --quick        smaller sweeps and shorter runs (study suites)\n"
	                "  -h, --help     this text\n"
	                "suites:\n";
	for (const auto& suite : suites)
		s += "  " + suite.name + std::string(suite.name.size() < 14 ? 14 - suite.name.size() : 1, ' ') +
		     suite.description + "\n";
	return s;
}

} // namespace

int main(int argc, char** argv)
{
	return bodyfit_cli::runMain("bodyfit-bench", [&] {
		bodyfit_cli::Args args(argc, argv, {{"--out", true, "DIR"}, {"--repeats", true, "N"}, {"--quick", false, ""}});
		if (args.helpRequested())
		{
			std::cout << usage();
			return bodyfit_cli::kExitOk;
		}
		args.requirePositional(1, "SUITE");
		bodyfit_bench::Context ctx;
		ctx.outDir = args.value("--out");
		if (args.has("--out")) // checked now, not after the suite has run (it was exit 1, "internal error", then)
			bodyfit_cli::requireWritableOutput(ctx.outDir, "--out", /*directory=*/true);
		ctx.repeats = args.integer("--repeats", ctx.repeats, 1, 10000);
		ctx.repeatsGiven = args.has("--repeats");
		ctx.quick = args.has("--quick");
		const std::string name = args.positional()[0];
		std::vector<bodyfit_bench::Suite> suites = bodyfit_bench::registry();
		std::sort(suites.begin(), suites.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
		int rc = 0;
		bool found = false;
		for (const auto& suite : suites)
			if (name == "all" || suite.name == name)
			{
				found = true;
				std::cout << "## " << suite.name << ": " << suite.description << "\n\n" << std::flush;
				rc = std::max(rc, suite.run(ctx));
				std::cout << "\n";
			}
		if (!found)
		{
			std::string list;
			for (const auto& suite : suites)
				list += (list.empty() ? "" : ", ") + suite.name;
			throw bodyfit_cli::UsageError("unknown suite \"" + name + "\" (available: " + list + ", all)");
		}
		return rc;
	});
}
