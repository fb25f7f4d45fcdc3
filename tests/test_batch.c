/* test_batch.c — the batch's eye hits (render/batch.h): what the driver traces, in advance and
 * through the batch's callback (more_hits), and the contract the reference integrator keeps
 * with it. The hits are the eye samples reference traced itself before (its pixel sequence,
 * the cross rule's stream B; the VPL integrators' sequence); a reference estimate is the same bit for bit whichever hits came in
 * advance; the callback is asked for exactly the eye rays the pixel takes (count), each range
 * once, in index order, stream A's pilot from the batch before stream B's (order); and images
 * are the same for any thread count, at a fixed spp and with a threshold (determinism). */
#include "harness.h"
#include "render_fields.h"

#include "core/rng.h"
#include "core/sobol.h"
#include "core/threadpool.h"
#include "integrators/integrator.h"
#include "integrators/registry.h"
#include "penumbra/penumbra.h"
#include "render/batch.h"
#include "scene/scene.h"
#include "shade/bsdf.h"
#include "vpl_scenes.h"

#include <stdlib.h>
#include <string.h>

/* The VPL tests' room with a glass sphere in it, so that some eye rays follow specular chains. */
static const char *glass_room(int w, int h) {
    static char text[8192];
    const char *room = pn_test_room_scene(0, w, h);
    const char *at = strstr(room, "LightSource");
    int head = (int)(at - room);
    snprintf(text, sizeof text,
             "%.*sAttributeBegin\n  Material \"dielectric\" \"float eta\" [ 1.5 ]\n  Translate -0.5 0.2 0.9\n"
             "  Shape \"sphere\" \"float radius\" [ 0.45 ]\nAttributeEnd\n%s",
             head, room, at);
    return text;
}

static void job_init(pn_render_job *job, pn_scene scene, int w, int h, atomic_int *cancel) {
    memset(job, 0, sizeof *job);
    job->scene = scene;
    job->accel = scene->accel;
    job->lights = scene->lights;
    float crop[4] = {0, 1, 0, 1};
    CHECK(pn_camera_setup(&scene->camera, w, h, crop, &job->camera));
    job->max_specular_depth = 8;
    job->seed = 7;
    job->shadow_rays = 2;
    job->max_shadow_rays = 20000;
    job->min_shadow_rays_black = 2500;
    job->min_eye_rays = 4;
    job->light_sampler = PN_LIGHT_SAMPLER_IRRADIANCE;
    job->adaptive_rule = PN_ADAPTIVE_CROSS;
    job->block_size = 8;
    atomic_init(cancel, 0);
    job->cancel = cancel;
}

/* pn_eye_hits_trace is the eye sample reference traced before the batch carried it: camera ray
 * from pn_pixel_eye_sample of the pixel's scramble (stream B: the cross rule's salted hash of
 * it), specular chain, BSDF at the end, filter weight; the index and scramble it carries. */
static void test_hits_are_the_eye_samples(pn_scene scene, int W, int H) {
    pn_render_job job;
    atomic_int cancel;
    job_init(&job, scene, W, H, &cancel);
    int chains = 0, points = 0, n = 0;
    for (int py = 0; py < H; py += 3)
        for (int px = 0; px < W; px += 3)
            for (int seq = 0; seq < PN_EYE_SEQ_COUNT; seq++) {
                if (seq == PN_EYE_SEQ_IAS_BLOCK) continue; /* a block's, not a pixel's: test_ias_hits */
                uint32_t scramble = pn_pixel_scramble(&job, px, py);
                if (seq == PN_EYE_SEQ_CROSS_B)
                    scramble = (uint32_t)pn_hash3(job.seed ^ UINT64_C(0x9e3779b97f4a7c15), (uint64_t)scramble, 1u);
                if (seq == PN_EYE_SEQ_VPL)
                    scramble = (uint32_t)pn_hash3(job.seed ^ UINT64_C(0x76706c), (uint64_t)px, (uint64_t)py);
                if (seq == PN_EYE_SEQ_IAS_EMITTER) scramble ^= 0x5eedu; /* ias_speed.c's emitter rays */
                pn_eye_hit hits[5];
                pn_eye_hits_trace(&job, px, py, (pn_eye_sequence)seq, 3, 5, hits);
                for (uint32_t k = 0; k < 5; k++) {
                    const pn_eye_hit *h = &hits[k];
                    uint32_t i = 3 + k;
                    float fw, u;
                    vec3 o, d;
                    pn_pixel_eye_sample(&job, px, py, scramble, i, &o, &d, &fw, &u);
                    pn_eye_path path;
                    pn_trace_eye_path(&job, o, d, u, &path);
                    n++;
                    CHECK(h->index == i && h->scramble == scramble);
                    CHECK(memcmp(&h->weight, &fw, sizeof fw) == 0);
                    CHECK(h->path.rays == path.rays && h->path.has_point == path.has_point);
                    CHECK(memcmp(&h->path.emitted, &path.emitted, sizeof(vec3)) == 0);
                    CHECK(memcmp(&h->path.throughput, &path.throughput, sizeof(vec3)) == 0);
                    CHECK(memcmp(&h->path.first_depth, &path.first_depth, sizeof(float)) == 0);
                    chains += path.rays > 1;
                    if (!path.has_point) continue;
                    points++;
                    CHECK(memcmp(&h->path.hit.p, &path.hit.p, sizeof(vec3)) == 0);
                    CHECK(memcmp(&h->path.wo, &path.wo, sizeof(vec3)) == 0);
                    pn_bsdf b, hb;
                    pn_bsdf_at(scene, &path.hit, path.wo, &b);
                    pn_eye_hit_bsdf(&job, h, &hb);
                    CHECK(hb.wl == NULL && hb.kind == b.kind);
                    CHECK(memcmp(&hb.kd, &b.kd, sizeof(vec3)) == 0 && memcmp(&hb.ns, &b.ns, sizeof(vec3)) == 0);
                    CHECK(memcmp(&hb.ng, &b.ng, sizeof(vec3)) == 0);
                }
            }
    CHECK_MSG(chains > 0 && points > n / 2, "%d of %d samples through glass, %d with a point", chains, n, points);
    /* The in-advance hits of a batch are the same samples. */
    int32_t px[2][2] = {{3, 4}, {10, 1}};
    pn_eye_hit adv[2 * 6], one[6];
    pn_batch_trace_hits(&job, 2, (const int32_t(*)[2])px, 6, adv);
    pn_eye_hits_trace(&job, 10, 1, PN_EYE_SEQ_PIXEL, 0, 6, one);
    for (int k = 0; k < 6; k++)
        CHECK(memcmp(&adv[6 + k].path.hit.p, &one[k].path.hit.p, sizeof(vec3)) == 0 && adv[6 + k].index == (uint32_t)k);
}

/* One call of the recording tracer. */
typedef struct call {
    int pi, seq;
    uint32_t first, count;
} call;

typedef struct recorder {
    call calls[4096];
    int n;
} recorder;

static void recording_more_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq,
                                uint32_t first, uint32_t count, pn_eye_hit *out) {
    recorder *r = batch->more_user;
    if (r->n < 4096) r->calls[r->n++] = (call){pi, (int)seq, first, count};
    pn_batch_more_hits(job, batch, pi, seq, first, count, out);
}

static bool same_estimate(const pn_pixel_estimate *a, const pn_pixel_estimate *b) {
    return memcmp(&a->radiance, &b->radiance, sizeof(vec3)) == 0 &&
           memcmp(&a->emitted, &b->emitted, sizeof(vec3)) == 0 && a->eye_rays == b->eye_rays &&
           a->shadow_rays == b->shadow_rays && a->specular_rays == b->specular_rays &&
           memcmp(&a->relative_variance, &b->relative_variance, sizeof(float)) == 0 &&
           memcmp(&a->depth, &b->depth, sizeof(float)) == 0;
}

/* Renders the batch of `px` with the in-advance hits per pixel given (0: none) through the
 * recording tracer. */
static void render_with(const pn_render_job *job, void *scratch, int n, const int32_t (*px)[2], uint32_t advance,
                        pn_eye_hit *buf, recorder *rec, pn_pixel_estimate *out) {
    if (advance) pn_batch_trace_hits(job, n, px, advance, buf);
    pn_batch batch = {
        0, 0, n, px, 0, NULL, advance, advance ? buf : NULL, recording_more_hits, rec, .hits_seq = PN_EYE_SEQ_PIXEL};
    rec->n = 0;
    CHECK(pn_integrator_reference.render_batch(job, &batch, out, scratch) == PN_OK);
}

/* The callback's contract, for each of reference's modes: the estimates do not depend on how many
 * hits came in advance; the callback is asked, per pixel in batch order, for the eye rays the
 * pixel takes beyond the in-advance ones and no more, each stream's indices contiguous and in
 * order; and the integrator reads the hits it is given. */
static void test_more_hits_contract(pn_scene scene, int W, int H) {
    pn_render_job job;
    atomic_int cancel;
    job_init(&job, scene, W, H, &cancel);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_integrator_reference.prepare(&job, &err) == PN_OK);
    void *scratch = pn_integrator_reference.scratch_create(&job);
    CHECK(scratch != NULL);
    enum { N = 16 };
    int32_t px[N][2];
    for (int k = 0; k < N; k++) {
        px[k][0] = (5 * k) % W; /* scattered pixels, as a progressive driver hands them */
        px[k][1] = (3 * k + 1) % H;
    }
    const int32_t(*cpx)[2] = (const int32_t(*)[2])px;
    pn_eye_hit *buf = malloc((size_t)N * 64 * sizeof *buf);
    recorder *rec = calloc(1, sizeof *rec);
    pn_pixel_estimate all[N], part[N], none[N];
    struct mode {
        uint32_t spp;
        double threshold;
        int rule;
    } modes[4] = {{5, 0.0, PN_ADAPTIVE_CROSS},
                  {40, 0.0, PN_ADAPTIVE_CROSS},
                  {0, 0.02, PN_ADAPTIVE_CROSS},
                  {0, 0.002, PN_ADAPTIVE_PAPER}};
    for (int m = 0; m < 4; m++) {
        job.spp = modes[m].spp;
        job.threshold = modes[m].threshold;
        job.adaptive_rule = modes[m].rule;
        const uint32_t want = pn_integrator_reference.batch_hits(&job);
        CHECK(want == (job.spp ? job.spp : job.adaptive_rule == PN_ADAPTIVE_CROSS ? 9u : 4u));
        render_with(&job, scratch, N, cpx, want, buf, rec, all);
        int calls_all = rec->n, traced_all = 0;
        for (int c = 0; c < calls_all; c++) traced_all += (int)rec->calls[c].count;
        render_with(&job, scratch, N, cpx, 2, buf, rec, part);
        for (int k = 0; k < N; k++)
            CHECK_MSG(same_estimate(&all[k], &part[k]), "mode %d pixel %d: 2 in advance differs", m, k);
        render_with(&job, scratch, N, cpx, 0, buf, rec, none);
        /* Count and order: per pixel, the calls cover each stream from 0 up without gap or
         * overlap, and add up to the pixel's eye rays. */
        uint32_t next[N][PN_EYE_SEQ_COUNT], total[N];
        memset(next, 0, sizeof next);
        memset(total, 0, sizeof total);
        int last_pi = 0;
        bool ordered = true;
        for (int c = 0; c < rec->n; c++) {
            const call *k = &rec->calls[c];
            ordered &= k->pi >= last_pi && k->count > 0 && k->first == next[k->pi][k->seq];
            last_pi = k->pi;
            next[k->pi][k->seq] = k->first + k->count;
            total[k->pi] += k->count;
            if (modes[m].rule == PN_ADAPTIVE_PAPER && !job.spp) ordered &= k->count == 1 && k->seq == PN_EYE_SEQ_PIXEL;
            if (job.spp) ordered &= k->seq == PN_EYE_SEQ_PIXEL && k->count <= 16;
        }
        CHECK_MSG(ordered, "mode %d: calls out of order", m);
        for (int k = 0; k < N; k++) {
            CHECK_MSG(same_estimate(&all[k], &none[k]), "mode %d pixel %d: none in advance differs", m, k);
            CHECK_MSG(total[k] == none[k].eye_rays, "mode %d pixel %d: %u hits asked, %u eye rays", m, k, total[k],
                      none[k].eye_rays);
            if (job.spp) CHECK(none[k].eye_rays == job.spp);
        }
        if (job.spp) {
            CHECK(calls_all == 0); /* everything came in advance */
        } else {
            /* The adaptive rules ask for every eye ray past the in-advance ones, in the cross
             * rule first stream B's pilot (its first call of a pixel). */
            int asked = 0, more = 0, b_first = 0;
            for (int k = 0; k < N; k++) {
                asked += (int)(all[k].eye_rays - want);
                more += all[k].eye_rays > want;
            }
            CHECK_MSG(asked == traced_all && rec->n < 4096, "mode %d: %d asked, %d traced", m, asked, traced_all);
            render_with(&job, scratch, N, cpx, want, buf, rec, all);
            for (int c = 0, seen = -1; c < rec->n; c++)
                if (rec->calls[c].pi != seen) {
                    seen = rec->calls[c].pi;
                    b_first += modes[m].rule == PN_ADAPTIVE_CROSS
                                   ? rec->calls[c].seq == PN_EYE_SEQ_CROSS_B && rec->calls[c].first == 0 &&
                                         rec->calls[c].count == 9
                                   : rec->calls[c].first == want;
                }
            CHECK_MSG(b_first == more && more >= N / 2, "mode %d: %d of %d pixels start with the expected call", m,
                      b_first, more);
        }
    }
    /* The integrator reads the hits it is given: light added to one in-advance hit reaches its
     * pixel, and only it. */
    job.spp = 5;
    pn_batch_trace_hits(&job, N, cpx, 5, buf);
    buf[5 * 3 + 2].path.emitted = v3_add(buf[5 * 3 + 2].path.emitted, v3(5, 5, 5));
    pn_batch batch = {0, 0, N, cpx, 0, NULL, 5, buf, recording_more_hits, rec, .hits_seq = PN_EYE_SEQ_PIXEL};
    CHECK(pn_integrator_reference.render_batch(&job, &batch, part, scratch) == PN_OK);
    render_with(&job, scratch, N, cpx, 5, buf, rec, all);
    for (int k = 0; k < N; k++)
        CHECK(k == 3 ? part[k].radiance.x > all[k].radiance.x + 0.1f : same_estimate(&part[k], &all[k]));
    free(rec);
    free(buf);
    pn_integrator_reference.scratch_free(scratch);
    pn_integrator_reference.release(&job);
}

/* A job of method `kind` resolved from the table as a render would (its options' defaults). */
static void resolve_job(pn_context ctx, pn_scene scene, int W, int H, pn_integrator_kind kind, uint32_t spp,
                        double threshold, pn_options options, pn_render_job *job, atomic_int *cancel) {
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = kind;
    rs.spp = spp;
    rs.threshold = threshold;
    rs.options = options;
    job_init(job, scene, W, H, cancel);
    CHECK(pn_registry_resolve(ctx, &rs, pn_registry_method_kind(PN_METHOD_INTEGRATOR, kind),
                              pn_registry_method_kind(PN_METHOD_DRIVER, PN_DRIVER_DEFAULT), job) == PN_OK);
    job->spp = spp; /* the common settings are the driver's to copy (render.c) */
    job->threshold = threshold;
    if (job->adaptive_rule == PN_ADAPTIVE_AUTO)
        job->adaptive_rule = kind == PN_INTEGRATOR_IAS ? PN_ADAPTIVE_PAPER : PN_ADAPTIVE_CROSS;
}

/* contour-mc takes its eye rays from the batch too: the same estimates whether its hits came in
 * advance or through the callback, which it then asks for sample i of every pixel, one at a
 * time, before sample i + 1; and light added to a given hit reaches its pixel. */
static void test_contour_mc_hits(pn_context ctx, pn_scene scene, int W, int H) {
    pn_render_job job;
    atomic_int cancel;
    resolve_job(ctx, scene, W, H, PN_INTEGRATOR_CONTOUR_MC, 2, 0.0, NULL, &job, &cancel);
    const pn_integrator *in = &pn_integrator_contour_mc;
    CHECK(in->batch_hits && in->batch_hits(&job) == 2);
    pn_err err;
    pn_err_init(&err);
    CHECK(in->prepare(&job, &err) == PN_OK);
    void *scratch = in->scratch_create(&job);
    CHECK(scratch != NULL);
    enum { N = 12 };
    int32_t px[N][2];
    for (int k = 0; k < N; k++) {
        px[k][0] = 8 + k % 6;
        px[k][1] = 4 + k / 6;
    }
    const int32_t(*cpx)[2] = (const int32_t(*)[2])px;
    pn_eye_hit buf[N * 2];
    recorder *rec = calloc(1, sizeof *rec);
    pn_pixel_estimate given[N], traced[N];
    pn_batch_trace_hits(&job, N, cpx, 2, buf);
    pn_batch a = {1, 0, N, cpx, 0, NULL, 2, buf, recording_more_hits, rec, .hits_seq = PN_EYE_SEQ_PIXEL};
    CHECK(in->render_batch(&job, &a, given, scratch) == PN_OK);
    CHECK(rec->n == 0);
    pn_batch b = {1, 0, N, cpx, 0, NULL, 0, NULL, recording_more_hits, rec, .hits_seq = PN_EYE_SEQ_PIXEL};
    CHECK(in->render_batch(&job, &b, traced, scratch) == PN_OK);
    CHECK_MSG(rec->n == 2 * N, "%d calls", rec->n);
    bool order = true;
    for (int c = 0; c < rec->n && c < 2 * N; c++)
        order &= rec->calls[c].pi == c % N && rec->calls[c].first == (uint32_t)(c / N) && rec->calls[c].count == 1;
    CHECK(order);
    int lit = 0;
    for (int k = 0; k < N; k++) {
        CHECK_MSG(same_estimate(&given[k], &traced[k]), "pixel %d differs", k);
        lit += given[k].radiance.x > 0.0f;
    }
    CHECK(lit > N / 2);
    buf[2 * 5 + 1].path.emitted = v3_add(buf[2 * 5 + 1].path.emitted, v3(5, 5, 5));
    CHECK(in->render_batch(&job, &a, given, scratch) == PN_OK);
    for (int k = 0; k < N; k++)
        CHECK(k == 5 ? given[k].radiance.x > traced[k].radiance.x + 0.1f : same_estimate(&given[k], &traced[k]));
    free(rec);
    in->scratch_free(scratch);
    in->release(&job);
}

/* What ias traced itself before the batch carried its eye rays (its ias.c of stop 16): eye ray
 * r of batch pixel pi is index pi * aa_rays + r of the block's sequence, in RGB. */
static void ias_former_trace(const pn_render_job *job, int bx, int by, int x, int y, uint32_t i, pn_eye_path *path,
                             float *rx, float *ry, float *fw) {
    const uint32_t scramble = (uint32_t)pn_hash3(job->seed ^ 0x1a5ull, (uint64_t)(uint32_t)bx, (uint64_t)(uint32_t)by);
    pn_camera_filter_sample(&job->camera, x, y, pn_sobol_sample(i, 0, scramble), pn_sobol_sample(i, 1, scramble), rx,
                            ry, fw);
    vec3 ro, rd;
    pn_camera_ray(&job->camera, *rx, *ry, pn_sobol_sample(i, 2, scramble), pn_sobol_sample(i, 3, scramble), &ro, &rd);
    pn_trace_eye_path(job, ro, rd, pn_sobol_sample(i, 4, scramble), path);
}

static bool same_path(const pn_eye_path *a, const pn_eye_path *b) {
    bool same = a->rays == b->rays && a->has_point == b->has_point &&
                memcmp(&a->emitted, &b->emitted, sizeof(vec3)) == 0 &&
                memcmp(&a->throughput, &b->throughput, sizeof(vec3)) == 0 &&
                memcmp(&a->first_depth, &b->first_depth, sizeof(float)) == 0;
    if (same && a->has_point)
        same = memcmp(&a->hit.p, &b->hit.p, sizeof(vec3)) == 0 && memcmp(&a->wo, &b->wo, sizeof(vec3)) == 0 &&
               a->hit.material == b->hit.material;
    return same;
}

/* A tracer that gives the pixel sequence where ias's block sequence is asked: an integrator
 * that reads the hits it is given renders differently with it. */
static void wrong_more_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq,
                            uint32_t first, uint32_t count, pn_eye_hit *out) {
    pn_batch_more_hits(job, batch, pi, seq == PN_EYE_SEQ_IAS_BLOCK ? PN_EYE_SEQ_PIXEL : seq, first, count, out);
}

/* ias takes its eye rays from the batch: they are the block sequence's samples it traced itself
 * before (in RGB also in spectral mode); its estimates are the same bit for bit whether they came
 * in advance, partly or through the callback, which is asked for each pixel's aa_rays samples
 * in order; it reads them (light added to one hit reaches its pixel; the pixel sequence in their
 * place changes the image); and a batch whose stride is not ias's is refused. */
static void test_ias_hits(pn_context ctx, pn_scene scene, int W, int H) {
    pn_render_job job;
    atomic_int cancel;
    resolve_job(ctx, scene, W, H, PN_INTEGRATOR_IAS, 0, 0.05, NULL, &job, &cancel);
    const pn_integrator *in = &pn_integrator_ias;
    CHECK(in->batch_hits && in->batch_hits_seq == PN_EYE_SEQ_IAS_BLOCK);
    const uint32_t n = in->batch_hits(&job);
    CHECK_MSG(n == 32, "ias takes %u eye rays per pixel", n);
    pn_err err;
    pn_err_init(&err);
    CHECK(in->prepare(&job, &err) == PN_OK);
    void *scratch = in->scratch_create(&job);
    CHECK(scratch != NULL);
    enum { N = 64, BX = 2 };
    int32_t px[N][2];
    for (int k = 0; k < N; k++) {
        px[k][0] = 8 * BX + k % 8; /* block (BX, 1), where the glass sphere is */
        px[k][1] = 8 + k / 8;
    }
    const int32_t(*cpx)[2] = (const int32_t(*)[2])px;
    pn_batch ref = {.block_x = BX, .block_y = 1, .count = N, .pixels = cpx, .hits_stride = n};
    pn_batch_set_tracers(&ref);
    int compared = 0, same = 0, chains = 0;
    for (int pi = 0; pi < N; pi += 9)
        for (uint32_t r = 0; r < n; r++) {
            pn_eye_hit h;
            pn_batch_more_hits(&job, &ref, pi, PN_EYE_SEQ_IAS_BLOCK, r, 1, &h);
            pn_eye_path path;
            float rx, ry, fw;
            ias_former_trace(&job, BX, 1, px[pi][0], px[pi][1], (uint32_t)pi * n + r, &path, &rx, &ry, &fw);
            compared++;
            chains += path.rays > 1;
            bool ok = h.index == (uint32_t)pi * n + r && same_path(&h.path, &path) &&
                      memcmp(&h.weight, &fw, sizeof fw) == 0 && memcmp(&h.raster_x, &rx, sizeof rx) == 0 &&
                      memcmp(&h.raster_y, &ry, sizeof ry) == 0;
            if (ok && path.has_point) {
                pn_bsdf b, hb;
                pn_bsdf_at(scene, &path.hit, path.wo, &b);
                pn_eye_hit_bsdf(&job, &h, &hb);
                ok = hb.wl == NULL && hb.kind == b.kind && memcmp(&hb.kd, &b.kd, sizeof(vec3)) == 0 &&
                     memcmp(&hb.ng, &b.ng, sizeof(vec3)) == 0;
            }
            same += ok;
        }
    CHECK_MSG(same == compared && chains > 0, "%d of %d ias eye rays as traced before (%d through glass)", same,
              compared, chains);
    /* Spectral mode: the same RGB paths, no wavelengths. */
    job.spectral = true;
    {
        pn_eye_hit h;
        pn_batch_more_hits(&job, &ref, 3, PN_EYE_SEQ_IAS_BLOCK, 1, 1, &h);
        pn_eye_path path;
        float rx, ry, fw;
        ias_former_trace(&job, BX, 1, px[3][0], px[3][1], 3 * n + 1, &path, &rx, &ry, &fw);
        CHECK(same_path(&h.path, &path) && pn_eye_hit_wavelengths(&job, &h) == NULL);
    }
    job.spectral = false;

    pn_eye_hit *buf = malloc((size_t)N * n * sizeof *buf);
    recorder *rec = calloc(1, sizeof *rec);
    pn_pixel_estimate all[N], part[N], none[N], other[N];
    /* All in advance, as the drivers give them. */
    pn_batch a = {.block_x = BX, .block_y = 1, .count = N, .pixels = cpx};
    pn_batch_supply(&job, in, &a, NULL, buf);
    CHECK(a.hits_per_pixel == n && a.hits_seq == PN_EYE_SEQ_IAS_BLOCK && a.hits_stride == n);
    CHECK(in->render_batch(&job, &a, all, scratch) == PN_OK);
    /* 5 in advance, the rest through the recording tracer. */
    pn_eye_hit *few = malloc((size_t)N * 5 * sizeof *few);
    for (int k = 0; k < N; k++) pn_batch_more_hits(&job, &ref, k, PN_EYE_SEQ_IAS_BLOCK, 0, 5, &few[k * 5]);
    pn_batch p = {BX, 1, N, cpx, 0, NULL, 5, few, recording_more_hits, rec, pn_batch_more_points, PN_EYE_SEQ_IAS_BLOCK,
                  n};
    rec->n = 0;
    CHECK(in->render_batch(&job, &p, part, scratch) == PN_OK);
    /* None in advance. */
    pn_batch z = {BX, 1, N, cpx, 0, NULL, 0, NULL, recording_more_hits, rec, pn_batch_more_points, PN_EYE_SEQ_IAS_BLOCK,
                  n};
    rec->n = 0;
    CHECK(in->render_batch(&job, &z, none, scratch) == PN_OK);
    uint32_t next[N], emitter = 0;
    memset(next, 0, sizeof next);
    bool ordered = rec->n < 4096;
    for (int c = 0; c < rec->n; c++) {
        const call *k = &rec->calls[c];
        if (k->seq == PN_EYE_SEQ_IAS_EMITTER) {
            emitter++;
            continue;
        }
        ordered &= k->seq == PN_EYE_SEQ_IAS_BLOCK && k->first == next[k->pi] && k->count > 0;
        next[k->pi] = k->first + k->count;
    }
    int lit = 0;
    for (int k = 0; k < N; k++) {
        CHECK_MSG(same_estimate(&all[k], &part[k]), "ias pixel %d: 5 in advance differs", k);
        CHECK_MSG(same_estimate(&all[k], &none[k]), "ias pixel %d: none in advance differs", k);
        ordered &= next[k] == n;
        lit += all[k].radiance.x > 0.0f;
    }
    CHECK_MSG(ordered, "ias: the tracer was not asked for each pixel's %u eye rays in order", n);
    CHECK(lit > N / 2);
    /* It reads them: light added to one in-advance hit reaches its pixel ... */
    buf[(size_t)5 * n + 3].path.emitted = v3_add(buf[(size_t)5 * n + 3].path.emitted, v3(5, 5, 5));
    CHECK(in->render_batch(&job, &a, other, scratch) == PN_OK);
    CHECK_MSG(other[5].radiance.x > all[5].radiance.x + 0.05f, "ias pixel 5: %g, unchanged %g",
              (double)other[5].radiance.x, (double)all[5].radiance.x);
    /* ... and another sequence in their place changes the image. */
    pn_batch w = {BX, 1, N, cpx, 0, NULL, 0, NULL, wrong_more_hits, NULL, pn_batch_more_points, PN_EYE_SEQ_IAS_BLOCK,
                  n};
    CHECK(in->render_batch(&job, &w, other, scratch) == PN_OK);
    int differ = 0;
    for (int k = 0; k < N; k++) differ += !same_estimate(&all[k], &other[k]);
    CHECK_MSG(differ > N / 2, "ias: %d of %d pixels differ under another sequence", differ, N);
    /* A stride that is not the number of eye rays ias takes is refused. */
    z.hits_stride = n + 1;
    CHECK(in->render_batch(&job, &z, other, scratch) == PN_ERROR_INTERNAL);
    free(few);
    free(rec);
    free(buf);
    in->scratch_free(scratch);
    in->release(&job);
}

/* The whole-image integrators' eye samples come from the driver's window tracers (render/batch.h,
 * pn_batch_part): a recording tracer per pixel, race-free because a pixel belongs to one job. */
typedef struct window_recorder {
    int W;
    uint32_t next[24 * 16]; /* the next index asked of each pixel */
    int disorder;           /* calls that did not continue their pixel's range */
    int32_t bright[2];      /* a pixel whose samples get light added (-1: none) */
    bool shift;             /* give sample i + 1 in place of i (another sequence) */
} window_recorder;

static void window_record(window_recorder *r, const pn_batch *batch, int pi, uint32_t first, uint32_t count) {
    int x = batch->pixels[pi][0], y = batch->pixels[pi][1];
    uint32_t *next = &r->next[y * r->W + x];
    if (first != *next) r->disorder++;
    *next = first + count;
}

static void window_points(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t first, uint32_t count,
                          pn_batch_point *out) {
    window_recorder *r = batch->more_user;
    window_record(r, batch, pi, first, count);
    pn_batch_more_points(job, batch, pi, first + (r->shift ? 1u : 0u), count, out);
    for (uint32_t k = 0; k < count; k++) {
        pn_batch_point want;
        pn_eye_point_trace(job, batch->pixels[pi][0], batch->pixels[pi][1], first + k, &want);
        if (!r->shift && memcmp(&want, &out[k], sizeof want) != 0) r->disorder++; /* the integrator's former points */
        if (batch->pixels[pi][0] == r->bright[0] && batch->pixels[pi][1] == r->bright[1])
            out[k].sp.emitted = v3_add(out[k].sp.emitted, v3(5, 5, 5));
    }
}

static void window_hits(const pn_render_job *job, const pn_batch *batch, int pi, pn_eye_sequence seq, uint32_t first,
                        uint32_t count, pn_eye_hit *out) {
    window_recorder *r = batch->more_user;
    window_record(r, batch, pi, first, count);
    pn_batch_more_hits(job, batch, pi, seq, first + (r->shift ? 1u : 0u), count, out);
    for (uint32_t k = 0; k < count; k++)
        if (batch->pixels[pi][0] == r->bright[0] && batch->pixels[pi][1] == r->bright[1])
            out[k].path.emitted = v3_add(out[k].path.emitted, v3(5, 5, 5));
}

/* Renders the window through render_image with the recorder's tracers (r NULL: the standard
 * ones). */
static pn_status window_render(const pn_render_job *job, const pn_integrator *in, struct pn_threadpool *pool,
                               window_recorder *r, pn_pixel_estimate *out, int W, int H) {
    pn_batch win;
    memset(&win, 0, sizeof win);
    pn_batch_set_tracers(&win);
    if (r) {
        win.more_points = window_points;
        win.more_hits = window_hits;
        win.more_user = r;
        memset(r->next, 0, sizeof r->next);
        r->disorder = 0;
    }
    for (int i = 0; i < W * H; i++) memset(&out[i], 0, sizeof out[i]);
    return in->render_image(job, pool, &win, out, W, H);
}

/* illumcut's whole-image path and contour's scanline rows read every eye sample through the
 * driver's tracers of the window: each pixel's spp samples, asked once each and in order, the
 * points illumcut traced itself before (pn_eye_point_trace); the same image as with the standard
 * tracers; light added to one pixel's samples reaches it, and another sequence in their place
 * changes the image. */
static void test_window_tracers(pn_context ctx, pn_scene scene, int W, int H) {
    struct pn_threadpool *pool = pn_threadpool_create(2);
    CHECK(pool != NULL);
    pn_options o = pn_options_new();
    pn_options_set_int(ctx, o, "vpls", 300);
    const pn_integrator_kind kinds[2] = {PN_INTEGRATOR_ILLUMCUT, PN_INTEGRATOR_CONTOUR};
    const pn_integrator *ins[2] = {&pn_integrator_illumcut, &pn_integrator_contour};
    pn_pixel_estimate *std = calloc((size_t)W * H, sizeof *std), *rec = calloc((size_t)W * H, sizeof *rec);
    window_recorder *r = calloc(1, sizeof *r);
    r->W = W;
    for (int m = 0; m < 2 && pool; m++) {
        const pn_integrator *in = ins[m];
        pn_render_job job;
        atomic_int cancel;
        resolve_job(ctx, scene, W, H, kinds[m], 2, 0.0, m == 0 ? o : NULL, &job, &cancel);
        pn_err err;
        pn_err_init(&err);
        CHECK(in->prepare(&job, &err) == PN_OK);
        r->bright[0] = r->bright[1] = -1;
        r->shift = false;
        CHECK(window_render(&job, in, pool, NULL, std, W, H) == PN_OK);
        CHECK(window_render(&job, in, pool, r, rec, W, H) == PN_OK);
        int asked = 0, same = 0, lit = 0;
        for (int i = 0; i < W * H; i++) {
            asked += r->next[i] == 2u;
            same += same_estimate(&std[i], &rec[i]);
            lit += std[i].radiance.x > 0.0f;
        }
        CHECK_MSG(asked == W * H && r->disorder == 0, "%s: %d of %d pixels asked for 2 samples, %d out of order",
                  in->name, asked, W * H, r->disorder);
        CHECK_MSG(same == W * H && lit > W * H / 2, "%s: %d of %d pixels the same", in->name, same, W * H);
        r->bright[0] = 10, r->bright[1] = 7;
        CHECK(window_render(&job, in, pool, r, rec, W, H) == PN_OK);
        CHECK_MSG(rec[7 * W + 10].radiance.x > std[7 * W + 10].radiance.x + 1.0f, "%s: light added is not seen",
                  in->name);
        r->bright[0] = r->bright[1] = -1;
        r->shift = true;
        CHECK(window_render(&job, in, pool, r, rec, W, H) == PN_OK);
        int differ = 0;
        for (int i = 0; i < W * H; i++) differ += !same_estimate(&std[i], &rec[i]);
        CHECK_MSG(differ > W * H / 2, "%s: %d of %d pixels differ under another sequence", in->name, differ, W * H);
        in->release(&job);
    }
    free(r);
    free(std);
    free(rec);
    pn_options_free(o);
    pn_threadpool_destroy(pool);
}

#ifdef NDEBUG
/* A batch without the tracer its integrator needs (a driver's bug; an assertion in debug builds):
 * its samples come out non-finite and are counted, never silently traced. */
static void test_unsupplied(pn_scene scene, int W, int H) {
    pn_render_job job;
    atomic_int cancel;
    job_init(&job, scene, W, H, &cancel);
    job.spp = 3;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_integrator_reference.prepare(&job, &err) == PN_OK);
    void *scratch = pn_integrator_reference.scratch_create(&job);
    int32_t px[4][2] = {{1, 1}, {5, 6}, {9, 9}, {20, 3}};
    pn_batch b = {.count = 4, .pixels = (const int32_t(*)[2])px};
    pn_pixel_estimate out[4];
    CHECK(pn_integrator_reference.render_batch(&job, &b, out, scratch) == PN_OK);
    for (int k = 0; k < 4; k++) CHECK(out[k].non_finite == 3 && out[k].radiance.x == 0.0f);
    pn_integrator_reference.scratch_free(scratch);
    pn_integrator_reference.release(&job);
    pn_shading_point sp;
    pn_pixel_estimate est;
    memset(&est, 0, sizeof est);
    pn_batch_eye_point(&job, &b, 0, 0, &sp, &est);
    CHECK(!sp.has_point && !v3_is_finite(sp.emitted));
}
#endif

/* Determinism: the tiled driver's images, fixed spp and threshold, with 1 and 3 threads. */
static void test_thread_counts(pn_context ctx, pn_scene scene) {
    pn_options o = pn_options_new();
    pn_options_set_int(ctx, o, "vpls", 300);
    for (int mode = 0; mode < 4; mode++) {
        pn_image img[2] = {NULL, NULL};
        for (int t = 0; t < 2; t++) {
            pn_render_settings rs;
            memset(&rs, 0, sizeof rs);
            /* reference at a fixed spp and a threshold; ias (threshold); illumcut */
            rs.integrator = mode < 2 ? PN_INTEGRATOR_REFERENCE : mode == 2 ? PN_INTEGRATOR_IAS : PN_INTEGRATOR_ILLUMCUT;
            rs.options = mode == 3 ? o : NULL;
            rs.threads = t ? 3 : 1;
            rs.spp = mode == 0 ? 6 : mode == 3 ? 2 : 0;
            rs.threshold = mode == 1 ? 0.03 : mode == 2 ? 0.05 : 0.0;
            CHECK(pn_test_render(ctx, scene, &rs, &img[t], NULL) == PN_OK);
        }
        if (img[0] && img[1]) {
            size_t n = (size_t)pn_image_width(img[0]) * (size_t)pn_image_height(img[0]) * 3;
            CHECK_MSG(memcmp(pn_image_layer_data(img[0], 0), pn_image_layer_data(img[1], 0), n * sizeof(float)) == 0,
                      "mode %d: 1 and 3 threads differ", mode);
        }
        pn_image_free(img[0]);
        pn_image_free(img[1]);
    }
    pn_options_free(o);
}

static void run_all(void) {
    vpl_test_setup("batch");
    pn_context ctx = pn_context_new();
    const int W = 24, H = 16;
    pn_scene scene = vpl_test_load(ctx, "glass_room.pbrt", glass_room(W, H));
    if (scene) {
        test_hits_are_the_eye_samples(scene, W, H);
        test_more_hits_contract(scene, W, H);
        test_contour_mc_hits(ctx, scene, W, H);
        test_ias_hits(ctx, scene, W, H);
        test_window_tracers(ctx, scene, W, H);
#ifdef NDEBUG
        test_unsupplied(scene, W, H);
#endif
        test_thread_counts(ctx, scene);
        pn_scene_free(scene);
    }
    pn_context_free(ctx);
    vpl_test_teardown();
}

PN_TESTS(TEST(run_all))
