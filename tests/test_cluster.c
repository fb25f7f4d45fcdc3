/* test_cluster.c — the light cluster trees of Donikian et al. 2006 (IAS §4.3, §4.3.1): forest
 * structure, equivalence of the fast greedy construction with a brute-force greedy one, the
 * per-point cut (solid angle, culling, partition of the lights), power-proportional picking, the
 * importance pick at a point (its pdf sums to 1, matches the picks' frequencies and leaves out no
 * light that can light the point), and the build time for 20,000 lights. */
#include "harness.h"

#include "lights/cluster_tree.h"

#include <stdint.h>
#include <time.h>

typedef struct test_rng {
    uint64_t s;
} test_rng;

static float rnd(test_rng *r) {
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return (float)(z >> 40) * (1.0f / 16777216.0f);
}

static float rnd_range(test_rng *r, float a, float b) {
    return a + (b - a) * rnd(r);
}

static vec3 rnd_unit(test_rng *r) {
    float z = 1.0f - 2.0f * rnd(r);
    float phi = 2.0f * PN_PI * rnd(r);
    float s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    return v3(s * cosf(phi), s * sinf(phi), z);
}

static vec3 rnd_box(test_rng *r, float h) {
    return v3(rnd_range(r, -h, h), rnd_range(r, -h, h), rnd_range(r, -h, h));
}

/* A random unit vector within `spread` radians of `axis`. */
static vec3 rnd_around(test_rng *r, vec3 axis, float spread) {
    vec3 t, b;
    v3_basis(axis, &t, &b);
    float ct = cosf(spread * rnd(r)), st = sqrtf(fmaxf(0.0f, 1.0f - ct * ct));
    float phi = 2.0f * PN_PI * rnd(r);
    return v3_normalize(v3_add(v3_scale(axis, ct), v3_add(v3_scale(t, st * cosf(phi)), v3_scale(b, st * sinf(phi)))));
}

static pn_light make_light(test_rng *r, pn_light_kind kind, float h, vec3 facing, float spread, int two_sided) {
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = kind;
    l.env = -1;
    l.p = rnd_box(r, h);
    l.emit = v3(rnd(r), rnd(r), rnd(r));
    vec3 dir = v3_is_zero(facing) ? rnd_unit(r) : rnd_around(r, facing, spread);
    switch (kind) {
    case PN_LIGHT_SPOT: {
        float w = rnd_range(r, 0.05f, 1.4f);
        l.n = dir;
        l.cos_total_width = cosf(w);
        l.cos_falloff_start = cosf(w * rnd(r));
        break;
    }
    case PN_LIGHT_DISTANT: l.n = dir; break;
    case PN_LIGHT_TRIANGLE: {
        vec3 t, b;
        v3_basis(dir, &t, &b);
        /* Edges in the plane orthogonal to dir, ordered so that cross(e1, e2) points along dir. */
        l.e1 = v3_add(v3_scale(t, rnd_range(r, 0.05f, 1.0f)), v3_scale(b, rnd_range(r, -0.3f, 0.3f)));
        l.e2 = v3_add(v3_scale(t, rnd_range(r, -0.3f, 0.3f)), v3_scale(b, rnd_range(r, 0.05f, 1.0f)));
        vec3 c = v3_cross(l.e1, l.e2);
        if (v3_dot(c, dir) < 0.0f) {
            vec3 tmp = l.e1;
            l.e1 = l.e2;
            l.e2 = tmp;
            c = v3_cross(l.e1, l.e2);
        }
        l.n = v3_normalize(c);
        l.area = 0.5f * v3_length(c);
        l.two_sided = two_sided;
        break;
    }
    case PN_LIGHT_RECTANGLE: {
        vec3 t, b;
        v3_basis(dir, &t, &b);
        l.e1 = v3_scale(t, rnd_range(r, 0.05f, 1.0f));
        l.e2 = v3_scale(b, rnd_range(r, 0.05f, 1.0f));
        l.n = v3_normalize(v3_cross(l.e1, l.e2));
        l.area = v3_length(l.e1) * v3_length(l.e2);
        l.two_sided = two_sided;
        break;
    }
    case PN_LIGHT_DISK:
        l.n = dir;
        l.radius = rnd_range(r, 0.01f, 0.5f);
        l.area = PN_PI * l.radius * l.radius;
        l.two_sided = two_sided;
        break;
    case PN_LIGHT_SPHERE:
        l.radius = rnd_range(r, 0.01f, 0.5f);
        l.area = 4.0f * PN_PI * l.radius * l.radius;
        break;
    case PN_LIGHT_ENVIRONMENT: l.env = 0; break;
    default: break;
    }
    return l;
}

static pn_lights wrap_lights(pn_light *l, int count) {
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = l;
    L.count = count;
    L.scene_radius = 20.0f;
    return L;
}

/* A mix of every kind, some lights with zero emission. */
static pn_light *mixed_lights(test_rng *r, int count, float h) {
    pn_light *l = malloc((size_t)count * sizeof *l);
    static const pn_light_kind kinds[] = {PN_LIGHT_POINT,       PN_LIGHT_SPOT,     PN_LIGHT_TRIANGLE,
                                          PN_LIGHT_RECTANGLE,   PN_LIGHT_DISK,     PN_LIGHT_SPHERE,
                                          PN_LIGHT_GONIOMETRIC, PN_LIGHT_TRIANGLE, PN_LIGHT_RECTANGLE};
    for (int i = 0; i < count; i++) {
        pn_light_kind k = kinds[(int)(rnd(r) * 9.0f) % 9];
        if (i % 97 == 5) k = PN_LIGHT_DISTANT;
        if (i % 211 == 7) k = PN_LIGHT_ENVIRONMENT;
        l[i] = make_light(r, k, h, v3(0, 0, 0), 0.0f, rnd(r) < 0.3f);
        if (i % 53 == 11) l[i].emit = v3(0, 0, 0);
    }
    return l;
}

/* ---------------------------------------------------------------- independent exact tests */

static double dotd(vec3 a, vec3 b) {
    return (double)a.x * (double)b.x + (double)a.y * (double)b.y + (double)a.z * (double)b.z;
}

static vec3 subv(vec3 a, vec3 b) {
    return v3_sub(a, b);
}

/* True when light l gives no light at all to p with normal n (n = 0: no horizon), computed in
 * double from the definitions: no part of the emitter above the tangent plane, p behind a
 * one-sided emitter, or outside the spot cone. */
static bool gives_nothing(const pn_light *l, vec3 p, vec3 n) {
    bool horizon = !v3_is_zero(n);
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_GONIOMETRIC: return horizon && dotd(subv(l->p, p), n) <= 0.0;
    case PN_LIGHT_SPOT: {
        vec3 d = subv(p, l->p);
        double d2 = dotd(d, d);
        if (d2 == 0.0) return true;
        if (horizon && dotd(d, n) >= 0.0) return true;
        return dotd(d, l->n) / sqrt(d2) <= (double)l->cos_total_width;
    }
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE: {
        if (!l->two_sided && dotd(subv(p, l->p), l->n) <= 0.0) return true;
        if (!horizon) return false;
        double base = dotd(subv(l->p, p), n), a = dotd(l->e1, n), b = dotd(l->e2, n);
        double m = fmax(base, fmax(base + a, base + b));
        if (l->kind == PN_LIGHT_RECTANGLE) m = fmax(m, base + a + b);
        return m <= 0.0;
    }
    case PN_LIGHT_DISK: {
        if (!l->two_sided && dotd(subv(p, l->p), l->n) <= 0.0) return true;
        if (!horizon) return false;
        double c = dotd(l->n, n);
        return dotd(subv(l->p, p), n) + (double)l->radius * sqrt(fmax(0.0, 1.0 - c * c)) <= 0.0;
    }
    case PN_LIGHT_SPHERE: return horizon && dotd(subv(l->p, p), n) + (double)l->radius <= 0.0;
    case PN_LIGHT_DISTANT: return horizon && dotd(l->n, n) <= 0.0;
    default: return false;
    }
}

/* ---------------------------------------------------------------- structure */

static double distd(vec3 a, vec3 b) {
    vec3 d = subv(a, b);
    return sqrt(dotd(d, d));
}

static bool sphere_holds(vec3 c, float r, vec3 ci, float ri) {
    return distd(c, ci) + (double)ri <= (double)r * (1.0 + 1e-6) + 1e-6;
}

static bool sphere_holds_light(const pn_cluster_node *nd, const pn_light *l) {
    switch (l->kind) {
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE: {
        vec3 v[4] = {l->p, v3_add(l->p, l->e1), v3_add(l->p, l->e2), v3_add(v3_add(l->p, l->e1), l->e2)};
        int k = l->kind == PN_LIGHT_TRIANGLE ? 3 : 4;
        for (int i = 0; i < k; i++)
            if (!sphere_holds(nd->center, nd->radius, v[i], 0.0f)) return false;
        return true;
    }
    case PN_LIGHT_DISK:
    case PN_LIGHT_SPHERE: return sphere_holds(nd->center, nd->radius, l->p, l->radius);
    default: return sphere_holds(nd->center, nd->radius, l->p, 0.0f);
    }
}

static bool box_holds(vec3 lo, vec3 hi, vec3 ilo, vec3 ihi) {
    return lo.x <= ilo.x && lo.y <= ilo.y && lo.z <= ilo.z && hi.x >= ihi.x && hi.y >= ihi.y && hi.z >= ihi.z;
}

static void check_forest(const pn_cluster_forest *f, const pn_lights *L) {
    int *seen = calloc((size_t)(L->count > 0 ? L->count : 1), sizeof *seen);
    for (int i = 0; i < f->order_count; i++) {
        int li = f->light_order[i];
        CHECK(li >= 0 && li < L->count);
        if (li >= 0 && li < L->count) seen[li]++;
    }
    for (int i = 0; i < L->count; i++) {
        const pn_light *l = &L->lights[i];
        int t = pn_cluster_light_tree(l);
        int leaf = f->leaf_of_light[i];
        if (l->kind == PN_LIGHT_ENVIRONMENT) {
            CHECK(t == PN_CLUSTER_EXCLUDED);
            CHECK(leaf == -1);
            CHECK(seen[i] == 0);
            continue;
        }
        CHECK_MSG(seen[i] == 1, "light %d appears %d times", i, seen[i]);
        CHECK(leaf >= 0 && leaf < f->node_count);
        if (leaf < 0) continue;
        const pn_cluster_node *nd = &f->nodes[leaf];
        CHECK(nd->light == i && nd->left < 0 && nd->right < 0 && nd->count == 1);
        CHECK(f->light_order[nd->first] == i);
        CHECK(nd->tree == (t == PN_CLUSTER_SINGLE ? -1 : t));
        CHECK_NEAR(nd->power, pn_cluster_light_power(l), 1e-6 * (double)nd->power);
        if (t == PN_CLUSTER_SINGLE) {
            CHECK(nd->parent == -1);
            continue;
        }
        CHECK(sphere_holds_light(nd, l));
        /* The leaf's tree: omni kinds and two-sided planar lights in the omni tree, others by the
         * dominant axis of their normal. */
        bool omni = l->kind == PN_LIGHT_POINT || l->kind == PN_LIGHT_SPHERE || l->kind == PN_LIGHT_GONIOMETRIC ||
                    (l->kind != PN_LIGHT_SPOT && l->two_sided);
        if (omni) {
            CHECK(t == PN_TREE_OMNI);
        } else {
            float comp[3] = {l->n.x, l->n.y, l->n.z};
            int axis = 0;
            for (int a = 1; a < 3; a++)
                if (fabsf(comp[a]) > fabsf(comp[axis])) axis = a;
            CHECK(t == 1 + 2 * axis + (comp[axis] < 0.0f ? 1 : 0));
        }
        /* Every ancestor bounds the light: sphere, box, normal cone. */
        int depth = 0;
        for (int a = nd->parent; a >= 0; a = f->nodes[a].parent) {
            const pn_cluster_node *an = &f->nodes[a];
            CHECK(an->tree == t);
            CHECK(sphere_holds_light(an, l));
            CHECK(box_holds(an->bmin, an->bmax, nd->bmin, nd->bmax));
            if (t != PN_TREE_OMNI) {
                double ang = acos(fmin(1.0, dotd(an->axis, l->n)));
                CHECK_MSG(ang <= acos((double)an->cos_spread) + 1e-4, "normal outside the cone by %g",
                          ang - acos((double)an->cos_spread));
                CHECK(an->cos_emit <= nd->cos_emit);
            }
            CHECK(nd->first >= an->first && nd->first < an->first + an->count);
            if (++depth > f->node_count) break;
        }
        CHECK(depth <= f->node_count);
        CHECK(f->roots[t] >= 0);
    }
    int interior = 0;
    for (int i = 0; i < f->node_count; i++) {
        const pn_cluster_node *nd = &f->nodes[i];
        CHECK(nd->first >= 0 && nd->count >= 1 && nd->first + nd->count <= f->order_count);
        if (nd->left < 0) {
            CHECK(nd->right < 0 && nd->light >= 0);
            continue;
        }
        interior++;
        const pn_cluster_node *l = &f->nodes[nd->left], *r = &f->nodes[nd->right];
        CHECK(nd->light == -1);
        CHECK(l->parent == i && r->parent == i);
        CHECK(l->tree == nd->tree && r->tree == nd->tree);
        CHECK(sphere_holds(nd->center, nd->radius, l->center, l->radius));
        CHECK(sphere_holds(nd->center, nd->radius, r->center, r->radius));
        CHECK(box_holds(nd->bmin, nd->bmax, l->bmin, l->bmax));
        CHECK(box_holds(nd->bmin, nd->bmax, r->bmin, r->bmax));
        CHECK_NEAR(nd->power, (double)l->power + (double)r->power, 1e-5 * (double)nd->power + 1e-30);
        CHECK(l->first == nd->first && r->first == nd->first + l->count && nd->count == l->count + r->count);
    }
    int roots = 0, tree_lights = 0;
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        if (f->roots[t] < 0) continue;
        roots++;
        const pn_cluster_node *rt = &f->nodes[f->roots[t]];
        CHECK(rt->parent == -1 && rt->tree == t);
        tree_lights += rt->count;
    }
    CHECK(tree_lights + f->single_count == f->order_count);
    CHECK(f->node_count == 2 * tree_lights - roots + f->single_count);
    CHECK(interior == tree_lights - roots);
    for (int s = 0; s < f->single_count; s++) {
        const pn_cluster_node *nd = &f->nodes[f->singles[s]];
        CHECK(nd->tree == -1 && nd->count == 1 && L->lights[nd->light].kind == PN_LIGHT_DISTANT);
    }
    free(seen);
}

static void test_forest_structure(void) {
    test_rng r = {1};
    int sizes[] = {0, 1, 2, 3, 17, 600};
    for (int s = 0; s < 6; s++) {
        pn_light *l = mixed_lights(&r, sizes[s] > 0 ? sizes[s] : 1, 8.0f);
        pn_lights L = wrap_lights(l, sizes[s]);
        pn_cluster_forest f;
        pn_err err;
        pn_err_init(&err);
        CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
        check_forest(&f, &L);
        pn_cluster_forest_free(&f);
        free(l);
    }
    /* Many coincident point lights and lights on a line: degenerate but valid trees. */
    pn_light *l = malloc(3000 * sizeof *l);
    for (int i = 0; i < 3000; i++) {
        l[i] = make_light(&r, PN_LIGHT_POINT, 1.0f, v3(0, 0, 0), 0.0f, 0);
        l[i].p = i < 1500 ? v3(1, 2, 3) : v3((float)i, 0, 0);
    }
    pn_lights L = wrap_lights(l, 3000);
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    check_forest(&f, &L);
    pn_cluster_forest_free(&f);
    /* A non-finite light is refused. */
    l[7].p.x = NAN;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_ERROR_BAD_INPUT);
    CHECK(f.nodes == NULL);
    free(l);
}

/* ---------------------------------------------------------------- greedy equivalence */

/* Exact greedy by brute force, O(n^3): at each step the pair with the smallest merged sphere.
 * Checks that the forest's tree `t` made the same merges in the same order. */
static void check_greedy(const pn_cluster_forest *f, const pn_lights *L, int t) {
    int m = 0;
    int *map = malloc((size_t)(2 * L->count + 1) * sizeof *map); /* brute cluster -> forest node */
    vec3 *c = malloc((size_t)(2 * L->count + 1) * sizeof *c);
    float *rad = malloc((size_t)(2 * L->count + 1) * sizeof *rad);
    bool *alive = calloc((size_t)(2 * L->count + 1), sizeof *alive);
    for (int i = 0; i < L->count; i++) {
        if (pn_cluster_light_tree(&L->lights[i]) != t) continue;
        pn_cluster_light_sphere(&L->lights[i], &c[m], &rad[m]);
        map[m] = f->leaf_of_light[i];
        alive[m] = true;
        m++;
    }
    /* The forest's internal nodes of tree t, in index (= merge) order. */
    int *internal = malloc((size_t)(m > 0 ? m : 1) * sizeof *internal);
    int k = 0;
    for (int i = 0; i < f->node_count; i++)
        if (f->nodes[i].tree == t && f->nodes[i].left >= 0 && k < m) internal[k++] = i;
    CHECK(k == (m > 0 ? m - 1 : 0));
    int count = m, mismatches = 0;
    for (int step = 0; step + 1 < m && step < k; step++) {
        int bi = -1, bj = -1;
        float best = INFINITY;
        for (int i = 0; i < count; i++) {
            if (!alive[i]) continue;
            for (int j = i + 1; j < count; j++) {
                if (!alive[j]) continue;
                vec3 cc;
                float rr;
                pn_cluster_merge_spheres(c[i], rad[i], c[j], rad[j], &cc, &rr);
                if (rr < best) {
                    best = rr;
                    bi = i;
                    bj = j;
                }
            }
        }
        const pn_cluster_node *nd = &f->nodes[internal[step]];
        if (nd->radius != best) mismatches++;
        bool same = (nd->left == map[bi] && nd->right == map[bj]) || (nd->left == map[bj] && nd->right == map[bi]);
        if (!same) mismatches++;
        if (mismatches && mismatches < 3)
            CHECK_MSG(nd->radius == best && same, "step %d of %d: forest radius %.9g, brute force %.9g", step, m - 1,
                      (double)nd->radius, (double)best);
        pn_cluster_merge_spheres(c[bi], rad[bi], c[bj], rad[bj], &c[count], &rad[count]);
        alive[bi] = alive[bj] = false;
        alive[count] = true;
        map[count] = internal[step];
        count++;
    }
    CHECK(mismatches == 0);
    free(map);
    free(c);
    free(rad);
    free(alive);
    free(internal);
}

static void test_greedy_matches_brute_force(void) {
    test_rng r = {7};
    int sizes[] = {2, 3, 8, 25, 60, 60, 60, 200};
    for (int s = 0; s < 8; s++) {
        int n = sizes[s];
        /* Points only. */
        pn_light *l = malloc((size_t)(3 * n) * sizeof *l);
        for (int i = 0; i < n; i++) l[i] = make_light(&r, PN_LIGHT_POINT, 5.0f, v3(0, 0, 0), 0.0f, 0);
        pn_lights L = wrap_lights(l, n);
        pn_cluster_forest f;
        pn_err err;
        pn_err_init(&err);
        CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
        check_greedy(&f, &L, PN_TREE_OMNI);
        pn_cluster_forest_free(&f);
        /* Omni mix (spheres, two-sided planar, points) and one-sided lights facing roughly +z
         * and -x, so the omni, +Z and -X trees all get about n lights. */
        static const pn_light_kind kinds[] = {PN_LIGHT_POINT, PN_LIGHT_SPHERE, PN_LIGHT_TRIANGLE, PN_LIGHT_RECTANGLE,
                                              PN_LIGHT_DISK};
        for (int i = 0; i < n; i++) l[i] = make_light(&r, kinds[i % 5], 3.0f, v3(0, 0, 0), 0.0f, 1);
        for (int i = n; i < 2 * n; i++)
            l[i] = make_light(&r, i % 2 ? PN_LIGHT_SPOT : kinds[2 + i % 3], 3.0f, v3(0, 0, 1), 0.5f, 0);
        for (int i = 2 * n; i < 3 * n; i++) l[i] = make_light(&r, kinds[2 + i % 3], 3.0f, v3(-1, 0, 0), 0.5f, 0);
        L = wrap_lights(l, 3 * n);
        pn_err_init(&err);
        CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
        for (int t = 0; t < PN_TREE_COUNT; t++) check_greedy(&f, &L, t);
        check_forest(&f, &L);
        pn_cluster_forest_free(&f);
        free(l);
    }
}

/* ---------------------------------------------------------------- cut */

static void check_cut(const pn_cluster_forest *f, const pn_lights *L, vec3 p, vec3 n, float max_sa, int *out,
                      int *culled, int cap, int *mark, int *stats) {
    int nc = 0;
    int count = pn_cluster_cut_ex(f, L, p, n, max_sa, out, cap, culled, cap, &nc);
    CHECK(count <= cap && nc <= cap);
    if (count > cap || nc > cap) return;
    memset(mark, 0, (size_t)L->count * sizeof *mark);
    for (int pass = 0; pass < 2; pass++) {
        const int *list = pass == 0 ? out : culled;
        int len = pass == 0 ? count : nc;
        for (int i = 0; i < len; i++) {
            int node = list[i];
            CHECK(node >= 0 && node < f->node_count);
            const pn_cluster_node *nd = &f->nodes[node];
            float sa = pn_cluster_solid_angle(nd->center, nd->radius, p);
            if (pass == 0 && nd->left >= 0) CHECK_MSG(sa < max_sa, "taken cluster subtends %g sr", (double)sa);
            if (pass == 0 && nd->left < 0) CHECK(!pn_cluster_light_culled(&L->lights[nd->light], p, n));
            /* Every node the walk reached had all its ancestors opened: each of them subtends at
             * least the limit. */
            for (int a = nd->parent; a >= 0; a = f->nodes[a].parent) {
                const pn_cluster_node *an = &f->nodes[a];
                CHECK(pn_cluster_solid_angle(an->center, an->radius, p) >= max_sa);
            }
            for (int j = nd->first; j < nd->first + nd->count; j++) {
                int li = f->light_order[j];
                mark[li]++;
                if (pass == 1) {
                    CHECK_MSG(gives_nothing(&L->lights[li], p, n), "culled light %d (kind %d) lights the point", li,
                              (int)L->lights[li].kind);
                    stats[1]++;
                    if (L->lights[li].kind == PN_LIGHT_POINT || L->lights[li].kind == PN_LIGHT_SPOT ||
                        L->lights[li].kind == PN_LIGHT_RECTANGLE || L->lights[li].kind == PN_LIGHT_TRIANGLE)
                        CHECK_MSG(v3_is_zero(n) || pn_light_irradiance_estimate(L, &L->lights[li], p, n) <= 1e-6f,
                                  "kind %d irradiance %g", (int)L->lights[li].kind,
                                  (double)pn_light_irradiance_estimate(L, &L->lights[li], p, n));
                }
            }
            if (pass == 1 && nd->left >= 0) stats[2]++;
        }
    }
    stats[0] += count;
    for (int i = 0; i < L->count; i++) {
        int expected = L->lights[i].kind == PN_LIGHT_ENVIRONMENT ? 0 : 1;
        CHECK_MSG(mark[i] == expected, "light %d covered %d times", i, mark[i]);
    }
    /* A short buffer gets the same first entries and the full count. */
    int small[3];
    int again = pn_cluster_cut(f, L, p, n, max_sa, small, 3);
    CHECK(again == count);
    for (int i = 0; i < 3 && i < count; i++) CHECK(small[i] == out[i]);
}

static void test_cut_properties(void) {
    test_rng r = {11};
    int count = 2500;
    pn_light *l = mixed_lights(&r, count, 6.0f);
    /* Some lights in tight groups, so that clusters get taken whole. */
    for (int i = 0; i < 800; i++) {
        vec3 c = v3((float)(i / 100) * 2.0f - 7.0f, 3.0f, 0.5f);
        l[i].p = v3_add(c, rnd_box(&r, 0.2f));
    }
    pn_lights L = wrap_lights(l, count);
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    int cap = f.node_count + 1;
    int *out = malloc((size_t)cap * sizeof *out), *culled = malloc((size_t)cap * sizeof *culled);
    int *mark = malloc((size_t)count * sizeof *mark);
    int stats[3] = {0, 0, 0}; /* taken nodes, culled lights, culled interior nodes */
    float limits[] = {0.02f, 0.2f, 2.0f, 20.0f};
    for (int i = 0; i < 240; i++) {
        vec3 p = rnd_box(&r, i % 3 == 0 ? 20.0f : 7.0f);
        vec3 n = i % 10 == 9 ? v3(0, 0, 0) : rnd_unit(&r);
        check_cut(&f, &L, p, n, limits[i % 4], out, culled, cap, mark, stats);
    }
    /* Points on a floor below oriented lights facing up and down, and inside clusters. */
    for (int i = 0; i < 60; i++) {
        vec3 p = v3(rnd_range(&r, -7, 7), 3.0f + rnd_range(&r, -0.3f, 0.3f), 0.5f);
        check_cut(&f, &L, p, rnd_unit(&r), 0.02f, out, culled, cap, mark, stats);
    }
    CHECK(stats[1] > 0 && stats[2] > 0);
    /* From afar the whole scene is a few clusters; close to a group, its lights one by one. */
    int far_count = pn_cluster_cut(&f, &L, v3(0, 0, 300), v3(0, 0, -1), 0.02f, out, cap);
    CHECK_MSG(far_count < 60, "%d clusters from afar", far_count);
    int near_count = pn_cluster_cut(&f, &L, v3(-7, 3, 0.5f), v3(0, 0, 0), 0.02f, out, cap);
    CHECK(near_count > 100);
    pn_cluster_forest_free(&f);
    free(l);

    /* Oriented lights only, all facing +z above a region: points above them see none. */
    l = malloc(400 * sizeof *l);
    for (int i = 0; i < 400; i++) {
        l[i] = make_light(&r, i % 2 ? PN_LIGHT_RECTANGLE : PN_LIGHT_SPOT, 2.0f, v3(0, 0, -1), 0.3f, 0);
        if (l[i].kind == PN_LIGHT_SPOT) {
            l[i].cos_total_width = fmaxf(l[i].cos_total_width, 0.5f);
            l[i].cos_falloff_start = fmaxf(l[i].cos_falloff_start, l[i].cos_total_width);
        }
    }
    L = wrap_lights(l, 400);
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    int cap2 = f.node_count + 1;
    int *out2 = malloc((size_t)cap2 * sizeof *out2), *culled2 = malloc((size_t)cap2 * sizeof *culled2);
    int nc = 0;
    int taken = pn_cluster_cut_ex(&f, &L, v3(0, 0, 10), v3(0, 0, -1), 0.02f, out2, cap2, culled2, cap2, &nc);
    CHECK(taken == 0);
    CHECK(nc >= 1 && nc < 50); /* removed high in the tree, not light by light */
    int stats2[3] = {0, 0, 0};
    for (int i = 0; i < 50; i++)
        check_cut(&f, &L, rnd_box(&r, 6.0f), rnd_unit(&r), 0.05f, out2, culled2, cap2, mark, stats2);
    pn_cluster_forest_free(&f);
    /* A flat grid of downward panels just below a ceiling at z = 3: seen from the ceiling (normal
     * up) the whole tree is removed at its root, by its bounding box. */
    for (int i = 0; i < 400; i++) {
        l[i] = make_light(&r, PN_LIGHT_RECTANGLE, 1.0f, v3(0, 0, -1), 0.0f, 0);
        l[i].p = v3((float)(i % 20) - 10.0f, (float)(i / 20) - 10.0f, 2.95f);
        l[i].e1 = v3(0, 0.5f, 0);
        l[i].e2 = v3(0.5f, 0, 0);
        l[i].n = v3(0, 0, -1);
        l[i].area = 0.25f;
    }
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    taken = pn_cluster_cut_ex(&f, &L, v3(0.2f, 0.3f, 3.0f), v3(0, 0, 1), 0.02f, out2, cap2, culled2, cap2, &nc);
    CHECK(taken == 0 && nc == 1);
    /* From the floor, all of them are lit: clusters near the zenith, single panels nearby. */
    taken = pn_cluster_cut_ex(&f, &L, v3(0.2f, 0.3f, 0.0f), v3(0, 0, 1), 0.02f, out2, cap2, culled2, cap2, &nc);
    CHECK(taken > 0 && nc == 0);
    for (int i = 0; i < 40; i++)
        check_cut(&f, &L, v3(rnd_range(&r, -12, 12), rnd_range(&r, -12, 12), rnd_range(&r, 0, 3)), rnd_unit(&r), 0.05f,
                  out2, culled2, cap2, mark, stats2);
    pn_cluster_forest_free(&f);
    free(out2);
    free(culled2);
    free(l);
    free(out);
    free(culled);
    free(mark);
}

/* pn_cluster_cut_capped: at or above the plain cut's size the same clusters in the same order;
 * below it exactly max_count clusters, in light order, disjoint, every lit light in one of them,
 * every cluster's ancestors opened, and only clusters that subtend the limit or more left whole. */
static void test_cut_capped(void) {
    test_rng r = {23};
    int count = 2500;
    pn_light *l = mixed_lights(&r, count, 6.0f);
    for (int i = 0; i < 800; i++) l[i].p = v3_add(v3((float)(i / 100) * 2.0f - 7.0f, 3.0f, 0.5f), rnd_box(&r, 0.2f));
    pn_lights L = wrap_lights(l, count);
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    const int cap = f.node_count + 1;
    int *plain = malloc((size_t)cap * sizeof *plain), *out = malloc((size_t)cap * sizeof *out);
    int *mark = calloc((size_t)count, sizeof *mark);
    void *work = calloc(1, pn_cluster_cut_capped_work(cap));
    int capped_points = 0, whole = 0;
    float limits[] = {0.02f, 0.2f, 0.002f};
    for (int i = 0; i < 200; i++) {
        vec3 p = rnd_box(&r, i % 3 == 0 ? 20.0f : 7.0f);
        vec3 n = i % 10 == 9 ? v3(0, 0, 0) : rnd_unit(&r);
        float sa = limits[i % 3];
        int k = pn_cluster_cut(&f, &L, p, n, sa, plain, cap);
        for (int extra = 0; extra <= 5; extra += 5) {
            int c = pn_cluster_cut_capped(&f, &L, p, n, sa, k + extra, out, cap, work);
            CHECK(c == k && memcmp(out, plain, (size_t)k * sizeof *out) == 0);
        }
        int single_lit = 0;
        for (int s = 0; s < f.single_count; s++)
            single_lit += !pn_cluster_light_culled(&L.lights[f.nodes[f.singles[s]].light], p, n);
        const int caps[3] = {k / 2, k - 1, single_lit + PN_TREE_COUNT + 3};
        for (int j = 0; j < 3; j++) {
            const int m = caps[j];
            if (m >= k || m < single_lit + PN_TREE_COUNT) continue;
            capped_points++;
            int c = pn_cluster_cut_capped(&f, &L, p, n, sa, m, out, cap, work);
            CHECK_MSG(c == m, "capped at %d: %d clusters (plain %d)", m, c, k);
            memset(mark, 0, (size_t)count * sizeof *mark);
            for (int a = 0; a < c && a < cap; a++) {
                const pn_cluster_node *nd = &f.nodes[out[a]];
                if (a > 0) CHECK(f.nodes[out[a - 1]].first + f.nodes[out[a - 1]].count <= nd->first);
                if (nd->left >= 0 && pn_cluster_solid_angle(nd->center, nd->radius, p) >= sa) whole++;
                for (int up = nd->parent; up >= 0; up = f.nodes[up].parent)
                    CHECK(pn_cluster_solid_angle(f.nodes[up].center, f.nodes[up].radius, p) >= sa);
                for (int q = nd->first; q < nd->first + nd->count; q++) mark[f.light_order[q]]++;
            }
            for (int li = 0; li < count; li++) {
                if (L.lights[li].kind == PN_LIGHT_ENVIRONMENT) continue;
                CHECK(mark[li] <= 1);
                if (!gives_nothing(&L.lights[li], p, n)) CHECK_MSG(mark[li] == 1, "lit light %d in no cluster", li);
            }
        }
    }
    printf("  %d capped cuts, %d clusters left whole above the limit\n", capped_points, whole);
    CHECK(capped_points > 100 && whole > 0);
    /* No cap (0): the plain cut. */
    int k = pn_cluster_cut(&f, &L, v3(-7, 3, 0.5f), v3(0, 0, 0), 0.02f, plain, cap);
    CHECK(pn_cluster_cut_capped(&f, &L, v3(-7, 3, 0.5f), v3(0, 0, 0), 0.02f, 0, out, cap, work) == k);
    CHECK(memcmp(out, plain, (size_t)k * sizeof *out) == 0);
    pn_cluster_forest_free(&f);
    free(work);
    free(mark);
    free(out);
    free(plain);
    free(l);
}

static void test_solid_angle(void) {
    /* A sphere of radius 1 at distance 2 subtends a cone of half-angle 30 degrees. */
    double expected = 2.0 * M_PI * (1.0 - cos(M_PI / 6.0));
    CHECK_NEAR(pn_cluster_solid_angle(v3(0, 0, 2), 1.0f, v3(0, 0, 0)), expected, 1e-6);
    CHECK_NEAR(pn_cluster_solid_angle(v3(0, 0, 0.5f), 1.0f, v3(0, 0, 0)), 4.0 * M_PI, 1e-6);
    CHECK(pn_cluster_solid_angle(v3(3, 0, 0), 0.0f, v3(0, 0, 0)) == 0.0f);
    /* Small spheres: close to pi r^2 / d^2. */
    CHECK_NEAR(pn_cluster_solid_angle(v3(0, 1000, 0), 1.0f, v3(0, 0, 0)), M_PI * 1e-6, 1e-12);
    vec3 c;
    float rad;
    pn_cluster_merge_spheres(v3(0, 0, 0), 1.0f, v3(4, 0, 0), 1.0f, &c, &rad);
    CHECK_NEAR(rad, 3.0, 1e-6);
    CHECK_NEAR(c.x, 2.0, 1e-6);
    pn_cluster_merge_spheres(v3(0, 0, 0), 5.0f, v3(1, 0, 0), 1.0f, &c, &rad);
    CHECK(rad == 5.0f && c.x == 0.0f);
}

/* ---------------------------------------------------------------- picking */

/* The picks' frequencies `hits` (per light, over `samples` picks from node nd) against the
 * probabilities `pdf` (per light): a chi-square bound over the node's lights, none picked with
 * probability 0, and none outside the node. Clears hits. */
static void check_pick_frequencies(const pn_cluster_forest *f, const pn_lights *L, const pn_cluster_node *nd,
                                   const double *pdf, int *hits, int samples) {
    double chi2 = 0.0;
    int dof = -1, outside = 0;
    for (int j = nd->first; j < nd->first + nd->count; j++) {
        int li = f->light_order[j];
        double e = pdf[li] * samples;
        if (e == 0.0) {
            CHECK(hits[li] == 0);
            continue;
        }
        chi2 += (hits[li] - e) * (hits[li] - e) / e;
        dof++;
        hits[li] = 0;
    }
    for (int i = 0; i < L->count; i++) outside += hits[i];
    CHECK(outside == 0); /* never a light outside the node */
    if (dof > 0) {
        double limit = dof + 5.0 * sqrt(2.0 * dof) + 10.0;
        CHECK_MSG(chi2 < limit, "chi-square %g with %d degrees of freedom", chi2, dof);
    }
}

static void check_pick(const pn_cluster_forest *f, const pn_lights *L, int node, test_rng *r, int samples) {
    const pn_cluster_node *nd = &f->nodes[node];
    int k = nd->count;
    int *hits = calloc((size_t)L->count, sizeof *hits);
    for (int s = 0; s < samples; s++) {
        float prob = -1.0f;
        int li = pn_cluster_pick(f, L, node, rnd(r), &prob);
        CHECK(li >= 0 && li < L->count);
        if (li < 0 || li >= L->count) continue;
        hits[li]++;
        float expected = nd->power > 0.0f ? pn_cluster_light_power(&L->lights[li]) / nd->power : 1.0f / (float)k;
        if (s < 2000 && k > 1) {
            /* The answer of a plain scan: the first position whose running sum passes the target
             * (the grouped search of pn_cluster_pick must find the very same light). */
            const double *pre = f->power_prefix;
            float u = rnd(r);
            double total = pre[nd->first + k] - pre[nd->first];
            if (total > 0.0) {
                double target = pre[nd->first] + (double)u * total;
                int j = nd->first;
                while (j < nd->first + k - 1 && !(pre[j + 1] > target)) j++;
                while (j > nd->first && !(pre[j + 1] > pre[j])) j--;
                CHECK(pn_cluster_pick(f, L, node, u, NULL) == f->light_order[j]);
            }
        }
        if (s < 2000) {
            CHECK_NEAR(prob, expected, 1e-5 * (double)expected + 1e-9);
            CHECK(prob > 0.0f);
            CHECK_NEAR(pn_cluster_pick_pdf(f, L, node, li), prob, 1e-7);
        }
    }
    double *pdf = calloc((size_t)L->count, sizeof *pdf);
    CHECK(pdf != NULL);
    for (int j = nd->first; pdf && j < nd->first + k; j++) {
        int li = f->light_order[j];
        pdf[li] = nd->power > 0.0f ? (double)pn_cluster_light_power(&L->lights[li]) / (double)nd->power : 1.0 / k;
    }
    if (pdf) check_pick_frequencies(f, L, nd, pdf, hits, samples);
    free(pdf);
    free(hits);
}

static void test_pick(void) {
    test_rng r = {23};
    int count = 300;
    pn_light *l = malloc((size_t)count * sizeof *l);
    for (int i = 0; i < count; i++) {
        l[i] = make_light(&r, i % 3 ? PN_LIGHT_POINT : PN_LIGHT_SPHERE, 4.0f, v3(0, 0, 0), 0.0f, 0);
        float s = rnd(&r);
        l[i].emit = v3_scale(l[i].emit, s * s * 10.0f);
        if (i % 7 == 0) l[i].emit = v3(0, 0, 0);
    }
    /* A group of zero-power lights far away: a zero-power cluster picks uniformly. */
    for (int i = 0; i < 6; i++) {
        l[i * 7].p = v3(100.0f + 0.01f * (float)i, 100, 100);
    }
    pn_lights L = wrap_lights(l, count);
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    int root = f.roots[PN_TREE_OMNI];
    check_pick(&f, &L, root, &r, 200000);
    int checked = 0, zero_checked = 0;
    for (int i = 0; i < f.node_count && checked < 6; i++) {
        if (f.nodes[i].left >= 0 && f.nodes[i].count >= 5 && f.nodes[i].count <= 40 && f.nodes[i].power > 0.0f &&
            i % 3 == 0) {
            check_pick(&f, &L, i, &r, 40000);
            checked++;
        }
    }
    for (int i = 0; i < f.node_count; i++) {
        if (f.nodes[i].left >= 0 && f.nodes[i].power == 0.0f && f.nodes[i].count >= 3) {
            check_pick(&f, &L, i, &r, 20000);
            zero_checked++;
            break;
        }
    }
    CHECK(checked == 6 && zero_checked == 1);
    /* Leaves: the one light with probability 1; u at the extremes stays in range. */
    int leaf = f.leaf_of_light[1];
    float prob = 0.0f;
    CHECK(pn_cluster_pick(&f, &L, leaf, 0.5f, &prob) == 1 && prob == 1.0f);
    int li = pn_cluster_pick(&f, &L, root, 0.99999994f, &prob);
    CHECK(li >= 0 && li < count && prob > 0.0f);
    li = pn_cluster_pick(&f, &L, root, 0.0f, &prob);
    CHECK(li >= 0 && li < count && prob > 0.0f);
    CHECK(pn_cluster_pick_pdf(&f, &L, leaf, 2) == 0.0f);
    pn_cluster_forest_free(&f);
    free(l);
}

/* pn_cluster_pick_importance: its probabilities sum to 1 over a node's lights, the pick reports
 * the probability pn_cluster_pick_importance_pdf gives, the picks' frequencies follow it
 * (chi-square), and every light that can light the point has a probability above 0. */
static void check_pick_importance(const pn_cluster_forest *f, const pn_lights *L, int node, vec3 p, vec3 n, float lim,
                                  test_rng *r, int samples) {
    const pn_cluster_node *nd = &f->nodes[node];
    double *pdf = calloc((size_t)L->count, sizeof *pdf);
    int *hits = calloc((size_t)L->count, sizeof *hits);
    double sum = 0.0;
    for (int j = nd->first; j < nd->first + nd->count; j++) {
        int li = f->light_order[j];
        pdf[li] = (double)pn_cluster_pick_importance_pdf(f, L, node, p, n, lim, li);
        CHECK(pdf[li] >= 0.0 && pdf[li] <= 1.0);
        sum += pdf[li];
        if (pdf[li] == 0.0 && pn_cluster_light_power(&L->lights[li]) > 0.0f)
            CHECK_MSG(pn_cluster_light_culled(&L->lights[li], p, n), "light %d can light p, probability 0", li);
    }
    CHECK_NEAR(sum, 1.0, 1e-5);
    for (int s = 0; s < samples; s++) {
        float prob = -1.0f;
        int li = pn_cluster_pick_importance(f, L, node, p, n, lim, rnd(r), &prob);
        CHECK(li >= 0 && li < L->count);
        if (li < 0 || li >= L->count) continue;
        hits[li]++;
        if (s < 2000) CHECK_NEAR(prob, pdf[li], 1e-5 * pdf[li] + 1e-12);
    }
    check_pick_frequencies(f, L, nd, pdf, hits, samples);
    CHECK(pn_cluster_pick_importance_pdf(f, L, node, p, n, lim, -1) == 0.0f);
    free(hits);
    free(pdf);
}

static void test_pick_importance(void) {
    test_rng r = {41};
    int count = 600;
    pn_light *l = mixed_lights(&r, count, 6.0f);
    pn_lights L = wrap_lights(l, count);
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    /* Points among the lights and outside them, with and without a horizon. */
    const vec3 pts[3] = {v3(0.3f, -0.2f, 0.1f), v3(9, 2, -1), v3(-2, 5, 3)};
    const vec3 nrm[3] = {v3(0, 0, 1), v3_normalize(v3(-1, 0.2f, 0.1f)), v3(0, 0, 0)};
    int checked = 0, skewed = 0;
    for (int q = 0; q < 3; q++) {
        for (int t = 0; t < PN_TREE_COUNT; t++)
            if (f.roots[t] >= 0 && f.nodes[f.roots[t]].count > 1) {
                check_pick_importance(&f, &L, f.roots[t], pts[q], nrm[q], q == 1 ? 0.05f : 0.0f, &r, 60000);
                checked++;
            }
        for (int i = 0, k = 0; i < f.node_count && k < 3; i++)
            if (f.nodes[i].left >= 0 && f.nodes[i].count >= 6 && f.nodes[i].count <= 60 && i % 5 == q) {
                check_pick_importance(&f, &L, i, pts[q], nrm[q], q == 2 ? 0.05f : 0.0f, &r, 30000);
                k++;
                checked++;
            }
    }
    /* The pick differs from power's: near the point, a near light outweighs a brighter far one. */
    int root = f.roots[PN_TREE_OMNI];
    for (int j = f.nodes[root].first; j < f.nodes[root].first + f.nodes[root].count && !skewed; j++) {
        int li = f.light_order[j];
        float pw = pn_cluster_pick_pdf(&f, &L, root, li),
              pi = pn_cluster_pick_importance_pdf(&f, &L, root, pts[0], nrm[0], 0.0f, li);
        if (pw > 0.0f && (pi > 2.0f * pw || pi < 0.5f * pw)) skewed = 1;
    }
    CHECK(checked >= 15 && skewed);
    /* Leaves and singles: the one light with probability 1. */
    int leaf = f.leaf_of_light[1];
    float prob = 0.0f;
    CHECK(pn_cluster_pick_importance(&f, &L, leaf, pts[0], nrm[0], 0.0f, 0.5f, &prob) == 1 && prob == 1.0f);
    CHECK(pn_cluster_pick_importance_pdf(&f, &L, leaf, pts[0], nrm[0], 0.0f, 1) == 1.0f);
    CHECK(pn_cluster_pick_importance_pdf(&f, &L, leaf, pts[0], nrm[0], 0.0f, 2) == 0.0f);
    int li = pn_cluster_pick_importance(&f, &L, root, pts[0], nrm[0], 0.0f, 0.99999994f, &prob);
    CHECK(li >= 0 && li < count && prob > 0.0f);
    pn_cluster_forest_free(&f);
    free(l);
}

/* ---------------------------------------------------------------- timing */

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void test_build_time(void) {
    test_rng r = {99};
    int count = 20000;
    pn_light *l = mixed_lights(&r, count, 30.0f);
    pn_lights L = wrap_lights(l, count);
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    double t0 = now_seconds();
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    double t1 = now_seconds();
    fprintf(stderr, "  20000 mixed lights: built in %.3f s (%d nodes)\n", t1 - t0, f.node_count);
    CHECK(t1 - t0 < 5.0);
    pn_cluster_forest_free(&f);
    /* Points in a few tight clumps far apart (uneven density), and uniform points. */
    for (int i = 0; i < count; i++) {
        l[i] = make_light(&r, PN_LIGHT_POINT, 0.5f, v3(0, 0, 0), 0.0f, 0);
        if (i % 2) l[i].p = v3_add(l[i].p, v3((float)(i % 5) * 1000.0f, 0, (float)(i % 3) * 300.0f));
    }
    pn_err_init(&err);
    t0 = now_seconds();
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    t1 = now_seconds();
    fprintf(stderr, "  20000 clumped points: built in %.3f s\n", t1 - t0);
    CHECK(t1 - t0 < 5.0);
    pn_cluster_forest_free(&f);
    free(l);
}

PN_TESTS(TEST(test_solid_angle), TEST(test_forest_structure), TEST(test_greedy_matches_brute_force),
         TEST(test_cut_properties), TEST(test_cut_capped), TEST(test_pick), TEST(test_pick_importance),
         TEST(test_build_time))
