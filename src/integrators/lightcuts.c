/* lightcuts.c — Lightcuts (Walter et al. 2005, §4 "Lightcuts"), the IlluminationCut paper's
 * baseline: for each shading point, a cut through the light trees is refined from the roots. Each
 * cluster C of the cut contributes its representative's M · G · V times the cluster's summed
 * intensity (IlluminationCut eq. 3), and carries the error bound M_max · G_max · sum I (eq. 5 with
 * V <= 1; shade/bounds.h — the same bound code as illumcut, for a one-point receiver cluster).
 * The cluster with the largest bound is replaced by its two children (a max-heap) until every
 * bound is below error · (luminance of the current total) — the relative error criterion of
 * Lightcuts §4 — or the cut has max_cut clusters. Individual VPLs (leaves) are exact.
 *
 * As in Lightcuts, the child that inherits its parent's representative reuses the parent's
 * M · G · V (no new shadow ray), so a refinement costs one shadow ray. */
#include "integrators/illumcut.h"

#include "core/heap.h"
#include "core/photometry.h"

#include "shade/bsdf.h"
#include "spectral/melanopic.h"

#include <stdlib.h>
#include <string.h>

typedef struct cut_entry {
    float bound;
    int32_t node;
    int32_t kind;
    vec3 unit;     /* M · G · V of the representative per unit intensity */
    vec3 unit_rgb; /* the same with the RGB reflectances (spectral mode; else unit) */
    vec3 value;    /* the cluster's term of the total: unit times its intensity (cluster_value) */
} cut_entry;

/* The open clusters of one receiver's cut: their entries in `open` (appended, one per push), their
 * bounds in a max-heap whose payload is the entry's index (ties in the sift's order, core/heap.h,
 * which is also the order of the bound sum). */
typedef struct lc_scratch {
    pn_heap heap;
    cut_entry *open;
    size_t used, capacity;
} lc_scratch;

static void lc_scratch_free(void *p) {
    lc_scratch *s = p;
    if (!s) return;
    pn_heap_free(&s->heap);
    free(s->open);
    free(s);
}

static void *lc_scratch_create(const pn_render_job *job) {
    (void)job;
    lc_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    pn_heap_init(&s->heap, PN_HEAP_MAX);
    s->capacity = 1024;
    s->open = malloc(s->capacity * sizeof *s->open);
    if (!s->open || !pn_heap_reserve(&s->heap, s->capacity)) {
        lc_scratch_free(s);
        return NULL;
    }
    return s;
}

static bool open_push(lc_scratch *s, cut_entry e) {
    if (s->used == s->capacity) {
        cut_entry *o = realloc(s->open, 2 * s->capacity * sizeof *o);
        if (!o) return false;
        s->open = o;
        s->capacity *= 2;
    }
    if (!pn_heap_push(&s->heap, e.bound, (int64_t)s->used)) return false;
    s->open[s->used++] = e;
    return true;
}

/* M · G · V of VPL `rep` at the receiver per unit intensity (one shadow ray when non-zero). In
 * spectral mode r is the receiver with its wavelengths switched off (unit_receiver), so the unit
 * is not upsampled (cluster_value multiplies it by the cluster's intensity at the wavelengths),
 * and r_rgb the receiver with its RGB reflectances: *unit_rgb, the unit RGB mode computes, which
 * the cut's stopping test uses, so the cut is RGB mode's. Without r_rgb (RGB mode) *unit_rgb is
 * the unit itself. */
static vec3 unit_value(const pn_lightcut_context *c, int32_t rep, const pn_vpl_receiver *r,
                       const pn_vpl_receiver *r_rgb, vec3 *unit_rgb, uint32_t *shadow_rays) {
    vec3 wi;
    float dist;
    const pn_vpl *vpl = &c->set->vpls[rep];
    vec3 v = pn_vpl_contribution_inline(c->lights, vpl, v3(1, 1, 1), r, c->set->min_dist2, &wi, &dist);
    vec3 vr = v;
    if (r_rgb) {
        vec3 wi_rgb;
        float dist_rgb;
        vr = pn_vpl_contribution_inline(c->lights, vpl, v3(1, 1, 1), r_rgb, c->set->min_dist2, &wi_rgb, &dist_rgb);
    }
    *unit_rgb = vr;
    if (v3_is_zero(v) && v3_is_zero(vr)) return v;
    (*shadow_rays)++;
    float t = pn_vpl_transmittance(c->accel, r, wi, dist, c->thin_glass);
    if (t != 1.0f) *unit_rgb = v3_scale(vr, t);
    return t == 1.0f ? v : v3_scale(v, t);
}

/* The receivers for unit_value: r without its wavelengths (kd_w, ks_w stay spectral), and with its
 * RGB reflectances. */
static pn_vpl_receiver unit_receiver(const pn_vpl_receiver *r) {
    pn_vpl_receiver u = *r;
    u.wl.on = false;
    return u;
}
static pn_vpl_receiver rgb_receiver(const pn_vpl_receiver *r) {
    return pn_vpl_receiver_rgb(r->p, r->ng, r->ns, r->wo, r->kd, r->ks, r->exponent);
}

/* A cluster's term of the cut: its unit value times its summed intensity, in spectral mode at the
 * receiver's wavelengths as the representative's spectrum (the RGB sum as one illuminant or black
 * body: exact when the cluster's VPLs share one colour, docs/spectral.md). */
static vec3 cluster_value(const pn_lightcut_context *cx, const pn_vpl_receiver *r, const pn_light_node *nd, vec3 unit) {
    return v3_mul(unit, pn_vpl_intensity_at(cx->lights, &cx->set->vpls[nd->rep], nd->intensity, &r->wl));
}

/* The radiance at one receiver by a lightcut; adds bound evaluations and the cut size, and the
 * sum of the final cut's error bounds to *bound_sum (may be NULL). */
static bool lightcut_point(const pn_lightcut_context *cx, lc_scratch *s, const pn_vpl_receiver *r, vec3 *out,
                           uint32_t *shadow_rays, uint64_t *bounds, uint64_t *cut_size, float *bound_sum) {
    const pn_vpl_receiver ru = unit_receiver(r), rr = rgb_receiver(r);
    const pn_vpl_receiver *r_rgb = r->wl.on ? &rr : NULL;
    const pn_light_tree *t = cx->tree;
    const pn_vpl_set *set = cx->set;
    pn_receiver_bounds rb = {r->p, r->p,  r->ns, 0.0f,        pn_reflect(r->wo, r->ns),
                             0.0f, r->kd, r->ks, r->exponent, r->exponent,
                             1.0f, 0.0f,  1.0f,  0.0f};
    s->used = 0;
    pn_heap_clear(&s->heap);
    vec3 total = v3(0, 0, 0), total_rgb = v3(0, 0, 0); /* total_rgb: RGB mode's, for the stopping test */
    uint64_t finished = 0; /* clusters of the cut outside the heap (exact leaves, zero bounds) */
    for (int k = 0; k < PN_VPL_KIND_COUNT; k++) {
        int32_t root = t->roots[k];
        if (root < 0) continue;
        const pn_light_node *nd = &t->nodes[root];
        cut_entry e = {0.0f, root, k, v3(0, 0, 0), v3(0, 0, 0), v3(0, 0, 0)};
        e.unit = unit_value(cx, nd->rep, &ru, r_rgb, &e.unit_rgb, shadow_rays);
        e.value = cluster_value(cx, r, nd, e.unit);
        total = v3_add(total, e.value);
        total_rgb = v3_add(total_rgb, v3_mul(e.unit_rgb, nd->intensity));
        if (nd->left >= 0) {
            pn_light_bounds lb = pn_light_node_bounds(nd, k);
            e.bound = pn_bound_error(&rb, &lb, nd->intensity, set->min_dist2);
            (*bounds)++;
        }
        if (e.bound > 0.0f) {
            if (!open_push(s, e)) return false;
        } else {
            finished++;
        }
    }
    const float delta = cx->error_bound;
    while (s->heap.count > 0) {
        if ((float)pn_heap_top(&s->heap).key <= delta * v3_luminance(total_rgb)) break;
        if (cx->max_cut > 0 && s->heap.count + finished >= cx->max_cut) break;
        cut_entry e = s->open[pn_heap_pop(&s->heap).payload];
        const pn_light_node *nd = &t->nodes[e.node];
        total = v3_sub(total, e.value);
        total_rgb = v3_sub(total_rgb, v3_mul(e.unit_rgb, nd->intensity));
        int32_t kids[2] = {nd->left, nd->right};
        for (int c = 0; c < 2; c++) {
            const pn_light_node *ch = &t->nodes[kids[c]];
            cut_entry ce = {0.0f, kids[c], e.kind, v3(0, 0, 0), v3(0, 0, 0), v3(0, 0, 0)};
            if (ch->rep == nd->rep) {
                ce.unit = e.unit;
                ce.unit_rgb = e.unit_rgb;
            } else {
                ce.unit = unit_value(cx, ch->rep, &ru, r_rgb, &ce.unit_rgb, shadow_rays);
            }
            ce.value = cluster_value(cx, r, ch, ce.unit);
            total = v3_add(total, ce.value);
            total_rgb = v3_add(total_rgb, v3_mul(ce.unit_rgb, ch->intensity));
            if (ch->left >= 0) {
                pn_light_bounds lb = pn_light_node_bounds(ch, e.kind);
                ce.bound = pn_bound_error(&rb, &lb, ch->intensity, set->min_dist2);
                (*bounds)++;
            }
            if (ce.bound > 0.0f) {
                if (!open_push(s, ce)) return false;
            } else {
                finished++;
            }
        }
    }
    *cut_size += s->heap.count + finished;
    if (bound_sum) {
        float b = 0.0f;
        for (size_t i = 0; i < s->heap.count; i++) b += (float)s->heap.entries[i].key;
        *bound_sum = b;
    }
    *out = v3(fmaxf(0.0f, total.x), fmaxf(0.0f, total.y), fmaxf(0.0f, total.z));
    return true;
}

static pn_status lc_prepare(pn_render_job *job, pn_err *err) {
    return pn_vpl_prepare(job, true, err);
}

static pn_status lc_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                 void *scratch) {
    pn_vpl_data *d = job->integrator_data;
    lc_scratch *s = scratch;
    pn_lightcut_context cx = {job->lights,      job->accel,   &d->set,           &d->tree,
                              job->error_bound, job->max_cut, !job->opaque_glass};
    const uint32_t spp = pn_vpl_spp(job);
    const bool mel = (job->aovs & PN_AOV_MELANOPIC_EDI) != 0 && job->spectral;
    uint64_t bounds_total = 0, cut_total = 0, points = 0;
    for (int pi = 0; pi < batch->count; pi++) {
        if (atomic_load(job->cancel)) break;
        pn_pixel_estimate *o = &out[pi];
        memset(o, 0, sizeof *o);
        o->depth = INFINITY;
        vec3 sum = v3(0, 0, 0);
        double wsum = 0.0, lux_sum = 0.0, mel_sum = 0.0;
        uint64_t bounds = 0, cut = 0, pts = 0;
        for (uint32_t smp = 0; smp < spp; smp++) {
            pn_shading_point sp;
            pn_batch_eye_point(job, batch, pi, smp, &sp, o);
            vec3 value = sp.emitted;
            if (sp.has_point) {
                vec3 L;
                if (!lightcut_point(&cx, s, &sp.r, &L, &o->shadow_rays, &bounds, &cut, NULL))
                    return PN_ERROR_OUT_OF_MEMORY;
                pts++;
                value = v3_add(value, v3_mul(sp.throughput, L));
                if (job->aovs & PN_AOV_ILLUMINANCE) {
                    /* Illuminance: a lightcut of its own for a white Lambertian receiver (the same
                     * error bound, relative to the irradiance). */
                    pn_vpl_receiver white = pn_vpl_irradiance_receiver(&sp.r);
                    vec3 E;
                    uint64_t b2 = 0, c2 = 0;
                    if (!lightcut_point(&cx, s, &white, &E, &o->shadow_rays, &b2, &c2, NULL))
                        return PN_ERROR_OUT_OF_MEMORY;
                    float lx = pn_photometric(E);
                    if (isfinite(lx)) lux_sum += (double)lx * (double)sp.weight;
                }
                if (mel && sp.r.wl.on) {
                    /* Melanopic EDI: the white receiver's lightcut at the eye sample's wavelengths
                     * (its cut is the RGB one's: the stopping test uses RGB mode's total). */
                    pn_vpl_receiver white_wl = pn_vpl_irradiance_receiver(&sp.r);
                    white_wl.wl = sp.r.wl;
                    vec3 E_wl;
                    uint64_t b2 = 0, c2 = 0;
                    if (!lightcut_point(&cx, s, &white_wl, &E_wl, &o->shadow_rays, &b2, &c2, NULL))
                        return PN_ERROR_OUT_OF_MEMORY;
                    float m = pn_swl_melanopic_edi_on(&sp.r.wl, E_wl);
                    if (isfinite(m)) mel_sum += (double)m * (double)sp.weight;
                }
            }
            value = pn_swl_rgb(&sp.r.wl, value); /* spectral mode: the sample's wavelengths to sRGB */
            if (!v3_is_finite(value)) {
                value = v3(0, 0, 0);
                o->non_finite++;
            }
            sum = v3_madd(sum, value, sp.weight);
            wsum += (double)sp.weight;
        }
        if (wsum != 0.0) o->radiance = v3_scale(sum, (float)(1.0 / wsum));
        if (wsum != 0.0) o->illuminance = (float)(lux_sum / wsum);
        if (wsum != 0.0) o->melanopic_edi = (float)(mel_sum / wsum);
        o->bound_evaluations = (float)bounds;
        o->cut_size = pts ? (float)cut / (float)pts : 0.0f;
        bounds_total += bounds;
        cut_total += cut;
        points += pts;
    }
    atomic_fetch_add(&d->bound_evaluations, bounds_total);
    atomic_fetch_add(&d->cut_nodes, cut_total);
    atomic_fetch_add(&d->points, points);
    return PN_OK;
}

const pn_integrator pn_integrator_lightcuts = {
    .name = "lightcuts",
    .prepare = lc_prepare,
    .release = pn_vpl_release,
    .report = pn_vpl_report,
    .scratch_create = lc_scratch_create,
    .scratch_free = lc_scratch_free,
    .render_batch = lc_render_batch,
    .batch_points = pn_vpl_batch_points,
};

bool pn_lightcut_eval(const pn_lightcut_context *cx, const pn_vpl_receiver *r, vec3 *radiance, float *bound_sum,
                      uint32_t *cut_size, uint32_t *shadow_rays) {
    lc_scratch *s = lc_scratch_create(NULL);
    if (!s) return false;
    uint64_t bounds = 0, cut = 0;
    uint32_t rays = 0;
    bool ok = lightcut_point(cx, s, r, radiance, &rays, &bounds, &cut, bound_sum);
    lc_scratch_free(s);
    if (cut_size) *cut_size = (uint32_t)cut;
    if (shadow_rays) *shadow_rays = rays;
    return ok;
}
