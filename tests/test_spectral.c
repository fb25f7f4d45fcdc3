/* test_spectral.c — the spectral module's data, upsampling and wavelength sampling (issue 20). */
#include "harness.h"
#include "spectral/cie.h"
#include "spectral/rgb2spec.h"
#include "spectral/wavelengths.h"

#include <stdint.h>

/* Chromaticity (x, y) of a spectrum given as a function of λ, integrated at 1 nm. */
static void chromaticity(double (*f)(double, const void *), const void *user, double xy[2]) {
    double xyz[3] = {0, 0, 0};
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX; l += 1.0) {
        double bar[3];
        pn_cie_xyz_bar(l, bar);
        double v = f(l, user);
        for (int j = 0; j < 3; j++) xyz[j] += v * bar[j];
    }
    double s = xyz[0] + xyz[1] + xyz[2];
    xy[0] = xyz[0] / s;
    xy[1] = xyz[1] / s;
}

static double table_fn(double l, const void *user) {
    return pn_cie_table_eval(user, l);
}

static double planck_fn(double l, const void *user) {
    return pn_planck(l, *(const double *)user);
}

/* The tables are the CIE's: ∫ȳ, and the chromaticities of D65 and A (CIE 015 values). */
static void test_cie_tables(void) {
    CHECK_NEAR(pn_cie_y_integral(), 106.857, 0.01);
    double xy[2];
    chromaticity(table_fn, pn_cie_d65_5nm, xy);
    CHECK_NEAR(xy[0], 0.31272, 2e-4);
    CHECK_NEAR(xy[1], 0.32903, 2e-4);
    chromaticity(table_fn, pn_cie_a_5nm, xy);
    CHECK_NEAR(xy[0], 0.44757, 2e-4);
    CHECK_NEAR(xy[1], 0.40745, 2e-4);
    /* sRGB white (1, 1, 1) is D65 at Y = 1. */
    double xyz[3];
    pn_linear_srgb_to_xyz((double[3]){1, 1, 1}, xyz);
    CHECK_NEAR(xyz[1], 1.0, 1e-6);
    CHECK_NEAR(xyz[0] / (xyz[0] + xyz[1] + xyz[2]), 0.3127, 1e-4);
}

/* A black body of known temperature has the CIE chromaticity of that temperature: illuminant A is
 * by definition a Planckian radiator at 2856 K (with the 1968 c2 = 1.4350e-2 m K, 2848 K with
 * today's 1.4388e-2), and the Planckian locus passes (0.3221, 0.3318) at 6000 K. */
static void test_blackbody_chromaticity(void) {
    double xy[2], t = 2856.0 * 1.4388 / 1.4350;
    chromaticity(planck_fn, &t, xy);
    CHECK_NEAR(xy[0], 0.44757, 1e-3);
    CHECK_NEAR(xy[1], 0.40745, 1e-3);
    t = 6000.0;
    chromaticity(planck_fn, &t, xy);
    CHECK_NEAR(xy[0], 0.3221, 1e-3);
    CHECK_NEAR(xy[1], 0.3318, 1e-3);
    CHECK(pn_planck(500.0, 0.0) == 0.0);
}

/* Every in-gamut colour of a grid is reproduced by its exact fit within 1e-4 (integrated at 1 nm,
 * not on the fitter's own quadrature), and by the build-time table within 1.5e-3 (its trilinear
 * interpolation of the coefficients; the worst of 20^3 colours measured 1.1e-3). */
static void test_round_trip(void) {
    const pn_rgb2spec_table *table = pn_rgb2spec_srgb();
    CHECK(table != NULL);
    if (!table) return;
    CHECK(table->res == 64);
    double worst_fit = 0.0, worst_table = 0.0;
    for (int r = 0; r < 7; r++)
        for (int g = 0; g < 7; g++)
            for (int b = 0; b < 7; b++) {
                double rgb[3] = {0.02 + 0.16 * r, 0.02 + 0.16 * g, 0.02 + 0.16 * b}, cn[3] = {0, 0, 0}, back[3];
                float c[3], rgbf[3] = {(float)rgb[0], (float)rgb[1], (float)rgb[2]};
                pn_rgb2spec_fit(rgb, cn);
                pn_rgb2spec_to_nm(cn, c);
                pn_rgb2spec_reflectance_rgb(c, back);
                for (int k = 0; k < 3; k++) worst_fit = fmax(worst_fit, fabs(back[k] - rgb[k]));
                pn_rgb2spec_lookup(table, rgbf, c);
                pn_rgb2spec_reflectance_rgb(c, back);
                for (int k = 0; k < 3; k++) worst_table = fmax(worst_table, fabs(back[k] - (double)rgbf[k]));
            }
    CHECK_MSG(worst_fit < 1e-4, "worst exact-fit round trip %g", worst_fit);
    CHECK_MSG(worst_table < 1.5e-3, "worst table round trip %g", worst_table);
    /* Greys are constant spectra, exactly; black and white are 0 and 1 everywhere. */
    float c[3];
    pn_rgb2spec_lookup(table, (float[3]){0.3f, 0.3f, 0.3f}, c);
    CHECK_NEAR(pn_sigmoid_spectrum(c, 400.0), 0.3, 1e-6);
    CHECK_NEAR(pn_sigmoid_spectrum(c, 700.0), 0.3, 1e-6);
    pn_rgb2spec_lookup(table, (float[3]){0.0f, 0.0f, 0.0f}, c);
    CHECK(pn_sigmoid_spectrum(c, 550.0) == 0.0);
    pn_rgb2spec_lookup(table, (float[3]){1.0f, 1.0f, 1.0f}, c);
    CHECK(pn_sigmoid_spectrum(c, 550.0) == 1.0);
    /* Reflectance spectra stay within [0, 1]. */
    pn_rgb2spec_lookup(table, (float[3]){0.95f, 0.05f, 0.02f}, c);
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX; l += 10.0) {
        double s = pn_sigmoid_spectrum(c, l);
        CHECK(s >= 0.0 && s <= 1.0);
    }
}

/* The table does not depend on the number of threads that fitted it. */
static void test_table_deterministic(void) {
    pn_rgb2spec_table one, three;
    CHECK(pn_rgb2spec_table_build(&one, 8, 1));
    CHECK(pn_rgb2spec_table_build(&three, 8, 3));
    CHECK(memcmp(one.coeffs, three.coeffs, sizeof(float) * 9 * 8 * 8 * 8) == 0);
    pn_rgb2spec_table_free(&one);
    pn_rgb2spec_table_free(&three);
}

/* The wavelength density integrates to 1, its inverse CDF inverts it, and samples follow it
 * (chi-square over 47 bins of 10 nm, 200 000 samples, against the 0.1% critical value). */
static void test_wavelength_sampling(void) {
    double integral = 0.0;
    for (double l = PN_LAMBDA_MIN; l < PN_LAMBDA_MAX; l += 0.01)
        integral += pn_visible_wavelength_pdf(l + 0.005) * 0.01;
    CHECK_NEAR(integral, 1.0, 1e-6);
    CHECK(pn_visible_wavelength_pdf(359.0) == 0.0 && pn_visible_wavelength_pdf(831.0) == 0.0);
    CHECK_NEAR(pn_visible_wavelength_sample(0.0), PN_LAMBDA_MIN, 1e-6);
    CHECK_NEAR(pn_visible_wavelength_sample(1.0), PN_LAMBDA_MAX, 1e-6);
    enum { BINS = 47, N = 200000 };
    double counts[BINS] = {0};
    uint64_t state = 0x9E3779B97F4A7C15ull;
    for (int i = 0; i < N; i++) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        double u = (double)(state >> 11) * 0x1.0p-53;
        double l = pn_visible_wavelength_sample(u);
        int b = (int)((l - PN_LAMBDA_MIN) / 10.0);
        counts[b < BINS ? b : BINS - 1] += 1.0;
    }
    double chi2 = 0.0;
    for (int b = 0; b < BINS; b++) {
        double p = 0.0, lo = PN_LAMBDA_MIN + 10.0 * b;
        for (double l = lo; l < lo + 10.0; l += 0.01) p += pn_visible_wavelength_pdf(l + 0.005) * 0.01;
        double expected = p * N;
        chi2 += (counts[b] - expected) * (counts[b] - expected) / expected;
    }
    CHECK_MSG(chi2 < 82.7, "chi-square %g over %d bins (0.1%% critical value 82.7 at 46 dof)", chi2, BINS);
    /* Hero and companions: stratified in the CDF, each with its own density. */
    pn_wavelengths w;
    pn_wavelengths_sample(0.9, &w);
    CHECK_NEAR(w.lambda[0], pn_visible_wavelength_sample(0.9), 1e-3);
    CHECK_NEAR(w.lambda[1], pn_visible_wavelength_sample(0.15), 1e-3);
    CHECK_NEAR(w.pdf[2], pn_visible_wavelength_pdf(w.lambda[2]), 1e-6);
}

/* Hero-wavelength estimates of a reflectance's Y under D65 average to the integral: 4000 pixel
 * samples, checked against five standard errors of their own spread. */
static void test_spectral_estimate_unbiased(void) {
    float c[3];
    double cn[3] = {0, 0, 0};
    pn_rgb2spec_fit((double[3]){0.7, 0.3, 0.1}, cn);
    pn_rgb2spec_to_nm(cn, c);
    double exact = 0.0, y_white = 0.0;
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX; l += 0.25) {
        double bar[3];
        pn_cie_xyz_bar(l, bar);
        double d = pn_cie_table_eval(pn_cie_d65_5nm, l);
        exact += pn_sigmoid_spectrum(c, l) * d * bar[1] * 0.25;
        y_white += d * bar[1] * 0.25;
    }
    exact /= y_white;
    enum { N = 4000 };
    double sum = 0.0, sum2 = 0.0;
    for (int i = 0; i < N; i++) {
        pn_wavelengths w;
        pn_wavelengths_sample((i + 0.5) / N * 0.999 + 0.0005 * ((i * 7) % 3), &w);
        double est = 0.0;
        for (int k = 0; k < PN_WAVELENGTHS; k++) {
            double bar[3];
            pn_cie_xyz_bar(w.lambda[k], bar);
            est += pn_sigmoid_spectrum(c, w.lambda[k]) * pn_cie_table_eval(pn_cie_d65_5nm, w.lambda[k]) * bar[1] /
                   (double)w.pdf[k];
        }
        est /= PN_WAVELENGTHS * y_white;
        sum += est;
        sum2 += est * est;
    }
    double mean = sum / N, var = sum2 / N - mean * mean;
    CHECK_MSG(fabs(mean - exact) < 5.0 * sqrt(var / N) + 1e-4, "mean %g, exact %g", mean, exact);
}

PN_TESTS(TEST(test_cie_tables), TEST(test_blackbody_chromaticity), TEST(test_round_trip),
         TEST(test_table_deterministic), TEST(test_wavelength_sampling), TEST(test_spectral_estimate_unbiased))
