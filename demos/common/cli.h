#pragma once
/// \file cli.h
/// Shared command-line helpers of the bodyfit demos: a small strict argument parser, one-line errors and the exit
/// codes every executable uses (0 ok, 1 internal failure, 2 bad input or usage).
///
///   int main(int argc, char** argv)
///   {
///       return bodyfit_cli::runMain("bodyfit-x", [&] {
///           bodyfit_cli::Args args(argc, argv, {{"-o", true, "OUT"}, {"--absolute", false}});
///           if (args.helpRequested()) { std::cout << kUsage; return bodyfit_cli::kExitOk; }
///           ...
///       });
///   }
/// A UsageError or any bodyfit typed error (MeshLoadError, InvalidInputError, FormatError) thrown inside prints
/// "bodyfit-x: error: <one line>" to stderr and returns 2; any other exception returns 1.

#include "bodyfit/fitting/errors.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace bodyfit_cli
{

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;  ///< internal error (a bug or an unexpected system failure)
constexpr int kExitBadInput = 2; ///< bad arguments, unreadable or invalid input files, unwritable outputs

/// Wrong command line: unknown option, missing value, value out of range, missing positional argument.
class UsageError : public std::runtime_error
{
public:
	using std::runtime_error::runtime_error;
};

/// An option the program accepts. `name` includes its dashes ("-o", "--mu-torso").
struct OptionSpec
{
	std::string name;
	bool takesValue = false;
	std::string metavar; ///< for messages: "--mu-torso R"
};

/// Collapses a message onto one line (newlines and tabs become spaces).
inline std::string oneLine(std::string s)
{
	for (char& c : s)
		if (c == '\n' || c == '\r' || c == '\t')
			c = ' ';
	while (!s.empty() && s.back() == ' ')
		s.pop_back();
	return s;
}

/// A number for messages: the shortest text that reads back as `v` (1e+39, 0.001, 1278.228983290694).
inline std::string formatNumber(double v)
{
	if (v == std::floor(v) && std::abs(v) < 1e15)
		return std::to_string((long long)v);
	for (int precision = 1;; ++precision)
	{
		char buf[40];
		std::snprintf(buf, sizeof buf, "%.*g", precision, v);
		if (precision >= 17 || std::strtod(buf, nullptr) == v)
			return buf;
	}
}

/// Strict parse of a finite double: the whole text must be a number.
inline double parseDouble(const std::string& text, const std::string& option)
{
	std::size_t used = 0;
	double v = 0.0;
	try
	{
		v = std::stod(text, &used);
	}
	catch (const std::exception&)
	{
		used = 0;
	}
	if (used == 0 || used != text.size() || !std::isfinite(v))
		throw UsageError(option + ": expected a number, got \"" + text + "\"");
	return v;
}

/// Strict parse of an int: the whole text must be an integer.
inline long long parseInt(const std::string& text, const std::string& option)
{
	std::size_t used = 0;
	long long v = 0;
	try
	{
		v = std::stoll(text, &used);
	}
	catch (const std::exception&)
	{
		used = 0;
	}
	if (used == 0 || used != text.size())
		throw UsageError(option + ": expected an integer, got \"" + text + "\"");
	return v;
}

/// Parsed command line. Options may be given as "--name value" or "--name=value"; "-h"/"--help" are always known;
/// "--" ends the options. Repeating an option is an error (the intent would be ambiguous).
class Args
{
public:
	Args(int argc, char** argv, std::vector<OptionSpec> specs) : specs_(std::move(specs))
	{
		bool optionsDone = false;
		for (int i = 1; i < argc; ++i)
		{
			std::string arg = argv[i];
			if (optionsDone || arg.size() < 2 || arg[0] != '-' || isNumberLike(arg))
			{
				positional_.push_back(arg);
				continue;
			}
			if (arg == "--")
			{
				optionsDone = true;
				continue;
			}
			if (arg == "-h" || arg == "--help")
			{
				help_ = true;
				continue;
			}
			std::string value;
			bool inlineValue = false;
			const std::size_t eq = arg.find('=');
			if (arg.rfind("--", 0) == 0 && eq != std::string::npos)
			{
				value = arg.substr(eq + 1);
				arg = arg.substr(0, eq);
				inlineValue = true;
			}
			const OptionSpec* spec = find(arg);
			if (spec == nullptr)
				throw UsageError("unknown option " + arg + " (see --help)");
			if (values_.count(arg) != 0)
				throw UsageError(arg + " given more than once");
			if (spec->takesValue)
			{
				if (!inlineValue)
				{
					if (i + 1 >= argc)
						throw UsageError(arg + " needs a value (" + describe(*spec) + ")");
					value = argv[++i];
					// "-o --scale" is a forgotten value, not a file named --scale (a file of that name is "./--scale")
					if (value.size() > 1 && value[0] == '-' && !isNumberLike(value))
						throw UsageError(arg + " needs a value (" + describe(*spec) + "), got the option " + value);
				}
			}
			else if (inlineValue)
				throw UsageError(arg + " takes no value");
			values_[arg] = value;
		}
	}

	bool helpRequested() const { return help_; }
	bool has(const std::string& name) const { return values_.count(name) != 0; }
	const std::vector<std::string>& positional() const { return positional_; }

	std::string value(const std::string& name, const std::string& fallback = "") const
	{
		const auto it = values_.find(name);
		return it == values_.end() ? fallback : it->second;
	}

	/// The value as a double in [lo, hi] (exclusive bounds when `open`), or `fallback` when absent.
	double number(const std::string& name, double fallback, double lo, double hi, bool open = false) const
	{
		if (!has(name))
			return fallback;
		const double v = parseDouble(value(name), name);
		const bool ok = open ? (v > lo && v < hi) : (v >= lo && v <= hi);
		if (!ok)
			throw UsageError(name + ": " + value(name) + " is out of range " + (open ? "(" : "[") + fmt(lo) + ", " +
							 fmt(hi) + (open ? ")" : "]"));
		return v;
	}

	/// The value as an int in [lo, hi], or `fallback` when absent.
	int integer(const std::string& name, int fallback, long long lo, long long hi) const
	{
		if (!has(name))
			return fallback;
		const long long v = parseInt(value(name), name);
		if (v < lo || v > hi)
			throw UsageError(name + ": " + value(name) + " is out of range [" + std::to_string(lo) + ", " +
							 std::to_string(hi) + "]");
		return int(v);
	}

	/// The value, which must be one of `choices`, or `fallback` when absent.
	std::string choice(const std::string& name, const std::vector<std::string>& choices,
					   const std::string& fallback) const
	{
		if (!has(name))
			return fallback;
		const std::string v = value(name);
		std::string list;
		for (const std::string& c : choices)
		{
			if (c == v)
				return v;
			list += (list.empty() ? "" : "|") + c;
		}
		throw UsageError(name + ": expected " + list + ", got \"" + v + "\"");
	}

	/// Exactly n positional arguments (named in the message).
	void requirePositional(std::size_t n, const std::string& what) const
	{
		if (positional_.size() < n)
			throw UsageError("missing " + what + " (see --help)");
		if (positional_.size() > n)
			throw UsageError("unexpected argument \"" + positional_[n] + "\" (see --help)");
	}

private:
	static bool isNumberLike(const std::string& s) { return s.size() > 1 && (std::isdigit((unsigned char)s[1]) || s[1] == '.'); }
	static std::string fmt(double v)
	{
		std::string s = std::to_string(v);
		while (s.find('.') != std::string::npos && (s.back() == '0' || s.back() == '.'))
		{
			const bool dot = s.back() == '.';
			s.pop_back();
			if (dot)
				break;
		}
		return s;
	}
	static std::string describe(const OptionSpec& s) { return s.name + (s.metavar.empty() ? "" : " " + s.metavar); }
	const OptionSpec* find(const std::string& name) const
	{
		for (const OptionSpec& s : specs_)
			if (s.name == name)
				return &s;
		return nullptr;
	}

	std::vector<OptionSpec> specs_;
	std::map<std::string, std::string> values_;
	std::vector<std::string> positional_;
	bool help_ = false;
};

/// Creates and removes `probe` (which must not exist): the one sure test that a file can be created there (access()
/// says yes to root in /proc, where nothing can be created). "" on success, else the reason.
inline std::string probeCreate(const std::string& probe)
{
	const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NONBLOCK | O_CLOEXEC, 0600);
	if (fd < 0)
		return std::strerror(errno);
	::close(fd);
	::unlink(probe.c_str());
	return "";
}

/// Checks, before any work is done and leaving nothing behind, that `path` can be written as the output file
/// (`directory` false) or directory (`directory` true) of `option`: an existing file must be writable and not a
/// directory (a FIFO only with a reader: it would block), an existing directory must take a new file; a missing
/// path is created and removed again (its directory exists) or needs its nearest existing ancestor to take a new
/// file (the missing levels are created when writing).
/// \throws UsageError "OPTION: cannot write 'PATH': <reason>".
inline void requireWritableOutput(const std::string& path, const std::string& option, bool directory = false)
{
	auto fail = [&](const std::string& why) { throw UsageError(option + ": cannot write '" + path + "': " + why); };
	if (path.empty())
		throw UsageError(option + ": empty file name");
	const std::string probeName = ".bodyfit_write_probe_" + std::to_string(long(::getpid()));
	struct stat st
	{
	};
	if (::stat(path.c_str(), &st) == 0)
	{
		if (S_ISDIR(st.st_mode) != directory)
			fail(directory ? "it exists and is not a directory" : "it is a directory");
		if (directory)
		{
			const std::string why = probeCreate((std::filesystem::path(path) / probeName).string());
			if (!why.empty())
				fail(why);
			return;
		}
		const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC); // no O_TRUNC: nothing changes
		if (fd < 0)
			fail(errno == ENXIO ? "it is a FIFO without a reader" : std::strerror(errno));
		::close(fd);
		return;
	}
	if (errno != ENOENT)
		fail(std::strerror(errno));
	const std::filesystem::path parent = std::filesystem::absolute(path).parent_path();
	if (!directory && ::stat(parent.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
	{
		const std::string why = probeCreate(path);
		if (!why.empty())
			fail(why);
		return;
	}
	std::filesystem::path ancestor = parent;
	while (::stat(ancestor.c_str(), &st) != 0 && errno == ENOENT && ancestor.has_relative_path())
		ancestor = ancestor.parent_path();
	if (::stat(ancestor.c_str(), &st) != 0)
		fail(ancestor.string() + ": " + std::strerror(errno));
	if (!S_ISDIR(st.st_mode))
		fail("'" + ancestor.string() + "' is not a directory");
	const std::string why = probeCreate((ancestor / probeName).string());
	if (!why.empty())
		fail("cannot create anything in '" + ancestor.string() + "': " + why);
}

/// Refuses an output that is one of the inputs (the same file, also through another name or a link) or the same
/// path as an earlier output: `outputs` are (option, path) pairs, `inputs` (what, path) pairs; empty paths are
/// skipped. \throws UsageError "OPTION: 'PATH' is the WHAT; refusing to overwrite it".
inline void requireDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& outputs,
								   const std::vector<std::pair<std::string, std::string>>& inputs)
{
	auto same = [](const std::string& a, const std::string& b) {
		std::error_code ec;
		if (std::filesystem::equivalent(a, b, ec))
			return true;
		return std::filesystem::weakly_canonical(a, ec) == std::filesystem::weakly_canonical(b, ec) && !ec;
	};
	for (std::size_t i = 0; i < outputs.size(); ++i)
	{
		const auto& [option, path] = outputs[i];
		if (path.empty())
			continue;
		for (const auto& [what, input] : inputs)
			if (!input.empty() && same(path, input))
				throw UsageError(option + ": '" + path + "' is the " + what + "; refusing to overwrite it");
		for (std::size_t j = 0; j < i; ++j)
			if (!outputs[j].second.empty() && same(path, outputs[j].second))
				throw UsageError(option + ": '" + path + "' is also the output of " + outputs[j].first);
	}
}

/// Creates the parent directory of an output file if it is missing. \throws UsageError naming the directory.
inline void ensureParentDirectory(const std::string& path)
{
	const std::filesystem::path parent = std::filesystem::path(path).parent_path();
	if (parent.empty())
		return;
	std::error_code ec;
	std::filesystem::create_directories(parent, ec);
	if (ec || !std::filesystem::is_directory(parent))
		throw UsageError("cannot create output directory " + parent.string() + ": " + ec.message());
}

/// Runs `body` and turns exceptions into one-line errors and exit codes (see the file comment).
template <class Body>
int runMain(const char* program, Body&& body)
{
	try
	{
		return body();
	}
	catch (const UsageError& e)
	{
		std::cerr << program << ": error: " << oneLine(e.what()) << "\n";
	}
	catch (const bodyfit::MeshLoadError& e)
	{
		std::cerr << program << ": error: " << oneLine(e.what()) << "\n";
	}
	catch (const bodyfit::InvalidInputError& e)
	{
		std::cerr << program << ": error: " << oneLine(e.what()) << "\n";
	}
	catch (const bodyfit::FormatError& e)
	{
		std::cerr << program << ": error: " << oneLine(e.what()) << "\n";
	}
	catch (const std::exception& e)
	{
		std::cerr << program << ": internal error: " << oneLine(e.what()) << "\n";
		return kExitFailure;
	}
	return kExitBadInput;
}

} // namespace bodyfit_cli
