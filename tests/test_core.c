/* test_core.c — tests for the hash functions, the PCG32 generator and the thread pool. */
#include "harness.h"

#include "core/rng.h"
#include "core/threadpool.h"

#include <stdatomic.h>
#include <stdint.h>

static int popcount64(uint64_t x) {
    int n = 0;
    while (x) {
        x &= x - 1;
        n++;
    }
    return n;
}

static void test_hash_determinism(void) {
    for (uint64_t i = 0; i < 1000; i++) {
        CHECK(pn_hash64(i) == pn_hash64(i));
        CHECK(pn_hash3(i, 2 * i, 3 * i) == pn_hash3(i, 2 * i, 3 * i));
    }
    CHECK(pn_hash64(0) != 0);
    CHECK(pn_hash3(1, 2, 3) != pn_hash3(2, 1, 3));
    CHECK(pn_hash3(1, 2, 3) != pn_hash3(1, 3, 2));
    CHECK(pn_hash3(0, 0, 0) != pn_hash3(0, 0, 1));
}

/* Flipping one input bit should flip about half of the output bits. */
static void test_hash_avalanche(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 123, 0);
    double total = 0.0;
    int trials = 0;
    int min_flips = 64;
    for (int t = 0; t < 2000; t++) {
        uint64_t x = ((uint64_t)pn_rng_u32(&rng) << 32) | pn_rng_u32(&rng);
        int bit = (int)pn_rng_below(&rng, 64);
        int flips = popcount64(pn_hash64(x) ^ pn_hash64(x ^ (UINT64_C(1) << bit)));
        total += flips;
        if (flips < min_flips) min_flips = flips;
        trials++;
    }
    double mean = total / trials;
    CHECK_NEAR(mean, 32.0, 1.0);
    CHECK(min_flips > 8);
    /* No collisions among a run of consecutive keys (the mixer is a bijection). */
    uint64_t prev = pn_hash64(0);
    int distinct = 1;
    for (uint64_t i = 1; i < 10000; i++) {
        uint64_t h = pn_hash64(i);
        if (h != prev) distinct++;
        prev = h;
    }
    CHECK(distinct == 10000);
}

static void test_rng_reference(void) {
    /* Reference output of the PCG32 demo program (seed 42, stream 54). */
    static const uint32_t expected[6] = {0xa15c02b7u, 0x7b47f409u, 0xba1d3330u, 0x83d2f293u, 0xbfa4784bu, 0xcbed606eu};
    pn_rng rng;
    pn_rng_seed(&rng, 42u, 54u);
    for (int i = 0; i < 6; i++) {
        uint32_t v = pn_rng_u32(&rng);
        CHECK_MSG(v == expected[i], "output %d: 0x%08x, expected 0x%08x", i, v, expected[i]);
    }
}

static void test_rng_determinism_and_streams(void) {
    pn_rng a, b, c;
    pn_rng_seed(&a, 7, 3);
    pn_rng_seed(&b, 7, 3);
    pn_rng_seed(&c, 7, 4);
    int same_as_other_stream = 0;
    for (int i = 0; i < 1000; i++) {
        uint32_t x = pn_rng_u32(&a), y = pn_rng_u32(&b), z = pn_rng_u32(&c);
        CHECK(x == y);
        if (x == z) same_as_other_stream++;
    }
    CHECK(same_as_other_stream < 3);
}

static void test_rng_float_range(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 99, 1);
    double sum = 0.0;
    float lo = 1.0f, hi = 0.0f;
    const int n = 1000000;
    int bins[16] = {0};
    for (int i = 0; i < n; i++) {
        float u = pn_rng_float(&rng);
        CHECK(u >= 0.0f && u < 1.0f);
        if (u < lo) lo = u;
        if (u > hi) hi = u;
        sum += (double)u;
        bins[(int)(u * 16.0f)]++;
    }
    CHECK_NEAR(sum / n, 0.5, 0.002);
    CHECK(lo < 1e-4f);
    CHECK(hi > 0.9999f);
    /* Chi-square with 15 degrees of freedom; critical value at p = 0.001 is 37.70. */
    double chi2 = 0.0, expected = n / 16.0;
    for (int i = 0; i < 16; i++) chi2 += (bins[i] - expected) * (bins[i] - expected) / expected;
    CHECK_MSG(chi2 < 37.70, "chi2 = %g", chi2);
    /* The largest value the conversion can produce is still below 1. */
    CHECK((float)(0xffffffffu >> 8) * 0x1p-24f < 1.0f);
    for (int i = 0; i < 1000; i++) CHECK(pn_rng_below(&rng, 10) < 10);
}

/* ---- thread pool ------------------------------------------------------------------------- */

#define MAX_JOBS 2000
#define MAX_WORKERS 64

typedef struct pool_check {
    atomic_int hits[MAX_JOBS];
    atomic_int busy[MAX_WORKERS]; /* 1 while a job runs on that worker index */
    atomic_int bad_worker;
    atomic_int overlap;
    int size;
} pool_check;

static void count_job(void *user, size_t job, int worker) {
    pool_check *pc = user;
    if (worker < 0 || worker >= pc->size || worker >= MAX_WORKERS) {
        atomic_fetch_add(&pc->bad_worker, 1);
        return;
    }
    if (atomic_exchange(&pc->busy[worker], 1) != 0) atomic_fetch_add(&pc->overlap, 1);
    atomic_fetch_add(&pc->hits[job], 1);
    /* A little uneven work so that the dynamic scheduling interleaves. */
    volatile unsigned spin = 0;
    for (unsigned i = 0; i < (unsigned)(job % 7) * 50u; i++) spin += i;
    atomic_store(&pc->busy[worker], 0);
}

static void run_pool_checks(pn_threadpool *pool, int runs) {
    static pool_check pc; /* large; test-local and used by one test at a time */
    pc.size = pn_threadpool_size(pool);
    for (int r = 0; r < runs; r++) {
        size_t jobs = (size_t)((r * 37) % MAX_JOBS);
        if (r % 5 == 0) jobs = (size_t)(r % 4); /* tiny job counts, including 0 and 1 */
        for (int i = 0; i < MAX_JOBS; i++) atomic_store(&pc.hits[i], 0);
        atomic_store(&pc.bad_worker, 0);
        atomic_store(&pc.overlap, 0);
        pn_threadpool_run(pool, jobs, count_job, &pc);
        int wrong = 0;
        for (size_t i = 0; i < MAX_JOBS; i++) {
            int expect = i < jobs ? 1 : 0;
            if (atomic_load(&pc.hits[i]) != expect) wrong++;
        }
        CHECK_MSG(wrong == 0, "run %d (%zu jobs, %d workers): %d jobs not run exactly once", r, jobs, pc.size, wrong);
        CHECK(atomic_load(&pc.bad_worker) == 0);
        CHECK(atomic_load(&pc.overlap) == 0);
        if (wrong) break;
    }
}

static void test_threadpool_counts(void) {
    static const int counts[] = {1, 2, 3, 8};
    for (int t = 0; t < 4; t++) {
        pn_threadpool *pool = pn_threadpool_create(counts[t]);
        CHECK(pool != NULL);
        if (!pool) continue;
        CHECK(pn_threadpool_size(pool) == counts[t]);
        run_pool_checks(pool, 150);
        pn_threadpool_destroy(pool);
    }
}

static void test_threadpool_null_and_default(void) {
    CHECK(pn_threadpool_size(NULL) == 1);
    run_pool_checks(NULL, 20);
    pn_threadpool *pool = pn_threadpool_create(0);
    CHECK(pool != NULL);
    if (pool) {
        CHECK(pn_threadpool_size(pool) >= 1);
        run_pool_checks(pool, 20);
        pn_threadpool_destroy(pool);
    }
    pn_threadpool_destroy(NULL);
    /* Create and destroy without ever running. */
    for (int i = 0; i < 20; i++) {
        pn_threadpool *p = pn_threadpool_create(3);
        CHECK(p != NULL);
        pn_threadpool_destroy(p);
    }
}

typedef struct sum_ctx {
    double partial[MAX_WORKERS];
} sum_ctx;

static void sum_job(void *user, size_t job, int worker) {
    sum_ctx *s = user;
    s->partial[worker] += (double)job;
}

/* Per-worker scratch accumulation gives the exact total (the documented usage pattern). */
static void test_threadpool_worker_scratch(void) {
    pn_threadpool *pool = pn_threadpool_create(4);
    CHECK(pool != NULL);
    if (!pool) return;
    for (int r = 0; r < 50; r++) {
        sum_ctx s;
        memset(&s, 0, sizeof s);
        size_t n = 10000 + (size_t)r;
        pn_threadpool_run(pool, n, sum_job, &s);
        double total = 0.0;
        for (int w = 0; w < MAX_WORKERS; w++) total += s.partial[w];
        CHECK(total == (double)n * (double)(n - 1) / 2.0);
    }
    pn_threadpool_destroy(pool);
}

PN_TESTS(TEST(test_hash_determinism), TEST(test_hash_avalanche), TEST(test_rng_reference),
         TEST(test_rng_determinism_and_streams), TEST(test_rng_float_range), TEST(test_threadpool_counts),
         TEST(test_threadpool_null_and_default), TEST(test_threadpool_worker_scratch))
