/* aovs.h — the per-pixel estimate every integrator returns, the one table of AOV layers (name,
 * PN_AOV_* bit, channels, which estimate field fills it) and the one routine that assembles an
 * image from estimates. The CLI's --aov parsing, the stats JSON, the method table's AOV lists and
 * every image assembler read names from here (ARCHITECTURE.md: film/ owns AOVs). */
#ifndef PN_FILM_AOVS_H
#define PN_FILM_AOVS_H

#include "core/vecmath.h"
#include "penumbra/penumbra.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* What an integrator returns for one pixel: its radiance estimate, the estimate's variance and
 * its counters. Film turns an array of these into the beauty image and its AOV layers. */
typedef struct pn_pixel_estimate {
    vec3 radiance;
    vec3 emitted;            /* the part of radiance that eye rays saw emitted, weighted as radiance
                                (filled where pn_integrator_reports_emitted says so) */
    float relative_variance; /* s^2 / L^2 of the estimate (luminance), 0 when L = 0 */
    uint32_t eye_rays, shadow_rays, specular_rays;
    /* eye samples (ias: pixels) whose value came out NaN or infinite and were counted as 0: an
     * integrator's bug made visible (the statistic non_finite_samples, a warning) */
    uint32_t non_finite;
    float depth;          /* first-hit distance of the first eye ray (INFINITY on a miss) */
    vec3 normal;          /* first-hit shading normal */
    vec3 albedo;          /* first-hit diffuse reflectance */
    float embree_seconds; /* estimated time inside Embree calls for this pixel (sampled) */
    /* ias statistics (zero for other integrators) */
    uint32_t passes, aa_regions;
    uint32_t visible_lights;        /* distinct lights (and environment regions) seen unoccluded */
    float clusters;                 /* clusters per shading point, mean over the pixel's regions */
    float visible_fraction;         /* unoccluded shadow rays / shadow rays */
    float cut_seconds, pdf_seconds; /* time in cluster cuts and in PDF upkeep (estimates) */
    /* VPL integrators (issue 5; zero otherwise): L_UB evaluations for the pixel's points, cut
     * size per point (lightcuts) or pairs touching the pixel (illumcut), Phase I radiance */
    float bound_evaluations, cut_size;
    vec3 phase1;
    /* contour: gradient of the irradiance luminance from contour lights (PN_AOV_GRADIENT) */
    vec3 gradient;
    /* PN_AOV_ILLUMINANCE: illuminance (lux) on the first non-specular surface of the eye
     * samples, filter-weighted as radiance (reference: direct; vpl, lightcuts: total) */
    float illuminance;
    /* PN_AOV_MELANOPIC_EDI: melanopic EDI (lux, CIE S 026; spectral/melanopic.h) on the same
     * receivers from the same samples as illuminance, in spectral mode (0 otherwise) */
    float melanopic_edi;
} pn_pixel_estimate;

/* How a layer's value is obtained. */
typedef enum pn_aov_source {
    PN_AOV_FROM_U32,       /* (float) of a uint32_t field of pn_pixel_estimate */
    PN_AOV_FROM_FLOAT,     /* a float field */
    PN_AOV_FROM_VEC3,      /* a vec3 field, 3 channels */
    PN_AOV_FROM_LOG10P1,   /* log10(1 + float field): a derived layer for false-colour pictures */
    PN_AOV_FROM_DRIVER,    /* not in the estimate: a progressive driver fills it from its own state */
    PN_AOV_FROM_LUMINANCE, /* the luminance Y of a vec3 field, in SI units (core/photometry.h, docs/units.md) */
    PN_AOV_FROM_XYZ        /* CIE 1931 XYZ of a linear-sRGB vec3 field, 3 channels (pn_film_xyz) */
} pn_aov_source;

/* One layer of the output image besides the beauty. Layers are written in table order. */
typedef struct pn_aov_layer {
    const char *name; /* the EXR layer name; for selectable layers also the --aov name */
    uint32_t bit;     /* the PN_AOV_* bit that requests it */
    int channels;     /* 1 or 3 */
    pn_aov_source source;
    size_t offset; /* offsetof the field in pn_pixel_estimate (unused for PN_AOV_FROM_DRIVER) */
    bool derived;  /* written with another layer of the same bit, not selectable by name */
} pn_aov_layer;

/* CIE 1931 XYZ of a linear sRGB value (the inverse of the matrix spectral mode's film applies to the
 * XYZ it integrates, spectral/cie.h, so in spectral mode this is the pixel's integrated XYZ).
 * Units: Y is the luminance of a radiance (cd/m^2), X and Z alike (docs/units.md). */
vec3 pn_film_xyz(vec3 rgb);

/* The table, in write order, and its length. */
int pn_aov_layer_count(void);
const pn_aov_layer *pn_aov_layer_at(int index);
/* The selectable layer of that bit; NULL if none. */
const pn_aov_layer *pn_aov_layer_of(uint32_t bit);

/* Appends the selectable layer of `bit` to img (name and channels from the table) and returns its
 * pixels, zeroed; NULL when out of memory or the bit names no layer. For drivers that fill their
 * own layers. */
float *pn_film_add_aov(pn_image img, uint32_t bit);

/* Warns through ctx when `count` eye samples of the render came out NaN or infinite (they were
 * counted as 0, so the image hides them): a bug of the integrator, named in the message. */
void pn_film_warn_non_finite(pn_context ctx, uint64_t count, const char *integrator);

/* Assembles the image of width x height estimates (row-major): the beauty from radiance and,
 * in table order, every layer of `aovs` that the estimate fills (PN_AOV_FROM_DRIVER layers are
 * skipped). *out is NULL on failure. */
pn_status pn_film_assemble(const pn_pixel_estimate *pixels, int width, int height, uint32_t aovs, pn_image *out);

#endif
