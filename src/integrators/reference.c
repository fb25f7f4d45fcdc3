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
#include "integrators/reference_direct.h"

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

static void *reference_scratch_create(const pn_render_job *job) {
    pn_reference_direct_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    if (!pn_reference_direct_init(s, job)) {
        free(s);
        return NULL;
    }
    return s;
}

static void reference_scratch_free(void *p) {
    pn_reference_direct_scratch *s = p;
    if (!s) return;
    pn_reference_direct_free(s);
    free(s);
}

typedef struct pixel_state {
    vec3 weighted_sum, weighted_emitted;
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
    pn_reference_direct_scratch *s = scratch;
    const uint32_t S = job->shadow_rays;
    for (int pi = 0; pi < batch->count; pi++) {
        int px = batch->pixels[pi][0], py = batch->pixels[pi][1];
        /* One scrambled Sobol sequence per pixel: the value is independent of the batch. */
        uint32_t scramble = pn_pixel_scramble(job, px, py);
        uint32_t index = 0;
        pixel_state ps;
        memset(&ps, 0, sizeof ps);
        pn_pixel_estimate *o = &out[pi];
        memset(o, 0, sizeof *o);
        o->depth = INFINITY;
        double embree_seconds = 0.0;
        while (!pixel_done(job, &ps)) {
            uint32_t i = index++;
            float fw, u_specular;
            vec3 ro, rd;
            pn_pixel_eye_sample(job, px, py, scramble, i, &ro, &rd, &fw, &u_specular);
            const bool timed = i % PN_TIMING_STRIDE == 0u;
            double t_start = timed ? pn_clock_seconds() : 0.0;
            pn_eye_path path;
            pn_trace_eye_path(job, ro, rd, u_specular, &path);
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
                vec3 direct = v3(0, 0, 0);
                if (pn_reference_direct(job, s, bvh, &b, path.hit.p, path.wo, i, scramble, NULL, timed, &direct,
                                        &ps.shadow_rays, &embree_seconds))
                    value = v3_add(value, v3_mul(path.throughput, v3_scale(direct, 1.0f / (float)S)));
            }
            if (!v3_is_finite(value)) value = path.emitted = v3(0, 0, 0);
            ps.n++;
            ps.weighted_sum = v3_madd(ps.weighted_sum, value, fw);
            ps.weighted_emitted = v3_madd(ps.weighted_emitted, path.emitted, fw);
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
        if (ps.weight_sum != 0.0) {
            o->radiance = v3_scale(ps.weighted_sum, (float)(1.0 / ps.weight_sum));
            o->emitted = v3_scale(ps.weighted_emitted, (float)(1.0 / ps.weight_sum));
        }
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
    .name = "reference",
    .prepare = reference_prepare,
    .release = reference_release,
    .scratch_create = reference_scratch_create,
    .scratch_free = reference_scratch_free,
    .render_batch = reference_render_batch,
};
