/* test_refimages.c — penumbra's reference integrator against converged pbrt-v4 renders of real
 * scenes (../shared/reference, direct lighting, matte versions). Each case renders a crop window
 * at fixed settings and seed, averages both images over 4x4-pixel boxes (which removes most of the
 * Monte Carlo noise of both, so that a bias shows) and checks relMSE (epsilon 0.01) of the boxes
 * against a bound. Each case also checks that the bound rejects the same render scaled by 1.1, so
 * a bound that could not fail is itself a failure. The pixel-level relMSE is printed as well.
 * Skipped when ../shared is absent. */
#include "harness.h"

#include "penumbra/penumbra.h"

#include <math.h>
#include <stdbool.h>
#include <unistd.h>

typedef struct ref_case {
    const char *scene;     /* relative to PN_SHARED_DIR/scenes */
    const char *reference; /* relative to PN_SHARED_DIR/reference */
    float crop[4];
    uint32_t spp;
    double max_relmse;
    /* Spectral mode (--spectral) and its tighter checks: mean luminance within max_lum and every
     * channel's mean within max_channel of the reference's (0: the RGB cases' 2% luminance). */
    bool spectral;
    double max_lum, max_channel;
} ref_case;

#define BOX 4

/* relMSE of the BOX x BOX averages of two w x h RGB images (partial boxes at the edges left out). */
static double box_relmse(const float *ref, const float *img, int w, int h, double scale) {
    double sum = 0.0;
    long n = 0;
    for (int by = 0; by + BOX <= h; by += BOX)
        for (int bx = 0; bx + BOX <= w; bx += BOX)
            for (int c = 0; c < 3; c++) {
                double a = 0.0, b = 0.0;
                for (int y = by; y < by + BOX; y++)
                    for (int x = bx; x < bx + BOX; x++) {
                        size_t i = 3u * ((size_t)y * (size_t)w + (size_t)x) + (size_t)c;
                        a += (double)img[i] * scale;
                        b += (double)ref[i];
                    }
                a /= BOX * BOX;
                b /= BOX * BOX;
                sum += (a - b) * (a - b) / (b * b + 0.01);
                n++;
            }
    return n ? sum / (double)n : -1.0;
}

/* Renders the case and returns its relMSE against the reference crop (negative on error). */
static double render_relmse(const ref_case *rc, double scale, double *relmse_scaled, double *lum_ratio,
                            double channel_ratio[3]) {
    char scene_path[1024], ref_path[1024];
    snprintf(scene_path, sizeof scene_path, "%s/scenes/%s", PN_SHARED_DIR, rc->scene);
    snprintf(ref_path, sizeof ref_path, "%s/reference/%s", PN_SHARED_DIR, rc->reference);
    if (access(scene_path, R_OK) != 0 || access(ref_path, R_OK) != 0) return -2.0;
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, NULL, NULL);
    pn_options opts = pn_options_new();
    pn_options_set(ctx, opts, "spectral", rc->spectral ? "1" : "0");
    pn_scene scene = NULL;
    pn_image ref = NULL, ref_crop = NULL, img = NULL;
    pn_stats stats = pn_stats_new();
    double result = -1.0;
    if (pn_scene_load(ctx, scene_path, &scene) != PN_OK || pn_image_read(ctx, ref_path, &ref) != PN_OK) {
        fprintf(stderr, "  %s\n", pn_context_error_message(ctx));
        goto done;
    }
    pn_render_settings s = {0};
    s.options = opts;
    s.spp = rc->spp;
    s.seed = 7;
    s.has_crop = 1;
    for (int i = 0; i < 4; i++) s.crop[i] = rc->crop[i];
    s.width = pn_image_width(ref);
    s.height = pn_image_height(ref);
    double shadow_per_pixel = 0.0, seconds = 0.0;
    if (!stats || pn_render(ctx, scene, &s, &img, stats) != PN_OK || !pn_stats_get(stats, "render_seconds", &seconds) ||
        !pn_stats_get(stats, "shadow_rays_per_pixel_mean", &shadow_per_pixel)) {
        fprintf(stderr, "  %s\n", pn_context_error_message(ctx));
        goto done;
    }
    int W = s.width, H = s.height;
    int x0 = (int)ceilf((float)W * rc->crop[0]), x1 = (int)ceilf((float)W * rc->crop[1]);
    int y0 = (int)ceilf((float)H * rc->crop[2]), y1 = (int)ceilf((float)H * rc->crop[3]);
    pn_image_metrics m;
    if (pn_image_crop(ctx, ref, x0, y0, x1 - x0, y1 - y0, &ref_crop) != PN_OK ||
        pn_image_compare(ctx, ref_crop, img, &m, NULL) != PN_OK) {
        fprintf(stderr, "  %s\n", pn_context_error_message(ctx));
        goto done;
    }
    const float *pr = pn_image_layer_data(ref_crop, 0), *pi = pn_image_layer_data(img, 0);
    result = box_relmse(pr, pi, x1 - x0, y1 - y0, 1.0);
    *lum_ratio = m.mean_luminance_reference > 0.0 ? m.mean_luminance_image / m.mean_luminance_reference : 0.0;
    for (int c = 0; c < 3; c++) {
        double a = 0.0, b = 0.0;
        size_t n = (size_t)(x1 - x0) * (size_t)(y1 - y0);
        for (size_t i = 0; i < n; i++) {
            a += (double)pi[3 * i + (size_t)c];
            b += (double)pr[3 * i + (size_t)c];
        }
        channel_ratio[c] = b > 0.0 ? a / b : 0.0;
    }
    /* The same image scaled: a 10% bias must exceed the bound. */
    *relmse_scaled = box_relmse(pr, pi, x1 - x0, y1 - y0, scale);
    fprintf(stderr,
            "  %s: %dx%d crop, %u spp, %.1f shadow rays/px, %.2f s: box relMSE %.3g (bound %.3g, "
            "x%.1f: %.3g), pixel relMSE %.3g, mean luminance %.4g vs reference %.4g, channels x %.4f %.4f %.4f\n",
            rc->scene, x1 - x0, y1 - y0, rc->spp, shadow_per_pixel, seconds, result, rc->max_relmse, scale,
            *relmse_scaled, m.relmse, m.mean_luminance_image, m.mean_luminance_reference, channel_ratio[0],
            channel_ratio[1], channel_ratio[2]);
done:
    pn_stats_free(stats);
    pn_image_free(img);
    pn_image_free(ref_crop);
    pn_image_free(ref);
    pn_scene_free(scene);
    pn_options_free(opts);
    pn_context_free(ctx);
    return result;
}

static void run_case(const ref_case *rc) {
    double scaled = -1.0, lum_ratio = 0.0, channels[3] = {0, 0, 0};
    double relmse = render_relmse(rc, 1.1, &scaled, &lum_ratio, channels);
    if (relmse == -2.0) {
        pn_test_skip("../shared scenes or references not found");
        return;
    }
    CHECK_MSG(relmse >= 0.0, "render of %s failed", rc->scene);
    CHECK_MSG(relmse <= rc->max_relmse, "%s: relMSE %.4g exceeds %.4g", rc->scene, relmse, rc->max_relmse);
    /* Mean luminance of the crop within 2%: Monte Carlo noise of a mean over thousands of pixels is
     * far below that (measured differences: 0.0%, 0.7%, 0.25%, 0.1%); 2% leaves room for RGB versus
     * spectral rendering of coloured lights and still rejects a 10% bias. */
    double max_lum = rc->max_lum > 0.0 ? rc->max_lum : 0.02;
    CHECK_MSG(fabs(lum_ratio - 1.0) <= max_lum, "%s: mean luminance ratio %.4f", rc->scene, lum_ratio);
    for (int c = 0; rc->max_channel > 0.0 && c < 3; c++)
        CHECK_MSG(fabs(channels[c] - 1.0) <= rc->max_channel, "%s: channel %d mean ratio %.4f", rc->scene, c,
                  channels[c]);
    CHECK_MSG(scaled > rc->max_relmse, "%s: the bound %.4g does not reject a 10%% bias (relMSE %.4g)", rc->scene,
              rc->max_relmse, scaled);
}

/* Bounds, from the box relMSE measured for these exact renders on 2026-11-27 (and the value the
 * same render scaled by 1.1 gives): cornell 6.7e-7 (5.9e-3) -> 1e-4; hall-many 9.8e-4 (9.8e-3) ->
 * 2.5e-3; staircase 1.3e-3 (8.6e-3) -> 3e-3; living-env 4.1e-3 (1.07e-2) -> 6e-3. Each bound
 * leaves room for noise above the measured value and stays below the 10% bias.
 * The staircase crop is the upper wall lit by the globe lights: lower down, where warm light falls
 * on orange wood, penumbra's RGB products differ from pbrt-v4's spectral ones by 4-9% in red.
 * Spectral mode renders that lower part too (test_staircase_832_matte_spectral: measured
 * luminance x1.0007, channels x1.0007 1.0006 1.0040 at seed 7; RGB mode x1.0444, red x1.0739).
 * Since image textures are read through pbrt-v4's pyramid at the camera footprint's level
 * (scene/mipmap.c): luminance x1.0005, channels x1.0008 1.0000 1.0105 (seed 8: 1.0084). Blue is
 * 0.5-4% of that crop's signal under 2200-3300 K light (negative in some rows in spectral mode),
 * so its ratio moves with small changes of the wood's upsampled spectra: the bound for the
 * channels is 1.5% there, luminance stays at 0.5%. */
static void test_cornell_box_matte(void) {
    ref_case rc = {"cornell-box/cornell-box-matte.pbrt",
                   "cornell-box-matte.exr",
                   {0.3f, 0.45f, 0.55f, 0.7f},
                   64,
                   1e-4,
                   false,
                   0,
                   0};
    run_case(&rc);
}

static void test_hall_many_matte(void) {
    ref_case rc = {
        "hall-many/hall-many-matte.pbrt", "hall-many-matte.exr", {0.4f, 0.5f, 0.4f, 0.5f}, 16, 2.5e-3, false, 0, 0};
    run_case(&rc);
}

static void test_staircase_832_matte(void) {
    ref_case rc = {"staircase-832/staircase-832-matte.pbrt",
                   "staircase-832-matte.exr",
                   {0.4f, 0.6f, 0.1f, 0.2f},
                   64,
                   3e-3,
                   false,
                   0,
                   0};
    run_case(&rc);
}

/* Spectral mode on the lower half, warm light on orange wood, where RGB mode is 4-9% too bright in
 * red: mean luminance within 0.5% and each channel within 1.5% of pbrt-v4's (RGB mode fails both;
 * blue's bound: see above). */
static void test_staircase_832_matte_spectral(void) {
    ref_case rc = {"staircase-832/staircase-832-matte.pbrt",
                   "staircase-832-matte.exr",
                   {0.3f, 0.7f, 0.55f, 0.8f},
                   32,
                   3e-3,
                   true,
                   0.005,
                   0.015};
    run_case(&rc);
}

static void test_living_env_138_matte(void) {
    ref_case rc = {"living-env-138/living-env-138-matte.pbrt",
                   "living-env-138-matte.exr",
                   {0.4f, 0.55f, 0.4f, 0.6f},
                   64,
                   6e-3,
                   false,
                   0,
                   0};
    run_case(&rc);
}

PN_TESTS(TEST(test_cornell_box_matte), TEST(test_hall_many_matte), TEST(test_staircase_832_matte),
         TEST(test_staircase_832_matte_spectral), TEST(test_living_env_138_matte))
