/* ias_ratio.c — the ratio estimator of the default `ias` variant (see ias_ratio.h). */
#include "integrators/ias_ratio.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

bool pn_ias_light_unshadowed(const pn_lights *lights, const pn_light *l, vec3 p, vec3 n, vec3 *e) {
    const float y = v3_luminance(l->emit);
    if (!(y > 0.0f) || v3_is_zero(n)) return false;
    float lum;
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_SPOT:
    case PN_LIGHT_DISTANT:
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE: lum = pn_light_irradiance_estimate(lights, l, p, n); break;
    case PN_LIGHT_SPHERE: {
        /* A spherical cap of half-angle a (sin a = r / d) wholly above the horizon gives
         * pi L sin^2 a cos t exactly; across the horizon lights.c's value is an approximation. */
        vec3 d = v3_sub(l->p, p);
        float d2 = v3_length2(d), r2 = l->radius * l->radius;
        if (!(d2 > r2)) return false;
        float c = v3_dot(n, d) / sqrtf(d2);
        if (c < sqrtf(r2 / d2)) return false;
        lum = y * PN_PI * (r2 / d2) * c;
        break;
    }
    default: return false;
    }
    if (!(lum >= 0.0f) || !isfinite(lum)) return false;
    *e = v3_scale(l->emit, lum / y);
    return true;
}

bool pn_ias_cluster_unshadowed(const pn_cluster_forest *f, const pn_lights *lights, int node, int max_members, vec3 p,
                               vec3 n, vec3 *e) {
    const pn_cluster_node *nd = &f->nodes[node];
    if (nd->light >= 0) return pn_ias_light_unshadowed(lights, &lights->lights[nd->light], p, n, e);
    if (nd->count > max_members) return false;
    vec3 sum = v3(0, 0, 0);
    for (int i = 0; i < nd->count; i++) {
        vec3 one;
        if (!pn_ias_light_unshadowed(lights, &lights->lights[f->light_order[nd->first + i]], p, n, &one)) return false;
        sum = v3_add(sum, one);
    }
    *e = sum;
    return true;
}

bool pn_ias_ratio_scratch_init(pn_ias_ratio_scratch *s, int id_count, int max_regions) {
    memset(s, 0, sizeof *s);
    size_t ids = (size_t)(id_count > 0 ? id_count : 1);
    s->id_count = (int)ids;
    s->num = malloc(ids * sizeof *s->num);
    s->den = malloc(ids * sizeof *s->den);
    s->count = malloc(ids * sizeof *s->count);
    s->stamp = calloc(ids, sizeof *s->stamp);
    const size_t regions = (size_t)(max_regions > 0 ? max_regions : 1);
    s->n_of = malloc(regions * sizeof *s->n_of);
    s->zs = malloc(regions * sizeof *s->zs);
    s->zv = malloc(regions * sizeof *s->zv);
    s->zv2 = malloc(regions * sizeof *s->zv2);
    s->zc = malloc(regions * sizeof *s->zc);
    return s->num && s->den && s->count && s->stamp && s->n_of && s->zs && s->zv && s->zv2 && s->zc;
}

void pn_ias_ratio_scratch_free(pn_ias_ratio_scratch *s) {
    free(s->num);
    free(s->den);
    free(s->count);
    free(s->stamp);
    free(s->n_of);
    free(s->zs);
    free(s->zv);
    free(s->zv2);
    free(s->zc);
    memset(s, 0, sizeof *s);
}

/* The cluster mode's ratio of cluster `id` (-1 when it has no sample with a denominator) and its
 * number of samples. */
static double cluster_beta(const pn_ias_ratio_scratch *sc, int id, unsigned *count) {
    *count = 0;
    if (id < 0 || id >= sc->id_count || sc->stamp[id] != sc->now) return -1.0;
    *count = sc->count[id];
    return sc->den[id] > 0.0 ? sc->num[id] / sc->den[id] : -1.0;
}

/* Entry e's beta for the estimate (*b) and for the residuals of the variance (*bv). */
static void entry_beta(int mode, const pn_ias_ratio_scratch *sc, const int *cut_ids, const double *beta, int e,
                       double rho, double *b, double *bv) {
    if (mode == PN_IAS_RATIO_CONTROL) {
        *b = *bv = beta[e];
        return;
    }
    *b = *bv = rho;
    if (mode != PN_IAS_RATIO_CLUSTER) return;
    unsigned m;
    double bc = cluster_beta(sc, cut_ids[e], &m);
    if (bc >= 0.0) *b = bc;
    if (bc >= 0.0 && m > 1) *bv = bc; /* a single sample's own ratio leaves it no residual */
}

void pn_ias_ratio_pass(int mode, const pn_ias_ratio_sample *smp, int count, const pn_ias_ratio_region *regions,
                       int region_count, const int *cut_ids, const vec3 *unshadowed, const double *beta,
                       pn_ias_ratio_scratch *sc, double *lum, vec3 *rgb, double *s2, unsigned *n) {
    unsigned *n_of = sc->n_of;
    double *zs = sc->zs, *zv = sc->zv, *zv2 = sc->zv2;
    vec3 *zc = sc->zc;
    for (int k = 0; k < region_count; k++) {
        n_of[k] = 0;
        zs[k] = zv[k] = zv2[k] = 0.0;
        zc[k] = v3(0, 0, 0);
    }
    for (int i = 0; i < count; i++) n_of[smp[i].region]++;
    if (mode == PN_IAS_RATIO_CLUSTER && ++sc->now == 0) {
        memset(sc->stamp, 0, (size_t)sc->id_count * sizeof *sc->stamp);
        sc->now = 1;
    }
    /* The pixel's ratio over all its samples in A, and with `cluster` each cluster's. */
    double num = 0.0, den = 0.0;
    for (int i = 0; i < count; i++) {
        const pn_ias_ratio_sample *q = &smp[i];
        if (q->entry < 0) continue;
        const double w = regions[q->region].weight / (double)n_of[q->region];
        const double a = w * (double)v3_luminance(q->v), b = w * (double)v3_luminance(q->u);
        num += a;
        den += b;
        if (mode != PN_IAS_RATIO_CLUSTER) continue;
        const int id = cut_ids[q->entry];
        if (id < 0 || id >= sc->id_count) continue;
        if (sc->stamp[id] != sc->now) {
            sc->stamp[id] = sc->now;
            sc->num[id] = sc->den[id] = 0.0;
            sc->count[id] = 0;
        }
        sc->num[id] += a;
        sc->den[id] += b;
        sc->count[id]++;
    }
    const double rho = den > 0.0 ? num / den : 0.0;
    /* No sample in A with a denominator (ratio modes): beta 0, the plain estimate. */
    const bool any = den > 0.0 || mode == PN_IAS_RATIO_CONTROL;
    double L = 0.0, var = 0.0;
    vec3 c = v3(0, 0, 0);
    unsigned total = 0;
    /* The closed-form part, W_k sum_e beta_e U_k,e. */
    for (int k = 0; k < region_count && any; k++) {
        if (n_of[k] == 0) continue;
        const pn_ias_ratio_region *r = &regions[k];
        for (int e = r->cut_first; e < r->cut_first + r->cut_count; e++) {
            if (unshadowed[e].x < 0.0f) continue;
            double b, bv;
            entry_beta(mode, sc, cut_ids, beta, e, rho, &b, &bv);
            vec3 u = v3_mul(r->m, unshadowed[e]);
            L += r->weight * b * (double)v3_luminance(u);
            c = v3_madd(c, u, (float)(r->weight * b));
        }
    }
    /* The residuals v - beta u, per region. */
    for (int i = 0; i < count; i++) {
        const pn_ias_ratio_sample *q = &smp[i];
        double b = 0.0, bv = 0.0;
        if (q->entry >= 0 && any) entry_beta(mode, sc, cut_ids, beta, q->entry, rho, &b, &bv);
        const vec3 z = v3_sub(q->v, v3_scale(q->u, (float)b));
        const double y = (double)v3_luminance(q->v) - bv * (double)v3_luminance(q->u);
        zs[q->region] += (double)v3_luminance(z);
        zv[q->region] += y;
        zv2[q->region] += y * y;
        zc[q->region] = v3_add(zc[q->region], z);
    }
    for (int k = 0; k < region_count; k++) {
        if (n_of[k] == 0) continue;
        const double nk = (double)n_of[k], w = regions[k].weight;
        L += w * zs[k] / nk;
        c = v3_madd(c, zc[k], (float)(w / nk));
        const double v = nk > 1.0 ? fmax(0.0, (zv2[k] - zv[k] * zv[k] / nk) / (nk - 1.0)) : 0.0;
        var += w * w * v / nk;
        total += n_of[k];
    }
    *lum = L;
    *rgb = c;
    *s2 = var;
    *n = total;
}
