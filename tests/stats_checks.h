/* stats_checks.h — statistical checks shared by the tests that sample distributions. */
#ifndef PN_TESTS_STATS_CHECKS_H
#define PN_TESTS_STATS_CHECKS_H

#include <math.h>
#include <stdbool.h>
#include <stdio.h>

/* Pearson's chi-square against probabilities prob (bins of expectation < 5 pooled); accepted at
 * p = 0.001 via the Wilson-Hilferty approximation of the critical value. */
static inline bool pn_test_chi2_ok(const double *obs, const double *prob, int n, double total) {
    double stat = 0.0, pe = 0.0, po = 0.0;
    int cells = 0;
    for (int i = 0; i < n; i++) {
        if (prob[i] <= 0.0) {
            if (obs[i] > 0.0) return false;
            continue;
        }
        double e = prob[i] * total;
        if (e < 5.0) {
            pe += e;
            po += obs[i];
            continue;
        }
        stat += (obs[i] - e) * (obs[i] - e) / e;
        cells++;
    }
    if (pe > 0.0) {
        stat += (po - pe) * (po - pe) / pe;
        cells++;
    }
    int dof = cells - 1;
    double z = 3.090232; /* upper 0.001 quantile of the normal */
    double a = 2.0 / (9.0 * dof), crit = dof * pow(1.0 - a + z * sqrt(a), 3.0);
    fprintf(stderr, "  chi2 = %.1f  dof = %d  crit(p=0.001) = %.1f\n", stat, dof, crit);
    return dof > 0 && stat <= crit;
}

#endif
