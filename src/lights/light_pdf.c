/* light_pdf.c — the unoccluded-irradiance estimates of all lights at one point, in one pass.
 *
 * The reference integrator (IAS paper §5.1) builds, at every eye-ray hit, a PDF over all lights
 * proportional to each light's unoccluded irradiance; with hundreds of lights this loop, not ray
 * tracing, is where the time goes. The lights are therefore also stored as plain arrays
 * (structure of arrays), and a first loop without branches — which the compiler vectorises —
 * computes for every light the far-field value:
 *
 *   point-like (point lights, spheres):  E = P * max(0, cos_r) / d^2,   P = I or L * pi * r^2
 *   planar (triangle, rectangle, disk):  E = P * cos_l * cos_r / d^2,   P = L * area
 *
 * with d the distance to the light's centre, cos_r the cosine at the receiver and cos_l at the
 * light. It is exact for points, and for spheres wholly above the horizon; for small planar
 * lights far away its relative error is of order (radius / d)^2. Lights for which it is not
 * good enough — planar lights nearer than PN_PDF_FAR_FIELD radii or straddling the horizon,
 * spheres straddling the horizon, spots (falloff), distant and environment lights — are flagged
 * by the same loop and recomputed exactly by pn_light_irradiance_estimate. */
#include "lights/lights.h"

#include <stdlib.h>
#include <string.h>

#define PN_PDF_FAR_FIELD 8.0f

enum { SOA_POINT = 0, SOA_PLANAR_ONE = 1, SOA_PLANAR_TWO = 2, SOA_EXACT = 3 };

pn_status pn_lights_build_soa(pn_lights *L, pn_err *err) {
    size_t n = (size_t)L->count;
    float *block = calloc(n * 9 + 1, sizeof *block);
    int *cls = calloc(n + 1, sizeof *cls);
    if (!block || !cls) {
        free(block);
        free(cls);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for %zu lights", n);
    }
    pn_light_soa *s = &L->soa;
    s->cx = block;
    s->cy = block + n;
    s->cz = block + 2 * n;
    s->nx = block + 3 * n;
    s->ny = block + 4 * n;
    s->nz = block + 5 * n;
    s->r2 = block + 6 * n;
    s->power = block + 7 * n;
    s->far2 = block + 8 * n;
    s->cls = cls;
    for (size_t i = 0; i < n; i++) {
        const pn_light *l = &L->lights[i];
        vec3 c = l->p, nn = v3(0, 0, 0);
        float r2 = 0.0f, power = 0.0f, lum = fmaxf(0.0f, v3_luminance(l->emit));
        int k = SOA_EXACT;
        switch (l->kind) {
        case PN_LIGHT_POINT:
            k = SOA_POINT;
            power = lum;
            break;
        case PN_LIGHT_SPHERE:
            k = SOA_POINT;
            r2 = l->radius * l->radius;
            power = lum * PN_PI * r2;
            break;
        case PN_LIGHT_TRIANGLE:
        case PN_LIGHT_RECTANGLE:
        case PN_LIGHT_DISK: {
            k = l->two_sided ? SOA_PLANAR_TWO : SOA_PLANAR_ONE;
            nn = l->n;
            power = lum * l->area;
            if (l->kind == PN_LIGHT_TRIANGLE) {
                c = v3_add(l->p, v3_scale(v3_add(l->e1, l->e2), 1.0f / 3.0f));
                r2 = fmaxf(v3_length2(v3_sub(l->p, c)),
                           fmaxf(v3_length2(v3_sub(v3_add(l->p, l->e1), c)), v3_length2(v3_sub(v3_add(l->p, l->e2), c))));
            } else if (l->kind == PN_LIGHT_RECTANGLE) {
                c = v3_add(l->p, v3_scale(v3_add(l->e1, l->e2), 0.5f));
                r2 = 0.25f * v3_length2(v3_add(l->e1, l->e2));
            } else {
                r2 = l->radius * l->radius;
            }
            break;
        }
        default:
            break;
        }
        s->cx[i] = c.x;
        s->cy[i] = c.y;
        s->cz[i] = c.z;
        s->nx[i] = nn.x;
        s->ny[i] = nn.y;
        s->nz[i] = nn.z;
        s->r2[i] = r2;
        s->power[i] = power;
        /* Planar lights need the far field; spheres are exact once above the horizon. */
        s->far2[i] = (k == SOA_PLANAR_ONE || k == SOA_PLANAR_TWO) ? PN_PDF_FAR_FIELD * PN_PDF_FAR_FIELD * r2 : 0.0f;
        s->cls[i] = k;
    }
    return PN_OK;
}

void pn_lights_free_soa(pn_lights *L) {
    free(L->soa.cx);
    free(L->soa.cls);
    memset(&L->soa, 0, sizeof L->soa);
}

int pn_lights_irradiance_all(const pn_lights *L, vec3 p, vec3 n, float *out, int *exact) {
    const pn_light_soa *s = &L->soa;
    const int count = L->count;
    /* Pass 1: far-field values and a flag where they do not apply (no branches). */
    for (int i = 0; i < count; i++) {
        float dx = s->cx[i] - p.x, dy = s->cy[i] - p.y, dz = s->cz[i] - p.z;
        float d2 = dx * dx + dy * dy + dz * dz;
        float above = dx * n.x + dy * n.y + dz * n.z;           /* d * cos_r */
        float plane = -(dx * s->nx[i] + dy * s->ny[i] + dz * s->nz[i]); /* d * cos_l, > 0 in front */
        int cls = s->cls[i];
        float inv_d2 = 1.0f / fmaxf(d2, 1e-30f);
        float inv_d = sqrtf(inv_d2);
        float point_e = s->power[i] * fmaxf(above, 0.0f) * inv_d2 * inv_d;
        float planar_cos_l = cls == SOA_PLANAR_TWO ? fabsf(plane) : fmaxf(plane, 0.0f);
        float planar_e = s->power[i] * planar_cos_l * fmaxf(above, 0.0f) * inv_d2 * inv_d2;
        out[i] = cls == SOA_POINT ? point_e : planar_e;
        /* Valid when the light lies wholly above the horizon (or wholly below: then zero) and,
         * for planar lights, is far enough away. */
        int straddles = above * above <= s->r2[i] && s->r2[i] > 0.0f;
        int near = d2 <= s->far2[i];
        int behind = cls == SOA_PLANAR_ONE && plane <= 0.0f; /* exact zero */
        exact[i] = cls == SOA_EXACT || (!behind && (straddles || near));
    }
    /* Pass 2: the exact estimate where the far field does not apply. */
    int flagged = 0;
    for (int i = 0; i < count; i++) {
        if (!exact[i]) continue;
        out[i] = pn_light_irradiance_estimate(L, &L->lights[i], p, n);
        flagged++;
    }
    return flagged;
}
