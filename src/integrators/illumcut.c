/* illumcut.c — IlluminationCut (Bus, Mustafa, Biri, Eurographics 2015), §3: the point tree, Phase I
 * (the approximate image), Phase II (Algorithm 1, illumination-aware product-space pairs found by
 * a stack-based simultaneous descent of the point tree and the light tree) and adaptive
 * visibility sampling (Algorithm 2, "IlluminationCut-Sampling").
 *
 * The whole image window is one batch: every eye sample of every pixel becomes a shading point
 * of one point tree (the tiled driver calls its render_image hook; the points come through the
 * driver's tracers of the window, render/batch.h). A driver that hands
 * out pixel sets gets one point tree per set (render_batch); a crop window's pixels therefore
 * differ slightly from the same pixels of the full image (other trees, other pairs), within the
 * error bound.
 *
 * Point tree (§3 "Light and point trees"): a compressed octree whose first three levels split the
 * space of normals (the cube [-1,1]^3) and the remaining levels split space (the points' box).
 * Each octree level is three binary splits at the cell's midplanes (x, then y, then z); the
 * points of a node are partitioned in place into two contiguous sub-arrays at each split, so they
 * end in Morton order and every node is a sub-array [first, first + count). A split that leaves
 * one side empty creates no node (the compression). Nodes keep their box, cone of shading
 * normals, cone of reflected view directions, a representative point (chosen at random in
 * proportion to the point count, as Multidimensional Lightcuts), the BRDF ranges (k_diff and
 * k_spec maxima per channel, exponent min/max over the glossy points), and `color` (the minimum
 * Phase I luminance of their points).
 *
 * Phase I: both trees descended until max(r(R), r(Q)) < 0.1 d(R, Q) and the light cluster's cone
 * aperture is below 20 degrees; the pair is then shaded once, at R's representative point with
 * Q's representative and summed intensity (eq. 3, with one shadow ray), accumulated in R's node
 * and pushed down to the points.
 *
 * Phase II: Algorithm 1 with IsIllumAwarePair: delta · color(R) > L_UB(R, Q) (eq. 4-5), L_UB from
 * shade/bounds.h (M_max, G_max with the bounding-box transforms of Multidimensional Lightcuts).
 *
 * Departures, and why:
 *   - Leaves. Algorithm 1 shades (R, Q) when the cluster to refine is a leaf; a pair whose R is
 *     a leaf but whose Q is not would then be shaded with Q's representative without any error
 *     test. Here a pair with a one-VPL Q is shaded (exactly: its representative is its only
 *     VPL), and otherwise a leaf R makes Q refined, so every shaded pair passed the bound test or
 *     is exact. Directional clusters have no spatial radius; their r is the radius of their box
 *     of directions times the scene diameter when it is compared with r(R).
 *   - Phase I distance. d(R, Q) in the Phase I test is never below the clamping distance of the
 *     VPL contributions (5% of the scene radius): closer than that, G is clamped and the pair's
 *     contribution varies no faster than at that distance; without it the descent would go down
 *     to single points and VPLs wherever VPLs lie on the shaded surfaces.
 *   - Phase I refinement. The paper refines the larger cluster; here a pair whose light cone is
 *     20 degrees or wider refines Q whatever the radii (pn_illumcut_phase1_refines_light):
 *     refining R cannot narrow Q's cone, so it split R down to single points before Q was ever
 *     split. The pairs shaded still meet the same criteria; on bathroom at 92x92 Phase I shades
 *     17% (10K VPLs) to 39% (160K VPLs) fewer pairs.
 *   - Aperture is the full angle of the light cluster's cone (twice its half-angle); omni
 *     clusters have none; a directional cluster's is 2 asin(radius of its direction box).
 *   - Pairs whose L_UB is 0 (the VPLs cannot light any point of R: behind, facing away) are
 *     dropped, which is exact.
 *   - Algorithm 2: R' takes the middle point of each of the vs equal sub-arrays; only samples
 *     with a non-zero unoccluded contribution vote; if none does, the pair recurses as if mixed.
 *     A mixed sub-array recurses on its sub-arrays, each of which holds one of its samples: that
 *     sample's ray is reused (it is the sub-array's sample in the next level, or its shadow ray
 *     when the sub-array is shaded point by point), so a pair never traces more rays than |R|
 *     (before: a mixed pair of 8-15 points traced 8 samples and then every point again). The
 *     sub-array that holds the reused point takes it as its sample instead of its middle point,
 *     so the image changes slightly; on the full-density crops (RESULTS.md, ic-s11) 2-4% fewer
 *     IC-S rays.
 *   - Algorithm 2 on one-VPL pairs: the paper shades a pair with a leaf Q point by point. Here
 *     such a pair is first given the bound test (which Algorithm 1 would have applied to it), and
 *     when it passes (|R| >= 8), Algorithm 2 samples it like any other illumination-aware pair;
 *     a one-VPL pair that fails the test is still shaded exactly. ic-s11, living-room at full
 *     density, IC-S 5%: 23% fewer shadow rays for a 1% higher RMSE; bathroom and staircase 2-3%
 *     fewer rays, RMSE unchanged to 3 digits.
 *   - Shadow rays are traced as Embree packets of up to 16 (pn_accel_occluded_packet): the
 *     samples of one Algorithm 2 sub-array together (they go from nearby points to one VPL), and
 *     the point-by-point rays (plain IC's included) through a per-group queue of the additions to
 *     the points' sums, applied in order, so that a packet may span consecutive pairs. Same rays
 *     and the same order of every point's sum; the answers are rtcOccluded1's except for rays
 *     exactly through a triangle edge (about 1 in 10^8 here: 1 pixel of ~40K differed, by
 *     <0.4%, in 3 of the 15 full-density bench images). Images stay bit-identical for any
 *     thread count (a group's packets do not depend on it). ics12, full-density render
 *     windows: render CPU time of IC about halved, of IC-S -35..45%.
 *   - The VPL contributions are evaluated by pn_vpl_contribution_inline (lights/vpl.h: the
 *     library's pn_vpl_contribution_with as an inline function, no libm fmaxf calls; lightcuts
 *     uses it too); images unchanged.
 *   - Threads: see run_phase2 — the pairs are generated in Algorithm 1's order by one thread and
 *     shaded by all, grouped by disjoint point sub-trees so that every point's sum is added in
 *     the same order whatever the thread count (bit-identical images).
 */
#include "integrators/illumcut.h"

#include "core/clock.h"
#include "core/photometry.h"
#include "core/rng.h"
#include "core/threadpool.h"
#include "render/progress.h"
#include "shade/bsdf.h"
#include "spectral/melanopic.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define IC_LEAF_SIZE 1
#define IC_MAX_SPLITS 96               /* binary splits along a root-to-leaf path (then a leaf) */
#define IC_PHASE1_RATIO 0.1f           /* max(r(R), r(Q)) < 0.1 d(R, Q) */
#define IC_PHASE1_APERTURE 0.34906585f /* 20 degrees */

typedef struct ic_point {
    pn_vpl_receiver r;
    vec3 L;       /* Phase II radiance */
    vec3 approx;  /* Phase I radiance */
    float bounds; /* amortised L_UB evaluations (Fig. 4) */
    float pairs;  /* shaded pairs covering the point */
    uint32_t shadow_rays;
    int32_t sample;
    double lux; /* PN_AOV_ILLUMINANCE: Phase II illuminance of the point's white Lambertian twin */
    double mel; /* PN_AOV_MELANOPIC_EDI: the same twin's melanopic EDI, at the point's wavelengths */
} ic_point;

typedef struct ic_node {
    vec3 lo, hi;
    vec3 n_axis, r_axis;
    float n_half, r_half;
    vec3 kd_max, ks_max;
    float n_min, n_max;
    float n_cos, n_sin, r_cos, r_sin; /* of n_half, r_half */
    int32_t first, count, left, right, rep;
    float color; /* min Phase I luminance of the node's points */
    vec3 acc;    /* Phase I contributions to all points of the node */
    float bound_acc, pair_acc;
} ic_node;

typedef struct ic_sample {
    vec3 emitted, throughput;
    float weight;
    int32_t point; /* -1: no shading point */
} ic_sample;

typedef struct ic_tree {
    ic_point *points;
    int32_t point_count;
    ic_node *nodes;
    int32_t node_count, node_capacity;
} ic_tree;

/* ---- point tree ---------------------------------------------------------------------------- */

static float axis_value(const ic_point *p, int normal_space, int axis) {
    vec3 v = normal_space ? p->r.ns : p->r.p;
    return v3_get(v, axis);
}

static int32_t new_node(ic_tree *t) {
    if (t->node_count == t->node_capacity) {
        int32_t cap = t->node_capacity ? t->node_capacity * 2 : 1024;
        ic_node *n = realloc(t->nodes, (size_t)cap * sizeof *n);
        if (!n) return -1;
        t->nodes = n;
        t->node_capacity = cap;
    }
    int32_t i = t->node_count++;
    memset(&t->nodes[i], 0, sizeof t->nodes[i]);
    t->nodes[i].left = t->nodes[i].right = -1;
    return i;
}

/* The cell being split: the normal-space cell during the first 9 binary splits, then the
 * spatial one. */
typedef struct ic_cell {
    vec3 nlo, nhi, plo, phi;
    int split; /* binary splits made so far on this path */
} ic_cell;

/* Partitions [first, first+count) at the cell's next midplane; returns the size of the low
 * side. */
static int32_t partition(ic_point *pts, int32_t first, int32_t count, ic_cell *cell, ic_cell *lo_cell,
                         ic_cell *hi_cell) {
    int normal_space = cell->split < 9;
    int axis = cell->split % 3;
    vec3 *clo = normal_space ? &cell->nlo : &cell->plo, *chi = normal_space ? &cell->nhi : &cell->phi;
    float mid = 0.5f * (v3_get(*clo, axis) + v3_get(*chi, axis));
    int32_t i = first, j = first + count - 1;
    while (i <= j) {
        if (axis_value(&pts[i], normal_space, axis) < mid) {
            i++;
        } else {
            ic_point tmp = pts[i];
            pts[i] = pts[j];
            pts[j] = tmp;
            j--;
        }
    }
    *lo_cell = *cell;
    *hi_cell = *cell;
    lo_cell->split = hi_cell->split = cell->split + 1;
    vec3 *l_hi = normal_space ? &lo_cell->nhi : &lo_cell->phi;
    vec3 *h_lo = normal_space ? &hi_cell->nlo : &hi_cell->plo;
    if (axis == 0)
        l_hi->x = h_lo->x = mid;
    else if (axis == 1)
        l_hi->y = h_lo->y = mid;
    else
        l_hi->z = h_lo->z = mid;
    return i - first;
}

static void leaf_attributes(ic_tree *t, ic_node *n, uint64_t seed) {
    const ic_point *p0 = &t->points[n->first];
    n->lo = n->hi = p0->r.p;
    n->n_axis = p0->r.ns;
    n->r_axis = pn_reflect(p0->r.wo, p0->r.ns);
    n->n_half = n->r_half = 0.0f;
    n->kd_max = p0->r.kd;
    n->ks_max = p0->r.ks;
    /* Exponent range over the glossy points only: a Lambert point (k_spec = 0, exponent 1)
     * would otherwise widen a glossy node's range to [1, n_max] and its lobe bound with it. */
    bool g0 = !v3_is_zero(p0->r.ks);
    n->n_min = g0 ? p0->r.exponent : INFINITY;
    n->n_max = g0 ? p0->r.exponent : -INFINITY;
    for (int32_t i = 1; i < n->count; i++) {
        const ic_point *p = &t->points[n->first + i];
        n->lo = v3_min(n->lo, p->r.p);
        n->hi = v3_max(n->hi, p->r.p);
        pn_cone_merge(n->n_axis, n->n_half, p->r.ns, 0.0f, &n->n_axis, &n->n_half);
        pn_cone_merge(n->r_axis, n->r_half, pn_reflect(p->r.wo, p->r.ns), 0.0f, &n->r_axis, &n->r_half);
        n->kd_max = v3_max(n->kd_max, p->r.kd);
        n->ks_max = v3_max(n->ks_max, p->r.ks);
        if (!v3_is_zero(p->r.ks)) {
            n->n_min = fminf(n->n_min, p->r.exponent);
            n->n_max = fmaxf(n->n_max, p->r.exponent);
        }
    }
    n->rep = n->first + (int32_t)(pn_hash_unit(pn_hash3(seed, (uint64_t)n->first, 1)) * (float)n->count);
    if (n->rep >= n->first + n->count) n->rep = n->first + n->count - 1;
}

/* Builds the subtree over [first, first+count) in `cell`; returns its node (or -1: no memory). */
static int32_t build_node(ic_tree *t, int32_t first, int32_t count, ic_cell cell, uint64_t seed) {
    ic_cell lo_cell, hi_cell;
    int32_t nlo = 0;
    bool leaf = count <= IC_LEAF_SIZE;
    while (!leaf) {
        if (cell.split >= IC_MAX_SPLITS) {
            leaf = true;
            break;
        }
        nlo = partition(t->points, first, count, &cell, &lo_cell, &hi_cell);
        if (nlo > 0 && nlo < count) break;
        cell = nlo == 0 ? hi_cell : lo_cell; /* compressed: no node for a one-sided split */
    }
    int32_t id = new_node(t);
    if (id < 0) return -1;
    t->nodes[id].first = first;
    t->nodes[id].count = count;
    if (leaf) {
        leaf_attributes(t, &t->nodes[id], seed);
        return id;
    }
    int32_t l = build_node(t, first, nlo, lo_cell, seed);
    if (l < 0) return -1;
    int32_t r = build_node(t, first + nlo, count - nlo, hi_cell, seed);
    if (r < 0) return -1;
    ic_node *n = &t->nodes[id];
    const ic_node *a = &t->nodes[l], *b = &t->nodes[r];
    n->left = l;
    n->right = r;
    n->lo = v3_min(a->lo, b->lo);
    n->hi = v3_max(a->hi, b->hi);
    pn_cone_merge(a->n_axis, a->n_half, b->n_axis, b->n_half, &n->n_axis, &n->n_half);
    pn_cone_merge(a->r_axis, a->r_half, b->r_axis, b->r_half, &n->r_axis, &n->r_half);
    n->kd_max = v3_max(a->kd_max, b->kd_max);
    n->ks_max = v3_max(a->ks_max, b->ks_max);
    n->n_min = fminf(a->n_min, b->n_min);
    n->n_max = fmaxf(a->n_max, b->n_max);
    float u = pn_hash_unit(pn_hash3(seed, (uint64_t)first, (uint64_t)count));
    n->rep = u * (float)count < (float)a->count ? a->rep : b->rep;
    return id;
}

static pn_status build_point_tree(ic_tree *t, uint64_t seed) {
    if (t->point_count == 0) return PN_OK;
    ic_cell cell;
    cell.nlo = v3(-1.0f, -1.0f, -1.0f);
    cell.nhi = v3(1.0f, 1.0f, 1.0f);
    cell.plo = cell.phi = t->points[0].r.p;
    for (int32_t i = 1; i < t->point_count; i++) {
        cell.plo = v3_min(cell.plo, t->points[i].r.p);
        cell.phi = v3_max(cell.phi, t->points[i].r.p);
    }
    /* A cube, so that spatial cells stay cubes as in an octree. */
    vec3 ext = v3_sub(cell.phi, cell.plo);
    float e = fmaxf(ext.x, fmaxf(ext.y, ext.z)) * 1.0001f + 1e-20f;
    cell.phi = v3_add(cell.plo, v3(e, e, e));
    cell.split = 0;
    t->node_capacity = 0;
    if (build_node(t, 0, t->point_count, cell, seed) < 0) return PN_ERROR_OUT_OF_MEMORY;
    for (int32_t i = 0; i < t->node_count; i++) {
        ic_node *n = &t->nodes[i];
        pn_receiver_bounds b = {n->lo,     n->hi,    n->n_axis, n->n_half, n->r_axis, n->r_half, n->kd_max,
                                n->ks_max, n->n_min, n->n_max,  0.0f,      0.0f,      0.0f,      0.0f};
        pn_receiver_bounds_set_cones(&b);
        n->n_cos = b.n_cos, n->n_sin = b.n_sin, n->r_cos = b.r_cos, n->r_sin = b.r_sin;
    }
    return PN_OK;
}

static pn_receiver_bounds node_bounds(const ic_node *n) {
    pn_receiver_bounds b = {n->lo,     n->hi,    n->n_axis, n->n_half, n->r_axis, n->r_half, n->kd_max,
                            n->ks_max, n->n_min, n->n_max,  n->n_cos,  n->n_sin,  n->r_cos,  n->r_sin};
    return b;
}

static float node_radius(const ic_node *n) {
    return 0.5f * v3_length(v3_sub(n->hi, n->lo));
}

/* ---- shared state of one render ------------------------------------------------------------- */

typedef struct ic_render {
    const pn_render_job *job;
    const pn_vpl_data *d;
    ic_tree tree;
    ic_sample *samples;
    pn_pixel_estimate *pixels;
    const int32_t (*coords)[2]; /* the batch's pixels, or NULL: the window in raster order */
    const pn_batch *batch;      /* the driver's batch, or its window (coords NULL): the eye samples' source */
    int32_t count;              /* pixels */
    int width;                  /* of the window (coords == NULL) */
    uint32_t spp;
    float scene_diameter;
    /* Phase II work items, grouped by point sub-tree (see run_phase2). */
    struct ic_group *groups;
    int32_t group_count;
    int32_t *group_of_node; /* group index of a node at or below a group root, -1 above */
    atomic_int failed;
    /* Progress of the whole window's render (NULL for batches: their driver reports): work
     * items of the running phase done, out of progress_items. */
    struct pn_progress *progress;
    atomic_size_t progress_done;
    size_t progress_items;
} ic_render;

/* The phases of a whole-window render as shares of its progress bar (fixed, not measured):
 * eye samples, point tree, Phase I, Phase II (the rest). */
#define IC_SHARE_EYE 0.25
#define IC_SHARE_TREE 0.05
#define IC_SHARE_PHASE1 0.10

static void ic_phase(ic_render *ir, double start, double end, size_t items) {
    if (!ir->progress) return;
    pn_progress_phase(ir->progress, start, end);
    atomic_store(&ir->progress_done, 0);
    ir->progress_items = items;
}

/* One work item of the running phase is done. */
static void ic_step(ic_render *ir) {
    if (!ir->progress || ir->progress_items == 0) return;
    size_t done = atomic_fetch_add(&ir->progress_done, 1) + 1;
    pn_progress_report(ir->progress, (double)done / (double)ir->progress_items);
}

static bool ic_cancelled(const ic_render *ir) {
    return atomic_load(ir->job->cancel) != 0;
}

static float light_radius(const ic_render *ir, const pn_light_node *q, int kind) {
    float r = pn_light_node_radius(q);
    return kind == PN_VPL_DIRECTIONAL ? r * ir->scene_diameter : r;
}

/* Shades point p with light cluster q (eq. 3); returns the contribution (shadowed) and counts
 * the shadow ray. With `assume_visible`, no ray is traced. */
static vec3 shade_point(const ic_render *ir, ic_point *p, const pn_light_node *q, int assume_visible) {
    const pn_vpl_data *d = ir->d;
    vec3 wi;
    float dist;
    vec3 c = pn_vpl_contribution_inline(ir->job->lights, &d->set.vpls[q->rep], q->intensity, &p->r, d->set.min_dist2,
                                        &wi, &dist);
    if (v3_is_zero(c)) return c;
    if (assume_visible) return c;
    p->shadow_rays++;
    float t = pn_vpl_transmittance(ir->job->accel, &p->r, wi, dist, !ir->job->opaque_glass);
    return t == 1.0f ? c : v3_scale(c, t);
}

/* ---- Phase I ----------------------------------------------------------------------------- */

static float light_aperture(const pn_light_node *q, int kind) {
    if (kind == PN_VPL_OMNI) return 0.0f;
    if (kind == PN_VPL_ORIENTED) return 2.0f * q->half;
    return 2.0f * asinf(fminf(1.0f, pn_light_node_radius(q)));
}

/* Phase I's choice of the cluster to refine for a pair that fails the criteria (not both
 * leaves): the larger one, as the paper, except that a light cone wider than 20 degrees is
 * narrowed only by refining Q — refining R there would split the point cluster down to single
 * points first and multiply the pairs without bringing the pair closer to the criteria. */
bool pn_illumcut_phase1_refines_light(float r_radius, float q_radius, bool q_narrow, bool r_leaf, bool q_leaf) {
    if (q_leaf) return false;
    return r_leaf || !q_narrow || q_radius > r_radius;
}

typedef struct ic_pair {
    int32_t r, q;
    int32_t kind;
} ic_pair;

typedef struct pair_stack {
    ic_pair *v;
    size_t n, cap;
} pair_stack;

static bool stack_push(pair_stack *s, ic_pair p) {
    if (s->n == s->cap) {
        size_t cap = s->cap ? s->cap * 2 : 256;
        ic_pair *v = realloc(s->v, cap * sizeof *v);
        if (!v) return false;
        s->v = v;
        s->cap = cap;
    }
    s->v[s->n++] = p;
    return true;
}

/* A shading job: the points [a, b) (inside one group) with light node q. */
typedef struct ic_item {
    int32_t a, b, q;
    bool leaf_ok; /* Q is one VPL and the pair passed the bound test: Algorithm 2 may sample it */
} ic_item;

typedef struct ic_group {
    int32_t root; /* point-tree node */
    ic_item *items;
    size_t n, cap;
    pair_stack pending;  /* pairs below the group root, descended by the group's worker */
    pair_stack pending1; /* the same for Phase I */
} ic_group;

/* Phase I's descent over a stack of pairs. With group < 0 (the top, one thread), pairs whose R
 * lies inside a group are queued to that group instead (see phase2 for why). */
static bool phase1_descend(ic_render *ir, pair_stack *st, int32_t group) {
    const pn_light_tree *lt = &ir->d->tree;
    ic_tree *t = &ir->tree;
    float clamp = ir->d->set.clamp_distance;
    while (st->n > 0) {
        ic_pair pr = st->v[--st->n];
        if (group < 0 && ir->group_of_node[pr.r] >= 0) {
            if (!stack_push(&ir->groups[ir->group_of_node[pr.r]].pending1, pr)) return false;
            continue;
        }
        ic_node *R = &t->nodes[pr.r];
        const pn_light_node *Q = &lt->nodes[pr.q];
        float rR = node_radius(R), rQ = light_radius(ir, Q, pr.kind);
        float dRQ;
        if (pr.kind == PN_VPL_DIRECTIONAL) {
            dRQ = INFINITY;
        } else {
            vec3 cR = v3_scale(v3_add(R->lo, R->hi), 0.5f), cQ = v3_scale(v3_add(Q->lo, Q->hi), 0.5f);
            dRQ = fmaxf(v3_length(v3_sub(cR, cQ)) - rR - pn_light_node_radius(Q), clamp);
        }
        bool r_leaf = R->left < 0, q_leaf = Q->left < 0;
        bool narrow = light_aperture(Q, pr.kind) < IC_PHASE1_APERTURE;
        bool close_enough = fmaxf(rR, rQ) < IC_PHASE1_RATIO * dRQ && narrow;
        if (close_enough || (r_leaf && q_leaf)) {
            /* Spectral mode: the representative's wavelengths to sRGB (Phase I is shared by points
             * of other wavelengths). */
            R->acc = v3_add(R->acc, pn_swl_rgb(&t->points[R->rep].r.wl, shade_point(ir, &t->points[R->rep], Q, 0)));
            continue;
        }
        bool refine_q = pn_illumcut_phase1_refines_light(rR, rQ, narrow, r_leaf, q_leaf);
        if (refine_q) {
            if (!stack_push(st, (ic_pair){pr.r, Q->left, pr.kind}) ||
                !stack_push(st, (ic_pair){pr.r, Q->right, pr.kind}))
                return false;
        } else {
            if (!stack_push(st, (ic_pair){R->left, pr.q, pr.kind}) ||
                !stack_push(st, (ic_pair){R->right, pr.q, pr.kind}))
                return false;
        }
    }
    return true;
}

static void reverse_pairs(pair_stack *st) {
    for (size_t i = 0, j = st->n; i + 1 < j; i++, j--) {
        ic_pair tmp = st->v[i];
        st->v[i] = st->v[j - 1];
        st->v[j - 1] = tmp;
    }
}

static void phase1_group(void *user, size_t gi, int worker) {
    (void)worker;
    ic_render *ir = user;
    ic_group *g = &ir->groups[gi];
    reverse_pairs(&g->pending1);
    if (!phase1_descend(ir, &g->pending1, (int32_t)gi)) atomic_store(&ir->failed, PN_ERROR_OUT_OF_MEMORY);
    ic_step(ir);
}

/* Phase I: the top of the descent on one thread, the groups in parallel (as Phase II), then the
 * accumulations pushed to the points and the minimum radiance (`color`) pulled up. */
static pn_status phase1(ic_render *ir, pn_threadpool *pool) {
    const pn_light_tree *lt = &ir->d->tree;
    ic_tree *t = &ir->tree;
    pair_stack st = {0};
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++)
        if (lt->roots[k] >= 0 && !stack_push(&st, (ic_pair){0, lt->roots[k], k})) {
            free(st.v);
            return PN_ERROR_OUT_OF_MEMORY;
        }
    bool ok = phase1_descend(ir, &st, -1);
    free(st.v);
    if (!ok) return PN_ERROR_OUT_OF_MEMORY;
    pn_threadpool_run(pool, (size_t)ir->group_count, phase1_group, ir);
    if (atomic_load(&ir->failed)) return (pn_status)atomic_load(&ir->failed);
    /* Push the accumulations down (nodes are in pre-order: parents before children), then the
     * minimum luminance up. */
    for (int32_t i = 0; i < t->node_count; i++) {
        ic_node *n = &t->nodes[i];
        if (n->left >= 0) {
            t->nodes[n->left].acc = v3_add(t->nodes[n->left].acc, n->acc);
            t->nodes[n->right].acc = v3_add(t->nodes[n->right].acc, n->acc);
        } else {
            for (int32_t j = n->first; j < n->first + n->count; j++) t->points[j].approx = n->acc;
        }
    }
    for (int32_t i = t->node_count - 1; i >= 0; i--) {
        ic_node *n = &t->nodes[i];
        if (n->left >= 0) {
            n->color = fminf(t->nodes[n->left].color, t->nodes[n->right].color);
        } else {
            float m = INFINITY;
            for (int32_t j = n->first; j < n->first + n->count; j++)
                m = fminf(m, fmaxf(0.0f, v3_luminance(t->points[j].approx)));
            n->color = m;
        }
    }
    return PN_OK;
}

/* ---- Phase II ----------------------------------------------------------------------------- */

/* ---- shadow rays traced as packets ---------------------------------------------------------- */

/* The rays of one pair all go from nearby points (a Morton-ordered sub-array) to one VPL, so they
 * are traced together as Embree packets (pn_accel_occluded_packet) instead of one by one. Each
 * ray is the one pn_vpl_visible would trace (same origin offset, direction and tfar), so the
 * answers are the same but for rays exactly through a triangle edge (see pn_accel_occluded_packet
 * and the header). */
#define IC_PACKET 16

/* The additions to the points' sums of one group's Phase II, queued in order, with the shadow
 * rays of the point-by-point shading: an entry adds c to its point unless its ray (if it has
 * one) is occluded. The rays are traced when 16 are pending (one packet, possibly spanning
 * consecutive pairs), and the entries applied in the order they were made, so every point's sum
 * is added in the same order as without the queue. */
#define IC_QUEUE 256
typedef struct ic_rays {
    int n, nr; /* entries, rays among them */
    int32_t point[IC_QUEUE];
    vec3 c[IC_QUEUE];
    float e[IC_QUEUE];         /* PN_AOV_ILLUMINANCE: the same addition's illuminance (pair_lux) */
    float m[IC_QUEUE];         /* PN_AOV_MELANOPIC_EDI: its melanopic EDI (pair_mel) */
    signed char ray[IC_QUEUE]; /* index into the rays, or -1 */
    vec3 o[IC_PACKET], d[IC_PACKET];
    float tmin[IC_PACKET], tmax[IC_PACKET];
} ic_rays;

/* The packet's shadow-ray visibilities: 0 or 1 by pn_accel_occluded_packet, or with thin glass
 * passed (pn_shadow_transmittance) the panes' transmittance. */
static void ic_packet_visibility(const ic_render *ir, int n, const vec3 *o, const vec3 *d, const float *tmin,
                                 const float *tmax, float *visibility) {
    const pn_render_job *job = ir->job;
    if (job->opaque_glass || !pn_accel_has_thin_glass(job->accel)) {
        bool occluded[IC_PACKET];
        pn_accel_occluded_packet(job->accel, n, o, d, tmin, tmax, occluded);
        for (int i = 0; i < n; i++) visibility[i] = occluded[i] ? 0.0f : 1.0f;
        return;
    }
    pn_accel_transmittance_packet(job->accel, n, o, d, tmin, tmax, visibility);
}

static void rays_flush(const ic_render *ir, ic_rays *rb) {
    float visibility[IC_PACKET];
    ic_packet_visibility(ir, rb->nr, rb->o, rb->d, rb->tmin, rb->tmax, visibility);
    ic_point *pts = ir->tree.points;
    for (int i = 0; i < rb->n; i++) {
        float t = rb->ray[i] < 0 ? 1.0f : visibility[rb->ray[i]];
        if (t > 0.0f) pts[rb->point[i]].L = v3_add(pts[rb->point[i]].L, t == 1.0f ? rb->c[i] : v3_scale(rb->c[i], t));
        if (t > 0.0f && rb->e[i] != 0.0f) pts[rb->point[i]].lux += (double)(t * rb->e[i]);
        if (t > 0.0f && rb->m[i] != 0.0f) pts[rb->point[i]].mel += (double)(t * rb->m[i]);
    }
    rb->n = rb->nr = 0;
}

/* PN_AOV_ILLUMINANCE: Y of what cluster q gives the white Lambertian twin of point p
 * (pn_vpl_irradiance_receiver: its illuminance, lux), unshadowed; 0 without the AOV. Added
 * wherever the pair's contribution is, with the same visibility; a pair whose contribution is 0
 * (a black receiver) adds none, so black surfaces read 0 lx. */
static float pair_lux(const ic_render *ir, const ic_point *p, const pn_light_node *q) {
    if (!(ir->job->aovs & PN_AOV_ILLUMINANCE)) return 0.0f;
    const pn_vpl_receiver white = pn_vpl_irradiance_receiver(&p->r);
    vec3 wi;
    float dist;
    return pn_photometric(pn_vpl_contribution_inline(ir->job->lights, &ir->d->set.vpls[q->rep], q->intensity, &white,
                                                     ir->d->set.min_dist2, &wi, &dist));
}

/* PN_AOV_MELANOPIC_EDI (spectral mode): the melanopic EDI of what cluster q gives the white twin
 * of point p at p's wavelengths, unshadowed; 0 without the AOV. Added where pair_lux is. */
static float pair_mel(const ic_render *ir, const ic_point *p, const pn_light_node *q) {
    if (!(ir->job->aovs & PN_AOV_MELANOPIC_EDI) || !p->r.wl.on) return 0.0f;
    pn_vpl_receiver white = pn_vpl_irradiance_receiver(&p->r);
    white.wl = p->r.wl;
    vec3 wi;
    float dist;
    return pn_swl_melanopic_edi_on(&p->r.wl,
                                   pn_vpl_contribution_inline(ir->job->lights, &ir->d->set.vpls[q->rep], q->intensity,
                                                              &white, ir->d->set.min_dist2, &wi, &dist));
}

/* Queues c (and its illuminance e and melanopic EDI m) for point i (no ray). Adding zero changes
 * no sum, so it is not queued. */
static void add_queued(const ic_render *ir, ic_rays *rb, int32_t i, vec3 c, float e, float m) {
    if (v3_is_zero(c)) return;
    rb->point[rb->n] = i;
    rb->c[rb->n] = c;
    rb->e[rb->n] = e;
    rb->m[rb->n] = m;
    rb->ray[rb->n] = -1;
    if (++rb->n == IC_QUEUE) rays_flush(ir, rb);
}

/* shade_point for point i of the tree, its shadow ray queued in rb. */
static void shade_point_queued(const ic_render *ir, ic_rays *rb, int32_t i, const pn_light_node *Q) {
    ic_point *p = &ir->tree.points[i];
    vec3 wi;
    float dist;
    vec3 c = pn_vpl_contribution_inline(ir->job->lights, &ir->d->set.vpls[Q->rep], Q->intensity, &p->r,
                                        ir->d->set.min_dist2, &wi, &dist);
    if (v3_is_zero(c)) return;
    p->shadow_rays++;
    const float e = pair_lux(ir, p, Q), m = pair_mel(ir, p, Q);
    int k = rb->nr;
    if (!pn_vpl_shadow_ray(ir->job->accel, &p->r, dist, &rb->o[k], &rb->tmax[k])) {
        add_queued(ir, rb, i, c, e, m);
        return;
    }
    rb->d[k] = wi;
    rb->tmin[k] = 0.0f;
    rb->point[rb->n] = i;
    rb->c[rb->n] = c;
    rb->e[rb->n] = e;
    rb->m[rb->n] = m;
    rb->ray[rb->n] = (signed char)k;
    rb->nr++;
    if (++rb->n == IC_QUEUE || rb->nr == IC_PACKET) rays_flush(ir, rb);
}

/* Algorithm 2 on the point sub-array [a, b) with cluster Q; plain shading (a shadow ray per point)
 * when sampling is off, Q is a one-VPL cluster that did not pass the bound test (`leaf_ok` false)
 * or the sub-array is short. `known` is a point of [a, b) whose visibility of rep(Q) the caller's
 * samples already traced (`known_vis` 1 visible, 0 occluded; -1 none, e.g. its contribution is 0):
 * it is taken as the sample of the sub-array that holds it (instead of that sub-array's middle
 * point) and shaded with that answer, so no point traces the same ray twice and a pair never
 * costs more rays than |R|. The samples of one sub-array are traced as one packet; the
 * point-by-point rays and every addition to a point's sum go to the group's queue `rb` (flushed
 * when 16 rays are pending and at the end of the group, by phase2_group). */
static void adaptive_sampling(const ic_render *ir, ic_rays *rb, int32_t a, int32_t b, const pn_light_node *Q,
                              bool leaf_ok, int32_t known, int known_vis) {
    ic_point *pts = ir->tree.points;
    int32_t n = b - a;
    if (known < a || known >= b) known_vis = -1;
    if (!ir->job->visibility_sampling || (Q->left < 0 && !leaf_ok) || n < 8) {
        for (int32_t i = a; i < b; i++) {
            if (i == known && known_vis >= 0) {
                if (known_vis == 1)
                    add_queued(ir, rb, i, shade_point(ir, &pts[i], Q, 1), pair_lux(ir, &pts[i], Q),
                               pair_mel(ir, &pts[i], Q));
                continue; /* occluded: adds nothing */
            }
            shade_point_queued(ir, rb, i, Q);
        }
        return;
    }
    int32_t vs = n > 32 ? 16 : 8;
    int32_t where[16];
    signed char vis[16];
    /* The samples that need a ray, traced as one packet. */
    int32_t slot[16];
    vec3 ro[16], rd[16];
    float rt0[16], rt1[16];
    float occ[16];
    int nr = 0;
    for (int32_t k = 0; k < vs; k++) {
        int32_t s0 = a + (int32_t)((int64_t)n * k / vs), s1 = a + (int32_t)((int64_t)n * (k + 1) / vs);
        bool reuse = known_vis >= 0 && known >= s0 && known < s1;
        int32_t qi = reuse ? known : (s0 + s1) / 2;
        where[k] = qi;
        vis[k] = -1;
        if (s1 <= s0) continue;
        if (reuse) {
            vis[k] = (signed char)known_vis;
        } else {
            ic_point *q = &pts[qi];
            vec3 wi;
            float dist;
            vec3 c = pn_vpl_contribution_inline(ir->job->lights, &ir->d->set.vpls[Q->rep], Q->intensity, &q->r,
                                                ir->d->set.min_dist2, &wi, &dist);
            if (v3_is_zero(c)) continue; /* does not vote */
            q->shadow_rays++;
            if (!pn_vpl_shadow_ray(ir->job->accel, &q->r, dist, &ro[nr], &rt1[nr])) {
                vis[k] = 1;
                continue;
            }
            rd[nr] = wi;
            rt0[nr] = 0.0f;
            slot[nr++] = k;
        }
    }
    /* A sample behind thin glass (0 < visibility < 1) votes both ways, so that its sub-array is
     * refined down to plain shading, which applies each point's transmittance. */
    ic_packet_visibility(ir, nr, ro, rd, rt0, rt1, occ);
    for (int i = 0; i < nr; i++) vis[slot[i]] = occ[i] == 1.0f ? 1 : occ[i] > 0.0f ? 2 : 0;
    int visible = 0, occluded = 0;
    for (int32_t k = 0; k < vs; k++) {
        if (vis[k] == 1 || vis[k] == 2) visible++;
        if (vis[k] == 0 || vis[k] == 2) occluded++;
    }
    if (visible > 0 && occluded == 0) {
        for (int32_t i = a; i < b; i++)
            add_queued(ir, rb, i, shade_point(ir, &pts[i], Q, 1), pair_lux(ir, &pts[i], Q), pair_mel(ir, &pts[i], Q));
    } else if (occluded > 0 && visible == 0) {
        return;
    } else {
        for (int32_t k = 0; k < vs; k++) {
            int32_t s0 = a + (int32_t)((int64_t)n * k / vs), s1 = a + (int32_t)((int64_t)n * (k + 1) / vs);
            if (s1 > s0) adaptive_sampling(ir, rb, s0, s1, Q, leaf_ok, where[k], vis[k]);
        }
    }
}

/* One pair (or a group's part of it): Algorithm 2; its additions go to the group's queue. */
static void shade_pair(const ic_render *ir, ic_rays *rb, int32_t a, int32_t b, const pn_light_node *Q, bool leaf_ok) {
    adaptive_sampling(ir, rb, a, b, Q, leaf_ok, -1, -1);
}

static bool group_add_item(ic_group *g, ic_item it) {
    if (g->n == g->cap) {
        size_t cap = g->cap ? g->cap * 2 : 64;
        ic_item *v = realloc(g->items, cap * sizeof *v);
        if (!v) return false;
        g->items = v;
        g->cap = cap;
    }
    g->items[g->n++] = it;
    return true;
}

/* Algorithm 1's loop over a stack; `emit` decides what happens to a pair to shade: with
 * group >= 0 the pair is shaded at once (the worker owns the group's points), else it is split
 * into the groups it covers and queued. Pairs whose R lies inside a group are handed to that
 * group when group < 0. `queue` is the group's queue of additions (group >= 0; NULL above the groups,
 * which shade nothing). Returns false when out of memory. */
static bool algorithm1(ic_render *ir, pair_stack *W, int32_t group, ic_rays *queue, uint64_t *bound_evals,
                       uint64_t *pairs) {
    const pn_light_tree *lt = &ir->d->tree;
    ic_tree *t = &ir->tree;
    const float delta = ir->job->error_bound;
    const float min_dist2 = ir->d->set.min_dist2;
    /* Counted locally and added once: the callers' totals of neighbouring groups share cache
     * lines, and two workers incrementing them on every pair kept those lines moving between
     * the cores. */
    uint64_t n_bounds = 0, n_pairs = 0;
    bool ok = true;
    while (W->n > 0) {
        ic_pair pr = W->v[--W->n];
        if (group < 0 && ir->group_of_node[pr.r] >= 0) {
            if (!stack_push(&ir->groups[ir->group_of_node[pr.r]].pending, pr)) {
                ok = false;
                break;
            }
            continue;
        }
        ic_node *R = &t->nodes[pr.r];
        const pn_light_node *Q = &lt->nodes[pr.q];
        bool q_leaf = Q->left < 0, r_leaf = R->left < 0;
        bool shade = q_leaf; /* one VPL: exact */
        bool leaf_ok = false;
        /* The bound test, for every pair with a cluster Q; a one-VPL pair takes it only when
         * Algorithm 2 may sample it if it passes (see the header). */
        if (!q_leaf || (ir->job->visibility_sampling && R->count >= 8)) {
            pn_receiver_bounds rb = node_bounds(R);
            pn_light_bounds lb = pn_light_node_bounds(Q, pr.kind);
            float ub = pn_bound_error(&rb, &lb, Q->intensity, min_dist2);
            n_bounds++;
            R->bound_acc += 1.0f / (float)R->count;
            if (ub <= 0.0f) continue;            /* nothing of Q reaches R */
            bool passes = delta * R->color > ub; /* IsIllumAwarePair, eq. 4-5 */
            if (q_leaf)
                leaf_ok = passes;
            else
                shade = passes;
        }
        if (shade) {
            n_pairs++;
            R->pair_acc += 1.0f;
            if (group >= 0) {
                shade_pair(ir, queue, R->first, R->first + R->count, Q, leaf_ok);
            } else {
                /* R spans several groups: one item per group, each on its part of R's range. */
                /* Groups are disjoint sub-trees in pre-order: their ranges are sorted. */
                int32_t lo = 0, hi = ir->group_count;
                while (hi - lo > 1) {
                    int32_t mid = (lo + hi) / 2;
                    if (t->nodes[ir->groups[mid].root].first <= R->first)
                        lo = mid;
                    else
                        hi = mid;
                }
                for (int32_t g = lo; g < ir->group_count; g++) {
                    const ic_node *G = &t->nodes[ir->groups[g].root];
                    if (G->first >= R->first + R->count) break;
                    int32_t a = R->first > G->first ? R->first : G->first;
                    int32_t b = R->first + R->count < G->first + G->count ? R->first + R->count : G->first + G->count;
                    if (a < b && !group_add_item(&ir->groups[g], (ic_item){a, b, pr.q, leaf_ok})) {
                        ok = false;
                        break;
                    }
                }
                if (!ok) break;
            }
            continue;
        }
        bool refine_q = r_leaf || (light_radius(ir, Q, pr.kind) > node_radius(R));
        if (refine_q) {
            if (!stack_push(W, (ic_pair){pr.r, Q->left, pr.kind}) ||
                !stack_push(W, (ic_pair){pr.r, Q->right, pr.kind})) {
                ok = false;
                break;
            }
        } else {
            if (!stack_push(W, (ic_pair){R->left, pr.q, pr.kind}) ||
                !stack_push(W, (ic_pair){R->right, pr.q, pr.kind})) {
                ok = false;
                break;
            }
        }
    }
    *bound_evals += n_bounds;
    *pairs += n_pairs;
    return ok;
}

typedef struct ic_worker_totals {
    uint64_t bound_evals, pairs;
} ic_worker_totals;

typedef struct ic_phase2_job {
    ic_render *ir;
    ic_worker_totals *per_group;
} ic_phase2_job;

/* Spectral mode: the most memory of one group's memo of illuminant spectra (pn_swl_memo). */
#define IC_MEMO_BYTES ((size_t)8 << 20)

static void phase2_group(void *user, size_t gi, int worker) {
    (void)worker;
    ic_phase2_job *pj = user;
    ic_render *ir = pj->ir;
    ic_group *g = &ir->groups[gi];
    if (atomic_load(ir->job->cancel)) return;
    ic_rays *rb = malloc(sizeof *rb);
    if (!rb) {
        atomic_store(&ir->failed, PN_ERROR_OUT_OF_MEMORY);
        return;
    }
    rb->n = rb->nr = 0;
    /* Spectral mode: a memo of illuminant spectra for each point of the group (transport.h's
     * pn_swl_memo), detached below; without memory the conversions take the slower path (the
     * same values). */
    const ic_node *root = &ir->tree.nodes[g->root];
    ic_point *gp = ir->tree.points + root->first;
    pn_swl_memo *memo = ir->job->spectral ? pn_swl_memo_new(root->count, IC_MEMO_BYTES) : NULL;
    if (memo)
        for (int32_t i = 0; i < root->count; i++) pn_swl_memo_attach(&gp[i].r.wl, memo, i);
    /* First the pairs shaded above the group (in Algorithm 1's order), then the group's own
     * descent. */
    for (size_t i = 0; i < g->n; i++) {
        const ic_item *it = &g->items[i];
        shade_pair(ir, rb, it->a, it->b, &ir->d->tree.nodes[it->q], it->leaf_ok);
    }
    /* The pending pairs were pushed in Algorithm 1's order; reverse them so that popping the
     * stack visits them in that order. */
    reverse_pairs(&g->pending);
    if (!algorithm1(ir, &g->pending, (int32_t)gi, rb, &pj->per_group[gi].bound_evals, &pj->per_group[gi].pairs))
        atomic_store(&ir->failed, PN_ERROR_OUT_OF_MEMORY);
    rays_flush(ir, rb);
    free(rb);
    if (memo) {
        for (int32_t i = 0; i < root->count; i++) pn_swl_memo_detach(&gp[i].r.wl);
        pn_swl_memo_free(memo);
    }
    ic_step(ir);
}

/* Marks the groups: the highest point-tree nodes with at most `limit` points. */
static bool make_groups(ic_render *ir, int32_t limit) {
    ic_tree *t = &ir->tree;
    ir->group_of_node = malloc((size_t)t->node_count * sizeof *ir->group_of_node);
    ir->groups = NULL;
    ir->group_count = 0;
    if (!ir->group_of_node) return false;
    int32_t cap = 0;
    for (int32_t i = 0; i < t->node_count; i++) ir->group_of_node[i] = -1;
    /* Pre-order: a node is a group root when it is small enough and its parent was not in a
     * group; children inherit their parent's group. */
    for (int32_t i = 0; i < t->node_count; i++) {
        ic_node *n = &t->nodes[i];
        if (ir->group_of_node[i] < 0 && (n->count <= limit || n->left < 0)) {
            if (ir->group_count == cap) {
                cap = cap ? cap * 2 : 64;
                ic_group *g = realloc(ir->groups, (size_t)cap * sizeof *g);
                if (!g) return false;
                ir->groups = g;
            }
            memset(&ir->groups[ir->group_count], 0, sizeof ir->groups[0]);
            ir->groups[ir->group_count].root = i;
            ir->group_of_node[i] = ir->group_count++;
        }
        if (n->left >= 0 && ir->group_of_node[i] >= 0) {
            ir->group_of_node[n->left] = ir->group_of_node[i];
            ir->group_of_node[n->right] = ir->group_of_node[i];
        }
    }
    return true;
}

/* Phase II over the whole point tree. The top of Algorithm 1 (pairs whose R is larger than a
 * group) runs on one thread; every pair it would shade is split into per-group items, and every
 * pair whose R is inside a group is queued to that group. The groups then run in parallel, each
 * shading its items in order and descending its queued pairs with Algorithm 1. A point belongs to
 * one group, so its sum is always added in the same order (deterministic). Algorithm 2 on an item
 * that is part of a larger R works on that part only. */
static pn_status phase2(ic_render *ir, pn_threadpool *pool, uint64_t *bound_evals, uint64_t *pairs) {
    const pn_light_tree *lt = &ir->d->tree;
    pair_stack W = {0};
    for (int k = PN_VPL_KIND_COUNT - 1; k >= 0; k--)
        if (lt->roots[k] >= 0 && !stack_push(&W, (ic_pair){0, lt->roots[k], k})) return PN_ERROR_OUT_OF_MEMORY;
    bool ok = algorithm1(ir, &W, -1, NULL, bound_evals, pairs);
    free(W.v);
    if (!ok) return PN_ERROR_OUT_OF_MEMORY;
    ic_worker_totals *tot = calloc((size_t)ir->group_count + 1, sizeof *tot);
    if (!tot) return PN_ERROR_OUT_OF_MEMORY;
    ic_phase2_job pj = {ir, tot};
    pn_threadpool_run(pool, (size_t)ir->group_count, phase2_group, &pj);
    for (int32_t g = 0; g < ir->group_count; g++) {
        *bound_evals += tot[g].bound_evals;
        *pairs += tot[g].pairs;
    }
    free(tot);
    return (pn_status)atomic_load(&ir->failed);
}

/* ---- the whole image ---------------------------------------------------------------------- */

typedef struct ic_eye_job {
    ic_render *ir;
} ic_eye_job;

#define IC_EYE_CHUNK 64

static void eye_chunk(void *user, size_t chunk, int worker) {
    (void)worker;
    ic_render *ir = ((ic_eye_job *)user)->ir;
    const pn_render_job *job = ir->job;
    if (ic_cancelled(ir)) return;
    size_t first = chunk * IC_EYE_CHUNK;
    size_t end = (chunk + 1) * IC_EYE_CHUNK < (size_t)ir->count ? (chunk + 1) * IC_EYE_CHUNK : (size_t)ir->count;
    /* The eye samples come from the driver: its batch's, or for the window in raster order
     * through a batch of this chunk's pixels with the window's tracers (render/batch.h). */
    const pn_batch *from = ir->batch;
    size_t base = 0;
    int32_t xy[IC_EYE_CHUNK][2];
    pn_batch part;
    if (!ir->coords) {
        for (size_t pix = first; pix < end; pix++) {
            xy[pix - first][0] = job->camera.x0 + (int)(pix % (size_t)ir->width);
            xy[pix - first][1] = job->camera.y0 + (int)(pix / (size_t)ir->width);
        }
        part = pn_batch_part(ir->batch, 0, 0, (int)(end - first), (const int32_t(*)[2])xy);
        from = &part;
        base = first;
    }
    for (size_t pix = first; pix < end; pix++) {
        pn_pixel_estimate *o = &ir->pixels[pix];
        memset(o, 0, sizeof *o);
        o->depth = INFINITY;
        for (uint32_t s = 0; s < ir->spp; s++) {
            pn_shading_point sp;
            pn_batch_eye_point(job, from, (int)(pix - base), s, &sp, o);
            ic_sample *smp = &ir->samples[pix * ir->spp + s];
            smp->emitted = pn_swl_rgb(&sp.r.wl, sp.emitted); /* spectral mode: to sRGB here */
            smp->throughput = sp.throughput;
            smp->weight = sp.weight;
            smp->point = sp.has_point ? 0 : -1;
            /* The receiver is parked in the sample's slot of the point array for now. */
            if (sp.has_point) ir->tree.points[pix * ir->spp + s].r = sp.r;
        }
    }
    ic_step(ir);
}

static void free_render(ic_render *ir) {
    free(ir->tree.points);
    free(ir->tree.nodes);
    free(ir->samples);
    for (int32_t g = 0; g < ir->group_count; g++) {
        free(ir->groups[g].items);
        free(ir->groups[g].pending.v);
        free(ir->groups[g].pending1.v);
    }
    free(ir->groups);
    free(ir->group_of_node);
}

/* IlluminationCut over a set of pixels: the window in raster order (coords NULL, `width` wide)
 * or a batch's pixels. The whole render's statistics are stored (whole window) or added (batches,
 * possibly from several threads). */
static pn_status illumcut_render_pixels(const pn_render_job *job, pn_threadpool *pool, const pn_batch *batch,
                                        const int32_t (*coords)[2], int32_t count, int width,
                                        pn_pixel_estimate *pixels) {
    pn_vpl_data *d = job->integrator_data;
    ic_render ir;
    memset(&ir, 0, sizeof ir);
    ir.job = job;
    ir.d = d;
    ir.pixels = pixels;
    ir.coords = coords;
    ir.batch = batch;
    ir.count = count;
    ir.width = width;
    ir.spp = pn_vpl_spp(job);
    ir.scene_diameter = 2.0f * job->lights->scene_radius;
    atomic_init(&ir.failed, 0);
    ir.progress = coords ? NULL : job->progress;
    atomic_init(&ir.progress_done, 0);
    size_t n = (size_t)count * ir.spp;
    if (n > (size_t)INT32_MAX) return PN_ERROR_UNSUPPORTED;
    ir.samples = malloc(n * sizeof *ir.samples);
    ir.tree.points = calloc(n, sizeof *ir.tree.points);
    if (!ir.samples || !ir.tree.points) {
        free_render(&ir);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    /* Eye samples (parallel by chunks of pixels), then the points compacted in sample order. */
    ic_eye_job ej = {&ir};
    size_t eye_chunks = ((size_t)count + IC_EYE_CHUNK - 1) / IC_EYE_CHUNK;
    ic_phase(&ir, 0.0, IC_SHARE_EYE, eye_chunks);
    pn_threadpool_run(pool, eye_chunks, eye_chunk, &ej);
    /* Cancelled: the samples are incomplete; the driver reports the render as cancelled. */
    if (ic_cancelled(&ir)) {
        free_render(&ir);
        return PN_OK;
    }
    int32_t m = 0;
    for (size_t i = 0; i < n; i++) {
        if (ir.samples[i].point < 0) continue;
        ir.tree.points[m] = ir.tree.points[i];
        ir.tree.points[m].sample = (int32_t)i;
        ir.samples[i].point = m;
        m++;
    }
    ir.tree.point_count = m;
    double t0 = pn_clock_seconds();
    ic_phase(&ir, IC_SHARE_EYE, IC_SHARE_EYE + IC_SHARE_TREE, 1);
    pn_status st = build_point_tree(&ir.tree, job->seed ^ UINT64_C(0x9071));
    ic_step(&ir);
    double t1 = pn_clock_seconds();
    /* The build permuted the points (Morton order): re-link the samples. */
    for (int32_t j = 0; j < ir.tree.point_count; j++) ir.samples[ir.tree.points[j].sample].point = j;
    uint64_t bound_evals = 0, pairs = 0;
    /* Groups (independent of the thread count, so that the image is too). */
    int32_t limit = m / 256 + 1;
    if (limit < 256) limit = 256;
    if (st == PN_OK && m > 0 && !make_groups(&ir, limit)) st = PN_ERROR_OUT_OF_MEMORY;
    const double p1 = IC_SHARE_EYE + IC_SHARE_TREE, p2 = p1 + IC_SHARE_PHASE1;
    ic_phase(&ir, p1, p2, (size_t)ir.group_count);
    /* Cancelled before Phase II: no point has its radiance; the driver reports the cancel. */
    if (st == PN_OK && ic_cancelled(&ir)) {
        free_render(&ir);
        return PN_OK;
    }
    if (st == PN_OK && m > 0) st = phase1(&ir, pool);
    double t2 = pn_clock_seconds();
    ic_phase(&ir, p2, 1.0, (size_t)ir.group_count);
    if (st == PN_OK && m > 0 && !ic_cancelled(&ir)) st = phase2(&ir, pool, &bound_evals, &pairs);
    double t3 = pn_clock_seconds();
    if (st != PN_OK) {
        free_render(&ir);
        return st;
    }
    /* Amortised bound evaluations and pair counts down to the points. */
    ic_tree *t = &ir.tree;
    for (int32_t i = 0; i < t->node_count; i++) {
        ic_node *nd = &t->nodes[i];
        if (nd->left >= 0) {
            t->nodes[nd->left].bound_acc += nd->bound_acc;
            t->nodes[nd->right].bound_acc += nd->bound_acc;
            t->nodes[nd->left].pair_acc += nd->pair_acc;
            t->nodes[nd->right].pair_acc += nd->pair_acc;
        } else {
            for (int32_t j = nd->first; j < nd->first + nd->count; j++) {
                t->points[j].bounds = nd->bound_acc;
                t->points[j].pairs = nd->pair_acc;
            }
        }
    }
    /* Pixels from their samples. */
    uint64_t points_total = 0;
    double pair_total = 0.0;
    for (int32_t ip = 0; ip < count; ip++) {
        size_t pix = (size_t)ip;
        pn_pixel_estimate *o = &pixels[pix];
        vec3 sum = v3(0, 0, 0), approx = v3(0, 0, 0);
        double wsum = 0.0, lux = 0.0, mel = 0.0;
        float bounds = 0.0f, pr = 0.0f;
        int pts = 0;
        for (uint32_t s = 0; s < ir.spp; s++) {
            const ic_sample *smp = &ir.samples[pix * ir.spp + s];
            vec3 value = smp->emitted, a = smp->emitted;
            if (smp->point >= 0) {
                const ic_point *p = &t->points[smp->point];
                value = v3_add(value, pn_swl_rgb(&p->r.wl, v3_mul(smp->throughput, p->L)));
                a = v3_add(a, v3_mul(smp->throughput, p->approx));
                o->shadow_rays += p->shadow_rays;
                if (isfinite(p->lux)) lux += p->lux * (double)smp->weight;
                if (isfinite(p->mel)) mel += p->mel * (double)smp->weight;
                bounds += p->bounds;
                pr += p->pairs;
                pts++;
            }
            if (!v3_is_finite(value)) {
                value = v3(0, 0, 0);
                o->non_finite++;
            }
            if (!v3_is_finite(a)) a = v3(0, 0, 0);
            sum = v3_madd(sum, value, smp->weight);
            approx = v3_madd(approx, a, smp->weight);
            wsum += (double)smp->weight;
        }
        if (wsum != 0.0) {
            o->radiance = v3_scale(sum, (float)(1.0 / wsum));
            o->phase1 = v3_scale(approx, (float)(1.0 / wsum));
            o->illuminance = (float)(lux / wsum);
            o->melanopic_edi = (float)(mel / wsum);
        }
        o->bound_evaluations = bounds;
        o->cut_size = pts ? pr / (float)pts : 0.0f;
        points_total += (uint64_t)pts;
        pair_total += (double)pr;
    }
    if (!coords) {
        /* Summed: the tiled driver's split renders (--tile-size) call this once per tile. */
        d->point_tree_seconds += t1 - t0;
        d->phase1_seconds += t2 - t1;
        d->phase2_seconds += t3 - t2;
        d->pairs += pairs;
        atomic_fetch_add(&d->bound_evaluations, bound_evals);
        atomic_fetch_add(&d->points, points_total);
        atomic_fetch_add(&d->cut_nodes, (uint64_t)(pair_total + 0.5));
    } else {
        /* Batches: counters only (the phase times of concurrent batches do not add up). */
        atomic_fetch_add(&d->bound_evaluations, bound_evals);
        atomic_fetch_add(&d->points, points_total);
        atomic_fetch_add(&d->cut_nodes, (uint64_t)(pair_total + 0.5));
    }
    free_render(&ir);
    return PN_OK;
}

static pn_status illumcut_render_image(const pn_render_job *job, pn_threadpool *pool, const pn_batch *window,
                                       pn_pixel_estimate *pixels, int width, int height) {
    return illumcut_render_pixels(job, pool, window, NULL, (int32_t)width * height, width, pixels);
}

static pn_status illumcut_prepare(pn_render_job *job, pn_err *err) {
    return pn_vpl_prepare(job, true, err);
}

/* For drivers that hand out batches (the default driver uses the whole-image hook instead): the
 * point tree spans the batch, on the calling thread. */
static pn_status illumcut_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                       void *scratch) {
    (void)scratch;
    return illumcut_render_pixels(job, NULL, batch, batch->pixels, batch->count, 0, out);
}

const pn_integrator pn_integrator_illumcut = {
    .name = "illumcut",
    .prepare = illumcut_prepare,
    .release = pn_vpl_release,
    .report = pn_vpl_report,
    .render_batch = illumcut_render_batch,
    .render_image = illumcut_render_image,
    .batch_points = pn_vpl_batch_points, /* batches only: the whole-image path reads its points one by one */
};

/* ---- for the tests ------------------------------------------------------------------------ */

int pn_illumcut_check_point_tree(const pn_vpl_receiver *receivers, int count, uint64_t seed) {
    ic_tree t;
    memset(&t, 0, sizeof t);
    t.points = calloc((size_t)count + 1, sizeof *t.points);
    if (!t.points) return -2;
    for (int i = 0; i < count; i++) {
        t.points[i].r = receivers[i];
        t.points[i].sample = i;
    }
    t.point_count = count;
    if (build_point_tree(&t, seed) != PN_OK) {
        free(t.points);
        free(t.nodes);
        return -2;
    }
    int bad = 0, why = 0;
    int *seen = calloc((size_t)count + 1, sizeof *seen);
    if (!seen) bad = 1;
    for (int32_t i = 0; i < t.node_count && !bad; i++) {
        const ic_node *n = &t.nodes[i];
        if (n->first < 0 || n->count <= 0 || n->first + n->count > count) bad = why = 1;
        if (n->left >= 0) {
            const ic_node *a = &t.nodes[n->left], *b = &t.nodes[n->right];
            if (a->first != n->first || b->first != a->first + a->count || a->count + b->count != n->count)
                bad = why = 2;
            if (n->left <= i || n->right <= i) bad = why = 3;
        } else {
            for (int32_t j = n->first; j < n->first + n->count; j++) seen[t.points[j].sample]++;
        }
        if (n->rep < n->first || n->rep >= n->first + n->count) bad = why = 4;
        for (int32_t j = n->first; j < n->first + n->count && !bad; j++) {
            const pn_vpl_receiver *r = &t.points[j].r;
            vec3 p = r->p;
            if (p.x < n->lo.x || p.y < n->lo.y || p.z < n->lo.z || p.x > n->hi.x || p.y > n->hi.y || p.z > n->hi.z)
                bad = why = 5;
            if (atan2f(v3_length(v3_cross(r->ns, n->n_axis)), v3_dot(r->ns, n->n_axis)) > n->n_half + 1e-4f)
                bad = why = 6;
            vec3 refl = pn_reflect(r->wo, r->ns);
            if (atan2f(v3_length(v3_cross(refl, n->r_axis)), v3_dot(refl, n->r_axis)) > n->r_half + 1e-4f)
                bad = why = 7;
            bool glossy = !v3_is_zero(r->ks);
            if (r->kd.x > n->kd_max.x || r->ks.y > n->ks_max.y ||
                (glossy && (r->exponent < n->n_min || r->exponent > n->n_max)))
                bad = why = 8;
        }
    }
    for (int i = 0; i < count && !bad; i++)
        if (seen[i] != 1) bad = why = 9;
    int nodes = t.node_count;
    free(seen);
    free(t.points);
    free(t.nodes);
    /* No printing in the library: the violated invariant is in the return value. */
    return bad ? (why ? -10 - why : -2) : nodes;
}
