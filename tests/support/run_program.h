#pragma once
// Runs a built executable through the shell and captures its exit code, stdout and stderr (files in a scratch
// directory of this process, so parallel test processes do not share them); the small helpers the CLI tests share
// (a scratch directory per process, a whole file as text, a shell-quoted path).
#include <unistd.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace bodyfit_test
{

/// A directory `tag`_<pid> in the temporary directory (created): one per process, since ctest runs the test cases
/// of a file in parallel processes.
inline std::filesystem::path scratchDir(const std::string& tag)
{
	const std::filesystem::path dir = std::filesystem::temp_directory_path() / (tag + "_" + std::to_string(::getpid()));
	std::filesystem::create_directories(dir);
	return dir;
}

/// The whole file as bytes ("" when it cannot be read).
inline std::string readFile(const std::filesystem::path& p)
{
	std::ifstream in(p, std::ios::binary);
	return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// `s` in double quotes, for a command line (paths without quotes or dollars, as the tests make them).
inline std::string quoted(const std::string& s)
{
	return "\"" + s + "\"";
}

struct ProgramRun
{
	int exitCode = -1; ///< -1 when the program did not exit normally
	std::string out, err;
};

/// `args` are passed to the shell as they are (quote paths with spaces).
inline ProgramRun runProgram(const std::string& exe, const std::string& args)
{
	namespace fs = std::filesystem;
	const fs::path dir = scratchDir("bodyfit_test_run");
	const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
	const std::string cmd = quoted(exe) + " " + args + " > " + quoted(out.string()) + " 2> " + quoted(err.string());
	const int status = std::system(cmd.c_str());
	ProgramRun r;
	r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
	r.out = readFile(out);
	r.err = readFile(err);
	return r;
}

} // namespace bodyfit_test
