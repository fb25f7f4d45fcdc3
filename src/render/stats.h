/* stats.h — the statistics of a render, inside the library: the struct the driver, the
 * integrators (their `report` hook) and MPI fill field by field, and the one declared table of
 * statistics (stats.c) that the public by-name interface (pn_stats_*, pn_stat_* in penumbra.h),
 * the CLI's JSON and summary, `penumbra merge` and the MPI reduction read.
 *
 * The struct is not public: a new statistic is a field here and one entry of the table, and
 * changes no public struct and no ABI. */
#ifndef PN_RENDER_STATS_H
#define PN_RENDER_STATS_H

#include <penumbra/penumbra.h>

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define PN_STATS_MAX_RANKS 256
/* Statistics of one render, as the driver, the integrators and MPI fill them. */
typedef struct pn_render_stats {
    double render_seconds;
    double embree_seconds_estimate; /* time inside Embree calls (every 8th eye ray's calls timed,
                                       scaled, summed over threads and divided by their number) */
    uint64_t eye_rays, shadow_rays, specular_rays;
    double shadow_rays_per_pixel_mean, eye_rays_per_pixel_mean;
    uint64_t shadow_rays_per_pixel_max, eye_rays_per_pixel_max;
    uint64_t non_finite_samples; /* eye samples (ias: pixels) whose value was NaN or infinite,
                                    counted as 0 (pn_pixel_estimate.non_finite) */
    double mrays_per_second;
    uint64_t peak_memory_bytes;
    int partial; /* 1 when cancelled: only finished tiles hold values */
    /* ias only (zero otherwise), means over the rendered pixels, as the paper's Tables 3-6:
     * passes and antialiasing regions per pixel, clusters per shading point, and the fraction of
     * shadow rays that were unoccluded. */
    double passes_per_pixel_mean, aa_regions_per_pixel_mean, clusters_per_point_mean;
    double visible_fraction_mean;
    /* ias, the paper's Table 5: lights (and environment-map regions) with at least one unoccluded
     * shadow ray anywhere in the image, and per pixel on average. */
    uint32_t lights_visible_viewpoint, env_regions_visible_viewpoint;
    double visible_lights_per_pixel_mean;
    /* ias, where its own time goes (summed over threads, divided by their number, as the
     * Embree estimate): computing cluster cuts, and keeping PDFs (feedback weights, eq. 6,
     * choosing clusters and lights, recording samples). */
    double cut_seconds_estimate, pdf_seconds_estimate;
    int threads;
    int width, height; /* of the rendered (cropped) image */
    /* VPL integrators (issue 5): preprocessing (VPL tracing + light tree build) and its parts,
     * the VPLs and light paths, L_UB evaluations per pixel (the paper's "upper bound" rows),
     * cut size per shading point (lightcuts) or product-space pairs per pixel (illumcut), and
     * illumcut's phases (point tree, Phase I, Phase II) in seconds. */
    double preprocess_seconds, vpl_seconds, light_tree_seconds;
    uint64_t vpl_count, vpl_paths;
    double bound_evaluations_per_pixel_mean, cut_size_mean;
    double point_tree_seconds, phase1_seconds, phase2_seconds;
    uint64_t illumcut_pairs;
    /* contour and contour-mc (zero otherwise): viewing rays that cast shadow rays towards
     * contour sources and those shadow rays (the paper's Table 1 counts rays per such viewing
     * ray); full contour integrations, pixels interpolated between them, restarts one level
     * finer, subdivided squares, and spans shaded by the closed form after shaft culling. */
    uint64_t contour_viewing_rays, contour_shadow_rays;
    uint64_t contour_integrations, contour_interpolated, contour_restarts, contour_subdivisions;
    uint64_t contour_culled_spans;
    /* Progressive drivers (issue 6). */
    uint64_t evaluated_pixels;                      /* work pixels evaluated by the integrator */
    double evaluated_percent;                       /* of all work pixels of the window */
    int work_width, work_height;                    /* of the work window */
    uint32_t dcm_simple_blocks, dcm_complex_blocks; /* edge blocks that passed / failed the tests */
    uint32_t dcm_lazy_blocks;                       /* quads that kept their parent's elements (lazy evaluation) */
    double primary_buffer_seconds;                  /* the id/normal/depth buffer of primary rays */
    uint64_t primary_grid_pixels;                   /* work pixels whose albedo and emitted radiance came from a
                                         grid of primary rays (--primary-grid) */
    double reconstruct_seconds_max;                 /* longest reconstruction of an approximate image */
    /* The tiled driver's distribution (docs/distributed.md): tiles of the window and those a
     * checkpoint already held; under MPI the ranks, and per rank (the first PN_STATS_MAX_RANKS)
     * the seconds it spent rendering tiles and the tiles it rendered. */
    uint32_t tiles, tiles_resumed;
    int ranks;
    double rank_busy_seconds[PN_STATS_MAX_RANKS];
    uint32_t rank_tiles[PN_STATS_MAX_RANKS];
    /* scene loading, copied from the scene by pn_render so that a render's statistics are whole */
    double parse_seconds, bvh_seconds;
} pn_render_stats;

/* How a statistic is stored in pn_render_stats. */
typedef enum pn_stat_field {
    PN_STAT_F64,       /* double */
    PN_STAT_U64,       /* uint64_t */
    PN_STAT_U32,       /* uint32_t */
    PN_STAT_I32,       /* int */
    PN_STAT_RATIO,     /* uint64_t at offset over uint64_t at offset2 (0 when that is 0) */
    PN_STAT_F64_RANKS, /* double[PN_STATS_MAX_RANKS], `ranks` of them in use */
    PN_STAT_U32_RANKS  /* uint32_t[PN_STATS_MAX_RANKS], `ranks` of them in use */
} pn_stat_field;

typedef struct pn_stat_decl {
    pn_stat_info info;
    size_t offset; /* of the field in pn_render_stats */
    pn_stat_field field;
    size_t offset2; /* PN_STAT_RATIO: the denominator */
    /* Counted by the integrator itself on every MPI rank (not from the pixels rank 0 gathers):
     * summed over the ranks by pn_dist_reduce_stats. */
    bool rank_sum;
} pn_stat_decl;

/* The statistics a render hands back through the public pn_stats handle. */
struct pn_stats_s {
    pn_render_stats fields;
    int integrator, driver; /* method-table indices of the render, -1 before one */
    bool produced;          /* a render filled `fields` (also a cancelled or failed one that ran) */
};

/* The table's entries (NULL when out of range). */
int pn_stats_decl_count(void);
const pn_stat_decl *pn_stats_decl(int index);
/* The value of scalar statistic d in s, as a double. */
double pn_stats_value(const pn_render_stats *s, const pn_stat_decl *d);
/* Stores v into scalar statistic d of s (rounded for integer fields; not for PN_STAT_RATIO). */
void pn_stats_store(pn_render_stats *s, const pn_stat_decl *d, double v);

#endif
