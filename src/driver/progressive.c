/* progressive.c — work image, batch evaluation, snapshots and output of the progressive drivers
 * (see progressive.h), and the `full` baseline driver: every work pixel evaluated in 8x8 blocks
 * and filtered down with the same Gaussian, so that a progressive driver that has evaluated every
 * pixel reproduces it bit for bit (the reference integrator's pixels do not depend on their batch).
 *
 * Batches: a chunk of queued pixels is sorted by 8x8 work block and then (y, x); each block's
 * pixels form one batch. Chunks end at the snapshot percentages and at stop_percent, so with a
 * block-adaptive integrator (ias) the batch composition, and with it the pixel values, depend on
 * those settings (never on the thread count); the reference integrator is unaffected. */
#include "driver/progressive.h"

#include "core/clock.h"
#include "core/context.h"
#include "core/rng.h"
#include "driver/dcm.h"
#include "film/aovs.h"
#include "film/downsample.h"
#include "integrators/registry.h"
#include "io/image.h"
#include "render/progress.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define PN_PROG_BLOCK 8
/* The primary-ray buffer's share of the progress bar (fixed); evaluation has the rest. */
#define PN_PROG_PRIMARY_SHARE 0.05

void pn_render_request_snapshot(pn_context ctx) {
    if (ctx) atomic_store(&ctx->snapshot_request, 1);
}

float pn_prog_lum(const pn_prog *p, int x, int y) {
    const float *c = p->rad + 3 * pn_prog_index(p, x, y);
    return v3_luminance(v3(c[0], c[1], c[2]));
}

float pn_prog_lum_sigma(const pn_prog *p, int x, int y) {
    size_t i = pn_prog_index(p, x, y);
    float rv = p->relvar[i];
    if (!(rv > 0.0f)) return 0.0f;
    /* The variance is relative to the whole estimate, emission included; in the units of rad. */
    const float *c = p->orig + 3 * i, *f = p->demod ? p->demod + 3 * i : NULL;
    vec3 v = f ? v3(c[0] / f[0], c[1] / f[1], c[2] / f[2]) : v3(c[0], c[1], c[2]);
    return sqrtf(rv) * fabsf(v3_luminance(v));
}

bool pn_prog_request(pn_prog *p, int x, int y) {
    size_t i = pn_prog_index(p, x, y);
    if ((p->state[i] & 3) == PN_PX_EVALUATED || (p->state[i] & PN_PX_QUEUED)) return true;
    if (p->queue_len == p->queue_cap) {
        size_t cap = p->queue_cap ? 2 * p->queue_cap : 1024;
        void *q = realloc(p->queue, cap * sizeof *p->queue);
        if (!q) return false;
        p->queue = q;
        p->queue_cap = cap;
    }
    p->queue[p->queue_len][0] = x;
    p->queue[p->queue_len][1] = y;
    p->queue_len++;
    p->state[i] |= PN_PX_QUEUED;
    return true;
}

static bool ensure_scratch(pn_prog *p, int worker) {
    if (!p->scratch[worker] && p->integ->scratch_create) {
        p->scratch[worker] = p->integ->scratch_create(&p->job);
        if (!p->scratch[worker]) {
            atomic_store(&p->failed, PN_ERROR_OUT_OF_MEMORY);
            return false;
        }
    }
    return true;
}

/* Stores estimates of a batch (window coordinates in px) and counts them. */
static void store_estimates(pn_prog *p, int worker, const int32_t (*px)[2], const pn_pixel_estimate *est, int n) {
    struct prog_counters *c = &p->counters[worker];
    for (int i = 0; i < n; i++) {
        size_t k = pn_prog_index(p, px[i][0], px[i][1]);
        p->orig[3 * k] = est[i].radiance.x;
        p->orig[3 * k + 1] = est[i].radiance.y;
        p->orig[3 * k + 2] = est[i].radiance.z;
        if (p->demod) {
            /* The integrator's own split where it reports one: the primary rays' estimate of the
             * emitted part would leave a residual at emitter borders that interpolation spreads. */
            const float *e = p->emit + 3 * k;
            vec3 em = p->integ_emitted ? est[i].emitted : v3(e[0], e[1], e[2]);
            p->rad[3 * k] = (p->orig[3 * k] - em.x) / p->demod[3 * k];
            p->rad[3 * k + 1] = (p->orig[3 * k + 1] - em.y) / p->demod[3 * k + 1];
            p->rad[3 * k + 2] = (p->orig[3 * k + 2] - em.z) / p->demod[3 * k + 2];
        } else {
            for (int ch = 0; ch < 3; ch++) p->rad[3 * k + ch] = p->orig[3 * k + ch];
        }
        p->state[k] = PN_PX_EVALUATED;
        p->relvar[k] = isfinite(est[i].relative_variance) ? est[i].relative_variance : 0.0f;
        c->eye += est[i].eye_rays;
        c->shadow += est[i].shadow_rays;
        c->non_finite += est[i].non_finite;
        c->spec += est[i].specular_rays;
        c->embree += (double)est[i].embree_seconds;
        if (est[i].eye_rays > c->max_eye) c->max_eye = est[i].eye_rays;
        if (est[i].shadow_rays > c->max_shadow) c->max_shadow = est[i].shadow_rays;
    }
}

/* Evaluates up to 64 window pixels of one 8x8 work block (already sorted). */
static bool eval_block_pixels(pn_prog *p, int worker, const int32_t (*px)[2], int n) {
    if (n <= 0) return true;
    if (!ensure_scratch(p, worker)) return false;
    int32_t full[PN_PROG_BLOCK * PN_PROG_BLOCK][2];
    pn_pixel_estimate est[PN_PROG_BLOCK * PN_PROG_BLOCK];
    for (int i = 0; i < n; i++) {
        full[i][0] = px[i][0] + p->wx0;
        full[i][1] = px[i][1] + p->wy0;
    }
    pn_batch batch = {.block_x = full[0][0] / PN_PROG_BLOCK,
                      .block_y = full[0][1] / PN_PROG_BLOCK,
                      .count = n,
                      .pixels = (const int32_t(*)[2])full};
    /* The eye samples every pixel of the batch takes, traced here in advance (render/batch.h),
     * and the tracers of the others. */
    uint32_t per_pixel = p->integ->batch_points ? p->integ->batch_points(&p->job) : 0;
    uint32_t per_hit = p->integ->batch_hits ? pn_batch_hits_in_advance(p->integ->batch_hits(&p->job), n) : 0;
    pn_batch_point *points = per_pixel ? malloc((size_t)n * per_pixel * sizeof *points) : NULL;
    pn_eye_hit *hits = per_hit ? malloc((size_t)n * per_hit * sizeof *hits) : NULL;
    if ((per_pixel && !points) || (per_hit && !hits)) {
        free(points);
        free(hits);
        atomic_store(&p->failed, (int)PN_ERROR_OUT_OF_MEMORY);
        return false;
    }
    pn_batch_supply(&p->job, p->integ, &batch, points, hits);
    memset(est, 0, (size_t)n * sizeof *est);
    pn_status st = p->integ->render_batch(&p->job, &batch, est, p->scratch[worker]);
    free(points);
    free(hits);
    if (st != PN_OK) {
        atomic_store(&p->failed, (int)st);
        return false;
    }
    store_estimates(p, worker, px, est, n);
    return true;
}

bool pn_prog_eval_now(pn_prog *p, int worker, int x, int y) {
    if ((p->state[pn_prog_index(p, x, y)] & 3) == PN_PX_EVALUATED) return true;
    if (atomic_load(&p->failed)) return false;
    int32_t px[1][2] = {{x, y}};
    if (!eval_block_pixels(p, worker, (const int32_t(*)[2])px, 1)) return false;
    p->counters[worker].extra++; /* added to p->evaluated by pn_prog_collect_extra */
    return true;
}

void pn_prog_collect_extra(pn_prog *p) {
    for (int w = 0; w <= p->workers; w++) {
        p->evaluated += p->counters[w].extra;
        p->counters[w].extra = 0;
    }
}

void pn_prog_parallel(pn_prog *p, size_t n, void (*fn)(void *user, size_t job, int worker), void *user) {
    pn_threadpool_run(p->pool, n, fn, user);
}

/* ---- chunks ---- */

typedef struct chunk_item {
    uint64_t key;
    int32_t xy[2];
} chunk_item;

typedef struct chunk_run {
    pn_prog *p;
    chunk_item *items;
    size_t *group_start; /* group g = items[group_start[g], group_start[g + 1]) */
} chunk_run;

static int cmp_chunk_item(const void *a, const void *b) {
    uint64_t ka = ((const chunk_item *)a)->key, kb = ((const chunk_item *)b)->key;
    return ka < kb ? -1 : ka > kb;
}

static void chunk_group_job(void *user, size_t g, int worker) {
    chunk_run *cr = user;
    pn_prog *p = cr->p;
    if (atomic_load(&p->failed) || atomic_load(p->job.cancel)) return;
    int32_t px[PN_PROG_BLOCK * PN_PROG_BLOCK][2];
    int n = 0;
    for (size_t i = cr->group_start[g]; i < cr->group_start[g + 1]; i++) {
        px[n][0] = cr->items[i].xy[0];
        px[n][1] = cr->items[i].xy[1];
        n++;
    }
    eval_block_pixels(p, worker, (const int32_t(*)[2])px, n);
}

static pn_status eval_chunk(pn_prog *p, const int32_t (*px)[2], size_t n) {
    chunk_item *items = malloc(n * sizeof *items);
    size_t *starts = malloc((n + 1) * sizeof *starts);
    if (!items || !starts) {
        free(items);
        free(starts);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    uint64_t bw = (uint64_t)((p->wx0 + p->W - 1) / PN_PROG_BLOCK + 1);
    for (size_t i = 0; i < n; i++) {
        int gx = px[i][0] + p->wx0, gy = px[i][1] + p->wy0;
        uint64_t block = (uint64_t)(gy / PN_PROG_BLOCK) * bw + (uint64_t)(gx / PN_PROG_BLOCK);
        items[i].key = (block << 8) | (uint64_t)((gy % PN_PROG_BLOCK) * PN_PROG_BLOCK + gx % PN_PROG_BLOCK);
        items[i].xy[0] = px[i][0];
        items[i].xy[1] = px[i][1];
    }
    qsort(items, n, sizeof *items, cmp_chunk_item);
    size_t groups = 0;
    for (size_t i = 0; i < n; i++)
        if (i == 0 || (items[i].key >> 8) != (items[i - 1].key >> 8)) starts[groups++] = i;
    starts[groups] = n;
    chunk_run cr = {p, items, starts};
    pn_threadpool_run(p->pool, groups, chunk_group_job, &cr);
    free(items);
    free(starts);
    int failed = atomic_load(&p->failed);
    if (failed) return (pn_status)failed;
    p->evaluated += n;
    return PN_OK;
}

/* ---- snapshots and output ---- */

static pn_status make_image(pn_prog *p, pn_image *out);

static void fire_snapshot(pn_prog *p, double requested) {
    if (!p->settings->snapshot) return;
    pn_image img = NULL;
    double t0 = pn_clock_seconds();
    pn_status st = make_image(p, &img);
    if (st != PN_OK) {
        p->snapshot_status = st;
        return;
    }
    double now = pn_clock_seconds();
    if (now - t0 > p->reconstruct_seconds_max) p->reconstruct_seconds_max = now - t0;
    p->settings->snapshot(p->settings->snapshot_user, img, requested, (double)pn_prog_evaluated_percent(p),
                          now - p->t0);
    pn_image_free(img);
}

/* --preview: the approximate image rewritten atomically (pn_image_write_file goes through
 * pn_write_atomic), so that a viewer reloading the file never reads half of it. Between two
 * previews the relative L1 change of the image is the estimate of the error that remains (the
 * image converges to the full render; what changed in the last interval bounds from below what
 * is still to change) and goes to the log with the percentage of evaluated work pixels. */
static void write_preview(pn_prog *p) {
    pn_image img = NULL;
    if (make_image(p, &img) != PN_OK) {
        p->snapshot_status = PN_ERROR_OUT_OF_MEMORY;
        return;
    }
    const float *v = pn_image_layer_data(img, 0);
    size_t n = 3 * (size_t)p->out_w * (size_t)p->out_h;
    if (!p->preview_prev)
        p->preview_prev = malloc(n * sizeof *p->preview_prev);
    else {
        double diff = 0.0, sum = 0.0;
        for (size_t i = 0; i < n; i++) {
            diff += fabs((double)v[i] - (double)p->preview_prev[i]);
            sum += fabs((double)v[i]);
        }
        p->preview_change = sum > 0.0 ? diff / sum : 0.0;
    }
    if (p->preview_prev) memcpy(p->preview_prev, v, n * sizeof *v);
    pn_err err = {0};
    pn_status st = pn_image_write_file(img, p->job.preview, 0.0f, &err);
    pn_image_free(img);
    if (st != PN_OK) {
        if (p->snapshot_status == PN_OK) {
            p->snapshot_status = st;
            snprintf(p->preview_error, sizeof p->preview_error, "cannot write the preview: %s", err.message);
        }
        return;
    }
    p->preview_count++;
    if (p->settings->progress_note) return; /* the progress bar shows it */
    pn_context_log(p->ctx, PN_LOG_INFO, "preview %s: %.2f%% of the work pixels, estimated error (change) %.4f",
                   p->job.preview, (double)pn_prog_evaluated_percent(p), p->preview_change);
}

static bool preview_path_ok(const char *path) {
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash)) return false;
    return strcasecmp(dot, ".exr") == 0 || strcasecmp(dot, ".png") == 0 || strcasecmp(dot, ".pfm") == 0;
}

static size_t percent_pixels(const pn_prog *p, double percent) {
    double n = ceil(percent / 100.0 * (double)p->W * (double)p->H);
    return n < 0.0 ? 0 : (size_t)n;
}

static void check_snapshots(pn_prog *p) {
    while (p->next_percent < p->percent_count && p->evaluated >= percent_pixels(p, p->percents[p->next_percent])) {
        fire_snapshot(p, p->percents[p->next_percent]);
        p->next_percent++;
    }
    if (p->job.snapshot_every_seconds > 0.0 && pn_clock_seconds() >= p->next_time) {
        fire_snapshot(p, -1.0);
        p->next_time = pn_clock_seconds() + p->job.snapshot_every_seconds;
    }
    if (atomic_exchange(&p->ctx->snapshot_request, 0)) fire_snapshot(p, -1.0);
    if (p->job.preview && pn_clock_seconds() >= p->next_preview) {
        write_preview(p);
        p->next_preview = pn_clock_seconds() + p->job.preview_every_seconds;
    }
}

pn_status pn_prog_flush(pn_prog *p) {
    size_t pos = 0, total = (size_t)p->W * (size_t)p->H;
    size_t chunk_max = total / 256;
    if (chunk_max < 512) chunk_max = 512;
    pn_status st = PN_OK;
    check_snapshots(p);
    while (pos < p->queue_len && !p->stopped) {
        size_t n = p->queue_len - pos;
        if (n > chunk_max) n = chunk_max;
        if (p->next_percent < p->percent_count) {
            size_t need = percent_pixels(p, p->percents[p->next_percent]);
            if (need > p->evaluated && need - p->evaluated < n) n = need - p->evaluated;
        }
        if (p->stop_pixels > p->evaluated && p->stop_pixels - p->evaluated < n) n = p->stop_pixels - p->evaluated;
        st = eval_chunk(p, (const int32_t(*)[2])(p->queue + pos), n);
        if (st != PN_OK) break;
        pos += n;
        /* Progress: pixels evaluated out of those the render will evaluate at most (all of the
         * work image, or the stop percentage's); the driver reports 1 when it ends earlier. */
        size_t target = p->stop_pixels > 0 ? p->stop_pixels : total;
        pn_progress_report(p->job.progress, (double)p->evaluated / (double)target);
        if (p->settings->progress_note)
            p->settings->progress_note(p->settings->progress_user, (double)pn_prog_evaluated_percent(p),
                                       p->preview_count > 1 ? p->preview_change : -1.0);
        if (atomic_load(p->job.cancel)) {
            st = PN_ERROR_CANCELLED;
            break;
        }
        check_snapshots(p);
        if (p->stop_pixels > 0 && p->evaluated >= p->stop_pixels) p->stopped = true;
    }
    for (size_t i = pos; i < p->queue_len; i++) p->state[pn_prog_index(p, p->queue[i][0], p->queue[i][1])] &= 3;
    p->queue_len = 0;
    if (st == PN_ERROR_CANCELLED) p->stopped = true;
    return st;
}

/* Builds the output image from the driver's reconstruction: the work image, evaluated pixels
 * restored, filtered down; AOVs at the output resolution. */
static pn_status make_image(pn_prog *p, pn_image *out) {
    size_t n = (size_t)p->W * (size_t)p->H;
    uint32_t aovs = p->settings->aovs;
    bool want_map = (aovs & (PN_AOV_BLOCK_MAP | PN_AOV_BLOCK_DIRECTION)) != 0;
    if (!p->work) p->work = malloc(3 * n * sizeof *p->work);
    float *work = p->work;
    float *cls = want_map ? malloc(n * sizeof *cls) : NULL;
    float *dir = want_map ? malloc(n * sizeof *dir) : NULL;
    pn_image img = pn_image_create(p->out_w, p->out_h);
    float *pattern = NULL, *map = NULL, *mapdir = NULL;
    bool ok = work && img && (!want_map || (cls && dir));
    if (ok && (aovs & PN_AOV_SAMPLING_PATTERN)) ok = (pattern = pn_film_add_aov(img, PN_AOV_SAMPLING_PATTERN)) != NULL;
    if (ok && (aovs & PN_AOV_BLOCK_MAP)) ok = (map = pn_film_add_aov(img, PN_AOV_BLOCK_MAP)) != NULL;
    if (ok && (aovs & PN_AOV_BLOCK_DIRECTION)) ok = (mapdir = pn_film_add_aov(img, PN_AOV_BLOCK_DIRECTION)) != NULL;
    if (ok) {
        if (cls)
            for (size_t i = 0; i < n; i++) {
                cls[i] = 0.0f;
                dir[i] = -1.0f;
            }
        memset(work, 0, 3 * n * sizeof *work);
        if (p->draw) p->draw(p, p->driver, work, cls, dir);
        for (size_t i = 0; i < n; i++) {
            if ((p->state[i] & 3) == PN_PX_EVALUATED)
                memcpy(work + 3 * i, p->orig + 3 * i, 3 * sizeof *work);
            else if (p->demod)
                for (int c = 0; c < 3; c++)
                    work[3 * i + c] = work[3 * i + c] * p->demod[3 * i + c] + p->emit[3 * i + c];
        }
        ok = pn_gauss_downsample(work, p->W, p->H, 3, p->scale, (float *)pn_image_layer_data(img, 0), p->out_w,
                                 p->out_h, p->pool, p->filter_tmp);
    }
    if (ok) {
        int s = p->scale;
        for (int y = 0; y < p->out_h; y++)
            for (int x = 0; x < p->out_w; x++) {
                size_t o = (size_t)y * (size_t)p->out_w + (size_t)x;
                size_t c = pn_prog_index(p, s * x + s / 2, s * y + s / 2);
                if (pattern) {
                    int count = 0;
                    for (int j = 0; j < s; j++)
                        for (int i = 0; i < s; i++) count += pn_prog_known(p, s * x + i, s * y + j);
                    pattern[o] = (float)count / (float)(s * s);
                }
                if (map) map[o] = cls[c];
                if (mapdir) mapdir[o] = dir[c];
            }
    }
    free(cls);
    free(dir);
    if (!ok) {
        pn_image_free(img);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    *out = img;
    return PN_OK;
}

/* ---- the primary-ray buffer ---- */

typedef struct primary_run {
    pn_prog *p;
    float *depth;
    vec3 *normal;
    unsigned char *refine; /* pixels whose demod and emit come from a g x g grid */
    float *guide;          /* W*H: unshadowed irradiance at the centre ray's point (NULL: none) */
    float *light_w;        /* per worker: lights->count + 1 weights ... */
    int *light_exact;      /* ... and scratch of pn_lights_irradiance_all */
} primary_run;

/* The demodulation factor of one primary ray: its first-hit albedo, floored so that dark texels
 * do not blow the interpolated quotient up; 1 where there is no albedo (background, black). */
static vec3 demod_factor(const pn_eye_path *path) {
    if (!path->has_point) return v3(1, 1, 1);
    vec3 a = path->first_albedo;
    if (fmaxf(a.x, fmaxf(a.y, a.z)) < 1e-3f) return v3(1, 1, 1);
    return v3(fmaxf(a.x, 0.02f), fmaxf(a.y, 0.02f), fmaxf(a.z, 0.02f));
}

#define GUIDE_ANCHOR 2 /* spacing of the work pixels where the light guide is computed (guide_fill_row) */

/* The unshadowed irradiance of all lights at the point a primary ray sees (0 where it sees no
 * surface that reflects light), at the shading normal turned towards the viewer. */
static float guide_at(const primary_run *r, int worker, const pn_eye_path *path) {
    if (!path->has_point) return 0.0f;
    const pn_lights *L = r->p->job.lights;
    size_t stride = (size_t)L->count + 1;
    float *w = r->light_w + (size_t)worker * stride, g = 0.0f;
    vec3 n = v3_dot(path->hit.ns, path->wo) < 0.0f ? v3_neg(path->hit.ns) : path->hit.ns;
    pn_lights_irradiance_all(L, path->hit.p, n, w, r->light_exact + (size_t)worker * stride);
    float part[8] = {0, 0, 0, 0, 0, 0, 0, 0}; /* eight running sums, so that the loop vectorises */
    int k = 0;
    for (; k + 8 <= L->count; k += 8)
        for (int j = 0; j < 8; j++) part[j] += (w[k + j] > 0.0f && w[k + j] < INFINITY) ? w[k + j] : 0.0f;
    for (; k < L->count; k++) g += (w[k] > 0.0f && w[k] < INFINITY) ? w[k] : 0.0f;
    for (int j = 0; j < 8; j++) g += part[j];
    return g;
}

/* The primary ray of work pixel (x, y): through its centre, the specular choice at 0.5. */
static void centre_path(const pn_prog *p, int x, int y, pn_eye_path *path) {
    vec3 o, d;
    pn_camera_ray(&p->job.camera, (float)(x + p->wx0) + 0.5f, (float)(y + p->wy0) + 0.5f, 0.5f, 0.5f, &o, &d);
    pn_trace_eye_path(&p->job, o, d, 0.5f, path);
}

static void primary_row(void *user, size_t row, int worker) {
    primary_run *r = user;
    pn_prog *p = r->p;
    int y = (int)row;
    for (int x = 0; x < p->W; x++) {
        pn_eye_path path;
        centre_path(p, x, y, &path);
        size_t i = pn_prog_index(p, x, y);
        r->depth[i] = path.first_depth;
        if (path.has_point) {
            /* The object of the first non-specular hit, so that object boundaries seen in mirrors
             * count as visible lines too. */
            uint32_t t = (uint32_t)(path.hit.mesh + 1) * 2654435761u ^ (uint32_t)(path.hit.sphere + 1) * 40503u ^
                         (uint32_t)(path.hit.instance + 1) * 97u;
            p->tag[i] = (int32_t)(t & 0x7fffffffu);
            r->normal[i] = path.hit.ng;
        } else {
            p->tag[i] = -1;
            r->normal[i] = v3(0, 0, 0);
        }
        if (!p->demod) continue;
        if (r->guide)
            r->guide[i] = (x % GUIDE_ANCHOR == 0 && y % GUIDE_ANCHOR == 0) ? guide_at(r, worker, &path) : 0.0f;
        vec3 f = demod_factor(&path), e = v3_is_finite(path.emitted) ? path.emitted : v3(0, 0, 0);
        float *fd = p->demod + 3 * i, *fe = p->emit + 3 * i;
        fd[0] = f.x, fd[1] = f.y, fd[2] = f.z;
        fe[0] = e.x, fe[1] = e.y, fe[2] = e.z;
    }
}

/* Whether what the centres of work pixels a and b see differs so much that the filter-weighted
 * mean of centre rays would misjudge a pixel between them. Bit 1: the albedo factor by more than
 * 30% (strong texture, silhouettes against other materials; weaker texture is left to the
 * filtered mean, as grids everywhere would cost a large part of a full render's eye rays on
 * textured scenes). Bit 2: emitted radiance by more than 2% of the larger value (an emitter's or
 * the sky's border). */
static int primary_differs(const pn_prog *p, size_t a, size_t b) {
    int d = 0;
    /* dcm's albedo rays (issue 18): weaker texture borders too, as the integrator's rays are cheap */
    float albedo_tol = p->albedo_rays > 0 ? PN_PROG_ALBEDO_RAYS_BORDER : 0.3f;
    for (int c = 0; c < 3; c++) {
        float fa = p->demod[3 * a + c], fb = p->demod[3 * b + c];
        if (fabsf(fa - fb) > albedo_tol * fmaxf(fa, fb)) d |= 1;
        float ea = p->emit[3 * a + c], eb = p->emit[3 * b + c];
        if (fabsf(ea - eb) > 0.02f * fmaxf(fabsf(ea), fabsf(eb))) d |= 2;
    }
    return d;
}

/* Marks the pixels whose demod and emit the grid or the integrator's eye rays replace: 1 next to
 * an albedo border, 2 where the pixel filter reaches an emitter's border (a few per cent of an
 * emitter's coverage is a lot of light, and the filter spreads it over R pixels). */
/* Whole pixels on each side that the camera's pixel filter reaches, at most max_r. */
static int filter_reach(const pn_filter_axis *ax, int max_r) {
    int R = (int)ceilf(ax->radius - 0.5f);
    return R < 0 ? 0 : R > max_r ? max_r : R;
}

static size_t mark_refined(const pn_prog *p, unsigned char *refine) {
    int rx = filter_reach(&p->job.camera.filter_x, 4), ry = filter_reach(&p->job.camera.filter_y, 4);
    int R = rx > ry ? rx : ry;
    for (int y = 0; y < p->H; y++)
        for (int x = 0; x < p->W; x++) {
            size_t i = pn_prog_index(p, x, y);
            int d = (x > 0 ? primary_differs(p, i, i - 1) : 0) | (x + 1 < p->W ? primary_differs(p, i, i + 1) : 0) |
                    (y > 0 ? primary_differs(p, i, i - (size_t)p->W) : 0) |
                    (y + 1 < p->H ? primary_differs(p, i, i + (size_t)p->W) : 0);
            refine[i] = (unsigned char)d;
        }
    size_t count = 0;
    for (int y = 0; y < p->H; y++)
        for (int x = 0; x < p->W; x++) {
            size_t i = pn_prog_index(p, x, y);
            bool e = false;
            for (int dy = -R; dy <= R && !e; dy++)
                for (int dx = -R; dx <= R && !e; dx++) {
                    int xx = x + dx, yy = y + dy;
                    e = xx >= 0 && yy >= 0 && xx < p->W && yy < p->H && (refine[pn_prog_index(p, xx, yy)] & 2);
                }
            refine[i] |= e ? 8 : (refine[i] & 1) ? 4 : 0;
        }
    for (size_t i = 0; i < (size_t)p->W * (size_t)p->H; i++) {
        refine[i] = (refine[i] & 8) ? 2 : (refine[i] & 4) ? 1 : 0;
        count += refine[i] != 0;
    }
    return count;
}

/* Weights of the camera's pixel filter per whole-pixel offset -R..R along one axis: the filter's
 * integral over each neighbour's extent, from its table. Returns R. */
static int filter_pixel_weights(const pn_filter_axis *ax, float *w, int max_r) {
    int R = filter_reach(ax, max_r);
    for (int d = -R; d <= R; d++) w[d + R] = 0.0f;
    if (ax->integral_abs <= 0.0f) { /* a box: the pixel itself */
        for (int d = -R; d <= R; d++) w[d + R] = d == 0 ? 1.0f : 0.0f;
        return R;
    }
    float bw = 2.0f * ax->radius / PN_FILTER_TABLE;
    for (int b = 0; b < PN_FILTER_TABLE; b++) {
        float c = -ax->radius + ((float)b + 0.5f) * bw;
        int d = (int)floorf(c + 0.5f);
        if (d >= -R && d <= R) w[d + R] += ax->f[b];
    }
    return R;
}

/* Replaces each of `count` per-pixel arrays (src[a], ch[a] <= 3 channels: demod, emit, the
 * light guide) by its pixel-filter-weighted mean over the neighbouring pixel centres (clipped
 * to the window): the integrator's eye rays spread over the filter's support, and one centre
 * ray per pixel is a quadrature of that footprint at no extra cost. One array at a time, through
 * one scratch array. */
static bool filter_primary(pn_prog *p, float *const *src, const int *ch, int count) {
    enum { MAXR = 4 };
    float wx[2 * MAXR + 1], wy[2 * MAXR + 1];
    int rx = filter_pixel_weights(&p->job.camera.filter_x, wx, MAXR);
    int ry = filter_pixel_weights(&p->job.camera.filter_y, wy, MAXR);
    size_t n = (size_t)p->W * (size_t)p->H;
    float *t = malloc(3 * n * sizeof *t);
    if (!t) return false;
    for (int a = 0; a < count; a++) {
        const int C = ch[a];
        for (int y = 0; y < p->H; y++) /* horizontal pass into t */
            for (int x = 0; x < p->W; x++) {
                float acc[3] = {0, 0, 0}, ws = 0.0f;
                for (int d = -rx; d <= rx; d++) {
                    int xx = x + d;
                    if (xx < 0 || xx >= p->W || wx[d + rx] == 0.0f) continue;
                    const float *v = src[a] + (size_t)C * pn_prog_index(p, xx, y);
                    for (int c = 0; c < C; c++) acc[c] += wx[d + rx] * v[c];
                    ws += wx[d + rx];
                }
                for (int c = 0; c < C; c++) t[(size_t)C * pn_prog_index(p, x, y) + c] = ws != 0.0f ? acc[c] / ws : 0.0f;
            }
        for (int y = 0; y < p->H; y++) /* vertical pass back */
            for (int x = 0; x < p->W; x++) {
                float acc[3] = {0, 0, 0}, ws = 0.0f;
                for (int d = -ry; d <= ry; d++) {
                    int yy = y + d;
                    if (yy < 0 || yy >= p->H || wy[d + ry] == 0.0f) continue;
                    const float *v = t + (size_t)C * pn_prog_index(p, x, yy);
                    for (int c = 0; c < C; c++) acc[c] += wy[d + ry] * v[c];
                    ws += wy[d + ry];
                }
                float *o = src[a] + (size_t)C * pn_prog_index(p, x, y);
                for (int c = 0; c < C; c++) o[c] = ws != 0.0f ? acc[c] / ws : t[(size_t)C * pn_prog_index(p, x, y) + c];
            }
    }
    free(t);
    return true;
}

/* Demodulation and emission split: what the drivers interpolate is (radiance - emitted) / albedo,
 * both known from primary rays alone, so that neither texture detail nor directly seen emitters
 * (lamps, the sky between blinds) are left to the interpolation. The integrator's estimate of a
 * pixel averages over its filter's footprint: filter_primary's mean of the centre rays stands for
 * it, except where mark_refined finds a border (emitters, where a few per cent of coverage is a
 * lot of light; strong albedo changes): there the factors are the means of a g x g grid of
 * primary rays stratified over the pixel filter. Where the filter reaches an emitter's border and
 * the integrator reports which eye rays it traces (pn_integrator_pixel_eye_samples: `reference`
 * at a fixed --spp), its own eye rays replace the grid, so that the emitted light is weighed
 * exactly as in its estimate; albedo borders keep the cheaper grid (on staircase, the integrator's
 * 16 rays there would cost 2% of a full render for 2% less error at 6%, at 16 eye rays per pixel),
 * except under dcm's albedo rays (dcm.c's header): borders from 5%, the first PN_PROG_ALBEDO_RAYS
 * of the integrator's eye rays (at 64 eye rays, 14% less error at 6% on staircase). */
static void primary_refine_row(void *user, size_t row, int worker) {
    (void)worker;
    primary_run *r = user;
    pn_prog *p = r->p;
    int y = (int)row, g = p->primary_grid;
    for (int x = 0; x < p->W; x++) {
        size_t i = pn_prog_index(p, x, y);
        if (!r->refine[i]) continue;
        uint64_t key = pn_hash3(p->job.seed, (uint64_t)(x + p->wx0), (uint64_t)(y + p->wy0));
        vec3 f = v3(0, 0, 0), e = v3(0, 0, 0);
        double wsum = 0.0;
        /* the integrator's own eye rays: all of them along emitters, the first albedo_rays of them
         * along albedo borders (dcm's albedo rays) */
        uint32_t own = r->refine[i] == 2                   ? p->pixel_samples
                       : p->albedo_rays < p->pixel_samples ? p->albedo_rays
                                                           : p->pixel_samples;
        if (own > 0) {
            int px = x + p->wx0, py = y + p->wy0;
            uint32_t scramble = pn_pixel_scramble(&p->job, px, py);
            for (uint32_t s = 0; s < own; s++) {
                float fw, u_specular;
                vec3 o, d;
                pn_pixel_eye_sample(&p->job, px, py, scramble, s, &o, &d, &fw, &u_specular);
                pn_eye_path sub;
                pn_trace_eye_path(&p->job, o, d, u_specular, &sub);
                f = v3_madd(f, demod_factor(&sub), fw);
                if (v3_is_finite(sub.emitted)) e = v3_madd(e, sub.emitted, fw);
                wsum += (double)fw;
            }
        } else
            for (int j = 0; j < g; j++)
                for (int k = 0; k < g; k++) {
                    /* Stratified over the camera's pixel filter, weighted as the integrators weight
                 * their eye rays. */
                    uint64_t h = pn_hash3(key, (uint64_t)(j * g + k), 0x9e1a);
                    float u1 = ((float)k + pn_hash_unit(h)) / (float)g;
                    float u2 = ((float)j + pn_hash_unit(pn_hash64(h))) / (float)g;
                    float rx, ry, fw;
                    pn_camera_filter_sample(&p->job.camera, x + p->wx0, y + p->wy0, u1, u2, &rx, &ry, &fw);
                    vec3 o, d;
                    pn_camera_ray(&p->job.camera, rx, ry, 0.5f, 0.5f, &o, &d);
                    pn_eye_path sub;
                    pn_trace_eye_path(&p->job, o, d, pn_hash_unit(h ^ 0x51f7u), &sub);
                    f = v3_madd(f, demod_factor(&sub), fw);
                    if (v3_is_finite(sub.emitted)) e = v3_madd(e, sub.emitted, fw);
                    wsum += (double)fw;
                }
        if (wsum == 0.0) continue; /* keep the filtered centre values */
        f = v3_scale(f, (float)(1.0 / wsum));
        if (r->guide) f = v3_scale(f, r->guide[i]); /* the centre rays' filtered guide */
        e = v3_scale(e, (float)(1.0 / wsum));
        float *fd = p->demod + 3 * i, *fe = p->emit + 3 * i;
        fd[0] = f.x, fd[1] = f.y, fd[2] = f.z;
        fe[0] = e.x, fe[1] = e.y, fe[2] = e.z;
    }
}

/* The guide between anchors (work pixels whose x and y are multiples of GUIDE_ANCHOR): bilinear
 * between the nearest anchors where they all see the same object, with geometric normals within
 * 10 degrees of the pixel's and depths within 2% (the guide varies smoothly there, and this saves
 * most of its cost); elsewhere the pixel's primary ray is traced again and the guide computed. */
static bool guide_close(const primary_run *r, size_t i, size_t a) {
    const pn_prog *p = r->p;
    if (p->tag[a] != p->tag[i]) return false;
    if (v3_dot(r->normal[a], r->normal[i]) < 0.985f) return false;
    return fabsf(r->depth[a] - r->depth[i]) <= 0.02f * r->depth[i];
}

static void guide_fill_row(void *user, size_t row, int worker) {
    primary_run *r = user;
    const pn_prog *p = r->p;
    const int S = GUIDE_ANCHOR;
    int y = (int)row;
    for (int x = 0; x < p->W; x++) {
        if (x % S == 0 && y % S == 0) continue;
        size_t i = pn_prog_index(p, x, y);
        float g = 0.0f;
        if (p->tag[i] >= 0) {
            /* The anchor columns and rows around the pixel and their bilinear weights; an anchor
             * beyond the window's last pixel is left out and its neighbour takes the weight. */
            int xs[2] = {x - x % S, x - x % S + S}, ys[2] = {y - y % S, y - y % S + S};
            float wx[2] = {1.0f - (float)(x % S) / (float)S, (float)(x % S) / (float)S};
            float wy[2] = {1.0f - (float)(y % S) / (float)S, (float)(y % S) / (float)S};
            if (xs[1] >= p->W) wx[0] = 1.0f, wx[1] = 0.0f;
            if (ys[1] >= p->H) wy[0] = 1.0f, wy[1] = 0.0f;
            bool ok = true;
            float sum = 0.0f;
            for (int j = 0; j < 2 && ok; j++)
                for (int k = 0; k < 2 && ok; k++) {
                    float w = wx[k] * wy[j];
                    if (w == 0.0f) continue;
                    size_t a = pn_prog_index(p, xs[k], ys[j]);
                    ok = guide_close(r, i, a);
                    sum += w * r->guide[a];
                }
            if (ok) {
                g = sum;
            } else {
                pn_eye_path path;
                centre_path(p, x, y, &path);
                g = guide_at(r, worker, &path);
            }
        }
        r->guide[i] = g;
    }
}

/* The light guide: the demodulation factor also divides out the unshadowed irradiance of all
 * lights at the pixel (pn_lights_irradiance_all at the centre ray's point and shading normal,
 * filtered like the albedo), so that what is interpolated is, for a diffuse surface lit
 * directly, about the visible fraction of that irradiance: the 1/r^2 pools and glows of lamps
 * and the cones of spots are known from the primary rays, and shadows, glossy lobes and
 * indirect light are what is left to the interpolation. This is the ratio of Heitz, Hill and
 * McGuire 2018 ("Combining analytic direct illumination and stochastic shadows"), which
 * denoises shadowed / unshadowed and multiplies the analytic unshadowed part back, applied to
 * DCM's interpolation. The guide is normalised by its mean over the pixels that see a surface
 * and offset by PN_GUIDE_OFFSET of that mean: where the guide is small next to it (lights at
 * grazing angles, near their horizon, light that arrives otherwise) the quotient stays the
 * albedo-demodulated radiance instead of an unstable ratio of small numbers. On the bench
 * crops (16 eye rays, 6%): staircase rel L1 / L2 0.0332 / 0.0310 -> 0.0287 / 0.0221; offset 0
 * gives 0.0279 / 0.0208 there but bathroom 0.0299 / 0.0162 against 0.0282 / 0.0142 unguided
 * (its window frame and blinds, lit at grazing angles through the slats); 0.5 leaves bathroom
 * and hall-many within 2% of unguided. */
#define PN_GUIDE_OFFSET 0.5f

static void apply_guide(pn_prog *p, float *guide) {
    size_t n = (size_t)p->W * (size_t)p->H;
    double sum = 0.0;
    size_t lit = 0;
    for (size_t i = 0; i < n; i++)
        if (p->tag[i] >= 0) {
            sum += (double)guide[i];
            lit++;
        }
    float scale = sum > 0.0 ? 1.0f / (float)(sum / (double)lit) : 1.0f;
    for (size_t i = 0; i < n; i++) {
        float g = p->tag[i] >= 0 ? guide[i] * scale + PN_GUIDE_OFFSET : 1.0f;
        for (int c = 0; c < 3; c++) p->demod[3 * i + c] *= g;
        guide[i] = g;
    }
}

static bool discontinuous(const primary_run *r, const pn_prog *p, size_t a, size_t b) {
    if (p->tag[a] != p->tag[b]) return true;
    if (p->tag[a] < 0) return false;
    if (v3_dot(r->normal[a], r->normal[b]) < 0.8f) return true;
    float da = r->depth[a], db = r->depth[b];
    if (!isfinite(da) || !isfinite(db)) return isfinite(da) != isfinite(db);
    return fabsf(da - db) > 0.1f * fminf(da, db);
}

pn_status pn_prog_build_primary(pn_prog *p) {
    if (p->tag) return PN_OK;
    double t0 = pn_clock_seconds();
    size_t n = (size_t)p->W * (size_t)p->H, ns = (size_t)(p->W + 1) * (size_t)(p->H + 1);
    primary_run r = {p, malloc(n * sizeof(float)), malloc(n * sizeof(vec3)), NULL, NULL, NULL, NULL};
    p->tag = malloc(n * sizeof *p->tag);
    p->sat_right = calloc(ns, sizeof *p->sat_right);
    p->sat_down = calloc(ns, sizeof *p->sat_down);
    if (!p->job.raw_radiance) {
        p->demod = malloc(3 * n * sizeof *p->demod);
        p->emit = malloc(3 * n * sizeof *p->emit);
    }
    if (!r.depth || !r.normal || !p->tag || !p->sat_right || !p->sat_down ||
        (!p->job.raw_radiance && (!p->demod || !p->emit))) {
        free(r.depth);
        free(r.normal);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    bool guided = p->demod && !p->job.no_light_guide && p->job.lights->count > 0;
    if (guided) {
        size_t stride = (size_t)p->job.lights->count + 1, nw = (size_t)pn_threadpool_size(p->pool);
        r.guide = malloc(n * sizeof *r.guide);
        r.light_w = malloc(nw * stride * sizeof *r.light_w);
        r.light_exact = malloc(nw * stride * sizeof *r.light_exact);
    }
    bool ok = !guided || (r.guide && r.light_w && r.light_exact);
    if (ok) pn_threadpool_run(p->pool, (size_t)p->H, primary_row, &r);
    if (ok && guided) pn_threadpool_run(p->pool, (size_t)p->H, guide_fill_row, &r);
    free(r.light_w);
    free(r.light_exact);
    if (ok && p->demod) {
        /* Borders are found on the centre values, the filter replaces them, then the grids
         * overwrite the border pixels. */
        bool grid = p->primary_grid > 1;
        ok = !grid || (r.refine = calloc(n, 1)) != NULL;
        if (ok && grid) p->primary_refined = mark_refined(p, r.refine);
        if (ok && guided) apply_guide(p, r.guide);
        float *const filtered[3] = {p->demod, p->emit, r.guide};
        const int channels[3] = {3, 3, 1};
        ok = ok && filter_primary(p, filtered, channels, guided ? 3 : 2);
        if (ok && grid) pn_threadpool_run(p->pool, (size_t)p->H, primary_refine_row, &r);
        free(r.refine);
    }
    free(r.guide);
    if (!ok) {
        free(r.depth);
        free(r.normal);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    size_t stride = (size_t)p->W + 1;
    for (int y = 0; y < p->H; y++)
        for (int x = 0; x < p->W; x++) {
            size_t i = pn_prog_index(p, x, y);
            uint32_t fr = x + 1 < p->W && discontinuous(&r, p, i, i + 1);
            uint32_t fd = y + 1 < p->H && discontinuous(&r, p, i, i + (size_t)p->W);
            size_t s = (size_t)(y + 1) * stride + (size_t)(x + 1);
            p->sat_right[s] = fr + p->sat_right[s - 1] + p->sat_right[s - stride] - p->sat_right[s - stride - 1];
            p->sat_down[s] = fd + p->sat_down[s - 1] + p->sat_down[s - stride] - p->sat_down[s - stride - 1];
        }
    p->depth = r.depth; /* kept for the guided reconstruction (dcm.c) */
    p->normal = r.normal;
    p->primary_seconds = pn_clock_seconds() - t0;
    return PN_OK;
}

static uint32_t sat_sum(const uint32_t *sat, int W, int x0, int y0, int x1, int y1) {
    if (x1 < x0 || y1 < y0) return 0;
    size_t stride = (size_t)W + 1;
    return sat[(size_t)(y1 + 1) * stride + (size_t)(x1 + 1)] - sat[(size_t)y0 * stride + (size_t)(x1 + 1)] -
           sat[(size_t)(y1 + 1) * stride + (size_t)x0] + sat[(size_t)y0 * stride + (size_t)x0];
}

bool pn_prog_line_right(const pn_prog *p, int x, int y) {
    return p->tag && x + 1 < p->W && sat_sum(p->sat_right, p->W, x, y, x, y) > 0;
}

bool pn_prog_line_down(const pn_prog *p, int x, int y) {
    return p->tag && y + 1 < p->H && sat_sum(p->sat_down, p->W, x, y, x, y) > 0;
}

bool pn_prog_visible_line(const pn_prog *p, int x0, int y0, int x1, int y1) {
    if (!p->tag) return false;
    return sat_sum(p->sat_right, p->W, x0, y0, x1 - 1, y1) > 0 || sat_sum(p->sat_down, p->W, x0, y0, x1, y1 - 1) > 0;
}

/* ---- the full driver ---- */

static pn_status full_run(pn_prog *p) {
    for (int by = 0; by < p->H; by += PN_PROG_BLOCK)
        for (int bx = 0; bx < p->W; bx += PN_PROG_BLOCK)
            for (int y = by; y < by + PN_PROG_BLOCK && y < p->H; y++)
                for (int x = bx; x < bx + PN_PROG_BLOCK && x < p->W; x++)
                    if (!pn_prog_request(p, x, y)) return PN_ERROR_OUT_OF_MEMORY;
    return pn_prog_flush(p);
}

/* ---- entry ---- */

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

pn_status pn_progressive_render(pn_context ctx, const pn_render_settings *s, const pn_integrator *integ,
                                const pn_render_job *job, pn_image *out_image, pn_render_stats *stats) {
    if (s->driver < PN_DRIVER_FULL || s->driver > PN_DRIVER_UNIFORM)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown driver %d", (int)s->driver);
    const char *refusal = s->driver != PN_DRIVER_FULL ? pn_integrator_progressive_refusal(integ) : NULL;
    if (refusal)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "%s does not run under the %s driver: %s",
                               pn_registry_integrator_entry(integ)->info.name,
                               pn_registry_method_kind(PN_METHOD_DRIVER, (int)s->driver)->info.name, refusal);
    int scale = job->work_scale > 0 ? job->work_scale : 3;
    if (job->work_scale < 0 || scale > 16)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "work scale %d is out of range (1..16)",
                               job->work_scale);
    if (job->primary_grid < 0 || job->primary_grid > 8)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "primary grid %d is out of range (1..8)",
                               job->primary_grid);
    if (s->aovs & ~(uint32_t)(PN_AOV_SAMPLING_PATTERN | PN_AOV_BLOCK_MAP | PN_AOV_BLOCK_DIRECTION))
        return pn_context_fail(
            ctx, PN_ERROR_INVALID_ARGUMENT,
            "progressive drivers write only the sampling_pattern, block_map and block_direction AOVs");
    if (!(job->stop_percent >= 0.0 && job->stop_percent <= 100.0) || !(job->snapshot_every_seconds >= 0.0))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "stop percentage must lie in [0, 100] and the snapshot interval be >= 0");
    for (int i = 0; i < job->snapshots.count; i++)
        if (!(job->snapshots.values[i] > 0.0 && job->snapshots.values[i] <= 100.0))
            return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "snapshot percentages must lie in (0, 100]");
    if (job->preview && job->preview[0] && !preview_path_ok(job->preview))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "%s: the preview must be an .exr, .png or .pfm file",
                               job->preview);
    if (job->preview && job->preview[0] && !(job->preview_every_seconds > 0.0))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "the preview interval must be > 0 seconds");
    const pn_camera *oc = &job->camera;
    if ((long)oc->full_width * scale > 65536 || (long)oc->full_height * scale > 65536)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "work image %dx%d too large", oc->full_width * scale,
                               oc->full_height * scale);

    pn_prog *p = calloc(1, sizeof *p);
    if (!p) return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    p->ctx = ctx;
    p->settings = s;
    p->integ = integ;
    p->job = *job;
    p->scale = scale;
    p->primary_grid = job->primary_grid > 0 ? job->primary_grid : 3;
    /* --dcm-variant paper / --dcm-off demod: the paper interpolates radiance itself */
    if (s->driver == PN_DRIVER_DCM && (pn_dcm_off_flags(job->dcm_variant, job->dcm_off) & PN_DCM_OFF_DEMOD))
        p->job.raw_radiance = true;
    p->integ_emitted = pn_integrator_reports_emitted(integ);
    p->pixel_samples = pn_integrator_pixel_eye_samples(integ, &p->job);
    /* dcm's albedo rays (issue 18, --dcm-off albedo-rays; dcm.c's header) */
    if (s->driver == PN_DRIVER_DCM && p->pixel_samples > 0 &&
        !(pn_dcm_off_flags(job->dcm_variant, job->dcm_off) & PN_DCM_OFF_ALBEDO_RAYS))
        p->albedo_rays = PN_PROG_ALBEDO_RAYS;
    float crop[4] = {0, 1, 0, 1};
    pn_camera_setup(&job->scene->camera, oc->full_width * scale, oc->full_height * scale, crop, &p->job.camera);
    p->job.camera.x0 = oc->x0 * scale;
    p->job.camera.x1 = oc->x1 * scale;
    p->job.camera.y0 = oc->y0 * scale;
    p->job.camera.y1 = oc->y1 * scale;
    p->out_w = oc->x1 - oc->x0;
    p->out_h = oc->y1 - oc->y0;
    p->W = p->out_w * scale;
    p->H = p->out_h * scale;
    p->wx0 = p->job.camera.x0;
    p->wy0 = p->job.camera.y0;
    size_t n = (size_t)p->W * (size_t)p->H;
    p->rad = calloc(3 * n, sizeof *p->rad);
    p->orig = calloc(3 * n, sizeof *p->orig);
    p->relvar = calloc(n, sizeof *p->relvar);
    p->state = calloc(n, 1);
    p->pool = pn_threadpool_create(s->threads);
    p->workers = pn_threadpool_size(p->pool);
    p->scratch = calloc((size_t)p->workers + 1, sizeof *p->scratch);
    p->counters = calloc((size_t)p->workers + 1, sizeof *p->counters);
    p->percent_count = job->snapshots.count;
    p->percents = p->percent_count ? malloc((size_t)p->percent_count * sizeof *p->percents) : NULL;
    pn_status st = PN_OK;
    if (!p->rad || !p->orig || !p->relvar || !p->state || !p->pool || !p->scratch || !p->counters ||
        (p->percent_count && !p->percents)) {
        st = pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d work image", p->W, p->H);
    } else {
        if (p->percent_count) {
            memcpy(p->percents, job->snapshots.values, (size_t)p->percent_count * sizeof *p->percents);
            qsort(p->percents, (size_t)p->percent_count, sizeof *p->percents, cmp_double);
        }
        p->stop_pixels = job->stop_percent > 0.0 ? percent_pixels(p, job->stop_percent) : 0;
        atomic_init(&p->failed, 0);
        atomic_store(&ctx->snapshot_request, 0);
        p->driver_stats = stats;
        /* The reconstruction buffer, touched once here so that the first snapshot does not pay
         * for the page faults. */
        p->work = calloc(3 * n, sizeof *p->work);
        if (p->work) memset(p->work, 0, 3 * n * sizeof *p->work);
        size_t nt = 3 * (size_t)p->out_w * (size_t)p->H;
        p->filter_tmp = calloc(nt, sizeof *p->filter_tmp);
        if (p->filter_tmp) memset(p->filter_tmp, 0, nt * sizeof *p->filter_tmp);
        p->t0 = pn_clock_seconds();
        p->next_time = p->t0 + job->snapshot_every_seconds;
        if (p->job.preview && !p->job.preview[0]) p->job.preview = NULL;
        p->next_preview = p->t0 + job->preview_every_seconds;
        /* A cancel issued before or during preparation is honoured here. */
        if (atomic_load(p->job.cancel)) st = PN_ERROR_CANCELLED;
        if (st == PN_OK && s->driver != PN_DRIVER_FULL) {
            pn_progress_phase(p->job.progress, 0.0, PN_PROG_PRIMARY_SHARE);
            st = pn_prog_build_primary(p);
            pn_progress_report(p->job.progress, 1.0);
            pn_progress_phase(p->job.progress, PN_PROG_PRIMARY_SHARE, 1.0);
        }
        if (st == PN_OK) switch (s->driver) {
            case PN_DRIVER_FULL: st = full_run(p); break;
            case PN_DRIVER_DCM: st = pn_dcm_run(p, false); break;
            case PN_DRIVER_UNIFORM: st = pn_dcm_run(p, true); break;
            case PN_DRIVER_PAINTER: st = pn_painter_run(p); break;
            default: st = PN_ERROR_INVALID_ARGUMENT; break;
            }
        double t1 = pn_clock_seconds();
        if (st == PN_OK) {
            pn_progress_phase(p->job.progress, 0.0, 1.0);
            pn_progress_report(p->job.progress, 1.0);
        }
        pn_status img_st = PN_OK;
        if (st == PN_OK || st == PN_ERROR_CANCELLED) {
            img_st = make_image(p, out_image);
            if (img_st == PN_OK) check_snapshots(p);
            if (img_st == PN_OK && p->job.preview && p->snapshot_status == PN_OK) write_preview(p); /* the last */
        }
        if (st == PN_OK && p->snapshot_status != PN_OK) st = p->snapshot_status;
        uint64_t non_finite = 0;
        for (int w = 0; w <= p->workers; w++) non_finite += p->counters[w].non_finite;
        pn_film_warn_non_finite(p->ctx, non_finite, integ->name);
        if (stats) {
            uint64_t eye = 0, shadow = 0, spec = 0, max_eye = 0, max_shadow = 0;
            double embree = 0.0;
            for (int w = 0; w <= p->workers; w++) {
                eye += p->counters[w].eye;
                shadow += p->counters[w].shadow;
                spec += p->counters[w].spec;
                embree += p->counters[w].embree;
                if (p->counters[w].max_eye > max_eye) max_eye = p->counters[w].max_eye;
                if (p->counters[w].max_shadow > max_shadow) max_shadow = p->counters[w].max_shadow;
            }
            size_t evaluated = 0;
            for (size_t i = 0; i < n; i++) evaluated += (p->state[i] & 3) == PN_PX_EVALUATED;
            stats->render_seconds = t1 - p->t0;
            stats->embree_seconds_estimate = embree / (double)(p->workers > 0 ? p->workers : 1);
            stats->eye_rays = eye;
            stats->shadow_rays = shadow;
            stats->specular_rays = spec;
            stats->eye_rays_per_pixel_mean = evaluated ? (double)eye / (double)evaluated : 0.0;
            stats->shadow_rays_per_pixel_mean = evaluated ? (double)shadow / (double)evaluated : 0.0;
            stats->eye_rays_per_pixel_max = max_eye;
            stats->shadow_rays_per_pixel_max = max_shadow;
            stats->non_finite_samples = non_finite;
            stats->mrays_per_second =
                stats->render_seconds > 0.0 ? (double)(eye + shadow + spec) / stats->render_seconds * 1e-6 : 0.0;
            stats->partial = st == PN_ERROR_CANCELLED;
            stats->peak_memory_bytes = pn_peak_memory_bytes();
            if (integ->report) integ->report(&p->job, stats);
            stats->threads = p->workers;
            stats->width = p->out_w;
            stats->height = p->out_h;
            stats->evaluated_pixels = evaluated;
            stats->evaluated_percent = 100.0 * (double)evaluated / (double)n;
            stats->work_width = p->W;
            stats->work_height = p->H;
            stats->primary_buffer_seconds = p->primary_seconds;
            stats->primary_grid_pixels = p->primary_refined;
            stats->reconstruct_seconds_max = p->reconstruct_seconds_max;
        }
        if (img_st != PN_OK)
            st = pn_context_fail(ctx, img_st, "out of memory for the output image");
        else if (st == PN_ERROR_CANCELLED)
            pn_context_fail(ctx, st, "render cancelled; the image is approximate");
        else if (st != PN_OK && p->preview_error[0])
            pn_context_fail(ctx, st, "%s", p->preview_error);
        else if (st != PN_OK)
            pn_context_fail(ctx, st, "render failed: %s", pn_status_string(st));
    }
    for (int w = 0; p->scratch && w <= p->workers; w++)
        if (p->scratch[w] && integ->scratch_free) integ->scratch_free(p->scratch[w]);
    if (p->free_driver) p->free_driver(p->driver);
    pn_threadpool_destroy(p->pool);
    free(p->scratch);
    free(p->counters);
    free(p->percents);
    free(p->work);
    free(p->filter_tmp);
    free(p->preview_prev);
    free(p->rad);
    free(p->orig);
    free(p->relvar);
    free(p->demod);
    free(p->emit);
    free(p->state);
    free(p->queue);
    free(p->tag);
    free(p->depth);
    free(p->normal);
    free(p->sat_right);
    free(p->sat_down);
    free(p);
    return st;
}
