/* point_eval.c — illuminance at calculation points (work-plane grids, rtrace -I style point
 * lists) with no camera, by the same estimators that fill the illuminance AOV:
 *
 *   reference  the reference's direct-light estimator (reference_direct.c; IAS paper §5.1) at a
 *              white Lambertian point of normal n: spp x shadow-rays light samples, each
 *              L cos / pdf; the point's Sobol scramble is a hash of (seed, point index), salted
 *              apart from the pixels', so every point is independent of the others and of the
 *              thread count.
 *   vpl        every VPL with a shadow ray, for a white Lambertian receiver (f = 1, so M G V I
 *              is the irradiance of each VPL; vpl_common.c pn_vpl_irradiance_receiver).
 *   lightcuts  a lightcut for that receiver (Walter et al. 2005 §4, its relative error bound).
 *
 * The VPL set is the render's (its clamp included: a VPL closer than the clamp distance is
 * counted at that distance, as in the image). Illuminance = Y of the irradiance (core/photometry.h, docs/units.md).
 *
 * Melanopic EDI (spectral mode): each of the spp samples (64 when spp is 0) draws 3 wavelengths
 * (pn_eye_wavelengths of the point's sequence); reference: its light samples' radiance at them
 * (pn_reference_direct_irradiance_wl); vpl: every VPL's irradiance at each sample's wavelengths,
 * with the VPL's one shadow ray; lightcuts: a lightcut of the white receiver at each sample's
 * wavelengths (the cut is the RGB receiver's, so the same for every sample). The EDI is the mean
 * of pn_swl_melanopic_edi_on of those irradiances. The illuminance itself stays the RGB estimate,
 * as in RGB mode. */
#include "integrators/point_eval.h"

#include "core/photometry.h"
#include "core/rng.h"
#include "integrators/illumcut.h"
#include "integrators/reference_direct.h"
#include "shade/bsdf.h"
#include "spectral/melanopic.h"
#include "spectral/transport.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Salt of the points' scrambles (no pixel has this hash input). */
#define PN_POINT_SALT UINT64_C(0x6c75782d67726964)

/* The melanopic EDI at points of the VPL integrators: the number of wavelength samples and the
 * i-th sample's wavelengths (the reference's convention: the point's Sobol sequence). */
static uint32_t point_wavelength_samples(const pn_render_job *job) {
    return job->spp > 0 ? job->spp : 64u;
}
static uint32_t point_scramble(const pn_render_job *job, uint32_t index) {
    return (uint32_t)pn_hash3(job->seed ^ PN_POINT_SALT, (uint64_t)index, 0u);
}

bool pn_point_supported(const pn_integrator *integrator) {
    return integrator == &pn_integrator_reference || integrator == &pn_integrator_vpl ||
           integrator == &pn_integrator_lightcuts;
}

/* The reference's own per-worker scratch (its pn_reference_direct_scratch); the VPL paths need
 * none (a byte, so that NULL still means out of memory). */
void *pn_point_scratch_create(const pn_render_job *job, const pn_integrator *integrator) {
    return integrator == &pn_integrator_reference ? integrator->scratch_create(job) : calloc(1, 1);
}

void pn_point_scratch_free(const pn_integrator *integrator, void *scratch) {
    if (integrator == &pn_integrator_reference)
        integrator->scratch_free(scratch);
    else
        free(scratch);
}

/* The receiver of a calculation point: white Lambert (f = 1 after pn_vpl_irradiance_receiver),
 * viewed along its normal. */
static pn_vpl_receiver point_receiver(vec3 p, vec3 n) {
    pn_vpl_receiver r;
    memset(&r, 0, sizeof r);
    r.p = p;
    r.ng = r.ns = r.wo = n;
    r.kd = v3(1, 1, 1);
    r.exponent = 1.0f;
    return pn_vpl_irradiance_receiver(&r);
}

static bool reference_point(const pn_render_job *job, pn_reference_direct_scratch *s, vec3 p, vec3 n, uint32_t index,
                            double *lux, double *edi) {
    pn_bsdf b;
    memset(&b, 0, sizeof b);
    b.kind = PN_MATERIAL_LAMBERT_BLINN;
    b.kd = v3(1, 1, 1);
    b.ng = b.ns = n;
    b.entering = true;
    const uint32_t scramble = point_scramble(job, index);
    const uint32_t spp = point_wavelength_samples(job);
    double sum = 0.0, sum_mel = 0.0;
    for (uint32_t i = 0; i < spp; i++) {
        vec3 direct, irradiance = v3(0, 0, 0), irradiance_wl = v3(0, 0, 0);
        uint32_t rays = 0;
        double embree = 0.0;
        pn_swl wl_storage;
        b.wl = edi ? pn_eye_wavelengths(job, scramble, i, &wl_storage) : NULL;
        if (!pn_reference_direct_irradiance_wl(job, s, job->integrator_data, &b, p, n, i, scramble, NULL, false,
                                               &direct, &irradiance, b.wl ? &irradiance_wl : NULL, &rays, &embree))
            continue; /* no light can reach the point */
        sum += (double)pn_photometric(irradiance);
        if (b.wl) {
            float m = pn_swl_melanopic_edi_on(b.wl, irradiance_wl);
            if (isfinite(m)) sum_mel += (double)m;
        }
    }
    *lux = sum / ((double)spp * (double)job->shadow_rays);
    if (edi) *edi = sum_mel / ((double)spp * (double)job->shadow_rays);
    return true;
}

/* The wavelength samples of point `index` as receivers: r with sample i's wavelengths in out[i]
 * (NULL when out of memory). */
static pn_vpl_receiver *wavelength_receivers(const pn_render_job *job, const pn_vpl_receiver *r, uint32_t index,
                                             uint32_t count) {
    pn_vpl_receiver *out = malloc((size_t)count * sizeof *out);
    if (!out) return NULL;
    const uint32_t scramble = point_scramble(job, index);
    for (uint32_t i = 0; i < count; i++) {
        out[i] = *r;
        pn_eye_wavelengths(job, scramble, i, &out[i].wl);
    }
    return out;
}

static bool vpl_point(const pn_render_job *job, vec3 p, vec3 n, uint32_t index, double *lux, double *edi) {
    const pn_vpl_data *d = job->integrator_data;
    pn_vpl_receiver r = point_receiver(p, n);
    const uint32_t nw = edi ? point_wavelength_samples(job) : 0u;
    pn_vpl_receiver *rw = edi ? wavelength_receivers(job, &r, index, nw) : NULL;
    if (edi && !rw) return false;
    vec3 e = v3(0, 0, 0);
    double mel = 0.0;
    for (uint32_t k = 0; k < d->set.count; k++) {
        vec3 wi;
        float dist;
        vec3 c = pn_vpl_contribution(job->lights, &d->set.vpls[k], &r, d->set.min_dist2, &wi, &dist);
        if (v3_is_zero(c)) continue;
        float t = pn_vpl_transmittance(job->accel, &r, wi, dist, !job->opaque_glass);
        if (t > 0.0f) e = v3_madd(e, c, t);
        for (uint32_t i = 0; i < nw && t > 0.0f; i++) {
            vec3 cw = pn_vpl_contribution(job->lights, &d->set.vpls[k], &rw[i], d->set.min_dist2, &wi, &dist);
            mel += (double)t * (double)pn_swl_melanopic_edi_on(&rw[i].wl, cw);
        }
    }
    *lux = (double)pn_photometric(e);
    if (edi) *edi = mel / (double)nw;
    free(rw);
    return true;
}

static bool lightcuts_point(const pn_render_job *job, vec3 p, vec3 n, uint32_t index, double *lux, double *edi) {
    const pn_vpl_data *d = job->integrator_data;
    pn_lightcut_context cx = {job->lights,      job->accel,   &d->set,           &d->tree,
                              job->error_bound, job->max_cut, !job->opaque_glass};
    pn_vpl_receiver r = point_receiver(p, n);
    vec3 e;
    if (!pn_lightcut_eval(&cx, &r, &e, NULL, NULL, NULL)) return false;
    *lux = (double)pn_photometric(e);
    if (!edi) return true;
    const uint32_t nw = point_wavelength_samples(job);
    pn_vpl_receiver *rw = wavelength_receivers(job, &r, index, nw);
    if (!rw) return false;
    double mel = 0.0;
    bool ok = true;
    for (uint32_t i = 0; i < nw && ok; i++) {
        vec3 ew;
        ok = pn_lightcut_eval(&cx, &rw[i], &ew, NULL, NULL, NULL);
        float m = ok ? pn_swl_melanopic_edi_on(&rw[i].wl, ew) : 0.0f;
        if (isfinite(m)) mel += (double)m;
    }
    free(rw);
    *edi = mel / (double)nw;
    return ok;
}

bool pn_point_illuminance(const pn_render_job *job, const pn_integrator *integrator, void *scratch, vec3 p, vec3 n,
                          uint32_t index, double *lux, double *edi) {
    *lux = 0.0;
    if (edi) *edi = 0.0;
    if (integrator == &pn_integrator_reference)
        return reference_point(job, scratch, p, n, index, lux, job->spectral ? edi : NULL);
    if (integrator == &pn_integrator_vpl) return vpl_point(job, p, n, index, lux, job->spectral ? edi : NULL);
    if (integrator == &pn_integrator_lightcuts)
        return lightcuts_point(job, p, n, index, lux, job->spectral ? edi : NULL);
    return false;
}
