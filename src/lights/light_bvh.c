/* light_bvh.c — pbrt-v4's light BVH (see light_bvh.h): light bounds, their union, the importance
 * of a node at a receiving point, the top-down build with the surface-area-orientation heuristic
 * (12 buckets per axis), and stochastic descent. */
#include "lights/light_bvh.h"

#include "lights/cluster_tree.h"

#include <stdlib.h>
#include <string.h>

#define BVH_BUCKETS 12

static float safe_sqrt(float x) {
    return sqrtf(fmaxf(0.0f, x));
}
static float safe_acos(float x) {
    return acosf(fminf(1.0f, fmaxf(-1.0f, x)));
}

static pn_light_bvh_bounds bounds_union(const pn_light_bvh_bounds *a, const pn_light_bvh_bounds *b) {
    if (a->phi == 0.0f) return *b;
    if (b->phi == 0.0f) return *a;
    pn_light_bvh_bounds u;
    u.bmin = v3_min(a->bmin, b->bmin);
    u.bmax = v3_max(a->bmax, b->bmax);
    if (a->cos_o == b->cos_o && a->cos_o > -1.0f && a->w.x == b->w.x && a->w.y == b->w.y && a->w.z == b->w.z) {
        /* Equal cones (the emitters of one flat mesh): what pn_cluster_merge_cones returns for
         * them (its first test, the angle between the axes being exactly 0), without its acos
         * and atan2. At 10^6 coplanar emitters (bench/ias/scaling.sh) that call was 26% of the
         * process CPU of reference --light-sampler bvh: 7.0 -> 5.5 s, images the same. */
        u.w = a->w;
        u.cos_o = a->cos_o;
    } else {
        pn_cluster_merge_cones(a->w, a->cos_o, b->w, b->cos_o, &u.w, &u.cos_o);
    }
    u.cos_e = fminf(a->cos_e, b->cos_e);
    u.phi = a->phi + b->phi;
    u.two_sided = a->two_sided || b->two_sided;
    return u;
}

/* ---- bounds of one light ------------------------------------------------------------------ */

bool pn_light_bounds_of(const pn_lights *lights, const pn_light *l, pn_light_bvh_bounds *b) {
    memset(b, 0, sizeof *b);
    b->w = v3(0, 0, 1);
    b->cos_o = -1.0f; /* any direction */
    b->cos_e = 0.0f;  /* cos(pi / 2) */
    float lum = v3_luminance(l->emit);
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_GONIOMETRIC: {
        float peak = 1.0f;
        if (l->kind == PN_LIGHT_GONIOMETRIC && l->env >= 0 && l->env < lights->gonio_count) {
            const pn_gonio *g = &lights->gonios[l->env];
            if (g->mono) {
                peak = 0.0f;
                for (int i = 0; i < g->width * g->height; i++) peak = fmaxf(peak, g->mono[i]);
            }
        }
        b->bmin = b->bmax = l->p;
        b->phi = 4.0f * PN_PI * lum * peak;
        if (l->kind == PN_LIGHT_GONIOMETRIC && l->env >= 0 && l->env < lights->gonio_count) {
            /* A measured luminaire dark beyond gamma_max (a downlight): its emission cone about
             * the nadir, when the light's transform keeps angles (lights/photometric.c). */
            const pn_gonio *g = &lights->gonios[l->env];
            if (g->photo && g->rigid && g->cos_max_gamma > -1.0f) {
                b->w = g->nadir;
                b->cos_o = fmaxf(-1.0f, fminf(1.0f, g->cos_max_gamma - 1e-5f));
                b->cos_e = cosf(1e-2f); /* theta_e > 0: pbrt's test is cos theta' <= cos theta_e */
            }
        }
        break;
    }
    case PN_LIGHT_SPOT:
        b->bmin = b->bmax = l->p;
        b->w = l->n;
        b->phi = 4.0f * PN_PI * lum;
        b->cos_o = l->cos_falloff_start;
        b->cos_e = cosf(safe_acos(l->cos_total_width) - safe_acos(l->cos_falloff_start));
        break;
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE:
    case PN_LIGHT_DISK:
        pn_cluster_light_box(l, &b->bmin, &b->bmax);
        b->w = l->n;
        b->cos_o = 1.0f;
        b->two_sided = l->two_sided;
        b->phi = lum * l->area * PN_PI * (l->two_sided ? 2.0f : 1.0f);
        break;
    case PN_LIGHT_SPHERE:
        pn_cluster_light_box(l, &b->bmin, &b->bmax);
        b->phi = lum * l->area * PN_PI;
        break;
    case PN_LIGHT_PROJECTION: {
        /* pbrt-v4's ProjectionLight::Bounds: the cone around the axis through the window's
         * corner (cos_theta_o = 1, cos_theta_e = that corner), phi from the mean over pixels of
         * the largest channel; times 4 pi here, as penumbra's point and spot bounds carry it
         * (pbrt-v4 leaves it out for this light only). */
        float mean_max = 1.0f;
        if (l->env >= 0 && l->env < lights->projection_count) mean_max = lights->projections[l->env].mean_max;
        b->bmin = b->bmax = l->p;
        b->w = l->n;
        b->cos_o = 1.0f;
        b->cos_e = l->cos_total_width;
        b->phi = 4.0f * PN_PI * lum * mean_max;
        break;
    }
    case PN_LIGHT_DISTANT:
    case PN_LIGHT_ENVIRONMENT:
    case PN_LIGHT_KIND_COUNT: return false;
    }
    return b->phi > 0.0f && isfinite(b->phi);
}

/* ---- importance --------------------------------------------------------------------------- */

float pn_light_bounds_importance(const pn_light_bvh_bounds *b, vec3 p, vec3 n) {
    vec3 pc = v3_scale(v3_add(b->bmin, b->bmax), 0.5f);
    vec3 dp = v3_sub(p, pc);
    float dc2 = v3_length2(dp);
    /* pbrt's guard against huge 1/d^2 near or inside big boxes: d^2 at least half the
     * diagonal's length (the units do not match; the rule is pbrt's). */
    float d2 = fmaxf(dc2, 0.5f * v3_length(v3_sub(b->bmax, b->bmin)));
    if (!(d2 > 0.0f)) return 0.0f;
    vec3 wi = v3_scale(dp, 1.0f / sqrtf(fmaxf(dc2, 1e-30f)));
    float cos_w = v3_dot(b->w, wi);
    if (b->two_sided) cos_w = fabsf(cos_w);
    float sin_w = safe_sqrt(1.0f - cos_w * cos_w);
    /* The angle the box subtends from p (its bounding sphere); everything if p is inside. */
    float r2 = 0.25f * v3_length2(v3_sub(b->bmax, b->bmin));
    float cos_b = dc2 < r2 ? -1.0f : safe_sqrt(1.0f - r2 / dc2);
    float sin_b = safe_sqrt(1.0f - cos_b * cos_b);
    /* theta' = max(0, theta_w - theta_o - theta_b): the smallest angle between an emitting
     * normal and the direction to p. */
    float sin_o = safe_sqrt(1.0f - b->cos_o * b->cos_o);
    float cos_x = pn_cos_sub_clamped(sin_w, cos_w, sin_o, b->cos_o);
    float sin_x = pn_sin_sub_clamped(sin_w, cos_w, sin_o, b->cos_o);
    float cos_p = pn_cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
    if (cos_p <= b->cos_e) return 0.0f;
    float importance = b->phi * cos_p / d2;
    if (!v3_is_zero(n)) {
        /* The largest incident cosine over the box: theta_i' = max(0, theta_i - theta_b). */
        float cos_i = fabsf(v3_dot(wi, n));
        float sin_i = safe_sqrt(1.0f - cos_i * cos_i);
        importance *= pn_cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
    }
    return fmaxf(importance, 0.0f);
}

/* ---- build -------------------------------------------------------------------------------- */

typedef struct bvh_item {
    int light;
    pn_light_bvh_bounds b;
} bvh_item;

typedef struct bvh_builder {
    pn_light_bvh *bvh;
    int capacity;
} bvh_builder;

/* pbrt's cost of a cluster: phi times the orientation measure M_Omega times the box's surface
 * area, with Kr penalising splits across the box's short axes. */
static float orientation_measure(float cos_o, float cos_e) {
    float to = safe_acos(cos_o), te = safe_acos(cos_e);
    float tw = fminf(to + te, PN_PI);
    float sin_o = safe_sqrt(1.0f - cos_o * cos_o);
    return 2.0f * PN_PI * (1.0f - cos_o) +
           0.5f * PN_PI * (2.0f * tw * sin_o - cosf(to - 2.0f * tw) - 2.0f * to * sin_o + cos_o);
}

static float surface_area(vec3 lo, vec3 hi) {
    vec3 d = v3_sub(hi, lo);
    return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
}

static float split_cost(const pn_light_bvh_bounds *b, float kr) {
    return b->phi * orientation_measure(b->cos_o, b->cos_e) * kr * surface_area(b->bmin, b->bmax);
}

static int push_node(bvh_builder *bb) {
    pn_light_bvh *t = bb->bvh;
    if (t->node_count == bb->capacity) return -1; /* sized up front: 2 n - 1 nodes */
    return t->node_count++;
}

static int build_range(bvh_builder *bb, bvh_item *items, int start, int end, int parent) {
    pn_light_bvh *t = bb->bvh;
    int me = push_node(bb);
    if (me < 0) return -1;
    pn_light_bvh_node *nd = &t->nodes[me];
    nd->parent = parent;
    if (end - start == 1) {
        nd->leaf = true;
        nd->second = items[start].light;
        nd->b = items[start].b;
        t->node_of_light[items[start].light] = me;
        return me;
    }
    pn_light_bvh_bounds all = items[start].b;
    vec3 cmin = v3_scale(v3_add(items[start].b.bmin, items[start].b.bmax), 0.5f), cmax = cmin;
    for (int i = start + 1; i < end; i++) {
        all = bounds_union(&all, &items[i].b);
        vec3 c = v3_scale(v3_add(items[i].b.bmin, items[i].b.bmax), 0.5f);
        cmin = v3_min(cmin, c);
        cmax = v3_max(cmax, c);
    }
    /* The cheapest bucket boundary over the three axes. */
    float best_cost = INFINITY;
    int best_dim = -1, best_bucket = -1;
    vec3 diag = v3_sub(all.bmax, all.bmin);
    float max_extent = fmaxf(diag.x, fmaxf(diag.y, diag.z));
    for (int dim = 0; dim < 3; dim++) {
        float lo = v3_get(cmin, dim), hi = v3_get(cmax, dim);
        if (!(hi > lo)) continue;
        pn_light_bvh_bounds bucket[BVH_BUCKETS];
        memset(bucket, 0, sizeof bucket);
        for (int i = start; i < end; i++) {
            float c = 0.5f * (v3_get(items[i].b.bmin, dim) + v3_get(items[i].b.bmax, dim));
            int k = (int)((float)BVH_BUCKETS * (c - lo) / (hi - lo));
            if (k >= BVH_BUCKETS) k = BVH_BUCKETS - 1;
            if (k < 0) k = 0;
            bucket[k] = bounds_union(&bucket[k], &items[i].b);
        }
        float extent = v3_get(diag, dim);
        float kr = extent > 0.0f ? max_extent / extent : 1.0f;
        for (int split = 0; split < BVH_BUCKETS - 1; split++) {
            pn_light_bvh_bounds below, above;
            memset(&below, 0, sizeof below);
            memset(&above, 0, sizeof above);
            for (int k = 0; k <= split; k++) below = bounds_union(&below, &bucket[k]);
            for (int k = split + 1; k < BVH_BUCKETS; k++) above = bounds_union(&above, &bucket[k]);
            if (below.phi == 0.0f || above.phi == 0.0f) continue;
            float cost = split_cost(&below, kr) + split_cost(&above, kr);
            if (cost < best_cost) {
                best_cost = cost;
                best_dim = dim;
                best_bucket = split;
            }
        }
    }
    int mid = -1;
    if (best_dim >= 0) {
        float lo = v3_get(cmin, best_dim), hi = v3_get(cmax, best_dim);
        int i = start, j = end - 1;
        while (i <= j) {
            float c = 0.5f * (v3_get(items[i].b.bmin, best_dim) + v3_get(items[i].b.bmax, best_dim));
            int k = (int)((float)BVH_BUCKETS * (c - lo) / (hi - lo));
            if (k >= BVH_BUCKETS) k = BVH_BUCKETS - 1;
            if (k < 0) k = 0;
            if (k <= best_bucket)
                i++;
            else {
                bvh_item tmp = items[i];
                items[i] = items[j];
                items[j] = tmp;
                j--;
            }
        }
        mid = i;
    }
    if (mid <= start || mid >= end) mid = start + (end - start) / 2; /* no useful split */
    nd->leaf = false;
    nd->b = all;
    if (build_range(bb, items, start, mid, me) < 0) return -1;
    int second = build_range(bb, items, mid, end, me);
    if (second < 0) return -1;
    t->nodes[me].second = second;
    return me;
}

pn_status pn_light_bvh_build(const pn_lights *lights, pn_light_bvh *out, pn_err *err) {
    memset(out, 0, sizeof *out);
    int n = lights->count;
    out->light_count = n;
    out->node_of_light = malloc((size_t)(n > 0 ? n : 1) * sizeof *out->node_of_light);
    out->infinite = malloc((size_t)(n > 0 ? n : 1) * sizeof *out->infinite);
    bvh_item *items = malloc((size_t)(n > 0 ? n : 1) * sizeof *items);
    /* One node per 64-byte cache line (a node is 64 bytes): a descent reads one line per node
     * instead of two for the nodes that malloc's 16-byte alignment made straddle lines. */
    out->nodes = aligned_alloc(64, (size_t)(n > 0 ? 2 * n : 1) * sizeof *out->nodes);
    if (!out->node_of_light || !out->infinite || !items || !out->nodes) {
        free(items);
        pn_light_bvh_free(out);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light BVH");
    }
    int bounded = 0;
    for (int i = 0; i < n; i++) {
        out->node_of_light[i] = -1;
        const pn_light *l = &lights->lights[i];
        if (l->kind == PN_LIGHT_DISTANT || l->kind == PN_LIGHT_ENVIRONMENT) {
            out->infinite[out->infinite_count++] = i;
            continue;
        }
        if (pn_light_bounds_of(lights, l, &items[bounded].b)) items[bounded++].light = i;
    }
    if (bounded > 0) {
        bvh_builder bb = {out, 2 * n};
        if (build_range(&bb, items, 0, bounded, -1) < 0) {
            free(items);
            pn_light_bvh_free(out);
            return pn_err_set(err, PN_ERROR_INTERNAL, "light BVH: node budget exceeded");
        }
    }
    free(items);
    return PN_OK;
}

void pn_light_bvh_free(pn_light_bvh *bvh) {
    if (!bvh) return;
    free(bvh->nodes);
    free(bvh->node_of_light);
    free(bvh->infinite);
    memset(bvh, 0, sizeof *bvh);
}

/* ---- sampling ------------------------------------------------------------------------------ */

static double infinite_share(const pn_light_bvh *t) {
    int parts = t->infinite_count + (t->node_count > 0 ? 1 : 0);
    return parts > 0 ? (double)t->infinite_count / (double)parts : 0.0;
}

int pn_light_bvh_sample(const pn_light_bvh *t, vec3 p, vec3 n, float u_in, float *pmf) {
    *pmf = 0.0f;
    double u = (double)u_in;
    double p_inf = infinite_share(t);
    if (u < p_inf) {
        /* Distant and environment lights, uniformly. */
        double v = u / p_inf;
        int k = (int)(v * (double)t->infinite_count);
        if (k >= t->infinite_count) k = t->infinite_count - 1;
        *pmf = (float)(p_inf / (double)t->infinite_count);
        return t->infinite[k];
    }
    if (t->node_count == 0) return -1;
    u = p_inf > 0.0 ? (u - p_inf) / (1.0 - p_inf) : u;
    double prob;
    int light = pn_light_bvh_descend(t, 0, p, n, u, 1.0 - p_inf, &prob);
    if (light >= 0) *pmf = (float)prob;
    return light;
}

int pn_light_bvh_descend(const pn_light_bvh *t, int node, vec3 p, vec3 n, double u, double prob, double *pmf) {
    *pmf = 0.0;
    if (u >= 1.0) u = nextafter(1.0, 0.0);
    for (;;) {
        const pn_light_bvh_node *nd = &t->nodes[node];
        if (nd->leaf) {
            if (!(pn_light_bounds_importance(&nd->b, p, n) > 0.0f)) return -1;
            *pmf = prob;
            return nd->second;
        }
        double i0 = (double)pn_light_bounds_importance(&t->nodes[node + 1].b, p, n);
        double i1 = (double)pn_light_bounds_importance(&t->nodes[nd->second].b, p, n);
        double sum = i0 + i1;
        if (!(sum > 0.0)) return -1;
        double p0 = i0 / sum;
        /* The choice, and u rescaled to [0,1) within the chosen child for the next level. */
        if (u < p0) {
            u = u / p0;
            prob *= p0;
            node = node + 1;
        } else {
            u = (u - p0) / (1.0 - p0);
            prob *= 1.0 - p0;
            node = nd->second;
        }
        if (u >= 1.0) u = nextafter(1.0, 0.0);
    }
}

/* ---- cuts ---------------------------------------------------------------------------------- */

int pn_light_bvh_cut(const pn_light_bvh *t, vec3 p, vec3 n, int max_nodes, int *nodes, float *prob, int *visited) {
    int k = 0, seen = 0;
    if (t->node_count > 0 && max_nodes > 0) {
        seen = 1;
        if (pn_light_bounds_importance(&t->nodes[0].b, p, n) > 0.0f) {
            nodes[0] = 0;
            prob[0] = 1.0f;
            k = 1;
        }
    }
    for (;;) {
        /* The interior node the descent reaches most often; splitting it replaces one entry by at
         * most two. */
        int best = -1;
        for (int j = 0; j < k; j++)
            if (!t->nodes[nodes[j]].leaf && (best < 0 || prob[j] > prob[best])) best = j;
        if (best < 0 || k + 1 > max_nodes) break;
        const int m = nodes[best];
        const int child[2] = {m + 1, t->nodes[m].second};
        float ic[2];
        for (int c = 0; c < 2; c++) ic[c] = pn_light_bounds_importance(&t->nodes[child[c]].b, p, n);
        seen += 2;
        const float parent = prob[best], sum = ic[0] + ic[1];
        /* The first child with importance takes the parent's place, the second is appended;
         * children without importance (behind the point, or facing away) are left out. */
        int at = best;
        for (int c = 0; c < 2; c++) {
            if (!(ic[c] > 0.0f)) continue;
            if (at < 0) at = k++;
            nodes[at] = child[c];
            prob[at] = parent * (ic[c] / sum);
            at = -1;
        }
        if (at >= 0) { /* neither child has importance: drop the entry */
            nodes[at] = nodes[k - 1];
            prob[at] = prob[k - 1];
            k--;
        }
    }
    if (visited) *visited = seen;
    return k;
}

float pn_light_bvh_pmf(const pn_light_bvh *t, vec3 p, vec3 n, int light) {
    if (light < 0 || light >= t->light_count) return 0.0f;
    double p_inf = infinite_share(t);
    int node = t->node_of_light[light];
    if (node < 0) {
        for (int k = 0; k < t->infinite_count; k++)
            if (t->infinite[k] == light) return (float)(p_inf / (double)t->infinite_count);
        return 0.0f;
    }
    if (!(pn_light_bounds_importance(&t->nodes[node].b, p, n) > 0.0f)) return 0.0f;
    double prob = 1.0;
    while (t->nodes[node].parent >= 0) {
        int parent = t->nodes[node].parent;
        double i0 = (double)pn_light_bounds_importance(&t->nodes[parent + 1].b, p, n);
        double i1 = (double)pn_light_bounds_importance(&t->nodes[t->nodes[parent].second].b, p, n);
        double mine = node == parent + 1 ? i0 : i1;
        if (!(i0 + i1 > 0.0)) return 0.0f;
        prob *= mine / (i0 + i1);
        node = parent;
    }
    return (float)(prob * (1.0 - p_inf));
}
