#pragma once
/// \file timing.h
/// Clocks for measurements: elapsed wall time and the CPU time of the calling thread. Thread CPU time is the
/// robust cost on a shared, busy machine (wall time there mostly measures the other processes).

#include <chrono>

namespace bodyfit
{

using SteadyClock = std::chrono::steady_clock;

/// Wall time since t0 in seconds.
double secondsSince(SteadyClock::time_point t0);

/// CPU time consumed by the calling thread, in seconds (0 where the platform has no per-thread clock).
double threadCpuSeconds();

} // namespace bodyfit
