/* downsample.h — the Gaussian filter that takes a progressive driver's work image (s x s the
 * output resolution) down to the output image, as RADIANCE's pfilt does for Guo 1998 (§5). */
#ifndef PN_FILM_DOWNSAMPLE_H
#define PN_FILM_DOWNSAMPLE_H

#include "core/threadpool.h"

#include <stdbool.h>

/* Filters `channels`-channel interleaved src (sw x sh) into dst (dw x dh), output pixel (x, y)
 * centred on work pixel s*x + (s-1)/2, with a separable Gaussian of standard deviation 0.4
 * output pixels truncated at 3 sigma; weights are renormalised over the taps that fall inside
 * the work window (so borders of a crop need no pixels outside it). Deterministic (fixed
 * summation order, whatever the thread count). Needs 1 <= s <= 16, sw >= s*dw and sh >= s*dh.
 * Rows are spread over `pool` (NULL: the caller alone). `tmp` (may be NULL: allocated here)
 * holds dw * sh * channels floats for the horizontal pass. Returns false on bad sizes or when
 * out of memory. */
bool pn_gauss_downsample(const float *src, int sw, int sh, int channels, int s, float *dst, int dw, int dh,
                         pn_threadpool *pool, float *tmp);

#endif
