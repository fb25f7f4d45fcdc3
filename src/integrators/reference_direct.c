/* reference_direct.c — the reference integrator's direct-light estimator at one shading point
 * (IAS paper §5.1), factored out of reference.c so that `contour` estimates every light it does
 * not integrate itself with exactly the reference's code. With skip == NULL the arithmetic is
 * the reference's, operation for operation. */
#include "integrators/reference_direct.h"

#include "core/clock.h"
#include "core/sobol.h"

#include <stdlib.h>

bool pn_reference_direct_init(pn_reference_direct_scratch *s, const pn_render_job *job) {
    size_t n = (size_t)job->lights->count + 1;
    s->cdf = malloc(n * sizeof *s->cdf);
    s->index = malloc(n * sizeof *s->index);
    s->weight = malloc(n * sizeof *s->weight);
    s->exact = malloc(n * sizeof *s->exact);
    if (!s->cdf || !s->index || !s->weight || !s->exact) {
        pn_reference_direct_free(s);
        return false;
    }
    return true;
}

void pn_reference_direct_free(pn_reference_direct_scratch *s) {
    free(s->cdf);
    free(s->index);
    free(s->weight);
    free(s->exact);
    s->cdf = NULL;
    s->index = NULL;
    s->weight = NULL;
    s->exact = NULL;
}

/* Builds the per-point PDF over lights; returns the number of lights with non-zero
 * probability. cdf[k] is the running sum over index[0..k). */
static int build_light_pdf(const pn_render_job *job, vec3 p, vec3 n, pn_reference_direct_scratch *s,
                           const unsigned char *skip, float *total) {
    const pn_lights *L = job->lights;
    int m = 0;
    float acc = 0.0f;
    s->cdf[0] = 0.0f;
    pn_lights_irradiance_all(L, p, n, s->weight, s->exact);
    if (skip)
        for (int i = 0; i < L->count; i++)
            if (skip[i]) s->weight[i] = 0.0f;
    /* Compaction without a branch per light: about half of the lights of a room are behind any
     * given surface, and a mispredicted branch per light cost more than the sum itself. */
    for (int i = 0; i < L->count; i++) {
        float w = s->weight[i];
        int keep = (w > 0.0f) & (w < INFINITY); /* false for NaN too */
        acc += keep ? w : 0.0f;
        s->index[m] = i;
        s->cdf[m + 1] = acc;
        m += keep;
    }
    *total = acc;
    return m;
}

static int choose_light(const pn_reference_direct_scratch *s, int m, float total, float u, float *prob) {
    float target = u * total;
    int lo = 0, hi = m; /* find k with cdf[k] <= target < cdf[k+1] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (s->cdf[mid] <= target)
            lo = mid;
        else
            hi = mid;
    }
    *prob = (s->cdf[lo + 1] - s->cdf[lo]) / total;
    return lo;
}

bool pn_reference_direct(const pn_render_job *job, pn_reference_direct_scratch *s, const pn_light_bvh *bvh,
                         const pn_bsdf *b, vec3 p, vec3 wo, uint32_t i, uint32_t scramble, const unsigned char *skip,
                         bool timed, vec3 *sum, uint32_t *shadow_rays, double *embree_seconds) {
    return pn_reference_direct_irradiance(job, s, bvh, b, p, wo, i, scramble, skip, timed, sum, NULL, shadow_rays,
                                          embree_seconds);
}

bool pn_reference_direct_irradiance(const pn_render_job *job, pn_reference_direct_scratch *s, const pn_light_bvh *bvh,
                                    const pn_bsdf *b, vec3 p, vec3 wo, uint32_t i, uint32_t scramble,
                                    const unsigned char *skip, bool timed, vec3 *sum, vec3 *irradiance,
                                    uint32_t *shadow_rays, double *embree_seconds) {
    return pn_reference_direct_irradiance_wl(job, s, bvh, b, p, wo, i, scramble, skip, timed, sum, irradiance, NULL,
                                             shadow_rays, embree_seconds);
}

bool pn_reference_direct_irradiance_wl(const pn_render_job *job, pn_reference_direct_scratch *s,
                                       const pn_light_bvh *bvh, const pn_bsdf *b, vec3 p, vec3 wo, uint32_t i,
                                       uint32_t scramble, const unsigned char *skip, bool timed, vec3 *sum,
                                       vec3 *irradiance, vec3 *irradiance_wl, uint32_t *shadow_rays,
                                       double *embree_seconds) {
    if (irradiance_wl && !irradiance) irradiance_wl = NULL; /* only beside the RGB irradiance */
    const uint32_t S = job->shadow_rays;
    float total = 0.0f;
    int m = bvh ? 0 : build_light_pdf(job, p, b->ng, s, skip, &total);
    if (!bvh && !(m > 0 && total > 0.0f)) return false;
    vec3 direct = v3(0, 0, 0), incident = v3(0, 0, 0), incident_wl = v3(0, 0, 0);
    float eps = pn_accel_ray_epsilon(job->accel, p);
    vec3 origin = v3_madd(p, b->ng, eps);
    pn_light_sample_cache cache = {0};
    for (uint32_t j = 0; j < S; j++) {
        uint32_t k = i * S + j;
        float prob;
        const pn_light *l;
        if (bvh) {
            int li = pn_light_bvh_sample(bvh, p, b->ng, pn_sobol_sample(k, 5, scramble), &prob);
            if (li < 0 || !(prob > 0.0f) || (skip && skip[li])) continue;
            l = &job->lights->lights[li];
        } else {
            int c = choose_light(s, m, total, pn_sobol_sample(k, 5, scramble), &prob);
            l = &job->lights->lights[s->index[c]];
        }
        pn_light_sample ls;
        if (!pn_light_sample_point_cached(job->lights, l, origin, pn_sobol_sample(k, 6, scramble),
                                          pn_sobol_sample(k, 7, scramble), &cache, &ls))
            continue;
        vec3 f = pn_bsdf_eval(b, wo, ls.wi);
        float cos_i = v3_dot(b->ns, ls.wi);
        if (v3_is_zero(f) && !(irradiance && cos_i > 0.0f)) continue;
        (*shadow_rays)++;
        float tmax = isinf(ls.dist) ? INFINITY : ls.dist * (1.0f - 1e-4f) - eps;
        double t_ray = timed ? pn_clock_seconds() : 0.0;
        float visibility = pn_shadow_transmittance(job, origin, ls.wi, 0.0f, tmax);
        if (timed) *embree_seconds += pn_clock_seconds() - t_ray;
        if (!(visibility > 0.0f)) continue;
        float w = cos_i / (ls.pdf * prob);
        if (visibility != 1.0f) w *= visibility;
        /* Spectral mode: the sample's radiance at the BSDF's wavelengths; the illuminance stays RGB,
         * the irradiance at the wavelengths (melanopic EDI) is asked for on its own. */
        const vec3 radiance = pn_light_radiance_spectral(job->lights, l, ls.radiance, b->wl);
        direct = v3_add(direct, v3_scale(v3_mul(f, radiance), w));
        if (irradiance) incident = v3_madd(incident, ls.radiance, w);
        if (irradiance_wl) incident_wl = v3_madd(incident_wl, radiance, w);
    }
    *sum = direct;
    if (irradiance) *irradiance = incident;
    if (irradiance_wl) *irradiance_wl = incident_wl;
    return true;
}
