/* metrics.h — error metrics between a reference image and an image under test, used by
 * pn_image_compare (penumbra diff) and by tests that compare renders with references.
 */
#ifndef PN_FILM_METRICS_H
#define PN_FILM_METRICS_H

#include "penumbra/penumbra.h"

#include <stdint.h>

/* Fills `m` from two interleaved w x h images with `channels` channels each (1..4; luminance
 * uses channels 0..2 with Rec. 709 weights, or channel 0 for greyscale). All sums use double
 * accumulators:
 *   rmse           sqrt(mean((a-b)^2))
 *   relmse         mean((a-b)^2 / (b^2 + 0.01)), b the reference; relmse_epsilon = 0.01
 *   rel_l1         sum|a-b| / sum|b|          (0 when both sums are 0, +inf when only the
 *   rel_l2         sqrt(sum (a-b)^2 / sum b^2)  denominator is)
 *   mae            mean|a-b|
 * Samples where either image holds NaN or infinity are left out of every sum and mean (the
 * means divide by the number of samples kept); their count is stored in *non_finite when that
 * pointer is not NULL. Returns PN_ERROR_INVALID_ARGUMENT for NULL pointers or bad sizes. */
pn_status pn_metrics_compute_ex(const float *ref, const float *img, int w, int h, int channels, pn_image_metrics *m,
                                uint64_t *non_finite);

/* pn_metrics_compute_ex without the count of skipped samples. */
pn_status pn_metrics_compute(const float *ref, const float *img, int w, int h, int channels, pn_image_metrics *m);

#endif
