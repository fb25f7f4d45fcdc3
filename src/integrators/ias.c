/* ias.c — Iterative Adaptive Sampling (Donikian, Walter, Bala, Fernandez, Greenberg, "Accurate
 * Direct Illumination Using Iterative Adaptive Sampling", IEEE TVCG 2006).
 *
 * Each 8x8 block of the image (the block side is a setting, --block-size) is rendered on its own,
 * in passes:
 *
 *  - Points (§4, §4.4). Every pixel shoots aa_rays eye rays (32) once; their shading points are
 *    grouped into antialiasing regions: a ray joins a region of its pixel whose representative
 *    point lies in the same plane, has the same material and is within the region radius (a
 *    quarter of the pixel radius at that depth); otherwise it starts a region and represents it.
 *    A region's weight is its share of the pixel's eye rays; regions are sampled in proportion.
 *    The radius is measured on the image plane (IAS_REGION_RADIUS).
 *    The points are cached for all passes.
 *  - Clusters (§4.3). Per region point, a cut through the light cluster trees (lights/cluster_tree.c:
 *    one omnidirectional tree and six oriented trees, built greedily by smallest bounding sphere)
 *    at clusters subtending less than cluster_solid_angle (0.02 sr, §5.7), after the standard
 *    geometric tests; distant lights are clusters of their own; an environment map contributes
 *    its static regions (lights/env_regions.c, 300 by default) that are not below the horizon.
 *    A chosen cluster picks one of its lights in proportion to power.
 *  - PDFs (§4.1). Running sums per block and per pixel, kept apart for the six normal classes
 *    (±X, ±Y, ±Z), of every cluster's one-sample contribution estimates and visibility (eq. 3),
 *    kept for every node on the path from the sampled light to its tree's root (each node's
 *    estimate is the sample divided by the light's probability within that node). Feedback
 *    weights C / sqrt(u) (eq. 4-5, ias_math.c) give the block and pixel PDFs, blended with the
 *    uniform PDF by the pass's weights (eq. 6, Fig. 2).
 *  - Samples per pass (§5.8). 1.5 N_C shadow rays per pixel (N_C: the pixel's area-weighted mean
 *    number of clusters per point), at least 50, given to the regions by area, clusters chosen
 *    stratified. A pixel within twice the target after a pass continues with the same PDFs in
 *    steps of 25 shadow rays.
 *  - Pass estimates (§4.2). Per pixel and pass the estimate of eq. 2 and the sample variance of
 *    its mean; passes combined by inverse variance (eq. 7-8); a pixel is done when
 *    s_p^2 / L_p^2 < threshold, a block when all its pixels are.
 *  - Termination (§5.9). At most max_passes passes (15); a pixel with no visible sample after 3
 *    passes and 250 shadow rays is black.
 *
 * What the paper leaves open, as done here: a pass's estimate is the area-weighted sum of its
 * regions' means and its variance that of a stratified estimate, sum w_k^2 s_k^2 / n_k; eq. 7-8
 * weights passes by the block's pooled relative variance of each pass rather than by the pixel's
 * own sample variance, which would bias the image dark (see combine_passes); the convergence test
 * uses the larger of the pixel's own variance and the one its block's relative variance predicts,
 * against termination bias; the 25-ray steps near the target are counted once from the variance
 * instead of testing after each step. Emitters seen directly are averaged over the eye rays and added to the
 * pixel (they count in L_p for the threshold test). Quasi-random numbers: one scrambled Sobol
 * sequence per block (as the reference integrator), eye ray dimensions 0-4, shadow ray dimensions
 * 5 (stratum jitter), 6 (light in cluster), 7-8 (point on the light); the default variant's 9
 * (member point) and, with ias-mis (off by default; ias_mis.h, mis_bsdf_sample), 10-12 (the
 * paired BSDF sample) and 13 (whether it is taken, ias-mis-share < 1).
 *
 * Two variants (issue 15; --ias-variant). `paper` is everything above, unchanged. `default`
 * departs where the bench (bench/ias/beyond.sh) showed the paper losing, each departure its own
 * option (registry.c) with its reason and measured effect where it is implemented:
 *  - ias-cut bvh (an option; the default cut is trees: the BVH cut was 2.2% dark on
 *    living-env-138-matte until balance_prior, and after it was slower at equal relMSE on three of
 *    four shared crops, docs/methods/ias.md): the clusters are a cut of the
 *    light BVH of at most ias-cut-size nodes
 *    (pn_light_bvh_cut), a node's light chosen by the BVH's importance descent, and the statistics
 *    kept in a hash table per worker (ias_table): cost per point O(cut size + tree depth) and
 *    memory following the shadow rays, not lights x pixels (compute_cut, ias_table);
 *  - ias-prior importance: c_U's PDF (all of pass 0's) is the BVH descent's own probability of
 *    each cut node instead of uniform, the tree, each distant light and each environment map
 *    taking equal shares as in pbrt-v4 (compute_cut, balance_prior, build_pdf_table);
 *  - ias-points members: shadow rays leave from the region's eye-ray points, not from its
 *    representative (push_point, group_points);
 *  - ias-pass-rays N: pass j takes max((j + 1) N, 1.5 N_C) shadow rays per pixel instead of
 *    max(1.5 N_C, 50): fewer where the cut is small, and N_C no longer grows with the emitters;
 *  - ias-cluster-numbers sobol: the cluster choice takes dimension 5's Sobol number itself (no
 *    stratum jitter; sample_pixel). Always with the BVH cut: its descent continues with the
 *    cluster's number rescaled within the node; with members, dimension 9 picks the point;
 *  - ias-aa-threshold T0 (issue 21; 0.01 by default since stop 16, 0 the paper's): below T0 a
 *    pixel takes aa_rays T0 / T eye rays, so that the antialiasing regions' error falls with T
 *    (ias_eye_rays); at T >= T0 nothing changes. relMSE slope against T 1.02 instead of 0.52 on
 *    tests/test_ias_converge.c's scene; at T = 0.001 on the bench crops relMSE 0.6-0.8x that of
 *    32 eye rays for 1.1-1.5x the CPU (docs/methods/ias.md). With --adaptive-rule cross (weights
 *    and stopping from the block's other pixels, pixel_estimate_cross) the mode is unbiased: the
 *    default test's eq. 7-8 weights include the pixel's own samples and bias the image by about
 *    -0.1% (-0.07% to -0.15% on the bench crops), a firefly suppression that cross's weights give
 *    up for 1.4-42x the relMSE at fixed passes (docs/adaptive-sampling.md, "ias");
 *  - ias-aa-power P (session 19; 1 by default, the 1 / T law above): below T0 the eye rays grow as
 *    (T0 / T)^P. Reason: on hall-many the eye rays' part of the error (E / n_eye, the glossy
 *    lobes' view dependence over the pixel; on hall-many-matte 32 -> 128 eye rays changes nothing)
 *    is 60% of relMSE at T = 0.01, and the CPU-optimal split there is n_eye ~ 0.28 n_shadow, which
 *    P = 0.5 with T0 = 0.1 approximates. Effect (bench crop, one thread): relMSE x CPU 0.0084 /
 *    0.0073 at T = 0.04 / 0.01 against 0.0097 / 0.0108 for P = 1, T0 = 0.01 (reference 64 spp
 *    0.0096). Not the default (stop 20, five bench crops at equal relMSE): 1.10-1.24x faster on
 *    hall-many and staircase-832, 0.77-0.89x on hall-many-matte, bathroom-72 and
 *    bathroom-72-matte, where 32 -> 102 eye rays lower relMSE only 4-11% (docs/methods/ias.md, "The
 *    eye-ray / shadow-ray balance as a default"); docs/methods/ias.md also gives the bound that
 *    puts the 3x goal out of reach on hall-many;
 *  - ias-prior-share S (off by default, 0): a defensive mixture, the prior keeping at least the
 *    weight S in every pass's PDF (build_pdf_table); measured in docs/methods/ias.md;
 *  - ias-prior importance with the trees cut (stop 16; ias_speed.c): c_U's PDF, all of pass 0's,
 *    follows each cluster's unoccluded irradiance at the region's point (a leaf's light as the
 *    reference's PDF computes it, far-field beyond 8 radii; a cluster from its power and bounding
 *    sphere), 5% kept uniform, instead of uniform over the ~47 clusters. Reason: on
 *    bathroom-72-matte the window, one cluster, lights most pixels near it; a uniform first pass
 *    samples it with probability 1/47, and pixels whose first pass missed it stopped at a twentieth
 *    of their value (ref 1.1, ias 0.05). Effect (128^2 central crop, T=0.01, one seed): relMSE
 *    away from emitters 0.0094 -> 0.0027 for 624 -> 686 shadow rays per pixel; --ias-prior
 *    uniform restores the paper's uniform PDF;
 *  - ias-emitter-rays 256 (stop 16; ias_speed.c): a pixel whose neighbours' eye rays (in its
 *    block, itself excluded) saw both emission and no emission takes 256 eye rays in all for what
 *    it sees directly, no shadow rays. Reason: with the paper's 32 eye rays the pixels along
 *    bathroom-72's emitter strips were 1/32 of an emitter of luminance 59 or nothing, 66% of the
 *    crop's relMSE in 111 of its 16384 pixels, at every threshold. Effect: that part 0.018 ->
 *    0.0012 (T=0.01, one seed), whole crop 0.0276 -> 0.0039 with the prior. The decision reads only
 *    the neighbours' rays, not the pixel's own (deciding on its own first 32 rays would bias it: a
 *    pixel that happened to miss the emitter would keep 0); the neighbours' rays come from the same
 *    scrambled block sequence, so it is independent only up to that sequence's correlation
 *    (test_ias_speed: the emitter's pixels at 1.0006 of a 1024-spp reference). A sub-pixel
 *    emitter with no neighbour seeing it is not helped; 0 switches it off;
 *  - ias-env-floor F (stop 17; 2 by default, 0 the paper's; trees cut only): in every pass an
 *    environment region keeps at least F times its pass-0 probability (c_U's PDF alone, the
 *    irradiance prior), renormalised (build_pdf). Reason: behind a mostly closed room the feedback
 *    gives the regions seen through a window almost nothing (late passes' c_U is 0.05-0.1, spread
 *    over a cut of some 350 clusters), so their rare visible samples carry weights 1/p in the
 *    thousands; eq. 7-8's weights, which include the pixel's own samples, and the own-variance
 *    stopping test suppress those passes and pixels, a firefly suppressor biased dark:
 *    living-env-138-matte -0.132% at T = 0.001 (8 seeds, crop 0.45-0.55, 2048-spp reference),
 *    tests/test_ias_bvh_prior.c's closed room -2.2%. Effect: -0.044% (F = 1), -0.029% +- 0.003%
 *    (F = 2) on living-env-138, relMSE 4.8e-4 -> 3.2e-4, for 1.76x the CPU at F = 2 (more passes:
 *    the stopping test now sees the variance that floor 0 hid); the closed room -0.28%; scenes
 *    without an environment map are unchanged bit for bit. With --adaptive-rule cross the floor
 *    also makes the unbiased test cheap there (living-env-138 at F = 2: relMSE 1.2e-3 -> 4.1e-4,
 *    +0.010% +- 0.004%; docs/adaptive-sampling.md);
 *  - ias-ratio off|pixel|cluster|control (stop 17; off by default, measured not to pay; ias_ratio.c,
 *    ratio_closed_forms, control_betas, store_pass): Heitz, Hill and McGuire 2018's ratio
 *    estimator. Where a cut entry's unshadowed irradiance has a closed form (point, spot, distant,
 *    triangle, rectangle lights, spheres above the horizon, clusters of at most ias-ratio-members
 *    lights), a pass takes sum_k W_k sum_e beta_e m_k E_k,e plus the residuals v - beta u of the
 *    same samples (u: the sample unshadowed with the diffuse part kd / pi), beta one ratio per
 *    pixel, one per cluster, or the block's learned visible fraction fixed before the pass (a
 *    control variate: unbiased); its variance, for eq. 7-8 and the test, is that of the residuals.
 *    Reason: on open scenes it removes the variance of sampling the lights' areas and choosing among
 *    them, which no PDF removes. Effect: on test_ias_ratio's two quads over a plane relMSE of the
 *    unoccluded pixels 1.15e-5 -> 3.7e-6 at equal shadow rays; on hall-many's central crop every
 *    mode is slower at equal relMSE (control by 20-30%, pixel by 65%; the light there is 30%
 *    occluded, the noise left is which lights are visible, and the floor is glossy); on
 *    bathroom-72-matte's control is 1.18-1.25x faster, pixel 2.6x slower; cluster is 0.25% dark
 *    after one pass on hall-many (pixel and control within noise; docs/methods/ias.md);
 *  - ias-light-guide on (stop 20; ias_guide.c, hooks: ias_prepare, the scratch, the block start and
 *    each pass start in ias_render_batch, and in sample_pixel the warp of (u1, u2) before the light
 *    is sampled and the record after the sample's value): rectangle and triangle lights of at least
 *    2% of the emitting area are sampled through a per-block 8 x 8 grid over their sample square
 *    whose cells follow the contribution the block's earlier passes found there, 20% kept uniform;
 *    the pdf carries the grid's density, so the estimate stays unbiased. Reason: on
 *    bathroom-72-matte choosing each light by its exactly known visible contribution (an oracle)
 *    lowers reference's relMSE only 1.75x at 16 shadow rays per pixel, sampling only the visible
 *    part of the chosen light 10.7x: the variance left is the window seen through the blinds, within
 *    one light, which no cluster PDF reaches. Effect (bench crop, one thread, beyond.sh, CPU at
 *    equal relMSE): bathroom-72-matte ias 6.2 -> 3.76 s at relMSE 0.0027 against 0.0025 (fixed 4
 *    passes: relMSE 0.0049 -> 0.0022 for the same shadow rays), bathroom-72 8.5 -> 4.9 s,
 *    bathroom-72-matte at T = 0.0025 1.6x; hall-many and hall-many-matte within 4%; scenes without
 *    such lights (staircase-832, living-env-138, the generated ones) unchanged bit for bit.
 *  - ias-guide-rotate on (stop 20; ias_guide.c pn_ias_guide_set_rotation, set before each pixel's
 *    pass in ias_render_batch): the numbers a guide grid warps are first rotated (mod 1) by a shift
 *    hashed from the seed, the block's scramble, the pixel and the pass. Reason: a block's numbers
 *    are one Sobol sequence, so a pixel's points depend on the earlier points that built the grid,
 *    and the grid's density is then not independent of where they fall: on tests/test_ias_guide.c's
 *    screened light the guide at 2 passes measured 0.99906 +- 0.00030 of the reference without the
 *    rotation, 0.99991 +- 0.00037 with it (512 seeds; rebuilding the grid within a pass,
 *    ias-guide-refresh, 1.0% bright without it). Effect: variance unchanged (test scene 0.000240 ->
 *    0.000244; bathroom-72-matte fixed 2 / 4 passes relMSE within the seeds' noise); CPU at equal
 *    relMSE in docs/methods/ias.md, "The light guide's gap to the oracles".
 *  - ias-stats cut (session 20; issue 15, light count; cut_record): with the hash-table statistics
 *    (sparse_stats, from PN_IAS_DENSE_IDS cluster ids) a sample is added only to the nodes of the
 *    block's cuts whose light range holds its light, each with the sample over the light's
 *    probability within the node, instead of at its leaf with every node above it aggregated
 *    (sparse_add, sparse_aggregate). The statistics are only ever read at cut nodes, so these are
 *    the same sums, but as power(node) / power(light) rather than the product of the ratios of
 *    the chain of children: equal up to rounding, not bit for bit by construction (the paper
 *    variant keeps the tree statistics). Reason: at 10^6 emitters the chain below the cut was some
 *    ten new hash-table entries per sample, the largest part of the render after the shadow rays
 *    (sparse_aggregate and replay_log 23% of the process's CPU). Effect (bench/ias/scaling.sh,
 *    docs/methods/ias.md "Light count, session 20"): render CPU per eye ray at 10^5 emitters
 *    54 -> 33 us, at 10^6 118 -> 54 us, peak memory at 10^6 948 -> 768 MB; the images came out
 *    bit for bit the tree statistics' on every scene tried (the generated 10^5 and 10^6
 *    emitters, tests/test_ias_scale.c's unequal emitters); --ias-stats tree restores them.
 *
 * Not a departure (the images are the same bit for bit, both variants): with the trees cut and at
 * least PN_IAS_DENSE_IDS cluster ids (ias_speed.h; some 30,000 emitters) the block's and the
 * pixels' statistics live in hash tables instead of arrays over all ids (sparse_stats, see
 * sparse_add): the arrays were aggregated and cleared in full per pass and pixel pass, O(lights)
 * per pixel. At 10^6 emitters (bench/ias/scaling.sh) process CPU 115 -> 23 s, render time per
 * eye ray 12x less, peak memory 3.77 GB -> 0.93 GB; the work per shadow ray grows with the depth
 * below the cut, not with N (tests/test_ias_scale.c). Nor are (session 20) pn_cluster_pick's search
 * by groups of 16 running sums and the tree build's compact k-d leaf lists (lights/cluster_tree.c):
 * the same lights and trees, fewer cache misses. Nor is ias's upkeep of stop 21 (docs/methods/ias.md,
 * "ias's upkeep, stop 21"; both variants): the trees cuts of a pixel's nearby regions share one
 * walk (pn_cluster_cut_record / _replay: a decision is reused only where it holds for every point
 * of the regions' ball, so the cuts are the same bit for bit), the PDF's entry is found through a
 * guide table (choose_guided), the Sobol seeds are hashed once per call of sample_pixel and the
 * scrambled points take one bit reversal (pn_sobol_samples), the statistics a sample is added to
 * are prefetched, aggregate_stats reads a compact post-order array, and the stats' timers read
 * the clock for every IAS_TIMING_STRIDE-th sample and IAS_REGION_TIMING_STRIDE-th region.
 *
 * Option, not the default: ias-cut-max K (session 20; compute_cut, pn_cluster_cut_capped) caps a
 * point's trees cut at K clusters, refined largest solid angle first, so that N_C and the passes
 * stop growing with the emitters; measured in docs/methods/ias.md, "Light count, session 20".
 * Nor ias-cluster-pick importance / large (session 20; sample_pixel's pick, mis_bsdf_sample's
 * pdf): a cluster's light by an importance descent at the shading point
 * (pn_cluster_pick_importance) instead of by power; the sample is weighted by the descent's own
 * probability (unbiased), the feedback statistics keep dividing by power ratios (a heuristic
 * estimate per node already). It halves a capped cut's relMSE at 10^3 emitters but not at 10^6
 * (visibility within the clusters, which no unoccluded bound sees), and costs CPU on the shared
 * scenes for no gain: docs/methods/ias.md, "A light pick by importance within a cluster". */
#include "integrators/integrator.h"

#include "core/clock.h"
#include "core/photometry.h"
#include "core/rng.h"
#include "core/sobol.h"
#include "integrators/ias_math.h"
#include "integrators/ias_mis.h"
#include "integrators/ias_guide.h"
#include "integrators/ias_ratio.h"
#include "integrators/ias_speed.h"
#include "lights/cluster_tree.h"
#include "lights/env_regions.h"
#include "lights/light_bvh.h"
#include "shade/bsdf.h"

#include <stdatomic.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#define IAS_MAX_PIXELS 64 /* the smallest pixel capacity of a worker's scratch (8x8) */
#define IAS_CLASSES 6
#define IAS_MIN_SAMPLES 50
#define IAS_STEP_SAMPLES 25
#define IAS_MAX_STEPS 40
#define IAS_BLACK_PASSES 3
#define IAS_BLACK_RAYS 250
#define IAS_MAX_PASSES_STORED 64
/* The region radius in pixels. The paper's "one-quarter of the pixel radius" is read as a quarter
 * of the pixel's width, measured on the image plane: a pixel without edges then gets at least four
 * regions, as §4.4.1 says, and about eight from 32 rays (Table 4 reports about ten with edges).
 * Measured in world space instead, pixels seen at grazing angles split into 20 or more. */
#define IAS_REGION_RADIUS 0.25f

/* ---- what the whole render shares -------------------------------------------------------- */

typedef struct ias_shared {
    pn_cluster_forest forest;
    int env_count;
    pn_env_regions *env; /* one partition per environment light */
    int *env_light;      /* the pn_lights index of each environment light */
    int *env_base;       /* first cluster id of each partition */
    int id_count;        /* cluster ids: forest nodes (distant lights are one-light nodes), then
                             environment regions */
    int max_cut;         /* capacity for one point's cut */
    /* Table 5: which lights (indices 0 .. light_count) and environment regions (then, by id
     * offset) were seen unoccluded anywhere in the image; bytes set by any thread. */
    int light_count, visible_slots;
    atomic_uchar *seen;
    double clock_cost;     /* what one timed interval adds by itself (two clock reads), subtracted */
    struct ias_post *post; /* the trees' interior nodes, every node after its children (aggregate_stats) */
    int post_count;
    int light_ids; /* ids below this are clusters of lights (forest nodes; or BVH nodes, then
                      distant lights), above are environment regions */
    /* The default variant (issue 15; see the header): which departures are on. */
    bool bvh_cut;          /* cut of the light BVH by importance instead of the cluster trees */
    bool importance_prior; /* c_U's PDF by the cut's importance instead of uniform */
    bool member_points;    /* shadow rays from the region's eye-ray points, not its representative */
    bool sobol_direct;     /* the cluster choice takes its Sobol number as it is (no stratum jitter) */
    unsigned pass_rays;    /* pass j takes (j + 1) pass_rays shadow rays; 0: the paper's §5.8 */
    uint32_t aa_rays;      /* eye rays per pixel (ias_eye_rays) */
    double prior_share;    /* the least weight c_U's PDF keeps in eq. 6 (build_pdf_table); 0: Fig. 2's */
    double env_floor;      /* trees cut: an environment region keeps this times its pass-0 probability */
    int cut_size;
    int cut_max;          /* trees cut: most clusters per point (pn_cluster_cut_capped); 0: no cap */
    bool importance_pick; /* trees cut: a cluster's light by importance at the point (pn_cluster_pick_importance) */
    float pick_limit;     /* its descent stops below this solid angle (ias-cluster-pick large); 0: at the leaf */
    pn_light_bvh bvh;
    int *distant; /* with bvh_cut: the distant lights, ids bvh.node_count + k */
    int distant_count;
    bool irradiance_prior;    /* trees cut: c_U's PDF by each cluster's unoccluded irradiance (ias_speed.h) */
    uint32_t emitter_rays;    /* eye rays for the emitted term next to emitter edges; 0: aa_rays only */
    int ratio;                /* PN_IAS_RATIO_*: the ratio estimator (ias_ratio.h); 0: off */
    int ratio_members;        /* largest cluster given its closed form */
    bool sparse_stats;        /* trees cut: statistics in hash tables, not dense arrays (sparse_add) */
    bool cut_stats;           /* sparse_stats, default variant: statistics of the block's cut nodes only
                                 (ias-stats cut; cut_record) */
    struct ias_tnode *tnodes; /* sparse_stats: the forest's links and power ratios, compact */
    int mis;                  /* PN_IAS_MIS_*: BSDF samples paired with the light samples (ias_mis.h) */
    pn_ias_mis_map mis_map;   /* mis: emitting surfaces -> lights */
    double mis_share;         /* mis: the expected BSDF rays per light sample, in (0, 1] */
    bool light_guide;         /* ias-light-guide: grids over large lights' sample squares (ias_guide.h) */
    pn_ias_guide_lights guide;
    unsigned guide_refresh; /* ias-guide-refresh: first-pass pixels between grid rebuilds; 0: none */
    bool guide_rotate;      /* ias-guide-rotate (always with ias-guide-refresh): pn_ias_guide_set_rotation */
} ias_shared;

/* A cluster node as sparse_add and sparse_aggregate read it (32 bytes instead of the node's 140):
 * ra, rb are aggregate_stats' factors power(node) / power(child), 1 for a child without power. */
typedef struct ias_tnode {
    int left, right, parent, pad;
    double ra, rb;
} ias_tnode;

/* An interior node as aggregate_stats reads it, in post order (32 bytes instead of three nodes'
 * 140 each): its children and their factors power(node) / power(child), 1 for a child without
 * power, the same doubles aggregate_stats computed per node and pass. */
typedef struct ias_post {
    int node, left, right, pad;
    double ra, rb;
} ias_post;

/* The smallest of many empty intervals: the cost a timed interval carries for its own clock
 * reads, which the sampled timings (scaled by IAS_TIMING_STRIDE) would otherwise multiply. */
static double measure_clock_cost(void) {
    double best = INFINITY;
    for (int i = 0; i < 200; i++) {
        double a = pn_clock_seconds(), b = pn_clock_seconds();
        if (b - a < best) best = b - a;
    }
    return isfinite(best) && best > 0.0 ? best : 0.0;
}

/* A timed interval [t0, now] without the clock's own cost. */
static double elapsed_since(const ias_shared *sh, double t0) {
    double d = pn_clock_seconds() - t0 - sh->clock_cost;
    return d > 0.0 ? d : 0.0;
}

static void ias_release(pn_render_job *job) {
    ias_shared *sh = job->integrator_data;
    if (!sh) return;
    pn_cluster_forest_free(&sh->forest);
    for (int i = 0; i < sh->env_count; i++) pn_env_regions_free(&sh->env[i]);
    free(sh->env);
    free(sh->env_light);
    free(sh->env_base);
    free(sh->seen);
    free(sh->post);
    pn_light_bvh_free(&sh->bvh);
    free(sh->distant);
    free(sh->tnodes);
    pn_ias_mis_map_free(&sh->mis_map);
    pn_ias_guide_lights_free(&sh->guide);
    free(sh);
    job->integrator_data = NULL;
}

/* The interior nodes of the cluster trees in an order that puts every node after its two
 * children (iterative depth-first walks), as aggregate_stats reads them (ias_post). */
static bool build_post_order(ias_shared *sh) {
    const pn_cluster_forest *f = &sh->forest;
    sh->post = malloc((size_t)(f->node_count > 0 ? f->node_count : 1) * sizeof *sh->post);
    int *stack = malloc((size_t)(f->node_count > 0 ? f->node_count : 1) * sizeof *stack);
    unsigned char *expanded = calloc((size_t)(f->node_count > 0 ? f->node_count : 1), 1);
    if (!sh->post || !stack || !expanded) {
        free(stack);
        free(expanded);
        return false;
    }
    sh->post_count = 0;
    for (int t = 0; t < PN_TREE_COUNT; t++) {
        if (f->roots[t] < 0) continue;
        int top = 0;
        stack[top++] = f->roots[t];
        while (top > 0) {
            int m = stack[top - 1];
            const pn_cluster_node *nd = &f->nodes[m];
            if (nd->left < 0) {
                top--;
                continue;
            }
            if (!expanded[m]) {
                /* At most one entry per node is on the stack: a tree has node_count nodes. */
                expanded[m] = 1;
                stack[top++] = nd->right;
                stack[top++] = nd->left;
                continue;
            }
            top--;
            const double pm = (double)nd->power, pa = (double)f->nodes[nd->left].power,
                         pb = (double)f->nodes[nd->right].power;
            sh->post[sh->post_count++] =
                (ias_post){m, nd->left, nd->right, 0, pa > 0.0 ? pm / pa : 1.0, pb > 0.0 ? pm / pb : 1.0};
        }
    }
    free(stack);
    free(expanded);
    return true;
}

/* Eye rays per pixel. The paper's aa_rays (32) are shot once and fixed, so the error of the
 * antialiasing regions (which eye-ray points a pixel's light is averaged over) is the same at
 * every threshold and no number of shadow rays removes it: on tests/test_ias.c's scene at 64x48,
 * relMSE 8.6e-5, 4.8e-5, 2.7e-5 at thresholds 0.01, 0.0025, 0.000625 (slope 0.41 against T).
 * With ias-aa-threshold T0 > 0 (default variant only; off by default) a pixel takes aa_rays T0 / T
 * eye rays below T0, so that the regions' share of the error falls as T does (the same thresholds
 * with 32, 128, 512 eye rays: 8.6e-5, 3.8e-5, 9.3e-6, slope 0.80; tests/test_ias_converge.c). */
static uint32_t ias_eye_rays(const pn_render_job *job, bool paper) {
    double t0 = paper ? 0.0 : job->ias_aa_threshold, n = (double)job->aa_rays;
    if (t0 > 0.0 && job->threshold > 0.0 && job->threshold < t0)
        n = ceil(job->ias_aa_power == 1.0 ? n * t0 / job->threshold : n * pow(t0 / job->threshold, job->ias_aa_power));
    return (uint32_t)fmin(n, 4096.0); /* aa-rays' own largest value */
}

/* The trees cut keeps its statistics in hash tables (sparse_stats) from this many cluster ids on;
 * below, in dense arrays, which are faster there. Either way the images are the same. */
static int dense_limit = PN_IAS_DENSE_IDS;

void pn_ias_set_dense_limit(int ids) {
    dense_limit = ids > 0 ? ids : PN_IAS_DENSE_IDS;
}

/* pn_ias_stats_work's counter: statistics entries walked, set or cleared (see ias_speed.h). */
static _Atomic uint64_t stats_work;

static void add_work(uint64_t n) {
    atomic_fetch_add_explicit(&stats_work, n, memory_order_relaxed);
}

uint64_t pn_ias_stats_work(void) {
    return atomic_load_explicit(&stats_work, memory_order_relaxed);
}

static pn_status ias_prepare(pn_render_job *job, pn_err *err) {
    ias_shared *sh = calloc(1, sizeof *sh);
    if (!sh) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    job->integrator_data = sh;
    sh->clock_cost = measure_clock_cost();
    const pn_lights *L = job->lights;
    const bool paper = job->ias_variant == PN_IAS_VARIANT_PAPER;
    sh->bvh_cut = !paper && job->ias_cut == PN_IAS_CUT_BVH;
    sh->importance_prior = sh->bvh_cut && job->ias_prior == PN_IAS_PRIOR_IMPORTANCE;
    sh->pass_rays = paper ? 0u : job->ias_pass_rays;
    sh->member_points = !paper && job->ias_points == PN_IAS_POINTS_MEMBERS;
    sh->sobol_direct = !paper && job->ias_cluster_numbers == PN_IAS_NUMBERS_SOBOL;
    sh->cut_size = job->ias_cut_size > 0 ? (int)job->ias_cut_size : 1;
    sh->cut_max = paper || sh->bvh_cut ? 0 : (int)job->ias_cut_max;
    sh->importance_pick = !paper && !sh->bvh_cut && job->ias_cluster_pick != PN_IAS_PICK_POWER;
    sh->pick_limit = job->ias_cluster_pick == PN_IAS_PICK_LARGE ? job->cluster_solid_angle : 0.0f;
    sh->aa_rays = ias_eye_rays(job, paper);
    sh->prior_share = sh->bvh_cut ? job->ias_prior_share : 0.0;
    sh->irradiance_prior = !paper && !sh->bvh_cut && job->ias_prior == PN_IAS_PRIOR_IMPORTANCE;
    sh->emitter_rays = paper ? 0u : job->ias_edge_rays;
    sh->env_floor = paper || sh->bvh_cut ? 0.0 : job->ias_env_floor;
    /* The ratio estimator needs the trees cut's ids and RGB samples (spectral samples are not). */
    sh->ratio = !paper && !sh->bvh_cut && !job->spectral ? job->ias_ratio : PN_IAS_RATIO_OFF;
    sh->ratio_members = job->ias_ratio_members > 0 ? (int)job->ias_ratio_members : 1;
    /* MIS needs the trees cut's ids (a light's cut entry by its ancestors) and RGB samples, and
     * does not combine with the ratio estimator's residuals. */
    sh->mis = !paper && !sh->bvh_cut && !job->spectral && sh->ratio == PN_IAS_RATIO_OFF ? job->ias_mis : PN_IAS_MIS_OFF;
    sh->mis_share = job->ias_mis_share > 0.0 && job->ias_mis_share < 1.0 ? job->ias_mis_share : 1.0;
    /* The guide warps a light's sample square, and the BSDF strategy's weight (mis_bsdf_sample)
     * would need the grid's density of a direction, which has no inverse here: with ias-mis on,
     * the guide is off, so that the two strategies' weights still sum to one. */
    if (!paper && job->ias_light_guide && sh->mis == PN_IAS_MIS_OFF) {
        if (!pn_ias_guide_lights_init(&sh->guide, L, PN_IAS_GUIDE_SIDE, PN_IAS_GUIDE_MIX)) {
            ias_release(job);
            return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        }
        sh->light_guide = sh->guide.count > 0;
        sh->guide_refresh = sh->light_guide ? job->ias_guide_refresh : 0u;
        sh->guide_rotate = sh->light_guide && (job->ias_guide_rotate || sh->guide_refresh);
    }
    pn_status st;
    int next;
    if (sh->bvh_cut) {
        for (int t = 0; t < PN_TREE_COUNT; t++) sh->forest.roots[t] = -1;
        st = pn_light_bvh_build(L, &sh->bvh, err);
        sh->distant = malloc((size_t)(L->count > 0 ? L->count : 1) * sizeof *sh->distant);
        if (st == PN_OK && !sh->distant) st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        for (int i = 0; st == PN_OK && i < L->count; i++)
            if (L->lights[i].kind == PN_LIGHT_DISTANT && v3_luminance(L->lights[i].emit) > 0.0f)
                sh->distant[sh->distant_count++] = i;
        next = sh->bvh.node_count + sh->distant_count;
    } else {
        st = pn_cluster_forest_build(L, &sh->forest, err);
        next = sh->forest.node_count;
    }
    if (st != PN_OK) {
        ias_release(job);
        return st;
    }
    sh->light_ids = next;
    for (int i = 0; i < L->count; i++)
        if (L->lights[i].kind == PN_LIGHT_ENVIRONMENT) sh->env_count++;
    if (sh->env_count) {
        sh->env = calloc((size_t)sh->env_count, sizeof *sh->env);
        sh->env_light = calloc((size_t)sh->env_count, sizeof *sh->env_light);
        sh->env_base = calloc((size_t)sh->env_count, sizeof *sh->env_base);
        if (!sh->env || !sh->env_light || !sh->env_base) {
            ias_release(job);
            return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        }
        int k = 0;
        for (int i = 0; i < L->count && st == PN_OK; i++) {
            if (L->lights[i].kind != PN_LIGHT_ENVIRONMENT) continue;
            sh->env_light[k] = i;
            st = pn_env_regions_build(&L->envs[L->lights[i].env], (int)job->env_regions, &sh->env[k], err);
            sh->env_base[k] = next;
            if (st == PN_OK) next += sh->env[k].count;
            k++;
        }
        if (st != PN_OK) {
            ias_release(job);
            return st;
        }
    }
    sh->id_count = next;
    sh->sparse_stats = !sh->bvh_cut && next >= dense_limit;
    sh->cut_stats = sh->sparse_stats && !paper && job->ias_stats == PN_IAS_STATS_CUT;
    if (sh->sparse_stats) {
        const pn_cluster_forest *f = &sh->forest;
        sh->tnodes = malloc((size_t)(f->node_count > 0 ? f->node_count : 1) * sizeof *sh->tnodes);
        if (!sh->tnodes) {
            ias_release(job);
            return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        }
        for (int m = 0; m < f->node_count; m++) {
            const pn_cluster_node *nd = &f->nodes[m];
            ias_tnode *t = &sh->tnodes[m];
            *t = (ias_tnode){nd->left, nd->right, nd->parent, 0, 1.0, 1.0};
            if (nd->left < 0) continue;
            double pm = (double)nd->power, pa = (double)f->nodes[nd->left].power,
                   pb = (double)f->nodes[nd->right].power;
            t->ra = pa > 0.0 ? pm / pa : 1.0;
            t->rb = pb > 0.0 ? pm / pb : 1.0;
        }
    }
    sh->max_cut = next > 0 ? next : 1;
    if (sh->bvh_cut) sh->max_cut = sh->cut_size + (next - sh->bvh.node_count);
    sh->light_count = L->count;
    sh->visible_slots = L->count + (next - sh->light_ids);
    sh->seen = calloc((size_t)sh->visible_slots + 1, sizeof *sh->seen);
    if (!sh->seen || (!sh->bvh_cut && !build_post_order(sh))) {
        ias_release(job);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    if (sh->mis && (st = pn_ias_mis_map_build(job, &sh->mis_map, err)) != PN_OK) {
        ias_release(job);
        return st;
    }
    return PN_OK;
}

/* ---- per worker ---------------------------------------------------------------------------- */

typedef struct ias_region {
    int pixel; /* index in the batch */
    pn_hit hit;
    vec3 wo, throughput, origin;
    float eps, radius;
    float raster_x, raster_y; /* where the representative eye ray crossed the image */
    pn_bsdf bsdf;
    int cls;                  /* normal class */
    double weight;            /* its share of the pixel's eye rays (summed filter weights) */
    int cut_first, cut_count; /* ids in scratch->cut */
    /* This pass's samples of the region: sums of the luminance and RGB of v / (P(cluster)
     * P(light)), of the squared luminance, and their number. */
    double sum, sum2;
    vec3 rgb;
    unsigned n;
    /* The default variant's member points (scratch->points[point_first ..], point_count of
     * them; 0: shadow rays leave from the representative point), visited in turn. */
    int point_first, point_count;
    /* PN_AOV_ILLUMINANCE: the sum over every pass's samples of Y(L) cos / pdf / (P(cluster)
     * P(light)) (a white receiver; lux) and their number; each is unbiased whatever its pass's
     * PDF, so they are pooled with equal weights. */
    double lux_sum;
    unsigned lux_n;
    double mel_sum;        /* PN_AOV_MELANOPIC_EDI: the same with the melanopic EDI (lux_n of them) */
    vec3 ratio_m;          /* ias-ratio: the mean over its points of share x throughput x kd / pi */
    bool cut_done, member; /* shared trees cuts (ias_render_batch): cut; replays its leader's walk */
    bool dup;              /* a member whose class and clusters are its leader's (compute_cut) */
} ias_region;

/* An eye ray's own shading point in its antialiasing region (members_points). */
typedef struct ias_point {
    vec3 origin, wo, throughput;
    float eps;
    float share; /* its filter weight over the region's mean filter weight */
    int region;  /* index in scratch->regions while the pixel's rays are gathered */
    pn_bsdf bsdf;
} ias_point;

typedef struct ias_pass {
    double lum, s2; /* luminance estimate and the variance of that estimate */
    vec3 rgb;
    unsigned n;
} ias_pass;

typedef struct ias_pixel {
    int first_region, region_count;
    vec3 emitted;      /* filter-weighted mean of what the eye rays saw directly */
    double weight_sum; /* filter weights of all eye rays */
    ias_pass passes[IAS_MAX_PASSES_STORED];
    int pass_count;
    uint32_t shadow_rays, visible;
    bool done;
    vec3 result;
    double clusters;                  /* N_C: clusters per point, weighted by region area */
    double region_weight;             /* sum of the regions' weights (the share of rays that hit a surface) */
    double embree_seconds;            /* sampled estimate of the time inside Embree */
    double cut_seconds;               /* time computing the cluster cuts of its regions */
    double pdf_seconds;               /* time keeping PDFs: feedback weights, eq. 6, choosing clusters and
                              lights, recording samples (the per-sample part sampled) */
    uint32_t visible_lights;          /* distinct lights / environment regions seen unoccluded */
    uint32_t emit_hits;               /* eye rays that saw emission (ias-emitter-rays) */
    unsigned classes;                 /* sparse_stats: bit c set when the pixel sampled class c */
    pn_ias_stats *stats[IAS_CLASSES]; /* pixel statistics per normal class, or NULL */
} ias_pixel;

/* ---- the default variant's statistics: one hash table per worker --------------------------
 *
 * The paper's statistics are arrays over all cluster ids per block and per pixel and class, which
 * grow as lights x pixels (487 MB at 10^5 emitters, issue 15). The default variant keeps only the
 * entries its samples touched, in an open-addressing table keyed by (pixel or block, normal class,
 * cluster id), cleared when the block ends: its size follows the block's shadow rays, not the
 * number of lights. The class IAS_SEEN_CLASS marks the lights a pixel saw unoccluded (Table 5). */
#define IAS_SEEN_CLASS 7u

typedef struct ias_entry {
    uint64_t key; /* 0: empty */
    pn_ias_stats st;
    double snap;    /* sparse trees statistics: the block's feedback weight when its pass began */
    unsigned dirty; /* sparse trees statistics: set since the last aggregation (sparse_add) */
} ias_entry;

typedef struct ias_table {
    ias_entry *e;
    uint32_t cap, used; /* cap a power of two */
    uint64_t *tops;     /* sparse trees statistics: keys of dirty entries without a parent */
    int top_count, top_cap;
} ias_table;

/* pixel -1: the block's entry. */
static uint64_t table_key(int pixel, unsigned cls, int id) {
    return ((uint64_t)(uint32_t)(pixel + 2) << 40) | ((uint64_t)cls << 36) | (uint64_t)(uint32_t)id;
}

static uint32_t table_slot(uint64_t key, uint32_t cap) {
    /* Fibonacci hashing: the slots only place entries, nothing computed depends on them. */
    uint64_t h = (key ^ (key >> 29)) * UINT64_C(0x9e3779b97f4a7c15);
    return (uint32_t)((h ^ (h >> 32)) & (uint64_t)(cap - 1u));
}

static bool table_grow(ias_table *t) {
    uint32_t cap = t->cap ? t->cap * 2u : 1024u;
    ias_entry *e = calloc(cap, sizeof *e);
    if (!e) return false;
    for (uint32_t i = 0; i < t->cap; i++) {
        if (!t->e[i].key) continue;
        uint32_t k = table_slot(t->e[i].key, cap);
        while (e[k].key) k = (k + 1u) & (cap - 1u);
        e[k] = t->e[i];
    }
    free(t->e);
    t->e = e;
    t->cap = cap;
    return true;
}

/* The entry of `key`; created (zero) when `create` (then *created says whether it is new), else
 * NULL when absent (or out of memory). */
static ias_entry *table_entry(ias_table *t, uint64_t key, bool create, bool *created) {
    if (created) *created = false;
    if (create && 2u * (t->used + 1u) > t->cap && !table_grow(t)) return NULL;
    if (!t->cap) return NULL;
    uint32_t k = table_slot(key, t->cap);
    while (t->e[k].key) {
        if (t->e[k].key == key) return &t->e[k];
        k = (k + 1u) & (t->cap - 1u);
    }
    if (!create) return NULL;
    t->e[k].key = key;
    t->used++;
    if (created) *created = true;
    return &t->e[k];
}

static pn_ias_stats *table_get(ias_table *t, uint64_t key, bool create) {
    ias_entry *e = table_entry(t, key, create, NULL);
    return e ? &e->st : NULL;
}

/* Room for element `count` of *array (capacity *cap): the capacity doubles, from `first`;
 * false (array unchanged) when out of memory. */
static bool room_for_one(void **array, int *cap, int count, int first, size_t elem) {
    if (count < *cap) return true;
    int n = *cap ? 2 * *cap : first;
    void *p = realloc(*array, (size_t)n * elem);
    if (!p) return false;
    *array = p;
    *cap = n;
    return true;
}

static void table_clear(ias_table *t) {
    if (t->used) memset(t->e, 0, (size_t)t->cap * sizeof *t->e);
    t->used = 0;
    t->top_count = 0;
}

/* Samples of the trees cut with sparse_stats, in the order they were taken, until they are added
 * to a table (replay_log): a pixel's only when its next pass needs its feedback weights. */
typedef struct ias_log_rec {
    int id;
    unsigned cls, visible;
    double value;
} ias_log_rec;

typedef struct ias_log {
    ias_log_rec *r;
    int count, cap, done; /* r[done .. count) are not in the table yet */
} ias_log;

/* A light evaluation of the current pixel pass, added to the table when the pass ends so that the
 * pixel's PDFs stay fixed during its pass (as the paper's are). */
typedef struct ias_pending {
    int id;
    int cls;
    double value;
    bool visible;
} ias_pending;

typedef struct ias_range {
    int first, end, r;
} ias_range;

/* A map from cluster ids to small numbers, emptied in O(1): slot[id] holds where stamp[id] == now.
 * Used for a block's cut members (ias-stats cut) and a region's cut entries (ias-mis). */
typedef struct ias_idmap {
    uint32_t *stamp, now;
    int *slot;
    size_t size;
} ias_idmap;

static bool idmap_init(ias_idmap *m, size_t size) {
    m->size = size > 0 ? size : 1;
    m->now = 0;
    m->stamp = calloc(m->size, sizeof *m->stamp);
    m->slot = malloc(m->size * sizeof *m->slot);
    return m->stamp && m->slot;
}

static void idmap_free(ias_idmap *m) {
    free(m->stamp);
    free(m->slot);
}

static void idmap_clear(ias_idmap *m) {
    if (++m->now == 0) {
        memset(m->stamp, 0, m->size * sizeof *m->stamp);
        m->now = 1;
    }
}

static void idmap_put(ias_idmap *m, int id, int v) {
    m->stamp[id] = m->now;
    m->slot[id] = v;
}

/* id's number, -1 when it has none. */
static int idmap_get(const ias_idmap *m, int id) {
    return m->stamp[id] == m->now ? m->slot[id] : -1;
}

typedef struct ias_scratch {
    int id_count;
    ias_region *regions;
    int region_cap, region_count;
    int *cut;
    int cut_cap, cut_used;
    void *cut_work;            /* pn_cluster_cut_capped's heap */
    pn_ias_stats *block_stats; /* IAS_CLASSES x id_count */
    bool block_class_used[IAS_CLASSES];
    int max_pixels;           /* pixels a batch may hold: at least 64, block_size^2 */
    pn_ias_stats *pixel_pool; /* max_pixels * IAS_CLASSES slots of id_count */
    int pool_used;
    ias_pixel *pixels; /* max_pixels */
    int pixel_count;
    unsigned char *pixel_seen; /* max_pixels x visible_slots flags (Table 5) */
    int visible_slots;
    unsigned *n_of; /* samples per region of one pixel (aa_rays entries) */
    double *pdf;    /* per cut entry */
    double *cdf;
    double *fpix;
    int *pick_guide; /* per cut entry: choose_guided's table for the PDF in s->cdf (guide_ok) */
    bool guide_ok;
    /* Feedback weights F = C / sqrt(u) (eq. 4) computed once instead of per region and pass:
     * the block's for every cluster of every class at the start of each pass (from the previous
     * passes' data, as §4.1 says), the current pixel's for the clusters of its regions' cuts at
     * the start of its pass (kept for the 25-ray steps, which continue "with the current PDFs"). */
    double *fb_cache; /* IAS_CLASSES x id_count */
    double *fp_cache; /* IAS_CLASSES x id_count, valid where fp_stamp == fp_now */
    uint32_t *fp_stamp;
    uint32_t fp_now;
    /* The default variant with the BVH cut (see ias_table). */
    double *cut_prior; /* per cut entry: its importance (or 1), for c_U's PDF */
    ias_table table;
    ias_pending *pending;
    int pending_count, pending_cap, pending_pixel;
    /* The trees cut with sparse_stats (see sparse_add): the block's and the pixels' statistics,
     * the pixel's feedback weights per cut entry when its pass began, a walk's stack. */
    ias_table btable, *ptables;  /* ptables: one per pixel of the batch (max_pixels) */
    struct ias_log blog, *plogs; /* the samples not yet in btable / ptables[pixel] */
    double *fp_snap;
    int *stack;
    /* ias-stats cut (cut_record): the block's cut nodes R, numbered 0 .. r_count in the order met;
     * node_r maps an id to its number. r_pre: the tree nodes of R by
     * light range (start ascending, larger first), pre_first their range starts; r_up: the nearest
     * member of R above (-1: none); r_end, r_power: range end and power. Statistics per class and
     * member: the block's (rb, its feedback weights when the pass began rb_snap) and, per pixel and
     * class, a slab of r_count (px_slab: its index in slab_pool, or -1). */
    bool r_ready;
    struct ias_range *r_sort;
    int r_count, r_cap;
    ias_idmap node_r;
    int *cut_r; /* per cut entry: its member number (cut_build), so that reads need no node_r */
    int *r_id, *r_pre, *pre_first, *r_first, *r_up, *r_end, pre_count;
    double *r_power;
    pn_ias_stats *rb;
    double *rb_snap;
    int *px_slab;
    pn_ias_stats *slab_pool;
    int slab_used, slab_cap;
    int stack_cap;
    bool oom;
    ias_point *points, *points_tmp; /* member points, by region; the pixel's, in ray order */
    int point_count, point_cap, tmp_cap, tmp_used;
    double *fprior;      /* per cut entry of the PDF being built */
    uint32_t *emit_hits; /* max_pixels: each pixel's eye rays that saw emission (ias-emitter-rays) */
    /* ias-ratio (ias_ratio.h): per cut entry its closed-form unshadowed irradiance (x < 0: none)
     * and the control variate's coefficient; the pixel pass's samples; its regions. */
    int ratio_mode;
    vec3 *cut_unshadowed;
    double *cut_beta;
    pn_ias_ratio_sample *ratio_smp;
    int ratio_count, ratio_cap;
    pn_ias_ratio_region *ratio_regions;
    int ratio_region_cap;
    pn_ias_ratio_scratch ratio;
    /* ias-mis: the cut entry of each cluster id in the cut whose PDF s->pdf holds. */
    ias_idmap mis_entry;
    uint32_t mis_rays;  /* BSDF rays traced (all of the worker's pixels) */
    pn_ias_guide guide; /* ias-light-guide: the block's grids */
    uint32_t tick;      /* the worker's timing counter (IAS_REGION_TIMING_STRIDE) */
    /* Shared trees cuts (compute_cut): the leading region's record, the ball it holds for, where
     * its tree part is in s->cut and how long it is. */
    pn_cluster_cut_share cut_share;
    float share_delta, share_dn;
    int share_first, share_k;
    const struct ias_region *share_leader;
    /* compute_cut's last environment part, copied (s->cut_prior's entries are rewritten later):
     * the normal it was for, its ids and priors, their number (env_valid: complete, not cut short
     * by max_cut); env_cap entries. */
    vec3 env_n;
    int *env_ids;
    double *env_prior;
    int env_count, env_cap;
    bool env_valid;
} ias_scratch;

static void ias_scratch_free(void *p) {
    ias_scratch *s = p;
    if (!s) return;
    free(s->regions);
    free(s->cut);
    free(s->cut_work);
    pn_cluster_cut_share_free(&s->cut_share);
    free(s->block_stats);
    free(s->pixel_pool);
    free(s->pdf);
    free(s->cdf);
    free(s->fpix);
    free(s->pick_guide);
    free(s->env_ids);
    free(s->env_prior);
    free(s->fb_cache);
    free(s->fp_cache);
    free(s->fp_stamp);
    free(s->n_of);
    free(s->pixel_seen);
    free(s->pixels);
    free(s->cut_prior);
    free(s->table.e);
    free(s->btable.e);
    free(s->btable.tops);
    for (int i = 0; s->ptables && i < s->max_pixels; i++) {
        free(s->ptables[i].e);
        free(s->ptables[i].tops);
    }
    free(s->ptables);
    free(s->blog.r);
    for (int i = 0; s->plogs && i < s->max_pixels; i++) free(s->plogs[i].r);
    free(s->plogs);
    free(s->fp_snap);
    free(s->stack);
    idmap_free(&s->node_r);
    free(s->cut_r);
    free(s->r_id);
    free(s->r_pre);
    free(s->pre_first);
    free(s->r_first);
    free(s->r_sort);
    free(s->r_up);
    free(s->r_end);
    free(s->r_power);
    free(s->rb);
    free(s->rb_snap);
    free(s->px_slab);
    free(s->slab_pool);
    free(s->pending);
    free(s->fprior);
    free(s->emit_hits);
    free(s->points);
    free(s->points_tmp);
    free(s->cut_unshadowed);
    free(s->cut_beta);
    free(s->ratio_smp);
    free(s->ratio_regions);
    pn_ias_ratio_scratch_free(&s->ratio);
    idmap_free(&s->mis_entry);
    pn_ias_guide_free(&s->guide);
    free(s);
}

static void *ias_scratch_create(const pn_render_job *job) {
    const ias_shared *sh = job->integrator_data;
    ias_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    size_t ids = (size_t)(sh->id_count > 0 ? sh->id_count : 1);
    /* With the BVH cut the statistics live in the table: the per-id arrays are not used, and
     * the per-cut ones are sized by the largest cut. With sparse_stats the trees' statistics
     * live in hash tables too. */
    const size_t per_cut = sh->bvh_cut ? (size_t)sh->max_cut : ids;
    if (sh->bvh_cut || sh->sparse_stats) ids = 1;
    s->id_count = (int)ids;
    s->max_pixels = (int)(job->block_size * job->block_size);
    if (s->max_pixels < IAS_MAX_PIXELS) s->max_pixels = IAS_MAX_PIXELS;
    s->pixels = calloc((size_t)s->max_pixels, sizeof *s->pixels);
    s->emit_hits = calloc((size_t)s->max_pixels, sizeof *s->emit_hits);
    s->region_cap = s->max_pixels * 8;
    s->regions = malloc((size_t)s->region_cap * sizeof *s->regions);
    s->cut_cap = (int)per_cut * 8;
    s->cut = malloc((size_t)s->cut_cap * sizeof *s->cut);
    s->cut_work = calloc(1, pn_cluster_cut_capped_work(sh->cut_max));
    s->cut_prior = malloc((size_t)s->cut_cap * sizeof *s->cut_prior);
    s->fprior = malloc((per_cut + 1) * sizeof *s->fprior);
    s->block_stats = calloc(IAS_CLASSES * ids, sizeof *s->block_stats);
    s->pixel_pool = calloc((size_t)s->max_pixels * IAS_CLASSES * ids, sizeof *s->pixel_pool);
    s->pdf = malloc((per_cut + 1) * sizeof *s->pdf);
    s->cdf = malloc((per_cut + 1) * sizeof *s->cdf);
    s->fpix = malloc((per_cut + 1) * sizeof *s->fpix);
    s->pick_guide = malloc((per_cut + 1) * sizeof *s->pick_guide);
    s->fb_cache = calloc(IAS_CLASSES * ids, sizeof *s->fb_cache);
    s->fp_cache = calloc(IAS_CLASSES * ids, sizeof *s->fp_cache);
    s->fp_stamp = calloc(IAS_CLASSES * ids, sizeof *s->fp_stamp);
    s->n_of = malloc(((size_t)sh->aa_rays + 1) * sizeof *s->n_of);
    s->visible_slots = sh->visible_slots;
    const bool seen_table = sh->bvh_cut || sh->sparse_stats;
    s->pixel_seen = calloc(seen_table ? 1 : (size_t)s->max_pixels * (size_t)(sh->visible_slots + 1), 1);
    if (sh->sparse_stats) {
        s->fp_snap = malloc((size_t)s->cut_cap * sizeof *s->fp_snap);
        s->ptables = calloc((size_t)s->max_pixels, sizeof *s->ptables);
        s->plogs = calloc((size_t)s->max_pixels, sizeof *s->plogs);
        bool ok = s->fp_snap && s->ptables && s->plogs && table_grow(&s->btable);
        if (ok && sh->cut_stats) {
            ok = idmap_init(&s->node_r, (size_t)sh->id_count);
            s->px_slab = malloc((size_t)s->max_pixels * IAS_CLASSES * sizeof *s->px_slab);
            s->cut_r = malloc((size_t)s->cut_cap * sizeof *s->cut_r);
            ok = ok && s->px_slab && s->cut_r;
        }
        for (int i = 0; ok && i < s->max_pixels; i++) ok = table_grow(&s->ptables[i]);
        if (!ok) {
            ias_scratch_free(s);
            return NULL;
        }
    }
    s->ratio_mode = sh->ratio;
    if (sh->ratio) {
        s->cut_unshadowed = malloc((size_t)s->cut_cap * sizeof *s->cut_unshadowed);
        s->cut_beta = malloc((size_t)s->cut_cap * sizeof *s->cut_beta);
        s->ratio_region_cap = (int)sh->aa_rays + 1;
        s->ratio_regions = malloc((size_t)s->ratio_region_cap * sizeof *s->ratio_regions);
        if (!s->cut_unshadowed || !s->cut_beta || !s->ratio_regions ||
            !pn_ias_ratio_scratch_init(&s->ratio, (int)per_cut, (int)sh->aa_rays + 1)) {
            ias_scratch_free(s);
            return NULL;
        }
    }
    if (sh->mis && !idmap_init(&s->mis_entry, (size_t)sh->id_count)) {
        ias_scratch_free(s);
        return NULL;
    }
    /* compute_cut's copy of the last environment part (trees cut: balance_prior rescales the BVH
     * cut's priors in place). */
    for (int e = 0; e < sh->env_count && !sh->bvh_cut; e++) s->env_cap += sh->env[e].count;
    if (s->env_cap > 0) {
        s->env_ids = malloc((size_t)s->env_cap * sizeof *s->env_ids);
        s->env_prior = malloc((size_t)s->env_cap * sizeof *s->env_prior);
        if (!s->env_ids || !s->env_prior) {
            ias_scratch_free(s);
            return NULL;
        }
    }
    if (!sh->bvh_cut && sh->cut_max == 0 && !pn_cluster_cut_share_init(&s->cut_share, &sh->forest)) {
        ias_scratch_free(s);
        return NULL;
    }
    if (!s->cut_prior || !s->fprior || !s->emit_hits || !s->cut_work || (sh->bvh_cut && !table_grow(&s->table)) ||
        (sh->light_guide && !pn_ias_guide_init(&s->guide, &sh->guide))) {
        ias_scratch_free(s);
        return NULL;
    }
    if (!s->regions || !s->cut || !s->block_stats || !s->pixel_pool || !s->pdf || !s->cdf || !s->fpix || !s->fb_cache ||
        !s->fp_cache || !s->fp_stamp || !s->n_of || !s->pixel_seen || !s->pixels || !s->pick_guide) {
        ias_scratch_free(s);
        return NULL;
    }
    return s;
}

/* ---- helpers ------------------------------------------------------------------------------- */

/* Every IAS_TIMING_STRIDE-th shadow ray has its Embree call timed, and every IAS_TIMING_STRIDE-th
 * sample its PDF upkeep; the sums, scaled by the stride, estimate those times (the stats'
 * estimates, not the image). 32 rather than 8 since stop 21: the clock's reads were 2.9% of
 * hall-many's render (clock_gettime in perf), the estimates over a render's millions of samples
 * move by well under a percent. The eye rays' times come from the driver at its own stride
 * (PN_EYE_TIMING_STRIDE). */
#define IAS_TIMING_STRIDE 32u
/* Every IAS_REGION_TIMING_STRIDE-th region's cut and PDF build, and every such pixel pass's
 * feedback upkeep, is timed and counted that many times (s->tick): two clock reads per region
 * and call of sample_pixel were most of the clock's share. */
#define IAS_REGION_TIMING_STRIDE 8u
/* Eye rays read from the batch at once when the driver's in-advance hits do not hold them. */
#define IAS_EYE_CHUNK 16u

static int normal_class(vec3 n) {
    float ax = fabsf(n.x), ay = fabsf(n.y), az = fabsf(n.z);
    if (ax >= ay && ax >= az) return n.x >= 0.0f ? 0 : 1;
    if (ay >= az) return n.y >= 0.0f ? 2 : 3;
    return n.z >= 0.0f ? 4 : 5;
}

static bool push_region(ias_scratch *s, ias_region **out) {
    if (s->region_count == s->region_cap) {
        int cap = s->region_cap * 2;
        ias_region *r = realloc(s->regions, (size_t)cap * sizeof *r);
        if (!r) return false;
        s->regions = r;
        s->region_cap = cap;
    }
    *out = &s->regions[s->region_count++];
    return true;
}

static bool reserve_cut(ias_scratch *s, int more) {
    if (s->cut_used + more <= s->cut_cap) return true;
    int cap = s->cut_cap;
    while (cap < s->cut_used + more) cap *= 2;
    int *c = realloc(s->cut, (size_t)cap * sizeof *c);
    if (!c) return false;
    s->cut = c;
    double *q = realloc(s->cut_prior, (size_t)cap * sizeof *q);
    if (!q) return false;
    s->cut_prior = q;
    if (s->fp_snap) {
        double *f = realloc(s->fp_snap, (size_t)cap * sizeof *f);
        if (!f) return false;
        s->fp_snap = f;
    }
    if (s->cut_r) {
        int *cr = realloc(s->cut_r, (size_t)cap * sizeof *cr);
        if (!cr) return false;
        s->cut_r = cr;
    }
    if (s->ratio_mode) {
        vec3 *e = realloc(s->cut_unshadowed, (size_t)cap * sizeof *e);
        if (!e) return false;
        s->cut_unshadowed = e;
        double *b = realloc(s->cut_beta, (size_t)cap * sizeof *b);
        if (!b) return false;
        s->cut_beta = b;
    }
    s->cut_cap = cap;
    return true;
}

/* The environment map of cluster id `id` >= light_ids (ids of map e start at env_base[e]). */
static int env_of(const ias_shared *sh, int id) {
    int e = 0;
    while (e + 1 < sh->env_count && id >= sh->env_base[e + 1]) e++;
    return e;
}

/* The importance prior's shares between the light BVH, each distant light and each environment
 * map, as pbrt-v4's BVH light sampler gives them: 1 / G each of the G that have entries in the
 * cut, the tree's share split by the descent's probabilities and an environment's by its regions'
 * power x cosine. Comparing the root's importance with the regions' power instead (the earlier
 * rule) weighs unoccluded bounds: on living-env-138-matte, whose 138 mostly hidden point lights
 * bound far more than the sky, the sky seen through the windows (most of a pixel's light) got 11%
 * of a pixel's first pass and its regions as little as 3e-5 of later passes' PDFs; their rare
 * samples (over 300x the pixel's value) left each pass unbiased but so skewed that the
 * inverse-variance combination and the convergence test turned them into a dark image (-4.3% at
 * 256x144, crop 0.4-0.6, T = 0.01; -0.4% with this rule, trees -0.7%, four seeds). */
static void balance_prior(const ias_shared *sh, const int *out, double *prior, int k_tree, int k) {
    int groups = k_tree > 0 ? 1 : 0;
    for (int i = k_tree; i < k; i++) /* a distant light, or the first region of an environment */
        if (out[i] < sh->light_ids || i == k_tree || out[i - 1] < sh->light_ids ||
            env_of(sh, out[i]) != env_of(sh, out[i - 1]))
            groups++;
    if (groups < 2) return; /* one group: its own proportions are the PDF */
    const double share = 1.0 / (double)groups;
    for (int i = 0; i < k;) {
        int j = i + 1;
        if (i >= k_tree && out[i] >= sh->light_ids)
            while (j < k && env_of(sh, out[j]) == env_of(sh, out[i])) j++;
        else if (i < k_tree)
            j = k_tree;
        double sum = 0.0;
        for (int m = i; m < j; m++) sum += prior[m];
        for (int m = i; m < j; m++) prior[m] = sum > 0.0 ? share * prior[m] / sum : share / (double)(j - i);
        i = j;
    }
}

/* Regions that share a leading region's trees cut walk (compute_cut): normals within IAS_SHARE_DN
 * of its normal, points within IAS_SHARE_REACH of its point, in units of its region radius (a
 * quarter pixel at that depth). */
#define IAS_SHARE_DN 1e-3
#define IAS_SHARE_REACH 8.0

/* The clusters of a region's point: the tree cut, distant lights above the horizon, and the
 * environment regions not below it, as cluster ids. share (trees cut without a cap): 1, a region
 * that leads later regions of its pixel, whose walk records the decisions that hold for all points
 * within s->share_delta and normals within s->share_dn; 2, such a later region, whose walk reads
 * them (all of them, when the record was sure of every node: then its trees cut is the leader's);
 * 0, neither.
 * The same cuts as the plain walk, bit for bit (pn_cluster_cut_record); on hall-many's bench crop
 * (11.4 regions per pixel) the walk was 15% of the render. */
static bool compute_cut(const pn_render_job *job, const ias_shared *sh, ias_scratch *s, ias_region *r, int share) {
    vec3 n = r->bsdf.ng;
    if (!reserve_cut(s, sh->max_cut)) return false;
    int *out = s->cut + s->cut_used;
    double *prior = s->cut_prior + s->cut_used;
    int k, k_tree = 0;
    if (sh->bvh_cut) {
        /* The light BVH cut, each node with the probability the BVH's own descent gives it (so
         * that the prior PDF followed by the descent in the node is exactly pbrt's light BVH
         * sampler), then the distant lights above the horizon and the environment regions. */
        float *imp = (float *)s->fprior; /* scratch of max_cut + 1 doubles */
        k = pn_light_bvh_cut(&sh->bvh, r->origin, n, sh->cut_size, out, imp, NULL);
        /* In the tree's depth-first order, which is the order of its leaves: one uniform number
         * then picks the node and, rescaled within it, the descent, so that stratified numbers
         * stay stratified over the lights (see sample_pixel). */
        for (int i = 1; i < k; i++)
            for (int j = i; j > 0 && out[j - 1] > out[j]; j--) {
                int t = out[j];
                out[j] = out[j - 1];
                out[j - 1] = t;
                float f = imp[j];
                imp[j] = imp[j - 1];
                imp[j - 1] = f;
            }
        /* The nodes' descent probabilities times the root's importance. The root's factor no longer
         * sets the tree's share against distant lights and environment regions (balance_prior
         * does); it is kept so that scenes without them keep their images bit for bit. */
        const double root = k > 0 ? (double)pn_light_bounds_importance(&sh->bvh.nodes[0].b, r->origin, n) : 0.0;
        for (int i = k - 1; i >= 0; i--) prior[i] = root * (double)imp[i];
        k_tree = k;
        for (int d = 0; d < sh->distant_count; d++) {
            const pn_light *l = &job->lights->lights[sh->distant[d]];
            float c = v3_dot(n, l->n);
            if (!(c > 0.0f)) continue;
            prior[k] = (double)PN_PI * (double)v3_luminance(l->emit) * (double)c;
            out[k++] = sh->bvh.node_count + d;
        }
    } else {
        if (share == 1)
            k = pn_cluster_cut_record(&sh->forest, job->lights, r->origin, n, job->cluster_solid_angle, s->share_delta,
                                      s->share_dn, out, sh->max_cut, &s->cut_share);
        else if (share == 2 && s->cut_share.all_sure) {
            k = s->share_k;
            memcpy(out, s->cut + s->share_first, (size_t)k * sizeof *out);
        } else if (share == 2)
            k = pn_cluster_cut_replay(&sh->forest, job->lights, r->origin, n, job->cluster_solid_angle, out,
                                      sh->max_cut, &s->cut_share);
        else
            k = pn_cluster_cut_capped(&sh->forest, job->lights, r->origin, n, job->cluster_solid_angle, sh->cut_max,
                                      out, sh->max_cut, s->cut_work);
        if (k > sh->max_cut) k = sh->max_cut;
        if (share == 1) {
            s->share_first = s->cut_used;
            s->share_k = k;
            s->share_leader = r;
        }
        for (int i = 0; i < k; i++) prior[i] = 1.0;
    }
    /* The environment regions depend on the normal alone: a region with the last one's normal
     * (bit for bit; a pixel's regions on one flat surface) copies its list (pn_env_region_below
     * per region and environment region was 2.6% of living-env-138's render). */
    const int k_env = k;
    const bool env_same = s->env_valid && memcmp(&s->env_n, &n, sizeof n) == 0 && k + s->env_count <= sh->max_cut;
    if (env_same) {
        memcpy(out + k, s->env_ids, (size_t)s->env_count * sizeof *out);
        memcpy(prior + k, s->env_prior, (size_t)s->env_count * sizeof *prior);
        k += s->env_count;
    }
    for (int e = 0; e < sh->env_count && !env_same; e++) {
        const pn_env_regions *reg = &sh->env[e];
        for (int q = 0; q < reg->count && k < sh->max_cut; q++) {
            if (!(reg->regions[q].power > 0.0f) || pn_env_region_below(&reg->regions[q], n)) continue;
            /* Its power times the cosine of its mean direction (at least 0.05: a region across
             * the horizon), times pi as the BVH importance carries it. */
            prior[k] = (double)PN_PI * (double)reg->regions[q].power *
                       fmax(0.05, (double)v3_dot(n, reg->regions[q].direction));
            out[k++] = sh->env_base[e] + q;
        }
    }
    if (s->env_ids && !env_same) {
        s->env_count = k - k_env;
        s->env_valid = k < sh->max_cut && s->env_count <= s->env_cap;
        s->env_n = n;
        if (s->env_valid) {
            memcpy(s->env_ids, out + k_env, (size_t)s->env_count * sizeof *out);
            memcpy(s->env_prior, prior + k_env, (size_t)s->env_count * sizeof *prior);
        }
    }
    if (sh->bvh_cut) balance_prior(sh, out, prior, k_tree, k);
    /* A member whose clusters and class are its leader's: its feedback weights are the leader's
     * (begin_pixel_feedback skips it). */
    const ias_region *lead = s->share_leader;
    r->dup = share == 2 && lead->cls == r->cls && lead->cut_count == k &&
             memcmp(s->cut + lead->cut_first, out, (size_t)k * sizeof *out) == 0;
    r->cut_first = s->cut_used;
    r->cut_count = k;
    s->cut_used += k;
    return true;
}

static pn_ias_stats *pixel_stats(ias_scratch *s, ias_pixel *px, int cls) {
    if (!px->stats[cls]) {
        if (s->pool_used >= s->max_pixels * IAS_CLASSES) return NULL;
        px->stats[cls] = s->pixel_pool + (size_t)s->pool_used++ * (size_t)s->id_count;
    }
    return px->stats[cls];
}

/* One light evaluation through cluster id `id`: `value` is the luminance of the one-sample
 * estimate of the chosen light's own contribution. For a tree node it is recorded at the light's
 * leaf only; aggregate_stats derives every interior node's statistics from its leaves when
 * feedback weights are computed. Distant lights and environment regions are clusters of their
 * own. */
static void record(const ias_shared *sh, pn_ias_stats *block, pn_ias_stats *pixel, int id, int light, double value,
                   bool visible) {
    if (id < sh->forest.node_count && light >= 0) id = sh->forest.leaf_of_light[light];
    pn_ias_stats_add(&block[id], value, visible);
    if (pixel) pn_ias_stats_add(&pixel[id], value, visible);
}

/* Interior nodes' statistics from their leaves: a node's contribution estimate of a sample of
 * light l is the sample divided by l's probability within the node, power(l) / power(node), so
 * sum(node) = sum over children c of sum(c) * power(node) / power(c); counts add up. The same
 * numbers as adding every sample along its leaf-to-root path, for one pass over the nodes instead
 * of a path walk per sample. */
static void aggregate_stats(const ias_shared *sh, pn_ias_stats *stats) {
    add_work((uint64_t)sh->post_count);
    for (int k = 0; k < sh->post_count; k++) {
        const ias_post *nd = &sh->post[k];
        const pn_ias_stats *a = &stats[nd->left], *b = &stats[nd->right];
        pn_ias_stats *o = &stats[nd->node];
        o->sum = a->sum * nd->ra + b->sum * nd->rb;
        o->count = a->count + b->count;
        o->visible = a->visible + b->visible;
    }
}

/* ---- the trees cut's statistics in hash tables (sparse_stats) --------------------------------
 *
 * The dense arrays above hold IAS_CLASSES x id_count statistics for the block and for every
 * pixel, and aggregate_stats and refresh_block_feedback walk all of them once per pass and pixel
 * pass: O(lights) per pixel, 181 of 205 s render and 3.8 GB at 10^6 emitters (issue 15,
 * bench/RESULTS.md "Light count"). With many cluster ids (sparse_stats) the statistics are kept
 * instead in hash tables (s->btable for the block, s->ptables[pixel] for each pixel) keyed by (pixel or
 * block, class, id), holding the numbers the dense arrays would hold, computed in the same order:
 *  - a sample recorded at a node creates the node's entry and those of its ancestors that have
 *    none, so that every entry's ancestors have entries;
 *  - aggregation walks down from the roots through the nodes that have entries only and sets each
 *    interior one from its two children as aggregate_stats does (a child without an entry counts
 *    as zero: the value the dense array holds there, exactly, since 0 x ratio + y = y);
 *  - the block's feedback weights at the start of a pass are kept in each entry (snap; entries
 *    made later had none then, snap 0), the pixel's per cut entry (s->fp_snap).
 * The images are the dense path's bit for bit (tests/test_ias_scale.c); the cost per sample is
 * O(1) amortised plus the new ancestors' entries, per aggregation the entries, not the lights. */
static const pn_ias_stats zero_stats;

static bool same_cut(const ias_scratch *s, const ias_region *a, const ias_region *b);

static void push_top(ias_scratch *s, ias_table *t, uint64_t key) {
    if (!room_for_one((void **)&t->tops, &t->top_cap, t->top_count, 64, sizeof *t->tops)) {
        s->oom = true;
        return;
    }
    t->tops[t->top_count++] = key;
}

/* Adds a sample at node (or distant light, or environment region) `id` and marks it and its
 * ancestors dirty up to the first one that already is (every dirty entry's ancestors are dirty,
 * and have entries); the dirty entries without a parent are listed in t->tops. */
static void sparse_add(const ias_shared *sh, ias_scratch *s, ias_table *t, int scope, unsigned cls, int id,
                       double value, bool visible) {
    ias_entry *e = table_entry(t, table_key(scope, cls, id), true, NULL);
    if (!e) {
        s->oom = true;
        return;
    }
    pn_ias_stats_add(&e->st, value, visible);
    for (int m = id; !e->dirty;) {
        e->dirty = 1u;
        const int up = m < sh->forest.node_count ? sh->tnodes[m].parent : -1;
        if (up < 0) {
            push_top(s, t, table_key(scope, cls, m));
            return;
        }
        m = up;
        e = table_entry(t, table_key(scope, cls, m), true, NULL);
        if (!e) {
            s->oom = true;
            return;
        }
    }
}

static const pn_ias_stats *sparse_find(ias_table *t, int scope, unsigned cls, int id) {
    const ias_entry *e = table_entry(t, table_key(scope, cls, id), false, NULL);
    return e ? &e->st : NULL;
}

static bool push_stack(ias_scratch *s, int *top, int v) {
    if (!room_for_one((void **)&s->stack, &s->stack_cap, *top, 256, sizeof *s->stack)) {
        s->oom = true;
        return false;
    }
    s->stack[(*top)++] = v;
    return true;
}

/* An entry brought up to date: clean, and (snap) its feedback weight kept. */
static void finish_entry(ias_entry *e, bool snap) {
    e->dirty = 0u;
    if (snap) e->snap = pn_ias_feedback(&e->st);
}

/* aggregate_stats over the table's dirty entries, from each dirty top down through the dirty
 * nodes, each interior one set from its two children after them (a clean child keeps the value
 * it was last set to, which is what aggregate_stats would set again); with `snap` each entry set
 * also keeps its feedback weight. */
static void sparse_aggregate(const ias_shared *sh, ias_scratch *s, ias_table *t, int scope, bool snap) {
    const ias_tnode *nodes = sh->tnodes;
    uint64_t work = 0;
    for (int k = 0; k < t->top_count; k++) {
        const uint64_t key = t->tops[k];
        const unsigned cls = (unsigned)(key >> 36) & 15u;
        const int root = (int)(key & ((UINT64_C(1) << 36) - 1u));
        ias_entry *re = table_entry(t, key, false, NULL);
        if (!re || !re->dirty) continue;
        if (root >= sh->forest.node_count || nodes[root].left < 0) { /* a leaf, single or region */
            finish_entry(re, snap);
            continue;
        }
        int top = 0;
        if (!push_stack(s, &top, root)) return;
        while (top > 0) {
            int m = s->stack[top - 1];
            const ias_tnode *nd = &nodes[m >= 0 ? m : ~m];
            if (m >= 0 && nd->left >= 0) {
                s->stack[top - 1] = ~m; /* its dirty children first */
                const ias_entry *b = table_entry(t, table_key(scope, cls, nd->right), false, NULL);
                if (b && b->dirty && !push_stack(s, &top, nd->right)) return;
                const ias_entry *a = table_entry(t, table_key(scope, cls, nd->left), false, NULL);
                if (a && a->dirty && !push_stack(s, &top, nd->left)) return;
                continue;
            }
            top--;
            ias_entry *o = table_entry(t, table_key(scope, cls, m >= 0 ? m : ~m), false, NULL);
            if (m < 0) {
                const pn_ias_stats *a = sparse_find(t, scope, cls, nd->left),
                                   *b = sparse_find(t, scope, cls, nd->right);
                if (!a) a = &zero_stats;
                if (!b) b = &zero_stats;
                o->st.sum = a->sum * nd->ra + b->sum * nd->rb;
                o->st.count = a->count + b->count;
                o->st.visible = a->visible + b->visible;
            }
            finish_entry(o, snap);
            work++;
        }
    }
    t->top_count = 0;
    add_work(work);
}

/* ---- ias-stats cut: the statistics of the block's cut nodes only ----------------------------
 *
 * A node's statistics are read only where the node is in a point's cut: the block's at the cuts
 * of all its regions (build_pdf), a pixel's at its regions' cuts (sparse_begin_pixel). The cuts
 * are computed for all of the block's regions before its first pass, so the set R of nodes that
 * can ever be read is known when the first sample is taken. Instead of recording a sample at its
 * light's leaf and aggregating every node above it (sparse_add, sparse_aggregate: some 20 entries
 * of a hash table per sample at 10^6 emitters, most of them below the cut), cut_record adds it to
 * the members of R whose light range holds the light, each with the sample divided by the light's
 * probability within the node, power(light) / power(node): the sum aggregate_stats forms through
 * the chain of children, up to rounding (the product of the ratios instead of the one ratio), and
 * the same counts. The members holding a light are the deepest one (a binary search over R's
 * ranges by start) and its chain of nearest members above (r_up); they are few, the cuts of one
 * block being alike. The images are the same up to that rounding, not bit for bit (the PDFs'
 * last bits move some stratified choices); tests/test_ias_scale.c compares them. */

/* The members of R in light-range order (start ascending, the larger range first on a tie). */
static int pre_before(const void *a, const void *b) {
    const ias_range *x = a, *y = b;
    if (x->first != y->first) return x->first < y->first ? -1 : 1;
    return x->end > y->end ? -1 : x->end < y->end ? 1 : 0;
}

static bool grow_r(ias_scratch *s, int need) {
    if (need <= s->r_cap) return true;
    int cap = s->r_cap ? s->r_cap : 1024;
    while (cap < need) cap *= 2;
#define GROW(field, n)                                                                                                 \
    do {                                                                                                               \
        void *p_ = realloc(s->field, (size_t)(n) * sizeof *s->field);                                                  \
        if (!p_) return false;                                                                                         \
        s->field = p_;                                                                                                 \
    } while (0)
    GROW(r_id, cap);
    GROW(r_pre, cap);
    GROW(r_sort, cap);
    GROW(pre_first, cap);
    GROW(r_first, cap);
    GROW(r_up, cap);
    GROW(r_end, cap);
    GROW(r_power, cap);
    GROW(rb, (size_t)IAS_CLASSES * (size_t)cap);
    GROW(rb_snap, (size_t)IAS_CLASSES * (size_t)cap);
#undef GROW
    s->r_cap = cap;
    return true;
}

/* R from the block's cuts (all computed before the first pass), its order and links. */
static bool cut_build(const ias_shared *sh, ias_scratch *s) {
    const pn_cluster_forest *f = &sh->forest;
    idmap_clear(&s->node_r);
    s->r_count = 0;
    for (int i = 0; i < s->cut_used; i++) {
        const int id = s->cut[i];
        int r = idmap_get(&s->node_r, id);
        if (r < 0) {
            if (!grow_r(s, s->r_count + 1)) return false;
            r = s->r_count++;
            idmap_put(&s->node_r, id, r);
            s->r_id[r] = id;
        }
        s->cut_r[i] = r;
    }
    int np = 0;
    for (int r = 0; r < s->r_count; r++) {
        const int id = s->r_id[r];
        s->r_up[r] = -1;
        if (id >= f->node_count) { /* an environment region: no range, nothing above */
            s->r_first[r] = s->r_end[r] = 0;
            s->r_power[r] = 0.0;
            continue;
        }
        s->r_first[r] = f->nodes[id].first;
        s->r_end[r] = f->nodes[id].first + f->nodes[id].count;
        s->r_power[r] = (double)f->nodes[id].power;
        s->r_sort[np++] = (ias_range){s->r_first[r], s->r_end[r], r};
    }
    qsort(s->r_sort, (size_t)np, sizeof *s->r_sort, pre_before);
    for (int k = 0; k < np; k++) s->r_pre[k] = s->r_sort[k].r;
    /* Nearest member above: the innermost open range holding the member's start. */
    int top = 0;
    for (int k = 0; k < np; k++) {
        const int r = s->r_pre[k], first = s->r_first[r];
        s->pre_first[k] = first;
        while (top > 0 && s->r_end[s->stack[top - 1]] <= first) top--;
        s->r_up[r] = top > 0 ? s->stack[top - 1] : -1;
        if (!push_stack(s, &top, r)) return false;
    }
    s->pre_count = np;
    memset(s->rb, 0, (size_t)IAS_CLASSES * (size_t)s->r_count * sizeof *s->rb);
    memset(s->rb_snap, 0, (size_t)IAS_CLASSES * (size_t)s->r_count * sizeof *s->rb_snap);
    for (int i = 0; i < s->max_pixels * IAS_CLASSES; i++) s->px_slab[i] = -1;
    s->slab_used = 0;
    s->r_ready = true;
    return true;
}

/* The pixel's statistics of class cls over R, zero until its first sample (NULL: out of memory). */
static pn_ias_stats *pixel_slab(ias_scratch *s, int pixel, unsigned cls) {
    int *slot = &s->px_slab[pixel * IAS_CLASSES + (int)cls];
    if (*slot < 0) {
        const size_t need = (size_t)(s->slab_used + 1) * (size_t)s->r_count;
        if (need > (size_t)s->slab_cap) {
            size_t cap = s->slab_cap ? (size_t)s->slab_cap : 4096;
            while (cap < need) cap *= 2;
            pn_ias_stats *p = realloc(s->slab_pool, cap * sizeof *p);
            if (!p) return NULL;
            s->slab_pool = p;
            s->slab_cap = (int)cap;
        }
        *slot = s->slab_used++;
        memset(s->slab_pool + (size_t)*slot * (size_t)s->r_count, 0, (size_t)s->r_count * sizeof *s->slab_pool);
        add_work((uint64_t)s->r_count);
    }
    return s->slab_pool + (size_t)*slot * (size_t)s->r_count;
}

static const pn_ias_stats *pixel_slab_find(const ias_scratch *s, int pixel, unsigned cls) {
    const int slot = s->px_slab[pixel * IAS_CLASSES + (int)cls];
    return slot < 0 ? NULL : s->slab_pool + (size_t)slot * (size_t)s->r_count;
}

/* A sample through cluster id `id` with light `light` (see above), for the block and the pixel. */
static void cut_record(const ias_shared *sh, ias_scratch *s, int pixel, unsigned cls, int id, int light, double value,
                       bool visible) {
    const pn_cluster_forest *f = &sh->forest;
    if (!s->r_ready && !cut_build(sh, s)) {
        s->oom = true;
        return;
    }
    pn_ias_stats *pix = pixel_slab(s, pixel, cls), *blk = s->rb + (size_t)cls * (size_t)s->r_count;
    if (!pix) {
        s->oom = true;
        return;
    }
    int r = s->node_r.slot[id]; /* a cut node of the block: its number is set */
    double base = 0.0;
    if (id < f->node_count) {
        const int from = light >= 0 ? f->leaf_of_light[light] : id;
        base = (double)f->nodes[from].power;
        if (light >= 0) { /* the deepest member holding the light: the last by start, or above it */
            const int pos = f->nodes[from].first;
            int lo = 0, hi = s->pre_count - 1;
            while (lo < hi) {
                const int mid = lo + (hi - lo + 1) / 2;
                if (s->pre_first[mid] <= pos)
                    lo = mid;
                else
                    hi = mid - 1;
            }
            r = s->r_pre[lo];
            while (r >= 0 && s->r_end[r] <= pos) r = s->r_up[r];
        }
    }
    uint64_t work = 0;
    for (; r >= 0; r = s->r_up[r]) {
        const double v = base > 0.0 ? value * (s->r_power[r] / base) : value;
        pn_ias_stats_add(&blk[r], v, visible);
        pn_ias_stats_add(&pix[r], v, visible);
        work++;
    }
    add_work(work);
}

/* sparse_refresh_block with ias-stats cut: every member's block feedback weight. */
static void cut_refresh_block(ias_scratch *s) {
    for (int c = 0; c < IAS_CLASSES; c++) {
        double *snap = s->rb_snap + (size_t)c * (size_t)s->r_count;
        const pn_ias_stats *b = s->rb + (size_t)c * (size_t)s->r_count;
        if (!s->block_class_used[c]) continue; /* zero since cut_build */
        for (int r = 0; r < s->r_count; r++) snap[r] = pn_ias_feedback(&b[r]);
        add_work((uint64_t)s->r_count);
    }
}

static void push_log(ias_scratch *s, ias_log *l, unsigned cls, int id, double value, bool visible) {
    if (!room_for_one((void **)&l->r, &l->cap, l->count, 1024, sizeof *l->r)) {
        s->oom = true;
        return;
    }
    l->r[l->count++] = (ias_log_rec){id, cls, visible ? 1u : 0u, value};
}

/* A sample through cluster id `id` (record()'s rule: a tree node's at its light's leaf), for the
 * block and for the pixel. */
static void sparse_record(const ias_shared *sh, ias_scratch *s, int pixel, unsigned cls, int id, int light,
                          double value, bool visible) {
    if (sh->cut_stats) {
        cut_record(sh, s, pixel, cls, id, light, value, visible);
        return;
    }
    if (id < sh->forest.node_count && light >= 0) id = sh->forest.leaf_of_light[light];
    push_log(s, &s->blog, cls, id, value, visible);
    push_log(s, &s->plogs[pixel], cls, id, value, visible);
}

/* The log's samples not yet in the table, added in the order they were taken. */
static void replay_log(const ias_shared *sh, ias_scratch *s, ias_log *l, ias_table *t, int scope) {
    for (int i = l->done; i < l->count; i++)
        sparse_add(sh, s, t, scope, l->r[i].cls, l->r[i].id, l->r[i].value, l->r[i].visible != 0);
    add_work((uint64_t)(l->count - l->done));
    l->done = l->count;
}

/* refresh_block_feedback with sparse_stats. */
static void sparse_refresh_block(const ias_shared *sh, ias_scratch *s) {
    if (sh->cut_stats) {
        cut_refresh_block(s);
        return;
    }
    replay_log(sh, s, &s->blog, &s->btable, -1);
    sparse_aggregate(sh, s, &s->btable, -1, true);
}

/* begin_pixel_feedback with sparse_stats: the feedback weights of the pixel's cut entries. */
static void sparse_begin_pixel(const ias_shared *sh, ias_scratch *s, ias_pixel *px) {
    const int pixel = (int)(px - s->pixels);
    if (sh->cut_stats && !s->r_ready && !cut_build(sh, s)) {
        s->oom = true;
        return;
    }
    if (!sh->cut_stats) {
        replay_log(sh, s, &s->plogs[pixel], &s->ptables[pixel], pixel);
        sparse_aggregate(sh, s, &s->ptables[pixel], pixel, false);
    }
    const ias_region *prev = NULL;
    for (int k = 0; k < px->region_count; k++) {
        const ias_region *r = &s->regions[px->first_region + k];
        double *f = s->fp_snap + r->cut_first;
        if (same_cut(s, prev, r)) {
            memcpy(f, s->fp_snap + prev->cut_first, (size_t)r->cut_count * sizeof *f);
        } else {
            const int *cut = s->cut + r->cut_first;
            const bool any = px->classes & (1u << r->cls); /* none: no data yet, F = 0 */
            const pn_ias_stats *slab = sh->cut_stats ? pixel_slab_find(s, pixel, (unsigned)r->cls) : NULL;
            if (sh->cut_stats) {
                const int *cr = s->cut_r + r->cut_first;
                for (int i = 0; i < r->cut_count; i++) f[i] = slab ? pn_ias_feedback(&slab[cr[i]]) : 0.0;
                prev = r;
                continue;
            }
            for (int i = 0; i < r->cut_count; i++) {
                const pn_ias_stats *q = any ? sparse_find(&s->ptables[pixel], pixel, (unsigned)r->cls, cut[i]) : NULL;
                f[i] = q ? pn_ias_feedback(q) : 0.0;
            }
        }
        prev = r;
    }
}

/* The current pixel's feedback weight of cluster `id` in class `cls` (see fp_cache). */
static double pixel_feedback(ias_scratch *s, const pn_ias_stats *pixel, int cls, int id) {
    size_t k = (size_t)cls * (size_t)s->id_count + (size_t)id;
    if (s->fp_stamp[k] != s->fp_now) {
        s->fp_cache[k] = pixel ? pn_ias_feedback(&pixel[id]) : 0.0;
        s->fp_stamp[k] = s->fp_now;
    }
    return s->fp_cache[k];
}

/* Eq. 6 for a region's point in pass j: fills s->pdf / s->cdf over its cut. */
static void build_pdf(const ias_shared *sh, ias_scratch *s, const ias_region *r, const pn_ias_stats *pixel, int pass) {
    double cu, cb, cp;
    pn_ias_blend_weights(pass, &cu, &cb, &cp);
    int nc = r->cut_count;
    const int *cut = s->cut + r->cut_first;
    const double *fb_class = sh->sparse_stats ? NULL : s->fb_cache + (size_t)r->cls * (size_t)s->id_count;
    double *fblock = s->pdf, *fpixel = s->fpix; /* feedback weights of the cut's clusters */
    double fb = 0.0, fp = 0.0;
    if (cb > 0.0 && sh->cut_stats) {
        const double *snap = s->rb_snap + (size_t)r->cls * (size_t)s->r_count;
        const int *cr = s->cut_r + r->cut_first;
        for (int i = 0; i < nc; i++) fb += (fblock[i] = snap[cr[i]]);
    } else if (cb > 0.0 && sh->sparse_stats) {
        for (int i = 0; i < nc; i++) {
            const ias_entry *e = table_entry(&s->btable, table_key(-1, (unsigned)r->cls, cut[i]), false, NULL);
            fb += (fblock[i] = e ? e->snap : 0.0);
        }
    } else if (cb > 0.0) {
        for (int i = 0; i < nc; i++) fb += (fblock[i] = fb_class[cut[i]]);
    }
    if (cp > 0.0 && sh->sparse_stats)
        for (int i = 0; i < nc; i++) fp += (fpixel[i] = s->fp_snap[r->cut_first + i]);
    else if (cp > 0.0 && pixel)
        for (int i = 0; i < nc; i++) fp += (fpixel[i] = pixel_feedback(s, pixel, r->cls, cut[i]));
    /* A feedback PDF without data gives its weight to the uniform PDF. */
    if (!(fb > 0.0)) {
        cu += cb;
        cb = 0.0;
    }
    if (!(fp > 0.0)) {
        cu += cp;
        cp = 0.0;
    }
    const double u = cu / (double)nc, kb = cb > 0.0 ? cb / fb : 0.0, kp = cp > 0.0 ? cp / fp : 0.0;
    /* The irradiance prior (default variant): c_U's share by each cluster's unoccluded irradiance. */
    double *fprior = sh->irradiance_prior ? s->fprior : NULL;
    if (fprior) pn_ias_prior_pdf(s->cut_prior + r->cut_first, nc, fprior);
    double acc = 0.0;
    s->cdf[0] = 0.0;
    for (int i = 0; i < nc; i++) {
        double p = fprior ? cu * fprior[i] : u;
        if (kb > 0.0) p += kb * fblock[i];
        if (kp > 0.0) p += kp * fpixel[i];
        /* ias-env-floor: an environment region is never drawn less often than env_floor times
         * its pass-0 probability (c_U's alone), whatever the feedback learned (see the header). */
        if (sh->env_floor > 0.0 && cut[i] >= sh->light_ids) {
            const double floor = sh->env_floor * (fprior ? fprior[i] : 1.0 / (double)nc);
            if (p < floor) p = floor;
        }
        s->pdf[i] = p;
        acc += p;
        s->cdf[i + 1] = acc;
    }
    const double inv = 1.0 / acc;
    for (int i = 0; i <= nc; i++) s->cdf[i] *= inv;
    for (int i = 0; i < nc; i++) s->pdf[i] *= inv;
}

/* Eq. 6 for the default variant with the BVH cut: as build_pdf, the feedback weights read from the
 * table (the pixel's entries as they were when its pass began: this pass's samples are pending),
 * and c_U's PDF by the cut's prior (importance) when importance_prior, else uniform. */
static void build_pdf_table(const ias_shared *sh, ias_scratch *s, const ias_region *r, int pass) {
    double cu, cb, cp;
    pn_ias_blend_weights(pass, &cu, &cb, &cp);
    const int nc = r->cut_count;
    const int *cut = s->cut + r->cut_first;
    const double *prior = s->cut_prior + r->cut_first;
    double *fblock = s->pdf, *fpixel = s->fpix, *fprior = s->fprior;
    double fb = 0.0, fp = 0.0, fq = 0.0;
    for (int i = 0; i < nc; i++) {
        const pn_ias_stats *b = cb > 0.0 ? table_get(&s->table, table_key(-1, (unsigned)r->cls, cut[i]), false) : NULL;
        const pn_ias_stats *q =
            cp > 0.0 ? table_get(&s->table, table_key(r->pixel, (unsigned)r->cls, cut[i]), false) : NULL;
        fb += (fblock[i] = b ? pn_ias_feedback(b) : 0.0);
        fp += (fpixel[i] = q ? pn_ias_feedback(q) : 0.0);
        fq += (fprior[i] = sh->importance_prior ? prior[i] : 1.0);
    }
    if (!(fb > 0.0)) {
        cu += cb;
        cb = 0.0;
    }
    if (!(fp > 0.0)) {
        cu += cp;
        cp = 0.0;
    }
    /* A defensive mixture (ias-prior-share): the prior keeps at least this weight, so that the
     * variance is at most 1 / share times the prior's own whatever the feedback learned. */
    if (cu < sh->prior_share && cb + cp > 0.0) {
        const double k = (1.0 - sh->prior_share) / (cb + cp);
        cb *= k;
        cp *= k;
        cu = sh->prior_share;
    }
    const double ku = fq > 0.0 ? cu / fq : 0.0, kb = cb > 0.0 ? cb / fb : 0.0, kp = cp > 0.0 ? cp / fp : 0.0;
    double acc = 0.0;
    s->cdf[0] = 0.0;
    for (int i = 0; i < nc; i++) {
        double p = ku * fprior[i] + kb * fblock[i] + kp * fpixel[i];
        s->pdf[i] = p;
        acc += p;
        s->cdf[i + 1] = acc;
    }
    const double inv = acc > 0.0 ? 1.0 / acc : 0.0;
    for (int i = 0; i <= nc; i++) s->cdf[i] *= inv;
    for (int i = 0; i < nc; i++) s->pdf[i] *= inv;
}

/* Adds the pending light evaluations of the last pixel pass to the table (block and pixel). */
static void flush_pending(ias_scratch *s) {
    for (int i = 0; i < s->pending_count; i++) {
        const ias_pending *e = &s->pending[i];
        /* One entry at a time: creating the second may grow the table and move the first. */
        pn_ias_stats *b = table_get(&s->table, table_key(-1, (unsigned)e->cls, e->id), true);
        if (b) pn_ias_stats_add(b, e->value, e->visible);
        pn_ias_stats *q = table_get(&s->table, table_key(s->pending_pixel, (unsigned)e->cls, e->id), true);
        if (q) pn_ias_stats_add(q, e->value, e->visible);
    }
    s->pending_count = 0;
}

static void push_pending(ias_scratch *s, int pixel, int cls, int id, double value, bool visible) {
    /* Out of memory: the evaluation is left out of the feedback only. */
    if (!room_for_one((void **)&s->pending, &s->pending_cap, s->pending_count, 256, sizeof *s->pending)) return;
    s->pending_pixel = pixel;
    s->pending[s->pending_count++] = (ias_pending){id, cls, value, visible};
}

/* Whether region b's PDF would be region a's: same normal class and the same clusters. */
static bool same_cut(const ias_scratch *s, const ias_region *a, const ias_region *b) {
    if (!a || a->cls != b->cls || a->cut_count != b->cut_count) return false;
    return a->cut_first == b->cut_first ||
           memcmp(s->cut + a->cut_first, s->cut + b->cut_first, (size_t)a->cut_count * sizeof *s->cut) == 0;
}

/* The block's feedback weights from all passes so far, at the start of a pass. */
static void refresh_block_feedback(const ias_shared *sh, ias_scratch *s) {
    for (int c = 0; c < IAS_CLASSES; c++) {
        double *f = s->fb_cache + (size_t)c * (size_t)s->id_count;
        if (!s->block_class_used[c]) {
            memset(f, 0, (size_t)s->id_count * sizeof *f);
            continue;
        }
        pn_ias_stats *b = s->block_stats + (size_t)c * (size_t)s->id_count;
        aggregate_stats(sh, b);
        for (int i = 0; i < s->id_count; i++) f[i] = pn_ias_feedback(&b[i]);
        add_work((uint64_t)s->id_count);
    }
}

/* A new pixel pass: its feedback weights are taken from the pixel's data before any of this
 * pass's samples (the 25-ray steps keep them). */
static void begin_pixel_feedback(const ias_shared *sh, ias_scratch *s, ias_pixel *px) {
    if (++s->fp_now == 0) {
        memset(s->fp_stamp, 0, (size_t)IAS_CLASSES * (size_t)s->id_count * sizeof *s->fp_stamp);
        s->fp_now = 1;
    }
    for (int c = 0; c < IAS_CLASSES; c++)
        if (px->stats[c]) aggregate_stats(sh, px->stats[c]);
    for (int k = 0; k < px->region_count; k++) {
        const ias_region *r = &s->regions[px->first_region + k];
        if (r->dup) continue; /* its leader, a region of this pixel, has the same (class, id) pairs */
        const pn_ias_stats *pixel = px->stats[r->cls]; /* NULL: no data yet, F = 0 */
        const int *cut = s->cut + r->cut_first;
        for (int i = 0; i < r->cut_count; i++) (void)pixel_feedback(s, pixel, r->cls, cut[i]);
    }
}

static int choose(const double *cdf, int n, double u) {
    int lo = 0, hi = n;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    while (lo < n - 1 && !(cdf[lo + 1] > cdf[lo])) lo++; /* never a zero-probability entry */
    return lo;
}

/* A guide table for choose over s->cdf's n entries: guide[b] is the last entry whose cdf is at
 * most b / n, so that a number u starts near its entry instead of a binary search's log2(n)
 * dependent reads (the search was a sixth of sample_pixel on hall-many, some 50 numbers per PDF).
 * Only for a non-decreasing CDF of finite numbers, where choose's answer is the last entry whose
 * cdf is at most u; otherwise guide_ok is false and choose decides. */
static void build_guide(ias_scratch *s, int n) {
    const double *cdf = s->cdf;
    s->guide_ok = false;
    for (int i = 0; i < n; i++)
        if (!(cdf[i + 1] >= cdf[i]) || !isfinite(cdf[i + 1])) return;
    int i = 0;
    const double step = 1.0 / (double)n; /* a hint only: choose_guided corrects either way */
    for (int b = 0; b < n; b++) {
        const double t = (double)b * step;
        while (i + 1 < n && cdf[i + 1] <= t) i++;
        s->pick_guide[b] = i;
    }
    s->guide_ok = true;
}

/* choose's entry, by the guide table when there is one: the same entry. */
static int choose_guided(const ias_scratch *s, int n, double u) {
    if (!s->guide_ok || !(u >= 0.0) || !(u < 1.0)) return choose(s->cdf, n, u);
    const double *cdf = s->cdf;
    int lo = s->pick_guide[(int)(u * (double)n) < n ? (int)(u * (double)n) : n - 1];
    while (lo > 0 && cdf[lo] > u) lo--; /* u * n rounded up to the next bucket */
    while (lo + 1 < n && cdf[lo + 1] <= u) lo++;
    while (lo < n - 1 && !(cdf[lo + 1] > cdf[lo])) lo++; /* never a zero-probability entry */
    return lo;
}

/* Eq. 7-8 over the pixel's passes: L_p = sum_j L_j / s_j^2 / sum_j 1 / s_j^2.
 *
 * Taking s_j^2 as the pixel's own sample variance of pass j makes the result biased: with few
 * visible samples, a pass that happened to see less light also has a smaller sample variance and
 * gets more weight (measured 7-15% too dark on hall-many-matte; splitting passes in halves that
 * weight each other only moved the bias around). So the weights use the pass's variance as the
 * whole block saw it: s_j^2 = L_j^2 r_j, with r_j the block's pooled relative variance of pass j
 * (sum of its pixels' variances over the sum of their squared estimates). The weights then follow
 * how good pass j's PDFs were for the block, which is what the paper's weighting is for, and
 * hardly depend on this pixel's noise. The variance of the combination, for the convergence test,
 * is sum_j w_j^2 s_j^2 / (sum_j w_j)^2 with the pixel's own s_j^2. */
static double block_relative_variance(const ias_scratch *sc, int pass) {
    double num = 0.0, den = 0.0;
    for (int q = 0; q < sc->pixel_count; q++) {
        const ias_pixel *o = &sc->pixels[q];
        if (o->pass_count <= pass) continue;
        num += o->passes[pass].s2;
        den += o->passes[pass].lum * o->passes[pass].lum;
    }
    return den > 0.0 && num > 0.0 ? num / den : 0.0;
}

static void combine_passes(const ias_scratch *sc, const ias_pixel *px, double *L, double *s2, vec3 *rgb,
                           double *block_relvar) {
    double wsum = 0.0, lum = 0.0, var = 0.0;
    vec3 c = v3(0, 0, 0);
    double r[IAS_MAX_PASSES_STORED];
    double r_min = INFINITY;
    for (int j = 0; j < px->pass_count; j++) {
        r[j] = block_relative_variance(sc, j);
        if (r[j] > 0.0 && r[j] < r_min) r_min = r[j];
    }
    for (int j = 0; j < px->pass_count; j++) {
        const ias_pass *p = &px->passes[j];
        /* A pass in which the block saw no variance at all: as good as the best pass. */
        double rj = r[j] > 0.0 ? r[j] : (isfinite(r_min) ? r_min : 1.0);
        double w = 1.0 / rj;
        wsum += w;
        lum += w * p->lum;
        var += w * w * p->s2;
        c = v3_madd(c, p->rgb, (float)w);
    }
    /* The relative variance the combination would have if this pixel behaved like its block:
     * 1 / sum_j (1 / r_j). */
    if (block_relvar) {
        double inv = 0.0;
        for (int j = 0; j < px->pass_count; j++)
            if (r[j] > 0.0) inv += 1.0 / r[j];
        *block_relvar = inv > 0.0 ? 1.0 / inv : 0.0;
    }
    if (wsum > 0.0) {
        *L = lum / wsum;
        *s2 = var / (wsum * wsum);
        *rgb = v3_scale(c, (float)(1.0 / wsum));
    } else {
        *L = 0.0;
        *s2 = INFINITY;
        *rgb = v3(0, 0, 0);
    }
}

/* The pixel's combined estimate, and the variance its convergence test uses: the larger of the
 * pixel's own variance and the one its block's relative variance predicts, so that a pixel whose
 * few samples happened to agree does not stop early with a low estimate (termination bias, 7% on
 * hall-many-matte with the pixel's own variance alone). */
static void pixel_estimate(const ias_scratch *s, const ias_pixel *px, double *L, double *s2, vec3 *rgb) {
    double block_relvar;
    combine_passes(s, px, L, s2, rgb, &block_relvar);
    *s2 = fmax(*s2, block_relvar * *L * *L);
}

/* ---- adaptive_rule = cross: the convergence test on what the pixel's own samples do not set --
 *
 * The rule above decides from the pixel's own pass estimates, so a pixel stops when its samples
 * happen to look converged (termination bias), and the black rule stops a pixel exactly when its
 * samples happened to see no light. Here the decision comes from the other pixels of the block:
 * rho_j, the block's pooled relative variance of pass j per shadow ray, leaving this pixel out,
 * predicts the relative variance of this pixel's pass j as rho_j / n_j (n_j its own shadow-ray
 * count, itself set by the rule, not by its values). Passes are weighted by n_j / rho_j, the
 * inverse of that prediction, and the pixel is done when 1 / sum_j (n_j / rho_j) < threshold. The
 * pixel's values then enter its estimate linearly with weights and a stopping time that do not
 * depend on them (only on its neighbours' values and on the PDFs, which are fixed before each
 * pass), so each pass being unbiased given its PDF, so is the combination. */
static double block_rho_loo(const ias_scratch *sc, int pass, const ias_pixel *self) {
    double num = 0.0, den = 0.0;
    for (int q = 0; q < sc->pixel_count; q++) {
        const ias_pixel *o = &sc->pixels[q];
        if (o == self || o->pass_count <= pass) continue;
        num += o->passes[pass].s2 * (double)o->passes[pass].n;
        den += o->passes[pass].lum * o->passes[pass].lum;
    }
    return den > 0.0 ? num / den : -1.0; /* -1: no other pixel measured this pass */
}

/* rho_j for the pixel's passes: a pass no other pixel measured (they had all finished or were
 * black) takes the last measured one, the PDFs only improving; false when none was measured. */
static bool pixel_rho(const ias_scratch *sc, const ias_pixel *px, double *rho) {
    double last = -1.0;
    for (int j = 0; j < px->pass_count; j++) {
        rho[j] = block_rho_loo(sc, j, px);
        if (rho[j] >= 0.0)
            last = rho[j];
        else
            rho[j] = last;
    }
    int first = 0;
    while (first < px->pass_count && rho[first] < 0.0) first++;
    if (first == px->pass_count) return false;
    for (int j = 0; j < first; j++) rho[j] = rho[first];
    return true;
}

/* The cross rule's estimate and predicted relative variance; *rho_last is rho of the last pass
 * (0 when the block saw no variance). A block whose other pixels measured nothing (all black,
 * or the pixel alone) leaves only the pixel's own variance, as the rule above uses. */
static void pixel_estimate_cross(const ias_scratch *sc, const ias_pixel *px, double *L, double *relvar, vec3 *rgb,
                                 double *rho_last) {
    double rho[IAS_MAX_PASSES_STORED];
    *rho_last = 0.0;
    if (!pixel_rho(sc, px, rho)) {
        double s2;
        pixel_estimate(sc, px, L, &s2, rgb);
        *relvar = *L > 0.0 ? s2 / (*L * *L) : (double)INFINITY;
        return;
    }
    double wsum = 0.0, lum = 0.0, n = 0.0, nlum = 0.0;
    vec3 c = v3(0, 0, 0), nc = v3(0, 0, 0);
    bool zero = false; /* a pass the block saw without variance: exact as far as it can tell */
    for (int j = 0; j < px->pass_count; j++) {
        const ias_pass *p = &px->passes[j];
        n += p->n;
        nlum += p->n * p->lum;
        nc = v3_madd(nc, p->rgb, (float)p->n);
        if (!(rho[j] > 0.0)) {
            zero = true;
            continue;
        }
        double w = (double)p->n / rho[j];
        wsum += w;
        lum += w * p->lum;
        c = v3_madd(c, p->rgb, (float)w);
    }
    if (zero || !(wsum > 0.0)) { /* equal weights per shadow ray */
        *L = n > 0.0 ? nlum / n : 0.0;
        *rgb = n > 0.0 ? v3_scale(nc, (float)(1.0 / n)) : v3(0, 0, 0);
        *relvar = 0.0;
        return;
    }
    *rho_last = rho[px->pass_count - 1];
    *L = lum / wsum;
    *rgb = v3_scale(c, (float)(1.0 / wsum));
    *relvar = 1.0 / wsum;
}

/* ias-ratio: one sample of the pixel pass (ias_ratio.h). False when out of memory. */
static bool push_ratio_sample(ias_scratch *s, int region, int entry, vec3 v, vec3 u) {
    if (s->ratio_count == s->ratio_cap) {
        int cap = s->ratio_cap ? 2 * s->ratio_cap : 1024;
        pn_ias_ratio_sample *e = realloc(s->ratio_smp, (size_t)cap * sizeof *e);
        if (!e) return false;
        s->ratio_smp = e;
        s->ratio_cap = cap;
    }
    s->ratio_smp[s->ratio_count++] = (pn_ias_ratio_sample){region, entry, v, u};
    return true;
}

/* ---- ias-mis: BSDF samples weighted against ias's own light sampling (ias_mis.h) -----------
 *
 * A light sample of cut entry c, light l in it and direction w has the density
 * p_L(w) = P_pass(c) P(l | c) p_l(w) (s->pdf, pn_cluster_pick_pdf, the light's solid-angle
 * density); a BSDF sample has p_B(w) (pn_bsdf_pdf). Each shadow ray's light sample is paired
 * with one BSDF sample from the same point, and each is weighted by the power heuristic,
 * p_X^2 / (p_L^2 + p_B^2): the pair's sum is one sample of the same integral, so the region's
 * mean and its variance (store_pass) stay those of what is averaged. A BSDF ray that reaches a
 * light no cut entry holds (p_L = 0) keeps its full value: the estimate is unbiased over the
 * union of the two strategies. */

/* Fills s->mis_entry for region r's cut (the cut s->pdf is built for). */
static void mis_map_cut(ias_scratch *s, const ias_region *r) {
    idmap_clear(&s->mis_entry);
    const int *cut = s->cut + r->cut_first;
    for (int i = 0; i < r->cut_count; i++) idmap_put(&s->mis_entry, cut[i], i);
}

/* The cut entry holding cluster-tree light `light` (its leaf or the first ancestor in the cut), -1
 * when none does. */
static int mis_entry_of_light(const ias_shared *sh, const ias_scratch *s, int light) {
    if (light < 0 || light >= sh->forest.light_count) return -1;
    int e = -1;
    for (int node = sh->forest.leaf_of_light[light]; node >= 0 && e < 0; node = sh->forest.nodes[node].parent)
        e = idmap_get(&s->mis_entry, node);
    return e;
}

/* The BSDF strategy at a point: its glossy lobe alone where it has one (a coated surface's lobe
 * has a weight of about 0.04 against the base's 0.5, so sampling the whole BSDF would spend some
 * 93% of the rays on directions light sampling already covers), else the whole BSDF. */
static bool mis_strategy_sample(const pn_bsdf *bsdf, vec3 wo, float u0, float u1, float u2, vec3 *wi, float *pdf) {
    if (!v3_is_zero(bsdf->ks)) return pn_bsdf_sample_glossy(bsdf, wo, u1, u2, wi, pdf);
    return pn_bsdf_sample(bsdf, wo, u0, u1, u2, wi, pdf);
}

static float mis_strategy_pdf(const pn_bsdf *bsdf, vec3 wo, vec3 wi) {
    return v3_is_zero(bsdf->ks) ? pn_bsdf_pdf(bsdf, wo, wi) : pn_bsdf_pdf_glossy(bsdf, wo, wi);
}

/* One BSDF-sampled ray from a shadow ray's point (region r's PDF in s->pdf): the MIS-weighted
 * f L cos / p_B of what it reaches, an area light or the environment, before the eye path's
 * throughput. With ias-mis-share b < 1 a light sample takes a BSDF ray with probability b: the
 * BSDF strategy's density counts as b p_B in both weights and its value is divided by b. *rays
 * counts the rays traced. */
static vec3 mis_bsdf_sample(const pn_render_job *job, const ias_shared *sh, const ias_scratch *s, const ias_region *r,
                            const pn_bsdf *bsdf, vec3 origin, vec3 wo, float u0, float u1, float u2, uint32_t *rays) {
    vec3 wi, sum = v3(0, 0, 0);
    float pb;
    if (!mis_strategy_sample(bsdf, wo, u0, u1, u2, &wi, &pb)) return sum;
    const vec3 f = pn_bsdf_eval(bsdf, wo, wi);
    const float cos_i = v3_dot(bsdf->ns, wi);
    if (v3_is_zero(f) || !(cos_i > 0.0f)) return sum;
    (*rays)++;
    pn_hit hit;
    float tr;
    const bool surface = pn_ias_mis_trace(job, origin, wi, &hit, &tr);
    if (!(tr > 0.0f)) return sum;
    const double b = sh->mis_share, k = (double)cos_i / ((double)pb * b) * (double)tr, pbb = (double)pb * b;
    if (surface) {
        const int light = pn_ias_mis_light_of_hit(&sh->mis_map, &hit);
        if (light < 0) return sum;
        const pn_light *l = &job->lights->lights[light];
        if (l->kind != PN_LIGHT_SPHERE && !l->two_sided && !(-v3_dot(wi, l->n) > 0.0f)) return sum;
        double pl = 0.0;
        const int e = mis_entry_of_light(sh, s, light);
        if (e >= 0) {
            const int node = s->cut[r->cut_first + e];
            const float pick = sh->importance_pick
                                   ? pn_cluster_pick_importance_pdf(&sh->forest, job->lights, node, origin, bsdf->ns,
                                                                    sh->pick_limit, light)
                                   : pn_cluster_pick_pdf(&sh->forest, job->lights, node, light);
            pl = s->pdf[e] * (double)pick * (double)pn_light_pdf_direction(l, origin, wi, hit.t);
        }
        return v3_scale(v3_mul(f, l->emit), (float)(k * pn_ias_mis_weight(pbb, pl)));
    }
    for (int m = 0; m < sh->env_count; m++) {
        const pn_env *env = &job->lights->envs[job->lights->lights[sh->env_light[m]].env];
        const vec3 L = pn_env_radiance(env, wi);
        if (v3_is_zero(L)) continue;
        const int q = pn_env_region_of(&sh->env[m], env, wi);
        const int id = q >= 0 ? sh->env_base[m] + q : -1;
        double pl = 0.0;
        const int e = id >= 0 && id < sh->id_count ? idmap_get(&s->mis_entry, id) : -1;
        if (e >= 0) pl = s->pdf[e] * (double)pn_env_region_pdf(&sh->env[m], env, q, wi);
        sum = v3_add(sum, v3_scale(v3_mul(f, L), (float)(k * pn_ias_mis_weight(pbb, pl))));
    }
    return sum;
}

/* Takes `count` shadow rays for pixel px with its regions' current PDFs (pass `pass`), adding
 * the samples to the regions' sums and the light evaluations to the statistics. Every region that
 * has clusters gets at least two per pass (for a variance) when count > 0. */
static void sample_pixel(const pn_render_job *job, const ias_shared *sh, ias_scratch *s, ias_pixel *px, int pass,
                         unsigned count, uint32_t scramble, uint32_t *counter) {
    const bool mel = (job->aovs & PN_AOV_MELANOPIC_EDI) != 0 && job->spectral;
    const bool lux = (job->aovs & PN_AOV_ILLUMINANCE) != 0 || mel;
    const double wsum = px->region_weight;
    if (!(wsum > 0.0) || count == 0) return;
    /* Samples to regions by area: floor shares, the rest to the largest remainders. */
    unsigned given = 0;
    unsigned *n_of = s->n_of;
    const int rc = px->region_count;
    for (int k = 0; k < rc; k++) {
        const ias_region *r = &s->regions[px->first_region + k];
        n_of[k] = r->cut_count > 0 ? (unsigned)floor((double)count * r->weight / wsum) : 0u;
        if (count > 0 && r->cut_count > 0 && r->n + n_of[k] < 2) n_of[k] = 2 - r->n;
        given += n_of[k];
    }
    while (given < count) {
        int best = -1;
        double best_rem = -1.0;
        for (int k = 0; k < rc; k++) {
            const ias_region *r = &s->regions[px->first_region + k];
            if (r->cut_count == 0) continue;
            double rem = (double)count * r->weight / wsum - (double)n_of[k];
            if (rem > best_rem) {
                best_rem = rem;
                best = k;
            }
        }
        if (best < 0) break;
        n_of[best]++;
        given++;
    }
    if (given == 0) return;
    /* The scramble seeds of the shadow rays' dimensions 5-9, hashed once per call instead of per
     * number (pn_sobol_samples: the same numbers). */
    uint32_t seeds[5];
    for (int d = 0; d < 5; d++) seeds[d] = pn_sobol_seed(5 + d, scramble);
    const ias_region *built = NULL; /* the region whose PDF s->pdf / s->cdf hold */
    for (int k = 0; k < rc; k++) {
        if (n_of[k] == 0) continue;
        ias_region *r = &s->regions[px->first_region + k];
        pn_ias_stats *block = sh->sparse_stats ? NULL : s->block_stats + (size_t)r->cls * (size_t)s->id_count;
        s->block_class_used[r->cls] = true;
        pn_ias_stats *pix = sh->bvh_cut || sh->sparse_stats ? NULL : pixel_stats(s, px, r->cls);
        px->classes |= 1u << r->cls;
        const bool timed_pdf = s->tick++ % IAS_REGION_TIMING_STRIDE == 0u;
        double t_pdf = timed_pdf ? pn_clock_seconds() : 0.0;
        /* Regions of one pixel on one surface usually have the same cut; their PDFs are then
         * the same numbers (the feedback weights are fixed for the pixel's pass), built once. */
        if (!same_cut(s, built, r)) {
            if (sh->bvh_cut)
                build_pdf_table(sh, s, r, pass);
            else
                build_pdf(sh, s, r, pix, pass);
            if (sh->mis) mis_map_cut(s, r);
            s->guide_ok = false;
            built = r;
        }
        /* The guide table where it saves more than it costs: some n log2(n) / 8 numbers drawn
         * with this PDF (living-env-138's ~316 clusters are often drawn from a few times). */
        if (!s->guide_ok && (int)n_of[k] * 8 >= r->cut_count) build_guide(s, r->cut_count);
        if (timed_pdf) px->pdf_seconds += elapsed_since(sh, t_pdf) * IAS_REGION_TIMING_STRIDE;
        const int *cut = s->cut + r->cut_first;
        pn_light_sample_cache cache = {0};
        for (unsigned i = 0; i < n_of[k]; i++) {
            uint32_t q = (*counter)++;
            /* Every IAS_TIMING_STRIDE-th sample times its PDF upkeep: choosing the cluster and
             * the light in it, and recording the result. */
            const bool timed_upkeep = q % IAS_TIMING_STRIDE == 1u;
            /* The paper variant jitters stratum i of n; the default takes the Sobol number itself,
             * whose consecutive points are already stratified: (i + xi_q) / n breaks that structure
             * (relMSE 2.6e-4 instead of 6.8e-5 on many-1000 at 64 shadow rays, one pass). */
            float xi[5]; /* dimensions 5-9 (9 only with member points) */
            pn_sobol_samples(q, 5, r->point_count > 0 ? 5 : 4, seeds, xi);
            double u = sh->sobol_direct ? (double)xi[0] : ((double)i + (double)xi[0]) / (double)n_of[k];
            float u_pick = xi[1];
            float u1 = xi[2], u2 = xi[3];
            double t_upkeep = timed_upkeep ? pn_clock_seconds() : 0.0;
            /* The point the shadow ray leaves from: the representative, or the next member. */
            const ias_point *pt = NULL;
            if (r->point_count > 0) {
                /* Its own quasi-random dimension: tied to the stratum index i instead, each member
                 * saw the same part of the lights' CDF in every pass (relMSE 3.6e-4 instead of
                 * 6.8e-5 on many-1000 at 64 shadow rays). */
                int m = (int)(xi[4] * (float)r->point_count);
                pt = &s->points[r->point_first + (m < r->point_count ? m : r->point_count - 1)];
            }
            const vec3 origin = pt ? pt->origin : r->origin, wo = pt ? pt->wo : r->wo;
            const vec3 throughput = pt ? pt->throughput : r->throughput;
            const pn_bsdf *bsdf = pt ? &pt->bsdf : &r->bsdf;
            const float eps = pt ? pt->eps : r->eps;
            /* ias-mis: BSDF samples at this point ('glossy': only where it has a glossy lobe). */
            const bool mis = sh->mis == PN_IAS_MIS_ON || (sh->mis == PN_IAS_MIS_GLOSSY && !v3_is_zero(bsdf->ks));
            int c = choose_guided(s, r->cut_count, u);
            int id = cut[c];
            double p_cluster = s->pdf[c];
            int light = -1;
            double p_light = 1.0;
            vec3 wi, radiance;
            float pdf, dist;
            bool ok, delta = false;
            float pl = 1.0f;
            if (!sh->bvh_cut) {
                /* ias-cluster-pick importance: the horizon is the shading normal's, the one the
                 * sample's cosine below is taken with (lights under it give nothing). */
                if (id < sh->forest.node_count)
                    light = sh->importance_pick ? pn_cluster_pick_importance(&sh->forest, job->lights, id, origin,
                                                                             bsdf->ns, sh->pick_limit, u_pick, &pl)
                                                : pn_cluster_pick(&sh->forest, job->lights, id, u_pick, &pl);
            } else if (id < sh->bvh.node_count) {
                /* A light of the BVH node by importance descent (O(depth)). */
                double pm;
                /* The stratified number that chose the node, rescaled within the node's share of
                 * the CDF, drives the descent: with the cut in leaf order the map from u to the
                 * light is monotone, and the quasi-random points stay well spread over the lights
                 * (with the independent dimension 6 instead, relMSE 7.4e-5 instead of 6.8e-5 on
                 * many-1000 at 64 shadow rays, one pass). */
                double width = s->cdf[c + 1] - s->cdf[c];
                double u_node = width > 0.0 ? (u - s->cdf[c]) / width : 0.0;
                u_node = fmin(fmax(u_node, 0.0), nextafter(1.0, 0.0));
                light = pn_light_bvh_descend(&sh->bvh, id, origin, bsdf->ng, u_node, 1.0, &pm);
                pl = (float)pm;
            } else if (id < sh->light_ids) {
                light = sh->distant[id - sh->bvh.node_count];
            }
            /* The statistics this sample will be added to (record), fetched while the light is
             * sampled and the shadow ray traced: the pixel's array is cold (zeroed at the block's
             * end), and that read was 12% of sample_pixel on hall-many. */
            if (pix) {
                const int slot = light >= 0 && id < sh->forest.node_count ? sh->forest.leaf_of_light[light] : id;
                __builtin_prefetch(&pix[slot], 1);
                __builtin_prefetch(&block[slot], 1);
            }
            if (timed_upkeep) px->pdf_seconds += elapsed_since(sh, t_upkeep) * IAS_TIMING_STRIDE;
            int guide_cell = -1; /* ias-light-guide: the sample's cell in its light's grid */
            double guide_density = 1.0;
            if (id < sh->light_ids) {
                p_light = (double)pl;
                pn_light_sample ls;
                if (sh->light_guide && light >= 0)
                    guide_cell = pn_ias_guide_warp(&s->guide, light, &u1, &u2, &guide_density);
                ok =
                    light >= 0 && pl > 0.0f &&
                    pn_light_sample_point_cached(job->lights, &job->lights->lights[light], origin, u1, u2, &cache, &ls);
                wi = ls.wi;
                radiance = ls.radiance;
                pdf = ls.pdf;
                if (guide_density != 1.0) pdf = (float)((double)pdf * guide_density);
                dist = ls.dist;
                delta = ok && ls.delta;
            } else {
                int e = 0;
                while (e + 1 < sh->env_count && id >= sh->env_base[e + 1]) e++;
                const pn_env *env = &job->lights->envs[job->lights->lights[sh->env_light[e]].env];
                ok = pn_env_region_sample(&sh->env[e], env, id - sh->env_base[e], u1, u2, &wi, &radiance, &pdf);
                dist = INFINITY;
            }
            vec3 v = v3(0, 0, 0);
            double lux_v = 0.0; /* PN_AOV_ILLUMINANCE: the sample's illuminance on a white receiver */
            float edi = 0.0f;   /* PN_AOV_MELANOPIC_EDI: the radiance's melanopic EDI, at its wavelengths */
            bool visible = false;
            if (ok && pdf > 0.0f) {
                vec3 f = pn_bsdf_eval(bsdf, wo, wi);
                float cos_i = v3_dot(bsdf->ns, wi);
                if (!v3_is_zero(f) && cos_i > 0.0f) {
                    px->shadow_rays++;
                    float tmax = isinf(dist) ? INFINITY : dist * (1.0f - 1e-4f) - eps;
                    bool timed = q % IAS_TIMING_STRIDE == 0u;
                    double t0 = timed ? pn_clock_seconds() : 0.0;
                    float transmittance = pn_shadow_transmittance(job, origin, wi, 0.0f, tmax);
                    visible = transmittance > 0.0f;
                    if (timed) px->embree_seconds += (pn_clock_seconds() - t0) * IAS_TIMING_STRIDE;
                    if (visible) {
                        px->visible++;
                        /* Table 5: this light (or environment region) is visible here. */
                        int slot = id < sh->light_ids ? light : sh->light_count + (id - sh->light_ids);
                        if ((sh->bvh_cut || sh->sparse_stats) && slot >= 0 && slot < s->visible_slots) {
                            pn_ias_stats *e = table_get(sh->bvh_cut ? &s->table : &s->ptables[px - s->pixels],
                                                        table_key((int)(px - s->pixels), IAS_SEEN_CLASS, slot), true);
                            if (e && !e->count) {
                                e->count = 1;
                                px->visible_lights++;
                                atomic_store_explicit(&sh->seen[slot], 1, memory_order_relaxed);
                            }
                        } else if (slot >= 0 && slot < s->visible_slots) {
                            unsigned char *mine = s->pixel_seen + (size_t)(px - s->pixels) * (size_t)s->visible_slots;
                            if (!mine[slot]) {
                                mine[slot] = 1;
                                px->visible_lights++;
                                atomic_store_explicit(&sh->seen[slot], 1, memory_order_relaxed);
                            }
                        }
                        /* Spectral mode: this sample's own wavelengths, converted back to sRGB here. */
                        vec3 fl = job->spectral ? pn_spectral_sample_value(job, bsdf, wo, wi, radiance, throughput,
                                                                           light, q, scramble, mel ? &edi : NULL)
                                                : v3_mul(v3_mul(f, radiance), throughput);
                        v = v3_scale(fl, cos_i / pdf);
                        if (transmittance != 1.0f) v = v3_scale(v, transmittance);
                        if (pt) v = v3_scale(v, pt->share);
                        if (lux)
                            lux_v = (double)pn_photometric(radiance) * (double)(cos_i / pdf * transmittance) *
                                    (pt ? (double)pt->share : 1.0);
                        if (mel) edi *= cos_i / pdf * transmittance * (pt ? pt->share : 1.0f);
                    }
                }
            }
            /* ias-ratio: the sample unshadowed with the diffuse part (its expectation is the
             * entry's closed form, ias_ratio.h), kept with v for the pass estimate. */
            if (s->ratio_mode) {
                const double wr = p_cluster > 0.0 && p_light > 0.0 ? 1.0 / (p_cluster * p_light) : 0.0;
                const int e = r->cut_first + c;
                vec3 un = v3(0, 0, 0);
                const bool in_a = s->cut_unshadowed[e].x >= 0.0f;
                if (in_a && ok && pdf > 0.0f) {
                    float ci = v3_dot(bsdf->ns, wi);
                    if (ci > 0.0f)
                        un = v3_scale(v3_mul(v3_mul(bsdf->kd, radiance), throughput),
                                      PN_INV_PI * ci / pdf * (pt ? pt->share : 1.0f));
                }
                if (!push_ratio_sample(s, k, in_a ? e : -1, v3_scale(v, (float)wr), v3_scale(un, (float)wr))) return;
            }
            /* Statistics: the cluster's contribution estimate (eq. 3), visibility. */
            double lum_v = (double)v3_luminance(v);
            /* ias-mis: the light sample's weight against the BSDF strategy's density of its
             * direction (delta lights: 1, no BSDF sample reaches them). */
            double wl = 1.0;
            if (mis && !delta && !v3_is_zero(v) && p_cluster > 0.0 && p_light > 0.0)
                wl = pn_ias_mis_weight(p_cluster * p_light * (double)pdf,
                                       sh->mis_share * (double)mis_strategy_pdf(bsdf, wo, wi));
            if (guide_cell >= 0) pn_ias_guide_record(&s->guide, light, guide_cell, lum_v * guide_density);
            if (timed_upkeep) t_upkeep = pn_clock_seconds();
            if (sh->bvh_cut) /* the node's own contribution estimate: the sample over P(light | node) */
                push_pending(s, (int)(px - s->pixels), r->cls, id, p_light > 0.0 ? lum_v / p_light : 0.0, visible);
            else if (sh->sparse_stats)
                sparse_record(sh, s, (int)(px - s->pixels), (unsigned)r->cls, id, light, lum_v, visible);
            else
                record(sh, block, pix, id, light, lum_v, visible);
            if (timed_upkeep) px->pdf_seconds += elapsed_since(sh, t_upkeep) * IAS_TIMING_STRIDE;
            /* The sample's estimate of the region's direct light (eq. 2 with this pass's PDF). */
            /* A descent that found no light with importance at this point (p_light 0) is a sample
             * of value 0, not 0 / 0: the NaN it made used to zero the whole pixel at output (the
             * default variant's BVH cut came out 45% dark on scenes/office's spots). */
            double w = p_cluster > 0.0 && p_light > 0.0 ? 1.0 / (p_cluster * p_light) : 0.0;
            vec3 ve = v3_scale(v, (float)w);
            double ly = lum_v * w;
            if (mis) {
                /* The light sample weighted against the BSDF's density of its direction, plus the
                 * paired BSDF sample (its own dimensions 10-12); the statistics above keep the
                 * light sample's unweighted value. */
                vec3 vb = v3(0, 0, 0);
                if (sh->mis_share >= 1.0 || (double)pn_sobol_sample(q, 13, scramble) < sh->mis_share)
                    vb = mis_bsdf_sample(job, sh, s, r, bsdf, origin, wo, pn_sobol_sample(q, 10, scramble),
                                         pn_sobol_sample(q, 11, scramble), pn_sobol_sample(q, 12, scramble),
                                         &s->mis_rays);
                vb = v3_mul(vb, throughput);
                if (pt) vb = v3_scale(vb, pt->share);
                ve = v3_add(v3_scale(v, (float)(w * wl)), vb);
                ly = (double)v3_luminance(ve);
            }
            r->sum += ly;
            r->sum2 += ly * ly;
            r->rgb = v3_add(r->rgb, ve);
            r->n++;
            if (lux) {
                r->lux_sum += lux_v * w;
                r->mel_sum += (double)edi * w;
                r->lux_n++;
            }
        }
    }
}

/* Stores the pass from the regions' sums: the area-weighted estimate L = sum_k w_k m_k and the
 * variance of a stratified estimate, V = sum_k w_k^2 s_k^2 / n_k (regions are sampled in
 * proportion to their area, so differences between regions are not noise). */
static void store_pass(ias_scratch *s, ias_pixel *px) {
    if (px->pass_count >= IAS_MAX_PASSES_STORED) return;
    ias_pass p;
    memset(&p, 0, sizeof p);
    if (s->ratio_mode) { /* the ratio estimator's pass (ias_ratio.h) */
        for (int k = 0; k < px->region_count; k++) {
            const ias_region *r = &s->regions[px->first_region + k];
            s->ratio_regions[k] = (pn_ias_ratio_region){r->weight, r->cut_first, r->cut_count, r->ratio_m};
        }
        pn_ias_ratio_pass(s->ratio_mode, s->ratio_smp, s->ratio_count, s->ratio_regions, px->region_count, s->cut,
                          s->cut_unshadowed, s->cut_beta, &s->ratio, &p.lum, &p.rgb, &p.s2, &p.n);
        if (p.n > 0) px->passes[px->pass_count++] = p;
        return;
    }
    for (int k = 0; k < px->region_count; k++) {
        const ias_region *r = &s->regions[px->first_region + k];
        unsigned nk = r->n;
        if (nk == 0) continue;
        double n = (double)nk, sum = r->sum, sum2 = r->sum2;
        double mean = sum / n;
        double var = n > 1.0 ? fmax(0.0, (sum2 - sum * mean) / (n - 1.0)) : 0.0;
        p.lum += r->weight * mean;
        p.rgb = v3_add(p.rgb, v3_scale(r->rgb, (float)(r->weight / n)));
        p.s2 += r->weight * r->weight * var / n;
        p.n += nk;
    }
    if (p.n > 0) px->passes[px->pass_count++] = p;
}

/* Clears the regions' sums before a pass. */
static void reset_regions(ias_scratch *s, ias_pixel *px) {
    for (int k = 0; k < px->region_count; k++) {
        ias_region *r = &s->regions[px->first_region + k];
        r->sum = r->sum2 = 0.0;
        r->n = 0;
        r->rgb = v3(0, 0, 0);
    }
    s->ratio_count = 0;
}

/* ---- member points (default variant) ---------------------------------------------------------
 *
 * The paper evaluates all of a region's shadow rays at its representative point, so a region's
 * light is its representative's: an error that no number of shadow rays removes (relMSE 1.0e-4 on
 * the generated 10^3-emitter scene at every threshold and every aa-rays count, where reference
 * reaches 4e-5). Here the region keeps the points of all its eye rays and its shadow rays leave
 * from them in turn, each sample weighted by its ray's share of the region's filter weight: the
 * region's estimate is then unbiased for the mean over its eye rays. The cut and the PDFs stay
 * the representative's (any PDF that covers the lights is unbiased). */
static bool push_point(ias_scratch *s, ptrdiff_t region, const pn_eye_path *path, const pn_bsdf *b,
                       const pn_render_job *job, float fw) {
    if (s->tmp_used == s->tmp_cap) {
        int cap = s->tmp_cap ? 2 * s->tmp_cap : (int)((const ias_shared *)job->integrator_data)->aa_rays;
        ias_point *t = realloc(s->points_tmp, (size_t)cap * sizeof *t);
        if (!t) return false;
        s->points_tmp = t;
        s->tmp_cap = cap;
    }
    ias_point *pt = &s->points_tmp[s->tmp_used++];
    pt->eps = pn_accel_ray_epsilon(job->accel, path->hit.p);
    pt->origin = v3_madd(path->hit.p, b->ng, pt->eps);
    pt->wo = path->wo;
    pt->throughput = path->throughput;
    pt->bsdf = *b;
    pt->share = fw;
    pt->region = (int)region;
    return true;
}

/* Moves the pixel's points into s->points grouped by region, and sets each point's share. */
static bool group_points(ias_scratch *s, ias_pixel *px) {
    const int n = s->tmp_used;
    if (s->point_count + n > s->point_cap) {
        int cap = s->point_cap ? s->point_cap : 1024;
        while (cap < s->point_count + n) cap *= 2;
        ias_point *p = realloc(s->points, (size_t)cap * sizeof *p);
        if (!p) return false;
        s->points = p;
        s->point_cap = cap;
    }
    for (int k = 0; k < px->region_count; k++) {
        ias_region *g = &s->regions[px->first_region + k];
        g->point_first = s->point_count;
        g->point_count = 0;
        double wsum = 0.0;
        for (int i = 0; i < n; i++) {
            const ias_point *t = &s->points_tmp[i];
            if (t->region != px->first_region + k) continue;
            s->points[s->point_count + g->point_count++] = *t;
            wsum += (double)t->share;
        }
        for (int i = 0; i < g->point_count; i++) {
            ias_point *t = &s->points[g->point_first + i];
            t->share = wsum != 0.0 ? (float)((double)t->share * (double)g->point_count / wsum) : 1.0f;
        }
        s->point_count += g->point_count;
    }
    s->tmp_used = 0;
    return true;
}

/* ---- the ratio estimator (ias-ratio, ias_ratio.h) ---------------------------------------------
 *
 * Region k of pixel px: its material factor (the mean over its points of share x throughput x
 * kd / pi: u's expectation over the points is that factor times the light's irradiance) and, per
 * cut entry with a closed form, the unshadowed irradiance at the points' centroid (x < 0: none),
 * their mean irradiance to first order. Per region, not once per pixel as the irradiance prior:
 * at the pixel's first eye ray (the same sub-pixel position in every pixel of the scrambled block
 * sequence) the closed form was 0.47% below the samples' mean on a quad over a plane; at the
 * centroid of all the pixel's regions with the same cut (10% of the render instead of 30% on
 * hall-many-matte) the image was 0.09% dark on test_ias_ratio's scene; per region 0.01%. */
static void ratio_closed_forms(const pn_render_job *job, const ias_shared *sh, ias_scratch *s, const ias_pixel *px,
                               int k) {
    ias_region *g = &s->regions[px->first_region + k];
    vec3 m = v3(0, 0, 0), at = g->origin;
    if (g->point_count > 0) {
        vec3 c = v3(0, 0, 0);
        for (int i = 0; i < g->point_count; i++) {
            const ias_point *pt = &s->points[g->point_first + i];
            m = v3_madd(m, v3_mul(pt->bsdf.kd, pt->throughput), pt->share);
            c = v3_madd(c, pt->origin, pt->share);
        }
        m = v3_scale(m, PN_INV_PI / (float)g->point_count);
        at = v3_scale(c, 1.0f / (float)g->point_count);
    } else {
        m = v3_scale(v3_mul(g->bsdf.kd, g->throughput), PN_INV_PI);
    }
    g->ratio_m = m;
    vec3 *e = s->cut_unshadowed + g->cut_first;
    for (int i = 0; i < g->cut_count; i++) {
        int id = s->cut[g->cut_first + i];
        if (id >= sh->forest.node_count ||
            !pn_ias_cluster_unshadowed(&sh->forest, job->lights, id, sh->ratio_members, at, g->bsdf.ns, &e[i]))
            e[i] = v3(-1, -1, -1);
    }
}

/* The control variate's coefficients for the pixel's next pass: each entry's visible fraction in
 * the block so far, (visible + 0.5) / (count + 1), fixed before the pass so that the estimate stays
 * unbiased (leaves' statistics are current; interior nodes' as aggregated at the pass's start). */
static void control_betas(const ias_shared *sh, ias_scratch *s, const ias_pixel *px) {
    if (sh->sparse_stats) replay_log(sh, s, &s->blog, &s->btable, -1); /* the leaves' current data */
    for (int k = 0; k < px->region_count; k++) {
        const ias_region *r = &s->regions[px->first_region + k];
        const pn_ias_stats *block = sh->sparse_stats ? NULL : s->block_stats + (size_t)r->cls * (size_t)s->id_count;
        for (int i = r->cut_first; i < r->cut_first + r->cut_count; i++) {
            if (s->cut_unshadowed[i].x < 0.0f) continue;
            const pn_ias_stats *st =
                block ? &block[s->cut[i]] : sparse_find(&s->btable, -1, (unsigned)r->cls, s->cut[i]);
            if (!st) st = &zero_stats;
            s->cut_beta[i] = ((double)st->visible + 0.5) / ((double)st->count + 1.0);
        }
    }
}

/* ---- a block --------------------------------------------------------------------------------- */

/* The smallest number of shadow rays at which a pixel whose samples saw no light may stop as
 * black under the cross rule: a pixel lit by a fraction p of its samples reaches the threshold t
 * within the budget M of a pixel only if p >= p_min = 1 / (1 + t M), and m unlit samples miss
 * such a pixel with probability (1 - p_min)^m <= exp(-m p_min), 1% at m = ln(100) / p_min. */
static uint32_t cross_black_rays(const pn_render_job *job) {
    double p_min = 1.0 / (1.0 + job->threshold * (double)job->max_shadow_rays);
    double m = ceil(log(100.0) / p_min);
    return m > (double)IAS_BLACK_RAYS ? (uint32_t)fmin(m, 4e9) : IAS_BLACK_RAYS;
}

/* The end of a pass under the cross rule: the §5.8 extension and the §5.9 tests, decided from
 * the block's other pixels (pixel_estimate_cross). */
static void ias_pass_end_cross(const pn_render_job *job, const ias_shared *sh, ias_scratch *s, ias_pixel *px, int pass,
                               uint32_t scramble, uint32_t *counter) {
    double L, relvar, rho_last;
    vec3 rgb;
    pixel_estimate_cross(s, px, &L, &relvar, &rgb, &rho_last);
    const double t = job->threshold;
    /* Within 2x of the target: the shadow rays that bring the prediction to the target, in
     * steps of 25 with the same PDFs (§5.8); the count follows from rho, not from the values. */
    if (rho_last > 0.0 && relvar >= t && relvar < 2.0 * t && px->pass_count > 0) {
        double needed = rho_last * (1.0 / t - 1.0 / relvar); /* extra shadow rays in this pass */
        unsigned steps = (unsigned)ceil(needed / IAS_STEP_SAMPLES);
        if (steps > IAS_MAX_STEPS) steps = IAS_MAX_STEPS;
        if (steps > 0) {
            px->pass_count--; /* extend this pass */
            sample_pixel(job, sh, s, px, pass, steps * IAS_STEP_SAMPLES, scramble, counter);
            store_pass(s, px);
            pixel_estimate_cross(s, px, &L, &relvar, &rgb, &rho_last);
        }
    }
    bool converged = relvar < t;
    /* Black: no visible sample after the paper's 3 passes and the binomial bound's rays. A pixel
     * that saw no light has all its values 0 already; the bound only keeps it from stopping while
     * a light its budget could measure may still be missed. */
    bool black = px->visible == 0 && pass + 1 >= IAS_BLACK_PASSES && px->shadow_rays >= cross_black_rays(job);
    px->result = v3_add(px->emitted, black ? v3(0, 0, 0) : rgb);
    px->done = converged || black || pass + 1 >= (int)job->max_passes || atomic_load(job->cancel);
}

static pn_status ias_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                  void *scratch) {
    const ias_shared *sh = job->integrator_data;
    ias_scratch *s = scratch;
    const uint32_t scramble = (uint32_t)pn_hash3(job->seed ^ 0x1a5ull, (uint64_t)(uint32_t)batch->block_x,
                                                 (uint64_t)(uint32_t)batch->block_y);
    s->region_count = 0;
    s->point_count = 0;
    s->cut_used = 0;
    s->oom = false;
    s->pool_used = 0;
    memset(s->block_class_used, 0, sizeof s->block_class_used);
    if (sh->light_guide) pn_ias_guide_begin_block(&s->guide);
    if (batch->count > s->max_pixels) return PN_ERROR_INTERNAL; /* larger than any block */
    const int np = batch->count;
    s->pixel_count = np;
    const float pixel_angle =
        2.0f * job->camera.tan_half_fov /
        (float)(job->camera.full_width < job->camera.full_height ? job->camera.full_width : job->camera.full_height);
    if (batch->hits_stride != sh->aa_rays) return PN_ERROR_INTERNAL; /* not the driver's ias_batch_hits */
    pn_eye_hit eye_chunk[IAS_EYE_CHUNK];

    /* Points and antialiasing regions (§4.4). */
    for (int pi = 0; pi < np; pi++) {
        ias_pixel *px = &s->pixels[pi];
        memset(px, 0, offsetof(ias_pixel, stats));
        memset(px->stats, 0, sizeof px->stats);
        px->first_region = s->region_count;
        memset(&out[pi], 0, sizeof out[pi]);
        out[pi].depth = INFINITY;
        vec3 emitted = v3(0, 0, 0);
        /* The pixel's eye rays, traced by the driver: its share of the block's sequence
         * (render/batch.h, PN_EYE_SEQ_IAS_BLOCK), IAS_EYE_CHUNK at a time. */
        const pn_eye_hit *hits = NULL;
        for (uint32_t r = 0; r < sh->aa_rays; r++) {
            if (r % IAS_EYE_CHUNK == 0)
                hits = pn_batch_eye_hits(job, batch, pi, PN_EYE_SEQ_IAS_BLOCK, r,
                                         sh->aa_rays - r < IAS_EYE_CHUNK ? sh->aa_rays - r : IAS_EYE_CHUNK, eye_chunk);
            const pn_eye_hit *h = &hits[r % IAS_EYE_CHUNK];
            const float rx = h->raster_x, ry = h->raster_y, fw = h->weight;
            pn_eye_path path = h->path;
            px->embree_seconds += (double)h->seconds * PN_EYE_TIMING_STRIDE; /* 0 unless timed */
            if (r == 0) {
                out[pi].depth = path.first_depth;
                out[pi].normal = path.first_normal;
                out[pi].albedo = path.first_albedo;
            }
            out[pi].specular_rays += path.rays - 1;
            emitted = v3_madd(emitted, path.emitted, fw);
            px->weight_sum += (double)fw;
            if (!v3_is_zero(path.emitted)) px->emit_hits++;
            if (!path.has_point) continue;
            pn_bsdf b;
            pn_eye_hit_bsdf(job, h, &b);
            /* Join a region of this pixel: same material, same plane, within its radius. */
            ias_region *join = NULL;
            for (int k = 0; k < px->region_count; k++) {
                ias_region *g = &s->regions[px->first_region + k];
                if (g->hit.material != path.hit.material) continue;
                if (v3_dot(g->bsdf.ng, b.ng) < 0.999f) continue;
                vec3 d = v3_sub(path.hit.p, g->hit.p);
                if (fabsf(v3_dot(d, g->bsdf.ng)) > 0.05f * g->radius + 4.0f * g->eps) continue; /* same plane */
                float dx = rx - g->raster_x, dy = ry - g->raster_y;
                if (dx * dx + dy * dy > IAS_REGION_RADIUS * IAS_REGION_RADIUS) continue;
                join = g;
                break;
            }
            if (join) {
                join->weight += (double)fw;
                if (sh->member_points && !push_point(s, join - s->regions, &path, &b, job, fw))
                    return PN_ERROR_OUT_OF_MEMORY;
                continue;
            }
            ias_region *g;
            if (!push_region(s, &g)) return PN_ERROR_OUT_OF_MEMORY;
            if (sh->member_points && !push_point(s, s->region_count - 1, &path, &b, job, fw))
                return PN_ERROR_OUT_OF_MEMORY;
            memset(g, 0, sizeof *g);
            g->pixel = pi;
            g->hit = path.hit;
            g->wo = path.wo;
            g->throughput = path.throughput;
            g->bsdf = b;
            g->eps = pn_accel_ray_epsilon(job->accel, path.hit.p);
            g->origin = v3_madd(path.hit.p, b.ng, g->eps);
            /* World size of a quarter pixel at this distance, for the plane test's tolerance. */
            g->radius = 0.25f * pixel_angle * (isfinite(path.first_depth) ? path.first_depth : path.hit.t);
            g->raster_x = rx;
            g->raster_y = ry;
            g->cls = normal_class(b.ng);
            g->weight = (double)fw;
            px->region_count++;
        }
        px->emitted = px->weight_sum != 0.0 ? v3_scale(emitted, (float)(1.0 / px->weight_sum)) : v3(0, 0, 0);
        if (sh->member_points && !group_points(s, px)) return PN_ERROR_OUT_OF_MEMORY;
        /* Trees cuts shared between the pixel's regions (compute_cut): each region not yet cut
         * leads the later ones near it, whose walks replay the decisions its walk records; the
         * members are cut right after their leader (a replay reads the latest record). */
        const bool share_cuts = s->cut_share.links && px->region_count >= 2;
        if (share_cuts) {
            const bool timed_cut = s->tick++ % IAS_REGION_TIMING_STRIDE == 0u;
            double t_cut = timed_cut ? pn_clock_seconds() : 0.0;
            for (int k = 0; k < px->region_count; k++) s->regions[px->first_region + k].cut_done = false;
            for (int k = 0; k < px->region_count; k++) {
                ias_region *lead = &s->regions[px->first_region + k];
                if (lead->cut_done) continue;
                double reach = 0.0, turn = 0.0;
                bool any = false;
                for (int j = k + 1; j < px->region_count && !v3_is_zero(lead->bsdf.ng); j++) {
                    ias_region *g = &s->regions[px->first_region + j];
                    g->member = false;
                    if (g->cut_done || v3_is_zero(g->bsdf.ng)) continue;
                    double t = sqrt((double)v3_length2(v3_sub(g->bsdf.ng, lead->bsdf.ng)));
                    double d = sqrt((double)v3_length2(v3_sub(g->origin, lead->origin)));
                    if (!(t <= IAS_SHARE_DN && d <= IAS_SHARE_REACH * (double)lead->radius)) continue;
                    g->member = any = true;
                    if (d > reach) reach = d;
                    if (t > turn) turn = t;
                }
                /* Rounded up: the ball must hold every member. */
                s->share_delta = (float)(reach * (1.0 + 1e-6)) * (1.0f + 1e-6f);
                s->share_dn = (float)(turn * (1.0 + 1e-6)) * (1.0f + 1e-6f);
                if (!compute_cut(job, sh, s, lead, any ? 1 : 0)) return PN_ERROR_OUT_OF_MEMORY;
                lead->cut_done = true;
                for (int j = k + 1; j < px->region_count && any; j++) {
                    ias_region *g = &s->regions[px->first_region + j];
                    if (!g->member || g->cut_done) continue;
                    if (!compute_cut(job, sh, s, g, 2)) return PN_ERROR_OUT_OF_MEMORY;
                    g->cut_done = true;
                }
            }
            if (timed_cut) px->cut_seconds += elapsed_since(sh, t_cut) * IAS_REGION_TIMING_STRIDE;
        }
        /* Region weights as shares of the pixel. */
        double ncl = 0.0;
        for (int k = 0; k < px->region_count; k++) {
            ias_region *g = &s->regions[px->first_region + k];
            g->weight = px->weight_sum != 0.0 ? g->weight / px->weight_sum : 0.0;
            const bool timed_cut = s->tick++ % IAS_REGION_TIMING_STRIDE == 0u;
            double t_cut = timed_cut ? pn_clock_seconds() : 0.0;
            if (!share_cuts && !compute_cut(job, sh, s, g, 0)) return PN_ERROR_OUT_OF_MEMORY;
            /* The irradiance prior of the trees' clusters (environment regions keep theirs), once
             * per pixel for regions with the same cut (the first one's point: a prior need not be
             * exact, and the polygon irradiance per region was 19% of bathroom-72-matte's time). */
            const ias_region *same = k > 0 ? &s->regions[px->first_region] : NULL;
            if (sh->irradiance_prior && same && same_cut(s, same, g))
                memcpy(s->cut_prior + g->cut_first, s->cut_prior + same->cut_first,
                       (size_t)g->cut_count * sizeof *s->cut_prior);
            else if (sh->irradiance_prior)
                for (int i = 0; i < g->cut_count; i++) {
                    int id = s->cut[g->cut_first + i];
                    if (id < sh->forest.node_count)
                        s->cut_prior[g->cut_first + i] =
                            pn_ias_cluster_irradiance(&sh->forest, job->lights, id, g->origin, g->bsdf.ng);
                }
            if (timed_cut) px->cut_seconds += elapsed_since(sh, t_cut) * IAS_REGION_TIMING_STRIDE;
            px->region_weight += g->weight;
            ncl += g->weight * (double)g->cut_count;
        }
        if (sh->ratio) {
            double t_cut = pn_clock_seconds();
            for (int k = 0; k < px->region_count; k++) ratio_closed_forms(job, sh, s, px, k);
            px->cut_seconds += elapsed_since(sh, t_cut);
        }
        px->clusters = px->region_weight > 0.0 ? ncl / px->region_weight : 0.0;
        out[pi].eye_rays = sh->aa_rays;
        out[pi].aa_regions = (uint32_t)px->region_count;
        bool any_cluster = false;
        for (int k = 0; k < px->region_count; k++) any_cluster |= s->regions[px->first_region + k].cut_count > 0;
        if (!any_cluster) { /* nothing can light this pixel: only what its eye rays saw */
            px->done = true;
            px->result = px->emitted;
        }
    }

    /* Emitter rays (default variant, ias_speed.h): pixels whose neighbours' eye rays saw an emitter
     * edge take emitter_rays eye rays in all for the emitted term, before any test uses it. */
    if (sh->emitter_rays > sh->aa_rays) {
        for (int pi = 0; pi < np; pi++) s->emit_hits[pi] = s->pixels[pi].emit_hits;
        for (int pi = 0; pi < np; pi++) {
            ias_pixel *px = &s->pixels[pi];
            if (!pn_ias_emitter_edge(batch->pixels, s->emit_hits, sh->aa_rays, np, pi)) continue;
            vec3 e = v3_scale(px->emitted, (float)px->weight_sum);
            double w = px->weight_sum;
            uint32_t calls = pn_ias_emitter_rays(job, batch, pi, sh->emitter_rays - sh->aa_rays, &e, &w);
            px->emitted = w != 0.0 ? v3_scale(e, (float)(1.0 / w)) : v3(0, 0, 0);
            out[pi].eye_rays += sh->emitter_rays - sh->aa_rays;
            out[pi].specular_rays += calls - (sh->emitter_rays - sh->aa_rays);
            if (px->done) px->result = px->emitted;
        }
    }

    /* Passes (§4.1, §4.2, §5.8, §5.9). */
    uint32_t counter = 0;
    for (int pass = 0; pass < (int)job->max_passes; pass++) {
        bool any = false;
        if (pass > 0 && !sh->bvh_cut) {
            double t_pdf = pn_clock_seconds();
            if (sh->sparse_stats)
                sparse_refresh_block(sh, s);
            else
                refresh_block_feedback(sh, s);
            s->pixels[0].pdf_seconds += elapsed_since(sh, t_pdf); /* the block's share, on its first pixel */
        }
        if (pass > 0 && sh->light_guide) pn_ias_guide_refresh(&s->guide);
        for (int pi = 0; pi < np; pi++) {
            ias_pixel *px = &s->pixels[pi];
            if (px->done) continue;
            any = true;
            reset_regions(s, px);
            const bool timed_pdf = s->tick++ % IAS_REGION_TIMING_STRIDE == 0u;
            double t_pdf = timed_pdf ? pn_clock_seconds() : 0.0;
            flush_pending(s); /* the previous pixel pass's evaluations (default variant) */
            if (sh->sparse_stats)
                sparse_begin_pixel(sh, s, px);
            else if (!sh->bvh_cut)
                begin_pixel_feedback(sh, s, px);
            if (sh->ratio == PN_IAS_RATIO_CONTROL) control_betas(sh, s, px);
            if (timed_pdf) px->pdf_seconds += elapsed_since(sh, t_pdf) * IAS_REGION_TIMING_STRIDE;
            /* 1.5 N_C samples, at least 50 (§5.8); the default variant: (j + 1) pass_rays. */
            unsigned count = (unsigned)ceil(1.5 * px->clusters);
            if (count < IAS_MIN_SAMPLES) count = IAS_MIN_SAMPLES;
            /* The default variant: (j + 1) pass_rays, but never fewer than 1.5 N_C. With the BVH
             * cut N_C is at most the cut size plus the distant lights and environment regions,
             * so it does not grow with the number of emitters; without the floor, 32 rays over
             * living-env-138-matte's ~316 clusters left the feedback too few samples per cluster
             * (relMSE 0.020 and 2.8% dark at threshold 0.01; 0.0044 and 0.8% with it). */
            if (sh->pass_rays) {
                unsigned grown = (unsigned)(pass + 1) * sh->pass_rays;
                count = (unsigned)ceil(1.5 * px->clusters);
                if (grown > count) count = grown;
            }
            /* ias-guide-refresh: the first pass's later pixels sample through the grids of what the
             * block's earlier pixels found (rebuilt before the pixel, so its samples share one PDF). */
            if (sh->guide_refresh && pass == 0 && pi > 0 && pi % (int)sh->guide_refresh == 0)
                pn_ias_guide_refresh(&s->guide);
            /* ias-guide-rotate: the pixel's guided numbers shifted independently of the samples
             * that built the grids (ias_guide.h, pn_ias_guide_set_rotation). */
            if (sh->guide_rotate)
                pn_ias_guide_set_rotation(&s->guide, pn_hash3(job->seed ^ 0x67d1ull, (uint64_t)scramble,
                                                              (uint64_t)(uint32_t)pi << 32 | (uint32_t)pass));
            sample_pixel(job, sh, s, px, pass, count, scramble, &counter);
            store_pass(s, px);
            if (job->adaptive_rule == PN_ADAPTIVE_CROSS) {
                ias_pass_end_cross(job, sh, s, px, pass, scramble, &counter);
                continue;
            }
            double L, s2;
            vec3 rgb;
            pixel_estimate(s, px, &L, &s2, &rgb);
            double Lt = L + (double)v3_luminance(px->emitted);
            /* Close to the target (within 2x): more samples with the same PDFs, in steps of 25
             * (§5.8). How many steps is decided once, from the variance falling as 1/n, instead of
             * testing after every step: stopping the moment a noisy estimate first dips below the
             * target made the image 5% too dark on tests/test_ias.c's scene (termination bias). */
            if (Lt > 0.0 && s2 >= job->threshold * Lt * Lt && s2 < 2.0 * job->threshold * Lt * Lt) {
                unsigned n_pass = px->passes[px->pass_count - 1].n;
                double needed = (double)n_pass * (s2 / (job->threshold * Lt * Lt) - 1.0);
                unsigned steps = (unsigned)ceil(needed / IAS_STEP_SAMPLES);
                if (steps > IAS_MAX_STEPS) steps = IAS_MAX_STEPS;
                if (steps > 0) {
                    px->pass_count--; /* extend this pass */
                    sample_pixel(job, sh, s, px, pass, steps * IAS_STEP_SAMPLES, scramble, &counter);
                    store_pass(s, px);
                    pixel_estimate(s, px, &L, &s2, &rgb);
                    Lt = L + (double)v3_luminance(px->emitted);
                }
            }
            bool converged = Lt > 0.0 && s2 < job->threshold * Lt * Lt;
            bool black = px->visible == 0 && pass + 1 >= IAS_BLACK_PASSES && px->shadow_rays >= IAS_BLACK_RAYS;
            if (black) rgb = v3(0, 0, 0);
            px->result = v3_add(px->emitted, rgb);
            px->done = converged || black || pass + 1 >= (int)job->max_passes || atomic_load(job->cancel);
        }
        flush_pending(s);
        if (!any) break;
    }

    for (int pi = 0; pi < np; pi++) {
        ias_pixel *px = &s->pixels[pi];
        out[pi].radiance = v3_is_finite(px->result) ? px->result : v3(0, 0, 0);
        out[pi].non_finite = v3_is_finite(px->result) ? 0u : 1u;
        /* PN_AOV_ILLUMINANCE: the regions' pooled estimates, weighted by area as the radiance. */
        double lux = 0.0, mel = 0.0; /* PN_AOV_MELANOPIC_EDI: the same pooling */
        for (int k = 0; k < px->region_count; k++) {
            const ias_region *g = &s->regions[px->first_region + k];
            if (g->lux_n == 0) continue;
            lux += g->weight * g->lux_sum / (double)g->lux_n;
            mel += g->weight * g->mel_sum / (double)g->lux_n;
        }
        if (isfinite(lux)) out[pi].illuminance = (float)lux;
        if (isfinite(mel)) out[pi].melanopic_edi = (float)mel;
        out[pi].emitted = v3_is_finite(px->result) && v3_is_finite(px->emitted) ? px->emitted : v3(0, 0, 0);
        out[pi].shadow_rays = px->shadow_rays;
        out[pi].passes = (uint32_t)px->pass_count;
        out[pi].clusters = (float)px->clusters;
        out[pi].visible_fraction = px->shadow_rays ? (float)px->visible / (float)px->shadow_rays : 0.0f;
        out[pi].visible_lights = px->visible_lights;
        out[pi].embree_seconds = (float)px->embree_seconds;
        out[pi].cut_seconds = (float)px->cut_seconds;
        out[pi].pdf_seconds = (float)px->pdf_seconds;
        double L, s2;
        vec3 rgb;
        if (job->adaptive_rule == PN_ADAPTIVE_CROSS) {
            double relvar, rho_last;
            pixel_estimate_cross(s, px, &L, &relvar, &rgb, &rho_last);
            s2 = relvar * L * L;
        } else {
            pixel_estimate(s, px, &L, &s2, &rgb);
        }
        double Lt = L + (double)v3_luminance(px->emitted);
        out[pi].relative_variance = Lt > 0.0 && isfinite(s2) ? (float)(s2 / (Lt * Lt)) : 0.0f;
    }
    /* Block and pixel data are cleared when the block ends (§3.2). */
    if (sh->sparse_stats) {
        add_work(s->btable.used);
        table_clear(&s->btable);
        for (int pi = 0; pi < np; pi++) {
            add_work(s->ptables[pi].used);
            table_clear(&s->ptables[pi]);
            s->plogs[pi].count = s->plogs[pi].done = 0;
        }
        s->blog.count = s->blog.done = 0;
        s->r_ready = false; /* ias-stats cut: the next block's cuts make its own R */
        if (s->oom) return PN_ERROR_OUT_OF_MEMORY;
        return PN_OK;
    }
    for (int c = 0; c < IAS_CLASSES; c++)
        if (s->block_class_used[c]) {
            memset(s->block_stats + (size_t)c * (size_t)s->id_count, 0, (size_t)s->id_count * sizeof *s->block_stats);
            if (!sh->bvh_cut) add_work((uint64_t)s->id_count);
        }
    memset(s->pixel_pool, 0, (size_t)s->pool_used * (size_t)s->id_count * sizeof *s->pixel_pool);
    if (!sh->bvh_cut) add_work((uint64_t)s->pool_used * (uint64_t)s->id_count);
    if (sh->bvh_cut)
        table_clear(&s->table);
    else
        memset(s->pixel_seen, 0, (size_t)np * (size_t)s->visible_slots);
    return PN_OK;
}

/* Table 5 "per viewpoint": lights and environment regions seen unoccluded anywhere. */
static void ias_report(const pn_render_job *job, pn_render_stats *stats) {
    const ias_shared *sh = job->integrator_data;
    uint32_t lights = 0, regions = 0;
    for (int i = 0; i < sh->visible_slots; i++) {
        if (!atomic_load_explicit(&sh->seen[i], memory_order_relaxed)) continue;
        if (i < sh->light_count)
            lights++;
        else
            regions++;
    }
    stats->lights_visible_viewpoint = lights;
    stats->env_regions_visible_viewpoint = regions;
}

/* The eye rays every pixel takes (all of its eye rays), which the drivers trace in advance. */
static uint32_t ias_batch_hits(const pn_render_job *job) {
    return ias_eye_rays(job, job->ias_variant == PN_IAS_VARIANT_PAPER);
}

const pn_integrator pn_integrator_ias = {
    .name = "ias",
    .prepare = ias_prepare,
    .release = ias_release,
    .report = ias_report,
    .scratch_create = ias_scratch_create,
    .scratch_free = ias_scratch_free,
    .render_batch = ias_render_batch,
    .batch_hits = ias_batch_hits,
    .batch_hits_seq = PN_EYE_SEQ_IAS_BLOCK,
};
