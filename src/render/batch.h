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
 * What a batch carries: the pixels (full-image coordinates, in evaluation order), the block they
 * lie in, and the eye samples of those pixels, traced by the driver (camera ray, perfect-specular
 * chain, BSDF at the end point), in one of two forms:
 *
 *  - VPL receivers (pn_batch_point; pn_integrator.batch_points: vpl, lightcuts, illumcut): a
 *    fixed number of samples per pixel of the VPL sequence, traced in advance by the tiled and
 *    progressive drivers for their batches (pn_batch_supply), or one at a time through the
 *    batch's more_points (illumcut's whole image).
 *  - Eye hits (pn_eye_hit; pn_integrator.batch_hits: reference, contour-mc, contour, ias): the
 *    whole end point of the path (the hit, its BSDF, the wavelengths, the camera ray's film
 *    point, the sequence's scramble, from which the estimator draws its light samples). The
 *    drivers trace in advance the samples 0..n-1 of the sequence that the integrator says it
 *    takes from every pixel (batch_hits_seq; its fixed spp, the pilot of its adaptive rule, ias's
 *    aa-rays), at most PN_BATCH_HITS_MAX per batch; an integrator that decides per pixel how
 *    many eye rays it needs (reference's --threshold, ias's emitter rays) gets the others through
 *    the batch's callback (more_hits), which the driver sets and which traces any range of any
 *    sequence of a pixel. pn_batch_eye_hits is the one accessor: it returns a range from the
 *    in-advance hits where they hold it and asks the callback for the rest. Every hit is a
 *    function of (seed, pixel, sequence, index) only (ias's block sequence: of the batch's block
 *    and the pixel's place in the batch, as ias numbered its eye rays), so an image does not
 *    depend on which hits came in advance, on the batch, or on the thread count.
 *
 * Whole-image integrators (render_image: illumcut's point tree, contour's scanline rows) get the
 * driver's tracers as a batch of no pixels (the window) and read every eye sample through batches
 * of the window's pixels built on it (pn_batch_part). No integrator traces an eye ray itself.
 * Outside any batch, the progressive drivers' primary refinement (progressive.c, driver code)
 * traces centre rays and its demodulation factors' rays through pn_trace_eye_path, the same
 * specular-chain tracer. */
#ifndef PN_RENDER_BATCH_H
#define PN_RENDER_BATCH_H

#include "film/aovs.h"
#include "lights/vpl.h"
#include "render/render_job.h"
#include "render/stats.h"
#include "shade/bsdf.h"
#include "spectral/transport.h"

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

/* The quasi-random eye-sample sequences. Each is one Owen-scrambled Sobol sequence, index 0 up
 * (pn_pixel_eye_sample's dimensions), its scramble a hash of the seed and the pixel, or for the
 * block sequence of the batch's block (pn_batch_sequence_scramble); every eye sample a driver
 * traces is one of them, through one tracer (eye_path.c). */
typedef enum pn_eye_sequence {
    PN_EYE_SEQ_PIXEL = 0,   /* pn_pixel_scramble: reference's fixed-spp sequence (the cross rule's
                               stream A), contour's, the progressive drivers' primary refinement */
    PN_EYE_SEQ_CROSS_B = 1, /* reference's cross-rule stream B (reference.c, render_pixel_cross) */
    PN_EYE_SEQ_VPL = 2,     /* the VPL integrators' (pn_eye_point_trace), salted apart */
    /* ias's eye rays (§4.4): one sequence per block (a hash of the seed and block_x, block_y),
     * numbered pixel by pixel in batch order, batch->hits_stride indices per pixel: sample s of
     * batch pixel pi is index pi * hits_stride + s. Traced in RGB in spectral mode too (ias
     * draws wavelengths per light sample, pn_spectral_sample_value). */
    PN_EYE_SEQ_IAS_BLOCK = 3,
    PN_EYE_SEQ_IAS_EMITTER = 4, /* ias's emitter rays (ias_speed.h): per pixel, RGB */
    PN_EYE_SEQ_COUNT
} pn_eye_sequence;

/* Every PN_EYE_TIMING_STRIDE-th eye sample of a sequence (index % stride == 0) has its trace
 * timed (pn_eye_hit.seconds); the sum, scaled by the stride, estimates the time spent in Embree
 * without timing every ray. */
#define PN_EYE_TIMING_STRIDE 8u

/* An eye sample traced by the driver to the end of its perfect-specular chain, with everything an
 * estimator at the hit reads. Read the BSDF through pn_eye_hit_bsdf and the wavelengths through
 * pn_eye_hit_wavelengths (the stored BSDF's wavelength pointer is not kept valid: hits are
 * copied). */
typedef struct pn_eye_hit {
    pn_eye_path path;         /* as pn_trace_eye_path_spectral leaves it: emitted and throughput at the
                         wavelengths in spectral mode */
    pn_bsdf bsdf;             /* at path.hit seen from path.wo when path.has_point, else zero */
    pn_swl wl;                /* spectral mode: the sample's wavelengths (pn_eye_wavelengths) */
    uint32_t scramble;        /* the sequence's scramble, from which the estimator draws the sample's
                          light samples (reference: dimensions 5-7 of index i * S + j) */
    uint32_t index;           /* the sample's index in its sequence */
    float weight;             /* pixel filter weight */
    float raster_x, raster_y; /* the camera ray's point on the film (pn_camera_filter_sample) */
    float seconds;            /* the trace's time when index % PN_EYE_TIMING_STRIDE == 0, else 0 */
} pn_eye_hit;

/* At most this many eye hits per batch are traced in advance (the tiled driver keeps one buffer
 * of them per worker; a hit is 336 bytes on x86-64, so 1.4 MB): 64 samples of an 8x8 block. A batch whose integrator asks for more gets
 * fewer per pixel in advance and the others through its callback. */
#define PN_BATCH_HITS_MAX 4096u

struct pn_batch;
/* The driver's tracer of further eye hits (pn_batch.more_hits): fills out[0..count) with
 * samples first..first+count-1 (per pixel: see PN_EYE_SEQ_IAS_BLOCK), in index order, of
 * sequence seq of batch pixel pi. Must give exactly what pn_batch_more_hits gives. */
typedef void (*pn_eye_hits_fn)(const pn_render_job *job, const struct pn_batch *batch, int pi, pn_eye_sequence seq,
                               uint32_t first, uint32_t count, pn_eye_hit *out);
/* The driver's tracer of further VPL receivers (pn_batch.more_points): eye samples
 * first..first+count-1 of batch pixel pi as pn_eye_point_trace gives them. */
typedef void (*pn_eye_points_fn)(const pn_render_job *job, const struct pn_batch *batch, int pi, uint32_t first,
                                 uint32_t count, pn_batch_point *out);

/* A set of pixels of the work image. All pixels of a batch lie in one block of the image
 * (block_x, block_y in block units; blocks are job->block_size pixels square, 8x8 by default, for
 * the tiled driver, 8x8 for the progressive ones), which seeds a block-adaptive integrator's
 * quasi-random sequence.
 *
 * Every eye sample an integrator reads comes from the batch: in advance (points, hits) or
 * through the driver's tracers (more_points, more_hits). A batch without the tracer an
 * integrator needs is a bug of its driver: an assertion in debug builds; in release builds the
 * samples come out non-finite (no point, NaN emission), so that the integrators count them in
 * the statistic non_finite_samples and the render warns, naming the integrator. */
typedef struct pn_batch {
    int block_x, block_y;
    int count;
    const int32_t (*pixels)[2]; /* full-image pixel coordinates, in evaluation order */
    /* Shading points the driver traced: points[i * points_per_pixel + s] is eye sample s of
     * pixels[i]; NULL (and 0): none in advance (see pn_batch_eye_point). */
    uint32_t points_per_pixel;
    const pn_batch_point *points;
    /* Eye hits the driver traced in advance (pn_integrator.batch_hits): hits[i * hits_per_pixel +
     * s] is sample s of sequence hits_seq of pixels[i]. hits_per_pixel may be less than the
     * integrator asked for (PN_BATCH_HITS_MAX); NULL (and 0): none. */
    uint32_t hits_per_pixel;
    const pn_eye_hit *hits;
    /* The driver's tracers of every other eye sample (pn_batch_set_tracers: pn_batch_more_hits,
     * pn_batch_more_points); more_user is theirs. */
    pn_eye_hits_fn more_hits;
    void *more_user;
    pn_eye_points_fn more_points;
    pn_eye_sequence hits_seq; /* the in-advance hits' sequence (pn_integrator.batch_hits_seq) */
    uint32_t hits_stride;     /* PN_EYE_SEQ_IAS_BLOCK's indices per pixel: the integrator's batch_hits */
} pn_batch;

/* pn_pixel_estimate, what an integrator returns per pixel, is film's (film/aovs.h). */

struct pn_threadpool;
/* Renders the whole window at once: fills pixels[y * width + x] for the window (camera x0..x1,
 * y0..y1) using the pool. `window` carries the driver's tracers of the window's eye samples (a
 * batch of no pixels): the integrator reads every eye sample through batches of the window's
 * pixels that it builds with pn_batch_part. */
typedef pn_status (*pn_render_image_fn)(const pn_render_job *job, struct pn_threadpool *pool, const pn_batch *window,
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
    /* Optional: called once after a render that finished (not cancelled, no failure), before
     * release: writes the files the integrator's own options ask for, atomically (contour-trace).
     * A failure here fails the render. */
    pn_status (*finish)(pn_render_job *job, pn_err *err);
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
     * integrator reads them through batch->more_points. */
    uint32_t (*batch_points)(const pn_render_job *job);
    /* Optional: the number n of eye samples 0..n-1 of sequence batch_hits_seq that the integrator
     * takes from every pixel of a batch, whatever they hold; the tiled and progressive drivers
     * trace (up to PN_BATCH_HITS_MAX of) them into batch->hits and set batch->more_hits for
     * everything else. The integrator reads eye samples only through pn_batch_eye_hits. */
    uint32_t (*batch_hits)(const pn_render_job *job);
    pn_eye_sequence batch_hits_seq; /* PN_EYE_SEQ_PIXEL unless set */
} pn_integrator;

/* Eye sample i of full-image pixel (px, py) in the VPL integrators' convention (one scrambled
 * Sobol sequence per pixel, salted apart from reference's), followed through specular chains
 * to its shading point; the same numbers in every VPL integrator, so that their images can be
 * compared point for point. */
void pn_eye_point_trace(const pn_render_job *job, int px, int py, uint32_t i, pn_batch_point *out);
/* Copies the point to *sp and adds its eye ray to *est (the first-hit AOV fields on i == 0). */
void pn_eye_point_apply(const pn_batch_point *pt, uint32_t i, pn_shading_point *sp, pn_pixel_estimate *est);
/* Eye sample i of batch pixel pi: the driver's point when the batch carries it in advance, else
 * from batch->more_points; either way applied to *est as pn_eye_point_apply does. */
void pn_batch_eye_point(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t i, pn_shading_point *sp,
                        pn_pixel_estimate *est);
/* Traces per_pixel eye samples of each of count pixels into out (count * per_pixel points). */
void pn_batch_trace_points(const pn_render_job *job, int count, const int32_t (*pixels)[2], uint32_t per_pixel,
                           pn_batch_point *out);
/* The standard pn_eye_points_fn (every driver's): pn_eye_point_trace of the batch's pixel. */
void pn_batch_more_points(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t first, uint32_t count,
                          pn_batch_point *out);

/* The scramble of per-pixel sequence seq (not PN_EYE_SEQ_IAS_BLOCK) of full-image pixel (px, py). */
uint32_t pn_eye_sequence_scramble(const pn_render_job *job, pn_eye_sequence seq, int px, int py);
/* The scramble of sequence seq for batch pixel pi: the pixel's, or the batch's block's. */
uint32_t pn_batch_sequence_scramble(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq);
/* Samples first..first+count-1 of per-pixel sequence seq of full-image pixel (px, py), traced into
 * out[0..count): camera ray (pn_pixel_eye_sample), wavelengths (pn_eye_wavelengths, spectral mode,
 * not for ias's sequences), specular chain (pn_trace_eye_path_spectral), BSDF at the end point
 * (pn_bsdf_at_spectral). */
void pn_eye_hits_trace(const pn_render_job *job, int px, int py, pn_eye_sequence seq, uint32_t first, uint32_t count,
                       pn_eye_hit *out);
/* The standard pn_eye_hits_fn (every driver's): samples first..first+count-1 of batch pixel pi's
 * share of sequence seq, through the same tracer as pn_eye_hits_trace (for every sequence). */
void pn_batch_more_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq, uint32_t first,
                        uint32_t count, pn_eye_hit *out);
/* How many eye samples per pixel a driver traces in advance for a batch of count pixels whose
 * integrator asks for `asked`: asked, capped so that the batch holds at most PN_BATCH_HITS_MAX. */
uint32_t pn_batch_hits_in_advance(uint32_t asked, int count);
/* Traces per_pixel samples 0..per_pixel-1 of sequence PN_EYE_SEQ_PIXEL of each of count pixels
 * into out (count * per_pixel hits, pixel-major), as batch->hits holds them. */
void pn_batch_trace_hits(const pn_render_job *job, int count, const int32_t (*pixels)[2], uint32_t per_pixel,
                         pn_eye_hit *out);
/* Sets the standard tracers (pn_batch_more_hits, pn_batch_more_points) on *batch. */
void pn_batch_set_tracers(pn_batch *batch);
/* What a driver does for a batch of its own: traces in advance the eye samples the integrator
 * takes from every pixel, its batch_points into `points` (room for count * batch_points) and
 * samples 0.. of its batch_hits_seq into `hits` (room for count * pn_batch_hits_in_advance of
 * its batch_hits), and sets the standard tracers for every other sample. */
void pn_batch_supply(const pn_render_job *job, const pn_integrator *integ, pn_batch *batch, pn_batch_point *points,
                     pn_eye_hit *hits);
/* A batch of `count` of the window's pixels, with no samples in advance, that reads its eye
 * samples through the tracers of `from` (a driver's window or batch): what a whole-image
 * integrator builds for the parts of its window. */
pn_batch pn_batch_part(const pn_batch *from, int block_x, int block_y, int count, const int32_t (*pixels)[2]);
/* Samples first..first+count-1 of sequence seq of batch pixel pi, in index order: a pointer into
 * batch->hits when it holds the whole range, else buf (count hits) filled from batch->hits and
 * batch->more_hits (which is asked once, for the range's part past the in-advance hits). */
const pn_eye_hit *pn_batch_eye_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq,
                                    uint32_t first, uint32_t count, pn_eye_hit *buf);
/* The hit's wavelengths (NULL in RGB mode and for ias's RGB sequences) and its BSDF with them, as
 * pn_bsdf_at_spectral left it at the hit. */
const pn_swl *pn_eye_hit_wavelengths(const pn_render_job *job, const pn_eye_hit *hit);
void pn_eye_hit_bsdf(const pn_render_job *job, const pn_eye_hit *hit, pn_bsdf *out);

#endif
