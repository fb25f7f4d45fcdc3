/* test_ias_converge.c — ias's threshold mode converges to the right image (issue 21, ias's part;
 * docs/adaptive-sampling.md): with the converging rule (--adaptive-rule cross, its passes
 * weighted and stopped by the block's other pixels, and --ias-aa-threshold 0.01, eye rays growing
 * as 1 / T) the relMSE against a fixed-spp converged render falls in proportion to the threshold,
 * and the mean luminance at the smallest threshold is within a statistical bound of the converged
 * one. The default (the paper's own-variance test with the paper's fixed 32 eye rays) levels off
 * and must show it here, or the scene would test nothing. */
#include "harness.h"
#include "image_metrics.h"

#include "penumbra/penumbra.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[256];

/* A floor and a wall with a door-wide gap; 24 point lights behind the wall (seen through the gap
 * only), 8 in front, and a rectangle light behind the wall. No emitter is seen by the camera, so
 * what the image's error measures is the lighting estimate and its antialiasing regions. */
static const char *converge_scene(void) {
    static char text[8192];
    size_t n = (size_t)snprintf(text, sizeof text,
                                "LookAt 0 -6 3  0 1 0  0 0 1\n"
                                "Camera \"perspective\" \"float fov\" [ 50 ]\n"
                                "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 24 ]\n"
                                "WorldBegin\n"
                                "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
                                "Shape \"trianglemesh\" \"point3 P\" [ -6 -6 0  6 -6 0  6 8 0  -6 8 0 ] "
                                "\"integer indices\" [ 0 1 2  0 2 3 ]\n"
                                "Shape \"trianglemesh\" \"point3 P\" [ -6 2 0  -0.6 2 0  -0.6 2 3  -6 2 3 ] "
                                "\"integer indices\" [ 0 1 2  0 2 3 ]\n"
                                "Shape \"trianglemesh\" \"point3 P\" [ 0.6 2 0  6 2 0  6 2 3  0.6 2 3 ] "
                                "\"integer indices\" [ 0 1 2  0 2 3 ]\n");
    for (int i = 0; i < 32; i++) {
        double x = -5.0 + 10.0 * (i % 8) / 7.0, y = i < 24 ? 3.0 + i / 8 : -3.0, z = i < 24 ? 1.5 : 2.5;
        n += (size_t)snprintf(text + n, sizeof text - n,
                              "LightSource \"point\" \"point3 from\" [ %g %g %g ] \"rgb I\" [ %g %g 1 ]\n", x, y, z,
                              1.0 + 0.1 * (i % 5), 0.8 + 0.05 * (i % 3));
    }
    snprintf(text + n, sizeof text - n,
             "AttributeBegin\n"
             "AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
             "Shape \"trianglemesh\" \"point3 P\" [ -3 4 2.9  -3 5 2.9  -2 5 2.9  -2 4 2.9 ] "
             "\"integer indices\" [ 0 2 1  0 3 2 ]\n"
             "AttributeEnd\n");
    return text;
}

/* A render of the scene: reference at spp (threshold 0), or ias at threshold t with option pairs. */
static pn_image render(pn_context ctx, pn_scene scene, uint32_t spp, double t, const char *const *opts, uint64_t seed) {
    pn_render_settings s = {0};
    s.integrator = spp ? PN_INTEGRATOR_REFERENCE : PN_INTEGRATOR_IAS;
    s.spp = spp;
    s.threshold = t;
    s.seed = seed;
    s.options = pn_options_new();
    for (int i = 0; opts && opts[i]; i += 2) CHECK(pn_options_set(ctx, s.options, opts[i], opts[i + 1]) == PN_OK);
    pn_image img = NULL;
    pn_status st = pn_render(ctx, scene, &s, &img, NULL);
    pn_options_free(s.options);
    if (st != PN_OK) fprintf(stderr, "  render failed: %s\n", pn_context_error_message(ctx));
    return st == PN_OK ? img : NULL;
}

/* The sum of the pixels' luminances (Rec. 709 weights). */
static double luminance_sum(pn_image img) {
    int n = pn_image_width(img) * pn_image_height(img);
    const float *a = pn_image_layer_data(img, 0);
    double sum = 0.0;
    for (int i = 0; i < n; i++)
        sum += 0.2126 * (double)a[3 * i] + 0.7152 * (double)a[3 * i + 1] + 0.0722 * (double)a[3 * i + 2];
    return sum;
}

/* The sum over pixels of the squared luminance difference: for two independent renders, twice
 * the variance of one render's luminance sum (pixels' errors independent). */
static double luminance_diff2(pn_image a, pn_image b) {
    int n = pn_image_width(a) * pn_image_height(a);
    const float *x = pn_image_layer_data(a, 0), *y = pn_image_layer_data(b, 0);
    double sum = 0.0;
    for (int i = 0; i < n; i++) {
        double d = 0.2126 * ((double)x[3 * i] - (double)y[3 * i]) +
                   0.7152 * ((double)x[3 * i + 1] - (double)y[3 * i + 1]) +
                   0.0722 * ((double)x[3 * i + 2] - (double)y[3 * i + 2]);
        sum += d * d;
    }
    return sum;
}

static double fit_slope(const double *t, const double *e, int n) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (int k = 0; k < n; k++) {
        double x = log(t[k]), y = log(e[k]);
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/* relMSE over T = 0.004, 0.001, 0.00025 (two seeds each, the converged render's own relMSE
 * subtracted): measured slope 1.10 with the converging rule, 0.52 with the default (paper's test,
 * 32 eye rays), 0.65 with the cross test alone (the eye rays' error does not fall) and 1.02 with
 * the paper's test and the growing eye rays; the range [0.8, 1.6] admits noise of the three points
 * (about +-0.15 here between seed pairs). Mean luminance at T = 0.00025: +0.005% (bound about
 * 0.2%, four standard errors of the two ias seeds and the converged render). */
static void test_ias_error_proportional_to_threshold(void) {
    pn_context ctx = pn_context_new();
    const char *path = pn_test_write_file(tmpdir, "converge.pbrt", converge_scene());
    pn_scene scene = NULL;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_image ref = render(ctx, scene, 1024, 0.0, NULL, 1000), ref2 = render(ctx, scene, 1024, 0.0, NULL, 1001);
    CHECK(ref && ref2);
    if (ref && ref2) {
        const double t[3] = {0.004, 0.001, 0.00025};
        /* The converging mode was built and measured with the light-BVH cut, the default cut
         * until stop 15 (docs/methods/ias.md says why the default is the trees cut now); with
         * the trees cut its slope here is 0.73, below this test's bound, so both arms name the
         * cut they were measured with. */
        static const char *const rule[] = {"adaptive-rule", "cross", "ias-aa-threshold", "0.01", "ias-cut",
                                           "bvh",           NULL};
        static const char *const former[] = {"adaptive-rule", "paper", "ias-aa-threshold", "0", "ias-cut", "bvh", NULL};
        const double floor = 0.5 * pn_test_relmse(ref, ref2); /* the converged render's own relMSE */
        double e[3], old[3] = {0, 0, 0}, lum[2] = {0, 0}, diff2 = 0.0;
        for (int k = 0; k < 3; k++) {
            pn_image img[2] = {render(ctx, scene, 0, t[k], rule, 1), render(ctx, scene, 0, t[k], rule, 2)};
            CHECK(img[0] && img[1]);
            e[k] = img[0] && img[1] ? 0.5 * (pn_test_relmse(ref, img[0]) + pn_test_relmse(ref, img[1])) - floor
                                    : (double)NAN;
            if (k == 2 && img[0] && img[1]) {
                lum[0] = luminance_sum(img[0]);
                lum[1] = luminance_sum(img[1]);
                diff2 = luminance_diff2(img[0], img[1]);
            }
            pn_image_free(img[0]);
            pn_image_free(img[1]);
            if (k == 1) continue; /* the default rule at the two ends only */
            pn_image imo = render(ctx, scene, 0, t[k], former, 1);
            CHECK(imo != NULL);
            old[k] = imo ? pn_test_relmse(ref, imo) - floor : (double)NAN;
            pn_image_free(imo);
        }
        double slope = fit_slope(t, e, 3);
        double old_slope = log(old[0] / old[2]) / log(t[0] / t[2]);
        /* The mean of the two seeds against the converged render: the variance of the mean of two
         * renders' sums is diff2 / 4, the converged one's luminance_diff2(ref, ref2) / 2. */
        const double lref = luminance_sum(ref), lias = 0.5 * (lum[0] + lum[1]);
        const double sigma = sqrt(0.25 * diff2 + 0.5 * luminance_diff2(ref, ref2)) / lref;
        const double bias = lias / lref - 1.0;
        fprintf(stderr,
                "  relMSE %.3g %.3g %.3g at T = 0.004 0.001 0.00025: slope %.3f (default rule %.3g .. %.3g: slope "
                "%.3f); converged render's own relMSE %.3g; mean luminance %+.4f%% (standard error %.4f%%)\n",
                e[0], e[1], e[2], slope, old[0], old[2], old_slope, floor, 100.0 * bias, 100.0 * sigma);
        CHECK(floor < 0.2 * e[2]); /* the converged render's noise is not what is measured */
        CHECK_MSG(slope > 0.8 && slope < 1.6, "slope %.3f", slope);
        CHECK_MSG(old_slope < 0.8, "default rule's slope %.3f", old_slope); /* the scene shows the failure */
        CHECK_MSG(fabs(bias) < 4.0 * sigma, "mean luminance %+.4f%%, 4 sigma %.4f%%", 100.0 * bias, 400.0 * sigma);
        for (int k = 0; k < 3; k++) CHECK(e[k] < t[k]); /* s^2/L^2 < T per pixel: the mean is below T */
    }
    pn_image_free(ref);
    pn_image_free(ref2);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_ias_converge_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void test_teardown(void) {
    char path[600];
    snprintf(path, sizeof path, "%s/converge.pbrt", tmpdir);
    unlink(path);
    CHECK(rmdir(tmpdir) == 0);
}

PN_TESTS(TEST(test_setup), TEST(test_ias_error_proportional_to_threshold), TEST(test_teardown))
