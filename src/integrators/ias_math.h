/* ias_math.h — the arithmetic of Iterative Adaptive Sampling (Donikian et al. 2006, §4.1-§4.2 and
 * the appendix) that does not depend on the scene: feedback weights C / sqrt(u) (eq. 4), the
 * per-pass blend of uniform, block and pixel PDFs (eq. 6, Fig. 2) and the inverse-variance
 * combination of pass estimates (eq. 7-8). The integrator (ias.c) is built on these. */
#ifndef PN_INTEGRATORS_IAS_MATH_H
#define PN_INTEGRATORS_IAS_MATH_H

#include <stdbool.h>

/* Running sums of the light evaluations of one cluster over a set of points (a pixel or a block,
 * per normal class): eq. 3's average contribution and the visible fraction u. */
typedef struct pn_ias_stats {
    double sum;       /* sum of the one-sample estimates L(x_i, y_i) of the cluster's contribution */
    unsigned count;   /* number of light evaluations */
    unsigned visible; /* of which the shadow ray was unoccluded */
} pn_ias_stats;

/* Adds one light evaluation. */
static inline void pn_ias_stats_add(pn_ias_stats *s, double value, bool visible) {
    s->sum += value;
    s->count++;
    s->visible += visible ? 1u : 0u;
}

/* Eq. 4: F = C / sqrt(u) with C the average contribution (eq. 3) and u the visible fraction; 0
 * when nothing was visible (or nothing sampled): such a cluster keeps only the uniform share of
 * eq. 6. The appendix shows that p proportional to F minimises the variance when visibility is
 * the source of variance. */
double pn_ias_feedback(const pn_ias_stats *s);

/* Eq. 6's weights for pass j (0-based): uniform c_U, block c_B, pixel c_P, summing to one.
 * Pass 0 is uniform only (no feedback yet); early passes lean on the block PDF, which averages
 * more data; later passes on the pixel PDF, which adapts more locally (Fig. 2). The uniform share
 * never drops to zero, so every cluster that was cut keeps a non-zero probability. */
void pn_ias_blend_weights(int pass, double *c_uniform, double *c_block, double *c_pixel);

/* Eq. 7-8: combines n pass estimates L[i] with sample variances s2[i] > 0 by inverse variance:
 * s2_p = 1 / sum(1 / s2[i]), L_p = s2_p * sum(L[i] / s2[i]). Returns false if n < 1 or a
 * variance is not positive and finite. */
bool pn_ias_combine(const double *L, const double *s2, int n, double *L_out, double *s2_out);

#endif
