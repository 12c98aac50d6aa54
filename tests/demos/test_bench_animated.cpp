// bodyfit-bench animated, a tiny run (10 steps of ours, 2 of Bullet's refitted mesh): it writes the comparison
// table, the time series of nodes inside and contact gap for both colliders, and ours has no node inside the
// skinned body. The full run is in the README (animated bodies).
#include "support/run_program.h"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace fs = std::filesystem;

TEST_CASE("bodyfit-bench animated: table, time series and 0 nodes inside for ours", "[cli][bench][animation]")
{
	const fs::path dir = fs::temp_directory_path() / ("bodyfit_bench_animated_" + std::to_string(long(::getpid())));
	fs::remove_all(dir);
	const bodyfit_test::ProgramRun r = bodyfit_test::runProgram(
		BODYFIT_BENCH_EXE, "animated --steps 10 --bullet-steps 2 --repeats 1 --out \"" + dir.string() + "\"");
	INFO(r.err);
	REQUIRE(r.exitCode == 0);
	CHECK(r.out.find("| ours (whole run)") != std::string::npos);
	CHECK(r.out.find("| Bullet refitted mesh") != std::string::npos);
	CHECK(r.out.find("Bullet / ours = ") != std::string::npos);
	std::ifstream table(dir / "animated.csv");
	std::string header, oursRow;
	std::getline(table, header);
	std::getline(table, oursRow);
	CHECK(header.find("max nodes inside skinned body") != std::string::npos);
	// Column 10 of the table is the largest count of nodes inside the skinned body over the samples: 0 for ours.
	std::vector<std::string> cells;
	std::stringstream ss(oursRow);
	for (std::string c; std::getline(ss, c, ',');)
		cells.push_back(c);
	REQUIRE(cells.size() >= 10);
	CHECK(cells[9] == "0");
	std::ifstream series(dir / "animated_series.csv");
	std::string line;
	std::getline(series, line);
	CHECK(line == "step,time_s,ours_nodes_inside,ours_contact_gap_mm,bullet_nodes_inside,bullet_contact_gap_mm,"
				  "ours_links_crossing,bullet_links_crossing");
	int rows = 0;
	while (std::getline(series, line))
		++rows;
	CHECK(rows == 2); // samples at steps 5 and 10
	fs::remove_all(dir);
}
