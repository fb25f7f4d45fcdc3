/* contour_math.h — the closed forms of Vedel 1993 (Approximate Contour Integration) that do not
 * trace rays: the form factor of a polygonal contour (eq. 4), its vector form G (eq. 5) and the
 * translational derivatives of G (appendix, eq. 8-10), the strip threshold of §3.2, and the
 * parametrisation of a planar convex source (rectangle or triangle) by the unit square. */
#ifndef PN_INTEGRATORS_CONTOUR_MATH_H
#define PN_INTEGRATORS_CONTOUR_MATH_H

#include "core/vecmath.h"

#include <stdbool.h>

/* Double-precision vectors: eq. 4 sums angles of nearly parallel directions in penumbrae. */
typedef struct pn_dvec3 {
    double x, y, z;
} pn_dvec3;

static inline pn_dvec3 pn_dv3(double x, double y, double z) {
    return (pn_dvec3){x, y, z};
}
static inline pn_dvec3 pn_dv3_from(vec3 a) {
    return pn_dv3((double)a.x, (double)a.y, (double)a.z);
}
static inline vec3 pn_dv3_to(pn_dvec3 a) {
    return v3((float)a.x, (float)a.y, (float)a.z);
}
static inline pn_dvec3 pn_dv3_add(pn_dvec3 a, pn_dvec3 b) {
    return pn_dv3(a.x + b.x, a.y + b.y, a.z + b.z);
}
static inline pn_dvec3 pn_dv3_sub(pn_dvec3 a, pn_dvec3 b) {
    return pn_dv3(a.x - b.x, a.y - b.y, a.z - b.z);
}
static inline pn_dvec3 pn_dv3_scale(pn_dvec3 a, double s) {
    return pn_dv3(a.x * s, a.y * s, a.z * s);
}
static inline double pn_dv3_dot(pn_dvec3 a, pn_dvec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static inline pn_dvec3 pn_dv3_cross(pn_dvec3 a, pn_dvec3 b) {
    return pn_dv3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double pn_dv3_length(pn_dvec3 a) {
    return sqrt(pn_dv3_dot(a, a));
}

/* The vector G of eq. 5 for a set of contour segments, with its translational derivatives:
 * F = g . n, and dF/dM_k = dg[k] . n for a receiver moved along axis k with its normal fixed.
 * g already carries the 1/(2 pi) of eq. 4, so F is the (dimensionless) form factor. */
typedef struct pn_contour_g {
    pn_dvec3 g;
    pn_dvec3 dg[3];
} pn_contour_g;

/* Adds the contribution of the oriented segment a -> b (points relative to the receiver M) to g:
 * beta * n_ab / (2 pi), eq. 6-7, where beta is the angle between a and b and n_ab the unit
 * normal of the plane (M, a, b) along a x b. With `derivatives`, also adds eq. 8: the derivative
 * of that term when M moves while the 3D points A and B stay fixed (eq. 9 for beta, eq. 10 for
 * n_ab). Zero-length or degenerate segments add nothing. */
void pn_contour_add_segment(pn_contour_g *acc, pn_dvec3 a, pn_dvec3 b, bool derivatives);

/* The same with moving endpoints: va[k] = dA/dM_k, vb[k] = dB/dM_k (NULL: fixed points). */
void pn_contour_add_segment_moving(pn_contour_g *acc, pn_dvec3 a, pn_dvec3 b, const pn_dvec3 *va, const pn_dvec3 *vb,
                                   bool derivatives);

/* Velocity dP/dM_k (k = x, y, z) of the point P where the source border line (through P, unit
 * direction t) meets the plane through M and a silhouette line (through the obstacle point i,
 * direction ds): P slides along the border as M moves. */
void pn_contour_border_velocity(pn_dvec3 p, pn_dvec3 t, pn_dvec3 i, pn_dvec3 ds, pn_dvec3 m, pn_dvec3 v[3]);

/* Adds the closed polygon v[0..count) (relative to M), after clipping it to the half-spaces
 * n1 . x >= 0 and n2 . x >= 0 (the receiver's shading and geometric horizons; pass the same
 * vector twice for one), multiplied by sign (+1 or -1). A polygon turning positively (right-hand
 * rule) about the direction from M towards it adds a positive form factor. Clipped horizon
 * vertices are treated as fixed points for the derivatives. count <= 16. */
void pn_contour_add_polygon(pn_contour_g *acc, const pn_dvec3 *v, int count, pn_dvec3 n1, pn_dvec3 n2, double sign,
                            bool derivatives);

/* Form factor (eq. 4) of the polygon v[0..count) relative to M with normal n, clipped to the
 * hemisphere of n; the absolute value (either orientation). */
double pn_contour_polygon_form_factor(const pn_dvec3 *v, int count, pn_dvec3 n);

/* The validity threshold of §3.2: the form factor from M (normal n) of a strip of width eps
 * along the segment a -> b (relative to M) on a source of unit normal ns, approximated as the
 * elementary form factor of a disc of the strip's area seen from M (Wallace et al. 1989). */
double pn_contour_strip_threshold(pn_dvec3 a, pn_dvec3 b, double eps, pn_dvec3 n, pn_dvec3 ns);

/* A planar convex source as the image of the unit square: P(u, v) = p0 + u e1 + v e2 + u v k.
 * Rectangles (parallelograms): k = 0; convex quadrilaterals: k != 0. Triangles p0 p1 p2: e1 = p1 - p0, e2 = 0,
 * k = p2 - p1, so the side u = 0 collapses onto p0 and the sides v = 0, u = 1, v = 1 are the
 * triangle's three edges. Lines u = const and v = const are straight in both cases, so every
 * cell of a grid on (u, v) maps to a planar convex quadrilateral and the cells tile the source.
 * uv_sign is the sign to give polygons that turn counter-clockwise in (u, v) so that they add a
 * positive form factor for receivers in front of the emitting normal (pn_contour_source_sign). */
typedef struct pn_contour_source {
    pn_dvec3 p0, e1, e2, k;
    pn_dvec3 normal;  /* unit emitting normal */
    double eps_scale; /* a typical length of the source (for the strip width eps) */
    double uv_sign;
    bool two_sided;
} pn_contour_source;

void pn_contour_source_rectangle(pn_contour_source *s, vec3 p0, vec3 e1, vec3 e2, vec3 normal, bool two_sided);
void pn_contour_source_triangle(pn_contour_source *s, vec3 p0, vec3 p1, vec3 p2, vec3 normal, bool two_sided);
/* A planar convex quadrilateral q0 q1 q2 q3 (in order around it) as the bilinear image of the unit
 * square: (0,0) -> q0, (1,0) -> q1, (1,1) -> q2, (0,1) -> q3. Its lines u = const and v = const
 * are straight too, so it can be diced like a rectangle (used for disks as polygons). */
void pn_contour_source_quad(pn_contour_source *s, vec3 q0, vec3 q1, vec3 q2, vec3 q3, vec3 normal, bool two_sided);

static inline pn_dvec3 pn_contour_source_point(const pn_contour_source *s, double u, double v) {
    return pn_dv3(s->p0.x + u * s->e1.x + v * s->e2.x + u * v * s->k.x,
                  s->p0.y + u * s->e1.y + v * s->e2.y + u * v * s->k.y,
                  s->p0.z + u * s->e1.z + v * s->e2.z + u * v * s->k.z);
}

/* The unoccluded form factor of the whole source seen from M with normals (ns, ng): eq. 4 on
 * the source's outline, clipped to both horizons; zero behind a one-sided source. With
 * derivatives, the gradient terms too. */
void pn_contour_source_unoccluded(const pn_contour_source *s, pn_dvec3 m, pn_dvec3 ns, pn_dvec3 ng, bool derivatives,
                                  pn_contour_g *out);

/* The sign for counter-clockwise (u, v) polygons seen from M, or 0 when M does not see the
 * emitting side (or lies in the source's plane). */
double pn_contour_source_sign(const pn_contour_source *s, pn_dvec3 m);

/* Closed-form form factor (for tests) from a differential area at height h below a corner of an
 * a x b rectangle, parallel to it (the classic catalogue case). */
double pn_contour_corner_rectangle_form_factor(double a, double b, double h);

#endif
