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

#include <assert.h>
#include <math.h>
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
    bw.kd = pn_bsdf_kd_at(b, &wl);
    /* A conductor's lobe: F0 from its eta and k at the sample's wavelengths, as
     * pn_bsdf_at_spectral gives the other integrators. */
    bw.ks = b->metal && b->kind != PN_MATERIAL_MIRROR ? pn_bsdf_metal_f0(b, &wl) : pn_swl_albedo(&wl, b->rgb_ks);
    vec3 f = pn_bsdf_eval(&bw, wo, wi);
    vec3 le = light >= 0 ? pn_light_radiance_spectral(job->lights, &job->lights->lights[light], radiance, &wl)
                         : pn_swl_illuminant(&wl, radiance);
    if (edi) *edi = pn_swl_melanopic_edi_on(&wl, le);
    return pn_swl_rgb(&wl, v3_mul(v3_mul(f, le), pn_swl_albedo(&wl, throughput)));
}

/* The texture footprint of a camera ray's hit (image textures' pyramid level): pbrt-v4 scales
 * camera ray differentials by max(1/8, 1/sqrt(spp)) (cameras.h GenerateRayDifferential's
 * caller); an adaptive job (spp 0) takes 1/8. Later hits of a specular chain keep a zero
 * footprint (difference: pbrt carries the differentials through specular bounces). */
static void camera_footprint(const pn_render_job *job, vec3 o, vec3 d, pn_hit *hit) {
    float scale = job->spp > 0 ? fmaxf(0.125f, 1.0f / sqrtf((float)job->spp)) : 0.125f;
    vec3 ox, dx, oy, dy;
    if (pn_camera_differentials(&job->camera, o, d, scale, &ox, &dx, &oy, &dy))
        pn_hit_uv_footprint(job->accel, hit, ox, dx, oy, dy);
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
        if (depth == 0 && scene->mipmap_count > 0) camera_footprint(job, o, d, &hit);
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

/* pn_pixel_eye_sample, with the camera ray's point on the film. */
static void eye_sample(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, float *rx, float *ry,
                       vec3 *o, vec3 *d, float *fw, float *u_specular) {
    pn_camera_filter_sample(&job->camera, px, py, pn_sobol_sample(i, 0, scramble), pn_sobol_sample(i, 1, scramble), rx,
                            ry, fw);
    pn_camera_ray(&job->camera, *rx, *ry, pn_sobol_sample(i, 2, scramble), pn_sobol_sample(i, 3, scramble), o, d);
    *u_specular = pn_sobol_sample(i, 4, scramble);
}

void pn_pixel_eye_sample(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, vec3 *o, vec3 *d,
                         float *fw, float *u_specular) {
    float rx, ry;
    eye_sample(job, px, py, scramble, i, &rx, &ry, o, d, fw, u_specular);
}

static void trace_hit(const pn_render_job *job, int px, int py, uint32_t scramble, bool spectral, uint32_t i,
                      pn_eye_hit *out);

/* A missing eye sample (render/batch.h: a batch without the tracer its integrator reads). */
static void unsupplied(void);

/* The VPL receiver form of an eye hit of the VPL sequence (the same tracer as every eye hit). */
void pn_eye_point_trace(const pn_render_job *job, int px, int py, uint32_t i, pn_batch_point *out) {
    pn_eye_hit h;
    trace_hit(job, px, py, pn_eye_sequence_scramble(job, PN_EYE_SEQ_VPL, px, py), true, i, &h);
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
    if (batch->more_points) {
        batch->more_points(job, batch, pi, i, 1, &pt);
    } else {
        unsupplied();
        memset(&pt, 0, sizeof pt);
        pt.rays = 1;
        pt.first_depth = INFINITY;
        pt.sp.emitted = v3(NAN, NAN, NAN);
    }
    pn_eye_point_apply(&pt, i, sp, est);
}

void pn_batch_trace_points(const pn_render_job *job, int count, const int32_t (*pixels)[2], uint32_t per_pixel,
                           pn_batch_point *out) {
    for (int k = 0; k < count; k++)
        for (uint32_t s = 0; s < per_pixel; s++)
            pn_eye_point_trace(job, pixels[k][0], pixels[k][1], s, &out[(size_t)k * per_pixel + s]);
}

void pn_batch_more_points(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t first, uint32_t count,
                          pn_batch_point *out) {
    for (uint32_t k = 0; k < count; k++)
        pn_eye_point_trace(job, batch->pixels[pi][0], batch->pixels[pi][1], first + k, &out[k]);
}

/* ---- eye hits (render/batch.h) ------------------------------------------------------------- */

static void unsupplied(void) {
    assert(!"a batch without the driver's tracer of the eye samples its integrator reads");
}

/* ias's sequences are traced in RGB (render/batch.h). */
static bool sequence_spectral(pn_eye_sequence seq) {
    return seq != PN_EYE_SEQ_IAS_BLOCK && seq != PN_EYE_SEQ_IAS_EMITTER;
}

uint32_t pn_eye_sequence_scramble(const pn_render_job *job, pn_eye_sequence seq, int px, int py) {
    assert(seq != PN_EYE_SEQ_IAS_BLOCK);
    if (seq == PN_EYE_SEQ_VPL)
        return (uint32_t)pn_hash3(job->seed ^ UINT64_C(0x76706c), (uint64_t)(uint32_t)px, (uint64_t)(uint32_t)py);
    uint32_t a = pn_pixel_scramble(job, px, py);
    if (seq == PN_EYE_SEQ_CROSS_B) return (uint32_t)pn_hash3(job->seed ^ UINT64_C(0x9e3779b97f4a7c15), (uint64_t)a, 1u);
    if (seq == PN_EYE_SEQ_IAS_EMITTER) return a ^ 0x5eedu;
    return a;
}

uint32_t pn_batch_sequence_scramble(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq) {
    if (seq == PN_EYE_SEQ_IAS_BLOCK)
        return (uint32_t)pn_hash3(job->seed ^ 0x1a5ull, (uint64_t)(uint32_t)batch->block_x,
                                  (uint64_t)(uint32_t)batch->block_y);
    return pn_eye_sequence_scramble(job, seq, batch->pixels[pi][0], batch->pixels[pi][1]);
}

/* Sample i of the sequence `scramble`: the camera ray first, then, timed on every
 * PN_EYE_TIMING_STRIDE-th sample, the wavelengths (in spectral mode, when `spectral`) and the
 * specular chain; the BSDF last. */
static void trace_hit(const pn_render_job *job, int px, int py, uint32_t scramble, bool spectral, uint32_t i,
                      pn_eye_hit *out) {
    float fw, u_specular, rx, ry;
    vec3 ro, rd;
    eye_sample(job, px, py, scramble, i, &rx, &ry, &ro, &rd, &fw, &u_specular);
    const bool timed = i % PN_EYE_TIMING_STRIDE == 0u;
    /* Traced on the stack and stored after the clock stops: the timed part is the trace, not the
     * stores into the batch's hits (a buffer of up to PN_BATCH_HITS_MAX, mostly out of cache). */
    pn_swl wl_storage;
    pn_eye_path path;
    double t_start = timed ? pn_clock_seconds() : 0.0;
    const pn_swl *wl = spectral ? pn_eye_wavelengths(job, scramble, i, &wl_storage) : NULL;
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
    out->raster_x = rx;
    out->raster_y = ry;
    if (out->path.has_point)
        pn_bsdf_at_spectral(job->scene, &out->path.hit, out->path.wo, wl, &out->bsdf);
    else
        memset(&out->bsdf, 0, sizeof out->bsdf);
    out->bsdf.wl = NULL; /* pn_eye_hit_bsdf restores it */
}

void pn_eye_hits_trace(const pn_render_job *job, int px, int py, pn_eye_sequence seq, uint32_t first, uint32_t count,
                       pn_eye_hit *out) {
    uint32_t scramble = pn_eye_sequence_scramble(job, seq, px, py);
    for (uint32_t k = 0; k < count; k++) trace_hit(job, px, py, scramble, sequence_spectral(seq), first + k, &out[k]);
}

void pn_batch_more_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq, uint32_t first,
                        uint32_t count, pn_eye_hit *out) {
    uint32_t scramble = pn_batch_sequence_scramble(job, batch, pi, seq);
    uint32_t base = seq == PN_EYE_SEQ_IAS_BLOCK ? (uint32_t)pi * batch->hits_stride : 0u;
    for (uint32_t k = 0; k < count; k++)
        trace_hit(job, batch->pixels[pi][0], batch->pixels[pi][1], scramble, sequence_spectral(seq), base + first + k,
                  &out[k]);
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

void pn_batch_set_tracers(pn_batch *batch) {
    batch->more_hits = pn_batch_more_hits;
    batch->more_points = pn_batch_more_points;
}

void pn_batch_supply(const pn_render_job *job, const pn_integrator *integ, pn_batch *batch, pn_batch_point *points,
                     pn_eye_hit *hits) {
    pn_batch_set_tracers(batch);
    uint32_t per_point = integ->batch_points ? integ->batch_points(job) : 0;
    if (per_point > 0) {
        pn_batch_trace_points(job, batch->count, batch->pixels, per_point, points);
        batch->points_per_pixel = per_point;
        batch->points = points;
    }
    if (!integ->batch_hits) return;
    const uint32_t asked = integ->batch_hits(job);
    batch->hits_seq = integ->batch_hits_seq;
    batch->hits_stride = asked;
    uint32_t per = pn_batch_hits_in_advance(asked, batch->count);
    if (per == 0) return;
    for (int k = 0; k < batch->count; k++)
        pn_batch_more_hits(job, batch, k, batch->hits_seq, 0, per, &hits[(size_t)k * per]);
    batch->hits_per_pixel = per;
    batch->hits = hits;
}

pn_batch pn_batch_part(const pn_batch *from, int block_x, int block_y, int count, const int32_t (*pixels)[2]) {
    return (pn_batch){.block_x = block_x,
                      .block_y = block_y,
                      .count = count,
                      .pixels = pixels,
                      .more_hits = from->more_hits,
                      .more_user = from->more_user,
                      .more_points = from->more_points};
}

const pn_eye_hit *pn_batch_eye_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq,
                                    uint32_t first, uint32_t count, pn_eye_hit *buf) {
    uint32_t have = seq == batch->hits_seq && batch->hits ? batch->hits_per_pixel : 0;
    const pn_eye_hit *mine = have ? &batch->hits[(size_t)pi * have] : NULL;
    if (first + count <= have) return mine + first;
    uint32_t from_advance = first < have ? have - first : 0;
    if (from_advance) memcpy(buf, mine + first, from_advance * sizeof *buf);
    uint32_t rest_first = first + from_advance, rest = count - from_advance;
    if (batch->more_hits) {
        batch->more_hits(job, batch, pi, seq, rest_first, rest, buf + from_advance);
        return buf;
    }
    unsupplied();
    for (uint32_t k = from_advance; k < count; k++) {
        pn_eye_hit *h = &buf[k];
        memset(h, 0, sizeof *h);
        h->path.emitted = v3(NAN, NAN, NAN);
        h->path.rays = 1;
        h->path.first_depth = INFINITY;
        h->index = first + k;
    }
    return buf;
}

const pn_swl *pn_eye_hit_wavelengths(const pn_render_job *job, const pn_eye_hit *hit) {
    return job->spectral && hit->wl.on ? &hit->wl : NULL;
}

void pn_eye_hit_bsdf(const pn_render_job *job, const pn_eye_hit *hit, pn_bsdf *out) {
    *out = hit->bsdf;
    out->wl = pn_eye_hit_wavelengths(job, hit);
}
