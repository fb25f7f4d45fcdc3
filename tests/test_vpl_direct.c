/* test_vpl_direct.c — the VPL integrators' direct-light-only setting (vpl_direct_only): the VPL
 * set is the lights themselves (exact omni VPLs for the point and spot lights, points on the area
 * light carrying exactly its power, directions of the environment map, no path VPLs); `vpl` in
 * that setting estimates the same quantity as `reference` (block means within the sampling error
 * of both, measured over seeds); `lightcuts` in that setting stays within its error bound of
 * `vpl` (per point: the guarantee |estimate - exact| <= the cut's bounds; per image: the mean
 * relative error below the bound); the setting's bad combinations are refused. */
#include "harness.h"
#include "render_fields.h"

#include "core/rng.h"
#include "integrators/illumcut.h"
#include "lights/light_tree.h"
#include "lights/vpl.h"
#include "penumbra/penumbra.h"
#include "scene/scene.h"
#include "shade/bsdf.h"
#include "vpl_scenes.h"

#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

/* A floor seen from straight above, a box standing on it (shadows), and four kinds of light: a
 * one-sided rectangle (0.6 x 0.6 at z = 1.6, radiance 6, facing down, outside the view), a point
 * light, a spot light and a dim uniform environment. */
#define AREA_L 6.0
#define AREA_SIDE 0.6
static const char *scene_text(int size) {
    static char text[4096];
    snprintf(
        text, sizeof text,
        "LookAt 0 0 3.2  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 60 ]\n"
        "Film \"rgb\" \"integer xresolution\" [ %d ] \"integer yresolution\" [ %d ]\nWorldBegin\n"
        "LightSource \"infinite\" \"rgb L\" [ 0.01 0.01 0.012 ]\n"
        "LightSource \"point\" \"point3 from\" [ -1.2 0.9 1.3 ] \"rgb I\" [ 1.5 1.4 1.2 ]\n"
        "LightSource \"spot\" \"point3 from\" [ 0.2 -1.0 2.0 ] \"point3 to\" [ 0.2 -1.0 0 ]\n"
        "    \"float coneangle\" [ 35 ] \"float conedeltaangle\" [ 10 ] \"rgb I\" [ 4 4 3.5 ]\n"
        "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ %g %g %g ]\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ 1.0 -0.3 1.6  1.0 0.3 1.6  1.6 0.3 1.6  1.6 -0.3 1.6 ]\n"
        "     \"integer indices\" [ 0 1 2  0 2 3 ]\nAttributeEnd\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -3 -3 0  3 -3 0  3 3 0  -3 3 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.4 0.3 ]\n"
        "AttributeBegin\n  Translate -0.3 0.2 0.25\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ -0.25 -0.25 -0.25  0.25 -0.25 -0.25  0.25 0.25 -0.25  -0.25 0.25 "
        "-0.25\n"
        "     -0.25 -0.25 0.25  0.25 -0.25 0.25  0.25 0.25 0.25  -0.25 0.25 0.25 ]\n"
        "     \"integer indices\" [ 4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  3 0 4  3 4 7 ]\n"
        "AttributeEnd\n",
        size, size, AREA_L, AREA_L, AREA_L);
    return text;
}

static pn_image render(pn_context ctx, pn_scene scene, pn_integrator_kind kind, uint64_t seed, uint32_t vpls,
                       uint32_t spp, float error, pn_render_stats *stats) {
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = kind;
    rs.seed = seed;
    rs.spp = spp;
    rs.threads = 2;
    rs.options = pn_options_new();
    if (kind == PN_INTEGRATOR_REFERENCE) {
        CHECK(pn_options_set_int(ctx, rs.options, "shadow-rays", 16) == PN_OK);
    } else {
        CHECK(pn_options_set_int(ctx, rs.options, "vpls", vpls) == PN_OK);
        CHECK(pn_options_set_int(ctx, rs.options, "vpl-direct-only", 1) == PN_OK);
        if (error > 0.0f) CHECK(pn_options_set_double(ctx, rs.options, "error", (double)error) == PN_OK);
    }
    pn_image img = NULL;
    pn_status st = pn_test_render(ctx, scene, &rs, &img, stats);
    pn_options_free(rs.options);
    CHECK_MSG(st == PN_OK, "render: %s", pn_context_error_message(ctx));
    return img;
}

static double pixel_lum(const float *px, int i) {
    return (double)v3_luminance(v3(px[3 * i], px[3 * i + 1], px[3 * i + 2]));
}

/* The direct-only VPL set: what it holds, and that the area light's VPLs carry its power. */
static void test_direct_vpl_set(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "set.pbrt", scene_text(8));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    const pn_lights *L = scene->lights;
    pn_vpl_settings vs = {3000, 0, 0.0f, 5};
    pn_vpl_trace_options vo = {true, NULL, NULL};
    pn_vpl_set a, b, c;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace_with(scene, L, scene->accel, &vs, &vo, &a, &err) == PN_OK);
    CHECK(pn_vpl_trace_with(scene, L, scene->accel, &vs, &vo, &b, &err) == PN_OK);
    vs.seed = 6;
    CHECK(pn_vpl_trace_with(scene, L, scene->accel, &vs, &vo, &c, &err) == PN_OK);
    /* The two exact lights, no more omni VPLs; the rest on the rectangle or from the sky. */
    CHECK(a.count_by_kind[PN_VPL_OMNI] == 2);
    CHECK(a.count_by_kind[PN_VPL_ORIENTED] > 500 && a.count_by_kind[PN_VPL_DIRECTIONAL] > 500);
    CHECK_MSG(a.count <= 3000 + 8 && a.count > 2500, "%u VPLs", a.count);
    CHECK(a.clamp_distance == 0.0f);
    double power = 0.0, cx = 0.0, cy = 0.0;
    uint32_t oriented = 0;
    for (uint32_t i = 0; i < a.count; i++) {
        const pn_vpl *v = &a.vpls[i];
        if (v->kind == PN_VPL_OMNI) {
            CHECK(v->light >= 0 &&
                  (L->lights[v->light].kind == PN_LIGHT_POINT || L->lights[v->light].kind == PN_LIGHT_SPOT));
        } else if (v->kind == PN_VPL_ORIENTED) {
            /* On the rectangle, facing down, with the rectangle's emission. */
            CHECK(fabsf(v->p.z - 1.6f) < 1e-4f && v->p.x >= 1.0f - 1e-4f && v->p.x <= 1.6f + 1e-4f &&
                  v->p.y >= -0.3f - 1e-4f && v->p.y <= 0.3f + 1e-4f);
            CHECK(v->n.z < -0.999f);
            power += (double)v->intensity.x;
            cx += (double)v->p.x;
            cy += (double)v->p.y;
            oriented++;
        } else {
            CHECK(fabsf(v3_length(v->p) - 1.0f) < 1e-4f);
        }
    }
    /* Intensities along the normal sum to L A (the power / pi) exactly, not just on average. */
    CHECK_NEAR(power, AREA_L * AREA_SIDE * AREA_SIDE, 1e-4 * AREA_L);
    /* Stratified: the centroid of the points is much closer to the centre than independent
     * points would put it (their standard error is 0.6 / sqrt(12 n), about 0.007 here). */
    CHECK_NEAR(cx / oriented, 1.3, 0.002);
    CHECK_NEAR(cy / oriented, 0.0, 0.002);
    /* The same set for a seed, another for another seed. */
    CHECK(a.count == b.count && memcmp(a.vpls, b.vpls, a.count * sizeof *a.vpls) == 0);
    CHECK(a.count != c.count || memcmp(a.vpls, c.vpls, a.count * sizeof *a.vpls) != 0);
    pn_vpl_set_free(&a);
    pn_vpl_set_free(&b);
    pn_vpl_set_free(&c);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* vpl (direct only) against reference. Both are unbiased estimates of the same image, so for
 * every 8x8 block (and the whole image) the difference of the means over seeds, d = mean(vpl) -
 * mean(reference), has mean 0 and standard error se = sqrt(s_v^2 / K + s_r^2 / J), with s_v, s_r
 * the sample standard deviations of the block mean over K vpl seeds and J reference seeds (the
 * VPL set, the eye samples and the reference's shadow rays all change with the seed). The test
 * asks |d| <= 5 se for all 17 comparisons (a false alarm below ~1e-3 each for a t statistic with
 * ~10 degrees of freedom), and that 5 se is below 3% of the block's value: the comparison can see
 * a 3% bias. */
static void test_vpl_matches_reference(void) {
    enum { SIZE = 32, B = 8, NB = (SIZE / B) * (SIZE / B) + 1, K = 8, J = 3 };
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "floor.pbrt", scene_text(SIZE));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    double v[K][NB], r[J][NB];
    bool ok = true;
    for (int k = 0; k < K + J && ok; k++) {
        bool is_ref = k >= K;
        pn_render_stats stats;
        pn_image img = is_ref ? render(ctx, scene, PN_INTEGRATOR_REFERENCE, 100 + (uint64_t)k, 0, 16, 0.0f, &stats)
                              : render(ctx, scene, PN_INTEGRATOR_VPL, 1 + (uint64_t)k, 1000, 4, 0.0f, &stats);
        if (!img) {
            ok = false;
            break;
        }
        if (!is_ref) CHECK(stats.vpl_count > 900 && stats.vpl_count <= 1008);
        const float *px = pn_image_layer_data(img, 0);
        double *out = is_ref ? r[k - K] : v[k];
        for (int b = 0; b < NB; b++) out[b] = 0.0;
        for (int y = 0; y < SIZE; y++)
            for (int x = 0; x < SIZE; x++) {
                double l = pixel_lum(px, y * SIZE + x);
                out[(y / B) * (SIZE / B) + x / B] += l / (B * B);
                out[NB - 1] += l / (SIZE * SIZE);
            }
        pn_image_free(img);
    }
    if (ok) {
        double worst_z = 0.0, worst_rel_bound = 0.0;
        for (int b = 0; b < NB; b++) {
            double mv = 0.0, mr = 0.0, sv = 0.0, sr = 0.0;
            for (int k = 0; k < K; k++) mv += v[k][b] / K;
            for (int j = 0; j < J; j++) mr += r[j][b] / J;
            for (int k = 0; k < K; k++) sv += (v[k][b] - mv) * (v[k][b] - mv) / (K - 1);
            for (int j = 0; j < J; j++) sr += (r[j][b] - mr) * (r[j][b] - mr) / (J - 1);
            double se = sqrt(sv / K + sr / J), d = mv - mr;
            CHECK_MSG(fabs(d) <= 5.0 * se, "block %d: vpl %g reference %g, difference %g > 5 x %g", b, mv, mr, d, se);
            CHECK_MSG(5.0 * se <= 0.03 * mr, "block %d: the bound 5 x %g is above 3%% of %g", b, se, mr);
            if (se > 0.0 && fabs(d) / se > worst_z) worst_z = fabs(d) / se;
            if (5.0 * se / mr > worst_rel_bound) worst_rel_bound = 5.0 * se / mr;
        }
        fprintf(stderr, "  vpl - reference: largest |d| / se %.2f, largest bound 5 se / value %.4f\n", worst_z,
                worst_rel_bound);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* lightcuts on the direct-only VPLs: per point, the guarantee against the exact sum over the VPL
 * set (with visibility); per image, against vpl with the same seed (so the same VPLs and the same
 * shading points): the mean relative error is below the 1% bound and no pixel is off by 5%. */
static void test_lightcuts_within_bound_of_vpl(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "floor_lc.pbrt", scene_text(24));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    const pn_lights *L = scene->lights;
    pn_vpl_settings vs = {3000, 0, 0.0f, 9};
    pn_vpl_trace_options vo = {true, NULL, NULL};
    pn_vpl_set set;
    pn_light_tree tree;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace_with(scene, L, scene->accel, &vs, &vo, &set, &err) == PN_OK);
    CHECK(pn_light_tree_build(&set, 2.0f * L->scene_radius, 9, &tree, &err) == PN_OK);
    pn_rng rng;
    pn_rng_seed(&rng, 31, 2);
    int n = 0;
    for (int t = 0; t < 200; t++) {
        /* Points on the floor and on the box, seen from above. */
        vec3 o = v3(-1.8f + 3.6f * pn_rng_float(&rng), -1.8f + 3.6f * pn_rng_float(&rng), 3.0f);
        vec3 d = v3(0, 0, -1);
        pn_hit hit;
        if (!pn_accel_intersect(scene->accel, o, d, 0.0f, INFINITY, &hit)) continue;
        pn_bsdf b;
        pn_bsdf_at(scene, &hit, v3_neg(d), &b);
        if (b.kind != PN_MATERIAL_LAMBERT_BLINN) continue;
        pn_vpl_receiver rc = pn_vpl_receiver_rgb(hit.p, b.ng, b.ns, v3_neg(d), b.kd, b.ks, b.exponent);
        vec3 exact = v3(0, 0, 0);
        for (uint32_t k = 0; k < set.count; k++) {
            vec3 wi;
            float dist;
            vec3 c = pn_vpl_contribution(L, &set.vpls[k], &rc, set.min_dist2, &wi, &dist);
            if (!v3_is_zero(c) && pn_vpl_visible(scene->accel, &rc, wi, dist)) exact = v3_add(exact, c);
        }
        pn_lightcut_context cx = {L, scene->accel, &set, &tree, 0.01f, 0, false};
        vec3 est;
        float bound_sum;
        uint32_t cut, rays;
        CHECK(pn_lightcut_eval(&cx, &rc, &est, &bound_sum, &cut, &rays));
        double e = (double)v3_luminance(exact), a = (double)v3_luminance(est);
        CHECK_MSG(fabs(a - e) <= (double)bound_sum * 1.001 + 1e-6 * e + 1e-9, "point %d: |%g - %g| > %g", t, a, e,
                  (double)bound_sum);
        CHECK((double)bound_sum <= 0.01 * a * (double)cut * 1.001 + 1e-9);
        CHECK(isfinite(a));
        n++;
    }
    CHECK(n > 150);
    pn_light_tree_free(&tree);
    pn_vpl_set_free(&set);

    pn_render_stats s_v, s_lc;
    pn_image vpl = render(ctx, scene, PN_INTEGRATOR_VPL, 4, 3000, 1, 0.0f, &s_v);
    pn_image lc = render(ctx, scene, PN_INTEGRATOR_LIGHTCUTS, 4, 3000, 1, 0.01f, &s_lc);
    if (vpl && lc) {
        const float *pv = pn_image_layer_data(vpl, 0), *pl = pn_image_layer_data(lc, 0);
        double sum = 0.0, mx = 0.0;
        int m = 0;
        for (int i = 0; i < 24 * 24; i++) {
            double lv = pixel_lum(pv, i), ll = pixel_lum(pl, i);
            if (!(lv > 0.0)) continue;
            double rel = fabs(ll - lv) / lv;
            sum += rel;
            if (rel > mx) mx = rel;
            m++;
        }
        CHECK(m == 24 * 24);
        CHECK_MSG(sum / m < 0.01 && mx < 0.05, "mean %g max %g", sum / m, mx);
        /* And lightcuts did cut: fewer shadow rays than one per VPL. */
        CHECK(s_lc.shadow_rays_per_pixel_mean < 0.5 * s_v.shadow_rays_per_pixel_mean);
        CHECK(s_lc.vpl_count == s_v.vpl_count);
    }
    pn_image_free(vpl);
    pn_image_free(lc);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A light path depth with direct light only is refused, by the library and by the CLI (exit 2). */
static void test_bad_combinations(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "bad.pbrt", scene_text(8));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = PN_INTEGRATOR_VPL;
    rs.options = pn_options_new();
    CHECK(pn_options_set_int(ctx, rs.options, "vpls", 100) == PN_OK);
    CHECK(pn_options_set_int(ctx, rs.options, "vpl-direct-only", 1) == PN_OK);
    CHECK(pn_options_set_int(ctx, rs.options, "vpl-depth", 2) == PN_OK);
    pn_image img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_ERROR_INVALID_ARGUMENT);
    pn_options_free(rs.options);
    CHECK(img == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "depth");
    pn_scene_free(scene);
    pn_context_free(ctx);
    char cmd[1024];
    snprintf(cmd, sizeof cmd,
             "'%s' render '%s/bad.pbrt' --integrator vpl --vpl-direct-only --vpl-depth 2 -o '%s/bad.exr' "
             ">'%s/bad.out' 2>&1",
             PN_CLI_PATH, tmpdir, tmpdir, tmpdir);
    int status = system(cmd);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 2);
    snprintf(cmd, sizeof cmd, "%s/bad.exr", tmpdir);
    CHECK(access(cmd, F_OK) != 0);
}

static void setup(void) {
    vpl_test_setup("vpl_direct");
}

static void teardown(void) {
    vpl_test_teardown();
}

PN_TESTS(TEST(setup), TEST(test_direct_vpl_set), TEST(test_vpl_matches_reference),
         TEST(test_lightcuts_within_bound_of_vpl), TEST(test_bad_combinations), TEST(teardown))
