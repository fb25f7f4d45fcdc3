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

pn_vpl_receiver pn_vpl_irradiance_receiver(const pn_vpl_receiver *r) {
    pn_vpl_receiver w = *r;
    w.kd = v3(PN_PI, PN_PI, PN_PI);
    w.ks = v3(0, 0, 0);
    w.kd_w = w.kd;
    w.ks_w = w.ks;
    w.wl.on = false; /* the illuminance stays linear sRGB in spectral mode */
    w.exponent = 1.0f;
    return w;
}

uint32_t pn_vpl_batch_points(const pn_render_job *job) {
    return pn_vpl_spp(job);
}
