/* ray_breakdown — where the contour integrator's shadow rays go, per pixel class, from the trace
 * that `penumbra render --integrator contour` writes with --contour-trace FILE
 * (contour_render.c: one line per counted pixel of eye ray 0: x y class why rays-by-phase...),
 * with the average 8-bit difference of each class against a reference image.
 *
 *   ray_breakdown TRACE REFERENCE IMAGE X0 Y0     (X0, Y0: the crop window's first pixel)
 *
 * Prints two markdown tables: rays per pixel by phase for each class, and how many pixels were
 * integrated for each reason. */
#include "penumbra/penumbra.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "display8.h"

enum { PHASES = 8, CLASSES = 4, WHYS = 5 };
static const char *phase_name[PHASES] = {"pattern check", "first level", "side dichotomy", "validity (diagonals)",
                                         "case-4 centre", "subdivision", "restart pass",   "island probe"};
static const char *class_name[CLASSES] = {"no candidate obstacle (culled)", "every ray visible", "every ray hidden",
                                          "penumbra (both)"};
static const char *why_name[WHYS] = {"span start", "pattern changed / span end", "run middle", "uniform run",
                                     "every pixel (spans off)"};

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: ray_breakdown TRACE REFERENCE IMAGE X0 Y0\n");
        return 2;
    }
    FILE *f = fopen(argv[1], "r");
    pn_context ctx = pn_context_new();
    pn_image ref = NULL, img = NULL;
    if (!f || pn_image_read(ctx, argv[2], &ref) != PN_OK || pn_image_read(ctx, argv[3], &img) != PN_OK) {
        fprintf(stderr, "ray_breakdown: cannot read the inputs\n");
        return 3;
    }
    int x0 = atoi(argv[4]), y0 = atoi(argv[5]);
    int w = pn_image_width(ref), h = pn_image_height(ref);
    const float *a = pn_image_layer_data(ref, 0), *b = pn_image_layer_data(img, 0);
    double rays[CLASSES][PHASES] = {{0}}, diff[CLASSES] = {0}, diff_interp[CLASSES] = {0}, signed_diff[CLASSES] = {0};
    long pixels[CLASSES] = {0}, interp[CLASSES] = {0}, why[CLASSES][WHYS] = {{0}};
    int x, y, cls;
    unsigned wh;
    unsigned r[PHASES];
    while (fscanf(f, "%d %d %d %u %u %u %u %u %u %u %u %u", &x, &y, &cls, &wh, &r[0], &r[1], &r[2], &r[3], &r[4], &r[5],
                  &r[6], &r[7]) == 12) {
        int ix = x - x0, iy = y - y0;
        if (ix < 0 || iy < 0 || ix >= w || iy >= h || cls < 0 || cls >= CLASSES) continue;
        size_t k = (size_t)iy * (size_t)w + (size_t)ix;
        double d = 0.0, sd = 0.0;
        for (int c = 0; c < 3; c++) {
            d += abs(to_8bit(a[3 * k + c]) - to_8bit(b[3 * k + c]));
            sd += to_8bit(b[3 * k + c]) - to_8bit(a[3 * k + c]);
        }
        d /= 3.0;
        signed_diff[cls] += sd / 3.0;
        pixels[cls]++;
        diff[cls] += d;
        for (int p = 0; p < PHASES; p++) rays[cls][p] += r[p];
        if (!wh) {
            interp[cls]++;
            diff_interp[cls] += d;
        }
        for (int q = 0; q < WHYS; q++)
            if (wh & (1u << q)) why[cls][q]++;
    }
    long counted = pixels[1] + pixels[2] + pixels[3];
    double total_rays = 0.0;
    printf("| class | pixels | share of counted | avg. diff. | mean signed diff. | interpolated pixels (avg. diff.) |");
    for (int p = 0; p < PHASES; p++) printf(" %s |", phase_name[p]);
    printf(" rays / pixel |\n|---|---|---|---|---|---|");
    for (int p = 0; p < PHASES; p++) printf("---|");
    printf("---|\n");
    for (int c = 0; c < CLASSES; c++) {
        if (!pixels[c]) continue;
        double t = 0.0;
        for (int p = 0; p < PHASES; p++) t += rays[c][p];
        total_rays += t;
        char share[32] = "-";
        if (c > 0) snprintf(share, sizeof share, "%.1f%%", 100.0 * (double)pixels[c] / (double)counted);
        printf("| %s | %ld | %s | %.3f | %+.3f | %ld (%.3f) |", class_name[c], pixels[c], share, diff[c] / pixels[c],
               signed_diff[c] / pixels[c], interp[c], interp[c] ? diff_interp[c] / interp[c] : 0.0);
        for (int p = 0; p < PHASES; p++) printf(" %.2f |", rays[c][p] / pixels[c]);
        printf(" %.2f |\n", t / pixels[c]);
    }
    double all[PHASES] = {0};
    for (int c = 1; c < CLASSES; c++)
        for (int p = 0; p < PHASES; p++) all[p] += rays[c][p];
    printf("| all counted | %ld | 100%% | %.3f | %+.3f | %ld |", counted,
           counted ? (diff[1] + diff[2] + diff[3]) / counted : 0.0,
           counted ? (signed_diff[1] + signed_diff[2] + signed_diff[3]) / counted : 0.0,
           interp[1] + interp[2] + interp[3]);
    for (int p = 0; p < PHASES; p++) printf(" %.2f |", counted ? all[p] / counted : 0.0);
    printf(" %.2f |\n\n", counted ? total_rays / counted : 0.0);
    printf("| class |");
    for (int q = 0; q < WHYS; q++) printf(" %s |", why_name[q]);
    printf("\n|---|");
    for (int q = 0; q < WHYS; q++) printf("---|");
    printf("\n");
    for (int c = 1; c < CLASSES; c++) {
        if (!pixels[c]) continue;
        printf("| %s |", class_name[c]);
        for (int q = 0; q < WHYS; q++) printf(" %ld |", why[c][q]);
        printf("\n");
    }
    fclose(f);
    pn_image_free(ref);
    pn_image_free(img);
    pn_context_free(ctx);
    return 0;
}
