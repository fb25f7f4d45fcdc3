/* registry.c — the one table of methods and options (ARCHITECTURE.md, "One table of methods").
 *
 * Every integrator and driver is one entry of `methods` below: name, description, paper, what it
 * computes, capabilities, AOVs and statistics. Every option is one entry of `options`, declared
 * once with its type, default, range, unit and help, the methods it applies to and the
 * pn_render_job field it fills. Help text (`penumbra methods`, `penumbra render --integrator X
 * --help`), validation ("does not apply to ias"), the statistics JSON and docs/options.md come
 * from these two tables; pn_render resolves a pn_options handle through them into the job, so
 * that the integrators read plain fields. */
#include "integrators/registry.h"

#include "core/context.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Method indices (the order of the table, which is the order `penumbra methods` lists). */
enum {
    M_REFERENCE,
    M_IAS,
    M_CONTOUR,
    M_CONTOUR_MC,
    M_VPL,
    M_LIGHTCUTS,
    M_ILLUMCUT,
    M_TILES,
    M_FULL,
    M_DCM,
    M_PAINTER,
    M_UNIFORM,
    M_COUNT
};
#define BIT(m) (1u << (m))
#define VPL_FAMILY (BIT(M_VPL) | BIT(M_LIGHTCUTS) | BIT(M_ILLUMCUT))
#define CONTOUR_FAMILY (BIT(M_CONTOUR) | BIT(M_CONTOUR_MC))
#define PROGRESSIVE_DRIVERS (BIT(M_FULL) | BIT(M_DCM) | BIT(M_PAINTER) | BIT(M_UNIFORM))

#define DIRECT                                                                                                         \
    "direct light only: the emitters' light reflected once, and emitters seen directly or through specular chains"
#define GLOBAL                                                                                                         \
    "global illumination through VPLs (light paths of --vpl-depth bounces), direct light included; direct light only " \
    "with --vpl-direct-only or a scene of maxdepth 1"
#define PROG_AOVS (PN_AOV_SAMPLING_PATTERN | PN_AOV_BLOCK_MAP | PN_AOV_BLOCK_DIRECTION)
#define PROG_CAPS (PN_CAP_PROGRESSIVE | PN_CAP_CROP | PN_CAP_OWN_AOVS)

static const pn_method_entry methods[M_COUNT] = {
    [M_REFERENCE] =
        {{"reference", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_REFERENCE,
          "Monte Carlo reference: shadow rays to lights chosen by unoccluded irradiance (or pbrt-v4's light BVH)",
          "Donikian et al. 2006, section 5.1", DIRECT,
          PN_CAP_PER_PIXEL | PN_CAP_PROGRESSIVE | PN_CAP_CROP | PN_CAP_SPP | PN_CAP_THRESHOLD | PN_CAP_EMITTED |
              PN_CAP_EYE_SAMPLES,
          PN_AOV_ILLUMINANCE | PN_AOV_MELANOPIC_EDI, "", 64},
         &pn_integrator_reference},
    /* Not PN_CAP_PROGRESSIVE (issue 18): refused by dcm, painter and uniform for the reason
     * IAS_NOT_PROGRESSIVE gives; the full driver, whose batches are whole blocks, takes it. */
    [M_IAS] = {{"ias", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_IAS,
                "Iterative Adaptive Sampling: per-block PDFs over light clusters, refined pass by pass",
                "Donikian et al. 2006, Accurate Direct Illumination Using Iterative Adaptive Sampling", DIRECT,
                PN_CAP_PER_BLOCK | PN_CAP_CROP | PN_CAP_THRESHOLD | PN_CAP_EMITTED,
                PN_AOV_PASSES | PN_AOV_AA_REGIONS | PN_AOV_CLUSTERS | PN_AOV_VISIBLE_FRACTION | PN_AOV_ILLUMINANCE |
                    PN_AOV_MELANOPIC_EDI,
                "ias_tables", 0},
               &pn_integrator_ias},
    [M_CONTOUR] = {{"contour", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_CONTOUR,
                    "Approximate Contour Integration of planar convex area lights along scanline spans; other "
                    "lights as reference",
                    "Vedel 1993, Computing Illumination from Area Light Sources by Approximate Contour Integration",
                    DIRECT, PN_CAP_WHOLE_IMAGE | PN_CAP_PROGRESSIVE | PN_CAP_CROP | PN_CAP_SPP,
                    PN_AOV_GRADIENT | PN_AOV_ILLUMINANCE | PN_AOV_MELANOPIC_EDI, "contour_rays", 1},
                   &pn_integrator_contour},
    [M_CONTOUR_MC] = {{"contour-mc", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_CONTOUR_MC,
                       "contour's comparison: adaptive Monte Carlo sampling of the same area lights",
                       "Kok & Jansen 1992, Adaptive Sampling of Area Light Sources in Ray Tracing", DIRECT,
                       PN_CAP_PER_BLOCK | PN_CAP_PROGRESSIVE | PN_CAP_CROP | PN_CAP_SPP,
                       PN_AOV_GRADIENT | PN_AOV_ILLUMINANCE | PN_AOV_MELANOPIC_EDI, "contour_rays", 1},
                      &pn_integrator_contour_mc},
    [M_VPL] = {{"vpl", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_VPL,
                "every shading point against every virtual point light (the reference of IlluminationCut)",
                "Keller 1997, Instant Radiosity", GLOBAL,
                PN_CAP_PER_PIXEL | PN_CAP_PROGRESSIVE | PN_CAP_CROP | PN_CAP_SPP,
                PN_AOV_ILLUMINANCE | PN_AOV_MELANOPIC_EDI, "vpl_cuts", 1},
               &pn_integrator_vpl},
    [M_LIGHTCUTS] = {{"lightcuts", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_LIGHTCUTS,
                      "Lightcuts: a cut of the VPL tree per shading point under a relative error bound",
                      "Walter et al. 2005, Lightcuts: A Scalable Approach to Illumination", GLOBAL,
                      PN_CAP_PER_PIXEL | PN_CAP_PROGRESSIVE | PN_CAP_CROP | PN_CAP_SPP,
                      PN_AOV_BOUND_EVALUATIONS | PN_AOV_CUT_SIZE | PN_AOV_ILLUMINANCE | PN_AOV_MELANOPIC_EDI,
                      "vpl_cuts", 1},
                     &pn_integrator_lightcuts},
    [M_ILLUMCUT] = {{"illumcut", PN_METHOD_INTEGRATOR, PN_INTEGRATOR_ILLUMCUT,
                     "IlluminationCut: cuts of the product of a point tree and the VPL tree, over the whole image",
                     "Bus et al. 2015, IlluminationCut", GLOBAL, PN_CAP_WHOLE_IMAGE | PN_CAP_PROGRESSIVE | PN_CAP_SPP,
                     PN_AOV_BOUND_EVALUATIONS | PN_AOV_CUT_SIZE | PN_AOV_PHASE1 | PN_AOV_ILLUMINANCE |
                         PN_AOV_MELANOPIC_EDI,
                     "vpl_cuts", 1},
                    &pn_integrator_illumcut},
    [M_TILES] = {{"tiles", PN_METHOD_DRIVER, PN_DRIVER_DEFAULT,
                  "the default: every pixel of the window, in square blocks handed to the worker threads", "",
                  "every pixel at the output resolution", PN_CAP_CROP | PN_CAP_DISTRIBUTED, 0, "", 0},
                 NULL},
    [M_FULL] = {{"full", PN_METHOD_DRIVER, PN_DRIVER_FULL,
                 "every pixel of the work image (work-scale x the resolution), then the Gaussian filter: the "
                 "baseline of the progressive drivers",
                 "Guo 1998 (its full-evaluation baseline)", "every work pixel", PROG_CAPS, PROG_AOVS, "progressive", 0},
                NULL},
    [M_DCM] = {{"dcm", PN_METHOD_DRIVER, PN_DRIVER_DCM,
                "Directional Coherence Maps: a few percent of the work pixels, edges found and interpolated along "
                "their least-discrepancy direction",
                "Guo 1998, Progressive Radiance Evaluation using Directional Coherence Maps",
                "a subset of the work pixels, the rest interpolated", PROG_CAPS, PROG_AOVS, "progressive", 0},
               NULL},
    [M_PAINTER] = {{"painter", PN_METHOD_DRIVER, PN_DRIVER_PAINTER,
                    "adaptive progressive refinement by a k-d tree of samples",
                    "Painter & Sloan 1989, Antialiased Ray Tracing by Adaptive Progressive Refinement",
                    "a subset of the work pixels, the rest interpolated", PROG_CAPS, PROG_AOVS, "progressive", 0},
                   NULL},
    [M_UNIFORM] = {{"uniform", PN_METHOD_DRIVER, PN_DRIVER_UNIFORM,
                    "regular subdivision only: uniform subsampling and bilinear interpolation", "",
                    "a regular subset of the work pixels, the rest interpolated", PROG_CAPS, PROG_AOVS, "progressive",
                    0},
                   NULL},
};

#define F(field) offsetof(pn_render_job, field)
#define UINT32_TOP 4294967295.0

/* name, type, default, min, max, min_exclusive, max_exclusive, unit, choices, help; methods,
 * field offset, field kind, choice base */
static const pn_option_decl options[] = {
    /* reference */
    {{"light-sampler", PN_OPTION_CHOICE, "irradiance", 0, 0, 0, 0, "", "irradiance,bvh",
      "how a light is chosen for each shadow ray: a PDF over all lights by unoccluded irradiance (section 5.1) "
      "or pbrt-v4's light BVH"},
     BIT(M_REFERENCE),
     F(light_sampler),
     PN_FIELD_INT,
     PN_LIGHT_SAMPLER_IRRADIANCE},
    {{"shadow-rays", PN_OPTION_INT, "4", 1, 65536, 0, 0, "rays", "",
      "shadow rays per eye ray (contour, contour-mc: for the lights they do not integrate themselves)"},
     BIT(M_REFERENCE) | CONTOUR_FAMILY,
     F(shadow_rays),
     PN_FIELD_U32,
     0},
    {{"max-samples", PN_OPTION_INT, "20000", 1, UINT32_TOP, 0, 0, "rays", "",
      "at most this many shadow rays per pixel (section 5.9)"},
     BIT(M_REFERENCE),
     F(max_shadow_rays),
     PN_FIELD_U32,
     0},
    {{"min-shadow-rays-black", PN_OPTION_INT, "2500", 1, UINT32_TOP, 0, 0, "rays", "",
      "shadow rays before an adaptive pixel may be declared black (section 5.9)"},
     BIT(M_REFERENCE),
     F(min_shadow_rays_black),
     PN_FIELD_U32,
     0},
    {{"min-eye-rays", PN_OPTION_INT, "4", 1, 1048576, 0, 0, "rays", "",
      "eye rays per pixel before the adaptive threshold test"},
     BIT(M_REFERENCE),
     F(min_eye_rays),
     PN_FIELD_U32,
     0},
    {{"adaptive-rule", PN_OPTION_CHOICE, "auto", 0, 0, 0, 0, "", "auto,paper,cross",
      "with a threshold, when a pixel stops taking eye rays: 'cross' (two independent eye-ray streams, each "
      "sized by the other's pilot: unbiased; ias: the test on the block's other pixels), 'paper' (s^2/L^2 of "
      "the kept samples, sections 5.1 and 5.9: biased) or 'auto' (cross for reference, paper for ias, the "
      "faster of the two on the bench scenes: docs/adaptive-sampling.md)"},
     BIT(M_REFERENCE) | BIT(M_IAS),
     F(adaptive_rule),
     PN_FIELD_INT,
     PN_ADAPTIVE_AUTO},
    /* ias */
    {{"cluster-solid-angle", PN_OPTION_DOUBLE, "0.02", 0, 12.6, 1, 0, "sr", "",
      "largest solid angle of a light cluster seen from a point"},
     BIT(M_IAS),
     F(cluster_solid_angle),
     PN_FIELD_F32,
     0},
    {{"aa-rays", PN_OPTION_INT, "32", 1, 4096, 0, 0, "rays", "",
      "eye rays per pixel grouped into antialiasing regions"},
     BIT(M_IAS),
     F(aa_rays),
     PN_FIELD_U32,
     0},
    {{"env-regions", PN_OPTION_INT, "300", 1, 100000, 0, 0, "regions", "", "regions of an environment map"},
     BIT(M_IAS),
     F(env_regions),
     PN_FIELD_U32,
     0},
    {{"max-passes", PN_OPTION_INT, "15", 1, 64, 0, 0, "passes", "", "passes per block"},
     BIT(M_IAS),
     F(max_passes),
     PN_FIELD_U32,
     0},
    {{"ias-variant", PN_OPTION_CHOICE, "default", 0, 0, 0, 0, "", "default,paper",
      "'paper': Donikian et al. 2006 exactly as published (the other ias-* options are ignored); 'default': the "
      "departures chosen by ias-cut, ias-prior and ias-pass-rays (docs/methods/ias.md)"},
     BIT(M_IAS),
     F(ias_variant),
     PN_FIELD_INT,
     PN_IAS_VARIANT_DEFAULT},
    {{"ias-cut", PN_OPTION_CHOICE, "trees", 0, 0, 0, 0, "", "trees,bvh",
      "default variant: the clusters of a point, 'trees' (the paper's cut of the cluster trees by solid angle) or "
      "'bvh' (a cut of the light BVH by importance with at most ias-cut-size nodes: cost per point independent of "
      "the number of lights)"},
     BIT(M_IAS),
     F(ias_cut),
     PN_FIELD_INT,
     PN_IAS_CUT_TREES},
    {{"ias-cut-size", PN_OPTION_INT, "16", 1, 4096, 0, 0, "clusters", "",
      "default variant with ias-cut bvh: most light-BVH nodes in a point's cut"},
     BIT(M_IAS),
     F(ias_cut_size),
     PN_FIELD_U32,
     0},
    {{"ias-cut-max", PN_OPTION_INT, "0", 0, 1000000, 0, 0, "clusters", "",
      "default variant with the cluster trees' cut: most clusters in a point's cut, the trees refined largest "
      "solid angle first until the cap (clusters left above cluster-solid-angle pick their light by power); 0: no "
      "cap, the paper's cut"},
     BIT(M_IAS),
     F(ias_cut_max),
     PN_FIELD_U32,
     0},
    {{"ias-stats", PN_OPTION_CHOICE, "cut", 0, 0, 0, 0, "", "tree,cut",
      "default variant with the cluster trees' cut and many cluster ids (the hash-table statistics, from about "
      "30,000 emitters): a sample's statistics kept at every tree node above its light ('tree', the paper's "
      "numbers bit for bit) or only at the nodes of the block's cuts above it ('cut': the same sums up to "
      "rounding, work per sample independent of the tree's depth below the cut)"},
     BIT(M_IAS),
     F(ias_stats),
     PN_FIELD_INT,
     PN_IAS_STATS_TREE},
    {{"ias-cluster-pick", PN_OPTION_CHOICE, "power", 0, 0, 0, 0, "", "power,importance,large",
      "default variant with the cluster trees' cut: the light a shadow ray takes within its cluster, in proportion "
      "to the lights' power ('power', the paper's) or by a descent of the cluster's subtree choosing each child in "
      "proportion to a bound on its unoccluded irradiance at the shading point ('importance': power times bounds "
      "of the emitting and incident cosines over the child's bounding sphere, over the squared distance; 'large': "
      "that descent only while the node subtends cluster-solid-angle or more, by power below, so that only the "
      "clusters a capped cut leaves large change)"},
     BIT(M_IAS),
     F(ias_cluster_pick),
     PN_FIELD_INT,
     PN_IAS_PICK_POWER},
    {{"ias-prior", PN_OPTION_CHOICE, "importance", 0, 0, 0, 0, "", "uniform,importance",
      "default variant: the PDF of the first pass and the share eq. 6 gives c_U, 'uniform' over the clusters (the "
      "paper) or by each cluster's importance (with ias-cut bvh its unoccluded-irradiance bound; with the trees "
      "cut its unoccluded irradiance, 5% kept uniform)"},
     BIT(M_IAS),
     F(ias_prior),
     PN_FIELD_INT,
     PN_IAS_PRIOR_UNIFORM},
    {{"ias-points", PN_OPTION_CHOICE, "members", 0, 0, 0, 0, "", "representative,members",
      "default variant: where a region's shadow rays leave from, its 'representative' point (the paper) or its "
      "eye rays' own points in turn ('members': no error from the region's extent)"},
     BIT(M_IAS),
     F(ias_points),
     PN_FIELD_INT,
     PN_IAS_POINTS_REPRESENTATIVE},
    {{"ias-cluster-numbers", PN_OPTION_CHOICE, "sobol", 0, 0, 0, 0, "", "jittered,sobol",
      "default variant: the number that chooses a shadow ray's cluster, 'jittered' (stratum i of the region's n "
      "samples jittered by the Sobol number, the paper's) or 'sobol' (the Sobol number itself)"},
     BIT(M_IAS),
     F(ias_cluster_numbers),
     PN_FIELD_INT,
     PN_IAS_NUMBERS_JITTERED},
    {{"ias-pass-rays", PN_OPTION_INT, "32", 0, 65536, 0, 0, "rays", "",
      "default variant: shadow rays per pixel in pass j, (j + 1) times this but at least 1.5 N_C (0: the paper's "
      "1.5 N_C, at least 50)"},
     BIT(M_IAS),
     F(ias_pass_rays),
     PN_FIELD_U32,
     0},
    {{"ias-aa-threshold", PN_OPTION_DOUBLE, "0.01", 0, 1, 0, 0, "", "",
      "default variant: below this threshold a pixel takes aa-rays x this / threshold eye rays (at most 4096), so "
      "that the antialiasing regions' error falls with the threshold too (0: always aa-rays, the paper's; with "
      "adaptive-rule cross the unbiased converging rule of docs/adaptive-sampling.md)"},
     BIT(M_IAS),
     F(ias_aa_threshold),
     PN_FIELD_F64,
     0},
    {{"ias-aa-power", PN_OPTION_DOUBLE, "1", 0.05, 1, 0, 0, "", "",
      "default variant: below ias-aa-threshold T0 a pixel takes aa-rays x (T0 / threshold)^this eye rays (1: in "
      "proportion to 1 / threshold; 0.5: to its square root, the balance of eye and shadow rays measured on "
      "hall-many, docs/methods/ias.md)"},
     BIT(M_IAS),
     F(ias_aa_power),
     PN_FIELD_F64,
     0},
    {{"ias-prior-share", PN_OPTION_DOUBLE, "0", 0, 1, 0, 0, "", "",
      "default variant with ias-cut bvh: the least weight the prior (ias-prior) keeps in every pass's PDF, a "
      "defensive mixture with the learned PDFs (0: the paper's Fig. 2 weights)"},
     BIT(M_IAS),
     F(ias_prior_share),
     PN_FIELD_F64,
     0},
    {{"ias-env-floor", PN_OPTION_DOUBLE, "2", 0, 1000, 0, 0, "", "",
      "default variant with the cluster trees' cut: in every pass an environment region keeps at least this times "
      "its pass-0 probability, a defensive floor against the rare bright samples of regions the feedback gave up "
      "(0: the paper's Fig. 2 weights alone)"},
     BIT(M_IAS),
     F(ias_env_floor),
     PN_FIELD_F64,
     0},
    {{"ias-emitter-rays", PN_OPTION_INT, "256", 0, 65536, 0, 0, "rays", "",
      "default variant: a pixel whose neighbours' eye rays saw an emitter's edge takes this many eye rays in all "
      "for what it sees directly (no shadow rays; the decision does not use the pixel's own rays, so it adds no "
      "bias); 0 or at most aa-rays: none"},
     BIT(M_IAS),
     F(ias_edge_rays),
     PN_FIELD_U32,
     0},
    {{"ias-ratio", PN_OPTION_CHOICE, "off", 0, 0, 0, 0, "", "off,pixel,cluster,control",
      "default variant, trees cut: where a light's (or small cluster's) unshadowed irradiance has a closed form, "
      "the estimate takes it and the shadow rays only estimate the visible fraction (Heitz et al. 2018's ratio "
      "estimator): 'pixel' (one ratio over the pixel's samples), 'cluster' (a ratio per cluster), 'control' (a "
      "control variate with the block's visible fraction learned so far: unbiased), 'off' (the plain estimate)"},
     BIT(M_IAS),
     F(ias_ratio),
     PN_FIELD_INT,
     0},
    {{"ias-ratio-members", PN_OPTION_INT, "1", 1, 4096, 0, 0, "lights", "",
      "default variant with ias-ratio: most lights in a cluster whose closed form (the sum of its lights') is used"},
     BIT(M_IAS),
     F(ias_ratio_members),
     PN_FIELD_U32,
     0},
    {{"ias-mis", PN_OPTION_CHOICE, "off", 0, 0, 0, 0, "", "off,on,glossy",
      "default variant, trees cut, RGB: each shadow ray's light sample is paired with a BSDF-sampled ray whose hits "
      "on area lights and the environment are weighted against ias's own light-sampling PDF by the power "
      "heuristic (multiple importance sampling), 'on' at every shaded point, 'glossy' only at points with a glossy "
      "lobe, 'off' light samples only; with 'on' or 'glossy' the light guide (ias-light-guide) is off"},
     BIT(M_IAS),
     F(ias_mis),
     PN_FIELD_INT,
     0},
    {{"ias-mis-share", PN_OPTION_DOUBLE, "1", 0, 1, 1, 0, "", "",
      "default variant with ias-mis: the expected BSDF rays per light sample (each light sample takes one with this "
      "probability; the MIS weights count the BSDF strategy's density times it)"},
     BIT(M_IAS),
     F(ias_mis_share),
     PN_FIELD_F64,
     0},
    {{"ias-light-guide", PN_OPTION_CHOICE, "on", 0, 0, 0, 0, "", "off,on",
      "default variant: 'on' learns, per block, where large rectangle and triangle lights are visible (an 8 x 8 "
      "grid over each light's sample square, following the contribution its samples found, 20% kept uniform) and "
      "samples those lights through it (unbiased: the pdf carries the grid's density); 'off' samples them "
      "uniformly (the paper's)"},
     BIT(M_IAS),
     F(ias_light_guide),
     PN_FIELD_INT,
     0},
    {{"ias-guide-rotate", PN_OPTION_CHOICE, "on", 0, 0, 0, 0, "", "off,on",
      "default variant with ias-light-guide on: 'on' rotates the numbers a grid warps (mod 1) by a shift drawn "
      "per pixel and pass, so that they are independent of the block's earlier samples that built the grid (a "
      "block's numbers are one Sobol sequence; without it the guide measured 0.09% dark at 2 passes on "
      "tests/test_ias_guide.c's scene); 'off' warps them as they come (ias-guide-refresh always rotates)"},
     BIT(M_IAS),
     F(ias_guide_rotate),
     PN_FIELD_INT,
     0},
    {{"ias-guide-refresh", PN_OPTION_INT, "0", 0, 4096, 0, 0, "pixels", "",
      "default variant with ias-light-guide on: in a block's first pass, the grids are rebuilt from the block's "
      "samples so far before every this many pixels (the block's later pixels then sample through what its earlier "
      "ones found; unbiased, and the same for any thread count: a block is one worker's); 0: the first pass "
      "samples the lights' whole squares, the grids being built between passes only"},
     BIT(M_IAS),
     F(ias_guide_refresh),
     PN_FIELD_U32,
     0},
    /* tiles */
    {{"block-size", PN_OPTION_INT, "8", 8, 32, 0, 0, "pixels", "",
      "pixels per side of the square blocks handed to the integrator (ias: its block of section 3.2)"},
     BIT(M_TILES),
     F(block_size),
     PN_FIELD_U32,
     0},
    /* tiles: distribution over processes, pieces and checkpoints (docs/distributed.md) */
    {{"tile-size", PN_OPTION_INT, "0", 0, 65536, 0, 0, "pixels", "",
      "side of the square tiles that MPI ranks, --piece pieces and --checkpoint records are made of, rounded up to a "
      "multiple of block-size; 0: 64, or one tile of the whole window for an integrator without crop-exact pixels "
      "(illumcut: each tile is one point tree, the same in one process as in many)"},
     BIT(M_TILES),
     F(tile_size),
     PN_FIELD_U32,
     0},
    {{"piece", PN_OPTION_STRING, "", 0, 0, 0, 0, "", "",
      "render only piece K of M (K/M, 1 <= K <= M): a band of whole rows of tiles, the bands balanced by tile count, "
      "written as a crop EXR; penumbra merge assembles the M pieces"},
     BIT(M_TILES),
     F(tiles_piece),
     PN_FIELD_STRING,
     0},
    {{"checkpoint", PN_OPTION_STRING, "", 0, 0, 0, 0, "", "",
      "record each finished tile in this file and, when it exists, resume from it (refused if it was written for "
      "another scene, options or seed)"},
     BIT(M_TILES),
     F(checkpoint_path),
     PN_FIELD_STRING,
     0},
    {{"tile-times", PN_OPTION_STRING, "", 0, 0, 0, 0, "", "",
      "bench instrumentation: write each tile's window and render seconds to this file (one process; "
      "bench/mpi/simulate.py replays them)"},
     BIT(M_TILES),
     F(tile_times_path),
     PN_FIELD_STRING,
     0},
    /* vpl, lightcuts, illumcut */
    {{"vpls", PN_OPTION_INT, "600000", 1, 100000000, 0, 0, "VPLs", "", "virtual point lights to trace"},
     VPL_FAMILY,
     F(vpls),
     PN_FIELD_U32,
     0},
    {{"vpl-depth", PN_OPTION_INT, "10", 1, 1000, 0, 0, "bounces", "",
      "light path bounces that leave VPLs (not given: the scene's Integrator maxdepth - 1, and maxdepth 1 means "
      "vpl-direct-only; without maxdepth 10)"},
     VPL_FAMILY,
     F(vpl_max_depth),
     PN_FIELD_U32,
     0},
    {{"vpl-direct-only", PN_OPTION_FLAG, "0", 0, 0, 0, 0, "", "",
      "direct light only, the quantity reference, ias and contour compute: the lights themselves as VPLs (points "
      "sampled on area lights and environment maps by their emission), no bounces; excludes vpl-depth, and no "
      "clamp unless vpl-clamp is given"},
     VPL_FAMILY,
     F(vpl_direct_only),
     PN_FIELD_BOOL,
     0},
    {{"vpl-clamp", PN_OPTION_DOUBLE, "0.05", 0, 1, 1, 1, "scene radius", "",
      "minimum distance between a point and a VPL, as a fraction of the scene radius"},
     VPL_FAMILY,
     F(vpl_clamp_fraction),
     PN_FIELD_F32,
     0},
    {{"error", PN_OPTION_DOUBLE, "0.01", 0, 1, 1, 1, "", "", "relative error bound of a cut"},
     BIT(M_LIGHTCUTS) | BIT(M_ILLUMCUT),
     F(error_bound),
     PN_FIELD_F32,
     0},
    {{"max-cut", PN_OPTION_INT, "0", 1, 100000000, 0, 0, "clusters", "",
      "at most this many clusters per point (default 0: no limit)"},
     BIT(M_LIGHTCUTS),
     F(max_cut),
     PN_FIELD_U32,
     0},
    {{"visibility", PN_OPTION_CHOICE, "exact", 0, 0, 0, 0, "", "exact,sampling",
      "a shadow ray per point and pair, or adaptive visibility sampling (Algorithm 2)"},
     BIT(M_ILLUMCUT),
     F(visibility_sampling),
     PN_FIELD_BOOL,
     0},
    /* contour, contour-mc */
    {{"contour-grid", PN_OPTION_INT, "3", 2, 65, 0, 0, "samples", "",
      "first-level samples per side of a source (3: a 3x3 grid of 9)"},
     CONTOUR_FAMILY,
     F(contour_grid),
     PN_FIELD_U32,
     0},
    {{"contour-steps", PN_OPTION_INT, "5", 1, 12, 0, 0, "steps", "", "dichotomy steps"},
     CONTOUR_FAMILY,
     F(contour_steps),
     PN_FIELD_U32,
     0},
    {{"contour-span", PN_OPTION_INT, "8", 1, 64, 0, 0, "pixels", "", "longest span of pixels sharing first-level rays"},
     CONTOUR_FAMILY,
     F(contour_span),
     PN_FIELD_U32,
     0},
    {{"contour-off", PN_OPTION_SET, "", 0, 0, 0, 0, "",
      "shaft,spans,validity,adaptive,restarts,islands,half,scouts,linear",
      "parts switched off for comparisons: shaft culling, spans, the validity test (Fig. 6's failure), the adaptive "
      "first-level density, restarts; our departures: island probes, half checks, scout probes, linear runs"},
     CONTOUR_FAMILY,
     F(contour_flags),
     PN_FIELD_U32,
     0},
    {{"contour-scout", PN_OPTION_INT, "-1", 0, 3, 0, 0, "", "",
      "scout probes inside agreeing first-level squares: 0 none, 1 4 points, 2 16, 3 49 (default -1: 3 with a "
      "fixed first-level density, else 1)"},
     BIT(M_CONTOUR),
     F(contour_scout),
     PN_FIELD_INT,
     0},
    {{"contour-part", PN_OPTION_CHOICE, "2", 0, 0, 0, 0, "", "1,2,4",
      "runs check 1/part of their first-level samples from their third pixel on"},
     BIT(M_CONTOUR),
     F(contour_part),
     PN_FIELD_INT,
     0},
    {{"contour-linear-tol", PN_OPTION_DOUBLE, "0.003", 0, 1, 0, 0, "", "",
      "tolerance of the test that interpolates a run linearly"},
     BIT(M_CONTOUR),
     F(contour_linear_tol),
     PN_FIELD_F64,
     0},
    {{"contour-trace", PN_OPTION_STRING, "", 0, 0, 0, 0, "", "",
      "bench instrumentation: write one line per pixel on where its shadow rays went to this file"},
     BIT(M_CONTOUR),
     F(contour_trace),
     PN_FIELD_STRING,
     0},
    {{"mc-threshold", PN_OPTION_DOUBLE, "0.002", 0, INFINITY, 1, 0, "", "",
      "refine a cell while its standard error exceeds this times the source's unoccluded form factor"},
     BIT(M_CONTOUR_MC),
     F(contour_mc_threshold),
     PN_FIELD_F64,
     0},
    {{"mc-max-rays", PN_OPTION_INT, "256", 4, 1048576, 0, 0, "rays", "", "shadow rays per source and point, at most"},
     BIT(M_CONTOUR_MC),
     F(contour_mc_max_rays),
     PN_FIELD_U32,
     0},
    /* progressive drivers */
    {{"work-scale", PN_OPTION_INT, "3", 1, 16, 0, 0, "", "",
      "the work image is this many times the output resolution per side"},
     PROGRESSIVE_DRIVERS,
     F(work_scale),
     PN_FIELD_INT,
     0},
    {{"snapshots", PN_OPTION_LIST, "", 0, 100, 1, 0, "%", "",
      "approximate images when these percentages of the work pixels are evaluated"},
     PROGRESSIVE_DRIVERS,
     F(snapshots),
     PN_FIELD_LIST,
     0},
    {{"snapshot-every", PN_OPTION_DOUBLE, "0", 0, INFINITY, 1, 0, "s", "",
      "and an approximate image every so many seconds (default 0: never)"},
     PROGRESSIVE_DRIVERS,
     F(snapshot_every_seconds),
     PN_FIELD_F64,
     0},
    {{"stop-at", PN_OPTION_DOUBLE, "0", 0, 100, 1, 0, "%", "",
      "stop after this percentage of the work pixels (default 0: run to the end)"},
     PROGRESSIVE_DRIVERS,
     F(stop_percent),
     PN_FIELD_F64,
     0},
    {{"raw-radiance", PN_OPTION_FLAG, "0", 0, 0, 0, 0, "", "",
      "interpolate radiance itself, not (radiance - emitted) / albedo"},
     PROGRESSIVE_DRIVERS,
     F(raw_radiance),
     PN_FIELD_BOOL,
     0},
    {{"no-light-guide", PN_OPTION_FLAG, "0", 0, 0, 0, 0, "", "",
      "divide by the albedo only, not also by the lights' unshadowed irradiance"},
     PROGRESSIVE_DRIVERS,
     F(no_light_guide),
     PN_FIELD_BOOL,
     0},
    {{"primary-grid", PN_OPTION_INT, "3", 1, 8, 0, 0, "rays per side", "",
      "g x g primary rays per work pixel measure its albedo and emitted radiance where they change"},
     PROGRESSIVE_DRIVERS,
     F(primary_grid),
     PN_FIELD_INT,
     0},
    {{"opaque-glass", PN_OPTION_FLAG, "0", 0, 0, 0, 0, "", "",
      "thin glass panes (thindielectric, or dielectric with \"bool thin\" true) block shadow rays, as in pbrt-v4, "
      "instead of passing them attenuated by their Fresnel transmittance (contour and contour-mc: for their own "
      "area lights too, the paper's binary visibility)"},
     BIT(M_REFERENCE) | BIT(M_IAS) | CONTOUR_FAMILY | VPL_FAMILY,
     F(opaque_glass),
     PN_FIELD_BOOL,
     0},
    /* dcm (issue 18): the paper's DCM or ours, and our departures one by one */
    {{"dcm-variant", PN_OPTION_CHOICE, "default", 0, 0, 0, 0, "", "default,paper",
      "'paper': Guo 1998 as published (8x8 blocks, its thresholds, radiance interpolated, every departure of "
      "--dcm-off switched off); 'default': with our departures (docs/methods/progressive.md)"},
     BIT(M_DCM),
     F(dcm_variant),
     PN_FIELD_INT,
     0},
    {{"dcm-off", PN_OPTION_SET, "", 0, 0, 0, 0, "",
      "edge-first,order,discrepancy,noise,lattice-mean,segments,demod,guided,albedo-rays,linear,residuals,smooth-fit",
      "departures from Guo 1998 switched off for comparisons: edge quads before smooth ones, boundary steps by "
      "expected error, the discrepancy as a mean, the Monte Carlo noise tests, noise-filtered smooth corners, "
      "segment-wise edge blocks, demodulation (as --raw-radiance), the guided reconstruction of edge blocks, "
      "the integrator's own eye rays for the albedo at texture borders, the guided fill as a weighted plane fit, "
      "boundary steps re-ordered by what the last step of the block found, smooth blocks' corners as a plane "
      "fitted over the block lattice"},
     BIT(M_DCM),
     F(dcm_off),
     PN_FIELD_U32,
     0},
    /* every progressive driver (issue 18): a preview file a viewer can watch */
    {{"preview", PN_OPTION_STRING, "", 0, 0, 0, 0, "", "",
      "rewrite this image (.exr, .png or .pfm) atomically every --preview-every seconds with the approximate "
      "image so far, for viewers that reload changed files (tev)"},
     PROGRESSIVE_DRIVERS,
     F(preview),
     PN_FIELD_STRING,
     0},
    {{"preview-every", PN_OPTION_DOUBLE, "2", 0, INFINITY, 1, 0, "s", "", "the interval of --preview"},
     PROGRESSIVE_DRIVERS,
     F(preview_every_seconds),
     PN_FIELD_F64,
     0},
    /* every method (issue 20): spectral light transport */
    {{"spectral", PN_OPTION_FLAG, "0", 0, 0, 0, 0, "", "",
      "spectral light transport as pbrt-v4: each eye sample carries 3 wavelengths, RGB inputs upsampled "
      "(reflectances by Jakob-Hanika 2019, emissions times D65), the film integrates against the CIE 1931 matching "
      "functions (docs/spectral.md); off: RGB products, bit-identical to earlier versions"},
     (1u << M_COUNT) - 1u,
     F(spectral),
     PN_FIELD_BOOL,
     0},
};
#define OPTION_COUNT ((int)(sizeof options / sizeof options[0]))

/* ---- methods --------------------------------------------------------------------------- */

int pn_method_count(void) {
    return M_COUNT;
}

const pn_method_info *pn_method_get(int index) {
    return index >= 0 && index < M_COUNT ? &methods[index].info : NULL;
}

int pn_method_find(pn_method_role role, const char *name) {
    if (!name) return -1;
    for (int i = 0; i < M_COUNT; i++)
        if (methods[i].info.role == role && strcmp(methods[i].info.name, name) == 0) return i;
    return -1;
}

int pn_method_find_kind(pn_method_role role, int kind) {
    if (role == PN_METHOD_INTEGRATOR && kind == PN_INTEGRATOR_DEFAULT) kind = PN_INTEGRATOR_REFERENCE;
    for (int i = 0; i < M_COUNT; i++)
        if (methods[i].info.role == role && methods[i].info.kind == kind) return i;
    return -1;
}

const pn_method_entry *pn_registry_method(int index) {
    return index >= 0 && index < M_COUNT ? &methods[index] : NULL;
}

const pn_method_entry *pn_registry_method_kind(pn_method_role role, int kind) {
    return pn_registry_method(pn_method_find_kind(role, kind));
}

const pn_method_entry *pn_registry_integrator_entry(const pn_integrator *integrator) {
    for (int i = 0; i < M_COUNT; i++)
        if (integrator && methods[i].integrator == integrator) return &methods[i];
    return NULL;
}

/* Why an integrator without PN_CAP_PROGRESSIVE cannot run under the subsampling drivers (issue 18;
 * measured with bench/progressive/ias_curve.sh). */
#define IAS_NOT_PROGRESSIVE                                                                                            \
    "ias pools its adaptive PDFs, eye-ray sequence and stopping test over the pixels of its block, and dcm, painter "  \
    "and uniform hand it a few scattered pixels per block: the image they converge to is 5.5x the noise floor away "   \
    "from ias's own (rel L1 0.089 against 0.016 between two seeds, hall-many crop, threshold 0.01); use --driver "     \
    "full or the default tiles"

const char *pn_integrator_progressive_refusal(const pn_integrator *integrator) {
    const pn_method_entry *e = pn_registry_integrator_entry(integrator);
    if (!e || (e->info.capabilities & PN_CAP_PROGRESSIVE)) return NULL;
    return e == &methods[M_IAS] ? IAS_NOT_PROGRESSIVE : "it does not work under the subsampling drivers";
}

/* Capabilities the drivers ask about (integrator.h). */
bool pn_integrator_reports_emitted(const pn_integrator *integrator) {
    const pn_method_entry *e = pn_registry_integrator_entry(integrator);
    return e && (e->info.capabilities & PN_CAP_EMITTED);
}

uint32_t pn_integrator_pixel_eye_samples(const pn_integrator *integrator, const pn_render_job *job) {
    const pn_method_entry *e = pn_registry_integrator_entry(integrator);
    return e && (e->info.capabilities & PN_CAP_EYE_SAMPLES) ? job->spp : 0;
}

const pn_integrator *pn_integrator_find(pn_integrator_kind kind) {
    const pn_method_entry *e = pn_registry_method_kind(PN_METHOD_INTEGRATOR, (int)kind);
    return e ? e->integrator : NULL;
}

/* AOV names: the one table is film's (film/aovs.c), which implements pn_aov_count / pn_aov_name. */

/* ---- options: declarations ------------------------------------------------------------- */

int pn_option_count(void) {
    return OPTION_COUNT;
}

const pn_option_info *pn_option_get(int index) {
    return index >= 0 && index < OPTION_COUNT ? &options[index].info : NULL;
}

int pn_option_find(const char *name) {
    if (!name) return -1;
    for (int i = 0; i < OPTION_COUNT; i++)
        if (strcmp(options[i].info.name, name) == 0) return i;
    return -1;
}

int pn_option_applies(int option, int method) {
    if (option < 0 || option >= OPTION_COUNT || method < 0 || method >= M_COUNT) return 0;
    return (options[option].methods & BIT(method)) != 0;
}

/* The k-th comma-separated name of a choice list into out; false past the end. */
static bool choice_at(const char *choices, int k, char *out, size_t size) {
    const char *p = choices;
    for (int i = 0; i < k; i++) {
        p = strchr(p, ',');
        if (!p) return false;
        p++;
    }
    if (*p == '\0' && k > 0) return false;
    size_t n = strcspn(p, ",");
    snprintf(out, size, "%.*s", (int)n, p);
    return n > 0;
}

/* Index of the choice named by text[0..n), or -1. */
static int choice_index(const char *choices, const char *text, size_t n) {
    char name[64];
    for (int k = 0; choice_at(choices, k, name, sizeof name); k++)
        if (strlen(name) == n && strncmp(name, text, n) == 0) return k;
    return -1;
}

static int choice_code(const pn_option_decl *d, int k) {
    char name[64];
    choice_at(d->info.choices, k, name, sizeof name);
    if (name[0] >= '0' && name[0] <= '9') return atoi(name);
    return d->choice_base + k;
}

static void append(char *buf, size_t size, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void append(char *buf, size_t size, const char *fmt, ...) {
    size_t len = strlen(buf);
    if (len + 1 >= size) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf + len, size - len, fmt, ap);
    va_end(ap);
}

void pn_option_describe(int option, char *buf, size_t size) {
    if (!buf || size == 0) return;
    buf[0] = '\0';
    const pn_option_info *o = pn_option_get(option);
    if (!o) return;
    const char *lo = o->min_exclusive ? "> " : ">= ", *hi = o->max_exclusive ? "< " : "<= ";
    char name[64];
    switch (o->type) {
    case PN_OPTION_INT: append(buf, size, "an integer from %.0f to %.0f", o->min, o->max); break;
    case PN_OPTION_DOUBLE:
    case PN_OPTION_LIST:
        append(buf, size, o->type == PN_OPTION_LIST ? "a comma-separated list of numbers, each " : "a number ");
        if (isfinite(o->max))
            append(buf, size, "%s%g and %s%g", lo, o->min, hi, o->max);
        else
            append(buf, size, "%s%g", lo, o->min);
        break;
    case PN_OPTION_FLAG: append(buf, size, "on or off (1 or 0)"); break;
    case PN_OPTION_CHOICE:
    case PN_OPTION_SET:
        if (o->type == PN_OPTION_SET) append(buf, size, "a comma-separated list of ");
        for (int k = 0; choice_at(o->choices, k, name, sizeof name); k++) {
            bool last = !choice_at(o->choices, k + 1, name, sizeof name);
            choice_at(o->choices, k, name, sizeof name);
            append(buf, size, "%s'%s'",
                   k == 0 ? ""
                   : last ? (o->type == PN_OPTION_SET ? " and " : " or ")
                          : ", ",
                   name);
        }
        break;
    case PN_OPTION_STRING: append(buf, size, "a text (e.g. a file name)"); break;
    }
}

/* ---- options: values ------------------------------------------------------------------- */

typedef struct option_value {
    bool set;
    double number; /* INT, DOUBLE, FLAG, CHOICE (code), SET (bits) */
    char *text;    /* canonical text (set values only) */
} option_value;

struct pn_options_s {
    option_value values[OPTION_COUNT];
};

pn_options pn_options_new(void) {
    return calloc(1, sizeof(struct pn_options_s));
}

void pn_options_free(pn_options o) {
    if (!o) return;
    for (int i = 0; i < OPTION_COUNT; i++) free(o->values[i].text);
    free(o);
}

static bool in_range(const pn_option_info *o, double v) {
    if (o->min_exclusive ? !(v > o->min) : !(v >= o->min)) return false;
    if (o->max_exclusive ? !(v < o->max) : !(v <= o->max)) return false;
    return true;
}

static bool parse_number(const char *text, size_t n, bool integer, double *out) {
    char buf[64];
    if (n == 0 || n >= sizeof buf) return false;
    memcpy(buf, text, n);
    buf[n] = '\0';
    if (buf[0] == ' ' || buf[0] == '\t' || buf[0] == '+') return false;
    char *end = NULL;
    errno = 0;
    if (integer) {
        long long v = strtoll(buf, &end, 10);
        if (errno || end == buf || *end) return false;
        *out = (double)v;
        return true;
    }
    double v = strtod(buf, &end);
    if (errno || end == buf || *end || !isfinite(v)) return false;
    *out = v;
    return true;
}

/* Shortest "%.Ng" text that reads back as v. */
static void format_double(double v, char *out, size_t size) {
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(out, size, "%.*g", digits, v);
        if (strtod(out, NULL) == v) return;
    }
}

/* Parses text for option d into *number and a canonical text (malloc'ed into *canon when not
 * NULL). check_range: false for declared defaults, which may lie outside the range ("none"). */
static bool parse_value(const pn_option_decl *d, const char *text, bool check_range, double *number, char **canon) {
    const pn_option_info *o = &d->info;
    char buf[1024];
    buf[0] = '\0';
    *number = 0.0;
    size_t len = strlen(text);
    switch (o->type) {
    case PN_OPTION_INT:
    case PN_OPTION_DOUBLE:
        if (!parse_number(text, len, o->type == PN_OPTION_INT, number)) return false;
        if (check_range && !in_range(o, *number)) return false;
        if (o->type == PN_OPTION_INT)
            snprintf(buf, sizeof buf, "%.0f", *number);
        else
            format_double(*number, buf, sizeof buf);
        break;
    case PN_OPTION_FLAG:
        if (!strcmp(text, "1") || !strcmp(text, "true") || !strcmp(text, "on"))
            *number = 1.0;
        else if (!strcmp(text, "0") || !strcmp(text, "false") || !strcmp(text, "off"))
            *number = 0.0;
        else
            return false;
        snprintf(buf, sizeof buf, "%d", (int)*number);
        break;
    case PN_OPTION_CHOICE: {
        int k = choice_index(o->choices, text, len);
        if (k < 0) return false;
        *number = (double)choice_code(d, k);
        snprintf(buf, sizeof buf, "%s", text);
        break;
    }
    case PN_OPTION_SET: {
        uint32_t bits = 0;
        const char *p = text;
        while (*p) {
            size_t n = strcspn(p, ",");
            int k = choice_index(o->choices, p, n);
            if (k < 0 || k >= 32) return false;
            bits |= 1u << k;
            p += n;
            if (*p == ',' && *++p == '\0') return false;
        }
        *number = (double)bits;
        char name[64];
        for (int k = 0; choice_at(o->choices, k, name, sizeof name); k++)
            if (bits & (1u << k)) append(buf, sizeof buf, "%s%s", buf[0] ? "," : "", name);
        break;
    }
    case PN_OPTION_LIST: {
        const char *p = text;
        int count = 0;
        while (*p) {
            size_t n = strcspn(p, ",");
            double v;
            if (!parse_number(p, n, false, &v) || (check_range && !in_range(o, v)) || count == PN_JOB_LIST_MAX)
                return false;
            char item[64];
            format_double(v, item, sizeof item);
            append(buf, sizeof buf, "%s%s", count ? "," : "", item);
            count++;
            p += n;
            if (*p == ',' && *++p == '\0') return false;
        }
        *number = (double)count;
        break;
    }
    case PN_OPTION_STRING: *number = 0.0; break;
    }
    if (canon) {
        *canon = strdup(o->type == PN_OPTION_STRING ? text : buf);
        if (!*canon) return false;
    }
    return true;
}

static pn_status bad_value(pn_context ctx, int index, const char *value) {
    char expected[512];
    pn_option_describe(index, expected, sizeof expected);
    return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "invalid value '%s' for option '%s' (%s): expected %s",
                           value, options[index].info.name, options[index].info.help, expected);
}

static pn_status unknown_option(pn_context ctx, const char *name) {
    char list[900];
    list[0] = '\0';
    for (int i = 0; i < OPTION_COUNT; i++) append(list, sizeof list, "%s%s", i ? ", " : "", options[i].info.name);
    return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown option '%s' (options: %s)", name ? name : "(null)",
                           list);
}

pn_status pn_options_set(pn_context ctx, pn_options o, const char *name, const char *value) {
    if (!o || !value) return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_options_set: NULL argument");
    int index = pn_option_find(name);
    if (index < 0) return unknown_option(ctx, name);
    double number;
    char *canon = NULL;
    if (!parse_value(&options[index], value, true, &number, &canon)) {
        free(canon);
        return bad_value(ctx, index, value);
    }
    option_value *v = &o->values[index];
    free(v->text);
    v->set = true;
    v->number = number;
    v->text = canon;
    return PN_OK;
}

pn_status pn_options_set_int(pn_context ctx, pn_options o, const char *name, int64_t value) {
    int index = pn_option_find(name);
    if (index < 0) return unknown_option(ctx, name);
    pn_option_type t = options[index].info.type;
    if (t != PN_OPTION_INT && t != PN_OPTION_FLAG && t != PN_OPTION_DOUBLE)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "option '%s' takes no integer", name);
    char text[32];
    snprintf(text, sizeof text, "%lld", (long long)value);
    return pn_options_set(ctx, o, name, text);
}

pn_status pn_options_set_double(pn_context ctx, pn_options o, const char *name, double value) {
    int index = pn_option_find(name);
    if (index < 0) return unknown_option(ctx, name);
    pn_option_type t = options[index].info.type;
    if (t != PN_OPTION_DOUBLE && t != PN_OPTION_INT)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "option '%s' takes no number", name);
    char text[64];
    if (!isfinite(value))
        snprintf(text, sizeof text, "%g", value);
    else if (t == PN_OPTION_INT && value == floor(value) && fabs(value) < 9e15)
        snprintf(text, sizeof text, "%.0f", value);
    else
        format_double(value, text, sizeof text);
    return pn_options_set(ctx, o, name, text);
}

void pn_options_unset(pn_options o, const char *name) {
    int index = pn_option_find(name);
    if (!o || index < 0) return;
    free(o->values[index].text);
    memset(&o->values[index], 0, sizeof o->values[index]);
}

int pn_options_is_set(pn_options o, int option) {
    return o && option >= 0 && option < OPTION_COUNT && o->values[option].set;
}

pn_status pn_options_get(pn_options o, int option, double *number, char *text, size_t text_size) {
    if (option < 0 || option >= OPTION_COUNT) return PN_ERROR_INVALID_ARGUMENT;
    const pn_option_decl *d = &options[option];
    double value;
    char *canon = NULL;
    if (pn_options_is_set(o, option)) {
        value = o->values[option].number;
        if (text && text_size) snprintf(text, text_size, "%s", o->values[option].text);
    } else {
        if (!parse_value(d, d->info.default_value, false, &value, text ? &canon : NULL)) return PN_ERROR_INTERNAL;
        if (text && text_size) snprintf(text, text_size, "%s", canon);
        free(canon);
    }
    if (number) *number = value;
    return PN_OK;
}

/* ---- options: checking and resolving into the job -------------------------------------- */

/* "reference, ias and contour" for the methods of a mask. */
static void method_list(uint32_t mask, char *buf, size_t size) {
    int total = 0, seen = 0;
    for (int m = 0; m < M_COUNT; m++) total += (mask & BIT(m)) != 0;
    for (int m = 0; m < M_COUNT; m++) {
        if (!(mask & BIT(m))) continue;
        seen++;
        append(buf, size, "%s%s", seen == 1 ? "" : seen == total ? " and " : ", ", methods[m].info.name);
    }
}

static void accepted_list(int method, char *buf, size_t size) {
    int n = 0;
    for (int i = 0; i < OPTION_COUNT; i++)
        if (options[i].methods & BIT(method)) append(buf, size, "%s%s", n++ ? ", " : "", options[i].info.name);
    if (n == 0) append(buf, size, "no options");
}

static pn_status not_applicable(pn_context ctx, const char *what, uint32_t where, int integ, int driver) {
    char msg[1024] = "", list[512] = "";
    method_list(where, list, sizeof list);
    int roles = 0;
    for (int m = 0; m < M_COUNT; m++)
        if (where & BIT(m)) roles |= methods[m].info.role == PN_METHOD_DRIVER ? 2 : 1;
    const char *kind = roles == 2 ? "driver" : roles == 1 ? "integrator" : "method";
    int count = 0;
    for (int m = 0; m < M_COUNT; m++) count += (where & BIT(m)) != 0;
    append(msg, sizeof msg, "%s does not apply to %s under the %s driver: it applies to the %s %s%s; %s accepts ", what,
           methods[integ].info.name, methods[driver].info.name, list, kind, count == 1 ? " only" : "s",
           methods[integ].info.name);
    accepted_list(integ, msg, sizeof msg);
    append(msg, sizeof msg, "; %s accepts ", methods[driver].info.name);
    accepted_list(driver, msg, sizeof msg);
    return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "%s", msg);
}

pn_status pn_options_check(pn_context ctx, pn_options o, pn_integrator_kind integrator, pn_driver_kind driver) {
    int mi = pn_method_find_kind(PN_METHOD_INTEGRATOR, (int)integrator);
    int md = pn_method_find_kind(PN_METHOD_DRIVER, (int)driver);
    if (mi < 0) return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown integrator %d", (int)integrator);
    if (md < 0) return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "unknown driver %d", (int)driver);
    for (int i = 0; o && i < OPTION_COUNT; i++) {
        if (!o->values[i].set || (options[i].methods & (BIT(mi) | BIT(md)))) continue;
        char what[96];
        snprintf(what, sizeof what, "option '%s'", options[i].info.name);
        return not_applicable(ctx, what, options[i].methods, mi, md);
    }
    return PN_OK;
}

static uint32_t cap_mask(uint32_t cap) {
    uint32_t mask = 0;
    for (int m = 0; m < M_COUNT; m++)
        if (methods[m].info.role == PN_METHOD_INTEGRATOR && (methods[m].info.capabilities & cap)) mask |= BIT(m);
    return mask;
}

pn_status pn_registry_resolve(pn_context ctx, const pn_render_settings *s, const pn_method_entry *integ,
                              const pn_method_entry *driver, pn_render_job *job) {
    pn_status st =
        pn_options_check(ctx, s->options, (pn_integrator_kind)integ->info.kind, (pn_driver_kind)driver->info.kind);
    if (st != PN_OK) return st;
    int mi = (int)(integ - methods), md = (int)(driver - methods);
    if (s->spp && !(integ->info.capabilities & PN_CAP_SPP))
        return not_applicable(ctx, "spp (a fixed eye-ray count)", cap_mask(PN_CAP_SPP), mi, md);
    if (s->threshold != 0.0 && !(integ->info.capabilities & PN_CAP_THRESHOLD))
        return not_applicable(ctx, "threshold (a relative-variance target)", cap_mask(PN_CAP_THRESHOLD), mi, md);
    for (int i = 0; i < OPTION_COUNT; i++) {
        const pn_option_decl *d = &options[i];
        double number;
        if (pn_options_get(s->options, i, &number, NULL, 0) != PN_OK)
            return pn_context_fail(ctx, PN_ERROR_INTERNAL, "option '%s': bad declared default", d->info.name);
        char *field = (char *)job + d->offset;
        switch (d->field) {
        case PN_FIELD_U32: *(uint32_t *)(void *)field = (uint32_t)number; break;
        case PN_FIELD_INT: *(int *)(void *)field = (int)number; break;
        case PN_FIELD_F32: *(float *)(void *)field = (float)number; break;
        case PN_FIELD_F64: *(double *)(void *)field = number; break;
        case PN_FIELD_BOOL: *(bool *)(void *)field = number != 0.0; break;
        case PN_FIELD_STRING:
            *(const char **)(void *)field = pn_options_is_set(s->options, i) ? s->options->values[i].text : NULL;
            break;
        case PN_FIELD_LIST: {
            pn_job_list *list = (pn_job_list *)(void *)field;
            list->count = 0;
            const char *p = pn_options_is_set(s->options, i) ? s->options->values[i].text : "";
            while (*p && list->count < PN_JOB_LIST_MAX) {
                list->values[list->count++] = strtod(p, NULL);
                p += strcspn(p, ",");
                if (*p == ',') p++;
            }
            break;
        }
        }
    }
    return PN_OK;
}
