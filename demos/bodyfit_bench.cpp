// bodyfit-bench SUITE [--out DIR] [--repeats N] [--quick] [suite options]: runs one benchmark suite (or `all`) and
// prints median timings. Suites live in demos/bench/suite_<name>.cpp and register themselves, with their own
// options (see bench/bench_common.h).
#include "bench/bench_common.h"
#include "common/cli.h"

#include <algorithm>
#include <iostream>

namespace
{

std::vector<bodyfit_bench::Suite> sortedSuites()
{
	std::vector<bodyfit_bench::Suite> suites = bodyfit_bench::registry();
	std::sort(suites.begin(), suites.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
	return suites;
}

std::string usage()
{
	std::string s = "usage: bodyfit-bench SUITE [--out DIR] [--repeats N] [--quick] [suite options]\n"
	                "Runs a benchmark suite (Release build, single thread) and prints markdown tables of medians.\n"
	                "  SUITE          one of the suites below, or `all`\n"
	                "  --out DIR      also write each table as DIR/<table>.csv (DIR is created)\n"
	                "  --repeats N    timed repetitions per measurement, median reported (default 15, 1..10000;\n"
	                "                 the study suites have their own defaults, see their descriptions)\n"
	                "  --quick        smaller sweeps and shorter runs (study suites)\n"
	                "  -h, --help     this text\n"
	                "suites (with their own options, accepted only with that suite):\n";
	for (const auto& suite : sortedSuites())
	{
		s += "  " + suite.name + std::string(suite.name.size() < 14 ? 14 - suite.name.size() : 1, ' ') +
		     suite.description + "\n";
		for (const auto& o : suite.options)
		{
			const std::string flag = o.name + " " + o.metavar;
			s += "      " + flag + std::string(flag.size() < 20 ? 20 - flag.size() : 1, ' ') + o.help + "\n";
		}
	}
	return s;
}

/// The common options plus every suite's own (one spec per name).
std::vector<bodyfit_cli::OptionSpec> optionSpecs()
{
	std::vector<bodyfit_cli::OptionSpec> specs = {
		{"--out", true, "DIR"}, {"--repeats", true, "N"}, {"--quick", false, ""}};
	for (const auto& suite : bodyfit_bench::registry())
		for (const auto& o : suite.options)
			if (std::none_of(specs.begin(), specs.end(), [&](const auto& s) { return s.name == o.name; }))
				specs.push_back({o.name, true, o.metavar});
	return specs;
}

/// The given suite options, each checked to belong to the suite that runs. \throws bodyfit_cli::UsageError.
std::map<std::string, std::string> suiteOptions(const bodyfit_cli::Args& args, const std::string& name)
{
	std::map<std::string, std::string> given;
	for (const auto& spec : optionSpecs())
	{
		if (!args.has(spec.name) || spec.name == "--out" || spec.name == "--repeats" || spec.name == "--quick")
			continue;
		if (name == "all")
			throw bodyfit_cli::UsageError(spec.name + " is a suite option: give one suite, not `all`");
		const auto suites = bodyfit_bench::registry();
		const auto suite = std::find_if(suites.begin(), suites.end(), [&](const auto& s) { return s.name == name; });
		if (suite == suites.end())
			continue; // the unknown suite is reported by the caller
		std::string list;
		bool known = false;
		for (const auto& o : suite->options)
		{
			known = known || o.name == spec.name;
			list += (list.empty() ? "" : ", ") + o.name;
		}
		if (!known)
			throw bodyfit_cli::UsageError(spec.name + " is not an option of suite " + name +
										  (list.empty() ? " (it has none)" : " (its options: " + list + ")"));
		given[spec.name] = args.value(spec.name);
	}
	return given;
}

} // namespace

int main(int argc, char** argv)
{
	return bodyfit_cli::runMain("bodyfit-bench", [&] {
		bodyfit_cli::Args args(argc, argv, optionSpecs());
		if (args.helpRequested())
		{
			std::cout << usage();
			return bodyfit_cli::kExitOk;
		}
		args.requirePositional(1, "SUITE");
		const std::string name = args.positional()[0];
		bodyfit_bench::Context ctx;
		ctx.outDir = args.value("--out");
		if (args.has("--out")) // checked now, not after the suite has run (it was exit 1, "internal error", then)
			bodyfit_cli::requireWritableOutput(ctx.outDir, "--out", /*directory=*/true);
		ctx.repeats = args.integer("--repeats", ctx.repeats, 1, 10000);
		ctx.repeatsGiven = args.has("--repeats");
		ctx.quick = args.has("--quick");
		ctx.options = suiteOptions(args, name);
		const std::vector<bodyfit_bench::Suite> suites = sortedSuites();
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
