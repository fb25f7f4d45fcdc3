/* closeups — a row of close-ups of the same window of several images, side by side and enlarged
 * (pixel replication), for bench/contour/RESULTS.md. Uses only the public header: the row is
 * written as a PFM and converted with pn_image_write.
 *
 *   closeups OUT.png X Y W H SCALE EXPOSURE IMAGE.pfm...   (EXPOSURE in stops, as penumbra --png)
 */
#include "penumbra/penumbra.h"

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
    if (argc < 9) {
        fprintf(stderr, "usage: closeups OUT.png X Y W H SCALE EXPOSURE IMAGE.pfm...\n");
        return 2;
    }
    int x0 = atoi(argv[2]), y0 = atoi(argv[3]), w = atoi(argv[4]), h = atoi(argv[5]), k = atoi(argv[6]);
    float exposure = (float)atof(argv[7]);
    int n = argc - 8, gap = 4, cw = n * w * k + (n - 1) * gap, ch = h * k;
    float *canvas = calloc((size_t)cw * (size_t)ch * 3, sizeof *canvas);
    pn_context ctx = pn_context_new();
    for (int i = 0; i < n && canvas; i++) {
        pn_image img = NULL;
        if (pn_image_read(ctx, argv[8 + i], &img) != PN_OK) {
            fprintf(stderr, "closeups: %s\n", pn_context_error_message(ctx));
            return 3;
        }
        int iw = pn_image_width(img), ih = pn_image_height(img);
        const float *d = pn_image_layer_data(img, 0);
        for (int y = 0; y < ch; y++)
            for (int x = 0; x < w * k; x++) {
                int sx = x0 + x / k, sy = y0 + y / k;
                if (sx < 0 || sy < 0 || sx >= iw || sy >= ih) continue;
                for (int c = 0; c < 3; c++)
                    canvas[3 * ((size_t)y * cw + (size_t)(i * (w * k + gap) + x)) + c] =
                        d[3 * ((size_t)sy * iw + sx) + c];
            }
        pn_image_free(img);
    }
    /* PFM: bottom row first. */
    char tmp[1100];
    snprintf(tmp, sizeof tmp, "%s.tmp.pfm", argv[1]);
    FILE *f = fopen(tmp, "wb");
    if (!f || !canvas) return 3;
    fprintf(f, "PF\n%d %d\n-1.0\n", cw, ch);
    for (int y = ch - 1; y >= 0; y--) fwrite(canvas + 3 * (size_t)y * cw, sizeof *canvas, 3 * (size_t)cw, f);
    fclose(f);
    pn_image out = NULL;
    int rc = pn_image_read(ctx, tmp, &out) == PN_OK && pn_image_write(ctx, out, argv[1], exposure) == PN_OK ? 0 : 3;
    if (rc) fprintf(stderr, "closeups: %s\n", pn_context_error_message(ctx));
    remove(tmp);
    pn_image_free(out);
    free(canvas);
    pn_context_free(ctx);
    return rc;
}
