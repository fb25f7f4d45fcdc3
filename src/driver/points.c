/* points.c — pn_illuminance: illuminance at calculation points with no camera (work-plane grids
 * and point lists, docs/lighting-design.md). The settings are resolved as for pn_render, the
 * integrator prepared once (light BVH, VPL set and tree), and the points handed to the worker
 * threads in chunks by an atomic counter; each point's value depends only on the scene, the
 * settings and its index (integrators/point_eval.c). pn_illuminance_melanopic adds each point's
 * melanopic EDI (CIE S 026) in spectral mode. */
#include "driver/points.h"
#include "driver/settings.h"

#include "core/context.h"
#include "core/threadpool.h"
#include "integrators/point_eval.h"
#include "render/progress.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Points per job of the pool. */
#define PN_POINT_CHUNK 16

typedef struct points_shared {
    const pn_render_job *job;
    const pn_integrator *integrator;
    const pn_illuminance_point *points;
    int count;
    double *lux;
    double *edi; /* NULL unless the melanopic EDI is asked for */
    void **scratch;
    atomic_int failed;
} points_shared;

static void run_chunk(void *user, size_t chunk, int worker) {
    points_shared *ps = user;
    if (atomic_load(&ps->failed) || atomic_load(ps->job->cancel)) return;
    if (!ps->scratch[worker]) ps->scratch[worker] = pn_point_scratch_create(ps->job, ps->integrator);
    if (!ps->scratch[worker]) {
        atomic_store(&ps->failed, (int)PN_ERROR_OUT_OF_MEMORY);
        return;
    }
    int end = (int)(chunk + 1) * PN_POINT_CHUNK;
    if (end > ps->count) end = ps->count;
    for (int i = (int)chunk * PN_POINT_CHUNK; i < end; i++) {
        const pn_illuminance_point *pt = &ps->points[i];
        vec3 p = v3(pt->p[0], pt->p[1], pt->p[2]);
        vec3 n = v3_normalize(v3(pt->n[0], pt->n[1], pt->n[2]));
        if (!pn_point_illuminance(ps->job, ps->integrator, ps->scratch[worker], p, n, (uint32_t)i, &ps->lux[i],
                                  ps->edi ? &ps->edi[i] : NULL)) {
            atomic_store(&ps->failed, (int)PN_ERROR_OUT_OF_MEMORY);
            return;
        }
    }
}

pn_status pn_illuminance(pn_context ctx, pn_scene scene, const pn_render_settings *caller_settings,
                         const pn_illuminance_point *points, int count, double *lux) {
    return pn_illuminance_melanopic(ctx, scene, caller_settings, points, count, lux, NULL);
}

pn_status pn_illuminance_melanopic(pn_context ctx, pn_scene scene, const pn_render_settings *caller_settings,
                                   const pn_illuminance_point *points, int count, double *lux, double *edi) {
    if (!ctx || !scene || !caller_settings || (count > 0 && (!points || !lux)) || count < 0) {
        if (ctx) pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_illuminance: NULL argument or negative count");
        return PN_ERROR_INVALID_ARGUMENT;
    }
    pn_render_settings settings_copy;
    pn_status copied = pn_render_settings_copy(ctx, "pn_illuminance", caller_settings, &settings_copy);
    if (copied != PN_OK) return copied;
    const pn_render_settings *settings = &settings_copy;
    const pn_method_entry *ientry = pn_registry_method_kind(PN_METHOD_INTEGRATOR, (int)settings->integrator);
    const pn_method_entry *dentry = pn_registry_method_kind(PN_METHOD_DRIVER, (int)PN_DRIVER_DEFAULT);
    if (!ientry || !dentry)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown integrator %d", (int)settings->integrator);
    const pn_integrator *integ = ientry->integrator;
    if (!pn_point_supported(integ))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "integrator %s does not compute illuminance at points (reference: direct; vpl, "
                               "lightcuts: total)",
                               ientry->info.name);
    for (int i = 0; i < count; i++) {
        const float *v = points[i].p, *n = points[i].n;
        bool finite = true;
        for (int k = 0; k < 3; k++) finite = finite && isfinite(v[k]) && isfinite(n[k]);
        if (!finite || !(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.0f))
            return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                                   "point %d has a non-finite coordinate or a zero normal", i);
    }
    pn_render_job job;
    pn_progress progress;
    pn_status st = pn_driver_prepare_job(ctx, scene, settings, ientry, dentry, &job, &progress);
    if (st != PN_OK) return st;
    if (edi && !job.spectral) {
        if (integ->release) integ->release(&job);
        pn_progress_destroy(&progress);
        atomic_store(&ctx->cancel, 0);
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "the melanopic EDI needs spectral mode (the option spectral, --spectral): it is "
                               "integrated from the light's spectrum at sampled wavelengths, which RGB mode does "
                               "not carry");
    }
    pn_threadpool *pool = pn_threadpool_create(settings->threads);
    int workers = pool ? pn_threadpool_size(pool) : 0;
    points_shared ps = {&job, integ, points, count, lux, edi, NULL, 0};
    ps.scratch = pool ? calloc((size_t)workers + 1, sizeof *ps.scratch) : NULL;
    if (!pool || !ps.scratch) {
        st = pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for %d points", count);
    } else {
        atomic_init(&ps.failed, 0);
        size_t chunks = ((size_t)count + PN_POINT_CHUNK - 1) / PN_POINT_CHUNK;
        pn_threadpool_run(pool, chunks, run_chunk, &ps);
        int failed = atomic_load(&ps.failed);
        if (failed)
            st = pn_context_fail(ctx, (pn_status)failed, "illuminance failed: %s", pn_status_string((pn_status)failed));
        else if (atomic_load(&ctx->cancel))
            st = pn_context_fail(ctx, PN_ERROR_CANCELLED, "illuminance cancelled");
        for (int w = 0; w <= workers; w++) pn_point_scratch_free(integ, ps.scratch[w]);
    }
    free(ps.scratch);
    pn_threadpool_destroy(pool);
    if (integ->release) integ->release(&job);
    pn_progress_destroy(&progress);
    atomic_store(&ctx->cancel, 0);
    return st;
}
