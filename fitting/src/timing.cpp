#include "bodyfit/fitting/timing.h"

#include <ctime>

namespace bodyfit
{

double secondsSince(SteadyClock::time_point t0)
{
	return std::chrono::duration<double>(SteadyClock::now() - t0).count();
}

double threadCpuSeconds()
{
#if defined(CLOCK_THREAD_CPUTIME_ID)
	timespec ts;
	if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0)
		return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
#endif
	return 0.0;
}

} // namespace bodyfit
