/* penumbra.h — the one public header of libpenumbra, a many-light renderer for pbrt-v4 scenes.
 *
 * Life cycle, as in Embree's rtcore.h: create a context, load a scene into it, fill a plain
 * settings struct (zero means "default"), render into an image, write the image, free everything
 * in reverse order. Every fallible call returns a pn_status; the context keeps the message of the
 * first error since pn_context_clear_error(), readable with pn_context_error_message().
 * Destructors accept NULL. Nothing in the library exits, aborts or prints to stdout; warnings go
 * through the context's log callback (stderr by default).
 */
#ifndef PENUMBRA_H
#define PENUMBRA_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(PN_STATIC_DEFINE)
#define PN_API
#elif defined(PN_BUILDING_LIBRARY)
#define PN_API __attribute__((visibility("default")))
#else
#define PN_API
#endif

#define PN_VERSION_MAJOR 0
#define PN_VERSION_MINOR 1
#define PN_VERSION_PATCH 0
#define PN_VERSION_STRING "0.1.0"

/* Status codes. Values are stable; the CLI maps them to exit codes (usage 2, bad input 3,
 * system error 4, internal bug 70). */
typedef enum pn_status {
    PN_OK = 0,
    PN_ERROR_INVALID_ARGUMENT = 1, /* a caller passed a value the API does not accept */
    PN_ERROR_BAD_INPUT = 2,        /* a scene, mesh or image file is missing, malformed or invalid */
    PN_ERROR_IO = 3,               /* the system failed to read or write a file */
    PN_ERROR_OUT_OF_MEMORY = 4,
    PN_ERROR_UNSUPPORTED = 5, /* valid input that penumbra cannot render (no substitute exists) */
    PN_ERROR_CANCELLED = 6,   /* the render was stopped through pn_render_cancel() */
    PN_ERROR_INTERNAL = 7     /* a bug in penumbra */
} pn_status;

/* A short, static English description of a status ("bad input", ...). Never NULL. */
PN_API const char *pn_status_string(pn_status status);

/* "0.1.0"; static storage. */
PN_API const char *pn_version_string(void);

/* ---------------------------------------------------------------------------------------- */
/* Context */

typedef struct pn_context_s *pn_context;

typedef enum pn_log_level { PN_LOG_INFO = 0, PN_LOG_WARNING = 1, PN_LOG_ERROR = 2 } pn_log_level;

/* Receives every warning and error message; `message` is valid only during the call. */
typedef void (*pn_log_fn)(void *user, pn_log_level level, const char *message);

/* Creates a context. Returns NULL only when memory is exhausted. Free with pn_context_free. */
PN_API pn_context pn_context_new(void);
PN_API void pn_context_free(pn_context ctx);

/* Replaces the log callback (NULL restores the default, which prints warnings to stderr). */
PN_API void pn_context_set_log(pn_context ctx, pn_log_fn fn, void *user);

/* The message of the first error since the context was created or last cleared, or "" if none.
 * Owned by the context; valid until the next call on it. */
PN_API const char *pn_context_error_message(pn_context ctx);
PN_API void pn_context_clear_error(pn_context ctx);

/* ---------------------------------------------------------------------------------------- */
/* Scene */

typedef struct pn_scene_s *pn_scene;

/* Parses a pbrt-v4 scene file (and everything it includes), validates it and builds the
 * acceleration structure. On success *out_scene owns all scene memory; free with pn_scene_free.
 * On failure *out_scene is NULL and the context's error reads "file:line:column: message". */
PN_API pn_status pn_scene_load(pn_context ctx, const char *path, pn_scene *out_scene);
PN_API void pn_scene_free(pn_scene scene);

/* Statistics of a loaded scene, for `penumbra info`. */
typedef struct pn_scene_info {
    uint64_t triangles;        /* after instancing is flattened in the count, not in memory */
    uint64_t unique_triangles; /* stored once */
    uint32_t meshes;
    uint32_t instances;
    uint32_t spheres;
    uint32_t lights_point, lights_spot, lights_distant, lights_infinite, lights_goniometric;
    uint32_t lights_area_triangle, lights_area_rectangle, lights_area_disk, lights_area_sphere;
    uint32_t materials;
    uint32_t textures;
    uint32_t warnings;
    float bounds_min[3], bounds_max[3];
    int resolution[2];   /* film resolution from the scene file */
    double parse_seconds; /* time spent parsing (PLY included) */
    double bvh_seconds;   /* time spent building the Embree BVH */
} pn_scene_info;

PN_API pn_status pn_scene_get_info(pn_scene scene, pn_scene_info *info);

/* Number of materials and, for material i, a NUL-terminated line saying what the pbrt material
 * was and how penumbra mapped it. Owned by the scene. */
PN_API uint32_t pn_scene_material_count(pn_scene scene);
PN_API const char *pn_scene_material_description(pn_scene scene, uint32_t index);

/* Warnings recorded while loading (each "file:line:column: message"); owned by the scene. */
PN_API uint32_t pn_scene_warning_count(pn_scene scene);
PN_API const char *pn_scene_warning(pn_scene scene, uint32_t index);

/* ---------------------------------------------------------------------------------------- */
/* Render settings: zero-initialise, then set what you need. Zero means the default. */

typedef enum pn_integrator_kind {
    PN_INTEGRATOR_DEFAULT = 0,   /* reference */
    PN_INTEGRATOR_REFERENCE = 1, /* Monte Carlo reference, Donikian et al. 2006 §5.1 */
    PN_INTEGRATOR_IAS = 2,       /* Iterative Adaptive Sampling, Donikian et al. 2006 */
    /* VPL integrators (issue 5): every shading point against every VPL (the reference of the
     * IlluminationCut paper), Lightcuts (Walter et al. 2005), IlluminationCut (Bus et al. 2015) */
    PN_INTEGRATOR_VPL = 4,
    PN_INTEGRATOR_LIGHTCUTS = 5,
    PN_INTEGRATOR_ILLUMCUT = 6,
    /* contour: Approximate Contour Integration for planar convex area lights, Vedel 1993; and
     * contour-mc, its comparison: adaptive Monte Carlo sampling of those lights (Kok & Jansen
     * 1992). Every other light is estimated as by the reference integrator. */
    PN_INTEGRATOR_CONTOUR = 3,
    PN_INTEGRATOR_CONTOUR_MC = 7
} pn_integrator_kind;

/* How the reference integrator chooses a light for a shadow ray. */
typedef enum pn_light_sampler {
    PN_LIGHT_SAMPLER_DEFAULT = 0,    /* irradiance */
    PN_LIGHT_SAMPLER_IRRADIANCE = 1, /* PDF over all lights by unoccluded irradiance (IAS §5.1) */
    PN_LIGHT_SAMPLER_BVH = 2         /* pbrt-v4's light BVH (Conty Estevez & Kulla 2018) */
} pn_light_sampler;

/* AOV layers written beside the beauty image. */
enum {
    PN_AOV_SHADOW_RAYS = 1u << 0,       /* shadow rays per pixel */
    PN_AOV_EYE_RAYS = 1u << 1,          /* eye rays per pixel */
    PN_AOV_RELATIVE_VARIANCE = 1u << 2, /* s^2 / L^2 of the pixel estimate */
    PN_AOV_DEPTH = 1u << 3,             /* camera distance of the first hit */
    PN_AOV_NORMAL = 1u << 4,            /* shading normal of the first hit, world space */
    PN_AOV_ALBEDO = 1u << 5,            /* diffuse reflectance of the first hit */
    PN_AOV_PASSES = 1u << 6,            /* ias: passes per pixel (the paper's Fig. 11) */
    PN_AOV_AA_REGIONS = 1u << 7,        /* ias: antialiasing regions per pixel */
    PN_AOV_CLUSTERS = 1u << 8,          /* ias: clusters per shading point (pixel mean) */
    PN_AOV_VISIBLE_FRACTION = 1u << 9,  /* ias: fraction of shadow rays unoccluded (Fig. 9) */
    /* VPL integrators (issue 5) */
    PN_AOV_BOUND_EVALUATIONS = 1u << 11, /* lightcuts / illumcut: L_UB evaluations per pixel
                                            (IlluminationCut Fig. 4; illumcut: amortised) */
    PN_AOV_CUT_SIZE = 1u << 12,          /* lightcuts: cut size per shading point (pixel mean);
                                            illumcut: pairs touching the pixel's points */
    PN_AOV_PHASE1 = 1u << 13,             /* illumcut: the Phase I approximate image (RGB) */
    PN_AOV_GRADIENT = 1u << 10          /* contour: world-space gradient of the irradiance
                                           luminance from contour lights (W/m^2 per unit length) */
};

/* Progressive drivers (issue 6: dcm, painter, uniform; Guo 1998). A driver decides which pixels
 * of the work image (work_scale x work_scale the output resolution) the integrator evaluates and
 * reconstructs the image from them; the work image is filtered down with a Gaussian. */
typedef enum pn_driver_kind {
    PN_DRIVER_DEFAULT = 0, /* full image in tiles at the output resolution */
    PN_DRIVER_FULL = 1,    /* every work pixel evaluated, then the Gaussian filter: the baseline */
    PN_DRIVER_DCM = 2,     /* Directional Coherence Maps, Guo 1998 */
    PN_DRIVER_PAINTER = 3, /* adaptive progressive refinement, Painter & Sloan 1989 */
    PN_DRIVER_UNIFORM = 4  /* regular subdivision only: uniform subsampling, bilinear interpolation */
} pn_driver_kind;
enum {
    PN_AOV_SAMPLING_PATTERN = 1u << 14, /* progressive: fraction of the work pixels evaluated */
    PN_AOV_BLOCK_MAP = 1u << 15,        /* dcm: 0 smooth, 1 simple, 2 complex, 3 evaluating edge block */
    PN_AOV_BLOCK_DIRECTION = 1u << 16   /* dcm: least-discrepancy direction (degrees), -1 if none */
};
/* Receives an approximate image (owned by the library, valid during the call), the snapshot
 * percentage it was asked for (-1 for a timed or requested snapshot), the percentage of work
 * pixels evaluated so far and the seconds since the render started. */
struct pn_image_s;
typedef void (*pn_snapshot_fn)(void *user, struct pn_image_s *image, double requested_percent,
                               double evaluated_percent, double seconds);

typedef struct pn_render_settings {
    pn_integrator_kind integrator;
    uint32_t spp;              /* fixed eye rays per pixel; 0 = adaptive with threshold */
    double threshold;          /* relative variance target s^2/L^2; default 0.01 when spp = 0 */
    uint32_t shadow_rays;      /* shadow rays per eye ray; default 4 */
    uint32_t max_shadow_rays;  /* per pixel (IAS paper §5.9); default 20000 */
    uint32_t min_shadow_rays_black; /* before a pixel may be declared black; default 2500 */
    uint32_t min_eye_rays;     /* eye rays before the threshold test; default 4 */
    int width, height;         /* 0 = the scene's film resolution */
    int has_crop;              /* when non-zero, crop[] is used instead of the scene's */
    float crop[4];             /* x0, x1, y0, y1 in fractions of the image, as pbrt's cropwindow */
    int threads;               /* 0 = all cores */
    uint64_t seed;
    uint32_t max_specular_depth; /* perfect specular bounces of eye rays; default 8 */
    uint32_t aovs;             /* PN_AOV_* bits */
    /* ias only (zero = the paper's values): maximum solid angle of a light cluster seen from a
     * point (0.02 sr), eye rays per pixel grouped into antialiasing regions (32), regions of an
     * environment map (300), passes per block (15). */
    float cluster_solid_angle;
    uint32_t aa_rays;
    uint32_t env_regions;
    uint32_t max_passes;
    /* Pixels per side of the square blocks the tiled driver hands to the integrator: ias's block
     * of §3.2 (its statistics and PDFs are per block). 8..32; default 8, the paper's. */
    uint32_t block_size;
    /* reference only: how a light is chosen for each shadow ray. */
    pn_light_sampler light_sampler;
    /* Progress: called from worker threads under a lock with the fraction done in [0,1],
     * increasing from call to call, 1 at the end of a finished render (preparation and the
     * phases of whole-image integrators included). */
    void (*progress)(void *user, double fraction);
    void *progress_user;
    /* VPL integrators (issue 5; zero = default): VPL count (600,000), light path depth (10),
     * clamping distance as a fraction of the scene radius (0.05), the relative error bound of
     * lightcuts / illumcut (0.01), lightcuts' maximum cut size (0 = none), and illumcut's
     * adaptive visibility sampling (Algorithm 2) when non-zero. Eye rays per pixel: spp (1). */
    uint32_t vpls;
    uint32_t vpl_max_depth;
    float vpl_clamp_fraction;
    float error_bound;
    uint32_t max_cut;
    int visibility_sampling;
    /* VPL integrators: non-zero for direct light only, the quantity reference, ias and contour
     * compute: the VPLs are the lights themselves (point, spot, goniometric and distant lights as
     * they are, points on area lights and directions of environment maps sampled with their
     * emission), no light path bounces; vpl_max_depth must then be 0, and the clamping distance
     * is 0 unless vpl_clamp_fraction is given. */
    int vpl_direct_only;
    /* contour (Vedel 1993) only; zero = the paper's values: first-level samples per side of a
     * source (3, i.e. a 3x3 grid of 9 samples), dichotomy steps (5), longest span of pixels
     * (8); contour_flags: PN_CONTOUR_* bits that switch parts of the algorithm off (for
     * comparisons). contour-mc (Kok & Jansen 1992) only: the variance threshold of a cell's
     * refinement (default 0.002) and the largest number of shadow rays per light and point
     * (default 256). */
    uint32_t contour_grid;
    uint32_t contour_steps;
    uint32_t contour_span;
    uint32_t contour_flags;
    double contour_mc_threshold;
    uint32_t contour_mc_max_rays;
    /* Progressive drivers (issue 6). */
    pn_driver_kind driver;
    int work_scale;                  /* work image scale s (default 3) */
    const double *snapshot_percents; /* snapshots when these percentages of work pixels are evaluated */
    int snapshot_percent_count;
    double snapshot_every_seconds;   /* and every so many seconds (0: never) */
    pn_snapshot_fn snapshot;         /* NULL: no snapshots */
    void *snapshot_user;
    double stop_percent;             /* stop after this percentage of work pixels (0: run to the end);
                                        with a low threshold: the paper's confidence relocation */
    int raw_radiance;                /* 1: interpolate radiance itself; 0 (default): radiance divided
                                        by the first-hit albedo of a primary ray, then multiplied back */
    int no_light_guide;              /* 1: the demodulation factor is the albedo alone; 0 (default):
                                        albedo x the unshadowed irradiance of all lights at the
                                        primary hit (the light guide, progressive.c) */
    int primary_grid;                /* g x g primary rays per work pixel give the albedo and the
                                        emitted radiance of the pixel where they change (1..8; 0:
                                        the default 3; 1: centre rays only). Along emitters,
                                        `reference` at a fixed spp traces its own eye rays
                                        instead, so emitters match its estimate exactly */
} pn_render_settings;

/* contour_flags bits. */
enum {
    PN_CONTOUR_NO_SHAFT_CULLING = 1u << 0, /* cast rays even where no obstacle is in the shaft */
    PN_CONTOUR_NO_SPANS = 1u << 1,         /* a full contour integration at every pixel */
    PN_CONTOUR_NO_VALIDITY = 1u << 2,      /* no corner test, no subdivision (the Fig. 6 failure) */
    PN_CONTOUR_NO_ADAPTIVE_DENSITY = 1u << 3, /* keep the first-level grid fixed */
    PN_CONTOUR_NO_RESTARTS = 1u << 4, /* accept inconsistencies instead of restarting finer */
    /* Our departures from the paper, on by default (bench/contour/RESULTS.md measures each): */
    PN_CONTOUR_NO_ISLANDS = 1u << 5,    /* no island probes from a nearby pixel's contour */
    PN_CONTOUR_NO_HALF_CHECK = 1u << 6, /* uniform runs check every first-level sample */
    PN_CONTOUR_NO_SCOUTS = 1u << 7,     /* no scout probes inside agreeing first-level squares */
    PN_CONTOUR_NO_LINEAR_RUNS = 1u << 8 /* every run gets its middle integration (the quadratic) */
};

/* ---------------------------------------------------------------------------------------- */
/* Images */

typedef struct pn_image_s *pn_image;

/* Statistics of one render. */
typedef struct pn_render_stats {
    double render_seconds;
    double embree_seconds_estimate; /* time inside Embree calls (every 8th eye ray's calls timed,
                                       scaled, summed over threads and divided by their number) */
    uint64_t eye_rays, shadow_rays, specular_rays;
    double shadow_rays_per_pixel_mean, eye_rays_per_pixel_mean;
    uint64_t shadow_rays_per_pixel_max, eye_rays_per_pixel_max;
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
    uint64_t evaluated_pixels;        /* work pixels evaluated by the integrator */
    double evaluated_percent;         /* of all work pixels of the window */
    int work_width, work_height;      /* of the work window */
    uint32_t dcm_simple_blocks, dcm_complex_blocks; /* edge blocks that passed / failed the tests */
    uint32_t dcm_lazy_blocks;         /* quads that kept their parent's elements (lazy evaluation) */
    double primary_buffer_seconds;    /* the id/normal/depth buffer of primary rays */
    uint64_t primary_grid_pixels;     /* work pixels whose albedo and emitted radiance came from a
                                         grid of primary rays (--primary-grid) */
    double reconstruct_seconds_max;   /* longest reconstruction of an approximate image */
} pn_render_stats;

/* Renders the scene. On success *out_image is a new image (free with pn_image_free) holding the
 * beauty and the requested AOVs; stats (may be NULL) is filled. If cancelled, the partial image
 * is still returned together with PN_ERROR_CANCELLED. */
PN_API pn_status pn_render(pn_context ctx, pn_scene scene, const pn_render_settings *settings,
                           pn_image *out_image, pn_render_stats *stats);

/* Asks running renders of this context to stop after their current tiles, or during their
 * preparation (VPL tracing, light trees). A cancel issued while no render runs applies to the
 * next pn_render of the context, which then returns PN_ERROR_CANCELLED at once; pn_render
 * clears the request when it returns. Safe from a signal handler (it only stores an atomic
 * flag). */
PN_API void pn_render_cancel(pn_context ctx);

/* Progressive drivers (issue 6): asks a running progressive render of this context for one
 * snapshot as soon as possible. Safe from a signal handler (it only stores an atomic flag). */
PN_API void pn_render_request_snapshot(pn_context ctx);

PN_API void pn_image_free(pn_image image);
PN_API int pn_image_width(pn_image image);
PN_API int pn_image_height(pn_image image);
/* Number of layers (beauty is layer 0, "R,G,B"); name of a layer ("" for beauty, else e.g.
 * "shadow_rays"), and its channel count (1 or 3). */
PN_API int pn_image_layer_count(pn_image image);
PN_API const char *pn_image_layer_name(pn_image image, int layer);
PN_API int pn_image_layer_channels(pn_image image, int layer);
/* Pointer to the layer's pixels, row-major, top row first, interleaved channels. Owned by the
 * image. */
PN_API const float *pn_image_layer_data(pn_image image, int layer);

/* Reads an image (EXR, PFM, PNG, TGA, JPG, HDR) as linear RGB into a one-layer image. 8-bit
 * formats are decoded from sRGB. Errors read "file: message". */
PN_API pn_status pn_image_read(pn_context ctx, const char *path, pn_image *out_image);

/* Writes the image; the format follows the extension: .exr (all layers, 32-bit float), .pfm
 * (beauty), .png (beauty, sRGB, multiplied by 2^exposure and clamped). The file is written to a
 * temporary name in the same folder and renamed, so a failed write leaves no broken file. */
PN_API pn_status pn_image_write(pn_context ctx, pn_image image, const char *path, float exposure);

/* A new image holding the pixel rectangle [x0, x0 + width) x [y0, y0 + height) of every layer
 * (for comparing a crop-window render with the matching part of a full reference). */
PN_API pn_status pn_image_crop(pn_context ctx, pn_image image, int x0, int y0, int width, int height,
                               pn_image *out_image);

/* A false-colour picture of one single-channel layer (e.g. "passes", "shadow_rays"), as the IAS
 * paper's Figs. 9 and 11 show them: values mapped linearly from [vmin, vmax] (both 0: the layer's
 * finite minimum and maximum) onto a blue-cyan-green-yellow-red scale, with a colour bar and its
 * two end values drawn below the image. The new image has the layer's width and a taller height;
 * write it with pn_image_write(..., ".png", 0). */
PN_API pn_status pn_image_false_color(pn_context ctx, pn_image image, const char *layer, double vmin, double vmax,
                                      pn_image *out_image);

/* Image comparison for `penumbra diff`. */
typedef struct pn_image_metrics {
    double rmse;
    double relmse;         /* mean over pixels and channels of (a-b)^2 / (b^2 + epsilon) */
    double relmse_epsilon; /* 0.01 */
    double rel_l1;         /* sum|a-b| / sum|b| */
    double rel_l2;         /* ||a-b||_2 / ||b||_2 */
    double mae;
    double mean_luminance_reference, mean_luminance_image;
} pn_image_metrics;

/* Compares the beauty layers of two images of equal size. If error_image is not NULL it
 * receives a new image of |a-b| x 16 (free with pn_image_free). */
PN_API pn_status pn_image_compare(pn_context ctx, pn_image reference, pn_image image,
                                  pn_image_metrics *metrics, pn_image *error_image);

#ifdef __cplusplus
}
#endif
#endif
