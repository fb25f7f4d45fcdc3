/* downsample.c — separable Gaussian downsampling of a work image (see downsample.h). */
#include "film/downsample.h"

#include <math.h>
#include <stdlib.h>

typedef struct gauss_run {
    const float *src;
    float *tmp, *dst;
    int sw, sh, dw, dh, channels, s, radius;
    const float *kernel; /* kernel[k] = weight at distance k/2 work pixels */
} gauss_run;

/* Taps of one output coordinate along an axis of n work pixels: first tap index and weights. */
static int axis_taps(const gauss_run *g, int o, int n, float *w, int *first) {
    int centre = g->s * o + (g->s - 1) / 2;
    int odd = (g->s - 1) % 2; /* even s: the centre lies between two work pixels */
    int lo = centre - g->radius, hi = centre + g->radius + odd;
    if (lo < 0) lo = 0;
    if (hi > n - 1) hi = n - 1;
    float sum = 0.0f;
    int count = 0;
    for (int i = lo; i <= hi; i++) {
        int d2 = 2 * (i - centre) - odd; /* twice the distance to the centre */
        int k = d2 < 0 ? -d2 : d2;
        w[count] = g->kernel[k];
        sum += w[count];
        count++;
    }
    for (int i = 0; i < count; i++) w[i] /= sum;
    *first = lo;
    return count;
}

/* Horizontal pass: one work row into dw values. */
static void row_job(void *user, size_t job, int worker) {
    (void)worker;
    const gauss_run *g = user;
    int y = (int)job, ch = g->channels;
    float w[128];
    for (int x = 0; x < g->dw; x++) {
        int first;
        int count = axis_taps(g, x, g->sw, w, &first);
        for (int c = 0; c < ch; c++) {
            float acc = 0.0f;
            for (int i = 0; i < count; i++)
                acc += w[i] * g->src[((size_t)y * (size_t)g->sw + (size_t)(first + i)) * (size_t)ch + (size_t)c];
            g->tmp[((size_t)y * (size_t)g->dw + (size_t)x) * (size_t)ch + (size_t)c] = acc;
        }
    }
}

/* Vertical pass: one output row. */
static void column_job(void *user, size_t job, int worker) {
    (void)worker;
    const gauss_run *g = user;
    int y = (int)job, ch = g->channels;
    float w[128];
    int first;
    int count = axis_taps(g, y, g->sh, w, &first);
    for (int x = 0; x < g->dw; x++)
        for (int c = 0; c < ch; c++) {
            float acc = 0.0f;
            for (int i = 0; i < count; i++)
                acc += w[i] * g->tmp[((size_t)(first + i) * (size_t)g->dw + (size_t)x) * (size_t)ch + (size_t)c];
            g->dst[((size_t)y * (size_t)g->dw + (size_t)x) * (size_t)ch + (size_t)c] = acc;
        }
}

bool pn_gauss_downsample(const float *src, int sw, int sh, int channels, int s, float *dst, int dw, int dh,
                         pn_threadpool *pool, float *tmp_in) {
    if (s < 1 || s > 16 || channels < 1 || sw < s * dw || sh < s * dh) return false;
    double sigma = 0.4 * (double)s;
    int radius = (int)ceil(3.0 * sigma); /* at most 20: 2 radius + 2 taps fit w[128] */
    int klen = 2 * radius + 3;
    float *kernel = malloc((size_t)klen * sizeof *kernel);
    float *tmp = tmp_in ? tmp_in : malloc((size_t)dw * (size_t)sh * (size_t)channels * sizeof *tmp);
    if (!kernel || !tmp) {
        free(kernel);
        if (!tmp_in) free(tmp);
        return false;
    }
    for (int k = 0; k < klen; k++) {
        double d = 0.5 * k;
        kernel[k] = (float)exp(-d * d / (2.0 * sigma * sigma));
    }
    gauss_run g = {src, tmp, dst, sw, sh, dw, dh, channels, s, radius, kernel};
    pn_threadpool_run(pool, (size_t)sh, row_job, &g);
    pn_threadpool_run(pool, (size_t)dh, column_job, &g);
    free(kernel);
    if (!tmp_in) free(tmp);
    return true;
}
