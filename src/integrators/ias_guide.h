/* ias_guide.h — visibility learned below the cluster in the default `ias` variant (issue 15,
 * stop 20; option ias-light-guide, reasons and measured effects in ias.c's header and
 * docs/methods/ias.md, "Visibility oracles and the light guide").
 *
 * A light's sampler maps two uniform numbers (u1, u2) in the unit square to a point on the light
 * (for a rectangle, a direction uniform in its solid angle). The guide warps that square: per
 * block of the image and per large area light, a side x side grid of cells over (u1, u2) whose
 * probabilities follow the mean contribution the block's shadow rays found in each cell so far
 * (visible light through the gaps of a blind, none behind its slats), mixed with the uniform
 * square defensively. A sample's pdf is the sampler's times the warp's density, q_c side^2 in
 * cell c, so every estimate stays unbiased whatever was learned; the grid is rebuilt between
 * passes only, from the samples of the earlier passes of the same block (deterministic for any
 * thread count: a block is one worker's).
 *
 * Guided lights: rectangles and triangles each of at least PN_IAS_GUIDE_MIN_SHARE of the scene's
 * emitting area of those kinds, the largest PN_IAS_GUIDE_MAX_LIGHTS of them. */
#ifndef PN_INTEGRATORS_IAS_GUIDE_H
#define PN_INTEGRATORS_IAS_GUIDE_H

#include "lights/lights.h"

#include <stdbool.h>
#include <stdint.h>

#define PN_IAS_GUIDE_MAX_LIGHTS 64
#define PN_IAS_GUIDE_MIN_SHARE 0.02
#define PN_IAS_GUIDE_MAX_SIDE 64
/* The grid ias uses: cells per side, and the uniform square's share of its PDF. */
#define PN_IAS_GUIDE_SIDE 8
#define PN_IAS_GUIDE_MIX 0.2

/* Which lights are guided, and the grid's settings; shared read-only by the workers. */
typedef struct pn_ias_guide_lights {
    int count;       /* guided lights (slots) */
    int *slot;       /* per light of the scene: its slot, or -1 */
    int side;        /* cells per side of a light's grid */
    double mix;      /* share of the uniform square in every grid's PDF (defensive) */
    int min_samples; /* samples of a light in a block before its grid leaves the uniform square */
} pn_ias_guide_lights;

/* Chooses the guided lights of L; false when out of memory. No light qualifying leaves count 0. */
bool pn_ias_guide_lights_init(pn_ias_guide_lights *g, const pn_lights *L, int side, double mix);
void pn_ias_guide_lights_free(pn_ias_guide_lights *g);

/* One worker's grids, for the block it renders. */
typedef struct pn_ias_guide {
    const pn_ias_guide_lights *lights;
    double *sum;           /* per slot and cell: sum of the recorded values */
    double *count;         /* per slot and cell: samples recorded */
    double *row_cdf;       /* per slot: side + 1 running sums over rows (u2) */
    double *col_cdf;       /* per slot and row: side + 1 running sums over columns (u1), within the row */
    double *prob;          /* per slot and cell: the cell's probability (q_c) */
    unsigned char *active; /* per slot: its grid is in use (else the uniform square) */
    unsigned char *touched;
    int *touched_list;
    int touched_count;
    /* Added (mod 1) to a sample's numbers before an active grid warps them, when `rotate`: a
     * Cranley-Patterson rotation drawn per pixel and pass, independent of the samples that built
     * the grid (ias-guide-refresh; see pn_ias_guide_set_rotation). */
    bool rotate;
    float shift[2];
} pn_ias_guide;

bool pn_ias_guide_init(pn_ias_guide *g, const pn_ias_guide_lights *lights);
void pn_ias_guide_free(pn_ias_guide *g);

/* Forgets the previous block's samples and grids. */
void pn_ias_guide_begin_block(pn_ias_guide *g);

/* Rebuilds the grids of the lights sampled so far in the block from all their samples (between
 * passes). */
void pn_ias_guide_refresh(pn_ias_guide *g);

/* Sets the rotation of the numbers warped from now on (ias-guide-refresh): the block's numbers are
 * one Sobol sequence, so the points of a pixel depend on those of the pixels before it; a grid
 * learned from those earlier points and applied to the later ones weights them by a density that is
 * not independent of where they fall (measured: 1.0% bright on tests/test_ias_guide.c's scene at one
 * pass). A rotation by a hash-drawn shift, fresh for each pixel and pass, makes each warped number
 * uniform given the grid, so the estimate is unbiased again. key: a hash of the seed, block, pixel and
 * pass. */
void pn_ias_guide_set_rotation(pn_ias_guide *g, uint64_t key);

/* For a sample of light `light` (index in the scene) with numbers (*u1, *u2): warps them through
 * the light's grid when it is in use and multiplies *density by the warp's density (1 for the
 * uniform square). Returns the cell the warped numbers fall in, to pass to pn_ias_guide_record, or
 * -1 when the light is not guided. */
int pn_ias_guide_warp(const pn_ias_guide *g, int light, float *u1, float *u2, double *density);

/* Records a sample of light `light` in `cell` (from pn_ias_guide_warp; ignored when -1): value is
 * its contribution as the sampler alone would weight it (the estimate times the warp's density;
 * 0 when occluded), so that a cell's mean is its mean contribution over the unit square. */
void pn_ias_guide_record(pn_ias_guide *g, int light, int cell, double value);

#endif
