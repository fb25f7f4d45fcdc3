/* progressive.h — the plumbing shared by the progressive drivers (issue 6): dcm (Guo 1998),
 * painter (Painter & Sloan 1989), uniform subsampling and the `full` baseline.
 *
 * A progressive render owns a work image (s x s the output window; the scene's camera set up at
 * s times the resolution). Drivers request work pixels; pn_prog_flush() evaluates the queued
 * pixels through the integrator's batch interface — grouped by their 8x8 block of the work image,
 * each group sorted by (y, x), groups spread over the thread pool — in chunks, and between chunks
 * fires the snapshots (percentages, every N seconds, on request) by asking the driver to
 * reconstruct its approximate work image, which is then filtered down with the Gaussian.
 * Evaluated pixels are kept and never overwritten. */
#ifndef PN_DRIVER_PROGRESSIVE_H
#define PN_DRIVER_PROGRESSIVE_H

#include "core/threadpool.h"
#include "render/batch.h"

#include <stdatomic.h>
#include <stdbool.h>

enum {
    PN_PX_NONE = 0,      /* nothing known */
    PN_PX_PREDICTED = 1, /* a value predicted by the DCM's elements (lazy boundary evaluation) */
    PN_PX_EVALUATED = 2, /* evaluated by the integrator */
    PN_PX_QUEUED = 4     /* flag: requested, not yet evaluated */
};

typedef struct pn_prog pn_prog;

/* dcm's albedo rays (dcm.c's header): how many of the integrator's eye rays, and the relative
 * albedo difference between neighbouring centre rays that marks a border for them. */
#define PN_PROG_ALBEDO_RAYS 16u
#define PN_PROG_ALBEDO_RAYS_BORDER 0.05f

/* Draws the driver's approximate work image into img (W*H RGB) and, when not NULL, its block map
 * (class and direction per work pixel; see PN_AOV_BLOCK_MAP). */
typedef void (*pn_prog_draw_fn)(pn_prog *p, void *driver, float *img, float *block_class, float *block_dir);

struct pn_prog {
    struct pn_context_s *ctx;
    const pn_render_settings *settings;
    const pn_integrator *integ;
    pn_render_job job; /* the camera at the work resolution */
    int scale;
    int W, H;               /* work window */
    int out_w, out_h;       /* output window */
    int wx0, wy0;           /* full-image coordinates of the work window's corner */
    float *rad;             /* W*H*3: what the drivers interpolate: evaluated or predicted radiance,
                          less the emitted part, divided by the demodulation factor */
    float *orig;            /* W*H*3: evaluated radiance as the integrator returned it */
    float *demod;           /* W*H*3: first-hit albedo factor (NULL: no demodulation) */
    float *emit;            /* W*H*3: radiance the primary rays saw emitted (with demod) */
    int primary_grid;       /* g: g x g primary rays per work pixel for demod and emit where the
                          pixel centres' values change */
    size_t primary_refined; /* pixels that got the g x g grid */
    bool integ_emitted;     /* the integrator reports each estimate's emitted part */
    uint32_t pixel_samples; /* the integrator's eye rays per pixel in pn_pixel_eye_sample's
                               convention (0: unknown); they replace the g x g grid */
    uint32_t albedo_rays;   /* dcm's albedo rays (issue 18): at albedo borders (found at
                               PN_PROG_ALBEDO_RAYS_BORDER) the first this many of the integrator's
                               eye rays replace the grid (0: off, the grid at 30% borders) */
    float *relvar;          /* W*H: relative variance s^2/L^2 of each evaluated pixel's estimate */
    unsigned char *state;
    size_t evaluated;
    int32_t (*queue)[2];
    size_t queue_len, queue_cap;
    pn_threadpool *pool;
    int workers;
    void **scratch;
    /* statistics per worker */
    struct prog_counters {
        uint64_t eye, shadow, spec, max_eye, max_shadow, non_finite;
        double embree;
        uint64_t extra; /* pixels evaluated by pn_prog_eval_now, not yet in `evaluated` */
    } * counters;
    atomic_int failed;
    bool stopped; /* stop_percent reached or cancelled */
    size_t stop_pixels;
    /* snapshots */
    double t0, next_time;
    double *percents;
    int percent_count, next_percent;
    /* --preview (issue 18) */
    double next_preview;
    float *preview_prev;   /* out_w*out_h*3: the previous preview (NULL before the first) */
    double preview_change; /* rel L1 between the last two previews: the error estimate */
    int preview_count;
    char preview_error[1100]; /* the first failure to write it */
    pn_prog_draw_fn draw;
    void *driver;
    void (*free_driver)(void *driver);
    pn_status snapshot_status;
    /* primary-ray buffer (object tags, visible lines), built on demand */
    int32_t *tag;
    float *depth;                   /* W*H: distance to the first hit of each centre ray (guided reconstruction) */
    vec3 *normal;                   /* W*H: its geometric normal (0 where nothing was hit) */
    uint32_t *sat_right, *sat_down; /* summed-area tables of discontinuities to the right/below */
    double primary_seconds;
    double reconstruct_seconds_max;
    float *work;                   /* W*H*3 reconstruction buffer */
    float *filter_tmp;             /* out_w*H*3: the Gaussian's horizontal pass */
    pn_render_stats *driver_stats; /* drivers add their counters here */
};

static inline size_t pn_prog_index(const pn_prog *p, int x, int y) {
    return (size_t)y * (size_t)p->W + (size_t)x;
}
static inline bool pn_prog_known(const pn_prog *p, int x, int y) {
    return (p->state[pn_prog_index(p, x, y)] & 3) == PN_PX_EVALUATED;
}
/* Rec. 709 luminance of a work pixel's stored value. */
float pn_prog_lum(const pn_prog *p, int x, int y);
/* Standard deviation of that luminance from the integrator's variance estimate (0 if unknown). */
float pn_prog_lum_sigma(const pn_prog *p, int x, int y);

/* Queues work pixel (x, y) (window coordinates) unless evaluated or queued. */
bool pn_prog_request(pn_prog *p, int x, int y);
/* Evaluates the queue (see above). Returns PN_ERROR_CANCELLED when cancelled, an error on
 * failure; when stop_percent is reached the queue is dropped and p->stopped is set. */
pn_status pn_prog_flush(pn_prog *p);
/* Evaluates one pixel right now, from inside a pn_prog_parallel job (its worker index). Returns
 * false on failure (recorded in p->failed). Thread-safe for distinct pixels. */
bool pn_prog_eval_now(pn_prog *p, int worker, int x, int y);
/* Adds the pixels evaluated by pn_prog_eval_now since the last call to p->evaluated. */
void pn_prog_collect_extra(pn_prog *p);
/* Runs fn over [0, n) on the thread pool. */
void pn_prog_parallel(pn_prog *p, size_t n, void (*fn)(void *user, size_t job, int worker), void *user);
/* Builds the primary-ray buffer: tags, visible-line tables and (unless settings->raw_radiance)
 * the demodulation factors. Must run before any pixel is evaluated. */
pn_status pn_prog_build_primary(pn_prog *p);
/* Whether a visible line (a change of object tag, a normal bend or a depth jump between two
 * 4-neighbours, both inside the rectangle) crosses [x0, x1] x [y0, y1] (inclusive). */
bool pn_prog_visible_line(const pn_prog *p, int x0, int y0, int x1, int y1);
/* Whether a visible line separates work pixel (x, y) from its right / lower neighbour. */
bool pn_prog_line_right(const pn_prog *p, int x, int y);
bool pn_prog_line_down(const pn_prog *p, int x, int y);
static inline float pn_prog_evaluated_percent(const pn_prog *p) {
    return (float)(100.0 * (double)p->evaluated / ((double)p->W * (double)p->H));
}

/* The drivers. */
pn_status pn_dcm_run(pn_prog *p, bool uniform_only);
pn_status pn_painter_run(pn_prog *p);

/* Entry point from pn_render for every driver except the default. */
pn_status pn_progressive_render(struct pn_context_s *ctx, const pn_render_settings *settings,
                                const pn_integrator *integ, const pn_render_job *job, pn_image *out_image,
                                pn_render_stats *stats);

#endif
