/* test_sampling.c — tests for Sobol' points, sample warps, spherical rectangle and sphere-cone
 * sampling, and the tabulated 1-D / 2-D distributions.
 *
 * Distribution tests are chi-square goodness-of-fit tests with fixed seeds compared against
 * the critical value at p = 0.001, so they are deterministic and would only fail for a real
 * error in a warp (or a badly unlucky seed, which is then fixed forever).
 */
#include "harness.h"

#include "core/rng.h"
#include "core/sampling.h"
#include "core/sobol.h"

#include <stdbool.h>
#include <stdint.h>

#define PI_D 3.14159265358979323846

/* ---- chi-square helpers ------------------------------------------------------------------ */

/* Critical value of the chi-square distribution at p = 0.001 (Wilson–Hilferty approximation,
 * accurate to well under 1% for the degrees of freedom used here). */
static double chi2_critical(int dof) {
    const double z = 3.090232; /* standard normal quantile at 0.999 */
    double k = (double)dof;
    double t = 1.0 - 2.0 / (9.0 * k) + z * sqrt(2.0 / (9.0 * k));
    return k * t * t * t;
}

/* Pearson statistic; bins with an expected count below 5 are pooled into one bin. Observed
 * counts in bins with zero expectation are reported through *impossible. */
static double chi2_stat(const double *observed, const double *expected, int n, int *dof, int *impossible) {
    double stat = 0.0, pool_obs = 0.0, pool_exp = 0.0;
    int bins = 0;
    *impossible = 0;
    for (int i = 0; i < n; i++) {
        if (expected[i] <= 0.0) {
            if (observed[i] > 0.0) (*impossible)++;
            continue;
        }
        if (expected[i] < 5.0) {
            pool_obs += observed[i];
            pool_exp += expected[i];
            continue;
        }
        double d = observed[i] - expected[i];
        stat += d * d / expected[i];
        bins++;
    }
    if (pool_exp > 0.0) {
        double d = pool_obs - pool_exp;
        stat += d * d / pool_exp;
        bins++;
    }
    *dof = bins - 1;
    return stat;
}

#define CHECK_CHI2(observed, expected, n)                                                                              \
    do {                                                                                                               \
        int dof_, impossible_;                                                                                         \
        double stat_ = chi2_stat(observed, expected, n, &dof_, &impossible_);                                          \
        double crit_ = chi2_critical(dof_);                                                                            \
        CHECK_MSG(stat_ < crit_, "chi2 = %.2f, critical %.2f (dof %d)", stat_, crit_, dof_);                           \
        CHECK_MSG(impossible_ == 0, "%d samples in zero-probability bins", impossible_);                               \
    } while (0)

/* ---- Sobol' ------------------------------------------------------------------------------ */

static void test_sobol_tables(void) {
    CHECK(pn_sobol_tables_consistent());
}

static void test_sobol_raw_values(void) {
    static const double dim1[8] = {0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875};
    for (uint32_t i = 0; i < 8; i++) CHECK_NEAR(pn_sobol_raw_u32(i, 1) * 0x1p-32, dim1[i], 0.0);
    /* Dimension 0 is van der Corput: the bit-reversed index. */
    CHECK(pn_sobol_raw_u32(1, 0) == 0x80000000u);
    CHECK(pn_sobol_raw_u32(6, 0) == 0x60000000u);
    CHECK(pn_sobol_raw_u32(0x12345678u, 0) == 0x1e6a2c48u);
    CHECK(pn_sobol_raw_u32(5, PN_SOBOL_DIMS) == 0);
}

/* The byte-table products equal the bit-by-bit products, for every dimension. */
static void test_sobol_byte_tables(void) {
    int bad = 0;
    for (int dim = 0; dim < PN_SOBOL_DIMS; dim++)
        for (uint32_t i = 0; i < 4096; i++) {
            uint32_t index = i < 2048 ? i : i * 2654435761u;
            if (pn_sobol_raw_u32(index, dim) != pn_sobol_raw_u32_by_bits(index, dim)) bad++;
        }
    CHECK_MSG(bad == 0, "%d points differ", bad);
}

static void test_sobol_range_and_determinism(void) {
    static const uint32_t scrambles[3] = {0u, 1u, 0xdeadbeefu};
    int bad = 0;
    for (int s = 0; s < 3; s++)
        for (int dim = 0; dim < PN_SOBOL_DIMS + 16; dim += 3)
            for (uint32_t i = 0; i < 2048; i++) {
                float u = pn_sobol_sample(i, dim, scrambles[s]);
                if (!(u >= 0.0f && u < 1.0f)) bad++;
                if (u != pn_sobol_sample(i, dim, scrambles[s])) bad++;
                if (pn_sobol_sample_u32(i, dim, scrambles[s]) != pn_sobol_sample_u32(i, dim, scrambles[s])) bad++;
            }
    CHECK(bad == 0);
    /* Large indices, including the very last, stay below 1. */
    for (int dim = 0; dim < 8; dim++) {
        CHECK(pn_sobol_sample(0xffffffffu, dim, 3u) < 1.0f);
        CHECK(pn_sobol_sample(0x80000000u, dim, 3u) < 1.0f);
    }
}

static void test_sobol_scrambling_changes_points(void) {
    /* Scramble 0 is a real randomisation, and different scrambles differ. */
    for (int dim = 0; dim < 8; dim++) {
        int same_raw = 0, same_other = 0;
        for (uint32_t i = 0; i < 256; i++) {
            uint32_t a = pn_sobol_sample_u32(i, dim, 0u);
            if (a == pn_sobol_raw_u32(i, dim)) same_raw++;
            if (a == pn_sobol_sample_u32(i, dim, 1u)) same_other++;
        }
        CHECK_MSG(same_raw < 4, "dim %d: %d points equal to the unscrambled ones", dim, same_raw);
        CHECK_MSG(same_other < 4, "dim %d: scrambles 0 and 1 share %d points", dim, same_other);
    }
    /* Different dimensions with the same scramble get different seeds. */
    int same = 0;
    for (uint32_t i = 0; i < 256; i++)
        if (pn_sobol_sample_u32(i, 2, 5u) == pn_sobol_sample_u32(i, 3, 5u)) same++;
    CHECK(same < 4);
}

/* Every aligned block of 2^k consecutive points has one point in each interval [j/2^k,
 * (j+1)/2^k) of every dimension (the scramble is a nested uniform permutation, so the
 * unscrambled property survives). */
static void test_sobol_1d_stratification(void) {
    static const uint32_t scrambles[3] = {0u, 12345u, 0x9e3779b9u};
    static unsigned char seen[1u << 12];
    int failures = 0;
    for (int s = 0; s < 3; s++)
        for (int dim = 0; dim < PN_SOBOL_DIMS; dim++)
            for (int k = 0; k <= 12; k++) {
                uint32_t n = 1u << k;
                for (uint32_t block = 0; block < 3; block += 2) { /* blocks 0 and 2 */
                    memset(seen, 0, n);
                    int dup = 0;
                    for (uint32_t i = 0; i < n; i++) {
                        float u = pn_sobol_sample(block * n + i, dim, scrambles[s]);
                        uint32_t cell = (uint32_t)(u * (float)n);
                        if (cell >= n || seen[cell])
                            dup++;
                        else
                            seen[cell] = 1;
                    }
                    if (dup) {
                        if (failures < 5)
                            fprintf(stderr, "  dim %d, 2^%d points, block %u, scramble %u: %d collisions\n", dim, k,
                                    block, scrambles[s], dup);
                        failures++;
                    }
                }
            }
    CHECK(failures == 0);
}

/* Dimensions 0 and 1 form a (0, k, 2)-net: for every split a + b = k, each 2^-a x 2^-b box
 * holds exactly one of 2^k consecutive aligned points. */
static void test_sobol_02_net(void) {
    static const uint32_t scrambles[3] = {0u, 77u, 0xfeedf00du};
    static unsigned char seen[1u << 12];
    int failures = 0;
    for (int s = 0; s < 3; s++)
        for (int k = 0; k <= 12; k++) {
            uint32_t n = 1u << k;
            for (int a = 0; a <= k; a++) {
                int b = k - a;
                for (uint32_t block = 0; block < 2; block++) {
                    memset(seen, 0, n);
                    int dup = 0;
                    for (uint32_t i = 0; i < n; i++) {
                        uint32_t idx = block * n + i;
                        float x = pn_sobol_sample(idx, 0, scrambles[s]);
                        float y = pn_sobol_sample(idx, 1, scrambles[s]);
                        uint32_t cx = (uint32_t)(x * (float)(1u << a));
                        uint32_t cy = (uint32_t)(y * (float)(1u << b));
                        uint32_t cell = (cy << a) | cx;
                        if (cell >= n || seen[cell])
                            dup++;
                        else
                            seen[cell] = 1;
                    }
                    if (dup) failures++;
                }
            }
        }
    CHECK_MSG(failures == 0, "%d (0,2)-net violations", failures);
}

/* Two-dimensional projections of the first 64 dimensions: the first 2^10 (scrambled) points of
 * every pair form a (t, 10, 2)-net with t <= 6, i.e. for every split a + b = 4 each 2^-a x 2^-b
 * box holds exactly 2^6 points. The bound is what the Joe–Kuo tables achieve for these
 * dimensions; duplicated or mistranscribed direction numbers break it (t = 10 for two equal
 * dimensions). */
static void test_sobol_pairs_net(void) {
    enum { DIMS = 64, M = 10, N = 1 << M, T = 6, K = M - T };
    static uint32_t pts[DIMS][N];
    for (int d = 0; d < DIMS; d++)
        for (uint32_t i = 0; i < N; i++) pts[d][i] = pn_sobol_sample_u32(i, d, 7u);
    int bad_pairs = 0;
    for (int d0 = 0; d0 < DIMS; d0++)
        for (int d1 = d0 + 1; d1 < DIMS; d1++) {
            bool ok = true;
            for (int a = 0; a <= K && ok; a++) {
                int b = K - a;
                int counts[1 << K] = {0};
                for (uint32_t i = 0; i < N; i++) {
                    uint32_t cx = a ? pts[d0][i] >> (32 - a) : 0u;
                    uint32_t cy = b ? pts[d1][i] >> (32 - b) : 0u;
                    counts[(cy << a) | cx]++;
                }
                for (int c = 0; c < (1 << K); c++)
                    if (counts[c] != (1 << T)) ok = false;
            }
            if (!ok) {
                if (bad_pairs < 5) fprintf(stderr, "  dims %d, %d: t > %d\n", d0, d1, T);
                bad_pairs++;
            }
        }
    CHECK(bad_pairs == 0);
}

static void test_sobol_high_dims_fallback(void) {
    double counts[32] = {0}, expected[32];
    const int n = 32768;
    for (int i = 0; i < n; i++) {
        float u = pn_sobol_sample((uint32_t)i, PN_SOBOL_DIMS + 5, 42u);
        CHECK(u >= 0.0f && u < 1.0f);
        counts[(int)(u * 32.0f)] += 1.0;
    }
    for (int i = 0; i < 32; i++) expected[i] = n / 32.0;
    CHECK_CHI2(counts, expected, 32);
    CHECK(pn_sobol_sample(3, 1000, 1u) == pn_sobol_sample(3, 1000, 1u));
    CHECK(pn_sobol_sample(3, 1000, 1u) != pn_sobol_sample(3, 1001, 1u));
}

/* ---- simple warps ------------------------------------------------------------------------ */

static void test_uniform_triangle(void) {
    /* The triangle b0, b1 >= 0, b0 + b1 <= 1 splits into N^2 congruent sub-triangles. */
    enum { N = 10, BINS = N * N };
    double counts[BINS] = {0}, expected[BINS];
    const int samples = 200000;
    pn_rng rng;
    pn_rng_seed(&rng, 2024, 1);
    int outside = 0;
    for (int s = 0; s < samples; s++) {
        float b0, b1;
        pn_sample_uniform_triangle(pn_rng_float(&rng), pn_rng_float(&rng), &b0, &b1);
        if (b0 < 0.0f || b1 < 0.0f || b0 + b1 > 1.0f + 1e-6f) {
            outside++;
            continue;
        }
        double x = (double)b0 * N, y = (double)b1 * N;
        int i = (int)x, j = (int)y;
        if (i >= N) i = N - 1;
        if (j >= N) j = N - 1;
        int upper = (x - i) + (y - j) >= 1.0;
        if (i + j >= N - 1) upper = 0; /* diagonal cells only have a lower half */
        /* Index cells: lower halves first (i + j <= N-1), then upper halves (i + j <= N-2). */
        int lower_index = 0, upper_index = 0;
        for (int jj = 0; jj < j; jj++) lower_index += N - jj, upper_index += N - 1 - jj;
        int bin = upper ? N * (N + 1) / 2 + upper_index + i : lower_index + i;
        counts[bin] += 1.0;
    }
    CHECK(outside == 0);
    for (int b = 0; b < BINS; b++) expected[b] = (double)samples / BINS;
    CHECK_CHI2(counts, expected, BINS);
}

static void test_concentric_disk(void) {
    /* Equal-area rings (uniform in r^2) times equal sectors. */
    enum { RINGS = 8, SECTORS = 16, BINS = RINGS * SECTORS };
    double counts[BINS] = {0}, expected[BINS];
    const int samples = 200000;
    pn_rng rng;
    pn_rng_seed(&rng, 77, 3);
    int outside = 0;
    for (int s = 0; s < samples; s++) {
        float x, y;
        pn_sample_concentric_disk(pn_rng_float(&rng), pn_rng_float(&rng), &x, &y);
        double r2 = (double)x * (double)x + (double)y * (double)y;
        if (r2 > 1.0 + 1e-6) outside++;
        int ring = (int)(fmin(r2, 0.999999) * RINGS);
        double phi = atan2((double)y, (double)x);
        if (phi < 0.0) phi += 2.0 * PI_D;
        int sector = (int)(phi / (2.0 * PI_D) * SECTORS);
        if (sector >= SECTORS) sector = SECTORS - 1;
        counts[ring * SECTORS + sector] += 1.0;
    }
    CHECK(outside == 0);
    for (int b = 0; b < BINS; b++) expected[b] = (double)samples / BINS;
    CHECK_CHI2(counts, expected, BINS);
    float x, y;
    pn_sample_concentric_disk(0.5f, 0.5f, &x, &y);
    CHECK(x == 0.0f && y == 0.0f);
}

static void test_sphere_and_hemisphere(void) {
    enum { ZB = 10, PB = 12, BINS = ZB * PB };
    double cs[BINS] = {0}, ch[BINS] = {0}, expected[BINS];
    const int samples = 120000;
    pn_rng rng;
    pn_rng_seed(&rng, 5, 5);
    int bad = 0;
    for (int s = 0; s < samples; s++) {
        float u1 = pn_rng_float(&rng), u2 = pn_rng_float(&rng);
        vec3 a = pn_sample_uniform_sphere(u1, u2);
        vec3 b = pn_sample_cosine_hemisphere(u1, u2);
        if (fabsf(v3_length(a) - 1.0f) > 1e-5f || fabsf(v3_length(b) - 1.0f) > 1e-5f || b.z < 0.0f) bad++;
        /* Sphere: z uniform in [-1, 1]. Cosine hemisphere: 1 - z^2 uniform in [0, 1]. */
        int za = (int)fmin(((double)a.z + 1.0) * 0.5 * ZB, ZB - 1);
        int zb = (int)fmin((1.0 - (double)b.z * (double)b.z) * ZB, ZB - 1);
        double pa = atan2((double)a.y, (double)a.x) + PI_D, pb = atan2((double)b.y, (double)b.x) + PI_D;
        int sa = (int)fmin(pa / (2.0 * PI_D) * PB, PB - 1), sb = (int)fmin(pb / (2.0 * PI_D) * PB, PB - 1);
        cs[za * PB + sa] += 1.0;
        ch[zb * PB + sb] += 1.0;
    }
    CHECK(bad == 0);
    for (int b = 0; b < BINS; b++) expected[b] = (double)samples / BINS;
    CHECK_CHI2(cs, expected, BINS);
    CHECK_CHI2(ch, expected, BINS);
}

/* ---- spherical rectangles ---------------------------------------------------------------- */

static void test_rectangle_solid_angle_closed_form(void) {
    /* Square of side 2a centred on the axis at distance d: omega = 4 asin(a^2 / (a^2 + d^2)). */
    static const double cases[][2] = {{1.0, 1.0}, {0.5, 2.0}, {3.0, 0.25}, {1.0, 1000.0}, {100.0, 0.01}, {0.01, 5.0}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        double a = cases[c][0], d = cases[c][1];
        double omega = 4.0 * asin(a * a / (a * a + d * d));
        vec3 corner = v3((float)-a, (float)-a, (float)d);
        vec3 e1 = v3((float)(2.0 * a), 0.0f, 0.0f), e2 = v3(0.0f, (float)(2.0 * a), 0.0f);
        pn_spherical_rectangle sr;
        bool ok = pn_spherical_rectangle_init(&sr, v3(0.0f, 0.0f, 0.0f), corner, e1, e2);
        CHECK(ok);
        CHECK_NEAR(sr.solid_angle, omega, 1e-5 * omega);
        CHECK_NEAR(pn_rectangle_solid_angle(v3(0.0f, 0.0f, 0.0f), corner, e1, e2), omega, 1e-6 * omega);
        /* Seen from the other side the solid angle is the same. */
        ok = pn_spherical_rectangle_init(&sr, v3(0.0f, 0.0f, (float)(2.0 * d)), corner, e1, e2);
        CHECK(ok);
        CHECK_NEAR(sr.solid_angle, omega, 1e-5 * omega);
    }
    /* Degenerate configurations. */
    pn_spherical_rectangle sr;
    CHECK(!pn_spherical_rectangle_init(&sr, v3(0.3f, 0.2f, 1.0f), v3(0, 0, 1), v3(1, 0, 0), v3(0, 1, 0)));
    CHECK(!pn_spherical_rectangle_init(&sr, v3(5.0f, 0.2f, 1.0f), v3(0, 0, 1), v3(1, 0, 0), v3(0, 1, 0)));
    CHECK(!pn_spherical_rectangle_init(&sr, v3(0, 0, 0), v3(0, 0, 1), v3(0, 0, 0), v3(0, 1, 0)));
}

/* Sub-rectangles of a Ga x Gb grid on the rectangle receive samples in proportion to their
 * solid angles (computed independently with the Van Oosterom–Strackee triangle formula). */
static void check_rectangle_distribution(vec3 p, vec3 corner, vec3 e1, vec3 e2, uint64_t seed) {
    enum { GA = 8, GB = 8, BINS = GA * GB };
    double counts[BINS] = {0}, expected[BINS];
    const int samples = 64000;
    pn_spherical_rectangle sr;
    bool ok = pn_spherical_rectangle_init(&sr, p, corner, e1, e2);
    CHECK(ok);
    if (!ok) return;
    double total = pn_rectangle_solid_angle(p, corner, e1, e2);
    CHECK_NEAR(sr.solid_angle, total, 1e-5 * total);
    double sum_sub = 0.0;
    for (int j = 0; j < GB; j++)
        for (int i = 0; i < GA; i++) {
            vec3 c = v3_add(corner, v3_add(v3_scale(e1, (float)i / GA), v3_scale(e2, (float)j / GB)));
            double w = pn_rectangle_solid_angle(p, c, v3_scale(e1, 1.0f / GA), v3_scale(e2, 1.0f / GB));
            sum_sub += w;
            expected[j * GA + i] = samples * w / total;
        }
    CHECK_NEAR(sum_sub, total, 1e-6 * total);
    pn_rng rng;
    pn_rng_seed(&rng, seed, 11);
    float l1 = v3_length2(e1), l2 = v3_length2(e2);
    vec3 n = v3_normalize(v3_cross(e1, e2));
    float size = sqrtf(l1) + sqrtf(l2);
    int off_plane = 0, param_mismatch = 0;
    for (int s = 0; s < samples; s++) {
        float a, b;
        vec3 y = pn_spherical_rectangle_sample_ab(&sr, pn_rng_float(&rng), pn_rng_float(&rng), &a, &b);
        vec3 rel = v3_sub(y, corner);
        float pa = v3_dot(rel, e1) / l1, pb = v3_dot(rel, e2) / l2;
        if (fabsf(v3_dot(rel, n)) > 1e-5f * size) off_plane++;
        if (fabsf(pa - a) > 1e-4f || fabsf(pb - b) > 1e-4f || a < 0.0f || a > 1.0f || b < 0.0f || b > 1.0f)
            param_mismatch++;
        int i = (int)fminf(a * GA, GA - 1), j = (int)fminf(b * GB, GB - 1);
        counts[j * GA + i] += 1.0;
    }
    CHECK(off_plane == 0);
    CHECK(param_mismatch == 0);
    CHECK_CHI2(counts, expected, BINS);
}

static void test_spherical_rectangle_distribution(void) {
    /* Axis-aligned, seen off-centre from moderately close. */
    check_rectangle_distribution(v3(0.2f, -0.3f, 0.0f), v3(-1.0f, -0.5f, 0.8f), v3(2.5f, 0.0f, 0.0f),
                                 v3(0.0f, 1.5f, 0.0f), 1);
    /* Very close: large solid angle and strong distortion. */
    check_rectangle_distribution(v3(0.1f, 0.1f, 0.05f), v3(-1.0f, -1.0f, 0.0f), v3(2.0f, 0.0f, 0.0f),
                                 v3(0.0f, 2.0f, 0.0f), 2);
    /* Tilted rectangle whose projection does not contain p, seen from below its plane. */
    vec3 e1 = v3(1.0f, 1.0f, 0.5f);
    vec3 e2 = v3_scale(v3_normalize(v3_cross(e1, v3(0.0f, 0.0f, 1.0f))), 0.7f);
    check_rectangle_distribution(v3(-2.0f, 1.0f, -1.0f), v3(1.0f, 2.0f, 3.0f), e1, e2, 3);
    /* Far away and small. */
    check_rectangle_distribution(v3(0.0f, 0.0f, 0.0f), v3(30.0f, 1.0f, 2.0f), v3(0.0f, 1.0f, 0.0f),
                                 v3(0.0f, 0.0f, 0.6f), 4);
    /* Tiny and distant (solid angle ~2e-8 sr). */
    check_rectangle_distribution(v3(0.0f, 0.0f, 0.0f), v3(100.0f, 0.0f, 0.0f), v3(0.0f, 0.01f, 0.0f),
                                 v3(0.0f, 0.0f, 0.02f), 5);
    /* Grazing: p barely above the plane, beside the rectangle. */
    check_rectangle_distribution(v3(0.0f, 0.0f, 0.01f), v3(0.5f, -1.0f, 0.0f), v3(2.0f, 0.0f, 0.0f),
                                 v3(0.0f, 2.0f, 0.0f), 6);
}

/* Sobol' inputs through the rectangle warp: the estimate of the rectangle's solid angle by
 * integrating 1 over directions converges fast, and the cosine-weighted integral matches a
 * brute-force area integral. */
static void test_spherical_rectangle_estimator(void) {
    vec3 p = v3(0.3f, 0.1f, 0.0f), corner = v3(-1.0f, -0.5f, 1.0f);
    vec3 e1 = v3(2.0f, 0.0f, 0.0f), e2 = v3(0.0f, 1.0f, 0.0f);
    pn_spherical_rectangle sr;
    CHECK(pn_spherical_rectangle_init(&sr, p, corner, e1, e2));
    /* Estimate E = integral over the rectangle's solid angle of cos(theta) (theta from +z),
     * i.e. the irradiance from a unit-radiance rectangle: sum cos / pdf. */
    double est = 0.0;
    const uint32_t n = 4096;
    for (uint32_t i = 0; i < n; i++) {
        vec3 y = pn_spherical_rectangle_sample(&sr, pn_sobol_sample(i, 0, 9u), pn_sobol_sample(i, 1, 9u));
        vec3 w = v3_normalize(v3_sub(y, p));
        est += (double)w.z * (double)sr.solid_angle;
    }
    est /= n;
    /* Reference by midpoint rule over area: cos(theta) cos(theta') / r^2 dA. */
    double ref = 0.0;
    const int m = 400;
    for (int j = 0; j < m; j++)
        for (int i = 0; i < m; i++) {
            double x = -1.0 + 2.0 * (i + 0.5) / m - 0.3, y = -0.5 + (j + 0.5) / m - 0.1, z = 1.0;
            double r2 = x * x + y * y + z * z;
            ref += (z * z / (r2 * r2)) * (2.0 / m) * (1.0 / m);
        }
    CHECK_NEAR(est, ref, 1e-3 * ref);
}

/* ---- sphere cones ------------------------------------------------------------------------ */

static void check_sphere_cone(vec3 center, float radius, vec3 p, uint64_t seed) {
    enum { RB = 8, PB = 12, BINS = RB * PB };
    double counts[BINS] = {0}, expected[BINS];
    const int samples = 96000;
    double dx = (double)center.x - (double)p.x, dy = (double)center.y - (double)p.y,
           dz = (double)center.z - (double)p.z;
    double dist = sqrt(dx * dx + dy * dy + dz * dz);
    double cos_max = sqrt(1.0 - ((double)radius * (double)radius) / (dist * dist));
    double omega = 2.0 * PI_D * (1.0 - cos_max);
    CHECK_NEAR(pn_sphere_cone_pdf(center, radius, p), 1.0 / omega, 1e-5 / omega);
    /* An axis and an arbitrary perpendicular frame, independent of the sampler's. */
    vec3 axis = v3((float)(dx / dist), (float)(dy / dist), (float)(dz / dist));
    vec3 helper = fabsf(axis.x) < 0.6f ? v3(1, 0, 0) : v3(0, 1, 0);
    vec3 t = v3_normalize(v3_cross(helper, axis)), b = v3_cross(axis, t);
    pn_rng rng;
    pn_rng_seed(&rng, seed, 17);
    int failures = 0, off_sphere = 0, far_side = 0, pdf_bad = 0;
    for (int s = 0; s < samples; s++) {
        vec3 y;
        float pdf;
        if (!pn_sample_sphere_from_point(center, radius, p, pn_rng_float(&rng), pn_rng_float(&rng), &y, &pdf)) {
            failures++;
            continue;
        }
        if (fabs((double)pdf - 1.0 / omega) > 1e-4 / omega) pdf_bad++;
        vec3 rel = v3_sub(y, center);
        if (fabsf(v3_length(rel) - radius) > 1e-4f * radius + 1e-6f * (float)dist) off_sphere++;
        /* The returned point is the near intersection: its normal faces p. */
        if (v3_dot(rel, v3_sub(p, y)) < -1e-3f * radius * (float)dist) far_side++;
        double wx = (double)y.x - (double)p.x, wy = (double)y.y - (double)p.y, wz = (double)y.z - (double)p.z;
        double wl = sqrt(wx * wx + wy * wy + wz * wz);
        wx /= wl, wy /= wl, wz /= wl;
        double c = wx * (double)axis.x + wy * (double)axis.y + wz * (double)axis.z;
        /* Uniform in solid angle <=> (1 - cos) / (1 - cos_max) uniform; phi uniform. */
        double q = (1.0 - c) / (1.0 - cos_max);
        if (q > 1.0 + 1e-3) failures++;
        int ring = (int)fmin(fmax(q, 0.0) * RB, RB - 1);
        double phi = atan2(wx * (double)b.x + wy * (double)b.y + wz * (double)b.z,
                           wx * (double)t.x + wy * (double)t.y + wz * (double)t.z) +
                     PI_D;
        int sector = (int)fmin(phi / (2.0 * PI_D) * PB, PB - 1);
        counts[ring * PB + sector] += 1.0;
    }
    CHECK(failures == 0);
    CHECK(off_sphere == 0);
    CHECK(far_side == 0);
    CHECK(pdf_bad == 0);
    for (int i = 0; i < BINS; i++) expected[i] = (double)samples / BINS;
    CHECK_CHI2(counts, expected, BINS);
}

static void test_sphere_from_point(void) {
    check_sphere_cone(v3(0.0f, 0.0f, 2.0f), 1.0f, v3(0.0f, 0.0f, 0.0f), 1);
    check_sphere_cone(v3(1.0f, -2.0f, 0.5f), 0.3f, v3(-0.5f, 0.4f, 0.1f), 2);
    check_sphere_cone(v3(0.0f, 0.0f, 0.0f), 1.0f, v3(0.0f, 1.05f, 0.0f), 3);    /* very close */
    check_sphere_cone(v3(50.0f, 20.0f, -10.0f), 0.5f, v3(0.0f, 0.0f, 0.0f), 4); /* small cone */
    vec3 y;
    float pdf;
    CHECK(!pn_sample_sphere_from_point(v3(0, 0, 0), 1.0f, v3(0.2f, 0.1f, 0.0f), 0.5f, 0.5f, &y, &pdf));
    CHECK(!pn_sample_sphere_from_point(v3(0, 0, 0), 0.0f, v3(2.0f, 0.0f, 0.0f), 0.5f, 0.5f, &y, &pdf));
    CHECK(pn_sphere_cone_pdf(v3(0, 0, 0), 1.0f, v3(0.5f, 0.0f, 0.0f)) == 0.0f);
    /* Known value: distance 2, radius 1 gives omega = 2 pi (1 - sqrt(3)/2). */
    CHECK(pn_sample_sphere_from_point(v3(0, 0, 2), 1.0f, v3(0, 0, 0), 0.3f, 0.7f, &y, &pdf));
    CHECK_NEAR(pdf, 1.0 / (2.0 * PI_D * (1.0 - sqrt(3.0) / 2.0)), 1e-4);
}

/* ---- tabulated distributions ------------------------------------------------------------- */

static void test_distribution1d(void) {
    static const float w[10] = {1.0f, 0.0f, 3.0f, 0.5f, 0.0f, 0.0f, 2.0f, 7.0f, 0.25f, 0.0f};
    pn_distribution1d *d = pn_distribution1d_create(w, 10);
    CHECK(d != NULL);
    if (!d) return;
    double total = 0.0;
    for (int i = 0; i < 10; i++) total += (double)w[i];
    CHECK(pn_distribution1d_count(d) == 10);
    CHECK_NEAR(pn_distribution1d_total(d), total, 1e-9);
    for (int i = 0; i < 10; i++) CHECK_NEAR(pn_distribution1d_pdf(d, i), (double)w[i] / total, 1e-6);
    CHECK(pn_distribution1d_pdf(d, -1) == 0.0f && pn_distribution1d_pdf(d, 10) == 0.0f);

    enum { SUB = 4 };
    double counts[10] = {0}, expected[10], rem_counts[10 * SUB] = {0}, rem_expected[10 * SUB];
    const int samples = 100000;
    pn_rng rng;
    pn_rng_seed(&rng, 31, 0);
    int pmf_bad = 0, range_bad = 0;
    for (int s = 0; s < samples; s++) {
        float pmf, r;
        int i = pn_distribution1d_sample_discrete(d, pn_rng_float(&rng), &pmf, &r);
        if (i < 0 || i >= 10 || !(r >= 0.0f && r < 1.0f)) {
            range_bad++;
            continue;
        }
        if (fabs((double)pmf - (double)w[i] / total) > 1e-6) pmf_bad++;
        counts[i] += 1.0;
        rem_counts[i * SUB + (int)(r * SUB)] += 1.0;
    }
    CHECK(range_bad == 0);
    CHECK(pmf_bad == 0);
    for (int i = 0; i < 10; i++) {
        expected[i] = samples * (double)w[i] / total;
        for (int k = 0; k < SUB; k++) rem_expected[i * SUB + k] = expected[i] / SUB;
    }
    CHECK_CHI2(counts, expected, 10);
    CHECK_CHI2(rem_counts, rem_expected, 10 * SUB);
    /* Extreme inputs never select zero-weight entries. */
    float pmf;
    CHECK(pn_distribution1d_sample_discrete(d, 0.0f, &pmf, NULL) == 0);
    CHECK(pn_distribution1d_sample_discrete(d, 0x1.fffffep-1f, &pmf, NULL) == 8);
    CHECK(pn_distribution1d_sample_discrete(d, 1.0f, &pmf, NULL) == 8);
    /* Continuous sampling: density = weight / mean weight. */
    float pdf;
    int idx;
    float x = pn_distribution1d_sample_continuous(d, 0.5f, &pdf, &idx);
    CHECK(x >= idx / 10.0f && x < (idx + 1) / 10.0f);
    CHECK_NEAR(pdf, (double)w[idx] / (total / 10.0), 1e-5);
    pn_distribution1d_free(d);

    static const float zeros[3] = {0.0f, 0.0f, 0.0f};
    CHECK(pn_distribution1d_create(zeros, 3) == NULL);
    CHECK(pn_distribution1d_create(w, 0) == NULL);
    static const float odd[3] = {-1.0f, NAN, 2.0f};
    d = pn_distribution1d_create(odd, 3);
    CHECK(d != NULL);
    if (d) {
        CHECK(pn_distribution1d_pdf(d, 2) == 1.0f);
        CHECK(pn_distribution1d_sample_discrete(d, 0.0f, &pmf, NULL) == 2);
        pn_distribution1d_free(d);
    }
    pn_distribution1d_free(NULL);
}

static void test_distribution2d(void) {
    enum { W = 16, H = 8, N = W * H };
    float w[N];
    pn_rng rng;
    pn_rng_seed(&rng, 8, 8);
    double total = 0.0;
    for (int i = 0; i < N; i++) {
        float x = pn_rng_float(&rng);
        w[i] = x < 0.2f ? 0.0f : x * x * 10.0f;
        total += (double)w[i];
    }
    for (int i = 0; i < W; i++) { /* one all-zero row */
        total -= (double)w[3 * W + i];
        w[3 * W + i] = 0.0f;
    }
    w[5 * W + 2] = 50.0f; /* a bright cell */
    total = 0.0;
    for (int i = 0; i < N; i++) total += (double)w[i];
    double mean = total / N;

    pn_distribution2d *d = pn_distribution2d_create(w, W, H);
    CHECK(d != NULL);
    if (!d) return;
    enum { SUB = 2 };
    double counts[N] = {0}, expected[N];
    double sub_counts[N * SUB * SUB] = {0}, sub_expected[N * SUB * SUB];
    const int samples = 200000;
    int bad = 0, pdf_mismatch = 0;
    for (int s = 0; s < samples; s++) {
        float u, v, pdf;
        if (!pn_distribution2d_sample(d, pn_rng_float(&rng), pn_rng_float(&rng), &u, &v, &pdf) ||
            !(u >= 0.0f && u < 1.0f && v >= 0.0f && v < 1.0f)) {
            bad++;
            continue;
        }
        int c = (int)(u * W), r = (int)(v * H);
        double want = (double)w[r * W + c] / mean;
        if (fabs((double)pdf - want) > 1e-4 * want) pdf_mismatch++;
        if (pn_distribution2d_pdf(d, u, v) != pdf) pdf_mismatch++;
        counts[r * W + c] += 1.0;
        int su = (int)((u * W - c) * SUB), sv = (int)((v * H - r) * SUB);
        if (su >= SUB) su = SUB - 1;
        if (sv >= SUB) sv = SUB - 1;
        sub_counts[(r * W + c) * SUB * SUB + sv * SUB + su] += 1.0;
    }
    CHECK(bad == 0);
    CHECK(pdf_mismatch == 0);
    for (int i = 0; i < N; i++) {
        expected[i] = samples * (double)w[i] / total;
        for (int k = 0; k < SUB * SUB; k++) sub_expected[i * SUB * SUB + k] = expected[i] / (SUB * SUB);
    }
    CHECK_CHI2(counts, expected, N);
    CHECK_CHI2(sub_counts, sub_expected, N * SUB * SUB);
    /* pdf() at cell centres, the zero row, and clamping at the border. */
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            float got = pn_distribution2d_pdf(d, (c + 0.5f) / W, (r + 0.5f) / H);
            double want = (double)w[r * W + c] / mean;
            CHECK_NEAR(got, want, 1e-4 * want + 1e-7);
        }
    double last = (double)w[N - 1] / mean;
    CHECK_NEAR(pn_distribution2d_pdf(d, 1.0f, 1.0f), last, 1e-4 * last + 1e-7);
    CHECK(pn_distribution2d_pdf(d, NAN, 0.5f) == 0.0f);
    /* Integral of the pdf over [0,1)^2 is 1. */
    double integral = 0.0;
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) integral += (double)pn_distribution2d_pdf(d, (c + 0.5f) / W, (r + 0.5f) / H) / N;
    CHECK_NEAR(integral, 1.0, 1e-5);
    /* Extreme random numbers stay inside and on positive cells. */
    float u, v, pdf;
    CHECK(pn_distribution2d_sample(d, 0x1.fffffep-1f, 0x1.fffffep-1f, &u, &v, &pdf) && u < 1.0f && v < 1.0f &&
          pdf > 0.0f);
    CHECK(pn_distribution2d_sample(d, 0.0f, 0.0f, &u, &v, &pdf) && pdf > 0.0f);
    pn_distribution2d_free(d);

    float zeros[4] = {0};
    CHECK(pn_distribution2d_create(zeros, 2, 2) == NULL);
    CHECK(pn_distribution2d_create(w, 0, 3) == NULL);
    CHECK(!pn_distribution2d_sample(NULL, 0.5f, 0.5f, &u, &v, &pdf));
    pn_distribution2d_free(NULL);

    /* A single cell is the uniform distribution. */
    float one = 3.0f;
    d = pn_distribution2d_create(&one, 1, 1);
    CHECK(d != NULL);
    if (d) {
        CHECK(pn_distribution2d_sample(d, 0.25f, 0.75f, &u, &v, &pdf));
        CHECK_NEAR(u, 0.25, 1e-6);
        CHECK_NEAR(v, 0.75, 1e-6);
        CHECK_NEAR(pdf, 1.0, 1e-6);
        pn_distribution2d_free(d);
    }
}

PN_TESTS(TEST(test_sobol_tables), TEST(test_sobol_raw_values), TEST(test_sobol_byte_tables),
         TEST(test_sobol_range_and_determinism), TEST(test_sobol_scrambling_changes_points),
         TEST(test_sobol_1d_stratification), TEST(test_sobol_02_net), TEST(test_sobol_pairs_net),
         TEST(test_sobol_high_dims_fallback), TEST(test_uniform_triangle), TEST(test_concentric_disk),
         TEST(test_sphere_and_hemisphere), TEST(test_rectangle_solid_angle_closed_form),
         TEST(test_spherical_rectangle_distribution), TEST(test_spherical_rectangle_estimator),
         TEST(test_sphere_from_point), TEST(test_distribution1d), TEST(test_distribution2d))
