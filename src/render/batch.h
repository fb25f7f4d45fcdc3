/* batch.h — the one interface between drivers and integrators (ARCHITECTURE.md, "The one
 * interface that holds it together"): a driver hands an integrator a batch of pixels; the
 * integrator returns, for each, a radiance estimate, its variance and its counters
 * (pn_pixel_estimate, film/aovs.h).
 *
 * The render/ module is what drivers and integrators share, below both of them: the resolved
 * render job (render_job.h), the camera and pixel filters (camera.h), camera-ray and
 * perfect-specular-chain tracing (pn_pixel_eye_sample, pn_trace_eye_path in render_job.h,
 * eye_path.c), and the progress and cancel path (progress.h). Integrators include no driver/
 * header; driver/ reaches integrators only through integrators/registry.h.
 *
 * What a batch carries today: the pixels (full-image coordinates, in evaluation order) and the
 * block they lie in. Every integrator still traces its own camera rays and specular chains, now
 * through render/ rather than driver/ code, because three of them decide the eye rays themselves:
 * the reference integrator's adaptive loop chooses how many eye rays a pixel gets, ias traces
 * per-block eye-ray sequences over its passes, contour-mc and contour's spans interleave eye rays
 * with their own refinement. What remains for the full design: the driver traces camera rays and
 * specular chains once and the batch carries, per pixel, its shading points with their filter
 * weights (one or more, the pn_shading_point of integrators/illumcut.h moved here), for the
 * integrators of a fixed eye-ray count (the VPL family, reference and contour at fixed spp);
 * adaptive integrators then ask the driver for more points of a pixel through a callback on the
 * batch instead of tracing them. */
#ifndef PN_RENDER_BATCH_H
#define PN_RENDER_BATCH_H

#include "film/aovs.h"
#include "render/render_job.h"

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

#endif
