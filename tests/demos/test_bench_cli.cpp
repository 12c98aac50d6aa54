// bodyfit-bench command line: suite options are flags of their suite (checked before any work), bad ones exit 2
// with one line naming the option; --help lists them. Nothing here runs a benchmark.
#include "support/run_program.h"

#include <catch2/catch.hpp>

#include <algorithm>

namespace
{

bodyfit_test::ProgramRun bench(const std::string& args) { return bodyfit_test::runProgram(BODYFIT_BENCH_EXE, args); }

/// One line on stderr, starting with the program name.
bool oneLineError(const bodyfit_test::ProgramRun& r)
{
	return r.err.rfind("bodyfit-bench: error: ", 0) == 0 && std::count(r.err.begin(), r.err.end(), '\n') == 1;
}

} // namespace

TEST_CASE("bodyfit-bench: --help lists every suite with its own options", "[cli][bench]")
{
	const auto r = bench("--help");
	CHECK(r.exitCode == 0);
	CHECK(r.out.find("colliders_patch") != std::string::npos);
	for (const char* flag : {"--cases LETTERS", "--steps N", "--resolution N", "--voxel M", "--mesh-margin M", "--kkhr K"})
		CHECK(r.out.find(flag) != std::string::npos);
}

TEST_CASE("bodyfit-bench: bad suite options exit 2 with one line naming the option", "[cli][bench]")
{
	struct Case
	{
		std::string args, expected;
	};
	const Case cases[] = {
		{"colliders_patch --frobnicate 1", "unknown option --frobnicate"},
		{"mvee --voxel 0.05", "--voxel is not an option of suite mvee"},
		{"all --steps 3", "--steps is a suite option: give one suite, not `all`"},
		{"colliders_patch --voxel big", "--voxel: expected a number, got \"big\""},
		{"colliders_patch --voxel 2", "--voxel: 2 is out of range [0.0001, 1]"},
		{"colliders_patch --steps 0", "--steps: 0 is out of range [1, 100000]"},
		{"colliders_patch --cases ax", "--cases: expected letters from \"abct\", got \"ax\""},
		{"colliders_patch --cases", "--cases needs a value"},
		{"nosuch", "unknown suite \"nosuch\""},
	};
	for (const Case& c : cases)
	{
		const auto r = bench(c.args);
		INFO(c.args << " -> " << r.exitCode << ": " << r.err);
		CHECK(r.exitCode == 2);
		CHECK(oneLineError(r));
		CHECK(r.err.find(c.expected) != std::string::npos);
	}
}
