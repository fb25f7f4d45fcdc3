/* ias_guide.c — per-block grids over a large light's sample square (ias_guide.h). */
#include "integrators/ias_guide.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A cell's weight is its mean value with PRIOR_SAMPLES pseudo-samples at the light's mean, so
 * that a cell seen once or never neither vanishes nor takes a single sample's word. */
#define PRIOR_SAMPLES 2.0

static int by_area_desc(const void *a, const void *b, const pn_lights *L) {
    float x = L->lights[*(const int *)a].area, y = L->lights[*(const int *)b].area;
    if (x != y) return x > y ? -1 : 1;
    return *(const int *)a - *(const int *)b; /* ties by index: the choice does not depend on qsort */
}

static bool guidable(const pn_light *l) {
    return (l->kind == PN_LIGHT_RECTANGLE || l->kind == PN_LIGHT_TRIANGLE) && l->area > 0.0f && isfinite(l->area);
}

bool pn_ias_guide_lights_init(pn_ias_guide_lights *g, const pn_lights *L, int side, double mix) {
    memset(g, 0, sizeof *g);
    g->side = side < 1 ? 1 : side > PN_IAS_GUIDE_MAX_SIDE ? PN_IAS_GUIDE_MAX_SIDE : side;
    g->mix = mix;
    g->min_samples = 4 * g->side;
    g->slot = malloc((size_t)(L->count > 0 ? L->count : 1) * sizeof *g->slot);
    int *cand = malloc((size_t)(L->count > 0 ? L->count : 1) * sizeof *cand);
    if (!g->slot || !cand) {
        free(cand);
        pn_ias_guide_lights_free(g);
        return false;
    }
    double total = 0.0;
    for (int i = 0; i < L->count; i++) {
        g->slot[i] = -1;
        if (guidable(&L->lights[i])) total += (double)L->lights[i].area;
    }
    int n = 0;
    for (int i = 0; i < L->count; i++)
        if (guidable(&L->lights[i]) && (double)L->lights[i].area >= PN_IAS_GUIDE_MIN_SHARE * total) cand[n++] = i;
    /* Largest first (insertion sort: few candidates, and no qsort context argument in C11). */
    for (int i = 1; i < n; i++) {
        int v = cand[i], j = i;
        while (j > 0 && by_area_desc(&v, &cand[j - 1], L) < 0) {
            cand[j] = cand[j - 1];
            j--;
        }
        cand[j] = v;
    }
    if (n > PN_IAS_GUIDE_MAX_LIGHTS) n = PN_IAS_GUIDE_MAX_LIGHTS;
    for (int k = 0; k < n; k++) g->slot[cand[k]] = k;
    g->count = n;
    free(cand);
    return true;
}

void pn_ias_guide_lights_free(pn_ias_guide_lights *g) {
    free(g->slot);
    g->slot = NULL;
    g->count = 0;
}

bool pn_ias_guide_init(pn_ias_guide *g, const pn_ias_guide_lights *lights) {
    memset(g, 0, sizeof *g);
    g->lights = lights;
    const size_t n = (size_t)(lights->count > 0 ? lights->count : 1), G = (size_t)lights->side;
    g->sum = calloc(n * G * G, sizeof *g->sum);
    g->count = calloc(n * G * G, sizeof *g->count);
    g->prob = calloc(n * G * G, sizeof *g->prob);
    g->row_cdf = calloc(n * (G + 1), sizeof *g->row_cdf);
    g->col_cdf = calloc(n * G * (G + 1), sizeof *g->col_cdf);
    g->active = calloc(n, 1);
    g->touched = calloc(n, 1);
    g->touched_list = calloc(n, sizeof *g->touched_list);
    if (!g->sum || !g->count || !g->prob || !g->row_cdf || !g->col_cdf || !g->active || !g->touched ||
        !g->touched_list) {
        pn_ias_guide_free(g);
        return false;
    }
    return true;
}

void pn_ias_guide_free(pn_ias_guide *g) {
    free(g->sum);
    free(g->count);
    free(g->prob);
    free(g->row_cdf);
    free(g->col_cdf);
    free(g->active);
    free(g->touched);
    free(g->touched_list);
    memset(g, 0, sizeof *g);
}

void pn_ias_guide_begin_block(pn_ias_guide *g) {
    const size_t cells = (size_t)g->lights->side * (size_t)g->lights->side;
    for (int k = 0; k < g->touched_count; k++) {
        int s = g->touched_list[k];
        memset(g->sum + (size_t)s * cells, 0, cells * sizeof *g->sum);
        memset(g->count + (size_t)s * cells, 0, cells * sizeof *g->count);
        g->active[s] = 0;
        g->touched[s] = 0;
    }
    g->touched_count = 0;
}

void pn_ias_guide_refresh(pn_ias_guide *g) {
    const int G = g->lights->side;
    const size_t cells = (size_t)G * (size_t)G;
    const double mix = g->lights->mix;
    for (int k = 0; k < g->touched_count; k++) {
        const int s = g->touched_list[k];
        const double *sum = g->sum + (size_t)s * cells, *cnt = g->count + (size_t)s * cells;
        double total = 0.0, n = 0.0;
        for (size_t c = 0; c < cells; c++) {
            total += sum[c];
            n += cnt[c];
        }
        g->active[s] = 0;
        if (!(n >= (double)g->lights->min_samples) || !(total > 0.0) || !isfinite(total)) continue;
        const double mean = total / n;
        double *q = g->prob + (size_t)s * cells;
        double wsum = 0.0;
        for (size_t c = 0; c < cells; c++) {
            q[c] = (sum[c] + PRIOR_SAMPLES * mean) / (cnt[c] + PRIOR_SAMPLES);
            wsum += q[c];
        }
        for (size_t c = 0; c < cells; c++) q[c] = (1.0 - mix) * q[c] / wsum + mix / (double)cells;
        double *row = g->row_cdf + (size_t)s * (size_t)(G + 1);
        row[0] = 0.0;
        for (int b = 0; b < G; b++) {
            double *col = g->col_cdf + ((size_t)s * (size_t)G + (size_t)b) * (size_t)(G + 1);
            col[0] = 0.0;
            for (int a = 0; a < G; a++) col[a + 1] = col[a] + q[(size_t)b * (size_t)G + (size_t)a];
            row[b + 1] = row[b] + col[G];
        }
        g->active[s] = 1;
    }
}

/* The index i with cdf[i] <= x < cdf[i + 1] among n entries (cdf[n] the total), and x's
 * position within it in [0, 1). */
static int invert(const double *cdf, int n, double x, double *frac) {
    x *= cdf[n];
    int i = 0;
    while (i + 1 < n && cdf[i + 1] <= x) i++;
    double w = cdf[i + 1] - cdf[i];
    double f = w > 0.0 ? (x - cdf[i]) / w : 0.5;
    *frac = f < 0.0 ? 0.0 : f;
    return i;
}

/* (i + f) / side as a float that still falls in cell i (rounding could carry it into i + 1). */
static float in_cell(int i, double f, int side) {
    float x = (float)(((double)i + f) / (double)side);
    while (x > 0.0f && (int)(x * (float)side) > i) x = nextafterf(x, 0.0f);
    return x;
}

void pn_ias_guide_set_rotation(pn_ias_guide *g, uint64_t key) {
    g->rotate = true;
    g->shift[0] = (float)(key >> 40) * 0x1p-24f; /* 24 bits each: exact in a float, below 1 */
    g->shift[1] = (float)((key >> 16) & 0xffffffu) * 0x1p-24f;
}

/* u + d modulo 1, in [0, 1). */
static float rotated(float u, float d) {
    float x = u + d;
    if (x >= 1.0f) x -= 1.0f;
    return x < 1.0f ? x : nextafterf(1.0f, 0.0f);
}

int pn_ias_guide_warp(const pn_ias_guide *g, int light, float *u1, float *u2, double *density) {
    const int s = g->lights->slot[light];
    if (s < 0) return -1;
    const int G = g->lights->side;
    if (!g->active[s]) {
        int a = (int)(*u1 * (float)G), b = (int)(*u2 * (float)G);
        a = a < G ? a : G - 1;
        b = b < G ? b : G - 1;
        return b * G + a;
    }
    if (g->rotate) {
        *u1 = rotated(*u1, g->shift[0]);
        *u2 = rotated(*u2, g->shift[1]);
    }
    const double *row = g->row_cdf + (size_t)s * (size_t)(G + 1);
    double fb, fa;
    const int b = invert(row, G, (double)*u2, &fb);
    const double *col = g->col_cdf + ((size_t)s * (size_t)G + (size_t)b) * (size_t)(G + 1);
    const int a = invert(col, G, (double)*u1, &fa);
    *u1 = in_cell(a, fa, G);
    *u2 = in_cell(b, fb, G);
    const double q = g->prob[(size_t)s * (size_t)G * (size_t)G + (size_t)b * (size_t)G + (size_t)a];
    *density *= q * (double)G * (double)G;
    return b * G + a;
}

void pn_ias_guide_record(pn_ias_guide *g, int light, int cell, double value) {
    if (cell < 0 || !isfinite(value)) return;
    const int s = g->lights->slot[light];
    if (s < 0) return;
    const size_t at = (size_t)s * (size_t)g->lights->side * (size_t)g->lights->side + (size_t)cell;
    g->sum[at] += value;
    g->count[at] += 1.0;
    if (!g->touched[s]) {
        g->touched[s] = 1;
        g->touched_list[g->touched_count++] = s;
    }
}
