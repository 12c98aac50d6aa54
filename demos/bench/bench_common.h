#pragma once
/// \file bench_common.h
/// Shared pieces of `bodyfit-bench`: the suite registry (with each suite's own command-line options), median timing
/// and result tables (markdown on stdout, CSV in --out DIR).
///
/// Adding a suite: create demos/bench/suite_<name>.cpp (demos/CMakeLists.txt globs demos/bench/suite_*.cpp into
/// bodyfit-bench; re-run cmake after adding the file) and register it at namespace scope:
///
///   BODYFIT_BENCH_SUITE(kmeans, "pruned K-means on body regions")
///   {
///       bodyfit_bench::Table t({"n", "median ms"});
///       const double ms = bodyfit_bench::medianMs(ctx.repeats, [&] { ... });
///       t.addRow({bodyfit_bench::fmtInt(n), bodyfit_bench::fmt(ms, 3)});
///       return bodyfit_bench::emit(ctx, "kmeans", t);
///   }
///
/// The body receives `const bodyfit_bench::Context& ctx` and returns a process exit code (0 = ok).
///
/// A suite with settings of its own declares them as options (`bodyfit-bench NAME --steps 120`); the command line
/// accepts them only together with that suite, and the body reads them from ctx (range-checked, one-line errors):
///
///   BODYFIT_BENCH_SUITE_WITH_OPTIONS(drop, "cloth drop", {"--steps", "N", "steps to run (default 120)"})
///   {
///       const int steps = ctx.integer("--steps", 120, 1, 100000);
///       ...
///   }

#include "common/cli.h"

#include "bodyfit/fitting/statistics.h"
#include "bodyfit/bullet_ext/btTiming.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace bodyfit_bench
{

/// An option of one suite: `name` with its dashes, always followed by a value.
struct SuiteOption
{
	std::string name;
	std::string metavar;
	std::string help;
};

/// What the command line asked for.
struct Context
{
	std::string outDir; ///< empty: no files; else each table is also written as <outDir>/<suite>[_<part>].csv
	int repeats = 15;   ///< timed repetitions per measurement (the median is reported)
	bool repeatsGiven = false; ///< --repeats was on the command line (suites with their own default use it then)
	bool quick = false;        ///< --quick: smaller sweeps / shorter runs (each suite says what it drops)
	std::map<std::string, std::string> options; ///< the suite's own options that were given (name -> value)

	bool has(const std::string& name) const { return options.count(name) != 0; }
	/// The option as text, or `fallback` when absent.
	std::string text(const std::string& name, const std::string& fallback) const
	{
		return has(name) ? options.at(name) : fallback;
	}
	/// The option as a number in [lo, hi], or `fallback`. \throws bodyfit_cli::UsageError naming the option.
	double number(const std::string& name, double fallback, double lo, double hi) const
	{
		if (!has(name))
			return fallback;
		const double v = bodyfit_cli::parseDouble(options.at(name), name);
		if (!(v >= lo && v <= hi))
			throw bodyfit_cli::UsageError(name + ": " + options.at(name) + " is out of range [" + fmtRange(lo) +
										  ", " + fmtRange(hi) + "]");
		return v;
	}
	/// The option as an integer in [lo, hi], or `fallback`. \throws bodyfit_cli::UsageError naming the option.
	int integer(const std::string& name, int fallback, long long lo, long long hi) const
	{
		if (!has(name))
			return fallback;
		const long long v = bodyfit_cli::parseInt(options.at(name), name);
		if (v < lo || v > hi)
			throw bodyfit_cli::UsageError(name + ": " + options.at(name) + " is out of range [" + std::to_string(lo) +
										  ", " + std::to_string(hi) + "]");
		return int(v);
	}

private:
	static std::string fmtRange(double v)
	{
		char buf[32];
		std::snprintf(buf, sizeof buf, "%g", v);
		return buf;
	}
};

using SuiteFunction = int (*)(const Context&);

struct Suite
{
	std::string name;
	std::string description;
	SuiteFunction run = nullptr;
	std::vector<SuiteOption> options;
};

/// All suites linked into the executable, in registration order (sorted by name when listed).
inline std::vector<Suite>& registry()
{
	static std::vector<Suite> suites;
	return suites;
}

struct SuiteRegistrar
{
	SuiteRegistrar(const char* name, const char* description, SuiteFunction run,
				   std::vector<SuiteOption> options = {})
	{
		registry().push_back(Suite{name, description, run, std::move(options)});
	}
};

/// Defines and registers a suite; the braces that follow are its body (parameter `ctx`).
#define BODYFIT_BENCH_SUITE(NAME, DESCRIPTION)                                                                        \
	static int bodyfitBenchSuite_##NAME(const ::bodyfit_bench::Context& ctx);                                         \
	static const ::bodyfit_bench::SuiteRegistrar bodyfitBenchRegistrar_##NAME(#NAME, DESCRIPTION,                     \
	                                                                           &bodyfitBenchSuite_##NAME);          \
	static int bodyfitBenchSuite_##NAME(const ::bodyfit_bench::Context& ctx)

/// The same, with the suite's own options (SuiteOption initialisers, e.g. {"--steps", "N", "steps to run"}).
#define BODYFIT_BENCH_SUITE_WITH_OPTIONS(NAME, DESCRIPTION, ...)                                                      \
	static int bodyfitBenchSuite_##NAME(const ::bodyfit_bench::Context& ctx);                                         \
	static const ::bodyfit_bench::SuiteRegistrar bodyfitBenchRegistrar_##NAME(                                        \
		#NAME, DESCRIPTION, &bodyfitBenchSuite_##NAME, std::vector<::bodyfit_bench::SuiteOption>{__VA_ARGS__});        \
	static int bodyfitBenchSuite_##NAME(const ::bodyfit_bench::Context& ctx)

/// Median over `repeats` calls of f (after one untimed warm-up call) of clock() after - before, in milliseconds;
/// `clock` returns seconds.
template <class F, class C>
double medianOfCalls(int repeats, F&& f, C&& clock)
{
	f();
	std::vector<double> ms;
	ms.reserve(size_t(std::max(1, repeats)));
	for (int r = 0; r < std::max(1, repeats); ++r)
	{
		const double t0 = clock();
		f();
		ms.push_back(1e3 * (clock() - t0));
	}
	return bodyfit::median(ms);
}

/// Median wall time in milliseconds of `repeats` calls of f (after one untimed warm-up call).
template <class F>
double medianMs(int repeats, F&& f)
{
	return medianOfCalls(repeats, f, [] {
		return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
	});
}

/// Median thread CPU time in milliseconds of `repeats` calls of f (after one untimed warm-up call): unlike wall time
/// it does not grow when other processes compete for the cores, so it is the figure to quote from a shared machine.
template <class F>
double medianCpuMs(int repeats, F&& f)
{
	return medianOfCalls(repeats, f, [] { return btThreadCpuSeconds(); });
}

/// Fixed-point formatting with `digits` decimals; scientific when the value is tiny or huge.
inline std::string fmt(double v, int digits = 3)
{
	char buf[64];
	const double a = std::abs(v);
	if (v != 0.0 && (a < 1e-3 || a >= 1e7))
		std::snprintf(buf, sizeof buf, "%.*e", std::max(1, digits - 1), v);
	else
		std::snprintf(buf, sizeof buf, "%.*f", digits, v);
	return buf;
}

inline std::string fmtInt(long long v) { return std::to_string(v); }

/// Shortest of fixed/scientific with `digits` significant digits (printf %g): parameters such as 1e-4.
inline std::string fmtGeneral(double v, int digits = 3)
{
	char buf[64];
	std::snprintf(buf, sizeof buf, "%.*g", digits, v);
	return buf;
}

/// A result table: printed as markdown, written as CSV.
class Table
{
public:
	explicit Table(std::vector<std::string> header) : header_(std::move(header)) {}

	void addRow(std::vector<std::string> row)
	{
		if (row.size() != header_.size())
			throw std::logic_error("bench table row has " + std::to_string(row.size()) + " cells, header has " +
			                       std::to_string(header_.size()));
		rows_.push_back(std::move(row));
	}

	void printMarkdown(std::ostream& os) const
	{
		std::vector<size_t> w(header_.size());
		for (size_t c = 0; c < header_.size(); ++c)
		{
			w[c] = header_[c].size();
			for (const auto& r : rows_)
				w[c] = std::max(w[c], r[c].size());
		}
		const auto line = [&](const std::vector<std::string>& cells) {
			os << "|";
			for (size_t c = 0; c < cells.size(); ++c)
				os << " " << cells[c] << std::string(w[c] - cells[c].size(), ' ') << " |";
			os << "\n";
		};
		line(header_);
		os << "|";
		for (size_t c = 0; c < header_.size(); ++c)
			os << std::string(w[c] + 2, '-') << "|";
		os << "\n";
		for (const auto& r : rows_)
			line(r);
	}

	/// \throws std::runtime_error naming the file when it cannot be written.
	void writeCsv(const std::string& path) const
	{
		std::ofstream f(path);
		if (!f)
			throw std::runtime_error("cannot write " + path);
		const auto line = [&](const std::vector<std::string>& cells) {
			for (size_t c = 0; c < cells.size(); ++c)
				f << (c ? "," : "") << cells[c];
			f << "\n";
		};
		line(header_);
		for (const auto& r : rows_)
			line(r);
		if (!f)
			throw std::runtime_error("cannot write " + path);
	}

private:
	std::vector<std::string> header_;
	std::vector<std::vector<std::string>> rows_;
};

/// Prints the table (markdown) and, with --out, writes <outDir>/<stem>.csv. Returns 0.
inline int emit(const Context& ctx, const std::string& stem, const Table& table)
{
	table.printMarkdown(std::cout);
	std::cout << std::flush;
	if (!ctx.outDir.empty())
	{
		std::filesystem::create_directories(ctx.outDir);
		const std::string path = (std::filesystem::path(ctx.outDir) / (stem + ".csv")).string();
		table.writeCsv(path);
		std::cout << "(written " << path << ")\n";
	}
	return 0;
}

} // namespace bodyfit_bench
