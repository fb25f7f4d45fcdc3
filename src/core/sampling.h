/* sampling.h — warping uniform random numbers into geometric samples, and tabulated
 * (piecewise-constant) distributions for discrete and 2-D importance sampling.
 *
 * All warps take numbers in [0, 1) and are measure-preserving up to the stated pdf, so
 * stratified / low-discrepancy inputs stay well distributed after warping.
 */
#ifndef PN_CORE_SAMPLING_H
#define PN_CORE_SAMPLING_H

#include "core/vecmath.h"

#include <stdbool.h>

/* ---- simple warps ------------------------------------------------------------------------ */

/* Uniform point on a triangle (by area) as barycentrics (b0, b1); b2 = 1 - b0 - b1. Uses the
 * low-distortion square-to-triangle map of Heitz 2019, which keeps stratification. */
void pn_sample_uniform_triangle(float u1, float u2, float *b0, float *b1);

/* Uniform point on the unit disk (Shirley–Chiu concentric map); pdf = 1/pi. */
void pn_sample_concentric_disk(float u1, float u2, float *x, float *y);

/* Uniform direction on the unit sphere; pdf = 1/(4 pi). */
vec3 pn_sample_uniform_sphere(float u1, float u2);

/* Cosine-weighted direction on the z-up hemisphere; pdf = cos(theta)/pi. */
vec3 pn_sample_cosine_hemisphere(float u1, float u2);

/* ---- spherical rectangles ---------------------------------------------------------------- */

/* Solid-angle sampling of a rectangle as seen from a point (Ureña, Fajardo,
 * King 2013, "An Area-Preserving Parametrization for Spherical Rectangles"). Fields other than
 * solid_angle are private to sampling.c. */
typedef struct pn_spherical_rectangle {
    vec3 corner, e1, e2;       /* the rectangle: corner + a e1 + b e2, a, b in [0, 1] */
    double len1, len2;         /* |e1|, |e2| */
    double x0, y0, x1, y1, z0; /* rectangle bounds in the local frame around p (z0 < 0) */
    double b0, b1, k, s;       /* parametrisation constants; s = solid angle */
    double z0sq, b0sq;
    float solid_angle; /* steradians; the sampling pdf is 1 / solid_angle */
} pn_spherical_rectangle;

/* Prepares sampling of the rectangle corner + a e1 + b e2 (e1 perpendicular to e2) seen from
 * p. Returns false if the rectangle is degenerate, p lies in its plane, or the solid angle is
 * not a positive finite number. */
bool pn_spherical_rectangle_init(pn_spherical_rectangle *sr, vec3 p, vec3 corner, vec3 e1, vec3 e2);

/* The point on the rectangle hit by a direction drawn uniformly from its solid angle
 * (pdf = 1/solid_angle per steradian). (u1, u2) map to the e1 and e2 directions resp. */
vec3 pn_spherical_rectangle_sample(const pn_spherical_rectangle *sr, float u1, float u2);

/* Like pn_spherical_rectangle_sample but also reports the rectangle parameters (a, b) of the
 * sampled point (either pointer may be NULL). */
vec3 pn_spherical_rectangle_sample_ab(const pn_spherical_rectangle *sr, float u1, float u2, float *a, float *b);

/* Exact solid angle (steradians) of the rectangle corner + a e1 + b e2 seen from p, or 0 for
 * degenerate configurations. Computed in double precision. */
double pn_rectangle_solid_angle(vec3 p, vec3 corner, vec3 e1, vec3 e2);

/* ---- spheres ----------------------------------------------------------------------------- */

/* Samples a direction uniformly inside the cone subtended by the sphere (center, radius) as
 * seen from p, and returns in *y the nearest point of the sphere along it; *pdf is per unit
 * solid angle (1 / cone solid angle). Returns false if p is inside or on the sphere. */
bool pn_sample_sphere_from_point(vec3 center, float radius, vec3 p, float u1, float u2, vec3 *y, float *pdf);

/* Solid-angle pdf of pn_sample_sphere_from_point for any direction inside the cone (0 if p is
 * inside the sphere). */
float pn_sphere_cone_pdf(vec3 center, float radius, vec3 p);

/* ---- 1-D discrete distribution ----------------------------------------------------------- */

typedef struct pn_distribution1d pn_distribution1d;

/* Builds a distribution proportional to weights[0..n-1]. Negative or non-finite weights count
 * as zero. Returns NULL if n <= 0, out of memory, or all weights are zero. */
pn_distribution1d *pn_distribution1d_create(const float *weights, int n);

/* Picks index i with probability *pmf (proportional to its weight; zero-weight entries are
 * never chosen). If u_remapped is not NULL it receives u rescaled to [0, 1) within the chosen
 * entry's interval, i.e. a fresh uniform number for further use. */
int pn_distribution1d_sample_discrete(const pn_distribution1d *d, float u, float *pmf, float *u_remapped);

/* Continuous sample in [0, 1) with density *pdf (= weight of the cell / mean weight); the cell
 * index is stored in *index if not NULL. */
float pn_distribution1d_sample_continuous(const pn_distribution1d *d, float u, float *pdf, int *index);

/* Probability of choosing index (0 outside [0, n)). */
float pn_distribution1d_pdf(const pn_distribution1d *d, int index);

int pn_distribution1d_count(const pn_distribution1d *d);

/* Sum of the (clamped) weights the distribution was built from. */
double pn_distribution1d_total(const pn_distribution1d *d);

void pn_distribution1d_free(pn_distribution1d *d);

/* ---- 2-D piecewise-constant distribution ------------------------------------------------- */

typedef struct pn_distribution2d pn_distribution2d;

/* Builds a density on [0,1)^2 proportional to a w x h grid of weights (row-major, row 0 first:
 * weights[row * w + col]; u runs along a row, v across rows). Negative or non-finite weights
 * count as zero. NULL if w or h <= 0, out of memory, or all weights are zero. */
pn_distribution2d *pn_distribution2d_create(const float *weights, int w, int h);

/* Samples (u, v) in [0, 1)^2; *pdf is the density with respect to area in uv space, i.e.
 * weight(cell) / mean weight. Returns false only if d is NULL or the pdf is not positive. */
bool pn_distribution2d_sample(const pn_distribution2d *d, float u1, float u2, float *u, float *v, float *pdf);

/* Density at (u, v); coordinates outside [0,1) are clamped to the border cells, NaN gives 0,
 * and zero-weight cells give 0. */
float pn_distribution2d_pdf(const pn_distribution2d *d, float u, float v);

void pn_distribution2d_free(pn_distribution2d *d);

#endif
