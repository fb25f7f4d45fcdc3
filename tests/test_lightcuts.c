/* test_lightcuts.c — the Lightcuts parts: the cosine bound of the bounding-box transform and the
 * bounds M_max, G_max, L_UB are never below the true values on random point and VPL clusters
 * (property test); the light tree's structure (ranges, sums, boxes, cones, representatives) and
 * its representatives' probabilities (in proportion to intensity); the lightcut guarantee per
 * point (|estimate - exact| <= the sum of the cut's error bounds, each bound <= error x estimate)
 * against an exact sum over all VPLs with visibility; and the lightcuts image against the vpl
 * image (error statistics, convergence as the error bound shrinks, thread-count independence). */
#include "harness.h"
#include "render_fields.h"

#include "core/rng.h"
#include "integrators/illumcut.h"
#include "lights/light_tree.h"
#include "penumbra/penumbra.h"
#include "scene/scene.h"
#include "shade/bounds.h"
#include "shade/bsdf.h"
#include "vpl_scenes.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static vec3 rand_dir(pn_rng *rng) {
    for (;;) {
        vec3 v = v3(2.0f * pn_rng_float(rng) - 1.0f, 2.0f * pn_rng_float(rng) - 1.0f, 2.0f * pn_rng_float(rng) - 1.0f);
        float l = v3_length(v);
        if (l > 0.05f && l <= 1.0f) return v3_scale(v, 1.0f / l);
    }
}

static vec3 rand_in_box(pn_rng *rng, vec3 lo, vec3 hi) {
    return v3(lo.x + (hi.x - lo.x) * pn_rng_float(rng), lo.y + (hi.y - lo.y) * pn_rng_float(rng),
              lo.z + (hi.z - lo.z) * pn_rng_float(rng));
}

/* A direction within roughly `spread` of axis. */
static vec3 near_dir(pn_rng *rng, vec3 axis, float spread) {
    return v3_normalize(v3_add(axis, v3_scale(rand_dir(rng), spread)));
}

static void test_bound_cos(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 1, 2);
    int tight = 0;
    for (int t = 0; t < 3000; t++) {
        vec3 c = v3_scale(rand_dir(&rng), 3.0f * pn_rng_float(&rng));
        vec3 e = v3_scale(v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng)), t % 5 == 0 ? 0.0f : 2.0f);
        vec3 lo = v3_sub(c, e), hi = v3_add(c, e);
        vec3 axis = rand_dir(&rng);
        float half = (t % 3 == 0) ? 0.0f : 0.8f * pn_rng_float(&rng);
        float bound = pn_bound_cos(lo, hi, axis, half);
        float best = -2.0f;
        for (int k = 0; k < 200; k++) {
            vec3 v = rand_in_box(&rng, lo, hi);
            vec3 a = half > 0.0f ? near_dir(&rng, axis, sinf(half) * 0.5f) : axis;
            if (acosf(fminf(1.0f, v3_dot(a, axis))) > half) continue;
            float l = v3_length(v);
            if (!(l > 0.0f)) continue;
            float cs = v3_dot(v, a) / l;
            if (cs > best) best = cs;
            CHECK_MSG(cs <= bound + 1e-5f, "cos %g > bound %g", (double)cs, (double)bound);
        }
        /* A point box and no cone: the bound is the cosine itself. */
        if (t % 5 == 0 && half == 0.0f) {
            float exact = v3_dot(c, axis) / v3_length(c);
            CHECK_NEAR(bound, exact, 1e-4);
            tight++;
        }
    }
    CHECK(tight > 100);
}

/* The Blinn-Phong lobe bound over an exponent range: never below (n + 2) / (2 pi) c^n for any
 * exponent n of the range and cosine c <= cb (checked on a fine grid of n), within rounding of
 * the largest grid value (it is the maximum, not a looser product), and the one-exponent value
 * when n_min = n_max. */
static void test_lobe_bound(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 17, 2);
    for (int t = 0; t < 2000; t++) {
        float cb = t % 10 == 0 ? 1.0f : (t % 10 == 1 ? 0.0f : pn_rng_float(&rng));
        if (t % 3 == 0) cb = 1.0f - 0.01f * pn_rng_float(&rng); /* near 1: the stationary point is large */
        float n0 = 1.0f + 500.0f * pn_rng_float(&rng), n1 = n0 + (t % 4 == 0 ? 0.0f : 2000.0f * pn_rng_float(&rng));
        float bound = pn_bound_lobe(cb, n0, n1);
        double best = 0.0;
        for (int k = 0; k <= 400; k++) {
            double n = (double)n0 + ((double)n1 - (double)n0) * k / 400.0;
            for (int j = 0; j <= 4; j++) {
                double c = (double)cb * (1.0 - 0.25 * j);
                double f = (n + 2.0) / (2.0 * (double)PN_PI) * pow(c, n);
                CHECK_MSG(f <= (double)bound * 1.0001 + 1e-12, "cb %g n [%g, %g]: lobe %g at n %g > bound %g",
                          (double)cb, (double)n0, (double)n1, f, n, (double)bound);
                if (j == 0 && f > best) best = f;
            }
        }
        /* The grid misses the maximum by at most a step of n: allow that much. */
        double step = ((double)n1 - (double)n0) / 400.0;
        double slack =
            step > 0.0 ? best * expm1(step * (1.0 / ((double)n0 + 2.0) - log(fmax((double)cb, 1e-30)))) : 0.0;
        CHECK_MSG((double)bound <= best * 1.0001 + slack + 1e-12, "cb %g n [%g, %g]: bound %g above the maximum %g",
                  (double)cb, (double)n0, (double)n1, (double)bound, best);
    }
}

/* Random receiver and VPL clusters: for every point, the luminance of the summed exact
 * contributions of the cluster's VPLs (eq. 2 with V = 1) never exceeds L_UB (eq. 5), and every
 * single pair's M G per channel never exceeds M_max G_max. */
static void test_bounds_never_below_truth(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 9, 4);
    pn_lights lights;
    memset(&lights, 0, sizeof lights);
    int informative = 0;
    for (int t = 0; t < 1500; t++) {
        enum { NP = 12, NQ = 12 };
        pn_vpl_receiver rc[NP];
        pn_receiver_bounds rb;
        vec3 rcen = v3_scale(rand_dir(&rng), 2.0f * pn_rng_float(&rng));
        vec3 rext = v3_scale(v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng)), 0.6f * pn_rng_float(&rng));
        vec3 naxis = rand_dir(&rng);
        float nspread = (t % 4 == 0) ? 0.0f : 0.5f * pn_rng_float(&rng);
        bool glossy = t % 2 == 1;
        /* Every 8th trial: one normal and one view direction, a tiny box (tight cones: the
         * glossy lobe's exponent range decides the bound). */
        bool tight = t % 8 == 1;
        vec3 wo_shared = rand_dir(&rng);
        if (tight) {
            nspread = 0.0f;
            rext = v3_scale(rext, 0.01f);
            if (v3_dot(wo_shared, naxis) < 0.0f) wo_shared = v3_neg(wo_shared);
        }
        for (int i = 0; i < NP; i++) {
            pn_vpl_receiver *r = &rc[i];
            r->p = rand_in_box(&rng, v3_sub(rcen, rext), v3_add(rcen, rext));
            r->ns = r->ng = near_dir(&rng, naxis, nspread);
            r->wo = tight ? wo_shared : rand_dir(&rng);
            if (v3_dot(r->wo, r->ns) < 0.0f) r->wo = v3_neg(r->wo);
            r->kd = v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng));
            /* Glossy trials mix in Lambert points (k_spec 0, exponent 1), whose exponent stays out
             * of the range as in the point tree's nodes. */
            bool lambert = !glossy || (t % 6 == 3 && i % 3 == 1);
            r->ks = lambert ? v3(0, 0, 0) : v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng));
            r->exponent = lambert ? 1.0f : 1.0f + 200.0f * pn_rng_float(&rng);
            *r = pn_vpl_receiver_rgb(r->p, r->ng, r->ns, r->wo, r->kd, r->ks, r->exponent);
            vec3 refl = pn_reflect(r->wo, r->ns);
            if (i == 0) {
                rb = (pn_receiver_bounds){r->p,  r->p,        r->ns,       0.0f, refl, 0.0f, r->kd,
                                          r->ks, r->exponent, r->exponent, 1,    0,    1,    0};
                if (lambert) rb.n_min = INFINITY, rb.n_max = -INFINITY;
            } else {
                rb.lo = v3_min(rb.lo, r->p);
                rb.hi = v3_max(rb.hi, r->p);
                pn_cone_merge(rb.n_axis, rb.n_half, r->ns, 0.0f, &rb.n_axis, &rb.n_half);
                pn_cone_merge(rb.r_axis, rb.r_half, refl, 0.0f, &rb.r_axis, &rb.r_half);
                rb.kd_max = v3_max(rb.kd_max, r->kd);
                rb.ks_max = v3_max(rb.ks_max, r->ks);
                if (!lambert) {
                    rb.n_min = fminf(rb.n_min, r->exponent);
                    rb.n_max = fmaxf(rb.n_max, r->exponent);
                }
            }
        }
        int kind = t % 3;
        pn_vpl vq[NQ];
        pn_light_bounds lb;
        vec3 qcen = v3_scale(rand_dir(&rng), 1.0f + 3.0f * pn_rng_float(&rng));
        vec3 qext = v3_scale(v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng)), 0.8f * pn_rng_float(&rng));
        vec3 qaxis = rand_dir(&rng);
        float qspread = 0.7f * pn_rng_float(&rng);
        vec3 isum = v3(0, 0, 0);
        for (int j = 0; j < NQ; j++) {
            pn_vpl *v = &vq[j];
            memset(v, 0, sizeof *v);
            v->kind = kind;
            v->light = -1;
            v->p = kind == PN_VPL_DIRECTIONAL ? near_dir(&rng, qaxis, qspread)
                                              : rand_in_box(&rng, v3_sub(qcen, qext), v3_add(qcen, qext));
            v->n = kind == PN_VPL_ORIENTED ? near_dir(&rng, qaxis, qspread) : v3(0, 0, 0);
            v->intensity = v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng));
            isum = v3_add(isum, v->intensity);
            if (j == 0) {
                lb =
                    (pn_light_bounds){kind, v->p, v->p, kind == PN_VPL_ORIENTED ? v->n : v3(0, 0, 1), 0.0f, 1.0f, 0.0f};
            } else {
                lb.lo = v3_min(lb.lo, v->p);
                lb.hi = v3_max(lb.hi, v->p);
                if (kind == PN_VPL_ORIENTED) pn_cone_merge(lb.axis, lb.half, v->n, 0.0f, &lb.axis, &lb.half);
            }
        }
        pn_receiver_bounds_set_cones(&rb);
        pn_light_bounds_set_cone(&lb);
        float dmin2 = (t % 5 == 0) ? 0.0f : 0.2f * pn_rng_float(&rng);
        float ub = pn_bound_error(&rb, &lb, isum, dmin2);
        vec3 mmax = pn_bound_material(&rb, &lb);
        float gmax = pn_bound_geometric(&rb, &lb, dmin2);
        for (int i = 0; i < NP; i++) {
            vec3 sum = v3(0, 0, 0);
            for (int j = 0; j < NQ; j++) {
                vec3 wi;
                float dist;
                vec3 mg = pn_vpl_contribution_with(&lights, &vq[j], v3(1, 1, 1), &rc[i], dmin2, &wi, &dist);
                CHECK(mg.x <= mmax.x * gmax * 1.0001f + 1e-7f && mg.y <= mmax.y * gmax * 1.0001f + 1e-7f &&
                      mg.z <= mmax.z * gmax * 1.0001f + 1e-7f);
                sum = v3_add(sum, v3_mul(mg, vq[j].intensity));
            }
            float actual = v3_luminance(sum);
            CHECK_MSG(actual <= ub * 1.0001f + 1e-7f, "actual %g > L_UB %g (trial %d)", (double)actual, (double)ub, t);
            if (actual > 0.05f * ub) informative++;
        }
    }
    /* The bounds are not vacuous: often within 20x of the truth. */
    CHECK_MSG(informative > 2000, "%d informative", informative);
}

static void test_light_tree_structure(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 3, 3);
    pn_vpl_set set;
    memset(&set, 0, sizeof set);
    set.count = 3000;
    set.vpls = calloc(set.count, sizeof *set.vpls);
    for (uint32_t i = 0; i < set.count; i++) {
        pn_vpl *v = &set.vpls[i];
        v->kind = (int32_t)(i % 7 == 0 ? PN_VPL_OMNI : (i % 11 == 0 ? PN_VPL_DIRECTIONAL : PN_VPL_ORIENTED));
        v->light = -1;
        v->p = v->kind == PN_VPL_DIRECTIONAL ? rand_dir(&rng) : v3_scale(rand_dir(&rng), 5.0f * pn_rng_float(&rng));
        v->n = v->kind == PN_VPL_ORIENTED ? rand_dir(&rng) : v3(0, 0, 0);
        v->intensity = v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng));
    }
    pn_light_tree t;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_light_tree_build(&set, 10.0f, 5, &t, &err) == PN_OK);
    int *leaf_seen = calloc(set.count, sizeof *leaf_seen);
    int total = 0;
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) {
        CHECK(t.roots[k] >= 0);
        if (t.roots[k] < 0) continue;
        total += t.nodes[t.roots[k]].count;
    }
    CHECK(total == (int)set.count);
    CHECK(t.node_count == 2 * (int)set.count - 3);
    /* The kind of every node, from its tree's root. */
    int *kind_of = malloc((size_t)t.node_count * sizeof *kind_of);
    int *stack = malloc((size_t)t.node_count * sizeof *stack);
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) {
        int sp = 0;
        if (t.roots[k] >= 0) stack[sp++] = t.roots[k];
        while (sp > 0) {
            int i = stack[--sp];
            kind_of[i] = k;
            if (t.nodes[i].left >= 0) {
                stack[sp++] = t.nodes[i].left;
                stack[sp++] = t.nodes[i].right;
            }
        }
    }
    int oriented_checked = 0;
    for (int i = 0; i < t.node_count; i++) {
        const pn_light_node *n = &t.nodes[i];
        if (n->left < 0) {
            CHECK(set.vpls[n->rep].kind == kind_of[i]);
            leaf_seen[n->rep]++;
            continue;
        }
        const pn_light_node *a = &t.nodes[n->left], *b = &t.nodes[n->right];
        CHECK(n->count == a->count + b->count);
        CHECK(n->rep == a->rep || n->rep == b->rep);
        CHECK_NEAR(n->weight, a->weight + b->weight, 1e-3 * (double)n->weight);
        CHECK(n->lo.x <= fminf(a->lo.x, b->lo.x) && n->hi.z >= fmaxf(a->hi.z, b->hi.z));
        float ca = acosf(fminf(1.0f, v3_dot(n->axis, a->axis))) + a->half;
        float cb = acosf(fminf(1.0f, v3_dot(n->axis, b->axis))) + b->half;
        if (kind_of[i] == PN_VPL_ORIENTED && n->half < PN_PI) {
            CHECK(ca <= n->half + 1e-3f && cb <= n->half + 1e-3f);
            oriented_checked++;
        }
    }
    CHECK(oriented_checked > 100);
    free(kind_of);
    free(stack);
    for (uint32_t i = 0; i < set.count; i++) CHECK(leaf_seen[i] == 1);
    free(leaf_seen);
    /* Depth-first pre-order: a left child is the next node, a right child follows the left
     * subtree, every subtree is the contiguous range [i, i + 2 count - 1). */
    for (int i = 0; i < t.node_count; i++) {
        const pn_light_node *n = &t.nodes[i];
        if (n->left < 0) continue;
        CHECK(n->left == i + 1);
        CHECK(n->right == n->left + 2 * t.nodes[n->left].count - 1);
        CHECK(n->right + 2 * t.nodes[n->right].count - 1 == i + 2 * n->count - 1);
    }
    /* Reordering the VPLs as the leaves: same VPL behind every node's representative, leaves
     * numbered 0, 1, 2, ... in node order. */
    pn_vpl *before = malloc(set.count * sizeof *before);
    int32_t *rep_before = malloc((size_t)t.node_count * sizeof *rep_before);
    memcpy(before, set.vpls, set.count * sizeof *before);
    for (int i = 0; i < t.node_count; i++) rep_before[i] = t.nodes[i].rep;
    CHECK(pn_light_tree_order_vpls(&t, &set, &err) == PN_OK);
    int32_t next_leaf = 0;
    for (int i = 0; i < t.node_count; i++) {
        const pn_light_node *n = &t.nodes[i];
        CHECK(memcmp(&set.vpls[n->rep], &before[rep_before[i]], sizeof *before) == 0);
        if (n->left < 0) CHECK(n->rep == next_leaf++);
    }
    CHECK(next_leaf == (int32_t)set.count);
    free(before);
    free(rep_before);
    pn_light_tree_free(&t);
    free(set.vpls);
}

/* Three omni VPLs of intensities 1, 2, 5: over many seeds, the root's representative is each
 * VPL with probability I / 8. */
static void test_representative_probability(void) {
    pn_vpl v[3];
    memset(v, 0, sizeof v);
    float I[3] = {1, 2, 5};
    for (int i = 0; i < 3; i++) {
        v[i].kind = PN_VPL_OMNI;
        v[i].light = -1;
        v[i].p = v3((float)i, 0.3f * (float)(i * i), 0);
        v[i].intensity = v3(I[i], I[i], I[i]);
    }
    pn_vpl_set set;
    memset(&set, 0, sizeof set);
    set.vpls = v;
    set.count = 3;
    int hits[3] = {0, 0, 0};
    const int N = 8000;
    for (int s = 0; s < N; s++) {
        pn_light_tree t;
        pn_err err;
        pn_err_init(&err);
        CHECK(pn_light_tree_build(&set, 1.0f, (uint64_t)s, &t, &err) == PN_OK);
        hits[t.nodes[t.roots[PN_VPL_OMNI]].rep]++;
        pn_light_tree_free(&t);
    }
    for (int i = 0; i < 3; i++) {
        double p = (double)I[i] / 8.0, sigma = sqrt(p * (1 - p) / N);
        CHECK_MSG(fabs((double)hits[i] / N - p) < 5 * sigma, "VPL %d: %g vs %g", i, (double)hits[i] / N, p);
    }
}

/* The lightcut guarantee, point by point, on a room with a glossy box. */
static void test_lightcut_guarantee(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room.pbrt", pn_test_room_scene(1, 8, 8));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_vpl_settings vs = {3000, 10, 0.05f, 1};
    pn_vpl_set set;
    pn_light_tree tree;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &vs, &set, &err) == PN_OK);
    CHECK(pn_light_tree_build(&set, 2.0f * scene->lights->scene_radius, 1, &tree, &err) == PN_OK);
    pn_rng rng;
    pn_rng_seed(&rng, 77, 1);
    double rel_sum = 0.0;
    int n = 0, capped = 0;
    uint64_t cut_total = 0;
    for (int t = 0; t < 300; t++) {
        vec3 o = v3(-1.5f + 3.0f * pn_rng_float(&rng), -1.8f, 0.2f + 2.6f * pn_rng_float(&rng));
        vec3 d = rand_dir(&rng);
        if (d.y < 0.0f) d.y = -d.y;
        pn_hit hit;
        if (!pn_accel_intersect(scene->accel, o, d, 0.0f, INFINITY, &hit)) continue;
        pn_bsdf b;
        pn_bsdf_at(scene, &hit, v3_neg(d), &b);
        if (b.kind != PN_MATERIAL_LAMBERT_BLINN) continue;
        pn_vpl_receiver r = pn_vpl_receiver_rgb(hit.p, b.ng, b.ns, v3_neg(d), b.kd, b.ks, b.exponent);
        vec3 exact = v3(0, 0, 0);
        for (uint32_t k = 0; k < set.count; k++) {
            vec3 wi;
            float dist;
            vec3 c = pn_vpl_contribution(scene->lights, &set.vpls[k], &r, set.min_dist2, &wi, &dist);
            if (!v3_is_zero(c) && pn_vpl_visible(scene->accel, &r, wi, dist)) exact = v3_add(exact, c);
        }
        uint32_t max_cut = (t % 4 == 3) ? 8u : 0u;
        pn_lightcut_context cx = {scene->lights, scene->accel, &set, &tree, 0.01f, max_cut, false};
        vec3 est;
        float bound_sum;
        uint32_t cut, rays;
        CHECK(pn_lightcut_eval(&cx, &r, &est, &bound_sum, &cut, &rays));
        double e = (double)v3_luminance(exact), a = (double)v3_luminance(est);
        CHECK_MSG(fabs(a - e) <= (double)bound_sum * 1.001 + 1e-6 * e + 1e-9, "point %d: |%g - %g| > %g", t, a, e,
                  (double)bound_sum);
        if (max_cut == 0) {
            /* Every cluster's bound is below 1% of the estimate. */
            CHECK((double)bound_sum <= 0.01 * a * (double)cut * 1.001 + 1e-9);
            CHECK(rays <= 2 * cut + 3);
            if (e > 0.0) {
                rel_sum += fabs(a - e) / e;
                n++;
            }
            cut_total += cut;
        } else {
            CHECK(cut <= max_cut + 1);
            capped++;
        }
    }
    CHECK(n > 150 && capped > 50);
    /* In practice the error is far below the worst case. */
    CHECK_MSG(rel_sum / n < 0.01, "mean relative error %g", rel_sum / n);
    /* And the cut is much smaller than the VPL set. */
    CHECK((double)cut_total / n < 0.5 * set.count);
    pn_light_tree_free(&tree);
    pn_vpl_set_free(&set);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static pn_image render(pn_context ctx, pn_scene scene, pn_integrator_kind kind, float error, int threads,
                       pn_render_stats *stats) {
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    pn_options o = pn_options_new();
    rs.options = o;
    rs.integrator = kind;
    pn_options_set_int(ctx, o, "vpls", 2000);
    /* The error bound where the integrator has one (not vpl). */
    if (error > 0.0f && pn_option_applies(pn_option_find("error"), pn_method_find_kind(PN_METHOD_INTEGRATOR, kind)))
        pn_options_set_double(ctx, o, "error", (double)error);
    rs.threads = threads;
    rs.aovs = PN_AOV_BOUND_EVALUATIONS | PN_AOV_CUT_SIZE;
    pn_image img = NULL;
    CHECK(pn_test_render(ctx, scene, &rs, &img, stats) == PN_OK);
    pn_options_free(o);
    return img;
}

/* Mean over pixels of |a - b| / b in luminance (pixels with b > 0), and the largest. */
static double mean_rel_error(pn_image a, pn_image b, double *max_rel) {
    int n = pn_image_width(a) * pn_image_height(a);
    const float *pa = pn_image_layer_data(a, 0), *pb = pn_image_layer_data(b, 0);
    double sum = 0.0, mx = 0.0;
    int m = 0;
    for (int i = 0; i < n; i++) {
        double la = (double)v3_luminance(v3(pa[3 * i], pa[3 * i + 1], pa[3 * i + 2]));
        double lb = (double)v3_luminance(v3(pb[3 * i], pb[3 * i + 1], pb[3 * i + 2]));
        if (!(lb > 0.0)) continue;
        double r = fabs(la - lb) / lb;
        sum += r;
        if (r > mx) mx = r;
        m++;
    }
    *max_rel = mx;
    return m ? sum / m : 0.0;
}

static void test_lightcuts_image_against_vpl(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room_img.pbrt", pn_test_room_scene(0, 24, 18));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_stats s_ref, s_lc, s_lc2, s_fine, s_coarse;
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_VPL, 0.0f, 2, &s_ref);
    pn_image lc = render(ctx, scene, PN_INTEGRATOR_LIGHTCUTS, 0.01f, 2, &s_lc);
    pn_image lc1 = render(ctx, scene, PN_INTEGRATOR_LIGHTCUTS, 0.01f, 1, &s_lc2);
    pn_image fine = render(ctx, scene, PN_INTEGRATOR_LIGHTCUTS, 0.001f, 2, &s_fine);
    pn_image coarse = render(ctx, scene, PN_INTEGRATOR_LIGHTCUTS, 0.1f, 2, &s_coarse);
    if (ref && lc && lc1 && fine && coarse) {
        double mx, mx_fine, mx_coarse;
        double e = mean_rel_error(lc, ref, &mx);
        double e_fine = mean_rel_error(fine, ref, &mx_fine);
        double e_coarse = mean_rel_error(coarse, ref, &mx_coarse);
        CHECK_MSG(e < 0.01 && mx < 0.05, "1%%: mean %g max %g", e, mx);
        CHECK_MSG(e_fine < 0.002 && mx_fine < 0.01, "0.1%%: mean %g max %g", e_fine, mx_fine);
        CHECK_MSG(e_fine < e && e < e_coarse, "%g %g %g", e_fine, e, e_coarse);
        /* Fewer shadow rays than all VPLs; more with a tighter bound. */
        CHECK(s_lc.shadow_rays_per_pixel_mean < 0.5 * s_ref.shadow_rays_per_pixel_mean);
        CHECK(s_fine.shadow_rays_per_pixel_mean > s_lc.shadow_rays_per_pixel_mean);
        CHECK(s_lc.bound_evaluations_per_pixel_mean > 0.0 && s_lc.cut_size_mean > 1.0);
        CHECK(s_lc.vpl_count >= 2000 && s_lc.light_tree_seconds > 0.0);
        /* The same image whatever the thread count. */
        int n = pn_image_width(lc) * pn_image_height(lc) * 3;
        CHECK(memcmp(pn_image_layer_data(lc, 0), pn_image_layer_data(lc1, 0), (size_t)n * sizeof(float)) == 0);
        /* Fig. 4's layer: the bound evaluations per pixel, consistent with the statistics. */
        CHECK(pn_image_layer_count(lc) == 4 && strcmp(pn_image_layer_name(lc, 1), "bound_evaluations") == 0);
        CHECK(strcmp(pn_image_layer_name(lc, 2), "log10_bound_evaluations") == 0);
        CHECK(strcmp(pn_image_layer_name(lc, 3), "cut_size") == 0);
        const float *be = pn_image_layer_data(lc, 1);
        double sum = 0.0;
        for (int i = 0; i < n / 3; i++) sum += (double)be[i];
        CHECK_NEAR(sum / (n / 3), s_lc.bound_evaluations_per_pixel_mean, 1e-6 * sum);
    }
    pn_image_free(ref);
    pn_image_free(lc);
    pn_image_free(lc1);
    pn_image_free(fine);
    pn_image_free(coarse);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* Every kind of light at once (environment, distant, spot, sphere; the directional and omni trees
 * as well as the oriented one) and a glossy sphere: lightcuts and illumcut against vpl. */
static void test_all_light_kinds(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(
        ctx, "kinds.pbrt",
        "LookAt 0 -6 3  0 0 0.5  0 0 1\nCamera \"perspective\" \"float fov\" [ 50 ]\n"
        "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 24 ]\nWorldBegin\n"
        "LightSource \"infinite\" \"rgb L\" [ 0.2 0.25 0.3 ]\n"
        "LightSource \"distant\" \"point3 from\" [ 1 -1 3 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 0.8 0.7 0.6 ]\n"
        "LightSource \"spot\" \"point3 from\" [ -1 -1 3 ] \"point3 to\" [ -1 0 0 ] \"float coneangle\" [ 30 ]\n"
        "    \"float conedeltaangle\" [ 10 ] \"rgb I\" [ 4 4 3 ]\n"
        "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ 5 4 3 ]\n  Translate 1.5 0 1.2\n"
        "  Shape \"sphere\" \"float radius\" [ 0.15 ]\nAttributeEnd\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -5 -5 0  5 -5 0  5 5 0  -5 5 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.3 0.5 0.7 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -2 1 0  2 1 0  2 1 2  -2 1 2 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "Material \"coateddiffuse\" \"rgb reflectance\" [ 0.5 0.3 0.2 ] \"float roughness\" [ 0.2 ]\n"
        "AttributeBegin\n  Translate 0 -0.5 0.5\n  Shape \"sphere\" \"float radius\" [ 0.5 ]\nAttributeEnd\n");
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_stats s_ref, s_lc, s_ic;
    pn_image ref = render(ctx, scene, PN_INTEGRATOR_VPL, 0.0f, 2, &s_ref);
    pn_image lc = render(ctx, scene, PN_INTEGRATOR_LIGHTCUTS, 0.01f, 2, &s_lc);
    pn_image ic = render(ctx, scene, PN_INTEGRATOR_ILLUMCUT, 0.015f, 2, &s_ic);
    if (ref && lc && ic) {
        double mx_lc, mx_ic;
        double e_lc = mean_rel_error(lc, ref, &mx_lc), e_ic = mean_rel_error(ic, ref, &mx_ic);
        CHECK_MSG(e_lc < 0.01 && mx_lc < 0.05, "lightcuts: mean %g max %g", e_lc, mx_lc);
        CHECK_MSG(e_ic < 0.015 && mx_ic < 0.08, "illumcut: mean %g max %g", e_ic, mx_ic);
        CHECK(s_lc.shadow_rays_per_pixel_mean < 0.5 * s_ref.shadow_rays_per_pixel_mean);
    }
    pn_image_free(ref);
    pn_image_free(lc);
    pn_image_free(ic);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void setup(void) {
    vpl_test_setup("lightcuts");
}

static void teardown(void) {
    vpl_test_teardown();
}

PN_TESTS(TEST(setup), TEST(test_bound_cos), TEST(test_lobe_bound), TEST(test_bounds_never_below_truth),
         TEST(test_light_tree_structure), TEST(test_representative_probability), TEST(test_lightcut_guarantee),
         TEST(test_lightcuts_image_against_vpl), TEST(test_all_light_kinds), TEST(teardown))
