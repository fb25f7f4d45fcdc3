/* clock.h — the library's one wall clock: monotonic seconds, for timings in the statistics. */
#ifndef PN_CORE_CLOCK_H
#define PN_CORE_CLOCK_H

#include <time.h>

static inline double pn_clock_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#endif
