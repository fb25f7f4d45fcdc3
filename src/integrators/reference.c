/* reference.c — the Monte Carlo reference of Donikian et al. 2006, §5.1 ("Reference Solution
 * Implementation"): at each eye-ray hit, a fixed PDF over all lights proportional to each light's
 * unoccluded irradiance at the point (zero behind the surface or facing away); a fixed number of
 * shadow rays per eye ray; scrambled Sobol numbers (footnote 1 resets the sequence once per 8x8
 * block; here it restarts for every pixel, with its own Owen scrambling — see below); eye rays
 * added to a pixel until its relative variance s^2/L^2 falls below the
 * threshold, with a maximum number of shadow rays per pixel (20,000) and a minimum number before
 * a pixel may be declared black (§5.9; 2,500 as for the paper's hard scenes) — or a fixed spp.
 *
 * Details the paper leaves open, as done here: s^2 is the variance of the pixel's mean (the
 * sample variance of the eye-ray values' luminance over their number, as in its eq. 7) and L the
 * mean; at least 4 eye rays are taken before the test; eye rays that cast no shadow rays (they see
 * an emitter, the sky, or nothing) count S shadow rays each against the 20,000 budget, so that no
 * pixel runs unbounded; pixels whose eye rays all see nothing that reflects light stop as soon as
 * the test allows. The light PDF comes from pn_lights_irradiance_all (lights/light_pdf.c): exact
 * for points, spots, distant lights, spheres above the horizon and near polygons, a point
 * approximation for small far polygons, spherical harmonics for environment maps.
 *
 * Departure from footnote 1: a pixel's value must not depend on which other pixels were evaluated
 * before it in the same batch, so that a progressive driver (dcm) that evaluates scattered pixels
 * in its own order gets exactly the pixels of the full render. Each pixel therefore draws from
 * its own Owen-scrambled Sobol sequence (scramble = hash(seed, pixel x, pixel y)), index 0 up.
 *
 * A second light sampler replaces the PDF over all lights when asked (--light-sampler bvh):
 * pbrt-v4's light BVH (lights/light_bvh.c), which descends a tree of light bounds by importance
 * instead of evaluating every light, so that IAS can also be compared with the sampler pbrt-v4
 * renders with. Everything else is the same.
 *
 * Quasi-random dimensions per eye ray i of a pixel: 0-1 pixel filter, 2-3 lens, 4 specular
 * choice; per shadow ray j, with index i * S + j: 5 light choice, 6-7 point on the light. */
#include "integrators/integrator.h"

#include "core/clock.h"
#include "core/sobol.h"
#include "core/rng.h"
#include "lights/light_bvh.h"
#include "shade/bsdf.h"

#include <stdlib.h>
#include <string.h>

/* Every PN_TIMING_STRIDE-th eye ray of a pixel has its Embree calls timed; the sum, scaled by the
 * stride, estimates the time spent in Embree without timing every ray. */
#define PN_TIMING_STRIDE 8u

typedef struct reference_scratch {
    float *cdf;    /* light_count + 1 */
    int *index;    /* lights with non-zero weight */
    float *weight; /* unoccluded irradiance of every light */
    int *exact;    /* scratch of pn_lights_irradiance_all */
} reference_scratch;

static void *reference_scratch_create(const pn_render_job *job) {
    reference_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    size_t n = (size_t)job->lights->count + 1;
    s->cdf = malloc(n * sizeof *s->cdf);
    s->index = malloc(n * sizeof *s->index);
    s->weight = malloc(n * sizeof *s->weight);
    s->exact = malloc(n * sizeof *s->exact);
    if (!s->cdf || !s->index || !s->weight || !s->exact) {
        free(s->cdf);
        free(s->index);
        free(s->weight);
        free(s->exact);
        free(s);
        return NULL;
    }
    return s;
}

static void reference_scratch_free(void *p) {
    reference_scratch *s = p;
    if (!s) return;
    free(s->cdf);
    free(s->index);
    free(s->weight);
    free(s->exact);
    free(s);
}

/* Builds the per-point PDF over lights; returns the number of lights with non-zero
 * probability. cdf[k] is the running sum over index[0..k). */
static int build_light_pdf(const pn_render_job *job, vec3 p, vec3 n, reference_scratch *s, float *total) {
    const pn_lights *L = job->lights;
    int m = 0;
    float acc = 0.0f;
    s->cdf[0] = 0.0f;
    pn_lights_irradiance_all(L, p, n, s->weight, s->exact);
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

static int choose_light(const reference_scratch *s, int m, float total, float u, float *prob) {
    float target = u * total;
    int lo = 0, hi = m; /* find k with cdf[k] <= target < cdf[k+1] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (s->cdf[mid] <= target) lo = mid;
        else hi = mid;
    }
    *prob = (s->cdf[lo + 1] - s->cdf[lo]) / total;
    return lo;
}

typedef struct pixel_state {
    vec3 weighted_sum;
    double weight_sum;
    double lum_mean, lum_m2; /* Welford on the luminance of eye-ray values */
    uint32_t n, shadow_rays, specular_rays;
    bool any_nonzero;
} pixel_state;

static bool pixel_done(const pn_render_job *job, const pixel_state *ps) {
    if (job->spp > 0) return ps->n >= job->spp;
    if (ps->shadow_rays >= job->max_shadow_rays) return true;
    /* Eye rays that cast no shadow rays (a pixel that sees emitters, the sky or unlit specular
     * paths) count against the same budget as if each had cast its shadow rays. */
    if ((uint64_t)ps->n * job->shadow_rays >= job->max_shadow_rays) return true;
    if (ps->n >= 1u << 20) return true;
    if (ps->n < job->min_eye_rays) return false;
    if (!ps->any_nonzero) {
        /* Black so far: only stop once enough shadow rays saw nothing, or if the pixel casts no
         * shadow rays at all (it sees only the void or unlit specular paths). */
        return ps->shadow_rays >= job->min_shadow_rays_black || ps->shadow_rays == 0;
    }
    double var_of_mean = ps->n > 1 ? ps->lum_m2 / ((double)(ps->n - 1) * (double)ps->n) : (double)INFINITY;
    double mean = ps->lum_mean;
    return var_of_mean <= job->threshold * mean * mean;
}

static pn_status reference_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                        void *scratch) {
    reference_scratch *s = scratch;
    const uint32_t S = job->shadow_rays;
    for (int pi = 0; pi < batch->count; pi++) {
        int px = batch->pixels[pi][0], py = batch->pixels[pi][1];
        /* One scrambled Sobol sequence per pixel: the value is independent of the batch. */
        uint32_t scramble = (uint32_t)pn_hash3(job->seed, (uint64_t)(uint32_t)px, (uint64_t)(uint32_t)py);
        uint32_t index = 0;
        pixel_state ps;
        memset(&ps, 0, sizeof ps);
        pn_pixel_estimate *o = &out[pi];
        memset(o, 0, sizeof *o);
        o->depth = INFINITY;
        double embree_seconds = 0.0;
        while (!pixel_done(job, &ps)) {
            uint32_t i = index++;
            float rx, ry, fw;
            pn_camera_filter_sample(&job->camera, px, py, pn_sobol_sample(i, 0, scramble),
                                    pn_sobol_sample(i, 1, scramble), &rx, &ry, &fw);
            vec3 ro, rd;
            pn_camera_ray(&job->camera, rx, ry, pn_sobol_sample(i, 2, scramble), pn_sobol_sample(i, 3, scramble),
                          &ro, &rd);
            const bool timed = i % PN_TIMING_STRIDE == 0u;
            double t_start = timed ? pn_clock_seconds() : 0.0;
            pn_eye_path path;
            pn_trace_eye_path(job, ro, rd, pn_sobol_sample(i, 4, scramble), &path);
            if (timed) embree_seconds += pn_clock_seconds() - t_start;
            if (ps.n == 0) {
                o->depth = path.first_depth;
                o->normal = path.first_normal;
                o->albedo = path.first_albedo;
            }
            ps.specular_rays += path.rays - 1;
            vec3 value = path.emitted;
            if (path.has_point) {
                pn_bsdf b;
                pn_bsdf_at(job->scene, &path.hit, path.wo, &b);
                const pn_light_bvh *bvh = job->integrator_data; /* set only with the BVH sampler */
                float total = 0.0f;
                int m = bvh ? 0 : build_light_pdf(job, path.hit.p, b.ng, s, &total);
                if (bvh || (m > 0 && total > 0.0f)) {
                    vec3 direct = v3(0, 0, 0);
                    float eps = pn_accel_ray_epsilon(job->accel, path.hit.p);
                    vec3 origin = v3_madd(path.hit.p, b.ng, eps);
                    pn_light_sample_cache cache = {0};
                    for (uint32_t j = 0; j < S; j++) {
                        uint32_t k = i * S + j;
                        float prob;
                        const pn_light *l;
                        if (bvh) {
                            int li = pn_light_bvh_sample(bvh, path.hit.p, b.ng, pn_sobol_sample(k, 5, scramble), &prob);
                            if (li < 0 || !(prob > 0.0f)) continue;
                            l = &job->lights->lights[li];
                        } else {
                            int c = choose_light(s, m, total, pn_sobol_sample(k, 5, scramble), &prob);
                            l = &job->lights->lights[s->index[c]];
                        }
                        pn_light_sample ls;
                        if (!pn_light_sample_point_cached(job->lights, l, origin, pn_sobol_sample(k, 6, scramble),
                                                          pn_sobol_sample(k, 7, scramble), &cache, &ls))
                            continue;
                        vec3 f = pn_bsdf_eval(&b, path.wo, ls.wi);
                        if (v3_is_zero(f)) continue;
                        float cos_i = v3_dot(b.ns, ls.wi);
                        ps.shadow_rays++;
                        float tmax = isinf(ls.dist) ? INFINITY : ls.dist * (1.0f - 1e-4f) - eps;
                        double t_ray = timed ? pn_clock_seconds() : 0.0;
                        bool blocked = pn_accel_occluded(job->accel, origin, ls.wi, 0.0f, tmax);
                        if (timed) embree_seconds += pn_clock_seconds() - t_ray;
                        if (blocked) continue;
                        float w = cos_i / (ls.pdf * prob);
                        direct = v3_add(direct, v3_scale(v3_mul(f, ls.radiance), w));
                    }
                    value = v3_add(value, v3_mul(path.throughput, v3_scale(direct, 1.0f / (float)S)));
                }
            }
            if (!v3_is_finite(value)) value = v3(0, 0, 0);
            ps.n++;
            ps.weighted_sum = v3_madd(ps.weighted_sum, value, fw);
            ps.weight_sum += (double)fw;
            double y = (double)v3_luminance(value);
            if (y != 0.0 || !v3_is_zero(value)) ps.any_nonzero = true;
            double delta = y - ps.lum_mean;
            ps.lum_mean += delta / (double)ps.n;
            ps.lum_m2 += delta * (y - ps.lum_mean);
        }
        o->eye_rays = ps.n;
        o->shadow_rays = ps.shadow_rays;
        o->specular_rays = ps.specular_rays;
        o->embree_seconds = (float)(embree_seconds * PN_TIMING_STRIDE);
        if (ps.weight_sum != 0.0) o->radiance = v3_scale(ps.weighted_sum, (float)(1.0 / ps.weight_sum));
        double var_of_mean = ps.n > 1 ? ps.lum_m2 / ((double)(ps.n - 1) * (double)ps.n) : 0.0;
        o->relative_variance = ps.lum_mean > 0.0 ? (float)(var_of_mean / (ps.lum_mean * ps.lum_mean)) : 0.0f;
    }
    return PN_OK;
}

/* With the BVH light sampler, the tree is built once per render. */
static pn_status reference_prepare(pn_render_job *job, pn_err *err) {
    job->integrator_data = NULL;
    if (job->light_sampler != PN_LIGHT_SAMPLER_BVH) return PN_OK;
    pn_light_bvh *bvh = calloc(1, sizeof *bvh);
    if (!bvh) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the light BVH");
    pn_status st = pn_light_bvh_build(job->lights, bvh, err);
    if (st != PN_OK) {
        free(bvh);
        return st;
    }
    job->integrator_data = bvh;
    return PN_OK;
}

static void reference_release(pn_render_job *job) {
    pn_light_bvh *bvh = job->integrator_data;
    if (bvh) pn_light_bvh_free(bvh);
    free(bvh);
    job->integrator_data = NULL;
}

const pn_integrator pn_integrator_reference = {
    "reference", reference_prepare, reference_release, NULL, reference_scratch_create, reference_scratch_free,
    reference_render_batch,
};

const pn_integrator *pn_integrator_find(pn_integrator_kind kind) {
    switch (kind) {
    case PN_INTEGRATOR_DEFAULT:
    case PN_INTEGRATOR_REFERENCE: return &pn_integrator_reference;
    case PN_INTEGRATOR_IAS: return &pn_integrator_ias;
    /* VPL integrators (issue 5) */
    case PN_INTEGRATOR_VPL: return &pn_integrator_vpl;
    case PN_INTEGRATOR_LIGHTCUTS: return &pn_integrator_lightcuts;
    case PN_INTEGRATOR_ILLUMCUT: return &pn_integrator_illumcut;
    }
    return NULL;
}
