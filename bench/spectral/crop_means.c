/* crop_means.c — the mean luminance and per-channel means of a rendered crop against the same
 * window of a reference image (bench/spectral/measure.sh): prints
 *   lum_ratio r_ratio g_ratio b_ratio  (image mean / reference mean)
 * or "black" when the reference window's mean luminance is 0.
 * usage: pn_crop_means REFERENCE.exr IMAGE.exr X0 X1 Y0 Y1   (the crop as fractions, --crop's)
 * With IMAGE "-", prints the reference window's mean luminance and R G B means instead. */
#include "penumbra/penumbra.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

static void means(const float *rgb, size_t pixels, double m[3]) {
    m[0] = m[1] = m[2] = 0.0;
    for (size_t i = 0; i < pixels; i++)
        for (int c = 0; c < 3; c++) m[c] += (double)rgb[3 * i + (size_t)c];
    for (int c = 0; c < 3; c++) m[c] /= (double)pixels;
}

int main(int argc, char **argv) {
    if (argc != 7) {
        fprintf(stderr, "usage: %s REFERENCE IMAGE X0 X1 Y0 Y1\n", argv[0]);
        return 2;
    }
    pn_context ctx = pn_context_new();
    pn_image ref = NULL, img = NULL, ref_crop = NULL;
    const bool only_ref = argv[2][0] == '-' && argv[2][1] == 0;
    if (pn_image_read(ctx, argv[1], &ref) != PN_OK || (!only_ref && pn_image_read(ctx, argv[2], &img) != PN_OK)) {
        fprintf(stderr, "%s\n", pn_context_error_message(ctx));
        return 3;
    }
    int W = pn_image_width(ref), H = pn_image_height(ref);
    float f[4];
    for (int i = 0; i < 4; i++) f[i] = strtof(argv[3 + i], NULL);
    /* The window --crop renders (the same rounding as the renderer and tests/test_refimages.c). */
    int x0 = (int)ceilf((float)W * f[0]), x1 = (int)ceilf((float)W * f[1]);
    int y0 = (int)ceilf((float)H * f[2]), y1 = (int)ceilf((float)H * f[3]);
    if (pn_image_crop(ctx, ref, x0, y0, x1 - x0, y1 - y0, &ref_crop) != PN_OK) {
        fprintf(stderr, "%s\n", pn_context_error_message(ctx));
        return 3;
    }
    double a[3], b[3];
    size_t n = (size_t)(x1 - x0) * (size_t)(y1 - y0);
    means(pn_image_layer_data(ref_crop, 0), n, b);
    if (only_ref) {
        printf("%.6g %.6g %.6g %.6g\n", 0.2126 * b[0] + 0.7152 * b[1] + 0.0722 * b[2], b[0], b[1], b[2]);
        return 0;
    }
    if (pn_image_width(img) != x1 - x0 || pn_image_height(img) != y1 - y0) {
        fprintf(stderr, "crop %dx%d does not match the image %dx%d\n", x1 - x0, y1 - y0, pn_image_width(img),
                pn_image_height(img));
        return 3;
    }
    means(pn_image_layer_data(img, 0), n, a);
    double la = 0.2126 * a[0] + 0.7152 * a[1] + 0.0722 * a[2], lb = 0.2126 * b[0] + 0.7152 * b[1] + 0.0722 * b[2];
    if (lb > 0.0)
        printf("%.4f %.4f %.4f %.4f\n", la / lb, a[0] / b[0], a[1] / b[1], a[2] / b[2]);
    else
        printf("black\n");
    pn_image_free(ref_crop);
    pn_image_free(img);
    pn_image_free(ref);
    pn_context_free(ctx);
    return 0;
}
