/* integrator.h — the one interface between drivers and integrators (ARCHITECTURE.md): a driver
 * hands an integrator a batch of pixels; the integrator returns, for each, a radiance estimate,
 * its variance and its counters. */
#ifndef PN_INTEGRATORS_INTEGRATOR_H
#define PN_INTEGRATORS_INTEGRATOR_H

#include "driver/render_job.h"
#include "film/aovs.h"

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

/* pn_pixel_estimate, what an integrator returns per pixel, is film's (film/aovs.h). */

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

#endif
