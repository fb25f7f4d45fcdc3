/* image_metrics.h — image error measures shared by the tests (header only). */
#ifndef PN_TEST_IMAGE_METRICS_H
#define PN_TEST_IMAGE_METRICS_H

#include "penumbra/penumbra.h"

/* relMSE of img against ref as `penumbra diff` reports it: (b - a)^2 / (a^2 + 0.01) averaged over
 * the pixels and channels of the beauty layer. */
static inline double pn_test_relmse(pn_image ref, pn_image img) {
    int n = 3 * pn_image_width(ref) * pn_image_height(ref);
    const float *a = pn_image_layer_data(ref, 0), *b = pn_image_layer_data(img, 0);
    double sum = 0.0;
    for (int i = 0; i < n; i++) {
        double d = (double)b[i] - (double)a[i];
        sum += d * d / ((double)a[i] * (double)a[i] + 0.01);
    }
    return sum / n;
}

#endif
