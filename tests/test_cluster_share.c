/* test_cluster_share.c — cuts shared between nearby points (lights/cluster_tree.c,
 * pn_cluster_cut_record / pn_cluster_cut_replay; ias's antialiasing regions of one pixel): for
 * random forests of every light kind and random balls (point, radius, normal turn), the replay's
 * cut at any point and normal within the ball is pn_cluster_cut's there, the same nodes in the same
 * order, and a record sure of every node has the cut of every point of its ball. Not vacuous: at
 * small radii the records decide nearly every node they meet for the whole ball. */
#include "harness.h"

#include "lights/cluster_tree.h"

#include <stdint.h>

typedef struct srng {
    uint64_t s;
} srng;

static float rnd(srng *r) {
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return (float)(z >> 40) * (1.0f / 16777216.0f);
}

static float rnd_in(srng *r, float a, float b) {
    return a + (b - a) * rnd(r);
}

static vec3 rnd_dir(srng *r) {
    float z = 1.0f - 2.0f * rnd(r), phi = 2.0f * PN_PI * rnd(r), s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    return v3(s * cosf(phi), s * sinf(phi), z);
}

static vec3 rnd_cube(srng *r, float h) {
    return v3(rnd_in(r, -h, h), rnd_in(r, -h, h), rnd_in(r, -h, h));
}

/* Lights of every kind the trees hold, many of them on a "ceiling" z = 2 facing down (grazing
 * horizons and cones for points near that plane), some two-sided, some dark. */
static pn_light *some_lights(srng *r, int count) {
    static const pn_light_kind kinds[] = {PN_LIGHT_POINT,     PN_LIGHT_SPOT, PN_LIGHT_TRIANGLE,
                                          PN_LIGHT_RECTANGLE, PN_LIGHT_DISK, PN_LIGHT_SPHERE};
    pn_light *ls = calloc((size_t)count, sizeof *ls);
    for (int i = 0; i < count; i++) {
        pn_light *l = &ls[i];
        l->kind = i % 61 == 3 ? PN_LIGHT_DISTANT : kinds[(int)(rnd(r) * 6.0f) % 6];
        l->env = -1;
        const bool ceiling = i % 3 != 0;
        l->p = ceiling ? v3(rnd_in(r, -4, 4), rnd_in(r, -4, 4), 2.0f) : rnd_cube(r, 4.0f);
        l->emit = i % 37 == 5 ? v3(0, 0, 0) : v3(rnd(r) + 0.1f, rnd(r), rnd(r));
        vec3 dir = ceiling ? v3(0, 0, -1) : rnd_dir(r), t, b;
        v3_basis(dir, &t, &b);
        l->two_sided = rnd(r) < 0.2f;
        switch (l->kind) {
        case PN_LIGHT_SPOT:
            l->n = dir;
            l->cos_total_width = cosf(rnd_in(r, 0.1f, 1.4f));
            l->cos_falloff_start = 1.0f;
            break;
        case PN_LIGHT_DISTANT: l->n = rnd_dir(r); break;
        case PN_LIGHT_TRIANGLE:
            l->e1 = v3_scale(t, rnd_in(r, 0.05f, 0.6f));
            l->e2 = v3_add(v3_scale(b, rnd_in(r, 0.05f, 0.6f)), v3_scale(t, rnd_in(r, -0.2f, 0.2f)));
            l->n = v3_normalize(v3_cross(l->e1, l->e2));
            l->area = 0.5f * v3_length(v3_cross(l->e1, l->e2));
            break;
        case PN_LIGHT_RECTANGLE:
            l->e1 = v3_scale(t, rnd_in(r, 0.05f, 0.6f));
            l->e2 = v3_scale(b, rnd_in(r, 0.05f, 0.6f));
            l->n = v3_normalize(v3_cross(l->e1, l->e2));
            l->area = v3_length(l->e1) * v3_length(l->e2);
            break;
        case PN_LIGHT_DISK:
            l->n = dir;
            l->radius = rnd_in(r, 0.02f, 0.4f);
            l->area = PN_PI * l->radius * l->radius;
            break;
        case PN_LIGHT_SPHERE:
            l->radius = rnd_in(r, 0.02f, 0.3f);
            l->area = 4.0f * PN_PI * l->radius * l->radius;
            break;
        default: break;
        }
    }
    return ls;
}

static double dist_d(vec3 a, vec3 b) {
    double x = (double)a.x - (double)b.x, y = (double)a.y - (double)b.y, z = (double)a.z - (double)b.z;
    return sqrt(x * x + y * y + z * z);
}

static void test_replay_is_the_cut(void) {
    srng r = {2021};
    const int count = 1500;
    pn_light *ls = some_lights(&r, count);
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = ls;
    L.count = count;
    L.scene_radius = 10.0f;
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    pn_cluster_cut_share sh;
    CHECK(pn_cluster_cut_share_init(&sh, &f));
    const int cap = f.node_count + 1;
    int *rec = malloc((size_t)cap * sizeof *rec), *rep = malloc((size_t)cap * sizeof *rep);
    int *plain = malloc((size_t)cap * sizeof *plain);
    static const float deltas[] = {0.0f, 1e-4f, 1e-3f, 1e-2f, 0.1f};
    static const float turns[] = {0.0f, 1e-4f, 1e-3f, 1e-2f};
    int records = 0, sure = 0, small_records = 0, small_sure = 0, replays = 0, mismatches = 0;
    long met_small = 0, decided_small = 0;
    for (int i = 0; i < 3000; i++) {
        /* Points on the floor, on walls and anywhere, some just under the ceiling. */
        vec3 p = i % 4 == 0   ? v3(rnd_in(&r, -5, 5), rnd_in(&r, -5, 5), -1.0f)
                 : i % 4 == 1 ? v3(rnd_in(&r, -5, 5), rnd_in(&r, -5, 5), rnd_in(&r, 1.95f, 1.999f))
                              : rnd_cube(&r, 5.0f);
        vec3 n = i % 4 == 0 ? v3(0, 0, 1) : rnd_dir(&r);
        const float delta = deltas[i % 5], dn = turns[(i / 5) % 4];
        const float sa = i % 7 == 0 ? 0.2f : 0.02f;
        int k = pn_cluster_cut_record(&f, &L, p, n, sa, delta, dn, rec, cap, &sh);
        int k0 = pn_cluster_cut(&f, &L, p, n, sa, plain, cap);
        CHECK(k == k0 && memcmp(rec, plain, (size_t)k * sizeof *rec) == 0);
        records++;
        sure += sh.all_sure;
        if (delta <= 1e-3f && dn <= 1e-3f) {
            small_records++;
            small_sure += sh.all_sure;
            met_small += sh.met;
            decided_small += sh.sure;
        }
        for (int j = 0; j < 12; j++) {
            /* A point within the ball (a third of them on its surface) and a turned normal. */
            vec3 e = v3_scale(rnd_dir(&r), delta * (j % 3 == 0 ? 1.0f : rnd(&r)) * 0.999999f);
            vec3 q = v3_add(p, e);
            vec3 m = n;
            if (dn > 0.0f) m = v3_normalize(v3_add(n, v3_scale(rnd_dir(&r), dn * 0.5f * (j % 2 ? 1.0f : rnd(&r)))));
            if (dist_d(q, p) > (double)delta || dist_d(m, n) > (double)dn) continue;
            int kr = pn_cluster_cut_replay(&f, &L, q, m, sa, rep, cap, &sh);
            int kp = pn_cluster_cut(&f, &L, q, m, sa, plain, cap);
            replays++;
            bool same = kr == kp && memcmp(rep, plain, (size_t)kp * sizeof *rep) == 0;
            if (sh.all_sure) same = same && k == kp && memcmp(rec, plain, (size_t)kp * sizeof *rec) == 0;
            if (!same) mismatches++;
        }
    }
    printf("  %d records (%d sure of every node; %d of %d at delta, dn <= 1e-3, which decided %.4f of the nodes they "
           "met), %d replays, %d mismatches\n",
           records, sure, small_sure, small_records, (double)decided_small / (double)met_small, replays, mismatches);
    CHECK(mismatches == 0);
    CHECK(replays > 20000);
    CHECK(small_sure > 0 && (double)decided_small > 0.95 * (double)met_small);
    CHECK(sure < records); /* the large balls are not sure of everything */
    free(rec);
    free(rep);
    free(plain);
    pn_cluster_cut_share_free(&sh);
    pn_cluster_forest_free(&f);
    free(ls);
}

/* A record that has no ball (a zero normal) falls back to the plain cut; the records after it
 * must not read what an earlier record noted. Each trial starts a fresh share so that its first
 * record and the one after the fallback would carry the same stamp if the fallback restarted the
 * stamps: a replay near the later point would then read the first point's decisions. */
static void test_fallback_forgets_older_records(void) {
    srng r = {77};
    const int count = 600;
    pn_light *ls = some_lights(&r, count);
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = ls;
    L.count = count;
    L.scene_radius = 10.0f;
    pn_cluster_forest f;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_cluster_forest_build(&L, &f, &err) == PN_OK);
    const int cap = f.node_count + 1;
    int *out = malloc((size_t)cap * sizeof *out), *plain = malloc((size_t)cap * sizeof *plain);
    int replays = 0, mismatches = 0;
    for (int t = 0; t < 200; t++) {
        pn_cluster_cut_share sh;
        CHECK(pn_cluster_cut_share_init(&sh, &f));
        vec3 pa = rnd_cube(&r, 5.0f), na = rnd_dir(&r);
        (void)pn_cluster_cut_record(&f, &L, pa, na, 0.02f, 1e-4f, 0.0f, out, cap, &sh);
        /* The fallback, and a replay after it: the plain cut wherever it is asked. */
        (void)pn_cluster_cut_record(&f, &L, pa, v3(0, 0, 0), 0.02f, 1e-4f, 0.0f, out, cap, &sh);
        CHECK(!sh.all_sure);
        vec3 q = rnd_cube(&r, 5.0f), m = rnd_dir(&r);
        int k = pn_cluster_cut_replay(&f, &L, q, m, 0.02f, out, cap, &sh);
        int kp = pn_cluster_cut(&f, &L, q, m, 0.02f, plain, cap);
        replays++;
        mismatches += !(k == kp && memcmp(out, plain, (size_t)k * sizeof *out) == 0);
        /* A wide ball (few sure decisions) at another point, and replays within it. */
        vec3 pb = rnd_cube(&r, 5.0f), nb = rnd_dir(&r);
        (void)pn_cluster_cut_record(&f, &L, pb, nb, 0.02f, 0.5f, 0.0f, out, cap, &sh);
        for (int j = 0; j < 4; j++) {
            vec3 qb = v3_add(pb, v3_scale(rnd_dir(&r), 0.5f * rnd(&r) * 0.999f));
            k = pn_cluster_cut_replay(&f, &L, qb, nb, 0.02f, out, cap, &sh);
            kp = pn_cluster_cut(&f, &L, qb, nb, 0.02f, plain, cap);
            replays++;
            mismatches += !(k == kp && memcmp(out, plain, (size_t)k * sizeof *out) == 0);
        }
        pn_cluster_cut_share_free(&sh);
    }
    printf("  %d replays after fallbacks, %d mismatches\n", replays, mismatches);
    CHECK(mismatches == 0);
    free(out);
    free(plain);
    pn_cluster_forest_free(&f);
    free(ls);
}

PN_TESTS(TEST(test_replay_is_the_cut), TEST(test_fallback_forgets_older_records))
