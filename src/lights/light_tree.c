/* light_tree.c — agglomerative construction of the Lightcuts light tree (see light_tree.h). */
#include "lights/light_tree.h"

#include "core/clock.h"
#include "core/rng.h"

#include <stdlib.h>
#include <string.h>

float pn_light_tree_metric(int kind, vec3 lo, vec3 hi, float half, float weight, float scene_diagonal) {
    float a2 = v3_length2(v3_sub(hi, lo));
    float m = a2;
    if (kind == PN_VPL_ORIENTED) {
        float c = 1.0f - cosf(fminf(half, PN_PI));
        m += scene_diagonal * scene_diagonal * c * c;
    }
    return weight * m;
}

/* 10-bit-per-axis Morton code of a point in a box. */
static uint32_t spread_bits(uint32_t x) {
    x &= 0x3ffu;
    x = (x | (x << 16)) & 0x030000ffu;
    x = (x | (x << 8)) & 0x0300f00fu;
    x = (x | (x << 4)) & 0x030c30c3u;
    x = (x | (x << 2)) & 0x09249249u;
    return x;
}

static uint32_t morton(vec3 p, vec3 lo, vec3 inv_ext) {
    uint32_t x = (uint32_t)fminf(1023.0f, fmaxf(0.0f, (p.x - lo.x) * inv_ext.x * 1023.0f));
    uint32_t y = (uint32_t)fminf(1023.0f, fmaxf(0.0f, (p.y - lo.y) * inv_ext.y * 1023.0f));
    uint32_t z = (uint32_t)fminf(1023.0f, fmaxf(0.0f, (p.z - lo.z) * inv_ext.z * 1023.0f));
    return (spread_bits(x) << 2) | (spread_bits(y) << 1) | spread_bits(z);
}

typedef struct keyed {
    uint64_t key;
    int32_t node;
} keyed;

static int cmp_keyed(const void *a, const void *b) {
    const keyed *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->node < y->node ? -1 : (x->node > y->node);
}

static float pair_cost(const pn_light_tree *t, int kind, int32_t ia, int32_t ib) {
    /* In node order, so that cost(a, b) == cost(b, a) bit for bit (mutual-best pairs rely on it). */
    if (ia > ib) {
        int32_t tmp = ia;
        ia = ib;
        ib = tmp;
    }
    const pn_light_node *a = &t->nodes[ia], *b = &t->nodes[ib];
    vec3 lo = v3_min(a->lo, b->lo), hi = v3_max(a->hi, b->hi);
    float half = 0.0f;
    if (kind == PN_VPL_ORIENTED) {
        vec3 axis;
        pn_cone_merge(a->axis, a->half, b->axis, b->half, &axis, &half);
    }
    return pn_light_tree_metric(kind, lo, hi, half, a->weight + b->weight, t->scene_diagonal);
}

/* Builds one tree over the leaves nodes[first .. first+count); returns its root. */
static int32_t build_kind(pn_light_tree *t, int kind, int32_t first, int32_t count, uint64_t seed, keyed *list,
                          int32_t *best, float *best_cost) {
    if (count == 0) return -1;
    int32_t n = count;
    for (int32_t i = 0; i < n; i++) list[i].node = first + i;
    while (n > 1) {
        /* Morton order of the current clusters (box centres, or directions). */
        vec3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
        for (int32_t i = 0; i < n; i++) {
            const pn_light_node *c = &t->nodes[list[i].node];
            vec3 m = v3_scale(v3_add(c->lo, c->hi), 0.5f);
            lo = v3_min(lo, m);
            hi = v3_max(hi, m);
        }
        vec3 ext = v3_sub(hi, lo);
        vec3 inv =
            v3(ext.x > 0 ? 1.0f / ext.x : 0.0f, ext.y > 0 ? 1.0f / ext.y : 0.0f, ext.z > 0 ? 1.0f / ext.z : 0.0f);
        for (int32_t i = 0; i < n; i++) {
            const pn_light_node *c = &t->nodes[list[i].node];
            uint64_t key = morton(v3_scale(v3_add(c->lo, c->hi), 0.5f), lo, inv);
            if (kind == PN_VPL_ORIENTED) /* normals as the low bits: similar directions stay close */
                key = (key << 9) | (uint64_t)morton(c->axis, v3(-1, -1, -1), v3(0.5f, 0.5f, 0.5f)) >> 21;
            list[i].key = key;
        }
        qsort(list, (size_t)n, sizeof *list, cmp_keyed);
        for (int32_t i = 0; i < n; i++) {
            best[i] = -1;
            best_cost[i] = INFINITY;
            int32_t j0 = i - PN_LIGHT_TREE_WINDOW < 0 ? 0 : i - PN_LIGHT_TREE_WINDOW;
            int32_t j1 = i + PN_LIGHT_TREE_WINDOW >= n ? n - 1 : i + PN_LIGHT_TREE_WINDOW;
            for (int32_t j = j0; j <= j1; j++) {
                if (j == i) continue;
                float c = pair_cost(t, kind, list[i].node, list[j].node);
                if (c < best_cost[i] || (c == best_cost[i] && best[i] >= 0 && j < best[i])) {
                    best_cost[i] = c;
                    best[i] = j;
                }
            }
        }
        int32_t m = 0;
        int32_t merged = 0;
        for (int32_t i = 0; i < n; i++) {
            int32_t j = best[i];
            if (j >= 0 && best[j] == i) {
                if (j < i) continue; /* merged when i was j's partner */
                const pn_light_node *a = &t->nodes[list[i].node], *b = &t->nodes[list[j].node];
                pn_light_node p;
                memset(&p, 0, sizeof p);
                p.lo = v3_min(a->lo, b->lo);
                p.hi = v3_max(a->hi, b->hi);
                if (kind == PN_VPL_ORIENTED) pn_cone_merge(a->axis, a->half, b->axis, b->half, &p.axis, &p.half);
                p.intensity = v3_add(a->intensity, b->intensity);
                p.weight = a->weight + b->weight;
                p.left = list[i].node;
                p.right = list[j].node;
                p.count = a->count + b->count;
                float u = pn_hash_unit(pn_hash3(seed, (uint64_t)p.left, (uint64_t)p.right));
                float pa = p.weight > 0.0f ? a->weight / p.weight : 0.5f;
                p.rep = u < pa ? a->rep : b->rep;
                int32_t idx = t->node_count++;
                t->nodes[idx] = p;
                list[m++].node = idx;
                merged++;
            } else {
                list[m++].node = list[i].node;
            }
        }
        if (merged == 0) return -2; /* cannot happen: the cheapest pair is mutually best */
        n = m;
    }
    return list[0].node;
}

/* Renumbers the nodes in depth-first pre-order (each node followed by its left subtree, then its
 * right one; the trees one after the other). The agglomerative build appends a parent after all
 * the nodes merged before it, so a parent and its children lie far apart in memory and a top-down
 * descent (a cut, a Phase II pair stack) missed the cache on nearly every child it visited; in
 * pre-order a left child is the next node and subtrees are contiguous. Same tree, same
 * representatives: only the indices change. */
static bool depth_first_order(pn_light_tree *t) {
    if (t->node_count == 0) return true;
    pn_light_node *dst = malloc((size_t)t->node_count * sizeof *dst);
    int32_t *stack = malloc((size_t)t->node_count * sizeof *stack);
    if (!dst || !stack) {
        free(dst);
        free(stack);
        return false;
    }
    int32_t m = 0;
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) {
        if (t->roots[k] < 0) continue;
        int32_t sp = 0;
        stack[sp++] = t->roots[k];
        t->roots[k] = m;
        while (sp > 0) {
            int32_t at = m++;
            dst[at] = t->nodes[stack[--sp]];
            if (dst[at].left >= 0) {
                stack[sp++] = dst[at].right; /* popped after the whole left subtree */
                stack[sp++] = dst[at].left;
            }
        }
    }
    free(stack);
    /* The children's new indices (dst still holds the old ones): the left child is the next node,
     * the right one follows the left subtree, which has 2 * (its VPLs) - 1 nodes (every internal
     * node has two children, every leaf one VPL). */
    for (int32_t i = 0; i < m; i++) {
        if (dst[i].left < 0) continue;
        int32_t left_count = t->nodes[dst[i].left].count;
        dst[i].left = i + 1;
        dst[i].right = i + 1 + (2 * left_count - 1);
    }
    free(t->nodes);
    t->nodes = dst;
    t->node_count = m;
    return true;
}

pn_status pn_light_tree_build(const pn_vpl_set *set, float scene_diagonal, uint64_t seed, pn_light_tree *out,
                              pn_err *err) {
    memset(out, 0, sizeof *out);
    double t0 = pn_clock_seconds();
    uint32_t n = set->count;
    out->scene_diagonal = scene_diagonal;
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) out->roots[k] = -1;
    size_t cap = n > 0 ? 2u * (size_t)n : 1u;
    out->nodes = calloc(cap, sizeof *out->nodes);
    keyed *list = malloc((n ? n : 1) * sizeof *list);
    int32_t *best = malloc((n ? n : 1) * sizeof *best);
    float *best_cost = malloc((n ? n : 1) * sizeof *best_cost);
    if (!out->nodes || !list || !best || !best_cost) {
        free(list);
        free(best);
        free(best_cost);
        free(out->nodes);
        out->nodes = NULL;
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light tree of %u VPLs", n);
    }
    /* Leaves, grouped by kind. */
    int32_t first[PN_VPL_KIND_COUNT], count[PN_VPL_KIND_COUNT];
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) {
        first[k] = out->node_count;
        for (uint32_t i = 0; i < n; i++) {
            const pn_vpl *v = &set->vpls[i];
            if (v->kind != k) continue;
            pn_light_node *l = &out->nodes[out->node_count++];
            l->lo = l->hi = v->p;
            l->axis = k == PN_VPL_ORIENTED ? v->n : v3(0, 0, 1);
            l->half = 0.0f;
            l->intensity = v->intensity;
            l->weight = v3_luminance(v->intensity);
            l->left = l->right = -1;
            l->rep = (int32_t)i;
            l->count = 1;
        }
        count[k] = out->node_count - first[k];
    }
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) {
        int32_t r = build_kind(out, k, first[k], count[k], pn_hash64(seed + (uint64_t)k), list, best, best_cost);
        if (r == -2) {
            free(list);
            free(best);
            free(best_cost);
            pn_light_tree_free(out);
            return pn_err_set(err, PN_ERROR_INTERNAL, "light tree construction made no progress");
        }
        out->roots[k] = r;
    }
    free(list);
    free(best);
    free(best_cost);
    if (!depth_first_order(out)) {
        pn_light_tree_free(out);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory ordering the light tree of %u VPLs", n);
    }
    for (int32_t i = 0; i < out->node_count; i++) {
        pn_light_node *nd = &out->nodes[i];
        nd->cos_half = nd->half >= PN_PI ? -1.0f : cosf(nd->half);
        nd->sin_half = nd->half >= PN_PI ? 0.0f : sinf(nd->half);
    }
    out->seconds = pn_clock_seconds() - t0;
    return PN_OK;
}

pn_status pn_light_tree_order_vpls(pn_light_tree *tree, pn_vpl_set *set, pn_err *err) {
    double t0 = pn_clock_seconds();
    uint32_t n = set->count;
    if (n == 0) return PN_OK;
    pn_vpl *vpls = malloc((size_t)n * sizeof *vpls);
    int32_t *to = malloc((size_t)n * sizeof *to);
    if (!vpls || !to) {
        free(vpls);
        free(to);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory ordering %u VPLs", n);
    }
    /* The nodes are in pre-order (depth_first_order), so their leaves come in the order of a
     * depth-first walk. */
    uint32_t m = 0;
    for (int32_t i = 0; i < tree->node_count; i++) {
        pn_light_node *nd = &tree->nodes[i];
        if (nd->left >= 0) continue;
        to[nd->rep] = (int32_t)m;
        vpls[m++] = set->vpls[nd->rep];
    }
    if (m != n) { /* every VPL is one leaf */
        free(vpls);
        free(to);
        return pn_err_set(err, PN_ERROR_INTERNAL, "light tree has %u leaves for %u VPLs", m, n);
    }
    for (int32_t i = 0; i < tree->node_count; i++) tree->nodes[i].rep = to[tree->nodes[i].rep];
    free(to);
    free(set->vpls);
    set->vpls = vpls;
    tree->seconds += pn_clock_seconds() - t0;
    return PN_OK;
}

void pn_light_tree_free(pn_light_tree *tree) {
    if (!tree) return;
    free(tree->nodes);
    memset(tree, 0, sizeof *tree);
}
