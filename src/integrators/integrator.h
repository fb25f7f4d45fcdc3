/* integrator.h — the one interface between drivers and integrators (ARCHITECTURE.md): a driver
 * hands an integrator a batch of pixels; the integrator returns, for each, a radiance estimate,
 * its variance and its counters. */
#ifndef PN_INTEGRATORS_INTEGRATOR_H
#define PN_INTEGRATORS_INTEGRATOR_H

#include "driver/render_job.h"

#include <stdbool.h>
#include <stdint.h>

/* A set of pixels of the work image. All pixels of a batch lie in one block of the image
 * (block_x, block_y in block units; blocks are job->block_size pixels square, 8x8 by default, for
 * the tiled driver, 8x8 for the progressive ones), which seeds a block-adaptive integrator's
 * quasi-random sequence. */
typedef struct pn_batch {
    int block_x, block_y;
    int count;
    const int32_t (*pixels)[2]; /* full-image pixel coordinates, in evaluation order */
} pn_batch;

typedef struct pn_pixel_estimate {
    vec3 radiance;
    vec3 emitted;            /* the part of radiance that eye rays saw emitted, weighted as radiance
                                (filled where pn_integrator_reports_emitted says so) */
    float relative_variance; /* s^2 / L^2 of the estimate (luminance), 0 when L = 0 */
    uint32_t eye_rays, shadow_rays, specular_rays;
    float depth;  /* first-hit distance of the first eye ray (INFINITY on a miss) */
    vec3 normal;  /* first-hit shading normal */
    vec3 albedo;  /* first-hit diffuse reflectance */
    float embree_seconds; /* estimated time inside Embree calls for this pixel (sampled) */
    /* ias statistics (zero for other integrators) */
    uint32_t passes, aa_regions;
    uint32_t visible_lights;  /* distinct lights (and environment regions) seen unoccluded */
    float clusters;          /* clusters per shading point, mean over the pixel's regions */
    float visible_fraction;  /* unoccluded shadow rays / shadow rays */
    float cut_seconds, pdf_seconds; /* time in cluster cuts and in PDF upkeep (estimates) */
    /* VPL integrators (issue 5; zero otherwise): L_UB evaluations for the pixel's points, cut
     * size per point (lightcuts) or pairs touching the pixel (illumcut), Phase I radiance */
    float bound_evaluations, cut_size;
    vec3 phase1;
    /* contour: gradient of the irradiance luminance from contour lights (PN_AOV_GRADIENT) */
    vec3 gradient;
} pn_pixel_estimate;

struct pn_threadpool;
/* Renders the whole window at once: fills pixels[y * width + x] for the window (camera x0..x1,
 * y0..y1) using the pool. */
typedef pn_status (*pn_render_image_fn)(const pn_render_job *job, struct pn_threadpool *pool,
                                        pn_pixel_estimate *pixels, int width, int height);

/* The code of one integrator. What it is, what it computes, its capabilities and options are
 * its entry in the method table (integrators/registry.c), which points here. */
typedef struct pn_integrator {
    const char *name;
    /* Optional: builds what the whole render shares (e.g. light cluster trees) into
     * job->integrator_data, and frees it. */
    pn_status (*prepare)(pn_render_job *job, pn_err *err);
    void (*release)(pn_render_job *job);
    /* Optional: adds what only the integrator knows to the statistics (before release). */
    void (*report)(const pn_render_job *job, pn_render_stats *stats);
    /* Per-worker scratch: created once per thread, freed at the end of the render. */
    void *(*scratch_create)(const pn_render_job *job);
    void (*scratch_free)(void *scratch);
    /* Fills out[i] for batch->pixels[i]. */
    pn_status (*render_batch)(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                              void *scratch);
    /* Optional: under the tiled driver, renders the whole window instead of blocks (illumcut's
     * point tree spans every shading point of the image; contour runs §5 spans along whole rows). */
    pn_render_image_fn render_image;
} pn_integrator;

/* Capabilities from the method table (registry.c): whether the integrator fills
 * pn_pixel_estimate.emitted (PN_CAP_EMITTED), so that the progressive drivers interpolate only the
 * rest; and how many eye rays per pixel it traces as samples 0..n-1 of pn_pixel_eye_sample, each
 * weighted by its filter weight (PN_CAP_EYE_SAMPLES: job->spp; else 0). */
bool pn_integrator_reports_emitted(const pn_integrator *integrator);
uint32_t pn_integrator_pixel_eye_samples(const pn_integrator *integrator, const pn_render_job *job);
/* The integrator of the table entry of that kind; NULL if unknown. */
const pn_integrator *pn_integrator_find(pn_integrator_kind kind);

/* The integrators, each defined at the bottom of its own file. */
extern const pn_integrator pn_integrator_reference;
extern const pn_integrator pn_integrator_ias;
/* contour (Vedel 1993) and contour-mc (Kok & Jansen 1992): src/integrators/contour*.c */
extern const pn_integrator pn_integrator_contour;
extern const pn_integrator pn_integrator_contour_mc;

extern const pn_integrator pn_integrator_vpl;
extern const pn_integrator pn_integrator_lightcuts;
extern const pn_integrator pn_integrator_illumcut;
/* Adds the VPL integrators' AOV layers (PN_AOV_BOUND_EVALUATIONS, _CUT_SIZE, _PHASE1) to img. */
struct pn_image_s;
bool pn_vpl_write_aovs(const pn_pixel_estimate *pixels, size_t count, uint32_t aovs, struct pn_image_s *img);

#endif
