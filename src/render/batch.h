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
 * What a batch carries today: the pixels (full-image coordinates, in evaluation order), the
 * block they lie in and, for integrators that take a fixed number of eye samples per pixel
 * (pn_integrator.batch_points: vpl, lightcuts, and illumcut's batch path), the shading points of those samples with
 * their filter weights, traced once by the tiled and the progressive drivers through
 * pn_batch_trace_points (camera ray, perfect-specular chain, BSDF at the end point).
 *
 * What remains for the full design (ARCHITECTURE.md): the other integrators still trace their own
 * eye rays, through render/ rather than driver/ code. reference's adaptive loop decides how many
 * eye rays a pixel gets, ias traces per-block eye-ray sequences over its passes, contour and
 * contour-mc interleave eye rays with their refinement, and illumcut's whole-image path
 * (render_image) traces the points of its point tree itself. For them the batch needs a way to
 * ask the driver for more points of a pixel (a callback on the batch) and a point type that
 * carries what reference's and ias's estimators read (the hit, not only the VPL receiver); the
 * whole-image path needs the driver to trace the image's points in chunks. */
#ifndef PN_RENDER_BATCH_H
#define PN_RENDER_BATCH_H

#include "film/aovs.h"
#include "lights/vpl.h"
#include "render/render_job.h"
#include "render/stats.h"

#include <stdbool.h>
#include <stdint.h>

/* One eye sample of a pixel, followed through specular chains (the same numbers in every VPL
 * integrator, so their images can be compared point for point). */
typedef struct pn_shading_point {
    pn_vpl_receiver r;
    vec3 throughput; /* specular tints up to the point */
    vec3 emitted;    /* emitters and environment seen along the way */
    float weight;    /* pixel filter weight */
    bool has_point;
} pn_shading_point;

/* A shading point traced by the driver for a batch: the point, and what its eye ray adds to the
 * pixel's estimate (its rays; the first-hit AOV fields, used for sample 0). */
typedef struct pn_batch_point {
    pn_shading_point sp;
    uint32_t rays; /* intersect calls of the eye path (1 + specular bounces) */
    float first_depth;
    vec3 first_normal, first_albedo;
} pn_batch_point;

/* A set of pixels of the work image. All pixels of a batch lie in one block of the image
 * (block_x, block_y in block units; blocks are job->block_size pixels square, 8x8 by default, for
 * the tiled driver, 8x8 for the progressive ones), which seeds a block-adaptive integrator's
 * quasi-random sequence. */
typedef struct pn_batch {
    int block_x, block_y;
    int count;
    const int32_t (*pixels)[2]; /* full-image pixel coordinates, in evaluation order */
    /* Shading points the driver traced: points[i * points_per_pixel + s] is eye sample s of
     * pixels[i]; NULL (and 0) when the integrator traces its own (see pn_batch_eye_point). */
    uint32_t points_per_pixel;
    const pn_batch_point *points;
} pn_batch;

/* pn_pixel_estimate, what an integrator returns per pixel, is film's (film/aovs.h). */

struct pn_threadpool;
/* Renders the whole window at once: fills pixels[y * width + x] for the window (camera x0..x1,
 * y0..y1) using the pool. */
typedef pn_status (*pn_render_image_fn)(const pn_render_job *job, struct pn_threadpool *pool, pn_pixel_estimate *pixels,
                                        int width, int height);

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
    pn_status (*render_batch)(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out, void *scratch);
    /* Optional: under the tiled driver, renders the whole window instead of blocks (illumcut's
     * point tree spans every shading point of the image; contour runs §5 spans along whole rows). */
    pn_render_image_fn render_image;
    /* Optional: the fixed number of eye samples per pixel (samples 0..n-1 of
     * pn_eye_point_trace) the integrator takes from the batch; the tiled and progressive drivers
     * then trace them into batch->points for render_batch (not for render_image). NULL: the
     * integrator traces its own eye rays. */
    uint32_t (*batch_points)(const pn_render_job *job);
} pn_integrator;

/* Eye sample i of full-image pixel (px, py) in the VPL integrators' convention (one scrambled
 * Sobol sequence per pixel, salted apart from reference's), followed through specular chains
 * to its shading point; the same numbers in every VPL integrator, so that their images can be
 * compared point for point. */
void pn_eye_point_trace(const pn_render_job *job, int px, int py, uint32_t i, pn_batch_point *out);
/* Copies the point to *sp and adds its eye ray to *est (the first-hit AOV fields on i == 0). */
void pn_eye_point_apply(const pn_batch_point *pt, uint32_t i, pn_shading_point *sp, pn_pixel_estimate *est);
/* Eye sample i of batch pixel pi: the driver's point when the batch carries them, else traced
 * here; either way applied to *est as pn_eye_point_apply does. */
void pn_batch_eye_point(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t i, pn_shading_point *sp,
                        pn_pixel_estimate *est);
/* Traces per_pixel eye samples of each of count pixels into out (count * per_pixel points). */
void pn_batch_trace_points(const pn_render_job *job, int count, const int32_t (*pixels)[2], uint32_t per_pixel,
                           pn_batch_point *out);

#endif
