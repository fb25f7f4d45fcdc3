/* bounds.h — upper bounds of the material and geometric terms of eq. 1 over a cluster of
 * receiving points and a cluster of VPLs: M_max and G_max of Lightcuts (Walter et al. 2005, §4.1
 * "bounding the material and geometric terms") with the bounding-box transforms of
 * Multidimensional Lightcuts (Walter et al. 2006, §5 "bounding cosine terms"), as IlluminationCut
 * (Bus et al. 2015, eq. 5) uses them: L_UB = M_max · G_max · V_max(=1) · sum of intensities.
 *
 * The one primitive is pn_bound_cos: an upper bound of cos(angle(v, axis)) over every vector v of
 * an axis-aligned box, widened by a cone of directions around the axis. The box is rotated so
 * that the axis is +z and re-boxed (the bounding box of its eight rotated corners contains the
 * rotated box), where the maximum of z / |v| has a closed form. Every cosine of eq. 1 (theta at
 * the receiver, beta to the reflected view direction, phi at an oriented VPL) is bounded this
 * way over the box of all point-to-light vectors (the Minkowski difference of the two boxes).
 * A single point is the degenerate cluster (zero-size box, zero cone angles), which is how the
 * per-point Lightcuts uses the same code. */
#ifndef PN_SHADE_BOUNDS_H
#define PN_SHADE_BOUNDS_H

#include "core/vecmath.h"

/* The kinds of point emitter (VPL) the bounds tell apart: omni (uniform intensity), oriented
 * (cosine-weighted about a normal) and directional (at infinity). Declared here rather than in
 * lights/vpl.h so that shade/ depends on nothing in lights/ (lights/ builds on shade/: VPLs
 * bounce off BSDFs and the light tree uses these bounds). */
typedef enum pn_vpl_kind {
    PN_VPL_OMNI = 0,
    PN_VPL_ORIENTED = 1,
    PN_VPL_DIRECTIONAL = 2,
    PN_VPL_KIND_COUNT = 3
} pn_vpl_kind;

/* A cluster of receiving points: box of positions, cone of shading normals, cone of reflected
 * view directions, and per-channel maxima / range of the BRDF parameters (Lambert k_diff,
 * Blinn-Phong k_spec and exponent n). The exponent range is over the points with a non-zero
 * k_spec only (a Lambert point has no lobe to bound); it is unused when ks_max is zero. */
typedef struct pn_receiver_bounds {
    vec3 lo, hi;
    vec3 n_axis;
    float n_half; /* radians */
    vec3 r_axis;
    float r_half; /* radians */
    vec3 kd_max, ks_max;
    float n_min, n_max;
    float n_cos, n_sin, r_cos, r_sin; /* cos and sin of n_half and r_half (pn_receiver_bounds_set_cones) */
} pn_receiver_bounds;

/* A cluster of VPLs of one kind (pn_vpl_kind): OMNI and ORIENTED: box of positions; ORIENTED:
 * cone of emitting normals; DIRECTIONAL: box of the unit directions towards the lights. */
typedef struct pn_light_bounds {
    int kind;
    vec3 lo, hi;
    vec3 axis;
    float half;               /* radians */
    float cos_half, sin_half; /* of half (pn_light_bounds_set_cone) */
} pn_light_bounds;

/* Upper bound of cos(angle(v, a)) for v in [lo, hi] and a within `half` radians of the unit
 * vector `axis`; 1 when the box contains the origin. pn_bound_cos_cs takes cos and sin of the
 * half-angle instead (no trigonometry in the hot path). */
float pn_bound_cos(vec3 lo, vec3 hi, vec3 axis, float half);
float pn_bound_cos_cs(vec3 lo, vec3 hi, vec3 axis, float cos_half, float sin_half);

/* Fill the cos / sin fields from the half-angles. */
static inline void pn_receiver_bounds_set_cones(pn_receiver_bounds *r) {
    r->n_cos = r->n_half >= PN_PI ? -1.0f : cosf(r->n_half);
    r->n_sin = r->n_half >= PN_PI ? 0.0f : sinf(r->n_half);
    r->r_cos = r->r_half >= PN_PI ? -1.0f : cosf(r->r_half);
    r->r_sin = r->r_half >= PN_PI ? 0.0f : sinf(r->r_half);
}
static inline void pn_light_bounds_set_cone(pn_light_bounds *q) {
    q->cos_half = q->half >= PN_PI ? -1.0f : cosf(q->half);
    q->sin_half = q->half >= PN_PI ? 0.0f : sinf(q->half);
}

/* Squared distance between two boxes (0 when they overlap). */
float pn_box_distance2(vec3 alo, vec3 ahi, vec3 blo, vec3 bhi);

/* G_max: upper bound of the geometric term (cos phi / max(d^2, min_dist2) for oriented VPLs,
 * 1 / max(d^2, min_dist2) for omni ones, 1 for directional ones) over every pair. */
float pn_bound_geometric(const pn_receiver_bounds *r, const pn_light_bounds *q, float min_dist2);

/* Upper bound of the normalised Blinn-Phong lobe (n + 2) / (2 pi) cos^n over every exponent n in
 * [n_min, n_max] and every cosine in [0, cb]. */
float pn_bound_lobe(float cb, float n_min, float n_max);

/* M_max: per-channel upper bound of the BRDF times cos theta (eq. 1) over every pair. */
vec3 pn_bound_material(const pn_receiver_bounds *r, const pn_light_bounds *q);

/* L_UB of eq. 5 in luminance: luminance(M_max * intensity_sum) * G_max. */
float pn_bound_error(const pn_receiver_bounds *r, const pn_light_bounds *q, vec3 intensity_sum, float min_dist2);

/* The smallest cone (axis, half-angle) found by merging two cones (not optimal, but it contains
 * both). half = PI means all directions. */
void pn_cone_merge(vec3 a1, float h1, vec3 a2, float h2, vec3 *axis, float *half);

#endif
