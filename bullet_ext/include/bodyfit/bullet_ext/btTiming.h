/*
bodyfit: clocks for measurements, shared by everything that times Bullet work (the cloth collider's statistics, the
scene runner's steps, the benchmarks): elapsed wall time, and the CPU time of the calling thread, which is the robust
cost on a shared, busy machine (wall time there mostly measures the other processes). Header only, no Bullet types.
*/

#ifndef BT_TIMING_H
#define BT_TIMING_H

#include <chrono>
#include <ctime>

/// CPU time consumed by the calling thread, in seconds (0 where the platform has no per-thread clock).
inline double btThreadCpuSeconds()
{
#if defined(CLOCK_THREAD_CPUTIME_ID)
	timespec ts;
	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0)
		return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
#endif
	return 0.0;
}

/// Wall time since t0 in seconds.
inline double btSecondsSince(std::chrono::steady_clock::time_point t0)
{
	return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

#endif // BT_TIMING_H
