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
 * The stopping rule (adaptive_rule; docs/adaptive-sampling.md has the measurements and commands).
 * `paper` is §5.1/§5.9 as described above. It decides from the same samples it averages, so a
 * pixel stops when its first samples happen to look converged: measured on hall-many-matte (crop
 * 0.45-0.55, against 2048 spp) +0.96% mean luminance at T = 0.005, +0.29% at T = 0.0002, with
 * relMSE falling only 7.6x for 25x the threshold; with --light-sampler bvh on bathroom-72-matte a
 * pixel whose first BVH samples were all rejected casts no shadow ray and is finalised black after
 * 4 eye rays (-17.5% at T = 0.01). `cross`, the default, departs from the paper in three ways:
 *
 *  1. Two independent eye-ray streams per pixel (A: the pixel's fixed-spp sequence; B: its own
 *     scramble). Each runs a pilot; A's count is set by B's pilot only and B's by A's, and the
 *     pixel is (mean A + mean B) / 2 with weights fixed in advance. Given its count, a stream's
 *     mean is a plain average of eye rays independent of that count: unbiased, whatever the
 *     threshold. Reason: any rule that stops on the kept samples' own s^2 / L^2 is biased (the
 *     selection favours high or low means). Measured: hall-many +0.047% at T = 0.005, -0.006% at
 *     0.001, -0.007% at 0.0002; relMSE 4.9e-4, 6.0e-5, 1.1e-5 (log-log slope 1.19).
 *  2. The pilot length (9 eye rays per stream) from the variance estimate's reliability (the
 *     relative standard error of a sample variance of n normal values is sqrt(2 / (n - 1)), 0.5
 *     at 9), and a floor on every count that grows as 1 / T (PN_CROSS_FLOOR): without it, a pixel
 *     whose pilot missed a rare contribution kept the pilot's count at every threshold and the
 *     error stopped falling (tests/test_adaptive.c: slope 0.15 without the floor, 1.3 with it).
 *  3. Black pixels by a binomial bound: a pilot that saw only zeros in k trials (light samples,
 *     or eye rays when it reached no lit surface) bounds the hit rate by p_up = ln(100) / k at
 *     99%, and the other stream gets the count a pixel lit at p_up needs to meet T, which grows
 *     as 1 / T; a black pixel is then an average of zeros, never a decision. Measured: bathroom-72
 *     --light-sampler bvh (crop 0.375-0.625, T = 0.01) +0.04% instead of -17.5%; thin bars lit on
 *     1/8 of each pixel (tests/test_adaptive.c) 0 black pixels instead of 173 of 256.
 * The budget (max_shadow_rays) is split between the streams. Cost: at equal relMSE, threshold
 * mode is 1.1-1.3x faster than the best fixed spp only on hall-many at T <= 0.001 and slower
 * elsewhere (0.2-1.0x), never the 1.5x asked for, so the reference's default is a fixed 64 spp
 * (render.c); at equal relMSE cross is 1.2-6.6x faster than paper in 23 of 24 bench comparisons.
 *
 * A second light sampler replaces the PDF over all lights when asked (--light-sampler bvh):
 * pbrt-v4's light BVH (lights/light_bvh.c), which descends a tree of light bounds by importance
 * instead of evaluating every light, so that IAS can also be compared with the sampler pbrt-v4
 * renders with. Everything else is the same.
 *
 * Quasi-random dimensions per eye ray i of a pixel: 0-1 pixel filter, 2-3 lens, 4 specular
 * choice; per shadow ray j, with index i * S + j: 5 light choice, 6-7 point on the light.
 *
 * The eye rays are the driver's (render/batch.h, pn_eye_hit): the tiled and progressive drivers
 * trace in advance the eye rays every pixel takes (reference_batch_hits: the fixed spp, or the
 * adaptive rule's first eye rays of stream A) and the batch's callback traces the rest when the
 * rule asks for them (pn_batch_eye_hits). The integrator traces no camera ray or specular chain;
 * it continues each eye ray's sequence (its scramble, its index) for the shadow rays. */
#include "integrators/integrator.h"
#include "integrators/reference_direct.h"

#include "core/photometry.h"
#include "core/sobol.h"
#include "lights/light_bvh.h"
#include "shade/bsdf.h"
#include "spectral/melanopic.h"
#include "spectral/transport.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Eye hits asked of the driver at once beyond its in-advance ones (pn_batch_eye_hits). */
#define PN_REFERENCE_CHUNK 16u

/* Per-worker scratch. The direct estimator's comes first: integrators/point_eval.c takes this
 * scratch as a pn_reference_direct_scratch. */
typedef struct reference_scratch {
    pn_reference_direct_scratch direct;
    pn_eye_hit hits[PN_REFERENCE_CHUNK]; /* the driver's further eye hits */
} reference_scratch;

static void *reference_scratch_create(const pn_render_job *job) {
    reference_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    if (!pn_reference_direct_init(&s->direct, job)) {
        free(s);
        return NULL;
    }
    return s;
}

static void reference_scratch_free(void *p) {
    reference_scratch *s = p;
    if (!s) return;
    pn_reference_direct_free(&s->direct);
    free(s);
}

typedef struct pixel_state {
    vec3 weighted_sum, weighted_emitted;
    double weighted_lux; /* PN_AOV_ILLUMINANCE: filter-weighted illuminance of the eye rays */
    double weighted_mel; /* PN_AOV_MELANOPIC_EDI: the same for the melanopic EDI (spectral mode) */
    double weight_sum;
    double lum_mean, lum_m2; /* Welford on the luminance of eye-ray values */
    uint32_t n, shadow_rays, specular_rays;
    uint32_t non_finite;    /* eye rays whose value was not finite, counted as 0 */
    uint32_t light_samples; /* light samples drawn (S per eye ray that had a light to sample) */
    bool any_nonzero;
} pixel_state;

/* The paper's rule (adaptive_rule = paper) and the fixed-spp count. */
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

/* Per-pixel outputs of the first eye ray and the timing, shared by both rules; where the pixel's
 * eye hits come from (the batch). */
typedef struct pixel_context {
    const pn_render_job *job;
    reference_scratch *s;
    const pn_batch *batch;
    int pi;
    pn_pixel_estimate *o;
    double embree_seconds;
    bool first_done;
} pixel_context;

/* Adds the eye ray of the driver's hit h (sample h->index of the stream h->scramble) to ps. */
static void add_eye_ray(pixel_context *c, const pn_eye_hit *h, pixel_state *ps) {
    const pn_render_job *job = c->job;
    const uint32_t S = job->shadow_rays;
    const uint32_t i = h->index, scramble = h->scramble;
    const float fw = h->weight;
    const bool timed = i % PN_EYE_TIMING_STRIDE == 0u;
    c->embree_seconds += (double)h->seconds;
    const pn_eye_path *path = &h->path;
    if (!c->first_done) {
        c->first_done = true;
        c->o->depth = path->first_depth;
        c->o->normal = path->first_normal;
        c->o->albedo = path->first_albedo;
    }
    ps->specular_rays += path->rays - 1;
    const pn_swl *wl = pn_eye_hit_wavelengths(job, h);
    vec3 value = path->emitted;
    if (path->has_point) {
        pn_bsdf b;
        pn_eye_hit_bsdf(job, h, &b);
        const pn_light_bvh *bvh = job->integrator_data; /* set only with the BVH sampler */
        vec3 direct = v3(0, 0, 0), incident = v3(0, 0, 0), incident_wl = v3(0, 0, 0);
        const bool mel = (job->aovs & PN_AOV_MELANOPIC_EDI) && pn_swl_active(wl);
        const bool lux = (job->aovs & PN_AOV_ILLUMINANCE) != 0 || mel;
        if (pn_reference_direct_irradiance_wl(job, &c->s->direct, bvh, &b, path->hit.p, path->wo, i, scramble, NULL,
                                              timed, &direct, lux ? &incident : NULL, mel ? &incident_wl : NULL,
                                              &ps->shadow_rays, &c->embree_seconds)) {
            value = v3_add(value, v3_mul(path->throughput, v3_scale(direct, 1.0f / (float)S)));
            ps->light_samples += S;
            float e = pn_photometric(incident) / (float)S;
            if (lux && isfinite(e)) ps->weighted_lux += (double)e * (double)fw;
            float m = mel ? pn_swl_melanopic_edi_on(wl, incident_wl) / (float)S : 0.0f;
            if (mel && isfinite(m)) ps->weighted_mel += (double)m * (double)fw;
        }
    }
    /* Spectral mode: the eye ray's value at its wavelengths to linear sRGB, where it is added. */
    value = pn_swl_rgb(wl, value);
    vec3 emitted = pn_swl_rgb(wl, path->emitted);
    if (!v3_is_finite(value)) {
        value = emitted = v3(0, 0, 0);
        ps->non_finite++;
    }
    ps->n++;
    ps->weighted_sum = v3_madd(ps->weighted_sum, value, fw);
    ps->weighted_emitted = v3_madd(ps->weighted_emitted, emitted, fw);
    ps->weight_sum += (double)fw;
    double y = (double)v3_luminance(value);
    if (y != 0.0 || !v3_is_zero(value)) ps->any_nonzero = true;
    double delta = y - ps->lum_mean;
    ps->lum_mean += delta / (double)ps->n;
    ps->lum_m2 += delta * (y - ps->lum_mean);
}

/* Adds eye rays first..end-1 of stream seq, taken from the batch PN_REFERENCE_CHUNK at a time;
 * when `cancellable`, stops before any of them once the render is cancelled. */
static void add_eye_rays(pixel_context *c, pn_eye_sequence seq, uint32_t first, uint32_t end, bool cancellable,
                         pixel_state *ps) {
    for (uint32_t i = first; i < end;) {
        if (cancellable && atomic_load(c->job->cancel)) return;
        uint32_t n = end - i < PN_REFERENCE_CHUNK ? end - i : PN_REFERENCE_CHUNK;
        const pn_eye_hit *h = pn_batch_eye_hits(c->job, c->batch, c->pi, seq, i, n, c->s->hits);
        for (uint32_t k = 0; k < n; k++) {
            if (cancellable && k > 0 && atomic_load(c->job->cancel)) return;
            add_eye_ray(c, &h[k], ps);
        }
        i += n;
    }
}

/* ---- the cross rule (adaptive_rule = cross; the header names each departure) -------------- */

/* Eye rays per stream before its statistics size the other stream. The relative standard error
 * of a sample variance from n normal values is sqrt(2 / (n - 1)); n = 9 makes it 0.5, so the
 * count it sets is within a factor 1.5 of the right one about two times in three. Heavier tails
 * make the estimate worse, which costs time (a count set too high or too low), never bias. */
#define PN_CROSS_PILOT 9u
/* The black-pixel rule's confidence: a stream whose pilot saw only zeros gives the other stream
 * the light samples a pixel needs if lit at the largest rate that its pilot misses with
 * probability PN_CROSS_BLACK_DELTA (cross_count). */
#define PN_CROSS_BLACK_DELTA 0.01

static uint32_t cross_pilot(const pn_render_job *job) {
    uint32_t half = (job->min_eye_rays + 1u) / 2u;
    return half > PN_CROSS_PILOT ? half : PN_CROSS_PILOT;
}

/* Eye rays per stream that the whole pixel may use: half the paper's budget each. */
static uint32_t cross_budget(const pn_render_job *job) {
    uint64_t n = job->max_shadow_rays / (2u * (uint64_t)job->shadow_rays);
    if (n > (1u << 19)) n = 1u << 19;
    uint32_t pilot = cross_pilot(job);
    return n > pilot ? (uint32_t)n : pilot;
}

/* The floor of every count, as a relative variance per eye ray: the count never falls below
 * what a pixel of this relative variance needs (PN_CROSS_FLOOR / (2 t) per stream). A pilot of
 * a few rays cannot see a contribution that arrives on one eye ray in fifty; without a floor such
 * a pixel keeps the pilot's count at every threshold and its error does not fall with t. With
 * it, every count grows as 1 / t. 0.25 is the relative variance of a pixel whose light is
 * visible from 80% of it (Bernoulli: 0.2 / 0.8). */
#define PN_CROSS_FLOOR 0.25

/* Eye rays for a stream, from the pilot statistics of the *other* stream only. */
static uint32_t cross_count(const pn_render_job *job, const pixel_state *pilot) {
    const uint32_t n0 = cross_pilot(job), budget = cross_budget(job);
    const double t2 = 2.0 * job->threshold;
    double n;
    if (pilot->any_nonzero && pilot->lum_mean > 0.0 && pilot->n > 1) {
        /* The output is the mean of two streams' means, each of variance v / N; both at N it is
         * v / (2N), so N = v / (2 t L^2) per stream meets s^2 / L^2 = t. */
        double v = pilot->lum_m2 / (double)(pilot->n - 1);
        n = v / (t2 * pilot->lum_mean * pilot->lum_mean);
    } else if (pilot->any_nonzero) {
        n = (double)budget; /* light of zero luminance (a colour that cancels): no relative scale */
    } else {
        /* Black so far. k trials without a hit (light samples drawn, or, when none was drawn,
         * eye rays that might have found a lit surface) bound the hit rate by
         * p_up = ln(1 / delta) / k with confidence 1 - delta, as (1 - p)^k <= exp(-p k). A pixel
         * hit on a fraction p of its trials (each hit of similar value) has a relative variance
         * of (1 - p) / p per trial and needs (1 - p) / (p t) trials to meet the threshold t:
         * the other stream gets the count a pixel hit at p_up needs, which grows as 1 / t. */
        double trials = pilot->light_samples > 0 ? (double)pilot->light_samples : (double)pilot->n;
        double per_ray = pilot->light_samples > 0 ? (double)job->shadow_rays : 1.0;
        double p_up = fmin(1.0, log(1.0 / PN_CROSS_BLACK_DELTA) / trials);
        n = (1.0 - p_up) / (p_up * t2) / per_ray;
    }
    n = fmax(n, PN_CROSS_FLOOR / t2);
    if (!(n < (double)budget)) return budget;
    uint32_t k = (uint32_t)ceil(n);
    return k > n0 ? k : n0;
}

static void render_pixel_cross(pixel_context *c) {
    const pn_render_job *job = c->job;
    /* Stream A is the fixed-spp sequence of the pixel (PN_EYE_SEQ_PIXEL); stream B has its own
     * scramble (PN_EYE_SEQ_CROSS_B, pn_eye_sequence_scramble). */
    pixel_state a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    const uint32_t n0 = cross_pilot(job);
    add_eye_rays(c, PN_EYE_SEQ_PIXEL, 0, n0, false, &a);
    add_eye_rays(c, PN_EYE_SEQ_CROSS_B, 0, n0, false, &b);
    /* Each stream's count depends only on the other's pilot, which is independent of it: given
     * its count, a stream's mean is a plain average of independent eye rays, hence unbiased. */
    const uint32_t na = cross_count(job, &b), nb = cross_count(job, &a);
    add_eye_rays(c, PN_EYE_SEQ_PIXEL, n0, na, true, &a);
    add_eye_rays(c, PN_EYE_SEQ_CROSS_B, n0, nb, true, &b);
    pn_pixel_estimate *o = c->o;
    o->eye_rays = a.n + b.n;
    o->shadow_rays = a.shadow_rays + b.shadow_rays;
    o->non_finite = a.non_finite + b.non_finite;
    o->specular_rays = a.specular_rays + b.specular_rays;
    /* Equal weights, fixed in advance: weights by count would depend on both pilots. */
    vec3 ra = a.weight_sum != 0.0 ? v3_scale(a.weighted_sum, (float)(1.0 / a.weight_sum)) : v3(0, 0, 0);
    vec3 rb = b.weight_sum != 0.0 ? v3_scale(b.weighted_sum, (float)(1.0 / b.weight_sum)) : v3(0, 0, 0);
    vec3 ea = a.weight_sum != 0.0 ? v3_scale(a.weighted_emitted, (float)(1.0 / a.weight_sum)) : v3(0, 0, 0);
    vec3 eb = b.weight_sum != 0.0 ? v3_scale(b.weighted_emitted, (float)(1.0 / b.weight_sum)) : v3(0, 0, 0);
    o->radiance = v3_scale(v3_add(ra, rb), 0.5f);
    o->emitted = v3_scale(v3_add(ea, eb), 0.5f);
    double la = a.weight_sum != 0.0 ? a.weighted_lux / a.weight_sum : 0.0;
    double lb = b.weight_sum != 0.0 ? b.weighted_lux / b.weight_sum : 0.0;
    o->illuminance = (float)(0.5 * (la + lb));
    double ma = a.weight_sum != 0.0 ? a.weighted_mel / a.weight_sum : 0.0;
    double mb = b.weight_sum != 0.0 ? b.weighted_mel / b.weight_sum : 0.0;
    o->melanopic_edi = (float)(0.5 * (ma + mb));
    double va = a.n > 1 ? a.lum_m2 / ((double)(a.n - 1) * (double)a.n) : 0.0;
    double vb = b.n > 1 ? b.lum_m2 / ((double)(b.n - 1) * (double)b.n) : 0.0;
    double mean = 0.5 * (a.lum_mean + b.lum_mean);
    o->relative_variance = mean > 0.0 ? (float)(0.25 * (va + vb) / (mean * mean)) : 0.0f;
}

static pn_status reference_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                        void *scratch) {
    reference_scratch *s = scratch;
    for (int pi = 0; pi < batch->count; pi++) {
        /* One scrambled Sobol sequence per pixel (the driver's eye hits): the value is
         * independent of the batch. */
        pn_pixel_estimate *o = &out[pi];
        memset(o, 0, sizeof *o);
        o->depth = INFINITY;
        pixel_context c = {job, s, batch, pi, o, 0.0, false};
        if (job->spp == 0 && job->adaptive_rule == PN_ADAPTIVE_CROSS) {
            render_pixel_cross(&c);
            o->embree_seconds = (float)(c.embree_seconds * PN_EYE_TIMING_STRIDE);
            continue;
        }
        pixel_state ps;
        memset(&ps, 0, sizeof ps);
        if (job->spp > 0) {
            add_eye_rays(&c, PN_EYE_SEQ_PIXEL, 0, job->spp, false, &ps);
        } else {
            /* The paper's rule decides after every eye ray: one at a time. */
            uint32_t index = 0;
            while (!pixel_done(job, &ps)) {
                const pn_eye_hit *h = pn_batch_eye_hits(job, batch, pi, PN_EYE_SEQ_PIXEL, index++, 1, s->hits);
                add_eye_ray(&c, h, &ps);
            }
        }
        o->eye_rays = ps.n;
        o->non_finite = ps.non_finite;
        o->shadow_rays = ps.shadow_rays;
        o->specular_rays = ps.specular_rays;
        o->embree_seconds = (float)(c.embree_seconds * PN_EYE_TIMING_STRIDE);
        if (ps.weight_sum != 0.0) {
            o->radiance = v3_scale(ps.weighted_sum, (float)(1.0 / ps.weight_sum));
            o->emitted = v3_scale(ps.weighted_emitted, (float)(1.0 / ps.weight_sum));
            o->illuminance = (float)(ps.weighted_lux / ps.weight_sum);
            o->melanopic_edi = (float)(ps.weighted_mel / ps.weight_sum);
        }
        double var_of_mean = ps.n > 1 ? ps.lum_m2 / ((double)(ps.n - 1) * (double)ps.n) : 0.0;
        o->relative_variance = ps.lum_mean > 0.0 ? (float)(var_of_mean / (ps.lum_mean * ps.lum_mean)) : 0.0f;
    }
    return PN_OK;
}

/* The eye rays every pixel takes, which the driver traces in advance: the fixed spp; the cross
 * rule's pilot of stream A; the paper rule's eye rays before its first test (min_eye_rays, or
 * fewer when the shadow-ray budget ends the pixel sooner: pixel_done). */
static uint32_t reference_batch_hits(const pn_render_job *job) {
    if (job->spp > 0) return job->spp;
    if (job->adaptive_rule == PN_ADAPTIVE_CROSS) return cross_pilot(job);
    uint64_t by_budget = ((uint64_t)job->max_shadow_rays + job->shadow_rays - 1u) / job->shadow_rays;
    return by_budget < job->min_eye_rays ? (uint32_t)by_budget : job->min_eye_rays;
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
    .batch_hits = reference_batch_hits,
};
