/* threadpool.h — a fixed set of pthreads that execute indexed jobs with dynamic scheduling.
 *
 * pn_threadpool_run(pool, n, fn, user) calls fn(user, job, worker) once for every job in
 * [0, n), handing out job indices from an atomic counter, and returns when all have finished.
 * The calling thread takes part as worker 0; background threads are workers 1..size-1, so
 * `worker` can index per-thread scratch memory of pn_threadpool_size() entries. A pool is
 * reused across any number of run() calls; run() must not be called concurrently on the same
 * pool (nor from inside a job). A NULL pool runs all jobs serially on the caller as worker 0.
 */
#ifndef PN_CORE_THREADPOOL_H
#define PN_CORE_THREADPOOL_H

#include <stddef.h>

#include "penumbra/penumbra.h"

#include <stddef.h>

typedef struct pn_threadpool pn_threadpool;

typedef void (*pn_job_fn)(void *user, size_t job, int worker);

/* threads <= 0 selects the number of online CPUs. threads == 1 creates no background thread
 * (jobs run on the caller); more than PN_MAX_THREADS (penumbra.h) are capped, as are the CPUs
 * (pn_render refuses such settings before it gets here). Returns NULL with errno set (ENOMEM,
 * or pthread_create's code such as EAGAIN) if memory or thread creation fails. */
pn_threadpool *pn_threadpool_create(int threads);

/* Number of distinct worker indices run() may pass (background threads + the caller);
 * 1 for a NULL pool. */
int pn_threadpool_size(const pn_threadpool *pool);

void pn_threadpool_run(pn_threadpool *pool, size_t job_count, void (*fn)(void *user, size_t job, int worker),
                       void *user);

/* Stops and joins the threads; NULL is ignored. */
void pn_threadpool_destroy(pn_threadpool *pool);

#endif
