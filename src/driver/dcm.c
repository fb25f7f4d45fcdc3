/* dcm.c — progressive radiance evaluation with Directional Coherence Maps (Guo 1998), and plain
 * uniform subsampling (the same machinery with every block smooth).
 *
 * Pipeline, as the paper's Fig. 1:
 *  - Work image: s x s the output (progressive.c), filtered down with a Gaussian at the end.
 *  - Regular subdivision stage (§2): a quadtree from the whole work image down to elementary
 *    8x8 blocks; the lattice of block corners of every level is evaluated, coarse to fine; the
 *    approximate image is the bilinear interpolation of the finest complete lattice.
 *  - DCM refinement (§4.1), one iteration per block size k = 8, 4, 2:
 *    (1) block classification (§4.2): a candidate quad of a smooth block (all elementary blocks
 *        in the first iteration) becomes an edge block when the contrast (max-min)/(max+min) of
 *        its corner luminances exceeds t_c = 0.05, or when a visible line crosses it; quads of
 *        complex edge blocks are edge blocks; quads of simple edge blocks go through lazy
 *        boundary evaluation (Fig. 6): their corners are evaluated and compared with the
 *        parent's elements; within 1% they keep the parent's direction and take their boundary
 *        from the parent's elements (corners and any evaluated pixel stay evaluated), otherwise
 *        they get real boundary evaluation.
 *    (2) boundary evaluation of edge blocks (Fig. 9): each edge block gets boundary pixels at
 *        spacing k/2, then k/4, ..., 1, so that evaluated pixels spread evenly over its boundary
 *        and elements can be built before the boundary is complete.
 *    (3) block simplicity tests (§4.3): zero-order (Bartlett filter of length 3, threshold
 *        t_b = (b1 + d1)/2, median filter of length 3, at most two transition points),
 *        first-order (tangents at the transition points from extra evaluations on the inner
 *        layer, Fig. 8; threshold t_m = 0.05 pi ||x1 - x0||), object test (at most two object
 *        tags and two object spans). Failing blocks are complex edge blocks.
 *    (4) oriented finite elements (§3.3) along the least-discrepancy direction (§3.2) over
 *        h = 8 directions, node values from the boundary pixels.
 *    (5) subdivision into quads; after k = 2 the quads are single pixels: every pixel gets
 *        evaluated and the approximate image equals the full render.
 *  - Smooth blocks are re-examined at every level (their quads are classified again).
 *
 * Departures from the paper, and why:
 *  - Visible lines (§4.2) come from a buffer of one primary ray per work pixel centre (object
 *    tag, geometric normal and depth of the first non-specular hit, followed through mirrors):
 *    a visible line crosses a block when two 4-neighbours inside it differ in tag, bend by more
 *    than ~37 degrees or jump in depth by more than 10%. This is our stand-in for the paper's
 *    Z-buffer visible-line rendering and gives mirror reflections of object boundaries for free.
 *    The object test uses the same tags (the paper takes them from the ray tracer).
 *  - Order of work: within an iteration, the quads of edge blocks are processed before the
 *    quads of smooth blocks, so that all 4x4 edge blocks are done before the smooth 8x8 blocks
 *    are subdivided — the paper's 6% images are "after processing all 4x4 edge blocks".
 *  - Order of boundary evaluation: the (block, spacing) steps of all edge blocks of an iteration
 *    are taken in decreasing order of (luminance range of the block's corners) x spacing, so
 *    blocks with large ranges (the largest errors) reach fine spacings before flat blocks get
 *    their coarse ones; the paper does not say how blocks are ordered. The range is that of the
 *    corners' radiance (the interpolated quotient multiplied back by albedo and light guide), so
 *    that the order follows the image's own error, not the quotient's: at 6% (prog-hr crops)
 *    bathroom 0.0282 / 0.0141 -> 0.0270 / 0.0130 rel L1 / L2, hall-many 0.0178 / 0.0222 ->
 *    0.0175 / 0.0217, staircase 0.0287 / 0.0221 -> 0.0288 / 0.0218. Classified blocks replace
 *    their parents in the approximate image at once; an edge block still under boundary
 *    evaluation is drawn with elements over the part of its boundary evaluated so far, oriented
 *    by its current least-discrepancy direction (what Fig. 9's even spreading is for).
 *  - Fig. 9 (e)-(h) (evaluating the quads' boundaries inside a complex block before its own
 *    boundary is complete) is replaced by the real boundary evaluation of the quads in the next
 *    iteration.
 *  - The directional discrepancy d_i is the mean over the boundary pixels whose line along n_i
 *    crosses the block interior (pixels whose line runs along their own side are left out),
 *    instead of a sum over all pixels divided by 4(k - 1): directions parallel to a side would
 *    otherwise be compared over fewer pairs.
 *  - Zero-order test: a boundary whose filtered luminance contrast (b1-d1)/(b1+d1) is at most
 *    t_c has no transition points (thresholding Monte Carlo noise would otherwise split flat
 *    boundaries into spans). First-order test: when the inner layer is exhausted without a
 *    transition the block fails (the tangent is unknown); blocks with fewer than two inner
 *    pixels per layer (k = 2) skip it.
 *  - Smooth blocks interpolate noise-filtered corners (lattice_mean): each corner is the mean of
 *    itself and those of its 8 neighbours on the block lattice that agree with it within the
 *    noise and that no visible line separates from it. With 16 eye rays per pixel, bilinear
 *    interpolation of single corners spread their Monte Carlo noise over whole blocks; at 6%
 *    smooth blocks held 85% of hall-many's error. Evaluated pixels are still drawn as evaluated,
 *    so the image still converges to the full render.
 *  - Elements are evaluated on RGB with the luminance-derived direction.
 *  - Edge blocks that a visible line crosses are drawn segment by segment (draw_segmented): the
 *    visible lines cut the block into segments of 4-connected pixels, and a pixel whose element
 *    line would reach across a line, or end on a pixel not yet evaluated, takes the
 *    inverse-squared-distance mean of the evaluated pixels of its own segment instead. The paper
 *    draws elements across the whole block; with a third of the image in edge blocks still under
 *    boundary evaluation at 6% (staircase at 1230 x 690 work pixels), the elements blended
 *    balusters and trims into the wall behind them (bench/progressive/README.md has the
 *    measurements).
 *  - Monte Carlo noise (the paper's RADIANCE pixels are nearly noise-free): contrast
 *    thresholding also asks the corners' luminance range to exceed 2 standard deviations of its
 *    noise, and the lazy test accepts deviations within 2 standard deviations of the pixel's
 *    estimate as well as within 1% (the integrator reports each pixel's variance).
 *  - What is interpolated is (radiance - emitted) / albedo, multiplied back and the emitted part
 *    added per pixel (progressive.c; --raw-radiance turns it off). Both come from primary rays
 *    (3 x 3 over the pixel filter where the pixel centres' values change, --primary-grid; along
 *    emitters `reference`'s own eye rays where its eye-ray count is fixed): texture
 *    and directly seen emitters (lamps, the sky between blinds) are known without evaluating the
 *    pixel and need not be sampled. At evaluated pixels the integrator's own emitted part is
 *    taken out where it reports one (reference, ias). Tests and directions see the same values.
 *  - Guided reconstruction of edge blocks under boundary evaluation (issue 18): at 6% most edge
 *    blocks hold little more than their corners, so (a) before the boundary steps, every segment
 *    of at least 3 pixels that a visible line cuts off inside such a block and that holds no
 *    evaluated pixel gets one, the pixel nearest its centroid (segment seeds); (b) a pixel filled
 *    from its segment's evaluated pixels weighs them by inverse squared distance times the
 *    agreement of the primary rays' normals (cos^8) and depths (Gaussian, 2% relative) — a joint
 *    bilateral filter guided by the primary buffer within the segment; (c) a block that a visible
 *    line crosses enters the boundary order with at least half its brightest corner's radiance as
 *    its range (what lies behind the line is unknown). Effect at 6% (prog-hr64 crops at a quarter
 *    of their pixels, rel L1 / L2): staircase 0.0344 / 0.0324 -> 0.0316 / 0.0279, hall-many
 *    0.0164 / 0.0317 -> 0.0152 / 0.0293, bathroom 0.0423 / 0.0342 -> 0.0333 / 0.0235, glossy
 *    bathroom-72 0.0324 / 0.0335 -> 0.0289 / 0.0323 (bench/progressive/README.md, "Issue 18",
 *    with each part alone). A margin of 4 pixels instead of 1 around the block
 *    (reading the neighbours' evaluated pixels) was measured and dropped: staircase rel L2 0.0283
 *    -> 0.0382. So were (stop 16, quarter staircase at 6%, rel L1 0.0280; bench/progressive/
 *    README.md): pixels next to a visible line drawn as the albedo- and guide-weighted mix of both
 *    sides' quotients (0.0288), and fill weights 1/d or 1/d^3 (0.0282, 0.0280).
 *  - Albedo rays (issue 18, progressive.c primary_refine_row): where the integrator reports the
 *    eye rays it traces (reference at a fixed --spp), work pixels whose centre ray's albedo
 *    differs by more than 5% (PN_PROG_ALBEDO_RAYS_BORDER) from a 4-neighbour's take their albedo
 *    factor from the first 16 of the integrator's own eye rays (PN_PROG_ALBEDO_RAYS) instead of
 *    the filtered centre rays (borders under 30%) or the 3 x 3 grid. Why: an interpolated pixel
 *    is the quotient times this factor, and the full render weighs the texture under its pixel
 *    filter with exactly those rays; the filtered centre rays alias fine texture (staircase's
 *    wallpaper), about 14% of the 6% image's error. Effect at 6% (full prog-hr64
 *    staircase, rel L1 / L2): 0.0191 / 0.0183 -> 0.0165 / 0.0162, CPU 1/13.7 -> 1/11.4 of the full
 *    render (all 64 rays: 0.0162, 1/7.2; 8 rays: 0.0172; 16 rays at every albedo difference:
 *    0.0165; the 3 x 3 grid at 5% borders: 0.0180; a 4 x 4 grid: 0.0173; bench/progressive/
 *    README.md, "Stop 15"). Emitter borders keep all of the integrator's eye rays, as before.
 *  - Linear fill (issue 18, stop 16): where the guided reconstruction fills a pixel from its
 *    segment's evaluated pixels and at least three take part, the pixel gets the value at its
 *    place of the plane fitted to them by least squares with the same weights (inverse squared
 *    distance x normal and depth agreement), clamped to the range of their values, instead of
 *    their weighted mean. Why: the weighted mean is a zero-order fit that pulls every pixel
 *    towards its nearest samples and flattens the gradient of shading between them (the pixels of
 *    edge blocks crossed by a visible line, away from the line, carried as much of the 6% error
 *    as those next to it; bench/progressive/attribution.patch). Effect at 6% (rel L1 / L2):
 *    quarter staircase 0.0280 / 0.0254 -> 0.0269 / 0.0232; full prog-hr64 staircase 0.0165 /
 *    0.0162 -> 0.0163 / 0.0155, bathroom 0.0146 / 0.0079 -> 0.0138 / 0.0071, hall-many 0.0077 /
 *    0.0108 -> 0.0076 / 0.0106, glossy bathroom-72 0.0134 / 0.0197 -> 0.0125 / 0.0194
 *    (bench/progressive/README.md, "Stop 16").
 *  - Residual order (issue 18, stop 17; boundary_rounds): the boundary steps are queued in chunks
 *    of 0.25% of the work pixels and evaluated chunk by chunk; a block's first step is keyed by
 *    its range x spacing as above, each later step by what the block's previous step found x the
 *    new spacing: twice the largest difference, in the image's radiance, between a pixel of that
 *    step and the mean of its two loop neighbours of the step before (step_residual; a step edge
 *    between two pixels leaves half its range at their midpoint). Why: the corners' range is a
 *    guess made before any boundary pixel is known, and it stays the key of all of a block's steps;
 *    after a step, the loop's interpolation error there is measured, so blocks whose boundary turned
 *    out linear give way to those where it was wrong. Effect at 6% (rel L1 / L2): quarter
 *    staircase 0.0269 / 0.0232 -> 0.0253 / 0.0223, bathroom 0.0292 / 0.0203 -> 0.0266 / 0.0176;
 *    full prog-hr64 staircase 0.0163 / 0.0155 -> 0.0156 / 0.0153, bathroom 0.0138 / 0.0071 ->
 *    0.0136 / 0.0071, glossy bathroom-72 0.0125 / 0.0194 -> 0.0123 / 0.0184; no measurable CPU cost (bench/progressive/README.md, "Stop 17"). Measured
 *    and dropped (quarter staircase): the mean instead of the largest difference (0.0252 /
 *    0.0228), differences less 1 or 2 sigma of noise (0.0251 / 0.0226, 0.0254 / 0.0227), the
 *    first key's range as a floor of the later keys (0.0266 / 0.0227), no visible-line floor in
 *    the first key (0.0259 / 0.0228), spacing^2 or spacing^0.5 in
 *    the key (0.0252 / 0.0229, 0.0259 / 0.0223), factors 1 or 4 for 2 (0.0251 / 0.0224, 0.0262 /
 *    0.0225). Also dropped: a wide guided fill (samples within 8 pixels of the block with the same
 *    object tag, weights by normal and by depth against the pixel's depth plane, instead of its
 *    segment within 1 pixel): 0.0287 / 0.0269, with segments inside the 1-pixel margin 0.0286 /
 *    0.0267, within 4 pixels 0.0284 / 0.0281.
 *  - Measured in stop 18 and dropped (quarter size at 6%, staircase / bathroom rel L1; main
 *    0.0253 / 0.0266; bench/progressive/README.md "Stop 18", stop18-experiments.patch): the
 *    leave-one-out residual of the guided linear fill as a boundary-order key (0.0253 / 0.0267);
 *    interior pixels chosen by distance and that residual as tasks of the residual heap (0.0245 /
 *    0.0293, L2 -15% on staircase); the guided fill instead of elements everywhere in partly
 *    evaluated line-crossed blocks (0.0247 / 0.0297); a cross-validated choice between the two
 *    per block (0.0251 / 0.0270); visible lines at a 26 degree bend (0.0250 / 0.0270). Interior
 *    pixels and the fill pay on staircase's thin oblique segments and cost bathroom's straight
 *    tile lines, where elements interpolate between exact boundary pixels; no selector tried kept
 *    both.
 *  - Smooth fit (issue 18, stop 19; lattice_fit): a smooth block's corner whose noise is large
 *    against its value (luminance sigma above 10% of its luminance) is drawn as the value at the
 *    corner of the plane fitted by weighted least squares (Gaussian weights, sigma 1.5 lattice
 *    steps) to the lattice corners within 2 steps that pass lattice_mean's tests (agreement within
 *    2 sigma, no visible line between), clamped to their range; other corners keep the lattice
 *    mean. Uniform subsampling and the regular stage keep the lattice mean. Why: split of the
 *    smooth blocks' 6% error at full prog-hr64 size (two seeds of the 6% image and of the full
 *    render): bathroom L1 0.0052 = corner noise 0.0039 (|seed 0 - seed 1| / sqrt 2 of the 6%
 *    images), bias about 0.0022, the full render's floor 0.0026; staircase 0.0066 = noise 0.0041,
 *    bias about 0.0046, floor 0.0021. Bathroom's noisy corners gain from a wider fit; staircase
 *    lost from every wider or plane filter tried, and the 10% gate leaves it nearly unchanged. Effect at 6%
 *    (full prog-hr64, rel L1 / L2): bathroom 0.01361 / 0.00706 -> 0.01324 / 0.00700 (its smooth
 *    blocks 0.0052 -> 0.0049), glossy bathroom-72 0.01225 / 0.01844 -> 0.01215 / 0.01843,
 *    staircase 0.01570 / 0.01532 -> 0.01575 / 0.01532, hall-many 0.00753 / 0.01057 -> 0.00753 /
 *    0.01062. Measured and dropped
 *    (full size, bathroom / staircase rel L1): the fit at every corner over radius 1, 2 or 2
 *    with sigma 1, with a refit without corners off the first plane by 2 sigma instead of the
 *    agreement test (0.0144 / 0.0169, 0.0141 / 0.0206, 0.0140 / 0.0171); the fit over the
 *    agreeing corners at every corner, radius 1 / 2 / 2 with sigma 1 / 1.5 (0.0137 / 0.0160,
 *    0.0131 / 0.0176, 0.0134 / 0.0160, 0.0132 / 0.0166); raw corners (--dcm-off lattice-mean:
 *    0.0163 / 0.0162, staircase L2 0.0146); per-corner shrinkage of the mean towards the raw corner
 *    by the estimated bias (radius 1 / 2: 0.0141 / 0.0156, 0.0136 / 0.0162); the fit only where it
 *    agrees with the lattice mean within 0.5 / 1 sigma (0.0132 / 0.0161, 0.0132 / 0.0164);
 *    Catmull-Rom over the 4 x 4 lattice means instead of bilinear interpolation (0.0138 / 0.0157,
 *    L2 0.0071 / 0.0152); the relative-noise gate at 3% (0.0131 / 0.0158).
 *
 * Switches (--dcm-off, dcm.h PN_DCM_OFF_*): edge-first (order of work), order (order of boundary
 * evaluation), discrepancy, noise (the Monte Carlo tests: contrast and lazy noise terms, the
 * zero-order flat-boundary rule), lattice-mean, segments, demod (the quotient of progressive.c,
 * as --raw-radiance), guided, albedo-rays, linear, residuals (needs order), smooth-fit (needs
 * lattice-mean). --dcm-variant paper
 * switches all of them off.
 * What stays in the paper variant, as the paper has no counterpart to choose instead: visible
 * lines from the primary buffer (the paper's Z-buffer visible lines), Fig. 9 (e)-(h) by the next
 * iteration, elements on RGB, and the first-order test's rule for an exhausted inner layer. */
#include "driver/dcm.h"

#include "driver/progressive.h"

#include "core/heap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DCM_MAX_LOOP 512       /* 2 (w + h) for blocks up to 128 pixels */
#define DCM_FIT_RADIUS 2       /* smooth fit: lattice steps around the corner */
#define DCM_FIT_SIGMA 1.5      /* smooth fit: Gaussian weight's width, in lattice steps */
#define DCM_FIT_REL_NOISE 0.1f /* smooth fit: only corners whose sigma exceeds this share of their luminance */

/* ---------------------------------------------------------------------------------------- */
/* Block-level pieces (dcm.h) */

int pn_dcm_loop_length(int w, int h) {
    return (w > 0 && h > 0) ? 2 * (w + h) : 0;
}

void pn_dcm_loop_pixel(int w, int h, int i, int *x, int *y) {
    if (i < w) {
        *x = i;
        *y = 0;
    } else if (i < w + h) {
        *x = w;
        *y = i - w;
    } else if (i < 2 * w + h) {
        *x = w - (i - w - h);
        *y = h;
    } else {
        *x = 0;
        *y = h - (i - 2 * w - h);
    }
}

/* Where (x, y) lies on the loop: between loop pixels *a and *b at fraction *f. */
static void loop_position(int w, int h, float x, float y, int *a, int *b, float *f) {
    int n = pn_dcm_loop_length(w, h);
    float dt = y, db = (float)h - y, dl = x, dr = (float)w - x;
    float s;
    if (dt <= db && dt <= dl && dt <= dr)
        s = x;
    else if (dr <= db && dr <= dl)
        s = (float)w + y;
    else if (db <= dl)
        s = (float)(w + h) + ((float)w - x);
    else
        s = (float)(2 * w + h) + ((float)h - y);
    if (s < 0.0f) s = 0.0f;
    if (s > (float)n) s = (float)n;
    int i0 = (int)floorf(s);
    *f = s - (float)i0;
    *a = i0 % n;
    *b = (i0 + 1) % n;
}

float pn_dcm_boundary_value(const float *loop, int channels, int c, int w, int h, float x, float y) {
    int a, b;
    float f;
    loop_position(w, h, x, y, &a, &b, &f);
    return loop[a * channels + c] + f * (loop[b * channels + c] - loop[a * channels + c]);
}

/* Parameters [tmin, tmax] of the line (x, y) + t n inside [0,w]x[0,h]. */
static void slab(int w, int h, float x, float y, float nx, float ny, float *tmin, float *tmax) {
    float lo = -INFINITY, hi = INFINITY;
    if (fabsf(nx) > 1e-6f) {
        float a = (0.0f - x) / nx, b = ((float)w - x) / nx;
        lo = fmaxf(lo, fminf(a, b));
        hi = fminf(hi, fmaxf(a, b));
    }
    if (fabsf(ny) > 1e-6f) {
        float a = (0.0f - y) / ny, b = ((float)h - y) / ny;
        lo = fmaxf(lo, fminf(a, b));
        hi = fminf(hi, fmaxf(a, b));
    }
    *tmin = lo;
    *tmax = hi;
}

static float clampf(float v, float lo, float hi) {
    return v < lo ? lo : v > hi ? hi : v;
}

/* n_i = (cos theta_i, sin theta_i), theta_i = i pi / 8 */
static const float dcm_dir[PN_DCM_DIRECTIONS][2] = {
    {1.0f, 0.0f},
    {0.923879532511286756f, 0.382683432365089772f},
    {0.707106781186547524f, 0.707106781186547524f},
    {0.382683432365089772f, 0.923879532511286756f},
    {0.0f, 1.0f},
    {-0.382683432365089772f, 0.923879532511286756f},
    {-0.707106781186547524f, 0.707106781186547524f},
    {-0.923879532511286756f, 0.382683432365089772f},
};

static void direction(int dir, float *nx, float *ny) {
    *nx = dcm_dir[dir & (PN_DCM_DIRECTIONS - 1)][0];
    *ny = dcm_dir[dir & (PN_DCM_DIRECTIONS - 1)][1];
}

void pn_dcm_element_value(const float *loop, int channels, int w, int h, int dir, float x, float y, float *out) {
    float nx, ny, tmin, tmax;
    direction(dir, &nx, &ny);
    slab(w, h, x, y, nx, ny, &tmin, &tmax);
    if (!(tmin <= 0.0f)) tmin = 0.0f;
    if (!(tmax >= 0.0f)) tmax = 0.0f;
    float ax = clampf(x + tmin * nx, 0.0f, (float)w), ay = clampf(y + tmin * ny, 0.0f, (float)h);
    float bx = clampf(x + tmax * nx, 0.0f, (float)w), by = clampf(y + tmax * ny, 0.0f, (float)h);
    float len = tmax - tmin, f = len > 1e-6f ? -tmin / len : 0.0f;
    /* the two ends' places on the loop once, then every channel (pn_dcm_boundary_value's sums) */
    int a0, a1, b0, b1;
    float fa, fb;
    loop_position(w, h, ax, ay, &a0, &a1, &fa);
    loop_position(w, h, bx, by, &b0, &b1, &fb);
    for (int c = 0; c < channels; c++) {
        float va = loop[a0 * channels + c] + fa * (loop[a1 * channels + c] - loop[a0 * channels + c]);
        float vb = loop[b0 * channels + c] + fb * (loop[b1 * channels + c] - loop[b0 * channels + c]);
        out[c] = va + f * (vb - va);
    }
}

int pn_dcm_least_discrepancy(const float *lum, int w, int h, float *d) {
    return pn_dcm_least_discrepancy_variant(lum, w, h, d, false);
}

int pn_dcm_least_discrepancy_variant(const float *lum, int w, int h, float *d, bool paper) {
    int n = pn_dcm_loop_length(w, h);
    int best = 0;
    float best_d = INFINITY;
    for (int i = 0; i < PN_DCM_DIRECTIONS; i++) {
        float nx, ny;
        direction(i, &nx, &ny);
        double sum = 0.0;
        int count = 0;
        for (int k = 0; k < n; k++) {
            int px, py;
            pn_dcm_loop_pixel(w, h, k, &px, &py);
            float tmin, tmax;
            slab(w, h, (float)px, (float)py, nx, ny, &tmin, &tmax);
            float t = fabsf(tmin) > fabsf(tmax) ? tmin : tmax;
            if (!paper) {
                if (fabsf(t) < 1e-3f) continue;
                /* Leave out lines that run along the boundary (their midpoint lies on it). */
                float mx = (float)px + 0.5f * t * nx, my = (float)py + 0.5f * t * ny;
                float margin = fminf(fminf(mx, (float)w - mx), fminf(my, (float)h - my));
                if (margin < 1e-3f) continue;
            }
            float qx = clampf((float)px + t * nx, 0.0f, (float)w), qy = clampf((float)py + t * ny, 0.0f, (float)h);
            float diff = pn_dcm_boundary_value(lum, 1, 0, w, h, qx, qy) - lum[k];
            sum += (double)diff * (double)diff;
            count++;
        }
        /* the paper: the sum over all 4(k - 1) boundary pixels, over their number */
        float di = paper ? (float)(sum / n) : count ? (float)(sum / count) : INFINITY;
        if (d) d[i] = di;
        if (di < best_d) {
            best_d = di;
            best = i;
        }
    }
    return best;
}

float pn_dcm_contrast(const float g[4]) {
    float mx = fmaxf(fmaxf(g[0], g[1]), fmaxf(g[2], g[3]));
    float mn = fminf(fminf(g[0], g[1]), fminf(g[2], g[3]));
    return mx + mn > 0.0f ? (mx - mn) / (mx + mn) : 0.0f;
}

bool pn_dcm_zero_order_test(const float *lum, int w, int h, pn_dcm_zero_order *z) {
    return pn_dcm_zero_order_test_variant(lum, w, h, z, true);
}

bool pn_dcm_zero_order_test_variant(const float *lum, int w, int h, pn_dcm_zero_order *z, bool flat_guard) {
    memset(z, 0, sizeof *z);
    int n = pn_dcm_loop_length(w, h);
    if (n < 3 || n > DCM_MAX_LOOP) return true;
    float f[DCM_MAX_LOOP];
    unsigned char b[DCM_MAX_LOOP], m[DCM_MAX_LOOP];
    float b1 = -INFINITY, d1 = INFINITY;
    for (int i = 0; i < n; i++) { /* Bartlett filter of length 3 */
        f[i] = 0.25f * lum[(i + n - 1) % n] + 0.5f * lum[i] + 0.25f * lum[(i + 1) % n];
        b1 = fmaxf(b1, f[i]);
        d1 = fminf(d1, f[i]);
    }
    z->tb = 0.5f * (b1 + d1);
    if (flat_guard && !(b1 - d1 > PN_DCM_CONTRAST * (b1 + d1))) return true; /* flat boundary */
    for (int i = 0; i < n; i++) b[i] = f[i] > z->tb;
    for (int i = 0; i < n; i++) /* median filter of length 3 */
        m[i] = (unsigned char)(b[(i + n - 1) % n] + b[i] + b[(i + 1) % n] >= 2);
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        if (m[i] == m[j]) continue;
        if (z->transitions < 2) {
            z->one_pixel[z->transitions] = m[i] ? i : j;
            z->zero_pixel[z->transitions] = m[i] ? j : i;
        }
        z->transitions++;
    }
    return z->transitions <= 2;
}

static double fold_angle(double a) { /* into [0, pi) */
    a = fmod(a, M_PI);
    return a < 0.0 ? a + M_PI : a;
}

static double angle_between(double a, double b) {
    double d = fabs(fold_angle(a) - fold_angle(b));
    return d > 0.5 * M_PI ? M_PI - d : d;
}

/* Tangent angle at transition j: walk the inner layer next to the transition point. Returns
 * false when no transition is found there. */
static bool tangent_at(int w, int h, const pn_dcm_zero_order *z, int j, pn_dcm_inner_fn inner, void *user,
                       double *angle) {
    int x1, y1, x0, y0;
    pn_dcm_loop_pixel(w, h, z->one_pixel[j], &x1, &y1);
    pn_dcm_loop_pixel(w, h, z->zero_pixel[j], &x0, &y0);
    bool horizontal = y1 == y0;           /* the pair lies on the top or bottom side */
    int len = horizontal ? w - 1 : h - 1; /* inner pixels 1 .. len along the side */
    int layer = horizontal ? (y1 == 0 ? 1 : h - 1) : (x1 == 0 ? 1 : w - 1);
    int a0 = horizontal ? x1 : y1;
    int start = a0 < 1 ? 1 : a0 > len ? len : a0;
    float v[DCM_MAX_LOOP];
    unsigned char bin[DCM_MAX_LOOP];
    int lo = start, hi = start;
    for (int step = 0;; step++) {
        int pos;
        if (step == 0)
            pos = start;
        else if ((step & 1) && lo > 1)
            pos = --lo;
        else if (hi < len)
            pos = ++hi;
        else if (lo > 1)
            pos = --lo;
        else
            return false;
        v[pos] = horizontal ? inner(user, pos, layer) : inner(user, layer, pos);
        for (int q = lo; q <= hi; q++) bin[q] = v[q] > z->tb;
        /* median filter of length 3 inside the walked segment, then the transition nearest to
         * the start */
        int found = -1, best = 1 << 30;
        unsigned char med[DCM_MAX_LOOP];
        for (int q = lo; q <= hi; q++)
            med[q] = (q > lo && q < hi) ? (unsigned char)(bin[q - 1] + bin[q] + bin[q + 1] >= 2) : bin[q];
        for (int q = lo; q < hi; q++) {
            if (med[q] == med[q + 1]) continue;
            int one = med[q] ? q : q + 1;
            int dist = abs(one - a0);
            if (dist < best) {
                best = dist;
                found = one;
            }
        }
        if (found >= 0) {
            double dx = horizontal ? (double)(found - x1) : (double)(layer - x1);
            double dy = horizontal ? (double)(layer - y1) : (double)(found - y1);
            *angle = atan2(dy, dx);
            return true;
        }
    }
}

bool pn_dcm_first_order_test(int w, int h, const pn_dcm_zero_order *z, pn_dcm_inner_fn inner, void *user) {
    if (z->transitions != 2) return z->transitions == 0;
    if (w < 3 || h < 3) return true; /* no inner layer of two pixels or more */
    double t0, t1;
    if (!tangent_at(w, h, z, 0, inner, user, &t0) || !tangent_at(w, h, z, 1, inner, user, &t1)) return false;
    int ax, ay, bx, by;
    pn_dcm_loop_pixel(w, h, z->one_pixel[0], &ax, &ay);
    pn_dcm_loop_pixel(w, h, z->one_pixel[1], &bx, &by);
    double dist = hypot((double)(bx - ax), (double)(by - ay));
    double t01 = atan2((double)(by - ay), (double)(bx - ax));
    double m01 = fmax(angle_between(t0, t01), angle_between(t1, t01));
    return m01 <= (double)PN_DCM_TANGENT * M_PI * dist;
}

bool pn_dcm_object_test(const int32_t *tags, int n) {
    if (n <= 0) return true;
    int32_t first = tags[0], second = first;
    bool has_second = false;
    int changes = 0;
    for (int i = 0; i < n; i++) {
        int32_t t = tags[i];
        if (t != first) {
            if (!has_second) {
                second = t;
                has_second = true;
            } else if (t != second) {
                return false; /* a third tag */
            }
        }
        if (t != tags[(i + 1) % n]) changes++;
    }
    return changes <= 2;
}

/* ---------------------------------------------------------------------------------------- */
/* The driver */

enum { DCM_SMOOTH = 0, DCM_SIMPLE = 1, DCM_COMPLEX = 2, DCM_PENDING = 3 };

typedef struct dcm_block {
    int32_t x0, y0;
    int32_t parent; /* index in the previous level, -1 for elementary blocks */
    uint16_t size;
    uint8_t kind, dir, lazy, replaced, final, parent_kind;
    uint8_t drawn_dir;    /* an edge block under boundary evaluation: its direction when last drawn ... */
    uint32_t drawn_known; /* ... from this loop state (loop_state_key plus one; 0: never drawn) */
} dcm_block;

typedef struct dcm_level {
    dcm_block *b;
    size_t n, cap;
} dcm_level;

#define DCM_MAX_LEVELS 8

typedef struct dcm_state {
    pn_prog *p;
    bool uniform;
    int elem;
    int reg_spacing;   /* finest complete lattice of the regular subdivision stage (0: none) */
    bool regular_done; /* elementary blocks are final */
    dcm_level lv[DCM_MAX_LEVELS];
    uint32_t simple, complex, lazy;
    uint32_t off; /* PN_DCM_OFF_*: departures switched off (dcm.h) */
} dcm_state;

static void block_extent(const pn_prog *p, const dcm_block *b, int *x1, int *y1) {
    *x1 = b->x0 + b->size < p->W - 1 ? b->x0 + b->size : p->W - 1;
    *y1 = b->y0 + b->size < p->H - 1 ? b->y0 + b->size : p->H - 1;
}

static bool push_block(dcm_level *l, dcm_block b) {
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 256;
        void *nb = realloc(l->b, cap * sizeof *l->b);
        if (!nb) return false;
        l->b = nb;
        l->cap = cap;
    }
    l->b[l->n++] = b;
    return true;
}

/* The block's boundary values (RGB and luminance); pixels neither evaluated nor predicted are
 * interpolated linearly along the loop between known ones (Fig. 9). Returns the loop length. */
static int gather_loop_known(const pn_prog *p, int x0, int y0, int w, int h, float *rgb, float *lum, int *known_count) {
    int n = pn_dcm_loop_length(w, h);
    unsigned char known[DCM_MAX_LOOP];
    int first_known = -1;
    for (int i = 0; i < n; i++) {
        int x, y;
        pn_dcm_loop_pixel(w, h, i, &x, &y);
        size_t k = pn_prog_index(p, x0 + x, y0 + y);
        known[i] = (p->state[k] & 3) != PN_PX_NONE;
        if (known[i]) {
            memcpy(rgb + 3 * i, p->rad + 3 * k, 3 * sizeof *rgb);
            if (first_known < 0) first_known = i;
        }
    }
    if (known_count) {
        /* evaluated and predicted pixels counted apart: a predicted pixel evaluated later
         * changes the key too (known pixels never go back to unknown) */
        int evaluated = 0, predicted = 0;
        for (int i = 0; i < n; i++) {
            int x, y;
            pn_dcm_loop_pixel(w, h, i, &x, &y);
            int st = p->state[pn_prog_index(p, x0 + x, y0 + y)] & 3;
            evaluated += st == PN_PX_EVALUATED;
            predicted += st == PN_PX_PREDICTED;
        }
        *known_count = evaluated * (DCM_MAX_LOOP + 1) + predicted;
    }
    if (first_known < 0) {
        memset(rgb, 0, 3 * (size_t)n * sizeof *rgb);
    } else {
        for (int s = 0; s < n;) { /* walk the runs of unknown pixels starting after a known one */
            int a = (first_known + s) % n;
            int len = 1;
            while (len <= n && !known[(a + len) % n]) len++;
            int b = (a + len) % n;
            for (int j = 1; j < len; j++) {
                float t = (float)j / (float)len;
                int i = (a + j) % n;
                for (int c = 0; c < 3; c++) rgb[3 * i + c] = rgb[3 * a + c] + t * (rgb[3 * b + c] - rgb[3 * a + c]);
            }
            s += len;
        }
    }
    for (int i = 0; i < n; i++) lum[i] = 0.2126f * rgb[3 * i] + 0.7152f * rgb[3 * i + 1] + 0.0722f * rgb[3 * i + 2];
    return n;
}

static int gather_loop(const pn_prog *p, int x0, int y0, int w, int h, float *rgb, float *lum) {
    return gather_loop_known(p, x0, y0, w, h, rgb, lum, NULL);
}

/* Blocks share their boundary pixels; each draws [x0, x1) x [y0, y1) (closed at the image's last
 * row and column), so that blocks can be drawn in parallel and in any order. */
static int draw_end(int v1, int last) {
    return v1 == last ? v1 + 1 : v1;
}

/* A corner of a smooth block of size k, as drawn (a departure for Monte Carlo pixels, see the
 * header): the mean of its value and those of its 8 lattice neighbours at distance k that agree
 * with it within PN_DCM_NOISE standard deviations of their difference and that no visible line
 * separates from it. Noise-free pixels (no variance reported) agree only when equal. */
static void lattice_mean(const pn_prog *p, int x, int y, int k, float *out) {
    const float *c = p->rad + 3 * pn_prog_index(p, x, y);
    memcpy(out, c, 3 * sizeof *out);
    if (k <= 1 || !pn_prog_known(p, x, y)) return;
    float lc = pn_prog_lum(p, x, y), sc = pn_prog_lum_sigma(p, x, y);
    double acc[3] = {c[0], c[1], c[2]};
    int count = 1;
    for (int dy = -k; dy <= k; dy += k)
        for (int dx = -k; dx <= k; dx += k) {
            int xx = x + dx, yy = y + dy;
            if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= p->W || yy >= p->H || !pn_prog_known(p, xx, yy))
                continue;
            float ln = pn_prog_lum(p, xx, yy), sn = pn_prog_lum_sigma(p, xx, yy);
            if (!(fabsf(ln - lc) <= PN_DCM_NOISE * sqrtf(sc * sc + sn * sn))) continue;
            if (pn_prog_visible_line(p, x < xx ? x : xx, y < yy ? y : yy, x < xx ? xx : x, y < yy ? yy : y)) continue;
            const float *v = p->rad + 3 * pn_prog_index(p, xx, yy);
            for (int ch = 0; ch < 3; ch++) acc[ch] += (double)v[ch];
            count++;
        }
    for (int ch = 0; ch < 3; ch++) out[ch] = (float)(acc[ch] / count);
}

/* How draw_bilinear takes a smooth block's corners. */
typedef enum { CORNERS_RAW, CORNERS_MEAN, CORNERS_FIT } corner_mode;

static void lattice_fit(const pn_prog *p, int x, int y, int k, float *out);

static void draw_bilinear(const pn_prog *p, float *img, int x0, int y0, int x1, int y1, corner_mode mode) {
    float s00[3], s10[3], s01[3], s11[3];
    int k = mode == CORNERS_RAW ? 0 : x1 - x0 > y1 - y0 ? x1 - x0 : y1 - y0; /* k 0: the corners themselves */
    void (*corner)(const pn_prog *, int, int, int, float *) = mode == CORNERS_FIT ? lattice_fit : lattice_mean;
    corner(p, x0, y0, k, s00);
    corner(p, x1, y0, k, s10);
    corner(p, x0, y1, k, s01);
    corner(p, x1, y1, k, s11);
    const float *c00 = s00, *c10 = s10, *c01 = s01, *c11 = s11;
    float iw = x1 > x0 ? 1.0f / (float)(x1 - x0) : 0.0f, ih = y1 > y0 ? 1.0f / (float)(y1 - y0) : 0.0f;
    int xe = draw_end(x1, p->W - 1), ye = draw_end(y1, p->H - 1);
    for (int y = y0; y < ye; y++) {
        float v = (float)(y - y0) * ih;
        for (int x = x0; x < xe; x++) {
            float u = (float)(x - x0) * iw;
            float *o = img + 3 * pn_prog_index(p, x, y);
            for (int c = 0; c < 3; c++)
                o[c] = (1 - v) * ((1 - u) * c00[c] + u * c10[c]) + v * ((1 - u) * c01[c] + u * c11[c]);
        }
    }
}

static bool draw_segmented(const pn_prog *p, float *img, const dcm_block *b, const float *loop, int dir, bool guided,
                           bool linear);

static void draw_elements(const pn_prog *p, const dcm_state *d, float *img, dcm_block *b) {
    int x1, y1, known;
    block_extent(p, b, &x1, &y1);
    int w = x1 - b->x0, h = y1 - b->y0;
    float rgb[3 * DCM_MAX_LOOP], lum[DCM_MAX_LOOP];
    gather_loop_known(p, b->x0, b->y0, w, h, rgb, lum, &known);
    /* An edge block still under boundary evaluation: oriented by what its boundary holds now,
     * found again only when its boundary gained pixels since it was last drawn (known pixels
     * never change, so the same count means the same loop). */
    int dir = b->dir;
    if (b->kind == DCM_PENDING) {
        if (b->drawn_known != (uint32_t)known + 1u) {
            b->drawn_dir =
                (uint8_t)pn_dcm_least_discrepancy_variant(lum, w, h, NULL, (d->off & PN_DCM_OFF_DISCREPANCY) != 0);
            b->drawn_known = (uint32_t)known + 1u;
        }
        dir = b->drawn_dir;
    }
    bool guided = b->kind == DCM_PENDING && !(d->off & PN_DCM_OFF_GUIDED);
    if (!(d->off & PN_DCM_OFF_SEGMENTS) &&
        draw_segmented(p, img, b, rgb, dir, guided, guided && !(d->off & PN_DCM_OFF_LINEAR)))
        return;
    int xe = draw_end(x1, p->W - 1) - b->x0, ye = draw_end(y1, p->H - 1) - b->y0;
    for (int y = 0; y < ye; y++)
        for (int x = 0; x < xe; x++)
            pn_dcm_element_value(rgb, 3, w, h, dir, (float)x, (float)y,
                                 img + 3 * pn_prog_index(p, b->x0 + x, b->y0 + y));
}

/* Segments (a departure, see the header): the visible lines of the primary buffer cut a window
 * of the work image into 4-connected pixels that no visible line separates. Labels the ww x wh
 * window at (wx0, wy0) and returns the number of segments. */
#define DCM_SEG_MARGIN 1
#define DCM_SEG_SIDE (16 + 1 + 2 * DCM_SEG_MARGIN)

static int label_segments(const pn_prog *p, int wx0, int wy0, int ww, int wh, int16_t *label) {
    int16_t stack[DCM_SEG_SIDE * DCM_SEG_SIDE];
    int n = ww * wh, segments = 0;
    for (int i = 0; i < n; i++) label[i] = -1;
    for (int i = 0; i < n; i++) {
        if (label[i] >= 0) continue;
        int top = 0;
        label[i] = (int16_t)segments;
        stack[top++] = (int16_t)i;
        while (top > 0) {
            int j = stack[--top], x = j % ww, y = j / ww, gx = wx0 + x, gy = wy0 + y;
            int nb[4] = {-1, -1, -1, -1};
            if (x + 1 < ww && !pn_prog_line_right(p, gx, gy)) nb[0] = j + 1;
            if (x > 0 && !pn_prog_line_right(p, gx - 1, gy)) nb[1] = j - 1;
            if (y + 1 < wh && !pn_prog_line_down(p, gx, gy)) nb[2] = j + ww;
            if (y > 0 && !pn_prog_line_down(p, gx, gy - 1)) nb[3] = j - ww;
            for (int m = 0; m < 4; m++)
                if (nb[m] >= 0 && label[nb[m]] < 0) {
                    label[nb[m]] = (int16_t)segments;
                    stack[top++] = (int16_t)nb[m];
                }
        }
        segments++;
    }
    return segments;
}

/* How much evaluated work pixel j may stand for pixel i of the same segment in the guided
 * reconstruction: the inverse squared distance, times the agreement of their primary rays'
 * normals (cosine to the 8th) and depths (a Gaussian in the relative depth difference, 2%). */
static double guide_weight(const pn_prog *p, size_t i, size_t j, int dx, int dy) {
    double w = 1.0 / (double)(dx * dx + dy * dy);
    if (!p->normal || !p->depth) return w;
    float c = v3_dot(p->normal[i], p->normal[j]);
    c = c > 0.0f ? c : 0.0f;
    float c2 = c * c, c4 = c2 * c2;
    float zi = p->depth[i], zj = p->depth[j];
    double fz = 1.0;
    if (isfinite(zi) && isfinite(zj) && zi > 0.0f) {
        double r = (double)(zi - zj) / (0.02 * (double)zi);
        fz = exp(-0.5 * r * r);
    }
    return w * (double)(c4 * c4) * fz + 1e-12 * w;
}

/* The guided fill's sums for one pixel: weighted mean and, for the linear fill, the normal
 * equations of the weighted plane fit v ~ a + g_x dx + g_y dy (dx, dy from the pixel). */
typedef struct fill_sums {
    double acc[3], wsum;
    double sx, sy, sxx, syy, sxy, svx[3], svy[3];
    float vmin[3], vmax[3];
    int used;
} fill_sums;

static void fill_begin(fill_sums *s) {
    memset(s, 0, sizeof *s);
    for (int c = 0; c < 3; c++) {
        s->vmin[c] = INFINITY;
        s->vmax[c] = -INFINITY;
    }
}

static void fill_add(fill_sums *s, double wt, int dx, int dy, const float *v) {
    for (int c = 0; c < 3; c++) {
        s->acc[c] += wt * (double)v[c];
        s->svx[c] += wt * dx * (double)v[c];
        s->svy[c] += wt * dy * (double)v[c];
        s->vmin[c] = fminf(s->vmin[c], v[c]);
        s->vmax[c] = fmaxf(s->vmax[c], v[c]);
    }
    s->sx += wt * dx, s->sy += wt * dy, s->sxx += wt * dx * dx, s->syy += wt * dy * dy, s->sxy += wt * dx * dy;
    s->wsum += wt;
    s->used++;
}

/* The weighted plane through the sums: its value a[c] at the origin per channel, by Cramer's rule
 * on the normal equations. False (nothing written) when fewer than three samples take part or
 * they lie nearly on a line (det small against wsum sxx syy). */
static bool fill_plane(const fill_sums *s, double *a) {
    if (s->used < 3) return false;
    double A[3][3] = {{s->wsum, s->sx, s->sy}, {s->sx, s->sxx, s->sxy}, {s->sy, s->sxy, s->syy}};
    double c0[3] = {A[1][1] * A[2][2] - A[1][2] * A[2][1], -(A[1][0] * A[2][2] - A[1][2] * A[2][0]),
                    A[1][0] * A[2][1] - A[1][1] * A[2][0]};
    double det = A[0][0] * c0[0] + A[0][1] * c0[1] + A[0][2] * c0[2];
    double scale = s->wsum * s->sxx * s->syy;
    if (!(scale > 0.0 && fabs(det) > 1e-3 * scale)) return false;
    for (int c = 0; c < 3; c++) a[c] = (c0[0] * s->acc[c] + c0[1] * s->svx[c] + c0[2] * s->svy[c]) / det;
    return true;
}

/* Writes the fill (the mean; with `linear` the plane's value where it is well posed) to o. */
static void fill_end(const fill_sums *s, bool linear, float *o) {
    for (int c = 0; c < 3; c++) o[c] = (float)(s->acc[c] / s->wsum);
    /* Linear fill (issue 18, see the header): the plane's value at the pixel, clamped to the
     * samples' range; an ill-posed fit keeps the mean. */
    double a[3];
    if (!linear || !fill_plane(s, a)) return;
    for (int c = 0; c < 3; c++) o[c] = clampf((float)a[c], s->vmin[c], s->vmax[c]);
}

/* A corner of a smooth block of size k drawn by the smooth fit (issue 18, a departure, see the
 * header). Where the corner's noise is large against its value (sigma above DCM_FIT_REL_NOISE of
 * its luminance): the value at the corner of the plane fitted by weighted least squares to the
 * lattice corners within DCM_FIT_RADIUS steps that agree with it within PN_DCM_NOISE standard
 * deviations and that no visible line separates from it (lattice_mean's tests, over a wider
 * neighbourhood; weights Gaussian in lattice distance), clamped to their range. Elsewhere, and
 * where the fit is ill posed, the lattice mean. */
static void lattice_fit(const pn_prog *p, int x, int y, int k, float *out) {
    lattice_mean(p, x, y, k, out);
    if (k <= 1 || !pn_prog_known(p, x, y)) return;
    float lc = pn_prog_lum(p, x, y), sc = pn_prog_lum_sigma(p, x, y);
    if (!(sc > DCM_FIT_REL_NOISE * lc)) return;
    fill_sums s;
    fill_begin(&s);
    for (int j = -DCM_FIT_RADIUS; j <= DCM_FIT_RADIUS; j++)
        for (int i = -DCM_FIT_RADIUS; i <= DCM_FIT_RADIUS; i++) {
            int xx = x + i * k, yy = y + j * k;
            if (xx < 0 || yy < 0 || xx >= p->W || yy >= p->H || !pn_prog_known(p, xx, yy)) continue;
            if (i || j) {
                float ln = pn_prog_lum(p, xx, yy), sn = pn_prog_lum_sigma(p, xx, yy);
                if (!(fabsf(ln - lc) <= PN_DCM_NOISE * sqrtf(sc * sc + sn * sn))) continue;
                if (pn_prog_visible_line(p, x < xx ? x : xx, y < yy ? y : yy, x < xx ? xx : x, y < yy ? yy : y))
                    continue;
            }
            double wt = exp(-0.5 * (double)(i * i + j * j) / (DCM_FIT_SIGMA * DCM_FIT_SIGMA));
            fill_add(&s, wt, i, j, p->rad + 3 * pn_prog_index(p, xx, yy));
        }
    double a[3];
    if (!fill_plane(&s, a)) return;
    for (int c = 0; c < 3; c++) out[c] = clampf((float)a[c], s.vmin[c], s.vmax[c]);
}

/* Segment-aware drawing of an edge block (a departure, see the header). The visible lines of the
 * primary buffer cut the block, widened by DCM_SEG_MARGIN pixels on each side, into segments.
 * When a visible line crosses the block, a pixel keeps its element value where both ends of the
 * element's line are evaluated pixels of its own segment, and otherwise takes the
 * inverse-squared-distance mean of the evaluated pixels of its segment, preferring those that
 * are, like it, next to a visible line or not; a pixel whose segment holds none keeps the
 * element. Guided (issue 18), the weights also ask for agreeing normals and depths
 * (guide_weight). With `linear` (issue 18), that fill is the weighted plane fit's value instead
 * of the mean. Returns false (nothing drawn) for blocks without a visible line or too large. */
static bool draw_segmented(const pn_prog *p, float *img, const dcm_block *b, const float *loop, int dir, bool guided,
                           bool linear) {
    int x1, y1, margin = DCM_SEG_MARGIN;
    block_extent(p, b, &x1, &y1);
    int wx0 = b->x0 > margin ? b->x0 - margin : 0;
    int wy0 = b->y0 > margin ? b->y0 - margin : 0;
    int wx1 = x1 + margin < p->W - 1 ? x1 + margin : p->W - 1;
    int wy1 = y1 + margin < p->H - 1 ? y1 + margin : p->H - 1;
    if (!pn_prog_visible_line(p, b->x0, b->y0, x1, y1)) return false;
    int ww = wx1 - wx0 + 1, wh = wy1 - wy0 + 1;
    if (ww > DCM_SEG_SIDE || wh > DCM_SEG_SIDE) return false;
    int16_t label[DCM_SEG_SIDE * DCM_SEG_SIDE], known[DCM_SEG_SIDE * DCM_SEG_SIDE];
    int n = ww * wh, nk = 0;
    label_segments(p, wx0, wy0, ww, wh, label);
    unsigned char near[DCM_SEG_SIDE * DCM_SEG_SIDE]; /* next to a visible line: a mixed pixel */
    for (int i = 0; i < n; i++) {
        int gx = wx0 + i % ww, gy = wy0 + i / ww;
        near[i] = pn_prog_line_right(p, gx, gy) || pn_prog_line_down(p, gx, gy) ||
                  (gx > 0 && pn_prog_line_right(p, gx - 1, gy)) || (gy > 0 && pn_prog_line_down(p, gx, gy - 1));
        if (pn_prog_known(p, gx, gy)) known[nk++] = (int16_t)i;
    }
    int w = x1 - b->x0, h = y1 - b->y0;
    int xe = draw_end(x1, p->W - 1), ye = draw_end(y1, p->H - 1);
    for (int y = b->y0; y < ye; y++)
        for (int x = b->x0; x < xe; x++) {
            int i = (y - wy0) * ww + (x - wx0);
            size_t gi = pn_prog_index(p, x, y);
            float *o = img + 3 * gi;
            if (pn_prog_known(p, x, y)) { /* restored from the integrator's value anyway */
                memcpy(o, p->rad + 3 * gi, 3 * sizeof *o);
                continue;
            }
            /* The element stays where both ends of its line through the pixel are evaluated
             * pixels of the pixel's own segment. */
            float nx, ny, tmin, tmax, fx = (float)(x - b->x0), fy = (float)(y - b->y0);
            direction(dir, &nx, &ny);
            slab(w, h, fx, fy, nx, ny, &tmin, &tmax);
            int ax = b->x0 + (int)lrintf(clampf(fx + fminf(tmin, 0.0f) * nx, 0.0f, (float)w));
            int ay = b->y0 + (int)lrintf(clampf(fy + fminf(tmin, 0.0f) * ny, 0.0f, (float)h));
            int bx = b->x0 + (int)lrintf(clampf(fx + fmaxf(tmax, 0.0f) * nx, 0.0f, (float)w));
            int by = b->y0 + (int)lrintf(clampf(fy + fmaxf(tmax, 0.0f) * ny, 0.0f, (float)h));
            if (label[(ay - wy0) * ww + (ax - wx0)] == label[i] && label[(by - wy0) * ww + (bx - wx0)] == label[i] &&
                pn_prog_known(p, ax, ay) && pn_prog_known(p, bx, by)) {
                pn_dcm_element_value(loop, 3, w, h, dir, fx, fy, o);
                continue;
            }
            /* First from pixels as near to a visible line as this one (pixels next to a line
             * mix both sides under the pixel filter), then from any of its segment. */
            fill_sums s;
            fill_begin(&s);
            for (int pass = 0; pass < 2 && s.wsum <= 0.0; pass++)
                for (int m = 0; m < nk; m++) {
                    int j = known[m];
                    if (label[j] != label[i] || (pass == 0 && near[j] != near[i])) continue;
                    int dx = wx0 + j % ww - x, dy = wy0 + j / ww - y;
                    size_t gj = pn_prog_index(p, wx0 + j % ww, wy0 + j / ww);
                    double wt = guided ? guide_weight(p, gi, gj, dx, dy) : 1.0 / (double)(dx * dx + dy * dy);
                    fill_add(&s, wt, dx, dy, p->rad + 3 * gj);
                }
            if (s.wsum > 0.0)
                fill_end(&s, linear, o);
            else
                pn_dcm_element_value(loop, 3, w, h, dir, fx, fy, o);
        }
    return true;
}

/* Segment seeds (issue 18, part of the guided reconstruction): before the boundary evaluation
 * of an edge block that a visible line crosses, the pixel nearest the centroid of every segment
 * of at least DCM_SEED_MIN pixels that holds no evaluated pixel yet is queued, so that each
 * segment is reconstructed from its own radiance instead of its neighbours'. */
#define DCM_SEED_MIN 3
static bool request_segment_seeds(pn_prog *p, const dcm_block *b) {
    int x1, y1;
    block_extent(p, b, &x1, &y1);
    if (!pn_prog_visible_line(p, b->x0, b->y0, x1, y1)) return true;
    int ww = x1 - b->x0 + 1, wh = y1 - b->y0 + 1;
    if (ww > DCM_SEG_SIDE || wh > DCM_SEG_SIDE) return true;
    int16_t label[DCM_SEG_SIDE * DCM_SEG_SIDE];
    int segments = label_segments(p, b->x0, b->y0, ww, wh, label), n = ww * wh;
    for (int s = 0; s < segments; s++) {
        int count = 0;
        double cx = 0, cy = 0;
        bool has = false;
        for (int i = 0; i < n; i++) {
            if (label[i] != s) continue;
            int gx = b->x0 + i % ww, gy = b->y0 + i / ww;
            if (p->state[pn_prog_index(p, gx, gy)] & (PN_PX_EVALUATED | PN_PX_QUEUED)) has = true;
            cx += gx;
            cy += gy;
            count++;
        }
        if (has || count < DCM_SEED_MIN) continue;
        cx /= count;
        cy /= count;
        int best = -1;
        double best_d = INFINITY;
        for (int i = 0; i < n; i++) {
            if (label[i] != s) continue;
            double dx = b->x0 + i % ww - cx, dy = b->y0 + i / ww - cy, dd = dx * dx + dy * dy;
            if (dd < best_d) {
                best_d = dd;
                best = i;
            }
        }
        if (best >= 0 && !pn_prog_request(p, b->x0 + best % ww, b->y0 + best / ww)) return false;
    }
    return true;
}

typedef struct draw_run {
    pn_prog *p;
    dcm_state *d;
    float *img, *cls, *dir;
    int spacing, cells_x; /* regular stage: lattice cells per row */
    int32_t (*chunks)[2]; /* DCM: (level, first block) of each job */
} draw_run;

#define DCM_DRAW_CHUNK 1024

static void draw_regular_row(void *user, size_t job, int worker) {
    (void)worker;
    draw_run *r = user;
    const pn_prog *p = r->p;
    int s = r->spacing, y = (int)job * s;
    for (int x = 0; x < p->W - 1 || x == 0; x += s)
        draw_bilinear(p, r->img, x, y, x + s < p->W - 1 ? x + s : p->W - 1, y + s < p->H - 1 ? y + s : p->H - 1,
                      (r->d->off & PN_DCM_OFF_LATTICE_MEAN) ? CORNERS_RAW : CORNERS_MEAN);
}

/* Corners of DCM's smooth blocks: the smooth fit unless switched off (or uniform subsampling,
 * which keeps the lattice mean). */
static corner_mode smooth_corners(const dcm_state *d) {
    if (d->off & PN_DCM_OFF_LATTICE_MEAN) return CORNERS_RAW;
    return (d->uniform || (d->off & PN_DCM_OFF_SMOOTH_FIT)) ? CORNERS_MEAN : CORNERS_FIT;
}

static void draw_chunk(void *user, size_t job, int worker) {
    (void)worker;
    draw_run *r = user;
    const pn_prog *p = r->p;
    dcm_level *L = &r->d->lv[r->chunks[job][0]];
    size_t end = (size_t)r->chunks[job][1] + DCM_DRAW_CHUNK;
    if (end > L->n) end = L->n;
    for (size_t i = (size_t)r->chunks[job][1]; i < end; i++) {
        dcm_block *b = &L->b[i]; /* each block is drawn by one job: its direction cache is its own */
        if (!b->final || b->replaced) continue;
        int x1, y1;
        block_extent(p, b, &x1, &y1);
        if (b->kind == DCM_SMOOTH)
            draw_bilinear(p, r->img, b->x0, b->y0, x1, y1, smooth_corners(r->d));
        else
            draw_elements(p, r->d, r->img, b);
        if (r->cls) {
            int xe = draw_end(x1, p->W - 1), ye = draw_end(y1, p->H - 1);
            for (int y = b->y0; y < ye; y++)
                for (int x = b->x0; x < xe; x++) {
                    size_t k = pn_prog_index(p, x, y);
                    r->cls[k] = (float)b->kind;
                    r->dir[k] = b->kind == DCM_SMOOTH ? -1.0f : (float)b->dir * (180.0f / PN_DCM_DIRECTIONS);
                }
        }
    }
}

static void dcm_draw(pn_prog *p, void *driver, float *img, float *cls, float *dir) {
    dcm_state *d = driver;
    draw_run r = {p, d, img, cls, dir, d->reg_spacing, 0, NULL};
    if (!d->regular_done) {
        if (r.spacing <= 0) return;
        size_t rows = (size_t)((p->H - 1 + r.spacing - 1) / r.spacing);
        pn_prog_parallel(p, rows > 0 ? rows : 1, draw_regular_row, &r);
        return;
    }
    size_t jobs = 0;
    for (int l = 0; l < DCM_MAX_LEVELS; l++) jobs += (d->lv[l].n + DCM_DRAW_CHUNK - 1) / DCM_DRAW_CHUNK;
    r.chunks = malloc((jobs ? jobs : 1) * sizeof *r.chunks);
    if (!r.chunks) { /* serial fallback, one block at a time */
        int32_t one[1][2];
        r.chunks = one;
        for (int l = 0; l < DCM_MAX_LEVELS; l++)
            for (size_t i = 0; i < d->lv[l].n; i += DCM_DRAW_CHUNK) {
                one[0][0] = l;
                one[0][1] = (int32_t)i;
                draw_chunk(&r, 0, 0);
            }
        return;
    }
    size_t j = 0;
    for (int l = 0; l < DCM_MAX_LEVELS; l++)
        for (size_t i = 0; i < d->lv[l].n; i += DCM_DRAW_CHUNK) {
            r.chunks[j][0] = l;
            r.chunks[j][1] = (int32_t)i;
            j++;
        }
    pn_prog_parallel(p, jobs, draw_chunk, &r);
    free(r.chunks);
}

static bool request_block_corners(pn_prog *p, const dcm_block *b) {
    int x1, y1;
    block_extent(p, b, &x1, &y1);
    return pn_prog_request(p, b->x0, b->y0) && pn_prog_request(p, x1, b->y0) && pn_prog_request(p, b->x0, y1) &&
           pn_prog_request(p, x1, y1);
}

/* Contrast thresholding (§4.2): the corners' contrast exceeds t_c — and, a departure for Monte
 * Carlo pixels, the luminance range exceeds the noise of its two ends (PN_DCM_NOISE standard
 * deviations of the difference, from the integrator's variance estimates), so that noise alone
 * does not make every block an edge block. */
static bool contrasted(const pn_prog *p, int x0, int y0, int x1, int y1, bool noise_test) {
    int cx[4] = {x0, x1, x0, x1}, cy[4] = {y0, y0, y1, y1};
    float g[4];
    int lo = 0, hi = 0;
    for (int i = 0; i < 4; i++) {
        g[i] = pn_prog_lum(p, cx[i], cy[i]);
        if (g[i] < g[lo]) lo = i;
        if (g[i] > g[hi]) hi = i;
    }
    if (!(pn_dcm_contrast(g) > PN_DCM_CONTRAST)) return false;
    if (!noise_test) return true;
    float sl = pn_prog_lum_sigma(p, cx[lo], cy[lo]), sh = pn_prog_lum_sigma(p, cx[hi], cy[hi]);
    return g[hi] - g[lo] > PN_DCM_NOISE * sqrtf(sl * sl + sh * sh);
}

/* Lazy boundary evaluation test (Fig. 6): the child's corners against the parent's elements,
 * within 1% — or, for Monte Carlo pixels, within PN_DCM_NOISE standard deviations of the
 * pixel's estimate (a departure: a 1% test on noisy pixels fails everywhere). */
static bool lazy_ok(const pn_prog *p, const dcm_block *parent, const dcm_block *child, bool noise_test) {
    int px1, py1, cx1, cy1;
    block_extent(p, parent, &px1, &py1);
    block_extent(p, child, &cx1, &cy1);
    int w = px1 - parent->x0, h = py1 - parent->y0;
    float rgb[3 * DCM_MAX_LOOP], lum[DCM_MAX_LOOP];
    gather_loop(p, parent->x0, parent->y0, w, h, rgb, lum);
    int cx[4] = {child->x0, cx1, child->x0, cx1}, cy[4] = {child->y0, child->y0, cy1, cy1};
    for (int i = 0; i < 4; i++) {
        float pred[3];
        pn_dcm_element_value(rgb, 3, w, h, parent->dir, (float)(cx[i] - parent->x0), (float)(cy[i] - parent->y0), pred);
        float lp = 0.2126f * pred[0] + 0.7152f * pred[1] + 0.0722f * pred[2];
        float la = pn_prog_lum(p, cx[i], cy[i]);
        float tol = PN_DCM_LAZY_TOLERANCE * fabsf(la);
        if (noise_test) tol = fmaxf(tol, PN_DCM_NOISE * pn_prog_lum_sigma(p, cx[i], cy[i]));
        if (!(fabsf(lp - la) <= tol + 1e-7f)) return false;
    }
    return true;
}

/* Writes the parent's element values on the child's boundary pixels that hold nothing yet. */
static void predict_boundary(pn_prog *p, const dcm_block *parent, const dcm_block *child) {
    int px1, py1, cx1, cy1;
    block_extent(p, parent, &px1, &py1);
    block_extent(p, child, &cx1, &cy1);
    int w = px1 - parent->x0, h = py1 - parent->y0;
    float rgb[3 * DCM_MAX_LOOP], lum[DCM_MAX_LOOP];
    gather_loop(p, parent->x0, parent->y0, w, h, rgb, lum);
    int cw = cx1 - child->x0, ch = cy1 - child->y0, n = pn_dcm_loop_length(cw, ch);
    for (int i = 0; i < n; i++) {
        int x, y;
        pn_dcm_loop_pixel(cw, ch, i, &x, &y);
        size_t k = pn_prog_index(p, child->x0 + x, child->y0 + y);
        if ((p->state[k] & 3) != PN_PX_NONE) continue;
        pn_dcm_element_value(rgb, 3, w, h, parent->dir, (float)(child->x0 + x - parent->x0),
                             (float)(child->y0 + y - parent->y0), p->rad + 3 * k);
        p->state[k] = (unsigned char)((p->state[k] & PN_PX_QUEUED) | PN_PX_PREDICTED);
    }
}

typedef struct boundary_task {
    float key;
    int spacing;
    size_t block;
} boundary_task;

static int cmp_task(const void *a, const void *b) {
    const boundary_task *x = a, *y = b;
    if (x->key != y->key) return x->key > y->key ? -1 : 1;
    if (x->spacing != y->spacing) return x->spacing > y->spacing ? -1 : 1;
    return x->block < y->block ? -1 : x->block > y->block;
}

/* The luminance of what a work pixel's interpolated value stands for in the image: the quotient
 * multiplied back by its demodulation factor (albedo and light guide), without the emitted part,
 * which the primary rays give exactly. */
static float corner_radiance(const pn_prog *p, int x, int y) {
    size_t i = pn_prog_index(p, x, y);
    const float *r = p->rad + 3 * i, *f = p->demod ? p->demod + 3 * i : NULL;
    if (!f) return pn_prog_lum(p, x, y);
    return v3_luminance(v3(r[0] * f[0], r[1] * f[1], r[2] * f[2]));
}

/* The expected error of an edge block before its boundary evaluation: the range of its corners'
 * radiance; with the guided order at least half the brightest corner's where a visible line
 * crosses it; 1 for the paper's order (spacing by spacing, blocks in turn). */
static float block_range(const pn_prog *p, const dcm_block *b, bool by_error, bool guided) {
    if (!by_error) return 1.0f;
    int x1, y1;
    block_extent(p, b, &x1, &y1);
    int cx[4] = {b->x0, x1, b->x0, x1}, cy[4] = {b->y0, b->y0, y1, y1};
    float g[4];
    for (int c = 0; c < 4; c++) g[c] = corner_radiance(p, cx[c], cy[c]);
    float range = fmaxf(fmaxf(g[0], g[1]), fmaxf(g[2], g[3])) - fminf(fminf(g[0], g[1]), fminf(g[2], g[3]));
    if (!(range >= 0.0f)) range = 0.0f;
    if (guided && pn_prog_visible_line(p, b->x0, b->y0, x1, y1)) {
        /* Guided order: behind a visible line lies a segment no corner may have seen, whose
         * radiance is unknown; its expected error is taken as half the brightest corner's. */
        float top = fmaxf(fmaxf(g[0], g[1]), fmaxf(g[2], g[3]));
        range = fmaxf(range, 0.5f * top);
    }
    return range;
}

/* Queues the boundary pixels of block b at spacing sp; returns the number newly queued, or -1
 * when out of memory. */
static long queue_spacing(pn_prog *p, const dcm_block *b, int sp) {
    int x1, y1;
    block_extent(p, b, &x1, &y1);
    int w = x1 - b->x0, h = y1 - b->y0, n = pn_dcm_loop_length(w, h);
    size_t before = p->queue_len;
    for (int i = 0; i < n; i++) {
        int x, y;
        pn_dcm_loop_pixel(w, h, i, &x, &y);
        if ((x % sp == 0 || x == w) && (y % sp == 0 || y == h))
            if (!pn_prog_request(p, b->x0 + x, b->y0 + y)) return -1;
    }
    return (long)(p->queue_len - before);
}

/* Queues the boundary pixels of the edge blocks in task order (see process()). */
static pn_status boundary_tasks(pn_prog *p, const dcm_block *blocks, const size_t *pending, size_t np, int k,
                                bool by_error, bool guided) {
    int rounds = 0;
    for (int sp = k / 2; sp >= 1; sp /= 2) rounds++;
    if (np == 0 || rounds == 0) return PN_OK;
    boundary_task *t = malloc(np * (size_t)rounds * sizeof *t);
    if (!t) return PN_ERROR_OUT_OF_MEMORY;
    size_t nt = 0;
    for (size_t j = 0; j < np; j++) {
        float range = block_range(p, &blocks[pending[j]], by_error, guided);
        for (int sp = k / 2; sp >= 1; sp /= 2) {
            t[nt].key = range * (float)sp;
            t[nt].spacing = sp;
            t[nt].block = pending[j];
            nt++;
        }
    }
    qsort(t, nt, sizeof *t, cmp_task);
    for (size_t m = 0; m < nt; m++)
        if (queue_spacing(p, &blocks[t[m].block], t[m].spacing) < 0) {
            free(t);
            return PN_ERROR_OUT_OF_MEMORY;
        }
    free(t);
    return PN_OK;
}

/* What block b's boundary step at spacing sp (just evaluated) found: the largest difference, in
 * the image's radiance, between a pixel of that step and the mean of its two loop neighbours of
 * the step before, i.e. the error that interpolation along the loop made there. Negative when the
 * loop does not divide into steps of 2 sp (clipped blocks) or nothing was evaluated. */
static float step_residual(const pn_prog *p, const dcm_block *b, int sp) {
    int x1, y1;
    block_extent(p, b, &x1, &y1);
    int w = x1 - b->x0, h = y1 - b->y0, n = pn_dcm_loop_length(w, h);
    if (n == 0 || w % (2 * sp) || h % (2 * sp)) return -1.0f;
    float worst = -1.0f;
    for (int i = sp; i < n; i += 2 * sp) {
        int x, y, xa, ya, xb, yb;
        pn_dcm_loop_pixel(w, h, i, &x, &y);
        pn_dcm_loop_pixel(w, h, i - sp, &xa, &ya);
        pn_dcm_loop_pixel(w, h, (i + sp) % n, &xb, &yb);
        x += b->x0, y += b->y0, xa += b->x0, ya += b->y0, xb += b->x0, yb += b->y0;
        if (!pn_prog_known(p, x, y) || !pn_prog_known(p, xa, ya) || !pn_prog_known(p, xb, yb)) continue;
        size_t ki = pn_prog_index(p, x, y), ka = pn_prog_index(p, xa, ya), kb = pn_prog_index(p, xb, yb);
        const float *f = p->demod ? p->demod + 3 * ki : NULL;
        float d[3];
        for (int c = 0; c < 3; c++) {
            d[c] = p->rad[3 * ki + c] - 0.5f * (p->rad[3 * ka + c] + p->rad[3 * kb + c]);
            if (f) d[c] *= f[c];
        }
        float r = fabsf(v3_luminance(v3(d[0], d[1], d[2])));
        worst = fmaxf(worst, r);
    }
    return worst;
}

/* The residual order's chunk: the share of the work pixels queued between two looks at what the
 * steps found (0.1% gave the same 6% image on quarter staircase as 0.25%). */
#define DCM_RESIDUAL_CHUNK 0.0025

/* Boundary tasks in a max-heap (core/heap.h) in cmp_task's order: the key, then the larger
 * spacing, then the lower block, both packed into the payload (spacing <= k / 2, blocks < 2^32). */
static void task_push(pn_heap *h, boundary_task t, int k) {
    pn_heap_push(h, t.key, (int64_t)(k - t.spacing) << 32 | (int64_t)t.block);
}

static boundary_task task_pop(pn_heap *h, int k) {
    pn_heap_entry e = pn_heap_pop(h);
    return (boundary_task){(float)e.key, k - (int)(e.payload >> 32), (size_t)(e.payload & 0xffffffff)};
}

/* Residual order (issue 18, see the header): boundary steps in chunks of DCM_RESIDUAL_CHUNK of
 * the work pixels; a block's first step goes by block_range x spacing, each later one by what the
 * step before it found (step_residual, doubled: a step edge between two pixels leaves half its
 * range at their midpoint) x spacing, so that blocks whose loop turned out smooth give way to
 * those where the interpolation was wrong. Evaluates as it goes (flushes). */
static pn_status boundary_rounds(pn_prog *p, const dcm_block *blocks, const size_t *pending, size_t np, int k,
                                 bool guided) {
    if (np == 0 || k < 2) return PN_OK;
    pn_heap h; /* one task a block at most: np entries */
    pn_heap_init(&h, PN_HEAP_MAX | PN_HEAP_TIES_BY_PAYLOAD);
    boundary_task *done = malloc(np * sizeof *done);
    float *range = malloc(np * sizeof *range);
    if (!pn_heap_reserve(&h, np) || !done || !range) {
        pn_heap_free(&h);
        free(done);
        free(range);
        return PN_ERROR_OUT_OF_MEMORY;
    }
    for (size_t j = 0; j < np; j++) {
        range[j] = block_range(p, &blocks[pending[j]], true, guided);
        task_push(&h, (boundary_task){range[j] * (float)(k / 2), k / 2, j}, k);
    }
    size_t chunk = (size_t)((double)p->W * (double)p->H * DCM_RESIDUAL_CHUNK);
    if (chunk < 64) chunk = 64;
    pn_status st = PN_OK;
    while (h.count > 0 && st == PN_OK && !p->stopped) {
        size_t nd = 0, queued = 0;
        while (h.count > 0 && queued < chunk) {
            boundary_task t = task_pop(&h, k);
            long q = queue_spacing(p, &blocks[pending[t.block]], t.spacing);
            if (q < 0) {
                st = PN_ERROR_OUT_OF_MEMORY;
                break;
            }
            queued += (size_t)q;
            done[nd++] = t;
        }
        if (st != PN_OK || (st = pn_prog_flush(p)) != PN_OK || p->stopped) break;
        for (size_t m = 0; m < nd; m++) {
            boundary_task t = done[m];
            if (t.spacing <= 1) continue;
            float r = step_residual(p, &blocks[pending[t.block]], t.spacing);
            float e = r >= 0.0f ? 2.0f * r : range[t.block];
            t.spacing /= 2;
            t.key = e * (float)t.spacing;
            task_push(&h, t, k);
        }
    }
    pn_heap_free(&h);
    free(done);
    free(range);
    return st;
}

typedef struct test_run {
    dcm_state *d;
    dcm_block *blocks;
    size_t *pending;
} test_run;

typedef struct inner_ctx {
    pn_prog *p;
    int x0, y0, worker;
} inner_ctx;

static float inner_eval(void *user, int x, int y) {
    inner_ctx *c = user;
    pn_prog_eval_now(c->p, c->worker, c->x0 + x, c->y0 + y);
    return pn_prog_lum(c->p, c->x0 + x, c->y0 + y);
}

/* Steps (3) and (4) for one edge block with its boundary evaluated. */
static void test_block(void *user, size_t job, int worker) {
    test_run *r = user;
    pn_prog *p = r->d->p;
    dcm_block *b = &r->blocks[r->pending[job]];
    int x1, y1;
    block_extent(p, b, &x1, &y1);
    int w = x1 - b->x0, h = y1 - b->y0;
    float rgb[3 * DCM_MAX_LOOP], lum[DCM_MAX_LOOP];
    int n = gather_loop(p, b->x0, b->y0, w, h, rgb, lum);
    uint32_t off = r->d->off;
    b->dir = (uint8_t)pn_dcm_least_discrepancy_variant(lum, w, h, NULL, (off & PN_DCM_OFF_DISCREPANCY) != 0);
    pn_dcm_zero_order z;
    bool simple = pn_dcm_zero_order_test_variant(lum, w, h, &z, !(off & PN_DCM_OFF_NOISE));
    if (simple) {
        inner_ctx ic = {p, b->x0, b->y0, worker};
        simple = pn_dcm_first_order_test(w, h, &z, inner_eval, &ic);
    }
    if (simple && p->tag) {
        int32_t tags[DCM_MAX_LOOP];
        for (int i = 0; i < n; i++) {
            int x, y;
            pn_dcm_loop_pixel(w, h, i, &x, &y);
            tags[i] = p->tag[pn_prog_index(p, b->x0 + x, b->y0 + y)];
        }
        simple = pn_dcm_object_test(tags, n);
    }
    b->kind = simple ? DCM_SIMPLE : DCM_COMPLEX;
}

/* One DCM iteration over the candidate blocks [start, end) of level l. */
static pn_status process(dcm_state *d, int l, size_t start, size_t end) {
    pn_prog *p = d->p;
    dcm_level *L = &d->lv[l];
    pn_status st;
    if (start == end) return PN_OK;
    for (size_t i = start; i < end; i++)
        if (!request_block_corners(p, &L->b[i])) return PN_ERROR_OUT_OF_MEMORY;
    if ((st = pn_prog_flush(p)) != PN_OK || p->stopped) return st;

    /* (1) block classification */
    size_t *pending = malloc((end - start) * sizeof *pending);
    if (!pending) return PN_ERROR_OUT_OF_MEMORY;
    size_t np = 0;
    for (size_t i = start; i < end; i++) {
        dcm_block *b = &L->b[i];
        int x1, y1;
        block_extent(p, b, &x1, &y1);
        bool degenerate = x1 == b->x0 || y1 == b->y0;
        b->kind = DCM_SMOOTH;
        if (d->uniform || degenerate) continue;
        if (b->parent_kind == DCM_SMOOTH) {
            if (contrasted(p, b->x0, b->y0, x1, y1, !(d->off & PN_DCM_OFF_NOISE)) ||
                pn_prog_visible_line(p, b->x0, b->y0, x1, y1))
                b->kind = DCM_PENDING;
        } else if (b->parent_kind == DCM_COMPLEX) {
            b->kind = DCM_PENDING;
        } else {
            const dcm_block *parent = &d->lv[l - 1].b[b->parent];
            if (lazy_ok(p, parent, b, !(d->off & PN_DCM_OFF_NOISE))) {
                b->kind = DCM_SIMPLE;
                b->lazy = 1;
                b->dir = parent->dir;
                predict_boundary(p, parent, b);
            } else {
                b->kind = DCM_PENDING;
            }
        }
        if (b->kind == DCM_PENDING) pending[np++] = i;
    }
    /* The classified blocks replace their parents in the approximate image at once; edge blocks
     * show elements over their partly evaluated boundaries, re-oriented after every round. */
    d->regular_done = true;
    for (size_t i = start; i < end; i++) {
        L->b[i].final = 1;
        if (L->b[i].parent >= 0) d->lv[l - 1].b[L->b[i].parent].replaced = 1;
    }

    /* (2) boundary evaluation at spacings k/2, k/4, ..., 1 (Fig. 9), as tasks (block, spacing)
     * ordered by the luminance range of the block's corners times the spacing: every block gets
     * its spacings coarse to fine, and blocks with a large range (the largest errors of the
     * image) reach the fine spacings before flat ones get their coarse ones. */
    int k = L->b[start].size;
    if (!(d->off & (PN_DCM_OFF_GUIDED | PN_DCM_OFF_SEGMENTS)))
        for (size_t j = 0; j < np; j++)
            if (!request_segment_seeds(p, &L->b[pending[j]])) {
                free(pending);
                return PN_ERROR_OUT_OF_MEMORY;
            }
    bool guided_order = !(d->off & (PN_DCM_OFF_GUIDED | PN_DCM_OFF_SEGMENTS));
    if (!(d->off & (PN_DCM_OFF_ORDER | PN_DCM_OFF_RESIDUALS)))
        st = boundary_rounds(p, L->b, pending, np, k, guided_order);
    else
        st = boundary_tasks(p, L->b, pending, np, k, !(d->off & PN_DCM_OFF_ORDER), guided_order);
    if (st != PN_OK || p->stopped) {
        free(pending);
        return st;
    }
    if ((st = pn_prog_flush(p)) != PN_OK || p->stopped) {
        free(pending);
        return st;
    }

    /* (3) simplicity tests and (4) least-discrepancy directions, in parallel */
    test_run tr = {d, L->b, pending};
    pn_prog_parallel(p, np, test_block, &tr);
    pn_prog_collect_extra(p);
    free(pending);
    int failed = atomic_load(&p->failed);
    if (failed) return (pn_status)failed;

    for (size_t i = start; i < end; i++) {
        dcm_block *b = &L->b[i];
        if (b->kind == DCM_SIMPLE) d->simple++;
        if (b->kind == DCM_COMPLEX) d->complex++;
        if (b->lazy) d->lazy++;
    }
    return pn_prog_flush(p); /* fires snapshots that are due */
}

static bool add_children(dcm_state *d, int l, size_t parent_index) {
    const pn_prog *p = d->p;
    dcm_block pb = d->lv[l - 1].b[parent_index];
    int x1, y1, half = pb.size / 2;
    block_extent(p, &pb, &x1, &y1);
    for (int cy = pb.y0; cy <= pb.y0 + half; cy += half) {
        if (cy != pb.y0 && cy >= y1) break;
        for (int cx = pb.x0; cx <= pb.x0 + half; cx += half) {
            if (cx != pb.x0 && cx >= x1) break;
            dcm_block c = {cx, cy, (int32_t)parent_index, (uint16_t)half, DCM_SMOOTH, 0, 0, 0, 0, pb.kind, 0, 0};
            if (!push_block(&d->lv[l], c)) return false;
        }
    }
    return true;
}

static pn_status dcm_iterate(dcm_state *d) {
    pn_prog *p = d->p;
    pn_status st;
    /* Regular subdivision stage: the quadtree's corner lattices, coarse to fine. */
    int root = d->elem;
    while (root < p->W - 1 || root < p->H - 1) root *= 2;
    for (int s = root; s >= d->elem; s /= 2) {
        for (int y = 0;; y += s) {
            int yy = y < p->H - 1 ? y : p->H - 1;
            for (int x = 0;; x += s) {
                int xx = x < p->W - 1 ? x : p->W - 1;
                if (!pn_prog_request(p, xx, yy)) return PN_ERROR_OUT_OF_MEMORY;
                if (xx == p->W - 1) break;
            }
            if (yy == p->H - 1) break;
        }
        if ((st = pn_prog_flush(p)) != PN_OK) return st;
        d->reg_spacing = s;
        if (p->stopped) return PN_OK;
    }
    /* Elementary blocks: the pool of the first DCM iteration. */
    for (int y = 0; y < p->H - 1 || y == 0; y += d->elem)
        for (int x = 0; x < p->W - 1 || x == 0; x += d->elem) {
            dcm_block b = {x, y, -1, (uint16_t)d->elem, DCM_SMOOTH, 0, 0, 0, 0, DCM_SMOOTH, 0, 0};
            if (!push_block(&d->lv[0], b)) return PN_ERROR_OUT_OF_MEMORY;
        }
    if ((st = process(d, 0, 0, d->lv[0].n)) != PN_OK || p->stopped) return st;
    d->regular_done = true;
    for (int l = 1; l < DCM_MAX_LEVELS; l++) {
        int k = d->elem >> l;
        dcm_level *prev = &d->lv[l - 1];
        if (k < 1) break;
        /* Edge blocks' quads first (pass 0), then smooth blocks' (pass 1); the paper's order is
         * one pass over all blocks (pass -1). */
        int first_pass = (d->off & PN_DCM_OFF_EDGE_FIRST) ? -1 : 0, last_pass = first_pass < 0 ? -1 : 1;
        if (k == 1) { /* the quads are pixels: evaluate everything, edge blocks first */
            for (int pass = first_pass; pass <= last_pass; pass++) {
                for (size_t i = 0; i < prev->n; i++) {
                    const dcm_block *b = &prev->b[i];
                    if (pass >= 0 && (b->kind == DCM_SMOOTH) != (pass == 1)) continue;
                    int x1, y1;
                    block_extent(p, b, &x1, &y1);
                    for (int y = b->y0; y <= y1; y++)
                        for (int x = b->x0; x <= x1; x++)
                            if (!pn_prog_request(p, x, y)) return PN_ERROR_OUT_OF_MEMORY;
                }
                if ((st = pn_prog_flush(p)) != PN_OK || p->stopped) return st;
                for (size_t i = 0; i < prev->n; i++)
                    if (pass < 0 || (prev->b[i].kind == DCM_SMOOTH) == (pass == 1)) prev->b[i].replaced = 1;
            }
            break;
        }
        for (int pass = first_pass; pass <= last_pass; pass++) { /* quads of edge blocks, then of smooth */
            size_t start = d->lv[l].n;
            for (size_t i = 0; i < prev->n; i++)
                if (pass < 0 || (prev->b[i].kind == DCM_SMOOTH) == (pass == 1))
                    if (!add_children(d, l, i)) return PN_ERROR_OUT_OF_MEMORY;
            if ((st = process(d, l, start, d->lv[l].n)) != PN_OK || p->stopped) return st;
        }
    }
    return PN_OK;
}

static void dcm_free(void *driver) {
    dcm_state *d = driver;
    if (!d) return;
    for (int l = 0; l < DCM_MAX_LEVELS; l++) free(d->lv[l].b);
    free(d);
}

pn_status pn_dcm_run(pn_prog *p, bool uniform_only) {
    dcm_state *d = calloc(1, sizeof *d);
    if (!d) return PN_ERROR_OUT_OF_MEMORY;
    d->p = p;
    d->uniform = uniform_only;
    d->elem = 8;
    d->off = pn_dcm_off_flags(p->job.dcm_variant, p->job.dcm_off);
    p->draw = dcm_draw;
    p->driver = d;
    p->free_driver = dcm_free;
    pn_status st = dcm_iterate(d);
    if (p->driver_stats) {
        p->driver_stats->dcm_simple_blocks = d->simple;
        p->driver_stats->dcm_complex_blocks = d->complex;
        p->driver_stats->dcm_lazy_blocks = d->lazy;
    }
    /* The state stays alive for the final image: progressive.c draws after we return. */
    return st;
}
