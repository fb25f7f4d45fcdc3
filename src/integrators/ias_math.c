/* ias_math.c — see ias_math.h. */
#include "integrators/ias_math.h"

#include <math.h>

double pn_ias_feedback(const pn_ias_stats *s) {
    if (s->count == 0 || s->visible == 0) return 0.0;
    double c = s->sum / (double)s->count;
    double u = (double)s->visible / (double)s->count;
    return c > 0.0 ? c / sqrt(u) : 0.0;
}

/* Fig. 2 of the paper gives the weights as a plot without numbers; this table follows its
 * description: uniform only in pass 0, the block PDF heaviest in the first feedback passes, the
 * pixel PDF almost alone towards the end (pass 15, the default maximum). */
static const double weights[][3] = {
    /* uniform, block, pixel */
    {1.00, 0.00, 0.00}, /* pass 0 */
    {0.20, 0.60, 0.20}, /* pass 1 */
    {0.15, 0.50, 0.35}, /* pass 2 */
    {0.10, 0.40, 0.50}, /* pass 3 */
    {0.10, 0.30, 0.60}, /* pass 4 */
    {0.10, 0.20, 0.70}, /* pass 5 */
    {0.08, 0.15, 0.77}, /* pass 6 */
    {0.06, 0.12, 0.82}, /* pass 7 */
    {0.05, 0.10, 0.85}, /* pass 8 */
    {0.05, 0.07, 0.88}, /* pass 9 and later */
};

void pn_ias_blend_weights(int pass, double *c_uniform, double *c_block, double *c_pixel) {
    const int last = (int)(sizeof weights / sizeof weights[0]) - 1;
    int j = pass < 0 ? 0 : (pass > last ? last : pass);
    *c_uniform = weights[j][0];
    *c_block = weights[j][1];
    *c_pixel = weights[j][2];
}

bool pn_ias_combine(const double *L, const double *s2, int n, double *L_out, double *s2_out) {
    if (n < 1) return false;
    double inv_sum = 0.0, weighted = 0.0;
    for (int i = 0; i < n; i++) {
        if (!(s2[i] > 0.0) || !isfinite(s2[i])) return false;
        inv_sum += 1.0 / s2[i];
        weighted += L[i] / s2[i];
    }
    double s2p = 1.0 / inv_sum;
    *s2_out = s2p;
    *L_out = weighted * s2p;
    return true;
}
