/* dcm.h — the parts of Guo 1998 (Directional Coherence Maps) that work on one block, exposed for
 * the unit tests: the block boundary ("loop"), the least-discrepancy direction (§3.2), oriented
 * finite elements (§3.3), the block contrast (§4.2) and the block simplicity tests (§4.3).
 *
 * A block of nominal size k spans the pixel lattice [0, w] x [0, h] (w, h <= k; both ends
 * included, so neighbouring blocks share their boundary pixels, and corners lie on the lattice of
 * multiples of k). Its boundary is a closed loop of 2(w + h) pixels, clockwise from the top-left
 * corner: top row left to right, right column downwards, bottom row right to left, left column
 * upwards. Coordinates here are relative to the block's top-left pixel. */
#ifndef PN_DRIVER_DCM_H
#define PN_DRIVER_DCM_H

#include <stdbool.h>
#include <stdint.h>

#define PN_DCM_DIRECTIONS 8         /* h: directions theta_i = i pi / h */
#define PN_DCM_CONTRAST 0.05f       /* t_c */
#define PN_DCM_LAZY_TOLERANCE 0.01f /* lazy boundary evaluation: 1% relative */
#define PN_DCM_TANGENT 0.05f        /* t_m = 0.05 pi ||x1 - x0|| */
#define PN_DCM_NOISE                                                                                                   \
    2.0f /* departure: differences within 2 sigma of the pixels' noise
                                      are not edges (contrast) and not deviations (lazy test) */

/* --dcm-variant and --dcm-off (issue 18): each bit switches one of our departures from the paper
 * off (dcm.c's header names them); the paper variant switches all of them off. */
enum {
    PN_DCM_VARIANT_DEFAULT = 0,
    PN_DCM_VARIANT_PAPER = 1,
};
enum {
    PN_DCM_OFF_EDGE_FIRST = 1u << 0,   /* quads of edge blocks before those of smooth blocks */
    PN_DCM_OFF_ORDER = 1u << 1,        /* boundary steps by expected error (else spacing, then block) */
    PN_DCM_OFF_DISCREPANCY = 1u << 2,  /* d_i as a mean over crossing lines (else the paper's sum) */
    PN_DCM_OFF_NOISE = 1u << 3,        /* Monte Carlo noise tests: contrast, lazy, flat boundaries */
    PN_DCM_OFF_LATTICE_MEAN = 1u << 4, /* noise-filtered corners of smooth blocks */
    PN_DCM_OFF_SEGMENTS = 1u << 5,     /* edge blocks drawn segment by segment */
    PN_DCM_OFF_DEMOD = 1u << 6,        /* (radiance - emitted) / (albedo x light guide) interpolated */
    PN_DCM_OFF_GUIDED = 1u << 7,       /* guided reconstruction of partly evaluated edge blocks */
    PN_DCM_OFF_ALBEDO_RAYS = 1u << 8,  /* the integrator's own eye rays for the albedo at texture borders */
    PN_DCM_OFF_LINEAR = 1u << 9,       /* the guided fill as a weighted plane fit, not a weighted mean */
    PN_DCM_OFF_RESIDUALS = 1u << 10,   /* boundary steps re-ordered by the residuals of the last step */
    PN_DCM_OFF_SMOOTH_FIT = 1u << 11,  /* smooth blocks' corners as a plane fit over the lattice */
    PN_DCM_OFF_ALL = (1u << 12) - 1u
};
/* The departures switched off for a variant and a --dcm-off set. */
static inline uint32_t pn_dcm_off_flags(int variant, uint32_t off) {
    return variant == PN_DCM_VARIANT_PAPER ? (uint32_t)PN_DCM_OFF_ALL : off;
}

int pn_dcm_loop_length(int w, int h);
void pn_dcm_loop_pixel(int w, int h, int i, int *x, int *y);

/* The boundary function at a point (x, y) of the block's boundary: linear between the loop's
 * pixels; channel c of `channels`-channel loop values. */
float pn_dcm_boundary_value(const float *loop, int channels, int c, int w, int h, float x, float y);

/* The oriented finite element approximation (§3.3) at (x, y) in [0,w]x[0,h], elements oriented
 * along direction `dir` (theta = dir pi / 8): Gouraud interpolation with the scan line rotated
 * parallel to the direction, node values from the boundary. out gets `channels` values. */
void pn_dcm_element_value(const float *loop, int channels, int w, int h, int dir, float x, float y, float *out);

/* The least-discrepancy direction (§3.2) of a block from its boundary luminances; d (optional)
 * receives the 8 directional discrepancies. */
int pn_dcm_least_discrepancy(const float *lum, int w, int h, float *d);
/* The same with the paper's d_i (paper true): the sum over every boundary pixel of the squared
 * difference to the other end of its line, divided by 4(k - 1). */
int pn_dcm_least_discrepancy_variant(const float *lum, int w, int h, float *d, bool paper);

/* Block contrast (max - min) / (max + min) of corner luminances (§4.2). */
float pn_dcm_contrast(const float g[4]);

/* Zero-order test (§4.3). */
typedef struct pn_dcm_zero_order {
    int transitions;   /* after the Bartlett and median filters */
    int one_pixel[2];  /* loop indices of the transition points (1-pixels next to a 0-pixel) */
    int zero_pixel[2]; /* their 0-pixel neighbours */
    float tb;          /* the luminance threshold (b1 + d1) / 2 */
} pn_dcm_zero_order;
bool pn_dcm_zero_order_test(const float *lum, int w, int h, pn_dcm_zero_order *z);
/* The same; flat_guard false is the paper's test (no contrast floor before thresholding). */
bool pn_dcm_zero_order_test_variant(const float *lum, int w, int h, pn_dcm_zero_order *z, bool flat_guard);

/* First-order test (§4.3, Fig. 8): inner(user, x, y) returns the luminance of an interior pixel
 * (the driver evaluates it on demand). Blocks with no transition pass. */
typedef float (*pn_dcm_inner_fn)(void *user, int x, int y);
bool pn_dcm_first_order_test(int w, int h, const pn_dcm_zero_order *z, pn_dcm_inner_fn inner, void *user);

/* Object test (§4.3): at most two object tags and two object spans on the loop. */
bool pn_dcm_object_test(const int32_t *tags, int n);

#endif
