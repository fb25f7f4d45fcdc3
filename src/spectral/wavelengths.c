/* wavelengths.c — the importance density of visible wavelengths and its inversion (wavelengths.h). */
#include "spectral/wavelengths.h"

#include "spectral/cie.h"

#include <math.h>

#define PN_WL_A 0.0072 /* 1 / nm */
#define PN_WL_MU 538.0 /* nm */

/* tanh(a (λ - μ)) at both ends of the range: the CDF is (tanh(a(λ-μ)) - t0) / (t1 - t0). */
static double cdf_lo(void) {
    return tanh(PN_WL_A * (PN_LAMBDA_MIN - PN_WL_MU));
}
static double cdf_hi(void) {
    return tanh(PN_WL_A * (PN_LAMBDA_MAX - PN_WL_MU));
}

double pn_visible_wavelength_pdf(double lambda) {
    if (!(lambda >= PN_LAMBDA_MIN && lambda <= PN_LAMBDA_MAX)) return 0.0;
    double c = cosh(PN_WL_A * (lambda - PN_WL_MU));
    return PN_WL_A / (c * c * (cdf_hi() - cdf_lo()));
}

double pn_visible_wavelength_sample(double u) {
    double t0 = cdf_lo(), t1 = cdf_hi();
    double lambda = PN_WL_MU + atanh(t0 + u * (t1 - t0)) / PN_WL_A;
    /* Rounding may step just outside the range at u = 0 or near 1. Comparisons, not fmin and fmax
     * (library calls in this build; the same result for the finite lambda here). */
    lambda = lambda > PN_LAMBDA_MIN ? lambda : PN_LAMBDA_MIN;
    return lambda < PN_LAMBDA_MAX ? lambda : PN_LAMBDA_MAX;
}

void pn_visible_wavelength_sample_inv_pdf(double u, double *lambda, double *inv_pdf) {
    double l = pn_visible_wavelength_sample(u);
    double c = cosh(PN_WL_A * (l - PN_WL_MU));
    *lambda = l;
    *inv_pdf = 1.0 / (PN_WL_A / (c * c * (cdf_hi() - cdf_lo())));
}

void pn_wavelengths_sample(double u, pn_wavelengths *out) {
    for (int i = 0; i < PN_WAVELENGTHS; i++) {
        double ui = u + (double)i / PN_WAVELENGTHS;
        if (ui >= 1.0) ui -= 1.0;
        double lambda = pn_visible_wavelength_sample(ui);
        out->lambda[i] = (float)lambda;
        out->pdf[i] = (float)pn_visible_wavelength_pdf(lambda);
    }
}
