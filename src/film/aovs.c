/* aovs.c — the one table of AOV layers and the image assembly from per-pixel estimates (see
 * aovs.h). The public pn_aov_count / pn_aov_name walk the selectable entries of this table. */
#include "film/aovs.h"

#include "core/context.h"
#include "core/photometry.h"
#include "io/image.h"
#include "spectral/cie.h"

#include <math.h>
#include <string.h>

#define EST(field) offsetof(pn_pixel_estimate, field)

/* The order is the order of the layers in the written EXR, and of the names in help text and
 * the stats JSON; changing it changes the output files' bytes. */
static const pn_aov_layer layers[] = {
    {"shadow_rays", PN_AOV_SHADOW_RAYS, 1, PN_AOV_FROM_U32, EST(shadow_rays), false},
    {"eye_rays", PN_AOV_EYE_RAYS, 1, PN_AOV_FROM_U32, EST(eye_rays), false},
    {"relative_variance", PN_AOV_RELATIVE_VARIANCE, 1, PN_AOV_FROM_FLOAT, EST(relative_variance), false},
    {"depth", PN_AOV_DEPTH, 1, PN_AOV_FROM_FLOAT, EST(depth), false},
    {"normal", PN_AOV_NORMAL, 3, PN_AOV_FROM_VEC3, EST(normal), false},
    {"albedo", PN_AOV_ALBEDO, 3, PN_AOV_FROM_VEC3, EST(albedo), false},
    {"passes", PN_AOV_PASSES, 1, PN_AOV_FROM_U32, EST(passes), false},
    {"aa_regions", PN_AOV_AA_REGIONS, 1, PN_AOV_FROM_U32, EST(aa_regions), false},
    {"clusters", PN_AOV_CLUSTERS, 1, PN_AOV_FROM_FLOAT, EST(clusters), false},
    {"visible_fraction", PN_AOV_VISIBLE_FRACTION, 1, PN_AOV_FROM_FLOAT, EST(visible_fraction), false},
    {"bound_evaluations", PN_AOV_BOUND_EVALUATIONS, 1, PN_AOV_FROM_FLOAT, EST(bound_evaluations), false},
    /* IlluminationCut's Fig. 4 is drawn on this logarithm (with --aov-png, the false-colour PNG). */
    {"log10_bound_evaluations", PN_AOV_BOUND_EVALUATIONS, 1, PN_AOV_FROM_LOG10P1, EST(bound_evaluations), true},
    {"cut_size", PN_AOV_CUT_SIZE, 1, PN_AOV_FROM_FLOAT, EST(cut_size), false},
    {"phase1", PN_AOV_PHASE1, 3, PN_AOV_FROM_VEC3, EST(phase1), false},
    {"gradient", PN_AOV_GRADIENT, 3, PN_AOV_FROM_VEC3, EST(gradient), false},
    {"sampling_pattern", PN_AOV_SAMPLING_PATTERN, 1, PN_AOV_FROM_DRIVER, 0, false},
    {"block_map", PN_AOV_BLOCK_MAP, 1, PN_AOV_FROM_DRIVER, 0, false},
    {"block_direction", PN_AOV_BLOCK_DIRECTION, 1, PN_AOV_FROM_DRIVER, 0, false},
    /* Lighting design (docs/lighting-design.md): lux and cd/m^2. */
    {"illuminance", PN_AOV_ILLUMINANCE, 1, PN_AOV_FROM_FLOAT, EST(illuminance), false},
    {"luminance", PN_AOV_LUMINANCE, 1, PN_AOV_FROM_LUMINANCE, EST(radiance), false},
    /* Colorimetry (docs/spectral.md): the pixel's CIE 1931 XYZ, channels X, Y, Z written as
     * XYZ.R, XYZ.G, XYZ.B (io/exr.c's naming of three-channel layers). */
    {"XYZ", PN_AOV_XYZ, 3, PN_AOV_FROM_XYZ, EST(radiance), false},
    /* CIE S 026 melanopic EDI, lux (spectral mode; docs/lighting-design.md). */
    {"melanopic_edi", PN_AOV_MELANOPIC_EDI, 1, PN_AOV_FROM_FLOAT, EST(melanopic_edi), false},
};

#define LAYER_COUNT ((int)(sizeof layers / sizeof layers[0]))

int pn_aov_layer_count(void) {
    return LAYER_COUNT;
}

const pn_aov_layer *pn_aov_layer_at(int index) {
    return index >= 0 && index < LAYER_COUNT ? &layers[index] : NULL;
}

const pn_aov_layer *pn_aov_layer_of(uint32_t bit) {
    for (int i = 0; i < LAYER_COUNT; i++)
        if (layers[i].bit == bit && !layers[i].derived) return &layers[i];
    return NULL;
}

/* ---- the public names: the selectable entries, in table order ---- */

int pn_aov_count(void) {
    int n = 0;
    for (int i = 0; i < LAYER_COUNT; i++) n += !layers[i].derived;
    return n;
}

const char *pn_aov_name(int index, uint32_t *bit) {
    if (index < 0) return NULL;
    for (int i = 0; i < LAYER_COUNT; i++) {
        if (layers[i].derived) continue;
        if (index-- == 0) {
            if (bit) *bit = layers[i].bit;
            return layers[i].name;
        }
    }
    return NULL;
}

float *pn_film_add_aov(pn_image img, uint32_t bit) {
    const pn_aov_layer *l = pn_aov_layer_of(bit);
    return l ? pn_image_add_layer(img, l->name, l->channels) : NULL;
}

vec3 pn_film_xyz(vec3 rgb) {
    const double in[3] = {rgb.x, rgb.y, rgb.z};
    double xyz[3];
    pn_linear_srgb_to_xyz(in, xyz);
    return v3((float)xyz[0], (float)xyz[1], (float)xyz[2]);
}

/* Fills one layer from the estimates. */
static void fill_layer(const pn_aov_layer *l, const pn_pixel_estimate *pixels, size_t n, float *dst) {
    for (size_t i = 0; i < n; i++) {
        const char *field = (const char *)&pixels[i] + l->offset;
        switch (l->source) {
        case PN_AOV_FROM_U32: {
            uint32_t v;
            memcpy(&v, field, sizeof v);
            dst[i] = (float)v;
            break;
        }
        case PN_AOV_FROM_FLOAT: memcpy(&dst[i], field, sizeof(float)); break;
        case PN_AOV_FROM_LOG10P1: {
            float v;
            memcpy(&v, field, sizeof v);
            dst[i] = log10f(1.0f + v);
            break;
        }
        case PN_AOV_FROM_VEC3: {
            vec3 v;
            memcpy(&v, field, sizeof v);
            dst[3 * i] = v.x;
            dst[3 * i + 1] = v.y;
            dst[3 * i + 2] = v.z;
            break;
        }
        case PN_AOV_FROM_LUMINANCE: {
            vec3 v;
            memcpy(&v, field, sizeof v);
            dst[i] = pn_photometric(v);
            break;
        }
        case PN_AOV_FROM_XYZ: {
            vec3 v;
            memcpy(&v, field, sizeof v);
            v = pn_film_xyz(v);
            dst[3 * i] = v.x;
            dst[3 * i + 1] = v.y;
            dst[3 * i + 2] = v.z;
            break;
        }
        case PN_AOV_FROM_DRIVER: break;
        }
    }
}

void pn_film_warn_non_finite(pn_context ctx, uint64_t count, const char *integrator) {
    if (count == 0 || !ctx) return;
    pn_context_log(ctx, PN_LOG_WARNING,
                   "%llu eye sample%s of the %s integrator came out NaN or infinite and %s counted as 0 (values "
                   "beyond the float range in the scene, or a bug to report; statistic non_finite_samples)",
                   (unsigned long long)count, count == 1 ? "" : "s", integrator, count == 1 ? "was" : "were");
}

pn_status pn_film_assemble(const pn_pixel_estimate *pixels, int width, int height, uint32_t aovs, pn_image *out) {
    *out = NULL;
    pn_image img = pn_image_create(width, height);
    if (!img) return PN_ERROR_OUT_OF_MEMORY;
    size_t n = (size_t)width * (size_t)height;
    float *beauty = (float *)pn_image_layer_data(img, 0);
    for (size_t i = 0; i < n; i++) {
        beauty[3 * i] = pixels[i].radiance.x;
        beauty[3 * i + 1] = pixels[i].radiance.y;
        beauty[3 * i + 2] = pixels[i].radiance.z;
    }
    for (int k = 0; k < LAYER_COUNT; k++) {
        const pn_aov_layer *l = &layers[k];
        if (!(aovs & l->bit) || l->source == PN_AOV_FROM_DRIVER) continue;
        float *dst = pn_image_add_layer(img, l->name, l->channels);
        if (!dst) {
            pn_image_free(img);
            return PN_ERROR_OUT_OF_MEMORY;
        }
        fill_layer(l, pixels, n, dst);
    }
    *out = img;
    return PN_OK;
}
