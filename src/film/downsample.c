/* downsample.c — separable Gaussian downsampling of a work image (see downsample.h). */
#include "film/downsample.h"

#include <math.h>
#include <stdlib.h>

/* Taps of one output coordinate along an axis of n work pixels: first tap index and weights. */
static int axis_taps(int o, int s, int n, int radius, const float *kernel, float *w, int *first) {
    int centre = s * o + (s - 1) / 2;
    int odd = (s - 1) % 2; /* even s: the centre lies between two work pixels */
    int lo = centre - radius, hi = centre + radius + odd;
    if (lo < 0) lo = 0;
    if (hi > n - 1) hi = n - 1;
    float sum = 0.0f;
    int count = 0;
    for (int i = lo; i <= hi; i++) {
        int d2 = 2 * (i - centre) - odd; /* twice the distance to the centre */
        int k = d2 < 0 ? -d2 : d2;
        w[count] = kernel[k];
        sum += w[count];
        count++;
    }
    for (int i = 0; i < count; i++) w[i] /= sum;
    *first = lo;
    return count;
}

bool pn_gauss_downsample(const float *src, int sw, int sh, int channels, int s, float *dst, int dw, int dh) {
    if (s < 1 || channels < 1 || sw < s * dw || sh < s * dh) return false;
    double sigma = 0.4 * (double)s;
    int radius = (int)ceil(3.0 * sigma);
    /* kernel[k] = weight at distance k/2 work pixels */
    int klen = 2 * radius + 3;
    float *kernel = malloc((size_t)klen * sizeof *kernel);
    float *w = malloc((size_t)(2 * radius + 2) * sizeof *w);
    float *tmp = malloc((size_t)dw * (size_t)sh * (size_t)channels * sizeof *tmp);
    if (!kernel || !w || !tmp) {
        free(kernel);
        free(w);
        free(tmp);
        return false;
    }
    for (int k = 0; k < klen; k++) {
        double d = 0.5 * k;
        kernel[k] = (float)exp(-d * d / (2.0 * sigma * sigma));
    }
    for (int x = 0; x < dw; x++) {
        int first;
        int count = axis_taps(x, s, sw, radius, kernel, w, &first);
        for (int y = 0; y < sh; y++)
            for (int c = 0; c < channels; c++) {
                float acc = 0.0f;
                for (int i = 0; i < count; i++) acc += w[i] * src[((size_t)y * sw + (size_t)(first + i)) * channels + c];
                tmp[((size_t)y * dw + (size_t)x) * channels + c] = acc;
            }
    }
    for (int y = 0; y < dh; y++) {
        int first;
        int count = axis_taps(y, s, sh, radius, kernel, w, &first);
        for (int x = 0; x < dw; x++)
            for (int c = 0; c < channels; c++) {
                float acc = 0.0f;
                for (int i = 0; i < count; i++) acc += w[i] * tmp[((size_t)(first + i) * dw + (size_t)x) * channels + c];
                dst[((size_t)y * dw + (size_t)x) * channels + c] = acc;
            }
    }
    free(kernel);
    free(w);
    free(tmp);
    return true;
}
