/* metrics.c — image error metrics (RMSE, relative MSE, relative L1/L2, MAE, mean luminance)
 * and the public pn_image_compare built on them.
 */
#include "film/metrics.h"

#include "core/context.h"
#include "io/image.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PN_RELMSE_EPSILON 0.01

/* Rec. 709 luminance of a pixel with `channels` interleaved values; grey for 1-2 channels. */
static double pn_luminance(const float *p, int channels) {
    if (channels < 3) return (double)p[0];
    return 0.2126 * (double)p[0] + 0.7152 * (double)p[1] + 0.0722 * (double)p[2];
}

pn_status pn_metrics_compute_ex(const float *ref, const float *img, int w, int h, int channels, pn_image_metrics *m,
                                uint64_t *non_finite) {
    if (non_finite) *non_finite = 0;
    if (!ref || !img || !m || w <= 0 || h <= 0 || channels < 1 || channels > 4) {
        return PN_ERROR_INVALID_ARGUMENT;
    }
    memset(m, 0, sizeof *m);
    m->relmse_epsilon = PN_RELMSE_EPSILON;

    const size_t pixels = (size_t)w * (size_t)h;
    double sum_sq = 0.0, sum_rel = 0.0, sum_abs = 0.0, sum_ref_abs = 0.0, sum_ref_sq = 0.0;
    double lum_ref = 0.0, lum_img = 0.0;
    uint64_t kept = 0, skipped = 0, lum_ref_count = 0, lum_img_count = 0;

    for (size_t p = 0; p < pixels; p++) {
        const float *a = img + p * (size_t)channels;
        const float *b = ref + p * (size_t)channels;
        int a_finite = 1, b_finite = 1;
        for (int c = 0; c < channels; c++) {
            if (!isfinite(a[c])) a_finite = 0;
            if (!isfinite(b[c])) b_finite = 0;
            if (!isfinite(a[c]) || !isfinite(b[c])) {
                skipped++;
                continue;
            }
            double bv = (double)b[c];
            double d = (double)a[c] - bv;
            sum_sq += d * d;
            sum_rel += d * d / (bv * bv + PN_RELMSE_EPSILON);
            sum_abs += fabs(d);
            sum_ref_abs += fabs(bv);
            sum_ref_sq += bv * bv;
            kept++;
        }
        if (b_finite) {
            lum_ref += pn_luminance(b, channels);
            lum_ref_count++;
        }
        if (a_finite) {
            lum_img += pn_luminance(a, channels);
            lum_img_count++;
        }
    }

    if (kept > 0) {
        m->rmse = sqrt(sum_sq / (double)kept);
        m->relmse = sum_rel / (double)kept;
        m->mae = sum_abs / (double)kept;
    }
    if (sum_ref_abs > 0.0) {
        m->rel_l1 = sum_abs / sum_ref_abs;
    } else {
        m->rel_l1 = sum_abs > 0.0 ? (double)INFINITY : 0.0;
    }
    if (sum_ref_sq > 0.0) {
        m->rel_l2 = sqrt(sum_sq / sum_ref_sq);
    } else {
        m->rel_l2 = sum_sq > 0.0 ? (double)INFINITY : 0.0;
    }
    if (lum_ref_count > 0) m->mean_luminance_reference = lum_ref / (double)lum_ref_count;
    if (lum_img_count > 0) m->mean_luminance_image = lum_img / (double)lum_img_count;
    if (non_finite) *non_finite = skipped;
    return PN_OK;
}

pn_status pn_metrics_compute(const float *ref, const float *img, int w, int h, int channels, pn_image_metrics *m) {
    return pn_metrics_compute_ex(ref, img, w, h, channels, m, NULL);
}

pn_status pn_image_compare(pn_context ctx, pn_image reference, pn_image image, pn_image_metrics *metrics,
                           pn_image *error_image) {
    if (error_image) *error_image = NULL;
    if (!reference || !image || !metrics) {
        const char *which = !image ? "image" : !metrics ? "metrics" : NULL;
        if (!reference) which = "reference"; /* not-a-method-name: the reference image */
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_image_compare: %s is NULL", which);
    }
    if (reference->layer_count < 1 || image->layer_count < 1 ||
        reference->layers[0].channels != image->layers[0].channels) {
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "images have different beauty layers");
    }
    if (reference->width != image->width || reference->height != image->height) {
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "images differ in size: %dx%d vs %dx%d",
                               reference->width, reference->height, image->width, image->height);
    }

    const int w = image->width, h = image->height, channels = image->layers[0].channels;
    const float *ref = reference->layers[0].data, *img = image->layers[0].data;
    uint64_t non_finite = 0;
    pn_status status = pn_metrics_compute_ex(ref, img, w, h, channels, metrics, &non_finite);
    if (status != PN_OK) {
        return pn_context_fail(ctx, status, "cannot compare images of %dx%d with %d channels", w, h, channels);
    }
    if (non_finite > 0 && ctx) {
        pn_context_log(ctx, PN_LOG_WARNING, "%llu samples are NaN or infinite and were left out of the metrics",
                       (unsigned long long)non_finite);
    }

    if (error_image) {
        pn_image diff = pn_image_create(w, h);
        if (!diff) {
            return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d error image", w, h);
        }
        float *out = diff->layers[0].data;
        const size_t pixels = (size_t)w * (size_t)h;
        for (size_t p = 0; p < pixels; p++) {
            for (int c = 0; c < 3; c++) {
                /* Greyscale beauties (never produced today) would be replicated. */
                int src = channels >= 3 ? c : 0;
                size_t i = p * (size_t)channels + (size_t)src;
                out[p * 3 + (size_t)c] = fabsf(img[i] - ref[i]) * 16.0f;
            }
        }
        *error_image = diff;
    }
    return PN_OK;
}
