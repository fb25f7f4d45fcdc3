/* env_regions.h — a static partition of an environment map into regions that the IAS integrator
 * treats as light clusters (Donikian et al. 2006, §4.3 and §5.1: "300 regions", jittered
 * sampling and pre-integration inside a region).
 *
 * Partition method: an equal-energy hierarchical (kd) partition of the texel grid, not
 * Structured Importance Sampling. Starting from the whole map, the region of largest energy
 * (luminance x texel solid angle) is split next (a max-heap), across its longer side measured
 * in angle, at the texel boundary that best halves its energy, until `target_count` regions
 * exist or nothing can be split any more. Every region is a texel rectangle, so the partition
 * tiles the map exactly. Regions without energy are kept (power == 0) and never sampled.
 *
 * Texel solid angles are exact: 4 pi / (w h) for the equal-area (octahedral) square, and
 * (2 pi / w)(cos theta0 - cos theta1) for a lat-long row between polar angles theta0 and theta1.
 * Inside a texel, sampling is uniform in solid angle (uniform in cos theta for lat-long), so the
 * density of a direction is luminance(texel) / region energy exactly.
 */
#ifndef PN_LIGHTS_ENV_REGIONS_H
#define PN_LIGHTS_ENV_REGIONS_H

#include "core/error.h"
#include "core/vecmath.h"
#include "lights/lights.h"

#include <stdbool.h>

typedef struct pn_env_region {
    int x0, y0, x1, y1;           /* texel rectangle [x0,x1) x [y0,y1) of the (possibly virtual) grid */
    vec3 irradiance_rgb_integral; /* integral of L(w) dw over the region (RGB, scale applied) */
    float power;                  /* luminance of the integral above (clamped texels); 0: never sampled */
    float solid_angle;            /* steradians covered */
    vec3 direction;               /* world space, luminance-weighted mean direction (unit) */
    float cos_extent;             /* cosine of the half-angle of a cone around `direction` that
                                     contains the whole region (conservative); -1: no useful cone */
} pn_env_region;

typedef struct pn_env_regions {
    pn_env_region *regions;
    int count;
    /* The grid that was partitioned: the map itself, or for a constant environment a virtual
     * 64 x 64 equal-area grid of the constant radiance. */
    int width, height;
    bool equal_area;
    bool virtual_grid;
    double total_power; /* sum of the regions' power */
    /* Private to env_regions.c: per-texel region index and clamped luminance, per-row solid
     * angle, and the per-region sampling tables (row cumulative weights at row_offset[k], and
     * per-texel cumulative weights along each row of a region). */
    int *texel_region;
    float *texel_lum;
    double *row_solid_angle;
    double *row_cum;
    int *row_offset;
    double *col_cum;
} pn_env_regions;

/* Default number of regions (the paper's 300). */
#define PN_ENV_REGIONS_DEFAULT 300

/* Partitions env into (at most) target_count >= 1 regions; exactly target_count when the map has
 * enough texels with energy. *out is overwritten; free it with pn_env_regions_free. */
pn_status pn_env_regions_build(const pn_env *env, int target_count, pn_env_regions *out, pn_err *err);
void pn_env_regions_free(pn_env_regions *r);

/* Samples a direction inside region k in proportion to luminance x solid angle (a texel by
 * its energy, then a uniform position in solid angle inside it). Returns the world direction,
 * the radiance pn_env_lookup gives for it, and the solid-angle pdf conditional on the region,
 * both taken from the texel the direction maps back to. False if the region has no energy or
 * the sample carries nothing. */
bool pn_env_region_sample(const pn_env_regions *r, const pn_env *env, int k, float u1, float u2, vec3 *wi,
                          vec3 *radiance, float *pdf);

/* Solid-angle pdf of pn_env_region_sample(k) for world direction w (0 outside region k). */
float pn_env_region_pdf(const pn_env_regions *r, const pn_env *env, int k, vec3 w);

/* The region containing world direction w. */
int pn_env_region_of(const pn_env_regions *r, const pn_env *env, vec3 w);

/* Conservative cull: true only if the whole region lies below the tangent plane of normal n
 * (dot(w, n) <= 0 for every direction w of the region). */
bool pn_env_region_below(const pn_env_region *reg, vec3 n);

#endif
