#pragma once
/// \file parallel.h
/// Deterministic fork-join over index ranges: [0, n) is cut into `threads` contiguous ranges of (nearly) equal
/// size, the calling thread runs the first and std::threads the others. The caller merges per-index results in
/// index order, so what it computes never depends on the thread count. The first exception thrown by any range is
/// rethrown after every range has finished.

#include <algorithm>
#include <exception>
#include <thread>
#include <vector>

namespace bodyfit
{

/// Hardware threads, at least 1.
inline int hardwareThreads()
{
	return std::max(1, int(std::thread::hardware_concurrency()));
}

/// The thread count of an option: `requested` when >= 1, else every hardware thread.
inline int resolveThreads(int requested)
{
	return requested >= 1 ? requested : hardwareThreads();
}

/// Calls f(part, begin, end) on the ranges of [0, n), part = 0, 1, ...; at most `threads` ranges (fewer when n is
/// small), none empty. `part` lets each range use scratch of its own.
template <class F>
void parallelParts(int n, int threads, F&& f)
{
	const int parts = std::max(1, std::min(threads, n));
	if (parts == 1)
	{
		if (n > 0)
			f(0, 0, n);
		return;
	}
	std::vector<std::exception_ptr> errors(static_cast<std::size_t>(parts));
	auto run = [&](int part) {
		try
		{
			f(part, int((long long)n * part / parts), int((long long)n * (part + 1) / parts));
		}
		catch (...)
		{
			errors[std::size_t(part)] = std::current_exception();
		}
	};
	std::vector<std::thread> workers;
	workers.reserve(std::size_t(parts - 1));
	for (int part = 1; part < parts; ++part)
		workers.emplace_back(run, part);
	run(0);
	for (std::thread& t : workers)
		t.join();
	for (const std::exception_ptr& e : errors)
		if (e)
			std::rethrow_exception(e);
}

/// Calls f(begin, end) on the ranges of [0, n) (parallelParts without the part index).
template <class F>
void parallelRanges(int n, int threads, F&& f)
{
	parallelParts(n, threads, [&](int, int begin, int end) { f(begin, end); });
}

} // namespace bodyfit
