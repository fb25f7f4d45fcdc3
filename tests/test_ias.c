/* test_ias.c — Iterative Adaptive Sampling: the scene-independent parts (ias_math.h: the
 * appendix's variance-minimising PDF on a two-light case, eq. 6's blend weights, eq. 7-8's
 * inverse-variance combination against a hand-computed case), and renders: ias converges to the
 * reference integrator's image on a small many-light scene with occlusion, and black-pixel
 * detection never blackens a pixel that a converged reference finds lit by a small light. */
#include "harness.h"
#include "render_fields.h"

#include "core/rng.h"
#include "integrators/ias_math.h"
#include "penumbra/penumbra.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

static char tmpdir[256];

/* Writes `text` as tmpdir/name and loads it with ctx; NULL, with the library's message printed
 * and a failed check, if it does not load. */
static pn_scene load_scene(pn_context ctx, const char *name, const char *text) {
    const char *path = pn_test_write_file(tmpdir, name, text);
    pn_scene scene = NULL;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    if (!scene) fprintf(stderr, "  %s\n", pn_context_error_message(ctx));
    return scene;
}

/* A room-like scene: a floor, a wall with a door-sized gap between two rooms, 24 point lights and
 * two rectangle lights behind the wall (mostly occluded from the camera's floor), one small
 * rectangle light in front, and a sphere light. Many clusters, partial visibility. */
static const char *many_light_scene(void) {
    static char text[8192];
    size_t n = 0;
    n += (size_t)snprintf(text + n, sizeof text - n,
                          "LookAt 0 -6 3  0 1 0  0 0 1\n"
                          "Camera \"perspective\" \"float fov\" [ 50 ]\n"
                          "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 24 ]\n"
                          "WorldBegin\n"
                          "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ -6 -6 0  6 -6 0  6 8 0  -6 8 0 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ -6 2 0  -0.6 2 0  -0.6 2 3  -6 2 3 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ 0.6 2 0  6 2 0  6 2 3  0.6 2 3 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n");
    for (int i = 0; i < 24; i++) {
        double x = -5.0 + 10.0 * (i % 6) / 5.0, y = 3.0 + 4.0 * (i / 6) / 3.0;
        n += (size_t)snprintf(text + n, sizeof text - n,
                              "LightSource \"point\" \"point3 from\" [ %g %g 1.5 ] \"rgb I\" [ %g %g 1 ]\n", x, y,
                              1.0 + 0.1 * (i % 5), 0.8 + 0.05 * (i % 3));
    }
    n += (size_t)snprintf(
        text + n, sizeof text - n,
        "AttributeBegin\n"
        "  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ -3 4 2.9  -3 5 2.9  -2 5 2.9  -2 4 2.9 ]\n"
        "     \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ 2 4 2.9  2 5 2.9  3 5 2.9  3 4 2.9 ]\n"
        "     \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ -0.2 -1.2 2.5  -0.2 -0.8 2.5  0.2 -0.8 2.5  0.2 -1.2 2.5 ]\n"
        "     \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "AttributeEnd\n"
        "AttributeBegin\n"
        "  AreaLightSource \"diffuse\" \"rgb L\" [ 20 16 12 ]\n"
        "  Translate 3 -2 1\n"
        "  Shape \"sphere\" \"float radius\" [ 0.1 ]\n"
        "AttributeEnd\n");
    return text;
}

static uint32_t block_size; /* 0: the default (8) */

static pn_image render(pn_context ctx, pn_scene scene, pn_integrator_kind kind, uint32_t spp, double threshold,
                       pn_render_stats *stats) {
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    if (block_size) pn_options_set_int(ctx, o, "block-size", block_size);
    s.integrator = kind;
    s.spp = spp;
    s.threshold = threshold;
    /* 8 shadow rays per eye ray where the integrator takes that option (ias does not). */
    if (pn_option_applies(pn_option_find("shadow-rays"), pn_method_find_kind(PN_METHOD_INTEGRATOR, kind)))
        pn_options_set_int(ctx, o, "shadow-rays", 8);
    s.seed = 3;
    pn_image img = NULL;
    pn_status st = pn_test_render(ctx, scene, &s, &img, stats);
    pn_options_free(o);
    if (st != PN_OK) {
        fprintf(stderr, "  render failed: %s\n", pn_context_error_message(ctx));
        return NULL;
    }
    return img;
}

/* Box-averaged (4x4) relMSE and mean luminance ratio of img against ref. */
static void compare(pn_image ref, pn_image img, double scale, double *relmse, double *lum_ratio) {
    int w = pn_image_width(ref), h = pn_image_height(ref);
    const float *a = pn_image_layer_data(ref, 0), *b = pn_image_layer_data(img, 0);
    double sum = 0.0, la = 0.0, lb = 0.0;
    long cnt = 0;
    for (int by = 0; by + 4 <= h; by += 4)
        for (int bx = 0; bx + 4 <= w; bx += 4)
            for (int c = 0; c < 3; c++) {
                double ra = 0.0, rb = 0.0;
                for (int y = by; y < by + 4; y++)
                    for (int x = bx; x < bx + 4; x++) {
                        ra += (double)a[3 * (y * w + x) + c];
                        rb += (double)b[3 * (y * w + x) + c] * scale;
                    }
                ra /= 16.0;
                rb /= 16.0;
                sum += (rb - ra) * (rb - ra) / (ra * ra + 0.01);
                cnt++;
                la += ra;
                lb += rb;
            }
    *relmse = sum / (double)cnt;
    *lum_ratio = la > 0.0 ? lb / la : 0.0;
}

static void test_ias_matches_reference(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "many.pbrt", many_light_scene());
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_stats rs, is;
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_REFERENCE, 256, 0.0, &rs);
    pn_image img = render(ctx, scene, PN_INTEGRATOR_IAS, 0, 0.002, &is);
    CHECK(ref && img);
    if (ref && img) {
        double relmse, ratio, scaled, ratio_scaled;
        compare(ref, img, 1.0, &relmse, &ratio);
        compare(ref, img, 1.1, &scaled, &ratio_scaled);
        fprintf(stderr,
                "  reference %.0f shadow rays/px, ias %.0f shadow rays/px: box relMSE %.3g (x1.1: %.3g), "
                "mean luminance ratio %.4f\n",
                rs.shadow_rays_per_pixel_mean, is.shadow_rays_per_pixel_mean, relmse, scaled, ratio);
        /* Measured on 2026-11-27: box relMSE 4.8e-5, 4.6e-4 for the same image scaled by 1.1 (the
         * scene is dark, so epsilon = 0.01 in relMSE damps both), mean luminance 0.988 of the
         * reference's: ias shades representative points (§4.4) and stops pixels adaptively, and
         * the reference itself at threshold 0.002 comes out 1.1% dark from termination bias. */
        CHECK_MSG(relmse < 2e-4, "box relMSE %.4g", relmse);
        CHECK_MSG(scaled > 2e-4, "the bound does not reject a 10%% bias (%.4g)", scaled);
        CHECK_MSG(fabs(ratio - 1.0) < 0.025, "mean luminance ratio %.4f", ratio);
    }
    pn_image_free(ref);
    pn_image_free(img);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* An ias render at threshold 0.002 with options given as name, value pairs (NULL-terminated). */
static pn_image render_ias_with(pn_context ctx, pn_scene scene, const char *const *opts, pn_render_stats *stats) {
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    for (int i = 0; opts[i]; i += 2) CHECK(pn_options_set(ctx, o, opts[i], opts[i + 1]) == PN_OK);
    s.integrator = PN_INTEGRATOR_IAS;
    s.threshold = 0.002;
    s.seed = 3;
    pn_image img = NULL;
    pn_status st = pn_test_render(ctx, scene, &s, &img, stats);
    pn_options_free(o);
    CHECK(st == PN_OK);
    return st == PN_OK ? img : NULL;
}

/* Issue 15: --ias-variant paper is the default variant with every departure switched off (the
 * paper's code path, the same bits; issue 21: the default variant's auto rule is cross, so the
 * paper's rule is named), and both variants meet test_ias_matches_reference's bound
 * against the reference; the paper variant's images are pinned to penumbra's before the variant
 * existed by bench/bitident.sh. */
static void test_ias_variants(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "many.pbrt", many_light_scene());
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    static const char *const paper[] = {"ias-variant", "paper", NULL};
    static const char *const off[] = {"ias-variant",
                                      "default",
                                      "ias-cut",
                                      "trees",
                                      "ias-prior",
                                      "uniform",
                                      "ias-points",
                                      "representative",
                                      "ias-pass-rays",
                                      "0",
                                      "ias-cluster-numbers",
                                      "jittered",
                                      "ias-aa-threshold",
                                      "0",
                                      "ias-emitter-rays",
                                      "0",
                                      "ias-light-guide",
                                      "off",
                                      "adaptive-rule",
                                      "paper",
                                      NULL};
    static const char *const def[] = {NULL};
    pn_render_stats rs, st[3];
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_REFERENCE, 256, 0.0, &rs);
    pn_image img[3] = {render_ias_with(ctx, scene, paper, &st[0]), render_ias_with(ctx, scene, off, &st[1]),
                       render_ias_with(ctx, scene, def, &st[2])};
    CHECK(ref && img[0] && img[1] && img[2]);
    if (ref && img[0] && img[1] && img[2]) {
        size_t n = (size_t)pn_image_width(img[0]) * (size_t)pn_image_height(img[0]) * 3u;
        CHECK(memcmp(pn_image_layer_data(img[0], 0), pn_image_layer_data(img[1], 0), n * sizeof(float)) == 0);
        CHECK(memcmp(pn_image_layer_data(img[0], 0), pn_image_layer_data(img[2], 0), n * sizeof(float)) != 0);
        for (int v = 0; v < 3; v += 2) {
            double relmse, ratio;
            compare(ref, img[v], 1.0, &relmse, &ratio);
            fprintf(stderr, "  %s variant: %.0f shadow rays/px, box relMSE %.3g, mean luminance ratio %.4f\n",
                    v ? "default" : "paper", st[v].shadow_rays_per_pixel_mean, relmse, ratio);
            CHECK_MSG(relmse < 2e-4, "box relMSE %.4g", relmse);
            CHECK_MSG(fabs(ratio - 1.0) < 0.025, "mean luminance ratio %.4f", ratio);
        }
    }
    pn_image_free(ref);
    for (int v = 0; v < 3; v++) pn_image_free(img[v]);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* Blocks of 16x16 and 32x32 pixels (the block side is a setting): the same image within the same
 * bound, and every pixel rendered (a block larger than the image included). Blocks smaller than
 * 8x8 are refused: at 4x4 the passes' weights and the convergence test, which use statistics
 * pooled over the block, rest on too few pixels; measured here: box relMSE 1.5e-3 and the mean
 * 3.1% too bright. */
static void test_ias_block_sizes(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "many.pbrt", many_light_scene());
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_REFERENCE, 256, 0.0, NULL);
    const uint32_t sizes[] = {16, 32};
    for (int k = 0; k < 2; k++) {
        block_size = sizes[k];
        pn_render_stats st;
        pn_image img = render(ctx, scene, PN_INTEGRATOR_IAS, 0, 0.002, &st);
        CHECK(ref && img);
        if (ref && img) {
            double relmse, ratio;
            compare(ref, img, 1.0, &relmse, &ratio);
            fprintf(stderr, "  block %ux%u: box relMSE %.3g, mean luminance ratio %.4f, %.1f passes/px\n", sizes[k],
                    sizes[k], relmse, ratio, st.passes_per_pixel_mean);
            CHECK_MSG(relmse < 2e-4, "block %u: box relMSE %.4g", sizes[k], relmse);
            CHECK_MSG(fabs(ratio - 1.0) < 0.025, "block %u: mean luminance ratio %.4f", sizes[k], ratio);
            CHECK(st.passes_per_pixel_mean >= 1.0); /* every pixel was rendered */
        }
        pn_image_free(img);
    }
    block_size = 0;
    pn_image_free(ref);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A floor under a ceiling with one small hole; above it a small light right over the hole and 30
 * point lights elsewhere above the ceiling (occluded for every point the camera sees). The lit
 * pixels are lit by the one small light among 31 clusters: §5.9's black-pixel rule (no visible
 * sample after 3 passes and 250 shadow rays) must not blacken any of them. */
static void test_black_detection_keeps_lit_pixels(void) {
    static char text[8192];
    size_t n = 0;
    n += (size_t)snprintf(text + n, sizeof text - n,
                          "LookAt 0 0 1.5  0 0 0  0 1 0\n"
                          "Camera \"perspective\" \"float fov\" [ 40 ]\n"
                          "Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n"
                          "WorldBegin\n"
                          "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ -4 -4 0  4 -4 0  4 4 0  -4 4 0 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          /* ceiling at z = 2 with a 0.1 x 0.1 hole at the origin, seen from below */
                          "Shape \"trianglemesh\" \"point3 P\" [ -4 -4 2  -0.05 -4 2  -0.05 4 2  -4 4 2 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ 0.05 -4 2  4 -4 2  4 4 2  0.05 4 2 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ -0.05 -4 2  0.05 -4 2  0.05 -0.05 2  -0.05 -0.05 2 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          "Shape \"trianglemesh\" \"point3 P\" [ -0.05 0.05 2  0.05 0.05 2  0.05 4 2  -0.05 4 2 ]\n"
                          "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                          "LightSource \"point\" \"point3 from\" [ 0 0 2.3 ] \"rgb I\" [ 2 2 2 ]\n");
    /* 30 lights above the ceiling, at least 1.6 m to the side of the hole: what they send through
     * it lands more than 6 m away, outside the floor the camera sees (about 1.1 m wide). */
    for (int i = 0; i < 30; i++) {
        double a = 2.0 * 3.14159265358979 * i / 30.0, r = 1.6 + 0.5 * (i % 3);
        n += (size_t)snprintf(text + n, sizeof text - n,
                              "LightSource \"point\" \"point3 from\" [ %g %g 2.5 ] \"rgb I\" [ 5 5 5 ]\n", r * cos(a),
                              r * sin(a));
    }
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "hole.pbrt", text);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_stats rs, is;
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_REFERENCE, 64, 0.0, &rs);
    pn_image img = render(ctx, scene, PN_INTEGRATOR_IAS, 0, 0.01, &is);
    CHECK(ref && img);
    if (ref && img) {
        /* Pixels on the edge of the light's spot are partly lit; ias shades a pixel at the
         * representative points of its antialiasing regions (§4.4), which may all lie outside the
         * spot: that is the region approximation, not black-pixel detection. So the check is on
         * pixels lit over at least a quarter of their area (value >= max / 4). */
        int w = pn_image_width(ref), h = pn_image_height(ref), lit = 0, wrongly_black = 0, edge_black = 0;
        const float *a = pn_image_layer_data(ref, 0), *b = pn_image_layer_data(img, 0);
        float max_value = 0.0f;
        for (int i = 0; i < w * h; i++) max_value = fmaxf(max_value, a[3 * i + 1]);
        for (int i = 0; i < w * h; i++) {
            if (!(a[3 * i + 1] > 0.0f)) continue;
            bool black = !(b[3 * i + 1] > 0.0f);
            if (a[3 * i + 1] >= 0.25f * max_value) {
                lit++;
                wrongly_black += black;
            } else {
                edge_black += black;
            }
        }
        fprintf(stderr, "  %d pixels lit in the reference, %d of them black in ias (%d partly lit edge pixels black)\n",
                lit, wrongly_black, edge_black);
        CHECK(lit > 0 && lit < w * h);
        CHECK(wrongly_black == 0);
        /* Table 5's visibility statistics: only the light over the hole is ever unoccluded. */
        CHECK(is.lights_visible_viewpoint == 1);
        CHECK(is.env_regions_visible_viewpoint == 0);
        CHECK(is.visible_lights_per_pixel_mean > 0.0 && is.visible_lights_per_pixel_mean <= 1.0);
    }
    pn_image_free(ref);
    pn_image_free(img);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* The same image for any thread count (each block is rendered from its own seed and data). */
static void test_ias_thread_determinism(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "many_t.pbrt", many_light_scene());
    pn_image img[2] = {NULL, NULL};
    for (int t = 0; t < 2 && scene; t++) {
        pn_render_settings s = {0};
        s.integrator = PN_INTEGRATOR_IAS;
        s.threshold = 0.01;
        s.threads = t + 1;
        CHECK(pn_render(ctx, scene, &s, &img[t], NULL) == PN_OK);
    }
    if (img[0] && img[1]) {
        size_t n = (size_t)pn_image_width(img[0]) * (size_t)pn_image_height(img[0]) * 3u;
        CHECK(memcmp(pn_image_layer_data(img[0], 0), pn_image_layer_data(img[1], 0), n * sizeof(float)) == 0);
    }
    pn_image_free(img[0]);
    pn_image_free(img[1]);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* The AOVs reproduce the paper's figures as false-colour pictures with a colour bar. */
static void test_false_color_aov(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "many_fc.pbrt", many_light_scene());
    pn_render_settings s = {0};
    s.integrator = PN_INTEGRATOR_IAS;
    s.aovs = PN_AOV_PASSES | PN_AOV_VISIBLE_FRACTION | PN_AOV_NORMAL;
    pn_image img = NULL, fc = NULL;
    CHECK(scene && pn_render(ctx, scene, &s, &img, NULL) == PN_OK);
    if (img) {
        int w = pn_image_width(img), h = pn_image_height(img), passes = -1;
        for (int l = 0; l < pn_image_layer_count(img); l++)
            if (strcmp(pn_image_layer_name(img, l), "passes") == 0) passes = l;
        CHECK(passes > 0);
        CHECK(pn_image_false_color(ctx, img, "passes", 0.0, 0.0, &fc) == PN_OK);
        if (fc && passes > 0) {
            CHECK(pn_image_width(fc) == w && pn_image_height(fc) > h);
            const float *src = pn_image_layer_data(img, passes), *rgb = pn_image_layer_data(fc, 0);
            float lo = src[0], hi = src[0];
            for (int i = 0; i < w * h; i++) {
                lo = fminf(lo, src[i]);
                hi = fmaxf(hi, src[i]);
            }
            CHECK(hi > lo);
            for (int i = 0; i < w * h; i++) {
                const float *c = rgb + 3 * i;
                if (src[i] == lo) CHECK(c[2] > c[0]); /* the minimum is blue */
                if (src[i] == hi) CHECK(c[0] > c[2]); /* the maximum is red */
            }
            /* The bar runs from blue (left) to red (right) under the picture. */
            int bar_y = h + 3;
            const float *left = rgb + 3 * (bar_y * w), *right = rgb + 3 * (bar_y * w + w - 1);
            CHECK(left[2] > left[0] && right[0] > right[2]);
        }
        pn_image_free(fc);
        fc = NULL;
        CHECK(pn_image_false_color(ctx, img, "no_such_layer", 0.0, 0.0, &fc) == PN_ERROR_INVALID_ARGUMENT);
        CHECK(pn_image_false_color(ctx, img, "normal", 0.0, 0.0, &fc) == PN_ERROR_INVALID_ARGUMENT); /* 3 channels */
        CHECK(fc == NULL);
    }
    pn_image_free(img);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* Sixteen narrow spot lights over a grey floor (a lighting designer's grid of downlights): each
 * floor point sees only the spots whose cones reach it, so the light BVH's descent from a cut
 * node often finds no light with importance at the point. Found at stop 15 on scenes/office: such
 * a sample had p_light 0 and weight 1/0, its 0 x inf a NaN that zeroed the whole pixel at output;
 * the default variant came out 45% dark there and 8% dark here (ratio 0.917 at this threshold),
 * 0 with --ias-cut-size 1. Now within 0.1% (the tolerance is 1.5%) with either cut; the
 * default cut is the cluster trees (docs/methods/ias.md), so the test names the BVH cut. */
static const char *spot_grid_scene(void) {
    static char text[4096];
    int n = snprintf(text, sizeof text,
                     "LookAt 0 -3 3  0 0 0  0 0 1\nCamera \"perspective\" \"float fov\" 60\n"
                     "Film \"rgb\" \"integer xresolution\" 48 \"integer yresolution\" 32\nWorldBegin\n");
    for (int x = -3; x <= 3; x += 2)
        for (int y = -3; y <= 3; y += 2)
            n += snprintf(text + n, sizeof text - (size_t)n,
                          "LightSource \"spot\" \"point3 from\" [%d %d 2] \"point3 to\" [%d %d 0] \"rgb I\" [10 10 10] "
                          "\"float coneangle\" 30 \"float conedeltaangle\" 10\n",
                          x, y, x, y);
    snprintf(text + n, sizeof text - (size_t)n,
             "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
             "Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-4 -4 0 4 -4 0 4 4 0 -4 4 0]\n");
    return text;
}

static void test_bvh_cut_unbiased_under_spot_grid(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx, "spots.pbrt", spot_grid_scene());
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_stats rs, is;
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_REFERENCE, 256, 0.0, &rs);
    static const char *const def[] = {"ias-cut", "bvh", NULL};
    pn_image img = render_ias_with(ctx, scene, def, &is);
    CHECK(ref && img);
    if (ref && img) {
        double relmse, ratio;
        compare(ref, img, 1.0, &relmse, &ratio);
        fprintf(stderr, "  16 spots: ias (BVH cut) mean luminance ratio %.4f, box relMSE %.3g\n", ratio, relmse);
        CHECK_MSG(fabs(ratio - 1.0) < 0.015, "mean luminance ratio %.4f", ratio);
    }
    pn_image_free(ref);
    pn_image_free(img);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_ias_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void test_teardown(void) {
    const char *written[] = {"many.pbrt", "hole.pbrt", "many_t.pbrt", "many_fc.pbrt", "spots.pbrt"};
    char path[600];
    for (size_t i = 0; i < sizeof written / sizeof written[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", tmpdir, written[i]);
        unlink(path);
    }
    CHECK(rmdir(tmpdir) == 0);
}

PN_TESTS(TEST(test_feedback_minimises_variance), TEST(test_blend_weights), TEST(test_inverse_variance),
         TEST(test_setup), TEST(test_ias_matches_reference), TEST(test_ias_block_sizes),
         TEST(test_black_detection_keeps_lit_pixels), TEST(test_ias_thread_determinism), TEST(test_ias_variants),
         TEST(test_false_color_aov), TEST(test_bvh_cut_unbiased_under_spot_grid), TEST(test_teardown))
