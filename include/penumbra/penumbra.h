/* penumbra.h — the one public header of libpenumbra, a many-light renderer for pbrt-v4 scenes.
 *
 * Life cycle, as in Embree's rtcore.h: create a context, load a scene into it, fill a plain
 * settings struct (zero means "default") and set the chosen methods' options by name on a
 * pn_options handle, render into an image (reading what the render measured by name from a
 * pn_stats handle), write the image, free everything in reverse order. Every fallible call
 * returns a pn_status; the context keeps the message of the first error since
 * pn_context_clear_error(), readable with pn_context_error_message().
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
    int resolution[2];          /* film resolution from the scene file */
    double parse_seconds;       /* time spent parsing (PLY included) */
    double bvh_seconds;         /* time spent building the Embree BVH */
    uint32_t lights_projection; /* pbrt-v4 "projection" lights */
    uint64_t texture_bytes;     /* memory of the decoded texture and environment images and of the
                                   image textures' MIP pyramids */
    uint32_t texture_images;    /* distinct image files decoded (one per file and encoding) */
} pn_scene_info;

PN_API pn_status pn_scene_get_info(pn_scene scene, pn_scene_info *info);

/* A measured luminaire: a LightSource "goniometric" whose "filename" is an IES LM-63 or EULUMDAT
 * file (docs/luminaires.md), for `penumbra info`. Strings are owned by the scene. */
typedef struct pn_luminaire_info {
    const char *file;               /* the photometric file, as resolved */
    const char *source;             /* "scene.pbrt:line:column" of the LightSource */
    double lumens;                  /* what the light emits: the file's integral times scale, tilt, power */
    double file_lumens;             /* the file's distribution integrated over the sphere */
    double stated_lumens;           /* lamp lumens the file states; -1: absolute photometry */
    double stated_luminaire_lumens; /* EULUMDAT: lamp flux x light output ratio; -1 when not stated */
    double peak_candela;            /* the light's largest intensity (cd) */
} pn_luminaire_info;

/* Number of measured luminaires, and luminaire i's numbers; index out of range:
 * PN_ERROR_INVALID_ARGUMENT. */
PN_API uint32_t pn_scene_luminaire_count(pn_scene scene);
PN_API pn_status pn_scene_luminaire_get(pn_scene scene, uint32_t index, pn_luminaire_info *info);

/* Number of materials and, for material i, a NUL-terminated line saying what the pbrt material
 * was and how penumbra mapped it. Owned by the scene. */
PN_API uint32_t pn_scene_material_count(pn_scene scene);
PN_API const char *pn_scene_material_description(pn_scene scene, uint32_t index);

/* Warnings recorded while loading (each "file:line:column: message"); owned by the scene. */
PN_API uint32_t pn_scene_warning_count(pn_scene scene);
PN_API const char *pn_scene_warning(pn_scene scene, uint32_t index);

/* ---------------------------------------------------------------------------------------- */
/* Methods: integrators and drivers, and the options they declare.
 *
 * Every integrator (how the light at a pixel is estimated) and every driver (which pixels are
 * evaluated, in which order) is one entry of the library's method table, with its options
 * declared once there (name, type, default, range, unit, help). A render chooses one integrator
 * and one driver in pn_render_settings; options are set by name on a pn_options handle, as
 * OSPRay's ospSetParam does, so that a new method or option changes no public struct. Everything
 * below points to static storage of the library and is valid for the life of the program. */

typedef enum pn_integrator_kind {
    PN_INTEGRATOR_DEFAULT = 0,   /* reference */
    PN_INTEGRATOR_REFERENCE = 1, /* Monte Carlo reference, Donikian et al. 2006 §5.1 */
    PN_INTEGRATOR_IAS = 2,       /* Iterative Adaptive Sampling, Donikian et al. 2006 */
    PN_INTEGRATOR_CONTOUR = 3,   /* Approximate Contour Integration, Vedel 1993 */
    PN_INTEGRATOR_VPL = 4,       /* every shading point against every VPL */
    PN_INTEGRATOR_LIGHTCUTS = 5, /* Walter et al. 2005 */
    PN_INTEGRATOR_ILLUMCUT = 6,  /* IlluminationCut, Bus et al. 2015 */
    PN_INTEGRATOR_CONTOUR_MC = 7 /* adaptive Monte Carlo sampling of area lights, Kok & Jansen 1992 */
} pn_integrator_kind;

typedef enum pn_driver_kind {
    PN_DRIVER_DEFAULT = 0, /* "tiles": the full image in blocks at the output resolution */
    PN_DRIVER_FULL = 1,    /* every work pixel evaluated, then the Gaussian filter: the baseline */
    PN_DRIVER_DCM = 2,     /* Directional Coherence Maps, Guo 1998 */
    PN_DRIVER_PAINTER = 3, /* adaptive progressive refinement, Painter & Sloan 1989 */
    PN_DRIVER_UNIFORM = 4  /* regular subdivision only: uniform subsampling, bilinear interpolation */
} pn_driver_kind;

typedef enum pn_method_role { PN_METHOD_INTEGRATOR = 0, PN_METHOD_DRIVER = 1 } pn_method_role;

/* Capability bits of a method (pn_method_info.capabilities). */
enum {
    PN_CAP_PER_PIXEL = 1u << 0,   /* integrator: each pixel on its own (any batch gives the same pixel) */
    PN_CAP_PER_BLOCK = 1u << 1,   /* integrator: statistics pooled over the batch's block */
    PN_CAP_WHOLE_IMAGE = 1u << 2, /* integrator: under the tiled driver, renders the window in one call */
    PN_CAP_PROGRESSIVE = 1u << 3, /* integrator: works under the progressive drivers; driver: is one */
    PN_CAP_CROP = 1u << 4,        /* a crop renders exactly the pixels of the full image */
    PN_CAP_SPP = 1u << 5,         /* integrator: takes a fixed eye-ray count (settings.spp) */
    PN_CAP_THRESHOLD = 1u << 6,   /* integrator: takes a relative-variance target (settings.threshold) */
    PN_CAP_EMITTED = 1u << 7,     /* integrator: reports the emitted part of each estimate */
    PN_CAP_EYE_SAMPLES = 1u << 8, /* integrator: at a fixed spp, traces pixel eye samples 0..spp-1 */
    PN_CAP_OWN_AOVS = 1u << 9,    /* driver: writes only its own AOVs, none of the integrator's */
    PN_CAP_DISTRIBUTED = 1u << 10 /* driver: renders in tiles that MPI ranks, --piece parts and
                                     checkpoints share out (integrators without PN_CAP_CROP need an
                                     explicit tile-size) */
};

typedef struct pn_method_info {
    const char *name; /* "reference", "ias", ..., "tiles", "dcm", ... */
    pn_method_role role;
    int kind;                /* the pn_integrator_kind or pn_driver_kind value */
    const char *description; /* one line */
    const char *paper;       /* the paper it implements, or "" */
    const char *computes;    /* "direct light", "global illumination (VPLs)", or for drivers which pixels */
    uint32_t capabilities;   /* PN_CAP_* bits */
    uint32_t aovs;           /* PN_AOV_* bits of the layers it can write besides the common ones */
    const char *stats;       /* comma-separated groups of statistics it produces (pn_stat_info.group) */
    uint32_t default_spp;    /* integrators with PN_CAP_SPP: eye rays per pixel when spp is 0 (0: adaptive) */
} pn_method_info;

/* Number of methods, and method i (0 <= i < count; NULL otherwise). */
PN_API int pn_method_count(void);
PN_API const pn_method_info *pn_method_get(int index);
/* The index of the method of that role and name, or -1. */
PN_API int pn_method_find(pn_method_role role, const char *name);
/* The index of the method of that role and kind, or -1 (PN_*_DEFAULT gives the default's). */
PN_API int pn_method_find_kind(pn_method_role role, int kind);

typedef enum pn_option_type {
    PN_OPTION_INT = 0,    /* an integer in [min, max] */
    PN_OPTION_DOUBLE = 1, /* a finite number in the range (bounds exclusive where flagged) */
    PN_OPTION_FLAG = 2,   /* on or off ("1"/"0", "true"/"false", "on"/"off") */
    PN_OPTION_CHOICE = 3, /* one name of `choices` */
    PN_OPTION_SET = 4,    /* a comma-separated subset of `choices` ("" for none) */
    PN_OPTION_LIST = 5,   /* a comma-separated list of numbers, each in the range */
    PN_OPTION_STRING = 6  /* any text (e.g. a file name) */
} pn_option_type;

typedef struct pn_option_info {
    const char *name; /* "vpls"; the CLI flag is "--" name */
    pn_option_type type;
    const char *default_value; /* as text, parsed like a set value; "" for none */
    double min, max;           /* range of INT, DOUBLE and LIST values */
    int min_exclusive, max_exclusive;
    const char *unit;    /* "sr", "pixels", "" ... */
    const char *choices; /* CHOICE and SET: comma-separated names */
    const char *help;    /* one sentence */
} pn_option_info;

/* Number of declared options, and option i (NULL when out of range). */
PN_API int pn_option_count(void);
PN_API const pn_option_info *pn_option_get(int index);
/* The index of the option of that name, or -1. */
PN_API int pn_option_find(const char *name);
/* Whether option `option` belongs to method `method` (indices as above). */
PN_API int pn_option_applies(int option, int method);
/* Writes what a value of the option must be ("an integer from 1 to 4096", "'exact' or
 * 'sampling'", ...) into buf (NUL-terminated, truncated to size). */
PN_API void pn_option_describe(int option, char *buf, size_t size);

/* A set of option values by name. Create, set, pass in pn_render_settings.options, free. */
typedef struct pn_options_s *pn_options;

/* Returns NULL only when memory is exhausted. Free with pn_options_free (NULL is accepted). */
PN_API pn_options pn_options_new(void);
PN_API void pn_options_free(pn_options options);
/* Sets an option from text, parsed strictly against its declared type and range (the whole
 * text must be a value). An unknown name or a bad value is PN_ERROR_INVALID_ARGUMENT with a
 * message on the context naming the option and what it accepts; the options are then unchanged. */
PN_API pn_status pn_options_set(pn_context ctx, pn_options options, const char *name, const char *value);
/* Typed setters, checked as pn_options_set (INT and FLAG options take set_int, DOUBLE set_double). */
PN_API pn_status pn_options_set_int(pn_context ctx, pn_options options, const char *name, int64_t value);
PN_API pn_status pn_options_set_double(pn_context ctx, pn_options options, const char *name, double value);
/* Removes a value set before (the default applies again). */
PN_API void pn_options_unset(pn_options options, const char *name);
/* Whether option `option` (an index) was set. */
PN_API int pn_options_is_set(pn_options options, int option);
/* The value in force for option `option`: the set one, else the declared default. For INT, FLAG,
 * DOUBLE and CHOICE options *number receives the value (a CHOICE its numeric code; may be NULL);
 * text receives the canonical text form, which pn_options_set accepts back (may be NULL). */
PN_API pn_status pn_options_get(pn_options options, int option, double *number, char *text, size_t text_size);
/* Checks that every option set applies to the chosen integrator or driver. Otherwise
 * PN_ERROR_INVALID_ARGUMENT, with a message naming the option, the method and what it accepts.
 * pn_render does the same check. */
PN_API pn_status pn_options_check(pn_context ctx, pn_options options, pn_integrator_kind integrator,
                                  pn_driver_kind driver);

/* ---------------------------------------------------------------------------------------- */
/* Render settings: PN_RENDER_SETTINGS_INIT (or zero-initialise), then set what you need. Zero
 * means the default. */

/* AOV layers written beside the beauty image. The first six every integrator writes under the
 * tiled driver; pn_method_info.aovs tells which of the others a method writes. */
enum {
    PN_AOV_SHADOW_RAYS = 1u << 0,        /* shadow rays per pixel */
    PN_AOV_EYE_RAYS = 1u << 1,           /* eye rays per pixel */
    PN_AOV_RELATIVE_VARIANCE = 1u << 2,  /* s^2 / L^2 of the pixel estimate */
    PN_AOV_DEPTH = 1u << 3,              /* camera distance of the first hit */
    PN_AOV_NORMAL = 1u << 4,             /* shading normal of the first hit, world space */
    PN_AOV_ALBEDO = 1u << 5,             /* diffuse reflectance of the first hit */
    PN_AOV_PASSES = 1u << 6,             /* ias: passes per pixel (the paper's Fig. 11) */
    PN_AOV_AA_REGIONS = 1u << 7,         /* ias: antialiasing regions per pixel */
    PN_AOV_CLUSTERS = 1u << 8,           /* ias: clusters per shading point (pixel mean) */
    PN_AOV_VISIBLE_FRACTION = 1u << 9,   /* ias: fraction of shadow rays unoccluded (Fig. 9) */
    PN_AOV_GRADIENT = 1u << 10,          /* contour: world-space gradient of the irradiance
                                           luminance from contour lights (W/m^2 per unit length) */
    PN_AOV_BOUND_EVALUATIONS = 1u << 11, /* lightcuts / illumcut: L_UB evaluations per pixel
                                            (IlluminationCut Fig. 4; illumcut: amortised) */
    PN_AOV_CUT_SIZE = 1u << 12,          /* lightcuts: cut size per shading point (pixel mean);
                                            illumcut: pairs touching the pixel's points */
    PN_AOV_PHASE1 = 1u << 13,            /* illumcut: the Phase I approximate image (RGB) */
    PN_AOV_SAMPLING_PATTERN = 1u << 14,  /* progressive: fraction of the work pixels evaluated */
    PN_AOV_BLOCK_MAP = 1u << 15,         /* dcm: 0 smooth, 1 simple, 2 complex, 3 evaluating edge block */
    PN_AOV_BLOCK_DIRECTION = 1u << 16,   /* dcm: least-discrepancy direction (degrees), -1 if none */
    PN_AOV_ILLUMINANCE = 1u << 17,       /* illuminance (lux) on the first non-specular surface seen:
                                            direct (reference), total (vpl, lightcuts); see
                                            docs/lighting-design.md */
    PN_AOV_LUMINANCE = 1u << 18,         /* luminance (cd/m^2) of the pixel's radiance */
    PN_AOV_XYZ = 1u << 19,               /* CIE 1931 XYZ of the pixel's radiance (Y in cd/m^2) */
    PN_AOV_MELANOPIC_EDI = 1u << 20      /* melanopic equivalent daylight (D65) illuminance (lux,
                                            CIE S 026) where the illuminance AOV is computed;
                                            spectral mode only; see docs/lighting-design.md */
};
/* the layers every integrator writes under the tiled driver: the first six, luminance and XYZ */
#define PN_AOV_COMMON (0x3fu | PN_AOV_LUMINANCE | PN_AOV_XYZ)

/* Number of AOV layers, and the name and PN_AOV_* bit of layer i (NULL when out of range). */
PN_API int pn_aov_count(void);
PN_API const char *pn_aov_name(int index, uint32_t *bit);

/* Receives an approximate image (owned by the library, valid during the call), the snapshot
 * percentage it was asked for (-1 for a timed or requested snapshot), the percentage of work
 * pixels evaluated so far and the seconds since the render started (progressive drivers). */
struct pn_image_s;
typedef void (*pn_snapshot_fn)(void *user, struct pn_image_s *image, double requested_percent, double evaluated_percent,
                               double seconds);

/* The most worker threads a render uses (pn_render_settings.threads). */
#define PN_MAX_THREADS 1024

typedef struct pn_render_settings {
    /* Forward compatibility: sizeof the struct as the caller was compiled (PN_RENDER_SETTINGS_INIT
     * and pn_render_settings_init set it). Later versions only append fields: a library reads
     * the fields the caller's size covers and gives the others their defaults; a size larger
     * than the library's is accepted when the fields it does not know are zero. 0 means this
     * layout (penumbra 0.1, the first with the field), so zero-initialised settings stay valid. */
    uint32_t struct_size;
    pn_integrator_kind integrator;
    pn_driver_kind driver;
    uint32_t spp;      /* fixed eye rays per pixel (integrators with PN_CAP_SPP); 0 = the
                                  method's default_spp, adaptive with threshold when that is 0 */
    double threshold;  /* relative variance target s^2/L^2 (PN_CAP_THRESHOLD); default 0.01 */
    int width, height; /* 0 = the scene's film resolution */
    int has_crop;      /* when non-zero, crop[] is used instead of the scene's */
    float crop[4];     /* x0, x1, y0, y1 in fractions of the image, as pbrt's cropwindow */
    int threads;       /* 0 = all cores (at most PN_MAX_THREADS); more is PN_ERROR_INVALID_ARGUMENT */
    uint64_t seed;
    uint32_t max_specular_depth; /* perfect specular bounces of eye rays; default 8 */
    uint32_t aovs;               /* PN_AOV_* bits */
    /* Options of the integrator and driver by name (NULL: all defaults). Not owned. */
    pn_options options;
    /* Progress: called from worker threads under a lock with the fraction done in [0,1],
     * increasing from call to call, 1 at the end of a finished render (preparation and the
     * phases of whole-image integrators included). */
    void (*progress)(void *user, double fraction);
    void *progress_user;
    /* Progressive drivers: called with each approximate image (options "snapshots",
     * "snapshot-every", or pn_render_request_snapshot); NULL: no snapshots. */
    pn_snapshot_fn snapshot;
    void *snapshot_user;
    /* Progressive drivers (issue 18): called with progress_user, the percentage of evaluated work
     * pixels and the error estimate (the relative L1 change between the last two --preview
     * images; -1 before there are two) after every chunk of pixels; NULL: previews are logged. */
    void (*progress_note)(void *user, double evaluated_percent, double error_estimate);
} pn_render_settings;

/* Settings at their defaults with struct_size set: `pn_render_settings s = PN_RENDER_SETTINGS_INIT;`
 * then set fields, or pn_render_settings_init(&s). */
#define PN_RENDER_SETTINGS_INIT                                                                                        \
    { .struct_size = (uint32_t)sizeof(pn_render_settings) }
static inline void pn_render_settings_init(pn_render_settings *settings) {
    pn_render_settings defaults = PN_RENDER_SETTINGS_INIT;
    *settings = defaults;
}

/* ---------------------------------------------------------------------------------------- */
/* Images */

typedef struct pn_image_s *pn_image;

/* ---------------------------------------------------------------------------------------- */
/* Statistics by name.
 *
 * What a render measured (rays, times, the methods' own counters) is declared once in the
 * library's table of statistics (name as in the stats JSON, type, unit, help, which methods
 * produce it, how the parts of a split render combine) and read by name from a pn_stats handle
 * that pn_render fills, as options are set by name: a new statistic changes no public struct.
 * Table entries point to static storage, valid for the life of the program. */

typedef enum pn_stat_type {
    PN_STAT_COUNT = 0,   /* a count of things (rays, pixels, bytes, VPLs, ...) */
    PN_STAT_SECONDS = 1, /* a time in seconds */
    PN_STAT_MEAN = 2,    /* a mean, fraction, percentage or rate */
    PN_STAT_MAX = 3,     /* a largest count */
    PN_STAT_INT = 4,     /* a size or number of the run (width, threads, ranks) */
    PN_STAT_FLAG = 5     /* 0 or 1 (partial) */
} pn_stat_type;

/* How the statistics of crop renders of one image combine into the whole image's (penumbra merge). */
typedef enum pn_stat_merge {
    PN_STAT_MERGE_SUM = 0,    /* the parts' values added */
    PN_STAT_MERGE_MAX = 1,    /* the largest part's value */
    PN_STAT_MERGE_MEAN = 2,   /* the mean of the parts' values weighted by their pixels */
    PN_STAT_MERGE_ANY = 3,    /* a flag: set when any part's is */
    PN_STAT_MERGE_WIDTH = 4,  /* the whole image's width (a work width: scaled as in the parts) */
    PN_STAT_MERGE_HEIGHT = 5, /* the whole image's height (likewise) */
    PN_STAT_MERGE_FIRST = 6   /* the first part's (per-rank arrays) */
} pn_stat_merge;

typedef struct pn_stat_info {
    const char *name; /* as in the stats JSON (docs/stats-json.md): "eye_rays", ... */
    pn_stat_type type;
    const char *unit;  /* "rays", "s", "pixels", "bytes", "%", "" ... */
    const char *group; /* "": every render produces it; else the group that a method's
                          pn_method_info.stats names ("ias_tables", "vpl_cuts", ...) */
    pn_stat_merge merge;
    int per_rank;     /* 1: one value per MPI rank (rank 0 first), read with pn_stats_get_array */
    const char *help; /* one sentence */
} pn_stat_info;

/* Number of declared statistics, and statistic i (NULL when out of range). */
PN_API int pn_stat_count(void);
PN_API const pn_stat_info *pn_stat_get(int index);
/* The index of the statistic of that name, or -1. */
PN_API int pn_stat_find(const char *name);
/* Whether method `method` (an index of the method table) produces statistic `stat`: its group
 * is among the method's pn_method_info.stats groups, or "" (every render). */
PN_API int pn_stat_applies(int stat, int method);

/* The statistics of one render. Create, pass to pn_render, read, free. */
typedef struct pn_stats_s *pn_stats;

/* Returns NULL only when memory is exhausted. Free with pn_stats_free (NULL is accepted). */
PN_API pn_stats pn_stats_new(void);
PN_API void pn_stats_free(pn_stats stats);
/* Whether the last render into `stats` produced the scalar statistic `name` (its integrator or
 * driver produces it, pn_stat_applies); if so *value (may be NULL) receives it. An unknown name,
 * a per-rank statistic, or stats that no render filled: 0, *value untouched. */
PN_API int pn_stats_get(pn_stats stats, const char *name, double *value);
/* Per-rank statistics (pn_stat_info.per_rank): the number of values the last render produced
 * (its MPI ranks when there were several, else 0; 0 as well for an unknown or scalar name), of
 * which the first min(count, capacity) are written to values (may be NULL when capacity is 0). */
PN_API int pn_stats_get_array(pn_stats stats, const char *name, double *values, int capacity);

/* ---- lighting design: illuminance at points, no camera (docs/lighting-design.md) ---------- */

/* A calculation point: position and the unit normal of the surface it measures. */
typedef struct pn_illuminance_point {
    float p[3];
    float n[3];
} pn_illuminance_point;

/* Computes the illuminance in lux at each of the count points, on the side of its normal, into
 * lux[i] (the caller's array of count values): with settings->integrator reference the direct
 * light, by the reference integrator's light estimator (settings->spp, default 64, times its
 * shadow-rays option light samples per point); with vpl or lightcuts the total (VPLs of
 * vpl-depth bounces) by that integrator's estimator for a white Lambertian receiver. Other
 * integrators: PN_ERROR_INVALID_ARGUMENT (the method table lists "illuminance" among the AOVs of
 * those that can). Points are independent (point i draws its numbers from (seed, i)), so the
 * result does not depend on the thread count. Driver and image settings are ignored. */
PN_API pn_status pn_illuminance(pn_context ctx, pn_scene scene, const pn_render_settings *settings,
                                const pn_illuminance_point *points, int count, double *lux);
/* pn_illuminance that also writes the melanopic equivalent daylight (D65) illuminance of each
 * point (CIE S 026, lux) into edi[i], from the same light samples at wavelengths of their own.
 * Needs spectral mode (the option "spectral") and the reference integrator, else
 * PN_ERROR_INVALID_ARGUMENT; edi NULL is pn_illuminance. */
PN_API pn_status pn_illuminance_melanopic(pn_context ctx, pn_scene scene, const pn_render_settings *settings,
                                          const pn_illuminance_point *points, int count, double *lux, double *edi);

/* Renders the scene. On success *out_image is a new image (free with pn_image_free) holding the
 * beauty and the requested AOVs; stats (may be NULL) receives the render's statistics, replacing
 * what it held (read them with pn_stats_get). If cancelled, the partial image and statistics are
 * still returned together with PN_ERROR_CANCELLED. */
PN_API pn_status pn_render(pn_context ctx, pn_scene scene, const pn_render_settings *settings, pn_image *out_image,
                           pn_stats stats);

/* Rendering across MPI processes (docs/distributed.md). A program started by mpirun calls
 * pn_mpi_init once before anything else: it joins the job (MPI_Init; nothing when the process
 * was not started by an MPI launcher) and tells this process's rank and the number of ranks.
 * From then on pn_render with the tiles driver renders across all ranks, which must all call it
 * with the same scene and settings: rank 0 hands out tiles and receives the image (the other
 * ranks get PN_OK and no image, *out_image NULL). pn_mpi_agree is a collective check of every
 * rank's status (e.g. after pn_scene_load): the first failure's status on every rank, and on
 * rank 0 the context's message "rank R of N: message". Without MPI in the build, pn_mpi_init
 * fails when started as one of several MPI processes, and otherwise these are the one-process
 * case. pn_mpi_finalize ends MPI at exit. */
PN_API int pn_mpi_available(void);
PN_API pn_status pn_mpi_init(pn_context ctx, int *argc, char ***argv, int *rank, int *size);
PN_API pn_status pn_mpi_agree(pn_context ctx, pn_status local);
PN_API void pn_mpi_finalize(void);

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
/* Reads the single-channel AOV layer `layer` of an EXR file written by pn_image_write into an
 * image with that layer (and its values as a grey beauty). Errors read "file: message". */
PN_API pn_status pn_image_read_layer(pn_context ctx, const char *path, const char *layer, pn_image *out_image);

/* The most pixels an image file (texture, environment map, or an image pn_image_read reads) may
 * have on this context; a larger one is PN_ERROR_BAD_INPUT before anything is allocated. 0 =
 * the default, 16384 x 16384 (2^28 pixels, 3 GiB as RGB floats). Applies to later loads. */
PN_API void pn_context_set_image_pixel_limit(pn_context ctx, uint64_t max_pixels);

/* Writes the image; the format follows the extension: .exr (all layers, 32-bit float), .pfm
 * (beauty), .png (beauty, sRGB, multiplied by 2^exposure and clamped). The file is written to a
 * temporary name in the same folder and renamed, so a failed write leaves no broken file. */
PN_API pn_status pn_image_write(pn_context ctx, pn_image image, const char *path, float exposure);

/* pbrt-v4's goniometric image of the measured luminaire in `path` (IES LM-63 .ies or EULUMDAT
 * .ldt), for `penumbra ies2goniometric`: a resolution x resolution image in pbrt-v4's
 * equal-area octahedral mapping of the light's frame with y and z swapped (pbrt-v4's
 * GoniometricLight), each pixel the mean candela over its solid angle (4 x 4 samples), R = G =
 * B. pbrt-v4 (and penumbra) render LightSource "goniometric" with this image as the luminaire
 * placed by the same transform. On success *out_image is new (free with pn_image_free); bad
 * files: PN_ERROR_BAD_INPUT with "file:line: message". */
PN_API pn_status pn_photometry_goniometric_image(pn_context ctx, const char *path, int resolution, pn_image *out_image);

/* Writes size bytes to path by the same atomic route as pn_image_write (a temporary beside it,
 * synced and renamed), so that a failed write leaves no broken file. For the CLI's JSON. */
PN_API pn_status pn_file_write(pn_context ctx, const char *path, const void *data, size_t size);

/* A set of output files written together (a render's image, PNG, statistics, AOV pictures):
 * each add writes a complete, synced temporary beside its target and fails without touching
 * the target; pn_output_set_commit renames all temporaries into place, in the order they were
 * added, stopping at the first failure; pn_output_set_free removes every temporary not renamed.
 * So a failure of any output leaves none of them (commit only when every add succeeded). Only
 * a regular file (or nothing) at a target is replaced; a device, FIFO, folder or symbolic link
 * is refused with PN_ERROR_IO. At most 64 files per set. */
typedef struct pn_output_set_s *pn_output_set;
PN_API pn_output_set pn_output_set_new(void); /* NULL when out of memory */
PN_API pn_status pn_output_set_add_image(pn_context ctx, pn_output_set set, pn_image image, const char *path,
                                         float exposure);
PN_API pn_status pn_output_set_add_file(pn_context ctx, pn_output_set set, const char *path, const void *data,
                                        size_t size);
PN_API pn_status pn_output_set_commit(pn_context ctx, pn_output_set set);
/* Removes the set's temporaries from disk (not its memory); async-signal-safe, for a handler
 * of SIGINT or SIGTERM that then ends the process. Accepts NULL. */
PN_API void pn_output_set_discard_temporaries(pn_output_set set);
PN_API void pn_output_set_free(pn_output_set set); /* accepts NULL */

/* A new image holding the pixel rectangle [x0, x0 + width) x [y0, y0 + height) of every layer
 * (for comparing a crop-window render with the matching part of a full reference). */
PN_API pn_status pn_image_crop(pn_context ctx, pn_image image, int x0, int y0, int width, int height,
                               pn_image *out_image);

/* Crop renders and their assembly (docs/distributed.md). A crop render's image remembers where
 * it lies: window[0], window[1] receive the position of its pixel (0, 0) in the whole image and
 * window[2], window[3] the whole image's size (for an uncropped image 0, 0, width, height). The
 * EXR writer stores it as the data window inside the display window, as pbrt-v4 does. */
PN_API void pn_image_window(pn_image image, int window[4]);
/* Reads every layer of an EXR file (beauty "R,G,B", "x.R/G/B" as layer x, other channels as
 * one-channel layers) with its data and display windows. Errors read "file: message". A data
 * window over the context's pixel limit, or more pixels x channels than an RGB image at that
 * limit, is refused before anything is allocated. */
PN_API pn_status pn_image_read_layers(pn_context ctx, const char *path, pn_image *out_image);
/* Assembles crop images of one render into the whole image: every part must have the same
 * display window and the same layers, no two may overlap, and together they must cover the
 * image; otherwise PN_ERROR_BAD_INPUT with a message naming the part (names[i] is parts[i]'s). */
PN_API pn_status pn_image_merge(pn_context ctx, const pn_image *parts, const char *const *names, int count,
                                pn_image *out_image);

/* A false-colour picture of one single-channel layer (e.g. "passes", "shadow_rays"), as the IAS
 * paper's Figs. 9 and 11 show them: values mapped linearly from [vmin, vmax] (both 0: the layer's
 * finite minimum and maximum) onto a blue-cyan-green-yellow-red scale, with a colour bar and its
 * two end values drawn below the image. The new image has the layer's width and a taller height;
 * write it with pn_image_write(..., ".png", 0). */
PN_API pn_status pn_image_false_color(pn_context ctx, pn_image image, const char *layer, double vmin, double vmax,
                                      pn_image *out_image);

/* False colour for lighting analysis, as RADIANCE's falsecolor draws it (docs/lighting-design.md):
 * a legend at the left with `divisions` boxes, each labelled with its lower value in real units,
 * the label on top. */
typedef enum pn_false_color_style {
    PN_FALSE_COLOR_SMOOTH = 0, /* continuous colours */
    PN_FALSE_COLOR_LINES = 1,  /* contour lines at the division values, on black (falsecolor -cl) */
    PN_FALSE_COLOR_BANDS = 2   /* one colour per division (falsecolor -cb) */
} pn_false_color_style;

typedef struct pn_false_color_options {
    double scale;      /* top of the scale (falsecolor -s); <= 0: the layer's largest finite value */
    double multiplier; /* the layer's values are multiplied by it first (-m); 0 means 1 */
    int log_decades;   /* > 0: logarithmic over this many decades below scale (-log); 0: linear from 0 */
    int divisions;     /* legend boxes and contour levels (-n); 0 means 8 */
    pn_false_color_style style;
    const char *label; /* legend title (-l), e.g. "lux" or "cd/m2"; NULL: none */
} pn_false_color_options;

/* The false-colour picture of single-channel layer `layer` with its legend (options NULL: the
 * defaults above). Colours run from dark purple (low) through blue, green and red to yellow
 * (high). The picture is the layer's height (at least 128 rows, for the legend) and its width
 * plus the legend's. Write it with pn_image_write(..., ".png", 0). */
PN_API pn_status pn_image_false_color_legend(pn_context ctx, pn_image image, const char *layer,
                                             const pn_false_color_options *options, pn_image *out_image);

/* A new image of width x height holding `values` (row-major, top row first) as its single-channel
 * layer `layer` (the beauty is black), e.g. for pn_image_false_color_legend of a grid. */
PN_API pn_status pn_image_from_values(pn_context ctx, int width, int height, const char *layer, const float *values,
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
PN_API pn_status pn_image_compare(pn_context ctx, pn_image reference, pn_image image, pn_image_metrics *metrics,
                                  pn_image *error_image);

#ifdef __cplusplus
}
#endif
#endif
