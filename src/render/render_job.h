/* render_job.h — everything an integrator needs to know about one render, resolved once. */
#ifndef PN_RENDER_RENDER_JOB_H
#define PN_RENDER_RENDER_JOB_H

#include "accel/accel.h"
#include "lights/lights.h"
#include "render/camera.h"
#include "scene/scene.h"

#include <stdatomic.h>
#include <stdbool.h>

/* How the reference integrator chooses a light for a shadow ray (option light-sampler). */
enum {
    PN_LIGHT_SAMPLER_IRRADIANCE = 1, /* PDF over all lights by unoccluded irradiance (IAS §5.1) */
    PN_LIGHT_SAMPLER_BVH = 2         /* pbrt-v4's light BVH (Conty Estevez & Kulla 2018) */
};

/* contour_flags bits (option contour-off, in the order of its choices). */
enum {
    PN_CONTOUR_NO_SHAFT_CULLING = 1u << 0,    /* cast rays even where no obstacle is in the shaft */
    PN_CONTOUR_NO_SPANS = 1u << 1,            /* a full contour integration at every pixel */
    PN_CONTOUR_NO_VALIDITY = 1u << 2,         /* no corner test, no subdivision (the Fig. 6 failure) */
    PN_CONTOUR_NO_ADAPTIVE_DENSITY = 1u << 3, /* keep the first-level grid fixed */
    PN_CONTOUR_NO_RESTARTS = 1u << 4,         /* accept inconsistencies instead of restarting finer */
    /* Our departures from the paper, on by default (bench/contour/RESULTS.md measures each): */
    PN_CONTOUR_NO_ISLANDS = 1u << 5,    /* no island probes from a nearby pixel's contour */
    PN_CONTOUR_NO_HALF_CHECK = 1u << 6, /* uniform runs check every first-level sample */
    PN_CONTOUR_NO_SCOUTS = 1u << 7,     /* no scout probes inside agreeing first-level squares */
    PN_CONTOUR_NO_LINEAR_RUNS = 1u << 8 /* every run gets its middle integration (the quadratic) */
};

/* A list option's values (e.g. snapshot percentages). */
#define PN_JOB_LIST_MAX 64
typedef struct pn_job_list {
    int count;
    double values[PN_JOB_LIST_MAX];
} pn_job_list;

/* The stopping rules of an adaptive render (docs/adaptive-sampling.md); the codes of the choices
 * of the option adaptive-rule, in its declared order. */
enum {
    PN_ADAPTIVE_AUTO = 0,  /* reference: cross; ias: paper */
    PN_ADAPTIVE_PAPER = 1, /* Donikian et al. 2006 sections 5.1/5.9: s^2/L^2 of the kept samples, biased */
    PN_ADAPTIVE_CROSS = 2  /* two independent eye-ray streams, each one's count decided by the
                              other's pilot: unbiased */
};

/* ias (issue 15): the codes of the choices of ias-variant, ias-cut and ias-prior, in their
 * declared order. */
enum { PN_IAS_VARIANT_DEFAULT = 0, PN_IAS_VARIANT_PAPER = 1 };
enum { PN_IAS_CUT_TREES = 0, PN_IAS_CUT_BVH = 1 };
enum { PN_IAS_STATS_TREE = 0, PN_IAS_STATS_CUT = 1 };
enum { PN_IAS_PICK_POWER = 0, PN_IAS_PICK_IMPORTANCE = 1, PN_IAS_PICK_LARGE = 2 };
enum { PN_IAS_PRIOR_UNIFORM = 0, PN_IAS_PRIOR_IMPORTANCE = 1 };
enum { PN_IAS_POINTS_REPRESENTATIVE = 0, PN_IAS_POINTS_MEMBERS = 1 };
enum { PN_IAS_NUMBERS_JITTERED = 0, PN_IAS_NUMBERS_SOBOL = 1 };

typedef struct pn_render_job {
    const struct pn_scene_s *scene;
    const pn_accel *accel;
    const pn_lights *lights;
    pn_camera camera;
    /* Common settings with defaults applied. */
    uint32_t spp; /* 0: adaptive */
    double threshold;
    uint32_t max_specular_depth;
    uint64_t seed;
    uint32_t aovs;
    /* Method options: every option of the table in integrators/registry.c, its set value or its
     * declared default (pn_registry_resolve). A new option adds its field here. */
    uint32_t shadow_rays;     /* per eye ray */
    uint32_t max_shadow_rays; /* per pixel */
    uint32_t min_shadow_rays_black;
    uint32_t min_eye_rays;
    /* ias */
    float cluster_solid_angle;
    uint32_t aa_rays, env_regions, max_passes;
    uint32_t block_size; /* pixels per side of the tiled driver's blocks (ias: its blocks) */
    /* ias, issue 15 (integrators/ias.c): the variant and the default variant's departures */
    int ias_variant;            /* PN_IAS_VARIANT_* */
    int ias_cut;                /* PN_IAS_CUT_* */
    int ias_prior;              /* PN_IAS_PRIOR_* */
    int ias_points;             /* PN_IAS_POINTS_* */
    int ias_cluster_numbers;    /* PN_IAS_NUMBERS_* */
    uint32_t ias_cut_size;      /* nodes of a light-BVH cut */
    uint32_t ias_pass_rays;     /* pass j takes (j + 1) times this; 0: the paper's 1.5 N_C >= 50 */
    uint32_t ias_cut_max;       /* trees cut: most clusters per point (priority refinement); 0: no cap */
    int ias_stats;              /* PN_IAS_STATS_*: where many-light statistics are kept */
    int ias_cluster_pick;       /* PN_IAS_PICK_*: a light within a trees-cut cluster, by power or importance */
    double ias_aa_threshold;    /* below this threshold the eye rays grow as 1 / threshold; 0: off */
    double ias_aa_power;        /* ias-aa-power: the eye rays grow as (ias_aa_threshold / threshold)^this */
    double ias_prior_share;     /* least weight of the prior in eq. 6's blend; 0: Fig. 2's weights */
    double ias_env_floor;       /* environment regions keep this times their pass-0 probability; 0: off */
    uint32_t ias_edge_rays;     /* ias-emitter-rays: eye rays next to emitter edges; 0: off */
    int ias_ratio;              /* ias-ratio: PN_IAS_RATIO_* (integrators/ias_ratio.h) */
    uint32_t ias_ratio_members; /* ias-ratio-members: largest cluster given its closed form */
    int ias_mis;                /* ias-mis: PN_IAS_MIS_* (integrators/ias_mis.h) */
    double ias_mis_share;       /* ias-mis-share: expected BSDF rays per light sample, (0, 1] */
    int ias_light_guide;        /* ias-light-guide: 1 to guide samples within large lights (ias_guide.h) */
    int ias_guide_rotate;       /* ias-guide-rotate: 1 to rotate the guided numbers per pixel and pass */
    uint32_t ias_guide_refresh; /* ias-guide-refresh: first-pass pixels between grid rebuilds; 0: off */
    /* reference */
    int light_sampler; /* PN_LIGHT_SAMPLER_IRRADIANCE or _BVH */
    /* reference and ias with a threshold: the stopping rule (option adaptive-rule; AUTO is
     * resolved by pn_render to CROSS for reference and PAPER for ias, never left AUTO) */
    int adaptive_rule;
    /* VPL integrators */
    uint32_t vpls, vpl_max_depth, max_cut;
    float vpl_clamp_fraction, error_bound;
    bool visibility_sampling;
    bool vpl_direct_only; /* the lights themselves as VPLs, no bounces (direct light only) */
    bool opaque_glass;    /* thin glass panes block shadow rays (option opaque-glass; render/shadow.c) */
    bool spectral;        /* spectral transport (option spectral; spectral/transport.h) */
    /* contour / contour-mc (Vedel 1993; Kok & Jansen 1992) */
    uint32_t contour_grid, contour_steps, contour_span, contour_flags;
    double contour_mc_threshold;
    uint32_t contour_mc_max_rays;
    int contour_scout; /* -1: by the first-level density */
    int contour_part;  /* 1, 2 or 4 */
    double contour_linear_tol;
    const char *contour_trace; /* NULL: no trace */
    /* progressive drivers */
    int work_scale, primary_grid;
    double stop_percent, snapshot_every_seconds;
    bool raw_radiance, no_light_guide;
    pn_job_list snapshots; /* percentages of the work pixels */
    /* the tiled driver's distribution (docs/distributed.md): tile side (0: 64, or the whole
     * window for integrators without PN_CAP_CROP), the piece "K/M" (option piece) and the checkpoint file */
    uint32_t tile_size;
    const char *tiles_piece;      /* NULL: the whole window */
    const char *checkpoint_path;  /* NULL: none */
    const char *tile_times_path;  /* NULL: none (bench instrumentation) */
    int dcm_variant;              /* 0 default, 1 paper (driver/dcm.h) */
    uint32_t dcm_off;             /* PN_DCM_OFF_* bits: departures switched off */
    const char *preview;          /* NULL: none; else rewritten every preview_every_seconds */
    double preview_every_seconds; /* > 0 */
    void *integrator_data;        /* what the integrator's prepare() built for this render */
    atomic_int *cancel;
    struct pn_progress *progress; /* render/progress.h: the render's progress path (may be NULL) */
} pn_render_job;

/* The visibility of a shadow ray o + t d, t in (tmin, tmax), in [0, 1]: 0 when something opaque
 * blocks it; else the Fresnel transmittance of the thin glass panes it crosses
 * (pn_accel_transmittance), or 0 if it crosses one and job->opaque_glass is set. Exactly 0 or 1
 * in scenes without thin glass, with the answer pn_accel_occluded gives. The one place every
 * integrator's shadow rays are answered (render/shadow.c). */
float pn_shadow_transmittance(const pn_render_job *job, vec3 o, vec3 d, float tmin, float tmax);

/* The result of following an eye ray through perfect specular interactions to the first
 * non-specular surface. */
typedef struct pn_eye_path {
    vec3 emitted;    /* radiance collected along the way (emitters, environment), weighted */
    bool has_point;  /* ended at a surface with a non-specular lobe */
    vec3 throughput; /* product of specular tints up to the point */
    pn_hit hit;
    vec3 wo;       /* unit direction from the point back along the path */
    uint32_t rays; /* intersect calls made (1 + specular bounces) */
    float first_depth;
    vec3 first_normal;
    vec3 first_albedo;
} pn_eye_path;

/* Traces the camera ray o + t d through mirrors, dielectrics and interfaces. u_specular drives
 * the first reflect/refract choice; deeper choices use a hash of (seed, u_specular, depth). */
void pn_trace_eye_path(const pn_render_job *job, vec3 o, vec3 d, float u_specular, pn_eye_path *path);
/* pn_trace_eye_path in spectral mode: emission, the environment and specular tints at the
 * wavelengths wl (NULL: RGB, as pn_trace_eye_path). first_albedo stays linear sRGB. */
struct pn_swl;
void pn_trace_eye_path_spectral(const pn_render_job *job, vec3 o, vec3 d, float u_specular, const struct pn_swl *wl,
                                pn_eye_path *path);
/* The wavelengths of eye sample i of the pixel sequence `scramble` in spectral mode, written to
 * *storage; NULL in RGB mode. From a Sobol dimension of its own (PN_SOBOL_DIMS - 1, its own
 * scramble), so RGB mode's numbers are unchanged. */
const struct pn_swl *pn_eye_wavelengths(const pn_render_job *job, uint32_t scramble, uint32_t i,
                                        struct pn_swl *storage);
/* Spectral mode, for integrators that share an eye ray's shading point between light samples
 * (ias): the linear sRGB of f(wo, wi) L T for one light sample at wavelengths of its own (from
 * Sobol dimension PN_SOBOL_DIMS - 1 of sample `index` in the sequence `scramble`, salted apart from
 * pn_eye_wavelengths). b is the RGB BSDF (pn_bsdf_at), radiance the light sample's RGB radiance
 * from scene light `light` (-1: an environment region), throughput the RGB specular tints (as one
 * albedo spectrum: exact for one tint). With edi non-NULL, *edi receives the melanopic EDI (lux,
 * spectral/melanopic.h) of the light's radiance at those wavelengths (PN_AOV_MELANOPIC_EDI: the
 * same sample's term on a white receiver, as pn_photometric(radiance) is its illuminance term). */
struct pn_bsdf;
vec3 pn_spectral_sample_value(const pn_render_job *job, const struct pn_bsdf *b, vec3 wo, vec3 wi, vec3 radiance,
                              vec3 throughput, int light, uint32_t index, uint32_t scramble, float *edi);

/* Eye sample i of full-image pixel (px, py) in the per-pixel convention of the `reference`
 * integrator: one scrambled Sobol sequence per pixel (the scramble a hash of the seed and the
 * pixel), dimensions 0-1 the position under the pixel filter (its weight in *fw), 2-3 the lens,
 * 4 the specular choice. The camera ray goes to *o, *d; pn_trace_eye_path takes *u_specular. */
uint32_t pn_pixel_scramble(const pn_render_job *job, int px, int py);
void pn_pixel_eye_sample(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, vec3 *o, vec3 *d,
                         float *fw, float *u_specular);

#endif
