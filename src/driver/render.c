/* render.c — the default driver: the image window cut into 8x8 blocks (the IAS paper's block,
 * which also seeds each block's quasi-random sequence), blocks handed to worker threads by an
 * atomic counter, per-pixel estimates gathered into the film, AOVs, statistics. The image does
 * not depend on the thread count: every block is computed by one thread from its own seed.
 *
 * Split, checkpointed and MPI renders (issue 16, docs/distributed.md) go through the tiled mode
 * (run_tiled): the window cut into tiles of whole blocks aligned to the whole image
 * (driver/tiles.h), rendered one after the other over the pool, recorded in the checkpoint, or
 * handed out to MPI ranks (driver/mpi.c). The plain render is unchanged. */
#include "core/clock.h"
#include "core/context.h"
#include "core/threadpool.h"
#include "driver/progressive.h" /* issue 6: progressive drivers */
#include "driver/settings.h"
#include "driver/tiles.h" /* issue 16: tiles for MPI ranks, pieces and checkpoints */
#include "film/aovs.h"
#include "integrators/registry.h"
#include "io/image.h"
#include "render/progress.h"
#include "driver/points.h"

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
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
    uint32_t hits_per_pixel;             /* integrator->batch_hits, 0 when it traces its own */
    pn_eye_hit **batch_hits;             /* per worker: block_size^2 * hits_per_pixel hits, at most
                                            PN_BATCH_HITS_MAX (pn_batch_hits_in_advance) */
    /* Distributed, split or checkpointed renders (driver/tiles.h): the tiles, the blocks of the
     * tile being rendered (indices of the window's blocks), the pool, the checkpoint. */
    pn_tile_grid grid;
    int *tile_blocks;
    pn_threadpool *pool;
    pn_checkpoint *checkpoint;
    unsigned char *tile_done;
    pn_pixel_estimate *tile_pack; /* one packed tile, for the checkpoint */
    double progress_start;
    long tiles_rendered;
    pn_context ctx;
    const pn_method_entry *entry; /* the integrator's entry in the method table */
    pn_batch window;              /* a whole-image integrator's: the tracers of the window's eye samples */
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
    pn_batch batch = {.block_x = gx0 / B, .block_y = gy0 / B, .count = count, .pixels = (const int32_t(*)[2])pixels};
    /* The camera rays and specular chains every pixel of the block takes, traced once here in
     * advance; the integrator gets any others through the batch's tracers (render/batch.h). */
    pn_batch_supply(job, rs->integrator, &batch, rs->batch_points ? rs->batch_points[worker] : NULL,
                    rs->batch_hits ? rs->batch_hits[worker] : NULL);
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

static void render_tile_block(void *user, size_t index, int worker) {
    render_shared *rs = user;
    render_block(rs, (size_t)rs->tile_blocks[index], worker);
}

/* Renders one tile (driver/tiles.h) into rs->pixels and packs it into `packed` when not NULL:
 * its blocks over the pool, or for a whole-image integrator one call on the tile's window. A
 * tile that a cancel cut short is PN_ERROR_CANCELLED (never stored nor recorded). */
static pn_status render_tile(void *user, int tile, pn_pixel_estimate *packed) {
    render_shared *rs = user;
    const pn_render_job *job = rs->job;
    const int B = (int)job->block_size;
    int r[4];
    pn_tile_rect(&rs->grid, tile, r);
    const pn_camera *cam = &job->camera;
    if (atomic_load(job->cancel)) return PN_ERROR_CANCELLED;
    if (rs->integrator->render_image) {
        /* The tile is the integrator's window (illumcut: one point tree per tile). */
        pn_render_job tjob = *job;
        tjob.camera.x0 = r[0], tjob.camera.y0 = r[1], tjob.camera.x1 = r[2], tjob.camera.y1 = r[3];
        int tw = r[2] - r[0], th = r[3] - r[1];
        pn_pixel_estimate *buf = calloc((size_t)tw * (size_t)th, sizeof *buf);
        if (!buf) return PN_ERROR_OUT_OF_MEMORY;
        for (size_t i = 0; i < (size_t)tw * (size_t)th; i++) buf[i].depth = INFINITY;
        double span = (1.0 - rs->progress_start) / (double)rs->grid.count;
        pn_progress_window(job->progress, rs->progress_start + span * (double)rs->tiles_rendered,
                           rs->progress_start + span * (double)(rs->tiles_rendered + 1));
        pn_status st = rs->integrator->render_image(&tjob, rs->pool, &rs->window, buf, tw, th);
        if (st == PN_OK && atomic_load(job->cancel)) st = PN_ERROR_CANCELLED;
        if (st == PN_OK) pn_tile_copy_in(&rs->grid, tile, buf, rs->pixels);
        free(buf);
        if (st != PN_OK) return st;
    } else {
        int bx0 = r[0] / B - cam->x0 / B, bx1 = (r[2] - 1) / B - cam->x0 / B;
        int by0 = r[1] / B - cam->y0 / B, by1 = (r[3] - 1) / B - cam->y0 / B;
        int n = 0;
        for (int by = by0; by <= by1; by++)
            for (int bx = bx0; bx <= bx1; bx++) rs->tile_blocks[n++] = by * rs->blocks_x + bx;
        pn_threadpool_run(rs->pool, (size_t)n, render_tile_block, rs);
        int failed = atomic_load(&rs->failed);
        if (failed) return (pn_status)failed;
        for (int i = 0; i < n; i++)
            if (!rs->block_finished[rs->tile_blocks[i]]) return PN_ERROR_CANCELLED;
    }
    rs->tiles_rendered++;
    if (packed) pn_tile_copy_out(&rs->grid, tile, rs->pixels, packed);
    return PN_OK;
}

/* A finished tile: into the window (tiles from other ranks) and into the checkpoint. */
static pn_status store_tile(void *user, int tile, const pn_pixel_estimate *packed, bool local) {
    render_shared *rs = user;
    if (!local) pn_tile_copy_in(&rs->grid, tile, packed, rs->pixels);
    rs->tile_done[tile] = 1;
    if (!rs->checkpoint) return PN_OK;
    pn_err err;
    pn_err_init(&err);
    pn_status st = pn_checkpoint_append(rs->checkpoint, tile, packed, pn_tile_pixel_count(&rs->grid, tile), &err);
    return st == PN_OK ? PN_OK : pn_context_fail_from(rs->ctx, &err);
}

typedef struct tile_times {
    const pn_tile_grid *grid;
    const double *seconds;
} tile_times;

static pn_status write_tile_times(void *user, FILE *file, const char *path, pn_err *err) {
    const tile_times *tt = user;
    fprintf(file, "# tile x0 y0 x1 y1 seconds\n");
    for (int t = 0; t < tt->grid->count; t++) {
        int r[4];
        pn_tile_rect(tt->grid, t, r);
        fprintf(file, "%d %d %d %d %d %.6f\n", t, r[0], r[1], r[2], r[3], tt->seconds[t]);
    }
    return ferror(file) ? pn_err_set(err, PN_ERROR_IO, "%s: write failed", path) : PN_OK;
}

/* The tiles of one process, in order, skipping those the checkpoint holds; with tile-times, each
 * tile's render seconds written at the end (bench/mpi). */
static pn_status render_tiles_locally(render_shared *rs) {
    double *seconds = rs->job->tile_times_path ? calloc((size_t)rs->grid.count, sizeof *seconds) : NULL;
    pn_status st = PN_OK;
    for (int t = 0; t < rs->grid.count && st == PN_OK; t++) {
        if (rs->tile_done[t]) continue;
        double t0 = pn_clock_seconds();
        st = render_tile(rs, t, rs->checkpoint ? rs->tile_pack : NULL);
        if (seconds) seconds[t] = pn_clock_seconds() - t0;
        if (st == PN_OK) st = store_tile(rs, t, rs->tile_pack, true);
    }
    if (st == PN_OK && seconds) {
        tile_times tt = {&rs->grid, seconds};
        pn_err err;
        pn_err_init(&err);
        st = pn_write_atomic(rs->job->tile_times_path, write_tile_times, &tt, &err);
        if (st != PN_OK) pn_context_fail_from(rs->ctx, &err);
    }
    free(seconds);
    return st;
}

static void free_batches(render_shared *rs, int workers) {
    for (int w = 0; w <= workers; w++) {
        if (rs->batch_pixels) free(rs->batch_pixels[w]);
        if (rs->batch_estimates) free(rs->batch_estimates[w]);
        if (rs->batch_points) free(rs->batch_points[w]);
        if (rs->batch_hits) free(rs->batch_hits[w]);
    }
    free(rs->batch_pixels);
    free(rs->batch_estimates);
    free(rs->batch_points);
    free(rs->batch_hits);
    rs->batch_points = NULL;
    rs->batch_hits = NULL;
    rs->batch_pixels = NULL;
    rs->batch_estimates = NULL;
}

/* Resolves the settings (zero = default) into the job. */
pn_status pn_driver_resolve_settings(pn_context ctx, struct pn_scene_s *scene, const pn_render_settings *s,
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
    /* The melanopic EDI is integrated from spectra at sampled wavelengths (spectral/melanopic.h):
     * in spectral mode only, and by the integrators that declare it. */
    if ((s->aovs & PN_AOV_MELANOPIC_EDI) && !job->spectral)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "the melanopic_edi AOV needs spectral mode (the option spectral, --spectral): it is "
                               "integrated from the light's spectrum at sampled wavelengths, which RGB mode does not "
                               "carry");
    if ((s->aovs & PN_AOV_MELANOPIC_EDI) && !(integ->info.aovs & PN_AOV_MELANOPIC_EDI))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "integrator %s does not compute the melanopic_edi AOV",
                               integ->info.name);
    job->cancel = &ctx->cancel;
    return PN_OK;
}

static pn_status run_job(pn_context ctx, const pn_render_settings *settings, const pn_integrator *integ,
                         pn_render_job *job_in, pn_image *out_image, pn_render_stats *stats);

/* The tiling of a distributed, split or checkpointed render (docs/distributed.md): the tile side
 * in force, and for --piece K/M the piece's band of tile rows as the job's window. What cannot be
 * split is refused here, by capability: a driver without PN_CAP_DISTRIBUTED under MPI, and an
 * integrator without PN_CAP_CROP split without an explicit tile-size. */
static pn_status resolve_tiles(pn_context ctx, pn_render_job *job, const pn_method_entry *integ,
                               const pn_method_entry *driver) {
    bool ranks = pn_dist_size() > 1;
    if (ranks && !(driver->info.capabilities & PN_CAP_DISTRIBUTED))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "the %s driver does not run over MPI ranks: it picks every next pixel from the results "
                               "of all earlier ones over the whole image (one refinement order), which ranks rendering "
                               "tiles of their own cannot follow; run it in one process, without mpirun",
                               driver->info.name);
    if (!(driver->info.capabilities & PN_CAP_DISTRIBUTED)) return PN_OK;
    bool crop_exact = (integ->info.capabilities & PN_CAP_CROP) != 0;
    if (job->tile_size == 0 && (ranks || job->tiles_piece)) {
        if (!crop_exact)
            return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                                   "%s renders the window as one whole (%s), so its pixels change when the image is "
                                   "split over %s; give --tile-size N to render it as N x N tiles: a single process "
                                   "given the same --tile-size renders the identical image",
                                   integ->info.name, integ->info.description, ranks ? "MPI ranks" : "--piece pieces");
        job->tile_size = 64;
    }
    if (job->tile_size == 0 && (job->checkpoint_path || job->tile_times_path) && crop_exact) job->tile_size = 64;
    const uint32_t B = job->block_size;
    if (job->tile_size % B) job->tile_size += B - job->tile_size % B;
    if (!job->tiles_piece) return PN_OK;
    long k = 0, m = 0;
    char tail = 0;
    if (sscanf(job->tiles_piece, "%ld/%ld%c", &k, &m, &tail) != 2 || m < 1 || k < 1 || k > m)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "piece '%s': expected K/M with 1 <= K <= M (piece K of M), e.g. 3/8", job->tiles_piece);
    pn_camera *cam = &job->camera;
    pn_tile_grid g;
    pn_tile_grid_init(&g, cam->x0, cam->y0, cam->x1, cam->y1, (int)job->tile_size, false);
    if (m > g.tiles_y)
        return pn_context_fail(
            ctx, PN_ERROR_INVALID_ARGUMENT,
            "piece %ld/%ld: the window has only %d rows of %d-pixel tiles; give at most %d pieces or "
            "a smaller --tile-size",
            k, m, g.tiles_y, (int)job->tile_size, g.tiles_y);
    /* Piece k: tile rows [floor((k-1) R / M), floor(k R / M)); every row holds the same tiles. */
    long r0 = (k - 1) * g.tiles_y / m, r1 = k * g.tiles_y / m;
    int y0 = (g.ty0 + (int)r0) * (int)job->tile_size, y1 = (g.ty0 + (int)r1) * (int)job->tile_size;
    if (y0 > cam->y0) cam->y0 = y0;
    if (y1 < cam->y1) cam->y1 = y1;
    return PN_OK;
}

/* A crop's image remembers where it lies in the whole image (its EXR data window). */
static void pn_image_set_crop_window(pn_image image, const pn_camera *cam) {
    if (!image || image->width != cam->x1 - cam->x0 || image->height != cam->y1 - cam->y0) return;
    if (cam->x0 == 0 && cam->y0 == 0 && cam->x1 == cam->full_width && cam->y1 == cam->full_height) return;
    image->origin_x = cam->x0;
    image->origin_y = cam->y0;
    image->display_width = cam->full_width;
    image->display_height = cam->full_height;
}

pn_status pn_driver_prepare_job(pn_context ctx, struct pn_scene_s *scene, const pn_render_settings *settings,
                                const pn_method_entry *integ, const pn_method_entry *driver, pn_render_job *job,
                                pn_progress *progress) {
    pn_status st = pn_driver_resolve_settings(ctx, scene, settings, integ, driver, job);
    if (st == PN_OK) st = resolve_tiles(ctx, job, integ, driver);
    if (st != PN_OK) {
        atomic_store(&ctx->cancel, 0);
        return st;
    }
    /* One progress and cancel path from here on: the integrator's preparation reports into the
     * first window it picks, the driver's work into the rest. A cancel issued before this call
     * or during preparation is honoured; the request is cleared when the render returns. */
    pn_progress_init(progress, settings->progress, settings->progress_user, &ctx->cancel);
    job->progress = progress;
    if (integ->integrator->prepare) {
        pn_err perr;
        pn_err_init(&perr);
        st = integ->integrator->prepare(job, &perr);
        if (st != PN_OK) {
            pn_context_fail_from(ctx, &perr);
            /* The other ranks wait for this one's word before they hand out tiles. */
            if (pn_dist_size() > 1 && (driver->info.capabilities & PN_CAP_DISTRIBUTED)) pn_dist_start(ctx, st, 0);
            pn_progress_destroy(progress);
            atomic_store(&ctx->cancel, 0);
            return st;
        }
    }
    return PN_OK;
}

pn_status pn_render_settings_copy(pn_context ctx, const char *who, const pn_render_settings *in,
                                  pn_render_settings *out) {
    size_t size = in->struct_size ? in->struct_size : sizeof *out;
    if (size < sizeof *out)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "%s: settings.struct_size %zu is smaller than any layout of pn_render_settings (%zu)",
                               who, size, sizeof *out);
    /* A newer caller's fields beyond this layout must be at their defaults (zero). */
    for (size_t i = sizeof *out; i < size; i++)
        if (((const unsigned char *)in)[i] != 0)
            return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                                   "%s: settings set fields unknown to penumbra %s (struct_size %zu, known %zu)", who,
                                   PN_VERSION_STRING, size, sizeof *out);
    memcpy(out, in, sizeof *out);
    out->struct_size = (uint32_t)sizeof *out;
    return PN_OK;
}

/* What every finished or cancelled render's statistics hold besides the drivers' counters, and
 * which methods produced them (the by-name interface answers from the table for those). */
static void finish_stats(pn_stats stats, const struct pn_scene_s *scene, const pn_method_entry *integrator,
                         const pn_method_entry *driver, pn_status st) {
    if (!stats || (st != PN_OK && st != PN_ERROR_CANCELLED)) return;
    stats->fields.parse_seconds = scene->parse_seconds;
    stats->fields.bvh_seconds = scene->bvh_seconds;
    if (stats->fields.ranks < 1) stats->fields.ranks = 1;
    stats->integrator = pn_method_find(PN_METHOD_INTEGRATOR, integrator->info.name);
    stats->driver = pn_method_find(PN_METHOD_DRIVER, driver->info.name);
    stats->produced = true;
}

pn_status pn_render(pn_context ctx, pn_scene scene, const pn_render_settings *caller_settings, pn_image *out_image,
                    pn_stats stats_out) {
    if (out_image) *out_image = NULL;
    pn_render_stats *stats = NULL;
    if (stats_out) {
        memset(&stats_out->fields, 0, sizeof stats_out->fields);
        stats_out->integrator = stats_out->driver = -1;
        stats_out->produced = false;
        stats = &stats_out->fields;
    }
    if (!ctx || !scene || !caller_settings || !out_image) {
        if (ctx) pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_render: NULL argument");
        return PN_ERROR_INVALID_ARGUMENT;
    }
    pn_render_settings settings_copy;
    pn_status copied = pn_render_settings_copy(ctx, "pn_render", caller_settings, &settings_copy);
    if (copied != PN_OK) return copied;
    const pn_render_settings *settings = &settings_copy;
    /* The chosen methods are entries of the one table (integrators/registry.c). */
    const pn_method_entry *ientry = pn_registry_method_kind(PN_METHOD_INTEGRATOR, (int)settings->integrator);
    const pn_method_entry *dentry = pn_registry_method_kind(PN_METHOD_DRIVER, (int)settings->driver);
    if (!ientry)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown integrator %d", (int)settings->integrator);
    if (!dentry) return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown driver %d", (int)settings->driver);
    const pn_integrator *integ = ientry->integrator;
    pn_render_job job;
    pn_progress progress;
    pn_status st = pn_driver_prepare_job(ctx, scene, settings, ientry, dentry, &job, &progress);
    if (st != PN_OK) {
        finish_stats(stats_out, scene, ientry, dentry, st); /* cancelled before rendering: zeros */
        return st;
    }
    pn_progress_window(&progress, pn_progress_value(&progress), 1.0);
    /* Progressive drivers (issue 6: dcm, painter, uniform, full) render a work image of their own. */
    if (dentry->info.capabilities & PN_CAP_PROGRESSIVE)
        st = pn_progressive_render(ctx, settings, integ, &job, out_image, stats);
    else
        st = run_job(ctx, settings, integ, &job, out_image, stats);
    if (st == PN_OK && *out_image)
        pn_camera_film_apply(&job.camera, *out_image); /* iso, shutter, white balance, clamp */
    pn_image_set_crop_window(*out_image, &job.camera);
    if (st == PN_OK && integ->finish && !atomic_load(&ctx->cancel)) {
        pn_err ferr;
        pn_err_init(&ferr);
        st = integ->finish(&job, &ferr);
        if (st != PN_OK) {
            pn_context_fail_from(ctx, &ferr);
            pn_image_free(*out_image);
            *out_image = NULL;
        }
    }
    if (integ->release) integ->release(&job);
    pn_progress_destroy(&progress);
    atomic_store(&ctx->cancel, 0);
    finish_stats(stats_out, scene, ientry, dentry, st);
    return st;
}

/* The tiled mode (driver/tiles.h): the checkpoint opened (rank 0), the ranks agreed, then the
 * tiles rendered here or handed out to the MPI ranks. */
static pn_status run_tiled(pn_context ctx, render_shared *rs, pn_threadpool *pool, const pn_render_settings *settings,
                           pn_render_stats *stats) {
    const pn_render_job *job = rs->job;
    const pn_camera *cam = &job->camera;
    /* A whole-image integrator with crop-exact pixels (contour) renders each row as one whole:
     * its tiles are bands of whole rows of the window, so that every row is the plain render's. */
    const uint32_t caps = rs->entry->info.capabilities;
    pn_tile_grid_init(&rs->grid, cam->x0, cam->y0, cam->x1, cam->y1, (int)job->tile_size,
                      (caps & PN_CAP_WHOLE_IMAGE) && (caps & PN_CAP_CROP));
    rs->pool = pool;
    rs->ctx = ctx;
    rs->progress_start = pn_progress_value(job->progress);
    const int B = (int)job->block_size;
    size_t tile_blocks = (size_t)rs->block_count;
    if (job->tile_size > 0 && !rs->grid.bands)
        tile_blocks = (size_t)(job->tile_size / (uint32_t)B) * (job->tile_size / (uint32_t)B);
    rs->tile_blocks = malloc(tile_blocks * sizeof *rs->tile_blocks);
    rs->tile_done = calloc((size_t)rs->grid.count, 1);
    size_t max_pixels = 0;
    for (int t = 0; t < rs->grid.count; t++)
        if (pn_tile_pixel_count(&rs->grid, t) > max_pixels) max_pixels = pn_tile_pixel_count(&rs->grid, t);
    rs->tile_pack = malloc(max_pixels * sizeof *rs->tile_pack);
    pn_status st = rs->tile_blocks && rs->tile_done && rs->tile_pack ? PN_OK : PN_ERROR_OUT_OF_MEMORY;
    if (st != PN_OK) pn_context_fail(ctx, st, "out of memory for the tiles of a %dx%d image", rs->width, rs->height);
    uint64_t key = pn_render_key(job, settings, (int)settings->integrator, (int)settings->driver);
    int resumed = 0;
    if (st == PN_OK && job->checkpoint_path && pn_dist_rank() == 0) {
        pn_err err;
        pn_err_init(&err);
        st = pn_checkpoint_open(job->checkpoint_path, key, &rs->grid, rs->pixels, rs->tile_done, &resumed,
                                &rs->checkpoint, &err);
        if (st != PN_OK) pn_context_fail_from(ctx, &err);
        if (st == PN_OK && resumed)
            pn_context_log(ctx, PN_LOG_INFO, "resuming from %s: %d of %d tiles done", job->checkpoint_path, resumed,
                           rs->grid.count);
    }
    if (stats) {
        stats->tiles = (uint32_t)rs->grid.count;
        stats->tiles_resumed = (uint32_t)resumed;
    }
    if (pn_dist_size() <= 1) return st == PN_OK ? render_tiles_locally(rs) : st;
    st = pn_dist_start(ctx, st, key);
    if (st != PN_OK) return st;
    pn_tile_work work = {&rs->grid, render_tile, store_tile, rs, rs->tile_done, job->cancel, max_pixels, job->progress};
    pn_dist_report report;
    memset(&report, 0, sizeof report);
    st = pn_dist_run_tiles(ctx, &work, &report);
    if (stats && pn_dist_rank() == 0) {
        stats->ranks = report.ranks;
        for (int r = 0; r < report.ranks && r < PN_STATS_MAX_RANKS; r++) {
            stats->rank_busy_seconds[r] = report.busy_seconds[r];
            stats->rank_tiles[r] = report.tiles[r];
        }
    }
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
    rs.entry = pn_registry_integrator_entry(integ);
    pn_batch_set_tracers(&rs.window);
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
        rs.hits_per_pixel = integ->batch_hits && !integ->render_image ? integ->batch_hits(&job) : 0;
        /* A block of fewer pixels may take more per pixel, never more than this in all. */
        uint64_t hits_per_batch = (uint64_t)rs.hits_per_pixel * (uint64_t)(B * B);
        if (hits_per_batch > PN_BATCH_HITS_MAX) hits_per_batch = PN_BATCH_HITS_MAX;
        rs.batch_hits = hits_per_batch ? calloc((size_t)workers + 1, sizeof *rs.batch_hits) : NULL;
        batches_ok = rs.batch_pixels && rs.batch_estimates && (!rs.points_per_pixel || rs.batch_points) &&
                     (!hits_per_batch || rs.batch_hits);
        for (int w = 0; batches_ok && w <= workers; w++) {
            rs.batch_pixels[w] = malloc((size_t)B * (size_t)B * sizeof *rs.batch_pixels[w]);
            rs.batch_estimates[w] = malloc((size_t)B * (size_t)B * sizeof *rs.batch_estimates[w]);
            batches_ok = rs.batch_pixels[w] && rs.batch_estimates[w];
            if (batches_ok && rs.points_per_pixel) {
                rs.batch_points[w] = malloc((size_t)B * (size_t)B * rs.points_per_pixel * sizeof *rs.batch_points[w]);
                batches_ok = rs.batch_points[w] != NULL;
            }
            if (batches_ok && hits_per_batch) {
                rs.batch_hits[w] = malloc((size_t)hits_per_batch * sizeof *rs.batch_hits[w]);
                batches_ok = rs.batch_hits[w] != NULL;
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
    pn_status tiled_status = PN_OK;
    bool tiled = job.tile_size > 0 || job.checkpoint_path || job.tile_times_path || pn_dist_size() > 1;
    if (tiled) {
        tiled_status = run_tiled(ctx, &rs, pool, settings, stats);
        if (tiled_status == PN_ERROR_CANCELLED) tiled_status = PN_OK; /* a partial image, as below */
        if (tiled_status != PN_OK && !atomic_load(&rs.failed)) atomic_store(&rs.failed, (int)tiled_status);
    } else if (whole_image) {
        pn_status ws = whole_image(&job, pool, &rs.window, rs.pixels, rs.width, rs.height);
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
    pn_checkpoint_close(rs.checkpoint);
    free(rs.tile_blocks);
    free(rs.tile_pack);
    bool worker_rank = tiled && pn_dist_rank() != 0;
    if (tiled && pn_dist_size() > 1) {
        /* Every rank adds what its integrator counted (collective, also after a failure). */
        pn_render_stats local;
        memset(&local, 0, sizeof local);
        if (integ->report && !worker_rank && stats) integ->report(&job, stats);
        if (integ->report && worker_rank) integ->report(&job, &local);
        pn_dist_reduce_stats(worker_rank || !stats ? &local : stats);
    }
    if (failed || worker_rank) {
        free(rs.pixels);
        free(rs.block_finished);
        free(rs.tile_done);
        if (!failed) return PN_OK; /* a worker rank: rank 0 holds the image */
        return pn_context_fail(ctx, (pn_status)failed, "render failed: %s", pn_status_string((pn_status)failed));
    }
    bool cancelled = atomic_load(&ctx->cancel) != 0;
    if (cancelled && !tiled) {
        for (long b = 0; b < rs.block_count; b++)
            if (!rs.block_finished[b]) cancelled = true;
    }
    for (int t = 0; tiled && t < rs.grid.count; t++)
        if (!rs.tile_done[t]) cancelled = true;
    free(rs.tile_done);
    st = pn_film_assemble(rs.pixels, rs.width, rs.height, settings->aovs, out_image);
    if (st != PN_OK) {
        free(rs.pixels);
        free(rs.block_finished);
        return pn_context_fail(ctx, st, "out of memory for the output image");
    }
    uint64_t non_finite = 0;
    for (size_t i = 0; i < n; i++) non_finite += rs.pixels[i].non_finite;
    pn_film_warn_non_finite(ctx, non_finite, integ->name);
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
        stats->non_finite_samples = non_finite;
        stats->mrays_per_second =
            stats->render_seconds > 0.0 ? (double)(eye + shadow + spec) / stats->render_seconds * 1e-6 : 0.0;
        stats->peak_memory_bytes = pn_peak_memory_bytes();
        stats->partial = cancelled ? 1 : 0;
        stats->passes_per_pixel_mean = passes / (double)n;
        stats->aa_regions_per_pixel_mean = regions / (double)n;
        stats->clusters_per_point_mean = clusters / (double)n;
        stats->visible_fraction_mean = visible_rays ? visible / (double)visible_rays : 0.0;
        stats->visible_lights_per_pixel_mean = vis_lights / (double)n;
        if (integ->report && !(tiled && pn_dist_size() > 1)) integ->report(&job, stats);
        stats->threads = workers;
        stats->width = rs.width;
        stats->height = rs.height;
    }
    free(rs.pixels);
    free(rs.block_finished);
    if (cancelled) return pn_context_fail(ctx, PN_ERROR_CANCELLED, "render cancelled; the image is partial");
    return PN_OK;
}
