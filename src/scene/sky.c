/* sky.c — the CIE standard overcast sky as an environment image, generated at load time (see
 * sky.h). The luminance distribution is the CIE's (Moon & Spencer 1942; CIE S 011/E:2003 type 1):
 * L(h) = L_z (1 + 2 sin h) / 3, independent of azimuth, with L_z fixed by the horizontal
 * illuminance asked for. The image uses pbrt-v4's equal-area octahedral mapping, so every texel
 * covers 4 pi / N sr; only a texel's elevation matters, and z of the mapping's point (u, v) is
 * sign(1 - |x| - |y|) (1 - r^2) with x = 2u - 1, y = 2v - 1, r = 1 - |1 - |x| - |y||.
 *
 * Discretisation: each texel holds the mean luminance of 4 x 4 points inside it, and the whole
 * image is scaled so that sum_i L_i (integral of cos over texel i) equals the horizontal
 * illuminance, the integral estimated from the same 4 x 4 points. The renderers read the map by
 * nearest texel, so this is the illuminance they integrate; the scale differs from the analytic
 * L_z by 2e-6 at 512 x 512 (the horizon texels). */
#include "scene/sky.h"

#include "core/photometry.h"
#include "core/vecmath.h"
#include "scene/parser_internal.h"
#include "scene/tokenizer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SKY_SUBSAMPLES 4
#define PN_PI_D 3.14159265358979323846

double pn_sky_overcast_relative(double sin_h) {
    return sin_h > 0.0 ? (1.0 + 2.0 * sin_h) / 3.0 : 0.0;
}

double pn_sky_overcast_zenith(double illuminance_lux) {
    return 9.0 * illuminance_lux / (7.0 * PN_PI_D);
}

/* z (the sine of the elevation) of the equal-area octahedral mapping at (u, v) in [0, 1]^2. */
static double equal_area_z(double u, double v) {
    double x = 2.0 * u - 1.0, y = 2.0 * v - 1.0;
    double signed_distance = 1.0 - (fabs(x) + fabs(y));
    double r = 1.0 - fabs(signed_distance);
    return copysign(1.0 - r * r, signed_distance);
}

pn_status pn_sky_requested(const pn_params *ps, const char **name, pn_err *err) {
    return pn_params_string(ps, "sky", "", name, err);
}

static pn_sky_model sky_model(const char *name) {
    if (strcmp(name, "cie-overcast") == 0) return PN_SKY_CIE_OVERCAST;
    return PN_SKY_NONE;
}

pn_status pn_sky_image(struct pn_scene_s *scene, const pn_params *ps, const char *name, double illuminance_lux,
                       int *image, pn_err *err) {
    *image = -1;
    const pn_param *at = pn_params_find(ps, "sky");
    if (sky_model(name) != PN_SKY_CIE_OVERCAST)
        return pn_loc_error(at ? &at->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "unknown sky \"%s\" (penumbra has \"cie-overcast\")", name);
    if (!(illuminance_lux > 0.0) || !isfinite(illuminance_lux))
        return pn_loc_error(at ? &at->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "sky \"%s\" needs a positive \"float illuminance\" (lux on an unobstructed horizontal "
                            "plane)",
                            name);
    const int n = PN_SKY_RESOLUTION;
    float *rgb = malloc(3 * (size_t)n * (size_t)n * sizeof *rgb);
    char *path = malloc(96);
    if (!rgb || !path || !pn_grow_for_append((void **)&scene->images, scene->image_count, sizeof *scene->images)) {
        free(rgb);
        free(path);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the sky image");
    }
    /* Relative luminance per texel and the horizontal illuminance it gives. */
    const double texel_sr = 4.0 * PN_PI_D / ((double)n * (double)n);
    const double sub = 1.0 / (double)SKY_SUBSAMPLES;
    double e_relative = 0.0;
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++) {
            double l_sum = 0.0, cos_sum = 0.0;
            for (int j = 0; j < SKY_SUBSAMPLES; j++)
                for (int i = 0; i < SKY_SUBSAMPLES; i++) {
                    double z = equal_area_z(((double)x + ((double)i + 0.5) * sub) / (double)n,
                                            ((double)y + ((double)j + 0.5) * sub) / (double)n);
                    l_sum += pn_sky_overcast_relative(z);
                    cos_sum += z > 0.0 ? z : 0.0;
                }
            double l = l_sum * sub * sub;
            e_relative += l * cos_sum * sub * sub * texel_sr;
            float *px = rgb + 3 * ((size_t)y * (size_t)n + (size_t)x);
            px[0] = px[1] = px[2] = (float)l;
        }
    /* cd/m^2 per unit relative luminance: scene radiance is luminance (docs/units.md). */
    const double scale = illuminance_lux / e_relative;
    for (size_t k = 0; k < 3 * (size_t)n * (size_t)n; k++) rgb[k] = (float)((double)rgb[k] * scale);
    snprintf(path, 96, "<sky %s, %.6g lx>", name, illuminance_lux);
    pn_texture_image *ti = &scene->images[scene->image_count];
    ti->width = n;
    ti->height = n;
    ti->rgb = rgb;
    ti->path = path;
    *image = scene->image_count++;
    return PN_OK;
}
