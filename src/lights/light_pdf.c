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
    float *block = calloc(n * 12 + 1, sizeof *block);
    int *only_exact = calloc(n + 1, sizeof *only_exact);
    if (!block || !only_exact) {
        free(block);
        free(only_exact);
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
    s->pointlike = block + 9 * n;
    s->two_sided = block + 10 * n;
    s->one_sided = block + 11 * n;
    s->only_exact = only_exact;
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
                r2 = fmaxf(v3_length2(v3_sub(l->p, c)), fmaxf(v3_length2(v3_sub(v3_add(l->p, l->e1), c)),
                                                              v3_length2(v3_sub(v3_add(l->p, l->e2), c))));
            } else if (l->kind == PN_LIGHT_RECTANGLE) {
                c = v3_add(l->p, v3_scale(v3_add(l->e1, l->e2), 0.5f));
                r2 = 0.25f * v3_length2(v3_add(l->e1, l->e2));
            } else {
                r2 = l->radius * l->radius;
            }
            break;
        }
        default: break;
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
        s->pointlike[i] = k == SOA_POINT ? 1.0f : 0.0f;
        s->two_sided[i] = k == SOA_PLANAR_TWO ? 1.0f : 0.0f;
        s->one_sided[i] = k == SOA_PLANAR_ONE ? 1.0f : 0.0f;
        s->only_exact[i] = k == SOA_EXACT;
    }
    return PN_OK;
}

void pn_lights_free_soa(pn_lights *L) {
    free(L->soa.cx);
    free(L->soa.only_exact);
    memset(&L->soa, 0, sizeof L->soa);
}

static inline float max0(float x) {
    return x > 0.0f ? x : 0.0f;
}

/* Pass 1: far-field values, and a flag where they do not apply. No branches, and restrict
 * parameters, so that the compiler vectorises it. */
static void far_field(int count, const float *restrict cx, const float *restrict cy, const float *restrict cz,
                      const float *restrict lnx, const float *restrict lny, const float *restrict lnz,
                      const float *restrict r2, const float *restrict power, const float *restrict far2,
                      const float *restrict pointlike, const float *restrict two, const float *restrict one,
                      const int *restrict only_exact, float *restrict out, int *restrict exact, float px, float py,
                      float pz, float nx, float ny, float nz) {
    for (int i = 0; i < count; i++) {
        float dx = cx[i] - px, dy = cy[i] - py, dz = cz[i] - pz;
        float d2 = dx * dx + dy * dy + dz * dz;
        float above = dx * nx + dy * ny + dz * nz;                /* d * cos_r */
        float plane = -(dx * lnx[i] + dy * lny[i] + dz * lnz[i]); /* d * cos_l, > 0 in front */
        float inv_d2 = 1.0f / (d2 + 1e-30f);                      /* the offset only matters at d = 0 */
        float inv_d = sqrtf(inv_d2);
        float a = max0(above);
        float point_e = power[i] * a * inv_d2 * inv_d;
        float cos_l = max0(plane) + two[i] * max0(-plane);
        float planar_e = power[i] * cos_l * a * inv_d2 * inv_d2;
        out[i] = pointlike[i] * point_e + (1.0f - pointlike[i]) * planar_e;
        /* Valid when the light lies wholly above the horizon (or wholly below: then zero) and,
         * for planar lights, is far enough away; exact zero behind a one-sided light. */
        int straddles = (above * above <= r2[i]) & (r2[i] > 0.0f);
        int near = d2 <= far2[i];
        int behind = (one[i] > 0.0f) & (plane <= 0.0f);
        exact[i] = only_exact[i] | ((behind ^ 1) & (straddles | near));
    }
}

int pn_lights_irradiance_all(const pn_lights *L, vec3 p, vec3 n, float *out, int *exact) {
    const pn_light_soa *s = &L->soa;
    const int count = L->count;
    far_field(count, s->cx, s->cy, s->cz, s->nx, s->ny, s->nz, s->r2, s->power, s->far2, s->pointlike, s->two_sided,
              s->one_sided, s->only_exact, out, exact, p.x, p.y, p.z, n.x, n.y, n.z);
    /* Pass 2: the exact estimate where the far field does not apply. */
    int flagged = 0;
    for (int i = 0; i < count; i++) {
        if (!exact[i]) continue;
        out[i] = pn_light_irradiance_estimate(L, &L->lights[i], p, n);
        flagged++;
    }
    return flagged;
}
