/* cluster_tree.c — light cluster hierarchies of Donikian et al. 2006, "Iterative Adaptive
 * Sampling for Accurate Direct Illumination", §4.3 / §4.3.1, and the per-point cut of §4.3.
 *
 * Construction (§4.3.1: "a greedy bottom up algorithm ... progressively pairing clusters together
 * starting with the pair that has the smallest bounding sphere"), done exactly but fast:
 *
 *   cost(A, B) = radius of the smallest sphere enclosing A's and B's spheres
 *              = max(rA, rB, (|cA - cB| + rA + rB) / 2).
 *
 * The cost is "reducible": the merged sphere of A and B contains both, so any sphere enclosing
 * it and C also encloses A and C, hence cost(A+B, C) >= min(cost(A, C), cost(B, C)). So a merge
 * never gives any other cluster a partner cheaper than the one it had. Every live cluster keeps
 * its nearest partner (by cost) as one (cost, cluster) entry of a binary min-heap (core/heap.h;
 * equal costs to the lower cluster index, the partner recorded per cluster); the heap minimum is
 * the globally cheapest pair. Entries are invalidated lazily: when popped, an entry of a dead
 * cluster is dropped, and an entry whose partner has died is re-queried and pushed again (by
 * reducibility its old cost is a lower bound of the new one, so the heap order stays valid).
 *
 * Nearest-partner queries run on a k-d tree over the live clusters' centres (median splits,
 * leaves of <= 8 at build time), each node with the box of its centres, the smallest radius below
 * it and a live count; a subtree is pruned when max(rC, rmin, (dist(cC, box) + rC + rmin) / 2)
 * exceeds the best cost found, and a candidate when a float bound of its cost does. Merged
 * clusters are inserted by descending the split planes (growing the boxes on the way; each k-d
 * leaf keeps a linked list), dead ones unlinked; the tree is rebuilt whenever the live count has
 * halved, so boxes and radii stay tight and the total rebuild work is O(n log n).
 *
 * After the merges, light_order is laid out depth-first so each subtree's lights are contiguous,
 * and node aggregates (power, bounding box, normal cone with emission spread) are filled bottom-up.
 *
 * A light within a node is picked by power (the paper's "relative intensities", pn_cluster_pick)
 * or, not in the paper (ias-cluster-pick, an option), by a descent of the node's subtree by an
 * importance bound at the shading point (pn_cluster_pick_importance; Conty & Kulla 2018's idea on
 * these trees' spheres and cones).
 */
#include "lights/cluster_tree.h"

#include "core/heap.h"

#include <limits.h>
#include <stdlib.h>
#include <string.h>

#define PN_CLUSTER_KD_LEAF 8
#define PN_CLUSTER_KD_STACK 128
/* Slack on the k-d tree's lower bound, so float rounding never prunes the true nearest. */
#define PN_CLUSTER_PRUNE_SLACK 1e-5f
/* Angular margin (radians) of the conservative facing-away test of interior nodes. */
#define PN_CLUSTER_ANGLE_MARGIN 1e-4f

/* ---------------------------------------------------------------- per-light quantities */

float pn_cluster_light_power(const pn_light *l) {
    float lum = fmaxf(v3_luminance(l->emit), 0.0f); /* fmaxf also turns NaN into 0 */
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_GONIOMETRIC: return 4.0f * PN_PI * lum;
    case PN_LIGHT_SPOT: {
        float f = 1.0f - 0.5f * (l->cos_falloff_start + l->cos_total_width);
        return 2.0f * PN_PI * lum * fmaxf(f, 0.0f);
    }
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE:
    case PN_LIGHT_DISK: return PN_PI * lum * fmaxf(l->area, 0.0f) * (l->two_sided ? 2.0f : 1.0f);
    case PN_LIGHT_SPHERE: return PN_PI * lum * 4.0f * PN_PI * l->radius * l->radius;
    case PN_LIGHT_DISTANT: return lum;
    case PN_LIGHT_PROJECTION: return fmaxf(l->power, 0.0f); /* luminance(emit * phi), exact (lights/projection.c) */
    default: return 0.0f;
    }
}

static int dominant_tree(vec3 d) {
    float ax = fabsf(d.x), ay = fabsf(d.y), az = fabsf(d.z);
    if (ax >= ay && ax >= az) return d.x >= 0.0f ? PN_TREE_POS_X : PN_TREE_NEG_X;
    if (ay >= az) return d.y >= 0.0f ? PN_TREE_POS_Y : PN_TREE_NEG_Y;
    return d.z >= 0.0f ? PN_TREE_POS_Z : PN_TREE_NEG_Z;
}

int pn_cluster_light_tree(const pn_light *l) {
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_SPHERE:
    case PN_LIGHT_GONIOMETRIC: return PN_TREE_OMNI;
    case PN_LIGHT_SPOT:
    case PN_LIGHT_PROJECTION: return dominant_tree(l->n);
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE:
    case PN_LIGHT_DISK: return l->two_sided ? PN_TREE_OMNI : dominant_tree(l->n);
    case PN_LIGHT_DISTANT: return PN_CLUSTER_SINGLE;
    default: return PN_CLUSTER_EXCLUDED;
    }
}

/* The float at or above x. */
static float round_up(double x) {
    float f = (float)x;
    if ((double)f < x) f = nextafterf(f, INFINITY);
    return f;
}

static double dist_d(vec3 a, vec3 b) {
    double dx = (double)a.x - (double)b.x, dy = (double)a.y - (double)b.y, dz = (double)a.z - (double)b.z;
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Vertices of a triangle or rectangle light; returns their number. */
static int planar_vertices(const pn_light *l, vec3 v[4]) {
    v[0] = l->p;
    v[1] = v3_add(l->p, l->e1);
    v[2] = v3_add(l->p, l->e2);
    if (l->kind == PN_LIGHT_TRIANGLE) return 3;
    v[3] = v3_add(v3_add(l->p, l->e1), l->e2);
    return 4;
}

void pn_cluster_light_sphere(const pn_light *l, vec3 *center, float *radius) {
    switch (l->kind) {
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE: {
        vec3 v[4];
        int k = planar_vertices(l, v);
        double s[3] = {0.0, 0.0, 0.0};
        for (int i = 0; i < k; i++) {
            s[0] += (double)v[i].x;
            s[1] += (double)v[i].y;
            s[2] += (double)v[i].z;
        }
        vec3 c = v3((float)(s[0] / k), (float)(s[1] / k), (float)(s[2] / k));
        double r = 0.0;
        for (int i = 0; i < k; i++) r = fmax(r, dist_d(c, v[i]));
        *center = c;
        *radius = round_up(r);
        return;
    }
    case PN_LIGHT_DISK:
    case PN_LIGHT_SPHERE:
        *center = l->p;
        *radius = fmaxf(l->radius, 0.0f);
        return;
    case PN_LIGHT_DISTANT:
        *center = l->n;
        *radius = 0.0f;
        return;
    default:
        *center = l->p;
        *radius = 0.0f;
        return;
    }
}

void pn_cluster_light_box(const pn_light *l, vec3 *lo, vec3 *hi) {
    switch (l->kind) {
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE: {
        vec3 v[4];
        int k = planar_vertices(l, v);
        *lo = *hi = v[0];
        for (int i = 1; i < k; i++) {
            *lo = v3_min(*lo, v[i]);
            *hi = v3_max(*hi, v[i]);
        }
        return;
    }
    case PN_LIGHT_DISK: {
        /* A disk's extent along axis i is r sqrt(1 - n_i^2). */
        vec3 e = v3(l->radius * sqrtf(fmaxf(0.0f, 1.0f - l->n.x * l->n.x)),
                    l->radius * sqrtf(fmaxf(0.0f, 1.0f - l->n.y * l->n.y)),
                    l->radius * sqrtf(fmaxf(0.0f, 1.0f - l->n.z * l->n.z)));
        e = v3_scale(e, 1.0f + 1e-6f);
        *lo = v3_sub(l->p, e);
        *hi = v3_add(l->p, e);
        return;
    }
    case PN_LIGHT_SPHERE: {
        vec3 e = v3(l->radius, l->radius, l->radius);
        *lo = v3_sub(l->p, e);
        *hi = v3_add(l->p, e);
        return;
    }
    default: *lo = *hi = l->p; return;
    }
}

/* Lexicographic order of spheres, so merging is symmetric bit for bit. */
static bool sphere_before(vec3 a, float ra, vec3 b, float rb) {
    if (ra != rb) return ra < rb;
    if (a.x != b.x) return a.x < b.x;
    if (a.y != b.y) return a.y < b.y;
    return a.z < b.z;
}

void pn_cluster_merge_spheres(vec3 c1, float r1, vec3 c2, float r2, vec3 *center, float *radius) {
    if (sphere_before(c2, r2, c1, r1)) {
        vec3 tc = c1;
        float tr = r1;
        c1 = c2;
        r1 = r2;
        c2 = tc;
        r2 = tr;
    }
    double d = dist_d(c1, c2);
    if (d + (double)r2 <= (double)r1) {
        *center = c1;
        *radius = r1;
        return;
    }
    if (d + (double)r1 <= (double)r2) {
        *center = c2;
        *radius = r2;
        return;
    }
    double r = 0.5 * (d + (double)r1 + (double)r2);
    double t = (r - (double)r1) / d; /* d > 0 here: with d = 0 one sphere contains the other */
    vec3 c = v3((float)((double)c1.x + t * ((double)c2.x - (double)c1.x)),
                (float)((double)c1.y + t * ((double)c2.y - (double)c1.y)),
                (float)((double)c1.z + t * ((double)c2.z - (double)c1.z)));
    /* The centre was rounded: make sure the sphere still holds both children. */
    r = fmax(r, fmax(dist_d(c, c1) + (double)r1, dist_d(c, c2) + (double)r2));
    *center = c;
    *radius = round_up(r);
}

float pn_cluster_solid_angle(vec3 center, float radius, vec3 p) {
    float d2 = v3_length2(v3_sub(center, p));
    float r2 = radius * radius;
    if (d2 <= r2) return 4.0f * PN_PI;
    float x = r2 / d2;
    /* 2 pi (1 - sqrt(1 - x)) without the cancellation for small x */
    return 2.0f * PN_PI * x / (1.0f + sqrtf(1.0f - x));
}

bool pn_cluster_light_culled(const pn_light *l, vec3 p, vec3 n) {
    bool horizon = !v3_is_zero(n);
    switch (l->kind) {
    case PN_LIGHT_POINT: return horizon && v3_dot(v3_sub(l->p, p), n) <= 0.0f;
    case PN_LIGHT_GONIOMETRIC: {
        if (horizon && v3_dot(v3_sub(l->p, p), n) <= 0.0f) return true;
        if (v3_is_zero(l->n)) return false;
        /* a measured luminaire dark beyond its cone (lights/lights.c sets n and the cosine) */
        vec3 d = v3_sub(p, l->p);
        return v3_dot(d, l->n) < l->cos_total_width * sqrtf(v3_length2(d));
    }
    case PN_LIGHT_SPOT: {
        vec3 d = v3_sub(p, l->p);
        float d2 = v3_length2(d);
        if (!(d2 > 0.0f)) return true;
        if (horizon && v3_dot(d, n) >= 0.0f) return true;
        return v3_dot(d, l->n) <= l->cos_total_width * sqrtf(d2);
    }
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE: {
        if (!l->two_sided && v3_dot(v3_sub(p, l->p), l->n) <= 0.0f) return true;
        if (!horizon) return false;
        vec3 v[4];
        int k = planar_vertices(l, v);
        for (int i = 0; i < k; i++)
            if (v3_dot(v3_sub(v[i], p), n) > 0.0f) return false;
        return true;
    }
    case PN_LIGHT_DISK: {
        if (!l->two_sided && v3_dot(v3_sub(p, l->p), l->n) <= 0.0f) return true;
        if (!horizon) return false;
        float c = v3_dot(l->n, n);
        float ext = l->radius * sqrtf(fmaxf(0.0f, 1.0f - c * c));
        return v3_dot(v3_sub(l->p, p), n) + ext <= 0.0f;
    }
    case PN_LIGHT_SPHERE: return horizon && v3_dot(v3_sub(l->p, p), n) + l->radius <= 0.0f;
    case PN_LIGHT_DISTANT: return horizon && v3_dot(l->n, n) <= 0.0f;
    case PN_LIGHT_PROJECTION: {
        /* The cone around the axis that holds the frustum (lights/projection.c): conservative,
         * a point inside the cone but outside the frustum is not culled. */
        vec3 d = v3_sub(p, l->p);
        float d2 = v3_length2(d);
        if (!(d2 > 0.0f)) return true;
        if (horizon && v3_dot(d, n) >= 0.0f) return true;
        return v3_dot(d, l->n) <= l->cos_total_width * sqrtf(d2);
    }
    default: return false;
    }
}

/* ---------------------------------------------------------------- normal cones */

static float clamp_unit(float x) {
    return fminf(1.0f, fmaxf(-1.0f, x));
}

static float angle_between(vec3 a, vec3 b) {
    return atan2f(v3_length(v3_cross(a, b)), v3_dot(a, b));
}

/* The cosine of angle t, rounded so that acos of it is never below t. */
static float cos_conservative(float t) {
    return nextafterf(nextafterf(cosf(t), -2.0f), -2.0f);
}

/* The smallest cone (as pbrt-v4's DirectionCone union) containing cones (wa, ca) and (wb, cb). */
void pn_cluster_merge_cones(vec3 wa, float ca, vec3 wb, float cb, vec3 *w, float *c) {
    if (ca <= -1.0f || cb <= -1.0f) {
        *w = ca <= -1.0f ? wa : wb;
        *c = -1.0f;
        return;
    }
    float ta = acosf(clamp_unit(ca)), tb = acosf(clamp_unit(cb));
    float td = angle_between(wa, wb);
    if (fminf(td + tb, PN_PI) <= ta) {
        *w = wa;
        *c = ca;
        return;
    }
    if (fminf(td + ta, PN_PI) <= tb) {
        *w = wb;
        *c = cb;
        return;
    }
    float to = 0.5f * (ta + td + tb);
    vec3 k = v3_cross(wa, wb);
    if (to >= PN_PI || !(v3_length2(k) > 0.0f)) {
        *w = wa;
        *c = -1.0f;
        return;
    }
    /* Rotate wa towards wb by to - ta about k (Rodrigues; k is orthogonal to wa). */
    k = v3_normalize(k);
    float tr = to - ta;
    vec3 r = v3_add(v3_scale(wa, cosf(tr)), v3_scale(v3_cross(k, wa), sinf(tr)));
    *w = v3_normalize(r);
    *c = cos_conservative(to);
}

/* ---------------------------------------------------------------- greedy construction */

/* Plain max/min (no NaN rules, so they compile to single instructions in the hot loops). */
static inline float max_f(float a, float b) {
    return a > b ? a : b;
}
static inline float min_f(float a, float b) {
    return a < b ? a : b;
}

typedef struct pn_kd_node {
    vec3 lo, hi;     /* box of the centres below (grows with insertions) */
    float rmin;      /* smallest radius ever below */
    int left, right; /* -1 for a k-d leaf */
    int parent;
    int alive; /* live clusters below */
    int axis;  /* split: left when centre[axis] < split */
    float split;
    int head; /* leaf: first cluster of its list */
} pn_kd_node;

/* A cluster's sphere, compact (16 bytes, where the forest's node is 140). */
typedef struct pn_build_item {
    vec3 center;
    float radius;
} pn_build_item;

/* An entry of a k-d leaf's doubly linked list: the cluster's sphere and index beside the links,
 * numbered in k-d leaf order when the k-d tree is built (each leaf's entries contiguous; merged
 * clusters appended), so that a leaf's candidates share cache lines. */
typedef struct pn_build_slot {
    vec3 center;
    float radius;
    int id, next, prev;
} pn_build_slot;

typedef struct pn_builder {
    pn_cluster_node *nodes;
    unsigned char *alive; /* per forest node */
    int *slot;            /* per forest node: its k-d leaf, or -1 */
    pn_build_item *it;    /* per forest node: its sphere */
    pn_build_slot *slots; /* the k-d leaves' lists (heads and links are slot indices) */
    int *slot_at;         /* per forest node: its slot while it is live */
    int slot_used;
    int *partner; /* per forest node: the partner of its entry in the heap */
    pn_kd_node *kd;
    int kd_count, kd_root;
    int *items; /* scratch for building the k-d tree */
    int alive_count, rebuild_below;
    pn_heap heap; /* (cost, cluster): the smallest cost first, ties to the lower cluster index */
    bool out_of_memory;
} pn_builder;

/* Moves the k-th smallest item (by centre coordinate `axis`) of items[0..n) to position k, with
 * smaller or equal ones before it (three-way quickselect: many equal keys stay linear). */
static void select_kth(int *items, int n, int k, const pn_build_item *nodes, int axis) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        float pivot = v3_get(nodes[items[lo + (hi - lo) / 2]].center, axis);
        int lt = lo, i = lo, gt = hi;
        while (i <= gt) {
            float v = v3_get(nodes[items[i]].center, axis);
            if (v < pivot) {
                int t = items[lt];
                items[lt++] = items[i];
                items[i++] = t;
            } else if (v > pivot) {
                int t = items[gt];
                items[gt--] = items[i];
                items[i] = t;
            } else {
                i++;
            }
        }
        if (k < lt)
            hi = lt - 1;
        else if (k > gt)
            lo = gt + 1;
        else
            return;
    }
}

static int kd_build(pn_builder *b, int begin, int end, int parent) {
    int id = b->kd_count++;
    pn_kd_node *kn = &b->kd[id];
    kn->parent = parent;
    kn->alive = end - begin;
    kn->left = kn->right = kn->head = -1;
    kn->axis = 0;
    kn->split = 0.0f;
    const pn_build_item *first = &b->it[b->items[begin]];
    kn->lo = kn->hi = first->center;
    kn->rmin = first->radius;
    for (int i = begin + 1; i < end; i++) {
        const pn_build_item *c = &b->it[b->items[i]];
        kn->lo = v3_min(kn->lo, c->center);
        kn->hi = v3_max(kn->hi, c->center);
        kn->rmin = min_f(kn->rmin, c->radius);
    }
    if (end - begin <= PN_CLUSTER_KD_LEAF) {
        int prev = -1;
        for (int i = begin; i < end; i++) {
            int c = b->items[i], e = b->slot_used++;
            b->slot[c] = id;
            b->slot_at[c] = e;
            b->slots[e] = (pn_build_slot){b->it[c].center, b->it[c].radius, c, -1, prev};
            if (prev >= 0)
                b->slots[prev].next = e;
            else
                kn->head = e;
            prev = e;
        }
        return id;
    }
    vec3 ext = v3_sub(kn->hi, kn->lo);
    int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    int mid = begin + (end - begin) / 2;
    select_kth(b->items + begin, end - begin, mid - begin, b->it, axis);
    float split = v3_get(b->it[b->items[mid]].center, axis);
    int left = kd_build(b, begin, mid, id);
    int right = kd_build(b, mid, end, id);
    kn = &b->kd[id];
    kn->left = left;
    kn->right = right;
    kn->axis = axis;
    kn->split = split;
    return id;
}

/* Rebuilds the k-d tree over the live clusters among nodes[base .. end): tight boxes and radii
 * again, and a depth that follows the shrinking count. */
static void kd_rebuild(pn_builder *b, int base, int end) {
    int n = 0;
    for (int i = base; i < end; i++)
        if (b->alive[i]) b->items[n++] = i;
    b->kd_count = 0;
    b->slot_used = 0;
    b->kd_root = kd_build(b, 0, n, -1);
    b->rebuild_below = n / 2;
}

static void kd_insert(pn_builder *b, int c) {
    const pn_build_item *nd = &b->it[c];
    int k = b->kd_root;
    for (;;) {
        pn_kd_node *kn = &b->kd[k];
        kn->lo = v3_min(kn->lo, nd->center);
        kn->hi = v3_max(kn->hi, nd->center);
        kn->rmin = min_f(kn->rmin, nd->radius);
        kn->alive++;
        if (kn->left < 0) break;
        k = v3_get(nd->center, kn->axis) < kn->split ? kn->left : kn->right;
    }
    pn_kd_node *leaf = &b->kd[k];
    const int e = b->slot_used++;
    b->slot[c] = k;
    b->slot_at[c] = e;
    b->slots[e] = (pn_build_slot){nd->center, nd->radius, c, leaf->head, -1};
    if (leaf->head >= 0) b->slots[leaf->head].prev = e;
    leaf->head = e;
    b->alive[c] = 1;
}

static void kd_remove(pn_builder *b, int c) {
    int s = b->slot[c];
    const int e = b->slot_at[c];
    int prev = b->slots[e].prev, next = b->slots[e].next;
    if (prev >= 0)
        b->slots[prev].next = next;
    else
        b->kd[s].head = next;
    if (next >= 0) b->slots[next].prev = prev;
    for (int k = s; k >= 0; k = b->kd[k].parent) b->kd[k].alive--;
    b->slot[c] = -1;
    b->alive[c] = 0;
}

/* A float lower bound of the merge cost (up to rounding), to skip the exact evaluation. */
static float cost_bound(const pn_build_item *x, const pn_build_slot *y) {
    float d = v3_length(v3_sub(x->center, y->center));
    return max_f(max_f(x->radius, y->radius), 0.5f * (d + x->radius + y->radius));
}

static float merge_cost(const pn_build_item *x, const pn_build_slot *y) {
    vec3 c;
    float r;
    pn_cluster_merge_spheres(x->center, x->radius, y->center, y->radius, &c, &r);
    return r;
}

/* The live cluster (other than c) whose merge with c has the smallest sphere; -1 if none. Ties
 * go to the lower index. */
static int nearest_partner(const pn_builder *b, int c, float *best_cost) {
    const pn_build_item *q = &b->it[c];
    float best = INFINITY;
    int best_id = -1;
    int stack[PN_CLUSTER_KD_STACK];
    int top = 0;
    stack[top++] = b->kd_root;
    while (top > 0) {
        const pn_kd_node *kn = &b->kd[stack[--top]];
        if (kn->alive == 0) continue;
        float dx = max_f(max_f(kn->lo.x - q->center.x, q->center.x - kn->hi.x), 0.0f);
        float dy = max_f(max_f(kn->lo.y - q->center.y, q->center.y - kn->hi.y), 0.0f);
        float dz = max_f(max_f(kn->lo.z - q->center.z, q->center.z - kn->hi.z), 0.0f);
        float dbox = sqrtf(dx * dx + dy * dy + dz * dz);
        float lb = max_f(max_f(q->radius, kn->rmin), 0.5f * (dbox + q->radius + kn->rmin));
        if (lb * (1.0f - PN_CLUSTER_PRUNE_SLACK) > best) continue;
        if (kn->left < 0) {
            for (int e = kn->head; e >= 0; e = b->slots[e].next) {
                const pn_build_slot *cand = &b->slots[e];
                const int j = cand->id;
                if (j == c) continue;
                if (cost_bound(q, cand) * (1.0f - PN_CLUSTER_PRUNE_SLACK) > best) continue;
                float cost = merge_cost(q, cand);
                if (cost < best || (cost == best && j < best_id)) {
                    best = cost;
                    best_id = j;
                }
            }
            continue;
        }
        /* Visit the child on the query's side of the split first (pushed last). */
        bool left_first = v3_get(q->center, kn->axis) < kn->split;
        if (top + 2 > PN_CLUSTER_KD_STACK) continue; /* cannot happen: depth ~ log2(n / 8) */
        stack[top++] = left_first ? kn->right : kn->left;
        stack[top++] = left_first ? kn->left : kn->right;
    }
    *best_cost = best;
    return best_id;
}

static bool push_nearest(pn_builder *b, int c) {
    float cost;
    int partner = nearest_partner(b, c, &cost);
    if (partner < 0) return true;
    b->partner[c] = partner;
    if (!pn_heap_push(&b->heap, cost, c)) b->out_of_memory = true;
    return !b->out_of_memory;
}

/* Merges the leaves nodes[base .. base+m) into internal nodes nodes[base+m .. base+2m-1), in
 * merge order; the root is the last. */
static bool build_tree(pn_builder *b, int base, int m, int tree) {
    if (m <= 1) return true;
    pn_heap_clear(&b->heap);
    for (int i = 0; i < m; i++) {
        b->alive[base + i] = 1;
        b->it[base + i].center = b->nodes[base + i].center;
        b->it[base + i].radius = b->nodes[base + i].radius;
    }
    b->alive_count = m;
    kd_rebuild(b, base, base + m);
    for (int i = 0; i < m; i++)
        if (!push_nearest(b, base + i)) return false;
    int next = base + m;
    while (b->alive_count > 1 && b->heap.count > 0) {
        /* A live cluster's entry is its only one (pushed when it was made or its last entry was
         * popped), so its partner is the one recorded; a dead cluster's entry is dropped. */
        const int a = (int)pn_heap_pop(&b->heap).payload, mate = b->partner[a];
        if (!b->alive[a]) continue;
        if (!b->alive[mate]) {
            if (!push_nearest(b, a)) return false;
            continue;
        }
        pn_cluster_node *nd = &b->nodes[next];
        const pn_cluster_node *na = &b->nodes[a], *nb = &b->nodes[mate];
        pn_cluster_merge_spheres(na->center, na->radius, nb->center, nb->radius, &nd->center, &nd->radius);
        b->it[next].center = nd->center;
        b->it[next].radius = nd->radius;
        nd->left = a < mate ? a : mate;
        nd->right = a < mate ? mate : a;
        nd->parent = -1;
        nd->light = -1;
        nd->tree = tree;
        b->nodes[a].parent = next;
        b->nodes[mate].parent = next;
        kd_remove(b, a);
        kd_remove(b, mate);
        b->alive_count--;
        if (b->alive_count < b->rebuild_below) {
            b->alive[next] = 1;
            kd_rebuild(b, base, next + 1);
        } else {
            kd_insert(b, next);
        }
        if (!push_nearest(b, next)) return false;
        next++;
    }
    return next == base + 2 * m - 1;
}

/* ---------------------------------------------------------------- forest */

void pn_cluster_forest_free(pn_cluster_forest *f) {
    if (!f) return;
    free(f->nodes);
    free(f->light_order);
    free(f->power_coarse);
    free(f->ranges);
    free(f->leaf_of_light);
    free(f->singles);
    free(f->power_prefix);
    memset(f, 0, sizeof *f);
    for (int t = 0; t < PN_TREE_COUNT; t++) f->roots[t] = -1;
}

static void init_leaf(pn_cluster_node *nd, const pn_light *l, int light, int tree) {
    memset(nd, 0, sizeof *nd);
    nd->left = nd->right = nd->parent = -1;
    nd->light = light;
    nd->tree = tree;
    pn_cluster_light_sphere(l, &nd->center, &nd->radius);
    pn_cluster_light_box(l, &nd->bmin, &nd->bmax);
    nd->power = pn_cluster_light_power(l);
    if (tree == PN_TREE_OMNI) {
        nd->axis = v3(0.0f, 0.0f, 0.0f);
        nd->cos_spread = -1.0f;
        nd->cos_emit = -1.0f;
    } else {
        nd->axis = tree < 0 ? l->n : v3_normalize(l->n);
        nd->cos_spread = 1.0f;
        nd->cos_emit = l->kind == PN_LIGHT_SPOT ? clamp_unit(l->cos_total_width) : 0.0f;
        if (l->kind == PN_LIGHT_PROJECTION) nd->cos_emit = clamp_unit(l->cos_total_width);
    }
}

pn_status pn_cluster_forest_build(const pn_lights *lights, pn_cluster_forest *out, pn_err *err) {
    memset(out, 0, sizeof *out);
    for (int t = 0; t < PN_TREE_COUNT; t++) out->roots[t] = -1;
    if (!lights || lights->count < 0) return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "cluster forest: no lights");
    int n = lights->count;
    int tree_size[PN_TREE_COUNT] = {0};
    int singles = 0, max_m = 0;
    for (int i = 0; i < n; i++) {
        const pn_light *l = &lights->lights[i];
        int t = pn_cluster_light_tree(l);
        if (t >= 0) {
            vec3 c;
            float r;
            pn_cluster_light_sphere(l, &c, &r);
            if (!v3_is_finite(c) || !isfinite(r))
                return pn_err_set(err, PN_ERROR_BAD_INPUT, "cluster forest: light %d has a non-finite extent", i);
            tree_size[t]++;
        } else if (t == PN_CLUSTER_SINGLE) {
            singles++;
        }
    }
    int base[PN_TREE_COUNT];
    int total = 0, tree_lights = 0;
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        base[t] = total;
        if (tree_size[t] > 0) total += 2 * tree_size[t] - 1;
        tree_lights += tree_size[t];
        if (tree_size[t] > max_m) max_m = tree_size[t];
    }
    int single_base = total;
    total += singles;
    int order_count = tree_lights + singles;

    out->light_count = n;
    out->node_count = total;
    out->order_count = order_count;
    out->single_count = singles;
    out->nodes = calloc((size_t)(total > 0 ? total : 1), sizeof *out->nodes);
    out->light_order = malloc((size_t)(order_count > 0 ? order_count : 1) * sizeof *out->light_order);
    out->leaf_of_light = malloc((size_t)(n > 0 ? n : 1) * sizeof *out->leaf_of_light);
    out->singles = malloc((size_t)(singles > 0 ? singles : 1) * sizeof *out->singles);
    out->power_prefix = malloc((size_t)(order_count + 1) * sizeof *out->power_prefix);
    pn_builder b;
    memset(&b, 0, sizeof b);
    b.nodes = out->nodes;
    b.alive = calloc((size_t)(total > 0 ? total : 1), 1);
    b.slot = malloc((size_t)(total > 0 ? total : 1) * sizeof *b.slot);
    b.partner = malloc((size_t)(total > 0 ? total : 1) * sizeof *b.partner);
    pn_heap_init(&b.heap, PN_HEAP_MIN | PN_HEAP_TIES_BY_PAYLOAD);
    b.items = malloc((size_t)(max_m > 0 ? max_m : 1) * sizeof *b.items);
    b.it = malloc((size_t)(total > 0 ? total : 1) * sizeof *b.it);
    b.slot_at = malloc((size_t)(total > 0 ? total : 1) * sizeof *b.slot_at);
    b.slots = malloc((size_t)(2 * max_m + 2) * sizeof *b.slots);
    b.kd = malloc((size_t)(2 * max_m + 1) * sizeof *b.kd);
    pn_status status = PN_OK;
    if (!out->nodes || !out->light_order || !out->leaf_of_light || !out->singles || !out->power_prefix || !b.alive ||
        !b.slot || !b.partner || !b.items || !b.it || !b.slot_at || !b.slots || !b.kd) {
        status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light cluster trees");
        goto done;
    }
    for (int i = 0; i < total; i++) b.slot[i] = -1;

    /* Leaves, in light order within each tree; singles after all trees. */
    int fill[PN_TREE_COUNT] = {0};
    int single_fill = 0;
    for (int i = 0; i < n; i++) {
        const pn_light *l = &lights->lights[i];
        int t = pn_cluster_light_tree(l);
        out->leaf_of_light[i] = -1;
        if (t >= 0) {
            int idx = base[t] + fill[t]++;
            init_leaf(&out->nodes[idx], l, i, t);
            out->leaf_of_light[i] = idx;
        } else if (t == PN_CLUSTER_SINGLE) {
            int idx = single_base + single_fill;
            init_leaf(&out->nodes[idx], l, i, -1);
            out->singles[single_fill++] = idx;
            out->leaf_of_light[i] = idx;
        }
    }

    for (int t = 0; t < PN_TREE_COUNT; t++) {
        if (tree_size[t] == 0) continue;
        if (!build_tree(&b, base[t], tree_size[t], t)) {
            status = b.out_of_memory
                         ? pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light cluster trees")
                         : pn_err_set(err, PN_ERROR_INTERNAL, "light cluster tree %d: construction failed", t);
            goto done;
        }
        out->roots[t] = base[t] + 2 * tree_size[t] - 2;
    }

    /* Aggregates bottom-up: children always have smaller indices than their parent. */
    {
        double *pw = malloc((size_t)(total > 0 ? total : 1) * sizeof *pw);
        if (!pw) {
            status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light cluster trees");
            goto done;
        }
        for (int i = 0; i < total; i++) {
            pn_cluster_node *nd = &out->nodes[i];
            if (nd->left < 0) {
                pw[i] = (double)nd->power;
                nd->count = 1;
                continue;
            }
            const pn_cluster_node *l = &out->nodes[nd->left], *r = &out->nodes[nd->right];
            pw[i] = pw[nd->left] + pw[nd->right];
            nd->power = (float)pw[i];
            nd->count = l->count + r->count;
            nd->bmin = v3_min(l->bmin, r->bmin);
            nd->bmax = v3_max(l->bmax, r->bmax);
            if (nd->tree == PN_TREE_OMNI) {
                nd->axis = v3(0.0f, 0.0f, 0.0f);
                nd->cos_spread = -1.0f;
                nd->cos_emit = -1.0f;
            } else {
                pn_cluster_merge_cones(l->axis, l->cos_spread, r->axis, r->cos_spread, &nd->axis, &nd->cos_spread);
                nd->cos_emit = fminf(l->cos_emit, r->cos_emit);
            }
        }
        free(pw);
    }
    /* Depth-first layout: each root's range, then parents before children (descending index). */
    {
        int offset = 0;
        for (int t = 0; t < PN_TREE_COUNT; t++) {
            if (out->roots[t] < 0) continue;
            out->nodes[out->roots[t]].first = offset;
            offset += out->nodes[out->roots[t]].count;
        }
        for (int i = single_base - 1; i >= 0; i--) {
            const pn_cluster_node *nd = &out->nodes[i];
            if (nd->left < 0) {
                out->light_order[nd->first] = nd->light;
                continue;
            }
            out->nodes[nd->left].first = nd->first;
            out->nodes[nd->right].first = nd->first + out->nodes[nd->left].count;
        }
        for (int s = 0; s < singles; s++) {
            pn_cluster_node *nd = &out->nodes[single_base + s];
            nd->first = offset + s;
            out->light_order[offset + s] = nd->light;
        }
        out->power_prefix[0] = 0.0;
        for (int i = 0; i < order_count; i++)
            out->power_prefix[i + 1] =
                out->power_prefix[i] + (double)pn_cluster_light_power(&lights->lights[out->light_order[i]]);
        out->coarse_count = order_count / PN_CLUSTER_COARSE + 1;
        out->power_coarse = malloc((size_t)out->coarse_count * sizeof *out->power_coarse);
        if (!out->power_coarse) {
            status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light cluster trees");
            goto done;
        }
        out->ranges = malloc(2 * (size_t)(total > 0 ? total : 1) * sizeof *out->ranges);
        if (!out->ranges) {
            status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light cluster trees");
            goto done;
        }
        for (int i = 0; i < total; i++) {
            out->ranges[2 * i] = out->nodes[i].first;
            out->ranges[2 * i + 1] = out->nodes[i].count;
        }
        for (int j = 0; j < out->coarse_count; j++) {
            int at = (j + 1) * PN_CLUSTER_COARSE;
            out->power_coarse[j] = out->power_prefix[at < order_count ? at : order_count];
        }
    }

done:
    /* The normal-cone half-angles the cut's facing-away test adds up, once per node. */
    for (int i = 0; status == PN_OK && i < out->node_count; i++) {
        pn_cluster_node *nd = &out->nodes[i];
        nd->cone_angle = acosf(clamp_unit(nd->cos_spread)) + acosf(clamp_unit(nd->cos_emit));
        double a = (double)nd->cone_angle + (double)PN_CLUSTER_ANGLE_MARGIN;
        nd->cut_cos = a < (double)PN_PI ? (float)cos(a) : -2.0f;
        nd->cut_sin = a < (double)PN_PI ? (float)sin(a) : 0.0f;
    }
    free(b.alive);
    free(b.slot);
    free(b.partner);
    free(b.items);
    free(b.it);
    free(b.slot_at);
    free(b.slots);
    free(b.kd);
    pn_heap_free(&b.heap);
    if (status != PN_OK) pn_cluster_forest_free(out);
    return status;
}

/* ---------------------------------------------------------------- cut */

/* Conservative: true only if no light below interior node nd can light p. */
static bool node_culled(const pn_cluster_node *nd, vec3 p, vec3 n, bool horizon) {
    vec3 pc = v3_sub(nd->center, p);
    if (horizon) {
        /* Below the tangent plane: the sphere, or the box (tighter for flat groups of lights). */
        float s = v3_dot(pc, n);
        if (s + nd->radius < -1e-5f * (fabsf(s) + nd->radius)) return true;
        /* A sphere wholly above the plane holds lights above it: the box cannot be below. */
        if (s > nd->radius) goto cone;
        vec3 bc = v3_scale(v3_add(nd->bmin, nd->bmax), 0.5f), he = v3_scale(v3_sub(nd->bmax, nd->bmin), 0.5f);
        float sb = v3_dot(v3_sub(bc, p), n);
        float reach = fabsf(n.x) * he.x + fabsf(n.y) * he.y + fabsf(n.z) * he.z;
        if (sb + reach < -1e-5f * (fabsf(sb) + reach)) return true;
    }
cone:
    if (nd->cos_spread > -1.0f && nd->cos_emit > -1.0f) {
        float d = v3_length(pc);
        if (d > nd->radius * (1.0f + 1e-5f) && d > 0.0f) {
            /* Every emitting normal is within theta_o of the axis, every direction from a point of
             * the sphere to p within theta_b of w: no light reaches p when the smallest possible
             * angle between them still exceeds the emission half-angle theta_e. */
            vec3 w = v3_scale(pc, -1.0f / d);
            /* theta_w - theta_b > A (A = the cone angle plus the margin) is tested as
             * cos(theta_w) < cos(A + theta_b), which holds only while A + theta_b < pi; with
             * sin(theta_b) = r/d that is A <= pi/2 or r/d < sin(A). The cosine side keeps a
             * small margin of its own for the rounding of the dot product. */
            if (nd->cut_cos > -1.5f) {
                float sb = fminf(nd->radius / d, 1.0f);
                if (nd->cut_cos >= 0.0f || sb < nd->cut_sin) {
                    float cb = sqrtf(fmaxf(0.0f, 1.0f - sb * sb));
                    float limit = nd->cut_cos * cb - nd->cut_sin * sb;
                    if (v3_dot(nd->axis, w) < limit - 2e-6f) return true;
                }
            }
        }
    }
    return false;
}

enum { PN_CUT_DESCEND, PN_CUT_TAKE, PN_CUT_CULL };

/* The solid-angle test without a square root where it is clear: a sphere of radius r at
 * distance d subtends 2 pi (1 - sqrt(1 - x)), x = r^2 / d^2, which is below the limit exactly when
 * x is below x_limit = 1 - (1 - limit / 2 pi)^2. Within a relative 1e-4 of x_limit the exact
 * function decides, so that the cut agrees with pn_cluster_solid_angle everywhere. */
typedef struct cut_limit {
    float max_solid_angle;
    float x_low, x_high;
} cut_limit;

static cut_limit make_cut_limit(float max_solid_angle) {
    cut_limit c = {max_solid_angle, 0.0f, 0.0f};
    double a = 1.0 - (double)max_solid_angle / (2.0 * (double)PN_PI);
    if (!(a > 0.0)) {
        /* Limits of 2 pi and more: the exact function decides every case. */
        c.x_high = INFINITY;
        return c;
    }
    double x = 1.0 - a * a;
    c.x_low = (float)(x * (1.0 - 1e-4));
    c.x_high = (float)(x * (1.0 + 1e-4));
    return c;
}

static int classify(const pn_lights *lights, const pn_cluster_node *nd, vec3 p, vec3 n, bool horizon,
                    const cut_limit *lim) {
    if (nd->left < 0) return pn_cluster_light_culled(&lights->lights[nd->light], p, n) ? PN_CUT_CULL : PN_CUT_TAKE;
    if (node_culled(nd, p, n, horizon)) return PN_CUT_CULL;
    float d2 = v3_length2(v3_sub(nd->center, p)), r2 = nd->radius * nd->radius;
    if (r2 < lim->x_low * d2) return PN_CUT_TAKE;
    if (r2 > lim->x_high * d2) return PN_CUT_DESCEND;
    return pn_cluster_solid_angle(nd->center, nd->radius, p) < lim->max_solid_angle ? PN_CUT_TAKE : PN_CUT_DESCEND;
}

/* pn_cluster_cut_ex's walk, abandoned (returning stop + 1) as soon as more than `stop` clusters
 * are taken: the count only grows, so the cut has more than `stop` of them. */
static int cut_walk(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                    int *out, int capacity, int *culled, int culled_capacity, int *culled_count, int stop) {
    int count = 0, ccount = 0;
    bool horizon = !v3_is_zero(n);
    const cut_limit lim = make_cut_limit(max_solid_angle);
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        int root = f->roots[t];
        if (root < 0) continue;
        /* Stackless depth-first walk with the parent links. */
        int node = root;
        for (;;) {
            const pn_cluster_node *nd = &f->nodes[node];
            int action = classify(lights, nd, p, n, horizon, &lim);
            if (action == PN_CUT_DESCEND) {
                node = nd->left;
                continue;
            }
            if (action == PN_CUT_TAKE) {
                if (count < capacity) out[count] = node;
                if (++count > stop) return count;
            } else {
                if (ccount < culled_capacity) culled[ccount] = node;
                ccount++;
            }
            while (node != root && f->nodes[f->nodes[node].parent].right == node) node = f->nodes[node].parent;
            if (node == root) break;
            node = f->nodes[f->nodes[node].parent].right;
        }
    }
    for (int s = 0; s < f->single_count; s++) {
        int node = f->singles[s];
        if (pn_cluster_light_culled(&lights->lights[f->nodes[node].light], p, n)) {
            if (ccount < culled_capacity) culled[ccount] = node;
            ccount++;
        } else {
            if (count < capacity) out[count] = node;
            if (++count > stop) return count;
        }
    }
    if (culled_count) *culled_count = ccount;
    return count;
}

int pn_cluster_cut_ex(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                      int *out, int capacity, int *culled, int culled_capacity, int *culled_count) {
    return cut_walk(f, lights, p, n, max_solid_angle, out, capacity, culled, culled_capacity, culled_count, INT_MAX);
}

int pn_cluster_cut(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle, int *out,
                   int capacity) {
    return pn_cluster_cut_ex(f, lights, p, n, max_solid_angle, out, capacity, NULL, 0, NULL);
}

/* ---------------------------------------------------------------- shared cuts */

/* A node's decision for every point p' within `delta` of p whose normal n' is within `dn` of n
 * (Euclidean; n and n' non-zero, so all have a horizon), or CUT_UNSURE. Each test of classify is
 * a comparison of a quantity with a threshold; the decision is sure when the quantity stays on
 * one side however p and n move within the ball, with room for the rounding of float arithmetic
 * on numbers of the size of |p| + |center| + r (SHARE_EPS of it, some 40 times the rounding of the
 * few operations involved). Sure decisions are then the ones classify computes at p' bit for bit,
 * so a walk that reads them for p' takes the same cut. */
enum { CUT_UNSURE = 3 };
#define SHARE_EPS 1e-5f

typedef struct cut_ball {
    vec3 p, n;
    float delta, dn, p1; /* p1: |p|_1, the size of the coordinates for the rounding allowance */
} cut_ball;

static inline float abs1(vec3 v) {
    return fabsf(v.x) + fabsf(v.y) + fabsf(v.z);
}

/* How far dot(X - p', n') can be from dot(X - p, n) for X at distance at most dist from p (|n| = 1
 * up to rounding): delta |n'| + |X - p'| dn, plus the rounding allowance at coordinate size
 * `scale`. (Leaves pass |X - p|_1 for the distance: no square root.) */
static inline float plane_margin(const cut_ball *b, float dist, float scale) {
    return b->delta * (1.0f + b->dn) + (dist + b->delta) * b->dn + SHARE_EPS * scale;
}

/* Of a quantity q with margin m: 1 when q' > 0 everywhere, -1 when q' < 0 everywhere, else 0. */
static inline int sure_sign(float q, float m) {
    return q - m > 0.0f ? 1 : q + m < 0.0f ? -1 : 0;
}

/* pn_cluster_light_culled over the ball: PN_CUT_CULL, PN_CUT_TAKE or CUT_UNSURE. */
static int leaf_ball(const pn_light *l, const cut_ball *b) {
    const float scale = b->p1 + abs1(l->p);
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_SPHERE: { /* culled when dot(l->p - p, n) (+ radius) <= 0 */
        vec3 x = v3_sub(l->p, b->p);
        float rad = l->kind == PN_LIGHT_SPHERE ? l->radius : 0.0f;
        int sg = sure_sign(v3_dot(x, b->n) + rad, plane_margin(b, abs1(x), scale + rad));
        return sg > 0 ? PN_CUT_TAKE : sg < 0 ? PN_CUT_CULL : CUT_UNSURE;
    }
    case PN_LIGHT_DISTANT: {
        int sg = sure_sign(v3_dot(l->n, b->n), b->dn * 1.001f + 1e-6f);
        return sg > 0 ? PN_CUT_TAKE : sg < 0 ? PN_CUT_CULL : CUT_UNSURE;
    }
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE:
    case PN_LIGHT_DISK: {
        if (!l->two_sided) { /* culled when p is not in front of the light's plane */
            int sg = sure_sign(v3_dot(v3_sub(b->p, l->p), l->n), b->delta * 1.001f * abs1(l->n) + SHARE_EPS * scale);
            if (sg < 0) return PN_CUT_CULL;
            if (sg == 0) return CUT_UNSURE;
        }
        if (l->kind == PN_LIGHT_DISK) {
            float c = v3_dot(l->n, b->n);
            float ext = l->radius * sqrtf(fmaxf(0.0f, 1.0f - c * c));
            vec3 x = v3_sub(l->p, b->p);
            /* ext moves by at most radius |n' - n| (|n x l->n| is 1-Lipschitz in n), and its
             * square root rounds by up to some 5e-4 radius where c is near +-1. */
            float m = plane_margin(b, abs1(x), scale + l->radius) + l->radius * (2.0f * b->dn + 1e-3f);
            int sg = sure_sign(v3_dot(x, b->n) + ext, m);
            return sg > 0 ? PN_CUT_TAKE : sg < 0 ? PN_CUT_CULL : CUT_UNSURE;
        }
        /* culled when every vertex is on or below the tangent plane */
        vec3 v[4];
        int k = planar_vertices(l, v);
        bool all_below = true;
        for (int i = 0; i < k; i++) {
            vec3 x = v3_sub(v[i], b->p);
            int sg = sure_sign(v3_dot(x, b->n), plane_margin(b, abs1(x), b->p1 + abs1(v[i])));
            if (sg > 0) return PN_CUT_TAKE;
            if (sg == 0) all_below = false;
        }
        return all_below ? PN_CUT_CULL : CUT_UNSURE;
    }
    case PN_LIGHT_SPOT:
    case PN_LIGHT_GONIOMETRIC:
    case PN_LIGHT_PROJECTION: return CUT_UNSURE; /* their cones are left to the exact test */
    default: return PN_CUT_TAKE;                 /* never culled */
    }
}

/* node_culled's cone test with the bounding sphere's radius replaced by `radius`, given d > 0 and
 * the cosine cos_w = dot(axis, (p - center) / d). */
static inline bool cone_culled(const pn_cluster_node *nd, float cos_w, float d, float radius) {
    if (!(d > radius * (1.0f + 1e-5f)) || !(nd->cut_cos > -1.5f)) return false;
    float sb = fminf(radius / d, 1.0f);
    if (!(nd->cut_cos >= 0.0f || sb < nd->cut_sin)) return false;
    float cb = sqrtf(fmaxf(0.0f, 1.0f - sb * sb));
    float limit = nd->cut_cos * cb - nd->cut_sin * sb;
    return cos_w < limit - 2e-6f;
}

/* The horizon tests' sums s + r + 1e-5 (|s| + r): below 0, culled. Increasing in s. */
static inline float horizon_sum(float s, float r) {
    return s + r + 1e-5f * (fabsf(s) + r);
}

/* classify over the ball (interior nodes: node_culled, then the solid angle). */
static int node_ball(const pn_lights *lights, const pn_cluster_node *nd, const cut_ball *b, const cut_limit *lim) {
    if (nd->left < 0) return leaf_ball(&lights->lights[nd->light], b);
    const vec3 pc = v3_sub(nd->center, b->p);
    const float d = v3_length(pc), r = nd->radius;
    const float scale = b->p1 + abs1(nd->center) + r;
    bool unsure = false;
    /* The horizon: the sphere below the plane, or the box when the sphere is not wholly above. */
    {
        const float s = v3_dot(pc, b->n), m = plane_margin(b, d, scale) * 1.001f;
        if (horizon_sum(s + m, r) < 0.0f) return PN_CUT_CULL;
        if (!(horizon_sum(s - m, r) >= 0.0f)) unsure = true;
        if (!(s - m > r)) { /* some p' reach the box test */
            vec3 bc = v3_scale(v3_add(nd->bmin, nd->bmax), 0.5f), he = v3_scale(v3_sub(nd->bmax, nd->bmin), 0.5f);
            vec3 x = v3_sub(bc, b->p);
            float sb = v3_dot(x, b->n);
            float reach = fabsf(b->n.x) * he.x + fabsf(b->n.y) * he.y + fabsf(b->n.z) * he.z;
            /* reach moves by at most dn (he.x + he.y + he.z) */
            float mb = (plane_margin(b, abs1(x), scale + abs1(bc)) + b->dn * (he.x + he.y + he.z)) * 1.001f;
            bool cull_all = horizon_sum(sb + mb, reach) < 0.0f, cull_none = horizon_sum(sb - mb, reach) >= 0.0f;
            if (cull_all && s + m <= r) return PN_CUT_CULL; /* every p' takes the box test */
            if (!cull_none) unsure = true;
        }
    }
    /* The cone: the directions from p' to the sphere lie within those from p to the sphere grown by
     * delta and contain those to the sphere shrunk by delta; the margin 1e-4 d also covers the
     * test's own constant margins and the rounding of the angles' cosines. */
    if (nd->cos_spread > -1.0f && nd->cos_emit > -1.0f && d > 0.0f) {
        const float dc = b->delta * 1.001f + 1e-4f * d + SHARE_EPS * scale;
        const float cos_w = v3_dot(nd->axis, v3_scale(pc, -1.0f / d));
        if (cone_culled(nd, cos_w, d, r + dc)) return PN_CUT_CULL;
        if (!(r - dc > 0.0f) || cone_culled(nd, cos_w, d, r - dc)) return CUT_UNSURE;
    } else if (nd->cos_spread > -1.0f && nd->cos_emit > -1.0f) {
        return CUT_UNSURE;
    }
    if (unsure) return CUT_UNSURE;
    /* The solid angle by make_cut_limit's bounds, which decide without the exact function. */
    const float ds = b->delta * 1.001f + SHARE_EPS * scale, r2 = r * r;
    const float lo = d - ds, hi = d + ds;
    if (lo > 0.0f && r2 < lim->x_low * (lo * lo) * 0.9999f) return PN_CUT_TAKE;
    if (r2 > lim->x_high * (hi * hi) * 1.0001f) return PN_CUT_DESCEND;
    return CUT_UNSURE;
}

bool pn_cluster_cut_share_init(pn_cluster_cut_share *sh, const pn_cluster_forest *f) {
    memset(sh, 0, sizeof *sh);
    const size_t n = f->node_count > 0 ? (size_t)f->node_count : 1u;
    sh->links = calloc(n, sizeof *sh->links);
    int *stack = malloc(n * sizeof *stack);
    if (!sh->links || !stack) {
        free(stack);
        pn_cluster_cut_share_free(sh);
        return false;
    }
    sh->node_count = f->node_count;
    for (int i = 0; i < f->node_count; i++) sh->links[i] = (pn_cluster_cut_link){f->nodes[i].left, -1, 0u};
    /* The stackless walk's successors, parents first: past a left child its sibling, past a right
     * child whatever follows its parent. */
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        if (f->roots[t] < 0) continue;
        int top = 0;
        stack[top++] = f->roots[t];
        while (top > 0) {
            const int i = stack[--top];
            const pn_cluster_node *nd = &f->nodes[i];
            if (nd->left < 0) continue;
            sh->links[nd->left].skip = nd->right;
            sh->links[nd->right].skip = sh->links[i].skip;
            stack[top++] = nd->left;
            stack[top++] = nd->right;
        }
    }
    free(stack);
    return true;
}

void pn_cluster_cut_share_free(pn_cluster_cut_share *sh) {
    free(sh->links);
    memset(sh, 0, sizeof *sh);
}

/* The walk of cut_walk (no cap, no culled list) for pn_cluster_cut_record (b != NULL: decides by
 * node_ball where sure and records it) and pn_cluster_cut_replay (b == NULL: reads the record). */
static int shared_walk(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                       int *out, int capacity, pn_cluster_cut_share *sh, const cut_ball *b) {
    int count = 0;
    const bool horizon = !v3_is_zero(n);
    const cut_limit lim = make_cut_limit(max_solid_angle);
    pn_cluster_cut_link *links = sh->links;
    const uint32_t tag = sh->stamp << 2;
    int met = 0, sure = 0;
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        /* The same walk as cut_walk's, by the links instead of the parents. */
        for (int node = f->roots[t]; node >= 0;) {
            pn_cluster_cut_link *ln = &links[node];
            int action;
            if (b) {
                const pn_cluster_node *nd = &f->nodes[node];
                action = node_ball(lights, nd, b, &lim);
                met++;
                if (action != CUT_UNSURE) {
                    sure++;
                    ln->memo = tag | (uint32_t)action;
#ifdef PN_CUT_SHARE_CHECK
                    if (action != classify(lights, nd, p, n, horizon, &lim)) abort();
#endif
                } else {
                    action = classify(lights, nd, p, n, horizon, &lim);
                }
            } else {
                action = (ln->memo & ~3u) == tag ? (int)(ln->memo & 3u)
                                                 : classify(lights, &f->nodes[node], p, n, horizon, &lim);
#ifdef PN_CUT_SHARE_CHECK
                if (action != classify(lights, &f->nodes[node], p, n, horizon, &lim)) abort();
#endif
            }
            if (action == PN_CUT_DESCEND) {
                node = ln->left;
                continue;
            }
            if (action == PN_CUT_TAKE) {
                if (count < capacity) out[count] = node;
                count++;
            }
            node = ln->skip;
        }
    }
    for (int s = 0; s < f->single_count; s++) {
        int node = f->singles[s];
        const pn_light *l = &lights->lights[f->nodes[node].light];
        int action;
        if (b) {
            action = leaf_ball(l, b);
            met++;
            if (action != CUT_UNSURE) {
                sure++;
                links[node].memo = tag | (uint32_t)action;
            } else {
                action = pn_cluster_light_culled(l, p, n) ? PN_CUT_CULL : PN_CUT_TAKE;
            }
        } else {
            action = (links[node].memo & ~3u) == tag ? (int)(links[node].memo & 3u)
                                                     : (pn_cluster_light_culled(l, p, n) ? PN_CUT_CULL : PN_CUT_TAKE);
        }
        if (action == PN_CUT_TAKE) {
            if (count < capacity) out[count] = node;
            count++;
        }
    }
    if (b) {
        sh->met = met;
        sh->sure = sure;
        sh->all_sure = sure == met;
    }
    return count;
}

int pn_cluster_cut_record(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                          float delta, float dn, int *out, int capacity, pn_cluster_cut_share *sh) {
    /* A new stamp for every record, the fallback's included: a memo of an older record never
     * matches (the stamps only grow until they wrap, and then every memo is forgotten). */
    if (++sh->stamp >= (1u << 30)) {
        for (int i = 0; i < sh->node_count; i++) sh->links[i].memo = 0u;
        sh->stamp = 1;
    }
    if (v3_is_zero(n) || !(delta >= 0.0f) || !(dn >= 0.0f) || !isfinite(delta) || !isfinite(dn)) {
        /* No ball to decide over: nothing is noted under the new stamp, so a replay classifies
         * every node itself (the plain cut). */
        sh->all_sure = false;
        sh->met = sh->sure = 0;
        return pn_cluster_cut(f, lights, p, n, max_solid_angle, out, capacity);
    }
    const cut_ball b = {p, n, delta, dn, abs1(p)};
    return shared_walk(f, lights, p, n, max_solid_angle, out, capacity, sh, &b);
}

int pn_cluster_cut_replay(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                          int *out, int capacity, pn_cluster_cut_share *sh) {
    if (sh->stamp == 0) return pn_cluster_cut(f, lights, p, n, max_solid_angle, out, capacity); /* never recorded */
    return shared_walk(f, lights, p, n, max_solid_angle, out, capacity, sh, NULL);
}

/* ---------------------------------------------------------------- capped cut */

/* An open node's key in pn_cluster_cut_capped's heaps: its r^2 / d^2 (the solid angle's order). */
static float open_key(const pn_cluster_node *nd, vec3 p) {
    float d2 = v3_length2(v3_sub(nd->center, p));
    return d2 > 0.0f ? nd->radius * nd->radius / d2 : INFINITY;
}

/* The capped cut's clusters as a doubly linked list in light order (a refined node's element
 * becomes its first child's that is not culled, the other child's is linked after it), so that
 * the depth-first order comes out without a sort. */
typedef struct cut_elem {
    int node, prev, next;
} cut_elem;

static int slots_for(int max_count) {
    return (max_count > 0 ? max_count : 0) + PN_TREE_COUNT + 1;
}

size_t pn_cluster_cut_capped_work(int max_count) {
    return (size_t)slots_for(max_count) * (2 * sizeof(pn_heap_entry) + sizeof(cut_elem));
}

int pn_cluster_cut_capped(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                          int max_count, int *out, int capacity, void *work) {
    if (max_count <= 0) return pn_cluster_cut(f, lights, p, n, max_solid_angle, out, capacity);
    /* Under the cap the plain walk's cut is the answer. (The priority walk alone would not always
     * give it there: its count can pass the cap on the way, before subtrees turn out culled.) */
    const int plain = cut_walk(f, lights, p, n, max_solid_angle, out, capacity, NULL, 0, NULL, max_count);
    if (plain <= max_count) return plain;
    /* heap: the open elements; held: elements whose refinement the cap stopped, refined after all
     * when a refinement that culls both children makes room (so the count ends at max_count);
     * both max-heaps keyed by the element's node's solid angle, ties to the lower element index
     * (the payload). At most slots elements are live: the trees' part of the count stays within
     * max_count. */
    const int slots = slots_for(max_count);
    pn_heap heap, held;
    pn_heap_init_fixed(&heap, PN_HEAP_MAX | PN_HEAP_TIES_BY_PAYLOAD, work, (size_t)slots);
    pn_heap_init_fixed(&held, PN_HEAP_MAX | PN_HEAP_TIES_BY_PAYLOAD, heap.entries + slots, (size_t)slots);
    cut_elem *el = (cut_elem *)(held.entries + slots);
    int used = 0, free_list = -1, head = -1, tail = -1;
    bool horizon = !v3_is_zero(n);
    const cut_limit lim = make_cut_limit(max_solid_angle);
    int singles = 0;
    for (int s = 0; s < f->single_count; s++)
        singles += !pn_cluster_light_culled(&lights->lights[f->nodes[f->singles[s]].light], p, n);
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        int root = f->roots[t];
        if (root < 0) continue;
        int action = classify(lights, &f->nodes[root], p, n, horizon, &lim);
        if (action == PN_CUT_CULL) continue;
        const int e = used++;
        el[e] = (cut_elem){root, tail, -1};
        if (tail >= 0)
            el[tail].next = e;
        else
            head = e;
        tail = e;
        if (action == PN_CUT_DESCEND) pn_heap_push(&heap, open_key(&f->nodes[root], p), e);
    }
    int total = singles + used;
    while (heap.count > 0) {
        const int e = (int)pn_heap_pop(&heap).payload, m = el[e].node;
        const pn_cluster_node *nd = &f->nodes[m];
        const int child[2] = {nd->left, nd->right};
        int act[2], delta = -1;
        for (int c = 0; c < 2; c++) {
            act[c] = classify(lights, &f->nodes[child[c]], p, n, horizon, &lim);
            delta += act[c] != PN_CUT_CULL;
        }
        if (delta > 0 && total + delta > max_count) { /* over the cap: held, unless room is made later */
            pn_heap_push(&held, open_key(nd, p), e);
            continue;
        }
        total += delta;
        if (delta < 0) { /* both children culled: the element leaves the list */
            if (el[e].prev >= 0)
                el[el[e].prev].next = el[e].next;
            else
                head = el[e].next;
            if (el[e].next >= 0)
                el[el[e].next].prev = el[e].prev;
            else
                tail = el[e].prev;
            el[e].node = free_list;
            free_list = e;
            if (held.count > 0) {
                const pn_heap_entry x = pn_heap_pop(&held);
                pn_heap_push(&heap, x.key, x.payload);
            }
            continue;
        }
        int at = -1;
        for (int c = 0; c < 2; c++) {
            if (act[c] == PN_CUT_CULL) continue;
            int x = e;
            if (at >= 0) { /* the second child: a new element after the first */
                if (free_list >= 0) {
                    x = free_list;
                    free_list = el[x].node;
                } else {
                    x = used++;
                }
                el[x] = (cut_elem){child[c], at, el[at].next};
                if (el[at].next >= 0)
                    el[el[at].next].prev = x;
                else
                    tail = x;
                el[at].next = x;
            }
            el[x].node = child[c];
            at = x;
            if (act[c] == PN_CUT_DESCEND) pn_heap_push(&heap, open_key(&f->nodes[child[c]], p), x);
        }
    }
    int count = 0;
    for (int e = head; e >= 0; e = el[e].next) {
        if (count < capacity) out[count] = el[e].node;
        count++;
    }
    for (int s = 0; s < f->single_count; s++)
        if (!pn_cluster_light_culled(&lights->lights[f->nodes[f->singles[s]].light], p, n)) {
            if (count < capacity) out[count] = f->singles[s];
            count++;
        }
    return count;
}

/* ---------------------------------------------------------------- picking */

int pn_cluster_pick(const pn_cluster_forest *f, const pn_lights *lights, int node, float u, float *prob) {
    int first = f->ranges[2 * node], count = f->ranges[2 * node + 1];
    if (count <= 1) {
        if (prob) *prob = 1.0f;
        return f->light_order[first];
    }
    const double *pre = f->power_prefix;
    double total = pre[first + count] - pre[first];
    if (!(total > 0.0)) {
        int i = (int)(u * (float)count);
        if (i < 0) i = 0;
        if (i >= count) i = count - 1;
        if (prob) *prob = 1.0f / (float)count;
        return f->light_order[first + i];
    }
    double target = pre[first] + (double)u * total;
    /* The first position whose running sum passes the target: never a zero-power light. The
     * predicate pre[i + 1] > target grows with i; its first true position among the coarse
     * entries (pre[16 j + 16] > target: position 16 j + 15 true) bounds the search to one group
     * of 16, the same answer as the search over the whole range. */
    int lo = first, hi = first + count - 1;
    if (count > 4 * PN_CLUSTER_COARSE && f->power_coarse) {
        int a = first / PN_CLUSTER_COARSE, b = hi / PN_CLUSTER_COARSE;
        while (a < b) {
            int mid = a + (b - a) / 2;
            if (f->power_coarse[mid] > target)
                b = mid;
            else
                a = mid + 1;
        }
        int g0 = a * PN_CLUSTER_COARSE, g1 = g0 + PN_CLUSTER_COARSE - 1;
        if (g0 > lo) lo = g0;
        if (g1 < hi) hi = g1;
    }
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (pre[mid + 1] > target)
            hi = mid;
        else
            lo = mid + 1;
    }
    while (lo > first && !(pre[lo + 1] > pre[lo])) lo--; /* rounding at the top end */
    int light = f->light_order[lo];
    if (prob) *prob = (float)((double)pn_cluster_light_power(&lights->lights[light]) / total);
    return light;
}

float pn_cluster_pick_pdf(const pn_cluster_forest *f, const pn_lights *lights, int node, int light) {
    if (light < 0 || light >= f->light_count) return 0.0f;
    int leaf = f->leaf_of_light[light];
    if (leaf < 0) return 0.0f;
    const pn_cluster_node *nd = &f->nodes[node];
    int pos = f->nodes[leaf].first;
    if (pos < nd->first || pos >= nd->first + nd->count) return 0.0f;
    double total = f->power_prefix[nd->first + nd->count] - f->power_prefix[nd->first];
    if (!(total > 0.0)) return 1.0f / (float)nd->count;
    return (float)((double)pn_cluster_light_power(&lights->lights[light]) / total);
}

/* ---------------------------------------------------------------- picking by importance */

#define PN_PICK_COS_FLOOR 1e-3f

double pn_cluster_importance(const pn_cluster_node *nd, vec3 p, vec3 n) {
    if (!(nd->power > 0.0f)) return 0.0;
    const bool horizon = !v3_is_zero(n);
    vec3 pc = v3_sub(nd->center, p);
    float d2 = v3_length2(pc), r2 = nd->radius * nd->radius;
    if (!(d2 > r2)) return (double)nd->power / (double)fmaxf(r2, 1e-30f); /* p in the sphere */
    float d = sqrtf(d2);
    vec3 w = v3_scale(pc, 1.0f / d); /* from p towards the centre */
    float sin_b = fminf(nd->radius / d, 1.0f), cos_b = sqrtf(fmaxf(0.0f, 1.0f - sin_b * sin_b));
    float emit = 1.0f, incident = 1.0f;
    if (nd->cos_spread > -1.0f) {
        /* The smallest angle between an emitting normal (within theta_o of the axis) and a
         * direction from a point of the sphere to p (within theta_b of -w): max(0, theta_w -
         * theta_o - theta_b); its cosine. */
        float cos_w = -v3_dot(nd->axis, w), sin_w = sqrtf(fmaxf(0.0f, 1.0f - cos_w * cos_w));
        float cos_o = nd->cos_spread, sin_o = sqrtf(fmaxf(0.0f, 1.0f - cos_o * cos_o));
        float cos_x = pn_cos_sub_clamped(sin_w, cos_w, sin_o, cos_o);
        float sin_x = pn_sin_sub_clamped(sin_w, cos_w, sin_o, cos_o);
        emit = fmaxf(pn_cos_sub_clamped(sin_x, cos_x, sin_b, cos_b), PN_PICK_COS_FLOOR);
    }
    if (horizon) {
        float cos_i = v3_dot(n, w), sin_i = sqrtf(fmaxf(0.0f, 1.0f - cos_i * cos_i));
        incident = fmaxf(pn_cos_sub_clamped(sin_i, cos_i, sin_b, cos_b), PN_PICK_COS_FLOOR);
    }
    return (double)nd->power * (double)emit * (double)incident / (double)d2;
}

/* The probability of the left child at interior node m. */
static double pick_left_share(const pn_cluster_forest *f, int m, vec3 p, vec3 n) {
    const pn_cluster_node *nd = &f->nodes[m], *a = &f->nodes[nd->left], *b = &f->nodes[nd->right];
    double ia = pn_cluster_importance(a, p, n), ib = pn_cluster_importance(b, p, n);
    if (ia + ib > 0.0) return ia / (ia + ib);
    double pa = (double)a->power, pb = (double)b->power;
    if (pa + pb > 0.0) return pa / (pa + pb);
    return (double)a->count / (double)(a->count + b->count);
}

/* True while the importance descent goes on at node m: an interior node subtending at least
 * max_solid_angle from p (always, max_solid_angle <= 0). */
static bool pick_descends(const pn_cluster_node *nd, vec3 p, float max_solid_angle) {
    if (nd->left < 0) return false;
    return !(max_solid_angle > 0.0f) || !(pn_cluster_solid_angle(nd->center, nd->radius, p) < max_solid_angle);
}

int pn_cluster_pick_importance(const pn_cluster_forest *f, const pn_lights *lights, int node, vec3 p, vec3 n,
                               float max_solid_angle, float u, float *prob) {
    double v = (double)u, pr = 1.0;
    if (!(v >= 0.0)) v = 0.0;
    if (v >= 1.0) v = nextafter(1.0, 0.0);
    while (pick_descends(&f->nodes[node], p, max_solid_angle)) {
        const double s = pick_left_share(f, node, p, n);
        if (v < s) {
            v /= s;
            pr *= s;
            node = f->nodes[node].left;
        } else {
            v = (v - s) / (1.0 - s);
            pr *= 1.0 - s;
            node = f->nodes[node].right;
        }
        if (v >= 1.0) v = nextafter(1.0, 0.0);
    }
    float pp = 1.0f, fv = (float)v;
    if (fv >= 1.0f) fv = nextafterf(1.0f, 0.0f);
    int light = pn_cluster_pick(f, lights, node, fv, &pp);
    if (prob) *prob = (float)(pr * (double)pp);
    return light;
}

float pn_cluster_pick_importance_pdf(const pn_cluster_forest *f, const pn_lights *lights, int node, vec3 p, vec3 n,
                                     float max_solid_angle, int light) {
    if (light < 0 || light >= f->light_count) return 0.0f;
    int at = f->leaf_of_light[light];
    if (at < 0) return 0.0f;
    const int pos = f->nodes[at].first;
    if (pos < f->nodes[node].first || pos >= f->nodes[node].first + f->nodes[node].count) return 0.0f;
    /* The descent's path down to the light: the child whose light range holds it. */
    double pr = 1.0;
    while (pick_descends(&f->nodes[node], p, max_solid_angle)) {
        const double s = pick_left_share(f, node, p, n);
        const pn_cluster_node *l = &f->nodes[f->nodes[node].left];
        if (pos >= l->first && pos < l->first + l->count) {
            pr *= s;
            node = f->nodes[node].left;
        } else {
            pr *= 1.0 - s;
            node = f->nodes[node].right;
        }
    }
    return (float)(pr * (double)pn_cluster_pick_pdf(f, lights, node, light));
}
