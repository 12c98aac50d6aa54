#pragma once
// Runs a built executable through the shell and captures its exit code, stdout and stderr (files in a scratch
// directory of this process, so parallel test processes do not share them).
#include <unistd.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace bodyfit_test
{

struct ProgramRun
{
	int exitCode = -1; ///< -1 when the program did not exit normally
	std::string out, err;
};

/// `args` are passed to the shell as they are (quote paths with spaces).
inline ProgramRun runProgram(const std::string& exe, const std::string& args)
{
	namespace fs = std::filesystem;
	const fs::path dir = fs::temp_directory_path() / ("bodyfit_test_run_" + std::to_string(::getpid()));
	fs::create_directories(dir);
	const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
	const std::string cmd = "\"" + exe + "\" " + args + " > \"" + out.string() + "\" 2> \"" + err.string() + "\"";
	const int status = std::system(cmd.c_str());
	ProgramRun r;
	r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
	auto slurp = [](const fs::path& p) {
		std::ifstream in(p, std::ios::binary);
		return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	};
	r.out = slurp(out);
	r.err = slurp(err);
	return r;
}

} // namespace bodyfit_test
