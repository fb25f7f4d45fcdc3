/* contour_metrics — the image comparison of Vedel 1993 Table 1 (after Kok & Jansen 1992): the
 * average absolute difference between two images in 8-bit display values (sRGB, exposure 0,
 * clamped, rounded; mean over pixels and the three channels), with relMSE, the |a-b| x 16 error
 * image and close-ups. Uses only the public header.
 *
 *   contour_metrics REFERENCE IMAGE [--error-png FILE] [--closeup x,y,w,h,FILE]... [--top N]
 *
 * Prints one JSON object: {"avg_diff_8bit": ..., "relmse": ..., "max_diff_8bit": ...}. */
#include "penumbra/penumbra.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "display8.h"

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: contour_metrics REFERENCE IMAGE [--error-png FILE] [--closeup x,y,w,h,FILE]...\n");
        return 2;
    }
    pn_context ctx = pn_context_new();
    pn_image ref = NULL, img = NULL, err = NULL;
    if (pn_image_read(ctx, argv[1], &ref) != PN_OK || pn_image_read(ctx, argv[2], &img) != PN_OK) {
        fprintf(stderr, "contour_metrics: %s\n", pn_context_error_message(ctx));
        return 3;
    }
    pn_image_metrics m;
    if (pn_image_compare(ctx, ref, img, &m, &err) != PN_OK) {
        fprintf(stderr, "contour_metrics: %s\n", pn_context_error_message(ctx));
        return 3;
    }
    int w = pn_image_width(ref), h = pn_image_height(ref);
    const float *a = pn_image_layer_data(ref, 0), *b = pn_image_layer_data(img, 0);
    double sum = 0.0;
    int worst = 0;
    for (size_t i = 0; i < (size_t)w * (size_t)h * 3; i++) {
        int d = abs(to_8bit(a[i]) - to_8bit(b[i]));
        sum += d;
        if (d > worst) worst = d;
    }
    for (int i = 3; i + 1 < argc; i += 2) {
        if (strcmp(argv[i], "--error-png") == 0) {
            if (pn_image_write(ctx, err, argv[i + 1], 0.0f) != PN_OK)
                fprintf(stderr, "%s\n", pn_context_error_message(ctx));
        } else if (strcmp(argv[i], "--top") == 0) {
            /* The pixels with the largest luminance difference (for debugging a comparison). */
            int count = atoi(argv[i + 1]);
            unsigned char *used = calloc((size_t)w * h, 1);
            for (int t = 0; t < count && used; t++) {
                double best = -1.0;
                int bi = 0;
                for (int k = 0; k < w * h; k++) {
                    double la = 0.2126 * a[3 * k] + 0.7152 * a[3 * k + 1] + 0.0722 * a[3 * k + 2];
                    double lb = 0.2126 * b[3 * k] + 0.7152 * b[3 * k + 1] + 0.0722 * b[3 * k + 2];
                    if (!used[k] && fabs(la - lb) > best) {
                        best = fabs(la - lb);
                        bi = k;
                    }
                }
                used[bi] = 1;
                fprintf(stderr, "pixel %d %d: reference %g image %g\n", bi % w, bi / w,
                        0.2126 * a[3 * bi] + 0.7152 * a[3 * bi + 1] + 0.0722 * a[3 * bi + 2],
                        0.2126 * b[3 * bi] + 0.7152 * b[3 * bi + 1] + 0.0722 * b[3 * bi + 2]);
            }
            free(used);
        } else if (strcmp(argv[i], "--closeup") == 0) {
            int x, y, cw, ch;
            char path[1024];
            if (sscanf(argv[i + 1], "%d,%d,%d,%d,%1023s", &x, &y, &cw, &ch, path) != 5) return 2;
            pn_image c = NULL;
            if (pn_image_crop(ctx, img, x, y, cw, ch, &c) == PN_OK) pn_image_write(ctx, c, path, 0.0f);
            pn_image_free(c);
        }
    }
    printf("{\"avg_diff_8bit\": %.4f, \"max_diff_8bit\": %d, \"relmse\": %.6g, \"mae\": %.6g}\n",
           sum / ((double)w * h * 3), worst, m.relmse, m.mae);
    pn_image_free(err);
    pn_image_free(ref);
    pn_image_free(img);
    pn_context_free(ctx);
    return 0;
}
