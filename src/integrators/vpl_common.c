/* vpl_common.c — preparation, eye samples and statistics shared by the VPL integrators
 * (vpl, lightcuts, illumcut; see illumcut.h). */
#include "integrators/illumcut.h"

#include "core/rng.h"
#include "io/image.h"
#include "render/progress.h"
#include "scene/scene.h"
#include "shade/bsdf.h"

#include <stdlib.h>
#include <string.h>

/* Shares of the whole render's progress bar (fixed, not measured): VPL tracing, then the
 * light tree. */
#define PN_VPL_TRACE_SHARE 0.08
#define PN_VPL_TREE_SHARE 0.04

static pn_status prepare_cancelled(pn_err *err) {
    return pn_err_set(err, PN_ERROR_CANCELLED, "render cancelled during preparation");
}

pn_status pn_vpl_prepare(pn_render_job *job, bool with_tree, pn_err *err) {
    if (pn_progress_cancelled(job->progress)) return prepare_cancelled(err);
    pn_vpl_data *d = calloc(1, sizeof *d);
    if (!d) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    pn_vpl_settings vs = {job->vpls, job->vpl_max_depth, job->vpl_clamp_fraction, job->seed};
    pn_vpl_trace_options vo = {job->vpl_direct_only, NULL, NULL};
    if (job->progress) {
        vo.progress = pn_progress_step;
        vo.progress_user = job->progress;
        pn_progress_phase(job->progress, 0.0, PN_VPL_TRACE_SHARE);
    }
    pn_status st = pn_vpl_trace_with(job->scene, job->lights, job->accel, &vs, &vo, &d->set, err);
    if (st != PN_OK) {
        free(d);
        return st;
    }
    d->vpl_seconds = d->set.seconds;
    /* The tree build runs to its end once started; a cancel during it is seen right after. */
    if (pn_progress_cancelled(job->progress)) {
        pn_vpl_set_free(&d->set);
        free(d);
        return prepare_cancelled(err);
    }
    if (with_tree) {
        pn_progress_phase(job->progress, PN_VPL_TRACE_SHARE, PN_VPL_TRACE_SHARE + PN_VPL_TREE_SHARE);
        float diag = 2.0f * job->lights->scene_radius;
        st = pn_light_tree_build(&d->set, diag, job->seed, &d->tree, err);
        if (st == PN_OK) st = pn_light_tree_order_vpls(&d->tree, &d->set, err);
        if (st != PN_OK) {
            pn_light_tree_free(&d->tree);
            pn_vpl_set_free(&d->set);
            free(d);
            return st;
        }
        d->tree_seconds = d->tree.seconds;
        pn_progress_report(job->progress, 1.0);
        if (pn_progress_cancelled(job->progress)) {
            pn_light_tree_free(&d->tree);
            pn_vpl_set_free(&d->set);
            free(d);
            return prepare_cancelled(err);
        }
    }
    job->integrator_data = d;
    return PN_OK;
}

void pn_vpl_release(pn_render_job *job) {
    pn_vpl_data *d = job->integrator_data;
    if (!d) return;
    pn_vpl_set_free(&d->set);
    pn_light_tree_free(&d->tree);
    free(d);
    job->integrator_data = NULL;
}

void pn_vpl_report(const pn_render_job *job, pn_render_stats *stats) {
    const pn_vpl_data *d = job->integrator_data;
    if (!d) return;
    stats->vpl_seconds = d->vpl_seconds;
    stats->light_tree_seconds = d->tree_seconds;
    stats->preprocess_seconds = d->vpl_seconds + d->tree_seconds;
    stats->vpl_count = d->set.count;
    stats->vpl_paths = d->set.paths;
    double pixels = (double)(job->camera.x1 - job->camera.x0) * (double)(job->camera.y1 - job->camera.y0);
    uint64_t points = atomic_load(&((pn_vpl_data *)d)->points);
    stats->bound_evaluations_per_pixel_mean = (double)atomic_load(&((pn_vpl_data *)d)->bound_evaluations) / pixels;
    stats->cut_size_mean = points ? (double)atomic_load(&((pn_vpl_data *)d)->cut_nodes) / (double)points : 0.0;
    stats->point_tree_seconds = d->point_tree_seconds;
    stats->phase1_seconds = d->phase1_seconds;
    stats->phase2_seconds = d->phase2_seconds;
    stats->illumcut_pairs = d->pairs;
}

void pn_vpl_eye_sample(const pn_render_job *job, int px, int py, uint32_t i, pn_shading_point *sp,
                       pn_pixel_estimate *est) {
    uint32_t scramble = (uint32_t)pn_hash3(job->seed ^ UINT64_C(0x76706c), (uint64_t)(uint32_t)px, (uint64_t)(uint32_t)py);
    float fw, u_specular;
    vec3 ro, rd;
    pn_pixel_eye_sample(job, px, py, scramble, i, &ro, &rd, &fw, &u_specular);
    pn_eye_path path;
    pn_trace_eye_path(job, ro, rd, u_specular, &path);
    if (i == 0) {
        est->depth = path.first_depth;
        est->normal = path.first_normal;
        est->albedo = path.first_albedo;
    }
    est->eye_rays++;
    est->specular_rays += path.rays - 1;
    memset(sp, 0, sizeof *sp);
    sp->weight = fw;
    sp->emitted = v3_is_finite(path.emitted) ? path.emitted : v3(0, 0, 0);
    sp->throughput = path.throughput;
    if (!path.has_point) return;
    pn_bsdf b;
    pn_bsdf_at(job->scene, &path.hit, path.wo, &b);
    sp->has_point = true;
    sp->r.p = path.hit.p;
    sp->r.ng = b.ng;
    sp->r.ns = b.ns;
    sp->r.wo = path.wo;
    sp->r.kd = b.kd;
    sp->r.ks = b.ks;
    sp->r.exponent = b.exponent;
}
