/* painter.c — the baseline of Guo 1998's Figs. 4 and 5: adaptive progressive refinement after
 * Painter & Sloan, "Antialiased ray tracing by adaptive progressive refinement" (SIGGRAPH 89).
 *
 * Adaptive stochastic sampling of the image plane with hierarchical integration: the work image
 * is cut by a k-d tree (each split halves the longer side of a leaf); every leaf holds at least
 * one sample, a work pixel chosen at random inside it (a hash of the seed and the leaf). The
 * leaf to refine next is the one of highest priority
 *     area / (W H) * (coverage + contrast),
 * which serves the paper's three goals — coverage of the image (area), location of features
 * (contrast (max - min)/(max + min) of the luminance of the leaf's samples, or of its parent's
 * while it holds a single sample) and confidence at the pixel level (a one-pixel leaf is
 * evaluated exactly and leaves the queue). The image is reconstructed by giving every pixel of a
 * leaf the mean of the leaf's samples (the hierarchical integration estimate), evaluated pixels
 * keep their values, and the work image goes through the same Gaussian as every driver.
 *
 * Departures: samples are whole work pixels evaluated by the integrator (the paper samples
 * continuous positions with one ray each), since the comparison is at equal numbers of evaluated
 * work pixels; the confidence goal is met by evaluating pixels with the integrator's own
 * adaptive test instead of a per-pixel sample count. Leaves are refined in batches (so that
 * pixels can be evaluated in parallel); the order inside a batch is the priority order. */
#include "driver/progressive.h"

#include "core/heap.h"
#include "core/rng.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PAINTER_COVERAGE 0.1

typedef struct pnode {
    int32_t x0, y0, x1, y1; /* [x0, x1) x [y0, y1) */
    int32_t *samples;       /* pixel indices */
    int ns, cap;
    int32_t pending; /* a requested sample not yet added, or -1 */
    float contrast;  /* of the samples (or inherited) */
    double mean[3];
    double priority;
    bool alive;
} pnode;

typedef struct painter_state {
    pn_prog *p;
    pnode *nodes;
    size_t n, cap;
    pn_heap heap; /* leaves to refine: (priority, node index), ties to the lower index */
} painter_state;

static int64_t new_node(painter_state *s, int x0, int y0, int x1, int y1) {
    if (s->n == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 1024;
        void *nn = realloc(s->nodes, cap * sizeof *s->nodes);
        if (!nn) return -1;
        s->nodes = nn;
        s->cap = cap;
    }
    pnode *d = &s->nodes[s->n];
    memset(d, 0, sizeof *d);
    d->x0 = x0;
    d->y0 = y0;
    d->x1 = x1;
    d->y1 = y1;
    d->pending = -1;
    d->alive = true;
    return (int64_t)s->n++;
}

static bool add_sample(pnode *d, int32_t idx) {
    if (d->ns == d->cap) {
        int cap = d->cap ? 2 * d->cap : 4;
        void *ns = realloc(d->samples, (size_t)cap * sizeof *d->samples);
        if (!ns) return false;
        d->samples = ns;
        d->cap = cap;
    }
    d->samples[d->ns++] = idx;
    return true;
}

/* Mean, contrast and priority from the node's samples. */
static void node_stats(painter_state *s, pnode *d, float inherited) {
    const pn_prog *p = s->p;
    double sum[3] = {0, 0, 0};
    float lmin = INFINITY, lmax = -INFINITY;
    for (int i = 0; i < d->ns; i++) {
        const float *c = p->rad + 3 * (size_t)d->samples[i];
        for (int k = 0; k < 3; k++) sum[k] += (double)c[k];
        float l = 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
        lmin = fminf(lmin, l);
        lmax = fmaxf(lmax, l);
    }
    if (d->ns > 0)
        for (int k = 0; k < 3; k++) d->mean[k] = sum[k] / d->ns;
    d->contrast = d->ns >= 2 ? (lmax + lmin > 0.0f ? (lmax - lmin) / (lmax + lmin) : 0.0f) : inherited;
    double area = (double)(d->x1 - d->x0) * (double)(d->y1 - d->y0);
    d->priority = area <= 1.0 ? -1.0 : area / ((double)p->W * (double)p->H) * (PAINTER_COVERAGE + (double)d->contrast);
}

static int32_t random_pixel(const painter_state *s, const pnode *d) {
    const pn_prog *p = s->p;
    uint64_t h = pn_hash3(p->job.seed ^ 0x7061696e746572ull, ((uint64_t)(uint32_t)d->x0 << 32) | (uint32_t)d->y0,
                          ((uint64_t)(uint32_t)d->x1 << 32) | (uint32_t)d->y1);
    int w = d->x1 - d->x0, hh = d->y1 - d->y0;
    int x = d->x0 + (int)(h % (uint64_t)w), y = d->y0 + (int)((h >> 32) % (uint64_t)hh);
    return (int32_t)pn_prog_index(p, x, y);
}

static void painter_draw(pn_prog *p, void *driver, float *img, float *cls, float *dir) {
    (void)cls;
    (void)dir;
    painter_state *s = driver;
    for (size_t i = 0; i < s->n; i++) {
        const pnode *d = &s->nodes[i];
        if (!d->alive) continue;
        for (int y = d->y0; y < d->y1; y++)
            for (int x = d->x0; x < d->x1; x++) {
                float *o = img + 3 * pn_prog_index(p, x, y);
                for (int k = 0; k < 3; k++) o[k] = (float)d->mean[k];
            }
    }
}

static void painter_free(void *driver) {
    painter_state *s = driver;
    if (!s) return;
    for (size_t i = 0; i < s->n; i++) free(s->nodes[i].samples);
    free(s->nodes);
    pn_heap_free(&s->heap);
    free(s);
}

static pn_status painter_loop(painter_state *s) {
    pn_prog *p = s->p;
    pn_status st;
    if (new_node(s, 0, 0, p->W, p->H) < 0) return PN_ERROR_OUT_OF_MEMORY;
    int32_t first = random_pixel(s, &s->nodes[0]);
    if (!pn_prog_request(p, first % p->W, first / p->W)) return PN_ERROR_OUT_OF_MEMORY;
    if ((st = pn_prog_flush(p)) != PN_OK || p->stopped) return st;
    if (!add_sample(&s->nodes[0], first)) return PN_ERROR_OUT_OF_MEMORY;
    node_stats(s, &s->nodes[0], 1.0f);
    if (!pn_heap_push(&s->heap, s->nodes[0].priority, 0)) return PN_ERROR_OUT_OF_MEMORY;
    size_t batch = ((size_t)p->W * (size_t)p->H) / 1024;
    if (batch < 16) batch = 16;
    uint32_t *fresh = malloc(2 * batch * sizeof *fresh);
    float *inherit = malloc(2 * batch * sizeof *inherit);
    if (!fresh || !inherit) {
        free(fresh);
        free(inherit);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    st = PN_OK;
    while (s->heap.count > 0 && st == PN_OK) {
        size_t nf = 0;
        for (size_t b = 0; b < batch && s->heap.count > 0; b++) {
            uint32_t pi = (uint32_t)pn_heap_pop(&s->heap).payload;
            if (s->nodes[pi].priority < 0.0) continue;
            pnode par = s->nodes[pi];
            bool vertical = (par.x1 - par.x0) >= (par.y1 - par.y0);
            int mid = vertical ? (par.x0 + par.x1) / 2 : (par.y0 + par.y1) / 2;
            int64_t a = vertical ? new_node(s, par.x0, par.y0, mid, par.y1) : new_node(s, par.x0, par.y0, par.x1, mid);
            int64_t c = vertical ? new_node(s, mid, par.y0, par.x1, par.y1) : new_node(s, par.x0, mid, par.x1, par.y1);
            if (a < 0 || c < 0) {
                st = PN_ERROR_OUT_OF_MEMORY;
                break;
            }
            s->nodes[pi].alive = false;
            for (int i = 0; i < par.ns; i++) {
                int32_t idx = par.samples[i];
                int x = idx % p->W, y = idx / p->W;
                int64_t to = (vertical ? x < mid : y < mid) ? a : c;
                if (!add_sample(&s->nodes[to], idx)) st = PN_ERROR_OUT_OF_MEMORY;
            }
            free(s->nodes[pi].samples);
            s->nodes[pi].samples = NULL;
            s->nodes[pi].ns = s->nodes[pi].cap = 0;
            int64_t kids[2] = {a, c};
            for (int k = 0; k < 2; k++) {
                pnode *d = &s->nodes[kids[k]];
                memcpy(d->mean, par.mean, sizeof d->mean); /* shown until its own sample arrives */
                if (d->ns == 0) {
                    d->pending = random_pixel(s, d);
                    if (!pn_prog_request(p, d->pending % p->W, d->pending / p->W)) st = PN_ERROR_OUT_OF_MEMORY;
                }
                fresh[nf] = (uint32_t)kids[k];
                inherit[nf] = par.contrast;
                nf++;
            }
        }
        if (st != PN_OK) break;
        if ((st = pn_prog_flush(p)) != PN_OK || p->stopped) break;
        for (size_t i = 0; i < nf; i++) {
            pnode *d = &s->nodes[fresh[i]];
            if (d->pending >= 0) {
                if (!add_sample(d, d->pending)) {
                    st = PN_ERROR_OUT_OF_MEMORY;
                    break;
                }
                d->pending = -1;
            }
            node_stats(s, d, inherit[i]);
            if (d->priority >= 0.0 && !pn_heap_push(&s->heap, d->priority, fresh[i])) {
                st = PN_ERROR_OUT_OF_MEMORY;
                break;
            }
        }
    }
    free(fresh);
    free(inherit);
    return st;
}

pn_status pn_painter_run(pn_prog *p) {
    painter_state *s = calloc(1, sizeof *s);
    if (!s) return PN_ERROR_OUT_OF_MEMORY;
    s->p = p;
    pn_heap_init(&s->heap, PN_HEAP_MAX | PN_HEAP_TIES_BY_PAYLOAD);
    p->draw = painter_draw;
    p->driver = s;
    p->free_driver = painter_free;
    return painter_loop(s);
}
