/* test_ias_ratio.c — the ratio estimator of the default ias variant (ias_ratio.h, issue 15):
 *  - the closed forms: a rectangle's and a sphere's unoccluded irradiance against a Monte Carlo
 *    estimate with the light's own sampler (within 4 standard errors); no closed form for a disk
 *    or a sphere across the horizon;
 *  - the pass estimate: with every sample visible the pixel ratio gives the closed form exactly
 *    and no variance; the control variate with beta 0 is the plain estimate;
 *  - renders of one quad light over a plane with a partial occluder, at fixed passes (the same
 *    shadow rays for every mode), against a 1024-spp reference: each mode's mean over four seeds
 *    within 0.5% of the reference, and on the pixels the occluder does not shadow (where the
 *    reference of the scene without it agrees) a relMSE well below the plain estimator's. */
#include "harness.h"
#include "ias_modes.h"
#include "render_fields.h"

#include "core/rng.h"
#include "integrators/ias_ratio.h"
#include "penumbra/penumbra.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* E[L cos / pdf] over the light's own samples at p (normal n), and its standard error. */
static double mc_irradiance(const pn_lights *L, const pn_light *l, vec3 p, vec3 n, double *se) {
    const int count = 200000;
    double s = 0.0, s2 = 0.0;
    pn_rng rng;
    pn_rng_seed(&rng, 5, 7);
    for (int i = 0; i < count; i++) {
        pn_light_sample ls;
        double y = 0.0;
        if (pn_light_sample_point(L, l, p, pn_rng_float(&rng), pn_rng_float(&rng), &ls) && ls.pdf > 0.0f) {
            float c = v3_dot(n, ls.wi);
            if (c > 0.0f) y = (double)v3_luminance(ls.radiance) * (double)c / (double)ls.pdf;
        }
        s += y;
        s2 += y * y;
    }
    double m = s / count;
    *se = sqrt(fmax(0.0, s2 / count - m * m) / count);
    return m;
}

static void test_closed_forms(void) {
    pn_light l[3];
    memset(l, 0, sizeof l);
    for (int i = 0; i < 3; i++) l[i].env = l[i].mesh = l[i].prim = -1;
    l[0].kind = PN_LIGHT_RECTANGLE;
    l[0].p = v3(-0.3f, -0.2f, 1.0f);
    l[0].e1 = v3(0.6f, 0.0f, 0.0f);
    l[0].e2 = v3(0.0f, 0.4f, 0.0f);
    l[0].n = v3(0.0f, 0.0f, -1.0f);
    l[0].area = 0.24f;
    l[0].emit = v3(3.0f, 2.0f, 1.0f);
    l[1].kind = PN_LIGHT_SPHERE;
    l[1].p = v3(0.5f, 0.2f, 1.2f);
    l[1].radius = 0.3f;
    l[1].area = 4.0f * PN_PI * 0.09f;
    l[1].emit = v3(1.0f, 1.0f, 2.0f);
    l[2].kind = PN_LIGHT_DISK;
    l[2].p = v3(0.0f, 0.0f, 1.0f);
    l[2].radius = 0.2f;
    l[2].n = v3(0.0f, 0.0f, -1.0f);
    l[2].area = PN_PI * 0.04f;
    l[2].emit = v3(1.0f, 1.0f, 1.0f);
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = l;
    L.count = 3;
    L.scene_radius = 10.0f;
    const vec3 pts[] = {v3(0, 0, 0), v3(0.8f, -0.4f, 0.1f), v3(-0.5f, 0.6f, 0.3f)};
    const vec3 nrm[] = {v3(0, 0, 1), v3(0.3f, 0.1f, 0.95f), v3(-0.2f, 0.0f, 0.98f)};
    for (int k = 0; k < 3; k++) {
        vec3 n = v3_normalize(nrm[k]);
        for (int i = 0; i < 2; i++) {
            vec3 e;
            CHECK(pn_ias_light_unshadowed(&L, &l[i], pts[k], n, &e));
            double se, mc = mc_irradiance(&L, &l[i], pts[k], n, &se);
            double y = (double)v3_luminance(e);
            CHECK_MSG(fabs(y - mc) < 4.0 * se + 1e-6 * mc,
                      "light %d point %d: closed form %.6g, Monte Carlo %.6g +- %.2g", i, k, y, mc, se);
            /* The colour is the emission's. */
            CHECK_NEAR((double)e.x / y, (double)(l[i].emit.x / v3_luminance(l[i].emit)), 1e-4);
        }
    }
    vec3 e;
    CHECK(!pn_ias_light_unshadowed(&L, &l[2], pts[0], v3(0, 0, 1), &e));
    /* The sphere across the horizon of a tilted receiver, and around the point. */
    CHECK(!pn_ias_light_unshadowed(&L, &l[1], v3(0.5f, 0.2f, 1.0f), v3(1, 0, 0), &e));
    CHECK(!pn_ias_light_unshadowed(&L, &l[1], v3(0.5f, 0.2f, 1.1f), v3(0, 0, 1), &e));
}

static void test_pass(void) {
    /* Two regions of weights 0.6 and 0.4, cut entries 0-1 and 2-3; entry 3 has no closed form. */
    pn_ias_ratio_region reg[2] = {{0.6, 0, 2, v3(0.1f, 0.1f, 0.1f)}, {0.4, 2, 2, v3(0.2f, 0.2f, 0.2f)}};
    const int ids[4] = {0, 1, 0, 2};
    const vec3 U[4] = {v3(1, 1, 1), v3(2, 2, 2), v3(1.5f, 1.5f, 1.5f), v3(-1, -1, -1)};
    const double beta0[4] = {0, 0, 0, 0};
    /* Visible samples of noisy values (v = u), and one of entry 3 (passed as -1). */
    pn_ias_ratio_sample smp[] = {
        {0, 0, v3(0.05f, 0.05f, 0.05f), v3(0.05f, 0.05f, 0.05f)},
        {0, 1, v3(0.9f, 0.9f, 0.9f), v3(0.9f, 0.9f, 0.9f)},
        {0, 1, v3(0.1f, 0.1f, 0.1f), v3(0.1f, 0.1f, 0.1f)},
        {1, 2, v3(0.7f, 0.7f, 0.7f), v3(0.7f, 0.7f, 0.7f)},
        {1, -1, v3(0.4f, 0.4f, 0.4f), v3(0, 0, 0)}, /* entry 3: no closed form */
    };
    pn_ias_ratio_scratch sc;
    CHECK(pn_ias_ratio_scratch_init(&sc, 3, 2));
    double lum, s2;
    vec3 rgb;
    unsigned n;
    pn_ias_ratio_pass(PN_IAS_RATIO_PIXEL, smp, 5, reg, 2, ids, U, NULL, &sc, &lum, &rgb, &s2, &n);
    /* 0.6 (0.1 + 0.2) + 0.4 (0.3) + 0.4 (0.4 / 2) for entry 3's plain estimate. */
    CHECK_NEAR(lum, 0.6 * 0.3 + 0.4 * 0.3 + 0.4 * 0.2, 1e-6);
    CHECK(n == 5);
    /* Only region 1 varies: its residuals are 0 (the sample in A) and 0.4 (entry 3's). */
    CHECK_NEAR(s2, 0.4 * 0.4 * (0.08) / 2.0, 1e-6);
    pn_ias_ratio_pass(PN_IAS_RATIO_CLUSTER, smp, 5, reg, 2, ids, U, NULL, &sc, &lum, &rgb, &s2, &n);
    CHECK_NEAR(lum, 0.6 * 0.3 + 0.4 * 0.3 + 0.4 * 0.2, 1e-6);
    /* beta 0: the plain estimate, sum_k W_k mean_k(v). */
    pn_ias_ratio_pass(PN_IAS_RATIO_CONTROL, smp, 5, reg, 2, ids, U, beta0, &sc, &lum, &rgb, &s2, &n);
    CHECK_NEAR(lum, 0.6 * (1.05 / 3.0) + 0.4 * (1.1 / 2.0), 1e-6);
    pn_ias_ratio_scratch_free(&sc);
}

static char tmpdir[256];

/* Two quad lights (1 x 1 m at 1.5 m, 0.3 x 0.3 m at 1 m, of different colours) over a plane seen
 * at an angle; with `occluder`, a plate at 0.5 m that shadows part of the left of the image. */
static const char *scene_text(bool occluder) {
    static char text[4096];
    snprintf(
        text, sizeof text,
        "LookAt 0 3 3  0 0 0  0 1 0\n"
        "Camera \"perspective\" \"float fov\" [ 50 ]\n"
        "Film \"rgb\" \"integer xresolution\" [ 40 ] \"integer yresolution\" [ 40 ]\n"
        "WorldBegin\n"
        "AttributeBegin\n"
        "  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
        "  Shape \"bilinearmesh\" \"point3 P\" [ -0.5 1.5 -0.5  0.5 1.5 -0.5  -0.5 1.5 0.5  0.5 1.5 0.5 ]\n"
        "AttributeEnd\n"
        "AttributeBegin\n"
        "  AreaLightSource \"diffuse\" \"rgb L\" [ 2 1 1 ]\n"
        "  Shape \"bilinearmesh\" \"point3 P\" [ 1 1 -0.5  1.3 1 -0.5  1 1 -0.2  1.3 1 -0.2 ]\n"
        "AttributeEnd\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -3 0 -3  3 0 -3  3 0 3  -3 0 3 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "%s",
        occluder ? "Shape \"trianglemesh\" \"point3 P\" [ -1.6 0.5 -0.4  -0.6 0.5 -0.4  -0.6 0.5 0.4  -1.6 0.5 0.4 ]\n"
                   "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
                 : "");
    return text;
}

static pn_image render(pn_context ctx, pn_scene scene, pn_integrator_kind kind, uint32_t spp, const char *mode,
                       uint64_t seed) {
    /* No pixel stops before its two passes: the same shadow rays for every mode. */
    const char *const opts[] = {"ias-ratio", mode, "max-passes", "2", "ias-aa-threshold", "0", NULL};
    return pn_test_render_modes(ctx, scene, kind, spp, seed, 1, mode ? opts : NULL);
}

static pn_scene load(pn_context ctx, const char *name, bool occluder) {
    const char *path = pn_test_write_file(tmpdir, name, scene_text(occluder));
    pn_scene scene = NULL;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    return scene;
}

static void test_renders(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load(ctx, "ratio.pbrt", true), open_scene = load(ctx, "open.pbrt", false);
    pn_image ref = scene ? render(ctx, scene, PN_INTEGRATOR_REFERENCE, 1024, NULL, 11) : NULL;
    pn_image free_ref = open_scene ? render(ctx, open_scene, PN_INTEGRATOR_REFERENCE, 256, NULL, 12) : NULL;
    CHECK(ref && free_ref);
    if (ref && free_ref) {
        const int np = pn_image_width(ref) * pn_image_height(ref);
        const float *r = pn_image_layer_data(ref, 0), *f = pn_image_layer_data(free_ref, 0);
        /* Unoccluded: where the scene without the plate agrees within 1%; shadowed: below 90%. */
        unsigned char *open = calloc((size_t)np, 1);
        int n_open = 0, n_shadow = 0;
        double ref_sum = 0.0;
        for (int i = 0; i < np; i++) {
            double a = pn_test_lum_at(r, i), b = pn_test_lum_at(f, i);
            open[i] = fabs(a - b) < 0.01 * b;
            n_open += open[i];
            n_shadow += a < 0.9 * b;
            ref_sum += a;
        }
        CHECK(n_open > np / 4 && n_shadow > np / 20);
        static const char *const modes[] = {"off", "pixel", "cluster", "control"};
        double err[4] = {0}, mean[4] = {0}, mean2[4] = {0};
        const int seeds = 4;
        for (int m = 0; m < 4; m++)
            for (int k = 0; k < seeds; k++) {
                pn_image img = render(ctx, scene, PN_INTEGRATOR_IAS, 0, modes[m], (uint64_t)k);
                CHECK(img != NULL);
                if (!img) continue;
                const float *b = pn_image_layer_data(img, 0);
                double e = 0.0, s = 0.0;
                for (int i = 0; i < np; i++) {
                    double ya = pn_test_lum_at(r, i), yb = pn_test_lum_at(b, i);
                    s += yb;
                    if (open[i]) e += (yb - ya) * (yb - ya) / (ya * ya + 0.01);
                }
                err[m] += e / n_open / seeds;
                mean[m] += s / ref_sum / seeds;
                mean2[m] += (s / ref_sum) * (s / ref_sum) / seeds;
                pn_image_free(img);
            }
        for (int m = 0; m < 4; m++) {
            double sd = sqrt(fmax(0.0, mean2[m] - mean[m] * mean[m]) * seeds / (seeds - 1.0) / seeds);
            fprintf(stderr, "  %-8s relMSE on the unoccluded pixels %.3g; mean over the reference's %.5f +- %.5f\n",
                    modes[m], err[m], mean[m], sd);
            CHECK_MSG(fabs(mean[m] - 1.0) < 0.005, "%s: mean %.5f of the reference", modes[m], mean[m]);
        }
        /* At the same shadow rays the closed form leaves the unoccluded pixels only the region
         * error and the reference's own noise (measured: plain 1.15e-5, the ratios 3.7e-6). */
        for (int m = 1; m < 4; m++)
            CHECK_MSG(err[m] < 0.4 * err[0], "%s: relMSE %.3g on the unoccluded pixels, plain %.3g", modes[m], err[m],
                      err[0]);
        free(open);
    }
    pn_image_free(ref);
    pn_image_free(free_ref);
    pn_scene_free(scene);
    pn_scene_free(open_scene);
    pn_context_free(ctx);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_ias_ratio_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void test_teardown(void) {
    char path[600];
    snprintf(path, sizeof path, "%s/ratio.pbrt", tmpdir);
    unlink(path);
    snprintf(path, sizeof path, "%s/open.pbrt", tmpdir);
    unlink(path);
    CHECK(rmdir(tmpdir) == 0);
}

PN_TESTS(TEST(test_closed_forms), TEST(test_pass), TEST(test_setup), TEST(test_renders), TEST(test_teardown))
