/* threadpool.c — pthread worker pool with an atomic job counter (see threadpool.h).
 *
 * Each run() publishes the job function under the lock and bumps a generation number; sleeping
 * workers notice the new generation, pull job indices from `next` until it passes job_count,
 * and report back. run() waits until every background worker has reported for the current
 * generation, so no worker can still be touching the previous job set when run() returns or
 * when the next run() starts. The mutex hand-off also makes the jobs' writes visible to the
 * caller after run() returns.
 */
#include "core/threadpool.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

#define PN_THREADPOOL_MAX_THREADS PN_MAX_THREADS

typedef struct pn_worker_arg {
    pn_threadpool *pool;
    int index;
} pn_worker_arg;

struct pn_threadpool {
    int size;    /* workers including the caller */
    int helpers; /* background threads actually running */
    pthread_t *threads;
    pn_worker_arg *args;

    pthread_mutex_t lock;
    pthread_cond_t wake; /* signalled when a new generation starts or on shutdown */
    pthread_cond_t done; /* signalled when the last helper finishes a generation */
    uint64_t generation;
    int finished; /* helpers done with the current generation */
    bool shutdown;

    /* Current job set (written under lock before the generation is bumped). */
    void (*fn)(void *user, size_t job, int worker);
    void *user;
    size_t job_count;
    atomic_size_t next;
};

static void drain_jobs(pn_threadpool *pool, int worker) {
    size_t count = pool->job_count;
    for (;;) {
        size_t job = atomic_fetch_add_explicit(&pool->next, 1, memory_order_relaxed);
        if (job >= count) break;
        pool->fn(pool->user, job, worker);
    }
}

static void *worker_main(void *arg) {
    pn_worker_arg *wa = arg;
    pn_threadpool *pool = wa->pool;
    uint64_t seen = 0;
    pthread_mutex_lock(&pool->lock);
    for (;;) {
        while (!pool->shutdown && pool->generation == seen) pthread_cond_wait(&pool->wake, &pool->lock);
        if (pool->shutdown) break;
        seen = pool->generation;
        pthread_mutex_unlock(&pool->lock);

        drain_jobs(pool, wa->index);

        pthread_mutex_lock(&pool->lock);
        if (++pool->finished == pool->helpers) pthread_cond_signal(&pool->done);
    }
    pthread_mutex_unlock(&pool->lock);
    return NULL;
}

static void stop_helpers(pn_threadpool *pool) {
    pthread_mutex_lock(&pool->lock);
    pool->shutdown = true;
    pthread_cond_broadcast(&pool->wake);
    pthread_mutex_unlock(&pool->lock);
    for (int i = 0; i < pool->helpers; i++) pthread_join(pool->threads[i], NULL);
    pool->helpers = 0;
}

pn_threadpool *pn_threadpool_create(int threads) {
    if (threads <= 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (int)(n < PN_THREADPOOL_MAX_THREADS ? n : PN_THREADPOOL_MAX_THREADS) : 1;
    }
    if (threads > PN_THREADPOOL_MAX_THREADS) threads = PN_THREADPOOL_MAX_THREADS;

    pn_threadpool *pool = calloc(1, sizeof *pool);
    if (!pool) return NULL;
    pool->size = threads;
    atomic_init(&pool->next, 0);
    if (pthread_mutex_init(&pool->lock, NULL) != 0) {
        free(pool);
        return NULL;
    }
    if (pthread_cond_init(&pool->wake, NULL) != 0) {
        pthread_mutex_destroy(&pool->lock);
        free(pool);
        return NULL;
    }
    if (pthread_cond_init(&pool->done, NULL) != 0) {
        pthread_cond_destroy(&pool->wake);
        pthread_mutex_destroy(&pool->lock);
        free(pool);
        return NULL;
    }
    int helpers = threads - 1;
    if (helpers > 0) {
        pool->threads = calloc((size_t)helpers, sizeof *pool->threads);
        pool->args = calloc((size_t)helpers, sizeof *pool->args);
        if (!pool->threads || !pool->args) {
            pn_threadpool_destroy(pool);
            return NULL;
        }
        for (int i = 0; i < helpers; i++) {
            pool->args[i].pool = pool;
            pool->args[i].index = i + 1;
            /* helpers is read by workers only under the lock after a generation starts, and
             * no generation starts before create() returns. */
            int rc = pthread_create(&pool->threads[i], NULL, worker_main, &pool->args[i]);
            if (rc != 0) {
                pn_threadpool_destroy(pool);
                errno = rc; /* for the caller's message: EAGAIN when the thread limit is reached */
                return NULL;
            }
            pool->helpers = i + 1;
        }
    }
    return pool;
}

int pn_threadpool_size(const pn_threadpool *pool) {
    return pool ? pool->size : 1;
}

void pn_threadpool_run(pn_threadpool *pool, size_t job_count, void (*fn)(void *user, size_t job, int worker),
                       void *user) {
    if (job_count == 0 || !fn) return;
    if (!pool || pool->helpers == 0 || job_count == 1) {
        for (size_t i = 0; i < job_count; i++) fn(user, i, 0);
        return;
    }
    pthread_mutex_lock(&pool->lock);
    pool->fn = fn;
    pool->user = user;
    pool->job_count = job_count;
    atomic_store_explicit(&pool->next, 0, memory_order_relaxed);
    pool->finished = 0;
    pool->generation++;
    pthread_cond_broadcast(&pool->wake);
    pthread_mutex_unlock(&pool->lock);

    drain_jobs(pool, 0);

    pthread_mutex_lock(&pool->lock);
    while (pool->finished < pool->helpers) pthread_cond_wait(&pool->done, &pool->lock);
    pthread_mutex_unlock(&pool->lock);
}

void pn_threadpool_destroy(pn_threadpool *pool) {
    if (!pool) return;
    stop_helpers(pool);
    pthread_cond_destroy(&pool->done);
    pthread_cond_destroy(&pool->wake);
    pthread_mutex_destroy(&pool->lock);
    free(pool->threads);
    free(pool->args);
    free(pool);
}
