/* rgb_product.c — how far the RGB product of a light and a reflectance is from the colour of the
 * product of their spectra, as pbrt-v4 computes it (issue "spectral": confirm the cause of
 * staircase-832-matte's +4.2 % luminance against pbrt-v4).
 *
 * pbrt-v4 turns an "rgb L"/"rgb I" light into an RGBIlluminantSpectrum, m S_L(λ) D65(λ) with
 * m = 2 max(rgb) and S_L the sigmoid-polynomial fit of rgb / m (its photometric normalisation
 * divides by the D65 part only, a constant common to both modes), and an RGB reflectance (texel
 * or constant) into the fit S_A(λ); a reflection is the spectral product, integrated against
 * the CIE 1931 functions to XYZ and converted to linear sRGB. penumbra multiplies the RGBs.
 * This program prints, for one light colour and each reflectance given, the mean over texels of
 * both results' luminance and channels (the light's own colour round-trips exactly by
 * construction: the RGB of m S_L D65 is rgb).
 *
 * usage: rgb_product R G B  TEXTURE.tga|r,g,b ...     (texture texels decoded with the sRGB curve)
 */
#include "io/image.h"
#include "spectral/cie.h"
#include "spectral/rgb2spec.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* XYZ -> linear sRGB of ∫ S_L(λ) m D65(λ) S_A(λ) x̄ȳz̄(λ) dλ, normalised so that D65 has Y = 1. */
static void spectral_product_rgb(const float cl[3], double m, const float ca[3], double rgb[3]) {
    double xyz[3] = {0, 0, 0}, y_white = 0;
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX; l += 1.0) {
        double w = (l == PN_LAMBDA_MIN || l == PN_LAMBDA_MAX ? 0.5 : 1.0) * pn_cie_table_eval(pn_cie_d65_5nm, l);
        double bar[3];
        pn_cie_xyz_bar(l, bar);
        double s = m * pn_sigmoid_spectrum(cl, l) * pn_sigmoid_spectrum(ca, l);
        for (int j = 0; j < 3; j++) xyz[j] += w * bar[j] * s;
        y_white += w * bar[1];
    }
    for (int j = 0; j < 3; j++) xyz[j] /= y_white;
    pn_xyz_to_linear_srgb(xyz, rgb);
}

static void fit(const double rgb[3], float c[3]) {
    double cn[3] = {0, 0, 0};
    pn_rgb2spec_fit(rgb, cn);
    pn_rgb2spec_to_nm(cn, c);
}

static double luminance(const double rgb[3]) {
    return 0.2126729 * rgb[0] + 0.7151522 * rgb[1] + 0.0721750 * rgb[2];
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: rgb_product R G B TEXTURE|r,g,b ...\n");
        return 2;
    }
    double light[3] = {atof(argv[1]), atof(argv[2]), atof(argv[3])};
    double m = 2.0 * fmax(light[0], fmax(light[1], light[2]));
    double light_n[3] = {light[0] / m, light[1] / m, light[2] / m};
    float cl[3];
    fit(light_n, cl);
    double own[3];
    spectral_product_rgb(cl, m, (float[3]){0.0f, 0.0f, INFINITY}, own);
    printf("light rgb %.5g %.5g %.5g: its spectrum's own rgb %.5g %.5g %.5g\n", light[0], light[1], light[2], own[0],
           own[1], own[2]);
    printf("%-40s %10s %10s %8s %8s %8s %8s\n", "reflectance", "Y rgb", "Y spec", "Y ratio", "R ratio", "G ratio",
           "B ratio");
    for (int a = 4; a < argc; a++) {
        double sum_rgb[3] = {0, 0, 0}, sum_spec[3] = {0, 0, 0};
        double albedo[3];
        if (sscanf(argv[a], "%lf,%lf,%lf", &albedo[0], &albedo[1], &albedo[2]) == 3) {
            float ca[3];
            fit(albedo, ca);
            spectral_product_rgb(cl, m, ca, sum_spec);
            for (int j = 0; j < 3; j++) sum_rgb[j] = light[j] * albedo[j];
        } else {
            pn_image img = NULL;
            pn_err err = {0};
            if (pn_image_read_file(argv[a], 0.0f, &img, &err) != PN_OK) {
                fprintf(stderr, "%s\n", err.message);
                return 3;
            }
            /* Texels are fitted exactly; a 64-entry cache per quantised texel keeps it fast. */
            size_t n = (size_t)img->width * img->height;
            size_t step = n > 20000 ? n / 20000 : 1, used = 0;
            for (size_t p = 0; p < n; p += step, used++) {
                const float *t = img->layers[0].data + 3 * p;
                double al[3] = {fmin(fmax(t[0], 0), 1), fmin(fmax(t[1], 0), 1), fmin(fmax(t[2], 0), 1)};
                float ca[3];
                fit(al, ca);
                double s[3];
                spectral_product_rgb(cl, m, ca, s);
                for (int j = 0; j < 3; j++) {
                    sum_spec[j] += s[j];
                    sum_rgb[j] += light[j] * al[j];
                }
            }
            for (int j = 0; j < 3; j++) {
                sum_spec[j] /= (double)used;
                sum_rgb[j] /= (double)used;
            }
            pn_image_free(img);
        }
        printf("%-40s %10.5g %10.5g %8.4f %8.4f %8.4f %8.4f\n",
               strrchr(argv[a], '/') ? strrchr(argv[a], '/') + 1 : argv[a], luminance(sum_rgb), luminance(sum_spec),
               luminance(sum_rgb) / luminance(sum_spec), sum_rgb[0] / sum_spec[0], sum_rgb[1] / sum_spec[1],
               sum_rgb[2] / sum_spec[2]);
    }
    return 0;
}
