/* eye_path.c — camera rays followed through perfect specular reflection and refraction to the
 * first surface whose direct illumination is estimated; in spectral mode at the eye sample's
 * wavelengths (pn_eye_wavelengths, docs/spectral.md). And the batch's eye samples
 * (render/batch.h): VPL receivers (pn_eye_point_trace) and eye hits (pn_eye_hits_trace), with
 * the accessors integrators read them through. */
#include "render/batch.h"

#include "core/clock.h"
#include "core/rng.h"
#include "core/sobol.h"
#include "shade/bsdf.h"
#include "spectral/melanopic.h"
#include "spectral/transport.h"

#include <string.h>

void pn_trace_eye_path(const pn_render_job *job, vec3 o, vec3 d, float u_specular, pn_eye_path *path) {
    pn_trace_eye_path_spectral(job, o, d, u_specular, NULL, path);
}

const pn_swl *pn_eye_wavelengths(const pn_render_job *job, uint32_t scramble, uint32_t i, pn_swl *storage) {
    if (!job->spectral) return NULL;
    pn_swl_sample(pn_sobol_sample(i, PN_SOBOL_DIMS - 1, scramble ^ 0x3c6ef372u), storage);
    return storage;
}

vec3 pn_spectral_sample_value(const pn_render_job *job, const pn_bsdf *b, vec3 wo, vec3 wi, vec3 radiance,
                              vec3 throughput, int light, uint32_t index, uint32_t scramble, float *edi) {
    pn_swl wl;
    pn_swl_sample(pn_sobol_sample(index, PN_SOBOL_DIMS - 1, scramble ^ 0x9b05688cu), &wl);
    pn_bsdf bw = *b;
    bw.kd = pn_swl_albedo(&wl, b->rgb_kd);
    bw.ks = pn_swl_albedo(&wl, b->rgb_ks);
    vec3 f = pn_bsdf_eval(&bw, wo, wi);
    vec3 le = light >= 0 ? pn_light_radiance_spectral(job->lights, &job->lights->lights[light], radiance, &wl)
                         : pn_swl_illuminant(&wl, radiance);
    if (edi) *edi = pn_swl_melanopic_edi_on(&wl, le);
    return pn_swl_rgb(&wl, v3_mul(v3_mul(f, le), pn_swl_albedo(&wl, throughput)));
}

void pn_trace_eye_path_spectral(const pn_render_job *job, vec3 o, vec3 d, float u_specular, const pn_swl *wl,
                                pn_eye_path *path) {
    memset(path, 0, sizeof *path);
    path->throughput = v3(1, 1, 1);
    path->first_depth = INFINITY;
    const struct pn_scene_s *scene = job->scene;
    float tmin = 0.0f;
    float u = u_specular;
    uint64_t chain_seed = (uint64_t)(u_specular * 16777216.0f) ^ (job->seed << 24);
    for (uint32_t depth = 0;; depth++) {
        pn_hit hit;
        path->rays++;
        if (!pn_accel_intersect(job->accel, o, d, tmin, INFINITY, &hit)) {
            vec3 le = pn_swl_illuminant(wl, pn_lights_environment_radiance(job->lights, d));
            path->emitted = v3_add(path->emitted, v3_mul(path->throughput, le));
            return;
        }
        vec3 wo = v3_neg(d);
        if (hit.emission >= 0)
            path->emitted =
                v3_add(path->emitted, v3_mul(path->throughput, pn_hit_emission_spectral(scene, &hit, wo, wl)));
        pn_bsdf b;
        pn_bsdf_at_spectral(scene, &hit, wo, wl, &b);
        if (depth == 0) {
            path->first_depth = hit.t;
            path->first_normal = b.ns;
            path->first_albedo = b.kind == PN_MATERIAL_LAMBERT_BLINN ? b.rgb_kd : b.rgb_specular;
        }
        if (b.kind == PN_MATERIAL_LAMBERT_BLINN) {
            if (!pn_bsdf_is_shadable(&b)) return;
            path->has_point = true;
            path->hit = hit;
            path->wo = wo;
            return;
        }
        if (depth >= job->max_specular_depth) return;
        vec3 next;
        vec3 offset_n = b.ng; /* on wo's side */
        if (b.kind == PN_MATERIAL_MIRROR) {
            next = pn_reflect(wo, b.ns);
            path->throughput = v3_mul(path->throughput, b.specular);
        } else if (b.kind == PN_MATERIAL_DIELECTRIC) {
            float eta = b.entering ? b.eta : 1.0f / b.eta;
            float F = pn_fresnel_dielectric(v3_dot(wo, b.ns), eta);
            vec3 wt;
            bool can_refract = pn_refract(wo, b.ns, eta, &wt);
            if (!can_refract || u < F) {
                next = pn_reflect(wo, b.ns);
            } else {
                next = wt;
                offset_n = v3_neg(b.ng);
            }
            path->throughput = v3_mul(path->throughput, b.specular);
            u = pn_hash_unit(pn_hash3(chain_seed, depth + 1, 0x5eed)); /* rare: no stratification needed */
        } else {
            /* INTERFACE surfaces are skipped by the ray mask and never reach here. */
            return;
        }
        if (v3_is_zero(path->throughput)) return;
        float eps = pn_accel_ray_epsilon(job->accel, hit.p);
        o = v3_madd(hit.p, offset_n, eps);
        d = v3_normalize(next);
        tmin = 0.0f;
    }
}

uint32_t pn_pixel_scramble(const pn_render_job *job, int px, int py) {
    return (uint32_t)pn_hash3(job->seed, (uint64_t)(uint32_t)px, (uint64_t)(uint32_t)py);
}

void pn_pixel_eye_sample(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, vec3 *o, vec3 *d,
                         float *fw, float *u_specular) {
    float rx, ry;
    pn_camera_filter_sample(&job->camera, px, py, pn_sobol_sample(i, 0, scramble), pn_sobol_sample(i, 1, scramble), &rx,
                            &ry, fw);
    pn_camera_ray(&job->camera, rx, ry, pn_sobol_sample(i, 2, scramble), pn_sobol_sample(i, 3, scramble), o, d);
    *u_specular = pn_sobol_sample(i, 4, scramble);
}

static void trace_hit(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, pn_eye_hit *out);

/* The VPL receiver form of an eye hit of the VPL sequence (the same tracer as every eye hit). */
void pn_eye_point_trace(const pn_render_job *job, int px, int py, uint32_t i, pn_batch_point *out) {
    pn_eye_hit h;
    trace_hit(job, px, py, pn_eye_sequence_scramble(job, PN_EYE_SEQ_VPL, px, py), i, &h);
    const pn_eye_path *path = &h.path;
    memset(out, 0, sizeof *out);
    out->rays = path->rays;
    out->first_depth = path->first_depth;
    out->first_normal = path->first_normal;
    out->first_albedo = path->first_albedo;
    pn_shading_point *sp = &out->sp;
    sp->weight = h.weight;
    sp->emitted = v3_is_finite(path->emitted) ? path->emitted : v3(0, 0, 0);
    sp->throughput = path->throughput;
    if (job->spectral) sp->r.wl = h.wl;
    if (!path->has_point) return;
    const pn_bsdf *b = &h.bsdf;
    sp->has_point = true;
    sp->r.p = path->hit.p;
    sp->r.ng = b->ng;
    sp->r.ns = b->ns;
    sp->r.wo = path->wo;
    sp->r.kd = b->rgb_kd;
    sp->r.ks = b->rgb_ks;
    sp->r.kd_w = b->kd;
    sp->r.ks_w = b->ks;
    sp->r.exponent = b->exponent;
}

void pn_eye_point_apply(const pn_batch_point *pt, uint32_t i, pn_shading_point *sp, pn_pixel_estimate *est) {
    if (i == 0) {
        est->depth = pt->first_depth;
        est->normal = pt->first_normal;
        est->albedo = pt->first_albedo;
    }
    est->eye_rays++;
    est->specular_rays += pt->rays - 1;
    *sp = pt->sp;
}

void pn_batch_eye_point(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t i, pn_shading_point *sp,
                        pn_pixel_estimate *est) {
    if (batch->points && i < batch->points_per_pixel) {
        pn_eye_point_apply(&batch->points[(size_t)pi * batch->points_per_pixel + i], i, sp, est);
        return;
    }
    pn_batch_point pt;
    pn_eye_point_trace(job, batch->pixels[pi][0], batch->pixels[pi][1], i, &pt);
    pn_eye_point_apply(&pt, i, sp, est);
}

void pn_batch_trace_points(const pn_render_job *job, int count, const int32_t (*pixels)[2], uint32_t per_pixel,
                           pn_batch_point *out) {
    for (int k = 0; k < count; k++)
        for (uint32_t s = 0; s < per_pixel; s++)
            pn_eye_point_trace(job, pixels[k][0], pixels[k][1], s, &out[(size_t)k * per_pixel + s]);
}

/* ---- eye hits (render/batch.h) ------------------------------------------------------------- */

uint32_t pn_eye_sequence_scramble(const pn_render_job *job, pn_eye_sequence seq, int px, int py) {
    if (seq == PN_EYE_SEQ_VPL)
        return (uint32_t)pn_hash3(job->seed ^ UINT64_C(0x76706c), (uint64_t)(uint32_t)px, (uint64_t)(uint32_t)py);
    uint32_t a = pn_pixel_scramble(job, px, py);
    if (seq == PN_EYE_SEQ_CROSS_B) return (uint32_t)pn_hash3(job->seed ^ UINT64_C(0x9e3779b97f4a7c15), (uint64_t)a, 1u);
    return a;
}

/* Sample i of the sequence `scramble`: the camera ray first, then, timed on every
 * PN_EYE_TIMING_STRIDE-th sample, the wavelengths and the specular chain; the BSDF last. */
static void trace_hit(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, pn_eye_hit *out) {
    float fw, u_specular;
    vec3 ro, rd;
    pn_pixel_eye_sample(job, px, py, scramble, i, &ro, &rd, &fw, &u_specular);
    const bool timed = i % PN_EYE_TIMING_STRIDE == 0u;
    /* Traced on the stack and stored after the clock stops: the timed part is the trace, not the
     * stores into the batch's hits (a buffer of up to PN_BATCH_HITS_MAX, mostly out of cache). */
    pn_swl wl_storage;
    pn_eye_path path;
    double t_start = timed ? pn_clock_seconds() : 0.0;
    const pn_swl *wl = pn_eye_wavelengths(job, scramble, i, &wl_storage);
    pn_trace_eye_path_spectral(job, ro, rd, u_specular, wl, &path);
    out->seconds = timed ? (float)(pn_clock_seconds() - t_start) : 0.0f;
    out->path = path;
    if (wl)
        out->wl = wl_storage;
    else
        memset(&out->wl, 0, sizeof out->wl);
    wl = wl ? &out->wl : NULL;
    out->scramble = scramble;
    out->index = i;
    out->weight = fw;
    if (out->path.has_point)
        pn_bsdf_at_spectral(job->scene, &out->path.hit, out->path.wo, wl, &out->bsdf);
    else
        memset(&out->bsdf, 0, sizeof out->bsdf);
    out->bsdf.wl = NULL; /* pn_eye_hit_bsdf restores it */
}

void pn_eye_hits_trace(const pn_render_job *job, int px, int py, pn_eye_sequence seq, uint32_t first, uint32_t count,
                       pn_eye_hit *out) {
    uint32_t scramble = pn_eye_sequence_scramble(job, seq, px, py);
    for (uint32_t k = 0; k < count; k++) trace_hit(job, px, py, scramble, first + k, &out[k]);
}

void pn_batch_more_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq, uint32_t first,
                        uint32_t count, pn_eye_hit *out) {
    pn_eye_hits_trace(job, batch->pixels[pi][0], batch->pixels[pi][1], seq, first, count, out);
}

uint32_t pn_batch_hits_in_advance(uint32_t asked, int count) {
    if (count <= 0) return 0;
    uint32_t cap = PN_BATCH_HITS_MAX / (uint32_t)count;
    return asked < cap ? asked : cap;
}

void pn_batch_trace_hits(const pn_render_job *job, int count, const int32_t (*pixels)[2], uint32_t per_pixel,
                         pn_eye_hit *out) {
    for (int k = 0; k < count; k++)
        pn_eye_hits_trace(job, pixels[k][0], pixels[k][1], PN_EYE_SEQ_PIXEL, 0, per_pixel, &out[(size_t)k * per_pixel]);
}

const pn_eye_hit *pn_batch_eye_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq,
                                    uint32_t first, uint32_t count, pn_eye_hit *buf) {
    uint32_t have = seq == PN_EYE_SEQ_PIXEL && batch->hits ? batch->hits_per_pixel : 0;
    const pn_eye_hit *mine = have ? &batch->hits[(size_t)pi * have] : NULL;
    if (first + count <= have) return mine + first;
    uint32_t from_advance = first < have ? have - first : 0;
    if (from_advance) memcpy(buf, mine + first, from_advance * sizeof *buf);
    uint32_t rest_first = first + from_advance, rest = count - from_advance;
    if (batch->more_hits)
        batch->more_hits(job, batch, pi, seq, rest_first, rest, buf + from_advance);
    else
        pn_batch_more_hits(job, batch, pi, seq, rest_first, rest, buf + from_advance);
    return buf;
}

const pn_swl *pn_eye_hit_wavelengths(const pn_render_job *job, const pn_eye_hit *hit) {
    return job->spectral ? &hit->wl : NULL;
}

void pn_eye_hit_bsdf(const pn_render_job *job, const pn_eye_hit *hit, pn_bsdf *out) {
    *out = hit->bsdf;
    out->wl = pn_eye_hit_wavelengths(job, hit);
}
