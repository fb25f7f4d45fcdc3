/* stats.c — the one declared table of render statistics and the public by-name interface over
 * it (pn_stat_* for the table, pn_stats_* for one render's values; penumbra.h).
 *
 * Each entry: the name (as in the stats JSON, docs/stats-json.md), type, unit, one-line help, the
 * group that says which methods produce it (a method's pn_method_info.stats lists its groups; ""
 * is every render), how crop renders of one image combine it (penumbra merge), whether MPI sums
 * it over the ranks, and the field of pn_render_stats (render/stats.h) that holds it. The table's
 * order is the order of the JSON's `stats` object. */
#include "render/stats.h"

#include <stdlib.h>
#include <string.h>

#define F(field) offsetof(pn_render_stats, field)
#define SUM PN_STAT_MERGE_SUM
#define MAX PN_STAT_MERGE_MAX
#define MEAN PN_STAT_MERGE_MEAN
#define TILES "tiles" /* not-a-method-name: the unit of tile counts */

/* {name, type, unit, group, merge, per_rank, help}, field offset, field kind, offset2, rank_sum */
static const pn_stat_decl stats_table[] = {
    /* every render */
    {{"parse_seconds", PN_STAT_SECONDS, "s", "", SUM, 0, "scene parsing, PLY files included"},
     F(parse_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"bvh_seconds", PN_STAT_SECONDS, "s", "", SUM, 0, "Embree BVH build of the scene"},
     F(bvh_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"partial", PN_STAT_FLAG, "", "", PN_STAT_MERGE_ANY, 0,
      "the render was cancelled: the image holds only finished tiles"},
     F(partial),
     PN_STAT_I32,
     0,
     false},
    {{"width", PN_STAT_INT, "pixels", "", PN_STAT_MERGE_WIDTH, 0, "width of the rendered (cropped) image"},
     F(width),
     PN_STAT_I32,
     0,
     false},
    {{"height", PN_STAT_INT, "pixels", "", PN_STAT_MERGE_HEIGHT, 0, "height of the rendered (cropped) image"},
     F(height),
     PN_STAT_I32,
     0,
     false},
    {{"threads", PN_STAT_INT, "threads", "", MAX, 0, "worker threads that ran"}, F(threads), PN_STAT_I32, 0, false},
    {{"render_seconds", PN_STAT_SECONDS, "s", "", SUM, 0, "wall-clock time of the render itself"},
     F(render_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"embree_seconds_estimate", PN_STAT_SECONDS, "s", "", SUM, 0,
      "time inside Embree (every 8th eye ray's calls timed and scaled), per thread"},
     F(embree_seconds_estimate),
     PN_STAT_F64,
     0,
     false},
    {{"eye_rays", PN_STAT_COUNT, "rays", "", SUM, 0, "eye rays traced"}, F(eye_rays), PN_STAT_U64, 0, false},
    {{"shadow_rays", PN_STAT_COUNT, "rays", "", SUM, 0, "shadow rays traced"}, F(shadow_rays), PN_STAT_U64, 0, false},
    {{"specular_rays", PN_STAT_COUNT, "rays", "", SUM, 0, "rays of perfect-specular chains traced"},
     F(specular_rays),
     PN_STAT_U64,
     0,
     false},
    {{"eye_rays_per_pixel_mean", PN_STAT_MEAN, "rays", "", MEAN, 0, "eye rays per (evaluated) pixel"},
     F(eye_rays_per_pixel_mean),
     PN_STAT_F64,
     0,
     false},
    {{"eye_rays_per_pixel_max", PN_STAT_MAX, "rays", "", MAX, 0, "most eye rays of one pixel"},
     F(eye_rays_per_pixel_max),
     PN_STAT_U64,
     0,
     false},
    {{"shadow_rays_per_pixel_mean", PN_STAT_MEAN, "rays", "", MEAN, 0, "shadow rays per (evaluated) pixel"},
     F(shadow_rays_per_pixel_mean),
     PN_STAT_F64,
     0,
     false},
    {{"shadow_rays_per_pixel_max", PN_STAT_MAX, "rays", "", MAX, 0, "most shadow rays of one pixel"},
     F(shadow_rays_per_pixel_max),
     PN_STAT_U64,
     0,
     false},
    {{"non_finite_samples", PN_STAT_COUNT, "samples", "", SUM, 0,
      "eye samples (ias: pixels) whose value was NaN or infinite and was counted as 0 (values beyond the float range, "
      "or a bug)"},
     F(non_finite_samples),
     PN_STAT_U64,
     0,
     false},
    {{"mrays_per_second", PN_STAT_MEAN, "Mrays/s", "", MEAN, 0, "all rays over render_seconds, in millions"},
     F(mrays_per_second),
     PN_STAT_F64,
     0,
     false},
    {{"peak_memory_bytes", PN_STAT_MAX, "bytes", "", MAX, 0, "peak resident memory of the process"},
     F(peak_memory_bytes),
     PN_STAT_U64,
     0,
     false},
    /* progressive drivers */
    {{"work_width", PN_STAT_INT, "pixels", "progressive", PN_STAT_MERGE_WIDTH, 0,
      "width of the work window (work-scale x the output window)"},
     F(work_width),
     PN_STAT_I32,
     0,
     false},
    {{"work_height", PN_STAT_INT, "pixels", "progressive", PN_STAT_MERGE_HEIGHT, 0, "height of the work window"},
     F(work_height),
     PN_STAT_I32,
     0,
     false},
    {{"evaluated_pixels", PN_STAT_COUNT, "pixels", "progressive", SUM, 0, "work pixels the integrator evaluated"},
     F(evaluated_pixels),
     PN_STAT_U64,
     0,
     false},
    {{"evaluated_percent", PN_STAT_MEAN, "%", "progressive", MEAN, 0, "evaluated work pixels, percent of all"},
     F(evaluated_percent),
     PN_STAT_F64,
     0,
     false},
    {{"dcm_simple_blocks", PN_STAT_COUNT, "blocks", "progressive", SUM, 0, "dcm: edge blocks that passed its tests"},
     F(dcm_simple_blocks),
     PN_STAT_U32,
     0,
     false},
    {{"dcm_complex_blocks", PN_STAT_COUNT, "blocks", "progressive", SUM, 0, "dcm: edge blocks that failed its tests"},
     F(dcm_complex_blocks),
     PN_STAT_U32,
     0,
     false},
    {{"dcm_lazy_blocks", PN_STAT_COUNT, "blocks", "progressive", SUM, 0,
      "dcm: quads that kept their parent's elements (lazy evaluation)"},
     F(dcm_lazy_blocks),
     PN_STAT_U32,
     0,
     false},
    {{"primary_buffer_seconds", PN_STAT_SECONDS, "s", "progressive", SUM, 0,
      "the id/normal/depth buffer of primary rays"},
     F(primary_buffer_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"primary_grid_pixels", PN_STAT_COUNT, "pixels", "progressive", SUM, 0,
      "work pixels whose albedo and emitted radiance came from a grid of primary rays"},
     F(primary_grid_pixels),
     PN_STAT_U64,
     0,
     false},
    {{"reconstruct_seconds_max", PN_STAT_SECONDS, "s", "progressive", MAX, 0,
      "longest reconstruction of an approximate image"},
     F(reconstruct_seconds_max),
     PN_STAT_F64,
     0,
     false},
    /* ias: the paper's Tables 3-6 */
    {{"passes_per_pixel_mean", PN_STAT_MEAN, "passes", "ias_tables", MEAN, 0, "ias passes per pixel"},
     F(passes_per_pixel_mean),
     PN_STAT_F64,
     0,
     false},
    {{"aa_regions_per_pixel_mean", PN_STAT_MEAN, "regions", "ias_tables", MEAN, 0, "antialiasing regions per pixel"},
     F(aa_regions_per_pixel_mean),
     PN_STAT_F64,
     0,
     false},
    {{"clusters_per_point_mean", PN_STAT_MEAN, "clusters", "ias_tables", MEAN, 0, "light clusters per shading point"},
     F(clusters_per_point_mean),
     PN_STAT_F64,
     0,
     false},
    {{"visible_fraction_mean", PN_STAT_MEAN, "", "ias_tables", MEAN, 0, "unoccluded shadow rays / shadow rays"},
     F(visible_fraction_mean),
     PN_STAT_F64,
     0,
     false},
    {{"lights_visible_viewpoint", PN_STAT_COUNT, "lights", "ias_tables", SUM, 0,
      "lights with at least one unoccluded shadow ray in the image"},
     F(lights_visible_viewpoint),
     PN_STAT_U32,
     0,
     false},
    {{"env_regions_visible_viewpoint", PN_STAT_COUNT, "regions", "ias_tables", SUM, 0,
      "environment-map regions with at least one unoccluded shadow ray in the image"},
     F(env_regions_visible_viewpoint),
     PN_STAT_U32,
     0,
     false},
    {{"visible_lights_per_pixel_mean", PN_STAT_MEAN, "lights", "ias_tables", MEAN, 0,
      "distinct lights seen unoccluded per pixel"},
     F(visible_lights_per_pixel_mean),
     PN_STAT_F64,
     0,
     false},
    {{"cut_seconds_estimate", PN_STAT_SECONDS, "s", "ias_tables", SUM, 0, "time in cluster cuts, per thread"},
     F(cut_seconds_estimate),
     PN_STAT_F64,
     0,
     false},
    {{"pdf_seconds_estimate", PN_STAT_SECONDS, "s", "ias_tables", SUM, 0,
      "time keeping PDFs (feedback weights, choices, recorded samples), per thread"},
     F(pdf_seconds_estimate),
     PN_STAT_F64,
     0,
     false},
    /* VPL integrators: IlluminationCut's Table 1 */
    {{"preprocess_seconds", PN_STAT_SECONDS, "s", "vpl_cuts", SUM, 0, "preprocessing: VPL tracing and the light tree"},
     F(preprocess_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"vpl_seconds", PN_STAT_SECONDS, "s", "vpl_cuts", SUM, 0, "VPL tracing"}, F(vpl_seconds), PN_STAT_F64, 0, false},
    {{"light_tree_seconds", PN_STAT_SECONDS, "s", "vpl_cuts", SUM, 0, "light (VPL) tree build"},
     F(light_tree_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"vpl_count", PN_STAT_COUNT, "VPLs", "vpl_cuts", SUM, 0, "virtual point lights"},
     F(vpl_count),
     PN_STAT_U64,
     0,
     false},
    {{"vpl_paths", PN_STAT_COUNT, "paths", "vpl_cuts", SUM, 0, "light paths that left the VPLs"},
     F(vpl_paths),
     PN_STAT_U64,
     0,
     false},
    {{"bound_evaluations_per_pixel_mean", PN_STAT_MEAN, "evaluations", "vpl_cuts", MEAN, 0,
      "L_UB (upper bound) evaluations per pixel"},
     F(bound_evaluations_per_pixel_mean),
     PN_STAT_F64,
     0,
     true},
    {{"cut_size_mean", PN_STAT_MEAN, "", "vpl_cuts", MEAN, 0,
      "lightcuts: cut size per shading point; illumcut: pairs touching a pixel"},
     F(cut_size_mean),
     PN_STAT_F64,
     0,
     false},
    {{"point_tree_seconds", PN_STAT_SECONDS, "s", "vpl_cuts", SUM, 0, "illumcut: point tree build (0 otherwise)"},
     F(point_tree_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"phase1_seconds", PN_STAT_SECONDS, "s", "vpl_cuts", SUM, 0, "illumcut: Phase I (0 otherwise)"},
     F(phase1_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"phase2_seconds", PN_STAT_SECONDS, "s", "vpl_cuts", SUM, 0, "illumcut: Phase II (0 otherwise)"},
     F(phase2_seconds),
     PN_STAT_F64,
     0,
     false},
    {{"illumcut_pairs", PN_STAT_COUNT, "pairs", "vpl_cuts", SUM, 0,
      "illumcut: product-space pairs of the final cut (0 otherwise)"},
     F(illumcut_pairs),
     PN_STAT_U64,
     0,
     true},
    /* contour, contour-mc: Vedel 1993, Table 1 */
    {{"contour_viewing_rays", PN_STAT_COUNT, "rays", "contour_rays", SUM, 0,
      "viewing rays that cast shadow rays towards contour sources"},
     F(contour_viewing_rays),
     PN_STAT_U64,
     0,
     true},
    {{"contour_shadow_rays", PN_STAT_COUNT, "rays", "contour_rays", SUM, 0,
      "shadow rays of those viewing rays towards contour sources"},
     F(contour_shadow_rays),
     PN_STAT_U64,
     0,
     true},
    {{"contour_integrations", PN_STAT_COUNT, "integrations", "contour_rays", SUM, 0, "full contour integrations"},
     F(contour_integrations),
     PN_STAT_U64,
     0,
     true},
    {{"contour_interpolated", PN_STAT_COUNT, "pixels", "contour_rays", SUM, 0,
      "pixels interpolated between contour integrations"},
     F(contour_interpolated),
     PN_STAT_U64,
     0,
     true},
    {{"contour_restarts", PN_STAT_COUNT, "restarts", "contour_rays", SUM, 0, "restarts one level finer"},
     F(contour_restarts),
     PN_STAT_U64,
     0,
     true},
    {{"contour_subdivisions", PN_STAT_COUNT, "squares", "contour_rays", SUM, 0, "subdivided squares"},
     F(contour_subdivisions),
     PN_STAT_U64,
     0,
     true},
    {{"contour_culled_spans", PN_STAT_COUNT, "spans", "contour_rays", SUM, 0,
      "spans shaded by the closed form after shaft culling"},
     F(contour_culled_spans),
     PN_STAT_U64,
     0,
     true},
    {{"contour_shadow_rays_per_viewing_ray", PN_STAT_MEAN, "rays", "contour_rays", MEAN, 0,
      "contour_shadow_rays over contour_viewing_rays (the paper's measure)"},
     F(contour_shadow_rays),
     PN_STAT_RATIO,
     F(contour_viewing_rays),
     false},
    /* the tiled driver's distribution (docs/distributed.md) */
    {{"tile_count", PN_STAT_COUNT, TILES, "", SUM, 0,
      "tiles of a tiled render (split, checkpointed or under MPI; 0 otherwise)"},
     F(tiles),
     PN_STAT_U32,
     0,
     false},
    {{"tiles_resumed", PN_STAT_COUNT, TILES, "", SUM, 0, "tiles that a checkpoint already held"},
     F(tiles_resumed),
     PN_STAT_U32,
     0,
     false},
    {{"ranks", PN_STAT_INT, "ranks", "", MAX, 0, "MPI ranks that rendered (1 without mpirun)"},
     F(ranks),
     PN_STAT_I32,
     0,
     false},
    {{"rank_busy_seconds", PN_STAT_SECONDS, "s", "", PN_STAT_MERGE_FIRST, 1,
      "per MPI rank: seconds spent rendering tiles (when ranks > 1)"},
     F(rank_busy_seconds),
     PN_STAT_F64_RANKS,
     0,
     false},
    {{"rank_tiles", PN_STAT_COUNT, TILES, "", PN_STAT_MERGE_FIRST, 1, "per MPI rank: tiles rendered (when ranks > 1)"},
     F(rank_tiles),
     PN_STAT_U32_RANKS,
     0,
     false},
};
#undef F
#undef SUM
#undef MAX
#undef MEAN
#undef TILES

enum { STAT_COUNT = (int)(sizeof stats_table / sizeof stats_table[0]) };

int pn_stats_decl_count(void) {
    return STAT_COUNT;
}

const pn_stat_decl *pn_stats_decl(int index) {
    return index >= 0 && index < STAT_COUNT ? &stats_table[index] : NULL;
}

double pn_stats_value(const pn_render_stats *s, const pn_stat_decl *d) {
    const char *p = (const char *)s + d->offset;
    switch (d->field) {
    case PN_STAT_F64: return *(const double *)(const void *)p;
    case PN_STAT_U64: return (double)*(const uint64_t *)(const void *)p;
    case PN_STAT_U32: return (double)*(const uint32_t *)(const void *)p;
    case PN_STAT_I32: return (double)*(const int *)(const void *)p;
    case PN_STAT_RATIO: {
        uint64_t den = *(const uint64_t *)(const void *)((const char *)s + d->offset2);
        return den ? (double)*(const uint64_t *)(const void *)p / (double)den : 0.0;
    }
    case PN_STAT_F64_RANKS:
    case PN_STAT_U32_RANKS: break;
    }
    return 0.0;
}

void pn_stats_store(pn_render_stats *s, const pn_stat_decl *d, double v) {
    char *p = (char *)s + d->offset;
    switch (d->field) {
    case PN_STAT_F64: *(double *)(void *)p = v; break;
    case PN_STAT_U64: *(uint64_t *)(void *)p = (uint64_t)v; break;
    case PN_STAT_U32: *(uint32_t *)(void *)p = (uint32_t)v; break;
    case PN_STAT_I32: *(int *)(void *)p = (int)v; break;
    case PN_STAT_RATIO:
    case PN_STAT_F64_RANKS:
    case PN_STAT_U32_RANKS: break;
    }
}

/* ---- the public table ---------------------------------------------------------------------- */

int pn_stat_count(void) {
    return STAT_COUNT;
}

const pn_stat_info *pn_stat_get(int index) {
    return index >= 0 && index < STAT_COUNT ? &stats_table[index].info : NULL;
}

int pn_stat_find(const char *name) {
    for (int i = 0; name && i < STAT_COUNT; i++)
        if (strcmp(stats_table[i].info.name, name) == 0) return i;
    return -1;
}

/* Whether the comma-separated list has the item. */
static bool list_has(const char *list, const char *item) {
    size_t n = strlen(item);
    for (const char *p = list; p && *p;) {
        size_t len = strcspn(p, ",");
        if (len == n && strncmp(p, item, n) == 0) return true;
        p += len;
        if (*p == ',') p++;
    }
    return false;
}

int pn_stat_applies(int stat, int method) {
    const pn_method_info *m = pn_method_get(method);
    if (stat < 0 || stat >= STAT_COUNT || !m) return 0;
    const char *group = stats_table[stat].info.group;
    return group[0] == '\0' || list_has(m->stats, group);
}

/* ---- one render's statistics ---------------------------------------------------------------- */

pn_stats pn_stats_new(void) {
    pn_stats s = calloc(1, sizeof *s);
    if (s) s->integrator = s->driver = -1;
    return s;
}

void pn_stats_free(pn_stats stats) {
    free(stats);
}

/* The produced statistic of that name, or NULL. */
static const pn_stat_decl *produced(pn_stats stats, const char *name) {
    int i = pn_stat_find(name);
    if (!stats || !stats->produced || i < 0) return NULL;
    if (!pn_stat_applies(i, stats->integrator) && !pn_stat_applies(i, stats->driver)) return NULL;
    return &stats_table[i];
}

int pn_stats_get(pn_stats stats, const char *name, double *value) {
    const pn_stat_decl *d = produced(stats, name);
    if (!d || d->info.per_rank) return 0;
    if (value) *value = pn_stats_value(&stats->fields, d);
    return 1;
}

int pn_stats_get_array(pn_stats stats, const char *name, double *values, int capacity) {
    const pn_stat_decl *d = produced(stats, name);
    if (!d || !d->info.per_rank) return 0;
    const pn_render_stats *s = &stats->fields;
    int n = s->ranks > 1 ? (s->ranks < PN_STATS_MAX_RANKS ? s->ranks : PN_STATS_MAX_RANKS) : 0;
    const char *p = (const char *)s + d->offset;
    for (int r = 0; values && r < n && r < capacity; r++)
        values[r] = d->field == PN_STAT_F64_RANKS ? ((const double *)(const void *)p)[r]
                                                  : (double)((const uint32_t *)(const void *)p)[r];
    return n;
}
