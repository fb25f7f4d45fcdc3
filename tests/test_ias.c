/* test_ias.c — the scene-independent parts of Iterative Adaptive Sampling (ias_math.h): the
 * appendix's variance-minimising PDF on a two-light case, eq. 6's blend weights, and eq. 7-8's
 * inverse-variance combination against a hand-computed case. */
#include "harness.h"

#include "core/rng.h"
#include "integrators/ias_math.h"

/* The appendix's model: two lights of unoccluded contribution L1, L2, visible with probability
 * u1, u2; light 1 is picked with probability p. Exact variance of the one-sample estimator. */
static double two_light_variance(double p, double L1, double L2, double u1, double u2) {
    double mean = u1 * L1 + u2 * L2;
    return u1 * L1 * L1 / p + u2 * L2 * L2 / (1.0 - p) - mean * mean;
}

static void test_feedback_minimises_variance(void) {
    const double cases[][4] = {{1.0, 1.0, 0.5, 0.5}, {2.0, 1.0, 0.1, 0.9}, {1.0, 3.0, 0.8, 0.05}, {5.0, 0.2, 1.0, 0.3}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        double L1 = cases[c][0], L2 = cases[c][1], u1 = cases[c][2], u2 = cases[c][3];
        /* Sample data as the integrator would collect it: many evaluations of each light. */
        pn_ias_stats s1 = {0}, s2 = {0};
        pn_rng rng;
        pn_rng_seed(&rng, 11 + c, 3);
        for (int i = 0; i < 200000; i++) {
            bool v1 = (double)pn_rng_float(&rng) < u1, v2 = (double)pn_rng_float(&rng) < u2;
            pn_ias_stats_add(&s1, v1 ? L1 : 0.0, v1);
            pn_ias_stats_add(&s2, v2 ? L2 : 0.0, v2);
        }
        double F1 = pn_ias_feedback(&s1), F2 = pn_ias_feedback(&s2);
        double p_feedback = F1 / (F1 + F2);
        /* The exact minimiser over a fine grid of p. */
        double best_p = 0.5, best_var = INFINITY;
        for (int k = 1; k < 100000; k++) {
            double p = k / 100000.0;
            double v = two_light_variance(p, L1, L2, u1, u2);
            if (v < best_var) {
                best_var = v;
                best_p = p;
            }
        }
        /* sqrt(u1) L1 / (sqrt(u1) L1 + sqrt(u2) L2) in closed form; the sampled F recovers it. */
        double p_closed = sqrt(u1) * L1 / (sqrt(u1) * L1 + sqrt(u2) * L2);
        CHECK_NEAR(best_p, p_closed, 2e-5);
        CHECK_NEAR(p_feedback, p_closed, 0.01);
        /* And it beats sampling in proportion to the contribution C alone, and uniform sampling. */
        double p_contribution = u1 * L1 / (u1 * L1 + u2 * L2);
        double v_feedback = two_light_variance(p_feedback, L1, L2, u1, u2);
        CHECK(v_feedback <= two_light_variance(p_contribution, L1, L2, u1, u2) * (1.0 + 1e-3));
        CHECK(v_feedback <= two_light_variance(0.5, L1, L2, u1, u2) * (1.0 + 1e-3));
    }
    /* Nothing visible: no feedback weight (the cluster keeps only its uniform share). */
    pn_ias_stats none = {0};
    pn_ias_stats_add(&none, 0.0, false);
    CHECK(pn_ias_feedback(&none) == 0.0);
    pn_ias_stats empty = {0};
    CHECK(pn_ias_feedback(&empty) == 0.0);
}

static void test_blend_weights(void) {
    for (int j = 0; j < 40; j++) {
        double u, b, p;
        pn_ias_blend_weights(j, &u, &b, &p);
        CHECK_NEAR(u + b + p, 1.0, 1e-12);
        CHECK(u > 0.0 && b >= 0.0 && p >= 0.0);
        if (j == 0) CHECK(u == 1.0 && b == 0.0 && p == 0.0);
        if (j == 1) CHECK(b > p && b > u);
        if (j >= 9) CHECK(p > 0.85);
    }
    /* The pixel share never decreases from pass to pass. */
    double u0, b0, p0;
    pn_ias_blend_weights(1, &u0, &b0, &p0);
    for (int j = 2; j < 20; j++) {
        double u, b, p;
        pn_ias_blend_weights(j, &u, &b, &p);
        CHECK(p >= p0);
        p0 = p;
    }
}

static void test_inverse_variance(void) {
    /* L = (1, 2), s^2 = (1, 4): s_p^2 = 1 / (1 + 1/4) = 0.8, L_p = 0.8 (1/1 + 2/4) = 1.2. */
    double L[] = {1.0, 2.0}, s2[] = {1.0, 4.0}, Lp, s2p;
    CHECK(pn_ias_combine(L, s2, 2, &Lp, &s2p));
    CHECK_NEAR(s2p, 0.8, 1e-12);
    CHECK_NEAR(Lp, 1.2, 1e-12);
    /* Equal variances: the plain mean, variance divided by n. */
    double L3[] = {3.0, 5.0, 10.0}, s3[] = {2.0, 2.0, 2.0};
    CHECK(pn_ias_combine(L3, s3, 3, &Lp, &s2p));
    CHECK_NEAR(Lp, 6.0, 1e-12);
    CHECK_NEAR(s2p, 2.0 / 3.0, 1e-12);
    double bad[] = {1.0, 0.0};
    CHECK(!pn_ias_combine(L, bad, 2, &Lp, &s2p));
    CHECK(!pn_ias_combine(L, s2, 0, &Lp, &s2p));
}

PN_TESTS(TEST(test_feedback_minimises_variance), TEST(test_blend_weights), TEST(test_inverse_variance))
