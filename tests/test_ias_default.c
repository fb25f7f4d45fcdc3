/* test_ias_default.c — the light-BVH cut of ias's default variant (issue 15,
 * pn_light_bvh_cut): from 10^3 to 10^5 emitters a point's cut costs at most 2K - 1 importance
 * evaluations and holds at most K nodes, its probabilities are those of the BVH's descent (they
 * sum to one, and descending from a cut node with them reproduces the descent from the root), and
 * the tree's depth, which bounds the descent below a cut node, grows as log N. */
#include "harness.h"

#include "core/rng.h"
#include "lights/light_bvh.h"

#include <stdlib.h>
#include <string.h>

/* n small one-sided triangles facing down in a 10 m ceiling at height 4. */
static pn_light *ceiling(int n, pn_lights *L) {
    pn_light *l = calloc((size_t)n, sizeof *l);
    int side = (int)ceil(sqrt((double)n));
    float cell = 10.0f / (float)side;
    for (int i = 0; i < n; i++) {
        pn_light *x = &l[i];
        x->kind = PN_LIGHT_TRIANGLE;
        x->env = x->mesh = x->prim = -1;
        x->p = v3(-5.0f + cell * (float)(i % side), 4.0f, -5.0f + cell * (float)(i / side));
        x->e1 = v3(0.3f * cell, 0, 0);
        x->e2 = v3(0, 0, 0.3f * cell);
        x->n = v3(0, -1, 0);
        x->area = 0.5f * 0.09f * cell * cell;
        x->emit = v3(1, 1, 1);
    }
    memset(L, 0, sizeof *L);
    L->lights = l;
    L->count = n;
    L->scene_radius = 10.0f;
    return l;
}

static int depth_of(const pn_light_bvh *t) {
    int worst = 0;
    for (int i = 0; i < t->node_count; i++) {
        if (!t->nodes[i].leaf) continue;
        int d = 0;
        for (int m = i; t->nodes[m].parent >= 0; m = t->nodes[m].parent) d++;
        if (d > worst) worst = d;
    }
    return worst;
}

static void test_cut_cost_and_probabilities(void) {
    const int K = 16;
    for (int n = 1000; n <= 100000; n *= 10) {
        pn_lights L;
        pn_light *l = ceiling(n, &L);
        pn_light_bvh t;
        pn_err err;
        pn_err_init(&err);
        CHECK(pn_light_bvh_build(&L, &t, &err) == PN_OK);
        int depth = depth_of(&t);
        /* log N growth: a balanced tree has depth log2 N; allow four times that. */
        CHECK(depth <= 4.0 * log2((double)n));
        pn_rng r;
        pn_rng_seed(&r, 7, (uint64_t)n);
        int nodes[16];
        float prob[16];
        for (int k = 0; k < 200; k++) {
            vec3 p = v3(-6.0f + 12.0f * pn_rng_float(&r), 0.0f, -6.0f + 12.0f * pn_rng_float(&r));
            vec3 nrm = v3(0, 1, 0);
            int visited = 0;
            int c = pn_light_bvh_cut(&t, p, nrm, K, nodes, prob, &visited);
            CHECK(c >= 1 && c <= K);
            CHECK(visited <= 2 * K - 1);
            double sum = 0.0;
            for (int i = 0; i < c; i++) {
                CHECK(prob[i] > 0.0f);
                sum += (double)prob[i];
            }
            CHECK_NEAR(sum, 1.0, 1e-4);
            /* A descent from the root lands in exactly one cut node; the probability it reports is
             * that node's times the descent's from the node down to the same light. */
            double u = (double)pn_rng_float(&r), pm_root;
            int light = pn_light_bvh_descend(&t, 0, p, nrm, u, 1.0, &pm_root);
            CHECK(light >= 0);
            if (light < 0) continue;
            int in = -1;
            for (int m = t.node_of_light[light]; m >= 0 && in < 0; m = t.nodes[m].parent)
                for (int i = 0; i < c; i++)
                    if (nodes[i] == m) in = i;
            CHECK(in >= 0);
            if (in < 0) continue;
            /* The descent's probability of that light from the cut node: recomputed by the
             * importance ratios along the path below it. */
            double below = 1.0;
            for (int m = t.node_of_light[light]; m != nodes[in]; m = t.nodes[m].parent) {
                int par = t.nodes[m].parent;
                double i0 = (double)pn_light_bounds_importance(&t.nodes[par + 1].b, p, nrm);
                double i1 = (double)pn_light_bounds_importance(&t.nodes[t.nodes[par].second].b, p, nrm);
                below *= (m == par + 1 ? i0 : i1) / (i0 + i1);
            }
            CHECK_NEAR((double)prob[in] * below / pm_root, 1.0, 1e-3);
        }
        pn_light_bvh_free(&t);
        free(l);
    }
}

PN_TESTS(TEST(test_cut_cost_and_probabilities))
