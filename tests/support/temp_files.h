#pragma once
// Scratch files for the robustness tests: a fresh directory per test (removed at the end), text files written
// into it, and FIFOs made at test time (never committed: a FIFO in the repository would block checkouts' tools).
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

namespace bodyfit_test
{

class TempDir
{
public:
	explicit TempDir(const std::string& tag)
		: dir_(std::filesystem::temp_directory_path() / (tag + "_" + std::to_string(long(::getpid()))))
	{
		std::filesystem::remove_all(dir_);
		std::filesystem::create_directories(dir_);
	}
	~TempDir()
	{
		std::error_code ec;
		std::filesystem::remove_all(dir_, ec);
	}
	TempDir(const TempDir&) = delete;
	TempDir& operator=(const TempDir&) = delete;

	std::string path(const std::string& name) const { return (dir_ / name).string(); }

	/// Writes `text` (binary-exact) to `name` and returns its path.
	std::string write(const std::string& name, const std::string& text) const
	{
		std::ofstream out(path(name), std::ios::binary);
		out << text;
		if (!out)
			throw std::runtime_error("cannot write " + path(name));
		return path(name);
	}

	/// Makes a FIFO `name` and returns its path.
	std::string fifo(const std::string& name) const
	{
		if (::mkfifo(path(name).c_str(), 0600) != 0)
			throw std::runtime_error("mkfifo failed for " + path(name));
		return path(name);
	}

private:
	std::filesystem::path dir_;
};

/// `n` nested JSON arrays: "[[[...]]]".
inline std::string nestedArrays(std::size_t n) { return std::string(n, '[') + std::string(n, ']'); }

} // namespace bodyfit_test

#include <fcntl.h>

#include <chrono>
#include <future>

namespace bodyfit_test
{

/// Runs `f` (which may throw) and returns whether it finished within `seconds`. If it did not, it is blocked on
/// opening `fifo` for reading: the FIFO is then opened read-write here, which releases it (it reads end of file), so
/// that a regression fails the test instead of hanging it. Exceptions of `f` are rethrown.
template <class F>
bool finishesWithin(double seconds, const std::string& fifo, F&& f)
{
	std::future<void> done = std::async(std::launch::async, std::forward<F>(f));
	if (done.wait_for(std::chrono::duration<double>(seconds)) == std::future_status::ready)
	{
		done.get();
		return true;
	}
	while (done.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready)
	{
		const int fd = ::open(fifo.c_str(), O_RDWR | O_NONBLOCK);
		if (fd >= 0)
			::close(fd);
	}
	try
	{
		done.get();
	}
	catch (...)
	{
	}
	return false;
}

} // namespace bodyfit_test
