/* test_light_bvh.c — pbrt-v4's light BVH (lights/light_bvh.c) as the reference integrator's
 * second light sampler: the tree holds every bounded light once with consistent bounds; the
 * probability a descent reports is the one pn_light_bvh_pmf recomputes, the choices follow it
 * (binomial bounds on counts), and the probabilities sum to at most one; a light that gives a
 * point any irradiance always has a non-zero probability there (so the estimator is unbiased);
 * and a render with `--light-sampler bvh` agrees with the default sampler within noise. */
#include "harness.h"

#include "core/rng.h"
#include "lights/light_bvh.h"
#include "penumbra/penumbra.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define N_LIGHTS 60

static float rnd(pn_rng *r, float lo, float hi) {
    return lo + (hi - lo) * pn_rng_float(r);
}

static vec3 rnd_unit(pn_rng *r) {
    for (;;) {
        vec3 v = v3(rnd(r, -1, 1), rnd(r, -1, 1), rnd(r, -1, 1));
        float l2 = v3_length2(v);
        if (l2 > 1e-3f && l2 <= 1.0f) return v3_scale(v, 1.0f / sqrtf(l2));
    }
}

/* A mix of every bounded kind scattered in a 20 m box, plus one distant light. */
static void make_lights(pn_lights *L, pn_light *l, pn_rng *r) {
    memset(L, 0, sizeof *L);
    memset(l, 0, (N_LIGHTS + 1) * sizeof *l);
    for (int i = 0; i < N_LIGHTS; i++) {
        pn_light *x = &l[i];
        x->env = -1;
        x->mesh = x->prim = -1;
        x->p = v3(rnd(r, -10, 10), rnd(r, -10, 10), rnd(r, -10, 10));
        x->emit = v3(rnd(r, 0.1f, 3), rnd(r, 0.1f, 3), rnd(r, 0.1f, 3));
        vec3 t, b;
        switch (i % 6) {
        case 0: x->kind = PN_LIGHT_POINT; break;
        case 1:
            x->kind = PN_LIGHT_SPOT;
            x->n = rnd_unit(r);
            x->cos_total_width = cosf(rnd(r, 0.3f, 1.2f));
            x->cos_falloff_start = cosf(acosf(x->cos_total_width) * 0.6f);
            break;
        case 2:
            x->kind = PN_LIGHT_TRIANGLE;
            x->e1 = v3(rnd(r, -1, 1), rnd(r, -1, 1), rnd(r, -1, 1));
            x->e2 = v3(rnd(r, -1, 1), rnd(r, -1, 1), rnd(r, -1, 1));
            x->n = v3_normalize(v3_cross(x->e1, x->e2));
            x->area = 0.5f * v3_length(v3_cross(x->e1, x->e2));
            x->two_sided = i % 12 == 2;
            break;
        case 3:
            x->kind = PN_LIGHT_RECTANGLE;
            x->n = rnd_unit(r);
            v3_basis(x->n, &t, &b);
            x->e1 = v3_scale(t, rnd(r, 0.2f, 2));
            x->e2 = v3_scale(b, rnd(r, 0.2f, 2));
            x->area = v3_length(x->e1) * v3_length(x->e2);
            break;
        case 4:
            x->kind = PN_LIGHT_DISK;
            x->n = rnd_unit(r);
            x->radius = rnd(r, 0.1f, 1);
            x->area = PN_PI * x->radius * x->radius;
            break;
        default:
            x->kind = PN_LIGHT_SPHERE;
            x->radius = rnd(r, 0.1f, 0.8f);
            x->area = 4.0f * PN_PI * x->radius * x->radius;
            break;
        }
    }
    pn_light *d = &l[N_LIGHTS];
    d->kind = PN_LIGHT_DISTANT;
    d->n = v3_normalize(v3(0.3f, 1, 0.2f));
    d->emit = v3(1, 1, 1);
    d->env = d->mesh = d->prim = -1;
    L->lights = l;
    L->count = N_LIGHTS + 1;
    L->scene_radius = 20.0f;
}

/* The lights of make_lights from a seeded stream (left for the test to go on with), and their
 * tree. */
static bool build_case(uint64_t seed, pn_rng *r, pn_lights *L, pn_light *l, pn_light_bvh *t) {
    pn_rng_seed(r, seed, 1);
    make_lights(L, l, r);
    pn_err err;
    pn_err_init(&err);
    return pn_light_bvh_build(L, t, &err) == PN_OK;
}

static bool box_holds(vec3 lo, vec3 hi, vec3 a_lo, vec3 a_hi) {
    return lo.x <= a_lo.x && lo.y <= a_lo.y && lo.z <= a_lo.z && hi.x >= a_hi.x && hi.y >= a_hi.y && hi.z >= a_hi.z;
}

static void test_structure(void) {
    pn_rng r;
    pn_light l[N_LIGHTS + 1];
    pn_lights L;
    pn_light_bvh t;
    CHECK(build_case(11, &r, &L, l, &t));
    CHECK(t.infinite_count == 1 && t.infinite[0] == N_LIGHTS);
    CHECK(t.node_count == 2 * N_LIGHTS - 1);
    int leaves = 0;
    for (int i = 0; i < t.node_count; i++) {
        const pn_light_bvh_node *nd = &t.nodes[i];
        if (nd->leaf) {
            leaves++;
            CHECK(t.node_of_light[nd->second] == i);
            continue;
        }
        const pn_light_bvh_node *a = &t.nodes[i + 1], *b = &t.nodes[nd->second];
        CHECK(a->parent == i && b->parent == i);
        CHECK(box_holds(nd->b.bmin, nd->b.bmax, a->b.bmin, a->b.bmax));
        CHECK(box_holds(nd->b.bmin, nd->b.bmax, b->b.bmin, b->b.bmax));
        CHECK_NEAR(nd->b.phi, a->b.phi + b->b.phi, 1e-4 * (double)nd->b.phi);
    }
    /* Every node's cone holds the cone of each light below it (not necessarily its children's:
     * cone unions over-approximate, differently in different orders). */
    for (int i = 0; i < t.node_count; i++) {
        const pn_light_bvh_node *leaf = &t.nodes[i];
        if (!leaf->leaf) continue;
        float tc = acosf(fmaxf(-1.0f, fminf(1.0f, leaf->b.cos_o)));
        for (int a = leaf->parent; a >= 0; a = t.nodes[a].parent) {
            const pn_light_bvh_node *nd = &t.nodes[a];
            CHECK(box_holds(nd->b.bmin, nd->b.bmax, leaf->b.bmin, leaf->b.bmax));
            CHECK(nd->b.cos_e <= leaf->b.cos_e);
            if (nd->b.cos_o <= -1.0f) continue;
            float to = acosf(fminf(1.0f, nd->b.cos_o));
            float td = acosf(fmaxf(-1.0f, fminf(1.0f, v3_dot(nd->b.w, leaf->b.w))));
            CHECK_MSG(td + tc <= to + 2e-3f, "node %d: the cone of light %d is outside (%g + %g > %g)", a, leaf->second,
                      (double)td, (double)tc, (double)to);
        }
    }
    CHECK(leaves == N_LIGHTS);
    pn_light_bvh_free(&t);
}

static void test_sampling_matches_pmf(void) {
    pn_rng r;
    pn_light l[N_LIGHTS + 1];
    pn_lights L;
    pn_light_bvh t;
    CHECK(build_case(12, &r, &L, l, &t));
    enum { DRAWS = 40000 };
    for (int trial = 0; trial < 6; trial++) {
        vec3 p = v3(rnd(&r, -12, 12), rnd(&r, -12, 12), rnd(&r, -12, 12));
        vec3 n = trial == 5 ? v3(0, 0, 0) : rnd_unit(&r);
        double pmf[N_LIGHTS + 1], total = 0.0;
        for (int i = 0; i <= N_LIGHTS; i++) total += pmf[i] = (double)pn_light_bvh_pmf(&t, p, n, i);
        CHECK_MSG(total <= 1.0 + 1e-4 && total > 0.5, "sum of probabilities %g", total);
        int count[N_LIGHTS + 1] = {0};
        int mismatched = 0;
        for (int k = 0; k < DRAWS; k++) {
            float prob;
            float u = ((float)k + pn_rng_float(&r)) / (float)DRAWS;
            int li = pn_light_bvh_sample(&t, p, n, u, &prob);
            if (li < 0) continue;
            count[li]++;
            if (fabs((double)prob - pmf[li]) > 1e-4 * pmf[li] + 1e-9) mismatched++;
        }
        CHECK_MSG(mismatched == 0, "%d draws reported a probability other than pn_light_bvh_pmf's", mismatched);
        /* Stratified draws: each count is within a few standard deviations of DRAWS * pmf. */
        for (int i = 0; i <= N_LIGHTS; i++) {
            double want = (double)DRAWS * pmf[i];
            double sd = sqrt(want * (1.0 - pmf[i])) + 1.0;
            CHECK_MSG(fabs((double)count[i] - want) <= 5.0 * sd, "light %d: %d draws, expected %.1f", i, count[i],
                      want);
        }
    }
    pn_light_bvh_free(&t);
}

/* A light that can light the point must be choosable there. */
static void test_support(void) {
    pn_rng r;
    pn_light l[N_LIGHTS + 1];
    pn_lights L;
    pn_light_bvh t;
    CHECK(build_case(13, &r, &L, l, &t));
    int lit = 0, missed = 0;
    for (int trial = 0; trial < 400; trial++) {
        vec3 p = v3(rnd(&r, -12, 12), rnd(&r, -12, 12), rnd(&r, -12, 12));
        vec3 n = rnd_unit(&r);
        for (int i = 0; i <= N_LIGHTS; i++) {
            if (!(pn_light_irradiance_estimate(&L, &l[i], p, n) > 0.0f)) continue;
            lit++;
            if (!(pn_light_bvh_pmf(&t, p, n, i) > 0.0f)) missed++;
        }
    }
    CHECK(lit > 1000);
    CHECK_MSG(missed == 0, "%d of %d (point, light) pairs with irradiance had probability 0", missed, lit);
    pn_light_bvh_free(&t);
}

/* Several kinds of lights over a floor and a box: both samplers estimate the same image. */
static const char *scene_text =
    "LookAt 0 -6 4  0 0 0.5  0 0 1\n"
    "Camera \"perspective\" \"float fov\" 50\n"
    "Film \"rgb\" \"integer xresolution\" 24 \"integer yresolution\" 24 \"string filename\" \"x.exr\"\n"
    "WorldBegin\n"
    "Material \"diffuse\" \"rgb reflectance\" [0.6 0.6 0.6]\n"
    "Shape \"trianglemesh\" \"point3 P\" [-5 -5 0 5 -5 0 5 5 0 -5 5 0] \"integer indices\" [0 1 2 0 2 3]\n"
    "Shape \"trianglemesh\" \"point3 P\" [-0.5 -0.5 1 0.5 -0.5 1 0.5 0.5 1 -0.5 0.5 1] \"integer indices\" [0 1 2 0 2 "
    "3]\n"
    "LightSource \"point\" \"point3 from\" [2 -1 2] \"rgb I\" [3 3 3]\n"
    "LightSource \"point\" \"point3 from\" [-2 1 1.5] \"rgb I\" [1 2 1]\n"
    "LightSource \"spot\" \"point3 from\" [0 -3 3] \"point3 to\" [0 0 0] \"float coneangle\" 40 \"rgb I\" [6 6 6]\n"
    "AttributeBegin\n"
    "AreaLightSource \"diffuse\" \"rgb L\" [4 4 4]\n"
    "Shape \"trianglemesh\" \"point3 P\" [-0.4 -0.4 3 -0.4 0.4 3 0.4 0.4 3 0.4 -0.4 3] \"integer indices\" [0 1 2 0 2 "
    "3]\n"
    "AttributeEnd\n"
    "AttributeBegin\n"
    "AreaLightSource \"diffuse\" \"rgb L\" [2 1 1]\n"
    "Translate 2 2 1\n"
    "Shape \"sphere\" \"float radius\" 0.3\n"
    "AttributeEnd\n";

static double mean_luminance(pn_image img) {
    const float *px = pn_image_layer_data(img, 0);
    size_t n = (size_t)pn_image_width(img) * (size_t)pn_image_height(img);
    double sum = 0.0;
    for (size_t i = 0; i < n; i++)
        sum += 0.2126 * (double)px[3 * i] + 0.7152 * (double)px[3 * i + 1] + 0.0722 * (double)px[3 * i + 2];
    return sum / (double)n;
}

static void test_render_agrees(void) {
    char dir[] = "/tmp/pn_light_bvh_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    const char *path = pn_test_write_file(dir, "scene.pbrt", scene_text);
    pn_context ctx = pn_context_new();
    pn_scene scene = NULL;
    CHECK(pn_scene_load(ctx, path, &scene) == PN_OK);
    if (!scene) {
        fprintf(stderr, "%s\n", pn_context_error_message(ctx));
        pn_context_free(ctx);
        return;
    }
    double mean[2];
    for (int k = 0; k < 2; k++) {
        pn_render_settings s;
        memset(&s, 0, sizeof s);
        s.spp = 64;
        pn_options o = pn_options_new();
        s.options = o;
        CHECK(pn_options_set_int(ctx, o, "shadow-rays", 4) == PN_OK);
        CHECK(pn_options_set(ctx, o, "light-sampler", k ? "bvh" : "irradiance") == PN_OK);
        pn_image img = NULL;
        CHECK(pn_render(ctx, scene, &s, &img, NULL) == PN_OK);
        pn_options_free(o);
        mean[k] = img ? mean_luminance(img) : 0.0;
        pn_image_free(img);
    }
    /* 576 pixels x 256 shadow rays each: the image means agree to well under 1.5%. */
    CHECK_MSG(mean[0] > 0.0 && fabs(mean[1] - mean[0]) <= 0.015 * mean[0], "irradiance %g, bvh %g", mean[0], mean[1]);
    pn_scene_free(scene);
    pn_context_free(ctx);
    unlink(path);
    rmdir(dir);
}

PN_TESTS(TEST(test_structure), TEST(test_sampling_matches_pmf), TEST(test_support), TEST(test_render_agrees))
