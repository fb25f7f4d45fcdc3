/* bounds.c — M_max and G_max of Lightcuts / Multidimensional Lightcuts (see bounds.h). */
#include "shade/bounds.h"

/* Inline min / max (the libm calls were a tenth of the render time). */
static inline float mnf(float a, float b) {
    return a < b ? a : b;
}
static inline float mxf(float a, float b) {
    return a > b ? a : b;
}

float pn_bound_cos_cs(vec3 lo, vec3 hi, vec3 axis, float cos_half, float sin_half) {
    if (cos_half <= -1.0f) return 1.0f;
    if (lo.x <= 0.0f && hi.x >= 0.0f && lo.y <= 0.0f && hi.y >= 0.0f && lo.z <= 0.0f && hi.z >= 0.0f) return 1.0f;
    vec3 t, b;
    v3_basis(axis, &t, &b);
    /* The box rotated into the frame (t, b, axis), re-boxed: centre rotated, half-extent through
     * the absolute rotation (the bounding box of the eight rotated corners). */
    vec3 c = v3_scale(v3_add(lo, hi), 0.5f), e = v3_scale(v3_sub(hi, lo), 0.5f);
    float cx = v3_dot(c, t), cy = v3_dot(c, b), cz = v3_dot(c, axis);
    float ex = fabsf(t.x) * e.x + fabsf(t.y) * e.y + fabsf(t.z) * e.z;
    float ey = fabsf(b.x) * e.x + fabsf(b.y) * e.y + fabsf(b.z) * e.z;
    float ez = fabsf(axis.x) * e.x + fabsf(axis.y) * e.y + fabsf(axis.z) * e.z;
    /* Rounding of the rotation: grow the box a little so that it still contains the rotated one. */
    float slack = 1e-6f * (fabsf(cx) + fabsf(cy) + fabsf(cz) + ex + ey + ez);
    ex += slack, ey += slack, ez += slack;
    float x0 = cx - ex, x1 = cx + ex, y0 = cy - ey, y1 = cy + ey, z1 = cz + ez;
    float cos_max;
    if (z1 > 0.0f) {
        float dx = (x0 <= 0.0f && x1 >= 0.0f) ? 0.0f : mnf(x0 * x0, x1 * x1);
        float dy = (y0 <= 0.0f && y1 >= 0.0f) ? 0.0f : mnf(y0 * y0, y1 * y1);
        float d2 = dx + dy;
        cos_max = d2 <= 0.0f ? 1.0f : z1 / sqrtf(d2 + z1 * z1);
    } else {
        float d2 = mxf(x0 * x0, x1 * x1) + mxf(y0 * y0, y1 * y1);
        float l2 = d2 + z1 * z1;
        cos_max = l2 > 0.0f ? z1 / sqrtf(l2) : 1.0f;
    }
    cos_max = mnf(1.0f, mxf(-1.0f, cos_max + 1e-5f));
    if (sin_half <= 0.0f && cos_half >= 1.0f) return cos_max;
    /* cos(max(0, theta - half)) = cos theta cos half + sin theta sin half when theta > half. */
    if (cos_max >= cos_half) return 1.0f;
    float s = sqrtf(mxf(0.0f, 1.0f - cos_max * cos_max));
    return mnf(1.0f, cos_max * cos_half + s * sin_half + 1e-6f);
}

float pn_bound_cos(vec3 lo, vec3 hi, vec3 axis, float half) {
    if (half >= PN_PI) return 1.0f;
    return pn_bound_cos_cs(lo, hi, axis, half > 0.0f ? cosf(half) : 1.0f, half > 0.0f ? sinf(half) : 0.0f);
}

float pn_box_distance2(vec3 alo, vec3 ahi, vec3 blo, vec3 bhi) {
    float dx = mxf(0.0f, mxf(blo.x - ahi.x, alo.x - bhi.x));
    float dy = mxf(0.0f, mxf(blo.y - ahi.y, alo.y - bhi.y));
    float dz = mxf(0.0f, mxf(blo.z - ahi.z, alo.z - bhi.z));
    return dx * dx + dy * dy + dz * dz;
}

float pn_bound_geometric(const pn_receiver_bounds *r, const pn_light_bounds *q, float min_dist2) {
    if (q->kind == PN_VPL_DIRECTIONAL) return 1.0f;
    float d2 = mxf(pn_box_distance2(r->lo, r->hi, q->lo, q->hi), min_dist2);
    if (!(d2 > 0.0f)) return INFINITY;
    float g = 1.0f / d2;
    if (q->kind == PN_VPL_ORIENTED) {
        /* phi: between the VPL normal and light-to-point vectors p - s. */
        float c = pn_bound_cos_cs(v3_sub(r->lo, q->hi), v3_sub(r->hi, q->lo), q->axis, q->cos_half, q->sin_half);
        if (c <= 0.0f) return 0.0f;
        g *= c;
    }
    return g;
}

float pn_bound_lobe(float cb, float n_min, float n_max) {
    /* f(n) = (n + 2) cb^n / (2 pi): ln f = ln(n + 2) + n ln cb is concave in n, so over
     * [n_min, n_max] f is largest at the stationary point n* = -1 / ln cb - 2 clamped to the
     * range (n_max when cb >= 1, where f only grows). Tighter than (n_max + 2) cb^n_min, which
     * pairs the largest factor with the largest power, and equal to it for one exponent. */
    float n = n_max;
    if (cb < 1.0f && n_min < n_max) {
        if (cb <= 0.0f)
            n = n_min;
        else
            n = mnf(n_max, mxf(n_min, -1.0f / logf(cb) - 2.0f));
    }
    return (n + 2.0f) * (0.5f * PN_INV_PI) * powf(cb, n);
}

vec3 pn_bound_material(const pn_receiver_bounds *r, const pn_light_bounds *q) {
    vec3 lo, hi; /* point-to-light vectors s - p */
    if (q->kind == PN_VPL_DIRECTIONAL) {
        lo = q->lo;
        hi = q->hi;
    } else {
        lo = v3_sub(q->lo, r->hi);
        hi = v3_sub(q->hi, r->lo);
    }
    float cos_theta = pn_bound_cos_cs(lo, hi, r->n_axis, r->n_cos, r->n_sin);
    if (cos_theta <= 0.0f) return v3(0, 0, 0);
    vec3 m = v3_scale(r->kd_max, PN_INV_PI);
    if (!v3_is_zero(r->ks_max)) {
        float cb = mxf(0.0f, pn_bound_cos_cs(lo, hi, r->r_axis, r->r_cos, r->r_sin));
        m = v3_madd(m, r->ks_max, pn_bound_lobe(cb, r->n_min, r->n_max));
    }
    return v3_scale(m, cos_theta);
}

float pn_bound_error(const pn_receiver_bounds *r, const pn_light_bounds *q, vec3 intensity_sum, float min_dist2) {
    float g = pn_bound_geometric(r, q, min_dist2);
    if (g <= 0.0f) return 0.0f;
    vec3 m = pn_bound_material(r, q);
    return v3_luminance(v3_mul(m, intensity_sum)) * g;
}

void pn_cone_merge(vec3 a1, float h1, vec3 a2, float h2, vec3 *axis, float *half) {
    if (h1 >= PN_PI || h2 >= PN_PI) {
        *axis = a1;
        *half = PN_PI;
        return;
    }
    /* atan2 keeps small angles accurate (acos of a cosine near 1 does not). */
    float theta = atan2f(v3_length(v3_cross(a1, a2)), v3_dot(a1, a2));
    if (theta + h2 <= h1) {
        *axis = a1;
        *half = h1;
        return;
    }
    if (theta + h1 <= h2) {
        *axis = a2;
        *half = h2;
        return;
    }
    float h = 0.5f * (theta + h1 + h2);
    if (h >= PN_PI) {
        *axis = a1;
        *half = PN_PI;
        return;
    }
    /* Rotate a1 towards a2 by (h - h1). */
    float phi = h - h1;
    float s = sinf(theta);
    vec3 a;
    if (s < 1e-6f && theta > 1.0f) { /* opposite axes: no preferred rotation, take everything */
        *axis = a1;
        *half = PN_PI;
        return;
    }
    if (s < 1e-6f)
        a = a1;
    else
        a = v3_add(v3_scale(a1, sinf(theta - phi) / s), v3_scale(a2, sinf(phi) / s));
    *axis = v3_normalize(a);
    *half = fminf(PN_PI, h * (1.0f + 1e-5f) + 1e-6f);
}
