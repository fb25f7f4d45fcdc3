/* ias_speed.c — the irradiance prior and the emitter rays of the default `ias` variant (see
 * ias_speed.h; reasons and measured effects in ias.c's header and docs/methods/ias.md). */
#include "integrators/ias_speed.h"

#include "core/rng.h"

#include <math.h>

#define PN_IAS_FAR_FIELD 8.0f

double pn_ias_cluster_irradiance(const pn_cluster_forest *f, const pn_lights *lights, int node, vec3 p, vec3 n) {
    const pn_cluster_node *nd = &f->nodes[node];
    if (nd->light >= 0) {
        /* One light (a leaf, or a distant light's own node): as the reference's PDF, with its
         * far-field form for planar lights more than PN_IAS_FAR_FIELD radii away and wholly above
         * the horizon (the exact polygon irradiance was 19% of the render time on
         * bathroom-72-matte; light_pdf.c makes the same choice). */
        const pn_light *l = &lights->lights[nd->light];
        if (l->kind == PN_LIGHT_TRIANGLE || l->kind == PN_LIGHT_RECTANGLE || l->kind == PN_LIGHT_DISK) {
            vec3 d = v3_sub(nd->center, p);
            float d2 = v3_length2(d), r2 = nd->radius * nd->radius, above = v3_dot(n, d);
            if (d2 > PN_IAS_FAR_FIELD * PN_IAS_FAR_FIELD * r2 && above * above > r2 && !v3_is_zero(n)) {
                if (!(above > 0.0f)) return 0.0;
                float plane = -v3_dot(d, l->n); /* d cos_l, > 0 in front */
                float cos_l = l->two_sided ? fabsf(plane) : fmaxf(plane, 0.0f);
                double e = (double)fmaxf(v3_luminance(l->emit), 0.0f) * (double)l->area * (double)cos_l *
                           (double)above / ((double)d2 * (double)d2);
                return e > 0.0 && isfinite(e) ? (double)PN_PI * e : 0.0;
            }
        }
        double e = (double)pn_light_irradiance_estimate(lights, l, p, n);
        return e > 0.0 && isfinite(e) ? (double)PN_PI * e : 0.0;
    }
    /* A cluster: its power seen as from its centre, the receiver's cosine widened by the bounding
     * sphere (a cluster straddling the horizon keeps a share), the distance not below the radius.
     * Oriented trees hold planar lights, whose power pi L A gives E = (power / pi) cos / d^2 when
     * they face the point; the omni tree isotropic ones, E = (power / 4 pi) cos / d^2. */
    vec3 d = v3_sub(nd->center, p);
    double d2 = (double)v3_length2(d), r = (double)nd->radius;
    double dist = sqrt(d2);
    double c = dist > 0.0 ? ((double)v3_dot(n, d) + r) / fmax(dist, r) : 1.0;
    if (v3_is_zero(n)) c = 1.0; /* no horizon (transmissive surfaces) */
    c = fmin(fmax(c, 0.0), 1.0);
    double share = nd->tree == PN_TREE_OMNI ? 0.25 : 1.0;
    double e = share * (double)nd->power * c / fmax(d2, r * r);
    return e > 0.0 && isfinite(e) ? e : 0.0;
}

void pn_ias_prior_pdf(const double *prior, int count, double *out) {
    double sum = 0.0;
    for (int i = 0; i < count; i++) sum += prior[i];
    const double s = sum > 0.0 ? PN_IAS_PRIOR_UNIFORM_SHARE : 1.0;
    const double k = sum > 0.0 ? (1.0 - s) / sum : 0.0;
    for (int i = 0; i < count; i++) out[i] = k * prior[i] + s / (double)count;
}

bool pn_ias_emitter_edge(const int32_t (*xy)[2], const uint32_t *hits, uint32_t rays, int count, int self) {
    bool hit = false, miss = false;
    for (int k = 0; k < count; k++) {
        if (k == self) continue;
        int dx = xy[k][0] - xy[self][0], dy = xy[k][1] - xy[self][1];
        if (dx < -1 || dx > 1 || dy < -1 || dy > 1) continue;
        hit |= hits[k] > 0;
        miss |= hits[k] < rays;
    }
    return hit && miss;
}

uint32_t pn_ias_emitter_rays(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t count, vec3 *emitted,
                             double *weight_sum) {
    enum { CHUNK = 16 };
    pn_eye_hit buf[CHUNK];
    uint32_t calls = 0;
    vec3 e = v3(0, 0, 0);
    double w = 0.0;
    for (uint32_t i = 0; i < count; i += CHUNK) {
        uint32_t n = count - i < CHUNK ? count - i : CHUNK;
        const pn_eye_hit *h = pn_batch_eye_hits(job, batch, pi, PN_EYE_SEQ_IAS_EMITTER, i, n, buf);
        for (uint32_t k = 0; k < n; k++) {
            calls += h[k].path.rays;
            if (v3_is_finite(h[k].path.emitted)) e = v3_madd(e, h[k].path.emitted, h[k].weight);
            w += (double)h[k].weight;
        }
    }
    *emitted = v3_add(*emitted, e);
    *weight_sum += w;
    return calls;
}
