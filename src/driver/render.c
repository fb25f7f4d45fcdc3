/* render.c — the default driver: the image window cut into 8x8 blocks (the IAS paper's block,
 * which also seeds each block's quasi-random sequence), blocks handed to worker threads by an
 * atomic counter, per-pixel estimates gathered into the film, AOVs, statistics. The image does
 * not depend on the thread count: every block is computed by one thread from its own seed. */
#include "core/clock.h"
#include "core/context.h"
#include "core/threadpool.h"
#include "driver/progressive.h" /* issue 6: progressive drivers */
#include "film/aovs.h"
#include "integrators/registry.h"
#include "io/image.h"
#include "render/progress.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* The block side is the option block-size (registry.c): 8 by default (the IAS paper's 8x8
 * blocks), also the smallest allowed: ias pools statistics over a block, and below 8x8 that
 * biases it (tests/test_ias.c). */

typedef struct render_shared {
    const pn_render_job *job;
    const pn_integrator *integrator;
    pn_pixel_estimate *pixels; /* width * height of the window */
    int width, height, blocks_x, blocks_y;
    void **scratch; /* per worker */
    atomic_int failed;
    atomic_long blocks_done;
    long block_count;
    const pn_render_settings *settings;
    unsigned char *block_finished;
    int32_t (**batch_pixels)[2];         /* per worker: block_size^2 pixel coordinates */
    pn_pixel_estimate **batch_estimates; /* per worker: block_size^2 estimates */
    uint32_t points_per_pixel;           /* integrator->batch_points, 0 when it traces its own */
    pn_batch_point **batch_points;       /* per worker: block_size^2 * points_per_pixel points */
} render_shared;

static void render_block(void *user, size_t job_index, int worker) {
    render_shared *rs = user;
    const pn_render_job *job = rs->job;
    if (atomic_load(job->cancel) || atomic_load(&rs->failed)) return;
    int bx = (int)(job_index % (size_t)rs->blocks_x), by = (int)(job_index / (size_t)rs->blocks_x);
    const pn_camera *cam = &job->camera;
    const int B = (int)job->block_size;
    int32_t(*pixels)[2] = rs->batch_pixels[worker];
    pn_pixel_estimate *est = rs->batch_estimates[worker];
    int count = 0;
    /* Blocks are aligned to the full image so that a crop renders the same pixels as the whole
     * image would (renders of rectangles merge into the identical full image). */
    int gx0 = (cam->x0 / B + bx) * B, gy0 = (cam->y0 / B + by) * B;
    for (int y = gy0; y < gy0 + B; y++)
        for (int x = gx0; x < gx0 + B; x++) {
            if (x < cam->x0 || x >= cam->x1 || y < cam->y0 || y >= cam->y1) continue;
            pixels[count][0] = x;
            pixels[count][1] = y;
            count++;
        }
    if (count == 0) return;
    if (!rs->scratch[worker] && rs->integrator->scratch_create) {
        rs->scratch[worker] = rs->integrator->scratch_create(job);
        if (!rs->scratch[worker]) {
            atomic_store(&rs->failed, PN_ERROR_OUT_OF_MEMORY);
            return;
        }
    }
    pn_batch batch = {gx0 / B, gy0 / B, count, (const int32_t(*)[2])pixels, 0, NULL};
    if (rs->points_per_pixel > 0) {
        /* The camera rays and specular chains of the block, traced once here (render/batch.h). */
        pn_batch_trace_points(job, count, batch.pixels, rs->points_per_pixel, rs->batch_points[worker]);
        batch.points_per_pixel = rs->points_per_pixel;
        batch.points = rs->batch_points[worker];
    }
    pn_status st = rs->integrator->render_batch(job, &batch, est, rs->scratch[worker]);
    if (st != PN_OK) {
        atomic_store(&rs->failed, (int)st);
        return;
    }
    for (int i = 0; i < count; i++) {
        int x = pixels[i][0] - cam->x0, y = pixels[i][1] - cam->y0;
        rs->pixels[(size_t)y * (size_t)rs->width + (size_t)x] = est[i];
    }
    rs->block_finished[job_index] = 1;
    long done = atomic_fetch_add(&rs->blocks_done, 1) + 1;
    pn_progress_report(job->progress, (double)done / (double)rs->block_count);
}

static void free_batches(render_shared *rs, int workers) {
    for (int w = 0; w <= workers; w++) {
        if (rs->batch_pixels) free(rs->batch_pixels[w]);
        if (rs->batch_estimates) free(rs->batch_estimates[w]);
        if (rs->batch_points) free(rs->batch_points[w]);
    }
    free(rs->batch_pixels);
    free(rs->batch_estimates);
    free(rs->batch_points);
    rs->batch_points = NULL;
    rs->batch_pixels = NULL;
    rs->batch_estimates = NULL;
}

/* Resolves the settings (zero = default) into the job. */
static pn_status resolve_settings(pn_context ctx, struct pn_scene_s *scene, const pn_render_settings *s,
                                  const pn_method_entry *integ, const pn_method_entry *driver, pn_render_job *job) {
    memset(job, 0, sizeof *job);
    job->scene = scene;
    job->accel = scene->accel;
    job->lights = scene->lights;
    int w = s->width > 0 ? s->width : scene->camera.width;
    int h = s->height > 0 ? s->height : scene->camera.height;
    if (s->width < 0 || s->height < 0 || w <= 0 || h <= 0 || w > 65536 || h > 65536)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "image resolution %dx%d is out of range (1..65536)", w,
                               h);
    float crop[4];
    if (s->has_crop)
        memcpy(crop, s->crop, sizeof crop);
    else
        memcpy(crop, scene->camera.crop, sizeof crop);
    for (int i = 0; i < 4; i++)
        if (!(crop[i] >= 0.0f && crop[i] <= 1.0f))
            return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "crop window values must lie in [0, 1]");
    if (!(crop[0] < crop[1] && crop[2] < crop[3]))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "crop window is empty (need x0 < x1 and y0 < y1)");
    if (!pn_camera_setup(&scene->camera, w, h, crop, &job->camera))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "crop window covers no pixel");
    if (s->threads < 0 || s->threads > PN_MAX_THREADS)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "threads %d is out of range (0 = all cores, at most %d)",
                               s->threads, PN_MAX_THREADS);
    if (s->threshold < 0.0 || !isfinite(s->threshold))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "threshold must be a positive number");
    /* Every method option (the table in integrators/registry.c) into its job field. */
    pn_status st = pn_registry_resolve(ctx, s, integ, driver, job);
    if (st != PN_OK) return st;
    job->spp = s->spp;
    /* Neither spp nor threshold: the method's default eye-ray count (reference: a fixed 64, which
     * reaches a given relMSE faster than the threshold mode on every bench scene,
     * docs/adaptive-sampling.md); 0 keeps it adaptive (ias). */
    if (s->spp == 0 && s->threshold == 0.0 && (integ->info.capabilities & PN_CAP_THRESHOLD))
        job->spp = integ->info.default_spp;
    job->threshold = s->threshold > 0.0 ? s->threshold : 0.01;
    /* adaptive-rule auto: cross for the reference (unbiased, and faster than the paper's rule at
     * equal relMSE on the bench scenes); for ias its own test, which its cross variant did not
     * beat (docs/adaptive-sampling.md). */
    if (job->adaptive_rule == PN_ADAPTIVE_AUTO)
        job->adaptive_rule = integ->integrator == &pn_integrator_ias ? PN_ADAPTIVE_PAPER : PN_ADAPTIVE_CROSS;
    /* vpl-depth not given: the scene's Integrator "maxdepth" (pbrt-v4 counts the camera segment,
     * so maxdepth - 1 bounces), else the declared default. */
    bool depth_given = pn_options_is_set(s->options, pn_option_find("vpl-depth"));
    if (job->vpl_direct_only && depth_given)
        return pn_context_fail(
            ctx, PN_ERROR_INVALID_ARGUMENT,
            "vpl-direct-only and vpl-depth exclude each other: direct light has no light path bounces");
    if (!depth_given) job->vpl_max_depth = pn_scene_vpl_depth(scene, job->vpl_max_depth);
    /* A scene whose Integrator "maxdepth" is 1 asks for direct lighting (pbrt-v4's meaning): the
     * VPL integrators then render the direct-light-only VPL set, the quantity of reference. */
    if (job->vpl_max_depth == 0) job->vpl_direct_only = true;
    /* Direct light only: no bounces, and no clamp unless asked for (reference has none). */
    if (job->vpl_direct_only) {
        job->vpl_max_depth = 0;
        if (!pn_options_is_set(s->options, pn_option_find("vpl-clamp"))) job->vpl_clamp_fraction = 0.0f;
    }
    job->max_specular_depth = s->max_specular_depth > 0 ? s->max_specular_depth : 8;
    job->seed = s->seed;
    job->aovs = s->aovs;
    job->cancel = &ctx->cancel;
    return PN_OK;
}

static pn_status run_job(pn_context ctx, const pn_render_settings *settings, const pn_integrator *integ,
                         pn_render_job *job_in, pn_image *out_image, pn_render_stats *stats);

pn_status pn_render(pn_context ctx, pn_scene scene, const pn_render_settings *settings, pn_image *out_image,
                    pn_render_stats *stats) {
    if (out_image) *out_image = NULL;
    if (stats) memset(stats, 0, sizeof *stats);
    if (!ctx || !scene || !settings || !out_image) {
        if (ctx) pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_render: NULL argument");
        return PN_ERROR_INVALID_ARGUMENT;
    }
    /* The chosen methods are entries of the one table (integrators/registry.c). */
    const pn_method_entry *ientry = pn_registry_method_kind(PN_METHOD_INTEGRATOR, (int)settings->integrator);
    const pn_method_entry *dentry = pn_registry_method_kind(PN_METHOD_DRIVER, (int)settings->driver);
    if (!ientry)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown integrator %d", (int)settings->integrator);
    if (!dentry) return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown driver %d", (int)settings->driver);
    const pn_integrator *integ = ientry->integrator;
    pn_render_job job;
    pn_status st = resolve_settings(ctx, scene, settings, ientry, dentry, &job);
    if (st != PN_OK) {
        atomic_store(&ctx->cancel, 0);
        return st;
    }
    /* One progress and cancel path from here on: the integrator's preparation reports into the
     * first window it picks, the driver's work into the rest. A cancel issued before this call
     * or during preparation is honoured; the request is cleared when the render returns. */
    pn_progress progress;
    pn_progress_init(&progress, settings->progress, settings->progress_user, &ctx->cancel);
    job.progress = &progress;
    if (integ->prepare) {
        pn_err perr;
        pn_err_init(&perr);
        st = integ->prepare(&job, &perr);
        if (st != PN_OK) {
            pn_progress_destroy(&progress);
            atomic_store(&ctx->cancel, 0);
            return pn_context_fail_from(ctx, &perr);
        }
    }
    pn_progress_window(&progress, pn_progress_value(&progress), 1.0);
    /* Progressive drivers (issue 6: dcm, painter, uniform, full) render a work image of their own. */
    if (dentry->info.capabilities & PN_CAP_PROGRESSIVE)
        st = pn_progressive_render(ctx, settings, integ, &job, out_image, stats);
    else
        st = run_job(ctx, settings, integ, &job, out_image, stats);
    if (st == PN_OK) pn_camera_film_apply(&job.camera, *out_image); /* iso, shutter, white balance, clamp */
    if (integ->release) integ->release(&job);
    pn_progress_destroy(&progress);
    atomic_store(&ctx->cancel, 0);
    return st;
}

/* Renders a prepared job: blocks over the thread pool, then the image and the statistics. */
static pn_status run_job(pn_context ctx, const pn_render_settings *settings, const pn_integrator *integ,
                         pn_render_job *job_in, pn_image *out_image, pn_render_stats *stats) {
    pn_render_job job = *job_in;
    pn_status st;

    render_shared rs;
    memset(&rs, 0, sizeof rs);
    rs.job = &job;
    rs.integrator = integ;
    rs.settings = settings;
    rs.width = job.camera.x1 - job.camera.x0;
    rs.height = job.camera.y1 - job.camera.y0;
    const int B = (int)job.block_size;
    rs.blocks_x = (job.camera.x1 - 1) / B - job.camera.x0 / B + 1;
    rs.blocks_y = (job.camera.y1 - 1) / B - job.camera.y0 / B + 1;
    rs.block_count = (long)rs.blocks_x * rs.blocks_y;
    size_t n = (size_t)rs.width * (size_t)rs.height;
    rs.pixels = calloc(n, sizeof *rs.pixels);
    rs.block_finished = calloc((size_t)rs.block_count, 1);
    pn_threadpool *pool = pn_threadpool_create(settings->threads);
    const int pool_errno = pool ? 0 : errno;
    int workers = pool ? pn_threadpool_size(pool) : 0;
    rs.scratch = pool ? calloc((size_t)workers + 1, sizeof *rs.scratch) : NULL;
    bool batches_ok = pool != NULL;
    if (pool) {
        rs.batch_pixels = calloc((size_t)workers + 1, sizeof *rs.batch_pixels);
        rs.batch_estimates = calloc((size_t)workers + 1, sizeof *rs.batch_estimates);
        /* Whole-image integrators take no batches here, so no points either. */
        rs.points_per_pixel = integ->batch_points && !integ->render_image ? integ->batch_points(&job) : 0;
        rs.batch_points = rs.points_per_pixel ? calloc((size_t)workers + 1, sizeof *rs.batch_points) : NULL;
        batches_ok = rs.batch_pixels && rs.batch_estimates && (!rs.points_per_pixel || rs.batch_points);
        for (int w = 0; batches_ok && w <= workers; w++) {
            rs.batch_pixels[w] = malloc((size_t)B * (size_t)B * sizeof *rs.batch_pixels[w]);
            rs.batch_estimates[w] = malloc((size_t)B * (size_t)B * sizeof *rs.batch_estimates[w]);
            batches_ok = rs.batch_pixels[w] && rs.batch_estimates[w];
            if (batches_ok && rs.points_per_pixel) {
                rs.batch_points[w] = malloc((size_t)B * (size_t)B * rs.points_per_pixel * sizeof *rs.batch_points[w]);
                batches_ok = rs.batch_points[w] != NULL;
            }
        }
    }
    if (!rs.pixels || !rs.block_finished || !pool || !rs.scratch || !batches_ok) {
        free(rs.pixels);
        free(rs.block_finished);
        free(rs.scratch);
        free_batches(&rs, workers);
        pn_threadpool_destroy(pool);
        if (!pool && pool_errno != ENOMEM)
            return pn_context_fail(ctx, PN_ERROR_IO, "cannot start the worker threads: %s", strerror(pool_errno));
        return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", rs.width, rs.height);
    }
    for (size_t i = 0; i < n; i++) rs.pixels[i].depth = INFINITY;
    atomic_init(&rs.failed, 0);
    atomic_init(&rs.blocks_done, 0);
    double t0 = pn_clock_seconds();
    /* Integrators with a whole-image hook (illumcut's point tree, contour's scanlines) render
     * the window in one call. */
    pn_render_image_fn whole_image = integ->render_image;
    if (whole_image) {
        pn_status ws = whole_image(&job, pool, rs.pixels, rs.width, rs.height);
        if (ws != PN_OK)
            atomic_store(&rs.failed, (int)ws);
        else
            memset(rs.block_finished, 1, (size_t)rs.block_count);
        if (ws == PN_OK && !atomic_load(&ctx->cancel)) {
            pn_progress_phase(job.progress, 0.0, 1.0);
            pn_progress_report(job.progress, 1.0);
        }
    } else {
        pn_threadpool_run(pool, (size_t)rs.block_count, render_block, &rs);
    }
    double t1 = pn_clock_seconds();
    for (int w = 0; w <= workers; w++)
        if (rs.scratch[w] && integ->scratch_free) integ->scratch_free(rs.scratch[w]);
    free(rs.scratch);
    free_batches(&rs, workers);
    pn_threadpool_destroy(pool);

    int failed = atomic_load(&rs.failed);
    if (failed) {
        free(rs.pixels);
        free(rs.block_finished);
        return pn_context_fail(ctx, (pn_status)failed, "render failed: %s", pn_status_string((pn_status)failed));
    }
    bool cancelled = atomic_load(&ctx->cancel) != 0;
    if (cancelled) {
        for (long b = 0; b < rs.block_count; b++)
            if (!rs.block_finished[b]) cancelled = true;
    }
    st = pn_film_assemble(rs.pixels, rs.width, rs.height, settings->aovs, out_image);
    if (st != PN_OK) {
        free(rs.pixels);
        free(rs.block_finished);
        return pn_context_fail(ctx, st, "out of memory for the output image");
    }
    if (stats) {
        uint64_t eye = 0, shadow = 0, spec = 0, max_eye = 0, max_shadow = 0;
        double cut_seconds = 0.0, pdf_seconds = 0.0;
        double embree_seconds = 0.0, passes = 0.0, regions = 0.0, clusters = 0.0, visible = 0.0, vis_lights = 0.0;
        uint64_t visible_rays = 0;
        for (size_t i = 0; i < n; i++) {
            const pn_pixel_estimate *e = &rs.pixels[i];
            eye += e->eye_rays;
            shadow += e->shadow_rays;
            spec += e->specular_rays;
            embree_seconds += (double)e->embree_seconds;
            cut_seconds += (double)e->cut_seconds;
            pdf_seconds += (double)e->pdf_seconds;
            passes += (double)e->passes;
            vis_lights += (double)e->visible_lights;
            regions += (double)e->aa_regions;
            clusters += (double)e->clusters;
            visible += (double)e->visible_fraction * (double)e->shadow_rays;
            visible_rays += e->shadow_rays;
            if (e->eye_rays > max_eye) max_eye = e->eye_rays;
            if (e->shadow_rays > max_shadow) max_shadow = e->shadow_rays;
        }
        stats->render_seconds = t1 - t0;
        /* Summed over threads: divide by the worker count to compare with wall-clock time. */
        stats->embree_seconds_estimate = embree_seconds / (double)(workers > 0 ? workers : 1);
        stats->cut_seconds_estimate = cut_seconds / (double)(workers > 0 ? workers : 1);
        stats->pdf_seconds_estimate = pdf_seconds / (double)(workers > 0 ? workers : 1);
        stats->eye_rays = eye;
        stats->shadow_rays = shadow;
        stats->specular_rays = spec;
        stats->eye_rays_per_pixel_mean = (double)eye / (double)n;
        stats->shadow_rays_per_pixel_mean = (double)shadow / (double)n;
        stats->eye_rays_per_pixel_max = max_eye;
        stats->shadow_rays_per_pixel_max = max_shadow;
        stats->mrays_per_second =
            stats->render_seconds > 0.0 ? (double)(eye + shadow + spec) / stats->render_seconds * 1e-6 : 0.0;
        stats->peak_memory_bytes = pn_peak_memory_bytes();
        stats->partial = cancelled ? 1 : 0;
        stats->passes_per_pixel_mean = passes / (double)n;
        stats->aa_regions_per_pixel_mean = regions / (double)n;
        stats->clusters_per_point_mean = clusters / (double)n;
        stats->visible_fraction_mean = visible_rays ? visible / (double)visible_rays : 0.0;
        stats->visible_lights_per_pixel_mean = vis_lights / (double)n;
        if (integ->report) integ->report(&job, stats);
        stats->threads = workers;
        stats->width = rs.width;
        stats->height = rs.height;
    }
    free(rs.pixels);
    free(rs.block_finished);
    if (cancelled) return pn_context_fail(ctx, PN_ERROR_CANCELLED, "render cancelled; the image is partial");
    return PN_OK;
}
