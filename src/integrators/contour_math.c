/* contour_math.c — closed forms of Vedel 1993: eq. 4 (form factor of a polygonal contour), eq. 5-7
 * (its vector G), eq. 8-10 (derivatives of G when the receiver moves), the §3.2 strip threshold,
 * and planar convex sources parametrised by the unit square.
 *
 * The derivative of one segment's term, as used here (our notation; a = A - M, b = B - M with A,
 * B fixed, e a unit axis, M moved by t e):
 *   w = a x b, s = |w|, c = a . b, beta = atan2(s, c), n = w / s;
 *   dw = e x (a - b)  (the appendix's "C_i C_{i+1} x I"),   dc = -e . (a + b),
 *   ds = n . dw,  dbeta = (c ds - s dc) / (s^2 + c^2)  (eq. 9, written with atan2),
 *   dn = (dw - (n . dw) n) / s  (eq. 10),   d(beta n) = dbeta n + beta dn  (eq. 8).
 * Departure: the appendix differentiates with every contour point fixed. A vertex where a
 * silhouette crosses the source's border is not fixed: it slides along the border as M moves,
 * and ignoring that leaves a first-order error (a sliver along the border). Endpoints may
 * therefore carry a velocity dA/dM (pn_contour_border_velocity), and then
 * dw = da x b + a x db, dc = da . b + a . db with da = dA/dM - e. */
#include "integrators/contour_math.h"

#include <stddef.h>

#define PN_TWO_PI 6.28318530717958647692

void pn_contour_add_segment_moving(pn_contour_g *acc, pn_dvec3 a, pn_dvec3 b, const pn_dvec3 *va, const pn_dvec3 *vb,
                                   bool derivatives) {
    pn_dvec3 w = pn_dv3_cross(a, b);
    double s = pn_dv3_length(w);
    double c = pn_dv3_dot(a, b);
    if (!(s > 1e-12 * fabs(c))) {
        /* Collinear with M (a segment along a ray from M, or zero length): no area swept, but
         * when its ends move differently it opens up: beta n ~ w / c for small angles. */
        if (!derivatives || !(c > 0.0) || (!va && !vb)) return;
        for (int k = 0; k < 3; k++) {
            pn_dvec3 e = pn_dv3(k == 0, k == 1, k == 2);
            pn_dvec3 da = va ? pn_dv3_sub(va[k], e) : pn_dv3_scale(e, -1.0);
            pn_dvec3 db = vb ? pn_dv3_sub(vb[k], e) : pn_dv3_scale(e, -1.0);
            pn_dvec3 dw = pn_dv3_add(pn_dv3_cross(da, b), pn_dv3_cross(a, db));
            acc->dg[k] = pn_dv3_add(acc->dg[k], pn_dv3_scale(dw, 1.0 / (c * PN_TWO_PI)));
        }
        return;
    }
    double beta = atan2(s, c);
    pn_dvec3 n = pn_dv3_scale(w, 1.0 / s);
    acc->g = pn_dv3_add(acc->g, pn_dv3_scale(n, beta / PN_TWO_PI));
    if (!derivatives) return;
    for (int k = 0; k < 3; k++) {
        pn_dvec3 e = pn_dv3(k == 0, k == 1, k == 2);
        /* d(A - M)/dM_k = dA/dM_k - e */
        pn_dvec3 da = va ? pn_dv3_sub(va[k], e) : pn_dv3_scale(e, -1.0);
        pn_dvec3 db = vb ? pn_dv3_sub(vb[k], e) : pn_dv3_scale(e, -1.0);
        pn_dvec3 dw = pn_dv3_add(pn_dv3_cross(da, b), pn_dv3_cross(a, db));
        double dc = pn_dv3_dot(da, b) + pn_dv3_dot(a, db);
        double ndw = pn_dv3_dot(n, dw);
        double dbeta = (c * ndw - s * dc) / (s * s + c * c);
        pn_dvec3 dn = pn_dv3_scale(pn_dv3_sub(dw, pn_dv3_scale(n, ndw)), 1.0 / s);
        pn_dvec3 d = pn_dv3_add(pn_dv3_scale(n, dbeta), pn_dv3_scale(dn, beta));
        acc->dg[k] = pn_dv3_add(acc->dg[k], pn_dv3_scale(d, 1.0 / PN_TWO_PI));
    }
}

void pn_contour_add_segment(pn_contour_g *acc, pn_dvec3 a, pn_dvec3 b, bool derivatives) {
    pn_contour_add_segment_moving(acc, a, b, NULL, NULL, derivatives);
}

void pn_contour_border_velocity(pn_dvec3 p, pn_dvec3 t, pn_dvec3 i, pn_dvec3 ds, pn_dvec3 m, pn_dvec3 v[3]) {
    pn_dvec3 q = pn_dv3_cross(ds, pn_dv3_sub(i, m));
    double qt = pn_dv3_dot(q, t);
    pn_dvec3 pm = pn_dv3_sub(p, m);
    for (int k = 0; k < 3; k++) {
        pn_dvec3 e = pn_dv3(k == 0, k == 1, k == 2);
        double dl = fabs(qt) > 1e-300 ? (pn_dv3_dot(q, e) + pn_dv3_dot(pn_dv3_cross(ds, e), pm)) / qt : 0.0;
        v[k] = pn_dv3_scale(t, dl);
    }
}

/* Sutherland–Hodgman against the plane n . x = 0, keeping n . x >= 0. */
static int clip_polygon(const pn_dvec3 *in, int count, pn_dvec3 n, pn_dvec3 *out) {
    int m = 0;
    for (int i = 0; i < count; i++) {
        pn_dvec3 a = in[i], b = in[(i + 1) % count];
        double da = pn_dv3_dot(a, n), db = pn_dv3_dot(b, n);
        if (da >= 0.0) out[m++] = a;
        if ((da >= 0.0) != (db >= 0.0)) {
            double t = da / (da - db);
            out[m++] = pn_dv3_add(a, pn_dv3_scale(pn_dv3_sub(b, a), t));
        }
    }
    return m;
}

void pn_contour_add_polygon(pn_contour_g *acc, const pn_dvec3 *v, int count, pn_dvec3 n1, pn_dvec3 n2, double sign,
                            bool derivatives) {
    pn_dvec3 a[64], b[64];
    if (count < 2 || count > 16) return;
    int m = clip_polygon(v, count, n1, a);
    if (m < 3) return;
    m = clip_polygon(a, m, n2, b);
    if (m < 3) return;
    pn_contour_g part = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    for (int i = 0; i < m; i++) pn_contour_add_segment(&part, b[i], b[(i + 1) % m], derivatives);
    acc->g = pn_dv3_add(acc->g, pn_dv3_scale(part.g, sign));
    if (derivatives)
        for (int k = 0; k < 3; k++) acc->dg[k] = pn_dv3_add(acc->dg[k], pn_dv3_scale(part.dg[k], sign));
}

double pn_contour_polygon_form_factor(const pn_dvec3 *v, int count, pn_dvec3 n) {
    pn_contour_g acc = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    pn_contour_add_polygon(&acc, v, count, n, n, 1.0, false);
    return fabs(pn_dv3_dot(acc.g, n));
}

double pn_contour_strip_threshold(pn_dvec3 a, pn_dvec3 b, double eps, pn_dvec3 n, pn_dvec3 ns) {
    pn_dvec3 mid = pn_dv3_scale(pn_dv3_add(a, b), 0.5);
    double r2 = pn_dv3_dot(mid, mid);
    if (!(r2 > 0.0)) return 0.0;
    pn_dvec3 dir = pn_dv3_scale(mid, 1.0 / sqrt(r2));
    double area = eps * pn_dv3_length(pn_dv3_sub(b, a));
    double cos1 = fmax(0.0, pn_dv3_dot(n, dir)), cos2 = fabs(pn_dv3_dot(ns, dir));
    return area * cos1 * cos2 / (3.14159265358979323846 * r2 + area);
}

static void finish_source(pn_contour_source *s, vec3 normal, bool two_sided) {
    s->normal = pn_dv3_from(v3_normalize(normal));
    s->two_sided = two_sided;
    /* d/du x d/dv at the corner u = 1, v = 0 (non-degenerate for both shapes). */
    pn_dvec3 du = s->e1, dv = pn_dv3_add(s->e2, s->k);
    double orient = pn_dv3_dot(pn_dv3_cross(du, dv), s->normal) >= 0.0 ? 1.0 : -1.0;
    /* A (u, v)-counter-clockwise polygon turns positively about orient * normal; the direction
     * from a receiver in front towards the source is -normal, hence the minus sign. */
    s->uv_sign = -orient;
    s->eps_scale = 0.5 * (pn_dv3_length(du) + pn_dv3_length(dv));
}

void pn_contour_source_rectangle(pn_contour_source *s, vec3 p0, vec3 e1, vec3 e2, vec3 normal, bool two_sided) {
    s->p0 = pn_dv3_from(p0);
    s->e1 = pn_dv3_from(e1);
    s->e2 = pn_dv3_from(e2);
    s->k = pn_dv3(0, 0, 0);
    finish_source(s, normal, two_sided);
}

void pn_contour_source_triangle(pn_contour_source *s, vec3 p0, vec3 p1, vec3 p2, vec3 normal, bool two_sided) {
    s->p0 = pn_dv3_from(p0);
    s->e1 = pn_dv3_sub(pn_dv3_from(p1), s->p0);
    s->e2 = pn_dv3(0, 0, 0);
    s->k = pn_dv3_sub(pn_dv3_from(p2), pn_dv3_from(p1));
    finish_source(s, normal, two_sided);
}

void pn_contour_source_quad(pn_contour_source *s, vec3 q0, vec3 q1, vec3 q2, vec3 q3, vec3 normal, bool two_sided) {
    s->p0 = pn_dv3_from(q0);
    s->e1 = pn_dv3_sub(pn_dv3_from(q1), s->p0);
    s->e2 = pn_dv3_sub(pn_dv3_from(q3), s->p0);
    /* q2 = p0 + e1 + e2 + k */
    s->k = pn_dv3_sub(pn_dv3_sub(pn_dv3_from(q2), pn_dv3_from(q1)), s->e2);
    finish_source(s, normal, two_sided);
}

double pn_contour_source_sign(const pn_contour_source *s, pn_dvec3 m) {
    double side = pn_dv3_dot(pn_dv3_sub(m, s->p0), s->normal);
    if (side > 0.0) return s->uv_sign;
    if (side < 0.0 && s->two_sided) return -s->uv_sign;
    return 0.0;
}

void pn_contour_source_unoccluded(const pn_contour_source *s, pn_dvec3 m, pn_dvec3 ns, pn_dvec3 ng, bool derivatives,
                                  pn_contour_g *out) {
    *out = (pn_contour_g){{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    double sign = pn_contour_source_sign(s, m);
    if (sign == 0.0) return;
    static const double uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    pn_dvec3 v[4];
    for (int i = 0; i < 4; i++) v[i] = pn_dv3_sub(pn_contour_source_point(s, uv[i][0], uv[i][1]), m);
    pn_contour_add_polygon(out, v, 4, ns, ng, sign, derivatives);
}

double pn_contour_corner_rectangle_form_factor(double a, double b, double h) {
    double A = a / h, B = b / h;
    double sa = sqrt(1.0 + A * A), sb = sqrt(1.0 + B * B);
    return (A / sa * atan(B / sa) + B / sb * atan(A / sb)) / PN_TWO_PI;
}
